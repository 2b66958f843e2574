//! Shell matrices and shell preconditioners over Rust closures (feature `petsc`): the shell
//! product equals the AIJ one, SLEPc's LOBPCG solves a shell pencil with a shell Jacobi
//! preconditioner to the analytic eigenvalues, a callback's error or panic comes back as its
//! message, and the closure is freed with the PETSc object.
//! Run: `cargo test -p freeform-ffi --features petsc`.
#![cfg(feature = "petsc")]

use freeform_ffi::{session, Convergence, Eps, Mat, ProblemType, ShellApply, Which};
use std::sync::Arc;

/// y = tridiag(-1, 2, -1) x (Dirichlet 1D Laplacian), the whole vector on one rank.
fn laplacian(x: &[f64], y: &mut [f64]) -> Result<(), String> {
    let n = x.len();
    for i in 0..n {
        let left = if i > 0 { x[i - 1] } else { 0.0 };
        let right = if i + 1 < n { x[i + 1] } else { 0.0 };
        y[i] = 2.0 * x[i] - left - right;
    }
    Ok(())
}

fn identity(x: &[f64], y: &mut [f64]) -> Result<(), String> {
    y.copy_from_slice(x);
    Ok(())
}

#[test]
fn shell_product_equals_the_aij_product() {
    let s = session().unwrap();
    let n: usize = 50;
    let (mut ptr, mut cols, mut vals) = (vec![0], Vec::new(), Vec::new());
    for i in 0..n {
        for (j, v) in [(i.wrapping_sub(1), -1.0), (i, 2.0), (i + 1, -1.0)] {
            if j < n {
                cols.push(j as u32);
                vals.push(v);
            }
        }
        ptr.push(cols.len());
    }
    let aij = Mat::aij_from_rows(&s, s.self_comm(), n, 0, &ptr, &cols, &vals, true).unwrap();
    // SAFETY: no EPS takes the shell; it is dropped before the closure's data.
    let (shell, failure) =
        unsafe { Mat::shell(&s, s.self_comm(), n, n, None, Box::new(laplacian)) }.unwrap();
    let mut x = aij.create_vector().unwrap();
    let xv: Vec<f64> = (0..n).map(|i| (i as f64 * 0.3).cos()).collect();
    x.set_local_values(&xv).unwrap();
    let (mut y1, mut y2) = (aij.create_vector().unwrap(), shell.create_vector().unwrap());
    aij.mult(&x, &mut y1).unwrap();
    shell.mult(&x, &mut y2).unwrap();
    // The same three products summed in the same order: identical.
    assert_eq!(y1.local_values().unwrap(), y2.local_values().unwrap());
    assert!(failure.take().is_none());
}

#[test]
fn lobpcg_on_a_shell_pencil_with_a_shell_preconditioner() {
    let s = session().unwrap();
    let n = 200;
    let token = Arc::new(());
    let held = Arc::clone(&token);
    let a_apply: ShellApply<'_> = Box::new(move |x, y| {
        let _keep = &held;
        laplacian(x, y)
    });
    {
        // SAFETY: the EPS below is dropped at the end of this block, with the shells.
        let (a, _) = unsafe { Mat::shell(&s, s.self_comm(), n, n, Some(4.0), a_apply) }.unwrap();
        let (b, _) =
            unsafe { Mat::shell(&s, s.self_comm(), n, n, Some(1.0), Box::new(identity)) }.unwrap();
        let mut eps = Eps::new(&s, s.self_comm()).unwrap();
        eps.set_operators(&a, &b).unwrap();
        eps.set_problem_type(ProblemType::Ghep).unwrap();
        eps.set_dimensions(4).unwrap();
        eps.set_tolerances(1e-10, 5000).unwrap();
        eps.set_convergence_test(Convergence::Norm).unwrap();
        eps.set_type("lobpcg").unwrap();
        eps.set_which(Which::SmallestReal).unwrap();
        eps.set_spectral_transform(Some("precond"), None, None, None)
            .unwrap();
        // Jacobi of tridiag(-1, 2, -1): 1/2.
        let jacobi: ShellApply<'_> = Box::new(|x, y| {
            for (yi, xi) in y.iter_mut().zip(x) {
                *yi = 0.5 * xi;
            }
            Ok(())
        });
        // SAFETY: the EPS is dropped at the end of this block.
        let pc_failure = unsafe { eps.set_shell_preconditioner(jacobi) }.unwrap();
        eps.solve().unwrap();
        assert!(pc_failure.take().is_none());
        assert!(eps.converged().unwrap() >= 4);
        let [_, st, ksp, pc, _] = eps.describe().unwrap();
        assert_eq!(
            (st.as_str(), ksp.as_str(), pc.as_str()),
            ("precond", "preonly", "shell")
        );
        let mut x = a.create_vector().unwrap();
        let mut values: Vec<f64> = (0..4).map(|i| eps.eigenpair(i, &mut x).unwrap()).collect();
        values.sort_by(f64::total_cmp);
        for (k, got) in values.iter().enumerate() {
            let want = 2.0 - 2.0 * (std::f64::consts::PI * (k + 1) as f64 / (n + 1) as f64).cos();
            // Residual <= 1e-10 (||A|| + |lambda|) ~ 4e-10 bounds the eigenvalue error.
            assert!((got - want).abs() < 1e-8, "{k}: {got} vs {want}");
        }
    }
    // The closure went with the matrix: the only reference left is ours.
    assert_eq!(Arc::strong_count(&token), 1);
}

#[test]
fn a_failing_or_panicking_callback_comes_back_as_its_message() {
    let s = session().unwrap();
    let n = 10;
    let failing: ShellApply<'_> = Box::new(|_, _| Err("device lost".to_string()));
    // SAFETY: dropped before the end of the test; no EPS takes it.
    let (a, failure) = unsafe { Mat::shell(&s, s.self_comm(), n, n, None, failing) }.unwrap();
    let x = a.create_vector().unwrap();
    let mut y = a.create_vector().unwrap();
    let e = a.mult(&x, &mut y).unwrap_err();
    assert_eq!(e.call, "MatMult");
    assert_eq!(failure.take().as_deref(), Some("device lost"));
    let panicking: ShellApply<'_> = Box::new(|_, _| panic!("index out of range"));
    // SAFETY: as above.
    let (p, failure) = unsafe { Mat::shell(&s, s.self_comm(), n, n, None, panicking) }.unwrap();
    assert!(p.mult(&x, &mut y).is_err());
    let message = failure.take().unwrap();
    assert!(
        message.contains("panicked") && message.contains("index out of range"),
        "{message}"
    );
    // The layer still works after both.
    let (ok, _) = unsafe { Mat::shell(&s, s.self_comm(), n, n, None, Box::new(identity)) }.unwrap();
    ok.mult(&x, &mut y).unwrap();
}
