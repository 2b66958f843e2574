//! The reverse pass's linear solves H lambda = r, one per recorded step, H the exact Hessian
//! at the step's end. Forming H costs C (4 (m + 1))^2 dense products per step (90% of a
//! reverse pass when each step formed it); consecutive steps' Hessians differ little, so
//! [`AdjointSolver`] keeps the Cholesky factor of one step's H and solves the next steps by
//! conjugate gradients on matrix-free products H v (about one elastic gradient each),
//! preconditioned by that factor. The iterations grow as the state moves away from the
//! factor's; H is formed and factorized again when a step's iterations cost more than the
//! average step since the last factor (the factor included), the renewal that minimises the
//! average cost when costs rise, or when they do not converge within [`MAX_CG`] iterations or
//! meet a direction of non-positive curvature. Decisions count products, not seconds, so a
//! pass is deterministic on one machine (the AVX2 and the portable kernels round
//! differently, and with them the iteration counts). A step solved by conjugate gradients is
//! not checked for a positive definite H as a formed one is: only the directions they explore.

use crate::sim::friction::Curvature;
use crate::sim::newton::{dot, Potential, RestSolve};
use crate::sim::object::StepPotential;
use crate::{Error, Result};
use faer::linalg::solvers::Llt;
use faer::Side;

/// Conjugate-gradient iterations per step before H is formed there instead: a factor that
/// needs more has drifted far from the step's H.
pub const MAX_CG: usize = 30;

/// What forming and factorizing H costs in matrix-free products, per column of one row of z
/// (4 (m + 1)): the dense products scale with (4 (m + 1))^2 and a product with 4 (m + 1).
/// Measured at m = 16 (2 cores): 7.2 ms against 0.30 ms, 24 = 0.35 x 68.
pub const FORMED_PER_COLUMN: f64 = 0.35;

/// The relative residual the conjugate gradients stop at, in the preconditioner's norm:
/// sqrt(r^T P^-1 r) <= CG_TOL sqrt(b^T P^-1 b). With P close to H that is about the solution's
/// relative error in H's energy norm; scale-free (a loss in any unit converges alike).
pub const CG_TOL: f64 = 1e-10;

/// The solves of one reverse pass and what they cost.
#[derive(Default)]
pub(super) struct AdjointSolver {
    /// Form and factorize H at every step (no conjugate gradients).
    direct: bool,
    /// The last factorized Hessian's factor.
    factor: Option<Llt<f64>>,
    /// Steps solved since the last factor (it included) and their cost in products (the
    /// factor counted as [`FORMED_PER_COLUMN`] x 4 (m + 1)).
    cycle: (usize, f64),
    /// Form H at the next step.
    refresh: bool,
    /// Exact Hessians formed and factorized.
    pub(super) hessians: usize,
    /// Matrix-free products H v taken.
    pub(super) products: usize,
}

impl AdjointSolver {
    /// A solver for one reverse pass; `direct`: form and factorize H at every step.
    pub(super) fn new(direct: bool) -> AdjointSolver {
        AdjointSolver {
            direct,
            ..AdjointSolver::default()
        }
    }

    /// Solve H x = rhs with the exact Hessian H of `pot` at `z` (the end of recorded step
    /// `t`).
    pub(super) fn solve(
        &mut self,
        pot: &StepPotential<'_>,
        z: &[f64],
        rhs: &[f64],
        t: usize,
    ) -> Result<Vec<f64>> {
        if let (Some(factor), false) = (&self.factor, self.direct || self.refresh) {
            let op = pot.exact_operator(z);
            let apply = |v: &[f64]| op.product(v);
            let (x, products) = conjugate_gradients(&apply, factor, rhs);
            self.products += products;
            if let Some(x) = x {
                let (steps, cost) = &mut self.cycle;
                *steps += 1;
                *cost += products as f64;
                self.refresh = products as f64 > *cost / *steps as f64;
                return Ok(x);
            }
        }
        let h = pot
            .exact_hessian(z, Curvature::Exact)
            .ok_or_else(|| Error::Gradient("the potential has no exact Hessian".into()))?;
        let factor = Llt::new(h.as_ref(), Side::Lower).map_err(|_| {
            Error::Gradient(format!(
                "the exact Hessian at the end of recorded step {t} is not positive definite: \
                 the step did not end at a strict minimum (tighten the solver's tol)"
            ))
        })?;
        self.hessians += 1;
        let x = RestSolve::solve(&factor, rhs);
        self.factor = Some(factor);
        self.cycle = (1, FORMED_PER_COLUMN * (h.nrows() / 3) as f64);
        self.refresh = false;
        Ok(x)
    }
}

/// Preconditioned conjugate gradients for `apply(x) = b` from x = P^-1 b: the solution, or
/// None when [`MAX_CG`] iterations do not reach [`CG_TOL`] or a direction has p^T H p <= 0
/// (or NaN); and the products taken. A zero b gives x = 0 at once.
fn conjugate_gradients(
    apply: &dyn Fn(&[f64]) -> Vec<f64>,
    p: &Llt<f64>,
    b: &[f64],
) -> (Option<Vec<f64>>, usize) {
    let mut x = RestSolve::solve(p, b);
    let target = CG_TOL * CG_TOL * dot(b, &x);
    if target == 0.0 {
        return (Some(x), 0);
    }
    let ax = apply(&x);
    let mut products = 1;
    let mut r: Vec<f64> = b.iter().zip(&ax).map(|(a, c)| a - c).collect();
    let mut s = RestSolve::solve(p, &r);
    let mut rs = dot(&r, &s);
    let mut d = s.clone();
    for _ in 0..MAX_CG {
        if rs <= target {
            return (Some(x), products);
        }
        let ad = apply(&d);
        products += 1;
        let curvature = dot(&d, &ad);
        // Non-positive or NaN curvature: not a direction of a positive definite H.
        if curvature.is_nan() || curvature <= 0.0 {
            return (None, products);
        }
        let alpha = rs / curvature;
        x.iter_mut().zip(&d).for_each(|(xi, di)| *xi += alpha * di);
        r.iter_mut().zip(&ad).for_each(|(ri, ai)| *ri -= alpha * ai);
        s = RestSolve::solve(p, &r);
        let next = dot(&r, &s);
        let beta = next / rs;
        rs = next;
        d.iter_mut()
            .zip(&s)
            .for_each(|(di, si)| *di = si + beta * *di);
    }
    ((rs <= target).then_some(x), products)
}
