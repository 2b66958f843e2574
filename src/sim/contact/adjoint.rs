//! The reverse pass of a step solved as an island (docs/gradients.md). The island's
//! converged state z* minimises the sum of its members' incremental potentials and the
//! contact energy between them, so its adjoint is one solve with the island's exact Hessian
//! (the members' own blocks and the coupling of the pairs in contact), H lambda = dL/dz*
//! stacked over the members; each member's own terms then take their share of lambda as when
//! it steps alone. Here, what the contact adds: -lambda^T d(grad E)/dp for the pair
//! stiffnesses (the penalty, and the lagged friction's normal force), the pair friction
//! coefficients, and the members' start states z_n, from which the friction is lagged (each
//! pair's normal force, direction and start offset).

use super::coarse::CoarseBasis;
use super::energy::{PairContact, PairHessian};
use super::step::{ContactWorld, IslandSolve};
use super::system::BlockHessian;
use super::IslandSolver;
use crate::sim::friction::{lagged_force_adjoint, Curvature};
use crate::sim::newton::{Potential, RestSolve};
use crate::sim::object::StepStart;
use crate::sim::ReducedSim;
use crate::{Error, Point3, Result};
use faer::{Mat, Side};
use rayon::prelude::*;
use std::sync::Arc;

/// The relative residual |H lambda - r| / |r| at which the block conjugate gradients stop for
/// an island's adjoint: 1e-11, a hundred times the block products' round-off (~1e-13) and
/// tighter than the per-object pass's 1e-10 (in its preconditioner's norm), so that the
/// solve's error stays far below the 1e-5 of the finite-difference tests.
pub const ADJOINT_TOLERANCE: f64 = 1e-11;

/// What the reverse pass of one island's step gives.
#[derive(Debug, Clone, PartialEq)]
pub struct IslandAdjoint {
    /// The adjoint lambda, stacked over the members in the solve's order, 12 (m + 1) each.
    pub lambda: Vec<f64>,
    /// dL/dz_n through the lagged object-object friction, stacked like `lambda`.
    pub start: Vec<f64>,
    /// dL/dkappa per pair of members (row-major over the members, symmetric: a pair's value
    /// at (a, b) and at (b, a); self-contact on the diagonal), with respect to the pair
    /// stiffness as given, each raise within the step held as a factor; per Pa/m^2.
    pub stiffness: Vec<f64>,
    /// dL/dmu per pair of members, laid out as `stiffness` (one-sided at mu = 0: the
    /// frictionless pairs' contacts are kept with a zero force).
    pub friction: Vec<f64>,
}

impl ContactWorld {
    /// The reverse pass of the island `solve` of recorded step `step`: `sims` its members (in
    /// the solve's order), `starts` their steps' starts, `z` and `z0` their stacked states
    /// at the end and the start of the step, `rhs` dL/dz* stacked.
    ///
    /// # Errors
    /// [`Error::Gradient`] when the island's exact Hessian is not positive definite at `z`.
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn island_adjoint(
        &self,
        solve: &IslandSolve,
        sims: &[&ReducedSim],
        starts: &[&StepStart],
        z: &[f64],
        z0: &[f64],
        rhs: &[f64],
        step: usize,
    ) -> Result<IslandAdjoint> {
        let group = &solve.members;
        let m = group.len();
        let kappas = self.island_stiffness(solve);
        let contact = PairContact::new(self.bodies(group, sims), kappas.clone());
        let mu = self.over(group, &self.mu);
        let eps = self.eps_v * sims.first().map_or(0.0, |s| s.dt());
        // Every pair active at the start, frictionless ones with a zero force (their blocks
        // are zero; they give dL/dmu).
        let lag = contact.lagged_pairs(z0, &mu, true);

        // The exact Hessian, as the island's Newton forms it.
        let diag: Vec<Mat<f64>> = sims
            .par_iter()
            .zip(starts)
            .zip(contact.bodies())
            .map(|((s, st), b)| {
                let zp = &z[b.offset..b.offset + b.layout.dofs()];
                let pot = s.potential(st);
                pot.exact_hessian(zp, Curvature::Exact)
                    .unwrap_or_else(|| pot.hessian(zp, Curvature::Exact))
            })
            .collect();
        let mut blocks = BlockHessian::new(diag);
        contact.add_hessian_blocks(z, PairHessian::Exact, &mut blocks);
        contact.add_friction_hessian_blocks(&lag, eps, z, Curvature::Exact, &mut blocks);
        let lambda = match self.solver {
            IslandSolver::Dense => dense_solve(&blocks, rhs, step)?,
            IslandSolver::Blocks => {
                let motions: Vec<Mat<f64>> = sims.iter().map(|s| s.affine_motions()).collect();
                let coarse = Arc::new(CoarseBasis::new(&motions));
                // None: a member's block or the coarse system is not positive definite, so
                // neither is H.
                match blocks.into_solver(Some(&coarse)) {
                    Some(solver) => {
                        let (x, info) = solver.solve_to(rhs, ADJOINT_TOLERANCE);
                        if info.negative_curvature || info.relative_residual > ADJOINT_TOLERANCE {
                            // Not converged within the cap, or not positive definite along
                            // some direction: the dense factor decides.
                            dense_solve(&solver.into_matrix(), rhs, step)?
                        } else {
                            x
                        }
                    }
                    None => return Err(not_positive_definite(step)),
                }
            }
        };

        // The adjoint as sample displacements, B lambda per body.
        let lx: Vec<Vec<Point3>> = contact
            .bodies()
            .iter()
            .map(|b| {
                b.samples
                    .displacements(b.layout, &lambda[b.offset..b.offset + b.layout.dofs()])
            })
            .collect();
        let relative = |a: usize, i: usize, b: usize, j: usize| -> [f64; 3] {
            std::array::from_fn(|k| lx[a][i][k] - lx[b][j][k])
        };
        let mut stiffness = vec![0.0; m * m];
        let mut friction = vec![0.0; m * m];
        let add_pair = |out: &mut Vec<f64>, a: usize, b: usize, v: f64| {
            out[a * m + b] += v;
            if a != b {
                out[b * m + a] += v;
            }
        };
        // The penalty: grad_xi E = -kappa w (d - r) u (and + at x_j), so
        // dL/dkappa = w (d - r) u . (lx_i - lx_j).
        let x = contact.positions(z);
        let (active, _) = contact.active(&x);
        for p in &active {
            let kappa = kappas[p.c.a * m + p.c.b];
            let rel = relative(p.c.a, p.c.i, p.c.b, p.c.j);
            let along: f64 = (0..3).map(|k| p.u[k] * rel[k]).sum();
            add_pair(
                &mut stiffness,
                p.c.a,
                p.c.b,
                p.kw / kappa * (p.d - p.r) * along,
            );
        }
        // The lagged friction: the force g(d) at x_i (and -g at x_j), d = x_i - x_j - s0, with
        // mu lambda = mu kappa w (d - r0), its direction u0 and offset s0 = v0 = x_i0 - x_j0
        // all read at the step's start.
        let mut gx0: Vec<Vec<[f64; 3]>> = x.iter().map(|p| vec![[0.0; 3]; p.len()]).collect();
        for l in &lag {
            let (a, b) = (l.c.a, l.c.b);
            let rel = relative(a, l.c.i, b, l.c.j);
            let d = l.displacement(&x);
            let (per_mu_lambda, dl_dn, dl_dd) =
                lagged_force_adjoint(l.mu_lambda(), eps, &l.normal, &l.projector, &d, &rel);
            let dl_dml = -per_mu_lambda;
            let kappa = kappas[a * m + b];
            add_pair(&mut friction, a, b, dl_dml * l.kw * l.depth);
            add_pair(&mut stiffness, a, b, dl_dml * l.mu * l.kw / kappa * l.depth);
            if l.distance <= 0.0 {
                // Coincident samples at the start have no direction to differentiate.
                continue;
            }
            // dL/dv0: through s0 (d = ... - s0), the direction u0 = v0 / r0 (du/dv =
            // (I - u u^T) / r0) and the depth d - r0 (dr0/dv0 = u0).
            let tangent = crate::sim::friction::project(&l.projector, &dl_dn);
            let dv: [f64; 3] = std::array::from_fn(|k| {
                -dl_dd[k] + tangent[k] / l.distance - dl_dml * l.mu * l.kw * l.normal[k]
            });
            for k in 0..3 {
                gx0[a][l.c.i][k] += dv[k];
                gx0[b][l.c.j][k] -= dv[k];
            }
        }
        let mut start = vec![0.0; lambda.len()];
        contact.scatter(&gx0, &mut start);
        // With respect to the stiffness as given: a raise multiplied it by a fixed factor.
        let given = self.over(group, &self.given_stiffness);
        for ((g, k), k0) in stiffness.iter_mut().zip(&kappas).zip(&given) {
            *g *= k / k0;
        }
        Ok(IslandAdjoint {
            lambda,
            start,
            stiffness,
            friction,
        })
    }
}

/// H x = rhs by the dense Cholesky factor of the island's exact Hessian H.
fn dense_solve(h: &BlockHessian, rhs: &[f64], step: usize) -> Result<Vec<f64>> {
    let factor = h
        .to_dense()
        .llt(Side::Lower)
        .map_err(|_| not_positive_definite(step))?;
    Ok(RestSolve::solve(&factor, rhs))
}

fn not_positive_definite(step: usize) -> Error {
    Error::Gradient(format!(
        "the exact Hessian of an island at the end of recorded step {step} is not positive \
         definite: the step did not end at a strict minimum (tighten the solver's tol)"
    ))
}
