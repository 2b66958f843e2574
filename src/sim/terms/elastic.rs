//! The elastic energy ([`ElasticTerm`], over the cubature points) as a term of the potential.

use super::adjoint::ParameterAdjoint;
use super::term::{EnergySum, HessianKind, StepAt, Term, TermKind};
use crate::sim::elastic::{ElasticTerm, Layout, Precision, Projection};
use crate::sim::environment::Environment;
use faer::Mat;

/// Add the elastic term's exact Hessian at `z` into `h`, its dense products in `precision`
/// ([`super::Terms::exact_hessian_in`]).
pub(super) fn add_exact_hessian(
    term: &ElasticTerm,
    z: &[f64],
    precision: Precision,
    h: &mut Mat<f64>,
) {
    add_matrix(h, &term.hessian_sampled(z, Projection::None, 1, precision));
}

/// Add `b` to `a`, entry by entry (both square, the same size).
fn add_matrix(a: &mut Mat<f64>, b: &Mat<f64>) {
    for j in 0..a.ncols() {
        for i in 0..a.nrows() {
            a[(i, j)] += b[(i, j)];
        }
    }
}

impl Term for ElasticTerm {
    fn kind(&self, _env: &Environment) -> TermKind {
        TermKind::Elastic
    }

    fn add_energy_gradient(&self, _at: &StepAt<'_>, z: &[f64], sum: &mut EnergySum<'_>) {
        let mut g = vec![0.0; z.len()];
        let (e, st) = self.energy_gradient(z, &mut g);
        sum.energy += e;
        sum.grad.iter_mut().zip(&g).for_each(|(a, b)| *a += b);
        sum.info.min_det = sum.info.min_det.min(st.min_det);
        sum.info.inverted += st.inverted;
    }

    fn add_hessian(&self, _at: &StepAt<'_>, z: &[f64], kind: HessianKind, h: &mut Mat<f64>) {
        match kind {
            HessianKind::Exact => add_exact_hessian(self, z, Precision::Double, h),
            HessianKind::Projected { stride, precision } => add_matrix(
                h,
                &self.hessian_sampled(z, Projection::PerPoint, stride, precision),
            ),
        }
    }

    fn add_parameter_adjoint(
        &self,
        _at: &StepAt<'_>,
        z: &[f64],
        adjoint: &[f64],
        out: &mut ParameterAdjoint,
    ) {
        out.inverted += self.add_material_adjoint(z, adjoint, &mut out.mu, &mut out.lambda);
    }

    fn add_rest_hessian(&self, layout: Layout, _dt: f64, h: &mut Mat<f64>) {
        add_matrix(
            h,
            &self.hessian(&vec![0.0; layout.dofs()], Projection::None),
        );
    }
}
