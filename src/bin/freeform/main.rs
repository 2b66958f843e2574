//! The `freeform` command-line tool. `freeform <COMMAND> --help` lists every option.

mod beam;
mod modes;
mod run;

use clap::{Parser, Subcommand};
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
    Modes(modes::ModesArgs),
    /// Simulate a scene file (TOML) and write frames for ParaView.
    Run(run::RunArgs),
    /// The standard beam benchmark: reduced model against the FEM reference (bend | twist).
    Beam(beam::BeamArgs),
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
        rayon::ThreadPoolBuilder::new()
            .num_threads(t)
            .build_global()?;
    }
    Ok(())
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Modes(args) => modes::run(args),
        Command::Run(args) => run::run(args),
        Command::Beam(args) => beam::run(args),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::FAILURE
        }
    }
}
