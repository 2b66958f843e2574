//! Sparse assembly of the weight-space Hessian (Prop. 1) and the consistent RKPM mass matrix:
//!
//! ```text
//! (H_w)_kl = sum_i v_i (lambda_i + 4 mu_i) grad phi_k(X_i) . grad phi_l(X_i)     [Pa m]
//! M_kl     = sum_i v_i phi_k(X_i) phi_l(X_i)                                    [m^3]
//! ```
//!
//! Row-parallel Gustavson product over the kernel-to-point transpose of the shape functions,
//! computing the upper triangle only and mirroring it: each entry's sum runs over points in
//! ascending order, so the result is the same bit for bit for any thread count, and exactly
//! symmetric. Memory is proportional to the non-zeros.

use super::rkpm::ShapeFunctions;
use crate::sparse::{from_compressed, SparseMatrix};
use crate::{Error, Result};
use rayon::prelude::*;

/// H_w and M, K x K, same sparsity pattern, both triangles stored.
#[derive(Debug, Clone)]
pub struct Assembled {
    /// Weight-space Hessian H_w, Pa m (units of E x length).
    pub hessian: SparseMatrix,
    /// Consistent mass matrix M, m^3 (density is not in it).
    pub mass: SparseMatrix,
}

/// Upper-triangle rows (columns j >= i) of a block of rows: per-row counts, then the
/// concatenated column indices and H and M values.
#[derive(Default)]
struct UpperRows {
    counts: Vec<usize>,
    cols: Vec<usize>,
    h: Vec<f64>,
    m: Vec<f64>,
}

/// Gustavson product for rows `rows` of the upper triangle: row i sums, over the points p in
/// kernel i's support (ascending), the contributions of the kernels j >= i covering p. Each
/// point's kernel list is sorted, so those start right at kernel i's own entry.
#[inline(never)]
#[allow(clippy::too_many_arguments)]
fn upper_rows(
    sf: &ShapeFunctions,
    volumes: &[f64],
    weights: &[f64],
    tptr: &[usize],
    tpoint: &[u32],
    tentry: &[u32],
    rows: std::ops::Range<usize>,
    k: usize,
) -> UpperRows {
    let mut acc_h = vec![0.0f64; k];
    let mut acc_m = vec![0.0f64; k];
    let mut seen = vec![false; k];
    let mut touched: Vec<usize> = Vec::new();
    let mut out = UpperRows::default();
    for row in rows {
        for s in tptr[row]..tptr[row + 1] {
            let p = tpoint[s] as usize;
            let ei = tentry[s] as usize;
            let (gi, fi) = (sf.grad[ei], sf.phi[ei]);
            let wh = volumes[p] * weights[p];
            let wm = volumes[p];
            let end = sf.pattern.ptr[p + 1];
            for ((&j, gj), &fj) in sf.pattern.kernels[ei..end]
                .iter()
                .zip(&sf.grad[ei..end])
                .zip(&sf.phi[ei..end])
            {
                let j = j as usize;
                if !seen[j] {
                    seen[j] = true;
                    touched.push(j);
                }
                acc_h[j] += wh * (gi[0] * gj[0] + gi[1] * gj[1] + gi[2] * gj[2]);
                acc_m[j] += wm * (fi * fj);
            }
        }
        touched.sort_unstable();
        out.counts.push(touched.len());
        for &j in &touched {
            out.cols.push(j);
            out.h.push(acc_h[j]);
            out.m.push(acc_m[j]);
            acc_h[j] = 0.0;
            acc_m[j] = 0.0;
            seen[j] = false;
        }
        touched.clear();
    }
    out
}

/// Full symmetric CSR (= CSC) arrays from upper-triangle rows: entry (i, j) with j > i is
/// also stored as (j, i) with the identical value, so the result is exactly symmetric.
/// Lower entries of a row come first (rows ascending), then its upper entries: columns stay
/// sorted.
#[inline(never)]
fn mirror(upper: &[UpperRows], k: usize) -> (Vec<usize>, Vec<usize>, Vec<f64>, Vec<f64>) {
    let mut count = vec![0usize; k];
    let mut row = 0;
    for block in upper {
        let mut at = 0;
        for &c in &block.counts {
            count[row] += c;
            for &j in &block.cols[at..at + c] {
                if j != row {
                    count[j] += 1;
                }
            }
            at += c;
            row += 1;
        }
    }
    let mut ptr = vec![0usize; k + 1];
    for i in 0..k {
        ptr[i + 1] = ptr[i] + count[i];
    }
    let nnz = ptr[k];
    let (mut idx, mut hv, mut mv) = (vec![0usize; nnz], vec![0.0; nnz], vec![0.0; nnz]);
    // Lower parts are filled from the front as rows are visited in ascending order, so each
    // row's lower entries end up sorted; its own upper entries go after them.
    let mut next = ptr.clone();
    let mut row = 0;
    for block in upper {
        let mut at = 0;
        for &c in &block.counts {
            for e in at..at + c {
                let j = block.cols[e];
                if j != row {
                    let d = next[j];
                    idx[d] = row;
                    hv[d] = block.h[e];
                    mv[d] = block.m[e];
                    next[j] += 1;
                }
            }
            at += c;
            row += 1;
        }
    }
    let mut row = 0;
    for block in upper {
        let mut at = 0;
        for &c in &block.counts {
            let d = next[row];
            idx[d..d + c].copy_from_slice(&block.cols[at..at + c]);
            hv[d..d + c].copy_from_slice(&block.h[at..at + c]);
            mv[d..d + c].copy_from_slice(&block.m[at..at + c]);
            at += c;
            row += 1;
        }
    }
    (ptr, idx, hv, mv)
}

/// Rows per parallel task: large enough to amortize the O(K) scratch, small enough to balance.
const ROWS_PER_TASK: usize = 128;

/// Assemble H_w and M from shape functions at N integration points with volumes `volumes`
/// (N, m^3) and Hessian weights `weights` (N, lambda + 4 mu, Pa). `k` is the kernel count.
pub fn assemble(
    sf: &ShapeFunctions,
    volumes: &[f64],
    weights: &[f64],
    k: usize,
) -> Result<Assembled> {
    let n = sf.rows();
    if volumes.len() != n {
        return Err(Error::LengthMismatch {
            what: "volumes",
            expected: n,
            got: volumes.len(),
        });
    }
    if weights.len() != n {
        return Err(Error::LengthMismatch {
            what: "hessian weights",
            expected: n,
            got: weights.len(),
        });
    }
    // Transpose: for each kernel, the (point, entry) pairs it covers, points ascending.
    let mut tptr = vec![0usize; k + 1];
    for &kk in &sf.pattern.kernels {
        tptr[kk as usize + 1] += 1;
    }
    for i in 0..k {
        tptr[i + 1] += tptr[i];
    }
    let mut fill = tptr.clone();
    let mut tpoint = vec![0u32; sf.nnz()];
    let mut tentry = vec![0u32; sf.nnz()];
    for p in 0..n {
        for e in sf.pattern.ptr[p]..sf.pattern.ptr[p + 1] {
            let kk = sf.pattern.kernels[e] as usize;
            tpoint[fill[kk]] = p as u32;
            tentry[fill[kk]] = e as u32;
            fill[kk] += 1;
        }
    }
    drop(fill);

    let upper: Vec<UpperRows> = (0..k.div_ceil(ROWS_PER_TASK))
        .into_par_iter()
        .map(|t| {
            let rows = t * ROWS_PER_TASK..((t + 1) * ROWS_PER_TASK).min(k);
            upper_rows(sf, volumes, weights, &tptr, &tpoint, &tentry, rows, k)
        })
        .collect();
    let (ptr, idx, hval, mval) = mirror(&upper, k);
    if let Some(bad) = hval.iter().chain(&mval).position(|v| !v.is_finite()) {
        return Err(Error::NonFinite {
            what: "assembled matrices (check volumes and material values)",
            index: bad,
        });
    }
    Ok(Assembled {
        hessian: from_compressed(k, ptr.clone(), idx.clone(), hval),
        mass: from_compressed(k, ptr, idx, mval),
    })
}
