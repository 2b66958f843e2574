//! The work of gravity, -sum rho v g . (X + B z): linear in z (the constant part is dropped).

use super::adjoint::ParameterAdjoint;
use super::term::{EnergySum, HessianKind, StepAt, Term, TermKind};
use crate::sim::environment::Environment;
use faer::Mat;

/// Gravity acting on an object (the acceleration is the step's environment's,
/// [`StepAt::env`]; the object holds this term while the environment has gravity).
#[derive(Debug, Clone)]
pub struct GravityTerm {
    /// sum rho v b over the integration points, 4 (m + 1) (the mass moments' `b`), kg m.
    pub b: Vec<f64>,
}

impl Term for GravityTerm {
    fn kind(&self, _env: &Environment) -> TermKind {
        TermKind::Gravity
    }

    fn add_energy_gradient(&self, at: &StepAt<'_>, z: &[f64], sum: &mut EnergySum<'_>) {
        let Some(g) = at.env.gravity() else {
            return;
        };
        let n4 = at.layout.row_len();
        for r in 0..3 {
            for k in 0..n4 {
                let f = g[r] * self.b[k];
                sum.energy -= f * z[r * n4 + k];
                sum.grad[r * n4 + k] -= f;
            }
        }
    }

    /// The gradient -g_r b (row r) gives dL/dg_r = adjoint_r . b, and each point's density
    /// the part g_r (b . adjoint_r).
    fn add_parameter_adjoint(
        &self,
        at: &StepAt<'_>,
        _z: &[f64],
        adjoint: &[f64],
        out: &mut ParameterAdjoint,
    ) {
        let Some(g) = at.env.gravity() else {
            return;
        };
        let n4 = at.layout.row_len();
        let dg = out.gravity.get_or_insert([0.0; 3]);
        for r in 0..3 {
            let a = &adjoint[r * n4..(r + 1) * n4];
            dg[r] += a.iter().zip(&self.b).map(|(x, y)| x * y).sum::<f64>();
            for (q, ak) in out.density_linear.iter_mut().zip(a) {
                *q += g[r] * ak;
            }
        }
    }

    /// Linear in z: no curvature.
    fn add_hessian(&self, _at: &StepAt<'_>, _z: &[f64], _kind: HessianKind, _h: &mut Mat<f64>) {}
}
