//! Sparse matrix type shared by assembly and the eigensolvers, plus the hot kernels on it.
//!
//! H_w and M are symmetric, so they are stored with both triangles as faer CSC matrices; for a
//! symmetric matrix the CSC arrays are also its CSR arrays, so row-parallel kernels can walk
//! columns.
//!
//! Kernels:
//! - [`sym_mul_row_major`] / [`sym_mul_block`]: Y = A X for a tall dense block X (K x b), rayon
//!   parallel over rows. faer 0.24's sparse x dense product ignores its parallelism argument;
//!   this kernel is the one the eigensolvers use. The fast layout is **row-major** X and Y
//!   (each row of the block contiguous): every stored entry a_ij is read once and multiplies a
//!   contiguous row of b values. `benches/eigen.rs`, K = 10,648, 105 entries per row, b = 40:
//!   row-major 7.2 ms, column-major (same rayon split, one column at a time) 24.6 ms, faer's
//!   `sparse_dense_matmul` 42.5 ms.
//! - [`diagonal`], [`norm_1`], [`norm_2_estimate`], [`first_non_finite`],
//!   [`symmetry_defect`], [`add_scaled`].
//!
//! Every kernel is deterministic: each output row is computed by one task in a fixed order, and
//! reductions are done over fixed-size chunks combined in order, so results do not depend on the
//! number of threads.

use crate::simd::multiversion;
use faer::prelude::ReborrowMut;
use faer::sparse::{SparseColMat, SparseColMatRef, SymbolicSparseColMat};
use faer::{Mat, MatMut, MatRef};
use rayon::prelude::*;

/// A symmetric sparse matrix, K x K, both triangles stored, sorted row indices per column,
/// 32-bit column pointers and row indices (at most 2^32 - 1 stored entries; see
/// [`MAX_ENTRIES`]).
pub type SparseMatrix = SparseColMat<u32, f64>;

/// A borrowed view of a symmetric sparse matrix with [`SparseMatrix`]'s layout: what the
/// kernels and the eigensolvers take, so that matrices which share one stored pattern (the
/// assembled pencil, [`crate::precompute::Assembled`]) need not own a copy each.
/// `owned.as_ref()` views a [`SparseMatrix`].
pub type SparseMatrixRef<'a> = SparseColMatRef<'a, u32, f64>;

/// Most stored entries a [`SparseMatrix`] holds: its column pointers are u32. (A K = 1,000,000
/// RKPM pencil has 253M; the limit is ~17 times that.)
pub const MAX_ENTRIES: usize = u32::MAX as usize;

/// Rows handled by one rayon task in the row-parallel kernels. Fixed, so the split does not
/// depend on the thread count; 128 rows x ~200 entries keeps a task at ~25k multiply-adds
/// per column, far above rayon's scheduling overhead.
const ROWS_PER_TASK: usize = 128;

/// Build a [`SparseMatrix`] from compressed arrays (column pointers `ptr`, length n + 1; sorted
/// row indices `idx`; values `val`). Panics only on violated structural invariants, which
/// callers in this crate construct by design.
pub fn from_compressed(n: usize, ptr: Vec<u32>, idx: Vec<u32>, val: Vec<f64>) -> SparseMatrix {
    let symbolic = SymbolicSparseColMat::new_checked(n, n, ptr, None, idx);
    SparseColMat::new(symbolic, val)
}

/// Y = A X for symmetric `a` (K x K) and row-major dense blocks.
///
/// `x` holds K rows of stride `ldx` (row i of the block is `x[i * ldx..i * ldx + ncols]`), `y`
/// likewise with stride `ldy`; only the first `ncols` entries of each row of `y` are written.
/// To address a column sub-block of a wider row-major buffer, pass the buffer sliced from the
/// first column (`&buf[c0..]`). Rows are processed in parallel; each output row is summed in
/// stored order by a single task, so the result is bit-identical for any thread count.
///
/// # Panics
/// If `ncols > ldx`, `ncols > ldy`, or a slice is too short for K rows (caller bug).
pub fn sym_mul_row_major(
    a: SparseMatrixRef<'_>,
    x: &[f64],
    ldx: usize,
    y: &mut [f64],
    ldy: usize,
    ncols: usize,
) {
    let n = a.nrows();
    if n == 0 || ncols == 0 {
        return;
    }
    check_row_major("sym_mul_row_major", n, x.len(), ldx, y.len(), ldy, ncols);
    let sym = a.symbolic();
    let idx = sym.row_idx();
    let val = a.val();
    let y = &mut y[..(n - 1) * ldy + ncols];
    y.par_chunks_mut(ldy * ROWS_PER_TASK)
        .enumerate()
        .for_each(|(task, ychunk)| {
            let r0 = task * ROWS_PER_TASK;
            for (lr, yrow) in ychunk.chunks_mut(ldy).enumerate() {
                // Symmetric: column i of the CSC arrays is row i.
                let range = sym.col_range(r0 + lr);
                row_times_block(&idx[range.clone()], &val[range], x, ldx, &mut yrow[..ncols]);
            }
        });
}

multiversion! {
    /// yrow = sum_t val[t] x[idx[t] * ldx..][..yrow.len()] (one row of a sparse x block product).
    /// The columns go in groups of 16, 8, 4 and 1 whose sums stay in registers over the whole
    /// row (one store per output instead of one per stored entry); each output is still the
    /// sum from 0 in stored order, so the bits do not depend on the grouping.
    fn row_times_block(idx: &[u32], val: &[f64], x: &[f64], ldx: usize, yrow: &mut [f64]) {
        let ncols = yrow.len();
        let mut c0 = 0;
        while ncols - c0 >= 16 {
            columns_in_registers::<16>(idx, val, x, ldx, c0, &mut yrow[c0..c0 + 16]);
            c0 += 16;
        }
        if ncols - c0 >= 8 {
            columns_in_registers::<8>(idx, val, x, ldx, c0, &mut yrow[c0..c0 + 8]);
            c0 += 8;
        }
        if ncols - c0 >= 4 {
            columns_in_registers::<4>(idx, val, x, ldx, c0, &mut yrow[c0..c0 + 4]);
            c0 += 4;
        }
        while c0 < ncols {
            columns_in_registers::<1>(idx, val, x, ldx, c0, &mut yrow[c0..c0 + 1]);
            c0 += 1;
        }
    }
}

/// `data[start..start + W]` as an array, so loops over it have a length known at compile time
/// (the register-blocked kernels here and in the IC(0) sweep).
#[inline(always)]
pub(crate) fn fixed_row<const W: usize>(data: &[f64], start: usize) -> &[f64; W] {
    data[start..start + W]
        .try_into()
        .unwrap_or_else(|_| unreachable!("a slice of length W"))
}

/// y = sum_t val[t] x[idx[t] * ldx + c0..][..W], the W sums kept in registers.
#[inline(always)]
fn columns_in_registers<const W: usize>(
    idx: &[u32],
    val: &[f64],
    x: &[f64],
    ldx: usize,
    c0: usize,
    y: &mut [f64],
) {
    let mut acc = [0.0f64; W];
    for (&j, &aij) in idx.iter().zip(val) {
        let xrow = fixed_row::<W>(x, j as usize * ldx + c0);
        for (a, &xv) in acc.iter_mut().zip(xrow) {
            *a += aij * xv;
        }
    }
    y.copy_from_slice(&acc);
}

multiversion! {
    /// rowa = sum_t va[t] x[idx[t] * ldx..], rowb likewise with vb: two sparse rows with the
    /// same pattern times one block, in one pass; columns grouped as in [`row_times_block`].
    fn rows_pair_times_block(
        idx: &[u32],
        va: &[f64],
        vb: &[f64],
        x: &[f64],
        ldx: usize,
        rowa: &mut [f64],
        rowb: &mut [f64],
    ) {
        let ncols = rowa.len();
        let mut c0 = 0;
        while ncols - c0 >= 8 {
            pair_columns_in_registers::<8>(idx, va, vb, x, ldx, c0, rowa, rowb);
            c0 += 8;
        }
        if ncols - c0 >= 4 {
            pair_columns_in_registers::<4>(idx, va, vb, x, ldx, c0, rowa, rowb);
            c0 += 4;
        }
        while c0 < ncols {
            pair_columns_in_registers::<1>(idx, va, vb, x, ldx, c0, rowa, rowb);
            c0 += 1;
        }
    }
}

/// Columns `c0..c0 + W` of both rows of [`rows_pair_times_block`], the 2 W sums in registers.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn pair_columns_in_registers<const W: usize>(
    idx: &[u32],
    va: &[f64],
    vb: &[f64],
    x: &[f64],
    ldx: usize,
    c0: usize,
    rowa: &mut [f64],
    rowb: &mut [f64],
) {
    let (mut acc_a, mut acc_b) = ([0.0f64; W], [0.0f64; W]);
    for ((&j, &ai), &bi) in idx.iter().zip(va).zip(vb) {
        let xrow = fixed_row::<W>(x, j as usize * ldx + c0);
        for ((ua, ub), &xv) in acc_a.iter_mut().zip(acc_b.iter_mut()).zip(xrow) {
            *ua += ai * xv;
            *ub += bi * xv;
        }
    }
    rowa[c0..c0 + W].copy_from_slice(&acc_a);
    rowb[c0..c0 + W].copy_from_slice(&acc_b);
}

/// `true` if `a` and `b` have the same shape and identical stored patterns (column ranges and
/// row indices), so one pass over the indices can serve both (see
/// [`sym_mul_pair_row_major`]). O(nnz).
pub fn same_pattern(a: SparseMatrixRef<'_>, b: SparseMatrixRef<'_>) -> bool {
    let (sa, sb) = (a.symbolic(), b.symbolic());
    // Two views of one stored pattern (precompute::Assembled's H_w and M) are the same
    // without comparing 250M indices at K = 1,000,000.
    let one_pattern = std::ptr::eq(sa.col_ptr(), sb.col_ptr())
        && std::ptr::eq(sa.row_idx(), sb.row_idx())
        && sa.col_nnz().map(<[u32]>::as_ptr) == sb.col_nnz().map(<[u32]>::as_ptr);
    if one_pattern && a.nrows() == b.nrows() {
        return true;
    }
    a.nrows() == b.nrows()
        && a.ncols() == b.ncols()
        && (0..a.ncols()).all(|j| {
            let (ra, rb) = (sa.col_range(j), sb.col_range(j));
            sa.row_idx()[ra] == sb.row_idx()[rb]
        })
}

/// The layout checks of the row-major products (`n` >= 1 rows): strides of at least
/// `ncols`, and X and Y long enough for `n` rows.
///
/// # Panics
/// If a check fails (a caller bug), naming `what`.
fn check_row_major(
    what: &str,
    n: usize,
    x_len: usize,
    ldx: usize,
    y_len: usize,
    ldy: usize,
    ncols: usize,
) {
    assert!(
        ncols <= ldx && ncols <= ldy,
        "{what}: ncols exceeds a stride"
    );
    assert!(x_len >= (n - 1) * ldx + ncols, "{what}: x too short");
    assert!(y_len >= (n - 1) * ldy + ncols, "{what}: y too short");
}

/// YA = A X and YB = B X in one pass when A and B share their pattern (one read of the
/// indices and one gather of each X row feed both products); otherwise two calls of
/// [`sym_mul_row_major`]. Same layout rules and determinism as [`sym_mul_row_major`]. Checks
/// the patterns on every call (O(nnz)); [`SharedPattern`] checks them once for many products.
#[allow(clippy::too_many_arguments)]
pub fn sym_mul_pair_row_major(
    a: SparseMatrixRef<'_>,
    b: SparseMatrixRef<'_>,
    x: &[f64],
    ldx: usize,
    ya: &mut [f64],
    yb: &mut [f64],
    ldy: usize,
    ncols: usize,
) {
    match SharedPattern::new(a, b) {
        Some(pair) => pair.mul_row_major(x, ldx, ya, yb, ldy, ncols),
        None => {
            sym_mul_row_major(a, x, ldx, ya, ldy, ncols);
            sym_mul_row_major(b, x, ldx, yb, ldy, ncols);
        }
    }
}

/// Two symmetric matrices whose stored patterns were found identical once ([`same_pattern`]),
/// for fused products without checking again: the borrow keeps both unchanged while it
/// lives.
#[derive(Clone, Copy)]
pub struct SharedPattern<'m> {
    a: SparseMatrixRef<'m>,
    b: SparseMatrixRef<'m>,
}

impl<'m> SharedPattern<'m> {
    /// The pair, if `a` and `b` share their pattern (O(nnz) check); None otherwise.
    pub fn new(a: SparseMatrixRef<'m>, b: SparseMatrixRef<'m>) -> Option<SharedPattern<'m>> {
        same_pattern(a, b).then_some(SharedPattern { a, b })
    }

    /// YA = A X and YB = B X in one pass over the shared pattern (layout as
    /// [`sym_mul_row_major`]; the same bits as two separate products).
    ///
    /// # Panics
    /// If a stride is below `ncols` or a slice is too short (caller bug).
    #[allow(clippy::too_many_arguments)]
    pub fn mul_row_major(
        &self,
        x: &[f64],
        ldx: usize,
        ya: &mut [f64],
        yb: &mut [f64],
        ldy: usize,
        ncols: usize,
    ) {
        let (a, b) = (self.a, self.b);
        let n = a.nrows();
        if n == 0 || ncols == 0 {
            return;
        }
        let y_len = ya.len().min(yb.len());
        check_row_major("sym_mul_pair_row_major", n, x.len(), ldx, y_len, ldy, ncols);
        let sym = a.symbolic();
        let idx = sym.row_idx();
        let sb = b.symbolic();
        let (va, vb) = (a.val(), b.val());
        let len = (n - 1) * ldy + ncols;
        ya[..len]
            .par_chunks_mut(ldy * ROWS_PER_TASK)
            .zip(yb[..len].par_chunks_mut(ldy * ROWS_PER_TASK))
            .enumerate()
            .for_each(|(task, (ca, cb))| {
                let r0 = task * ROWS_PER_TASK;
                for (lr, (rowa, rowb)) in ca.chunks_mut(ldy).zip(cb.chunks_mut(ldy)).enumerate() {
                    let i = r0 + lr;
                    let range = sym.col_range(i);
                    let rb = sb.col_range(i);
                    rows_pair_times_block(
                        &idx[range.clone()],
                        &va[range],
                        &vb[rb],
                        x,
                        ldx,
                        &mut rowa[..ncols],
                        &mut rowb[..ncols],
                    );
                }
            });
    }
}

/// Y = A X for symmetric `a` (K x K) and any dense layout of X, Y (K x b).
///
/// Row-major views (column stride 1) go straight to [`sym_mul_row_major`]; column-major views
/// use a row-chunked kernel that sums each column over a chunk of rows; other layouts are
/// copied through a row-major temporary. Deterministic for any thread count.
///
/// # Panics
/// If the shapes do not match (caller bug).
pub fn sym_mul_block(a: SparseMatrixRef<'_>, x: MatRef<'_, f64>, y: MatMut<'_, f64>) {
    let n = a.nrows();
    assert!(
        a.ncols() == n && x.nrows() == n && y.nrows() == n && x.ncols() == y.ncols(),
        "sym_mul_block: shape mismatch"
    );
    let b = x.ncols();
    if n == 0 || b == 0 {
        return;
    }
    let sym = a.symbolic();
    let idx = sym.row_idx();
    let val = a.val();
    if x.row_stride() == 1 && y.row_stride() == 1 {
        // Column-major: for each chunk of rows, each column in turn.
        let mut y = y;
        y.rb_mut()
            .par_row_chunks_mut(ROWS_PER_TASK)
            .enumerate()
            .for_each(|(task, mut ychunk)| {
                let r0 = task * ROWS_PER_TASK;
                for c in 0..b {
                    let xcol = x.col(c);
                    let mut ycol = ychunk.rb_mut().col_mut(c);
                    for lr in 0..ycol.nrows() {
                        let range = sym.col_range(r0 + lr);
                        let mut acc = 0.0;
                        for (&j, &aij) in idx[range.clone()].iter().zip(&val[range]) {
                            acc += aij * xcol[j as usize];
                        }
                        ycol[lr] = acc;
                    }
                }
            });
        return;
    }
    if let (Some(xr), true) = (
        x.try_as_row_major(),
        y.col_stride() == 1 && y.row_stride() >= 0,
    ) {
        if xr.row_stride() >= 0 && x.nrows() > 0 {
            // Contiguous rows with non-negative strides: view the storage as slices.
            let ldx = xr.row_stride().unsigned_abs();
            let ldy = y.row_stride().unsigned_abs();
            if ldx >= b && ldy >= b {
                let xs = row_major_slice(xr.as_dyn_stride(), ldx);
                let mut y = y;
                let ys = row_major_slice_mut(y.rb_mut(), ldy);
                sym_mul_row_major(a, xs, ldx, ys, ldy, b);
                return;
            }
        }
    }
    // Fallback: through a row-major copy.
    let mut xt = vec![0.0; n * b];
    for i in 0..n {
        for c in 0..b {
            xt[i * b + c] = x[(i, c)];
        }
    }
    let mut yt = vec![0.0; n * b];
    sym_mul_row_major(a, &xt, b, &mut yt, b, b);
    let mut y = y;
    for i in 0..n {
        for c in 0..b {
            y[(i, c)] = yt[i * b + c];
        }
    }
}

/// The storage of a row-major view (column stride 1, row stride `ld` >= ncols) as a slice of
/// length (nrows - 1) * ld + ncols.
fn row_major_slice(x: MatRef<'_, f64>, ld: usize) -> &[f64] {
    let len = (x.nrows() - 1) * ld + x.ncols();
    // SAFETY: the view has column stride 1 and row stride `ld` >= ncols >= 1 (checked by the
    // caller), so elements (i, c) for i < nrows, c < ncols live at offsets i * ld + c, all
    // below `len`, inside one allocation that outlives the view; the gaps between rows belong
    // to the same allocation (a faer view never spans two allocations).
    unsafe { std::slice::from_raw_parts(x.as_ptr(), len) }
}

/// Mutable counterpart of [`row_major_slice`].
fn row_major_slice_mut(y: MatMut<'_, f64>, ld: usize) -> &mut [f64] {
    let len = (y.nrows() - 1) * ld + y.ncols();
    // SAFETY: as in `row_major_slice`; the mutable view grants exclusive access to its
    // elements. The gap entries between rows (columns >= ncols) are not written by
    // `sym_mul_row_major`, which only touches the first ncols entries of each row.
    unsafe { std::slice::from_raw_parts_mut(y.as_ptr_mut(), len) }
}

/// Diagonal of `a` (length K; absent entries are 0).
pub fn diagonal(a: SparseMatrixRef<'_>) -> Vec<f64> {
    let n = a.ncols();
    let sym = a.symbolic();
    let idx = sym.row_idx();
    let val = a.val();
    (0..n)
        .map(|j| {
            let range = sym.col_range(j);
            idx[range.clone()]
                .iter()
                .zip(&val[range])
                .filter(|(&i, _)| i as usize == j)
                .map(|(_, &v)| v)
                .sum()
        })
        .collect()
}

/// Trace of `a` (sum of the diagonal).
pub fn trace(a: SparseMatrixRef<'_>) -> f64 {
    diagonal(a).iter().sum()
}

/// ||A||_1 = max over columns of the sum of |a_ij|. For a symmetric matrix this equals
/// ||A||_inf and bounds the spectral norm from above: ||A||_2 <= sqrt(||A||_1 ||A||_inf) =
/// ||A||_1. For Laplacian-like and mass-like matrices it is within a small factor (<= ~2) of
/// ||A||_2. Exact and cheap (one pass over the values), so the residual norms built on it are
/// reproducible.
pub fn norm_1(a: SparseMatrixRef<'_>) -> f64 {
    let sym = a.symbolic();
    let val = a.val();
    (0..a.ncols())
        .into_par_iter()
        .with_min_len(ROWS_PER_TASK)
        .map(|j| val[sym.col_range(j)].iter().map(|v| v.abs()).sum::<f64>())
        .reduce(|| 0.0, f64::max)
}

/// Estimate of ||A||_2 = max |eigenvalue| of symmetric `a` by `iters` power iterations from a
/// fixed, deterministic start vector (a lower bound that approaches ||A||_2 from below; 20-30
/// iterations give 1-2 correct digits for the matrices of this crate). Returns 0 for an empty
/// or zero matrix.
pub fn norm_2_estimate(a: SparseMatrixRef<'_>, iters: usize) -> f64 {
    let n = a.nrows();
    if n == 0 {
        return 0.0;
    }
    // Deterministic start with components in every direction: 1 + small pseudo-random part.
    let mut rng = crate::random::SplitMix64::new(0x2545_f491_4f6c_dd1d);
    let mut x: Vec<f64> = (0..n).map(|_| rng.uniform(0.5, 1.5)).collect();
    let mut y = vec![0.0; n];
    let mut estimate = 0.0;
    for _ in 0..iters.max(1) {
        let nx = norm2(&x);
        if nx == 0.0 || !nx.is_finite() {
            return estimate;
        }
        x.iter_mut().for_each(|v| *v /= nx);
        sym_mul_row_major(a, &x, 1, &mut y, 1, 1);
        estimate = norm2(&y);
        std::mem::swap(&mut x, &mut y);
    }
    estimate
}

/// Euclidean norm of a slice, summed in fixed-size chunks combined in order (deterministic).
pub fn norm2(x: &[f64]) -> f64 {
    // Scale-free accumulation is unnecessary here: entries are O(1) after normalization in
    // every caller, and squares of f64 in [1e-150, 1e150] do not under/overflow.
    x.par_chunks(4096)
        .map(|c| c.iter().map(|v| v * v).sum::<f64>())
        .collect::<Vec<_>>()
        .iter()
        .sum::<f64>()
        .sqrt()
}

/// First stored entry that is NaN or infinite, as (row, column), or `None`.
pub fn first_non_finite(a: SparseMatrixRef<'_>) -> Option<(usize, usize)> {
    let sym = a.symbolic();
    let idx = sym.row_idx();
    let val = a.val();
    (0..a.ncols()).find_map(|j| {
        let range = sym.col_range(j);
        idx[range.clone()]
            .iter()
            .zip(&val[range])
            .find(|(_, v)| !v.is_finite())
            .map(|(&i, _)| (i as usize, j))
    })
}

/// Neumaier's compensated sum (error ~ eps |sum| + n eps^2 sum |x|, independent of the length
/// to first order), in iteration order: deterministic.
pub fn compensated_sum(values: impl Iterator<Item = f64>) -> f64 {
    let (mut sum, mut comp) = (0.0f64, 0.0f64);
    for v in values {
        let t = sum + v;
        comp += if sum.abs() >= v.abs() {
            (sum - t) + v
        } else {
            (v - t) + sum
        };
        sum = t;
    }
    sum + comp
}

/// Sorted (row index, value) pairs of column j, duplicates summed (handles unsorted input).
pub(crate) fn sorted_column(a: SparseMatrixRef<'_>, j: usize, out: &mut Vec<(usize, f64)>) {
    let sym = a.symbolic();
    let range = sym.col_range(j);
    out.clear();
    out.extend(
        sym.row_idx()[range.clone()]
            .iter()
            .map(|&i| i as usize)
            .zip(a.val()[range].iter().copied()),
    );
    if !out.windows(2).all(|w| w[0].0 < w[1].0) {
        out.sort_by_key(|p| p.0);
        out.dedup_by(|next, kept| {
            if next.0 == kept.0 {
                kept.1 += next.1;
                true
            } else {
                false
            }
        });
    }
}

/// max |a_ij - a_ji| over all stored entries (0 for an exactly symmetric matrix); an entry
/// whose mirror is not stored counts as |a_ij|. Non-square input returns +inf. O(nnz) time;
/// with sorted columns (every matrix built by [`from_compressed`] or faer's checked
/// constructors) the only extra memory is one cursor per column, otherwise the transpose is
/// built by a counting sort (O(nnz) memory).
pub fn symmetry_defect(a: SparseMatrixRef<'_>) -> f64 {
    let n = a.nrows();
    if a.ncols() != n {
        return f64::INFINITY;
    }
    let sym = a.symbolic();
    let idx = sym.row_idx();
    let sorted = (0..n)
        .into_par_iter()
        .all(|j| idx[sym.col_range(j)].windows(2).all(|w| w[0] < w[1]));
    if sorted {
        symmetry_defect_sorted(a)
    } else {
        symmetry_defect_by_transpose(a)
    }
}

/// [`symmetry_defect`] for strictly sorted columns, by one walk with a cursor per column.
///
/// Columns are visited in order. A lower entry a_rj (r > j) of column j has its mirror a_jr in
/// the upper part of column r; the upper entries of column r are met in increasing row order
/// as j grows, so `cursor[r]` walks them once: entries it passes over without a match have no
/// mirror, and so do those left above the diagonal at the end.
fn symmetry_defect_sorted(a: SparseMatrixRef<'_>) -> f64 {
    let n = a.nrows();
    let sym = a.symbolic();
    let idx = sym.row_idx();
    let val = a.val();
    let mut cursor: Vec<usize> = (0..n).map(|j| sym.col_range(j).start).collect();
    let mut defect = 0.0f64;
    for j in 0..n {
        let range = sym.col_range(j);
        for (&r, &v) in idx[range.clone()].iter().zip(&val[range]) {
            let r = r as usize;
            if r <= j {
                continue;
            }
            let end = sym.col_range(r).end;
            let mut p = cursor[r];
            while p < end && (idx[p] as usize) < j {
                defect = defect.max(val[p].abs());
                p += 1;
            }
            if p < end && idx[p] as usize == j {
                defect = defect.max((v - val[p]).abs());
                p += 1;
            } else {
                defect = defect.max(v.abs());
            }
            cursor[r] = p;
        }
    }
    for (r, &start) in cursor.iter().enumerate() {
        let end = sym.col_range(r).end;
        for p in start..end {
            if idx[p] as usize >= r {
                break;
            }
            defect = defect.max(val[p].abs());
        }
    }
    defect
}

/// [`symmetry_defect`] for any column order: builds the transpose by a counting sort and
/// merges each column with its mirror.
fn symmetry_defect_by_transpose(a: SparseMatrixRef<'_>) -> f64 {
    let n = a.nrows();
    // Transpose by counting sort: column j of the transpose lists row j of `a` in
    // increasing column order, hence sorted.
    let sym = a.symbolic();
    let idx = sym.row_idx();
    let val = a.val();
    let mut count = vec![0usize; n + 1];
    for j in 0..n {
        for &i in &idx[sym.col_range(j)] {
            count[i as usize + 1] += 1;
        }
    }
    for i in 0..n {
        count[i + 1] += count[i];
    }
    let nnz = count[n];
    let mut t_idx = vec![0usize; nnz];
    let mut t_val = vec![0.0; nnz];
    let mut next = count.clone();
    for j in 0..n {
        let range = sym.col_range(j);
        for (&i, &v) in idx[range.clone()].iter().zip(&val[range]) {
            let i = i as usize;
            t_idx[next[i]] = j;
            t_val[next[i]] = v;
            next[i] += 1;
        }
    }
    let mut col = Vec::new();
    let mut tcol: Vec<(usize, f64)> = Vec::new();
    let mut defect = 0.0f64;
    for j in 0..n {
        sorted_column(a, j, &mut col);
        tcol.clear();
        tcol.extend(
            t_idx[count[j]..count[j + 1]]
                .iter()
                .copied()
                .zip(t_val[count[j]..count[j + 1]].iter().copied()),
        );
        tcol.dedup_by(|next, kept| {
            if next.0 == kept.0 {
                kept.1 += next.1;
                true
            } else {
                false
            }
        });
        // Merge the two sorted lists.
        let (mut p, mut q) = (0, 0);
        while p < col.len() || q < tcol.len() {
            let d = match (col.get(p), tcol.get(q)) {
                (Some(&(i, v)), Some(&(k, w))) if i == k => {
                    p += 1;
                    q += 1;
                    v - w
                }
                (Some(&(i, v)), Some(&(k, _))) if i < k => {
                    p += 1;
                    v
                }
                (Some(&(_, v)), None) => {
                    p += 1;
                    v
                }
                (_, Some(&(_, w))) => {
                    q += 1;
                    w
                }
                (None, None) => 0.0,
            };
            defect = defect.max(d.abs());
        }
    }
    defect
}

/// alpha A + beta B for two K x K sparse matrices (patterns may differ: the result has the
/// union pattern, sorted, duplicates summed). Used to form H + sigma M for the preconditioner.
///
/// # Panics
/// If the shapes differ, or the union holds more than [`MAX_ENTRIES`] entries (caller bugs:
/// callers bound nnz(A) + nnz(B) first).
pub fn add_scaled(
    alpha: f64,
    a: SparseMatrixRef<'_>,
    beta: f64,
    b: SparseMatrixRef<'_>,
) -> SparseMatrix {
    assert!(
        a.nrows() == b.nrows() && a.ncols() == b.ncols(),
        "add_scaled: shape mismatch"
    );
    let (nrows, ncols) = (a.nrows(), a.ncols());
    let mut ptr = Vec::with_capacity(ncols + 1);
    let cap = a.val().len().max(b.val().len());
    let mut idx = Vec::with_capacity(cap);
    let mut val = Vec::with_capacity(cap);
    ptr.push(0);
    let (mut ca, mut cb, mut merged) = (Vec::new(), Vec::new(), Vec::new());
    for j in 0..ncols {
        sorted_column(a, j, &mut ca);
        sorted_column(b, j, &mut cb);
        merged.clear();
        merge_scaled(alpha, &ca, beta, &cb, &mut merged);
        // Row indices are below nrows, which a SparseMatrix's u32 indices address.
        idx.extend(merged.iter().map(|&(i, _)| i as u32));
        val.extend(merged.iter().map(|&(_, v)| v));
        ptr.push(u32::try_from(idx.len()).expect("add_scaled: more than MAX_ENTRIES entries"));
    }
    let symbolic = SymbolicSparseColMat::new_checked(nrows, ncols, ptr, None, idx);
    SparseColMat::new(symbolic, val)
}

/// alpha a + beta b for two sorted, duplicate-free (index, value) lists (columns from
/// [`sorted_column`]), appended to `out` in index order over the union of their indices: an
/// index in one list only gives that list's term alone.
pub(crate) fn merge_scaled(
    alpha: f64,
    a: &[(usize, f64)],
    beta: f64,
    b: &[(usize, f64)],
    out: &mut Vec<(usize, f64)>,
) {
    let (mut p, mut q) = (0, 0);
    loop {
        let entry = match (a.get(p), b.get(q)) {
            (Some(&(i, v)), Some(&(k, w))) if i == k => {
                p += 1;
                q += 1;
                (i, alpha * v + beta * w)
            }
            (Some(&(i, v)), Some(&(k, _))) if i < k => {
                p += 1;
                (i, alpha * v)
            }
            (Some(&(i, v)), None) => {
                p += 1;
                (i, alpha * v)
            }
            (_, Some(&(k, w))) => {
                q += 1;
                (k, beta * w)
            }
            (None, None) => return,
        };
        out.push(entry);
    }
}

/// Dense copy of `a` (K x K). For the dense reference solver and tests only.
pub fn to_dense(a: SparseMatrixRef<'_>) -> Mat<f64> {
    a.to_dense()
}

#[cfg(test)]
mod tests {
    use super::*;
    use faer::sparse::Triplet;

    /// A triplet of a SparseMatrix (u32 indices) from usize indices.
    fn tri(i: usize, j: usize, v: f64) -> Triplet<u32, u32, f64> {
        Triplet::new(i as u32, j as u32, v)
    }

    /// A small symmetric test matrix: 1D Laplacian-like with a random-ish diagonal.
    fn small(n: usize) -> SparseMatrix {
        let mut t = Vec::new();
        for i in 0..n {
            t.push(tri(i, i, 2.0 + (i % 7) as f64 * 0.25));
            if i + 1 < n {
                t.push(tri(i, i + 1, -1.0 + 0.01 * i as f64));
                t.push(tri(i + 1, i, -1.0 + 0.01 * i as f64));
            }
            if i + 5 < n {
                t.push(tri(i, i + 5, 0.3));
                t.push(tri(i + 5, i, 0.3));
            }
        }
        SparseMatrix::try_new_from_triplets(n, n, &t).unwrap()
    }

    #[test]
    fn block_product_matches_dense_in_every_layout() {
        let n = 300;
        let a = small(n);
        let ad = to_dense(a.as_ref());
        let b = 7;
        let x = Mat::from_fn(n, b, |i, j| ((i * 31 + j * 17) % 13) as f64 - 6.0);
        let reference = &ad * &x;
        // Column-major.
        let mut y = Mat::zeros(n, b);
        sym_mul_block(a.as_ref(), x.as_ref(), y.as_mut());
        // Integer-valued inputs: the products are exact sums of small integers times the
        // matrix values, so the only difference is summation order (~1e-14 relative).
        assert!((&y - &reference).norm_max() < 1e-12);
        // Row-major (transpose of a column-major b x n matrix).
        let xt = x.transpose().to_owned();
        let mut yt = Mat::<f64>::zeros(b, n);
        sym_mul_block(
            a.as_ref(),
            xt.as_ref().transpose(),
            yt.as_mut().transpose_mut(),
        );
        assert!((yt.transpose() - &reference).norm_max() < 1e-12);
        // Strided row-major sub-block of a wider buffer via the slice kernel.
        let ld = 11;
        let mut xs = vec![0.0; n * ld];
        for i in 0..n {
            for c in 0..b {
                xs[i * ld + 2 + c] = x[(i, c)];
            }
        }
        let mut ys = vec![-7.0; n * ld];
        sym_mul_row_major(a.as_ref(), &xs[2..], ld, &mut ys[3..], ld, b);
        for i in 0..n {
            for c in 0..b {
                assert!((ys[i * ld + 3 + c] - reference[(i, c)]).abs() < 1e-12);
            }
            // Entries outside the sub-block untouched.
            assert_eq!(ys[i * ld], -7.0);
        }
        // Reversed rows (row stride -1) go through the generic fallback.
        let mut y2 = Mat::zeros(n, b);
        sym_mul_block(a.as_ref(), x.as_ref().reverse_rows(), y2.as_mut());
        let expected = &ad * x.as_ref().reverse_rows();
        assert!((&y2 - &expected).norm_max() < 1e-12);
    }

    #[test]
    fn pair_product_matches_single_products() {
        let n = 257;
        let a = small(n);
        let mut b = a.clone();
        b.val_mut()
            .iter_mut()
            .enumerate()
            .for_each(|(i, v)| *v = 0.5 * *v + (i % 3) as f64);
        assert!(same_pattern(a.as_ref(), b.as_ref()));
        // Two views of one stored pattern (as precompute::Assembled hands out) share it without
        // a comparison; a view of it against another pattern does not.
        let shared = SparseMatrixRef::new(a.symbolic(), b.val());
        assert!(same_pattern(a.as_ref(), shared));
        let (ld, w) = (5, 3);
        let x: Vec<f64> = (0..n * ld).map(|i| ((i * 37) % 11) as f64 - 5.0).collect();
        let (mut ya, mut yb) = (vec![0.0; n * ld], vec![0.0; n * ld]);
        sym_mul_pair_row_major(
            a.as_ref(),
            b.as_ref(),
            &x[1..],
            ld,
            &mut ya[2..],
            &mut yb[2..],
            ld,
            w,
        );
        let (mut za, mut zb) = (vec![0.0; n * ld], vec![0.0; n * ld]);
        sym_mul_row_major(a.as_ref(), &x[1..], ld, &mut za[2..], ld, w);
        sym_mul_row_major(b.as_ref(), &x[1..], ld, &mut zb[2..], ld, w);
        // Same summation order: bit-identical.
        assert_eq!(ya, za);
        assert_eq!(yb, zb);
        // A different pattern falls back to two products.
        let eye = from_compressed(
            n,
            (0..=n as u32).collect(),
            (0..n as u32).collect(),
            vec![2.0; n],
        );
        assert!(!same_pattern(a.as_ref(), eye.as_ref()));
        assert!(!same_pattern(shared, eye.as_ref()));
        sym_mul_pair_row_major(
            a.as_ref(),
            eye.as_ref(),
            &x[1..],
            ld,
            &mut ya[2..],
            &mut yb[2..],
            ld,
            w,
        );
        assert_eq!(ya, za);
        for i in 0..n {
            for c in 0..w {
                assert_eq!(yb[2 + i * ld + c], 2.0 * x[1 + i * ld + c]);
            }
        }
    }

    #[test]
    fn norms_diagonal_and_checks() {
        let n = 200;
        let a = small(n);
        let ad = to_dense(a.as_ref());
        let d = diagonal(a.as_ref());
        for i in 0..n {
            assert_eq!(d[i], ad[(i, i)]);
        }
        assert!((trace(a.as_ref()) - d.iter().sum::<f64>()).abs() < 1e-12);
        // ||A||_1 by brute force.
        let mut n1 = 0.0f64;
        for j in 0..n {
            n1 = n1.max((0..n).map(|i| ad[(i, j)].abs()).sum());
        }
        assert_eq!(norm_1(a.as_ref()), n1);
        // ||A||_2 from the dense eigenvalues; the power estimate is a lower bound and, after 60
        // iterations on this well-separated spectrum, within 1% of it.
        let ev = ad.self_adjoint_eigenvalues(faer::Side::Lower).unwrap();
        let n2 = ev.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        let est = norm_2_estimate(a.as_ref(), 60);
        assert!(
            est <= n2 * (1.0 + 1e-12) && est > 0.99 * n2,
            "est {est} vs {n2}"
        );
        assert!(n2 <= n1 + 1e-12);
        assert_eq!(first_non_finite(a.as_ref()), None);
        assert_eq!(symmetry_defect(a.as_ref()), 0.0);
        // alpha A + beta I.
        let eye = SparseMatrix::try_new_from_triplets(
            n,
            n,
            &(0..n).map(|i| tri(i, i, 1.0)).collect::<Vec<_>>(),
        )
        .unwrap();
        let s = add_scaled(2.0, a.as_ref(), 0.5, eye.as_ref());
        let sd = to_dense(s.as_ref());
        for i in 0..n {
            for j in 0..n {
                let e = 2.0 * ad[(i, j)] + if i == j { 0.5 } else { 0.0 };
                assert_eq!(sd[(i, j)], e);
            }
        }
    }

    #[test]
    fn detects_non_finite_and_asymmetry() {
        let t = vec![
            tri(0, 0, 1.0),
            tri(1, 0, 2.0),
            tri(0, 1, 2.5),
            tri(1, 1, f64::NAN),
            tri(2, 2, 1.0),
        ];
        let a = SparseMatrix::try_new_from_triplets(3, 3, &t).unwrap();
        assert_eq!(first_non_finite(a.as_ref()), Some((1, 1)));
        let t = vec![
            tri(0, 0, 1.0),
            tri(1, 0, 2.0),
            tri(0, 1, 2.5),
            tri(2, 1, 1.0),
        ];
        let a = SparseMatrix::try_new_from_triplets(3, 3, &t).unwrap();
        // |2.0 - 2.5| = 0.5 and the unmatched (2,1) entry gives 1.0.
        assert_eq!(symmetry_defect(a.as_ref()), 1.0);
    }

    /// The cursor walk (sorted columns) and the transpose merge (unsorted columns) both give
    /// max |A - A^T| of the dense copy, exactly (the same differences are taken), on random
    /// patterns that are symmetric, almost symmetric, or have unmatched entries on either side.
    #[test]
    fn symmetry_defect_equals_the_dense_definition() {
        let mut rng = crate::random::SplitMix64::new(7);
        for trial in 0..60 {
            let n = 1 + trial % 13;
            let mut t = Vec::new();
            for i in 0..n {
                for j in 0..=i {
                    if rng.next_f64() < 0.4 {
                        let v = rng.uniform(-0.5, 0.5);
                        let w = match trial % 3 {
                            0 => v,
                            1 => v + 1e-3 * rng.uniform(-0.5, 0.5),
                            _ => rng.uniform(-0.5, 0.5),
                        };
                        // trial % 3 == 2 leaves some entries of either triangle without
                        // a mirror.
                        let (lower, upper) = match trial % 3 == 2 && i != j {
                            true => (rng.next_f64() < 0.8, rng.next_f64() < 0.8),
                            false => (true, i != j),
                        };
                        if lower {
                            t.push(tri(i, j, v));
                        }
                        if upper {
                            t.push(tri(j, i, w));
                        }
                    }
                }
            }
            let a = SparseMatrix::try_new_from_triplets(n, n, &t).unwrap();
            let d = to_dense(a.as_ref());
            let mut want = 0.0f64;
            for i in 0..n {
                for j in 0..n {
                    want = want.max((d[(i, j)] - d[(j, i)]).abs());
                }
            }
            assert_eq!(symmetry_defect(a.as_ref()), want, "trial {trial}");
            // The same matrix with every column reversed takes the transpose path.
            let sym = a.symbolic();
            let (mut idx, mut val) = (Vec::new(), Vec::new());
            for j in 0..n {
                let range = sym.col_range(j);
                idx.extend(sym.row_idx()[range.clone()].iter().rev());
                val.extend(a.val()[range].iter().rev());
            }
            let ptr = sym.col_ptr().to_vec();
            let reversed = SparseColMat::new(
                SymbolicSparseColMat::new_unsorted_checked(n, n, ptr, None, idx),
                val,
            );
            assert_eq!(
                symmetry_defect(reversed.as_ref()),
                want,
                "trial {trial}, unsorted"
            );
        }
    }
}
