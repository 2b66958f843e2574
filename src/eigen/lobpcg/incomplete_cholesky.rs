//! Zero-fill incomplete Cholesky IC(0): L with the pattern of the lower triangle of A, such
//! that (L L^T)_ij = A_ij on that pattern. The cheap ("shallow-fill") alternative to the exact
//! sparse Cholesky when the latter's fill is too large: the factor has exactly as many entries
//! as the lower triangle of A, and factorization costs ~ sum over rows of (row length)^2.
//!
//! A = H + sigma M is never formed: each row of the factor starts as the merge of the lower
//! triangles of H and M (the values A would hold, bit for bit) and is factored in place.
//!
//! Stored by rows (CSR of the lower triangle, diagonal last in each row, u32 column indices).
//! Row i of L has the pattern of column i of A above and on the diagonal, so when H and M
//! share one sorted pattern the factor borrows its column indices from it and stores only
//! its values (8 bytes an entry instead of 12: 0.5 GB at K = 1,000,000). Solves sweep the
//! rows sequentially on row-major slabs of columns (each step a contiguous row operation), one
//! slab per thread: deterministic.
//!
//! Breakdown (a non-positive pivot, possible for matrices that are not M-matrices) is handled
//! by the caller by factoring A + alpha diag(A) with a growing alpha (Manteuffel's shift).

use super::workspace::{Block, ROW_CHUNK};
use crate::simd::multiversion;
use crate::sparse::{self, SparseMatrixRef};
use crate::triangle::UpperRef;
use rayon::prelude::*;
use std::borrow::Cow;

/// An IC(0) factor.
#[derive(Debug, Clone)]
pub(super) struct IncompleteCholesky<'a> {
    /// Value pointers per row, length n + 1: row i's values are `val[ptr[i]..ptr[i + 1]]`.
    ptr: Vec<usize>,
    /// Where row i's column indices start in `idx` (its length is the row's).
    idx_start: Vec<usize>,
    /// Column indices per row, ascending, diagonal last: the factor's own, or the shared
    /// pattern of H and M (column i's rows <= i start column i's stored rows).
    idx: Cow<'a, [u32]>,
    /// Values of L (the diagonal entry of each row is L_ii).
    val: Vec<f64>,
}

/// The rows of a factor's pattern: value pointers and where each row's indices start.
#[derive(Clone, Copy)]
struct Rows<'r> {
    ptr: &'r [usize],
    idx_start: &'r [usize],
    idx: &'r [u32],
}

impl<'r> Rows<'r> {
    fn n(&self) -> usize {
        self.ptr.len() - 1
    }

    /// Row i's value range.
    #[inline(always)]
    fn range(&self, i: usize) -> std::ops::Range<usize> {
        self.ptr[i]..self.ptr[i + 1]
    }

    /// Row i's column indices (the diagonal last).
    #[inline(always)]
    fn cols(&self, i: usize) -> &'r [u32] {
        let s = self.idx_start[i];
        &self.idx[s..s + self.ptr[i + 1] - self.ptr[i]]
    }
}

/// A non-positive (or non-finite) pivot, or a missing diagonal, at `row`.
#[derive(Debug, Clone, Copy)]
pub(super) struct Breakdown {
    pub row: usize,
}

impl<'a> IncompleteCholesky<'a> {
    /// Entries of the factor.
    pub fn entries(&self) -> usize {
        self.val.len()
    }

    /// IC(0) of `A + alpha diag(A)` with A = `h` + `sigma` `m` (both symmetric K x K, both
    /// triangles stored; only the lower triangles are read; the factor's u32 column indices
    /// are the matrices' own row indices, borrowed when H and M share one sorted pattern). A
    /// pivot below `1e-12 * (1 + alpha) a_ii` counts as a breakdown.
    pub fn factor(
        h: SparseMatrixRef<'a>,
        m: SparseMatrixRef<'a>,
        sigma: f64,
        alpha: f64,
    ) -> Result<Self, Breakdown> {
        let mut ic = match shared_lower_pencil(h, m, sigma) {
            Some(ic) => ic?,
            None => lower_pencil(h, m, sigma)?,
        };
        ic.shift_and_factor(alpha)?;
        Ok(ic)
    }

    /// Manteuffel's shift `alpha` on the diagonal (last in each row), then the factorization
    /// in place.
    fn shift_and_factor(&mut self, alpha: f64) -> Result<(), Breakdown> {
        for &end in &self.ptr[1..] {
            self.val[end - 1] *= 1.0 + alpha;
        }
        let rows = Rows {
            ptr: &self.ptr,
            idx_start: &self.idx_start,
            idx: &self.idx,
        };
        factor_rows(rows, &mut self.val)
    }

    /// [`IncompleteCholesky::factor`] for H and M stored as upper triangles of one pattern
    /// (`crate::triangle`): column i of that pattern is row i of the factor, so the factor
    /// borrows its indices and its values are `1.0 * h + sigma * m` entry by entry, the bits
    /// [`IncompleteCholesky::factor`] gives from both-triangle storage of the same matrices.
    ///
    /// # Panics
    /// If `h` and `m` do not share their pattern (caller bug: the solver checks it).
    pub fn factor_upper(
        h: UpperRef<'a>,
        m: UpperRef<'a>,
        sigma: f64,
        alpha: f64,
    ) -> Result<Self, Breakdown> {
        assert!(h.same_pattern(&m), "factor_upper: two patterns");
        let pattern = h.pattern();
        let ptr: Vec<usize> = pattern.col_ptr().iter().map(|&p| p as usize).collect();
        let val: Vec<f64> = h
            .val()
            .iter()
            .zip(m.val())
            .map(|(&a, &b)| 1.0 * a + sigma * b)
            .collect();
        let mut ic = IncompleteCholesky {
            idx_start: ptr[..ptr.len() - 1].to_vec(),
            ptr,
            idx: Cow::Borrowed(pattern.row_idx()),
            val,
        };
        ic.shift_and_factor(alpha)?;
        Ok(ic)
    }

    /// The factor holding its own column indices (for a preconditioner that outlives H and M).
    pub fn into_owned(self) -> IncompleteCholesky<'static> {
        match self.idx {
            Cow::Owned(idx) => IncompleteCholesky {
                ptr: self.ptr,
                idx_start: self.idx_start,
                idx: Cow::Owned(idx),
                val: self.val,
            },
            Cow::Borrowed(shared) => {
                let rows = Rows {
                    ptr: &self.ptr,
                    idx_start: &self.idx_start,
                    idx: shared,
                };
                let idx: Vec<u32> = (0..rows.n()).flat_map(|i| rows.cols(i)).copied().collect();
                IncompleteCholesky {
                    idx_start: self.ptr.clone(),
                    ptr: self.ptr,
                    idx: Cow::Owned(idx),
                    val: self.val,
                }
            }
        }
    }

    /// Columns `c0..c0 + w` of `s` <- (L L^T)^-1 times them, using `tmp` (at least w columns)
    /// as scratch. The columns are split into one group per thread; each group is copied to
    /// its own contiguous slab of `tmp`, solved there by sequential sweeps, and copied back.
    /// Every column goes through the same operations in the same order whatever the grouping,
    /// so the result is bit-identical for any thread count. No allocation.
    pub fn solve_in_place(&self, s: &mut Block, c0: usize, w: usize, tmp: &mut Block) {
        let n = self.ptr.len() - 1;
        if w == 0 || n == 0 {
            return;
        }
        let groups = rayon::current_num_threads().clamp(1, w);
        let gw = w.div_ceil(groups);
        let ld = s.ld;
        let src = &s.data;
        tmp.data[..n * w]
            .par_chunks_mut(n * gw)
            .enumerate()
            .for_each(|(g, slab)| {
                let width = slab.len() / n;
                let first = c0 + g * gw;
                for (i, row) in slab.chunks_mut(width).enumerate() {
                    row.copy_from_slice(&src[i * ld + first..i * ld + first + width]);
                }
                self.solve_slab(slab, width);
            });
        let slabs = &tmp.data[..n * w];
        s.data
            .par_chunks_mut(ld * ROW_CHUNK)
            .enumerate()
            .for_each(|(chunk, rows)| {
                for (r, row) in rows.chunks_mut(ld).enumerate() {
                    let i = chunk * ROW_CHUNK + r;
                    for g in 0..groups {
                        let first = g * gw;
                        if first >= w {
                            break;
                        }
                        let width = gw.min(w - first);
                        let slab = &slabs[n * first..n * (first + width)];
                        row[c0 + first..c0 + first + width]
                            .copy_from_slice(&slab[i * width..(i + 1) * width]);
                    }
                }
            });
    }

    /// (L L^T)^-1 in place on a row-major n x `width` slab (row stride `width`).
    fn solve_slab(&self, data: &mut [f64], width: usize) {
        let rows = Rows {
            ptr: &self.ptr,
            idx_start: &self.idx_start,
            idx: &self.idx,
        };
        solve_slab(rows, &self.val, data, width);
    }
}

/// The lower triangle of H + sigma M by rows (row i = column i's entries k <= i, sorted,
/// the diagonal last), not yet factored, merged as [`sparse::add_scaled`] merges the columns
/// of A (the same bits).
fn lower_pencil(
    h: SparseMatrixRef<'_>,
    m: SparseMatrixRef<'_>,
    sigma: f64,
) -> Result<IncompleteCholesky<'static>, Breakdown> {
    let n = h.nrows();
    let lower = |a: SparseMatrixRef<'_>| (a.val().len() + n) / 2;
    let cap = lower(h).max(lower(m));
    let mut ptr = Vec::with_capacity(n + 1);
    let mut idx: Vec<u32> = Vec::with_capacity(cap);
    let mut val = Vec::with_capacity(cap);
    ptr.push(0);
    let (mut ch, mut cm, mut row) = (Vec::new(), Vec::new(), Vec::new());
    for i in 0..n {
        sparse::sorted_column(h, i, &mut ch);
        sparse::sorted_column(m, i, &mut cm);
        let (ph, pm) = (
            ch.partition_point(|e| e.0 <= i),
            cm.partition_point(|e| e.0 <= i),
        );
        row.clear();
        sparse::merge_scaled(1.0, &ch[..ph], sigma, &cm[..pm], &mut row);
        if row.last().map(|e| e.0) != Some(i) {
            // Missing diagonal: a zero pivot.
            return Err(Breakdown { row: i });
        }
        // Indices k <= i come from the matrices' own u32 row indices.
        idx.extend(row.iter().map(|&(k, _)| k as u32));
        val.extend(row.iter().map(|&(_, v)| v));
        ptr.push(idx.len());
    }
    Ok(IncompleteCholesky {
        idx_start: ptr.clone(),
        ptr,
        idx: Cow::Owned(idx),
        val,
    })
}

/// [`lower_pencil`] for H and M of one pattern with ascending rows in every column: row i of
/// the factor is column i's stored rows up to i, so the factor borrows those indices and its
/// values are `1.0 * h + sigma * m` entry by entry (the bits the merge gives). `None` when
/// the patterns differ or a column is not sorted (the general merge handles those).
fn shared_lower_pencil<'a>(
    h: SparseMatrixRef<'a>,
    m: SparseMatrixRef<'a>,
    sigma: f64,
) -> Option<Result<IncompleteCholesky<'a>, Breakdown>> {
    sparse::SharedPattern::new(h, m)?;
    let sym = h.symbolic();
    let rows = sym.row_idx();
    let n = h.nrows();
    let (hv, mv) = (h.val(), m.val());
    let mut ptr = Vec::with_capacity(n + 1);
    let mut idx_start = Vec::with_capacity(n);
    // The lower triangle of a symmetric pattern with its diagonal.
    let mut val = Vec::with_capacity((hv.len() + n) / 2);
    ptr.push(0);
    for i in 0..n {
        let range = sym.col_range(i);
        let column = &rows[range.clone()];
        if !column.windows(2).all(|w| w[0] < w[1]) {
            return None;
        }
        let len = column.partition_point(|&k| k as usize <= i);
        if len == 0 || column[len - 1] as usize != i {
            // Missing diagonal: a zero pivot.
            return Some(Err(Breakdown { row: i }));
        }
        idx_start.push(range.start);
        let r = range.start..range.start + len;
        val.extend(
            hv[r.clone()]
                .iter()
                .zip(&mv[r])
                .map(|(&a, &b)| 1.0 * a + sigma * b),
        );
        ptr.push(val.len());
    }
    Some(Ok(IncompleteCholesky {
        ptr,
        idx_start,
        idx: Cow::Borrowed(rows),
        val,
    }))
}

/// Factor the rows in place: L_ik = (a_ik - sum_{j<k} L_ij L_kj) / L_kk, L_ii = sqrt(...).
fn factor_rows(rows: Rows<'_>, val: &mut [f64]) -> Result<(), Breakdown> {
    let n = rows.n();
    // `pos[j]` = offset of column j in the current row, or u32::MAX.
    let mut pos = vec![u32::MAX; n];
    for i in 0..n {
        let range = rows.range(i);
        let (start, end) = (range.start, range.end);
        let cols = rows.cols(i);
        let diag_scale = val[end - 1];
        for (p, &j) in cols.iter().enumerate() {
            // A row has at most n <= u32::MAX entries.
            pos[j as usize] = p as u32;
        }
        for (p, &k) in (start..end - 1).zip(cols) {
            let k = k as usize;
            let kr = rows.range(k);
            let mut s = val[p];
            for (q, &j) in (kr.start..kr.end - 1).zip(rows.cols(k)) {
                let pj = pos[j as usize];
                if pj != u32::MAX {
                    s -= val[start + pj as usize] * val[q];
                }
            }
            val[p] = s / val[kr.end - 1];
        }
        let d = val[end - 1] - val[start..end - 1].iter().map(|v| v * v).sum::<f64>();
        if !(d.is_finite() && d > 1e-12 * diag_scale) {
            return Err(Breakdown { row: i });
        }
        val[end - 1] = d.sqrt();
        for &j in cols {
            pos[j as usize] = u32::MAX;
        }
    }
    Ok(())
}

multiversion! {
    /// (L L^T)^-1 in place on a row-major n x `width` slab, L in compressed rows (`ptr`,
    /// `idx`, `val`, the diagonal last in each row).
    fn solve_slab(rows: Rows<'_>, val: &[f64], data: &mut [f64], width: usize) {
        let n = rows.n();
        // Forward: L y = b, the columns of row i in groups kept in registers over the row.
        for i in 0..n {
            let (start, end) = (rows.ptr[i], rows.ptr[i + 1]);
            let (before, rest) = data.split_at_mut(i * width);
            let yi = &mut rest[..width];
            let row = rows.cols(i);
            let (cols, ls) = (&row[..row.len() - 1], &val[start..end - 1]);
            let mut c0 = 0;
            while width - c0 >= 8 {
                subtract_in_registers::<8>(cols, ls, before, width, c0, yi);
                c0 += 8;
            }
            if width - c0 >= 4 {
                subtract_in_registers::<4>(cols, ls, before, width, c0, yi);
                c0 += 4;
            }
            while c0 < width {
                subtract_in_registers::<1>(cols, ls, before, width, c0, yi);
                c0 += 1;
            }
            let inv = 1.0 / val[end - 1];
            yi.iter_mut().for_each(|a| *a *= inv);
        }
        // Backward: L^T x = y (column-oriented sweep over the rows of L).
        for i in (0..n).rev() {
            let (start, end) = (rows.ptr[i], rows.ptr[i + 1]);
            let (before, rest) = data.split_at_mut(i * width);
            let xi = &mut rest[..width];
            let inv = 1.0 / val[end - 1];
            xi.iter_mut().for_each(|a| *a *= inv);
            for (p, &k) in (start..end - 1).zip(rows.cols(i)) {
                let k = k as usize;
                let l = val[p];
                let yk = &mut before[k * width..(k + 1) * width];
                for (a, &b) in yk.iter_mut().zip(xi.iter()) {
                    *a -= l * b;
                }
            }
        }
    }
}

/// y[c0..c0 + W] -= sum_t l[t] rows[cols[t] * width + c0..][..W], in stored order, the W
/// values in registers (the same operations as one subtraction per entry and column).
#[inline(always)]
fn subtract_in_registers<const W: usize>(
    cols: &[u32],
    l: &[f64],
    rows: &[f64],
    width: usize,
    c0: usize,
    y: &mut [f64],
) {
    let mut acc = *sparse::fixed_row::<W>(y, c0);
    for (&k, &lk) in cols.iter().zip(l) {
        let yk = sparse::fixed_row::<W>(rows, k as usize * width + c0);
        for (a, &b) in acc.iter_mut().zip(yk) {
            *a -= lk * b;
        }
    }
    y[c0..c0 + W].copy_from_slice(&acc);
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::eigen::testing;

    #[test]
    fn ic0_is_exact_on_a_tridiagonal_and_matches_on_the_pattern() {
        // For a tridiagonal matrix IC(0) = exact Cholesky: the solve inverts A to round-off.
        let n = 40;
        let mut ptr = vec![0u32];
        let (mut idx, mut val) = (Vec::new(), Vec::new());
        for j in 0..n as u32 {
            if j > 0 {
                idx.push(j - 1);
                val.push(-1.0);
            }
            idx.push(j);
            val.push(2.5);
            if j + 1 < n as u32 {
                idx.push(j + 1);
                val.push(-1.0);
            }
            ptr.push(idx.len() as u32);
        }
        let a = crate::sparse::from_compressed(n, ptr, idx, val);
        let zero = crate::sparse::from_compressed(
            n,
            (0..=n as u32).collect(),
            (0..n as u32).collect(),
            vec![0.0; n],
        );
        let ic = IncompleteCholesky::factor(a.as_ref(), zero.as_ref(), 1.0, 0.0).unwrap();
        assert_eq!(ic.entries(), 2 * n - 1);
        let mut b = Block::new(n, 3);
        for i in 0..n {
            b.data[i * 3 + 1] = (i as f64).sin();
        }
        let rhs: Vec<f64> = (0..n).map(|i| b.data[i * 3 + 1]).collect();
        let mut tmp = Block::new(n, 2);
        ic.solve_in_place(&mut b, 1, 1, &mut tmp);
        let x: Vec<f64> = (0..n).map(|i| b.data[i * 3 + 1]).collect();
        let mut ax = vec![0.0; n];
        crate::sparse::sym_mul_row_major(a.as_ref(), &x, 1, &mut ax, 1, 1);
        for i in 0..n {
            // cond(A) < 10: residual at round-off level.
            assert!((ax[i] - rhs[i]).abs() < 1e-13, "{i}");
        }
        // On a 3D stencil (fill dropped) L L^T reproduces A on the pattern of A.
        let h = testing::grid_laplacian([5, 4, 3], 1.5);
        let m = testing::identity(60);
        let a = crate::sparse::add_scaled(1.0, h.as_ref(), 0.1, m.as_ref());
        let ic = IncompleteCholesky::factor(h.as_ref(), m.as_ref(), 0.1, 0.0).unwrap();
        let dense = crate::sparse::to_dense(a.as_ref());
        let mut l = faer::Mat::<f64>::zeros(60, 60);
        for i in 0..60 {
            for (p, &k) in (ic.ptr[i]..ic.ptr[i + 1]).zip(&ic.idx[ic.idx_start[i]..]) {
                l[(i, k as usize)] = ic.val[p];
            }
        }
        let llt = &l * l.transpose();
        for i in 0..60 {
            for &k in &ic.idx[ic.idx_start[i]..ic.idx_start[i] + ic.ptr[i + 1] - ic.ptr[i]] {
                let k = k as usize;
                assert!((llt[(i, k)] - dense[(i, k)]).abs() < 1e-12);
            }
        }
    }

    #[test]
    fn a_shared_pattern_is_borrowed_and_gives_the_merged_factor_bit_for_bit() {
        // H and M of one pattern (M = a positive multiple of |H| plus the identity on it).
        let h = testing::grid_laplacian([6, 5, 4], 2.0);
        let m_vals: Vec<f64> = h.val().iter().map(|v| 0.25 * v.abs() + 0.5).collect();
        let m = crate::sparse::SparseMatrix::new(h.symbolic().to_owned().unwrap(), m_vals);
        let shared = IncompleteCholesky::factor(h.as_ref(), m.as_ref(), 0.3, 0.0).unwrap();
        assert!(
            matches!(shared.idx, Cow::Borrowed(_)),
            "the indices are borrowed"
        );
        // The general merge on the same matrices (the route unshared patterns take).
        let mut merged = lower_pencil(h.as_ref(), m.as_ref(), 0.3).unwrap();
        let rows = Rows {
            ptr: &merged.ptr,
            idx_start: &merged.idx_start,
            idx: &merged.idx,
        };
        factor_rows(rows, &mut merged.val).unwrap();
        assert_eq!(shared.val, merged.val, "the same values, bit for bit");
        let owned = shared.clone().into_owned();
        assert_eq!(owned.idx, merged.idx, "the same pattern, row by row");
        assert_eq!(owned.val, merged.val);
        // And the same solve.
        let n = h.nrows();
        let mut a = Block::new(n, 2);
        for i in 0..n {
            a.data[2 * i] = (i as f64 * 0.7).cos();
            a.data[2 * i + 1] = (i as f64 * 0.3).sin();
        }
        let mut b = Block::new(n, 2);
        b.data.copy_from_slice(&a.data);
        let mut tmp = Block::new(n, 2);
        shared.solve_in_place(&mut a, 0, 2, &mut tmp);
        merged.solve_in_place(&mut b, 0, 2, &mut tmp);
        assert_eq!(a.data, b.data);
    }
}
