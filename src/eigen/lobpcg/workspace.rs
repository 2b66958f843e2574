//! Preallocated storage of one LOBPCG run: the tall row-major blocks S = [X | P | W], H S and
//! M S, a tall temporary, and the small dense matrices of the Rayleigh-Ritz step. Everything
//! is allocated once in [`Workspace::new`]; the iteration only takes views.

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::evd::{self_adjoint_evd, self_adjoint_evd_scratch, ComputeEigenvectors};
use faer::{Accum, Mat, MatMut, MatRef, Par};
use rayon::prelude::*;

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

    /// Copy columns `src0..src0 + w` of `src` into columns `dst0..dst0 + w` of `self`.
    pub fn copy_cols_from(&mut self, dst0: usize, src: &Block, src0: usize, w: usize) {
        let (ld, sld) = (self.ld, src.ld);
        self.data
            .par_chunks_mut(ld * ROW_CHUNK)
            .zip(src.data.par_chunks(sld * ROW_CHUNK))
            .for_each(|(d, s)| {
                for (drow, srow) in d.chunks_mut(ld).zip(s.chunks(sld)) {
                    drow[dst0..dst0 + w].copy_from_slice(&srow[src0..src0 + w]);
                }
            });
    }
}

/// dst = alpha * a * b (+ dst if `add`), with faer's parallel dense product.
pub(super) fn gemm(
    dst: MatMut<'_, f64>,
    add: bool,
    a: MatRef<'_, f64>,
    b: MatRef<'_, f64>,
    alpha: f64,
    par: Par,
) {
    let accum = if add { Accum::Add } else { Accum::Replace };
    faer::linalg::matmul::matmul(dst, accum, a, b, alpha, par);
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
            Default::default(),
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
        let ok = self_adjoint_evd(a, diag, Some(u), Par::Seq, stack, Default::default()).is_ok();
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
        let mut g = Mat::zeros(3, 3);
        gemm(g.as_mut(), false, v.transpose(), v, 1.0, Par::rayon(0));
        let expect = v.transpose() * v;
        assert!((&g - &expect).norm_max() == 0.0);
    }
}
