//! Minimisation of one time step's incremental potential: Newton or quasi-Newton with a
//! backtracking (Armijo) line search.
//!
//! Strategies ([`HessianStrategy`]):
//! - `Newton`: the full Hessian (per-point PSD projection) rebuilt and Cholesky-factorized
//!   every iteration. Quadratic convergence; O(C (4 (m + 1))^2) per iteration for C
//!   cubature points.
//! - `Fixed`: the rest-state system matrix S (inertia + rest elastic Hessian + boundary
//!   penalties), factorized once for the whole run; each iteration costs one gradient and two
//!   triangular solves. Linear convergence.
//! - `Lbfgs`: L-BFGS with S^-1 as the initial inverse Hessian (Liu et al. 2017); the same
//!   cost per iteration as `Fixed`, fewer iterations.
//!
//! Convergence: with delta = B^-1 grad E, where B is the best Hessian model at hand (the
//! latest factorized Hessian for `Newton` and for `Lbfgs` after a refresh, the rest matrix S
//! otherwise and always for `Fixed`), the mass-weighted RMS length of delta over the object,
//! divided by the rest bounding-box diagonal D, must fall below `tol`. It reads "one more
//! Newton step would move the points by less than tol x D on average" (a Newton decrement in
//! length units): scale free, and comparable across strategies. With `Fixed` under large
//! rotations S overestimates the stiffness of rotated material, so it can stop early: prefer
//! `Lbfgs` there (docs/performance.md has the measurements).
//!
//! Every step takes at least one iteration, even when its starting point (the initial guess,
//! [`InitialGuess`]) already meets the tolerance: with small time steps the whole per-step
//! change (g h^2 for gravity) can be below tol x D, and accepting the velocity predictor
//! would leave the object hanging in the air (measured: a beam under gravity did not move at
//! h = 1e-4 s; docs/limits.md).

pub use crate::sim::elastic::Precision;
use crate::sim::friction::Curvature;
use faer::linalg::solvers::{Llt, Solve};
use faer::{Mat, Side};
use serde::{Deserialize, Serialize};

/// How the Newton system is built.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum HessianStrategy {
    /// Full PSD-projected Hessian, refactorized every iteration.
    Newton,
    /// Rest-state Hessian factorized once.
    Fixed,
    /// L-BFGS on top of the rest-state Hessian (default: fastest to the same tolerance in
    /// our measurements, docs/performance.md).
    #[default]
    Lbfgs,
}

impl HessianStrategy {
    /// Name used in reports and scene files.
    pub fn name(self) -> &'static str {
        crate::names::variant_name(&self)
    }
}

/// Where each time step's minimisation starts.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum InitialGuess {
    /// The inertial predictor z_n + h zdot_n (constant velocity): the safer start when the
    /// motion reverses from step to step (a vibrating cantilever at m = 16 takes 3.50
    /// evaluations per step from here against 4.01 extrapolated; docs/performance.md).
    Velocity,
    /// Quadratic extrapolation z_n + h zdot_n + h (zdot_n - zdot_{n-1}) (constant
    /// acceleration; the first step uses the velocity predictor). Default: exact for free
    /// fall, and closer for smoothly driven motion (the twist at m = 32: 10% fewer
    /// evaluations and 24% fewer base refreshes), at the price of more line-search cutbacks
    /// where the motion reverses. Only the start changes: every step still minimises the
    /// same potential to the same tolerance.
    #[default]
    Extrapolate,
}

impl InitialGuess {
    /// Name used in reports and scene files.
    pub fn name(self) -> &'static str {
        crate::names::variant_name(&self)
    }
}

/// Solver settings for each time step.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct NewtonOptions {
    /// Hessian strategy.
    pub hessian: HessianStrategy,
    /// Convergence tolerance on the RMS step length relative to the object's diagonal.
    pub tol: f64,
    /// Iteration cap per time step.
    pub max_iter: usize,
    /// L-BFGS history length (pairs kept).
    pub lbfgs_history: usize,
    /// L-BFGS: every this many iterations within a step, rebuild and refactorize the
    /// Hessian as the new base matrix (0: never; keep the rest matrix).
    pub refresh_iterations: usize,
    /// L-BFGS: the refreshed base uses every this-many-th cubature point (volumes rescaled):
    /// a cheaper, still PSD model of the Hessian, but a looser one (more iterations, and the
    /// convergence measure uses it). Default 1: all points (docs/performance.md measures 4).
    pub refresh_stride: usize,
    /// L-BFGS: arithmetic of the refreshed base's dense products. Default `single`: about
    /// twice as fast, and a quasi-Newton base only needs to be a good SPD model (a base that
    /// does not factorize is rebuilt in `double` before falling back to the rest matrix).
    /// docs/performance.md measures both.
    pub refresh_precision: Precision,
    /// Starting point of each step's minimisation (default `extrapolate`).
    pub initial_guess: InitialGuess,
}

impl Default for NewtonOptions {
    fn default() -> Self {
        Self {
            hessian: HessianStrategy::default(),
            tol: 1e-6,
            max_iter: 100,
            lbfgs_history: 8,
            refresh_iterations: 10,
            refresh_stride: 1,
            refresh_precision: Precision::Single,
            initial_guess: InitialGuess::Extrapolate,
        }
    }
}

/// Most Newton iterations a step may be given: 100,000 (a typo guard).
pub const MAX_NEWTON_ITERATIONS: usize = 100_000;

/// Most L-BFGS pairs: 10,000 (a typo guard; an object has 12 (m + 1) unknowns).
pub const MAX_LBFGS_HISTORY: usize = 10_000;

impl NewtonOptions {
    /// Check ranges.
    pub fn validate(&self) -> crate::Result<()> {
        if !(self.tol > 0.0 && self.tol < 1.0) {
            return Err(crate::Error::param(
                "tol",
                self.tol,
                "the Newton tolerance must be in (0, 1) (default 1e-6)",
            ));
        }
        if self.max_iter == 0 {
            return Err(crate::Error::param(
                "max_iter",
                0,
                "need at least one Newton iteration per step (default 100)",
            ));
        }
        if self.max_iter > MAX_NEWTON_ITERATIONS {
            return Err(crate::Error::param(
                "max_iter",
                self.max_iter,
                format!(
                    "at most {MAX_NEWTON_ITERATIONS} Newton iterations per step (default 100; \
                     a step that needs more will not converge with more)"
                ),
            ));
        }
        if self.lbfgs_history > MAX_LBFGS_HISTORY {
            return Err(crate::Error::param(
                "lbfgs_history",
                self.lbfgs_history,
                format!(
                    "at most {MAX_LBFGS_HISTORY} L-BFGS pairs (default 8; more pairs than \
                     unknowns add nothing)"
                ),
            ));
        }
        if self.refresh_stride == 0 {
            return Err(crate::Error::param(
                "refresh_stride",
                0,
                "the Hessian refresh stride must be at least 1 (default 1)",
            ));
        }
        if self.hessian == HessianStrategy::Lbfgs && self.lbfgs_history == 0 {
            return Err(crate::Error::param(
                "lbfgs_history",
                0,
                "L-BFGS needs a history of at least one pair (default 8)",
            ));
        }
        Ok(())
    }
}

/// What a potential reports besides its value.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize)]
pub struct EvalInfo {
    /// Smallest det F over the cubature points.
    pub min_det: f64,
    /// Cubature points with det F <= 0.
    pub inverted: usize,
    /// Collider penetrations (point-obstacle pairs).
    pub contacts: usize,
    /// Deepest collider penetration, metres (0 without contact).
    pub penetration: f64,
    /// Estimated rounding error of the energy, J (the penalty quadratics cancel large
    /// terms): energy changes below it are noise.
    #[serde(skip)]
    pub rounding: f64,
}

/// A smooth function of z to minimise.
pub trait Potential {
    /// Energy (J), gradient written to `grad`.
    fn energy_gradient(&self, z: &[f64], grad: &mut [f64]) -> (f64, EvalInfo);
    /// PSD approximation of the Hessian at z, its friction terms curved as `friction` says.
    fn hessian(&self, z: &[f64], friction: Curvature) -> Mat<f64>;
    /// A cheaper PSD approximation for quasi-Newton bases (default: [`Potential::hessian`]);
    /// `stride` and `precision` as in [`NewtonOptions::refresh_stride`] and
    /// [`NewtonOptions::refresh_precision`].
    fn base_hessian(&self, z: &[f64], stride: usize, precision: Precision) -> Mat<f64> {
        let _ = (stride, precision);
        self.hessian(z, Curvature::Exact)
    }
    /// The largest step fraction alpha the line search may take along `dir` from `z`
    /// (default: unbounded). Object-object contact bounds it so that no sample pair passes
    /// through another between iterates ([`crate::sim::contact`]).
    fn max_step(&self, z: &[f64], dir: &[f64]) -> f64 {
        let _ = (z, dir);
        f64::INFINITY
    }
    /// The exact Hessian at z (default: none, Newton factorizes [`Potential::hessian`]).
    /// Where it exists Newton factorizes it first and takes the PSD approximation only when
    /// the exact one is not positive definite: near a minimum it is, and the projected
    /// curvature (clipped compression modes, dropped contact curvature) slows Newton to a
    /// linear rate (docs/performance.md, "Object-object contact"). Its friction terms are
    /// curved as `friction` says.
    fn exact_hessian(&self, z: &[f64], friction: Curvature) -> Option<Mat<f64>> {
        let _ = (z, friction);
        None
    }
    /// The Newton step at z for the gradient `grad` when the potential solves its system in
    /// its own structure (an island of objects: block sparse,
    /// [`crate::sim::contact::system`]); default [`NewtonSystem::Dense`]: factorize
    /// [`Potential::exact_hessian`] or [`Potential::hessian`] densely. Friction terms are
    /// curved as `friction` says.
    fn newton_system(&self, z: &[f64], grad: &[f64], friction: Curvature) -> NewtonSystem {
        let _ = (z, grad, friction);
        NewtonSystem::Dense
    }
    /// Whether it has friction terms, whose Hessian depends on the [`Curvature`] asked for
    /// (default: none).
    fn has_friction(&self) -> bool {
        false
    }
}

/// How a potential's Newton system at one iterate is solved ([`Potential::newton_system`]).
pub enum NewtonSystem {
    /// Build the dense Hessian and factorize it (Cholesky).
    Dense,
    /// The potential solved it: its solver of H(z) d = g (kept to measure convergence at
    /// the next iterate) and d for the given gradient, a descent direction (-d).
    Solved {
        /// The factorized system.
        solver: Box<dyn RestSolve + Send>,
        /// H(z)^-1 grad.
        direction: Vec<f64>,
        /// Whether the exact Hessian was not positive definite and the PSD approximation
        /// was used.
        projected: bool,
    },
    /// The system is not positive definite (the rest step is taken, as when a dense
    /// Cholesky factorization fails).
    Indefinite,
}

/// A fixed SPD solve, x = S^-1 b: the rest system of one object (a Cholesky factor) or of an
/// island of objects (one factor per object, block diagonal).
pub trait RestSolve: Sync {
    /// S^-1 `rhs`.
    fn solve(&self, rhs: &[f64]) -> Vec<f64>;
}

impl RestSolve for Llt<f64> {
    fn solve(&self, rhs: &[f64]) -> Vec<f64> {
        solve_with(self, rhs)
    }
}

/// A block-diagonal SPD solve: each block a Cholesky factor acting on consecutive entries.
pub struct BlockRest<'a> {
    /// The factors, in the order of the blocks.
    pub blocks: Vec<&'a Llt<f64>>,
}

impl RestSolve for BlockRest<'_> {
    fn solve(&self, rhs: &[f64]) -> Vec<f64> {
        let mut out = Vec::with_capacity(rhs.len());
        let mut at = 0;
        for f in &self.blocks {
            let n = f.L().nrows();
            out.extend(solve_with(f, &rhs[at..at + n]));
            at += n;
        }
        out
    }
}

/// Outcome of one time step's minimisation.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize)]
pub struct SolveReport {
    /// Iterations taken.
    pub iterations: usize,
    /// Whether the tolerance was met.
    pub converged: bool,
    /// Final convergence measure (compare with `tol`).
    pub residual: f64,
    /// Final energy, J.
    pub energy: f64,
    /// Energy at the start of the step (the initial guess), J: `energy` <= this up to
    /// rounding.
    pub initial_energy: f64,
    /// Largest energy increase accepted by one iteration's line search, J (0 when every
    /// iteration decreased the energy; positive only within the energy's rounding level,
    /// where the line search accepts flat steps that reduce the slope).
    pub max_energy_rise: f64,
    /// Energy/gradient evaluations (the dominant cost of the quasi-Newton strategies).
    pub evaluations: usize,
    /// Step halvings in the line search, summed over iterations.
    pub line_search_cutbacks: usize,
    /// Whether the line search failed to decrease the energy (the step ended early).
    pub line_search_failed: bool,
    /// Iterations whose line search started below a full step because of the potential's
    /// step bound ([`Potential::max_step`]; object-object contact).
    pub bounded_steps: usize,
    /// Hessian factorizations (Newton).
    pub factorizations: usize,
    /// Times a Newton Hessian was not positive definite and the rest matrix was used.
    pub cholesky_fallbacks: usize,
    /// Times the exact Hessian ([`Potential::exact_hessian`]) was not positive definite and
    /// its PSD approximation was factorized instead.
    pub projected_fallbacks: usize,
    /// Newton models whose friction terms took their majorizer's curvature (after a line
    /// search that cut back; [`crate::sim::friction::Curvature`]).
    pub majorized_models: usize,
    /// Diagnostics at the final state.
    pub info: EvalInfo,
    /// Seconds spent in energy/gradient evaluations.
    pub gradient_s: f64,
    /// Seconds spent building Hessians.
    pub hessian_s: f64,
    /// Seconds spent factorizing and solving.
    pub solve_s: f64,
}

/// The fixed pieces the solver needs.
pub struct SolverContext<'a> {
    /// The rest system matrix S (its Cholesky factor, or one per object of an island).
    pub rest: &'a dyn RestSolve,
    /// Convergence measure of delta = S^-1 grad (relative RMS length).
    pub measure: &'a dyn Fn(&[f64]) -> f64,
    /// Options.
    pub options: &'a NewtonOptions,
}

/// a . b of two vectors of one length.
pub(super) fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

fn solve_with(f: &Llt<f64>, rhs: &[f64]) -> Vec<f64> {
    let b = Mat::from_fn(rhs.len(), 1, |i, _| rhs[i]);
    let x = Solve::solve(f, &b);
    (0..rhs.len()).map(|i| x[(i, 0)]).collect()
}

/// Quasi-Newton memory carried across time steps (the Hessian changes little from one step
/// to the next): L-BFGS curvature pairs and the current base matrix.
#[derive(Default)]
pub struct QuasiNewtonState {
    /// Curvature pairs (s, y, 1 / s.y), oldest first.
    pairs: std::collections::VecDeque<(Vec<f64>, Vec<f64>, f64)>,
    /// Factor of the latest refreshed Hessian (None: the rest matrix S).
    base: Option<Llt<f64>>,
    /// The latest Newton system solved in the potential's own structure
    /// ([`NewtonSystem::Solved`]), used like `base`.
    structured: Option<Box<dyn RestSolve + Send>>,
}

/// Build the quasi-Newton base Hessian at `z` and factorize it (None: not positive
/// definite), with the time and the factorization counted in `rep`.
fn refreshed_base(
    pot: &dyn Potential,
    z: &[f64],
    stride: usize,
    precision: Precision,
    rep: &mut SolveReport,
) -> Option<Llt<f64>> {
    use crate::report::Stopwatch;
    let sw = Stopwatch::start();
    let h = pot.base_hessian(z, stride, precision);
    rep.hessian_s += sw.elapsed();
    let sw = Stopwatch::start();
    rep.factorizations += 1;
    let factor = h.llt(Side::Lower).ok();
    rep.solve_s += sw.elapsed();
    factor
}

/// f(), its wall time added to `seconds`.
fn timed<T>(seconds: &mut f64, f: impl FnOnce() -> T) -> T {
    let sw = crate::report::Stopwatch::start();
    let out = f();
    *seconds += sw.elapsed();
    out
}

/// The dense Newton direction H(z)^-1 `grad` (the step `delta` of the best model at hand
/// when the Hessian does not factorize), with its time and factorization counted in `rep`.
fn newton_direction(
    pot: &dyn Potential,
    z: &[f64],
    grad: &[f64],
    delta: &[f64],
    friction: Curvature,
    base: &mut Option<Llt<f64>>,
    rep: &mut SolveReport,
) -> Vec<f64> {
    use crate::report::Stopwatch;
    if let Some(h) = timed(&mut rep.hessian_s, || pot.exact_hessian(z, friction)) {
        rep.factorizations += 1;
        let solved = timed(&mut rep.solve_s, || {
            let f = h.llt(Side::Lower).ok()?;
            let d = solve_with(&f, grad);
            (dot(grad, &d) > 0.0).then_some((f, d))
        });
        if let Some((f, d)) = solved {
            *base = Some(f);
            return d;
        }
        rep.projected_fallbacks += 1;
    }
    let h = timed(&mut rep.hessian_s, || pot.hessian(z, friction));
    let sw = Stopwatch::start();
    rep.factorizations += 1;
    let d = match h.llt(Side::Lower) {
        Ok(f) => {
            let d = solve_with(&f, grad);
            *base = Some(f);
            d
        }
        Err(_) => {
            // The PSD-projected Hessian plus the SPD inertia is positive definite in exact
            // arithmetic; if rounding breaks that, take the rest step.
            rep.cholesky_fallbacks += 1;
            delta.to_vec()
        }
    };
    rep.solve_s += sw.elapsed();
    d
}

/// Where a minimisation should start from the previous state `from` when `guess`
/// extrapolates the motion: the guess itself when [`Potential::max_step`] allows the whole way
/// (bit for bit), else pulled back along `guess - from` as far as it allows (the guess may
/// carry a point across a thin obstacle or a contact sample through another).
pub fn bounded_start(pot: &dyn Potential, from: &[f64], guess: &[f64]) -> Vec<f64> {
    let dir: Vec<f64> = guess.iter().zip(from).map(|(g, z0)| g - z0).collect();
    let alpha = pot.max_step(from, &dir);
    if alpha >= 1.0 {
        return guess.to_vec();
    }
    from.iter()
        .zip(&dir)
        .map(|(z0, d)| z0 + alpha * d)
        .collect()
}

/// Minimise `pot` starting from `z` (updated in place); `state` carries the quasi-Newton memory between
/// calls.
pub fn minimize(
    pot: &dyn Potential,
    z: &mut [f64],
    ctx: &SolverContext,
    state: &mut QuasiNewtonState,
) -> SolveReport {
    use crate::report::Stopwatch;
    let n = z.len();
    let opts = ctx.options;
    let mut rep = SolveReport::default();
    let mut grad = vec![0.0; n];
    let sw = Stopwatch::start();
    let (mut e, mut info) = pot.energy_gradient(z, &mut grad);
    rep.gradient_s += sw.elapsed();
    rep.evaluations += 1;
    rep.initial_energy = e;
    let mut trial = vec![0.0; n];
    let mut tgrad = vec![0.0; n];
    // The friction curvature of the next Newton model, and that of the model the convergence
    // measure's step comes from. The next model takes the majorizer after a line search that
    // had to cut back the step for a real decrease (the exact model overshot, most often where
    // a contact's slip turns through zero, the friction potential's kink), the exact curvature
    // otherwise. Convergence is judged only on an exact model's step: where contacts slide
    // the majorizer's is shorter.
    let mut curvature = Curvature::Exact;
    let mut measured_with = Curvature::Exact;
    // Fixed for the solve: friction contacts are lagged from the step's start.
    let has_friction = pot.has_friction();
    let judged = |c: Curvature| c == Curvature::Exact || !has_friction;
    loop {
        // The convergence measure uses the best Hessian model at hand: the latest factorized
        // Hessian (Newton; L-BFGS after a refresh), else the rest matrix S.
        let sw = Stopwatch::start();
        let delta = match (opts.hessian, state.base.as_ref(), state.structured.as_ref()) {
            (HessianStrategy::Fixed, _, _) => ctx.rest.solve(&grad),
            (HessianStrategy::Newton, _, Some(s)) => s.solve(&grad),
            (_, Some(base), _) => solve_with(base, &grad),
            (_, None, _) => ctx.rest.solve(&grad),
        };
        rep.solve_s += sw.elapsed();
        rep.residual = (ctx.measure)(&delta);
        if !rep.residual.is_finite() {
            rep.residual = f64::INFINITY;
            break;
        }
        if rep.residual <= opts.tol && rep.iterations > 0 && judged(measured_with) {
            rep.converged = true;
            break;
        }
        if rep.iterations == opts.max_iter {
            break;
        }
        rep.iterations += 1;
        if opts.hessian == HessianStrategy::Lbfgs
            && opts.refresh_iterations > 0
            && rep.iterations % opts.refresh_iterations == 0
        {
            // Slow progress: the base matrix is too far from the current Hessian (large
            // rotations, contact). Rebuild it here; later steps keep using it.
            let mut factor = refreshed_base(
                pot,
                z,
                opts.refresh_stride,
                opts.refresh_precision,
                &mut rep,
            );
            if factor.is_none() && opts.refresh_precision == Precision::Single {
                // Single-precision rounding can break positive definiteness of a badly
                // conditioned system: rebuild in double before giving up.
                factor = refreshed_base(pot, z, opts.refresh_stride, Precision::Double, &mut rep);
            }
            let sw = Stopwatch::start();
            match factor {
                Some(f) => state.base = Some(f),
                None => rep.cholesky_fallbacks += 1,
            }
            state.pairs.clear();
            rep.solve_s += sw.elapsed();
        }
        let hist = &mut state.pairs;
        // Search direction.
        let mut dir: Vec<f64> = match opts.hessian {
            HessianStrategy::Fixed => delta.iter().map(|v| -v).collect(),
            HessianStrategy::Lbfgs => {
                let sw = Stopwatch::start();
                let mut q = grad.clone();
                let mut alpha = Vec::with_capacity(hist.len());
                for (s, y, rho) in hist.iter().rev() {
                    let a = rho * dot(s, &q);
                    q.iter_mut().zip(y).for_each(|(qi, yi)| *qi -= a * yi);
                    alpha.push(a);
                }
                let mut r = match state.base.as_ref() {
                    Some(base) => solve_with(base, &q),
                    None => ctx.rest.solve(&q),
                };
                for ((s, y, rho), a) in hist.iter().zip(alpha.iter().rev()) {
                    let b = rho * dot(y, &r);
                    r.iter_mut().zip(s).for_each(|(ri, si)| *ri += (a - b) * si);
                }
                rep.solve_s += sw.elapsed();
                r.iter().map(|v| -v).collect()
            }
            HessianStrategy::Newton => {
                let sw = Stopwatch::start();
                let system = pot.newton_system(z, &grad, curvature);
                if !matches!(system, NewtonSystem::Indefinite) {
                    measured_with = curvature;
                }
                if curvature == Curvature::Majorizer && has_friction {
                    rep.majorized_models += 1;
                }
                let d = match system {
                    NewtonSystem::Dense => newton_direction(
                        pot,
                        z,
                        &grad,
                        &delta,
                        curvature,
                        &mut state.base,
                        &mut rep,
                    ),
                    NewtonSystem::Solved {
                        solver,
                        direction,
                        projected,
                    } => {
                        // The potential built, factorized and solved in one call.
                        rep.hessian_s += sw.elapsed();
                        rep.factorizations += 1;
                        rep.projected_fallbacks += usize::from(projected);
                        state.structured = Some(solver);
                        direction
                    }
                    NewtonSystem::Indefinite => {
                        rep.hessian_s += sw.elapsed();
                        rep.factorizations += 1;
                        rep.cholesky_fallbacks += 1;
                        delta.clone()
                    }
                };
                d.iter().map(|v| -v).collect()
            }
        };
        let mut slope = dot(&grad, &dir);
        if slope.is_nan() || slope >= 0.0 {
            // Not a descent direction (cannot happen with positive curvature pairs; guard
            // against rounding): fall back to the rest-preconditioned gradient.
            hist.clear();
            dir = delta.iter().map(|v| -v).collect();
            slope = dot(&grad, &dir);
        }
        // Backtracking line search (Armijo, c = 1e-4). Near convergence the decrease can be
        // below the rounding noise of E (E sums terms of much larger size); then a trial is
        // accepted when E did not grow beyond that noise and the directional derivative
        // shrank (the step moved toward the minimum along the direction).
        let noise = 1e-11 * e.abs() + info.rounding;
        let bound = pot.max_step(z, &dir);
        let mut alpha = if bound < 1.0 {
            rep.bounded_steps += 1;
            bound.max(0.0)
        } else {
            1.0
        };
        let first_alpha = alpha;
        let mut accepted = None;
        for _ in 0..40 {
            for i in 0..n {
                trial[i] = z[i] + alpha * dir[i];
            }
            let sw = Stopwatch::start();
            let (et, it) = pot.energy_gradient(&trial, &mut tgrad);
            rep.gradient_s += sw.elapsed();
            rep.evaluations += 1;
            let armijo = et <= e + 1e-4 * alpha * slope;
            let flat = et <= e + noise && dot(&tgrad, &dir).abs() <= -slope;
            if et.is_finite() && (armijo || flat) {
                accepted = Some((et, it, armijo));
                break;
            }
            rep.line_search_cutbacks += 1;
            alpha *= 0.5;
        }
        let Some((et, it, armijo)) = accepted else {
            if opts.hessian == HessianStrategy::Lbfgs && !hist.is_empty() {
                // Start the quasi-Newton model afresh before giving up.
                hist.clear();
                continue;
            }
            if rep.residual <= opts.tol {
                // The forced first iteration found nothing to improve: the initial guess was
                // already the minimiser to within rounding.
                rep.converged = true;
            } else {
                rep.line_search_failed = true;
            }
            break;
        };
        // Curvature pair for L-BFGS.
        if opts.hessian == HessianStrategy::Lbfgs {
            let s: Vec<f64> = dir.iter().map(|d| alpha * d).collect();
            let y: Vec<f64> = tgrad.iter().zip(&grad).map(|(a, b)| a - b).collect();
            let sy = dot(&s, &y);
            if sy > 1e-12 * dot(&y, &y).sqrt() * dot(&s, &s).sqrt() {
                hist.push_back((s, y, 1.0 / sy));
                if hist.len() > opts.lbfgs_history {
                    hist.pop_front();
                }
            }
        }
        if opts.hessian == HessianStrategy::Newton {
            curvature = if armijo && alpha < first_alpha {
                Curvature::Majorizer
            } else {
                Curvature::Exact
            };
        }
        z.copy_from_slice(&trial);
        std::mem::swap(&mut grad, &mut tgrad);
        rep.max_energy_rise = rep.max_energy_rise.max(et - e);
        e = et;
        info = it;
    }
    rep.energy = e;
    rep.info = info;
    if !e.is_finite() {
        // A state whose energy is NaN or infinite is no minimum, whatever the residual says
        // (a NaN boundary target leaves the gradient finite and the state frozen).
        rep.converged = false;
    }
    rep
}

// The simulator fills the report's monitors (the report module imports no stage).
impl crate::report::Monitors {
    /// Count one simulated time step's solver report into the simulation monitors (they
    /// become `Some` at the first step).
    pub fn add_step(&mut self, s: &SolveReport) {
        fn bump(field: &mut Option<usize>, by: usize) {
            *field = Some(field.unwrap_or(0) + by);
        }
        bump(&mut self.steps, 1);
        bump(
            &mut self.newton_nonconverged_steps,
            usize::from(!s.converged),
        );
        bump(&mut self.newton_cholesky_fallbacks, s.cholesky_fallbacks);
        bump(
            &mut self.line_search_failures,
            usize::from(s.line_search_failed),
        );
        bump(&mut self.line_search_cutbacks, s.line_search_cutbacks);
        self.min_det = Some(
            self.min_det
                .map_or(s.info.min_det, |d| d.min(s.info.min_det)),
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// E = 1/2 z^T A z - b^T z with A = diag(2, 5); its single-precision base Hessian is
    /// deliberately indefinite, the double one exact.
    struct Quadratic;

    const A: [f64; 2] = [2.0, 5.0];
    const B: [f64; 2] = [1.0, -3.0];

    impl Potential for Quadratic {
        fn energy_gradient(&self, z: &[f64], grad: &mut [f64]) -> (f64, EvalInfo) {
            let mut e = 0.0;
            for i in 0..2 {
                grad[i] = A[i] * z[i] - B[i];
                e += 0.5 * A[i] * z[i] * z[i] - B[i] * z[i];
            }
            (e, EvalInfo::default())
        }
        fn hessian(&self, _z: &[f64], _friction: Curvature) -> Mat<f64> {
            Mat::from_fn(2, 2, |i, j| if i == j { A[i] } else { 0.0 })
        }
        fn base_hessian(&self, z: &[f64], _stride: usize, precision: Precision) -> Mat<f64> {
            match precision {
                Precision::Single => Mat::from_fn(2, 2, |i, j| if i == j { -1.0 } else { 0.0 }),
                Precision::Double => self.hessian(z, Curvature::Exact),
            }
        }
    }

    #[test]
    fn a_single_precision_base_that_fails_to_factorize_is_rebuilt_in_double() {
        let rest = Mat::<f64>::identity(2, 2).llt(Side::Lower).unwrap();
        let measure = |d: &[f64]| d.iter().map(|v| v.abs()).fold(0.0, f64::max);
        let options = NewtonOptions {
            refresh_iterations: 1,
            ..NewtonOptions::default()
        };
        assert_eq!(options.refresh_precision, Precision::Single);
        let ctx = SolverContext {
            rest: &rest,
            measure: &measure,
            options: &options,
        };
        let mut z = vec![0.0; 2];
        let rep = minimize(&Quadratic, &mut z, &ctx, &mut QuasiNewtonState::default());
        // The first refresh factorizes twice (single fails, double succeeds), and no step
        // falls back to the rest matrix.
        assert!(rep.converged);
        assert_eq!(rep.cholesky_fallbacks, 0);
        assert_eq!(rep.factorizations, 2 * rep.iterations);
        // With the exact Hessian as base, L-BFGS takes the Newton step: z = A^-1 b.
        for i in 0..2 {
            assert!((z[i] - B[i] / A[i]).abs() < 1e-12, "z = {z:?}");
        }
    }

    /// E = NaN everywhere with the quadratic's finite gradient: what a NaN boundary target
    /// once gave a step (finite residual, energy NaN, no line-search step accepted).
    struct NanEnergy;

    impl Potential for NanEnergy {
        fn energy_gradient(&self, z: &[f64], grad: &mut [f64]) -> (f64, EvalInfo) {
            let (_, info) = Quadratic.energy_gradient(z, grad);
            (f64::NAN, info)
        }
        fn hessian(&self, z: &[f64], friction: Curvature) -> Mat<f64> {
            Quadratic.hessian(z, friction)
        }
    }

    #[test]
    fn a_state_whose_energy_is_not_finite_is_never_converged() {
        let rest = Mat::<f64>::identity(2, 2).llt(Side::Lower).unwrap();
        let measure = |d: &[f64]| d.iter().map(|v| v.abs()).fold(0.0, f64::max);
        // Start at the quadratic's minimiser, where the residual is 0 (at most rounding).
        let options = NewtonOptions::default();
        let ctx = SolverContext {
            rest: &rest,
            measure: &measure,
            options: &options,
        };
        let mut z: Vec<f64> = (0..2).map(|i| B[i] / A[i]).collect();
        let rep = minimize(&NanEnergy, &mut z, &ctx, &mut QuasiNewtonState::default());
        assert!(rep.residual <= options.tol, "{rep:?}");
        assert!(!rep.converged, "{rep:?}");
    }

    /// E = z^4 / 4 - z^2 + z / 2 in one unknown: E'' = 3 z^2 - 2 is negative near 0; the
    /// "projected" model 3 z^2 + 1 is positive everywhere and 3 too large, as a clipped
    /// compression mode or a dropped contact curvature makes Newton's model too stiff.
    struct DoubleWell {
        exact: bool,
    }

    impl Potential for DoubleWell {
        fn energy_gradient(&self, z: &[f64], grad: &mut [f64]) -> (f64, EvalInfo) {
            let x = z[0];
            grad[0] = x * x * x - 2.0 * x + 0.5;
            (x.powi(4) / 4.0 - x * x + 0.5 * x, EvalInfo::default())
        }
        fn hessian(&self, z: &[f64], _friction: Curvature) -> Mat<f64> {
            Mat::from_fn(1, 1, |_, _| 3.0 * z[0] * z[0] + 1.0)
        }
        fn exact_hessian(&self, z: &[f64], _friction: Curvature) -> Option<Mat<f64>> {
            self.exact
                .then(|| Mat::from_fn(1, 1, |_, _| 3.0 * z[0] * z[0] - 2.0))
        }
    }

    fn newton_from(z0: f64, exact: bool) -> (f64, SolveReport) {
        let rest = Mat::<f64>::identity(1, 1).llt(Side::Lower).unwrap();
        let measure = |d: &[f64]| d[0].abs();
        let options = NewtonOptions {
            hessian: HessianStrategy::Newton,
            tol: 1e-10,
            ..NewtonOptions::default()
        };
        let ctx = SolverContext {
            rest: &rest,
            measure: &measure,
            options: &options,
        };
        let mut z = vec![z0];
        let rep = minimize(
            &DoubleWell { exact },
            &mut z,
            &ctx,
            &mut QuasiNewtonState::default(),
        );
        (z[0], rep)
    }

    /// E' = 0 on [lo, hi] by bisection (E' changes sign there).
    fn root(mut lo: f64, mut hi: f64) -> f64 {
        let f = |x: f64| x * x * x - 2.0 * x + 0.5;
        for _ in 0..200 {
            let mid = 0.5 * (lo + hi);
            if f(lo) * f(mid) <= 0.0 {
                hi = mid;
            } else {
                lo = mid;
            }
        }
        0.5 * (lo + hi)
    }

    #[test]
    fn newton_takes_the_exact_hessian_where_it_is_positive_definite() {
        let right = root(1.0, 2.0);
        // Where E'' > 0 all the way, the exact model converges quadratically; the
        // three-too-stiff model only linearly (rate 1 - E''/(E''+3) ~ 0.5 at the minimum).
        let (z, exact) = newton_from(2.0, true);
        let (zp, projected) = newton_from(2.0, false);
        assert!(exact.converged && projected.converged);
        assert_eq!(exact.projected_fallbacks, 0);
        // Both to 1e-10 (the tolerance on the step) of the bisected minimiser.
        assert!(
            (z - right).abs() < 1e-9 && (zp - right).abs() < 1e-9,
            "{z} {zp} {right}"
        );
        assert!(exact.iterations <= 6, "{exact:?}");
        assert!(
            projected.iterations >= 2 * exact.iterations,
            "{projected:?}"
        );
        // From inside the concave band the exact Hessian is negative: the projected one is
        // taken there (counted), and Newton still ends at a minimiser (E' = 0, E'' > 0).
        let (z, rep) = newton_from(0.1, true);
        assert!(rep.converged, "{rep:?}");
        assert!(rep.projected_fallbacks >= 1, "{rep:?}");
        assert_eq!(rep.cholesky_fallbacks, 0);
        let left = root(-2.0, -1.0);
        assert!((z - left).abs() < 1e-9 || (z - right).abs() < 1e-9, "{z}");
    }

    /// E = k/2 |z - a|^2 + D(P z): a unit mass on a spring, with one lagged friction contact
    /// of normal e_z whose tangential slip is z's first two coordinates. The spring's pull
    /// k |a_t| is below mu lambda, so the minimiser sticks (|s| < eps); from a start that
    /// slides the other way the exact model jumps across the kink at s = 0 to the far side
    /// and back.
    struct StickingSpring {
        asked: std::cell::RefCell<Vec<Curvature>>,
    }

    const K: f64 = 1.0;
    const MU_LAMBDA: f64 = 1.0;
    const EPS: f64 = 1e-3;
    const TARGET: [f64; 3] = [0.1, 0.05, -0.2];

    fn tangent() -> crate::linalg3::Mat3 {
        crate::sim::friction::tangent_projector(&[0.0, 0.0, 1.0])
    }

    impl Potential for StickingSpring {
        fn energy_gradient(&self, z: &[f64], grad: &mut [f64]) -> (f64, EvalInfo) {
            use crate::sim::friction::{gradient, potential, project};
            let p = tangent();
            let d = [z[0], z[1], z[2]];
            let g = gradient(MU_LAMBDA, EPS, &p, &d);
            let mut e = potential(MU_LAMBDA, EPS, &project(&p, &d));
            for k in 0..3 {
                grad[k] = K * (z[k] - TARGET[k]) + g[k];
                e += 0.5 * K * (z[k] - TARGET[k]).powi(2);
            }
            (e, EvalInfo::default())
        }
        fn hessian(&self, z: &[f64], friction: Curvature) -> Mat<f64> {
            self.asked.borrow_mut().push(friction);
            let h = crate::sim::friction::model_hessian(
                friction,
                MU_LAMBDA,
                EPS,
                &tangent(),
                &[z[0], z[1], z[2]],
            );
            Mat::from_fn(3, 3, |r, c| h[r][c] + if r == c { K } else { 0.0 })
        }
        fn exact_hessian(&self, z: &[f64], friction: Curvature) -> Option<Mat<f64>> {
            Some(self.hessian(z, friction))
        }
        fn has_friction(&self) -> bool {
            true
        }
    }

    fn sticking_spring() -> (Vec<f64>, SolveReport, Vec<Curvature>) {
        let rest = Mat::<f64>::identity(3, 3).llt(Side::Lower).unwrap();
        let measure = |d: &[f64]| d.iter().map(|v| v.abs()).fold(0.0, f64::max);
        let options = NewtonOptions {
            hessian: HessianStrategy::Newton,
            tol: 1e-10,
            max_iter: 200,
            ..NewtonOptions::default()
        };
        let ctx = SolverContext {
            rest: &rest,
            measure: &measure,
            options: &options,
        };
        let pot = StickingSpring {
            asked: Default::default(),
        };
        let mut z = vec![-2.0, -1.0, 0.3];
        let rep = minimize(&pot, &mut z, &ctx, &mut QuasiNewtonState::default());
        (z, rep, pot.asked.into_inner())
    }

    #[test]
    fn newton_takes_the_friction_majorizer_after_a_cut_back_and_converges_on_an_exact_model() {
        // The minimiser: z_n = a_n; z_t = a_t y / |a_t| with y < eps solving
        // y (k + mu lambda (2/eps - y/eps^2)) = k |a_t| (bisection).
        let at = TARGET[0].hypot(TARGET[1]);
        let f = |y: f64| y * (K + MU_LAMBDA * (2.0 / EPS - y / (EPS * EPS))) - K * at;
        let (mut lo, mut hi) = (0.0, EPS);
        for _ in 0..200 {
            let mid = 0.5 * (lo + hi);
            if f(mid) > 0.0 {
                hi = mid;
            } else {
                lo = mid;
            }
        }
        let y = 0.5 * (lo + hi);
        let best = [TARGET[0] * y / at, TARGET[1] * y / at, TARGET[2]];
        let (z, rep, asked) = sticking_spring();
        assert!(rep.converged, "{rep:?}");
        // The tolerance 1e-10 bounds the last Newton step; the error after it is smaller.
        for k in 0..3 {
            assert!((z[k] - best[k]).abs() < 1e-9, "{z:?} {best:?}");
        }
        // The majorizer was taken after a cut-back line search, and convergence judged on
        // an exact model's step (the last one built).
        assert!(asked.contains(&Curvature::Majorizer), "{asked:?}");
        let majorized = asked.iter().filter(|c| **c == Curvature::Majorizer).count();
        assert_eq!(rep.majorized_models, majorized, "{rep:?}");
        assert_eq!(asked.last(), Some(&Curvature::Exact), "{asked:?}");
    }
}
