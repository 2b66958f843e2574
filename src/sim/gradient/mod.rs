//! Reverse-mode gradients through a simulated object's run (docs/gradients.md).
//!
//! A converged backward-Euler step ends at a minimum z* of the incremental potential
//! E(z; z_pred, p), so grad E(z*) = 0 and, by the implicit function theorem,
//! dz*/dq = -H^-1 d(grad E)/dq with H the exact Hessian at z*. The reverse pass solves
//! H lambda = dL/dz* once per step (12 (m + 1) unknowns, `solve`) and each
//! term adds -lambda^T d(its gradient)/dq for its parameters
//! ([`crate::sim::terms::Term::add_parameter_adjoint`]). z_pred = z_n + h zdot_n and
//! zdot_{n+1} = (z_{n+1} - z_n) / h carry the adjoint back to the step before.
//!
//! [`Recording`] is the tape: the states z_0..z_T and zdot_0 (12 (m + 1) values per step,
//! so no checkpointing is needed: a million steps at m = 16 take 1.6 GB). The solves run in
//! the reverse pass (`solve`): conjugate gradients on matrix-free exact Hessian products,
//! preconditioned by the factor of an earlier step's exact Hessian, formed again where they
//! do not converge.
//!
//! Leaves first: `positions` (a loss on positions as a loss on z), `gradients` (what the pass
//! returns), `solve` (the adjoint solves), then this file (the tape and the pass).

mod gradients;
mod positions;
mod solve;

pub use crate::sim::object::PlacementGradient;
pub use gradients::{lame_derivatives, Gradients};
pub use positions::positions_adjoint;
pub use solve::{CG_TOL, FORMED_PER_COLUMN, MAX_CG};

use crate::precompute::memory::available_memory;
use crate::report::Stopwatch;
use crate::sim::object::{ReducedSim, StepReport, StepStart};
use crate::sim::terms::{ParameterAdjoint, PoseGradient, StepPoseGradient};
use crate::{Error, Result};

/// A recorded run of one object: start it on the object, step the object through it, then
/// take the reverse pass ([`Recording::backward`]) once.
///
/// Collider friction is differentiated as it is lagged: from each step's start, which the
/// reverse pass follows back (dL/dz_n through the lagged normal forces, normals and carried
/// points). Object-object contact is a world's: its recording keeps the islands each step
/// solved and reverses them jointly, driving its objects' [`ObjectReverse`] passes.
#[derive(Debug, Clone)]
pub struct Recording {
    dofs: usize,
    dt: f64,
    /// The object's revision at the start ([`ReducedSim::revision`]).
    revision: u64,
    /// The object's step count at the start.
    first_step: usize,
    /// The object's time at the start, s (where the first step's friction is lagged from).
    start_time: f64,
    /// zdot_0, 12 (m + 1).
    zdot0: Vec<f64>,
    /// z_0 .. z_T, (T + 1) x 12 (m + 1).
    states: Vec<f64>,
    /// End time of each recorded step, s.
    times: Vec<f64>,
    /// The first step that did not converge: (step within the recording, 1-based; residual).
    unconverged: Option<(usize, f64)>,
    /// Wall time of the recorded steps, s.
    forward_s: f64,
}

/// Steps of tape reserved up front at most.
const RESERVE_STEPS: usize = 1 << 16;

/// Bytes of one recorded step: one state of 12 (m + 1) f64.
fn step_bytes(dofs: usize) -> u64 {
    8 * dofs as u64
}

impl Recording {
    /// Start recording `sim` from its current state, for a run of about `steps` steps: the
    /// tape's memory ((steps + 1) x 12 (m + 1) x 8 bytes, plus the reverse pass's four
    /// 12 (m + 1) square matrices and F at every cubature point) is checked against the
    /// memory available first.
    ///
    /// # Errors
    /// [`Error::Gradient`] for a tape that would not fit.
    pub fn start(sim: &ReducedSim, steps: usize) -> Result<Recording> {
        let dofs = sim.z().len();
        // The tape, and what the reverse pass holds at once: the formed H, its factor, the
        // factor it replaces and the other terms' dense Hessian (four 12 (m + 1) squares),
        // and F at every cubature point (9 values each).
        let estimate = (steps as u64)
            .saturating_add(1)
            .saturating_mul(step_bytes(dofs))
            .saturating_add(4 * step_bytes(dofs * dofs))
            .saturating_add(step_bytes(9 * sim.cubature().len()));
        if let Some((available, source)) = available_memory()? {
            if estimate > available {
                return Err(Error::Gradient(format!(
                    "a tape of {steps} steps needs about {:.2} GB ({} bytes per step) but {:.2} GB \
                     is available ({source}); record fewer steps per recording",
                    estimate as f64 / 1e9,
                    step_bytes(dofs),
                    available as f64 / 1e9
                )));
            }
        }
        // The tape grows as it records; the reservation is only a hint (capped, so that a
        // count nobody will record does not allocate where the memory check cannot run).
        let reserve = steps.min(RESERVE_STEPS);
        let mut states = Vec::with_capacity((reserve + 1) * dofs);
        states.extend_from_slice(sim.z());
        Ok(Recording {
            dofs,
            dt: sim.dt(),
            revision: sim.revision(),
            first_step: sim.steps(),
            start_time: sim.time(),
            zdot0: sim.zdot().to_vec(),
            states,
            times: Vec::with_capacity(reserve),
            unconverged: None,
            forward_s: 0.0,
        })
    }

    /// Steps recorded so far (T).
    pub fn steps(&self) -> usize {
        self.times.len()
    }

    /// Wall time of the recorded steps, seconds.
    pub fn forward_s(&self) -> f64 {
        self.forward_s
    }

    /// Bytes the tape holds.
    pub fn tape_bytes(&self) -> u64 {
        8 * (self.states.len() + self.zdot0.len() + self.times.len()) as u64
    }

    /// z after recorded step `t` (0: the start), 12 (m + 1).
    pub fn state(&self, t: usize) -> Option<&[f64]> {
        self.states.get(t * self.dofs..(t + 1) * self.dofs)
    }

    /// Whether `sim` is the object recorded, unchanged since (same revision, step count,
    /// state and time step): the check [`Recording::step`] and [`Recording::backward`] make.
    ///
    /// # Errors
    /// [`Error::Gradient`] naming what differs.
    pub fn check_object(&self, sim: &ReducedSim) -> Result<()> {
        let t = self.steps();
        let last = self.state(t).unwrap_or_default();
        if sim.revision() != self.revision
            || sim.steps() != self.first_step + t
            || sim.z() != last
            || sim.dt() != self.dt
        {
            return Err(Error::Gradient(format!(
                "the object is not the one recorded, or it was changed since (a setter, a reset \
                 or a step outside the recording after {t} recorded steps); start a new recording"
            )));
        }
        // Switching collider friction on is a setter: the revision above catches it.
        Ok(())
    }

    /// Take one step of `sim` and record it.
    ///
    /// # Errors
    /// [`Error::Gradient`] when the object was changed since the recording began (then
    /// nothing is stepped).
    pub fn step(&mut self, sim: &mut ReducedSim) -> Result<StepReport> {
        self.check_object(sim)?;
        let report = sim.step();
        self.push(sim, &report);
        Ok(report)
    }

    /// Record the step `report` that `sim` just took, stepped by its owner (a world): `sim`
    /// passed [`Recording::check_object`] right before that step. The world's own step may
    /// have undone and redone the object's step (an island solved again, stiffer or merged),
    /// which moves its revision: the recording follows it.
    ///
    /// # Errors
    /// [`Error::Gradient`] when `sim` took anything but one step since.
    pub fn record_step(&mut self, sim: &ReducedSim, report: &StepReport) -> Result<()> {
        if sim.steps() != self.first_step + self.steps() + 1 {
            return Err(Error::Gradient(
                "the object did more than one step since the last recorded one; start a new \
                 recording"
                    .into(),
            ));
        }
        self.revision = sim.revision();
        self.push(sim, report);
        Ok(())
    }

    fn push(&mut self, sim: &ReducedSim, report: &StepReport) {
        self.forward_s += report.wall_s;
        self.states.extend_from_slice(sim.z());
        self.times.push(report.time);
        if !report.solve.converged && self.unconverged.is_none() {
            self.unconverged = Some((self.steps(), report.solve.residual));
        }
    }

    /// The reverse pass for a loss L(z_0, ..., z_T): `dl_dz[t]` is dL/dz after recorded step t
    /// (`dl_dz[0]` at the start), 12 (m + 1) values, or empty where L does not see that frame;
    /// T + 1 entries. Positions become z with [`positions_adjoint`]. Consumes the recording.
    ///
    /// # Errors
    /// [`Error::Gradient`]: a changed object, a loss gradient of the wrong shape or with NaN,
    /// a step that did not converge or ended with inverted points (named), a step whose exact
    /// Hessian is not positive definite.
    pub fn backward(self, sim: &ReducedSim, dl_dz: &[Vec<f64>]) -> Result<Gradients> {
        self.reverse(sim, dl_dz, false)
    }

    /// [`Recording::backward`] with the exact Hessian formed and factorized at every step
    /// instead of conjugate gradients preconditioned by an earlier step's factor: the
    /// reference the default pass is checked against, several times slower.
    ///
    /// # Errors
    /// As [`Recording::backward`].
    pub fn backward_direct(self, sim: &ReducedSim, dl_dz: &[Vec<f64>]) -> Result<Gradients> {
        self.reverse(sim, dl_dz, true)
    }

    fn reverse(self, sim: &ReducedSim, dl_dz: &[Vec<f64>], direct: bool) -> Result<Gradients> {
        let mut pass = ObjectReverse::new(self, sim, dl_dz, direct)?;
        for t in (1..=pass.steps()).rev() {
            let (start, rhs) = pass.begin(t);
            let lambda = pass.solve_alone(&start, t, &rhs)?;
            pass.finish_step(t, &start, &lambda, None)?;
        }
        Ok(pass.finish())
    }

    /// T + 1 entries, each empty or 12 (m + 1) finite values.
    fn check_loss(&self, dl_dz: &[Vec<f64>]) -> Result<()> {
        let frames = self.steps() + 1;
        if dl_dz.len() != frames {
            return Err(Error::Gradient(format!(
                "the loss gradient has {} frames; the recording has {frames} (the start and \
                 {} steps)",
                dl_dz.len(),
                self.steps()
            )));
        }
        for (t, g) in dl_dz.iter().enumerate() {
            if !g.is_empty() && g.len() != self.dofs {
                return Err(Error::Gradient(format!(
                    "the loss gradient of frame {t} has {} values; z has {} (12 (m + 1)), or \
                     leave it empty",
                    g.len(),
                    self.dofs
                )));
            }
            if let Some(i) = g.iter().position(|v| !v.is_finite()) {
                return Err(Error::Gradient(format!(
                    "the loss gradient of frame {t} is not finite at index {i}"
                )));
            }
        }
        Ok(())
    }

    /// The start of recorded step t (1-based) as the object began it: z_pred from z_{t-1}
    /// and zdot_{t-1} (zdot_0 recorded, later ones as the step computed them), and the
    /// collider friction lagged from z_{t-1} at the step's start time.
    fn step_start(&self, sim: &ReducedSim, t: usize) -> StepStart {
        let prev = self.state(t - 1).unwrap_or_default();
        let zpred = if t == 1 {
            prev.iter()
                .zip(&self.zdot0)
                .map(|(z, v)| z + self.dt * v)
                .collect()
        } else {
            let before = self.state(t - 2).unwrap_or_default();
            prev.iter()
                .zip(before)
                .map(|(z, b)| z + self.dt * ((z - b) / self.dt))
                .collect()
        };
        // The time the step began at, as the object held it (the previous step's end).
        let t0 = if t == 1 {
            self.start_time
        } else {
            self.times[t - 2]
        };
        StepStart {
            guess: Vec::new(),
            zpred,
            t: self.times[t - 1],
            friction: sim.lagged_friction(t0, prev),
        }
    }
}

/// One object's reverse pass, a step at a time ([`Recording::backward`] drives it alone; a
/// world drives its objects' passes together, solving the steps they took as an island
/// jointly): per recorded step t from T down to 1, [`ObjectReverse::begin`] gives the step's
/// start and the right-hand side of its adjoint solve, the adjoint lambda comes from
/// [`ObjectReverse::solve_alone`] or the island's joint solve, and
/// [`ObjectReverse::finish_step`] adds the object's parameter adjoints and carries the
/// adjoint to the step before.
pub struct ObjectReverse<'a> {
    rec: Recording,
    sim: &'a ReducedSim,
    dl_dz: &'a [Vec<f64>],
    sw: Stopwatch,
    adj: ParameterAdjoint,
    /// dL/dz and dL/dzdot of the step being reversed (from later steps and the loss).
    zbar: Vec<f64>,
    vbar: Vec<f64>,
    solver: solve::AdjointSolver,
    poses: Vec<Vec<StepPoseGradient>>,
    targets: Vec<Vec<PoseGradient>>,
}

impl<'a> ObjectReverse<'a> {
    /// The reverse pass of `rec` on `sim` (the object recorded, unchanged since) for the loss
    /// gradient `dl_dz` ([`Recording::backward`]'s); `direct`: form and factorize the exact
    /// Hessian at every step.
    ///
    /// # Errors
    /// As [`Recording::backward`]: a changed object, a loss gradient of the wrong shape or
    /// with NaN, a step that did not converge.
    pub fn new(
        rec: Recording,
        sim: &'a ReducedSim,
        dl_dz: &'a [Vec<f64>],
        direct: bool,
    ) -> Result<ObjectReverse<'a>> {
        let sw = Stopwatch::start();
        rec.check_object(sim)?;
        rec.check_loss(dl_dz)?;
        if let Some((t, residual)) = rec.unconverged {
            return Err(Error::Gradient(format!(
                "recorded step {t} did not converge (residual {residual:e}): the gradient is the \
                 minimiser's only where each step converged; raise the solver's max_iter"
            )));
        }
        let n = rec.dofs;
        let steps = rec.steps();
        Ok(ObjectReverse {
            adj: ParameterAdjoint::new(n, sim.cubature().len()),
            zbar: vec![0.0; n],
            vbar: vec![0.0; n],
            solver: solve::AdjointSolver::new(direct),
            poses: vec![Vec::new(); steps],
            targets: vec![Vec::new(); steps],
            rec,
            sim,
            dl_dz,
            sw,
        })
    }

    /// Steps recorded (T).
    pub fn steps(&self) -> usize {
        self.rec.steps()
    }

    /// The object.
    pub fn sim(&self) -> &'a ReducedSim {
        self.sim
    }

    /// z after recorded step `t` (0: the start), 12 (m + 1).
    pub fn state(&self, t: usize) -> &[f64] {
        self.rec.state(t).unwrap_or_default()
    }

    /// The start of recorded step `t` (1-based, taken from T down) as the object began it,
    /// and the right-hand side of its adjoint solve: dL/dz_t from the loss, the later steps'
    /// predictors and zdot_t.
    pub(crate) fn begin(&mut self, t: usize) -> (StepStart, Vec<f64>) {
        add(&mut self.zbar, &self.dl_dz[t]);
        let h = self.rec.dt;
        let rhs = self
            .zbar
            .iter()
            .zip(&self.vbar)
            .map(|(a, b)| a + b / h)
            .collect();
        (self.rec.step_start(self.sim, t), rhs)
    }

    /// The adjoint of recorded step `t` stepped alone: H lambda = rhs with H the exact Hessian
    /// of the step's potential at its end.
    ///
    /// # Errors
    /// [`Error::Gradient`]: an exact Hessian that is not positive definite.
    pub(crate) fn solve_alone(
        &mut self,
        start: &StepStart,
        t: usize,
        rhs: &[f64],
    ) -> Result<Vec<f64>> {
        let pot = self.sim.potential(start);
        let z = self.rec.state(t).unwrap_or_default();
        self.solver.solve(&pot, z, rhs, t)
    }

    /// Finish recorded step `t` with its adjoint `lambda`: the object's terms' parameter
    /// adjoints, and the adjoint carried to z_{t-1} and zdot_{t-1} (plus `start`, dL/dz_{t-1}
    /// through what an island lagged from it, if given).
    ///
    /// # Errors
    /// [`Error::Gradient`]: a non-finite adjoint, or inverted points at the step's end.
    pub(crate) fn finish_step(
        &mut self,
        t: usize,
        start: &StepStart,
        lambda: &[f64],
        lagged: Option<&[f64]>,
    ) -> Result<()> {
        if let Some(i) = lambda.iter().position(|v| !v.is_finite()) {
            return Err(Error::Gradient(format!(
                "the adjoint of recorded step {t} is not finite at index {i}: the loss \
                 gradient or the step's state overflowed"
            )));
        }
        let (n, h) = (self.rec.dofs, self.rec.dt);
        let pot = self.sim.potential(start);
        let adj = &mut self.adj;
        adj.zpred.fill(0.0);
        adj.start.fill(0.0);
        adj.collider_pose.fill(StepPoseGradient::default());
        adj.boundary_pose.fill(PoseGradient::default());
        adj.inverted = 0;
        pot.parameter_adjoint(self.rec.state(t).unwrap_or_default(), lambda, adj);
        self.poses[t - 1].clone_from(&adj.collider_pose);
        self.targets[t - 1].clone_from(&adj.boundary_pose);
        if adj.inverted > 0 {
            return Err(Error::Gradient(format!(
                "recorded step {t} ended with {} inverted cubature points (det F <= 0): \
                 the motion went through a non-physical state, and a gradient would fit \
                 parameters to it; take a smaller time step or check the material",
                adj.inverted
            )));
        }
        if let Some(l) = lagged {
            add(&mut adj.start, l);
        }
        // z_pred = z_{t-1} + h zdot_{t-1}; zdot_t = (z_t - z_{t-1}) / h; the lagged
        // friction reads z_{t-1} itself.
        for i in 0..n {
            self.zbar[i] = adj.zpred[i] - self.vbar[i] / h + adj.start[i];
            self.vbar[i] = h * adj.zpred[i];
        }
        Ok(())
    }

    /// The gradients, once every step is finished.
    pub fn finish(mut self) -> Gradients {
        add(&mut self.zbar, &self.dl_dz[0]);
        let steps = self.steps();
        let cub = self.sim.cubature();
        let start = (
            self.rec.state(0).unwrap_or_default().to_vec(),
            self.rec.zdot0,
        );
        Gradients::new(
            self.adj,
            (self.zbar, self.vbar),
            (start, self.sim.revision()),
            (&cub.lambda, &cub.mu, &cub.source),
            steps,
            (
                self.sw.elapsed(),
                self.solver.hessians,
                self.solver.products,
            ),
            (self.poses, self.targets),
        )
    }
}

/// a += b (b empty: nothing).
fn add(a: &mut [f64], b: &[f64]) {
    a.iter_mut().zip(b).for_each(|(x, y)| *x += y);
}
