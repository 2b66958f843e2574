//! Building an object's reduced model: the cubature, the terms its options ask for (and no
//! others) and the rest system's factor.

use super::options::{placement_transform, SimOptions, PENALTY_FACTOR, SWEEP_DEPTH};
use crate::material::MaterialField;
use crate::precompute::boundary_modes::lift_column;
use crate::precompute::sampling::IntegrationPoints;
use crate::precompute::skinning::{Basis, SkinningWeights};
use crate::sim::cubature::{self, Cubature};
use crate::sim::elastic::{ElasticTerm, Layout};
use crate::sim::environment::{check_gravity, Environment};
use crate::sim::motion::Rigid;
use crate::sim::terms::{BoundaryTerm, ContactTerm, GravityTerm, InertiaTerm, Moments, Terms};
use crate::{Error, Point3, Result};
use faer::linalg::solvers::Llt;
use faer::Side;

/// An object's reduced model, before it has a state.
pub(super) struct Model {
    pub(super) layout: Layout,
    pub(super) terms: Terms,
    pub(super) rest_factor: Llt<f64>,
    /// Rest bounding-box diagonal D, metres.
    pub(super) diag: f64,
    /// [`PENALTY_FACTOR`] x max(rho / h^2, E / D^2), Pa/m^2.
    pub(super) default_penalty: f64,
    pub(super) cubature: Cubature,
    /// The initial placement's rigid transform.
    pub(super) placement: Rigid,
    /// Gravity and the colliders of the options.
    pub(super) env: Environment,
}

/// `v` is positive and finite, else an error naming `name` and saying `what` it is.
pub(super) fn positive(name: &'static str, v: f64, what: &str) -> Result<()> {
    if v > 0.0 && v.is_finite() {
        Ok(())
    } else {
        Err(Error::param(
            name,
            v,
            format!("{what} must be positive and finite"),
        ))
    }
}

/// The model of an object with basis `basis`, integration points `ip`, material `material`
/// and the skinning weights at the points `weights`, as `opts` ask.
pub(super) fn build(
    basis: &Basis,
    ip: &IntegrationPoints,
    material: &MaterialField,
    weights: &SkinningWeights,
    opts: &SimOptions,
) -> Result<Model> {
    positive("dt", opts.dt, "the time step (seconds)")?;
    opts.newton.validate()?;
    check_gravity(opts.gravity)?;
    let n = ip.len();
    if material.len() != n {
        return Err(Error::LengthMismatch {
            what: "material (integration points)",
            expected: n,
            got: material.len(),
        });
    }
    if weights.modes != basis.modes()
        || weights.points() != n
        || weights.gradients.len() != weights.values.len()
    {
        return Err(Error::LengthMismatch {
            what: "skinning weights (integration points x modes, with gradients)",
            expected: n * basis.modes(),
            got: weights.gradients.len().min(weights.values.len()),
        });
    }
    let all = weights;
    let layout = Layout {
        handles: basis.modes(),
    };
    let cub = cubature::select(ip, material, opts.cubature)?;
    let cw = subset(all, &cub.source);
    let elastic = ElasticTerm::new(&cub, &cw)?;
    let idx: Vec<usize> = (0..n).collect();
    let rho_v: Vec<f64> = (0..n)
        .map(|i| material.density[i] * ip.volumes[i])
        .collect();
    let mass = Moments::new(&ip.points, all, &idx, &rho_v);
    let aabb = crate::geometry::Aabb::from_points(&ip.points)
        .ok_or_else(|| Error::param("points", 0, "the object has no integration points"))?;
    let diag = aabb.diagonal().max(f64::MIN_POSITIVE);
    let h2 = opts.dt * opts.dt;
    let rho_max = material.density.iter().cloned().fold(0.0, f64::max);
    let e_max = material.youngs.iter().cloned().fold(0.0, f64::max);
    let default_k = PENALTY_FACTOR * (rho_max / h2).max(e_max / (diag * diag));
    let placement = placement_transform(&opts.placement)?;
    let mut boundaries = Vec::new();
    for (b, spec) in opts.boundaries.iter().enumerate() {
        spec.motion.validate()?;
        let k = spec.stiffness.unwrap_or(default_k);
        positive("stiffness", k, "a boundary penalty stiffness (Pa/m^2)")?;
        let pts: Vec<usize> = (0..n)
            .filter(|&i| spec.region.contains(&ip.points[i]))
            .collect();
        if pts.is_empty() {
            return Err(Error::param(
                "boundary",
                b,
                format!(
                    "region {:?} contains no integration point of the object (regions are \
                     in rest coordinates; the object spans {:?} to {:?})",
                    spec.region, aabb.min, aabb.max
                ),
            ));
        }
        let coef: Vec<f64> = pts.iter().map(|&i| k * ip.volumes[i]).collect();
        let pointwise = Moments::new(&ip.points, all, &pts, &coef);
        let (moments, pointwise) = match lift_column(basis, &spec.region) {
            // An aware region is held through its lift's handle alone (the region's points
            // as if every other weight were 0 there): the free modes ramp up near the
            // region's edge and must not be held (boundary_modes.rs).
            Some(j) => {
                let nh = all.modes;
                let held = SkinningWeights {
                    modes: nh,
                    values: (0..pts.len() * nh)
                        .map(|e| if e % nh == j { 1.0 } else { 0.0 })
                        .collect(),
                    gradients: vec![[0.0; 3]; pts.len() * nh],
                };
                let local: Vec<Point3> = pts.iter().map(|&i| ip.points[i]).collect();
                let idx: Vec<usize> = (0..pts.len()).collect();
                (Moments::new(&local, &held, &idx, &coef), Some(pointwise))
            }
            None => (pointwise, None),
        };
        boundaries.push(BoundaryTerm {
            index: b,
            motion: spec.motion.clone(),
            stiffness: k,
            moments,
            points: pts,
            placement,
            pointwise,
        });
    }
    let env = Environment::new(opts.gravity, &opts.colliders)?;
    let colliders = if opts.colliders.is_empty() {
        None
    } else {
        let mut ks = Vec::new();
        for (i, c) in opts.colliders.iter().enumerate() {
            let k = c.stiffness.unwrap_or(default_k);
            positive("stiffness", k, "a collider penalty stiffness (Pa/m^2)")
                .map_err(|e| c.error(i, e))?;
            ks.push(k);
        }
        Some(ContactTerm::new(
            ks,
            &cub.points,
            &cub.volumes,
            &cw,
            SWEEP_DEPTH * diag,
        ))
    };
    let gravity = opts.gravity.map(|_| GravityTerm { b: mass.b.clone() });
    let terms = Terms {
        inertia: InertiaTerm { mass },
        elastic,
        gravity,
        boundaries,
        colliders,
        added: Vec::new(),
    };
    let rest_factor = rest_factor(&terms, layout, opts.dt)?;
    Ok(Model {
        layout,
        terms,
        rest_factor,
        diag,
        default_penalty: default_k,
        cubature: cub,
        placement,
        env,
    })
}

/// The Cholesky factor of the rest system S = M/h^2 + K_rest + boundary penalties (every
/// term's rest Hessian, [`crate::sim::terms::Term::add_rest_hessian`]).
pub(super) fn rest_factor(terms: &Terms, layout: Layout, dt: f64) -> Result<Llt<f64>> {
    terms
        .rest_hessian(layout, dt)
        .llt(Side::Lower)
        .map_err(|e| {
            Error::param(
                "modes",
                layout.handles - 1,
                format!(
                    "the reduced rest system is not positive definite ({e:?}): the skinning \
                 modes are linearly dependent on the integration points; use fewer modes \
                 or more kernels"
                ),
            )
        })
}

/// The weights (values and gradients) at the points `idx`.
fn subset(w: &SkinningWeights, idx: &[usize]) -> SkinningWeights {
    let m = w.modes;
    SkinningWeights {
        modes: m,
        values: idx
            .iter()
            .flat_map(|&i| w.values[i * m..(i + 1) * m].iter().copied())
            .collect(),
        gradients: idx
            .iter()
            .flat_map(|&i| w.gradients[i * m..(i + 1) * m].iter().copied())
            .collect(),
    }
}
