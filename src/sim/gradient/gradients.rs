//! What a reverse pass returns ([`Gradients`]): dL/d(parameter) for the initial state, the
//! materials (per cubature point, as the simulation uses them; per integration point or per
//! region by summing), gravity and the colliders' friction and stiffness.

use crate::precompute::sampling::IntegrationPoints;
use crate::precompute::skinning::SkinningWeights;
use crate::sim::object::{Placement, PlacementGradient, ReducedSim};
use crate::sim::terms::{ParameterAdjoint, PoseGradient, StepPoseGradient};
use crate::{Error, Result};
use faer::Mat;
use rayon::prelude::*;

/// The gradients of a scalar loss L over a recorded run ([`super::Recording::backward`]).
/// Units: the loss's unit per unit of each parameter.
#[derive(Debug, Clone)]
pub struct Gradients {
    /// dL/dz at the recording's start, 12 (m + 1).
    pub z0: Vec<f64>,
    /// dL/dzdot at the recording's start, 12 (m + 1), per (1/s).
    pub zdot0: Vec<f64>,
    /// dL/dE per cubature point (the elastic energy's points; E of the integration point it
    /// sits on), per Pa. A region's dL/dE is the sum over its points
    /// ([`Gradients::youngs_at_points`] scatters them to the integration points).
    pub youngs: Vec<f64>,
    /// dL/dnu per cubature point.
    pub poisson: Vec<f64>,
    /// The integration point each cubature point sits on (the cubature's `source`).
    pub cubature_source: Vec<usize>,
    /// dL/dg, per (m/s^2); None when the object has no gravity term (gravity is not a
    /// parameter of this run).
    pub gravity: Option<[f64; 3]>,
    /// dL/dmu per collider (its friction coefficient), the loss's unit; None when the object
    /// has no collider friction (then mu is not a parameter of this run). A collider with
    /// mu = 0 among others with friction gets its one-sided derivative.
    pub friction: Option<Vec<f64>>,
    /// dL/dkappa per collider (its penalty stiffness), per Pa/m^2; empty without colliders.
    pub collider_stiffness: Vec<f64>,
    /// The density's bilinear form: dL/drho_i = v_i (b_i^T Q b_i + q . b_i).
    density_quadratic: Mat<f64>,
    density_linear: Vec<f64>,
    /// The recording's start state (z_0, zdot_0), for [`Gradients::placement`].
    start: (Vec<f64>, Vec<f64>),
    /// The recorded object's revision ([`ReducedSim::revision`]) when the pass ran.
    revision: u64,
    /// Steps reversed.
    pub steps: usize,
    /// Wall time of the reverse pass, seconds.
    pub backward_s: f64,
    /// Exact Hessians the reverse pass formed and factorized (the other steps' solves were
    /// conjugate gradients preconditioned by the last factor).
    pub exact_hessians: usize,
    /// Matrix-free Hessian-vector products those conjugate gradients took.
    pub hessian_products: usize,
    /// dL/d(pose) of every collider in every recorded step, steps x colliders (empty
    /// without colliders): at the pose the step began with and at its end. For a pose that
    /// follows a motion, dL/d(pose at the end of step t) = `[t - 1][o].end` +
    /// `[t][o].start`; for a pose held through the whole run (set before it), the sum of
    /// every step's `start` and `end`. Setting a pose during a recording changes the object
    /// (the recording refuses the next step).
    pub collider_poses: Vec<Vec<StepPoseGradient>>,
    /// dL/d(target pose) of every held region at the end of every recorded step, steps x
    /// regions (empty without held regions): the target transform of rest positions (its
    /// motion after the placement) along a small world translation and rotation about its
    /// origin.
    pub boundary_poses: Vec<Vec<PoseGradient>>,
    /// dL/dkappa per held region (its penalty stiffness), per Pa/m^2.
    pub boundary_stiffness: Vec<f64>,
}

/// (dmu/dE, dlambda/dE, dmu/dnu, dlambda/dnu) at Lame parameters (lambda, mu), Pa, from
/// mu = E / (2 (1 + nu)) and lambda = E nu / ((1 + nu)(1 - 2 nu)).
pub fn lame_derivatives(lambda: f64, mu: f64) -> [f64; 4] {
    let e = mu * (3.0 * lambda + 2.0 * mu) / (lambda + mu);
    let nu = lambda / (2.0 * (lambda + mu));
    let d = (1.0 + nu) * (1.0 - 2.0 * nu);
    [
        mu / e,
        lambda / e,
        -mu / (1.0 + nu),
        e * (1.0 + 2.0 * nu * nu) / (d * d),
    ]
}

impl Gradients {
    /// The gradients from the terms' summed adjoints `adj` over `steps` steps, the
    /// cubature's Lame parameters (`lambda`, `mu`, Pa) and source indices.
    pub(crate) fn new(
        adj: ParameterAdjoint,
        state: (Vec<f64>, Vec<f64>),
        (start, revision): ((Vec<f64>, Vec<f64>), u64),
        cubature: (&[f64], &[f64], &[usize]),
        steps: usize,
        (backward_s, exact_hessians, hessian_products): (f64, usize, usize),
        (collider_poses, boundary_poses): (Vec<Vec<StepPoseGradient>>, Vec<Vec<PoseGradient>>),
    ) -> Gradients {
        let (lambda, mu, source) = cubature;
        let (youngs, poisson) = (0..mu.len())
            .map(|c| {
                let [mu_e, la_e, mu_nu, la_nu] = lame_derivatives(lambda[c], mu[c]);
                (
                    adj.mu[c] * mu_e + adj.lambda[c] * la_e,
                    adj.mu[c] * mu_nu + adj.lambda[c] * la_nu,
                )
            })
            .unzip();
        Gradients {
            z0: state.0,
            zdot0: state.1,
            youngs,
            poisson,
            cubature_source: source.to_vec(),
            gravity: adj.gravity,
            friction: (!adj.friction.is_empty()).then_some(adj.friction),
            collider_stiffness: adj.collider_stiffness,
            density_quadratic: adj.density_quadratic,
            density_linear: adj.density_linear,
            start,
            revision,
            steps,
            backward_s,
            exact_hessians,
            hessian_products,
            collider_poses,
            boundary_poses,
            boundary_stiffness: adj.boundary_stiffness,
        }
    }

    /// dL/d(placement): translation, rotation, velocity and angular velocity of `placement`,
    /// the placement `sim` (the object recorded) started the recording at
    /// ([`ReducedSim::placement_gradient`]).
    ///
    /// # Errors
    /// [`Error::Gradient`] for another object or one changed since the pass, a recording
    /// that did not start at `placement`, or an object with held regions.
    pub fn placement(&self, sim: &ReducedSim, placement: &Placement) -> Result<PlacementGradient> {
        if sim.revision() != self.revision {
            return Err(Error::Gradient(
                "the object is not the one the gradients were taken of, or it was changed \
                 since (a setter or a reset)"
                    .into(),
            ));
        }
        sim.placement_gradient(
            placement,
            (&self.start.0, &self.start.1),
            (&self.z0, &self.zdot0),
        )
    }

    /// dL/dE of a homogeneous object (every point's E the one parameter): the sum over the
    /// cubature points, per Pa.
    pub fn youngs_total(&self) -> f64 {
        self.youngs.iter().sum()
    }

    /// dL/dnu of a homogeneous object: the sum over the cubature points.
    pub fn poisson_total(&self) -> f64 {
        self.poisson.iter().sum()
    }

    /// dL/dE per integration point (`points` of them, the object's): the cubature points'
    /// values at the points they sit on, 0 elsewhere (the elastic energy does not see them).
    pub fn youngs_at_points(&self, points: usize) -> Result<Vec<f64>> {
        self.scatter(&self.youngs, points)
    }

    /// dL/dnu per integration point, as [`Gradients::youngs_at_points`].
    pub fn poisson_at_points(&self, points: usize) -> Result<Vec<f64>> {
        self.scatter(&self.poisson, points)
    }

    fn scatter(&self, values: &[f64], points: usize) -> Result<Vec<f64>> {
        let mut out = vec![0.0; points];
        for (&i, v) in self.cubature_source.iter().zip(values) {
            let slot = out.get_mut(i).ok_or_else(|| {
                Error::Gradient(format!(
                    "cubature point on integration point {i}, but the object has {points} \
                     integration points: pass the object's own count"
                ))
            })?;
            *slot += v;
        }
        Ok(out)
    }

    /// dL/drho per integration point, per (kg/m^3): the points `ip` and their skinning
    /// weights `weights` (values used) are the ones the object was built from (the mass
    /// moments sum over all of them). A region's dL/drho is the sum over its points.
    pub fn density(&self, ip: &IntegrationPoints, weights: &SkinningWeights) -> Result<Vec<f64>> {
        let nh = weights.modes;
        let n4 = self.density_linear.len();
        if 4 * nh != n4 || weights.points() != ip.len() {
            return Err(Error::Gradient(format!(
                "density gradients need the object's integration points and their weights \
                 ({} handles, one weight row per point); got {} handles for {} points with \
                 {} weight rows",
                n4 / 4,
                nh,
                ip.len(),
                weights.points()
            )));
        }
        let q = &self.density_quadratic;
        Ok((0..ip.len())
            .into_par_iter()
            .map(|i| {
                let x = ip.points[i];
                let xh = [x[0], x[1], x[2], 1.0];
                let b: Vec<f64> = (0..n4)
                    .map(|k| weights.values[i * nh + k / 4] * xh[k % 4])
                    .collect();
                let mut s: f64 = b.iter().zip(&self.density_linear).map(|(a, c)| a * c).sum();
                for (k, bk) in b.iter().enumerate() {
                    let col = q.col(k);
                    s += bk * b.iter().enumerate().map(|(l, bl)| col[l] * bl).sum::<f64>();
                }
                ip.volumes[i] * s
            })
            .collect())
    }
}
