//! M-orthogonalization of a new block W: removal of the constant mode, SVQB (Stathopoulos &
//! Wu 2002; Duersch, Shao, Yang & Gu 2018) with a drop tolerance, and repeated projection
//! against the current basis [X | P] ("ortho" in Duersch et al.).
//!
//! All updates of W are mirrored on M W (and H W when present) through the same small
//! transforms, so no extra sparse product is needed; the drop tolerances bound how much these
//! implicit updates can amplify round-off.

use super::workspace::{
    inner, subtract_product, subtract_rank1, transform, Block, Partials, SmallEig, ROW_CHUNK,
};
use faer::Mat;
use rayon::prelude::*;

/// Small dense scratch shared by the orthogonalization and Rayleigh-Ritz steps, sized for the
/// largest basis (n x n with n = 3 x block size), plus the per-chunk partial products of the
/// K-long inner products.
#[derive(Debug)]
pub(super) struct Small {
    pub g: Mat<f64>,
    pub a: Mat<f64>,
    pub t: Mat<f64>,
    pub c: Mat<f64>,
    pub eig: SmallEig,
    pub keep: Vec<usize>,
    pub scale: Vec<f64>,
    pub parts: Partials,
    /// Set by [`svqb`] when the M-Gram matrix of a block has a clearly negative diagonal entry
    /// or eigenvalue (value relative to the largest): M is not positive definite.
    pub indefinite: Option<f64>,
}

impl Small {
    pub fn new(rows: usize, nmax: usize) -> Self {
        Self {
            g: Mat::zeros(nmax, nmax),
            a: Mat::zeros(nmax, nmax),
            t: Mat::zeros(nmax, nmax),
            c: Mat::zeros(nmax, nmax),
            eig: SmallEig::new(nmax),
            keep: Vec::with_capacity(nmax),
            scale: vec![0.0; nmax],
            parts: Partials::new(rows, nmax),
            indefinite: None,
        }
    }
}

/// W <- W - y0 (M y0)^T W for the columns `c0..c0 + w` of `s`: removes the component along the
/// constant mode in the M-inner product (y0^T M y0 = 1). `y0` and `my0` are K x 1 blocks.
pub(super) fn project_constant(
    s: &mut Block,
    c0: usize,
    w: usize,
    y0: &Block,
    my0: &Block,
    small: &mut Small,
) {
    if w == 0 {
        return;
    }
    let mut row = small.c.as_mut().submatrix_mut(0, 0, 1, w);
    inner(row.as_mut(), my0, 0, s, c0, &mut small.parts, false);
    for j in 0..w {
        small.scale[j] = row[(0, j)];
    }
    subtract_rank1(s, c0, &y0.data, &small.scale[..w]);
}

/// SVQB M-orthonormalization of columns `c0..c0 + w` of `s` with M S in `ms` (and H S in `hs`,
/// transformed alongside when given). With G = W^T M W and D = diag(G)^-1/2:
/// - columns with G_jj <= `col_drop` (absolute; used after a projection of unit columns, so it
///   is the squared norm fraction left) or non-finite are dropped;
/// - eig(D G D) = V diag(mu) V^T; eigenvalues mu <= `svqb_drop` * max(mu) are dropped;
/// - W <- W D V mu^-1/2 (M-orthonormal up to round-off amplified by 1/min(mu)).
///
/// Returns the number r of columns kept, now in `c0..c0 + r`. Returns 0 on a breakdown of the
/// small eigensolver.
#[allow(clippy::too_many_arguments)]
pub(super) fn svqb(
    s: &mut Block,
    ms: &mut Block,
    hs: Option<&mut Block>,
    c0: usize,
    w: usize,
    col_drop: f64,
    svqb_drop: f64,
    small: &mut Small,
) -> usize {
    if w == 0 {
        return 0;
    }
    let Small {
        g,
        a,
        t,
        keep,
        scale,
        eig,
        parts,
        indefinite,
        ..
    } = small;
    inner(
        g.as_mut().submatrix_mut(0, 0, w, w),
        s,
        c0,
        ms,
        c0,
        parts,
        false,
    );
    keep.clear();
    let dmax = (0..w).map(|j| g[(j, j)].abs()).fold(0.0f64, f64::max);
    for j in 0..w {
        let d = g[(j, j)];
        if d.is_finite() && d > col_drop && d > 0.0 {
            keep.push(j);
            scale[j] = 1.0 / d.sqrt();
        } else if d < -1e-10 * dmax {
            *indefinite = Some(d / dmax);
        }
    }
    let nk = keep.len();
    if nk == 0 {
        return 0;
    }
    for (q, &j) in keep.iter().enumerate() {
        for (p, &i) in keep.iter().enumerate() {
            a[(p, q)] = 0.5 * (g[(i, j)] + g[(j, i)]) * scale[i] * scale[j];
        }
    }
    if !eig.compute(a.as_ref().submatrix(0, 0, nk, nk)) {
        return 0;
    }
    let mu_max = eig.values[nk - 1];
    if mu_max.is_nan() || mu_max <= 0.0 {
        return 0;
    }
    if eig.values[0] < -1e-8 * mu_max {
        *indefinite = Some(eig.values[0] / mu_max);
    }
    // Eigenvalues ascending: keep the trailing ones above the threshold.
    let first = (0..nk)
        .find(|&i| eig.values[i] > svqb_drop * mu_max)
        .unwrap_or(nk);
    let r = nk - first;
    // t (w x r): rows of dropped columns are zero.
    t.as_mut().submatrix_mut(0, 0, w, r).fill(0.0);
    for q in 0..r {
        let f = 1.0 / eig.values[first + q].sqrt();
        for (p, &i) in keep.iter().enumerate() {
            t[(i, q)] = scale[i] * eig.vectors[(p, first + q)] * f;
        }
    }
    let tv = t.as_ref().submatrix(0, 0, w, r);
    transform(s, c0, tv, c0);
    transform(ms, c0, tv, c0);
    if let Some(hs) = hs {
        transform(hs, c0, tv, c0);
    }
    r
}

/// Make columns `w0..w0 + w` of `s` (W, with M W in `ms`) M-orthonormal and M-orthogonal to
/// columns `0..nb` (the basis B = [X | P], assumed M-orthonormal, with M B in `ms`).
///
/// Duersch et al.'s ortho: columns scaled to unit M-norm, then up to `passes` rounds of
/// W <- W - B (B^T M W) followed by SVQB. In the first round columns that lost all but a
/// fraction `ortho_drop` of their M-norm to the projection are dropped (what is left is
/// mostly round-off); later rounds are skipped once max |B^T M W| <= 1e-12.
/// Returns the number of columns kept (moved to the front of the W range).
#[allow(clippy::too_many_arguments)]
pub(super) fn ortho_against_basis(
    s: &mut Block,
    ms: &mut Block,
    nb: usize,
    w0: usize,
    w: usize,
    ortho_drop: f64,
    svqb_drop: f64,
    passes: usize,
    small: &mut Small,
) -> usize {
    if w == 0 {
        return 0;
    }
    // Unit M-norm columns first, so the squared norm left after the projection is the
    // fraction of the column outside span(B). (A diagonal scaling: linear dependence among
    // the W columns is left to the SVQB after the projection.)
    inner(
        small.g.as_mut().submatrix_mut(0, 0, w, w),
        s,
        w0,
        ms,
        w0,
        &mut small.parts,
        false,
    );
    for j in 0..w {
        let d = small.g[(j, j)];
        small.scale[j] = if d.is_finite() && d > 0.0 {
            1.0 / d.sqrt()
        } else {
            0.0
        };
    }
    scale_cols(&mut [&mut *s, &mut *ms], w0, &small.scale[..w]);
    let mut w = w;
    for pass in 0..passes {
        if w == 0 || nb == 0 {
            break;
        }
        inner(
            small.c.as_mut().submatrix_mut(0, 0, nb, w),
            s,
            0,
            ms,
            w0,
            &mut small.parts,
            false,
        );
        let c = small.c.as_ref().submatrix(0, 0, nb, w);
        let cmax = (0..w)
            .flat_map(|j| (0..nb).map(move |i| (i, j)))
            .fold(0.0f64, |m, (i, j)| m.max(c[(i, j)].abs()));
        if pass > 0 && cmax <= ORTHO_DONE {
            break;
        }
        subtract_product(s, c, w0);
        subtract_product(ms, c, w0);
        let col_drop = if pass == 0 {
            ortho_drop * ortho_drop
        } else {
            0.0
        };
        w = svqb(s, ms, None, w0, w, col_drop, svqb_drop, small);
    }
    w
}

/// Largest |B^T M W| entry (cosines: B and W have unit M-norm columns) at which the repeated
/// projection stops: ~10^4 eps, the level one projection reaches when W is not nearly inside
/// span(B).
const ORTHO_DONE: f64 = 1e-12;

/// Multiply column `c0 + j` of each block by `scale[j]`.
fn scale_cols(blocks: &mut [&mut Block], c0: usize, scale: &[f64]) {
    for b in blocks.iter_mut() {
        let ld = b.ld;
        b.data.par_chunks_mut(ld * ROW_CHUNK).for_each(|d| {
            for row in d.chunks_mut(ld) {
                for (x, f) in row[c0..c0 + scale.len()].iter_mut().zip(scale) {
                    *x *= f;
                }
            }
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn svqb_orthonormalizes() {
        let (k, w, ld) = (50, 4, 9);
        let mut s = Block::new(k, ld);
        let mut ms = Block::new(k, ld);
        let mut rng = crate::eigen::SplitMix64::new(3);
        for i in 0..k {
            for j in 0..w {
                s.data[i * ld + 2 + j] = rng.next_f64() - 0.5;
                ms.data[i * ld + 2 + j] = s.data[i * ld + 2 + j];
            }
        }
        let mut small = Small::new(k, ld);
        let r = svqb(&mut s, &mut ms, None, 2, w, 0.0, 1e-14, &mut small);
        assert_eq!(r, w);
        let g = s.cols(2, w).transpose() * ms.cols(2, w);
        let e = &g - Mat::<f64>::identity(w, w);
        assert!(e.norm_max() < 1e-13, "{g:?}");
    }
}
