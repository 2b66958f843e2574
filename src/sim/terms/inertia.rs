//! Inertia, 1/(2 h^2) |z - z_pred|_M^2, from the mass moments over all integration points.

use super::adjoint::ParameterAdjoint;
use super::moments::{add_block_diagonal, add_block_product, Moments};
use super::term::{EnergySum, HessianKind, StepAt, Term, TermKind};
use crate::sim::elastic::Layout;
use crate::sim::environment::Environment;
use faer::Mat;

/// The inertia of an object: its mass moments (coefficients rho v per integration point).
#[derive(Debug, Clone)]
pub struct InertiaTerm {
    /// Moments with coefficients rho_i v_i (kg): `bb` is the reduced mass matrix's block,
    /// `total` the mass.
    pub mass: Moments,
}

impl Term for InertiaTerm {
    fn kind(&self, _env: &Environment) -> TermKind {
        TermKind::Inertia
    }

    fn add_energy_gradient(&self, at: &StepAt<'_>, z: &[f64], sum: &mut EnergySum<'_>) {
        let h2 = at.dt * at.dt;
        let dz: Vec<f64> = z.iter().zip(at.zpred).map(|(a, b)| a - b).collect();
        let mut mdz = vec![0.0; dz.len()];
        add_block_product(at.layout, &self.mass.bb, 1.0 / h2, &dz, &mut mdz);
        sum.energy += 0.5 * dz.iter().zip(&mdz).map(|(a, b)| a * b).sum::<f64>();
        sum.grad.iter_mut().zip(&mdz).for_each(|(g, m)| *g += m);
    }

    fn add_hessian(&self, at: &StepAt<'_>, _z: &[f64], _kind: HessianKind, h: &mut Mat<f64>) {
        self.add_rest_hessian(at.layout, at.dt, h);
    }

    /// The gradient M (z - z_pred) / h^2 gives z_pred the adjoint M adjoint / h^2 and each
    /// point's density the part -(1/h^2) sum_r (b . adjoint_r)(b . (z - z_pred)_r).
    fn add_parameter_adjoint(
        &self,
        at: &StepAt<'_>,
        z: &[f64],
        adjoint: &[f64],
        out: &mut ParameterAdjoint,
    ) {
        let h2 = at.dt * at.dt;
        add_block_product(at.layout, &self.mass.bb, 1.0 / h2, adjoint, &mut out.zpred);
        let n4 = at.layout.row_len();
        for r in 0..3 {
            let a = &adjoint[r * n4..(r + 1) * n4];
            for (k, (zk, pk)) in z[r * n4..(r + 1) * n4]
                .iter()
                .zip(&at.zpred[r * n4..(r + 1) * n4])
                .enumerate()
            {
                let d = (zk - pk) / h2;
                if d != 0.0 {
                    for (i, ai) in a.iter().enumerate() {
                        out.density_quadratic[(i, k)] -= ai * d;
                    }
                }
            }
        }
    }

    fn add_rest_hessian(&self, layout: Layout, dt: f64, h: &mut Mat<f64>) {
        add_block_diagonal(layout, &self.mass.bb, 1.0 / (dt * dt), h);
    }
}
