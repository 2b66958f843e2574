//! `freeform modes`: compute skinning eigenmodes and write a basis file.

use crate::problem::BasisArgs;
use crate::{emit, set_threads, CliResult};
use clap::{Args, ValueEnum};
use freeform::eigen::EigenRequest;
use freeform::eigen::SlepcPreset;
use freeform::io::basis::BasisMetadata;
use freeform::io::read_shape;
use freeform::options;
use freeform::precompute::{BasisOptions, Problem, SolverConfig};
use freeform::progress::{Progress, Silent, TerminalProgress};
use std::io::IsTerminal;
use std::path::PathBuf;

#[derive(Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum SolverArg {
    Lobpcg,
    Dense,
    /// SLEPc (needs a build with `--features slepc`; works under mpirun).
    Slepc,
}

#[derive(Args)]
#[command(allow_negative_numbers = true)]
pub struct ModesArgs {
    /// The shape: box:LX,LY,LZ (corner at the origin), sphere:R (centred at the origin), or a
    /// .obj / .stl / .off / .ply file (a PLY without faces is a point cloud, e.g. Gaussian splats).
    #[arg(required_unless_present = "from_matrices")]
    shape: Option<String>,
    /// Discretization, material and tolerance (shared with `export` and `compare`).
    #[command(flatten)]
    basis: BasisArgs,
    // The eigensolver's flags, written out here (only `modes` takes them in this form): their
    // help lines are the option table's rows, their defaults the library's.
    #[arg(
        long,
        value_enum,
        help = options::SOLVER.help,
        default_value = SolverConfig::default().to_string()
    )]
    solver: SolverArg,
    #[arg(long, help = options::SLEPC.help, default_value = SlepcPreset::default().name())]
    slepc: String,
    #[arg(
        long,
        allow_hyphen_values = true,
        help = options::PETSC_OPTIONS.help,
        default_value = ""
    )]
    petsc_options: String,
    #[arg(long, help = options::LOBPCG.help, default_value = "")]
    lobpcg: String,
    /// Solve the matrices in DIR (hessian.mtx, mass.mtx from `freeform export` or any
    /// MatrixMarket pair) instead of building them from a shape; writes the eigenvectors as a
    /// MatrixMarket array to --out (default eigenvectors.mtx).
    #[arg(long, value_name = "DIR")]
    from_matrices: Option<PathBuf>,
    /// With --solver slepc: assemble distributed (each MPI rank only its kernels' rows)
    /// even on one rank [default: when run under mpirun with more than one rank].
    #[arg(long)]
    distributed: bool,
    /// Where to write the basis [default: basis.npz; eigenvectors.mtx with --from-matrices].
    #[arg(long)]
    out: Option<PathBuf>,
    /// Print the JSON report on standard output.
    #[arg(long)]
    json: bool,
    /// Worker threads (default: all cores).
    #[arg(long)]
    threads: Option<usize>,
    /// Also write the basis as a USD stage Kaolin loads: Kaolin's physics schemas (materials,
    /// skinning weights) at the integration points (docs/usd.md).
    #[arg(long, value_name = "FILE")]
    usd: Option<PathBuf>,
    /// Also draw the first modes' weights on the shape into this PNG file (a grid of
    /// tiles, three per row; docs/pictures.md).
    #[arg(long, value_name = "FILE")]
    png: Option<PathBuf>,
    /// Number of non-constant modes in the --png picture.
    #[arg(long, default_value_t = 6)]
    png_modes: usize,
    /// Size of each mode's tile in the --png picture, WIDTHxHEIGHT pixels.
    #[arg(long, default_value = "360x300")]
    png_tile: String,
    /// The camera of the --png picture.
    #[command(flatten)]
    view: crate::render::ViewArgs,
    /// Turn warnings (moment matrices close to singular, reproducing error, eigen-residuals
    /// above --tol, lost M-orthonormality) into an error: exit code 1, no basis file written.
    #[arg(long)]
    strict: bool,
}

pub fn run(args: ModesArgs) -> CliResult {
    set_threads(args.threads)?;
    if let Some(dir) = &args.from_matrices {
        return from_matrices(dir, &args);
    }
    let shape_arg = args.shape.clone().unwrap_or_default();
    let out = args
        .out
        .clone()
        .unwrap_or_else(|| PathBuf::from("basis.npz"));
    let mut opts = args.basis.options();
    // Check the parameters before reading a possibly large file.
    opts.validate()?;
    let png_tile = crate::render::parse_size(&args.png_tile, "--png-tile")?;
    // Check the camera flags before the precompute, not after it.
    let _ = args.view.options()?;
    opts.solver = solver_config(args.solver, &args.slepc, &args.petsc_options, &args.lobpcg)?;
    let shape = read_shape(&shape_arg, &args.basis.shape_options())?;
    let bar = TerminalProgress::new();
    let progress: &dyn Progress = if std::io::stderr().is_terminal() {
        &bar
    } else {
        &Silent
    };
    let Computed {
        report,
        basis,
        points,
        distributed,
    } = match distributed_run(&args, &shape, &opts, progress)? {
        Some(computed) => computed,
        None => {
            let run = Problem::from_shape(&shape, &opts, progress)?.solve(progress)?;
            Computed {
                report: run.report,
                basis: Some(run.basis),
                points: Some(run.points),
                distributed: None,
            }
        }
    };
    // Under mpirun only rank 0 (which holds the basis) writes and prints.
    let Some(basis) = basis else {
        return Ok(());
    };
    if !crate::is_root_rank(&opts.solver)? {
        return Ok(());
    }
    let metadata = BasisMetadata::for_modes(&shape_arg, &opts, &report);
    if args.strict && !report.warnings.is_empty() {
        for w in &report.warnings {
            eprintln!("warning: {w}");
        }
    }
    let warnings: Vec<_> = (report.warnings.iter())
        .map(freeform::report::Warning::monitor)
        .collect();
    freeform::error::check_strict(args.strict, &warnings)?;
    freeform::io::basis::save(&out, &basis, &metadata)?;
    // A distributed run keeps no point set: sample one for the picture or the stage.
    let sample = |count: usize| {
        freeform::precompute::sample_shape(
            &shape,
            freeform::precompute::sampling::Resolution::Count(count),
            &opts.cloud,
        )
    };
    if let Some(usd) = &args.usd {
        let ip = match &points {
            Some(p) => p.clone(),
            None => sample(report.points)?,
        };
        let material = opts.material_field(&shape, &ip.points)?;
        let name = out
            .file_stem()
            .map_or("basis".into(), |s| s.to_string_lossy());
        freeform::io::usd::kaolin::write_basis_stage(
            usd,
            &name,
            &ip.points,
            &ip.volumes,
            &material,
            &basis,
        )?;
    }
    if let Some(png) = &args.png {
        let sampled;
        let points = match &points {
            Some(p) => &p.points,
            None => {
                sampled = sample(report.points.min(PICTURE_POINTS))?.points;
                &sampled
            }
        };
        crate::render::modes_png(
            png,
            &shape,
            &basis,
            points,
            crate::render::ModesLayout {
                count: args.png_modes,
                tile: png_tile,
                density_tile: !opts.density.is_off(),
            },
            &args.view,
        )?;
    }
    let r = &report;
    if args.json {
        let mut value = serde_json::to_value(r)?;
        value["shape"] = serde_json::Value::String(shape_arg.clone());
        value["basis_file"] = serde_json::Value::String(out.display().to_string());
        if let Some(d) = distributed {
            // The name for the check, at the top level, beside the full figures.
            value["peak_memory_bytes_per_rank"] = d["peak_memory_bytes_per_rank"].clone();
            value["distributed"] = d;
        }
        emit(&(serde_json::to_string_pretty(&value)? + "\n"))?;
    } else {
        emit(&summary(r, &shape_arg, &out))?;
    }
    Ok(())
}

/// The human-readable summary of a `modes` run.
fn summary(r: &freeform::precompute::ModesReport, shape: &str, out: &std::path::Path) -> String {
    let t = &r.timings_s;
    let ev: Vec<String> = r.eigenvalues.iter().map(|v| format!("{v:.6e}")).collect();
    let mut lines = vec![
        format!("freeform modes {shape}"),
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
    lines.push(format!("  basis written to {}", out.display()));
    lines.join("\n") + "\n"
}

/// The eigensolver asked for on the command line (`--solver`; `--slepc` and
/// `--petsc-options` only apply to `--solver slepc`, `--lobpcg` to `--solver lobpcg`). A
/// build without SLEPc says so before judging the `--slepc` value.
pub fn solver_config(
    solver: SolverArg,
    slepc: &str,
    petsc_options: &str,
    lobpcg: &str,
) -> Result<SolverConfig, Box<dyn std::error::Error>> {
    match solver {
        SolverArg::Lobpcg | SolverArg::Dense if !petsc_options.is_empty() => {
            Err("--petsc-options applies to --solver slepc only".into())
        }
        SolverArg::Dense | SolverArg::Slepc if !lobpcg.is_empty() => {
            Err("--lobpcg applies to --solver lobpcg only".into())
        }
        SolverArg::Lobpcg if !lobpcg.is_empty() => Ok(SolverConfig::Lobpcg(
            freeform::eigen::lobpcg::LobpcgOptions::parse(lobpcg)?,
        )),
        SolverArg::Lobpcg => Ok(SolverConfig::lobpcg()),
        SolverArg::Dense => Ok(SolverConfig::Dense),
        #[cfg(not(feature = "slepc"))]
        SolverArg::Slepc => {
            let _ = slepc;
            Err(crate::no_slepc())
        }
        #[cfg(feature = "slepc")]
        SolverArg::Slepc => Ok(SolverConfig::slepc(slepc, petsc_options)?),
    }
}

/// What `modes` computed: the report, the basis (on the rank that writes it), the integration
/// points (a one-process run) and the per-rank figures (`DistributedReport` as JSON).
struct Computed {
    report: freeform::precompute::ModesReport,
    basis: Option<freeform::precompute::skinning::Basis>,
    points: Option<freeform::precompute::sampling::IntegrationPoints>,
    distributed: Option<serde_json::Value>,
}

/// Integration points drawn by `--png` after a distributed run (which keeps none).
const PICTURE_POINTS: usize = 200_000;

/// The MPI-distributed pipeline when asked for (`--distributed`) or when running on several
/// ranks with `--solver slepc`; `None` otherwise.
#[cfg(feature = "slepc")]
fn distributed_run(
    args: &ModesArgs,
    shape: &freeform::geometry::Shape,
    opts: &BasisOptions,
    progress: &dyn Progress,
) -> Result<Option<Computed>, Box<dyn std::error::Error>> {
    use freeform::eigen::slepc::world_rank;
    let SolverConfig::Slepc(slepc) = &opts.solver else {
        if args.distributed {
            return Err("--distributed needs --solver slepc".into());
        }
        return Ok(None);
    };
    if !args.distributed && world_rank()?.1 == 1 {
        return Ok(None);
    }
    let run = freeform::precompute::distributed::build_basis_mpi(shape, opts, slepc, progress)?;
    Ok(Some(Computed {
        distributed: Some(serde_json::to_value(&run.distributed)?),
        report: run.report,
        basis: run.basis,
        points: None,
    }))
}

#[cfg(not(feature = "slepc"))]
fn distributed_run(
    args: &ModesArgs,
    _shape: &freeform::geometry::Shape,
    _opts: &BasisOptions,
    _progress: &dyn Progress,
) -> Result<Option<Computed>, Box<dyn std::error::Error>> {
    if args.distributed {
        return Err(crate::no_slepc());
    }
    Ok(None)
}

/// `--from-matrices DIR`: solve given H and M, report, write the eigenvectors.
fn from_matrices(dir: &std::path::Path, args: &ModesArgs) -> CliResult {
    use freeform::io::matrix_market::{read_matrices, write_dense_matrix_market};
    let config = solver_config(args.solver, &args.slepc, &args.petsc_options, &args.lobpcg)?;
    let solver = config.build()?;
    let clock = freeform::report::Stopwatch::start();
    let (h, m) = read_matrices(dir)?;
    let read_s = clock.elapsed();
    let request = EigenRequest {
        nev: args.basis.choices.options.modes.saturating_add(1),
        tol: args.basis.choices.options.tol,
        max_iter: args.basis.choices.options.max_iter,
    };
    let clock = freeform::report::Stopwatch::start();
    let solution = solver.solve_converged(
        h.as_ref(),
        m.as_ref(),
        &request,
        &freeform::progress::Silent,
    )?;
    let solve_s = clock.elapsed();
    if !crate::is_root_rank(&config)? {
        return Ok(());
    }
    let out = args
        .out
        .clone()
        .unwrap_or_else(|| PathBuf::from("eigenvectors.mtx"));
    write_dense_matrix_market(
        &out,
        &solution.vectors,
        &["freeform eigenvectors, K x (m + 1), columns ascending by eigenvalue, M-orthonormal"],
    )?;
    let report = serde_json::json!({
        "matrices": dir.display().to_string(),
        "kernels": h.nrows(),
        "modes": args.basis.choices.options.modes,
        "nnz_hessian": h.compute_nnz(),
        "nnz_mass": m.compute_nnz(),
        "solver": solver.name(),
        "eigenvalues": solution.values,
        "max_relative_residual": solution.info.max_relative_residual,
        "orthonormality_error": solution.info.orthonormality_error,
        "timings_s": { "read": read_s, "eigensolve": solve_s },
        "eigen": solution.info,
        "tol": args.basis.choices.options.tol,
        "eigenvectors_file": out.display().to_string(),
    });
    if args.json {
        emit(&(serde_json::to_string_pretty(&report)? + "\n"))?;
    } else {
        let ev: Vec<String> = solution.values.iter().map(|v| format!("{v:.6e}")).collect();
        emit(&format!(
            "freeform modes --from-matrices {}\n  K {}  solver {}\n  eigenvalues: {}\n  max relative residual {:.2e}  orthonormality error {:.2e}\n  time [s]: read {read_s:.3}  eigensolve {solve_s:.3}\n  eigenvectors written to {}\n",
            dir.display(),
            h.nrows(),
            solution.info.solver,
            ev.join(" "),
            solution.info.max_relative_residual,
            solution.info.orthonormality_error,
            out.display()
        ))?;
    }
    Ok(())
}
