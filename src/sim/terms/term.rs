//! What every term of the incremental potential provides ([`Term`]) and what it is given: the
//! step's fixed data ([`StepAt`]), the running sum of energy and gradient ([`EnergySum`]) and
//! which Hessian is asked for ([`HessianKind`]).

use super::adjoint::ParameterAdjoint;
use crate::sim::elastic::{Layout, Precision};
use crate::sim::environment::Environment;
use crate::sim::friction::{ColliderLag, Curvature};
use crate::sim::newton::EvalInfo;
use faer::Mat;
use std::fmt;

/// What a step fixes when it begins, the same for every evaluation within it.
#[derive(Debug, Clone, Copy)]
pub struct StepAt<'a> {
    /// The layout of z.
    pub layout: Layout,
    /// Time at the end of the step (where the potential is evaluated), seconds.
    pub t: f64,
    /// The time step h, seconds.
    pub dt: f64,
    /// The inertial predictor z_n + h zdot_n, 12 (m + 1).
    pub zpred: &'a [f64],
    /// Lagged collider friction contacts and the smoothing displacement eps_v h, metres
    /// (None: frictionless).
    pub friction: Option<(&'a [ColliderLag], f64)>,
    /// The curvature the friction's Hessian takes ([`crate::sim::friction::Curvature`]):
    /// exact, or its majorizer in a Newton model.
    pub friction_curvature: Curvature,
    /// Gravity and the colliders, as the step's owner holds them.
    pub env: &'a Environment,
}

/// The energy (J) and gradient (J per unit of z) of the terms evaluated so far, and what they
/// found. Terms add to `energy` and `grad`; the potential reads the total at the end.
pub struct EnergySum<'g> {
    /// Energy so far, J.
    pub energy: f64,
    /// Gradient so far, 12 (m + 1); zero before the first term.
    pub grad: &'g mut [f64],
    /// Inversion and contact statistics (`rounding` is set by [`EnergySum::rounding`]).
    pub info: EvalInfo,
    /// The size of the summed parts for the rounding estimate: |energy of the smooth terms|
    /// once the first penalty term began, plus every penalty's own size.
    scale: Option<f64>,
}

impl<'g> EnergySum<'g> {
    /// An empty sum writing its gradient to `grad` (zeroed here).
    pub fn new(grad: &'g mut [f64]) -> EnergySum<'g> {
        grad.fill(0.0);
        EnergySum {
            energy: 0.0,
            grad,
            info: EvalInfo {
                min_det: f64::INFINITY,
                ..EvalInfo::default()
            },
            scale: None,
        }
    }

    /// A penalty term begins: the smooth terms before it count in the rounding estimate by the
    /// size of their sum (each is a sum of like-signed parts, or a small linear one).
    pub(crate) fn begin_penalty(&mut self) {
        if self.scale.is_none() {
            self.scale = Some(self.energy.abs());
        }
    }

    /// A penalty term's energy is a difference of parts of total size `magnitude` (J): its
    /// rounding is a few ulps of that, not of its value.
    pub fn add_magnitude(&mut self, magnitude: f64) {
        let s = self.scale.get_or_insert(self.energy.abs());
        *s += magnitude;
    }

    /// The estimated rounding error of the energy (J) over `layout`'s dot products of n4
    /// terms: a few ulps of the summed size.
    pub fn rounding(&self, layout: Layout) -> f64 {
        let scale = self.scale.unwrap_or(self.energy.abs());
        scale * 1e-16 * (layout.row_len() as f64).sqrt() * 4.0
    }
}

/// Which Hessian a term adds.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum HessianKind {
    /// The exact Hessian (it may be indefinite).
    Exact,
    /// A positive semi-definite approximation, as Newton and the quasi-Newton bases factorize
    /// it: the elastic part from every `stride`-th cubature point in `precision`, collider
    /// curvature that is negative dropped.
    Projected {
        /// Every stride-th cubature point carries the elastic part (1: all).
        stride: usize,
        /// The arithmetic of the elastic part's dense products.
        precision: Precision,
    },
}

/// What a term is, for reports ([`crate::sim::ReducedSim::terms`]); its `Display` is the
/// report's text.
#[derive(Debug, Clone, PartialEq)]
pub enum TermKind {
    /// 1/(2 h^2) |z - z_pred|_M^2.
    Inertia,
    /// The hyperelastic energy over the cubature points.
    Elastic,
    /// The work of gravity.
    Gravity,
    /// A held or driven region: its index among the boundaries and its integration points.
    Boundary {
        /// Index in [`crate::sim::SimOptions::boundaries`].
        index: usize,
        /// Integration points in the region.
        points: usize,
    },
    /// The collider penalties (and their friction): the obstacles' kinds.
    Colliders {
        /// One kind per collider ("plane", "box", ...).
        kinds: Vec<&'static str>,
    },
    /// A term added by the caller ([`crate::sim::ReducedSim::add_term`]), named by it.
    Custom(String),
}

impl fmt::Display for TermKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            TermKind::Inertia => f.write_str("inertia"),
            TermKind::Elastic => f.write_str("elastic"),
            TermKind::Gravity => f.write_str("gravity"),
            TermKind::Boundary { index, points } => write!(f, "boundary {index} ({points} points)"),
            TermKind::Colliders { kinds } => {
                write!(f, "colliders ({}: {})", kinds.len(), kinds.join(", "))
            }
            TermKind::Custom(name) => f.write_str(name),
        }
    }
}

/// One term of an object's incremental potential E(z) = sum of its terms, z the reduced
/// coordinates (12 (m + 1)). The object evaluates its terms in order and adds up what each
/// returns; a term that is not built is not evaluated.
///
/// A new term is a type implementing this trait, registered with
/// [`crate::sim::ReducedSim::add_term`] (or, built in, one entry of
/// [`super::Terms::iter`]). Its energy, gradient and Hessian are checked against each other
/// by [`crate::derivatives::check_derivatives`].
pub trait Term: Send + Sync {
    /// What the term is, for reports, in the environment `env` (the colliders' kinds are
    /// the environment's).
    fn kind(&self, env: &Environment) -> TermKind;

    /// Add the energy (J) at `z` to `sum.energy` and its gradient to `sum.grad`. A penalty
    /// term ([`Term::is_penalty`]) reports the size of its summed parts with
    /// [`EnergySum::add_magnitude`].
    fn add_energy_gradient(&self, at: &StepAt<'_>, z: &[f64], sum: &mut EnergySum<'_>);

    /// Add the Hessian at `z` to `h` (12 (m + 1) square): exact or PSD ([`HessianKind`]).
    fn add_hessian(&self, at: &StepAt<'_>, z: &[f64], kind: HessianKind, h: &mut Mat<f64>);

    /// Add the Hessian at rest (z = 0) that the object's fixed preconditioner includes (the
    /// rest system, factorized once at setup); default: nothing (a term that is zero at rest,
    /// or whose curvature comes and goes, like contact).
    /// `dt` is the time step, seconds.
    fn add_rest_hessian(&self, layout: Layout, dt: f64, h: &mut Mat<f64>) {
        let _ = (layout, dt, h);
    }

    /// The largest step fraction the line search may take along `dir` from `z` (default:
    /// unbounded); colliders bound it so that no point crosses a thin obstacle.
    fn max_step(&self, at: &StepAt<'_>, z: &[f64], dir: &[f64]) -> f64 {
        let _ = (at, z, dir);
        f64::INFINITY
    }

    /// The reverse pass of a converged step: add -adjoint^T d(this term's gradient at `z`)/dp
    /// to `out` for every parameter p the term depends on (the step's predictor, materials,
    /// gravity; [`ParameterAdjoint`]), where `adjoint` solves H adjoint = dL/dz at the step's
    /// end `z`. Default: nothing, for a term that depends on none of them (a caller's term
    /// that reads [`StepAt::zpred`] must add its part to `out.zpred`).
    fn add_parameter_adjoint(
        &self,
        at: &StepAt<'_>,
        z: &[f64],
        adjoint: &[f64],
        out: &mut ParameterAdjoint,
    ) {
        let _ = (at, z, adjoint, out);
    }

    /// Whether the energy is a penalty: a difference of large parts whose rounding is
    /// estimated from their size, evaluated after the smooth terms (default: no).
    fn is_penalty(&self) -> bool {
        false
    }
}
