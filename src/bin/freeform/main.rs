//! The `freeform` command-line tool. `freeform <COMMAND> --help` lists every option.

mod beam;
mod compare;
mod eval;
mod export;
mod modes;
mod problem;
mod render;
mod render_usd;
mod run;
mod sweep;
mod sweep_plot;

use clap::{Parser, Subcommand};
use freeform::options::Front;
use std::process::ExitCode;

/// What every subcommand returns: errors are printed by `main` and give exit code 1.
pub type CliResult = Result<(), Box<dyn std::error::Error>>;

#[derive(Parser)]
#[command(
    name = "freeform",
    version,
    about = "Mesh-free reduced-order elastic simulation from RKPM skinning eigenmodes"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Compute skinning eigenmodes of a shape and write them to a basis file (.npz).
    Modes(Box<modes::ModesArgs>),
    /// Simulate a scene file (TOML) and write frames for ParaView.
    Run(run::RunArgs),
    /// The standard beam benchmark: reduced model against the FEM reference (bend | twist).
    Beam(beam::BeamArgs),
    /// The beam benchmark over m x K plus variations of points, cubature and Hessian
    /// strategy: CSV and PNG plots of error against precompute and step time (Pareto front).
    Sweep(sweep::SweepArgs),
    /// The real-shape accuracy protocol (paper Table 2) over a folder of closed meshes:
    /// fix side, pull farthest points, pull ends against TetGen FEM; CSV, JSON and a plot.
    Eval(eval::EvalArgs),
    /// Build H_w and M once and compare eigensolvers on them (native LOBPCG, SLEPc, dense).
    Compare(compare::CompareArgs),
    /// Write H_w and M of a shape as MatrixMarket and PETSc binary files.
    Export(export::ExportArgs),
    /// Draw a run's frames (the --out directory of `run`) as PNG pictures.
    Render(render::RenderArgs),
}

/// The error for SLEPc options in a build without the `slepc` feature (the library's).
#[cfg(not(feature = "slepc"))]
pub fn no_slepc() -> Box<dyn std::error::Error> {
    freeform::eigen::EigenError::SlepcUnavailable.into()
}

/// Whether this process prints and writes: rank 0 of the MPI run when `solver` is SLEPc
/// (every rank runs the command under mpirun), always otherwise.
pub fn is_root_rank(
    solver: &freeform::precompute::SolverConfig,
) -> Result<bool, Box<dyn std::error::Error>> {
    if matches!(solver, freeform::precompute::SolverConfig::Slepc(_)) {
        is_root_rank_any()
    } else {
        Ok(true)
    }
}

/// Rank 0 of the MPI run (true without SLEPc, where there is no MPI).
pub fn is_root_rank_any() -> Result<bool, Box<dyn std::error::Error>> {
    #[cfg(feature = "slepc")]
    {
        Ok(freeform::eigen::slepc::world_rank()?.0 == 0)
    }
    #[cfg(not(feature = "slepc"))]
    {
        Ok(true)
    }
}

/// Write to standard output; a closed pipe (`freeform ... | head`) is not an error.
pub fn emit(text: &str) -> std::io::Result<()> {
    use std::io::Write;
    let mut out = std::io::stdout().lock();
    match out.write_all(text.as_bytes()).and_then(|_| out.flush()) {
        Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => Ok(()),
        other => other,
    }
}

/// Size rayon's global pool from `--threads` (None: all cores).
pub fn set_threads(threads: Option<usize>) -> CliResult {
    if let Some(t) = threads {
        if t == 0 {
            return Err("--threads must be at least 1".into());
        }
        if t > 1024 {
            return Err(format!(
                "--threads {t} is more than 1024; use at most the number of cores (or omit it)"
            )
            .into());
        }
        rayon::ThreadPoolBuilder::new()
            .num_threads(t)
            .build_global()?;
    }
    Ok(())
}

fn dispatch(command: Command) -> CliResult {
    match command {
        Command::Modes(args) => modes::run(*args),
        Command::Run(args) => run::run(args),
        Command::Beam(args) => beam::run(args),
        Command::Sweep(args) => sweep::run(args),
        Command::Compare(args) => compare::run(args),
        Command::Eval(args) => eval::run(args),
        Command::Export(args) => export::run(args),
        Command::Render(args) if render_usd::is_usd(&args.dir) => render_usd::run(&args),
        Command::Render(args) => render::run(args),
    }
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    // Every message of the command (errors, warnings, JSON reports) names an option as its
    // users set it: by its flag, or for `run` by its scene-file key.
    let front = match cli.command {
        Command::Run(_) => Front::Scene,
        _ => Front::Flags,
    };
    front.scope(|| finish(front, cli.command))
}

/// Run `command` and end the process: exit code, messages, PETSc/MPI finalization.
fn finish(front: Front, command: Command) -> ExitCode {
    // A panic must not skip PETSc/MPI finalization (mpirun would report an abort).
    let result = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| dispatch(command)));
    let code = match result {
        Ok(Ok(())) => ExitCode::SUCCESS,
        Ok(Err(e)) => {
            eprintln!("error: {}", front.render(&*e));
            ExitCode::FAILURE
        }
        // The panic hook has printed the message.
        Err(_) => {
            // Other ranks may wait in a collective for this one: end the whole run.
            #[cfg(feature = "slepc")]
            freeform::eigen::slepc::abort_if_parallel(101);
            ExitCode::from(101)
        }
    };
    #[cfg(feature = "slepc")]
    if let Err(e) = freeform::eigen::slepc::finalize() {
        eprintln!("error: {}", front.render(&e));
        return ExitCode::FAILURE;
    }
    code
}
