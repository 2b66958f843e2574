//! What the operator interface costs: the whole native eigensolve (LOBPCG, the IC(0)
//! preconditioner of H + sigma M built from the assembled matrices) on the RKPM beam, once on
//! the assembled matrices (the fused sparse kernels) and once with H and M given as plain
//! closures around the same matrices and the same IC(0) handed in as the caller's
//! preconditioner (`AssembledPreconditioner`). Prints both times, their ratio, iterations and
//! the largest eigenvalue difference; runs the two solves alternately `--repeat` times.
//!
//!     cargo run --release --example operator_overhead -- [kernels] [modes] [repeat]
//!
//! Defaults: 100000 kernels, 32 modes, 1 repeat (docs/matrix_free.md has the measurements).

use faer::{MatMut, MatRef};
use freeform::eigen::lobpcg::{AssembledPreconditioner, Lobpcg, LobpcgOptions, PreconditionerKind};
use freeform::eigen::{EigenRequest, Eigensolver, FnOperator, OperatorProblem};
use freeform::io::read_shape;
use freeform::precompute::{BasisOptions, MatrixStorage, Problem};
use freeform::progress::Silent;
use freeform::report::Stopwatch;
use freeform::sparse;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<usize> = std::env::args()
        .skip(1)
        .map(|a| a.parse())
        .collect::<Result<_, _>>()?;
    let kernels = args.first().copied().unwrap_or(100_000);
    let modes = args.get(1).copied().unwrap_or(32);
    let repeat = args.get(2).copied().unwrap_or(1).max(1);
    let shape = read_shape("box:5,1,1", &Default::default())?;
    let opts = BasisOptions {
        kernels,
        modes,
        matrix_storage: MatrixStorage::Full,
        ..BasisOptions::default()
    };
    let sw = Stopwatch::start();
    let problem = Problem::from_shape(&shape, &opts, &Silent)?;
    let (h, m) = (problem.matrices().hessian(), problem.matrices().mass());
    println!(
        "K = {}, nnz(H) = {}, assembled in {:.1} s, {} rayon threads",
        h.nrows(),
        h.compute_nnz(),
        sw.elapsed(),
        rayon::current_num_threads()
    );
    let request = EigenRequest {
        nev: modes + 1,
        ..EigenRequest::default()
    };
    // The same IC(0) on both paths (Auto would pick it at this size; fixed so the comparison
    // does not depend on the Auto budget).
    let options = LobpcgOptions {
        preconditioner: PreconditionerKind::IncompleteCholesky,
        ..LobpcgOptions::default()
    };
    let solver = Lobpcg::new(options.clone());
    let hc = FnOperator::new(h.nrows(), |x: MatRef<'_, f64>, y: MatMut<'_, f64>| {
        sparse::sym_mul_block(h.as_ref(), x, y);
        Ok(())
    });
    let mc = FnOperator::new(m.nrows(), |x: MatRef<'_, f64>, y: MatMut<'_, f64>| {
        sparse::sym_mul_block(m.as_ref(), x, y);
        Ok(())
    });
    println!("| run | path | solve s | iterations | matvecs | sparse products s | max residual |");
    println!("|---|---|---|---|---|---|---|");
    let (mut direct_total, mut closure_total, mut worst) = (0.0, 0.0, 0.0f64);
    for run in 1..=repeat {
        let sw = Stopwatch::start();
        let direct = solver.solve_converged(h, m, &request, &Silent)?;
        let t_direct = sw.elapsed();
        let sw = Stopwatch::start();
        // Built inside the timed region: the direct path builds its IC(0) inside its solve.
        let ic0 = AssembledPreconditioner::build(h, m, &options, &request)?;
        let problem = OperatorProblem::new(&hc, &mc).with_preconditioner(&ic0);
        let free = solver
            .solve_operators(&problem, &request, &Silent)?
            .into_converged()?;
        let t_free = sw.elapsed();
        for (label, s, t) in [
            ("assembled", &direct, t_direct),
            ("closures", &free, t_free),
        ] {
            let spmm = s
                .info
                .notes
                .iter()
                .find_map(|n| n.strip_prefix("time: preconditioner "))
                .and_then(|n| n.split("sparse products ").nth(1))
                .and_then(|n| n.split(' ').next())
                .unwrap_or("?");
            println!(
                "| {run} | {label} | {t:.2} | {} | {} | {spmm} | {:.2e} |",
                s.info.iterations, s.info.matvecs, s.info.max_relative_residual
            );
        }
        let top = direct.values.last().copied().unwrap_or(1.0);
        for (a, b) in direct.values.iter().zip(&free.values) {
            worst = worst.max((a - b).abs() / top);
        }
        direct_total += t_direct;
        closure_total += t_free;
    }
    println!(
        "mean: assembled {:.2} s, closures {:.2} s, ratio {:.3}; largest eigenvalue difference {worst:.2e} of lambda_max",
        direct_total / repeat as f64,
        closure_total / repeat as f64,
        closure_total / direct_total
    );
    Ok(())
}
