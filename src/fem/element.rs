//! Per-tet quantities of linear tetrahedra: shape-function gradients, rest volumes, Lame
//! parameters and densities; the elastic energy, its gradient (nodal forces) and element
//! Hessians, all from the stable Neo-Hookean density in [`crate::elasticity`] (the same one
//! the reduced model uses).
//!
//! With rest corners X_0..X_3 and D_m = [X_1 - X_0, X_2 - X_0, X_3 - X_0] (columns), the
//! shape-function gradients are g_a = row (a - 1) of D_m^-1 for a = 1, 2, 3 and
//! g_0 = -(g_1 + g_2 + g_3); the deformation gradient is constant per tet:
//!
//! ```text
//! F = sum_a x_a g_a^T,   E_e = V_e Psi(F),   dE_e/dx_a = V_e P(F) g_a,
//! d2E_e/dx_a[r] dx_b[s] = V_e sum_{c,d} d2Psi/dF_rc dF_sd g_a[c] g_b[d].
//! ```
//!
//! Mass is **lumped**: node a carries m_a = sum over its tets of rho_e V_e / 4. For linear
//! tets the gravity potential sum_a m_a g . x_a equals the exact integral of rho g . x.

use super::tetmesh::TetMesh;
use super::FemError;
use crate::elasticity::{self, Mat3};
use crate::material::{Material, MaterialField, MaterialOverride};
use crate::Point3;
use rayon::prelude::*;

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

/// Precomputed per-tet data for energy, force and Hessian evaluation.
#[derive(Debug, Clone)]
pub struct Elements {
    tets: Vec<[u32; 4]>,
    /// Shape-function gradients g_0..g_3 per tet, 1/m.
    grads: Vec<[Point3; 4]>,
    /// Rest volume per tet, m^3.
    volumes: Vec<f64>,
    lambda: Vec<f64>,
    mu: Vec<f64>,
    /// Lumped node masses, kg.
    masses: Vec<f64>,
    /// Lumped node volumes, m^3.
    node_volumes: Vec<f64>,
}

/// Element stiffness, 12 x 12, DoF order (node a, axis r) -> 3 a + r.
pub type TetHessian = [[f64; 12]; 12];

impl Elements {
    /// Precompute gradients, volumes and masses of `mesh` with per-tet `materials`.
    ///
    /// # Errors
    /// [`FemError::Mesh`] when `materials` does not have one entry per tet.
    pub fn new(mesh: &TetMesh, materials: &TetMaterials) -> Result<Self, FemError> {
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
        let nodes = mesh.nodes();
        let volumes = mesh.tet_volumes();
        let grads = mesh
            .tets()
            .iter()
            .zip(&volumes)
            .map(|(tet, &v)| {
                let x = tet.map(|i| nodes[i as usize]);
                let dm: Mat3 = [0, 1, 2].map(|r| [0, 1, 2].map(|c| x[c + 1][r] - x[0][r]));
                // D_m^-1 = cof(D_m)^T / det(D_m), det(D_m) = 6 V > 0 for a valid mesh.
                let cof = elasticity::cofactor3(&dm);
                let det = 6.0 * v;
                let mut g = [[0.0; 3]; 4];
                for a in 0..3 {
                    for c in 0..3 {
                        g[a + 1][c] = cof[c][a] / det;
                    }
                }
                for c in 0..3 {
                    g[0][c] = -(g[1][c] + g[2][c] + g[3][c]);
                }
                g
            })
            .collect();
        let mut masses = vec![0.0; mesh.num_nodes()];
        let mut node_volumes = vec![0.0; mesh.num_nodes()];
        for ((tet, &v), &rho) in mesh.tets().iter().zip(&volumes).zip(&materials.density) {
            for &i in tet {
                masses[i as usize] += 0.25 * rho * v;
                node_volumes[i as usize] += 0.25 * v;
            }
        }
        Ok(Self {
            tets: mesh.tets().to_vec(),
            grads,
            volumes,
            lambda: materials.lambda.clone(),
            mu: materials.mu.clone(),
            masses,
            node_volumes,
        })
    }

    /// Number of tets.
    pub fn len(&self) -> usize {
        self.tets.len()
    }

    /// True when there are no tets (never, for a validated mesh).
    pub fn is_empty(&self) -> bool {
        self.tets.is_empty()
    }

    /// Tets, T x 4 node indices.
    pub fn tets(&self) -> &[[u32; 4]] {
        &self.tets
    }

    /// Lumped node masses, N entries, kg.
    pub fn masses(&self) -> &[f64] {
        &self.masses
    }

    /// Lumped node volumes, N entries, m^3.
    pub fn node_volumes(&self) -> &[f64] {
        &self.node_volumes
    }

    /// Deformation gradient of tet `t` for node positions `x` (N x 3, metres).
    #[inline]
    pub fn deformation_gradient(&self, t: usize, x: &[Point3]) -> Mat3 {
        let g = &self.grads[t];
        let mut f = [[0.0; 3]; 3];
        for (a, &i) in self.tets[t].iter().enumerate() {
            let xa = x[i as usize];
            for r in 0..3 {
                for c in 0..3 {
                    f[r][c] += xa[r] * g[a][c];
                }
            }
        }
        f
    }

    /// Elastic energy sum_e V_e Psi(F_e), J, for node positions `x` (N x 3, metres).
    /// Summed in fixed chunks, so the value does not depend on the thread count.
    pub fn energy(&self, x: &[Point3]) -> f64 {
        let partial: Vec<f64> = (0..self.len())
            .into_par_iter()
            .chunks(4096)
            .map(|ts| {
                ts.into_iter()
                    .map(|t| {
                        let f = self.deformation_gradient(t, x);
                        self.volumes[t] * elasticity::energy_density(&f, self.lambda[t], self.mu[t])
                    })
                    .sum::<f64>()
            })
            .collect();
        partial.iter().sum()
    }

    /// Element forces dE_e/dx_a = V_e P(F_e) g_a, 4 x 3 per tet, N (gradient of the energy).
    pub fn tet_gradient(&self, t: usize, x: &[Point3]) -> [Point3; 4] {
        let f = self.deformation_gradient(t, x);
        let p = elasticity::first_piola(&f, self.lambda[t], self.mu[t]);
        let (v, g) = (self.volumes[t], &self.grads[t]);
        [0, 1, 2, 3].map(|a| [0, 1, 2].map(|r| v * (0..3).map(|c| p[r][c] * g[a][c]).sum::<f64>()))
    }

    /// Add the elastic energy gradient (N x 3, newtons) for positions `x` into `grad`.
    /// Element gradients are computed in parallel and scattered in tet order (deterministic).
    pub fn add_gradient(&self, x: &[Point3], grad: &mut [Point3]) {
        let local: Vec<[Point3; 4]> = (0..self.len())
            .into_par_iter()
            .map(|t| self.tet_gradient(t, x))
            .collect();
        for (tet, ge) in self.tets.iter().zip(&local) {
            for (a, &i) in tet.iter().enumerate() {
                for r in 0..3 {
                    grad[i as usize][r] += ge[a][r];
                }
            }
        }
    }

    /// Element Hessian d2E_e/dx2 of tet `t` (12 x 12, N/m, DoF order 3 a + r), from the exact
    /// d2Psi/dF2 or, with `project_psd`, from its projection to positive semi-definite (then
    /// the element Hessian is PSD too, as it is a congruence of the projected one).
    pub fn tet_hessian(&self, t: usize, x: &[Point3], project_psd: bool) -> TetHessian {
        let f = self.deformation_gradient(t, x);
        let (l, m) = (self.lambda[t], self.mu[t]);
        let h = if project_psd {
            elasticity::hessian_psd(&f, l, m)
        } else {
            elasticity::hessian(&f, l, m)
        };
        let (v, g) = (self.volumes[t], &self.grads[t]);
        // hg[r][c][s][b] = sum_d H[3r + c][3s + d] g_b[d]
        let mut hg = [[[[0.0; 4]; 3]; 3]; 3];
        for r in 0..3 {
            for c in 0..3 {
                for s in 0..3 {
                    for b in 0..4 {
                        hg[r][c][s][b] = (0..3).map(|d| h[3 * r + c][3 * s + d] * g[b][d]).sum();
                    }
                }
            }
        }
        let mut k = [[0.0; 12]; 12];
        for a in 0..4 {
            for r in 0..3 {
                for b in 0..4 {
                    for s in 0..3 {
                        k[3 * a + r][3 * b + s] =
                            v * (0..3).map(|c| g[a][c] * hg[r][c][s][b]).sum::<f64>();
                    }
                }
            }
        }
        k
    }
}
