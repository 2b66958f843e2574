//! `freeform modes`: compute skinning eigenmodes and write a basis file.

use crate::{emit, set_threads, CliResult};
use clap::{Args, ValueEnum};
use freeform::geometry::{Shape, ShapeOptions};
use freeform::material::Material;
use freeform::pipeline::{build_basis, BasisOptions, SolverChoice};
use freeform::progress::{Progress, Silent, TerminalProgress};
use freeform::rkpm::{KernelType, SupportOptions};
use freeform::sampling::{CloudVolumeOptions, Resolution};
use std::io::IsTerminal;
use std::path::PathBuf;

#[derive(Clone, Copy, ValueEnum)]
enum KernelArg {
    Cubic,
    Quartic,
    Gaussian,
}

#[derive(Clone, Copy, ValueEnum)]
enum SolverArg {
    Lobpcg,
    Dense,
}

#[derive(Args)]
#[command(allow_negative_numbers = true)]
pub struct ModesArgs {
    /// The shape: box:LX,LY,LZ (corner at the origin), sphere:R (centred at the origin), or a
    /// .obj / .stl / .ply file (a PLY without faces is a point cloud, e.g. Gaussian splats).
    shape: String,
    /// Number of RKPM kernels K.
    #[arg(long, default_value_t = 1000)]
    kernels: usize,
    /// Number of non-constant modes m (m + 1 handles are computed).
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
    /// Eigensolver.
    #[arg(long, value_enum, default_value = "lobpcg")]
    solver: SolverArg,
    /// Relative residual tolerance of the eigensolver.
    #[arg(long, default_value_t = 1e-8)]
    tol: f64,
    /// Eigensolver iteration cap.
    #[arg(long, default_value_t = 1000)]
    max_iter: usize,
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
    /// Where to write the basis.
    #[arg(long, default_value = "basis.npz")]
    out: PathBuf,
    /// Print the JSON report on standard output.
    #[arg(long)]
    json: bool,
    /// Worker threads (default: all cores).
    #[arg(long)]
    threads: Option<usize>,
}

pub fn run(args: ModesArgs) -> CliResult {
    set_threads(args.threads)?;
    let opts = BasisOptions {
        kernels: args.kernels,
        modes: args.modes,
        resolution: match (args.points, args.spacing) {
            (Some(n), _) => Some(Resolution::Count(n)),
            (None, Some(h)) => Some(Resolution::Spacing(h)),
            (None, None) => None,
        },
        kernel: match args.kernel {
            KernelArg::Cubic => KernelType::Cubic,
            KernelArg::Quartic => KernelType::Quartic,
            KernelArg::Gaussian => KernelType::Gaussian,
        },
        support: SupportOptions {
            factor: args.support,
            neighbor: args.support_neighbor,
        },
        material: Material {
            youngs: args.youngs,
            poisson: args.poisson,
            density: args.density,
        },
        solver: match args.solver {
            SolverArg::Lobpcg => SolverChoice::Lobpcg,
            SolverArg::Dense => SolverChoice::Dense,
        },
        tol: args.tol,
        max_iter: args.max_iter,
        cloud: CloudVolumeOptions {
            voxel: args.voxel,
            total_volume: args.volume,
        },
        ..BasisOptions::default()
    };
    // Check the parameters before reading a possibly large file.
    opts.validate()?;
    let shape = Shape::parse(
        &args.shape,
        &ShapeOptions {
            allow_open_mesh: args.allow_open_mesh,
        },
    )?;
    let bar = TerminalProgress::new();
    let progress: &dyn Progress = if std::io::stderr().is_terminal() {
        &bar
    } else {
        &Silent
    };
    let run = build_basis(&shape, &opts, progress)?;
    let metadata = serde_json::json!({
        "freeform_version": env!("CARGO_PKG_VERSION"),
        "shape": args.shape,
        "options": opts,
        "points": run.report.points,
        "volume": run.report.volume,
        "max_relative_residual": run.report.max_relative_residual,
        "orthonormality_error": run.report.orthonormality_error,
    });
    freeform::io::basis::save(&args.out, &run.basis, &metadata)?;
    let r = &run.report;
    if args.json {
        let mut value = serde_json::to_value(r)?;
        value["shape"] = serde_json::Value::String(args.shape.clone());
        value["basis_file"] = serde_json::Value::String(args.out.display().to_string());
        emit(&(serde_json::to_string_pretty(&value)? + "\n"))?;
    } else {
        emit(&summary(r, &args))?;
    }
    Ok(())
}

/// The human-readable summary of a `modes` run.
fn summary(r: &freeform::pipeline::ModesReport, args: &ModesArgs) -> String {
    let t = &r.timings_s;
    let ev: Vec<String> = r.eigenvalues.iter().map(|v| format!("{v:.6e}")).collect();
    let mut lines = vec![
        format!("freeform modes {}", args.shape),
        format!("  kernels {}  integration points {}  volume {:.6} m^3", r.kernels, r.points, r.volume),
        format!("  modes {} (+ constant)  solver {}  H_w nnz {}  M nnz {}", r.modes, r.solver, r.nnz_hessian, r.nnz_mass),
        format!("  eigenvalues [Pa/m^2]: {}", ev.join(" ")),
        format!(
            "  max relative residual {:.2e}  orthonormality error {:.2e}  reproducing error {:.2e}",
            r.max_relative_residual, r.orthonormality_error, r.reproducing_error
        ),
        format!(
            "  time [s]: sampling {:.3}  centers {:.3}  neighbors {:.3}  shape functions {:.3}  assembly {:.3}  eigensolve {:.3}  total {:.3}",
            t.sampling, t.centers, t.neighbors, t.shape_functions, t.assembly, t.eigensolve, t.total
        ),
        format!("  peak memory {:.1} MB", r.peak_memory_bytes as f64 / 1e6),
    ];
    lines.extend(r.warnings.iter().map(|w| format!("  warning: {w}")));
    lines.push(format!("  basis written to {}", args.out.display()));
    lines.join("\n") + "\n"
}
