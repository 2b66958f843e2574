//! Preallocated storage of one LOBPCG run: the tall row-major blocks S = [X | P | W], H S and
//! M S, a tall temporary, and the small dense matrices of the Rayleigh-Ritz step. Everything
//! is allocated once (in `State::new`, iterate.rs); the iteration only takes views.

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::evd::{self_adjoint_evd, self_adjoint_evd_scratch, ComputeEigenvectors};
use faer::linalg::matmul::triangular::BlockStructure;
use faer::{Accum, Mat, MatMut, MatRef, Par};
use rayon::prelude::*;
use std::cell::RefCell;

/// Rows per task in the row-parallel block loops (fixed: results do not depend on threads).
pub(super) const ROW_CHUNK: usize = 1024;

/// A K x `ld` row-major buffer. Logical blocks are column ranges `[c0, c0 + w)`.
#[derive(Debug)]
pub(super) struct Block {
    pub data: Vec<f64>,
    pub rows: usize,
    pub ld: usize,
}

impl Block {
    pub fn new(rows: usize, ld: usize) -> Self {
        Self {
            data: vec![0.0; rows * ld],
            rows,
            ld,
        }
    }

    /// View of columns `c0..c0 + w` (K x w, row stride `ld`).
    pub fn cols(&self, c0: usize, w: usize) -> MatRef<'_, f64> {
        MatRef::from_row_major_slice_with_stride(&self.data[c0..], self.rows, w, self.ld)
    }

    /// Mutable view of columns `c0..c0 + w`.
    ///
    /// Built as the transpose of a column-major view: faer 0.24.4's
    /// `MatMut::from_row_major_slice_with_stride_mut` swaps the strides (it returns a
    /// column-major view), so it must not be used.
    pub fn cols_mut(&mut self, c0: usize, w: usize) -> MatMut<'_, f64> {
        MatMut::from_column_major_slice_with_stride_mut(&mut self.data[c0..], w, self.rows, self.ld)
            .transpose_mut()
    }
}

/// Rows per task in the tall dense products below. Fixed, so the split (and the order of the
/// partial sums) does not depend on the thread count: the results are bit-identical for any
/// number of threads. 2048 rows x 120 columns is ~60 Mflop per Gram task.
pub(super) const DENSE_CHUNK: usize = 2048;

/// Row-major view of rows `0..rows` and columns `c0..c0 + n` of a chunk of a block.
fn chunk_view(chunk: &[f64], ld: usize, c0: usize, n: usize) -> MatRef<'_, f64> {
    let rows = chunk.len() / ld;
    MatRef::from_row_major_slice_with_stride(&chunk[c0..], rows, n, ld)
}

/// Mutable counterpart of [`chunk_view`] (through a transposed column-major view, see
/// [`Block::cols_mut`]).
fn chunk_view_mut(chunk: &mut [f64], ld: usize, c0: usize, n: usize) -> MatMut<'_, f64> {
    let rows = chunk.len() / ld;
    MatMut::from_column_major_slice_with_stride_mut(&mut chunk[c0..], n, rows, ld).transpose_mut()
}

/// Preallocated per-chunk partial results of the K-long inner products.
#[derive(Debug)]
pub(super) struct Partials {
    parts: Vec<Mat<f64>>,
}

impl Partials {
    /// For blocks of `rows` rows and inner products of at most `nmax` x `nmax`.
    pub fn new(rows: usize, nmax: usize) -> Self {
        Self {
            parts: (0..rows.div_ceil(DENSE_CHUNK).max(1))
                .map(|_| Mat::zeros(nmax, nmax))
                .collect(),
        }
    }
}

/// g = A^T B with A = columns `ca..ca + g.nrows()` of `a`, B = columns `cb..cb + g.ncols()` of
/// `b` (both K rows). Each chunk of rows is multiplied sequentially in its own task, and the
/// partial products are added in chunk order (deterministic for any thread count). With
/// `lower`, only the lower triangle of g is computed (square g; half the flops).
pub(super) fn inner(
    mut g: MatMut<'_, f64>,
    a: &Block,
    ca: usize,
    b: &Block,
    cb: usize,
    parts: &mut Partials,
    lower: bool,
) {
    let (n1, n2) = (g.nrows(), g.ncols());
    let (lda, ldb) = (a.ld, b.ld);
    let nchunks = a.rows.div_ceil(DENSE_CHUNK);
    parts.parts[..nchunks]
        .par_iter_mut()
        .zip(a.data.par_chunks(lda * DENSE_CHUNK))
        .zip(b.data.par_chunks(ldb * DENSE_CHUNK))
        .for_each(|((p, ac), bc)| {
            let av = chunk_view(ac, lda, ca, n1);
            let bv = chunk_view(bc, ldb, cb, n2);
            let dst = p.as_mut().submatrix_mut(0, 0, n1, n2);
            if lower {
                faer::linalg::matmul::triangular::matmul(
                    dst,
                    BlockStructure::TriangularLower,
                    Accum::Replace,
                    av.transpose(),
                    BlockStructure::Rectangular,
                    bv,
                    BlockStructure::Rectangular,
                    1.0,
                    Par::Seq,
                );
            } else {
                faer::linalg::matmul::matmul(
                    dst,
                    Accum::Replace,
                    av.transpose(),
                    bv,
                    1.0,
                    Par::Seq,
                );
            }
        });
    for j in 0..n2 {
        let i0 = if lower { j } else { 0 };
        for i in i0..n1 {
            let mut sum = 0.0;
            for p in &parts.parts[..nchunks] {
                sum += p[(i, j)];
            }
            g[(i, j)] = sum;
        }
    }
}

/// In place, row by row: columns `c0..c0 + c.ncols()` of `blk` become
/// (columns `s0..s0 + c.nrows()` of `blk`) * c. The source and destination column ranges may
/// overlap.
pub(super) fn transform(blk: &mut Block, s0: usize, c: MatRef<'_, f64>, c0: usize) {
    chunk_products(blk, s0, c, |brow, trow| {
        brow[c0..c0 + trow.len()].copy_from_slice(trow)
    });
}

/// In place, row by row: columns `w0..w0 + c.ncols()` of `blk` -= (columns
/// `0..c.nrows()` of `blk`) * c. The two column ranges must not overlap.
pub(super) fn subtract_product(blk: &mut Block, c: MatRef<'_, f64>, w0: usize) {
    if c.nrows() == 0 {
        return;
    }
    chunk_products(blk, 0, c, |brow, trow| {
        for (x, y) in brow[w0..w0 + trow.len()].iter_mut().zip(trow) {
            *x -= *y;
        }
    });
}

thread_local! {
    /// Each thread's scratch for [`chunk_products`]: DENSE_CHUNK rows of the widest update
    /// (1.3 MB at 80 columns), allocated once per thread instead of once per call.
    static CHUNK_SCRATCH: RefCell<Vec<f64>> = const { RefCell::new(Vec::new()) };
}

/// For each chunk of DENSE_CHUNK rows of `blk`: t = (its columns `s0..s0 + c.nrows()`) * c,
/// then `update(row of blk, row of t)` row by row. t lives in the thread's scratch of
/// DENSE_CHUNK rows: a K-row scratch would cost a block of memory (0.64 GB at K = 1,000,000
/// for the Rayleigh-Ritz update).
fn chunk_products(
    blk: &mut Block,
    s0: usize,
    c: MatRef<'_, f64>,
    update: impl Fn(&mut [f64], &[f64]) + Sync,
) {
    let (n, nout) = (c.nrows(), c.ncols());
    if nout == 0 {
        return;
    }
    let ld = blk.ld;
    blk.data.par_chunks_mut(ld * DENSE_CHUNK).for_each(|bc| {
        // Nothing below re-enters chunk_products (the product is sequential), so the borrow
        // is the thread's only one.
        CHUNK_SCRATCH.with_borrow_mut(|scratch| {
            let t = bc.len() / ld * nout;
            if scratch.len() < t {
                scratch.resize(t, 0.0);
            }
            let scratch = &mut scratch[..t];
            {
                let src = chunk_view(bc, ld, s0, n);
                let dst = chunk_view_mut(scratch, nout, 0, nout);
                faer::linalg::matmul::matmul(dst, Accum::Replace, src, c, 1.0, Par::Seq);
            }
            for (brow, trow) in bc.chunks_mut(ld).zip(scratch.chunks(nout)) {
                update(brow, trow);
            }
        })
    });
}

/// Columns `c0..c0 + row.len()` of `blk` -= y row^T (y: K values).
pub(super) fn subtract_rank1(blk: &mut Block, c0: usize, y: &[f64], row: &[f64]) {
    let ld = blk.ld;
    let w = row.len();
    blk.data
        .par_chunks_mut(ld * DENSE_CHUNK)
        .zip(y.par_chunks(DENSE_CHUNK))
        .for_each(|(bc, yc)| {
            for (brow, &yi) in bc.chunks_mut(ld).zip(yc) {
                for (x, &r) in brow[c0..c0 + w].iter_mut().zip(row) {
                    *x -= yi * r;
                }
            }
        });
}

/// Small symmetric eigensolver with preallocated scratch for matrices up to `nmax` x `nmax`.
pub(super) struct SmallEig {
    mem: MemBuffer,
    pub values: Vec<f64>,
    pub vectors: Mat<f64>,
    values_diag: Mat<f64>,
}

impl std::fmt::Debug for SmallEig {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "SmallEig({})", self.values.len())
    }
}

impl SmallEig {
    pub fn new(nmax: usize) -> Self {
        let req = self_adjoint_evd_scratch::<f64>(
            nmax.max(1),
            ComputeEigenvectors::Yes,
            Par::Seq,
            crate::eigen::accurate_evd_params(),
        );
        Self {
            mem: MemBuffer::new(req),
            values: vec![0.0; nmax],
            vectors: Mat::zeros(nmax, nmax),
            values_diag: Mat::zeros(nmax, 1),
        }
    }

    /// Eigendecomposition of the symmetric n x n matrix `a` (lower triangle read): ascending
    /// eigenvalues in `values[..n]`, orthonormal eigenvectors in `vectors[.., ..n]`.
    /// Returns false if the QR iteration did not converge or produced non-finite values.
    pub fn compute(&mut self, a: MatRef<'_, f64>) -> bool {
        let n = a.nrows();
        if n == 0 {
            return true;
        }
        let stack = MemStack::new(&mut self.mem);
        let diag = self
            .values_diag
            .as_mut()
            .subrows_mut(0, n)
            .col_mut(0)
            .as_diagonal_mut();
        let u = self.vectors.as_mut().submatrix_mut(0, 0, n, n);
        let ok = self_adjoint_evd(
            a,
            diag,
            Some(u),
            Par::Seq,
            stack,
            crate::eigen::accurate_evd_params(),
        )
        .is_ok();
        for i in 0..n {
            self.values[i] = self.values_diag[(i, 0)];
        }
        ok && self.values[..n].iter().all(|v| v.is_finite())
    }
}

/// Symmetrize the leading n x n block of `a` in place: a = (a + a^T) / 2.
pub(super) fn symmetrize(a: &mut Mat<f64>, n: usize) {
    for j in 0..n {
        for i in j + 1..n {
            let v = 0.5 * (a[(i, j)] + a[(j, i)]);
            a[(i, j)] = v;
            a[(j, i)] = v;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn small_eig_and_views() {
        let n = 5;
        let a = Mat::from_fn(n, n, |i, j| {
            if i == j {
                (n - i) as f64
            } else {
                0.1 / (1.0 + (i + j) as f64)
            }
        });
        let mut e = SmallEig::new(8);
        assert!(e.compute(a.as_ref()));
        let v = e.vectors.as_ref().submatrix(0, 0, n, n);
        let d = Mat::from_fn(n, n, |i, j| if i == j { e.values[i] } else { 0.0 });
        let r = &a * v - v * &d;
        eprintln!("{:?}", &e.values[..n]);
        assert!(r.norm_max() < 1e-13);
        assert!(e.values[..n].windows(2).all(|w| w[0] <= w[1]));
        let mut b = Block::new(7, 6);
        for (i, x) in b.data.iter_mut().enumerate() {
            *x = i as f64;
        }
        let v = b.cols(2, 3);
        assert_eq!(v[(1, 0)], 8.0);
        assert_eq!(v[(6, 2)], 40.0);
        // Mutable views address the same elements (regression: faer's row-major mutable
        // constructor swaps the strides).
        let mut b2 = Block::new(7, 6);
        b2.cols_mut(2, 3).copy_from(v);
        assert_eq!(b2.data[6 * 6 + 4], 40.0);
        assert_eq!(b2.cols(2, 3), v);
        // Chunked inner products and in-place transforms agree with plain products.
        let mut parts = Partials::new(7, 6);
        let mut g = Mat::zeros(3, 3);
        inner(g.as_mut(), &b, 2, &b, 2, &mut parts, false);
        let expect = v.transpose() * v;
        assert!((&g - &expect).norm_max() < 1e-12);
        let c = Mat::from_fn(3, 2, |i, j| (i + 2 * j) as f64 - 1.5);
        let before = b.cols(2, 3).to_owned();
        transform(&mut b, 2, c.as_ref(), 1);
        assert!((b.cols(1, 2) - &before * &c).norm_max() < 1e-12);
    }

    #[test]
    fn chunked_products_span_several_chunks_and_widths() {
        // Three chunks (the last short), then a narrower product through the same scratch.
        let (k, ld) = (2 * DENSE_CHUNK + 5, 7);
        let mut b = Block::new(k, ld);
        for (i, v) in b.data.iter_mut().enumerate() {
            *v = ((i * 37) % 101) as f64 / 50.0 - 1.0;
        }
        let src = b.cols(0, 3).to_owned();
        let c = Mat::from_fn(3, 4, |i, j| (i as f64 - 1.0) * 0.5 + j as f64);
        transform(&mut b, 0, c.as_ref(), 3);
        // Each entry is a 3-term sum of products of O(1) values: round-off ~1e-15.
        assert!((b.cols(3, 4) - &src * &c).norm_max() < 1e-13);
        let before = b.cols(3, 2).to_owned();
        let d = Mat::from_fn(3, 2, |i, j| 0.25 * (i + j) as f64 - 0.3);
        subtract_product(&mut b, d.as_ref(), 3);
        assert!((b.cols(3, 2) - (&before - &src * &d)).norm_max() < 1e-13);
        assert_eq!(b.cols(0, 3), src, "the source columns are untouched");
    }
}
