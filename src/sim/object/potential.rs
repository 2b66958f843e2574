//! The incremental potential of one step: the sum of the object's terms at the step's end
//! time, with the step's predictor and lagged friction ([`StepAt`]), as Newton sees it.

use crate::sim::elastic::{Layout, Precision};
use crate::sim::environment::Environment;
use crate::sim::friction::{ColliderLag, Curvature};
use crate::sim::newton::{EvalInfo, Potential};
use crate::sim::terms::{ExactHessian, HessianKind, ParameterAdjoint, StepAt, Terms};
use faer::Mat;

/// Where a step starts: the inertial predictor z_pred = z_n + h zdot_n, the initial guess
/// of the minimisation and the time at the end of the step, s.
pub(crate) struct StepStart {
    pub(crate) zpred: Vec<f64>,
    pub(crate) guess: Vec<f64>,
    pub(crate) t: f64,
    /// Lagged collider friction contacts and the smoothing displacement eps_v h, metres.
    pub(crate) friction: Option<(Vec<ColliderLag>, f64)>,
}

/// The incremental potential of one step:
/// 1/(2 h^2) |z - z_pred|_M^2 + elastic(z) - gravity work + penalties at time t, and any
/// term the caller added.
pub(crate) struct StepPotential<'a> {
    terms: &'a Terms,
    at: StepAt<'a>,
}

impl<'a> StepPotential<'a> {
    /// The potential of the step that `start` begins, for an object with terms `terms`,
    /// layout `layout` and time step `dt` (s), in the environment `env`.
    pub(crate) fn new(
        terms: &'a Terms,
        layout: Layout,
        dt: f64,
        env: &'a Environment,
        start: &'a StepStart,
    ) -> StepPotential<'a> {
        StepPotential {
            terms,
            at: StepAt {
                layout,
                t: start.t,
                dt,
                zpred: &start.zpred,
                friction: start.friction.as_ref().map(|(l, e)| (l.as_slice(), *e)),
                friction_curvature: Curvature::Exact,
                env,
            },
        }
    }

    /// Number of reduced coordinates.
    pub(crate) fn dofs(&self) -> usize {
        self.at.layout.dofs()
    }

    /// The exact Hessian at `z` as an operator ([`Terms::exact_operator`]).
    pub(crate) fn exact_operator(&self, z: &[f64]) -> ExactHessian<'_> {
        self.terms.exact_operator(&self.at, z)
    }

    /// The step with its friction terms curved as `friction` says.
    fn curved(&self, friction: Curvature) -> StepAt<'a> {
        StepAt {
            friction_curvature: friction,
            ..self.at
        }
    }

    /// The Hessian at `z` an island's Newton factorizes: exact, or with the objects' and
    /// colliders' curvature projected, the elastic part's dense products in `precision`.
    pub(crate) fn hessian_in(
        &self,
        z: &[f64],
        friction: Curvature,
        exact: bool,
        precision: Precision,
    ) -> Mat<f64> {
        let at = self.curved(friction);
        if exact {
            self.terms.exact_hessian_in(&at, z, precision)
        } else {
            let kind = HessianKind::Projected {
                stride: 1,
                precision,
            };
            self.terms.hessian(&at, z, kind)
        }
    }

    /// The terms' parameter adjoints at the step's end `z` ([`Terms::parameter_adjoint`]).
    pub(crate) fn parameter_adjoint(&self, z: &[f64], adjoint: &[f64], out: &mut ParameterAdjoint) {
        self.terms.parameter_adjoint(&self.at, z, adjoint, out);
    }
}

impl Potential for StepPotential<'_> {
    fn energy_gradient(&self, z: &[f64], grad: &mut [f64]) -> (f64, EvalInfo) {
        self.terms.energy_gradient(&self.at, z, grad)
    }

    fn hessian(&self, z: &[f64], friction: Curvature) -> Mat<f64> {
        let kind = HessianKind::Projected {
            stride: 1,
            precision: Precision::Double,
        };
        self.terms.hessian(&self.curved(friction), z, kind)
    }

    fn base_hessian(&self, z: &[f64], stride: usize, precision: Precision) -> Mat<f64> {
        let kind = HessianKind::Projected { stride, precision };
        self.terms.hessian(&self.at, z, kind)
    }

    fn exact_hessian(&self, z: &[f64], friction: Curvature) -> Option<Mat<f64>> {
        Some(
            self.terms
                .hessian(&self.curved(friction), z, HessianKind::Exact),
        )
    }

    fn has_friction(&self) -> bool {
        self.at.friction.is_some_and(|(lag, _)| !lag.is_empty())
    }

    /// The terms' step bound (the colliders' swept bound,
    /// [`crate::sim::terms::ContactTerm::swept_step`]).
    fn max_step(&self, z: &[f64], dir: &[f64]) -> f64 {
        self.terms.max_step(&self.at, z, dir)
    }
}
