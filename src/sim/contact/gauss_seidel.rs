//! Nonlinear block Gauss-Seidel over an island's members ([`IslandSolver::GaussSeidel`]):
//! each member in turn minimises the island's incremental potential over its own
//! coordinates, the other members frozen, with its own solver settings (by default L-BFGS on
//! its rest factor, as when it steps alone), sweeping until a sweep finds every member
//! already stationary. Only the member's terms and the contact and friction terms of the
//! pairs it can reach change with its coordinates, so each member solve sees its own
//! incremental potential plus the penalties against its neighbours' samples where they are.
//!
//! [`IslandSolver::GaussSeidel`]: super::IslandSolver::GaussSeidel

use super::energy::{PairContact, PairHessian, PairLag};
use super::system::BlockHessian;
use crate::sim::friction::Curvature;
use crate::sim::newton::{
    self, EvalInfo, NewtonOptions, Potential, QuasiNewtonState, RestSolve, SolveReport,
    SolverContext,
};
use crate::sim::object::StepPotential;
use crate::sim::ReducedSim;
use crate::Point3;
use faer::Mat;

/// Most sweeps of one island's Gauss-Seidel solve before the island's Newton takes over
/// from where the sweeps ended.
pub const MAX_SWEEPS: usize = 30;

/// One member's minimisation: its own potential, and the contact between it (body 0) and
/// its neighbours (frozen at `frozen`, the sub-island's stacked coordinates).
struct MemberPotential<'a, 'b> {
    part: &'b StepPotential<'a>,
    contact: PairContact<'a>,
    frozen: Vec<f64>,
    lag: Vec<PairLag>,
    eps: f64,
}

impl MemberPotential<'_, '_> {
    fn dofs(&self) -> usize {
        self.part.dofs()
    }

    /// The sub-island's coordinates with the member at `z`.
    fn stacked(&self, z: &[f64]) -> Vec<f64> {
        let mut s = self.frozen.clone();
        s[..z.len()].copy_from_slice(z);
        s
    }

    /// The member's block of the contact and friction Hessians at `z`.
    fn contact_block(&self, z: &[f64], which: PairHessian, friction: Curvature) -> Mat<f64> {
        let zs = self.stacked(z);
        let sizes: Vec<usize> = self
            .contact
            .bodies()
            .iter()
            .map(|b| b.layout.dofs())
            .collect();
        let mut h = BlockHessian::zeros(&sizes);
        self.contact.add_hessian_blocks(&zs, which, &mut h);
        self.contact
            .add_friction_hessian_blocks(&self.lag, self.eps, &zs, friction, &mut h);
        h.block_mut(0, 0).to_owned()
    }
}

impl Potential for MemberPotential<'_, '_> {
    fn energy_gradient(&self, z: &[f64], grad: &mut [f64]) -> (f64, EvalInfo) {
        grad.fill(0.0);
        let (mut e, info) = self.part.energy_gradient(z, grad);
        let zs = self.stacked(z);
        let mut gs = vec![0.0; zs.len()];
        e += self.contact.energy_gradient(&zs, &mut gs).energy;
        e += self
            .contact
            .friction_energy_gradient(&self.lag, self.eps, &zs, &mut gs);
        for (g, c) in grad.iter_mut().zip(&gs) {
            *g += c;
        }
        (e, info)
    }

    fn hessian(&self, z: &[f64], friction: Curvature) -> Mat<f64> {
        self.part.hessian(z, friction) + self.contact_block(z, PairHessian::Psd, friction)
    }

    fn base_hessian(
        &self,
        z: &[f64],
        stride: usize,
        precision: crate::sim::elastic::Precision,
    ) -> Mat<f64> {
        self.part.base_hessian(z, stride, precision)
            + self.contact_block(z, PairHessian::Psd, Curvature::Exact)
    }

    fn exact_hessian(&self, z: &[f64], friction: Curvature) -> Option<Mat<f64>> {
        let own = self.part.exact_hessian(z, friction)?;
        Some(own + self.contact_block(z, PairHessian::Exact, friction))
    }

    fn max_step(&self, z: &[f64], dir: &[f64]) -> f64 {
        let mut ds = vec![0.0; self.frozen.len()];
        ds[..dir.len()].copy_from_slice(dir);
        self.part
            .max_step(z, dir)
            .min(self.contact.max_step(&self.stacked(z), &ds))
    }

    fn has_friction(&self) -> bool {
        self.part.has_friction() || !self.lag.is_empty()
    }
}

/// The outcome of the sweeps: each member's solve report (its sub-solves summed) and whether the last sweep found every member stationary.
pub(super) struct Sweeps {
    pub(super) reports: Vec<SolveReport>,
    pub(super) converged: bool,
}

/// The members' sample boxes at `z`, each grown by its samples' thickness plus `reach[a]`.
fn boxes(contact: &PairContact, z: &[f64], reach: &[f64]) -> Vec<(Point3, Point3)> {
    contact
        .positions(z)
        .iter()
        .zip(contact.bodies())
        .zip(reach)
        .map(|((x, b), r)| {
            let grow = b.samples.thickness + r;
            let mut lo = [f64::INFINITY; 3];
            let mut hi = [f64::NEG_INFINITY; 3];
            for p in x {
                for d in 0..3 {
                    lo[d] = lo[d].min(p[d] - grow);
                    hi[d] = hi[d].max(p[d] + grow);
                }
            }
            (lo, hi)
        })
        .collect()
}

/// Sweep over the members of an island (`parts`, stacked at `offsets` in `z`, their objects
/// `sims`) until a sweep finds each member stationary given the others, or [`MAX_SWEEPS`];
/// `z` (updated in place) is where the sweeps start, `z0` the state at the step's start
/// (friction is lagged from it: `mu` row-major over the members, `eps` the smoothing
/// displacement, metres); `contact` the island's contact.
#[allow(clippy::too_many_arguments)]
pub(super) fn sweep(
    parts: &[StepPotential],
    offsets: &[usize],
    sims: &[&ReducedSim],
    contact: &PairContact,
    mu: &[f64],
    eps: f64,
    z0: &[f64],
    z: &mut [f64],
) -> Sweeps {
    let m = parts.len();
    let mut states: Vec<QuasiNewtonState> = (0..m).map(|_| QuasiNewtonState::default()).collect();
    let mut reports: Vec<SolveReport> = vec![SolveReport::default(); m];
    // How far each member's samples may move in its solve, for its neighbourhood: as far as
    // they moved from the step's start to where the sweeps start, and that again.
    let moved = {
        let (x0, x1) = (contact.positions(z0), contact.positions(z));
        x0.iter()
            .zip(&x1)
            .map(|(a, b)| {
                a.iter()
                    .zip(b)
                    .map(|(p, q)| crate::linalg3::norm(&crate::linalg3::sub(p, q)))
                    .fold(0.0, f64::max)
            })
            .collect::<Vec<f64>>()
    };
    let reach: Vec<f64> = moved.iter().map(|d| 2.0 * d).collect();
    for sweep in 1..=MAX_SWEEPS {
        let boxes = boxes(contact, z, &reach);
        let mut moved_any = false;
        for a in 0..m {
            let meet = |b: usize| {
                (0..3).all(|d| boxes[a].0[d] <= boxes[b].1[d] && boxes[b].0[d] <= boxes[a].1[d])
            };
            let order: Vec<usize> = std::iter::once(a)
                .chain((0..m).filter(|&b| b != a && meet(b)))
                .collect();
            let sub = contact.subset(&order);
            let stack = |v: &[f64]| -> Vec<f64> {
                order
                    .iter()
                    .flat_map(|&b| v[offsets[b]..offsets[b] + parts[b].dofs()].iter().copied())
                    .collect()
            };
            let sub_mu: Vec<f64> = order
                .iter()
                .flat_map(|&p| order.iter().map(move |&q| mu[p * m + q]))
                .collect();
            let lag = sub.friction_lag(&stack(z0), &sub_mu);
            let pot = MemberPotential {
                part: &parts[a],
                contact: sub,
                frozen: stack(z),
                lag,
                eps,
            };
            let n = pot.dofs();
            let za = &mut z[offsets[a]..offsets[a] + n];
            // Stationary already (given its neighbours now): nothing to solve.
            let mut grad = vec![0.0; n];
            pot.energy_gradient(za, &mut grad);
            let options: &NewtonOptions = sims[a].newton_options();
            // The member's rest system with its contacts' stiffness where it is now: the
            // rest system alone has none, so its steps (and the convergence measure) would
            // overshoot along the contact normals.
            let rest = {
                let l = sims[a].rest_factor().L();
                let s =
                    l * l.transpose() + pot.contact_block(za, PairHessian::Psd, Curvature::Exact);
                s.llt(faer::Side::Lower).ok()
            };
            let rest: &dyn RestSolve = match rest.as_ref() {
                Some(f) => f,
                None => sims[a].rest_factor(),
            };
            let delta = states[a].model_solve(options.hessian, rest, &grad);
            if sweep > 1 && sims[a].measure(&delta) <= options.tol {
                continue;
            }
            moved_any = true;
            let measure = |d: &[f64]| sims[a].measure(d);
            let ctx = SolverContext {
                rest,
                measure: &measure,
                options,
            };
            let rep = newton::minimize(&pot, za, &ctx, &mut states[a]);
            add(&mut reports[a], &rep);
        }
        if !moved_any {
            return Sweeps {
                reports,
                converged: true,
            };
        }
    }
    Sweeps {
        reports,
        converged: false,
    }
}

/// Count the sub-solve `s` into a member's report: iterations, evaluations and times summed;
/// the last one's residual, energies and state.
pub(super) fn add(total: &mut SolveReport, s: &SolveReport) {
    let first = total.evaluations == 0;
    total.iterations += s.iterations;
    total.evaluations += s.evaluations;
    total.line_search_cutbacks += s.line_search_cutbacks;
    total.line_search_failed |= s.line_search_failed;
    total.bounded_steps += s.bounded_steps;
    total.factorizations += s.factorizations;
    total.cholesky_fallbacks += s.cholesky_fallbacks;
    total.projected_fallbacks += s.projected_fallbacks;
    total.majorized_models += s.majorized_models;
    total.gradient_s += s.gradient_s;
    total.hessian_s += s.hessian_s;
    total.solve_s += s.solve_s;
    total.max_energy_rise = total.max_energy_rise.max(s.max_energy_rise);
    if first {
        total.initial_energy = s.initial_energy;
    }
    total.energy = s.energy;
    total.residual = s.residual;
    total.converged = s.converged;
    total.info = s.info;
}
