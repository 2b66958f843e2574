//! Per-element quantities of linear (4-node) or quadratic (10-node) tetrahedra:
//! shape-function gradients at quadrature points, quadrature weights, Lame parameters and
//! densities; the elastic energy, its gradient (nodal forces) and element Hessians, all from
//! the stable Neo-Hookean density in [`crate::elasticity`] (the same one the reduced model
//! uses).
//!
//! With rest corners X_0..X_3 and D_m = [X_1 - X_0, X_2 - X_0, X_3 - X_0] (columns), the
//! barycentric gradients are g_a = row (a - 1) of D_m^-1 for a = 1, 2, 3 and
//! g_0 = -(g_1 + g_2 + g_3). At a quadrature point q with shape-function gradients G_qa:
//!
//! ```text
//! F_q = sum_a x_a G_qa^T,   E_e = sum_q w_q Psi(F_q),   dE_e/dx_a = sum_q w_q P(F_q) G_qa,
//! d2E_e/dx_a[r] dx_b[s] = sum_q w_q sum_{c,d} d2Psi/dF_rc dF_sd G_qa[c] G_qb[d].
//! ```
//!
//! - **Linear** ([`ElementOrder::Linear`]): N_a = lambda_a, G_a = g_a, one point, w = V_e.
//!   Mass lumped: m_a = sum over the node's tets of rho_e V_e / 4 (the gravity potential
//!   sum_a m_a g . x_a is then the exact integral of rho g . x).
//! - **Quadratic** ([`ElementOrder::Quadratic`]): 4 corner nodes and 6 edge-midpoint nodes
//!   (edges 01, 02, 03, 12, 13, 23), N_a = lambda_a (2 lambda_a - 1),
//!   N_ab = 4 lambda_a lambda_b; the 4-point degree-2 rule (exact for the small-strain
//!   stiffness). Mass lumped by HRZ (the diagonal of the consistent mass scaled to the
//!   element mass): rho V / 36 per corner, 4 rho V / 27 per edge node (all positive, unlike
//!   row sums). Gravity uses the same lumped masses. Quadratic tets do not lock in bending
//!   the way linear ones do (docs/accuracy.md).
//!
//! FE nodes: the mesh's nodes first (same indices), then one node per mesh edge
//! (quadratic only), in order of first appearance; see [`fe_nodes`].

use super::tetmesh::TetMesh;
use super::FemError;
use crate::elasticity;
use crate::linalg3::{cofactor3, Mat3};
use crate::material::{Material, MaterialField, MaterialOverride};
use crate::Point3;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::collections::HashMap;

/// Material per tet: Lame parameters (Pa) and density (kg/m^3), T entries each.
#[derive(Debug, Clone, PartialEq)]
pub struct TetMaterials {
    /// First Lame parameter lambda per tet, Pa.
    pub lambda: Vec<f64>,
    /// Shear modulus mu per tet, Pa.
    pub mu: Vec<f64>,
    /// Density per tet, kg/m^3.
    pub density: Vec<f64>,
}

impl TetMaterials {
    /// The same material in every tet of `mesh`.
    ///
    /// # Errors
    /// [`crate::Error::InvalidParameter`] when the material is invalid.
    pub fn homogeneous(mesh: &TetMesh, material: &Material) -> crate::Result<Self> {
        Self::from_regions(mesh, material, &[])
    }

    /// `base` everywhere, then each override (in order) on the tets whose centroid lies in its
    /// region: the same region rules as the reduced model's [`MaterialField::from_regions`].
    ///
    /// # Errors
    /// [`crate::Error::InvalidParameter`] when a material is invalid.
    pub fn from_regions(
        mesh: &TetMesh,
        base: &Material,
        overrides: &[MaterialOverride],
    ) -> crate::Result<Self> {
        let f = MaterialField::from_regions(&mesh.centroids(), base, overrides)?;
        let (lambda, mu) = (0..f.len()).map(|i| f.lame(i)).unzip();
        Ok(Self {
            lambda,
            mu,
            density: f.density,
        })
    }
}

/// Polynomial order of the tetrahedral elements.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ElementOrder {
    /// 4-node linear tets (constant strain).
    #[default]
    Linear,
    /// 10-node quadratic tets (corners and edge midpoints).
    Quadratic,
}

impl ElementOrder {
    /// Nodes per element: 4 or 10.
    pub fn nodes_per_element(&self) -> usize {
        match self {
            ElementOrder::Linear => 4,
            ElementOrder::Quadratic => 10,
        }
    }
}

/// Local corner pairs of the 6 edge nodes of a quadratic tet, in local order 4..10.
pub const TET_EDGES: [(usize, usize); 6] = [(0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)];

/// FE node rest positions (metres) and element connectivity (`nodes_per_element` indices
/// per tet, flattened) of `mesh` at `order`. The mesh nodes come first with their indices;
/// quadratic elements add one node at the midpoint of every mesh edge.
pub fn fe_nodes(mesh: &TetMesh, order: ElementOrder) -> (Vec<Point3>, Vec<u32>) {
    let mut nodes = mesh.nodes().to_vec();
    match order {
        ElementOrder::Linear => (nodes, mesh.tets().iter().flatten().copied().collect()),
        ElementOrder::Quadratic => {
            let mut edge_node: HashMap<(u32, u32), u32> = HashMap::new();
            let mut conn = Vec::with_capacity(10 * mesh.num_tets());
            for tet in mesh.tets() {
                conn.extend_from_slice(tet);
                for (a, b) in TET_EDGES {
                    let key = (tet[a].min(tet[b]), tet[a].max(tet[b]));
                    let id = *edge_node.entry(key).or_insert_with(|| {
                        let (p, q) = (nodes[key.0 as usize], nodes[key.1 as usize]);
                        nodes.push([0, 1, 2].map(|r| 0.5 * (p[r] + q[r])));
                        (nodes.len() - 1) as u32
                    });
                    conn.push(id);
                }
            }
            (nodes, conn)
        }
    }
}

/// Precomputed per-element data for energy, force and Hessian evaluation.
#[derive(Debug, Clone)]
pub struct Elements {
    order: ElementOrder,
    /// Nodes per element.
    npe: usize,
    /// Quadrature points per element.
    nq: usize,
    /// FE node rest positions, metres.
    nodes: Vec<Point3>,
    /// Connectivity, npe per element.
    conn: Vec<u32>,
    /// Shape-function gradients, nq x npe per element, 1/m.
    grads: Vec<Point3>,
    /// Quadrature weights (volume each point stands for), nq per element, m^3.
    weights: Vec<f64>,
    lambda: Vec<f64>,
    mu: Vec<f64>,
    /// Lumped node masses, kg.
    masses: Vec<f64>,
    /// Lumped node volumes, m^3.
    node_volumes: Vec<f64>,
}

/// The 4-point degree-2 rule on a tet: barycentric (a, b, b, b) and permutations.
const Q4_A: f64 = 0.585_410_196_624_968_5;
const Q4_B: f64 = 0.138_196_601_125_010_5;

impl Elements {
    /// Precompute gradients, weights and masses of `mesh` with per-tet `materials` at
    /// polynomial `order`.
    ///
    /// # Errors
    /// [`FemError::Mesh`] when `materials` does not have one entry per tet.
    pub fn new(
        mesh: &TetMesh,
        materials: &TetMaterials,
        order: ElementOrder,
    ) -> Result<Self, FemError> {
        let t = mesh.num_tets();
        for (what, len) in [
            ("lambda", materials.lambda.len()),
            ("mu", materials.mu.len()),
            ("density", materials.density.len()),
        ] {
            if len != t {
                return Err(FemError::Mesh(format!(
                    "materials: {what} has {len} entries for {t} tets"
                )));
            }
        }
        let (nodes, conn) = fe_nodes(mesh, order);
        let npe = order.nodes_per_element();
        let nq = if order == ElementOrder::Linear { 1 } else { 4 };
        let volumes = mesh.tet_volumes();
        let mut grads = Vec::with_capacity(t * nq * npe);
        let mut weights = Vec::with_capacity(t * nq);
        let mut masses = vec![0.0; nodes.len()];
        let mut node_volumes = vec![0.0; nodes.len()];
        for (e, (tet, &v)) in mesh.tets().iter().zip(&volumes).enumerate() {
            let x = tet.map(|i| mesh.nodes()[i as usize]);
            let dm: Mat3 = [0, 1, 2].map(|r| [0, 1, 2].map(|c| x[c + 1][r] - x[0][r]));
            // D_m^-1 = cof(D_m)^T / det(D_m), det(D_m) = 6 V > 0 for a valid mesh.
            let cof = cofactor3(&dm);
            let mut g = [[0.0; 3]; 4];
            for a in 0..3 {
                for c in 0..3 {
                    g[a + 1][c] = cof[c][a] / (6.0 * v);
                }
            }
            for c in 0..3 {
                g[0][c] = -(g[1][c] + g[2][c] + g[3][c]);
            }
            let rho = materials.density[e];
            let en = &conn[npe * e..npe * (e + 1)];
            match order {
                ElementOrder::Linear => {
                    grads.extend_from_slice(&g);
                    weights.push(v);
                    for &i in en {
                        masses[i as usize] += 0.25 * rho * v;
                        node_volumes[i as usize] += 0.25 * v;
                    }
                }
                ElementOrder::Quadratic => {
                    for q in 0..4 {
                        let l: [f64; 4] = [0, 1, 2, 3].map(|k| if k == q { Q4_A } else { Q4_B });
                        for a in 0..4 {
                            grads.push(g[a].map(|c| (4.0 * l[a] - 1.0) * c));
                        }
                        for (a, b) in TET_EDGES {
                            grads.push([0, 1, 2].map(|c| 4.0 * (l[a] * g[b][c] + l[b] * g[a][c])));
                        }
                        weights.push(0.25 * v);
                    }
                    for (k, &i) in en.iter().enumerate() {
                        let share = if k < 4 { 1.0 / 36.0 } else { 4.0 / 27.0 };
                        masses[i as usize] += share * rho * v;
                        node_volumes[i as usize] += share * v;
                    }
                }
            }
        }
        Ok(Self {
            order,
            npe,
            nq,
            nodes,
            conn,
            grads,
            weights,
            lambda: materials.lambda.clone(),
            mu: materials.mu.clone(),
            masses,
            node_volumes,
        })
    }

    /// Element order.
    pub fn order(&self) -> ElementOrder {
        self.order
    }

    /// Number of elements.
    pub fn len(&self) -> usize {
        self.lambda.len()
    }

    /// True when there are no elements (never, for a validated mesh).
    pub fn is_empty(&self) -> bool {
        self.lambda.is_empty()
    }

    /// Nodes per element (4 or 10).
    pub fn nodes_per_element(&self) -> usize {
        self.npe
    }

    /// FE node rest positions, N x 3, metres (mesh nodes first).
    pub fn rest_nodes(&self) -> &[Point3] {
        &self.nodes
    }

    /// The FE nodes of element `e` (4 or 10 indices).
    pub fn connectivity(&self, e: usize) -> &[u32] {
        &self.conn[self.npe * e..self.npe * (e + 1)]
    }

    /// Lumped node masses, N entries, kg.
    pub fn masses(&self) -> &[f64] {
        &self.masses
    }

    /// Lumped node volumes, N entries, m^3.
    pub fn node_volumes(&self) -> &[f64] {
        &self.node_volumes
    }

    /// Deformation gradient of element `e` at its quadrature point `q` for FE node positions
    /// `x` (N x 3, metres).
    #[inline]
    pub fn deformation_gradient(&self, e: usize, q: usize, x: &[Point3]) -> Mat3 {
        let g = &self.grads[(e * self.nq + q) * self.npe..(e * self.nq + q + 1) * self.npe];
        let mut f = [[0.0; 3]; 3];
        for (a, &i) in self.connectivity(e).iter().enumerate() {
            let xa = x[i as usize];
            for r in 0..3 {
                for c in 0..3 {
                    f[r][c] += xa[r] * g[a][c];
                }
            }
        }
        f
    }

    fn element_energy(&self, e: usize, x: &[Point3]) -> f64 {
        (0..self.nq)
            .map(|q| {
                let f = self.deformation_gradient(e, q, x);
                self.weights[e * self.nq + q]
                    * elasticity::energy_density(&f, self.lambda[e], self.mu[e])
            })
            .sum()
    }

    /// Elastic energy sum_e sum_q w_q Psi(F_q), J, for FE node positions `x` (N x 3,
    /// metres). Summed in fixed chunks, so the value does not depend on the thread count.
    pub fn energy(&self, x: &[Point3]) -> f64 {
        let partial: Vec<f64> = (0..self.len())
            .into_par_iter()
            .chunks(4096)
            .map(|es| {
                es.into_iter()
                    .map(|e| self.element_energy(e, x))
                    .sum::<f64>()
            })
            .collect();
        partial.iter().sum()
    }

    /// Element forces dE_e/dx_a, npe x 3 (newtons), the gradient of the element energy.
    pub fn element_gradient(&self, e: usize, x: &[Point3]) -> Vec<Point3> {
        let mut out = vec![[0.0; 3]; self.npe];
        for q in 0..self.nq {
            let f = self.deformation_gradient(e, q, x);
            let p = elasticity::first_piola(&f, self.lambda[e], self.mu[e]);
            let w = self.weights[e * self.nq + q];
            let g = &self.grads[(e * self.nq + q) * self.npe..(e * self.nq + q + 1) * self.npe];
            for (a, o) in out.iter_mut().enumerate() {
                for r in 0..3 {
                    o[r] += w * (0..3).map(|c| p[r][c] * g[a][c]).sum::<f64>();
                }
            }
        }
        out
    }

    /// Add the elastic energy gradient (N x 3, newtons) for positions `x` into `grad`.
    /// Element gradients are computed in parallel and scattered in element order
    /// (deterministic).
    pub fn add_gradient(&self, x: &[Point3], grad: &mut [Point3]) {
        let local: Vec<Vec<Point3>> = (0..self.len())
            .into_par_iter()
            .map(|e| self.element_gradient(e, x))
            .collect();
        for (e, ge) in local.iter().enumerate() {
            for (a, &i) in self.connectivity(e).iter().enumerate() {
                for r in 0..3 {
                    grad[i as usize][r] += ge[a][r];
                }
            }
        }
    }

    /// Element Hessian d2E_e/dx2 of element `e`, (3 npe) x (3 npe) row-major (N/m, DoF order
    /// 3 a + r), from the exact d2Psi/dF2 or, with `project_psd`, from its projection to
    /// positive semi-definite (then the element Hessian is PSD too: a sum of congruences of
    /// PSD matrices).
    pub fn element_hessian(&self, e: usize, x: &[Point3], project_psd: bool) -> Vec<f64> {
        let n = 3 * self.npe;
        let mut k = vec![0.0; n * n];
        let (l, m) = (self.lambda[e], self.mu[e]);
        let mut hg = vec![0.0; 27 * self.npe];
        for q in 0..self.nq {
            let f = self.deformation_gradient(e, q, x);
            let h = if project_psd {
                elasticity::hessian_psd(&f, l, m)
            } else {
                elasticity::hessian(&f, l, m)
            };
            let w = self.weights[e * self.nq + q];
            let g = &self.grads[(e * self.nq + q) * self.npe..(e * self.nq + q + 1) * self.npe];
            // hg[((r * 3 + c) * 3 + s) * npe + b] = sum_d H[3r + c][3s + d] g_b[d]
            for r in 0..3 {
                for c in 0..3 {
                    for s in 0..3 {
                        for (b, gb) in g.iter().enumerate() {
                            hg[((r * 3 + c) * 3 + s) * self.npe + b] =
                                (0..3).map(|d| h[3 * r + c][3 * s + d] * gb[d]).sum();
                        }
                    }
                }
            }
            for (a, ga) in g.iter().enumerate() {
                for r in 0..3 {
                    for b in 0..self.npe {
                        for s in 0..3 {
                            k[(3 * a + r) * n + 3 * b + s] += w
                                * (0..3)
                                    .map(|c| ga[c] * hg[((r * 3 + c) * 3 + s) * self.npe + b])
                                    .sum::<f64>();
                        }
                    }
                }
            }
        }
        k
    }
}
