//! M-orthogonalization of a new block W: removal of the constant mode, SVQB (Stathopoulos &
//! Wu 2002; Duersch, Shao, Yang & Gu 2018) with a drop tolerance, and repeated projection
//! against the current basis [X | P] ("ortho" in Duersch et al.).
//!
//! All updates of W are mirrored on M W (and H W when present) through the same small
//! transforms, so no extra sparse product is needed; the drop tolerances bound how much these
//! implicit updates can amplify round-off.

use super::workspace::{gemm, Block, SmallEig};
use faer::prelude::{Reborrow, ReborrowMut};
use faer::{Mat, MatRef, Par};

/// Small dense scratch shared by the orthogonalization and Rayleigh-Ritz steps, sized for the
/// largest basis (n x n with n = 3 x block size).
#[derive(Debug)]
pub(super) struct Small {
    pub g: Mat<f64>,
    pub a: Mat<f64>,
    pub t: Mat<f64>,
    pub c: Mat<f64>,
    pub eig: SmallEig,
    pub keep: Vec<usize>,
    pub scale: Vec<f64>,
}

impl Small {
    pub fn new(nmax: usize) -> Self {
        Self {
            g: Mat::zeros(nmax, nmax),
            a: Mat::zeros(nmax, nmax),
            t: Mat::zeros(nmax, nmax),
            c: Mat::zeros(nmax, nmax),
            eig: SmallEig::new(nmax),
            keep: Vec::with_capacity(nmax),
            scale: vec![0.0; nmax],
        }
    }
}

/// W <- W - y0 (M y0)^T W for the columns `c0..c0 + w` of `s`: removes the component along the
/// constant mode in the M-inner product (y0^T M y0 = 1). `y0` and `my0` are K x 1.
pub(super) fn project_constant(
    s: &mut Block,
    c0: usize,
    w: usize,
    y0: MatRef<'_, f64>,
    my0: MatRef<'_, f64>,
    coef: &mut Mat<f64>,
    par: Par,
) {
    if w == 0 {
        return;
    }
    let mut row = coef.as_mut().submatrix_mut(0, 0, 1, w);
    gemm(
        row.rb_mut(),
        false,
        my0.transpose(),
        s.cols(c0, w),
        1.0,
        par,
    );
    gemm(s.cols_mut(c0, w), true, y0, row.rb(), -1.0, par);
}

/// Apply the w x r transform `t` to columns `c0..c0 + w` of each block in `blocks`, in place:
/// columns `c0..c0 + r` become (old columns) * t. `tmp` must have at least r columns.
pub(super) fn transform_cols(
    blocks: &mut [&mut Block],
    c0: usize,
    w: usize,
    t: MatRef<'_, f64>,
    tmp: &mut Block,
    par: Par,
) {
    let r = t.ncols();
    for b in blocks.iter_mut() {
        gemm(tmp.cols_mut(0, r), false, b.cols(c0, w), t, 1.0, par);
        b.copy_cols_from(c0, tmp, 0, r);
    }
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
    tmp: &mut Block,
    par: Par,
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
        ..
    } = small;
    gemm(
        g.as_mut().submatrix_mut(0, 0, w, w),
        false,
        s.cols(c0, w).transpose(),
        ms.cols(c0, w),
        1.0,
        par,
    );
    keep.clear();
    for j in 0..w {
        let d = g[(j, j)];
        if d.is_finite() && d > col_drop && d > 0.0 {
            keep.push(j);
            scale[j] = 1.0 / d.sqrt();
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
    match hs {
        Some(hs) => transform_cols(&mut [s, ms, hs], c0, w, tv, tmp, par),
        None => transform_cols(&mut [s, ms], c0, w, tv, tmp, par),
    }
    r
}

/// Make columns `w0..w0 + w` of `s` (W, with M W in `ms`) M-orthonormal and M-orthogonal to
/// columns `0..nb` (the basis B = [X | P], assumed M-orthonormal, with M B in `ms`).
///
/// Duersch et al.'s ortho: an SVQB first (unit columns), then up to `passes` rounds of
/// W <- W - B (B^T M W) followed by SVQB. In the first round columns that lost all but a
/// fraction `ortho_drop` of their M-norm to the projection are dropped (what is left is
/// mostly round-off); rounds stop early once max |B^T M W| <= 1e-14 (already orthogonal).
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
    tmp: &mut Block,
    par: Par,
) -> usize {
    let mut w = svqb(s, ms, None, w0, w, 0.0, svqb_drop, small, tmp, par);
    for pass in 0..passes {
        if w == 0 || nb == 0 {
            break;
        }
        let mut c = small.c.as_mut().submatrix_mut(0, 0, nb, w);
        gemm(
            c.rb_mut(),
            false,
            s.cols(0, nb).transpose(),
            ms.cols(w0, w),
            1.0,
            par,
        );
        let mut cmax = 0.0f64;
        for j in 0..w {
            for i in 0..nb {
                cmax = cmax.max(c[(i, j)].abs());
            }
        }
        if pass > 0 && cmax <= 1e-14 {
            break;
        }
        let c = small.c.as_ref().submatrix(0, 0, nb, w);
        // s and ms are distinct blocks: subtract B C from W and (M B) C from M W. The W
        // columns do not overlap the basis columns (w0 >= nb), so each gemm reads columns
        // 0..nb and writes columns w0..w0 + w of the same buffer through a temporary.
        for blk in [&mut *s, &mut *ms] {
            gemm(tmp.cols_mut(0, w), false, blk.cols(0, nb), c, 1.0, par);
            subtract_cols(blk, w0, tmp, w);
        }
        let col_drop = if pass == 0 {
            ortho_drop * ortho_drop
        } else {
            0.0
        };
        w = svqb(s, ms, None, w0, w, col_drop, svqb_drop, small, tmp, par);
    }
    w
}

/// blk[:, c0..c0 + w] -= tmp[:, 0..w].
fn subtract_cols(blk: &mut Block, c0: usize, tmp: &Block, w: usize) {
    use super::workspace::ROW_CHUNK;
    use rayon::prelude::*;
    let (ld, tld) = (blk.ld, tmp.ld);
    blk.data
        .par_chunks_mut(ld * ROW_CHUNK)
        .zip(tmp.data.par_chunks(tld * ROW_CHUNK))
        .for_each(|(d, t)| {
            for (drow, trow) in d.chunks_mut(ld).zip(t.chunks(tld)) {
                for (x, y) in drow[c0..c0 + w].iter_mut().zip(&trow[..w]) {
                    *x -= *y;
                }
            }
        });
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
        let mut small = Small::new(ld);
        let mut tmp = Block::new(k, 6);
        let r = svqb(
            &mut s,
            &mut ms,
            None,
            2,
            w,
            0.0,
            1e-14,
            &mut small,
            &mut tmp,
            Par::Seq,
        );
        assert_eq!(r, w);
        let g = s.cols(2, w).transpose() * ms.cols(2, w);
        let e = &g - Mat::<f64>::identity(w, w);
        assert!(e.norm_max() < 1e-13, "{g:?}");
    }
}
