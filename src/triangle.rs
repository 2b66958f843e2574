//! Symmetric sparse matrices stored as their upper triangle only: half the memory of
//! [`crate::sparse::SparseMatrix`]'s both-triangle storage, for the large assembled pencils
//! (at K = 1,000,000, H_w and M hold 253M entries with both triangles, 127M with one).
//!
//! The layout is CSC of the upper triangle: column j holds the rows i <= j, ascending, the
//! diagonal last. Column j of it is also row j of the lower triangle, which is the row of the
//! IC(0) factor L (`eigen::lobpcg`), so a factor can share this pattern.
//!
//! A product Y = A X uses each stored entry twice: the gather y_j += a_ij x_i (the whole
//! column j, summed in registers) and the scatter y_i += a_ij x_j for i < j. To stay
//! deterministic for any thread count, the rows are cut into fixed segments (their size
//! depends on K only, [`UpperPattern::new`]): one task per segment walks its columns in
//! ascending order, gathers each column and scatters the entries whose row lies in its own
//! segment; a second pass, one task per segment again, adds the entries scattered into it from
//! later segments, in ascending column order (the lists are built once with the pattern).
//! Each output row is so summed in one fixed order whatever the threads.

use crate::sparse::{self, SparseMatrix};
use faer::sparse::{SymbolicSparseColMat, SymbolicSparseColMatRef};
use rayon::prelude::*;

/// Most segments the rows are cut into (more only add scattered entries in the second pass).
const MAX_SEGMENTS: usize = 16;
/// Fewest rows in a segment, so a small matrix is not all cross-segment entries.
const MIN_SEGMENT_ROWS: usize = 256;

/// One run of stored entries `lo..hi` of column `col` whose rows lie in another (earlier)
/// segment: what the second pass of a product adds to that segment.
#[derive(Debug, Clone, Copy)]
struct CrossRun {
    col: u32,
    lo: u32,
    hi: u32,
}

/// The upper-triangle pattern of a symmetric K x K matrix (CSC, rows ascending, diagonal last
/// in every column, u32 pointers and indices) with the plan of its deterministic parallel
/// products. Shared by the matrices of one pencil (H_w and M).
#[derive(Debug, Clone)]
pub struct UpperPattern {
    symbolic: SymbolicSparseColMat<u32>,
    segment_rows: usize,
    /// Per column: the first stored position whose row lies in the column's own segment.
    own_start: Vec<u32>,
    /// Per segment: the runs of later columns' entries with rows in it, columns ascending.
    cross: Vec<Vec<CrossRun>>,
}

/// Why compressed arrays are not an upper-triangle pattern.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum PatternError {
    /// Wrong array lengths, unsorted rows or rows out of range.
    #[error("not a compressed K x K pattern: {0}")]
    Layout(String),
    /// A column whose last (largest) row is not its diagonal: a row below the diagonal, or
    /// no diagonal entry.
    #[error("column {0}: the upper triangle needs rows <= {0}, ascending, the diagonal last")]
    NotUpper(usize),
}

impl UpperPattern {
    /// The pattern from compressed arrays: `ptr` (K + 1 column pointers), `idx` (row indices,
    /// ascending in each column, every column ending with its diagonal).
    ///
    /// # Errors
    /// [`PatternError`] when the arrays are not such a pattern.
    pub fn new(k: usize, ptr: Vec<u32>, idx: Vec<u32>) -> Result<Self, PatternError> {
        if ptr.len() != k + 1 || ptr[0] != 0 || ptr[k] as usize != idx.len() {
            return Err(PatternError::Layout(format!(
                "{} column pointers for K = {k} (need K + 1, from 0 to the {} indices)",
                ptr.len(),
                idx.len()
            )));
        }
        for j in 0..k {
            let (start, end) = (ptr[j] as usize, ptr[j + 1] as usize);
            if start > end {
                return Err(PatternError::Layout(format!(
                    "column {j}: pointers decrease"
                )));
            }
            let col = &idx[start..end];
            if !col.windows(2).all(|w| w[0] < w[1]) {
                return Err(PatternError::Layout(format!(
                    "column {j}: rows not ascending"
                )));
            }
            if col.last().map(|&i| i as usize) != Some(j) {
                return Err(PatternError::NotUpper(j));
            }
        }
        // Checked above: faer's own checks cannot fail.
        let symbolic = SymbolicSparseColMat::new_checked(k, k, ptr, None, idx);
        let segment_rows = k.div_ceil(MAX_SEGMENTS).max(MIN_SEGMENT_ROWS);
        let (own_start, cross) = plan(symbolic.as_ref(), segment_rows);
        Ok(UpperPattern {
            symbolic,
            segment_rows,
            own_start,
            cross,
        })
    }

    /// K.
    pub fn dim(&self) -> usize {
        self.symbolic.ncols()
    }

    /// Stored entries (the upper triangle with the diagonal).
    pub fn nnz(&self) -> usize {
        self.symbolic.row_idx().len()
    }

    /// The compressed pattern (faer's view).
    pub fn symbolic(&self) -> SymbolicSparseColMatRef<'_, u32> {
        self.symbolic.as_ref()
    }

    /// Column pointers, K + 1.
    pub fn col_ptr(&self) -> &[u32] {
        self.symbolic.col_ptr()
    }

    /// Row indices, one per stored entry.
    pub fn row_idx(&self) -> &[u32] {
        self.symbolic.row_idx()
    }

    /// The share of stored entries added in the second pass of a product (rows in an earlier
    /// segment than their column's).
    pub fn cross_fraction(&self) -> f64 {
        let cross: usize = self
            .cross
            .iter()
            .flatten()
            .map(|r| (r.hi - r.lo) as usize)
            .sum();
        cross as f64 / self.nnz().max(1) as f64
    }

    /// Bytes held (pattern and plan), for memory estimates.
    pub fn bytes(&self) -> usize {
        4 * (self.col_ptr().len() + self.nnz() + self.own_start.len())
            + 12 * self.cross.iter().map(Vec::len).sum::<usize>()
    }

    fn segments(&self) -> usize {
        self.dim().div_ceil(self.segment_rows)
    }
}

/// One source segment's part of the plan: its columns' first own-segment entries, and its
/// runs with the segment each goes to.
type SourcePlan = (Vec<u32>, Vec<(usize, CrossRun)>);

/// The second-pass runs and each column's first own-segment entry (module docs).
fn plan(sym: SymbolicSparseColMatRef<'_, u32>, seg: usize) -> (Vec<u32>, Vec<Vec<CrossRun>>) {
    let k = sym.ncols();
    let rows = sym.row_idx();
    let segments = k.div_ceil(seg);
    // One task per source segment; the runs into each destination are then joined in source
    // order, so every list is in ascending column order.
    let per_source: Vec<SourcePlan> = (0..segments)
        .into_par_iter()
        .map(|s| {
            let cols = s * seg..((s + 1) * seg).min(k);
            let mut own = Vec::with_capacity(cols.len());
            let mut runs = Vec::new();
            for j in cols {
                let range = sym.col_range(j);
                let mut p = range.start;
                while p < range.end && rows[p] as usize / seg < s {
                    let t = rows[p] as usize / seg;
                    let lo = p;
                    while p < range.end && rows[p] as usize / seg == t {
                        p += 1;
                    }
                    // Positions fit u32: the pattern's pointers are u32.
                    runs.push((
                        t,
                        CrossRun {
                            col: j as u32,
                            lo: lo as u32,
                            hi: p as u32,
                        },
                    ));
                }
                own.push(p as u32);
            }
            (own, runs)
        })
        .collect();
    let mut own_start = Vec::with_capacity(k);
    let mut cross = vec![Vec::new(); segments];
    for (own, runs) in per_source {
        own_start.extend(own);
        for (t, run) in runs {
            cross[t].push(run);
        }
    }
    (own_start, cross)
}

/// A symmetric matrix stored as its upper triangle: a pattern and one value per stored entry.
#[derive(Debug, Clone, Copy)]
pub struct UpperRef<'a> {
    pattern: &'a UpperPattern,
    val: &'a [f64],
}

impl<'a> UpperRef<'a> {
    /// The matrix with `pattern` and `val` (one value per stored entry, in stored order).
    ///
    /// # Panics
    /// If `val` has another length than the pattern's entries (caller bug).
    pub fn new(pattern: &'a UpperPattern, val: &'a [f64]) -> Self {
        assert_eq!(
            val.len(),
            pattern.nnz(),
            "UpperRef: one value per stored entry"
        );
        UpperRef { pattern, val }
    }

    /// K.
    pub fn dim(&self) -> usize {
        self.pattern.dim()
    }

    /// The pattern.
    pub fn pattern(&self) -> &'a UpperPattern {
        self.pattern
    }

    /// The stored values.
    pub fn val(&self) -> &'a [f64] {
        self.val
    }

    /// Two matrices share one pattern (the same object, so products of both can go in one
    /// pass).
    pub fn same_pattern(&self, other: &UpperRef<'_>) -> bool {
        std::ptr::eq(self.pattern, other.pattern)
    }

    /// The diagonal, length K (the last stored entry of each column).
    pub fn diagonal(&self) -> Vec<f64> {
        self.pattern.col_ptr()[1..]
            .iter()
            .map(|&end| self.val[end as usize - 1])
            .collect()
    }

    /// ||A||_1 = max over rows of sum_j |a_ij| over both triangles (one pass; each row's sum
    /// taken in one fixed order, so deterministic).
    pub fn norm_1(&self) -> f64 {
        let k = self.dim();
        let mut sums = vec![0.0f64; k];
        let sym = self.pattern.symbolic();
        let rows = sym.row_idx();
        for j in 0..k {
            let range = sym.col_range(j);
            let mut own = 0.0;
            for (&i, &v) in rows[range.clone()].iter().zip(&self.val[range]) {
                own += v.abs();
                if i as usize != j {
                    sums[i as usize] += v.abs();
                }
            }
            sums[j] += own;
        }
        sums.into_iter().fold(0.0, f64::max)
    }

    /// The first stored entry that is NaN or infinite, as (row, column).
    pub fn first_non_finite(&self) -> Option<(usize, usize)> {
        let sym = self.pattern.symbolic();
        let p = self.val.iter().position(|v| !v.is_finite())?;
        let col = self.pattern.col_ptr().partition_point(|&s| s as usize <= p) - 1;
        Some((sym.row_idx()[p] as usize, col))
    }

    /// The entries summed over both triangles (1^T A 1), compensated (Neumaier) in stored
    /// order: the off-diagonal entries count twice.
    pub fn sum_all(&self) -> f64 {
        let rows = self.pattern.row_idx();
        let ptr = self.pattern.col_ptr();
        sparse::compensated_sum((0..self.dim()).flat_map(|j| {
            (ptr[j] as usize..ptr[j + 1] as usize).map(move |p| {
                if rows[p] as usize == j {
                    self.val[p]
                } else {
                    2.0 * self.val[p]
                }
            })
        }))
    }

    /// Both triangles as a [`SparseMatrix`] (rows ascending in each column): for consumers
    /// that read whole columns (the dense and SLEPc solvers, exports, restrictions).
    pub fn to_full(&self) -> SparseMatrix {
        let (ptr, idx, order) = full_layout(self.pattern);
        let val = order.iter().map(|&p| self.val[p as usize]).collect();
        sparse::from_compressed(self.dim(), ptr, idx, val)
    }

    /// Y = A X for row-major blocks (layout as [`sparse::sym_mul_row_major`]).
    ///
    /// # Panics
    /// If a stride is below `ncols` or a slice is too short (caller bug).
    pub fn mul_row_major(&self, x: &[f64], ldx: usize, y: &mut [f64], ldy: usize, ncols: usize) {
        let (vals, ys) = ([self.val], [y]);
        products(self.pattern, vals, x, ldx, ys, ldy, ncols);
    }
}

/// Both triangles' column pointers and row indices of `pattern`, and for each full entry the
/// stored position it takes its value from. Column j of the full matrix is row j of the upper
/// triangle's transpose (entries above the diagonal) followed by the stored column j.
fn full_layout(pattern: &UpperPattern) -> (Vec<u32>, Vec<u32>, Vec<u32>) {
    let k = pattern.dim();
    let sym = pattern.symbolic();
    let rows = sym.row_idx();
    let mut count = vec![0u32; k + 1];
    for j in 0..k {
        count[j + 1] += sym.col_range(j).len() as u32;
        for &i in &rows[sym.col_range(j)] {
            if i as usize != j {
                count[i as usize + 1] += 1;
            }
        }
    }
    for j in 0..k {
        count[j + 1] += count[j];
    }
    let ptr = count.clone();
    let total = ptr[k] as usize;
    let mut idx = vec![0u32; total];
    let mut order = vec![0u32; total];
    let mut next = count;
    // Full column i gets, in ascending row order: the stored rows of column i (all <= i), then
    // the mirrored entries (j, i) for the columns j > i that hold row i, visited in ascending j.
    for i in 0..k {
        for p in sym.col_range(i) {
            let at = next[i] as usize;
            idx[at] = rows[p];
            order[at] = p as u32;
            next[i] += 1;
        }
    }
    for j in 0..k {
        for p in sym.col_range(j) {
            let i = rows[p] as usize;
            if i != j {
                let at = next[i] as usize;
                idx[at] = j as u32;
                order[at] = p as u32;
                next[i] += 1;
            }
        }
    }
    (ptr, idx, order)
}

/// Two symmetric matrices stored as upper triangles of one shared pattern (the assembled
/// pencil): H_w and M, 20 bytes a stored entry of one triangle.
#[derive(Debug, Clone)]
pub struct UpperPencil {
    pattern: UpperPattern,
    a: Vec<f64>,
    b: Vec<f64>,
}

impl UpperPencil {
    /// The pencil of `pattern` with values `a` and `b` (one each per stored entry).
    ///
    /// # Panics
    /// If a value array has another length than the pattern's entries (caller bug).
    pub fn new(pattern: UpperPattern, a: Vec<f64>, b: Vec<f64>) -> Self {
        assert!(
            a.len() == pattern.nnz() && b.len() == pattern.nnz(),
            "UpperPencil: one value per stored entry"
        );
        UpperPencil { pattern, a, b }
    }

    /// The upper triangles of two symmetric matrices stored with both triangles (`a`, `b`:
    /// K x K, only the entries on and above the diagonal are read), on the union of their
    /// patterns (an entry one of them lacks is an explicit zero in it).
    ///
    /// # Errors
    /// [`PatternError`] when the two are not K x K of one K, a column has no diagonal in
    /// either, or the entries do not fit u32 positions.
    pub fn from_full(
        a: sparse::SparseMatrixRef<'_>,
        b: sparse::SparseMatrixRef<'_>,
    ) -> Result<Self, PatternError> {
        let k = a.nrows();
        if a.ncols() != k || b.nrows() != k || b.ncols() != k {
            return Err(PatternError::Layout(format!(
                "{} x {} and {} x {}: both must be K x K",
                a.nrows(),
                a.ncols(),
                b.nrows(),
                b.ncols()
            )));
        }
        let (mut ca, mut cb) = (Vec::new(), Vec::new());
        let (mut ptr, mut idx) = (vec![0u32], Vec::new());
        let (mut va, mut vb) = (Vec::new(), Vec::new());
        for j in 0..k {
            sparse::sorted_column(a, j, &mut ca);
            sparse::sorted_column(b, j, &mut cb);
            let (mut p, mut q) = (0, 0);
            loop {
                let ra = ca.get(p).map(|e| e.0).filter(|&i| i <= j);
                let rb = cb.get(q).map(|e| e.0).filter(|&i| i <= j);
                let row = match (ra, rb) {
                    (None, None) => break,
                    (Some(x), None) => x,
                    (None, Some(y)) => y,
                    (Some(x), Some(y)) => x.min(y),
                };
                let take_a = ra == Some(row);
                let take_b = rb == Some(row);
                va.push(if take_a { ca[p].1 } else { 0.0 });
                vb.push(if take_b { cb[q].1 } else { 0.0 });
                p += usize::from(take_a);
                q += usize::from(take_b);
                idx.push(row as u32);
            }
            let end = u32::try_from(idx.len())
                .map_err(|_| PatternError::Layout("more than u32::MAX entries".into()))?;
            ptr.push(end);
        }
        let pattern = UpperPattern::new(k, ptr, idx)?;
        Ok(UpperPencil::new(pattern, va, vb))
    }

    /// The first matrix.
    pub fn first(&self) -> UpperRef<'_> {
        UpperRef::new(&self.pattern, &self.a)
    }

    /// The second matrix.
    pub fn second(&self) -> UpperRef<'_> {
        UpperRef::new(&self.pattern, &self.b)
    }

    /// The shared pattern.
    pub fn pattern(&self) -> &UpperPattern {
        &self.pattern
    }

    /// Both matrices with both triangles, one shared full pattern: (pattern, first values,
    /// second values).
    pub fn to_full(&self) -> (SymbolicSparseColMat<u32>, Vec<f64>, Vec<f64>) {
        let (ptr, idx, order) = full_layout(&self.pattern);
        let a = order.iter().map(|&p| self.a[p as usize]).collect();
        let b = order.iter().map(|&p| self.b[p as usize]).collect();
        let k = self.pattern.dim();
        (
            SymbolicSparseColMat::new_checked(k, k, ptr, None, idx),
            a,
            b,
        )
    }
}

/// YA = A X and YB = B X for two matrices of one pattern, in one pass over it (layout as
/// [`sparse::sym_mul_row_major`]).
///
/// # Panics
/// If the two do not share their pattern, a stride is below `ncols` or a slice is too short
/// (caller bugs).
#[allow(clippy::too_many_arguments)]
pub fn mul_pair_row_major(
    a: UpperRef<'_>,
    b: UpperRef<'_>,
    x: &[f64],
    ldx: usize,
    ya: &mut [f64],
    yb: &mut [f64],
    ldy: usize,
    ncols: usize,
) {
    assert!(a.same_pattern(&b), "mul_pair_row_major: two patterns");
    products(a.pattern, [a.val, b.val], x, ldx, [ya, yb], ldy, ncols);
}

/// Y_n = A_n X for the N value arrays of one pattern: the two passes of the module docs.
fn products<const N: usize>(
    pattern: &UpperPattern,
    vals: [&[f64]; N],
    x: &[f64],
    ldx: usize,
    ys: [&mut [f64]; N],
    ldy: usize,
    ncols: usize,
) {
    let k = pattern.dim();
    if k == 0 || ncols == 0 {
        return;
    }
    assert!(
        ncols <= ldx && ncols <= ldy,
        "upper products: ncols exceeds a stride"
    );
    assert!(
        x.len() >= (k - 1) * ldx + ncols,
        "upper products: x too short"
    );
    let len = (k - 1) * ldy + ncols;
    let seg = pattern.segment_rows;
    // Per segment, the N output slabs.
    let mut slabs: Vec<[&mut [f64]; N]> = Vec::with_capacity(pattern.segments());
    let mut iters = ys.map(|y| {
        assert!(y.len() >= len, "upper products: y too short");
        y[..len].chunks_mut(seg * ldy)
    });
    for _ in 0..pattern.segments() {
        slabs.push(std::array::from_fn(|n| {
            iters[n]
                .next()
                .unwrap_or_else(|| unreachable!("one chunk per segment"))
        }));
    }
    let sym = pattern.symbolic();
    let rows = sym.row_idx();
    let fast = crate::simd::avx2_fma();

    slabs.par_iter_mut().enumerate().for_each(|(s, slab)| {
        let r0 = s * seg;
        for j in r0..(r0 + seg).min(k) {
            let range = sym.col_range(j);
            let column = Column {
                rows: &rows[range.clone()],
                vals: vals.map(|v| &v[range.clone()]),
                own: pattern.own_start[j] as usize - range.start,
                j,
            };
            let mut c0 = 0;
            while c0 < ncols {
                let out = Slab { r0, ldy, c0 };
                let w = match ncols - c0 {
                    w if w >= 16 => {
                        column_step_dispatch::<N, 16>(fast, &column, x, ldx, &out, slab);
                        16
                    }
                    w if w >= 8 => {
                        column_step_dispatch::<N, 8>(fast, &column, x, ldx, &out, slab);
                        8
                    }
                    w => {
                        column_step_narrow(&column, x, ldx, &out, w, slab);
                        w
                    }
                };
                c0 += w;
            }
        }
    });
    slabs.par_iter_mut().enumerate().for_each(|(t, slab)| {
        let r0 = t * seg;
        for run in &pattern.cross[t] {
            let (j, lo, hi) = (run.col as usize, run.lo as usize, run.hi as usize);
            let column = Column {
                rows: &rows[lo..hi],
                vals: vals.map(|v| &v[lo..hi]),
                own: 0,
                j,
            };
            let mut c0 = 0;
            while c0 < ncols {
                let out = Slab { r0, ldy, c0 };
                let w = if ncols - c0 >= 16 {
                    16
                } else {
                    8.min(ncols - c0)
                };
                match w {
                    16 => scatter_dispatch::<N, 16>(fast, &column, x, ldx, &out, slab),
                    8 => scatter_dispatch::<N, 8>(fast, &column, x, ldx, &out, slab),
                    w => scatter_narrow(&column, x, ldx, &out, w, slab),
                }
                c0 += w;
            }
        }
    });
}

/// Column j of the pattern with the N matrices' values: `own` is the first entry whose row
/// lies in j's segment.
struct Column<'a, const N: usize> {
    rows: &'a [u32],
    vals: [&'a [f64]; N],
    own: usize,
    j: usize,
}

/// Where a segment's outputs go: its first row `r0`, the row stride, the first output column.
struct Slab {
    r0: usize,
    ldy: usize,
    c0: usize,
}

/// [`column_step`] for W output columns, compiled with AVX2 + FMA when `fast` (the CPU has
/// them): the same arithmetic, no fused multiply-adds.
#[inline(always)]
fn column_step_dispatch<const N: usize, const W: usize>(
    fast: bool,
    column: &Column<'_, N>,
    x: &[f64],
    ldx: usize,
    out: &Slab,
    slab: &mut [&mut [f64]; N],
) {
    #[cfg(target_arch = "x86_64")]
    if fast {
        // SAFETY: `fast` says the CPU has AVX2 and FMA.
        return unsafe { column_step_avx2::<N, W>(column, x, ldx, out, slab) };
    }
    let _ = fast;
    column_step::<N, W>(column, x, ldx, out, slab)
}

/// [`column_step`] compiled with AVX2 + FMA.
///
/// # Safety
/// The CPU must have AVX2 and FMA.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
unsafe fn column_step_avx2<const N: usize, const W: usize>(
    column: &Column<'_, N>,
    x: &[f64],
    ldx: usize,
    out: &Slab,
    slab: &mut [&mut [f64]; N],
) {
    column_step::<N, W>(column, x, ldx, out, slab)
}

/// Column j's part of the first pass for the W output columns from `out.c0`: y_j = the sum
/// over the stored entries of a_ij x_i (in registers, one read of each X row for the N
/// matrices), then y_i += a_ij x_j for the entries from `own` on with i != j (rows of this
/// segment, already holding their own gather: they are earlier columns).
#[inline(always)]
fn column_step<const N: usize, const W: usize>(
    column: &Column<'_, N>,
    x: &[f64],
    ldx: usize,
    out: &Slab,
    slab: &mut [&mut [f64]; N],
) {
    let (rows, c0, ldy) = (column.rows, out.c0, out.ldy);
    let mut acc = [[0.0f64; W]; N];
    for (t, &i) in rows.iter().enumerate() {
        let xi = sparse::fixed_row::<W>(x, i as usize * ldx + c0);
        for n in 0..N {
            let v = column.vals[n][t];
            for (a, &xv) in acc[n].iter_mut().zip(xi) {
                *a += v * xv;
            }
        }
    }
    scatter::<N, W>(column, column.own..rows.len() - 1, x, ldx, out, slab);
    let at = (column.j - out.r0) * ldy + c0;
    for n in 0..N {
        slab[n][at..at + W].copy_from_slice(&acc[n]);
    }
}

/// y_i += a_ij x_j for the entries `range` of `column` (rows of the segment from `out.r0`),
/// the W columns from `out.c0`, x_j's W values in registers.
#[inline(always)]
fn scatter<const N: usize, const W: usize>(
    column: &Column<'_, N>,
    range: std::ops::Range<usize>,
    x: &[f64],
    ldx: usize,
    out: &Slab,
    slab: &mut [&mut [f64]; N],
) {
    let xj = *sparse::fixed_row::<W>(x, column.j * ldx + out.c0);
    for t in range {
        let at = (column.rows[t] as usize - out.r0) * out.ldy + out.c0;
        for n in 0..N {
            let v = column.vals[n][t];
            let y: &mut [f64; W] = (&mut slab[n][at..at + W])
                .try_into()
                .unwrap_or_else(|_| unreachable!("a slice of length W"));
            for (y, &xv) in y.iter_mut().zip(&xj) {
                *y += v * xv;
            }
        }
    }
}

/// The second pass over one run (`column.rows`, all in the segment from `out.r0`), W columns,
/// compiled with AVX2 + FMA when `fast`.
#[inline(always)]
fn scatter_dispatch<const N: usize, const W: usize>(
    fast: bool,
    column: &Column<'_, N>,
    x: &[f64],
    ldx: usize,
    out: &Slab,
    slab: &mut [&mut [f64]; N],
) {
    #[cfg(target_arch = "x86_64")]
    if fast {
        // SAFETY: `fast` says the CPU has AVX2 and FMA.
        return unsafe { scatter_avx2::<N, W>(column, x, ldx, out, slab) };
    }
    let _ = fast;
    scatter::<N, W>(column, 0..column.rows.len(), x, ldx, out, slab)
}

/// [`scatter`] over a whole run, compiled with AVX2 + FMA.
///
/// # Safety
/// The CPU must have AVX2 and FMA.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
unsafe fn scatter_avx2<const N: usize, const W: usize>(
    column: &Column<'_, N>,
    x: &[f64],
    ldx: usize,
    out: &Slab,
    slab: &mut [&mut [f64]; N],
) {
    scatter::<N, W>(column, 0..column.rows.len(), x, ldx, out, slab)
}

/// The second pass over one run for fewer than 8 columns, one at a time.
fn scatter_narrow<const N: usize>(
    column: &Column<'_, N>,
    x: &[f64],
    ldx: usize,
    out: &Slab,
    w: usize,
    slab: &mut [&mut [f64]; N],
) {
    for n in 0..N {
        for c in out.c0..out.c0 + w {
            let xj = x[column.j * ldx + c];
            for (&i, &v) in column.rows.iter().zip(column.vals[n]) {
                slab[n][(i as usize - out.r0) * out.ldy + c] += v * xj;
            }
        }
    }
}

/// [`column_step`] for a last group narrower than 8 (`w` columns), one column at a time.
fn column_step_narrow<const N: usize>(
    column: &Column<'_, N>,
    x: &[f64],
    ldx: usize,
    out: &Slab,
    w: usize,
    slab: &mut [&mut [f64]; N],
) {
    let (rows, ldy) = (column.rows, out.ldy);
    let last = rows.len() - 1;
    for n in 0..N {
        let vals = column.vals[n];
        for c in out.c0..out.c0 + w {
            let mut acc = 0.0;
            for (&i, &v) in rows.iter().zip(vals) {
                acc += v * x[i as usize * ldx + c];
            }
            let xj = x[column.j * ldx + c];
            for (&i, &v) in rows[column.own..last].iter().zip(&vals[column.own..last]) {
                slab[n][(i as usize - out.r0) * ldy + c] += v * xj;
            }
            slab[n][(column.j - out.r0) * ldy + c] = acc;
        }
    }
}

#[cfg(test)]
mod tests;
