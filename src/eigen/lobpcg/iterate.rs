//! The LOBPCG iteration proper (Knyazev 2001 with the robustness measures of Duersch, Shao,
//! Yang & Gu 2018), in the M-orthogonal complement of the constant mode.
//!
//! Storage: S = [X | P | W] in one row-major K x 3nx block (X: nx columns, P: np <= nx,
//! W: nw <= nx), with H S and M S alongside. One iteration:
//! 1. residuals R = H X - M X Theta, relative norms, soft locking (converged columns get no W);
//! 2. W = T R_active, constant mode removed, M W computed, W made M-orthonormal and
//!    M-orthogonal to [X | P] (SVQB with drop tolerances), H W computed;
//! 3. Rayleigh-Ritz on [X | P | W] (restart without P if its M-Gram matrix is
//!    ill-conditioned);
//! 4. X, P <- S C_X, S C_P (and H S, M S alike); every `recompute_every` iterations H X, M X,
//!    H P, M P are recomputed from scratch.
//!
//! Convergence is declared only after an explicit check: H X and M X recomputed, Rayleigh-Ritz
//! on X alone, residuals recomputed; otherwise the iteration continues.

use super::operators::{Operators, Which};
use super::options::LobpcgOptions;
use super::orthogonalize::{ortho_against_basis, project_constant, svqb, Small};
use super::precondition::Preconditioner;
use super::rayleigh_ritz::{next_p, solve_projected, Projected, RrScratch};
use super::workspace::{inner, transform, Block, ROW_CHUNK};
use crate::eigen::{relative_residual, EigenError, SplitMix64};
use crate::progress::Progress;
use faer::Mat;
use rayon::prelude::*;
use std::fmt::Write as _;
use std::time::Instant;

/// How the iteration ended.
#[derive(Debug)]
pub(super) enum Stop {
    /// All wanted pairs passed the explicit check.
    Converged,
    /// Iteration cap reached.
    MaxIter,
    /// No new search direction could be added and the pairs are not converged.
    Stagnated,
    /// The caller's progress receiver asked to stop.
    Cancelled,
    /// M is not positive definite on the search space (x^T M x <= 0 found).
    Indefinite(String),
    /// A breakdown (small eigensolver failure, non-finite values).
    Breakdown(String),
    /// A caller's operator or preconditioner failed (error, wrong shape, non-finite output).
    Operator(EigenError),
}

/// Counters filled during the run.
#[derive(Debug, Default)]
pub(super) struct Counters {
    pub iterations: usize,
    pub restarts: usize,
    pub matvecs: usize,
    pub explicit_checks: usize,
    /// Wall-clock seconds in the preconditioner, the sparse products, the orthogonalization
    /// and the Rayleigh-Ritz step with the block update (Gram matrices, small eigenproblems,
    /// S C products).
    pub seconds_precondition: f64,
    pub seconds_spmm: f64,
    pub seconds_ortho: f64,
    pub seconds_rayleigh_ritz: f64,
}

/// The whole state of one run; allocated once.
pub(super) struct State<'a> {
    ops: Operators<'a>,
    k: usize,
    /// Wanted non-constant pairs.
    nwant: usize,
    /// Block size (wanted + guard).
    nx: usize,
    /// Current P width.
    np: usize,
    s: Block,
    hs: Block,
    ms: Block,
    tmp: Block,
    y0: Block,
    my0: Block,
    gram_h: Mat<f64>,
    gram_m: Mat<f64>,
    coef: Mat<f64>,
    small: Small,
    rr: RrScratch,
    /// Current Ritz values (nx).
    pub theta: Vec<f64>,
    /// Current relative residuals (nx).
    pub residuals: Vec<f64>,
    sq_partial: Vec<f64>,
    active: Vec<usize>,
    idx: Vec<usize>,
    message: String,
    pub counters: Counters,
}

impl<'a> State<'a> {
    /// Allocate everything for a run with block size `nx` on K x K operators.
    ///
    /// # Errors
    /// The operator M failing on the constant mode.
    pub fn new(
        ops: Operators<'a>,
        y0: &[f64],
        nwant: usize,
        nx: usize,
    ) -> Result<Self, EigenError> {
        let k = ops.dim();
        let ld = 3 * nx;
        let y0b = Block {
            data: y0.to_vec(),
            rows: k,
            ld: 1,
        };
        let mut my0 = Block::new(k, 1);
        ops.apply(Which::M, &y0b, &mut my0, 0, 1)?;
        let nchunks = k.div_ceil(ROW_CHUNK);
        Ok(Self {
            ops,
            k,
            nwant,
            nx,
            np: 0,
            s: Block::new(k, ld),
            hs: Block::new(k, ld),
            ms: Block::new(k, ld),
            tmp: Block::new(k, nx),
            y0: y0b,
            my0,
            gram_h: Mat::zeros(ld, ld),
            gram_m: Mat::zeros(ld, ld),
            coef: Mat::zeros(ld, ld),
            small: Small::new(k, ld),
            rr: RrScratch::new(ld),
            theta: vec![0.0; nx],
            residuals: vec![f64::INFINITY; nx],
            sq_partial: vec![0.0; nchunks * 2 * nx],
            active: Vec::with_capacity(nx),
            idx: Vec::with_capacity(ld),
            message: String::with_capacity(128),
            counters: Counters::default(),
        })
    }

    fn spmm(&mut self, which: Which, c0: usize, w: usize) -> Result<(), Stop> {
        if w == 0 {
            return Ok(());
        }
        let t0 = Instant::now();
        let out = match which {
            Which::H => &mut self.hs,
            Which::M => &mut self.ms,
        };
        self.ops
            .apply(which, &self.s, out, c0, w)
            .map_err(Stop::Operator)?;
        self.counters.matvecs += w;
        self.counters.seconds_spmm += t0.elapsed().as_secs_f64();
        Ok(())
    }

    /// H S and M S for the columns `c0..c0 + w`, in one pass when the patterns agree.
    fn spmm_both(&mut self, c0: usize, w: usize) -> Result<(), Stop> {
        if w == 0 {
            return Ok(());
        }
        let t0 = Instant::now();
        self.ops
            .apply_both(&self.s, &mut self.hs, &mut self.ms, c0, w)
            .map_err(Stop::Operator)?;
        self.counters.matvecs += 2 * w;
        self.counters.seconds_spmm += t0.elapsed().as_secs_f64();
        Ok(())
    }

    /// Random start block (fixed seed), constant mode removed, M-orthonormalized, Rayleigh-Ritz.
    pub fn start(&mut self, seed: u64, opts: &LobpcgOptions) -> Result<(), Stop> {
        let (k, nx, ld) = (self.k, self.nx, self.s.ld);
        let mut rng = SplitMix64::new(seed);
        for i in 0..k {
            for j in 0..nx {
                self.s.data[i * ld + j] = 2.0 * rng.next_f64() - 1.0;
            }
        }
        project_constant(&mut self.s, 0, nx, &self.y0, &self.my0, &mut self.small);
        self.spmm_both(0, nx)?;
        let r = svqb(
            &mut self.s,
            &mut self.ms,
            Some(&mut self.hs),
            0,
            nx,
            0.0,
            opts.svqb_drop,
            &mut self.small,
        );
        if let Some(v) = self.small.indefinite.take() {
            return Err(indefinite_block(v));
        }
        if r < nx {
            return Err(Stop::Breakdown(format!(
                "random start block has rank {r} < {nx}"
            )));
        }
        self.np = 0;
        self.rayleigh_ritz_x(opts)
    }

    /// Recompute H X, M X explicitly (after removing the constant mode) and Rayleigh-Ritz on X
    /// alone. P is left as is (still M-orthogonal to the unchanged span of X).
    fn rayleigh_ritz_x(&mut self, opts: &LobpcgOptions) -> Result<(), Stop> {
        let nx = self.nx;
        self.gram(nx);
        self.idx.clear();
        self.idx.extend(0..nx);
        match solve_projected(
            &self.gram_h,
            &self.gram_m,
            &self.idx,
            opts.svqb_drop,
            &mut self.small,
            &mut self.rr,
        ) {
            Projected::Ok { rank, .. } if rank == nx => {}
            Projected::Ok { rank, .. } => {
                return Err(Stop::Breakdown(format!("X lost rank ({rank} < {nx})")))
            }
            Projected::Indefinite { g_min, g_max } => return Err(indefinite(g_min, g_max)),
            Projected::Failed => {
                return Err(Stop::Breakdown("small eigensolver failed on X".into()))
            }
        }
        self.theta.copy_from_slice(&self.rr.theta[..nx]);
        let c = self.rr.ritz.as_ref().submatrix(0, 0, nx, nx);
        for blk in [&mut self.s, &mut self.hs, &mut self.ms] {
            transform(blk, 0, c, 0);
        }
        Ok(())
    }

    /// Gram matrices of the first n columns of S: gram_h = S^T H S, gram_m = S^T M S.
    fn gram(&mut self, n: usize) {
        // Lower triangles only (half the flops of a full product), then mirrored.
        for (g, other) in [(&mut self.gram_h, &self.hs), (&mut self.gram_m, &self.ms)] {
            inner(
                g.as_mut().submatrix_mut(0, 0, n, n),
                &self.s,
                0,
                other,
                0,
                &mut self.small.parts,
                true,
            );
            for j in 0..n {
                for i in j + 1..n {
                    g[(j, i)] = g[(i, j)];
                }
            }
        }
    }

    /// Relative residuals of the current X into `self.residuals` (row chunks summed in order).
    fn residual_norms(&mut self) {
        let (nx, ld, k) = (self.nx, self.s.ld, self.k);
        let theta = &self.theta;
        let (s, hs, ms) = (&self.s.data, &self.hs.data, &self.ms.data);
        self.sq_partial
            .par_chunks_mut(2 * nx)
            .enumerate()
            .for_each(|(c, part)| {
                part.fill(0.0);
                let (r0, r1) = (c * ROW_CHUNK, ((c + 1) * ROW_CHUNK).min(k));
                for i in r0..r1 {
                    let (xs, hx, mx) = (
                        &s[i * ld..i * ld + nx],
                        &hs[i * ld..i * ld + nx],
                        &ms[i * ld..i * ld + nx],
                    );
                    for j in 0..nx {
                        let r = hx[j] - theta[j] * mx[j];
                        part[j] += r * r;
                        part[nx + j] += xs[j] * xs[j];
                    }
                }
            });
        for j in 0..nx {
            let (mut rr, mut xx) = (0.0, 0.0);
            for part in self.sq_partial.chunks(2 * nx) {
                rr += part[j];
                xx += part[nx + j];
            }
            self.residuals[j] = relative_residual(
                rr.sqrt(),
                self.theta[j],
                self.ops.norm_h,
                self.ops.norm_m,
                xx.sqrt(),
            );
        }
    }

    /// Explicit check: H X, M X recomputed, Rayleigh-Ritz on X, residuals recomputed.
    fn explicit_refresh(&mut self, opts: &LobpcgOptions) -> Result<(), Stop> {
        let nb = self.nx + self.np;
        project_constant(&mut self.s, 0, nb, &self.y0, &self.my0, &mut self.small);
        self.spmm_both(0, nb)?;
        self.rayleigh_ritz_x(opts)?;
        self.residual_norms();
        Ok(())
    }

    /// Run the iteration until convergence, the cap, or a failure.
    pub fn run(
        &mut self,
        tol: f64,
        max_iter: usize,
        opts: &LobpcgOptions,
        pre: &mut Preconditioner<'_>,
        progress: &dyn Progress,
    ) -> Stop {
        let (nx, nwant) = (self.nx, self.nwant);
        self.residual_norms();
        let mut since_refresh = 0usize;
        loop {
            let converged = self.residuals[..nwant]
                .iter()
                .filter(|&&r| r <= tol)
                .count();
            if converged == nwant {
                // Confirm on explicitly recomputed products before stopping.
                self.counters.explicit_checks += 1;
                if let Err(stop) = self.explicit_refresh(opts) {
                    return stop;
                }
                since_refresh = 0;
                if self.residuals[..nwant].iter().all(|&r| r <= tol) {
                    return Stop::Converged;
                }
            }
            if self.counters.iterations >= max_iter {
                return Stop::MaxIter;
            }
            if progress.cancelled() {
                return Stop::Cancelled;
            }
            self.counters.iterations += 1;
            let it = self.counters.iterations;

            // 1. Soft locking: active = columns above the tolerance (guards included).
            self.active.clear();
            self.active
                .extend((0..nx).filter(|&j| self.residuals[j].is_nan() || self.residuals[j] > tol));
            let w0 = nx + self.np;
            let mut nw = self.active.len();
            // 2. W = T R_active.
            {
                let ld = self.s.ld;
                let theta = &self.theta;
                let active = &self.active;
                self.s
                    .data
                    .par_chunks_mut(ld * ROW_CHUNK)
                    .zip(self.hs.data.par_chunks(ld * ROW_CHUNK))
                    .zip(self.ms.data.par_chunks(ld * ROW_CHUNK))
                    .for_each(|((s, hs), ms)| {
                        for ((srow, hrow), mrow) in
                            s.chunks_mut(ld).zip(hs.chunks(ld)).zip(ms.chunks(ld))
                        {
                            for (q, &j) in active.iter().enumerate() {
                                srow[w0 + q] = hrow[j] - theta[j] * mrow[j];
                            }
                        }
                    });
            }
            let t0 = Instant::now();
            if let Err(e) = pre.apply(&mut self.s, w0, nw, &mut self.tmp) {
                return Stop::Operator(e);
            }
            self.counters.seconds_precondition += t0.elapsed().as_secs_f64();
            project_constant(&mut self.s, w0, nw, &self.y0, &self.my0, &mut self.small);
            if let Err(stop) = self.spmm(Which::M, w0, nw) {
                return stop;
            }
            let t0 = Instant::now();
            nw = ortho_against_basis(
                &mut self.s,
                &mut self.ms,
                w0,
                w0,
                nw,
                opts.ortho_drop,
                opts.svqb_drop,
                3,
                &mut self.small,
            );
            if let Some(v) = self.small.indefinite.take() {
                return indefinite_block(v);
            }
            if nw == 0 {
                // Nothing new to add: verify explicitly; if still not converged, stop.
                if let Err(stop) = self.explicit_refresh(opts) {
                    return stop;
                }
                if self.residuals[..nwant].iter().all(|&r| r <= tol) {
                    return Stop::Converged;
                }
                return Stop::Stagnated;
            }
            self.counters.seconds_ortho += t0.elapsed().as_secs_f64();
            if let Err(stop) = self.spmm(Which::H, w0, nw) {
                return stop;
            }
            let t0 = Instant::now();

            // 3. Rayleigh-Ritz on [X | P | W].
            let ns = w0 + nw;
            self.gram(ns);
            self.idx.clear();
            self.idx.extend(0..ns);
            let mut outcome = solve_projected(
                &self.gram_h,
                &self.gram_m,
                &self.idx,
                opts.svqb_drop,
                &mut self.small,
                &mut self.rr,
            );
            let ill = match outcome {
                Projected::Ok { rank, g_ratio } => rank < nx || g_ratio < opts.restart_tol,
                _ => true,
            };
            if self.np > 0 && ill {
                // Restart: drop P from the basis.
                self.counters.restarts += 1;
                self.idx.clear();
                self.idx.extend((0..nx).chain(w0..ns));
                outcome = solve_projected(
                    &self.gram_h,
                    &self.gram_m,
                    &self.idx,
                    opts.svqb_drop,
                    &mut self.small,
                    &mut self.rr,
                );
            }
            let rank = match outcome {
                Projected::Ok { rank, .. } if rank >= nx => rank,
                Projected::Ok { rank, .. } => {
                    return Stop::Breakdown(format!(
                        "Rayleigh-Ritz basis rank {rank} < block size {nx}"
                    ))
                }
                Projected::Indefinite { g_min, g_max } => return indefinite(g_min, g_max),
                Projected::Failed => {
                    return Stop::Breakdown("small eigensolver failed in Rayleigh-Ritz".into())
                }
            };
            // 4. New P from the active columns, then X, P <- S [C_X C_P].
            let np_new = next_p(
                &self.gram_m,
                &self.idx,
                rank,
                nx,
                &self.active,
                opts.svqb_drop,
                &mut self.small,
                &mut self.rr,
            );
            let nout = nx + np_new;
            self.coef.as_mut().submatrix_mut(0, 0, ns, nout).fill(0.0);
            for (p, &row) in self.idx.iter().enumerate() {
                for j in 0..nx {
                    self.coef[(row, j)] = self.rr.ritz[(p, j)];
                }
                for j in 0..np_new {
                    self.coef[(row, nx + j)] = self.rr.cp[(p, j)];
                }
            }
            let c = self.coef.as_ref().submatrix(0, 0, ns, nout);
            for blk in [&mut self.s, &mut self.hs, &mut self.ms] {
                transform(blk, 0, c, 0);
            }
            self.np = np_new;
            self.theta.copy_from_slice(&self.rr.theta[..nx]);
            self.counters.seconds_rayleigh_ritz += t0.elapsed().as_secs_f64();

            since_refresh += 1;
            if since_refresh >= opts.recompute_every {
                since_refresh = 0;
                let nb = nx + self.np;
                project_constant(&mut self.s, 0, nb, &self.y0, &self.my0, &mut self.small);
                if let Err(stop) = self.spmm_both(0, nb) {
                    return stop;
                }
            }
            self.residual_norms();
            if !self
                .theta
                .iter()
                .chain(&self.residuals)
                .all(|v| !v.is_nan())
            {
                return Stop::Breakdown(format!(
                    "NaN in Ritz values or residuals at iteration {it}"
                ));
            }
            let converged = self.residuals[..nwant]
                .iter()
                .filter(|&&r| r <= tol)
                .count();
            let max_res = self.residuals[..nwant].iter().copied().fold(0.0, f64::max);
            self.message.clear();
            let _ = write!(
                self.message,
                "iter {it}, {converged}/{nwant} converged, max residual {max_res:.2e}"
            );
            progress.set_position(it as u64);
            progress.message(&self.message);
        }
    }

    /// `y0` (the constant mode, K) followed by the first `nwant` Ritz vectors, as a
    /// K x (nwant + 1) column-major matrix.
    pub fn vectors_with_constant(&self, y0: &[f64]) -> Mat<f64> {
        let ld = self.s.ld;
        Mat::from_fn(self.k, self.nwant + 1, |i, j| match j {
            0 => y0[i],
            _ => self.s.data[i * ld + j - 1],
        })
    }

    /// Current width of X plus P (for the final report).
    pub fn p_width(&self) -> usize {
        self.np
    }

    /// Refresh explicitly (used to build a consistent partial result).
    pub fn finalize(&mut self, opts: &LobpcgOptions) -> Result<(), Stop> {
        self.explicit_refresh(opts)
    }
}

fn indefinite_block(relative: f64) -> Stop {
    Stop::Indefinite(format!(
        "a block of the search space has an M-Gram eigenvalue or diagonal entry {relative:.3e} times the largest: \
         x^T M x < 0 for some x"
    ))
}

fn indefinite(g_min: f64, g_max: f64) -> Stop {
    Stop::Indefinite(format!(
        "the M-Gram matrix of the search space has eigenvalue {g_min:.3e} (largest {g_max:.3e}): x^T M x <= 0 for some x"
    ))
}
