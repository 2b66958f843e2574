//! Small Gaussians (3D Gaussian splats) carried by a deformation with gradient F at their
//! centres: covariance Sigma = R diag(exp(2 s)) R^T becomes F Sigma F^T, re-derived exactly
//! as rotation and log-scales (symmetric eigendecomposition, proper rotation), and the
//! view-dependent colour (real spherical harmonics of degree 1 to 3, in the 3DGS basis) is
//! rotated by the rotation R_p of the polar decomposition F = R_p U.
//!
//! docs/splats.md gives the math and the conventions.

use crate::linalg3::Mat3;
use crate::linalg3::{
    cross, det3, matrix_to_quat, mul, quat_to_matrix, svd3_rv, sym_eig3, transpose,
};
use rayon::prelude::*;
use std::sync::OnceLock;

/// Eigenvalues of F Sigma F^T closer than this (relative to the largest) form one eigenspace:
/// its axes are then chosen closest to the carried rotation (so a splat at rest, or an
/// isotropic one, keeps its rotation bit for bit up to rounding) and its variances are the
/// Rayleigh quotients of those axes. The error this allows in the covariance is below this
/// fraction of its norm, far under float32 rounding.
const CLUSTER_TOL: f64 = 1e-10;

/// Smallest variance kept, relative to the largest: a deformation that flattens a splat
/// (det F -> 0) gives it an axis ratio of 1e-7 (log-scale difference -16), so every written
/// covariance stays positive definite.
const MIN_VARIANCE_RATIO: f64 = 1e-14;

/// One Gaussian after the deformation.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DeformedGaussian {
    /// Log of the standard deviations along the axes (natural log, metres).
    pub log_scale: [f64; 3],
    /// Unit quaternion (w, x, y, z) of the axes, with the sign of the carried one.
    pub rotation: [f64; 4],
    /// The rotation R_p of the polar decomposition F = R_p U (proper: det +1).
    pub polar: Mat3,
    /// Whether a variance was raised to [`MIN_VARIANCE_RATIO`] times the largest.
    pub clamped: bool,
}

/// Covariance R diag(exp(2 s)) R^T of a Gaussian with log-scales `s` and unit quaternion `q`
/// (w, x, y, z), metres^2.
pub fn covariance(log_scale: &[f64; 3], rotation: &[f64; 4]) -> Mat3 {
    let r = quat_to_matrix(rotation);
    let mut c = [[0.0; 3]; 3];
    for a in 0..3 {
        let v = (2.0 * log_scale[a]).exp();
        for i in 0..3 {
            for j in 0..3 {
                c[i][j] += r[i][a] * v * r[j][a];
            }
        }
    }
    c
}

/// The Gaussian with log-scales `s` and unit quaternion `q` (w, x, y, z) moved by a map with
/// gradient `f`: the exact decomposition of F Sigma F^T. The eigendecomposition is taken in
/// the frame Q = R_p R of the carried axes, M = Q^T F Sigma F^T Q, and each eigenvector is
/// matched to the axis it is closest to (sign and order), so a rigid motion keeps the scales
/// and composes the rotation, and nothing jumps between frames unless two variances cross.
pub fn deform_gaussian(f: &Mat3, log_scale: &[f64; 3], rotation: &[f64; 4]) -> DeformedGaussian {
    let (u, _, v) = svd3_rv(f);
    let polar = mul(&u, &transpose(&v));
    let r = quat_to_matrix(rotation);
    let q = mul(&polar, &r);
    // G = Q^T F R, M = G D G^T.
    let g = mul(&mul(&transpose(&q), f), &r);
    let d = log_scale.map(|s| (2.0 * s).exp());
    let mut m = [[0.0; 3]; 3];
    for i in 0..3 {
        for j in i..3 {
            let mut s = 0.0;
            for a in 0..3 {
                s += g[i][a] * d[a] * g[j][a];
            }
            m[i][j] = s;
            m[j][i] = s;
        }
    }
    let axes = matched_eigenvectors(&m);
    // Variances: Rayleigh quotients of the chosen axes (exact for an eigenvector).
    let mut var = [0.0; 3];
    for a in 0..3 {
        let x = [axes[0][a], axes[1][a], axes[2][a]];
        let mut s = 0.0;
        for i in 0..3 {
            for j in 0..3 {
                s += x[i] * m[i][j] * x[j];
            }
        }
        var[a] = s;
    }
    let vmax = var.iter().copied().fold(0.0, f64::max);
    let floor = (vmax * MIN_VARIANCE_RATIO).max(f64::MIN_POSITIVE);
    let mut clamped = false;
    for v in &mut var {
        if v.is_nan() || *v < floor {
            *v = floor;
            clamped = true;
        }
    }
    let rot = mul(&q, &axes);
    let mut quat = matrix_to_quat(&rot);
    if quat.iter().zip(rotation).map(|(a, b)| a * b).sum::<f64>() < 0.0 {
        quat = quat.map(|c| -c);
    }
    DeformedGaussian {
        log_scale: var.map(|v| 0.5 * v.ln()),
        rotation: quat,
        polar,
        clamped,
    }
}

/// Orthonormal eigenvectors (columns, a proper rotation) of the symmetric `m`, each matched to
/// the coordinate axis it is closest to: column a is the eigenvector with the largest |x_a|,
/// signed so that x_a >= 0. Within an eigenspace of repeated eigenvalues the axes closest to
/// the coordinate axes are taken. For a diagonal `m` this is the identity.
fn matched_eigenvectors(m: &Mat3) -> Mat3 {
    let (lam, v) = sym_eig3(m);
    let scale = lam.iter().map(|l| l.abs()).fold(0.0, f64::max);
    let tol = CLUSTER_TOL * scale;
    let close = |i: usize, j: usize| (lam[i] - lam[j]).abs() <= tol;
    let col = |c: usize| [v[0][c], v[1][c], v[2][c]];
    let mut out = [[0.0; 3]; 3];
    let set = |out: &mut Mat3, a: usize, x: [f64; 3]| {
        for k in 0..3 {
            out[k][a] = x[k];
        }
    };
    let ncl = [close(0, 1), close(0, 2), close(1, 2)]
        .iter()
        .filter(|&&b| b)
        .count();
    if ncl >= 2 || scale == 0.0 {
        // One eigenspace (isotropic): keep the axes.
        return [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    }
    if ncl == 1 {
        // Two equal eigenvalues: the single eigenvector is well defined; the other two axes
        // are the coordinate axes projected onto its orthogonal plane.
        let single = if close(0, 1) {
            2
        } else if close(0, 2) {
            1
        } else {
            0
        };
        let mut x = col(single);
        let k = (0..3)
            .max_by(|&a, &b| x[a].abs().total_cmp(&x[b].abs()))
            .unwrap_or(0);
        if x[k] < 0.0 {
            x = x.map(|c| -c);
        }
        let (i, j) = match k {
            0 => (1, 2),
            1 => (0, 2),
            _ => (0, 1),
        };
        // e_i - x_i x, normalized (|x_i| <= |x_k| keeps its norm >= 1/sqrt 2).
        let mut yi = [-x[i] * x[0], -x[i] * x[1], -x[i] * x[2]];
        yi[i] += 1.0;
        let n = (yi[0] * yi[0] + yi[1] * yi[1] + yi[2] * yi[2]).sqrt();
        let yi = yi.map(|c| c / n);
        let yj = cross(&x, &yi);
        set(&mut out, k, x);
        set(&mut out, i, yi);
        set(&mut out, j, yj);
        if det3(&out) < 0.0 {
            set(&mut out, j, yj.map(|c| -c));
        }
        return out;
    }
    // Distinct eigenvalues: the permutation with the largest total alignment.
    const PERMS: [[usize; 3]; 6] = [
        [0, 1, 2],
        [0, 2, 1],
        [1, 0, 2],
        [1, 2, 0],
        [2, 0, 1],
        [2, 1, 0],
    ];
    let best = PERMS
        .iter()
        .max_by(|p, q| {
            let score = |p: &[usize; 3]| (0..3).map(|a| v[a][p[a]].abs()).sum::<f64>();
            score(p).total_cmp(&score(q))
        })
        .unwrap_or(&PERMS[0]);
    for a in 0..3 {
        let mut x = col(best[a]);
        if x[a] < 0.0 {
            x = x.map(|c| -c);
        }
        set(&mut out, a, x);
    }
    if det3(&out) < 0.0 {
        // Flip the axis least aligned with its coordinate axis.
        let a = (0..3)
            .min_by(|&a, &b| out[a][a].abs().total_cmp(&out[b][b].abs()))
            .unwrap_or(2);
        for k in 0..3 {
            out[k][a] = -out[k][a];
        }
    }
    out
}

// --- Spherical harmonics -------------------------------------------------------------------

/// Real spherical harmonics of degree `l` (1..=3) at the unit direction `d`, in the basis
/// and order of the 3DGS reference code (`sh_utils.eval_sh`): degree 1 is
/// (-C1 y, C1 z, -C1 x), degree 2 (xy, yz, 2z^2 - x^2 - y^2, xz, x^2 - y^2) with their
/// constants, degree 3 likewise. Writes 2 l + 1 values to `out`.
pub fn sh_basis(l: usize, d: &[f64; 3], out: &mut [f64]) {
    let [x, y, z] = *d;
    const C1: f64 = 0.488_602_511_902_919_9;
    const C2: [f64; 5] = [
        1.092_548_430_592_079_2,
        -1.092_548_430_592_079_2,
        0.315_391_565_252_520_05,
        -1.092_548_430_592_079_2,
        0.546_274_215_296_039_6,
    ];
    const C3: [f64; 7] = [
        -0.590_043_589_926_643_5,
        2.890_611_442_640_554,
        -0.457_045_799_464_465_8,
        0.373_176_332_590_115_4,
        -0.457_045_799_464_465_8,
        1.445_305_721_320_277,
        -0.590_043_589_926_643_5,
    ];
    let (xx, yy, zz) = (x * x, y * y, z * z);
    match l {
        1 => {
            out[0] = -C1 * y;
            out[1] = C1 * z;
            out[2] = -C1 * x;
        }
        2 => {
            out[0] = C2[0] * x * y;
            out[1] = C2[1] * y * z;
            out[2] = C2[2] * (2.0 * zz - xx - yy);
            out[3] = C2[3] * x * z;
            out[4] = C2[4] * (xx - yy);
        }
        3 => {
            out[0] = C3[0] * y * (3.0 * xx - yy);
            out[1] = C3[1] * x * y * z;
            out[2] = C3[2] * y * (4.0 * zz - xx - yy);
            out[3] = C3[3] * z * (2.0 * zz - 3.0 * xx - 3.0 * yy);
            out[4] = C3[4] * x * (4.0 * zz - xx - yy);
            out[5] = C3[5] * z * (xx - yy);
            out[6] = C3[6] * x * (xx - 3.0 * yy);
        }
        _ => panic!("spherical harmonics degree {l} is not 1..=3"),
    }
}

/// Per degree l = 1..=3: 2 l + 1 fixed directions d_i and the inverse of P_l = [Y_l(d_i)].
struct ShSamples {
    dirs: [Vec<[f64; 3]>; 3],
    /// (2l+1) x (2l+1), row-major.
    inverse: [Vec<f64>; 3],
}

/// Fixed sample directions: a Fibonacci spiral of n points, shifted off the symmetric
/// positions (a symmetric spiral of 3 points is coplanar with the origin, which makes P_1
/// singular), so P_l is well conditioned (the tests check the largest entry of P_l^-1 and
/// the rotation identity to 1e-12).
fn sample_dirs(n: usize) -> Vec<[f64; 3]> {
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    (0..n)
        .map(|i| {
            let z = 1.0 - 2.0 * (i as f64 + 0.37) / n as f64;
            let r = (1.0 - z * z).sqrt();
            let t = golden * i as f64 + 0.3;
            [r * t.cos(), r * t.sin(), z]
        })
        .collect()
}

/// Inverse of the n x n row-major `a` by Gauss-Jordan with partial pivoting.
fn invert(mut a: Vec<f64>, n: usize) -> Vec<f64> {
    let mut inv = vec![0.0; n * n];
    for i in 0..n {
        inv[i * n + i] = 1.0;
    }
    for c in 0..n {
        let p = (c..n)
            .max_by(|&i, &j| a[i * n + c].abs().total_cmp(&a[j * n + c].abs()))
            .unwrap_or(c);
        for k in 0..n {
            a.swap(c * n + k, p * n + k);
            inv.swap(c * n + k, p * n + k);
        }
        let piv = a[c * n + c];
        for k in 0..n {
            a[c * n + k] /= piv;
            inv[c * n + k] /= piv;
        }
        for r in 0..n {
            if r != c {
                let f = a[r * n + c];
                if f != 0.0 {
                    for k in 0..n {
                        a[r * n + k] -= f * a[c * n + k];
                        inv[r * n + k] -= f * inv[c * n + k];
                    }
                }
            }
        }
    }
    inv
}

fn sh_samples() -> &'static ShSamples {
    static SAMPLES: OnceLock<ShSamples> = OnceLock::new();
    SAMPLES.get_or_init(|| {
        let make = |l: usize| {
            let n = 2 * l + 1;
            let dirs = sample_dirs(n);
            let mut p = vec![0.0; n * n];
            for (i, d) in dirs.iter().enumerate() {
                sh_basis(l, d, &mut p[i * n..(i + 1) * n]);
            }
            (dirs, invert(p, n))
        };
        let (d1, i1) = make(1);
        let (d2, i2) = make(2);
        let (d3, i3) = make(3);
        ShSamples {
            dirs: [d1, d2, d3],
            inverse: [i1, i2, i3],
        }
    })
}

/// Rotate the SH coefficients of one splat by `r` (a proper rotation): afterwards the colour
/// seen from direction d is what was seen from r^T d. `rest` holds the 3DGS `f_rest` values of
/// the splat: 3 channels x K coefficients, channel-major (K = (degree + 1)^2 - 1; coefficient k
/// is SH index k + 1). Degree 0 (f_dc) does not change. Exact: each degree's coefficients are
/// mapped by P_l^-1 [Y_l(r^T d_i)], the interpolation of the rotated function at 2 l + 1 fixed
/// directions.
pub fn rotate_sh(r: &Mat3, degree: usize, rest: &mut [f64]) {
    let k_total = (degree + 1) * (degree + 1) - 1;
    debug_assert_eq!(rest.len(), 3 * k_total);
    let samples = sh_samples();
    let rt = transpose(r);
    let mut y = [0.0; 7];
    let mut t = [[0.0; 7]; 3];
    for l in 1..=degree.min(3) {
        let n = 2 * l + 1;
        let off = l * l - 1;
        for (i, d) in samples.dirs[l - 1].iter().enumerate() {
            let dr = [
                rt[0][0] * d[0] + rt[0][1] * d[1] + rt[0][2] * d[2],
                rt[1][0] * d[0] + rt[1][1] * d[1] + rt[1][2] * d[2],
                rt[2][0] * d[0] + rt[2][1] * d[1] + rt[2][2] * d[2],
            ];
            sh_basis(l, &dr, &mut y[..n]);
            for (c, tc) in t.iter_mut().enumerate() {
                let coeffs = &rest[c * k_total + off..c * k_total + off + n];
                tc[i] = y[..n].iter().zip(coeffs).map(|(a, b)| a * b).sum();
            }
        }
        let inv = &samples.inverse[l - 1];
        for (c, tc) in t.iter().enumerate() {
            for m in 0..n {
                let row = &inv[m * n..(m + 1) * n];
                rest[c * k_total + off + m] = row.iter().zip(&tc[..n]).map(|(a, b)| a * b).sum();
            }
        }
    }
}

/// Splats after a deformation (see [`deform_splats`]).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct DeformedSplats {
    /// Log-scales, N x 3.
    pub log_scales: Vec<[f64; 3]>,
    /// Unit quaternions (w, x, y, z), N.
    pub rotations: Vec<[f64; 4]>,
    /// Rotated `f_rest` coefficients (N x 3 K, as given), None when SH rotation is off.
    pub sh_rest: Option<Vec<f64>>,
    /// Splats whose smallest variance was raised to keep the covariance positive definite.
    pub clamped: usize,
}

/// [`deform_gaussian`] for N splats with deformation gradients `f` (N), log-scales (N x 3) and
/// unit quaternions (N); with `rotate` the `f_rest` coefficients `sh_rest` (N x 3 K, K =
/// (degree + 1)^2 - 1) are rotated by each splat's polar rotation ([`rotate_sh`]).
/// Parallel over splats; the result does not depend on the thread count.
pub fn deform_splats(
    f: &[Mat3],
    log_scales: &[[f64; 3]],
    rotations: &[[f64; 4]],
    sh_rest: &[f64],
    degree: usize,
    rotate: bool,
) -> DeformedSplats {
    let n = f.len();
    let per = 3 * ((degree + 1) * (degree + 1) - 1);
    let gaussians: Vec<DeformedGaussian> = f
        .par_iter()
        .zip(log_scales.par_iter().zip(rotations.par_iter()))
        .map(|(f, (s, q))| deform_gaussian(f, s, q))
        .collect();
    let sh = (rotate && per > 0).then(|| {
        let mut out = sh_rest.to_vec();
        out.par_chunks_mut(per)
            .zip(gaussians.par_iter())
            .for_each(|(c, g)| rotate_sh(&g.polar, degree, c));
        out
    });
    let mut result = DeformedSplats {
        log_scales: Vec::with_capacity(n),
        rotations: Vec::with_capacity(n),
        sh_rest: sh,
        clamped: 0,
    };
    for g in &gaussians {
        result.log_scales.push(g.log_scale);
        result.rotations.push(g.rotation);
        result.clamped += usize::from(g.clamped);
    }
    result
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rel_diff(a: &Mat3, b: &Mat3) -> f64 {
        let mut d = 0.0f64;
        let mut n = 0.0f64;
        for i in 0..3 {
            for j in 0..3 {
                d = d.max((a[i][j] - b[i][j]).abs());
                n = n.max(b[i][j].abs());
            }
        }
        d / n
    }

    fn push(f: &Mat3, c: &Mat3) -> Mat3 {
        mul(&mul(f, c), &transpose(f))
    }

    /// Uniform in [-1, 1) from the library's generator (this test moved to it from its own
    /// linear congruential one: other random inputs, the same checks).
    fn uniform(state: &mut crate::random::SplitMix64) -> f64 {
        state.uniform(-1.0, 1.0)
    }

    fn unit_quat(state: &mut crate::random::SplitMix64) -> [f64; 4] {
        let q = [
            uniform(state),
            uniform(state),
            uniform(state),
            uniform(state),
        ];
        let n = q.iter().map(|v| v * v).sum::<f64>().sqrt();
        q.map(|v| v / n)
    }

    #[test]
    fn rest_keeps_scales_and_rotation() {
        let id = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
        let mut st = crate::random::SplitMix64::new(7);
        for s in [
            [-3.0, -2.5, -4.0],
            [-2.0, -2.0, -5.0],
            [-1.0, -1.0, -1.0],
            [0.1, -3.0, 0.1],
        ] {
            for _ in 0..20 {
                let q = unit_quat(&mut st);
                let g = deform_gaussian(&id, &s, &q);
                for a in 0..3 {
                    assert!((g.log_scale[a] - s[a]).abs() < 1e-14, "{s:?} {g:?}");
                }
                for k in 0..4 {
                    assert!((g.rotation[k] - q[k]).abs() < 1e-14, "{q:?} {g:?}");
                }
            }
        }
    }

    #[test]
    fn rigid_motion_composes_rotation() {
        let mut st = crate::random::SplitMix64::new(11);
        let s = [-2.0, -3.0, -2.5];
        for _ in 0..20 {
            let q = unit_quat(&mut st);
            let rq = quat_to_matrix(&unit_quat(&mut st));
            let g = deform_gaussian(&rq, &s, &q);
            let want = mul(&rq, &quat_to_matrix(&q));
            assert!(rel_diff(&quat_to_matrix(&g.rotation), &want) < 1e-14);
            for a in 0..3 {
                assert!((g.log_scale[a] - s[a]).abs() < 1e-13);
            }
        }
    }

    #[test]
    fn covariance_is_pushed_forward_under_any_affine_map() {
        let mut st = crate::random::SplitMix64::new(3);
        for case in 0..500 {
            let q = unit_quat(&mut st);
            let s = [
                2.0 * uniform(&mut st) - 3.0,
                2.0 * uniform(&mut st) - 3.0,
                uniform(&mut st) - 3.0,
            ];
            let mut f = [[0.0; 3]; 3];
            for r in 0..3 {
                for c in 0..3 {
                    f[r][c] = 2.0 * uniform(&mut st) + if r == c { 1.0 } else { 0.0 };
                }
            }
            if case % 5 == 0 {
                // Inverted.
                f[0] = f[0].map(|v| -v);
            }
            let g = deform_gaussian(&f, &s, &q);
            let want = push(&f, &covariance(&s, &q));
            let got = covariance(&g.log_scale, &g.rotation);
            assert!(
                rel_diff(&got, &want) < 1e-12,
                "case {case}: {got:?} vs {want:?}"
            );
            let (lam, _) = sym_eig3(&got);
            assert!(lam.iter().all(|&l| l > 0.0));
            assert!((det3(&g.polar) - 1.0).abs() < 1e-12);
        }
    }

    #[test]
    fn singular_map_keeps_the_covariance_positive_definite() {
        let f = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 0.0]];
        let g = deform_gaussian(&f, &[-2.0, -2.0, -2.0], &[1.0, 0.0, 0.0, 0.0]);
        assert!(g.clamped);
        assert!(g.log_scale.iter().all(|s| s.is_finite()));
        let zero = deform_gaussian(&[[0.0; 3]; 3], &[-2.0; 3], &[1.0, 0.0, 0.0, 0.0]);
        assert!(zero.log_scale.iter().all(|s| s.is_finite()));
    }

    #[test]
    fn sample_matrices_are_well_conditioned() {
        let s = sh_samples();
        for l in 1..=3 {
            let worst = s.inverse[l - 1].iter().fold(0.0f64, |m, v| m.max(v.abs()));
            assert!(worst < 50.0, "degree {l}: max |P^-1| = {worst}");
        }
    }

    fn eval(l: usize, coeffs: &[f64], d: &[f64; 3]) -> f64 {
        let mut y = [0.0; 7];
        sh_basis(l, d, &mut y[..2 * l + 1]);
        y.iter().zip(coeffs).map(|(a, b)| a * b).sum()
    }

    #[test]
    fn sh_rotation_matches_evaluation_at_the_inverse_direction() {
        let mut st = crate::random::SplitMix64::new(5);
        for degree in 1..=3 {
            let k = (degree + 1) * (degree + 1) - 1;
            for _ in 0..20 {
                let r = quat_to_matrix(&unit_quat(&mut st));
                let c: Vec<f64> = (0..3 * k).map(|_| uniform(&mut st)).collect();
                let mut rc = c.clone();
                rotate_sh(&r, degree, &mut rc);
                for _ in 0..10 {
                    let v = [uniform(&mut st), uniform(&mut st), uniform(&mut st)];
                    let n = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
                    let d = v.map(|x| x / n);
                    let rt = transpose(&r);
                    let back = [
                        rt[0][0] * d[0] + rt[0][1] * d[1] + rt[0][2] * d[2],
                        rt[1][0] * d[0] + rt[1][1] * d[1] + rt[1][2] * d[2],
                        rt[2][0] * d[0] + rt[2][1] * d[1] + rt[2][2] * d[2],
                    ];
                    for ch in 0..3 {
                        for l in 1..=degree {
                            let off = ch * k + l * l - 1;
                            let n = 2 * l + 1;
                            let got = eval(l, &rc[off..off + n], &d);
                            let want = eval(l, &c[off..off + n], &back);
                            assert!((got - want).abs() < 1e-12, "l {l}: {got} vs {want}");
                        }
                    }
                }
            }
        }
    }

    #[test]
    fn sh_degree_one_follows_the_rotation_matrix() {
        // Degree 1 in the 3DGS basis is (-y, z, -x) up to C1: a coefficient vector
        // c = (-a_y, a_z, -a_x) stands for the linear function a . d, which a rotation maps to
        // (R a) . d.
        let r = quat_to_matrix(&[0.8, 0.2, -0.4, 0.4]);
        let a = [0.3, -0.7, 0.5];
        let mut c = vec![0.0; 9];
        c[..3].copy_from_slice(&[-a[1], a[2], -a[0]]);
        rotate_sh(&r, 1, &mut c);
        let ra = [
            r[0][0] * a[0] + r[0][1] * a[1] + r[0][2] * a[2],
            r[1][0] * a[0] + r[1][1] * a[1] + r[1][2] * a[2],
            r[2][0] * a[0] + r[2][1] * a[1] + r[2][2] * a[2],
        ];
        let want = [-ra[1], ra[2], -ra[0]];
        for k in 0..3 {
            assert!((c[k] - want[k]).abs() < 1e-14);
        }
    }
}
