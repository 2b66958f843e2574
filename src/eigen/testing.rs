//! Synthetic generalized eigenproblems with known structure, for the eigensolver tests and
//! benchmarks (public so `benches/` and integration tests can build the same matrices).
//!
//! All matrices live on an `n[0] x n[1] x n[2]` grid of nodes, node (i, j, k) has index
//! `i + n[0] * (j + n[1] * k)`. Every H here is PSD with exactly the constant vector as null
//! space (row sums are zero by construction), every M is SPD, and both share one pattern.
//!
//! - [`grid_laplacian`]: weighted graph Laplacian with all neighbours within a Euclidean radius
//!   (radius 1: the 7-point Laplacian; radius 3: 123 entries per row; radius 4: 257), to mimic
//!   the 100-300 entries per row of the RKPM matrices.
//! - [`q1_fem`]: tensor-product Q1 finite elements (Neumann Laplacian stiffness and consistent
//!   mass, 27 entries per row) with analytic eigenvalues [`q1_fem_eigenvalues`].
//! - [`identity`], [`kernel_mass`], [`perturb_diagonal`]: masses.

use super::SplitMix64;
use crate::sparse::{SparseMatrix, SparseMatrixRef};
use faer::sparse::{SparseColMat, Triplet};

/// Index of grid node (i, j, k).
fn node(n: [usize; 3], i: usize, j: usize, k: usize) -> usize {
    i + n[0] * (j + n[1] * k)
}

/// Neighbour offsets (excluding 0) with |d| <= radius, with their squared length.
fn offsets(radius: f64) -> Vec<([i64; 3], f64)> {
    let r = radius.floor() as i64;
    let mut out = Vec::new();
    for dk in -r..=r {
        for dj in -r..=r {
            for di in -r..=r {
                let d2 = (di * di + dj * dj + dk * dk) as f64;
                if d2 > 0.0 && d2 <= radius * radius + 1e-12 {
                    out.push(([di, dj, dk], d2));
                }
            }
        }
    }
    out
}

/// Assemble a symmetric matrix on the grid from a per-offset weight: off-diagonal
/// `offdiag(d2)` for every neighbour pair, diagonal `diag(i, row_sum_of_offdiag)`.
fn assemble(
    n: [usize; 3],
    radius: f64,
    offdiag: impl Fn(f64) -> f64,
    diag: impl FnMut(usize, f64) -> f64,
) -> SparseMatrix {
    let mut diag = diag;
    let size = n[0] * n[1] * n[2];
    let offs = offsets(radius);
    let mut ptr = Vec::with_capacity(size + 1);
    let mut idx = Vec::with_capacity(size * (offs.len() + 1));
    let mut val = Vec::with_capacity(size * (offs.len() + 1));
    ptr.push(0);
    let mut col: Vec<(usize, f64)> = Vec::with_capacity(offs.len() + 1);
    for k in 0..n[2] {
        for j in 0..n[1] {
            for i in 0..n[0] {
                col.clear();
                let mut sum = 0.0;
                for &(d, d2) in &offs {
                    let (a, b, c) = (i as i64 + d[0], j as i64 + d[1], k as i64 + d[2]);
                    if a < 0
                        || b < 0
                        || c < 0
                        || a >= n[0] as i64
                        || b >= n[1] as i64
                        || c >= n[2] as i64
                    {
                        continue;
                    }
                    let w = offdiag(d2);
                    sum += w;
                    col.push((node(n, a as usize, b as usize, c as usize), w));
                }
                let me = node(n, i, j, k);
                col.push((me, diag(me, sum)));
                col.sort_by_key(|e| e.0);
                // Test grids are far below u32's range.
                idx.extend(col.iter().map(|e| e.0 as u32));
                val.extend(col.iter().map(|e| e.1));
                ptr.push(idx.len() as u32);
            }
        }
    }
    crate::sparse::from_compressed(size, ptr, idx, val)
}

/// Weighted graph Laplacian of the grid: edge weight 1 / |d|^2 between nodes at distance
/// |d| <= `radius` (grid units). H = D - W, so H 1 = 0 and H is PSD. With `radius = 1` it is
/// the 7-point Laplacian whose eigenvalues (mass = identity) are the sums
/// `2 - 2 cos(pi k_a / n_a)` over the three axes ([`grid_laplacian_eigenvalues`]).
pub fn grid_laplacian(n: [usize; 3], radius: f64) -> SparseMatrix {
    // Off-diagonal -w, diagonal +sum w.
    assemble(n, radius, |d2| -1.0 / d2, |_, sum| -sum)
}

/// The `count` smallest eigenvalues (ascending, with multiplicity) of the 7-point grid
/// Laplacian `grid_laplacian(n, 1.0)` with identity mass.
pub fn grid_laplacian_eigenvalues(n: [usize; 3], count: usize) -> Vec<f64> {
    let axis = |m: usize| -> Vec<f64> {
        (0..m)
            .map(|k| 2.0 - 2.0 * (std::f64::consts::PI * k as f64 / m as f64).cos())
            .collect()
    };
    sums_of_three(&axis(n[0]), &axis(n[1]), &axis(n[2]), count)
}

/// All sums a + b + c, sorted ascending, first `count`.
fn sums_of_three(a: &[f64], b: &[f64], c: &[f64], count: usize) -> Vec<f64> {
    let mut all = Vec::with_capacity(a.len() * b.len() * c.len());
    for x in a {
        for y in b {
            for z in c {
                all.push(x + y + z);
            }
        }
    }
    all.sort_by(f64::total_cmp);
    all.truncate(count);
    all
}

/// Identity mass, K x K.
pub fn identity(size: usize) -> SparseMatrix {
    crate::sparse::from_compressed(
        size,
        (0..=size as u32).collect(),
        (0..size as u32).collect(),
        vec![1.0; size],
    )
}

/// An SPD "consistent-like" mass on the same pattern as `grid_laplacian(n, radius)`:
/// off-diagonal `coupling * exp(-|d|^2 / radius^2)`, diagonal `1 + sum of off-diagonals`
/// (strictly diagonally dominant with positive diagonal, hence SPD, condition number below
/// `1 + 2 * coupling * (row length)`), then each diagonal entry scaled by `1 + spread * u`,
/// u uniform in [0, 1) from `seed` (keeps SPD: adds a non-negative diagonal).
pub fn kernel_mass(
    n: [usize; 3],
    radius: f64,
    coupling: f64,
    spread: f64,
    seed: u64,
) -> SparseMatrix {
    let mut rng = SplitMix64::new(seed);
    let mut factors = vec![0.0; n[0] * n[1] * n[2]];
    for f in &mut factors {
        *f = 1.0 + spread * rng.next_f64();
    }
    assemble(
        n,
        radius,
        |d2| coupling * (-d2 / (radius * radius)).exp(),
        |me, sum| (1.0 + sum) * factors[me],
    )
}

/// A copy of `m` with each diagonal entry scaled by `1 + spread * u`, u uniform in [0, 1) from
/// `seed`. Adding a non-negative diagonal keeps an SPD matrix SPD.
pub fn perturb_diagonal(m: SparseMatrixRef<'_>, spread: f64, seed: u64) -> SparseMatrix {
    let mut rng = SplitMix64::new(seed);
    let mut out = SparseMatrix::new(
        m.symbolic().to_owned().expect("a copy of a valid pattern"),
        m.val().to_vec(),
    );
    let sym = m.symbolic();
    let ptr: Vec<std::ops::Range<usize>> = (0..m.ncols()).map(|j| sym.col_range(j)).collect();
    let idx = sym.row_idx().to_vec();
    let val = out.val_mut();
    for (j, range) in ptr.into_iter().enumerate() {
        let factor = 1.0 + spread * rng.next_f64();
        for p in range {
            if idx[p] as usize == j {
                val[p] *= factor;
            }
        }
    }
    out
}

/// (row, column, value) entries of a small matrix.
type Entries = Vec<(usize, usize, f64)>;

/// 1D linear-element Neumann stiffness and consistent mass on `m` nodes with spacing `h`, as
/// (row, col, value) tridiagonal entries.
fn p1_1d(m: usize, h: f64) -> (Entries, Entries) {
    let mut k = Vec::new();
    let mut mm = Vec::new();
    for i in 0..m {
        let ends = if i == 0 || i + 1 == m { 1.0 } else { 2.0 };
        k.push((i, i, ends / h));
        mm.push((i, i, ends * 2.0 * h / 6.0));
        if i + 1 < m {
            for (a, b) in [(i, i + 1), (i + 1, i)] {
                k.push((a, b, -1.0 / h));
                mm.push((a, b, h / 6.0));
            }
        }
    }
    (k, mm)
}

/// Q1 (trilinear) finite elements on the grid with spacing `h` (metres): the Neumann Laplacian
/// stiffness H = K1 x M2 x M3 + M1 x K2 x M3 + M1 x M2 x K3 and the consistent mass
/// M = M1 x M2 x M3 (Kronecker products of the 1D linear-element matrices), 27 entries per
/// interior row. Eigenvalues: [`q1_fem_eigenvalues`].
pub fn q1_fem(n: [usize; 3], h: f64) -> (SparseMatrix, SparseMatrix) {
    let (k1, m1) = p1_1d(n[0], h);
    let (k2, m2) = p1_1d(n[1], h);
    let (k3, m3) = p1_1d(n[2], h);
    let size = n[0] * n[1] * n[2];
    let kron = |a: &[(usize, usize, f64)],
                b: &[(usize, usize, f64)],
                c: &[(usize, usize, f64)],
                out: &mut Vec<Triplet<u32, u32, f64>>| {
        for &(ai, aj, av) in a {
            for &(bi, bj, bv) in b {
                for &(ci, cj, cv) in c {
                    out.push(Triplet::new(
                        node(n, ai, bi, ci) as u32,
                        node(n, aj, bj, cj) as u32,
                        av * bv * cv,
                    ));
                }
            }
        }
    };
    let mut th = Vec::new();
    kron(&k1, &m2, &m3, &mut th);
    kron(&m1, &k2, &m3, &mut th);
    kron(&m1, &m2, &k3, &mut th);
    let mut tm = Vec::new();
    kron(&m1, &m2, &m3, &mut tm);
    // Indices are in range and the size fits in usize by construction.
    let hmat = SparseColMat::try_new_from_triplets(size, size, &th)
        .expect("valid triplets by construction");
    let mmat = SparseColMat::try_new_from_triplets(size, size, &tm)
        .expect("valid triplets by construction");
    (hmat, mmat)
}

/// The `count` smallest generalized eigenvalues of [`q1_fem`]`(n, h)`, ascending with
/// multiplicity: sums over the axes of the 1D values
/// `mu_k = (6 / h^2) (1 - cos t) / (2 + cos t)`, `t = pi k / (n_a - 1)`.
pub fn q1_fem_eigenvalues(n: [usize; 3], h: f64, count: usize) -> Vec<f64> {
    let axis = |m: usize| -> Vec<f64> {
        (0..m)
            .map(|k| {
                let t = std::f64::consts::PI * k as f64 / (m - 1) as f64;
                6.0 / (h * h) * (1.0 - t.cos()) / (2.0 + t.cos())
            })
            .collect()
    };
    sums_of_three(&axis(n[0]), &axis(n[1]), &axis(n[2]), count)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn structure_of_synthetic_matrices() {
        // Interior row lengths match the lattice-point counts of the balls.
        let h = grid_laplacian([9, 9, 9], 3.0);
        let centre = node([9, 9, 9], 4, 4, 4);
        assert_eq!(h.symbolic().col_range(centre).len(), 123);
        // H 1 = 0 up to round-off of summing ~120 weights of size <= 1.
        let mut y = vec![0.0; h.nrows()];
        crate::sparse::sym_mul_row_major(h.as_ref(), &vec![1.0; h.nrows()], 1, &mut y, 1, 1);
        assert!(y.iter().all(|v| v.abs() < 1e-13));
        assert_eq!(crate::sparse::symmetry_defect(h.as_ref()), 0.0);
        let m = kernel_mass([9, 9, 9], 3.0, 0.05, 0.5, 1);
        assert_eq!(m.symbolic().row_idx(), h.symbolic().row_idx());
        let (hq, mq) = q1_fem([4, 5, 6], 0.1);
        assert_eq!(hq.symbolic().col_range(node([4, 5, 6], 1, 1, 1)).len(), 27);
        // Sum of all consistent-mass entries = volume of the box.
        let vol = 0.3 * 0.4 * 0.5;
        assert!((mq.val().iter().sum::<f64>() - vol).abs() < 1e-14);
        let mut y = vec![0.0; hq.nrows()];
        crate::sparse::sym_mul_row_major(hq.as_ref(), &vec![1.0; hq.nrows()], 1, &mut y, 1, 1);
        assert!(y.iter().all(|v| v.abs() < 1e-14));
    }
}
