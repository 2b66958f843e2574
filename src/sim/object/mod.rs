//! One simulated object: its reduced model (built from a basis, integration points and
//! materials), its state (z, dz/dt, time) and backward-Euler time stepping.
//!
//! Only the terms the setup declares are built: no gravity code runs without gravity, no
//! boundary moments without boundaries, no contact loop without colliders.

mod options;

use crate::material::MaterialField;
use crate::precompute::boundary_modes::lift_column;
use crate::precompute::sampling::IntegrationPoints;
use crate::precompute::skinning::{Basis, SkinningWeights};
use crate::report::Stopwatch;
use crate::sim::collider::{self, ColliderShape, Obstacle};
use crate::sim::cubature::{self, Cubature};
pub use crate::sim::deformation::map_points;
use crate::sim::elastic::{ElasticTerm, Layout, Precision, Projection};
use crate::sim::motion::{Motion, Rigid};
use crate::sim::newton::{
    self, EvalInfo, InitialGuess, NewtonOptions, Potential, SolveReport, SolverContext,
};
use crate::sim::terms::{
    add_block_diagonal, add_block_product, BoundaryTerm, ColliderLag, ContactHessian, ContactTerm,
    Moments,
};
use crate::{Error, Point3, Result};
use faer::linalg::solvers::Llt;
use faer::{Mat, Side};
use options::placement_transform;
pub use options::{Boundary, Placement, SimOptions, StepReport, PENALTY_FACTOR, SWEEP_DEPTH};

/// A simulated object.
pub struct ReducedSim {
    layout: Layout,
    elastic: ElasticTerm,
    mass: Moments,
    gravity: Option<[f64; 3]>,
    boundaries: Vec<BoundaryTerm>,
    contacts: Option<ContactTerm>,
    rest_factor: Llt<f64>,
    dt: f64,
    diag: f64,
    default_penalty: f64,
    /// Collider friction: mu per collider and the smoothing velocity eps_v (m/s); None:
    /// frictionless (no friction code runs).
    friction: Option<(Vec<f64>, f64)>,
    options: NewtonOptions,
    cubature: Cubature,
    /// Reduced coordinates z, 12 (m + 1).
    z: Vec<f64>,
    /// Reduced velocity dz/dt.
    zdot: Vec<f64>,
    /// zdot before the last step (for [`InitialGuess::Extrapolate`]).
    zdot_prev: Vec<f64>,
    /// Simulated time, s.
    time: f64,
    /// Steps taken.
    steps: usize,
    history: newton::QuasiNewtonState,
}

fn positive(name: &'static str, v: f64, what: &str) -> Result<()> {
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

impl ReducedSim {
    /// Build the reduced model of an object from its basis, integration points and material.
    pub fn new(
        basis: &Basis,
        ip: &IntegrationPoints,
        material: &MaterialField,
        opts: &SimOptions,
    ) -> Result<ReducedSim> {
        let all = basis.weights(&ip.points)?;
        Self::with_weights(basis, ip, material, &all, opts)
    }

    /// [`ReducedSim::new`] with the skinning weights (values and gradients) at the
    /// integration points already evaluated, `weights = basis.weights(&ip.points)`: for callers
    /// that also need them elsewhere (the scene runner draws primitives at their integration
    /// points), so they are computed once.
    pub fn with_weights(
        basis: &Basis,
        ip: &IntegrationPoints,
        material: &MaterialField,
        weights: &SkinningWeights,
        opts: &SimOptions,
    ) -> Result<ReducedSim> {
        positive("dt", opts.dt, "the time step (seconds)")?;
        opts.newton.validate()?;
        if let Some(g) = opts.gravity {
            if !g.iter().all(|v| v.is_finite()) {
                return Err(Error::param("gravity", format!("{g:?}"), "must be finite"));
            }
        }
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
                // An aware region is held through its lift's handle alone (the region's
                // points as if every other weight were 0 there): the free modes ramp up near
                // the region's edge and must not be held (boundary_modes.rs).
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
                motion: spec.motion.clone(),
                stiffness: k,
                moments,
                points: pts,
                placement,
                pointwise,
            });
        }
        let contacts = if opts.colliders.is_empty() {
            None
        } else {
            let kinematics = collider::kinematics(&opts.colliders)?;
            let mut ks = Vec::new();
            for (i, c) in opts.colliders.iter().enumerate() {
                let k = c.stiffness.unwrap_or(default_k);
                positive("stiffness", k, "a collider penalty stiffness (Pa/m^2)")
                    .map_err(|e| c.error(i, e))?;
                ks.push(k);
            }
            Some(ContactTerm::new(
                kinematics,
                ks,
                &cub.points,
                &cub.volumes,
                &cw,
            ))
        };
        // Rest system matrix S = M/h^2 + K_rest + boundary penalties.
        let z0 = vec![0.0; layout.dofs()];
        let mut s = elastic.hessian(&z0, Projection::None);
        add_block_diagonal(layout, &mass.bb, 1.0 / h2, &mut s);
        for b in &boundaries {
            add_block_diagonal(layout, &b.moments.bb, 1.0, &mut s);
        }
        let rest_factor = s.llt(Side::Lower).map_err(|e| {
            Error::param(
                "modes",
                layout.handles - 1,
                format!(
                    "the reduced rest system is not positive definite ({e:?}): the skinning \
                     modes are linearly dependent on the integration points; use fewer modes \
                     or more kernels"
                ),
            )
        })?;
        let mut sim = ReducedSim {
            layout,
            elastic,
            mass,
            gravity: opts.gravity,
            boundaries,
            contacts,
            rest_factor,
            dt: opts.dt,
            diag,
            default_penalty: default_k,
            friction: None,
            options: opts.newton,
            cubature: cub,
            z: vec![0.0; layout.dofs()],
            zdot: vec![0.0; layout.dofs()],
            zdot_prev: vec![0.0; layout.dofs()],
            time: 0.0,
            steps: 0,
            history: Default::default(),
        };
        sim.place(&opts.placement, &placement)?;
        Ok(sim)
    }

    /// The layout of z.
    pub fn layout(&self) -> Layout {
        self.layout
    }

    /// The cubature points used for the elastic energy.
    pub fn cubature(&self) -> &Cubature {
        &self.cubature
    }

    /// The boundary terms (with their penalty stiffness and point sets).
    pub fn boundaries(&self) -> &[BoundaryTerm] {
        &self.boundaries
    }

    /// The terms of the incremental potential that were built, in evaluation order
    /// (terms the setup did not ask for are neither built nor evaluated).
    pub fn terms(&self) -> Vec<String> {
        let mut t = vec!["inertia".to_string(), "elastic".to_string()];
        if self.gravity.is_some() {
            t.push("gravity".into());
        }
        for (i, b) in self.boundaries.iter().enumerate() {
            t.push(format!("boundary {i} ({} points)", b.points.len()));
        }
        if let Some(c) = &self.contacts {
            let kinds: Vec<&str> = c
                .kinematics()
                .obstacles()
                .iter()
                .map(Obstacle::kind)
                .collect();
            t.push(format!("colliders ({}: {})", kinds.len(), kinds.join(", ")));
        }
        t
    }

    /// Rest bounding-box diagonal D, metres.
    pub fn diagonal(&self) -> f64 {
        self.diag
    }

    /// Total mass, kg.
    pub fn total_mass(&self) -> f64 {
        self.mass.total
    }

    /// The combination of the weights that is 1 everywhere, alpha with sum_j alpha_j W_j = 1
    /// (m^(3/2)): a free basis has it in mode 0 alone, a boundary-aware one in its lifts. It
    /// is the mass-weighted least-squares fit G alpha = g over the integration points
    /// (G_jk = sum rho v W_j W_k, g_j = sum rho v W_j), checked to reproduce 1.
    fn unity(&self) -> Result<Vec<f64>> {
        let nh = self.layout.handles;
        let b = &self.mass;
        let g = faer::Mat::from_fn(nh, nh, |j, k| b.bb[(4 * j + 3, 4 * k + 3)]);
        let rhs = faer::Mat::from_fn(nh, 1, |j, _| b.b[4 * j + 3]);
        let fail = |detail: String| {
            Error::param(
                "basis",
                nh,
                format!("no combination of the modes is constant ({detail}): a rigid placement needs one"),
            )
        };
        // sum rho v (alpha^T W - 1)^2 / total = (alpha^T G alpha - 2 alpha^T g + total) / total:
        // 0 for a basis that holds the constant; 1e-8 is far above the rounding of the
        // cancellation (~1e-16 times the Gram matrix's condition number, ~1e3 here).
        let misfit = |alpha: &[f64]| {
            let quad: f64 = (0..nh)
                .map(|j| {
                    (0..nh)
                        .map(|k| alpha[j] * g[(j, k)] * alpha[k])
                        .sum::<f64>()
                })
                .sum();
            let lin: f64 = (0..nh).map(|j| alpha[j] * rhs[(j, 0)]).sum();
            (quad - 2.0 * lin + b.total) / b.total
        };
        let ok = |alpha: &[f64]| misfit(alpha).abs() <= 1e-8 && alpha.iter().all(|a| a.is_finite());
        // A free basis: mode 0 alone (exactly as the constant mode's value says).
        let mut alpha = vec![0.0; nh];
        alpha[0] = b.total / b.b[3];
        if ok(&alpha) {
            return Ok(alpha);
        }
        let llt = g
            .llt(faer::Side::Lower)
            .map_err(|e| fail(format!("weight Gram matrix: {e:?}")))?;
        use faer::linalg::solvers::Solve;
        let sol = llt.solve(&rhs);
        let alpha: Vec<f64> = (0..nh).map(|j| sol[(j, 0)]).collect();
        if !ok(&alpha) {
            return Err(fail(format!("relative misfit {:.2e}", misfit(&alpha))));
        }
        Ok(alpha)
    }

    /// Put the object at `placement` with its initial velocity.
    fn place(&mut self, p: &Placement, rigid: &Rigid) -> Result<()> {
        let nonzero = rigid != &Rigid::IDENTITY
            || p.velocity
                .iter()
                .chain(&p.angular_velocity)
                .any(|v| *v != 0.0);
        if !nonzero {
            return Ok(());
        }
        for v in p.velocity.iter().chain(&p.angular_velocity) {
            if !v.is_finite() {
                return Err(Error::param("velocity", v, "must be finite"));
            }
        }
        let alpha = self.unity()?;
        let l = self.layout;
        let r = &rigid.rotation;
        // Velocity v + w x (x - c) at x = R X + t, with c the placed centre of mass.
        let com0: Point3 = std::array::from_fn(|d| self.mass.xx[d][3] / self.mass.total);
        let com = rigid.apply(&com0);
        let w = p.angular_velocity;
        let wx = [[0.0, -w[2], w[1]], [w[2], 0.0, -w[0]], [-w[1], w[0], 0.0]];
        for (j, &aj) in alpha.iter().enumerate() {
            for row in 0..3 {
                for a in 0..3 {
                    let id = if row == a { 1.0 } else { 0.0 };
                    self.z[l.index(row, j, a)] = aj * (r[row][a] - id);
                    let v: f64 = (0..3).map(|k| wx[row][k] * r[k][a]).sum();
                    self.zdot[l.index(row, j, a)] = aj * v;
                }
                self.z[l.index(row, j, 3)] = aj * rigid.translation[row];
                let wt: f64 = (0..3)
                    .map(|k| wx[row][k] * (rigid.translation[k] - com[k]))
                    .sum();
                self.zdot[l.index(row, j, 3)] = aj * (p.velocity[row] + wt);
            }
        }
        Ok(())
    }

    /// Advance one time step of backward Euler.
    pub fn step(&mut self) -> StepReport {
        let sw = Stopwatch::start();
        let start = self.begin_step();
        let mut history = std::mem::take(&mut self.history);
        let pot = self.potential(&start);
        // The colliders' swept bound keeps the guess from carrying points across a thin
        // obstacle (without colliders nothing bounds it and the guess stands as it is).
        let mut z = newton::bounded_start(&pot, &self.z, &start.guess);
        let measure = |d: &[f64]| self.measure(d);
        let ctx = SolverContext {
            rest: &self.rest_factor,
            measure: &measure,
            options: &self.options,
        };
        let solve = newton::minimize(&pot, &mut z, &ctx, &mut history);
        self.history = history;
        self.finish_step(&start, z, solve, sw.elapsed())
    }

    /// The predictor, initial guess and end time of the next step (nothing changes).
    pub(crate) fn begin_step(&self) -> StepStart {
        let t = self.time + self.dt;
        let zpred: Vec<f64> = self
            .z
            .iter()
            .zip(&self.zdot)
            .map(|(z, v)| z + self.dt * v)
            .collect();
        let mut guess = zpred.clone();
        if self.options.initial_guess == InitialGuess::Extrapolate && self.steps > 0 {
            for i in 0..guess.len() {
                guess[i] += self.dt * (self.zdot[i] - self.zdot_prev[i]);
            }
        }
        let friction = match (&self.friction, &self.contacts) {
            (Some((mu, eps_v)), Some(c)) => Some((
                c.friction_lag(self.layout, self.time, t, &self.z, mu),
                eps_v * self.dt,
            )),
            _ => None,
        };
        StepStart {
            zpred,
            guess,
            t,
            friction,
        }
    }

    /// Lagged Coulomb friction against the colliders from the next step on: `mu` per
    /// collider (>= 0; all 0 or an empty list: none), `eps_v` the smoothing velocity, m/s
    /// (sliding slower than it is treated as sticking, smoothly).
    pub fn set_collider_friction(&mut self, mu: &[f64], eps_v: f64) -> Result<()> {
        let count = self.contacts.as_ref().map_or(0, |c| c.kinematics().len());
        if !mu.is_empty() && mu.len() != count {
            return Err(Error::LengthMismatch {
                what: "friction coefficients (one per collider)",
                expected: count,
                got: mu.len(),
            });
        }
        if let Some(m) = mu.iter().find(|m| !(**m >= 0.0 && m.is_finite())) {
            return Err(Error::param(
                "friction",
                m,
                "a friction coefficient must be >= 0 and finite",
            ));
        }
        positive(
            "friction_velocity",
            eps_v,
            "the friction smoothing velocity (m/s)",
        )?;
        self.friction = mu.iter().any(|m| *m > 0.0).then(|| (mu.to_vec(), eps_v));
        Ok(())
    }

    /// The incremental potential of the step that `start` begins.
    pub(crate) fn potential<'a>(&'a self, start: &'a StepStart) -> StepPotential<'a> {
        StepPotential {
            sim: self,
            zpred: &start.zpred,
            t: start.t,
            friction: start.friction.as_ref().map(|(l, e)| (l.as_slice(), *e)),
        }
    }

    /// The convergence measure of a step `d` in z: its mass-weighted RMS length over the
    /// object divided by the rest diagonal (dimensionless).
    pub(crate) fn measure(&self, d: &[f64]) -> f64 {
        let mut md = vec![0.0; d.len()];
        add_block_product(self.layout, &self.mass.bb, 1.0, d, &mut md);
        let q: f64 = d.iter().zip(&md).map(|(a, b)| a * b).sum();
        (q.max(0.0) / self.mass.total).sqrt() / self.diag
    }

    /// The Cholesky factor of the rest system matrix.
    pub(crate) fn rest_factor(&self) -> &Llt<f64> {
        &self.rest_factor
    }

    /// The solver settings of each step.
    pub(crate) fn newton_options(&self) -> &NewtonOptions {
        &self.options
    }

    /// Take the step that `start` began, ending at `z` (found by `solve` in `wall_s` seconds).
    pub(crate) fn finish_step(
        &mut self,
        start: &StepStart,
        z: Vec<f64>,
        solve: SolveReport,
        wall_s: f64,
    ) -> StepReport {
        self.zdot_prev.copy_from_slice(&self.zdot);
        for i in 0..z.len() {
            self.zdot[i] = (z[i] - self.z[i]) / self.dt;
        }
        self.z = z;
        self.time = start.t;
        self.steps += 1;
        StepReport {
            step: self.steps,
            time: start.t,
            wall_s,
            solve,
            boundary_rms_deviation: self
                .boundaries
                .iter()
                .map(|b| b.rms_deviation(self.layout, start.t, &self.z))
                .reduce(f64::max),
        }
    }

    /// The state (z, zdot, zdot before the last step, time, steps), to undo a step.
    pub(crate) fn snapshot(&self) -> SimSnapshot {
        SimSnapshot {
            z: self.z.clone(),
            zdot: self.zdot.clone(),
            zdot_prev: self.zdot_prev.clone(),
            time: self.time,
            steps: self.steps,
        }
    }

    /// Go back to a [`ReducedSim::snapshot`] (the quasi-Newton memory stays: it only
    /// changes where later minimisations start).
    pub(crate) fn restore(&mut self, s: &SimSnapshot) {
        self.z.clone_from(&s.z);
        self.zdot.clone_from(&s.zdot);
        self.zdot_prev.clone_from(&s.zdot_prev);
        self.time = s.time;
        self.steps = s.steps;
    }

    /// The default penalty stiffness of this object, Pa/m^2:
    /// [`PENALTY_FACTOR`] x max(rho / h^2, E / D^2).
    pub fn default_penalty(&self) -> f64 {
        self.default_penalty
    }

    /// The time step h, seconds.
    pub fn dt(&self) -> f64 {
        self.dt
    }

    /// Gravity from the next step on, m/s^2 (None: no gravity term).
    pub fn set_gravity(&mut self, gravity: Option<[f64; 3]>) -> Result<()> {
        if let Some(g) = gravity {
            if !g.iter().all(|v| v.is_finite()) {
                return Err(Error::param("gravity", format!("{g:?}"), "must be finite"));
            }
        }
        self.gravity = gravity;
        Ok(())
    }

    /// Gravity, m/s^2 (None: no gravity term).
    pub fn gravity(&self) -> Option<[f64; 3]> {
        self.gravity
    }

    /// Prescribe a new motion for boundary `index` (in the order of
    /// [`SimOptions::boundaries`]) from the next step on. The motion is evaluated at the
    /// simulation time (a keyframe at [`ReducedSim::time`] starts from now) and acts on the
    /// placed rest positions, like the motion it replaces; the region and its stiffness stay.
    pub fn set_boundary_motion(&mut self, index: usize, motion: Motion) -> Result<()> {
        motion.validate()?;
        let count = self.boundaries.len();
        let b = self.boundaries.get_mut(index).ok_or_else(|| {
            Error::param(
                "boundary",
                index,
                format!("the object has {count} boundaries (indices from 0)"),
            )
        })?;
        b.motion = motion;
        Ok(())
    }

    /// Replace the shape of collider `index` (in the order of [`SimOptions::colliders`]) from
    /// the next step on; its penalty stiffness, motion and parent stay. A mesh not yet
    /// [`ColliderShape::load`]ed is read here.
    pub fn set_collider_shape(&mut self, index: usize, shape: ColliderShape) -> Result<()> {
        let obstacle = Obstacle::new(&shape)?;
        self.contact_kinematics(index)?
            .set_obstacle(index, obstacle)
    }

    /// Move collider `index` by `motion` from the next step on (evaluated at the simulation
    /// time; relative to its parent's frame if it has one), e.g. a [`Motion::Pose`] set
    /// between steps by a caller.
    pub fn set_collider_motion(&mut self, index: usize, motion: Motion) -> Result<()> {
        self.contact_kinematics(index)?.set_motion(index, motion)
    }

    fn contact_kinematics(&mut self, index: usize) -> Result<&mut collider::Kinematics> {
        let count = self.contacts.as_ref().map_or(0, |c| c.kinematics().len());
        match self.contacts.as_mut() {
            Some(c) if index < count => Ok(c.kinematics_mut()),
            _ => Err(Error::param(
                "collider",
                index,
                format!("the object has {count} colliders (indices from 0)"),
            )),
        }
    }

    /// The collider penalties (None without colliders), for diagnostics and tests.
    pub fn contacts(&self) -> Option<&ContactTerm> {
        self.contacts.as_ref()
    }

    /// Put the object back into its rest shape at `placement`, with the placement's initial
    /// velocities, as at setup: the deformation, the velocity and the solver's history are
    /// dropped; time and step count go on. Boundary motions act on the new placement from
    /// then on, at the current time: a held region whose motion is not at rest now (a moving
    /// or keyframed target) is pulled to that target in the next steps.
    pub fn reset_placement(&mut self, placement: &Placement) -> Result<()> {
        let rigid = placement_transform(placement)?;
        let old = (self.z.clone(), self.zdot.clone());
        self.z.fill(0.0);
        self.zdot.fill(0.0);
        if let Err(e) = self.place(placement, &rigid) {
            // All or nothing: a rejected placement leaves the state as it was.
            (self.z, self.zdot) = old;
            return Err(e);
        }
        // No acceleration is implied by a reset: the extrapolated start sees zdot_prev = zdot.
        self.zdot_prev.copy_from_slice(&self.zdot);
        self.history = Default::default();
        for b in &mut self.boundaries {
            b.placement = rigid;
        }
        Ok(())
    }

    /// Reduced coordinates z, 12 (m + 1): the affine handles' 3 x 4 matrices, row-major.
    pub fn z(&self) -> &[f64] {
        &self.z
    }

    /// Reduced velocity dz/dt, 12 (m + 1), 1/s (set it with [`ReducedSim::set_velocity`] or
    /// [`ReducedSim::set_state`]).
    pub fn zdot(&self) -> &[f64] {
        &self.zdot
    }

    /// Simulated time, seconds.
    pub fn time(&self) -> f64 {
        self.time
    }

    /// Steps taken.
    pub fn steps(&self) -> usize {
        self.steps
    }

    /// Set the state: reduced coordinates `z` and velocity `zdot` (each 12 (m + 1), the
    /// lengths of [`ReducedSim::z`]), e.g. one saved earlier. The solver's history is dropped;
    /// time and step count go on. All or nothing: wrong lengths or non-finite values are
    /// refused and leave the state as it was.
    pub fn set_state(&mut self, z: &[f64], zdot: &[f64]) -> Result<()> {
        self.check_state_vector("z", z)?;
        self.check_state_vector("zdot", zdot)?;
        self.z.copy_from_slice(z);
        self.zdot.copy_from_slice(zdot);
        self.zdot_prev.copy_from_slice(zdot);
        self.history = Default::default();
        Ok(())
    }

    /// Set the reduced velocity only (a kick between steps; 12 (m + 1) values, 1/s): the
    /// positions and the solver's history stay, and with [`InitialGuess::Extrapolate`] the
    /// next step starts from an extrapolation that includes the change. All or nothing, as
    /// [`ReducedSim::set_state`].
    pub fn set_velocity(&mut self, zdot: &[f64]) -> Result<()> {
        self.check_state_vector("zdot", zdot)?;
        self.zdot.copy_from_slice(zdot);
        Ok(())
    }

    /// A state vector has one finite value per reduced coordinate.
    fn check_state_vector(&self, name: &'static str, v: &[f64]) -> Result<()> {
        let n = self.z.len();
        if v.len() != n {
            return Err(Error::param(
                name,
                v.len(),
                format!(
                    "the state has {n} values (12 (m + 1) for m + 1 = {} modes)",
                    n / 12
                ),
            ));
        }
        if let Some(i) = v.iter().position(|x| !x.is_finite()) {
            return Err(Error::param(name, v[i], format!("value {i} is not finite")));
        }
        Ok(())
    }

    /// Elastic energy (J) of the current state.
    pub fn elastic_energy(&self) -> f64 {
        self.elastic.energy(&self.z).0
    }

    /// The elastic term (for diagnostics and tests).
    pub fn elastic(&self) -> &ElasticTerm {
        &self.elastic
    }

    /// Deformed positions of points with rest positions `rest` and skinning weights `w`
    /// (values only are used), metres.
    pub fn positions(&self, rest: &[Point3], w: &SkinningWeights) -> Vec<Point3> {
        map_points(self.layout, &self.z, rest, w)
    }

    /// The incremental potential of the next step for a given predictor, for tests:
    /// (energy, gradient) at `z`. With collider friction, its contacts are lagged from the
    /// current state as the next step's would be.
    pub fn step_potential(&self, zpred: &[f64], t: f64, z: &[f64]) -> (f64, Vec<f64>) {
        let lag = self.begin_step().friction;
        let pot = StepPotential {
            sim: self,
            zpred,
            t,
            friction: lag.as_ref().map(|(l, e)| (l.as_slice(), *e)),
        };
        let mut g = vec![0.0; z.len()];
        let (e, _) = pot.energy_gradient(z, &mut g);
        (e, g)
    }

    /// The PSD Hessian of the step potential at `z` (what `Newton` factorizes).
    pub fn step_hessian(&self, zpred: &[f64], t: f64, z: &[f64]) -> Mat<f64> {
        let lag = self.begin_step().friction;
        StepPotential {
            sim: self,
            zpred,
            t,
            friction: lag.as_ref().map(|(l, e)| (l.as_slice(), *e)),
        }
        .hessian(z)
    }
}

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

/// A saved state of a [`ReducedSim`].
pub(crate) struct SimSnapshot {
    z: Vec<f64>,
    zdot: Vec<f64>,
    zdot_prev: Vec<f64>,
    time: f64,
    steps: usize,
}

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
/// 1/(2 h^2) |z - z_pred|_M^2 + elastic(z) - gravity work + penalties at time t.
pub(crate) struct StepPotential<'a> {
    sim: &'a ReducedSim,
    zpred: &'a [f64],
    t: f64,
    friction: Option<(&'a [ColliderLag], f64)>,
}

impl StepPotential<'_> {
    /// Number of reduced coordinates.
    pub(crate) fn dofs(&self) -> usize {
        self.sim.layout.dofs()
    }
}

impl StepPotential<'_> {
    /// The Hessian at z with every cubature point's elastic Hessian and every collider
    /// penalty's curvature exact (`exact`), or projected to PSD as Newton and the
    /// quasi-Newton bases factorize it ([`Potential::hessian`]); friction's is exact either
    /// way.
    fn assembled_hessian(
        &self,
        z: &[f64],
        stride: usize,
        precision: Precision,
        exact: bool,
    ) -> Mat<f64> {
        let s = self.sim;
        let l = s.layout;
        let (projection, contact) = if exact {
            (Projection::None, ContactHessian::Exact)
        } else {
            (Projection::PerPoint, ContactHessian::Psd)
        };
        let mut h = s.elastic.hessian_sampled(z, projection, stride, precision);
        add_block_diagonal(l, &s.mass.bb, 1.0 / (s.dt * s.dt), &mut h);
        for b in &s.boundaries {
            add_block_diagonal(l, &b.moments.bb, 1.0, &mut h);
        }
        if let Some(c) = &s.contacts {
            c.add_hessian(l, self.t, z, contact, &mut h);
            if let Some((lag, eps)) = self.friction {
                c.add_friction_hessian(l, lag, eps, z, &mut h);
            }
        }
        h
    }
}

impl Potential for StepPotential<'_> {
    fn energy_gradient(&self, z: &[f64], grad: &mut [f64]) -> (f64, EvalInfo) {
        let s = self.sim;
        let l = s.layout;
        let (mut e, st) = s.elastic.energy_gradient(z, grad);
        let h2 = s.dt * s.dt;
        let dz: Vec<f64> = z.iter().zip(self.zpred).map(|(a, b)| a - b).collect();
        let mut mdz = vec![0.0; dz.len()];
        add_block_product(l, &s.mass.bb, 1.0 / h2, &dz, &mut mdz);
        e += 0.5 * dz.iter().zip(&mdz).map(|(a, b)| a * b).sum::<f64>();
        grad.iter_mut().zip(&mdz).for_each(|(g, m)| *g += m);
        if let Some(g) = s.gravity {
            // -sum rho v g . (X + B z): the constant part is dropped.
            let n4 = l.row_len();
            for r in 0..3 {
                for k in 0..n4 {
                    let f = g[r] * s.mass.b[k];
                    e -= f * z[r * n4 + k];
                    grad[r * n4 + k] -= f;
                }
            }
        }
        // Rounding of E: a few ulps of the summed magnitudes (n4 terms per dot product).
        let mut scale = e.abs();
        for b in &s.boundaries {
            let (eb, sb) = b.energy_gradient(l, self.t, z, grad);
            e += eb;
            scale += sb;
        }
        let mut contacts = crate::sim::terms::ContactInfo::default();
        if let Some(c) = &s.contacts {
            contacts = c.energy_gradient(l, self.t, z, grad);
            e += contacts.energy;
            if let Some((lag, eps)) = self.friction {
                e += c.friction_energy_gradient(l, lag, eps, z, grad);
            }
        }
        (
            e,
            EvalInfo {
                min_det: st.min_det,
                inverted: st.inverted,
                contacts: contacts.active,
                penetration: contacts.deepest,
                rounding: scale * 1e-16 * (l.row_len() as f64).sqrt() * 4.0,
            },
        )
    }

    fn hessian(&self, z: &[f64]) -> Mat<f64> {
        self.base_hessian(z, 1, Precision::Double)
    }

    fn base_hessian(&self, z: &[f64], stride: usize, precision: Precision) -> Mat<f64> {
        self.assembled_hessian(z, stride, precision, false)
    }

    fn exact_hessian(&self, z: &[f64]) -> Option<Mat<f64>> {
        Some(self.assembled_hessian(z, 1, Precision::Double, true))
    }

    /// The colliders' swept bound ([`crate::sim::terms::ContactTerm::max_step`]): no cubature
    /// point enters an obstacle deeper than [`SWEEP_DEPTH`] of the object's diagonal (or half
    /// the obstacle's half-thickness) beyond where it is, along its path.
    fn max_step(&self, z: &[f64], dir: &[f64]) -> f64 {
        let s = self.sim;
        s.contacts.as_ref().map_or(f64::INFINITY, |c| {
            c.max_step(s.layout, self.t, z, dir, SWEEP_DEPTH * s.diag)
        })
    }
}
