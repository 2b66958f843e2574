//! The terms of an object's incremental potential, each behind [`Term`]: inertia, elasticity
//! and gravity (smooth), kinematic boundary penalties and one-sided collider penalties with
//! their friction, and any term a caller adds. [`Terms`] holds an object's built terms and
//! sums them.
//!
//! Leaves first: `term` (the trait and what it is given), `moments` (the quadratic forms'
//! coefficients), then one file per term, then this file's sum. Every term's test checks its
//! derivatives with [`check_derivatives`] (the leaf `crate::derivatives`, re-exported here).

mod adjoint;
mod boundary;
mod collider;
mod elastic;
mod gravity;
mod inertia;
mod moments;
mod term;

pub use crate::derivatives::{check_derivatives, DerivativeCheck, Floors, HessianFn};
pub use crate::sim::collider::ColliderShape;
pub use crate::sim::friction::ColliderLag;
pub use adjoint::{ParameterAdjoint, PoseGradient, StepPoseGradient};
pub use boundary::BoundaryTerm;
pub use collider::{ContactHessian, ContactInfo, ContactTerm, SWEEP_SAMPLES};
pub use gravity::GravityTerm;
pub use inertia::InertiaTerm;
pub use moments::{add_block_diagonal, add_block_product, add_outer_blocks, Moments};
pub use term::{EnergySum, HessianKind, StepAt, Term, TermKind};

use crate::sim::elastic::{ElasticHessian, ElasticTerm, Layout, Precision};
use crate::sim::environment::Environment;
use crate::sim::newton::EvalInfo;
use faer::Mat;

/// The exact Hessian of a potential at one state as an operator ([`Terms::exact_operator`]).
pub struct ExactHessian<'a> {
    /// Every term's exact Hessian but the elastic one, 12 (m + 1) square.
    others: Mat<f64>,
    elastic: ElasticHessian<'a>,
}

impl ExactHessian<'_> {
    /// H v, 12 (m + 1).
    pub fn product(&self, v: &[f64]) -> Vec<f64> {
        let mut out = self.elastic.product(v);
        let hv = &self.others * faer::ColRef::from_slice(v);
        out.iter_mut().zip(hv.iter()).for_each(|(a, b)| *a += b);
        out
    }
}

/// The terms one object was built with, in evaluation order: inertia, elastic, gravity (if
/// any), boundaries, colliders (if any), then the caller's.
pub struct Terms {
    pub(crate) inertia: InertiaTerm,
    pub(crate) elastic: ElasticTerm,
    pub(crate) gravity: Option<GravityTerm>,
    pub(crate) boundaries: Vec<BoundaryTerm>,
    pub(crate) colliders: Option<ContactTerm>,
    pub(crate) added: Vec<Box<dyn Term>>,
}

impl Terms {
    /// Every built term, in evaluation order (the smooth ones before the penalties).
    pub fn iter(&self) -> impl Iterator<Item = &dyn Term> + '_ {
        let inertia: &dyn Term = &self.inertia;
        let elastic: &dyn Term = &self.elastic;
        [inertia, elastic].into_iter().chain(self.after_elastic())
    }

    /// The terms after inertia and elasticity, in evaluation order.
    fn after_elastic(&self) -> impl Iterator<Item = &dyn Term> + '_ {
        self.gravity
            .iter()
            .map(|t| t as &dyn Term)
            .chain(self.boundaries.iter().map(|t| t as &dyn Term))
            .chain(self.colliders.iter().map(|t| t as &dyn Term))
            .chain(self.added.iter().map(|t| t.as_ref()))
    }

    /// The potential's energy (J) at `z`, its gradient written to `grad`, and what the terms
    /// found.
    pub fn energy_gradient(&self, at: &StepAt<'_>, z: &[f64], grad: &mut [f64]) -> (f64, EvalInfo) {
        let mut sum = EnergySum::new(grad);
        for term in self.iter() {
            if term.is_penalty() {
                sum.begin_penalty();
            }
            term.add_energy_gradient(at, z, &mut sum);
        }
        let info = EvalInfo {
            rounding: sum.rounding(at.layout),
            ..sum.info
        };
        (sum.energy, info)
    }

    /// The Hessian at `z`, 12 (m + 1) square: exact or PSD ([`HessianKind`]).
    pub fn hessian(&self, at: &StepAt<'_>, z: &[f64], kind: HessianKind) -> Mat<f64> {
        self.sum_hessian(at, z, kind, |h| self.elastic.add_hessian(at, z, kind, h))
    }

    /// The exact Hessian at `z`, as [`Terms::hessian`] sums it for [`HessianKind::Exact`],
    /// with the elastic part's dense products in `precision` (an island's Newton model;
    /// [`Precision::Double`] gives `hessian`'s bits).
    pub fn exact_hessian_in(&self, at: &StepAt<'_>, z: &[f64], precision: Precision) -> Mat<f64> {
        self.sum_hessian(at, z, HessianKind::Exact, |h| {
            elastic::add_exact_hessian(&self.elastic, z, precision, h)
        })
    }

    /// Every term's Hessian of `kind` at `z` summed in evaluation order, the elastic term's
    /// added by `elastic`.
    fn sum_hessian(
        &self,
        at: &StepAt<'_>,
        z: &[f64],
        kind: HessianKind,
        elastic: impl FnOnce(&mut Mat<f64>),
    ) -> Mat<f64> {
        let n = at.layout.dofs();
        let mut h = Mat::zeros(n, n);
        self.inertia.add_hessian(at, z, kind, &mut h);
        elastic(&mut h);
        for term in self.after_elastic() {
            term.add_hessian(at, z, kind, &mut h);
        }
        h
    }

    /// The exact Hessian at `z` as an operator ([`ExactHessian`]): every term but the
    /// elastic one formed (they are cheap), the elastic one matrix-free (forming it is the
    /// costly part).
    pub fn exact_operator(&self, at: &StepAt<'_>, z: &[f64]) -> ExactHessian<'_> {
        let n = at.layout.dofs();
        let mut others = Mat::zeros(n, n);
        let inertia: &dyn Term = &self.inertia;
        for term in std::iter::once(inertia).chain(self.after_elastic()) {
            term.add_hessian(at, z, HessianKind::Exact, &mut others);
        }
        ExactHessian {
            others,
            elastic: self.elastic.hessian_at(z),
        }
    }

    /// The rest system: every term's [`Term::add_rest_hessian`] for the time step `dt`, s.
    pub fn rest_hessian(&self, layout: Layout, dt: f64) -> Mat<f64> {
        let n = layout.dofs();
        let mut h = Mat::zeros(n, n);
        for term in self.iter() {
            term.add_rest_hessian(layout, dt, &mut h);
        }
        h
    }

    /// Every term's [`Term::add_parameter_adjoint`] at the step's end `z` for the adjoint
    /// vector `adjoint` (H adjoint = dL/dz).
    pub fn parameter_adjoint(
        &self,
        at: &StepAt<'_>,
        z: &[f64],
        adjoint: &[f64],
        out: &mut ParameterAdjoint,
    ) {
        for term in self.iter() {
            term.add_parameter_adjoint(at, z, adjoint, out);
        }
    }

    /// The largest line-search step along `dir` from `z` that every term allows.
    pub fn max_step(&self, at: &StepAt<'_>, z: &[f64], dir: &[f64]) -> f64 {
        self.iter()
            .map(|t| t.max_step(at, z, dir))
            .fold(f64::INFINITY, f64::min)
    }

    /// Every term's description in the environment `env`, in evaluation order.
    pub fn kinds(&self, env: &Environment) -> Vec<TermKind> {
        self.iter().map(|t| t.kind(env)).collect()
    }
}
