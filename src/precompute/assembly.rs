//! Sparse assembly of the weight-space Hessian (Prop. 1) and the consistent RKPM mass matrix,
//! streamed over chunks of integration points:
//!
//! ```text
//! (H_w)_kl = sum_i v_i (lambda_i + 4 mu_i) grad phi_k(X_i) . grad phi_l(X_i)     [Pa m]
//! M_kl     = sum_i v_i phi_k(X_i) phi_l(X_i)                                    [m^3]
//! ```
//!
//! An [`Accumulator`] holds the upper triangle (columns l >= k) of both matrices, row by row,
//! and takes the shape functions of one chunk of points at a time ([`Accumulator::add`]), so
//! memory is O(nnz(H_w)) plus one chunk, whatever the number of points. Each entry is one
//! running sum over the points in the order they are added: for a chunk, the rows are
//! updated in parallel (a row belongs to one task), and a row's sums continue from where the
//! previous chunk left them. The result is therefore the same bit for bit for any chunk size
//! and thread count, and [`Accumulator::finish`] mirrors the upper triangle, so it is exactly
//! symmetric.

use super::rkpm::ShapeFunctions;
use crate::eigen::RowPencil;
use crate::simd;
use crate::sparse::{self, SparseMatrix, SparseMatrixRef};
use crate::triangle::{UpperPattern, UpperPencil};
use crate::{Error, Result};
use faer::sparse::SymbolicSparseColMat;
use rayon::prelude::*;
use std::sync::OnceLock;

/// H_w and M, K x K, with one sparsity pattern held once for both: both triangles (20 bytes a
/// stored entry: two f64 values, one u32 row index), or the upper triangle alone
/// ([`crate::triangle::UpperPencil`], half that; [`super::options::MatrixStorage`]).
/// [`Assembled::hessian`] and [`Assembled::mass`] are views of the both-triangle matrices: of
/// upper-triangle storage they mirror it on first use (the memory of full storage on top).
#[derive(Debug, Clone)]
pub struct Assembled {
    /// Both triangles: set at construction, or mirrored from `upper` on first use.
    full: OnceLock<Full>,
    upper: Option<UpperPencil>,
}

/// Both triangles of H_w and M on one pattern.
#[derive(Debug, Clone)]
struct Full {
    pattern: SymbolicSparseColMat<u32>,
    hessian: Vec<f64>,
    mass: Vec<f64>,
}

impl Assembled {
    /// The pencil from compressed arrays shared by both matrices (as
    /// [`sparse::from_compressed`]; values in stored order).
    ///
    /// # Panics
    /// On violated structural invariants (unsorted or out-of-range indices, value arrays of
    /// another length), which the assembly rules out by construction.
    fn from_compressed(
        k: usize,
        ptr: Vec<u32>,
        idx: Vec<u32>,
        hessian: Vec<f64>,
        mass: Vec<f64>,
    ) -> Self {
        let pattern = SymbolicSparseColMat::new_checked(k, k, ptr, None, idx);
        assert!(
            hessian.len() == pattern.row_idx().len() && mass.len() == hessian.len(),
            "Assembled: one value per stored entry"
        );
        Assembled {
            full: OnceLock::from(Full {
                pattern,
                hessian,
                mass,
            }),
            upper: None,
        }
    }

    /// The pencil stored as upper triangles (H_w first, M second).
    pub fn from_upper(upper: UpperPencil) -> Self {
        Assembled {
            full: OnceLock::new(),
            upper: Some(upper),
        }
    }

    /// Both triangles, mirrored from the upper triangles on first use.
    fn full(&self) -> &Full {
        self.full.get_or_init(|| match &self.upper {
            Some(upper) => {
                let (pattern, hessian, mass) = upper.to_full();
                Full {
                    pattern,
                    hessian,
                    mass,
                }
            }
            // Every constructor sets `full` or `upper`.
            None => unreachable!("Assembled holds full or upper storage"),
        })
    }

    /// Weight-space Hessian H_w, K x K, Pa m (units of E x length), both triangles.
    pub fn hessian(&self) -> SparseMatrixRef<'_> {
        let full = self.full();
        SparseMatrixRef::new(full.pattern.as_ref(), &full.hessian)
    }

    /// Consistent mass matrix M, K x K, m^3 (density is not in it), both triangles.
    pub fn mass(&self) -> SparseMatrixRef<'_> {
        let full = self.full();
        SparseMatrixRef::new(full.pattern.as_ref(), &full.mass)
    }

    /// Both triangles only: upper-triangle storage is mirrored and then dropped (the peak is
    /// both storages at once, as while the assembly mirrors); full storage as it is.
    pub fn into_full(self) -> Assembled {
        self.full();
        Assembled {
            full: self.full,
            upper: None,
        }
    }

    /// H_w and M as upper triangles, when that is how they are stored.
    pub fn upper(&self) -> Option<&UpperPencil> {
        self.upper.as_ref()
    }

    /// Entries of each matrix with both triangles counted (as if stored in full).
    pub fn nnz(&self) -> usize {
        match (&self.upper, self.full.get()) {
            (_, Some(full)) => full.hessian.len(),
            (Some(upper), None) => 2 * upper.pattern().nnz() - upper.pattern().dim(),
            (None, None) => unreachable!("Assembled holds full or upper storage"),
        }
    }

    /// H_w and M as two owned matrices (the pattern copied for the second).
    pub fn into_pair(self) -> (SparseMatrix, SparseMatrix) {
        self.full();
        let full = self
            .full
            .into_inner()
            .unwrap_or_else(|| unreachable!("set by full() above"));
        let pattern = full.pattern.clone();
        (
            SparseMatrix::new(full.pattern, full.hessian),
            SparseMatrix::new(pattern, full.mass),
        )
    }
}

/// An error for the first non-finite sum of H_w's values then M's.
fn check_finite(hval: &[f64], mval: &[f64]) -> Result<()> {
    match hval.iter().chain(mval).position(|v| !v.is_finite()) {
        Some(bad) => Err(Error::NonFinite {
            what: "assembled matrices (check volumes and material values)",
            index: bad,
        }),
        None => Ok(()),
    }
}

/// One upper-triangle row: columns ascending, with the H and M sums.
#[derive(Debug, Clone, Default)]
struct Row {
    cols: Box<[u32]>,
    h: Box<[f64]>,
    m: Box<[f64]>,
}

/// Running sums of H_w and M over the chunks of points added so far.
#[derive(Debug, Clone)]
pub struct Accumulator {
    rows: Vec<Row>,
    /// The rows wanted (all of them, or one MPI rank's block): entries with neither index in
    /// it are not summed.
    own: std::ops::Range<usize>,
    /// Scratch: kernel -> index among the current chunk's kernels (`NONE` outside a chunk).
    local: Vec<u32>,
}

const NONE: u32 = u32::MAX;

/// Rows per parallel task within a chunk.
const ROWS_PER_TASK: usize = 64;

/// How many of a row's points ahead the update prefetches a point's entries.
const PREFETCH_AHEAD: usize = 4;

impl Accumulator {
    /// Empty sums for `k` kernels.
    ///
    /// # Errors
    /// [`Error::InvalidParameter`] when `k` does not fit the u32 kernel indices.
    pub fn new(k: usize) -> Result<Self> {
        if k >= NONE as usize {
            return Err(Error::param(
                "kernels",
                k,
                "too many kernels for u32 indices",
            ));
        }
        Ok(Self {
            rows: vec![Row::default(); k],
            own: 0..k,
            local: vec![NONE; k],
        })
    }

    /// Empty sums for rows `own` of K = `k` kernels only (one MPI rank's block): an entry
    /// (i, j) is summed when i or j is in `own`, so the rows come out complete when the points
    /// added are all points of those kernels' supports. Each summed entry is the same running
    /// sum as in [`Accumulator::new`]'s, bit for bit. Finish with [`Accumulator::finish_rows`].
    ///
    /// # Errors
    /// As [`Accumulator::new`]; [`Error::InvalidParameter`] when `own` is not within 0..k.
    pub fn for_rows(k: usize, own: std::ops::Range<usize>) -> Result<Self> {
        if own.start > own.end || own.end > k {
            return Err(Error::param(
                "rows",
                format!("{own:?}"),
                format!("not a row range of {k} kernels"),
            ));
        }
        Ok(Self {
            own,
            ..Self::new(k)?
        })
    }

    /// Number of kernels K.
    pub fn kernels(&self) -> usize {
        self.rows.len()
    }

    /// Stored upper-triangle entries so far (diagonal included).
    pub fn upper_nnz(&self) -> usize {
        self.rows.iter().map(|r| r.cols.len()).sum()
    }

    /// Add the contributions of the points of `sf` (one chunk, after every chunk added
    /// before it), with volumes `volumes` (m^3) and Hessian weights `weights`
    /// (lambda + 4 mu, Pa), one per point.
    ///
    /// # Errors
    /// [`Error::LengthMismatch`] when `volumes` or `weights` do not have one entry per point,
    /// [`Error::InvalidParameter`] when a kernel index is out of range.
    pub fn add(&mut self, sf: &ShapeFunctions, volumes: &[f64], weights: &[f64]) -> Result<()> {
        let n = sf.rows();
        check_point_lengths(n, volumes, weights)?;
        let k = self.rows.len();
        if let Some(&bad) = sf.pattern.kernels.iter().find(|&&j| j as usize >= k) {
            return Err(Error::param(
                "kernels",
                bad,
                format!("kernel index out of range (K = {k})"),
            ));
        }
        // The chunk's kernels, ascending, and its pattern in their local numbering (the
        // order is the same, so each point's local row stays sorted).
        let mut present: Vec<u32> = Vec::new();
        for &j in &sf.pattern.kernels {
            if self.local[j as usize] == NONE {
                self.local[j as usize] = 0;
                present.push(j);
            }
        }
        present.sort_unstable();
        for (l, &j) in present.iter().enumerate() {
            self.local[j as usize] = l as u32;
        }
        let kl = present.len();
        // The wanted rows' span in local numbering (local order is global order).
        let own_local = (
            present.partition_point(|&j| (j as usize) < self.own.start) as u32,
            present.partition_point(|&j| (j as usize) < self.own.end) as u32,
        );
        let lpat: Vec<u32> = sf
            .pattern
            .kernels
            .iter()
            .map(|&j| self.local[j as usize])
            .collect();
        // Transpose: for each local kernel, the (point, entry) pairs it covers, points
        // ascending.
        let mut tptr = vec![0usize; kl + 1];
        for &l in &lpat {
            tptr[l as usize + 1] += 1;
        }
        for i in 0..kl {
            tptr[i + 1] += tptr[i];
        }
        let mut fill = tptr.clone();
        let mut tpoint = vec![0u32; lpat.len()];
        let mut tentry = vec![0u32; lpat.len()];
        for p in 0..n {
            for e in sf.pattern.ptr[p]..sf.pattern.ptr[p + 1] {
                let l = lpat[e] as usize;
                tpoint[fill[l]] = p as u32;
                tentry[fill[l]] = e as u32;
                fill[l] += 1;
            }
        }
        drop(fill);
        // Move the chunk's rows out, update them in parallel, put them back.
        let mut work: Vec<Row> = present
            .iter()
            .map(|&j| std::mem::take(&mut self.rows[j as usize]))
            .collect();
        let chunk = ChunkView {
            sf,
            lpat: &lpat,
            local: &self.local,
            present: &present,
            own_local,
            volumes,
            weights,
            tptr: &tptr,
            tpoint: &tpoint,
            tentry: &tentry,
        };
        work.par_chunks_mut(ROWS_PER_TASK)
            .enumerate()
            .for_each(|(t, rows)| chunk.update(t * ROWS_PER_TASK, rows));
        for (&j, row) in present.iter().zip(work) {
            self.rows[j as usize] = row;
            self.local[j as usize] = NONE;
        }
        Ok(())
    }

    /// Mirror the upper triangle into H_w and M (full symmetric CSC, K x K).
    ///
    /// # Errors
    /// [`Error::InvalidParameter`] for an accumulator of some rows only
    /// ([`Accumulator::for_rows`]); [`Error::NonFinite`] when a sum is not finite (bad volumes or material values).
    pub fn finish(self) -> Result<Assembled> {
        let k = self.whole()?;
        let mut rows = self.rows;
        let (ptr, idx, hval, mval) = mirror(&mut rows, k)?;
        drop(rows);
        crate::report::release_freed_memory();
        check_finite(&hval, &mval)?;
        Ok(Assembled::from_compressed(k, ptr, idx, hval, mval))
    }

    /// K, or an error for an accumulator of some rows only (no whole matrices).
    fn whole(&self) -> Result<usize> {
        let k = self.rows.len();
        if self.own != (0..k) {
            return Err(Error::param(
                "rows",
                format!("{:?}", self.own),
                "an accumulator of some rows only has no full matrices: use finish_rows",
            ));
        }
        Ok(k)
    }
}

impl Accumulator {
    /// H_w and M as upper triangles of one pattern ([`UpperPencil`], CSC: column j holds rows
    /// i <= j ascending), the same sums as [`Accumulator::finish`]'s matrices, bit for bit,
    /// in half their memory. Each accumulated row is freed once moved.
    ///
    /// # Errors
    /// As [`Accumulator::finish`].
    pub fn finish_upper(self) -> Result<Assembled> {
        let k = self.whole()?;
        let mut rows = self.rows;
        // Row i of the upper triangle holds columns j >= i; column j of the CSC gets them in
        // ascending i, so its rows are sorted and its diagonal (from row j) comes last.
        let mut ptr = vec![0u32; k + 1];
        for r in &rows {
            for &j in r.cols.iter() {
                ptr[j as usize + 1] += 1;
            }
        }
        for j in 0..k {
            ptr[j + 1] = ptr[j]
                .checked_add(ptr[j + 1])
                .ok_or_else(|| Error::param("kernels", k, "more than u32::MAX stored entries"))?;
        }
        let nnz = ptr[k] as usize;
        let (mut idx, mut hval, mut mval) = (vec![0u32; nnz], vec![0.0; nnz], vec![0.0; nnz]);
        let mut next = ptr[..k].to_vec();
        for (i, row) in rows.iter_mut().enumerate() {
            let r = std::mem::take(row);
            for (e, &j) in r.cols.iter().enumerate() {
                let at = next[j as usize] as usize;
                idx[at] = i as u32;
                hval[at] = r.h[e];
                mval[at] = r.m[e];
                next[j as usize] += 1;
            }
        }
        drop((rows, next));
        crate::report::release_freed_memory();
        check_finite(&hval, &mval)?;
        let pattern = UpperPattern::new(k, ptr, idx)
            .map_err(|e| Error::param("assembly", "upper triangle", format!("internal: {e}")))?;
        Ok(Assembled::from_upper(UpperPencil::new(pattern, hval, mval)))
    }

    /// The wanted rows ([`Accumulator::for_rows`]) of H_w and M with both triangles, as the
    /// same rows of [`Accumulator::finish`]'s matrices, bit for bit, without forming the
    /// K x K matrices.
    ///
    /// # Errors
    /// [`Error::NonFinite`] when a sum is not finite (bad volumes or material values).
    pub fn finish_rows(self) -> Result<RowPencil> {
        let (a, b) = (self.own.start, self.own.end);
        let mut rows = self.rows;
        let wanted = |j: usize| j >= a && j < b;
        let mut ptr = vec![0usize; b - a + 1];
        for (i, r) in rows[..b].iter().enumerate() {
            if i >= a {
                ptr[i - a + 1] += r.cols.len();
            }
            for &j in r.cols.iter() {
                let j = j as usize;
                if j != i && wanted(j) {
                    ptr[j - a + 1] += 1;
                }
            }
        }
        for r in 0..b - a {
            ptr[r + 1] += ptr[r];
        }
        let nnz = ptr[b - a];
        let (mut cols, mut hv, mut mv) = (vec![0u32; nnz], vec![0.0; nnz], vec![0.0; nnz]);
        // As `mirror`: lower entries first, rows visited ascending, then the row's own upper.
        let mut next = ptr[..b - a].to_vec();
        for (i, r) in rows[..b].iter().enumerate() {
            for (e, &j) in r.cols.iter().enumerate() {
                let j = j as usize;
                if j != i && wanted(j) {
                    let d = next[j - a];
                    cols[d] = i as u32;
                    hv[d] = r.h[e];
                    mv[d] = r.m[e];
                    next[j - a] += 1;
                }
            }
        }
        for i in a..b {
            let r = std::mem::take(&mut rows[i]);
            let d = next[i - a];
            let c = r.cols.len();
            cols[d..d + c].copy_from_slice(&r.cols);
            hv[d..d + c].copy_from_slice(&r.h);
            mv[d..d + c].copy_from_slice(&r.m);
        }
        drop(rows);
        crate::report::release_freed_memory();
        if let Some(bad) = hv.iter().chain(&mv).position(|v| !v.is_finite()) {
            return Err(Error::NonFinite {
                what: "assembled matrices (check volumes and material values)",
                index: bad,
            });
        }
        Ok(RowPencil {
            first: a,
            ptr,
            cols,
            hessian: hv,
            mass: mv,
        })
    }
}

/// Assemble H_w and M from shape functions at all N integration points at once (one chunk
/// of an [`Accumulator`]), with volumes `volumes` (N, m^3) and Hessian weights `weights`
/// (N, lambda + 4 mu, Pa). `k` is the kernel count. For more points than fit in memory as
/// shape functions, stream them instead ([`super::stream::assemble_streamed`]).
///
/// # Errors
/// As [`Accumulator::add`] and [`Accumulator::finish`].
pub fn assemble(
    sf: &ShapeFunctions,
    volumes: &[f64],
    weights: &[f64],
    k: usize,
) -> Result<Assembled> {
    let mut acc = Accumulator::new(k)?;
    acc.add(sf, volumes, weights)?;
    acc.finish()
}

/// [`Error::LengthMismatch`] unless `volumes` and `weights` have one entry per point (`n`).
pub(crate) fn check_point_lengths(n: usize, volumes: &[f64], weights: &[f64]) -> Result<()> {
    for (what, got) in [
        ("volumes", volumes.len()),
        ("hessian weights", weights.len()),
    ] {
        if got != n {
            return Err(Error::LengthMismatch {
                what,
                expected: n,
                got,
            });
        }
    }
    Ok(())
}

/// One chunk's shape functions seen from its kernels.
struct ChunkView<'a> {
    sf: &'a ShapeFunctions,
    /// `sf.pattern.kernels` in local numbering.
    lpat: &'a [u32],
    /// Global kernel -> local index (NONE when not in the chunk).
    local: &'a [u32],
    /// Local index -> global kernel, ascending.
    present: &'a [u32],
    /// Local indices of the wanted rows, `[first, end)`.
    own_local: (u32, u32),
    volumes: &'a [f64],
    weights: &'a [f64],
    tptr: &'a [usize],
    tpoint: &'a [u32],
    tentry: &'a [u32],
}

impl ChunkView<'_> {
    /// Continue the sums of rows `first..first + rows.len()` (local numbering) over the
    /// chunk's points: row i adds, point by point (ascending), the contributions of the
    /// kernels j >= i covering the point. Each point's kernel list is sorted, so those start
    /// right at kernel i's own entry.
    #[inline(never)]
    fn update(&self, first: usize, rows: &mut [Row]) {
        let kl = self.present.len();
        let sf = self.sf;
        let mut acc_h = vec![0.0f64; kl];
        let mut acc_m = vec![0.0f64; kl];
        let mut seen = vec![false; kl];
        // The columns touched by the current row, `touched[..nt]`: a buffer of fixed length
        // (a column is listed once), so the inner loop makes no call that could grow it; a
        // call there would make the compiler keep the loop's floats on the stack.
        let mut touched = vec![0usize; kl];
        let mut nt = 0;
        let (own_lo, own_hi) = (self.own_local.0 as usize, self.own_local.1 as usize);
        for (r, row) in rows.iter_mut().enumerate() {
            let li = first + r;
            if li >= own_hi {
                // Its columns j >= li are all past the wanted rows: nothing to sum.
                continue;
            }
            // Resume the sums of the columns this chunk touches; the others stay as they are.
            for (c, &j) in row.cols.iter().enumerate() {
                let l = self.local[j as usize];
                if l != NONE {
                    let l = l as usize;
                    acc_h[l] = row.h[c];
                    acc_m[l] = row.m[c];
                    seen[l] = true;
                    touched[nt] = l;
                    nt += 1;
                }
            }
            for s in self.tptr[li]..self.tptr[li + 1] {
                // The points of a row lie far apart in the chunk's arrays: fetch the start of
                // a later point's entries while this one is summed.
                if let Some(&ahead) = self.tentry.get(s + PREFETCH_AHEAD) {
                    let ahead = ahead as usize;
                    simd::prefetch(&sf.grad, ahead);
                    simd::prefetch(&sf.phi, ahead);
                    simd::prefetch(self.lpat, ahead);
                }
                let p = self.tpoint[s] as usize;
                let ei = self.tentry[s] as usize;
                let (gi, fi) = (sf.grad[ei], sf.phi[ei]);
                let wh = self.volumes[p] * self.weights[p];
                let wm = self.volumes[p];
                let end = sf.pattern.ptr[p + 1];
                // A row before the wanted ones sums only their columns (a point's kernels are
                // ascending, so they are one stretch).
                let (from, to) = if li < own_lo {
                    let seg = &self.lpat[ei..end];
                    (
                        ei + seg.partition_point(|&j| (j as usize) < own_lo),
                        ei + seg.partition_point(|&j| (j as usize) < own_hi),
                    )
                } else {
                    (ei, end)
                };
                for ((&j, gj), &fj) in self.lpat[from..to]
                    .iter()
                    .zip(&sf.grad[from..to])
                    .zip(&sf.phi[from..to])
                {
                    let j = j as usize;
                    if !seen[j] {
                        seen[j] = true;
                        touched[nt] = j;
                        nt += 1;
                    }
                    acc_h[j] += wh * (gi[0] * gj[0] + gi[1] * gj[1] + gi[2] * gj[2]);
                    acc_m[j] += wm * (fi * fj);
                }
            }
            let touched = &mut touched[..nt];
            touched.sort_unstable();
            // Merge the untouched old columns with the chunk's (both ascending globally).
            let len = row
                .cols
                .iter()
                .filter(|&&j| self.local[j as usize] == NONE)
                .count()
                + touched.len();
            let (mut cols, mut h, mut m) = (
                Vec::with_capacity(len),
                Vec::with_capacity(len),
                Vec::with_capacity(len),
            );
            let mut old = 0;
            for &l in touched.iter() {
                let j = self.present[l];
                while old < row.cols.len() && row.cols[old] < j {
                    if self.local[row.cols[old] as usize] == NONE {
                        cols.push(row.cols[old]);
                        h.push(row.h[old]);
                        m.push(row.m[old]);
                    }
                    old += 1;
                }
                cols.push(j);
                h.push(acc_h[l]);
                m.push(acc_m[l]);
                acc_h[l] = 0.0;
                acc_m[l] = 0.0;
                seen[l] = false;
            }
            for c in old..row.cols.len() {
                if self.local[row.cols[c] as usize] == NONE {
                    cols.push(row.cols[c]);
                    h.push(row.h[c]);
                    m.push(row.m[c]);
                }
            }
            nt = 0;
            *row = Row {
                cols: cols.into_boxed_slice(),
                h: h.into_boxed_slice(),
                m: m.into_boxed_slice(),
            };
        }
    }
}

/// The compressed arrays of H_w and M on their shared pattern: column pointers, row indices,
/// H_w's values, M's values.
type Mirrored = (Vec<u32>, Vec<u32>, Vec<f64>, Vec<f64>);

/// Full symmetric CSR (= CSC) arrays from the upper-triangle rows: entry (i, j) with j > i is
/// also stored as (j, i) with the identical value, so the result is exactly symmetric.
/// Lower entries of a row come first (rows ascending), then its upper entries: columns stay
/// sorted. Each row's storage is released once it is copied.
#[inline(never)]
fn mirror(rows: &mut [Row], k: usize) -> Result<Mirrored> {
    let mut count = vec![0usize; k];
    for (i, r) in rows.iter().enumerate() {
        count[i] += r.cols.len();
        for &j in r.cols.iter() {
            if j as usize != i {
                count[j as usize] += 1;
            }
        }
    }
    let nnz: usize = count.iter().sum();
    // The margin keeps a boundary-aware basis's grounded restriction (nnz + 2 K + 1 entries at
    // most) within range too.
    if nnz + 2 * k + 1 > sparse::MAX_ENTRIES {
        return Err(Error::param(
            "kernels",
            k.to_string(),
            format!(
                "H_w and M would hold {nnz} entries each, more than the {} a SparseMatrix \
                 addresses (u32): use fewer kernels or a smaller support factor",
                sparse::MAX_ENTRIES
            ),
        ));
    }
    // Every partial sum is at most nnz <= u32::MAX (checked above).
    let mut ptr = vec![0u32; k + 1];
    for i in 0..k {
        ptr[i + 1] = ptr[i] + count[i] as u32;
    }
    drop(count);
    let (mut idx, mut hv, mut mv) = (vec![0u32; nnz], vec![0.0; nnz], vec![0.0; nnz]);
    // Lower parts are filled from the front as rows are visited in ascending order, so each
    // row's lower entries end up sorted; its own upper entries go after them.
    let mut next: Vec<usize> = ptr.iter().map(|&p| p as usize).collect();
    for (i, r) in rows.iter().enumerate() {
        for (e, &j) in r.cols.iter().enumerate() {
            let j = j as usize;
            if j != i {
                let d = next[j];
                // Row indices are below k, which u32 kernel indices (Row::cols) address.
                idx[d] = i as u32;
                hv[d] = r.h[e];
                mv[d] = r.m[e];
                next[j] += 1;
            }
        }
    }
    for (i, r) in rows.iter_mut().enumerate() {
        let d = next[i];
        let c = r.cols.len();
        idx[d..d + c].copy_from_slice(&r.cols);
        hv[d..d + c].copy_from_slice(&r.h);
        mv[d..d + c].copy_from_slice(&r.m);
        *r = Row::default();
    }
    Ok((ptr, idx, hv, mv))
}
