//! One simulated object: its reduced model (built from a basis, integration points and
//! materials), its state (z, dz/dt, time) and backward-Euler time stepping.
//!
//! Only the terms the setup declares are built: no gravity code runs without gravity, no
//! boundary moments without boundaries, no contact loop without colliders.
//!
//! Leaves first: `options` (what a caller asks for), `placement` (the rigid placement's
//! state), `setup` (the model: cubature, terms, rest factor), `potential` (one step's sum of
//! the terms), then this file: the state and the step.

mod options;
mod placement;
mod potential;
mod setup;
mod start;

use crate::material::MaterialField;
use crate::precompute::sampling::IntegrationPoints;
use crate::precompute::skinning::{Basis, SkinningWeights};
use crate::report::Stopwatch;
use crate::sim::collider::ColliderShape;
use crate::sim::cubature::Cubature;
pub use crate::sim::deformation::map_points;
use crate::sim::elastic::{ElasticTerm, Layout};
use crate::sim::environment::Environment;
use crate::sim::motion::Motion;
use crate::sim::newton::{
    self, InitialGuess, NewtonOptions, Potential, SolveReport, SolverContext,
};
use crate::sim::terms::{add_block_product, BoundaryTerm, ContactTerm, GravityTerm, Term, Terms};
use crate::{Error, Point3, Result};
use faer::linalg::solvers::Llt;
use faer::Mat;
use options::placement_transform;
pub use options::{Boundary, Placement, SimOptions, StepReport, PENALTY_FACTOR, SWEEP_DEPTH};
pub use placement::PlacementGradient;
pub(crate) use potential::{StepPotential, StepStart};
use setup::positive;
pub use start::{check_start_outside_colliders, START_DEPTH_FRACTION};
use std::sync::Arc;

/// A simulated object.
pub struct ReducedSim {
    layout: Layout,
    /// The terms of the incremental potential that were built.
    terms: Terms,
    /// Gravity and the colliders: the object's own, or the one its world shares with every
    /// object ([`ReducedSim::share_environment`]).
    env: Arc<Environment>,
    rest_factor: Llt<f64>,
    dt: f64,
    diag: f64,
    default_penalty: f64,
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
    /// Counts the calls that change the model or the state other than a step (setters,
    /// resets, undone steps): a [`crate::sim::gradient::Recording`] refuses an object whose
    /// revision moved.
    revision: u64,
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
        let model = setup::build(basis, ip, material, weights, opts)?;
        let dofs = model.layout.dofs();
        let mut sim = ReducedSim {
            layout: model.layout,
            terms: model.terms,
            env: Arc::new(model.env),
            rest_factor: model.rest_factor,
            dt: opts.dt,
            diag: model.diag,
            default_penalty: model.default_penalty,
            options: opts.newton,
            cubature: model.cubature,
            z: vec![0.0; dofs],
            zdot: vec![0.0; dofs],
            zdot_prev: vec![0.0; dofs],
            time: 0.0,
            steps: 0,
            history: Default::default(),
            revision: 0,
        };
        placement::place(
            sim.layout,
            &sim.terms.inertia.mass,
            &opts.placement,
            &model.placement,
            &mut sim.z,
            &mut sim.zdot,
        )?;
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
        &self.terms.boundaries
    }

    /// The terms of the incremental potential that were built, in evaluation order
    /// (terms the setup did not ask for are neither built nor evaluated), as reports name
    /// them ([`crate::sim::terms::TermKind`]).
    pub fn terms(&self) -> Vec<String> {
        let kinds = self.terms.kinds(&self.env);
        kinds.iter().map(ToString::to_string).collect()
    }

    /// The terms themselves, to evaluate or inspect one by one.
    pub fn potential_terms(&self) -> &Terms {
        &self.terms
    }

    /// Add a term of the caller's to the incremental potential, evaluated after the built
    /// ones from the next step on. Its rest Hessian ([`Term::add_rest_hessian`]) joins the
    /// rest system, which is factorized again; all or nothing: a term that makes it
    /// indefinite is refused and the object stays as it was.
    pub fn add_term(&mut self, term: Box<dyn Term>) -> Result<()> {
        self.revision += 1;
        self.terms.added.push(term);
        match setup::rest_factor(&self.terms, self.layout, self.dt) {
            Ok(f) => {
                self.rest_factor = f;
                self.history = Default::default();
                Ok(())
            }
            Err(e) => {
                self.terms.added.pop();
                Err(e)
            }
        }
    }

    /// Rest bounding-box diagonal D, metres.
    pub fn diagonal(&self) -> f64 {
        self.diag
    }

    /// Total mass, kg.
    pub fn total_mass(&self) -> f64 {
        self.terms.inertia.mass.total
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
        StepStart {
            zpred,
            guess,
            t,
            friction: self.lagged_friction(self.time, &self.z),
        }
    }

    /// The collider friction a step from time `t0` (s) at state `z` lags, and the smoothing
    /// displacement; None when frictionless.
    pub(crate) fn lagged_friction(
        &self,
        t0: f64,
        z: &[f64],
    ) -> Option<(Vec<crate::sim::friction::ColliderLag>, f64)> {
        let c = self.terms.colliders.as_ref()?;
        c.step_friction(self.env.kinematics(), self.layout, t0, self.dt, z)
    }

    /// Lagged Coulomb friction against the colliders from the next step on: `mu` per
    /// collider (>= 0; all 0 or an empty list: none), `eps_v` the smoothing velocity, m/s
    /// (sliding slower than it is treated as sticking, smoothly).
    pub fn set_collider_friction(&mut self, mu: &[f64], eps_v: f64) -> Result<()> {
        self.revision += 1;
        let count = self.collider_count();
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
        let friction = mu.iter().any(|m| *m > 0.0).then(|| (mu.to_vec(), eps_v));
        if let Some(c) = self.terms.colliders.as_mut() {
            c.set_friction(friction);
        }
        Ok(())
    }

    /// The incremental potential of the step that `start` begins.
    pub(crate) fn potential<'a>(&'a self, start: &'a StepStart) -> StepPotential<'a> {
        StepPotential::new(&self.terms, self.layout, self.dt, &self.env, start)
    }

    /// The convergence measure of a step `d` in z: its mass-weighted RMS length over the
    /// object divided by the rest diagonal (dimensionless).
    pub(crate) fn measure(&self, d: &[f64]) -> f64 {
        let mut md = vec![0.0; d.len()];
        let mass = &self.terms.inertia.mass;
        add_block_product(self.layout, &mass.bb, 1.0, d, &mut md);
        let q: f64 = d.iter().zip(&md).map(|(a, b)| a * b).sum();
        (q.max(0.0) / mass.total).sqrt() / self.diag
    }

    /// The Cholesky factor of the rest system matrix.
    pub(crate) fn rest_factor(&self) -> &Llt<f64> {
        &self.rest_factor
    }

    /// The object's affine motions in reduced coordinates (12 (m + 1) x 12): the coarse
    /// space of an island's preconditioner.
    pub(crate) fn affine_motions(&self) -> faer::Mat<f64> {
        placement::affine_motions(self.layout, &self.terms.inertia.mass)
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
                .terms
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
        self.revision += 1;
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
        self.revision += 1;
        Arc::make_mut(&mut self.env).set_gravity(gravity)?;
        self.follow_environment();
        Ok(())
    }

    /// Gravity, m/s^2 (None: no gravity term).
    pub fn gravity(&self) -> Option<[f64; 3]> {
        self.env.gravity()
    }

    /// Gravity and the colliders this object steps in.
    pub fn environment(&self) -> &Environment {
        &self.env
    }

    /// Step in `env` from the next step on, shared with whoever else holds it (a world gives
    /// every object its one environment, so the colliders and gravity are held once). It must
    /// have the colliders the object was built with (the same count: each has this object's
    /// penalty stiffness and friction); otherwise it is refused and nothing changes.
    pub fn share_environment(&mut self, env: Arc<Environment>) -> Result<()> {
        self.revision += 1;
        let (have, got) = (self.collider_count(), env.kinematics().len());
        if have != got {
            return Err(Error::LengthMismatch {
                what: "colliders of the shared environment (the object's own)",
                expected: have,
                got,
            });
        }
        self.env = env;
        self.follow_environment();
        Ok(())
    }

    /// The gravity term is built while the environment has gravity.
    fn follow_environment(&mut self) {
        let has = self.env.gravity().is_some();
        if has != self.terms.gravity.is_some() {
            self.terms.gravity = has.then(|| GravityTerm {
                b: self.terms.inertia.mass.b.clone(),
            });
        }
    }

    /// Colliders the object was built with.
    fn collider_count(&self) -> usize {
        self.terms.colliders.as_ref().map_or(0, ContactTerm::len)
    }

    /// Prescribe a new motion for boundary `index` (in the order of
    /// [`SimOptions::boundaries`]) from the next step on. The motion is evaluated at the
    /// simulation time (a keyframe at [`ReducedSim::time`] starts from now) and acts on the
    /// placed rest positions, like the motion it replaces; the region and its stiffness stay.
    pub fn set_boundary_motion(&mut self, index: usize, motion: Motion) -> Result<()> {
        self.revision += 1;
        motion.validate()?;
        let count = self.terms.boundaries.len();
        let b = self.terms.boundaries.get_mut(index).ok_or_else(|| {
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
        self.revision += 1;
        self.check_collider(index)?;
        Arc::make_mut(&mut self.env).set_collider_shape(index, &shape)
    }

    /// Move collider `index` by `motion` from the next step on (evaluated at the simulation
    /// time; relative to its parent's frame if it has one), e.g. a [`Motion::Pose`] set
    /// between steps by a caller.
    pub fn set_collider_motion(&mut self, index: usize, motion: Motion) -> Result<()> {
        self.revision += 1;
        self.check_collider(index)?;
        Arc::make_mut(&mut self.env).set_collider_motion(index, motion)
    }

    fn check_collider(&self, index: usize) -> Result<()> {
        let count = self.collider_count();
        if index < count {
            Ok(())
        } else {
            Err(Error::param(
                "collider",
                index,
                format!("the object has {count} colliders (indices from 0)"),
            ))
        }
    }

    /// The collider penalties (None without colliders), for diagnostics and tests.
    pub fn contacts(&self) -> Option<&ContactTerm> {
        self.terms.colliders.as_ref()
    }

    /// Put the object back into its rest shape at `placement`, with the placement's initial
    /// velocities, as at setup: the deformation, the velocity and the solver's history are
    /// dropped; time and step count go on. Boundary motions act on the new placement from
    /// then on, at the current time: a held region whose motion is not at rest now (a moving
    /// or keyframed target) is pulled to that target in the next steps.
    pub fn reset_placement(&mut self, placement: &Placement) -> Result<()> {
        self.revision += 1;
        let rigid = placement_transform(placement)?;
        let old = (self.z.clone(), self.zdot.clone());
        self.z.fill(0.0);
        self.zdot.fill(0.0);
        let placed = placement::place(
            self.layout,
            &self.terms.inertia.mass,
            placement,
            &rigid,
            &mut self.z,
            &mut self.zdot,
        );
        if let Err(e) = placed {
            // All or nothing: a rejected placement leaves the state as it was.
            (self.z, self.zdot) = old;
            return Err(e);
        }
        // No acceleration is implied by a reset: the extrapolated start sees zdot_prev = zdot.
        self.zdot_prev.copy_from_slice(&self.zdot);
        self.history = Default::default();
        for b in &mut self.terms.boundaries {
            b.placement = rigid;
        }
        Ok(())
    }

    /// dL/d(placement) from dL/dz_0 and dL/dzdot_0 (`bar`, 12 (m + 1) each) of a run that
    /// started at `start` = (z_0, zdot_0), which must be the state `placement` gives this
    /// object (as built or reset to it; checked).
    ///
    /// # Errors
    /// [`Error::Gradient`] when `start` is not that state (a recording begun after steps or
    /// a setter), or when the object has held regions (their targets move with the placement,
    /// which is not differentiated); the placement's own errors.
    pub fn placement_gradient(
        &self,
        placement: &Placement,
        start: (&[f64], &[f64]),
        bar: (&[f64], &[f64]),
    ) -> Result<PlacementGradient> {
        if !self.terms.boundaries.is_empty() {
            return Err(Error::Gradient(
                "the object has held regions, whose targets move with the placement: its \
                 gradient is not differentiated through them; fit z0 and zdot0 instead"
                    .into(),
            ));
        }
        let rigid = placement_transform(placement)?;
        let mut z = vec![0.0; self.z.len()];
        let mut zdot = vec![0.0; self.z.len()];
        let mass = &self.terms.inertia.mass;
        placement::place(self.layout, mass, placement, &rigid, &mut z, &mut zdot)?;
        if z != start.0 || zdot != start.1 {
            return Err(Error::Gradient(
                "the recording did not start at this placement (it began after steps, a \
                 setter or another placement): record from the object as placed"
                    .into(),
            ));
        }
        placement::place_adjoint(self.layout, mass, placement, &rigid, bar.0, bar.1)
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

    /// The model's and state's revision: it moves with every setter, reset or undone step
    /// (not with a step).
    pub fn revision(&self) -> u64 {
        self.revision
    }

    /// Whether the colliders have friction (its contacts are lagged from each step's start).
    pub fn has_collider_friction(&self) -> bool {
        self.terms
            .colliders
            .as_ref()
            .is_some_and(ContactTerm::has_friction)
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
        self.revision += 1;
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
        self.revision += 1;
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
        self.terms.elastic.energy(&self.z).0
    }

    /// The elastic term (for diagnostics and tests).
    pub fn elastic(&self) -> &ElasticTerm {
        &self.terms.elastic
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
        let start = self.start_at(zpred, t);
        let mut g = vec![0.0; z.len()];
        let (e, _) = self.potential(&start).energy_gradient(z, &mut g);
        (e, g)
    }

    /// The PSD Hessian of the step potential at `z` (what `Newton` factorizes).
    pub fn step_hessian(&self, zpred: &[f64], t: f64, z: &[f64]) -> Mat<f64> {
        let start = self.start_at(zpred, t);
        self.potential(&start)
            .hessian(z, crate::sim::friction::Curvature::Exact)
    }

    /// A step start with predictor `zpred` and end time `t`, friction lagged from now.
    fn start_at(&self, zpred: &[f64], t: f64) -> StepStart {
        StepStart {
            zpred: zpred.to_vec(),
            guess: zpred.to_vec(),
            t,
            friction: self.begin_step().friction,
        }
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
