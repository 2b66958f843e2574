//! `freeform compare`: build H_w and M once, solve them with the native LOBPCG and each SLEPc
//! configuration asked for (and optionally the dense oracle), and compare the results.

use crate::problem::ShapeArgs;
use crate::{emit, set_threads, CliResult};
use clap::Args;
use freeform::eigen::compare::{max_eigenvalue_rel_diff, max_subspace_angle};
use freeform::eigen::{EigenRequest, EigenSolution, Eigensolver};
use freeform::precompute::{Problem, SolverConfig};
use freeform::progress::Silent;
use freeform::report::Stopwatch;
use serde::Serialize;

#[derive(Args)]
#[command(allow_negative_numbers = true)]
pub struct CompareArgs {
    #[command(flatten)]
    shape: ShapeArgs,
    /// SLEPc configurations, comma-separated or repeated: ks-sinvert, lobpcg-gamg,
    /// lobpcg-hypre, raw PETSc options ("-eps_type jd -st_pc_type gamg"), or
    /// preset:options [default with a `slepc` build: ks-sinvert,lobpcg-gamg].
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

/// One solver's figures.
#[derive(Serialize)]
struct Entry {
    solver: String,
    /// Wall-clock seconds of the solve.
    time_s: f64,
    /// CPU seconds of this process during the solve (all threads; user + system): less
    /// sensitive than `time_s` to other processes sharing the cores. 0 where unknown.
    cpu_s: f64,
    iterations: usize,
    max_relative_residual: f64,
    orthonormality_error: f64,
    eigenvalues: Vec<f64>,
    /// Against the reference solver (the first entry that succeeded).
    eigenvalue_rel_diff: f64,
    subspace_angle: f64,
    notes: Vec<String>,
    /// Set when the solver failed; the figures above are then from its partial result or 0.
    error: Option<String>,
}

#[derive(Serialize)]
struct Report {
    shape: String,
    kernels: usize,
    points: usize,
    modes: usize,
    tol: f64,
    nnz_hessian: usize,
    /// Seconds spent building H_w and M (once, shared by every solver).
    matrices_s: f64,
    reference: String,
    solvers: Vec<Entry>,
    max_eigenvalue_rel_diff: f64,
    max_subspace_angle: f64,
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
            vec!["ks-sinvert".into(), "lobpcg-gamg".into()]
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
    let (shape, opts) = args.shape.build()?;
    let solvers = solvers(&args)?
        .iter()
        .map(SolverConfig::build)
        .collect::<Result<Vec<Box<dyn Eigensolver>>, _>>()?;
    let clock = Stopwatch::start();
    let problem = Problem::from_shape(&shape, &opts, &Silent)?;
    let matrices_s = clock.elapsed();
    let (h, m) = (&problem.matrices().hessian, &problem.matrices().mass);
    let request = EigenRequest {
        nev: opts.modes + 1,
        tol: opts.tol,
        max_iter: opts.max_iter,
    };
    let mut results: Vec<(Entry, Option<EigenSolution>)> = Vec::new();
    for solver in &solvers {
        let clock = Stopwatch::start();
        let cpu0 = process_cpu_seconds();
        let outcome = solver.solve(h, m, &request, &Silent);
        let time_s = clock.elapsed();
        let cpu_s = match (cpu0, process_cpu_seconds()) {
            (Some(a), Some(b)) => b - a,
            _ => 0.0,
        };
        let (solution, error) = match outcome {
            Ok(s) => (Some(s), None),
            Err(
                freeform::eigen::EigenError::NotConverged { partial, .. }
                | freeform::eigen::EigenError::SlepcLobpcgNotConverged { partial, .. },
            ) => {
                let msg = format!(
                    "not converged (max relative residual {:.2e})",
                    partial.info.max_relative_residual
                );
                (Some(*partial), Some(msg))
            }
            Err(e) => (None, Some(e.to_string())),
        };
        let entry = Entry {
            solver: solution
                .as_ref()
                .map(|s| s.info.solver.clone())
                .filter(|s| !s.is_empty())
                .unwrap_or_else(|| solver.name().to_string()),
            time_s,
            cpu_s,
            iterations: solution.as_ref().map_or(0, |s| s.info.iterations),
            max_relative_residual: solution
                .as_ref()
                .map_or(f64::INFINITY, |s| s.info.max_relative_residual),
            orthonormality_error: solution
                .as_ref()
                .map_or(f64::INFINITY, |s| s.info.orthonormality_error),
            eigenvalues: solution.as_ref().map_or(Vec::new(), |s| s.values.clone()),
            eigenvalue_rel_diff: 0.0,
            subspace_angle: 0.0,
            notes: solution
                .as_ref()
                .map_or(Vec::new(), |s| s.info.notes.clone()),
            error,
        };
        results.push((entry, solution));
    }
    // Reference: the first solver that succeeded.
    let reference = results
        .iter()
        .position(|(e, s)| e.error.is_none() && s.is_some());
    let (mut max_diff, mut max_angle) = (0.0f64, 0.0f64);
    if let Some(r) = reference {
        let (ref_vals, ref_vecs) = {
            let s = results[r].1.as_ref().ok_or("reference solution missing")?;
            (s.values.clone(), s.vectors.clone())
        };
        for (entry, solution) in results.iter_mut() {
            let Some(s) = solution else {
                continue;
            };
            if s.values.len() != ref_vals.len() {
                entry.eigenvalue_rel_diff = f64::INFINITY;
                entry.subspace_angle = f64::INFINITY;
            } else {
                entry.eigenvalue_rel_diff = max_eigenvalue_rel_diff(&s.values, &ref_vals);
                entry.subspace_angle = max_subspace_angle(
                    m,
                    &s.values,
                    &s.vectors,
                    &ref_vals,
                    &ref_vecs,
                    args.cluster_gap,
                )?;
            }
            if entry.error.is_none() {
                max_diff = max_diff.max(entry.eigenvalue_rel_diff);
                max_angle = max_angle.max(entry.subspace_angle);
            }
        }
    }
    if !crate::is_root_rank_any()? {
        return Ok(());
    }
    let report = Report {
        shape: args.shape.shape.clone(),
        kernels: problem.kernels().len(),
        points: problem.points().len(),
        modes: opts.modes,
        tol: opts.tol,
        nnz_hessian: h.compute_nnz(),
        matrices_s,
        reference: reference.map_or(String::new(), |r| results[r].0.solver.clone()),
        solvers: results.into_iter().map(|(e, _)| e).collect(),
        max_eigenvalue_rel_diff: max_diff,
        max_subspace_angle: max_angle,
    };
    if args.json {
        emit(&(serde_json::to_string_pretty(&report)? + "\n"))?;
    } else {
        emit(&summary(&report))?;
    }
    if report.solvers.iter().any(|e| e.error.is_some()) {
        return Err("at least one solver failed (see the report)".into());
    }
    Ok(())
}

/// User + system CPU seconds of this process so far, from /proc/self/stat (Linux; clock
/// ticks of 1/100 s), or None elsewhere.
fn process_cpu_seconds() -> Option<f64> {
    let stat = std::fs::read_to_string("/proc/self/stat").ok()?;
    // Fields after the command name (which may contain spaces) end with ')'.
    let rest = stat.rsplit_once(')')?.1;
    let f: Vec<&str> = rest.split_whitespace().collect();
    // utime and stime are fields 14 and 15 of the whole line: 12 and 13 after ')'.
    let utime: f64 = f.get(11)?.parse().ok()?;
    let stime: f64 = f.get(12)?.parse().ok()?;
    Some((utime + stime) / 100.0)
}

fn summary(r: &Report) -> String {
    let mut lines = vec![
        format!("freeform compare {}", r.shape),
        format!(
            "  K {}  points {}  modes {} (+ constant)  tol {:.1e}  matrices built in {:.3} s",
            r.kernels, r.points, r.modes, r.tol, r.matrices_s
        ),
        format!(
            "  {:<40} {:>9} {:>8} {:>6} {:>10} {:>10} {:>10} {:>10}",
            "solver", "time [s]", "cpu [s]", "iters", "residual", "orthonorm", "eig diff", "angle"
        ),
    ];
    for e in &r.solvers {
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
        r.reference, r.max_eigenvalue_rel_diff, r.max_subspace_angle
    ));
    lines.join("\n") + "\n"
}
