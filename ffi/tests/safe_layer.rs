//! The safe layer against PETSc itself (feature `petsc`): a linear solve with a known answer,
//! errors carrying PETSc's message, and a small GHEP with known eigenvalues.
//! Run: `cargo test -p freeform-ffi --features petsc`.
#![cfg(feature = "petsc")]

use freeform_ffi::{session, Convergence, Eps, Ksp, Mat, ProblemType, Which};

/// Rows of the n x n tridiagonal matrix tridiag(-1, d, -1) in CSR form.
fn tridiagonal(n: usize, d: f64) -> (Vec<usize>, Vec<u32>, Vec<f64>) {
    let (mut ptr, mut cols, mut vals) = (vec![0], Vec::new(), Vec::new());
    for i in 0..n {
        let iu = i as u32;
        if i > 0 {
            cols.push(iu - 1);
            vals.push(-1.0);
        }
        cols.push(iu);
        vals.push(d);
        if i + 1 < n {
            cols.push(iu + 1);
            vals.push(-1.0);
        }
        ptr.push(cols.len());
    }
    (ptr, cols, vals)
}

#[test]
fn cg_solves_a_known_system() {
    let s = session().unwrap();
    let n = 100;
    let (ptr, cols, vals) = tridiagonal(n, 3.0);
    let a = Mat::aij_from_rows(&s, s.self_comm(), n, 0, &ptr, &cols, &vals, true).unwrap();
    // b = A x_true, formed here without PETSc.
    let x_true: Vec<f64> = (0..n).map(|i| ((i as f64) * 0.37).sin()).collect();
    let b_vals: Vec<f64> = (0..n)
        .map(|i| {
            (ptr[i]..ptr[i + 1])
                .map(|e| vals[e] * x_true[cols[e] as usize])
                .sum()
        })
        .collect();
    let mut b = a.create_vector().unwrap();
    b.set_local_values(&b_vals).unwrap();
    let mut x = a.create_vector().unwrap();
    let mut ksp = Ksp::new(&s, s.self_comm()).unwrap();
    ksp.set_operator(&a).unwrap();
    ksp.configure("cg", "jacobi", 1e-13, 1000).unwrap();
    let (its, reason) = ksp.solve(&b, &mut x).unwrap();
    assert!(reason > 0 && its > 0, "reason {reason}, {its} iterations");
    // cond(A) <= 5: CG at rtol 1e-13 leaves an error below 1e-12 relative.
    let x = x.gather_all().unwrap();
    let err = x
        .iter()
        .zip(&x_true)
        .fold(0.0f64, |m, (p, q)| m.max((p - q).abs()));
    assert!(err < 1e-11, "{err}");
}

#[test]
fn petsc_errors_carry_petscs_message() {
    let s = session().unwrap();
    let (ptr, cols, vals) = tridiagonal(5, 3.0);
    let a = Mat::aij_from_rows(&s, s.self_comm(), 5, 0, &ptr, &cols, &vals, true).unwrap();
    let mut ksp = Ksp::new(&s, s.self_comm()).unwrap();
    ksp.set_operator(&a).unwrap();
    let err = ksp.configure("bogus_ksp", "jacobi", 1e-8, 10).unwrap_err();
    assert_eq!(err.call, "KSPSetType");
    assert!(err.message.contains("bogus_ksp"), "{err}");
    // Checked on our side before PETSc sees it.
    let err = Mat::aij_from_rows(&s, s.self_comm(), 5, 0, &ptr, &[9; 13], &vals, true)
        .err()
        .expect("column index out of range");
    assert!(err.message.contains("column index 9"), "{err}");
}

#[test]
fn ghep_with_known_eigenvalues() {
    // A = tridiag(-1, 2, -1) (n = 50), B = 2 I: eigenvalues (2 - 2 cos(k pi / (n + 1))) / 2.
    let s = session().unwrap();
    let n = 50;
    let (ptr, cols, vals) = tridiagonal(n, 2.0);
    let a = Mat::aij_from_rows(&s, s.world(), n, 0, &ptr, &cols, &vals, true).unwrap();
    let bptr: Vec<usize> = (0..=n).collect();
    let bcols: Vec<u32> = (0..n as u32).collect();
    let b = Mat::aij_from_rows(&s, s.world(), n, 0, &bptr, &bcols, &vec![2.0; n], true).unwrap();
    let mut eps = Eps::new(&s, s.world()).unwrap();
    eps.set_operators(&a, &b).unwrap();
    eps.set_problem_type(ProblemType::Ghep).unwrap();
    eps.set_dimensions(3).unwrap();
    eps.set_tolerances(1e-12, 1000).unwrap();
    eps.set_convergence_test(Convergence::Relative).unwrap();
    eps.set_which(Which::TargetMagnitude).unwrap();
    eps.set_target(-0.01).unwrap();
    eps.set_spectral_transform(Some("sinvert"), Some("preonly"), Some("cholesky"), None)
        .unwrap();
    eps.solve().unwrap();
    assert!(eps.converged().unwrap() >= 3);
    let mut x = a.create_vector().unwrap();
    for k in 0..3 {
        let lambda = eps.eigenpair(k, &mut x).unwrap();
        let t = std::f64::consts::PI * (k + 1) as f64 / (n + 1) as f64;
        let exact = (2.0 - 2.0 * t.cos()) / 2.0;
        assert!(
            (lambda - exact).abs() < 1e-12 * exact.max(1.0) + 1e-14,
            "{lambda} vs {exact}"
        );
    }
    let [eps_type, st, _, pc, _] = eps.describe().unwrap();
    assert_eq!(
        (eps_type.as_str(), st.as_str(), pc.as_str()),
        ("krylovschur", "sinvert", "cholesky")
    );
}

#[test]
fn axpy_on_the_same_and_on_a_different_pattern() {
    // tridiag(-1, 3, -1) - 0.5 tridiag(-1, 2, -1) = tridiag(-0.5, 2, -0.5), and + 0.25 I
    // (a diagonal pattern, a subset of the tridiagonal one): every product entry is a sum of
    // at most three terms of exact binary fractions, so the comparison is exact.
    let s = session().unwrap();
    let n = 7;
    let (ptr, cols, a_vals) = tridiagonal(n, 3.0);
    let (_, _, b_vals) = tridiagonal(n, 2.0);
    let mut a = Mat::aij_from_rows(&s, s.self_comm(), n, 0, &ptr, &cols, &a_vals, true).unwrap();
    let b = Mat::aij_from_rows(&s, s.self_comm(), n, 0, &ptr, &cols, &b_vals, true).unwrap();
    a.axpy(-0.5, &b, true).unwrap();
    let diag_ptr: Vec<usize> = (0..=n).collect();
    let diag_cols: Vec<u32> = (0..n as u32).collect();
    let i = Mat::aij_from_rows(
        &s,
        s.self_comm(),
        n,
        0,
        &diag_ptr,
        &diag_cols,
        &vec![1.0; n],
        true,
    )
    .unwrap();
    a.axpy(0.25, &i, false).unwrap();
    let x_vals: Vec<f64> = (0..n).map(|i| (i + 1) as f64).collect();
    let mut x = a.create_vector().unwrap();
    x.set_local_values(&x_vals).unwrap();
    let mut y = a.create_vector().unwrap();
    a.mult(&x, &mut y).unwrap();
    let expected: Vec<f64> = (0..n)
        .map(|i| {
            let left = if i > 0 { x_vals[i - 1] } else { 0.0 };
            let right = if i + 1 < n { x_vals[i + 1] } else { 0.0 };
            2.25 * x_vals[i] - 0.5 * (left + right)
        })
        .collect();
    assert_eq!(y.gather_all().unwrap(), expected);
}
