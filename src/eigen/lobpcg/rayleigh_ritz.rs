//! The Rayleigh-Ritz step on the basis S = [X | P | W] and the construction of the next
//! conjugate block P (Duersch et al. 2018, orthogonal P variant).
//!
//! With the Gram matrices A = S^T H S and G = S^T M S (G ~ I because every block is
//! M-orthonormalized), the projected problem A c = theta G c is solved through
//! G = V diag(g) V^T: T = V_k g_k^-1/2 on the eigenvalues g above `drop * max(g)`, then
//! eig(T^T A T) = Z diag(theta) Z^T and C = T Z (G-orthonormal columns, ascending theta).
//! The smallest eigenvalue ratio min(g) / max(g) is returned so the caller can restart
//! without P when the basis is ill-conditioned.
//!
//! New P: the new X is S C_1 (the first nx Ritz vectors); the LOBPCG direction of column j is
//! the part of its coefficient vector outside the old X rows, z_j = [0; C_1(W and P rows, j)].
//! Expanded in the G-orthonormal Ritz basis, z_j = C_1 a_j + C_r b_j, and only C_r b_j adds
//! something to span(X_new). P = S C_r Q with Q an orthonormal basis of span{b_j} over the
//! active columns j, so P is M-orthonormal and M-orthogonal to X_new by construction.

use super::orthogonalize::Small;
use faer::Mat;

/// Preallocated small matrices of the Rayleigh-Ritz step (all nmax x nmax).
#[derive(Debug)]
pub(super) struct RrScratch {
    pub gsub: Mat<f64>,
    pub ritz: Mat<f64>,
    pub z: Mat<f64>,
    pub gz: Mat<f64>,
    pub b: Mat<f64>,
    pub q: Mat<f64>,
    pub cp: Mat<f64>,
    pub theta: Vec<f64>,
}

impl RrScratch {
    pub fn new(nmax: usize) -> Self {
        Self {
            gsub: Mat::zeros(nmax, nmax),
            ritz: Mat::zeros(nmax, nmax),
            z: Mat::zeros(nmax, nmax),
            gz: Mat::zeros(nmax, nmax),
            b: Mat::zeros(nmax, nmax),
            q: Mat::zeros(nmax, nmax),
            cp: Mat::zeros(nmax, nmax),
            theta: vec![0.0; nmax],
        }
    }
}

/// Outcome of [`solve_projected`].
#[derive(Debug, Clone, Copy)]
pub(super) enum Projected {
    /// `rank` Ritz pairs in `rr.theta[..rank]`, `rr.ritz[..n, ..rank]`; `g_ratio` =
    /// min(g) / max(g) of the Gram matrix of M.
    Ok { rank: usize, g_ratio: f64 },
    /// G has an eigenvalue below -`drop` * max(g): M is not positive definite on the basis.
    Indefinite { g_min: f64, g_max: f64 },
    /// The small eigensolver failed (non-convergence or non-finite values).
    Failed,
}

/// Solve the projected problem on the basis columns `idx` (indices into the full Gram matrices
/// `gram_h`, `gram_m`, both symmetric).
pub(super) fn solve_projected(
    gram_h: &Mat<f64>,
    gram_m: &Mat<f64>,
    idx: &[usize],
    drop: f64,
    small: &mut Small,
    rr: &mut RrScratch,
) -> Projected {
    let n = idx.len();
    let Small {
        g, a, t, c, eig, ..
    } = small;
    for (q, &j) in idx.iter().enumerate() {
        for (p, &i) in idx.iter().enumerate() {
            g[(p, q)] = gram_m[(i, j)];
            a[(p, q)] = gram_h[(i, j)];
        }
    }
    if !eig.compute(g.as_ref().submatrix(0, 0, n, n)) {
        return Projected::Failed;
    }
    let g_max = eig.values[n - 1];
    let g_min = eig.values[0];
    if g_max.is_nan() || g_max <= 0.0 || g_min < -drop.max(1e-12) * g_max {
        return Projected::Indefinite { g_min, g_max };
    }
    let first = (0..n).find(|&i| eig.values[i] > drop * g_max).unwrap_or(n);
    let r = n - first;
    for q in 0..r {
        let f = 1.0 / eig.values[first + q].sqrt();
        for p in 0..n {
            t[(p, q)] = eig.vectors[(p, first + q)] * f;
        }
    }
    // c = A T (n x r); a <- T^T c (r x r).
    {
        let tv = t.as_ref().submatrix(0, 0, n, r);
        faer::linalg::matmul::matmul(
            c.as_mut().submatrix_mut(0, 0, n, r),
            faer::Accum::Replace,
            a.as_ref().submatrix(0, 0, n, n),
            tv,
            1.0,
            faer::Par::Seq,
        );
        faer::linalg::matmul::matmul(
            a.as_mut().submatrix_mut(0, 0, r, r),
            faer::Accum::Replace,
            tv.transpose(),
            c.as_ref().submatrix(0, 0, n, r),
            1.0,
            faer::Par::Seq,
        );
    }
    super::workspace::symmetrize(a, r);
    if !eig.compute(a.as_ref().submatrix(0, 0, r, r)) {
        return Projected::Failed;
    }
    rr.theta[..r].copy_from_slice(&eig.values[..r]);
    faer::linalg::matmul::matmul(
        rr.ritz.as_mut().submatrix_mut(0, 0, n, r),
        faer::Accum::Replace,
        t.as_ref().submatrix(0, 0, n, r),
        eig.vectors.as_ref().submatrix(0, 0, r, r),
        1.0,
        faer::Par::Seq,
    );
    Projected::Ok {
        rank: r,
        g_ratio: if g_max > 0.0 { g_min / g_max } else { 0.0 },
    }
}

/// Coefficients (in the local `idx` coordinates, n rows) of the next P block for the active
/// columns, from the Ritz vectors of [`solve_projected`] (`rank` of them, the first `nx` being
/// the new X). X occupies local rows `0..nx`. Returns the number of P columns, stored in
/// `rr.cp[..n, ..np]`.
#[allow(clippy::too_many_arguments)]
pub(super) fn next_p(
    gram_m: &Mat<f64>,
    idx: &[usize],
    rank: usize,
    nx: usize,
    active: &[usize],
    drop: f64,
    small: &mut Small,
    rr: &mut RrScratch,
) -> usize {
    let n = idx.len();
    let na = active.len();
    let nr = rank.saturating_sub(nx);
    if na == 0 || nr == 0 || n <= nx {
        return 0;
    }
    for (q, &j) in idx.iter().enumerate() {
        for (p, &i) in idx.iter().enumerate() {
            rr.gsub[(p, q)] = gram_m[(i, j)];
        }
    }
    // z (n x na): the active Ritz columns with the X rows zeroed.
    for (col, &j) in active.iter().enumerate() {
        for p in 0..n {
            rr.z[(p, col)] = if p < nx { 0.0 } else { rr.ritz[(p, j)] };
        }
    }
    let seq = faer::Par::Seq;
    faer::linalg::matmul::matmul(
        rr.gz.as_mut().submatrix_mut(0, 0, n, na),
        faer::Accum::Replace,
        rr.gsub.as_ref().submatrix(0, 0, n, n),
        rr.z.as_ref().submatrix(0, 0, n, na),
        1.0,
        seq,
    );
    // b = C_r^T G z (nr x na).
    faer::linalg::matmul::matmul(
        rr.b.as_mut().submatrix_mut(0, 0, nr, na),
        faer::Accum::Replace,
        rr.ritz.as_ref().submatrix(0, nx, n, nr).transpose(),
        rr.gz.as_ref().submatrix(0, 0, n, na),
        1.0,
        seq,
    );
    // Orthonormal basis of span(b) by two rounds of scaled Gram eigen-orthonormalization.
    let mut cols = na;
    for round in 0..2 {
        let src = if round == 0 { &rr.b } else { &rr.q };
        let Small {
            g,
            a,
            t,
            keep,
            scale,
            eig,
            ..
        } = &mut *small;
        faer::linalg::matmul::matmul(
            g.as_mut().submatrix_mut(0, 0, cols, cols),
            faer::Accum::Replace,
            src.as_ref().submatrix(0, 0, nr, cols).transpose(),
            src.as_ref().submatrix(0, 0, nr, cols),
            1.0,
            seq,
        );
        keep.clear();
        for j in 0..cols {
            let d = g[(j, j)];
            if d.is_finite() && d > 0.0 {
                keep.push(j);
                scale[j] = 1.0 / d.sqrt();
            }
        }
        let nk = keep.len();
        if nk == 0 {
            return 0;
        }
        for (qq, &j) in keep.iter().enumerate() {
            for (pp, &i) in keep.iter().enumerate() {
                a[(pp, qq)] = g[(i, j)] * scale[i] * scale[j];
            }
        }
        if !eig.compute(a.as_ref().submatrix(0, 0, nk, nk)) {
            return 0;
        }
        let mu_max = eig.values[nk - 1];
        if mu_max.is_nan() || mu_max <= 0.0 {
            return 0;
        }
        let first = (0..nk)
            .find(|&i| eig.values[i] > drop * mu_max)
            .unwrap_or(nk);
        let r = nk - first;
        t.as_mut().submatrix_mut(0, 0, cols, r).fill(0.0);
        for qq in 0..r {
            let f = 1.0 / eig.values[first + qq].sqrt();
            for (pp, &i) in keep.iter().enumerate() {
                t[(i, qq)] = scale[i] * eig.vectors[(pp, first + qq)] * f;
            }
        }
        // new q = src t (nr x r); src may be q itself, so go through c.
        faer::linalg::matmul::matmul(
            small.c.as_mut().submatrix_mut(0, 0, nr, r),
            faer::Accum::Replace,
            src.as_ref().submatrix(0, 0, nr, cols),
            small.t.as_ref().submatrix(0, 0, cols, r),
            1.0,
            seq,
        );
        rr.q.as_mut()
            .submatrix_mut(0, 0, nr, r)
            .copy_from(small.c.as_ref().submatrix(0, 0, nr, r));
        cols = r;
    }
    // cp = C_r q (n x cols).
    faer::linalg::matmul::matmul(
        rr.cp.as_mut().submatrix_mut(0, 0, n, cols),
        faer::Accum::Replace,
        rr.ritz.as_ref().submatrix(0, nx, n, nr),
        rr.q.as_ref().submatrix(0, 0, nr, cols),
        1.0,
        seq,
    );
    cols
}
