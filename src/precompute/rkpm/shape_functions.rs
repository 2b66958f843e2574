//! Linear-reproducing RKPM shape functions in the shifted, scaled form (design.md section 2):
//!
//! ```text
//! q_k(X) = [1, (X - p_k) / a_ref],  M(X) = sum_k w_k q_k q_k^T,  b = M^-1 e_1,
//! phi_k(X) = w_k(X) q_k(X)^T b(X)
//! ```
//!
//! with analytic gradients (grad b = -M^-1 (grad M) b). `a_ref` is the mean support radius of
//! the kernels covering X; phi does not depend on it (it cancels exactly), it only keeps the
//! 4 x 4 moment matrix well scaled for objects of any size or unit.

use super::{covering_kernels, CoverPattern, Kernels};
use crate::Point3;
use rayon::prelude::*;

/// Settings of the shape-function evaluation.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ShapeFunctionOptions {
    /// Smallest acceptable reciprocal condition number (1-norm) of the scaled moment matrix.
    /// Default 1e-6: with the scaled basis a well-covered interior point measures ~1e-2 and a
    /// box corner ~1e-3; below 1e-6 the linear correction amplifies round-off by more than a
    /// million and the point is effectively covered by (nearly) coplanar kernels.
    pub min_rcond: f64,
}

impl Default for ShapeFunctionOptions {
    fn default() -> Self {
        Self { min_rcond: 1e-6 }
    }
}

/// Shape function values and gradients at N query points, sparse N x K (CSR by query point).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ShapeFunctions {
    /// Which kernels cover each point (row structure).
    pub pattern: CoverPattern,
    /// phi_k(X_i), aligned with `pattern.kernels` (dimensionless).
    pub phi: Vec<f64>,
    /// grad phi_k(X_i), aligned with `pattern.kernels`, 1/metres.
    pub grad: Vec<[f64; 3]>,
}

impl ShapeFunctions {
    /// Number of query points N.
    pub fn rows(&self) -> usize {
        self.pattern.rows()
    }
    /// Number of stored (point, kernel) pairs.
    pub fn nnz(&self) -> usize {
        self.pattern.nnz()
    }
    /// Bytes held by this structure.
    pub fn memory_bytes(&self) -> usize {
        self.pattern.ptr.len() * 8
            + self.pattern.kernels.len() * 4
            + self.phi.len() * 8
            + self.grad.len() * 24
    }
}

/// Quality figures of an evaluation.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize)]
pub struct ShapeStats {
    /// Smallest reciprocal condition number of a moment matrix over all points (0 if singular).
    pub min_rcond: f64,
    /// Point where it occurs.
    pub min_rcond_point: usize,
    /// Fewest covering kernels at any point.
    pub min_cover: usize,
    /// Most covering kernels at any point.
    pub max_cover: usize,
    /// Mean covering kernels per point.
    pub mean_cover: f64,
    /// Points that failed the conditioning check (indices, ascending).
    pub failed: Vec<usize>,
}

/// Per-point outcome: rcond (0 when singular).
struct PointResult {
    rcond: f64,
}

/// Evaluate phi and grad phi at every query point (N x 3, metres). Points whose moment matrix
/// is singular or worse than `opts.min_rcond` are listed in `ShapeStats::failed` and get zero
/// rows; use [`ShapeStats::failed`] (or the pipeline's coverage repair) before using the result.
pub fn evaluate(
    kernels: &Kernels,
    queries: &[Point3],
    opts: &ShapeFunctionOptions,
) -> (ShapeFunctions, ShapeStats) {
    evaluate_on(kernels, queries, covering_kernels(kernels, queries), opts)
}

/// [`evaluate`] with the covering pattern already found (by [`covering_kernels`] on the same
/// kernels and queries).
pub fn evaluate_on(
    kernels: &Kernels,
    queries: &[Point3],
    pattern: CoverPattern,
    opts: &ShapeFunctionOptions,
) -> (ShapeFunctions, ShapeStats) {
    let nnz = pattern.nnz();
    let mut phi = vec![0.0; nnz];
    let mut grad = vec![[0.0; 3]; nnz];
    // Split the output arrays into per-point slices so the points run in parallel.
    let results: Vec<PointResult> = {
        let mut phi_rows: Vec<&mut [f64]> = Vec::with_capacity(queries.len());
        let mut grad_rows: Vec<&mut [[f64; 3]]> = Vec::with_capacity(queries.len());
        let (mut prest, mut grest) = (&mut phi[..], &mut grad[..]);
        for i in 0..queries.len() {
            let n = pattern.ptr[i + 1] - pattern.ptr[i];
            let (p, pr) = prest.split_at_mut(n);
            let (g, gr) = grest.split_at_mut(n);
            phi_rows.push(p);
            grad_rows.push(g);
            prest = pr;
            grest = gr;
        }
        phi_rows
            .into_par_iter()
            .zip(grad_rows)
            .enumerate()
            .map(|(i, (prow, grow))| {
                point_shape(
                    kernels,
                    queries[i],
                    pattern.row(i),
                    opts.min_rcond,
                    prow,
                    grow,
                )
            })
            .collect()
    };
    let mut stats = ShapeStats {
        min_rcond: f64::INFINITY,
        min_cover: usize::MAX,
        ..Default::default()
    };
    for (i, r) in results.iter().enumerate() {
        let cover = pattern.ptr[i + 1] - pattern.ptr[i];
        stats.min_cover = stats.min_cover.min(cover);
        stats.max_cover = stats.max_cover.max(cover);
        if r.rcond < stats.min_rcond {
            stats.min_rcond = r.rcond;
            stats.min_rcond_point = i;
        }
        if r.rcond.is_nan() || r.rcond < opts.min_rcond {
            stats.failed.push(i);
        }
    }
    if queries.is_empty() {
        stats.min_rcond = 0.0;
        stats.min_cover = 0;
    }
    stats.mean_cover = if queries.is_empty() {
        0.0
    } else {
        nnz as f64 / queries.len() as f64
    };
    (ShapeFunctions { pattern, phi, grad }, stats)
}

/// Shape functions at one point. Returns the moment matrix's reciprocal condition number;
/// on failure the rows stay zero.
fn point_shape(
    kernels: &Kernels,
    x: Point3,
    row: &[u32],
    min_rcond: f64,
    phi: &mut [f64],
    grad: &mut [[f64; 3]],
) -> PointResult {
    let n = row.len();
    if n == 0 {
        return PointResult { rcond: 0.0 };
    }
    let a_ref = row.iter().map(|&k| kernels.radii[k as usize]).sum::<f64>() / n as f64;
    let inv_ref = 1.0 / a_ref;
    // Pass 1: window values and gradients, moment matrix and its gradient.
    let mut m = [[0.0f64; 4]; 4];
    let mut dm = [[[0.0f64; 4]; 4]; 3];
    // M and dM_j are symmetric: only their upper triangles (r <= c) are summed, and mirrored
    // after the loop. Each upper entry receives the same terms in the same order as when all
    // 16 were summed (q_r q_c = q_c q_r exactly), so the result is the same bit for bit.
    for (slot, &k) in row.iter().enumerate() {
        let (w, gw, q) = window(kernels, k as usize, x, inv_ref);
        for r in 0..4 {
            for c in r..4 {
                let qq = q[r] * q[c];
                m[r][c] += w * qq;
                for j in 0..3 {
                    dm[j][r][c] += gw[j] * qq;
                }
            }
        }
        // d q / d x_j = e_{j+1} / a_ref: adds w (e q^T + q e^T) / a_ref, whose upper entries
        // are (j + 1, c) for c >= j + 1 and (c, j + 1) for c <= j + 1 (the diagonal twice).
        for j in 0..3 {
            let e = j + 1;
            for c in 0..4 {
                let t = w * q[c] * inv_ref;
                if e <= c {
                    dm[j][e][c] += t;
                }
                if c <= e {
                    dm[j][c][e] += t;
                }
            }
        }
        // Stash w and gw in the output rows to avoid recomputing them in pass 2.
        phi[slot] = w;
        grad[slot] = gw;
    }
    for r in 1..4 {
        for c in 0..r {
            m[r][c] = m[c][r];
            for d in dm.iter_mut() {
                d[r][c] = d[c][r];
            }
        }
    }
    let Some(l) = cholesky4(&m) else {
        phi.fill(0.0);
        grad.fill([0.0; 3]);
        return PointResult { rcond: 0.0 };
    };
    let mut minv = [[0.0f64; 4]; 4];
    for c in 0..4 {
        let mut e = [0.0; 4];
        e[c] = 1.0;
        let col = solve4(&l, e);
        for r in 0..4 {
            minv[r][c] = col[r];
        }
    }
    let rcond = 1.0 / (norm1(&m) * norm1(&minv));
    if rcond.is_nan() || rcond < min_rcond {
        phi.fill(0.0);
        grad.fill([0.0; 3]);
        return PointResult {
            rcond: if rcond.is_finite() { rcond } else { 0.0 },
        };
    }
    let b = [minv[0][0], minv[1][0], minv[2][0], minv[3][0]];
    // grad b_j = -M^-1 (dM_j b)
    let mut db = [[0.0f64; 4]; 3];
    for j in 0..3 {
        let t = matvec4(&dm[j], &b);
        let s = matvec4(&minv, &t);
        for r in 0..4 {
            db[j][r] = -s[r];
        }
    }
    // Pass 2: phi_k = w q.b, grad phi_k = gw (q.b) + w b_{j+1} / a_ref + w q.db_j.
    for (slot, &k) in row.iter().enumerate() {
        let w = phi[slot];
        let gw = grad[slot];
        let p = kernels.centers[k as usize];
        let q = [
            1.0,
            (x[0] - p[0]) * inv_ref,
            (x[1] - p[1]) * inv_ref,
            (x[2] - p[2]) * inv_ref,
        ];
        let qb = dot4(&q, &b);
        phi[slot] = w * qb;
        for j in 0..3 {
            grad[slot][j] = gw[j] * qb + w * (b[j + 1] * inv_ref + dot4(&q, &db[j]));
        }
    }
    PointResult { rcond }
}

/// Window value, its gradient (1/metres) and the scaled basis q for kernel k at x.
#[inline]
fn window(kernels: &Kernels, k: usize, x: Point3, inv_ref: f64) -> (f64, [f64; 3], [f64; 4]) {
    let p = kernels.centers[k];
    let a = kernels.radii[k];
    let d = [x[0] - p[0], x[1] - p[1], x[2] - p[2]];
    let r = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
    let (w, wps) = kernels.kind.eval(r / a);
    let f = wps / (a * a);
    (
        w,
        [f * d[0], f * d[1], f * d[2]],
        [1.0, d[0] * inv_ref, d[1] * inv_ref, d[2] * inv_ref],
    )
}

#[inline]
fn dot4(a: &[f64; 4], b: &[f64; 4]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2] + a[3] * b[3]
}

#[inline]
fn matvec4(m: &[[f64; 4]; 4], v: &[f64; 4]) -> [f64; 4] {
    [
        dot4(&m[0], v),
        dot4(&m[1], v),
        dot4(&m[2], v),
        dot4(&m[3], v),
    ]
}

fn norm1(m: &[[f64; 4]; 4]) -> f64 {
    (0..4)
        .map(|c| (0..4).map(|r| m[r][c].abs()).sum::<f64>())
        .fold(0.0, f64::max)
}

/// Cholesky factor (lower) of a 4 x 4 SPD matrix; None if a pivot is not positive.
fn cholesky4(m: &[[f64; 4]; 4]) -> Option<[[f64; 4]; 4]> {
    let mut l = [[0.0f64; 4]; 4];
    for j in 0..4 {
        let mut d = m[j][j];
        for k in 0..j {
            d -= l[j][k] * l[j][k];
        }
        if d.is_nan() || d <= 0.0 {
            return None;
        }
        let djj = d.sqrt();
        l[j][j] = djj;
        for i in j + 1..4 {
            let mut s = m[i][j];
            for k in 0..j {
                s -= l[i][k] * l[j][k];
            }
            l[i][j] = s / djj;
        }
    }
    Some(l)
}

fn solve4(l: &[[f64; 4]; 4], mut b: [f64; 4]) -> [f64; 4] {
    for i in 0..4 {
        for k in 0..i {
            b[i] -= l[i][k] * b[k];
        }
        b[i] /= l[i][i];
    }
    for i in (0..4).rev() {
        for k in i + 1..4 {
            b[i] -= l[k][i] * b[k];
        }
        b[i] /= l[i][i];
    }
    b
}

/// Largest violation of the four reproducing identities over all query points, each made
/// dimensionless with the local support scale a_ref (the mean covering radius):
/// `partition_of_unity` = max |sum phi - 1|, `linear` = max |sum phi (p - X)| / a_ref,
/// `gradient_sum` = max |sum grad phi| a_ref, `gradient_linear` = max |sum grad phi (p - X)^T - I|.
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ReproducingError {
    /// max |sum_k phi_k - 1|.
    pub partition_of_unity: f64,
    /// max |sum_k phi_k (p_k - X)| / a_ref.
    pub linear: f64,
    /// max |sum_k grad phi_k| * a_ref.
    pub gradient_sum: f64,
    /// max over entries of |sum_k grad phi_k (p_k - X)^T - I|.
    pub gradient_linear: f64,
}

impl ReproducingError {
    /// The largest of the four figures.
    pub fn max(&self) -> f64 {
        self.partition_of_unity
            .max(self.linear)
            .max(self.gradient_sum)
            .max(self.gradient_linear)
    }
}

/// Check the reproducing identities of `sf` (evaluated at `queries`) to round-off. Rows of
/// points that failed the conditioning check (all zero) are skipped.
pub fn reproducing_error(
    kernels: &Kernels,
    queries: &[Point3],
    sf: &ShapeFunctions,
) -> ReproducingError {
    (0..sf.rows())
        .into_par_iter()
        .map(|i| {
            let (lo, hi) = (sf.pattern.ptr[i], sf.pattern.ptr[i + 1]);
            if hi == lo || sf.phi[lo..hi].iter().all(|&v| v == 0.0) {
                return ReproducingError::default();
            }
            let x = queries[i];
            let mut a_ref = 0.0;
            let mut sum = 0.0;
            let mut lin = [0.0; 3];
            let mut gsum = [0.0; 3];
            let mut glin = [[0.0; 3]; 3];
            for e in lo..hi {
                let k = sf.pattern.kernels[e] as usize;
                let p = kernels.centers[k];
                a_ref += kernels.radii[k];
                let d = [p[0] - x[0], p[1] - x[1], p[2] - x[2]];
                sum += sf.phi[e];
                for r in 0..3 {
                    lin[r] += sf.phi[e] * d[r];
                    gsum[r] += sf.grad[e][r];
                    for c in 0..3 {
                        glin[r][c] += sf.grad[e][r] * d[c];
                    }
                }
            }
            a_ref /= (hi - lo) as f64;
            let norm = |v: [f64; 3]| (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
            let mut gl = 0.0f64;
            for r in 0..3 {
                for c in 0..3 {
                    let id = if r == c { 1.0 } else { 0.0 };
                    gl = gl.max((glin[r][c] - id).abs());
                }
            }
            ReproducingError {
                partition_of_unity: (sum - 1.0).abs(),
                linear: norm(lin) / a_ref,
                gradient_sum: norm(gsum) * a_ref,
                gradient_linear: gl,
            }
        })
        .reduce(ReproducingError::default, |a, b| ReproducingError {
            partition_of_unity: a.partition_of_unity.max(b.partition_of_unity),
            linear: a.linear.max(b.linear),
            gradient_sum: a.gradient_sum.max(b.gradient_sum),
            gradient_linear: a.gradient_linear.max(b.gradient_linear),
        })
}
