//! One MPI rank's rows of the pencil (H, M): the block layout shared by the distributed
//! assembly and the SLEPc backend.

/// Rows `[start, end)` owned by `rank` of `size` in a block distribution of `n` (the first
/// `n % size` ranks get one more). Used for the PETSc layout and, under MPI, for which kernels,
/// integration points and grid rows a rank takes.
pub fn block_range(n: usize, rank: usize, size: usize) -> std::ops::Range<usize> {
    let base = n / size.max(1);
    let rem = n % size.max(1);
    let start = rank * base + rank.min(rem);
    start..start + base + usize::from(rank < rem)
}

/// Rows `first..first + rows()` of a symmetric pencil (H, M) that share one sparsity pattern
/// (both triangles, columns ascending, global column indices), as the RKPM assembly makes
/// them: CSR with one index array for both matrices.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct RowPencil {
    /// Global index of the first row.
    pub first: usize,
    /// Row pointers, length rows + 1.
    pub ptr: Vec<usize>,
    /// Global column indices (below 2^32), shared by both matrices.
    pub cols: Vec<u32>,
    /// H's values (H_w: Pa m).
    pub hessian: Vec<f64>,
    /// M's values (m^3).
    pub mass: Vec<f64>,
}

impl RowPencil {
    /// Number of rows.
    pub fn rows(&self) -> usize {
        self.ptr.len().saturating_sub(1)
    }

    /// Stored entries of each matrix.
    pub fn nnz(&self) -> usize {
        self.cols.len()
    }

    /// Sums of the diagonal entries of these rows: (of H, of M).
    pub fn diagonal_sums(&self) -> (f64, f64) {
        let mut sums = (0.0, 0.0);
        for r in 0..self.rows() {
            for e in self.ptr[r]..self.ptr[r + 1] {
                if self.cols[e] as usize == self.first + r {
                    sums.0 += self.hessian[e];
                    sums.1 += self.mass[e];
                }
            }
        }
        sums
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn block_ranges_tile() {
        for n in [0, 1, 5, 17] {
            for size in 1..5 {
                let mut next = 0;
                for rank in 0..size {
                    let r = block_range(n, rank, size);
                    assert_eq!(r.start, next);
                    next = r.end;
                }
                assert_eq!(next, n);
            }
        }
    }
}
