//! Comparing two eigensolutions of the same pencil (H, M): eigenvalue differences and
//! principal angles between eigenspaces in the M-inner product (used by `freeform compare`
//! and the backend tests).

use super::EigenError;
use crate::sparse::{self, SparseMatrixRef};
use faer::{Mat, Side};

/// Largest relative eigenvalue difference between `a` and the reference `b` (same length,
/// ascending): `|a_i - b_i| / |b_i|` for non-zero `b_i`; a (near-)zero reference value (the
/// constant mode) is compared relative to the largest `|b_i|` instead, so round-off around 0
/// does not count as a large relative difference. Empty input gives 0.
pub fn max_eigenvalue_rel_diff(a: &[f64], b: &[f64]) -> f64 {
    let scale = b.iter().fold(0.0f64, |s, v| s.max(v.abs()));
    a.iter()
        .zip(b)
        .map(|(x, y)| {
            let d = (x - y).abs();
            let denom = if y.abs() > 1e-8 * scale {
                y.abs()
            } else {
                scale
            };
            if d == 0.0 {
                0.0
            } else if denom > 0.0 {
                d / denom
            } else {
                f64::INFINITY
            }
        })
        .fold(
            0.0,
            |m, v| if v.is_nan() { f64::INFINITY } else { m.max(v) },
        )
}

/// Index ranges of clusters of nearly equal eigenvalues: consecutive values (ascending) whose
/// gap is at most `rel_gap` times the larger magnitude (or times the largest magnitude, for
/// values near zero) share a cluster. Both solutions' values are used: a gap must be open in
/// both to split.
pub fn clusters(a: &[f64], b: &[f64], rel_gap: f64) -> Vec<std::ops::Range<usize>> {
    let n = a.len().min(b.len());
    let scale = a
        .iter()
        .chain(b)
        .fold(0.0f64, |s, v| s.max(v.abs()))
        .max(f64::MIN_POSITIVE);
    let close = |v: &[f64], i: usize| {
        let (x, y) = (v[i], v[i + 1]);
        (y - x).abs() <= rel_gap * x.abs().max(y.abs()).max(1e-8 * scale)
    };
    let mut out = Vec::new();
    let mut start = 0;
    for i in 0..n {
        if i + 1 == n || !(close(a, i) || close(b, i)) {
            out.push(start..i + 1);
            start = i + 1;
        }
    }
    out
}

/// Largest principal angle (radians) between the eigenspaces of `a` and `b` (K x n each,
/// M-orthonormal columns, eigenvalues ascending `values_a`, `values_b`), taken cluster by
/// cluster ([`clusters`] with `rel_gap`), in the M-inner product: for a cluster G,
/// sin(theta_max) = ||(I - A_G A_G^T M) B_G||_M, computed as the square root of the largest
/// eigenvalue of R^T M R with R = B_G - A_G (A_G^T M B_G). Accurate for small angles (no
/// arccos of a value near 1). A cluster cut by the end of the returned range can show a large
/// angle that is not an error of either solver; choose m so the last wanted eigenvalue is
/// separated from the next one.
///
/// # Errors
/// [`EigenError::InvalidRequest`] on shape mismatch; [`EigenError::NonFinite`] if the small
/// eigenproblem fails.
pub fn max_subspace_angle(
    m: SparseMatrixRef<'_>,
    values_a: &[f64],
    a: &Mat<f64>,
    values_b: &[f64],
    b: &Mat<f64>,
    rel_gap: f64,
) -> Result<f64, EigenError> {
    let k = m.nrows();
    if a.nrows() != k || b.nrows() != k || a.ncols() != b.ncols() {
        return Err(EigenError::InvalidRequest(format!(
            "cannot compare a {} x {} and a {} x {} eigenvector block with K = {k}",
            a.nrows(),
            a.ncols(),
            b.nrows(),
            b.ncols()
        )));
    }
    let n = a.ncols().min(values_a.len()).min(values_b.len());
    let mut mb = Mat::<f64>::zeros(k, n);
    sparse::sym_mul_block(m, b.subcols(0, n), mb.as_mut());
    let mut worst = 0.0f64;
    for g in clusters(&values_a[..n], &values_b[..n], rel_gap) {
        let ag = a.subcols(g.start, g.len());
        let bg = b.subcols(g.start, g.len());
        let mbg = mb.subcols(g.start, g.len());
        // C = A_G^T M B_G; R = B_G - A_G C; G = R^T M R = B^T M B - C^T C (for M-orthonormal
        // A, B) loses accuracy for small angles, so form R and M R explicitly.
        let c = ag.transpose() * mbg;
        let r = bg - ag * &c;
        let mut mr = Mat::<f64>::zeros(k, g.len());
        sparse::sym_mul_block(m, r.as_ref(), mr.as_mut());
        let gram = r.transpose() * &mr;
        let ev = gram
            .self_adjoint_eigenvalues(Side::Lower)
            .map_err(|e| EigenError::NonFinite(format!("subspace angle: {e:?}")))?;
        let top = ev.last().copied().unwrap_or(0.0).max(0.0);
        if top.is_nan() {
            return Err(EigenError::NonFinite("subspace angle is NaN".into()));
        }
        worst = worst.max(top.sqrt().min(1.0).asin());
    }
    Ok(worst)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::eigen::testing::identity;

    #[test]
    fn angles_of_known_rotations() {
        // M = I, K = 4. A = e0, e1 (values 1, 2); B = rotated by 1e-3 rad into e2 within the
        // second column and the first column swapped sign (sign is not an angle).
        let m = identity(4);
        let mut a = Mat::<f64>::zeros(4, 2);
        a[(0, 0)] = 1.0;
        a[(1, 1)] = 1.0;
        let t = 1e-3f64;
        let mut b = Mat::<f64>::zeros(4, 2);
        b[(0, 0)] = -1.0;
        b[(1, 1)] = t.cos();
        b[(2, 1)] = t.sin();
        let angle = max_subspace_angle(m.as_ref(), &[1.0, 2.0], &a, &[1.0, 2.0], &b, 1e-6).unwrap();
        assert!((angle - t).abs() < 1e-15, "{angle}");
        // A degenerate pair: any rotation inside the cluster is no angle.
        let mut c = Mat::<f64>::zeros(4, 2);
        c[(0, 0)] = (0.3f64).cos();
        c[(1, 0)] = (0.3f64).sin();
        c[(0, 1)] = -(0.3f64).sin();
        c[(1, 1)] = (0.3f64).cos();
        let vals = [1.0, 1.0 + 1e-9];
        assert!(max_subspace_angle(m.as_ref(), &vals, &a, &vals, &c, 1e-6).unwrap() < 1e-15);
        // Separate eigenvalues: the same rotation is a 0.3 rad angle.
        let vals = [1.0, 2.0];
        let angle = max_subspace_angle(m.as_ref(), &vals, &a, &vals, &c, 1e-6).unwrap();
        assert!((angle - 0.3).abs() < 1e-12, "{angle}");
    }

    #[test]
    fn eigenvalue_differences() {
        assert_eq!(max_eigenvalue_rel_diff(&[0.0, 2.0], &[0.0, 2.0]), 0.0);
        let d = max_eigenvalue_rel_diff(&[1e-13, 2.0 + 2e-9], &[0.0, 2.0]);
        assert!((d - 1e-9).abs() < 1e-15, "{d}");
        assert_eq!(
            clusters(&[0.0, 1.0, 1.0, 3.0], &[0.0, 1.0, 1.0, 3.0], 1e-6).len(),
            3
        );
    }
}
