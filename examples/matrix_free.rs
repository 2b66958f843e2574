//! The smallest eigenpairs of a matrix-free Q1 finite-element Laplacian (stiffness and mass
//! applied by a loop over the elements, never assembled; `eigen::q1_operator`) against the
//! assembled matrices and the closed-form eigenvalues: through the native LOBPCG and, built
//! with `--features slepc`, through SLEPc on shell matrices, on one rank or several (each rank
//! owning a block of rows and gathering its halo inside the operator). Exits 0 when every
//! eigenvalue equals the assembled solve's to 1e-8 (relative to the largest), 1 otherwise.
//!
//!     cargo run --release --example matrix_free
//!     cargo run --release --features slepc --example matrix_free
//!     mpirun -n 2 target/release/examples/matrix_free      (after the build above)
//!     mpirun -n 2 target/release/examples/matrix_free --fail-on-rank 1
//!
//! With `--fail-on-rank R` the operator H fails on rank R only (after its 20th product); the
//! run exits 0 when the SLEPc solve then fails on every rank instead of leaving the others
//! waiting in a collective call.

use freeform::eigen::lobpcg::Lobpcg;
use freeform::eigen::q1_operator::{Q1Operator, Q1Part};
use freeform::eigen::testing::{q1_fem, q1_fem_eigenvalues};
use freeform::eigen::{EigenRequest, EigenSolution, Eigensolver, OperatorProblem};
use freeform::progress::Silent;

const GRID: [usize; 3] = [10, 11, 12];
const SPACING: f64 = 0.05;
const NEV: usize = 10;
const TOL: f64 = 1e-8;

/// Largest |a - b| over the eigenvalues, relative to the largest reference eigenvalue.
fn difference(reference: &[f64], got: &[f64]) -> f64 {
    let top = reference.last().copied().unwrap_or(1.0).abs();
    if reference.len() != got.len() {
        return f64::INFINITY;
    }
    reference
        .iter()
        .zip(got)
        .map(|(a, b)| (a - b).abs() / top)
        .fold(0.0, f64::max)
}

fn report(label: &str, reference: &[f64], s: &EigenSolution, rows: &mut Vec<(String, f64)>) {
    let d = difference(reference, &s.values);
    // SLEPc does not report its operator applications.
    let products = match s.info.matvecs {
        0 => "-".to_string(),
        n => n.to_string(),
    };
    println!(
        "| {label} | {} | {products} | {:.2e} | {d:.2e} |",
        s.info.iterations, s.info.max_relative_residual
    );
    rows.push((
        label.to_string(),
        if s.converged() { d } else { f64::INFINITY },
    ));
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    #[cfg(feature = "slepc")]
    if let Some(rank) = fail_on_rank()? {
        return slepc_run::one_rank_fails(rank);
    }
    let request = EigenRequest {
        nev: NEV,
        tol: TOL,
        max_iter: 2000,
    };
    let exact = q1_fem_eigenvalues(GRID, SPACING, NEV);
    let (ha, ma) = q1_fem(GRID, SPACING);
    let h = Q1Operator::new(GRID, SPACING, Q1Part::Stiffness)?;
    let m = Q1Operator::new(GRID, SPACING, Q1Part::Mass)?;
    let assembled =
        Lobpcg::default().solve_converged(ha.as_ref(), ma.as_ref(), &request, &Silent)?;
    let mut rows = Vec::new();
    let rank = mpi_rank();
    if rank == 0 {
        println!(
            "Q1 Laplacian on {GRID:?} nodes (K = {}), h = {SPACING} m, {NEV} pairs, tol {TOL:e}",
            ha.nrows()
        );
        println!(
            "closed form vs assembled LOBPCG: {:.2e}",
            difference(&exact, &assembled.values)
        );
        println!("| path | iterations | products | max residual | vs assembled |");
        println!("|---|---|---|---|---|");
    }
    let native =
        Lobpcg::default().solve_operators(&OperatorProblem::new(&h, &m), &request, &Silent)?;
    if rank == 0 {
        report(
            "native LOBPCG, matrix-free, Jacobi",
            &assembled.values,
            &native,
            &mut rows,
        );
    }
    #[cfg(feature = "slepc")]
    {
        let slepc = slepc_run::solve(&request)?;
        if rank == 0 {
            let label = format!(
                "SLEPc LOBPCG, shell matrices, {} rank(s)",
                slepc_run::ranks()?
            );
            report(&label, &assembled.values, &slepc, &mut rows);
        }
    }
    let worst = rows.iter().map(|r| r.1).fold(0.0, f64::max);
    let ok = worst <= 1e-8 && difference(&exact, &assembled.values) <= 1e-8;
    if rank == 0 {
        println!(
            "{}: largest difference {worst:.2e} (bar 1e-8)",
            if ok { "PASS" } else { "FAIL" }
        );
    }
    #[cfg(feature = "slepc")]
    freeform::eigen::slepc::finalize()?;
    if !ok {
        std::process::exit(1);
    }
    Ok(())
}

/// The rank of `--fail-on-rank R`, if given.
#[cfg(feature = "slepc")]
fn fail_on_rank() -> Result<Option<usize>, Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    match args.iter().position(|a| a == "--fail-on-rank") {
        Some(i) => Ok(Some(
            args.get(i + 1)
                .ok_or("--fail-on-rank needs a rank")?
                .parse()?,
        )),
        None => Ok(None),
    }
}

#[cfg(feature = "slepc")]
fn mpi_rank() -> usize {
    freeform::eigen::slepc::world_rank().map_or(0, |r| r.0)
}

#[cfg(not(feature = "slepc"))]
fn mpi_rank() -> usize {
    0
}

/// SLEPc on shell matrices: each rank owns a block of rows of the Q1 operators and gathers
/// the rest of x (its halo, here simply all of it) by an all-reduce inside the operator.
#[cfg(feature = "slepc")]
mod slepc_run {
    use super::{GRID, SPACING};
    use faer::{Mat, MatMut, MatRef};
    use freeform::eigen::q1_operator::{Q1Operator, Q1Part};
    use freeform::eigen::slepc::{block_range, operator_allreduce_sum, world_rank, SlepcSolver};
    use freeform::eigen::{
        EigenError, EigenRequest, EigenSolution, Eigensolver, LinearOperator, OperatorError,
        OperatorProblem,
    };
    use freeform::progress::Silent;
    use std::ops::Range;

    /// One rank's rows of a Q1 operator; with `fail_after`, it reports an error from that
    /// many products on.
    struct RankRows {
        full: Q1Operator,
        rows: Range<usize>,
        fail_after: Option<usize>,
        products: std::sync::atomic::AtomicUsize,
    }

    impl LinearOperator for RankRows {
        fn dim(&self) -> usize {
            self.full.dim()
        }
        fn local_rows(&self) -> Range<usize> {
            self.rows.clone()
        }
        fn apply(&self, x: MatRef<'_, f64>, mut out: MatMut<'_, f64>) -> Result<(), OperatorError> {
            let (k, b) = (self.dim(), x.ncols());
            // The halo: every rank contributes its rows of x, all get the whole x.
            let mut whole = vec![0.0; k * b];
            for j in 0..b {
                for (i, r) in self.rows.clone().enumerate() {
                    whole[j * k + r] = x[(i, j)];
                }
            }
            operator_allreduce_sum(&mut whole)?;
            let xf = MatRef::from_column_major_slice(&whole, k, b);
            let mut yf = Mat::<f64>::zeros(k, b);
            self.full.apply(xf, yf.as_mut())?;
            for j in 0..b {
                for (i, r) in self.rows.clone().enumerate() {
                    out[(i, j)] = yf[(r, j)];
                }
            }
            let done = self
                .products
                .fetch_add(1, std::sync::atomic::Ordering::Relaxed);
            if self.fail_after.is_some_and(|n| done >= n) {
                return Err(OperatorError::new("injected failure (--fail-on-rank)"));
            }
            Ok(())
        }
        fn diagonal(&self) -> Option<Vec<f64>> {
            self.full.diagonal().map(|d| d[self.rows.clone()].to_vec())
        }
    }

    pub fn ranks() -> Result<usize, EigenError> {
        Ok(world_rank()?.1)
    }

    type Failure = Box<dyn std::error::Error>;

    fn operators(fail_after: Option<usize>) -> Result<(RankRows, RankRows), Failure> {
        let (rank, size) = world_rank()?;
        let k = GRID[0] * GRID[1] * GRID[2];
        let rows = block_range(k, rank, size);
        let part = |p: Q1Part, fail_after: Option<usize>| -> Result<RankRows, Failure> {
            Ok(RankRows {
                full: Q1Operator::new(GRID, SPACING, p)?,
                rows: rows.clone(),
                fail_after,
                products: Default::default(),
            })
        };
        Ok((
            part(Q1Part::Stiffness, fail_after)?,
            part(Q1Part::Mass, None)?,
        ))
    }

    pub fn solve(request: &EigenRequest) -> Result<EigenSolution, Box<dyn std::error::Error>> {
        let (h, m) = operators(None)?;
        let solution = SlepcSolver::default()
            .solve_operators(&OperatorProblem::new(&h, &m), request, &Silent)?
            .into_converged()?;
        Ok(solution)
    }

    /// H fails on rank `failing` only: every rank must get an error (exit 0), none may hang.
    pub fn one_rank_fails(failing: usize) -> Result<(), Box<dyn std::error::Error>> {
        let rank = world_rank()?.0;
        let (h, m) = operators((rank == failing).then_some(20))?;
        let request = EigenRequest {
            nev: super::NEV,
            tol: super::TOL,
            max_iter: 2000,
        };
        let result = SlepcSolver::default().solve_operators(
            &OperatorProblem::new(&h, &m),
            &request,
            &Silent,
        );
        freeform::eigen::slepc::finalize()?;
        match result {
            Err(e) => {
                println!("rank {rank}: the solve failed as it should: {e}");
                Ok(())
            }
            Ok(_) => Err(format!("rank {rank}: the solve did not fail").into()),
        }
    }
}
