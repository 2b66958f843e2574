//! Hierarchical evaluation of the winding number on a [`WindingTree`].

use super::tree::WindingTree;
use super::{dot, solid_angle, sub};
use crate::Point3;
use rayon::prelude::*;
use std::f64::consts::PI;

/// Deepest tree the fixed traversal stack supports. Median splits keep the depth at
/// ceil(log2(F / leaf_size)) + 1 <= 33 for any u32 triangle count.
const STACK: usize = 96;

impl WindingTree {
    /// Generalized winding number at `q` (metres), dimensionless: ~1 inside and ~0 outside a
    /// closed outward-oriented mesh.
    ///
    /// Nodes far from `q` (distance > beta x radius) contribute their dipole + quadrupole +
    /// octupole expansion, the rest is summed exactly. Deterministic: the result depends only
    /// on `q` and the tree.
    pub fn winding_number(&self, q: &Point3) -> f64 {
        if self.nodes.is_empty() {
            return 0.0;
        }
        let mut stack = [0u32; STACK];
        let mut sp = 1;
        let mut sum = 0.0;
        while sp > 0 {
            sp -= 1;
            let i = stack[sp] as usize;
            let node = &self.nodes[i];
            let d = sub(&node.center, q);
            let d2 = dot(&d, &d);
            if d2 > node.far2 {
                sum += self.moments[i].far_field(&d, d2);
            } else if node.count > 0 {
                let start = node.first as usize;
                for [a, b, c] in &self.tris[start..start + node.count as usize] {
                    sum += solid_angle(a, b, c, q);
                }
            } else {
                stack[sp] = node.first;
                stack[sp + 1] = node.first + 1;
                sp += 2;
            }
        }
        sum / (4.0 * PI)
    }

    /// [`WindingTree::winding_number`] for every point (N x 3, metres), rayon-parallel.
    pub fn winding_numbers(&self, points: &[Point3]) -> Vec<f64> {
        points
            .par_iter()
            .with_min_len(256)
            .map(|q| self.winding_number(q))
            .collect()
    }

    /// Inside test for every point (N x 3, metres): `w >= 0.5`, rayon-parallel. Points with a
    /// NaN coordinate get `w = NaN` and are reported outside.
    pub fn contains(&self, points: &[Point3]) -> Vec<bool> {
        points
            .par_iter()
            .with_min_len(256)
            .map(|q| self.winding_number(q) >= 0.5)
            .collect()
    }
}
