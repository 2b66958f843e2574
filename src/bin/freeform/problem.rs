//! The shape and discretization options shared by `export` and `compare` (the same flags and
//! defaults as `modes`).

use clap::{Args, ValueEnum};
use freeform::geometry::{Shape, ShapeOptions};
use freeform::io::read_shape;
use freeform::material::{Material, Region};
use freeform::precompute::rkpm::{KernelType, SupportOptions};
use freeform::precompute::sampling::{CloudVolumeOptions, Resolution};
use freeform::precompute::BasisOptions;

#[derive(Clone, Copy, ValueEnum)]
enum KernelArg {
    Cubic,
    Quartic,
    Gaussian,
}

/// The discretization, material and eigensolver-tolerance flags of every command that builds
/// H_w and M (`modes`, `export`, `compare`), with the same defaults everywhere.
#[derive(Args)]
pub struct BasisArgs {
    /// Number of RKPM kernels K.
    #[arg(long, default_value_t = 1000)]
    pub kernels: usize,
    /// Number of non-constant modes m (m + 1 handles are computed).
    #[arg(long, default_value_t = 16)]
    pub modes: usize,
    /// Target number of integration points [default: 50 K, clamped to 20,000..2,000,000, and
    /// 10 K above K = 200,000].
    #[arg(long, conflicts_with = "spacing")]
    points: Option<usize>,
    /// Integration grid spacing, metres (instead of --points).
    #[arg(long)]
    spacing: Option<f64>,
    /// Kernel window function.
    #[arg(long, value_enum, default_value = "cubic")]
    kernel: KernelArg,
    /// Support radius = F x distance to the n-th nearest other centre.
    #[arg(long, default_value_t = SupportOptions::default().factor)]
    support: f64,
    /// The n in --support.
    #[arg(long, default_value_t = SupportOptions::default().neighbor)]
    support_neighbor: usize,
    /// Relative residual tolerance of the eigensolver(s).
    #[arg(long, default_value_t = 1e-8)]
    pub tol: f64,
    /// Eigensolver iteration cap.
    #[arg(long, default_value_t = 1000)]
    pub max_iter: usize,
    /// Young's modulus E, Pa.
    #[arg(long, default_value_t = Material::default().youngs)]
    youngs: f64,
    /// Poisson ratio nu, in (-1, 0.5).
    #[arg(long, default_value_t = Material::default().poisson)]
    poisson: f64,
    /// Density rho, kg/m^3.
    #[arg(long, default_value_t = Material::default().density)]
    density: f64,
    /// Point clouds: total object volume, m^3 (default: voxel-occupancy estimate).
    #[arg(long)]
    volume: Option<f64>,
    /// Point clouds: voxel edge for the volume estimate, metres (default: 2 x median spacing).
    #[arg(long)]
    voxel: Option<f64>,
    /// Accept a mesh with holes (inside = winding number >= 0.5).
    #[arg(long)]
    allow_open_mesh: bool,
    /// A boundary region the basis follows exactly (a boundary-aware basis: one lift per
    /// region, free modes that vanish there; docs/math.md), rest coordinates in metres:
    /// box:X0,Y0,Z0,X1,Y1,Z1, sphere:CX,CY,CZ,R or halfspace:PX,PY,PZ,NX,NY,NZ. Repeat for
    /// several regions (at most --modes).
    #[arg(long = "region", value_name = "REGION", value_parser = parse_region)]
    regions: Vec<Region>,
}

fn parse_region(s: &str) -> Result<Region, String> {
    s.parse::<Region>().map_err(|e| e.to_string())
}

impl BasisArgs {
    /// The pipeline options these flags ask for (not yet validated; the solver is the
    /// default LOBPCG).
    pub fn options(&self) -> BasisOptions {
        BasisOptions {
            kernels: self.kernels,
            modes: self.modes,
            resolution: match (self.points, self.spacing) {
                (Some(n), _) => Some(Resolution::Count(n)),
                (None, Some(h)) => Some(Resolution::Spacing(h)),
                (None, None) => None,
            },
            kernel: match self.kernel {
                KernelArg::Cubic => KernelType::Cubic,
                KernelArg::Quartic => KernelType::Quartic,
                KernelArg::Gaussian => KernelType::Gaussian,
            },
            support: SupportOptions {
                factor: self.support,
                neighbor: self.support_neighbor,
            },
            material: Material {
                youngs: self.youngs,
                poisson: self.poisson,
                density: self.density,
            },
            tol: self.tol,
            max_iter: self.max_iter,
            cloud: CloudVolumeOptions {
                voxel: self.voxel,
                total_volume: self.volume,
            },
            boundary_regions: self.regions.clone(),
            ..BasisOptions::default()
        }
    }

    /// How to read the shape.
    pub fn shape_options(&self) -> ShapeOptions {
        ShapeOptions {
            allow_open_mesh: self.allow_open_mesh,
        }
    }
}

/// A shape and its [`BasisArgs`] (`export`, `compare`).
#[derive(Args)]
pub struct ShapeArgs {
    /// The shape: box:LX,LY,LZ, sphere:R, or a .obj / .stl / .off / .ply file (see `modes --help`).
    pub shape: String,
    /// Discretization, material and tolerance.
    #[command(flatten)]
    pub basis: BasisArgs,
}

impl ShapeArgs {
    /// The pipeline options (validated) and the parsed shape.
    pub fn build(&self) -> Result<(Shape, BasisOptions), Box<dyn std::error::Error>> {
        let opts = self.basis.options();
        opts.validate()?;
        let shape = read_shape(&self.shape, &self.basis.shape_options())?;
        Ok((shape, opts))
    }
}
