//! One SLEPc solve on assembled PETSc matrices, shared by the SLEPc paths (feature `slepc`):
//! the preset's configuration, the caller's PETSc options on top, `EPSSolve`, and what a
//! failure means for the user.

use super::lobpcg::LobpcgOptions;
use super::slepc_status::{backend, option_names, ScopedOptions, SolveStatus};
use super::{slepc_lobpcg_single_block, EigenError, EigenRequest, SlepcOptions, SlepcPreset};
use crate::options;
use freeform_ffi as petsc;

/// The shift sigma of `options`, or -1e-4 tr(H)/tr(M) from the traces `[tr H, tr M]`.
///
/// # Errors
/// [`EigenError::NonFinite`] when it is not finite.
pub(super) fn shift(options: &SlepcOptions, traces: [f64; 2]) -> Result<f64, EigenError> {
    let sigma = options
        .shift
        .unwrap_or(-1e-4 * traces[0] / traces[1].max(f64::MIN_POSITIVE));
    if !sigma.is_finite() {
        return Err(EigenError::NonFinite(format!(
            "SLEPc shift sigma = {sigma} (tr H = {}, tr M = {})",
            traces[0], traces[1]
        )));
    }
    Ok(sigma)
}

/// A LAPACK failure as SLEPc words it (`SlepcCheckLapackInfo`): "Error in LAPACK subroutine
/// sygvd: info=74" gives `("sygvd", 74)`.
pub(super) fn lapack_failure(message: &str) -> Option<(String, i64)> {
    let rest = message.split("Error in LAPACK subroutine ").nth(1)?;
    let (routine, rest) = rest.split_once(": info=")?;
    let digits: String = rest
        .chars()
        .enumerate()
        .take_while(|&(i, c)| c.is_ascii_digit() || (i == 0 && c == '-'))
        .map(|(_, c)| c)
        .collect();
    let info = digits.parse().ok()?;
    let routine = routine.trim();
    (!routine.is_empty() && !routine.contains(char::is_whitespace))
        .then(|| (routine.to_string(), info))
}

/// What a failed `EPSSolve` means for the user. A LAPACK failure inside SLEPc's LOBPCG
/// (`EPSSolve_LOBPCG` in the call chain; in practice `sygvd` in its Rayleigh-Ritz step, after
/// the basis lost B-orthogonality) becomes [`EigenError::SlepcLobpcgBreakdown`] with the
/// ways out; anything else stays [`EigenError::Backend`] with PETSc's message.
pub(super) fn solve_error(
    e: petsc::PetscError,
    k: usize,
    nev: usize,
    block_size: Option<usize>,
) -> EigenError {
    if e.message.contains("EPSSolve_LOBPCG()") {
        if let Some((routine, info)) = lapack_failure(&e.message) {
            return EigenError::SlepcLobpcgBreakdown {
                routine,
                info,
                k,
                nev,
                block_size,
                message: e.to_string(),
            };
        }
    }
    backend(e)
}

/// A finished `EPSSolve` on (H - sigma M, M): the solver (to read pairs from with
/// [`Solved::eigenpair`]), how it ended, and notes on the configuration used. It holds the
/// shifted H until [`Solved::finish`] (SLEPc may still apply its spectral transformation while
/// it forms the eigenvectors, so H is shifted back only after the last pair is read).
pub(super) struct Solved<'a, 's> {
    eps: petsc::Eps<'s>,
    sigma: f64,
    hm: &'a mut petsc::Mat<'s>,
    mm: &'a petsc::Mat<'s>,
    same_pattern: bool,
    pub(super) status: SolveStatus,
    notes: Vec<String>,
}

impl<'s> Solved<'_, 's> {
    /// Pair `i` of H x = lambda M x: its eigenvalue (SLEPc's one of the shifted pencil plus
    /// sigma) and its vector in `x`. Collective.
    pub(super) fn eigenpair(&self, i: usize, x: &mut petsc::Vector<'s>) -> petsc::Result<f64> {
        Ok(self.eps.eigenpair(i, x)? + self.sigma)
    }

    /// How the run ended and the notes, after freeing SLEPc's solver (its blocks and the
    /// preconditioner's hierarchy) and shifting H back (up to rounding of |sigma| ||M|| times
    /// the machine epsilon). Collective.
    ///
    /// # Errors
    /// PETSc's error from the shift back.
    pub(super) fn finish(self) -> Result<(SolveStatus, Vec<String>), EigenError> {
        drop(self.eps);
        self.hm
            .axpy(self.sigma, self.mm, self.same_pattern)
            .map_err(backend)?;
        Ok((self.status, self.notes))
    }
}

/// Configure an EPS on the assembled pencil (`hm`, `mm`: K x K) with the preset of
/// `options`, then its PETSc options, and solve.
///
/// SLEPc is given the shifted pencil (H - sigma M, M), shifted in place in `hm`
/// (`same_pattern`: H and M share their nonzero pattern, so no memory is allocated), with its
/// own target and shift at 0: the presets' spectral transformations then use H - sigma M as
/// it is instead of building it as a third matrix (the memory of one matrix, docs/slepc.md
/// "Memory per rank"). [`Solved::eigenpair`] adds sigma back; [`Solved::finish`] shifts `hm`
/// back to H (on an error here, `hm` is H again too).
pub(super) fn solve_pencil<'a, 's>(
    session: &'s petsc::Session,
    hm: &'a mut petsc::Mat<'s>,
    mm: &'a petsc::Mat<'s>,
    same_pattern: bool,
    request: &EigenRequest,
    options: &SlepcOptions,
    sigma: f64,
) -> Result<Solved<'a, 's>, EigenError> {
    let k = hm.size().map_err(backend)?.0;
    refuse_lobpcg_too_small(k, request.nev, options)?;
    hm.axpy(-sigma, mm, same_pattern).map_err(backend)?;
    match solve_shifted(session, hm, mm, k, request, options, sigma) {
        Ok((eps, status, notes)) => Ok(Solved {
            eps,
            sigma,
            hm,
            mm,
            same_pattern,
            status,
            notes,
        }),
        Err(e) => {
            hm.axpy(sigma, mm, same_pattern).map_err(backend)?;
            Err(e)
        }
    }
}

/// [`solve_pencil`] on the pencil already shifted: `hm` holds H - sigma M.
fn solve_shifted<'s>(
    session: &'s petsc::Session,
    hm: &petsc::Mat<'s>,
    mm: &petsc::Mat<'s>,
    k: usize,
    request: &EigenRequest,
    options: &SlepcOptions,
    sigma: f64,
) -> Result<(petsc::Eps<'s>, SolveStatus, Vec<String>), EigenError> {
    let world = session.world();
    let mut eps = petsc::Eps::new(session, world).map_err(backend)?;
    configure(&mut eps, hm, mm, request, options).map_err(backend)?;
    // The preset's options, then the user's (later ones win), in the global database for this
    // solve only (until `scoped` is dropped, after the solve).
    let all = format!(
        "{} {}",
        options.preset.petsc_options(),
        options.petsc_options
    );
    let scoped = ScopedOptions::insert(session, all.trim()).map_err(backend)?;
    eps.set_from_options().map_err(backend)?;
    // Options that switch to LOBPCG (e.g. "-eps_type lobpcg" on top of ks-sinvert) would keep
    // the relative test and abort on the zero eigenvalue: use ours unless the user chose one.
    let chosen_type = eps.describe().map_err(backend)?[0].clone();
    if chosen_type == "lobpcg" && !scoped.has_prefix("-eps_conv_") {
        eps.set_convergence_test(petsc::Convergence::Norm)
            .map_err(backend)?;
    }
    let solved = eps.solve();
    drop(scoped);
    // SLEPc sets the LOBPCG block size up inside EPSSolve and reports it after a failed solve
    // too; the error and the status both name it.
    let block_size = if chosen_type == "lobpcg" {
        eps.lobpcg_block_size().ok().filter(|&b| b > 0)
    } else {
        None
    };
    if let Err(e) = solved {
        return Err(solve_error(e, k, request.nev, block_size));
    }
    let converged = eps.converged().map_err(backend)?;
    let status = SolveStatus {
        eps_type: chosen_type,
        iterations: eps.iterations().map_err(backend)?,
        converged,
        reason: eps.converged_reason().map_err(backend)?,
        block_size,
    };
    let [eps_type, st_type, ksp_type, pc_type, package] = eps.describe().map_err(backend)?;
    let ranks = session.size(world).map_err(backend)?;
    let mut notes = vec![
        format!(
            "slepc: eps {eps_type}, st {st_type}, ksp {ksp_type}, pc {pc_type}{}",
            if package.is_empty() {
                String::new()
            } else {
                format!(" ({package})")
            }
        ),
        format!(
            "slepc: pencil (H - sigma M, M), sigma {sigma:.6e}, {ranks} MPI rank(s), \
             {converged} converged"
        ),
    ];
    let preset_options = options.preset.petsc_options();
    if !preset_options.is_empty() {
        notes.push(format!(
            "slepc: preset {} sets {preset_options}",
            options.preset.name()
        ));
    }
    if !options.petsc_options.is_empty() {
        notes.push(format!("slepc: options {}", options.petsc_options));
    }
    Ok((eps, status, notes))
}

/// The preset's settings on a fresh EPS (before the options database is applied), for the
/// shifted pencil (`hm` = H - sigma M): target and shift 0.
pub(super) fn configure<'s>(
    eps: &mut petsc::Eps<'s>,
    hm: &petsc::Mat<'s>,
    mm: &petsc::Mat<'s>,
    request: &EigenRequest,
    options: &SlepcOptions,
) -> petsc::Result<()> {
    eps.set_operators(hm, mm)?;
    eps.set_problem_type(petsc::ProblemType::Ghep)?;
    eps.set_dimensions(request.nev)?;
    eps.set_tolerances(request.tol, request.max_iter)?;
    match options.preset {
        SlepcPreset::KsSinvert => {
            // The Krylov residual lives in the transformed problem (theta = 1 / (lambda -
            // sigma), never 0 here: H - sigma M is positive definite): SLEPc's relative test
            // is the right one there. The EPS_CONV_NORM test would divide that residual by
            // ||H||, of the original problem's scale, and stop after one restart with
            // residuals ~1e-4 (measured).
            eps.set_convergence_test(petsc::Convergence::Relative)?;
            eps.set_type("krylovschur")?;
            eps.set_which(petsc::Which::TargetMagnitude)?;
            eps.set_target(0.0)?;
            eps.set_spectral_transform(
                Some("sinvert"),
                Some("preonly"),
                Some("cholesky"),
                Some("mumps"),
            )?;
        }
        SlepcPreset::LobpcgGamg | SlepcPreset::LobpcgHypre => {
            // Our own residual definition; the relative default divides by |lambda| = 0 for
            // the constant mode and aborts in LAPACK.
            eps.set_convergence_test(petsc::Convergence::Norm)?;
            eps.set_type("lobpcg")?;
            eps.set_which(petsc::Which::SmallestReal)?;
            let pc = if options.preset == SlepcPreset::LobpcgGamg {
                "gamg"
            } else {
                "hypre"
            };
            eps.set_spectral_transform(Some("precond"), Some("preonly"), Some(pc), None)?;
            eps.set_st_shift(0.0)?;
            if let Some(block) = lobpcg_block(request.nev, hm.size()?.0) {
                eps.set_lobpcg_block_size(block)?;
            }
        }
    }
    Ok(())
}

/// The LOBPCG presets on a pencil too small for one block of every pair ([`lobpcg_block`] is
/// None: K < 5 x the block) are refused before SLEPc starts: with several blocks SLEPc's
/// LOBPCG breaks down, stops short or reports false convergence at such sizes, and below
/// 5 x its own block it refuses with a PETSc error (docs/slepc.md). The same on every rank (K,
/// nev and the options are). Options that choose the block size or the solver are the caller's
/// to keep.
fn refuse_lobpcg_too_small(k: usize, nev: usize, options: &SlepcOptions) -> Result<(), EigenError> {
    let lobpcg = matches!(
        options.preset,
        SlepcPreset::LobpcgGamg | SlepcPreset::LobpcgHypre
    );
    let own_choice = option_names(&options.petsc_options)
        .iter()
        .any(|&n| n == "-eps_lobpcg_blocksize" || n == "-eps_type");
    if !lobpcg || own_choice || lobpcg_block(nev, k).is_some() {
        return Ok(());
    }
    let single = slepc_lobpcg_single_block(nev);
    Err(EigenError::InvalidRequest(format!(
        "K = {k} is too small for SLEPc's LOBPCG ({}) to hold all {nev} pairs in one block \
         (it needs K >= 5 x {single} = {}). Use SLEPc's direct configuration {} (fast at this \
         size), freeform's native LOBPCG ({}), or fewer modes",
        options.preset.name(),
        5 * single,
        options::SLEPC.with("ks-sinvert"),
        options::SOLVER.with("lobpcg"),
    )))
}

/// The LOBPCG presets' block size for `nev` pairs of a K x K pencil: one block for all pairs
/// with the native LOBPCG's guard vectors (at least SLEPc's own, [`slepc_lobpcg_single_block`]),
/// so no pair is hard-locked early (SLEPc's default of min(16, nev) breaks down, docs/slepc.md),
/// and at most K / 5, SLEPc's limit. None (SLEPc's default) when K is too small for one block
/// to hold every pair: several blocks of SLEPc's own size then, as before.
pub(super) fn lobpcg_block(nev: usize, k: usize) -> Option<usize> {
    let single = slepc_lobpcg_single_block(nev);
    let native = nev + LobpcgOptions::default().guard_for(nev.saturating_sub(1));
    (k / 5 >= single).then(|| native.max(single).min(k / 5))
}
