//! `freeform compare`: build H_w and M once, solve them with the native LOBPCG and each SLEPc
//! configuration asked for (and optionally the dense oracle), and compare the results
//! (`Problem::compare` does the work).

use crate::problem::ShapeArgs;
use crate::{emit, set_threads, CliResult};
use clap::Args;
use freeform::precompute::{MatrixStorage, Problem, ProblemComparison, SolverConfig};
use freeform::progress::Silent;
use serde::Serialize;

#[derive(Args)]
#[command(allow_negative_numbers = true)]
pub struct CompareArgs {
    #[command(flatten)]
    shape: ShapeArgs,
    /// SLEPc configurations, comma-separated or repeated: ks-sinvert, lobpcg-gamg,
    /// lobpcg-hypre, raw PETSc options ("-eps_type jd -st_pc_type gamg"), or
    /// preset:options [default with a `slepc` build: lobpcg-gamg, the default of
    /// `--solver slepc`, and ks-sinvert, the direct one; docs/slepc.md].
    #[arg(long, value_delimiter = ',', allow_hyphen_values = true)]
    slepc: Vec<String>,
    /// Also run the dense reference solver (K up to a few thousand).
    #[arg(long)]
    dense: bool,
    /// Skip the native LOBPCG (then the first other solver is the reference).
    #[arg(long)]
    no_native: bool,
    /// Eigenvalues closer than this (relative) form one cluster for the subspace angles.
    #[arg(long, default_value_t = 1e-6)]
    cluster_gap: f64,
    /// Print the JSON report on standard output.
    #[arg(long)]
    json: bool,
    /// Worker threads for the native solver (default: all cores).
    #[arg(long)]
    threads: Option<usize>,
}

/// The JSON report: the shape, then the library's comparison.
#[derive(Serialize)]
struct Report<'a> {
    shape: &'a str,
    #[serde(flatten)]
    comparison: &'a ProblemComparison,
}

/// The solvers to compare, in order: native LOBPCG, the SLEPc configurations, dense.
fn solvers(args: &CompareArgs) -> Result<Vec<SolverConfig>, Box<dyn std::error::Error>> {
    let mut out = Vec::new();
    if !args.no_native {
        out.push(SolverConfig::lobpcg());
    }
    #[cfg(feature = "slepc")]
    {
        let specs: Vec<String> = if args.slepc.is_empty() {
            vec!["lobpcg-gamg".into(), "ks-sinvert".into()]
        } else {
            args.slepc.clone()
        };
        for spec in specs.iter().filter(|s| !s.trim().is_empty()) {
            out.push(SolverConfig::slepc(spec, "")?);
        }
    }
    #[cfg(not(feature = "slepc"))]
    if !args.slepc.is_empty() {
        return Err(crate::no_slepc());
    }
    if args.dense {
        out.push(SolverConfig::Dense);
    }
    if out.is_empty() {
        return Err("nothing to compare: no solver selected".into());
    }
    Ok(out)
}

pub fn run(args: CompareArgs) -> CliResult {
    set_threads(args.threads)?;
    let (shape, mut opts) = args.shape.build()?;
    let solvers = solvers(&args)?;
    // Every solver compared reads both triangles: assemble them so.
    if opts.matrix_storage == MatrixStorage::Auto {
        opts.matrix_storage = MatrixStorage::Full;
    }
    let problem = Problem::from_shape(&shape, &opts, &Silent)?;
    // A failed solver's message is formatted in the command's front (`--slepc ...`).
    let comparison = problem.compare(&solvers, args.cluster_gap, &Silent)?;
    if !crate::is_root_rank_any()? {
        return Ok(());
    }
    let report = Report {
        shape: &args.shape.shape,
        comparison: &comparison,
    };
    if args.json {
        emit(&(serde_json::to_string_pretty(&report)? + "\n"))?;
    } else {
        emit(&summary(&report))?;
    }
    if comparison.comparison.any_failed() {
        return Err("at least one solver failed (see the report)".into());
    }
    Ok(())
}

fn summary(r: &Report) -> String {
    let p = r.comparison;
    let c = &p.comparison;
    let mut lines = vec![
        format!("freeform compare {}", r.shape),
        format!(
            "  K {}  points {}  modes {} (+ constant)  tol {:.1e}  iteration cap {}  \
             matrices built in {:.3} s",
            p.kernels, p.points, p.modes, p.tol, c.max_iter, p.matrices_s
        ),
        format!(
            "  {:<40} {:>9} {:>8} {:>6} {:>10} {:>10} {:>10} {:>10}",
            "solver", "time [s]", "cpu [s]", "iters", "residual", "orthonorm", "eig diff", "angle"
        ),
    ];
    for e in &c.solvers {
        lines.push(format!(
            "  {:<40} {:>9.3} {:>8.2} {:>6} {:>10.2e} {:>10.2e} {:>10.2e} {:>10.2e}{}",
            e.solver,
            e.time_s,
            e.cpu_s,
            e.iterations,
            e.max_relative_residual,
            e.orthonormality_error,
            e.eigenvalue_rel_diff,
            e.subspace_angle,
            e.error
                .as_ref()
                .map_or(String::new(), |m| format!("  FAILED: {m}"))
        ));
    }
    lines.push(format!(
        "  reference {}: max eigenvalue rel diff {:.2e}, max subspace angle {:.2e} rad",
        c.reference, c.max_eigenvalue_rel_diff, c.max_subspace_angle
    ));
    lines.join("\n") + "\n"
}
