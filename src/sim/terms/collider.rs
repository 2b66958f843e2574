//! One-sided collider penalties on the cubature points, their swept step bound and lagged
//! friction against the colliders.

use super::adjoint::ParameterAdjoint;
use super::moments::add_outer_blocks;
use super::term::{EnergySum, HessianKind, StepAt, Term, TermKind};
use crate::linalg3::{dot, mul, transpose};
use crate::precompute::skinning::SkinningWeights;
use crate::sim::collider::{Kinematics, Obstacle, Penetration};
use crate::sim::elastic::Layout;
use crate::sim::environment::Environment;
use crate::sim::friction::{ColliderLag, Curvature};
use crate::Point3;
use faer::Mat;

/// Path samples a cubature point's sweep follows at most per line-search direction
/// ([`ContactTerm::swept_step`]): with delta = 1% of the object's diagonal, a point may move
/// 5 diagonals near an obstacle in one iterate.
pub const SWEEP_SAMPLES: usize = 1000;

/// One obstacle in [`ContactTerm::swept_step`]: its index, the allowed extra depth delta
/// (metres) and its bounding sphere at its pose (None: unbounded).
#[derive(Clone, Copy)]
struct Sweep {
    obstacle: usize,
    delta: f64,
    sphere: Option<(Point3, f64)>,
}

/// Distance from `c` to the segment from `x` to `x + dx`, metres.
fn segment_distance(x: &Point3, dx: &[f64; 3], c: &Point3) -> f64 {
    let w: [f64; 3] = std::array::from_fn(|d| c[d] - x[d]);
    let len2 = dot(dx, dx);
    let s = if len2 > 0.0 {
        (dot(&w, dx) / len2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    let e: [f64; 3] = std::array::from_fn(|d| w[d] - s * dx[d]);
    dot(&e, &e).sqrt()
}

/// One-sided collider penalties kappa/2 sum_c v_c d_c^2 on the cubature points, d_c the
/// penetration depth of point c in each obstacle at the obstacles' poses at time t
/// ([`Kinematics`]).
#[derive(Debug, Clone)]
pub struct ContactTerm {
    /// Penalty stiffness per obstacle, Pa/m^2.
    pub stiffness: Vec<f64>,
    points: Vec<Point3>,
    volumes: Vec<f64>,
    w: Vec<f64>,
    handles: usize,
    /// How much deeper than where it is a point may enter an obstacle within one line-search
    /// step, metres ([`ContactTerm::swept_step`]'s `scale`).
    sweep_depth: f64,
    /// Friction: mu per collider and the smoothing velocity eps_v (m/s); None: frictionless
    /// (no friction code runs).
    friction: Option<(Vec<f64>, f64)>,
}

/// What one evaluation of the contact penalties found.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ContactInfo {
    /// Penalty energy, J.
    pub energy: f64,
    /// Penetrating (cubature point, obstacle) pairs.
    pub active: usize,
    /// Deepest penetration, metres (0 without contact).
    pub deepest: f64,
}

/// Which Hessian of the penalties to add.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ContactHessian {
    /// The positive semi-definite part (what Newton factorizes): exact for planes, boxes and
    /// meshes; for spheres and capsules the curvature part, negative inside, is left out.
    Psd,
    /// The exact Hessian of the penalty (for tests and diagnostics).
    Exact,
}

impl ContactTerm {
    /// Contacts of the cubature points `points` (volumes `volumes`, skinning weights `w`)
    /// with the environment's obstacles, one penalty stiffness (Pa/m^2) each; a line-search
    /// step takes no point deeper than `sweep_depth` (metres) beyond where it is. Frictionless
    /// until [`ContactTerm::set_friction`].
    pub fn new(
        stiffness: Vec<f64>,
        points: &[Point3],
        volumes: &[f64],
        w: &SkinningWeights,
        sweep_depth: f64,
    ) -> ContactTerm {
        ContactTerm {
            stiffness,
            points: points.to_vec(),
            volumes: volumes.to_vec(),
            w: w.values.clone(),
            handles: w.modes,
            sweep_depth,
            friction: None,
        }
    }

    /// Friction from the next step on: mu per collider (checked by the caller) and the
    /// smoothing velocity eps_v, m/s; None: frictionless.
    pub(crate) fn set_friction(&mut self, friction: Option<(Vec<f64>, f64)>) {
        self.friction = friction;
    }

    /// Whether any collider has friction.
    pub fn has_friction(&self) -> bool {
        self.friction.is_some()
    }

    /// The lagged friction contacts of a step of `dt` seconds from `t0` (state `z`, the
    /// obstacles of `kin`) and the smoothing displacement eps_v dt, metres; None when
    /// frictionless.
    pub(crate) fn step_friction(
        &self,
        kin: &Kinematics,
        layout: Layout,
        t0: f64,
        dt: f64,
        z: &[f64],
    ) -> Option<(Vec<ColliderLag>, f64)> {
        let (mu, eps_v) = self.friction.as_ref()?;
        Some((
            self.friction_lag(kin, layout, t0, t0 + dt, z, mu),
            eps_v * dt,
        ))
    }

    /// Colliders this term was built for.
    pub fn len(&self) -> usize {
        self.stiffness.len()
    }

    /// Whether it has no collider (never: an object without colliders has no such term).
    pub fn is_empty(&self) -> bool {
        self.stiffness.is_empty()
    }

    fn b(&self, c: usize) -> impl Iterator<Item = (usize, f64)> + '_ {
        let x = self.points[c];
        let xh = [x[0], x[1], x[2], 1.0];
        (0..4 * self.handles).map(move |k| (k, self.w[c * self.handles + k / 4] * xh[k % 4]))
    }

    /// Current position of cubature point `c`: X + B(X) z, handle by handle (the hot loop of
    /// every collider query).
    fn position(&self, layout: Layout, c: usize, z: &[f64]) -> Point3 {
        crate::sim::deformation::skinned_position(
            self.points[c],
            &self.w[c * self.handles..(c + 1) * self.handles],
            z,
            layout.row_len(),
        )
    }

    /// Every penetration at `z` and time `t`: (cubature point, obstacle, penetration).
    fn penetrations(
        &self,
        kin: &Kinematics,
        layout: Layout,
        t: f64,
        z: &[f64],
    ) -> Vec<(usize, usize, Penetration)> {
        let poses = kin.poses(t);
        let obstacles = kin.obstacles();
        // Bounding spheres in world coordinates, for a cheap rejection.
        let bounds: Vec<Option<(Point3, f64)>> = obstacles
            .iter()
            .zip(&poses)
            .map(|(o, p)| o.bounding_sphere().map(|(c, r)| (p.apply(&c), r)))
            .collect();
        let point = |c: usize| {
            let x = self.position(layout, c, z);
            let mut found = Vec::new();
            for (o, ((obstacle, pose), bound)) in
                obstacles.iter().zip(&poses).zip(&bounds).enumerate()
            {
                if let Some((centre, r)) = bound {
                    let d2: f64 = (0..3).map(|d| (x[d] - centre[d]).powi(2)).sum();
                    if d2 >= r * r {
                        continue;
                    }
                }
                if let Some(p) = obstacle.penetration(pose, &x) {
                    found.push((c, o, p));
                }
            }
            found
        };
        // Mesh queries cost microseconds per point (docs/performance.md): spread the points
        // over threads. The result keeps point order, so the sums over it do not depend on
        // the thread count.
        if obstacles.iter().any(|o| o.mesh().is_some()) {
            use rayon::prelude::*;
            (0..self.points.len())
                .into_par_iter()
                .with_min_len(64)
                .flat_map_iter(point)
                .collect()
        } else {
            (0..self.points.len()).flat_map(point).collect()
        }
    }

    /// Energy (J), gradient added to `grad`, the number of penetrating (point, obstacle)
    /// pairs and the deepest penetration, with the obstacles at their poses at time `t` (s).
    pub fn energy_gradient(
        &self,
        kin: &Kinematics,
        layout: Layout,
        t: f64,
        z: &[f64],
        grad: &mut [f64],
    ) -> ContactInfo {
        let n4 = layout.row_len();
        let mut info = ContactInfo::default();
        for (c, o, p) in self.penetrations(kin, layout, t, z) {
            let (k, v, d, u) = (self.stiffness[o], self.volumes[c], p.depth, p.normal);
            info.active += 1;
            info.deepest = info.deepest.max(d);
            info.energy += 0.5 * k * v * d * d;
            // dE/dx = -k v d u.
            for (kk, bk) in self.b(c) {
                for r in 0..3 {
                    grad[r * n4 + kk] -= k * v * d * u[r] * bk;
                }
            }
        }
        info
    }

    /// The largest step fraction alpha in [0, 1] along `dir` from `z` (infinite when
    /// nothing limits it) such that no cubature point goes deeper into an obstacle (at its
    /// pose at time `t`) than its depth at `z` plus delta, delta = min(`scale` (metres), half
    /// the obstacle's [`crate::sim::collider::Obstacle::half_thickness`]), anywhere along its
    /// straight path: a swept
    /// test, so a fast point cannot jump across a thin obstacle between iterates (the
    /// penalty alone only sees where it lands). The depth is 1-Lipschitz in the position, so
    /// it is checked at path samples delta/2 apart against depth(z) + delta/2; a path is
    /// followed for at most [`SWEEP_SAMPLES`] samples (a point moving farther near an
    /// obstacle is bounded there). Planes bound nothing.
    pub fn swept_step(
        &self,
        kin: &Kinematics,
        layout: Layout,
        t: f64,
        z: &[f64],
        dir: &[f64],
        scale: f64,
    ) -> f64 {
        let poses = kin.poses(t);
        let obstacles = kin.obstacles();
        let swept: Vec<Sweep> = obstacles
            .iter()
            .zip(&poses)
            .enumerate()
            .filter_map(|(o, (obstacle, pose))| {
                let half = obstacle.half_thickness()?;
                let delta = scale.min(0.5 * half);
                let sphere = obstacle.bounding_sphere().map(|(c, r)| (pose.apply(&c), r));
                (delta > 0.0).then_some(Sweep {
                    obstacle: o,
                    delta,
                    sphere,
                })
            })
            .collect();
        if swept.is_empty() {
            return f64::INFINITY;
        }
        let n4 = layout.row_len();
        let point = |c: usize| -> f64 {
            let x = self.position(layout, c, z);
            let mut dx = [0.0; 3];
            for (k, bk) in self.b(c) {
                for (r, v) in dx.iter_mut().enumerate() {
                    *v += bk * dir[r * n4 + k];
                }
            }
            let len = dot(&dx, &dx).sqrt();
            if len == 0.0 {
                return f64::INFINITY;
            }
            let mut bound = f64::INFINITY;
            for &Sweep {
                obstacle: o,
                delta,
                sphere,
            } in &swept
            {
                if let Some((centre, r)) = sphere {
                    if segment_distance(&x, &dx, &centre) >= r {
                        continue;
                    }
                }
                let (obstacle, pose) = (&obstacles[o], &poses[o]);
                let depth = |y: &Point3| obstacle.penetration(pose, y).map_or(0.0, |p| p.depth);
                let limit = depth(&x) + 0.5 * delta;
                let sigma = 0.5 * delta / len;
                for k in 1..=SWEEP_SAMPLES {
                    let s = (k as f64 * sigma).min(1.0);
                    let y = std::array::from_fn(|d| x[d] + s * dx[d]);
                    if depth(&y) > limit {
                        // The first sample is within delta/2 of x, so within the limit but
                        // for rounding: at least that far is always allowed.
                        bound = bound.min((k - 1).max(1) as f64 * sigma);
                        break;
                    }
                    if s == 1.0 {
                        break;
                    }
                    if k == SWEEP_SAMPLES {
                        bound = bound.min(s);
                    }
                }
            }
            bound
        };
        if obstacles.iter().any(|o| o.mesh().is_some()) {
            use rayon::prelude::*;
            (0..self.points.len())
                .into_par_iter()
                .with_min_len(64)
                .map(point)
                .reduce(|| f64::INFINITY, f64::min)
        } else {
            (0..self.points.len())
                .map(point)
                .fold(f64::INFINITY, f64::min)
        }
    }

    /// The collider contacts at the start of a step (`z`, time `t0`) as friction sees them
    /// for the step to `t1`: per penetrating (point, obstacle), mu[o] times the penalty force
    /// kappa v d (N), the tangent projector of the normal, and the point's position carried
    /// along by the obstacle's motion over the step (the point the obstacle's surface would
    /// take it to if it stuck), with their derivatives in the start position. Colliders with
    /// mu = 0 keep their contacts (with no force), so that a gradient sees them.
    pub fn friction_lag(
        &self,
        kin: &Kinematics,
        layout: Layout,
        t0: f64,
        t1: f64,
        z: &[f64],
        mu: &[f64],
    ) -> Vec<ColliderLag> {
        let (p0, p1) = (kin.poses(t0), kin.poses(t1));
        self.penetrations(kin, layout, t0, z)
            .into_iter()
            .map(|(c, o, p)| {
                let x = self.position(layout, c, z);
                let (a, b) = (&p0[o], &p1[o]);
                // x in the obstacle's frame at t0, then back out at t1.
                let local: Point3 = std::array::from_fn(|k| {
                    (0..3)
                        .map(|m| a.rotation[m][k] * (x[m] - a.translation[m]))
                        .sum()
                });
                let mu_kv = mu[o] * self.stiffness[o] * self.volumes[c];
                ColliderLag {
                    point: c,
                    obstacle: o,
                    normal_force: self.stiffness[o] * self.volumes[c] * p.depth,
                    mu_lambda: mu_kv * p.depth,
                    // The depth's gradient is -n.
                    mu_lambda_gradient: p.normal.map(|v| -mu_kv * v),
                    normal: p.normal,
                    normal_jacobian: p.normal_jacobian(),
                    projector: crate::sim::friction::tangent_projector(&p.normal),
                    carried: b.apply(&local),
                    carry: mul(&b.rotation, &transpose(&a.rotation)),
                    start_position: x,
                    origins: [a.translation, b.translation],
                }
            })
            .collect()
    }

    /// The friction potential (J) of the lagged contacts `lag` at `z`, gradient added to
    /// `grad`; eps the smoothing displacement, metres.
    pub fn friction_energy_gradient(
        &self,
        layout: Layout,
        lag: &[ColliderLag],
        eps: f64,
        z: &[f64],
        grad: &mut [f64],
    ) -> f64 {
        use crate::sim::friction;
        let n4 = layout.row_len();
        let mut e = 0.0;
        for l in lag {
            let x = self.position(layout, l.point, z);
            let d: [f64; 3] = std::array::from_fn(|k| x[k] - l.carried[k]);
            e += friction::potential(l.mu_lambda, eps, &friction::project(&l.projector, &d));
            let g = friction::gradient(l.mu_lambda, eps, &l.projector, &d);
            for (kk, bk) in self.b(l.point) {
                for r in 0..3 {
                    grad[r * n4 + kk] += g[r] * bk;
                }
            }
        }
        e
    }

    /// Add the (positive semi-definite) Hessian of the friction potential to `h`, exact or
    /// its majorizer's (`curvature`).
    pub fn add_friction_hessian(
        &self,
        layout: Layout,
        lag: &[ColliderLag],
        eps: f64,
        z: &[f64],
        curvature: Curvature,
        h: &mut Mat<f64>,
    ) {
        use crate::sim::friction;
        let blocks: Vec<(usize, crate::linalg3::Mat3)> = lag
            .iter()
            .map(|l| {
                let x = self.position(layout, l.point, z);
                let d: [f64; 3] = std::array::from_fn(|k| x[k] - l.carried[k]);
                (
                    l.point,
                    friction::model_hessian(curvature, l.mu_lambda, eps, &l.projector, &d),
                )
            })
            .collect();
        self.add_point_blocks(layout, &blocks, h);
    }

    /// Add the Hessian of the active penalties at time `t` to `h`: k v B^T H B per
    /// penetrating point, H the exact Hessian of d^2/2 or its PSD part ([`ContactHessian`]).
    pub fn add_penalty_hessian(
        &self,
        kin: &Kinematics,
        layout: Layout,
        t: f64,
        z: &[f64],
        which: ContactHessian,
        h: &mut Mat<f64>,
    ) {
        let blocks: Vec<(usize, crate::linalg3::Mat3)> = self
            .penetrations(kin, layout, t, z)
            .into_iter()
            .map(|(c, o, p)| {
                let kv = self.stiffness[o] * self.volumes[c];
                let hx = match which {
                    ContactHessian::Psd => p.hessian_psd,
                    ContactHessian::Exact => p.hessian,
                };
                (c, hx.map(|row| row.map(|v| kv * v)))
            })
            .collect();
        self.add_point_blocks(layout, &blocks, h);
    }

    /// Add sum over `blocks` of (b_c b_c^T) (x) H_c (H_c a 3 x 3 matrix per cubature point c)
    /// to `h` ([`add_outer_blocks`] with the b rows of the points).
    fn add_point_blocks(
        &self,
        layout: Layout,
        blocks: &[(usize, crate::linalg3::Mat3)],
        h: &mut Mat<f64>,
    ) {
        if blocks.is_empty() {
            return;
        }
        let mut rows = Mat::<f64>::zeros(blocks.len(), layout.row_len());
        for (p, &(c, _)) in blocks.iter().enumerate() {
            for (k, bk) in self.b(c) {
                rows[(p, k)] = bk;
            }
        }
        let hs: Vec<crate::linalg3::Mat3> = blocks.iter().map(|&(_, m)| m).collect();
        add_outer_blocks(h.as_mut(), rows.as_ref(), &hs);
    }
}

impl Term for ContactTerm {
    fn kind(&self, env: &Environment) -> TermKind {
        let obstacles = env.kinematics().obstacles();
        TermKind::Colliders {
            kinds: obstacles.iter().map(Obstacle::kind).collect(),
        }
    }

    /// A penalty whose parts (k v d^2 / 2 per penetrating point) are all positive: nothing
    /// cancels, so it adds no size to the rounding estimate.
    fn add_energy_gradient(&self, at: &StepAt<'_>, z: &[f64], sum: &mut EnergySum<'_>) {
        let found = self.energy_gradient(at.env.kinematics(), at.layout, at.t, z, sum.grad);
        sum.energy += found.energy;
        sum.info.contacts += found.active;
        sum.info.penetration = sum.info.penetration.max(found.deepest);
        if let Some((lag, eps)) = at.friction {
            sum.energy += self.friction_energy_gradient(at.layout, lag, eps, z, sum.grad);
        }
    }

    /// The penalties' exact Hessian or its PSD part; friction's is exact either way.
    fn add_hessian(&self, at: &StepAt<'_>, z: &[f64], kind: HessianKind, h: &mut Mat<f64>) {
        let which = match kind {
            HessianKind::Exact => ContactHessian::Exact,
            HessianKind::Projected { .. } => ContactHessian::Psd,
        };
        self.add_penalty_hessian(at.env.kinematics(), at.layout, at.t, z, which, h);
        if let Some((lag, eps)) = at.friction {
            self.add_friction_hessian(at.layout, lag, eps, z, at.friction_curvature, h);
        }
    }

    /// The penalties are linear in kappa: dL/dkappa_o = lambda_x . (v d n) summed over the
    /// penetrating points (lambda_x = B_c adjoint). Friction is linear in mu lambda =
    /// mu kappa v d(x0), lagged from the step's start x0: it adds to dL/dmu and dL/dkappa, and
    /// its dependence on x0 to the start's adjoint ([`crate::sim::friction::lag_adjoint`]).
    ///
    /// The obstacles' poses: a small world motion (tau, delta) of an obstacle (translation,
    /// rotation about its pose's origin o) moves its penalty as if the point moved by
    /// u = -(tau + delta x (x - o)), so with the penalty's gradient g and exact Hessian H at
    /// the point, dL/dtau = H lambda_x and dL/ddelta = (x - o) x H lambda_x - g x lambda_x at
    /// the step's end pose. Friction sees the end pose through the carried point
    /// (carried + tau + delta x (carried - o)) and the start pose as if x0 moved by u, its
    /// normal turning with delta.
    fn add_parameter_adjoint(
        &self,
        at: &StepAt<'_>,
        z: &[f64],
        adjoint: &[f64],
        out: &mut ParameterAdjoint,
    ) {
        use crate::linalg3::{cross, mat_vec};
        let n4 = at.layout.row_len();
        let colliders = self.len();
        out.collider_stiffness.resize(colliders, 0.0);
        out.collider_pose.resize(colliders, Default::default());
        let at_point = |c: usize| -> [f64; 3] {
            let mut l = [0.0; 3];
            for (k, bk) in self.b(c) {
                for (r, v) in l.iter_mut().enumerate() {
                    *v += bk * adjoint[r * n4 + k];
                }
            }
            l
        };
        let add = |acc: &mut [f64], v: [f64; 3], s: f64| {
            acc.iter_mut().zip(v).for_each(|(a, b)| *a += s * b);
        };
        let kin = at.env.kinematics();
        let poses = kin.poses(at.t);
        for (c, o, p) in self.penetrations(kin, at.layout, at.t, z) {
            let lam = at_point(c);
            let kv = self.stiffness[o] * self.volumes[c];
            out.collider_stiffness[o] += self.volumes[c] * p.depth * dot(&p.normal, &lam);
            let h_lam = mat_vec(&p.hessian, &lam).map(|v| kv * v);
            let g = p.normal.map(|v| -kv * p.depth * v);
            let x = self.position(at.layout, c, z);
            let y: [f64; 3] = std::array::from_fn(|k| x[k] - poses[o].translation[k]);
            let end = &mut out.collider_pose[o].end;
            add(&mut end.translation, h_lam, 1.0);
            add(&mut end.rotation, cross(&y, &h_lam), 1.0);
            add(&mut end.rotation, cross(&g, &lam), -1.0);
        }
        let (Some((lag, eps)), Some((mu, _))) = (at.friction, self.friction.as_ref()) else {
            return;
        };
        out.friction.resize(colliders, 0.0);
        for l in lag {
            let x = self.position(at.layout, l.point, z);
            let lam = at_point(l.point);
            let r = crate::sim::friction::lag_adjoint(l, eps, &x, &lam);
            let o = l.obstacle;
            out.friction[o] -= r.per_mu_lambda * l.normal_force;
            out.collider_stiffness[o] -=
                r.per_mu_lambda * mu[o] * l.normal_force / self.stiffness[o];
            for (k, bk) in self.b(l.point) {
                for (row, v) in r.start.iter().enumerate() {
                    out.start[row * n4 + k] += bk * v;
                }
            }
            let pose = &mut out.collider_pose[o];
            let yc: [f64; 3] = std::array::from_fn(|k| l.carried[k] - l.origins[1][k]);
            add(&mut pose.end.translation, r.carried, 1.0);
            add(&mut pose.end.rotation, cross(&yc, &r.carried), 1.0);
            let y0: [f64; 3] = std::array::from_fn(|k| l.start_position[k] - l.origins[0][k]);
            add(&mut pose.start.translation, r.start, -1.0);
            add(&mut pose.start.rotation, cross(&y0, &r.start), -1.0);
            add(&mut pose.start.rotation, cross(&l.normal, &r.normal), 1.0);
        }
    }

    /// The swept bound ([`ContactTerm::swept_step`]) at the term's sweep depth.
    fn max_step(&self, at: &StepAt<'_>, z: &[f64], dir: &[f64]) -> f64 {
        let kin = at.env.kinematics();
        self.swept_step(kin, at.layout, at.t, z, dir, self.sweep_depth)
    }

    fn is_penalty(&self) -> bool {
        true
    }
}
