//! An island: objects that may touch within a time step, solved as one minimisation over
//! their stacked reduced coordinates. Its potential is the sum of the objects' own
//! incremental potentials (inertia, elasticity, gravity, boundaries, collider penalties) and
//! the contact energy between them; it is minimised by Newton with the contact step bound in
//! the line search, from a start that the same bound keeps on the safe side of the previous
//! state. The Newton system keeps its block structure (one block per object, coupling blocks
//! only between objects in contact; [`super::system`]) and is solved by conjugate gradients
//! preconditioned by block Jacobi with a coarse level over the members' affine motions, or
//! densely on request ([`IslandSolver::Dense`], the reference the tests compare with).

use super::coarse::CoarseBasis;
use super::energy::{PairContact, PairHessian, PairLag};
use super::system::BlockHessian;
use super::{ContactStats, IslandSolver};
use crate::report::Stopwatch;
use crate::sim::elastic::Precision;
use crate::sim::friction::Curvature;
use crate::sim::newton::{
    self, BlockRest, EvalInfo, HessianStrategy, NewtonSystem, Potential, QuasiNewtonState,
    RestSolve, SolverContext,
};
use crate::sim::object::{StepPotential, StepStart};
use crate::sim::{ReducedSim, StepReport};
use faer::Mat;
use std::sync::Arc;

/// The incremental potential of an island.
struct IslandPotential<'a> {
    parts: Vec<StepPotential<'a>>,
    offsets: Vec<usize>,
    contact: &'a PairContact<'a>,
    /// Lagged object-object friction and its smoothing displacement, metres.
    friction: (Vec<PairLag>, f64),
    solver: IslandSolver,
    /// The arithmetic of the members' elastic Hessian products.
    precision: Precision,
    /// The members' affine motions, the coarse space of the block solve.
    coarse: Arc<CoarseBasis>,
}

impl IslandPotential<'_> {
    /// The Hessian in blocks: each object's own (built in parallel, each by itself, so the
    /// result does not depend on the thread count), then the contact and friction terms;
    /// exact (`exact`: may be indefinite) or with the objects' and the pairs' curvature
    /// projected to PSD.
    fn blocks(&self, z: &[f64], exact: bool, friction: Curvature) -> BlockHessian {
        use rayon::prelude::*;
        let diag: Vec<Mat<f64>> = self
            .parts
            .par_iter()
            .zip(&self.offsets)
            .map(|(p, &o)| p.hessian_in(&z[o..o + p.dofs()], friction, exact, self.precision))
            .collect();
        let mut h = BlockHessian::new(diag);
        let pairs = if exact {
            PairHessian::Exact
        } else {
            PairHessian::Psd
        };
        self.contact.add_hessian_blocks(z, pairs, &mut h);
        let (lag, eps) = &self.friction;
        self.contact
            .add_friction_hessian_blocks(lag, *eps, z, friction, &mut h);
        h
    }

    /// Factorize the blocks and solve for `grad`: Some when the system is positive definite
    /// along every direction the solve explored and the step descends.
    fn solve(
        &self,
        h: BlockHessian,
        grad: &[f64],
    ) -> Option<(Box<dyn RestSolve + Send>, Vec<f64>)> {
        let (solver, d): (Box<dyn RestSolve + Send>, Vec<f64>) = match self.solver {
            IslandSolver::Dense => {
                let f = h.to_dense().llt(faer::Side::Lower).ok()?;
                let d = f.solve(grad);
                (Box::new(f), d)
            }
            IslandSolver::Blocks => {
                let s = h.into_solver(Some(&self.coarse))?;
                let (d, info) = s.solve_with_info(grad);
                if info.negative_curvature {
                    return None;
                }
                (Box::new(s), d)
            }
        };
        let slope: f64 = grad.iter().zip(&d).map(|(g, v)| g * v).sum();
        (slope > 0.0).then_some((solver, d))
    }
}

impl Potential for IslandPotential<'_> {
    fn energy_gradient(&self, z: &[f64], grad: &mut [f64]) -> (f64, EvalInfo) {
        let mut e = 0.0;
        let mut info = EvalInfo {
            min_det: f64::INFINITY,
            ..EvalInfo::default()
        };
        for (p, &o) in self.parts.iter().zip(&self.offsets) {
            let n = p.dofs();
            grad[o..o + n].fill(0.0);
            let (ep, ip) = p.energy_gradient(&z[o..o + n], &mut grad[o..o + n]);
            e += ep;
            info.min_det = info.min_det.min(ip.min_det);
            info.inverted += ip.inverted;
            info.contacts += ip.contacts;
            info.penetration = info.penetration.max(ip.penetration);
            info.rounding += ip.rounding;
        }
        let s = self.contact.energy_gradient(z, grad);
        e += s.energy;
        let (lag, eps) = &self.friction;
        e += self.contact.friction_energy_gradient(lag, *eps, z, grad);
        (e, info)
    }

    fn hessian(&self, z: &[f64], friction: Curvature) -> Mat<f64> {
        self.blocks(z, false, friction).to_dense()
    }

    /// The exact Hessian first, the projected one when it is not positive definite (as
    /// [`Potential::exact_hessian`] describes), solved densely or in blocks.
    fn newton_system(&self, z: &[f64], grad: &[f64], friction: Curvature) -> NewtonSystem {
        for exact in [true, false] {
            if let Some((solver, direction)) = self.solve(self.blocks(z, exact, friction), grad) {
                return NewtonSystem::Solved {
                    solver,
                    direction,
                    projected: !exact,
                };
            }
        }
        NewtonSystem::Indefinite
    }

    fn has_friction(&self) -> bool {
        !self.friction.0.is_empty() || self.parts.iter().any(|p| p.has_friction())
    }

    /// The object-object bound and each member's swept collider bound (the same guard
    /// against jumping across a thin obstacle that an object stepping alone has).
    fn max_step(&self, z: &[f64], dir: &[f64]) -> f64 {
        self.parts
            .iter()
            .zip(&self.offsets)
            .map(|(p, &o)| {
                let n = p.dofs();
                p.max_step(&z[o..o + n], &dir[o..o + n])
            })
            .fold(self.contact.max_step(z, dir), f64::min)
    }
}

/// Step the objects `sims` of one island together; `contact` holds their samples with
/// offsets into the stacked coordinates in the same order, `mu` the friction coefficient of
/// each pair of them (row-major), `eps_v` the friction smoothing velocity, m/s,
/// `solver` how the Newton systems are solved and `precision` the arithmetic of the members'
/// elastic Hessian products in them; `start` (stacked z) where the minimisation
/// starts instead of the pulled-back guess: the end of an earlier solve of the same step
/// (from the same state), which the step bound keeps on the safe side. Returns
/// each object's step report (the island's solve report, its wall time shared evenly) and
/// the contact statistics at the end of the step.
pub fn step_island(
    sims: &mut [&mut ReducedSim],
    contact: &PairContact,
    mu: &[f64],
    eps_v: f64,
    solver: IslandSolver,
    precision: Precision,
    start: Option<&[f64]>,
) -> (Vec<StepReport>, ContactStats) {
    let sw = Stopwatch::start();
    let starts: Vec<StepStart> = sims.iter().map(|s| s.begin_step()).collect();
    let mut offsets = Vec::with_capacity(sims.len());
    let mut at = 0;
    for s in sims.iter() {
        offsets.push(at);
        at += s.layout().dofs();
    }
    let z0: Vec<f64> = sims.iter().flat_map(|s| s.z().iter().copied()).collect();
    let guess: Vec<f64> = starts
        .iter()
        .flat_map(|s| s.guess.iter().copied())
        .collect();
    let (solve, z, stats) = {
        let shared: Vec<&ReducedSim> = sims.iter().map(|s| &**s).collect();
        let pot = IslandPotential {
            parts: shared
                .iter()
                .zip(&starts)
                .map(|(s, st)| s.potential(st))
                .collect(),
            offsets: offsets.clone(),
            contact,
            friction: (contact.friction_lag(&z0, mu), eps_v * shared[0].dt()),
            solver,
            precision,
            coarse: Arc::new(CoarseBasis::new(
                &shared
                    .iter()
                    .map(|s| s.affine_motions())
                    .collect::<Vec<_>>(),
            )),
        };
        // The start: a given one (an earlier solve of this step, reached from z0 by bounded
        // line searches), or the guess within the step bound.
        let mut z: Vec<f64> = match start {
            Some(s) => s.to_vec(),
            None => newton::bounded_start(&pot, &z0, &guess),
        };
        let measure = |d: &[f64]| {
            shared
                .iter()
                .zip(&offsets)
                .map(|(s, &o)| s.measure(&d[o..o + s.layout().dofs()]))
                .fold(0.0, f64::max)
        };
        let rest = BlockRest {
            blocks: shared.iter().map(|s| s.rest_factor()).collect(),
        };
        let options = newton::NewtonOptions {
            hessian: HessianStrategy::Newton,
            ..*shared[0].newton_options()
        };
        let ctx = SolverContext {
            rest: &rest,
            measure: &measure,
            options: &options,
        };
        let solve = newton::minimize(&pot, &mut z, &ctx, &mut QuasiNewtonState::default());
        let stats = contact.stats(&z);
        (solve, z, stats)
    };
    let wall = sw.elapsed() / sims.len() as f64;
    let reports = sims
        .iter_mut()
        .zip(starts.iter().zip(&offsets))
        .map(|(s, (st, &o))| {
            let n = s.layout().dofs();
            s.finish_step(st, z[o..o + n].to_vec(), solve, wall)
        })
        .collect();
    (reports, stats)
}
