//! Small 3 x 3 dense linear algebra used per integration point: the [`Mat3`] type, product,
//! transpose, determinant and cofactor, a symmetric eigensolver (cyclic Jacobi) and the
//! rotation-variant SVD (U, V proper rotations, the smallest singular value carries the sign of
//! det F), as used for the analytic Hessian projection. A leaf: it imports no other module.

/// A 3 x 3 matrix, row-major: `f[r][c]`.
pub type Mat3 = [[f64; 3]; 3];

/// det F.
#[inline]
pub fn det3(f: &Mat3) -> f64 {
    f[0][0] * (f[1][1] * f[2][2] - f[1][2] * f[2][1])
        - f[0][1] * (f[1][0] * f[2][2] - f[1][2] * f[2][0])
        + f[0][2] * (f[1][0] * f[2][1] - f[1][1] * f[2][0])
}

/// Cofactor matrix of F (= det(F) F^-T), the derivative of det F with respect to F.
#[inline]
pub fn cofactor3(f: &Mat3) -> Mat3 {
    [
        [
            f[1][1] * f[2][2] - f[1][2] * f[2][1],
            f[1][2] * f[2][0] - f[1][0] * f[2][2],
            f[1][0] * f[2][1] - f[1][1] * f[2][0],
        ],
        [
            f[0][2] * f[2][1] - f[0][1] * f[2][2],
            f[0][0] * f[2][2] - f[0][2] * f[2][0],
            f[0][1] * f[2][0] - f[0][0] * f[2][1],
        ],
        [
            f[0][1] * f[1][2] - f[0][2] * f[1][1],
            f[0][2] * f[1][0] - f[0][0] * f[1][2],
            f[0][0] * f[1][1] - f[0][1] * f[1][0],
        ],
    ]
}

/// Product A B.
#[inline]
pub fn mul(a: &Mat3, b: &Mat3) -> Mat3 {
    let mut c = [[0.0; 3]; 3];
    for r in 0..3 {
        for k in 0..3 {
            for s in 0..3 {
                c[r][s] += a[r][k] * b[k][s];
            }
        }
    }
    c
}

/// Transpose.
#[inline]
pub fn transpose(a: &Mat3) -> Mat3 {
    let mut t = [[0.0; 3]; 3];
    for r in 0..3 {
        for c in 0..3 {
            t[c][r] = a[r][c];
        }
    }
    t
}

/// Eigen-decomposition of a symmetric 3 x 3 matrix by cyclic Jacobi rotations:
/// returns (eigenvalues, eigenvectors as the columns of V) with A = V diag(w) V^T, V
/// orthogonal. Accurate to a few ulps of ||A|| (Jacobi is backward stable).
pub fn sym_eig3(a: &Mat3) -> ([f64; 3], Mat3) {
    let mut m = *a;
    let mut v = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    for _sweep in 0..32 {
        let off = m[0][1].powi(2) + m[0][2].powi(2) + m[1][2].powi(2);
        let diag = m[0][0].powi(2) + m[1][1].powi(2) + m[2][2].powi(2);
        // Converged once the off-diagonal part is below rounding of the diagonal; an exactly
        // zero matrix (diag = off = 0) also stops here.
        if off <= 1e-36 * diag || off == 0.0 {
            break;
        }
        for (p, q) in [(0usize, 1usize), (0, 2), (1, 2)] {
            let apq = m[p][q];
            if apq == 0.0 {
                continue;
            }
            // Rotation angle annihilating m[p][q] (Golub & Van Loan, symmetric Schur 2x2).
            let theta = (m[q][q] - m[p][p]) / (2.0 * apq);
            let t = theta.signum() / (theta.abs() + (theta * theta + 1.0).sqrt());
            let t = if theta == 0.0 { 1.0 } else { t };
            let c = 1.0 / (t * t + 1.0).sqrt();
            let s = t * c;
            for k in 0..3 {
                let (mkp, mkq) = (m[k][p], m[k][q]);
                m[k][p] = c * mkp - s * mkq;
                m[k][q] = s * mkp + c * mkq;
            }
            for k in 0..3 {
                let (mpk, mqk) = (m[p][k], m[q][k]);
                m[p][k] = c * mpk - s * mqk;
                m[q][k] = s * mpk + c * mqk;
            }
            for k in 0..3 {
                let (vkp, vkq) = (v[k][p], v[k][q]);
                v[k][p] = c * vkp - s * vkq;
                v[k][q] = s * vkp + c * vkq;
            }
        }
    }
    ([m[0][0], m[1][1], m[2][2]], v)
}

fn col(m: &Mat3, c: usize) -> [f64; 3] {
    [m[0][c], m[1][c], m[2][c]]
}

/// a . b.
#[inline]
pub fn dot(a: &[f64; 3], b: &[f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// a x b.
#[inline]
pub fn cross(a: &[f64; 3], b: &[f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

/// a - b.
#[inline]
pub fn sub(a: &[f64; 3], b: &[f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

/// |a|, the Euclidean norm.
#[inline]
pub fn norm(a: &[f64; 3]) -> f64 {
    dot(a, a).sqrt()
}

/// a / |a|, or `None` for a zero or non-finite length.
pub fn normalize(a: [f64; 3]) -> Option<[f64; 3]> {
    let n = dot(&a, &a).sqrt();
    (n > 0.0 && n.is_finite()).then(|| [a[0] / n, a[1] / n, a[2] / n])
}

/// The outer product u u^T.
#[inline]
pub fn outer(u: &[f64; 3]) -> Mat3 {
    std::array::from_fn(|r| std::array::from_fn(|s| u[r] * u[s]))
}

/// I - u u^T: for a unit u, the projector across it.
#[inline]
pub fn identity_minus_outer(u: &[f64; 3]) -> Mat3 {
    std::array::from_fn(|r| std::array::from_fn(|s| if r == s { 1.0 } else { 0.0 } - u[r] * u[s]))
}

/// A v (for a rotation R: v rotated into the outer frame).
#[inline]
pub fn mat_vec(a: &Mat3, v: &[f64; 3]) -> [f64; 3] {
    std::array::from_fn(|i| dot(&a[i], v))
}

/// A^T v (for a rotation R: v rotated back into the rotated frame).
#[inline]
pub fn mat_t_vec(a: &Mat3, v: &[f64; 3]) -> [f64; 3] {
    std::array::from_fn(|i| a[0][i] * v[0] + a[1][i] * v[1] + a[2][i] * v[2])
}

/// Any unit vector orthogonal to the unit vector `a`.
fn orthogonal_to(a: &[f64; 3]) -> [f64; 3] {
    // Cross with the coordinate axis least aligned with a: |a x e| >= sqrt(2/3).
    let i = (0..3)
        .min_by(|&i, &j| a[i].abs().total_cmp(&a[j].abs()))
        .unwrap_or(0);
    let mut e = [0.0; 3];
    e[i] = 1.0;
    normalize(cross(a, &e)).unwrap_or([1.0, 0.0, 0.0])
}

/// Rotation-variant SVD F = U diag(s) V^T with U, V proper rotations (det = +1),
/// `s[0] >= s[1] >= |s[2]|`, and `s[2] < 0` exactly when det F < 0. V comes from the
/// eigenvectors of F^T F, U by Gram-Schmidt on F V (completed by cross products when F is
/// rank deficient), so F = U diag(s) V^T holds to `O(eps ||F||^2 / s[1])`.
pub fn svd3_rv(f: &Mat3) -> (Mat3, [f64; 3], Mat3) {
    let ftf = mul(&transpose(f), f);
    let (w, mut v) = sym_eig3(&ftf);
    // Sort the eigenpairs by decreasing eigenvalue.
    let mut order = [0usize, 1, 2];
    order.sort_by(|&i, &j| w[j].total_cmp(&w[i]));
    let vs = v;
    for (dst, &src) in order.iter().enumerate() {
        for k in 0..3 {
            v[k][dst] = vs[k][src];
        }
    }
    // Make V a proper rotation.
    let det_v = det3(&v);
    if det_v < 0.0 {
        for row in v.iter_mut() {
            row[2] = -row[2];
        }
    }
    let apply = |c: usize| {
        let vc = col(&v, c);
        [dot(&f[0], &vc), dot(&f[1], &vc), dot(&f[2], &vc)]
    };
    let (fv0, fv1, fv2) = (apply(0), apply(1), apply(2));
    let u0 = normalize(fv0).unwrap_or([1.0, 0.0, 0.0]);
    let p = dot(&u0, &fv1);
    let u1 = normalize([fv1[0] - p * u0[0], fv1[1] - p * u0[1], fv1[2] - p * u0[2]])
        .unwrap_or_else(|| orthogonal_to(&u0));
    let u2 = cross(&u0, &u1);
    let s = [dot(&u0, &fv0), dot(&u1, &fv1), dot(&u2, &fv2)];
    let u = [
        [u0[0], u1[0], u2[0]],
        [u0[1], u1[1], u2[1]],
        [u0[2], u1[2], u2[2]],
    ];
    (u, s, v)
}

/// Rotation matrix of a unit quaternion `q = (w, x, y, z)` (w first, as 3D Gaussian splat
/// files store it): the matrix of x -> q x q^*. `q` is used as given (not normalized).
pub fn quat_to_matrix(q: &[f64; 4]) -> Mat3 {
    let [w, x, y, z] = *q;
    [
        [
            1.0 - 2.0 * (y * y + z * z),
            2.0 * (x * y - w * z),
            2.0 * (x * z + w * y),
        ],
        [
            2.0 * (x * y + w * z),
            1.0 - 2.0 * (x * x + z * z),
            2.0 * (y * z - w * x),
        ],
        [
            2.0 * (x * z - w * y),
            2.0 * (y * z + w * x),
            1.0 - 2.0 * (x * x + y * y),
        ],
    ]
}

/// Unit quaternion `(w, x, y, z)` of a proper rotation matrix (Shepperd's method: the
/// largest of the four squared components is taken from the diagonal, the others from the
/// off-diagonal sums, so every rotation is converted to a few ulps). The sign is the one
/// with `w >= 0` when that is unambiguous; callers that need continuity flip it themselves.
pub fn matrix_to_quat(r: &Mat3) -> [f64; 4] {
    let tr = r[0][0] + r[1][1] + r[2][2];
    let cands = [tr, r[0][0], r[1][1], r[2][2]];
    let mut k = 0;
    for i in 1..4 {
        if cands[i] > cands[k] {
            k = i;
        }
    }
    let q = match k {
        0 => {
            let s = 2.0 * (1.0 + tr).sqrt();
            [
                0.25 * s,
                (r[2][1] - r[1][2]) / s,
                (r[0][2] - r[2][0]) / s,
                (r[1][0] - r[0][1]) / s,
            ]
        }
        1 => {
            let s = 2.0 * (1.0 + r[0][0] - r[1][1] - r[2][2]).sqrt();
            [
                (r[2][1] - r[1][2]) / s,
                0.25 * s,
                (r[0][1] + r[1][0]) / s,
                (r[0][2] + r[2][0]) / s,
            ]
        }
        2 => {
            let s = 2.0 * (1.0 + r[1][1] - r[0][0] - r[2][2]).sqrt();
            [
                (r[0][2] - r[2][0]) / s,
                (r[0][1] + r[1][0]) / s,
                0.25 * s,
                (r[1][2] + r[2][1]) / s,
            ]
        }
        _ => {
            let s = 2.0 * (1.0 + r[2][2] - r[0][0] - r[1][1]).sqrt();
            [
                (r[1][0] - r[0][1]) / s,
                (r[0][2] + r[2][0]) / s,
                (r[1][2] + r[2][1]) / s,
                0.25 * s,
            ]
        }
    };
    // Renormalize (removes the rounding of a slightly non-orthogonal input).
    let n = (q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]).sqrt();
    let sign = if q[0] < 0.0 { -1.0 } else { 1.0 };
    [
        sign * q[0] / n,
        sign * q[1] / n,
        sign * q[2] / n,
        sign * q[3] / n,
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quaternions_round_trip_through_matrices() {
        let id = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
        // Generic, half-turns about each axis (w = 0, the branches of Shepperd's method)
        // and the identity.
        let s = 0.5f64.sqrt();
        let cases: [[f64; 4]; 7] = [
            [0.3, -0.5, 0.7, 0.1],
            [0.0, 1.0, 0.0, 0.0],
            [0.0, 0.0, 1.0, 0.0],
            [0.0, 0.0, 0.0, 1.0],
            [0.0, s, s, 0.0],
            [1.0, 0.0, 0.0, 0.0],
            [0.9, 0.1, -0.2, -0.3],
        ];
        for q in cases {
            let n = q.iter().map(|v| v * v).sum::<f64>().sqrt();
            let q = q.map(|v| v / n);
            let r = quat_to_matrix(&q);
            assert!(max_abs_diff(&mul(&transpose(&r), &r), &id) < 1e-15, "{q:?}");
            assert!((det3(&r) - 1.0).abs() < 1e-15);
            let back = matrix_to_quat(&r);
            let sign = if back.iter().zip(&q).map(|(a, b)| a * b).sum::<f64>() < 0.0 {
                -1.0
            } else {
                1.0
            };
            for k in 0..4 {
                assert!((sign * back[k] - q[k]).abs() < 1e-15, "{q:?} -> {back:?}");
            }
        }
        // A quarter turn about z maps x to y.
        let h = 0.25 * std::f64::consts::PI;
        let r = quat_to_matrix(&[h.cos(), 0.0, 0.0, h.sin()]);
        assert!(max_abs_diff(&r, &[[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]) < 1e-15);
    }

    fn max_abs_diff(a: &Mat3, b: &Mat3) -> f64 {
        (0..9)
            .map(|k| (a[k / 3][k % 3] - b[k / 3][k % 3]).abs())
            .fold(0.0, f64::max)
    }

    fn reconstruct(u: &Mat3, s: &[f64; 3], v: &Mat3) -> Mat3 {
        let mut us = *u;
        for row in us.iter_mut() {
            for c in 0..3 {
                row[c] *= s[c];
            }
        }
        mul(&us, &transpose(v))
    }

    #[test]
    fn svd_reconstructs_and_keeps_rotations_proper() {
        let cases: [Mat3; 6] = [
            [[1.1, 0.2, -0.05], [0.03, 0.9, 0.1], [-0.2, 0.05, 1.2]],
            // Inverted (det < 0).
            [[-1.0, 0.1, 0.0], [0.2, 0.8, 0.3], [0.0, 0.1, 1.5]],
            // Rank deficient (flat) and rank one.
            [[1.0, 2.0, 3.0], [2.0, 4.0, 6.0], [0.0, 1.0, 0.0]],
            [[1.0, 2.0, 3.0], [2.0, 4.0, 6.0], [3.0, 6.0, 9.0]],
            // Identity (repeated singular values) and zero.
            [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
            [[0.0; 3]; 3],
        ];
        for f in &cases {
            let (u, s, v) = svd3_rv(f);
            // Backward error bound: O(eps ||F||^2 / s_1) with ||F|| <= 14 here.
            assert!(max_abs_diff(&reconstruct(&u, &s, &v), f) < 1e-12, "{f:?}");
            let id = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
            assert!(max_abs_diff(&mul(&transpose(&u), &u), &id) < 1e-14);
            assert!(max_abs_diff(&mul(&transpose(&v), &v), &id) < 1e-14);
            assert!((det3(&u) - 1.0).abs() < 1e-14);
            assert!((det3(&v) - 1.0).abs() < 1e-14);
            assert!(s[0] >= s[1] && s[1] >= s[2].abs());
            let det = det3(f);
            assert!((s[0] * s[1] * s[2] - det).abs() < 1e-12 * (1.0 + det.abs()));
        }
    }

    #[test]
    fn jacobi_diagonalises() {
        let a = [[4.0, 1.0, -2.0], [1.0, 2.0, 0.5], [-2.0, 0.5, 3.0]];
        let (w, v) = sym_eig3(&a);
        let mut d = [[0.0; 3]; 3];
        for k in 0..3 {
            d[k][k] = w[k];
        }
        let back = mul(&mul(&v, &d), &transpose(&v));
        assert!(max_abs_diff(&back, &a) < 1e-14 * 8.0);
        // Trace and determinant are invariants.
        assert!((w.iter().sum::<f64>() - 9.0).abs() < 1e-13);
        let det = det3(&a);
        assert!((w[0] * w[1] * w[2] - det).abs() < 1e-12);
    }
}
