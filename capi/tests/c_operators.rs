//! Compiles `examples/operators.c` (a matrix-free Q1 Laplacian applied by C callbacks) against
//! the static library, runs it, and checks its eigenvalues against the closed form and its
//! error lines against the callbacks' failures.

use freeform::eigen::testing::q1_fem_eigenvalues;

mod common;
use common::compile_and_run;

#[test]
fn c_callbacks_give_the_closed_form_eigenvalues_and_their_errors() {
    let dir = tempfile::tempdir().unwrap();
    let out = compile_and_run("operators", dir.path(), &[]);
    let values: Vec<f64> = out
        .lines()
        .filter_map(|l| l.strip_prefix("lambda "))
        .map(|v| v.parse().unwrap())
        .collect();
    let exact = q1_fem_eigenvalues([7, 8, 9], 0.1, 8);
    assert_eq!(values.len(), 8, "{out}");
    let top = exact[7];
    for (got, want) in values.iter().zip(&exact) {
        // tol 1e-9 on the residual: eigenvalues to ~1e-14 relative; the bar is 1e-8.
        assert!((got - want).abs() <= 1e-8 * top, "{got} vs {want}\n{out}");
    }
    let errors: Vec<&str> = out.lines().filter(|l| l.starts_with("error")).collect();
    assert_eq!(errors.len(), 2, "{out}");
    // FF_ERR_EIGENSOLVER = 4, with the callback's own message.
    assert!(
        errors[0].starts_with("error 4:") && errors[0].contains("device lost"),
        "{}",
        errors[0]
    );
    // The short write leaves NaN in the output block: refused, naming H.
    assert!(
        errors[1].starts_with("error 4:") && errors[1].contains("operator H returned NaN"),
        "{}",
        errors[1]
    );
}
