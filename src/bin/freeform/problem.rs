//! The shape and discretization options shared by `export` and `compare` (the same flags and
//! defaults as `modes`).

use clap::{Args, ValueEnum};
use freeform::geometry::{Shape, ShapeOptions};
use freeform::material::Material;
use freeform::pipeline::BasisOptions;
use freeform::rkpm::{KernelType, SupportOptions};
use freeform::sampling::{CloudVolumeOptions, Resolution};

#[derive(Clone, Copy, ValueEnum)]
enum KernelArg {
    Cubic,
    Quartic,
    Gaussian,
}

#[derive(Args)]
pub struct ShapeArgs {
    /// The shape: box:LX,LY,LZ, sphere:R, or a .obj / .stl / .ply file (see `modes --help`).
    pub shape: String,
    /// Number of RKPM kernels K.
    #[arg(long, default_value_t = 1000)]
    kernels: usize,
    /// Number of non-constant modes m (m + 1 pairs are computed).
    #[arg(long, default_value_t = 16)]
    modes: usize,
    /// Target number of integration points [default: 50 K, clamped to 20,000..2,000,000].
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
    /// Relative residual tolerance of the eigensolvers.
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
    /// Point clouds: total object volume, m^3.
    #[arg(long)]
    volume: Option<f64>,
    /// Point clouds: voxel edge for the volume estimate, metres.
    #[arg(long)]
    voxel: Option<f64>,
    /// Accept a mesh with holes.
    #[arg(long)]
    allow_open_mesh: bool,
}

impl ShapeArgs {
    /// The pipeline options (validated) and the parsed shape.
    pub fn build(&self) -> Result<(Shape, BasisOptions), Box<dyn std::error::Error>> {
        let opts = BasisOptions {
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
            ..BasisOptions::default()
        };
        opts.validate()?;
        let shape = Shape::parse(
            &self.shape,
            &ShapeOptions {
                allow_open_mesh: self.allow_open_mesh,
            },
        )?;
        Ok((shape, opts))
    }
}
