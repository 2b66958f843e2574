//! Sparse assembly of the weight-space Hessian (Prop. 1) and the consistent RKPM mass matrix:
//!
//! ```text
//! (H_w)_kl = sum_i v_i (lambda_i + 4 mu_i) grad phi_k(X_i) . grad phi_l(X_i)     [Pa m]
//! M_kl     = sum_i v_i phi_k(X_i) phi_l(X_i)                                    [m^3]
//! ```
//!
//! Row-parallel Gustavson product over the kernel-to-point transpose of the shape functions:
//! each row's sum runs over points in ascending order, so the result is the same bit for bit
//! for any thread count, and exactly symmetric. Memory is proportional to the non-zeros.

use crate::rkpm::ShapeFunctions;
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

    let tasks: Vec<(Vec<usize>, Vec<usize>, Vec<f64>, Vec<f64>)> = (0..k.div_ceil(ROWS_PER_TASK))
        .into_par_iter()
        .map(|t| {
            let rows = t * ROWS_PER_TASK..((t + 1) * ROWS_PER_TASK).min(k);
            let mut acc_h = vec![0.0f64; k];
            let mut acc_m = vec![0.0f64; k];
            let mut seen = vec![false; k];
            let mut touched: Vec<usize> = Vec::new();
            let (mut counts, mut cols, mut hv, mut mv) =
                (Vec::new(), Vec::new(), Vec::new(), Vec::new());
            for _row in rows {
                let row = _row;
                for s in tptr[row]..tptr[row + 1] {
                    let p = tpoint[s] as usize;
                    let ei = tentry[s] as usize;
                    let (gi, fi) = (sf.grad[ei], sf.phi[ei]);
                    let wh = volumes[p] * weights[p];
                    let wm = volumes[p];
                    for e in sf.pattern.ptr[p]..sf.pattern.ptr[p + 1] {
                        let j = sf.pattern.kernels[e] as usize;
                        let gj = sf.grad[e];
                        if !seen[j] {
                            seen[j] = true;
                            touched.push(j);
                        }
                        acc_h[j] += wh * (gi[0] * gj[0] + gi[1] * gj[1] + gi[2] * gj[2]);
                        acc_m[j] += wm * (fi * sf.phi[e]);
                    }
                }
                touched.sort_unstable();
                counts.push(touched.len());
                for &j in &touched {
                    cols.push(j);
                    hv.push(acc_h[j]);
                    mv.push(acc_m[j]);
                    acc_h[j] = 0.0;
                    acc_m[j] = 0.0;
                    seen[j] = false;
                }
                touched.clear();
            }
            (counts, cols, hv, mv)
        })
        .collect();

    let nnz: usize = tasks.iter().map(|t| t.1.len()).sum();
    let mut ptr = Vec::with_capacity(k + 1);
    ptr.push(0);
    let (mut idx, mut hval, mut mval) = (
        Vec::with_capacity(nnz),
        Vec::with_capacity(nnz),
        Vec::with_capacity(nnz),
    );
    for (counts, cols, hv, mv) in tasks {
        for c in counts {
            let last = *ptr.last().unwrap_or(&0);
            ptr.push(last + c);
        }
        idx.extend_from_slice(&cols);
        hval.extend_from_slice(&hv);
        mval.extend_from_slice(&mv);
    }
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
