//! The eigensolvers over operators (`Eigensolver::solve_operators`): assembled matrices passed
//! as operators give the direct path's bits; closures around them with the same IC(0) give
//! the same eigenpairs; an element-by-element Q1 Laplacian that is never assembled gives the
//! closed-form eigenvalues; and every bad operator is refused with a typed error.

use faer::{Mat, MatMut, MatRef};
use freeform::eigen::dense::DenseSolver;
use freeform::eigen::lobpcg::{AssembledPreconditioner, Lobpcg, LobpcgOptions, PreconditionerKind};
use freeform::eigen::q1_operator::{Q1Operator, Q1Part};
use freeform::eigen::testing::{q1_fem, q1_fem_eigenvalues};
use freeform::eigen::{
    EigenError, EigenRequest, EigenSolution, Eigensolver, FnOperator, LinearOperator,
    OperatorError, OperatorProblem,
};
use freeform::progress::Silent;
use freeform::sparse::{self, SparseMatrix, SparseMatrixRef};
use std::ops::Range;

const GRID: [usize; 3] = [7, 8, 9];
const SPACING: f64 = 0.1;

fn request(nev: usize) -> EigenRequest {
    EigenRequest {
        nev,
        tol: 1e-9,
        max_iter: 2000,
    }
}

/// A closure operator around an assembled matrix, hiding the matrix (and its diagonal).
fn closure(a: SparseMatrixRef<'_>) -> impl LinearOperator + '_ {
    FnOperator::new(a.nrows(), move |x: MatRef<'_, f64>, y: MatMut<'_, f64>| {
        sparse::sym_mul_block(a.as_ref(), x, y);
        Ok(())
    })
}

/// Largest relative eigenvalue difference between two solutions.
fn max_relative_difference(a: &EigenSolution, b: &EigenSolution) -> f64 {
    assert_eq!(a.values.len(), b.values.len());
    let scale = a.values.last().copied().unwrap_or(1.0).abs();
    a.values
        .iter()
        .zip(&b.values)
        .map(|(x, y)| (x - y).abs() / scale)
        .fold(0.0, f64::max)
}

/// Largest M-norm of the part of each of `b`'s vectors outside the span of `a`'s
/// (M-orthonormal both): the sine of the largest principal angle between the eigenspaces.
fn subspace_gap(m: SparseMatrixRef<'_>, a: &Mat<f64>, b: &Mat<f64>) -> f64 {
    let k = m.nrows();
    let mut mb = Mat::<f64>::zeros(k, b.ncols());
    sparse::sym_mul_block(m.as_ref(), b.as_ref(), mb.as_mut());
    let coeffs = a.transpose() * &mb;
    let rest = b - a * &coeffs;
    let mut m_rest = Mat::<f64>::zeros(k, b.ncols());
    sparse::sym_mul_block(m.as_ref(), rest.as_ref(), m_rest.as_mut());
    (0..b.ncols())
        .map(|j| {
            (0..k)
                .map(|i| rest[(i, j)] * m_rest[(i, j)])
                .sum::<f64>()
                .max(0.0)
                .sqrt()
        })
        .fold(0.0, f64::max)
}

/// The analytic eigenvalues have a clear gap after the `nev`-th, so the eigenspace is defined.
fn assert_gap_at_cut(nev: usize) {
    let exact = q1_fem_eigenvalues(GRID, SPACING, nev + 1);
    assert!(exact[nev] - exact[nev - 1] > 1e-3 * exact[nev], "{exact:?}");
}

#[test]
fn sparse_matrices_through_operators_give_the_direct_bits() {
    let (h, m) = q1_fem(GRID, SPACING);
    let solver = Lobpcg::default();
    let direct = solver
        .solve(h.as_ref(), m.as_ref(), &request(9), &Silent)
        .unwrap();
    let through = solver
        .solve_operators(&OperatorProblem::new(&h, &m), &request(9), &Silent)
        .unwrap();
    assert!(direct.converged() && through.converged());
    assert_eq!(direct.values, through.values);
    assert_eq!(direct.vectors, through.vectors);
    assert_eq!(direct.info.iterations, through.info.iterations);
}

#[test]
fn closures_with_the_assembled_ic0_match_the_direct_path() {
    let nev = 9;
    assert_gap_at_cut(nev);
    let (h, m) = q1_fem(GRID, SPACING);
    let options = LobpcgOptions {
        preconditioner: PreconditionerKind::IncompleteCholesky,
        ..LobpcgOptions::default()
    };
    let solver = Lobpcg::new(options.clone());
    let direct = solver
        .solve(h.as_ref(), m.as_ref(), &request(nev), &Silent)
        .unwrap();
    let ic0 =
        AssembledPreconditioner::build(h.as_ref(), m.as_ref(), &options, &request(nev)).unwrap();
    assert!(
        ic0.notes().iter().any(|n| n.contains("IC(0)")),
        "{:?}",
        ic0.notes()
    );
    let (hc, mc) = (closure(h.as_ref()), closure(m.as_ref()));
    let problem = OperatorProblem::new(&hc, &mc).with_preconditioner(&ic0);
    let free = solver
        .solve_operators(&problem, &request(nev), &Silent)
        .unwrap();
    assert!(direct.converged() && free.converged(), "{:?}", free.info);
    assert!(free.info.notes.iter().any(|n| n.contains("matrix-free")));
    assert!(free.info.notes.iter().any(|n| n.contains("the caller's")));
    // Residuals <= 1e-9 bound each eigenvalue's error by ~(residual)^2 * cond ~ 1e-14 of the
    // largest; 1e-10 leaves room for the estimated norms moving the stopping point.
    assert!(max_relative_difference(&direct, &free) < 1e-10);
    // Eigenvector error ~ residual / relative gap (>= 1e-3 here): 1e-9 / 1e-3 = 1e-6.
    assert!(subspace_gap(m.as_ref(), &direct.vectors, &free.vectors) < 1e-5);
    // The independent check recomputes the residuals through the closures.
    assert!(free.info.max_relative_residual <= 1e-9);
}

#[test]
fn element_loop_laplacian_has_the_closed_form_eigenvalues() {
    let nev = 12;
    let exact = q1_fem_eigenvalues(GRID, SPACING, nev);
    let h = Q1Operator::new(GRID, SPACING, Q1Part::Stiffness).unwrap();
    let m = Q1Operator::new(GRID, SPACING, Q1Part::Mass).unwrap();
    let (ha, ma) = q1_fem(GRID, SPACING);
    let assembled = Lobpcg::default()
        .solve(ha.as_ref(), ma.as_ref(), &request(nev), &Silent)
        .unwrap();
    for (label, hop, mop) in [
        ("Jacobi from the operators' diagonals", h.clone(), m.clone()),
        (
            "preconditioner: none",
            h.clone().without_diagonal(),
            m.clone().without_diagonal(),
        ),
    ] {
        let solution = Lobpcg::default()
            .solve_operators(&OperatorProblem::new(&hop, &mop), &request(nev), &Silent)
            .unwrap();
        assert!(solution.converged(), "{label}: {:?}", solution.info);
        assert!(
            solution.info.notes.iter().any(|n| n.contains(label)),
            "{label}"
        );
        let top = exact[nev - 1];
        for (got, want) in solution.values.iter().zip(&exact) {
            // The discrete eigenvalues are exact in closed form; tol 1e-9 on the residual
            // gives eigenvalues to ~1e-14 relative; 1e-8 is the bar.
            assert!((got - want).abs() <= 1e-8 * top, "{label}: {got} vs {want}");
        }
        assert!(
            max_relative_difference(&assembled, &solution) <= 1e-8,
            "{label}"
        );
    }
}

#[test]
fn operators_that_fail_stop_the_solve_with_their_error() {
    let (h, m) = q1_fem([5, 5, 5], 0.2);
    let k = h.nrows();
    let solver = Lobpcg::default();
    let hc = closure(h.as_ref());
    let solve = |h: &dyn LinearOperator, m: &dyn LinearOperator| {
        solver.solve_operators(&OperatorProblem::new(h, m), &request(5), &Silent)
    };
    // A callback that reports an error: its message comes back, with the operator's name.
    let failing = FnOperator::new(k, |_: MatRef<'_, f64>, _: MatMut<'_, f64>| {
        Err(OperatorError::new("device lost"))
    });
    match solve(&hc, &failing) {
        Err(EigenError::Operator { which, message }) => {
            assert_eq!(which, "M");
            assert!(message.contains("device lost"));
        }
        other => panic!("{other:?}"),
    }
    // NaN out: refused, naming the operator.
    let nan = FnOperator::new(k, |x: MatRef<'_, f64>, mut y: MatMut<'_, f64>| {
        y.fill(0.0);
        y[(x.nrows() / 2, 0)] = f64::NAN;
        Ok(())
    });
    match solve(&nan, &closure(m.as_ref())) {
        Err(EigenError::NonFinite(msg)) => assert!(msg.contains("operator H"), "{msg}"),
        other => panic!("{other:?}"),
    }
    // Sizes that disagree.
    let (h4, _) = q1_fem([4, 5, 5], 0.2);
    assert!(matches!(
        solve(&h4, &m),
        Err(EigenError::InvalidRequest(msg)) if msg.contains("K x K")
    ));
    // An M that is not positive definite: said so, not a failure to converge.
    let negative = FnOperator::new(k, |x: MatRef<'_, f64>, mut y: MatMut<'_, f64>| {
        sparse::sym_mul_block(m.as_ref(), x, y.as_mut());
        y *= faer::Scale(-1.0);
        Ok(())
    });
    assert!(matches!(
        solve(&hc, &negative),
        Err(EigenError::NotPositiveDefinite { what: "M", .. })
    ));
    // A failing preconditioner, by name.
    let bad_pre = |_: MatRef<'_, f64>, _: MatMut<'_, f64>| -> Result<(), OperatorError> {
        Err(OperatorError::new("no factor"))
    };
    let mc = closure(m.as_ref());
    let problem = OperatorProblem::new(&hc, &mc).with_preconditioner(&bad_pre);
    match solver.solve_operators(&problem, &request(5), &Silent) {
        Err(EigenError::Operator { which, message }) => {
            assert_eq!(which, "preconditioner");
            assert!(message.contains("no factor"));
        }
        other => panic!("{other:?}"),
    }
}

/// An operator that claims to own only some rows (as one MPI rank's would).
struct Partial<'a>(&'a SparseMatrix, Range<usize>);

impl LinearOperator for Partial<'_> {
    fn dim(&self) -> usize {
        self.0.nrows()
    }
    fn local_rows(&self) -> Range<usize> {
        self.1.clone()
    }
    fn apply(&self, x: MatRef<'_, f64>, y: MatMut<'_, f64>) -> Result<(), OperatorError> {
        sparse::sym_mul_block(self.0.as_ref(), x, y);
        Ok(())
    }
}

#[test]
fn problems_the_solver_cannot_take_are_refused_up_front() {
    let (h, m) = q1_fem([5, 5, 5], 0.2);
    let k = h.nrows();
    let (hc, mc) = (closure(h.as_ref()), closure(m.as_ref()));
    let solver = Lobpcg::default();
    // A distributed operator in a one-process solver.
    let part = Partial(&h, 0..k / 2);
    match solver.solve_operators(&OperatorProblem::new(&part, &mc), &request(5), &Silent) {
        Err(EigenError::InvalidRequest(msg)) => assert!(msg.contains("owns rows"), "{msg}"),
        other => panic!("{other:?}"),
    }
    // A non-symmetric operator, found by the probe on request.
    let skew = FnOperator::new(k, |x: MatRef<'_, f64>, mut y: MatMut<'_, f64>| {
        sparse::sym_mul_block(h.as_ref(), x, y.as_mut());
        for j in 0..x.ncols() {
            y[(0, j)] += x[(1, j)];
        }
        Ok(())
    });
    let probed = OperatorProblem::new(&skew, &mc).with_symmetry_probe(true);
    match solver.solve_operators(&probed, &request(5), &Silent) {
        Err(EigenError::InvalidRequest(msg)) => assert!(msg.contains("not symmetric"), "{msg}"),
        other => panic!("{other:?}"),
    }
    // A factorization preconditioner without a matrix to factor.
    let cholesky = Lobpcg::new(LobpcgOptions {
        preconditioner: PreconditionerKind::Cholesky,
        ..LobpcgOptions::default()
    });
    match cholesky.solve_operators(&OperatorProblem::new(&hc, &mc), &request(5), &Silent) {
        Err(EigenError::InvalidRequest(msg)) => assert!(msg.contains("matrix-free"), "{msg}"),
        other => panic!("{other:?}"),
    }
    // nev out of range, as for matrices.
    assert!(matches!(
        solver.solve_operators(&OperatorProblem::new(&hc, &mc), &request(k), &Silent),
        Err(EigenError::InvalidRequest(_))
    ));
    // A solver without a matrix-free path says where to go.
    match DenseSolver.solve_operators(&OperatorProblem::new(&hc, &mc), &request(5), &Silent) {
        Err(EigenError::InvalidRequest(msg)) => assert!(msg.contains("native LOBPCG"), "{msg}"),
        other => panic!("{other:?}"),
    }
    // ... and takes assembled matrices through the same entry.
    let dense = DenseSolver
        .solve_operators(&OperatorProblem::new(&h, &m), &request(5), &Silent)
        .unwrap();
    assert!(dense.converged());
}
