//! A matrix-free operator for tests, examples and benchmarks: the Q1 (trilinear) finite-element
//! Neumann Laplacian stiffness or consistent mass on a box grid, applied by a loop over the
//! elements (gather the 8 nodes, multiply by the 8 x 8 element matrix, scatter-add), never
//! assembled. Equal to [`crate::eigen::testing::q1_fem`] up to round-off, whose eigenvalues
//! are known in closed form ([`crate::eigen::testing::q1_fem_eigenvalues`]).

use crate::eigen::operator::{check_block_shapes, LinearOperator, OperatorError};
use faer::{MatMut, MatRef};

/// Which Q1 matrix the operator applies.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Q1Part {
    /// The Laplacian stiffness, integral of grad u . grad v (PSD, constant null vector).
    Stiffness,
    /// The consistent mass, integral of u v (SPD).
    Mass,
}

/// The Q1 stiffness or mass on an `n[0] x n[1] x n[2]` grid of nodes with spacing `h` metres
/// (node (i, j, k) is row `i + n[0] (j + n[1] k)`, as in [`crate::eigen::testing`]).
/// Applied element by element, one column at a time, sequentially.
#[derive(Debug, Clone)]
pub struct Q1Operator {
    n: [usize; 3],
    element: [[f64; 8]; 8],
    with_diagonal: bool,
}

impl Q1Operator {
    /// The operator for `part` on the grid `n` (each at least 2 nodes) with spacing `h > 0`.
    ///
    /// # Errors
    /// [`OperatorError`] for a grid with fewer than 2 nodes along an axis or a spacing that is
    /// not finite and positive.
    pub fn new(n: [usize; 3], h: f64, part: Q1Part) -> Result<Self, OperatorError> {
        if n.iter().any(|&a| a < 2) || !(h.is_finite() && h > 0.0) {
            return Err(OperatorError::new(format!(
                "Q1 grid {n:?} with spacing {h}: need at least 2 nodes per axis and h > 0"
            )));
        }
        let k1 = [[1.0 / h, -1.0 / h], [-1.0 / h, 1.0 / h]];
        let m1 = [[h / 3.0, h / 6.0], [h / 6.0, h / 3.0]];
        let mut element = [[0.0; 8]; 8];
        for (l, row) in element.iter_mut().enumerate() {
            for (r, v) in row.iter_mut().enumerate() {
                let (a, b, c) = (l & 1, (l >> 1) & 1, l >> 2);
                let (ap, bp, cp) = (r & 1, (r >> 1) & 1, r >> 2);
                *v = match part {
                    Q1Part::Mass => m1[a][ap] * m1[b][bp] * m1[c][cp],
                    Q1Part::Stiffness => {
                        k1[a][ap] * m1[b][bp] * m1[c][cp]
                            + m1[a][ap] * k1[b][bp] * m1[c][cp]
                            + m1[a][ap] * m1[b][bp] * k1[c][cp]
                    }
                };
            }
        }
        Ok(Self {
            n,
            element,
            with_diagonal: true,
        })
    }

    /// The same operator with [`LinearOperator::diagonal`] unknown (as for an operator that
    /// cannot give it), so a solver must do without Jacobi.
    pub fn without_diagonal(mut self) -> Self {
        self.with_diagonal = false;
        self
    }

    /// The 8 global node indices of element (ex, ey, ez), local order a + 2 b + 4 c.
    fn element_nodes(&self, ex: usize, ey: usize, ez: usize) -> [usize; 8] {
        let [nx, ny, _] = self.n;
        std::array::from_fn(|l| {
            let (a, b, c) = (l & 1, (l >> 1) & 1, l >> 2);
            (ex + a) + nx * ((ey + b) + ny * (ez + c))
        })
    }

    fn for_each_element(&self, mut f: impl FnMut([usize; 8])) {
        let [nx, ny, nz] = self.n;
        for ez in 0..nz - 1 {
            for ey in 0..ny - 1 {
                for ex in 0..nx - 1 {
                    f(self.element_nodes(ex, ey, ez));
                }
            }
        }
    }
}

impl LinearOperator for Q1Operator {
    fn dim(&self) -> usize {
        self.n[0] * self.n[1] * self.n[2]
    }

    fn apply(&self, x: MatRef<'_, f64>, mut out: MatMut<'_, f64>) -> Result<(), OperatorError> {
        check_block_shapes(self.dim(), &x, &out)?;
        out.fill(0.0);
        for j in 0..x.ncols() {
            self.for_each_element(|nodes| {
                let local: [f64; 8] = std::array::from_fn(|l| x[(nodes[l], j)]);
                for (l, &node) in nodes.iter().enumerate() {
                    let row = &self.element[l];
                    out[(node, j)] += (0..8).map(|r| row[r] * local[r]).sum::<f64>();
                }
            });
        }
        Ok(())
    }

    fn diagonal(&self) -> Option<Vec<f64>> {
        if !self.with_diagonal {
            return None;
        }
        let mut d = vec![0.0; self.dim()];
        self.for_each_element(|nodes| {
            for (l, &node) in nodes.iter().enumerate() {
                d[node] += self.element[l][l];
            }
        });
        Some(d)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::eigen::testing::q1_fem;
    use crate::sparse;
    use faer::Mat;

    #[test]
    fn element_loop_equals_the_assembled_kronecker_matrices() {
        let (n, h) = ([3, 4, 5], 0.1);
        let (ha, ma) = q1_fem(n, h);
        let k = ha.nrows();
        let x = Mat::<f64>::from_fn(k, 3, |i, j| ((i * 7 + j * 13) % 11) as f64 - 5.0);
        for (part, a) in [(Q1Part::Stiffness, &ha), (Q1Part::Mass, &ma)] {
            let op = Q1Operator::new(n, h, part).unwrap();
            let mut free = Mat::<f64>::zeros(k, 3);
            let mut assembled = Mat::<f64>::zeros(k, 3);
            op.apply(x.as_ref(), free.as_mut()).unwrap();
            sparse::sym_mul_block(a.as_ref(), x.as_ref(), assembled.as_mut());
            // Both sum the same 27 products per row in different orders: round-off only,
            // ~1e-15 of the row's magnitude (entries <= 8/3 h for H, x entries <= 5).
            let scale = sparse::norm_1(a.as_ref()) * 5.0;
            for j in 0..3 {
                for i in 0..k {
                    assert!((free[(i, j)] - assembled[(i, j)]).abs() <= 1e-14 * scale);
                }
            }
            let diag = op.diagonal().unwrap();
            let exact = sparse::diagonal(a.as_ref());
            for (d, e) in diag.iter().zip(&exact) {
                assert!((d - e).abs() <= 1e-14 * e.abs()); // sums of 8 terms: <= 7 eps
            }
        }
        let op = Q1Operator::new(n, h, Q1Part::Mass)
            .unwrap()
            .without_diagonal();
        assert!(op.diagonal().is_none());
        assert!(Q1Operator::new([1, 4, 4], h, Q1Part::Mass).is_err());
        assert!(Q1Operator::new(n, 0.0, Q1Part::Mass).is_err());
    }
}
