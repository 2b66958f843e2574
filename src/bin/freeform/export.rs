//! `freeform export`: build H_w and M for a shape and write them for other solvers.

use crate::problem::ShapeArgs;
use crate::{emit, set_threads, CliResult};
use clap::Args;
use freeform::io::matrix_market::write_matrices;
use freeform::precompute::{MatrixStorage, Problem};
use std::path::PathBuf;

#[derive(Args)]
#[command(allow_negative_numbers = true)]
pub struct ExportArgs {
    #[command(flatten)]
    shape: ShapeArgs,
    /// Output directory: hessian.mtx and mass.mtx (MatrixMarket, symmetric) plus
    /// hessian.petsc and mass.petsc (PETSc binary, for MatLoad).
    #[arg(long)]
    out: PathBuf,
    /// Print a JSON report on standard output.
    #[arg(long)]
    json: bool,
    /// Worker threads (default: all cores).
    #[arg(long)]
    threads: Option<usize>,
}

pub fn run(args: ExportArgs) -> CliResult {
    set_threads(args.threads)?;
    let (shape, mut opts) = args.shape.build()?;
    // Both triangles are written: assemble them so (auto would take the upper triangle and
    // mirror it, holding both).
    if opts.matrix_storage == MatrixStorage::Auto {
        opts.matrix_storage = MatrixStorage::Full;
    }
    let problem = Problem::from_shape(&shape, &opts, &freeform::progress::Silent)?;
    let a = problem.matrices();
    let files = write_matrices(&args.out, a.hessian(), a.mass(), true)?;
    let report = serde_json::json!({
        "shape": args.shape.shape,
        "kernels": problem.kernels().len(),
        "points": problem.points().len(),
        "nnz_hessian": a.hessian().compute_nnz(),
        "nnz_mass": a.mass().compute_nnz(),
        "files": files.iter().map(|p| p.display().to_string()).collect::<Vec<_>>(),
        "timings_s": problem.timings(),
        "note": "solve H_w c = lambda M c for the m + 1 smallest pairs (lambda_0 = 0: constant)",
    });
    if args.json {
        emit(&(serde_json::to_string_pretty(&report)? + "\n"))?;
    } else {
        emit(&format!(
            "freeform export {}\n  K {}  H_w nnz {}  M nnz {}\n  wrote {}\n",
            args.shape.shape,
            problem.kernels().len(),
            a.hessian().compute_nnz(),
            a.mass().compute_nnz(),
            files
                .iter()
                .map(|p| p.display().to_string())
                .collect::<Vec<_>>()
                .join(", ")
        ))?;
    }
    Ok(())
}
