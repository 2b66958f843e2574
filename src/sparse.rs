//! Sparse matrix type shared by assembly and the eigensolvers, plus the hot kernels on it.
//!
//! H_w and M are symmetric, so they are stored with both triangles as faer CSC matrices; for a
//! symmetric matrix the CSC arrays are also its CSR arrays, so row-parallel kernels can walk
//! columns.

use faer::sparse::{SparseColMat, SymbolicSparseColMat};

/// A symmetric sparse matrix, K x K, both triangles stored, sorted row indices per column.
pub type SparseMatrix = SparseColMat<usize, f64>;

/// Build a [`SparseMatrix`] from compressed arrays (column pointers `ptr`, length n + 1; sorted
/// row indices `idx`; values `val`). Panics only on violated structural invariants, which
/// callers in this crate construct by design.
pub fn from_compressed(n: usize, ptr: Vec<usize>, idx: Vec<usize>, val: Vec<f64>) -> SparseMatrix {
    let symbolic = SymbolicSparseColMat::new_checked(n, n, ptr, None, idx);
    SparseColMat::new(symbolic, val)
}
