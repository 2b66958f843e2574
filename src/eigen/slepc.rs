//! SLEPc backend (feature `slepc`): H_w c = lambda M c solved by SLEPc 3.18 through our own
//! bindings (`freeform-ffi`).
//!
//! The matrices go into PETSc AIJ matrices (MPIAIJ under `mpirun`, each rank holding a block of
//! rows), the problem is a GHEP, and the solver is configured by a [`SlepcPreset`]:
//!
//! - `ks-sinvert`: Krylov-Schur, shift-and-invert at a small negative target
//!   sigma = -1e-4 tr(H)/tr(M) (H - sigma M is then SPD, so a Cholesky factorization applies),
//!   KSP `preonly`, PC `cholesky` with MUMPS.
//! - `lobpcg-gamg` (default) / `lobpcg-hypre`: SLEPc's LOBPCG with ST `precond`, the AMG
//!   preconditioner built on H - sigma M (same sigma: a shift that is too small stalls AMG);
//!   GAMG's levels smoothed by Richardson + SOR ([`SlepcPreset::petsc_options`]), one block for
//!   every pair with the native guard vectors where K allows it.
//!
//! Both are given the shifted pencil (H - sigma M, M) with target and shift 0, and sigma is
//! added back to the eigenvalues (`slepc_pencil.rs`): PETSc then holds two matrices, not a
//! third shifted copy.
//!
//! The LOBPCG presets use SLEPc's `EPS_CONV_NORM` test, ||r|| / ((||H|| + |lambda| ||M||)
//! ||x||), which is freeform's own tolerance definition ([`super::EigenRequest::tol`]); the
//! default relative test divides by |lambda| and aborts LOBPCG on the zero eigenvalue of the
//! constant mode. Shift-and-invert keeps the relative test, applied to the transformed
//! eigenvalue 1 / (lambda - sigma) (never 0); the residuals we recompute in the original
//! problem decide convergence in the end. `EPSSetFromOptions` is always called after the
//! preset, so PETSc options given in [`SlepcOptions::petsc_options`] (or the `PETSC_OPTIONS`
//! environment variable) override any of these choices. Residuals and M-orthonormality are recomputed by
//! [`super::check_solution`], not taken from SLEPc.
//!
//! SLEPc's LOBPCG can lose B-orthogonality when it works through several blocks; LAPACK's
//! `sygvd` then fails in its Rayleigh-Ritz step and the solve ends with
//! [`EigenError::SlepcLobpcgBreakdown`], whose message names the alternatives (docs/slepc.md).
//! When it reports pairs converged that our residual check rejects, or stops at its iteration
//! cap or on a breakdown it detects itself, the solution comes back with the status
//! [`EigenStatus::SlepcLobpcgNotConverged`] ([`convergence_status`]), whose error
//! ([`EigenError::SlepcLobpcgNotConverged`]) says which and names the same alternatives.

use super::{
    check_solution, validate_problem, EigenError, EigenInfo, EigenRequest, EigenSolution,
    Eigensolver, OperatorProblem,
};
use crate::progress::Progress;
use crate::sparse::SparseMatrixRef;
use faer::Mat;
use freeform_ffi as petsc;

use super::slepc_pencil::{shift, solve_pencil};
pub use super::slepc_rows::{solve_distributed, DistributedSolution};
use super::slepc_status::backend;
pub use super::slepc_status::{convergence_status, SolveStatus};
pub use super::{SlepcOptions, SlepcPreset};

/// The SLEPc eigensolver (name "slepc"). Under `mpirun` every rank calls
/// [`Eigensolver::solve`] with the same matrices; each inserts only its block of rows and
/// every rank gets all eigenvectors back.
#[derive(Debug, Clone, Default)]
pub struct SlepcSolver {
    /// Configuration.
    pub options: SlepcOptions,
}

impl SlepcSolver {
    /// A solver with the given configuration.
    pub fn new(options: SlepcOptions) -> Self {
        Self { options }
    }
}

/// `(rank, size)` of `PETSC_COMM_WORLD`, initializing PETSc (and MPI) if needed.
///
/// # Errors
/// [`EigenError::Backend`] if PETSc cannot start.
pub fn world_rank() -> Result<(usize, usize), EigenError> {
    let session = petsc::session().map_err(backend)?;
    let world = session.world();
    Ok((
        session.rank(world).map_err(backend)?,
        session.size(world).map_err(backend)?,
    ))
}

/// Element-wise sum of `values` over all ranks, from inside a caller's operator while SLEPc
/// applies it (a distributed operator gathering its halo). Collective: every rank's operator
/// must make the same calls in the same order.
///
/// # Errors
/// [`crate::eigen::OperatorError`] with MPI's message.
pub fn operator_allreduce_sum(values: &mut [f64]) -> Result<(), super::OperatorError> {
    petsc::callback_allreduce_sum(values).map_err(|e| super::OperatorError::new(e.to_string()))
}

/// Element-wise sum of `values` over all ranks of `PETSC_COMM_WORLD`, in place (collective).
///
/// # Errors
/// [`EigenError::Backend`] with the MPI/PETSc error.
pub fn allreduce_sum(values: &mut [f64]) -> Result<(), EigenError> {
    let session = petsc::session().map_err(backend)?;
    let world = session.world();
    session.allreduce_sum(world, values).map_err(backend)
}

/// Element-wise maximum of `values` over all ranks of `PETSC_COMM_WORLD` (collective).
///
/// # Errors
/// [`EigenError::Backend`] with the MPI/PETSc error.
pub fn allreduce_max(values: &mut [f64]) -> Result<(), EigenError> {
    let session = petsc::session().map_err(backend)?;
    let world = session.world();
    session.allreduce_max(world, values).map_err(backend)
}

/// Overwrite `values` on every rank of `PETSC_COMM_WORLD` with rank `root`'s (collective;
/// every rank passes the same length).
///
/// # Errors
/// [`EigenError::Backend`] with the MPI/PETSc error.
pub fn broadcast(values: &mut [f64], root: usize) -> Result<(), EigenError> {
    let session = petsc::session().map_err(backend)?;
    let world = session.world();
    session.broadcast(world, values, root).map_err(backend)
}

/// Every rank's `mine` (the same length on every rank), concatenated in rank order on every
/// rank of `PETSC_COMM_WORLD` (collective).
///
/// # Errors
/// [`EigenError::Backend`] with the MPI/PETSc error.
pub fn all_gather(mine: &[f64]) -> Result<Vec<f64>, EigenError> {
    let session = petsc::session().map_err(backend)?;
    let world = session.world();
    session.all_gather(world, mine).map_err(backend)
}

/// Load a PETSc binary matrix file (e.g. `hessian.petsc` from `freeform export`) with PETSc's
/// own `MatLoad` on this rank and compare it with `a`: returns max_i |(A_file x - A x)_i| /
/// max_i |(A x)_i| for a fixed pseudo-random x (0 when the file holds exactly `a`).
///
/// # Errors
/// [`EigenError::Backend`] if PETSc cannot read the file; [`EigenError::InvalidRequest`] if
/// the sizes differ.
pub fn petsc_binary_difference(
    path: &std::path::Path,
    a: SparseMatrixRef<'_>,
) -> Result<f64, EigenError> {
    let session = petsc::session().map_err(backend)?;
    let comm = session.self_comm();
    let mat = petsc::Mat::load_binary(&session, comm, path).map_err(backend)?;
    let (rows, cols) = mat.size().map_err(backend)?;
    if rows != a.nrows() || cols != a.ncols() {
        return Err(EigenError::InvalidRequest(format!(
            "{} holds a {rows} x {cols} matrix, expected {} x {}",
            path.display(),
            a.nrows(),
            a.ncols()
        )));
    }
    let mut rng = super::SplitMix64::new(7);
    let xv: Vec<f64> = (0..cols).map(|_| rng.next_f64() - 0.5).collect();
    let mut x = mat.create_vector().map_err(backend)?;
    x.set_local_values(&xv).map_err(backend)?;
    let mut y = mat.create_vector().map_err(backend)?;
    mat.mult(&x, &mut y).map_err(backend)?;
    let file_y = y.local_values().map_err(backend)?;
    let mut ours = vec![0.0; rows];
    crate::sparse::sym_mul_row_major(a, &xv, 1, &mut ours, 1, 1);
    let scale = ours.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let diff = file_y
        .iter()
        .zip(&ours)
        .fold(0.0f64, |m, (p, q)| m.max((p - q).abs()));
    Ok(if scale > 0.0 { diff / scale } else { diff })
}

/// Finalize PETSc and MPI (a no-op if the backend was never used). Programs that used the
/// backend call it once before exiting; afterwards the backend cannot be used again in the
/// process. Without it, an exit hook finalizes.
///
/// # Errors
/// [`EigenError::Backend`] with PETSc's message.
pub fn finalize() -> Result<(), EigenError> {
    petsc::finalize().map_err(backend)
}

/// After a panic: if this is one rank of several, abort the whole MPI run (the other ranks
/// may be waiting for this one in a collective and would hang). A no-op on one rank or if
/// PETSc was never started.
pub fn abort_if_parallel(code: i32) {
    petsc::abort_world_if_parallel(code);
}

pub use super::rows::block_range;

/// A block of consecutive rows of a K x K sparse matrix in CSR form with global column
/// indices: row `first + r` holds `cols[ptr[r]..ptr[r + 1]]` / `vals[..]`.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct RowBlock {
    /// Global index of the first row.
    pub first: usize,
    /// Row pointers, length rows + 1.
    pub ptr: Vec<usize>,
    /// Global column indices (below 2^32).
    pub cols: Vec<u32>,
    /// Values.
    pub vals: Vec<f64>,
}

impl RowBlock {
    /// Rows `range` of a symmetric [`SparseMatrix`] (column j of the CSC arrays is row j).
    pub fn from_symmetric(a: SparseMatrixRef<'_>, range: std::ops::Range<usize>) -> Self {
        let sym = a.symbolic();
        let mut out = RowBlock {
            first: range.start,
            ptr: vec![0],
            ..RowBlock::default()
        };
        for j in range {
            let r = sym.col_range(j);
            out.cols.extend_from_slice(&sym.row_idx()[r.clone()]);
            out.vals.extend_from_slice(&a.val()[r]);
            out.ptr.push(out.cols.len());
        }
        out
    }

    /// Number of rows.
    pub fn rows(&self) -> usize {
        self.ptr.len().saturating_sub(1)
    }

    /// Sum of the diagonal entries of these rows.
    pub fn diagonal_sum(&self) -> f64 {
        (0..self.rows())
            .map(|r| {
                (self.ptr[r]..self.ptr[r + 1])
                    .filter(|&e| self.cols[e] as usize == self.first + r)
                    .map(|e| self.vals[e])
                    .sum::<f64>()
            })
            .sum()
    }
}

/// What [`solve_rows`] returns: eigenpairs gathered on every rank, plus SLEPc's bookkeeping.
#[derive(Debug, Clone)]
pub struct RowsSolution {
    /// Eigenvalues, ascending, at most nev (fewer if SLEPc converged fewer).
    pub values: Vec<f64>,
    /// Eigenvectors, K x values.len(), on every rank.
    pub vectors: Mat<f64>,
    /// How SLEPc's run ended (type, iterations, converged count, reason, block size), for
    /// [`convergence_status`].
    pub status: SolveStatus,
    /// Configuration actually used (types, target, options).
    pub notes: Vec<String>,
}

/// Solve H x = lambda M x with SLEPc on `PETSC_COMM_WORLD`, where this rank holds rows
/// `h.first .. h.first + h.rows()` of H and the same rows of M (collective: every rank calls
/// it with its own block; blocks must tile 0..k in rank order). H, M: K x K symmetric
/// (H Pa m, M m^3). Eigenvectors are gathered onto every rank. Convergence is not judged
/// here: recompute the residuals and pass the pairs with [`RowsSolution::status`] to
/// [`convergence_status`].
///
/// # Errors
/// [`EigenError::SlepcLobpcgBreakdown`] when SLEPc's LOBPCG breaks down in its Rayleigh-Ritz
/// step; [`EigenError::Backend`] with PETSc's message for any other PETSc/SLEPc failure.
pub fn solve_rows(
    k: usize,
    h: &RowBlock,
    m: &RowBlock,
    request: &EigenRequest,
    options: &SlepcOptions,
) -> Result<RowsSolution, EigenError> {
    let session = petsc::session().map_err(backend)?;
    let world = session.world();
    let mut traces = [h.diagonal_sum(), m.diagonal_sum()];
    session.allreduce_sum(world, &mut traces).map_err(backend)?;
    let sigma = shift(options, traces)?;
    let mut hm =
        petsc::Mat::aij_from_rows(&session, world, k, h.first, &h.ptr, &h.cols, &h.vals, true)
            .map_err(backend)?;
    let mm = petsc::Mat::aij_from_rows(&session, world, k, m.first, &m.ptr, &m.cols, &m.vals, true)
        .map_err(backend)?;
    // MatAXPY is collective: the pattern counts as shared only if it is on every rank.
    let mut differs = [f64::from(u8::from(h.ptr != m.ptr || h.cols != m.cols))];
    session
        .allreduce_max(world, &mut differs)
        .map_err(backend)?;
    let same_pattern = differs[0] == 0.0;
    let solved = solve_pencil(
        &session,
        &mut hm,
        &mm,
        same_pattern,
        request,
        options,
        sigma,
    )?;
    let converged = solved.status.converged;
    let mut x = mm.create_vector().map_err(backend)?;
    let mut pairs: Vec<(f64, Vec<f64>)> = Vec::new();
    for i in 0..converged.min(request.nev) {
        let lambda = solved.eigenpair(i, &mut x).map_err(backend)?;
        pairs.push((lambda, x.gather_all().map_err(backend)?));
    }
    let (status, notes) = solved.finish()?;
    pairs.sort_by(|a, b| a.0.total_cmp(&b.0));
    let mut vectors = Mat::<f64>::zeros(k, pairs.len());
    for (j, (_, v)) in pairs.iter().enumerate() {
        for (i, &x) in v.iter().enumerate().take(k) {
            vectors[(i, j)] = x;
        }
    }
    Ok(RowsSolution {
        values: pairs.iter().map(|p| p.0).collect(),
        vectors,
        status,
        notes,
    })
}

/// [`super::SLEPC_RESIDUAL_SLACK`] under its earlier name (it lives in `eigen` so the error
/// messages can use it without the `slepc` feature).
pub const RESIDUAL_SLACK: f64 = super::SLEPC_RESIDUAL_SLACK;

impl Eigensolver for SlepcSolver {
    fn name(&self) -> &'static str {
        "slepc"
    }

    /// Operators backed by assembled matrices (and no caller's preconditioner) take
    /// [`Eigensolver::solve`]'s path with the configured preset; anything else goes to SLEPc's
    /// LOBPCG on shell matrices (`slepc_shell.rs`; `SlepcOptions::petsc_options` apply).
    fn solve_operators(
        &self,
        problem: &OperatorProblem<'_>,
        request: &EigenRequest,
        progress: &dyn Progress,
    ) -> Result<EigenSolution, EigenError> {
        if let (Some(h), Some(m), None) = (
            problem.h.assembled(),
            problem.m.assembled(),
            problem.preconditioner,
        ) {
            return self.solve(h, m, request, progress);
        }
        progress.begin("eigen (slepc, matrix-free)", None);
        let result = super::slepc_shell::solve(problem, request, &self.options);
        progress.finish();
        result
    }

    fn solve(
        &self,
        h: SparseMatrixRef<'_>,
        m: SparseMatrixRef<'_>,
        request: &EigenRequest,
        progress: &dyn Progress,
    ) -> Result<EigenSolution, EigenError> {
        validate_problem(h, m, request)?;
        let k = h.nrows();
        let (rank, size) = world_rank()?;
        let rows = block_range(k, rank, size);
        progress.begin("eigen (slepc)", None);
        let result = solve_rows(
            k,
            &RowBlock::from_symmetric(h, rows.clone()),
            &RowBlock::from_symmetric(m, rows),
            request,
            &self.options,
        );
        progress.finish();
        let rs = result?;
        let mut info = EigenInfo {
            solver: format!("slepc:{}", self.options.label()),
            iterations: rs.status.iterations,
            locked: rs.status.converged,
            notes: rs.notes,
            ..EigenInfo::default()
        };
        check_solution(h, m, &rs.values, &rs.vectors, &mut info);
        let mut solution = EigenSolution {
            values: rs.values,
            vectors: rs.vectors,
            info,
        };
        solution.info.status = convergence_status(k, request, &rs.status, &solution);
        Ok(solution)
    }
}

#[cfg(test)]
mod tests {
    use super::super::slepc_pencil::{lapack_failure, solve_error};
    use super::super::slepc_status::option_names;
    use super::*;
    use crate::eigen::{EigenStatus, SlepcLobpcgStop};

    /// The message as the command line prints it (options named by their flags,
    /// `crate::options::Front::Flags`): the text these checks were written against.
    trait CliText {
        fn cli_text(&self) -> String;
    }

    impl CliText for EigenError {
        fn cli_text(&self) -> String {
            crate::options::Front::Flags.render(self)
        }
    }

    /// The failure as SLEPc 3.18 reported it for `modes box:5,1,1 --kernels 3000 --modes 32
    /// --solver slepc --slepc lobpcg-gamg` (message recorded by our error handler).
    fn sygvd_failure() -> petsc::PetscError {
        petsc::PetscError {
            code: 76,
            call: "EPSSolve",
            message: "Error in LAPACK subroutine sygvd: info=74 [DSSolve_GHEP() at \
                      ./src/sys/classes/ds/impls/ghep/dsghep.c:131] <- DSSolve() <- \
                      EPSSolve_LOBPCG() <- EPSSolve()"
                .to_string(),
        }
    }

    #[test]
    fn lapack_failures_are_parsed() {
        assert_eq!(
            lapack_failure(&sygvd_failure().message),
            Some(("sygvd".to_string(), 74))
        );
        assert_eq!(
            lapack_failure("Error in LAPACK subroutine syevr: info=-3 [x]"),
            Some(("syevr".to_string(), -3))
        );
        assert_eq!(lapack_failure("Unknown EPS type given: bogus"), None);
        assert_eq!(lapack_failure("Error in LAPACK subroutine : info=x"), None);
    }

    #[test]
    fn a_lobpcg_sygvd_failure_becomes_the_breakdown_error() {
        match solve_error(sygvd_failure(), 3000, 33, Some(16)) {
            EigenError::SlepcLobpcgBreakdown {
                routine,
                info,
                k,
                nev,
                block_size,
                message,
            } => {
                assert_eq!(
                    (routine.as_str(), info, k, nev, block_size),
                    ("sygvd", 74, 3000, 33, Some(16))
                );
                assert!(message.contains("DSSolve_GHEP"), "{message}");
            }
            other => panic!("expected the LOBPCG breakdown, got {other:?}"),
        }
        let text = solve_error(sygvd_failure(), 3000, 33, Some(16)).cli_text();
        for needle in [
            "SLEPc's LOBPCG broke down",
            "loss of B-orthogonality in the Rayleigh-Ritz step",
            "LAPACK sygvd info=74",
            "block size 16",
            "--slepc ks-sinvert",
            "--solver lobpcg",
            "\"-eps_lobpcg_blocksize 33\") or ask for fewer modes",
        ] {
            assert!(text.contains(needle), "{needle:?} missing in: {text}");
        }
        // Already one block for all pairs: the block-size advice is left out.
        let single = EigenError::SlepcLobpcgBreakdown {
            routine: "sygvd".to_string(),
            info: 60,
            k: 3000,
            nev: 8,
            block_size: Some(8),
            message: String::new(),
        }
        .cli_text();
        assert!(
            single.ends_with("to keep SLEPc's LOBPCG, ask for fewer modes")
                && !single.contains("blocksize"),
            "{single}"
        );
        // K too small for one block of 33 (SLEPc needs K >= 5 x block size): left out too.
        let small = solve_error(sygvd_failure(), 150, 33, Some(16)).cli_text();
        assert!(
            small.ends_with("ask for fewer modes") && !small.contains("blocksize"),
            "{small}"
        );
        // The same LAPACK failure under another solver is not LOBPCG's: PETSc's message stays.
        let mut other = sygvd_failure();
        other.message = other
            .message
            .replace("EPSSolve_LOBPCG", "EPSSolve_KrylovSchur");
        assert!(matches!(
            solve_error(other, 3000, 33, None),
            EigenError::Backend { .. }
        ));
        // So does a non-LAPACK error inside LOBPCG.
        let mut other = sygvd_failure();
        other.message = "Out of memory [EPSSolve_LOBPCG()] <- EPSSolve()".to_string();
        assert!(matches!(
            solve_error(other, 3000, 33, None),
            EigenError::Backend { .. }
        ));
    }

    /// SLEPc's guard vectors and the block that holds nev pairs plus them, from SLEPc 3.18's
    /// rule guard = min(floor((1 - 0.9) b + 0.45), b - 1) worked by hand.
    #[test]
    fn single_lobpcg_block_leaves_room_for_the_guard_vectors() {
        use super::super::{slepc_lobpcg_guard, slepc_lobpcg_single_block};
        for (b, guard) in [
            (1, 0),
            (2, 0),
            (5, 0),
            (6, 1),
            (15, 1),
            (16, 2),
            (25, 2),
            (26, 3),
        ] {
            assert_eq!(slepc_lobpcg_guard(b), guard, "b = {b}");
        }
        // 16 pairs: 16 - 2 = 14 and 17 - 2 = 15 are too few, 18 - 2 = 16 is enough.
        for (nev, block) in [
            (1, 1),
            (5, 5),
            (8, 9),
            (16, 18),
            (17, 19),
            (23, 25),
            (33, 37),
        ] {
            assert_eq!(slepc_lobpcg_single_block(nev), block, "nev = {nev}");
        }
    }

    /// A SLEPc result of `n` pairs with the given recomputed residuals (eigenvalues 0, 1e6,
    /// 2e6, ...).
    fn returned(k: usize, residuals: &[f64]) -> EigenSolution {
        let n = residuals.len();
        EigenSolution {
            values: (0..n).map(|j| j as f64 * 1e6).collect(),
            vectors: Mat::zeros(k, n),
            info: EigenInfo {
                residuals: residuals.to_vec(),
                max_relative_residual: residuals.iter().copied().fold(0.0, f64::max),
                ..EigenInfo::default()
            },
        }
    }

    fn lobpcg_status(converged: usize, reason: i32, block_size: usize) -> SolveStatus {
        SolveStatus {
            eps_type: "lobpcg".to_string(),
            iterations: 33,
            converged,
            reason,
            block_size: Some(block_size),
        }
    }

    /// The solution with its status, made an error where it did not converge (what the
    /// solver's caller gets from `solve_converged`).
    fn accept(
        k: usize,
        request: &EigenRequest,
        status: &SolveStatus,
        mut solution: EigenSolution,
    ) -> Result<EigenSolution, EigenError> {
        solution.info.status = convergence_status(k, request, status, &solution);
        solution.into_converged()
    }

    #[test]
    fn accept_names_each_lobpcg_outcome_and_its_ways_out() {
        let req = EigenRequest {
            nev: 4,
            tol: 1e-8,
            max_iter: 1000,
        };
        // All pairs within 10 tol (SLEPc's own reason does not matter then).
        let ok = accept(
            120,
            &req,
            &lobpcg_status(4, 1, 4),
            returned(120, &[0.0, 9e-8, 1e-9, 9.9e-8]),
        );
        assert!(ok.is_ok());

        // SLEPc claims 5 converged (blocks of 2); pairs 1 and 2 are far off, 2 the worst.
        let err = accept(
            120,
            &req,
            &lobpcg_status(5, 1, 2),
            returned(120, &[1e-9, 3e-3, 5e-2, 1e-9]),
        )
        .unwrap_err();
        let text = err.cli_text();
        match err {
            EigenError::SlepcLobpcgNotConverged {
                stop,
                reported,
                converged,
                partial,
                ..
            } => {
                assert_eq!(
                    stop,
                    SlepcLobpcgStop::ClaimedConverged {
                        pair: 2,
                        lambda: 2e6,
                        residual: 5e-2,
                        above: 2
                    }
                );
                assert_eq!((reported, converged, partial.values.len()), (5, 2, 4));
            }
            other => panic!("expected SlepcLobpcgNotConverged, got {other:?}"),
        }
        assert_eq!(
            text,
            "SLEPc's LOBPCG reported convergence (5 pairs after 33 iterations), but freeform's \
             own residual check finds pair 2 of 0..3 (lambda 2.0000e6) at relative residual \
             5.00e-2 > 1.0e-7 (10 x tol 1.0e-8; 2 pair(s) above it). Use SLEPc's direct \
             configuration --slepc ks-sinvert (Krylov-Schur, shift-and-invert), or freeform's \
             native LOBPCG (--solver lobpcg, the default); to keep SLEPc's LOBPCG, solve all \
             pairs in one block with room for SLEPc's guard vectors (--petsc-options \
             \"-eps_lobpcg_blocksize 4\"), or ask for fewer modes"
        );
        assert!(!text.contains("raise --tol"), "{text}");
        // The same outcome as a status on the solution, with the same figures.
        let sol = returned(120, &[1e-9, 3e-3, 5e-2, 1e-9]);
        match convergence_status(120, &req, &lobpcg_status(5, 1, 2), &sol) {
            EigenStatus::SlepcLobpcgNotConverged {
                stop: SlepcLobpcgStop::ClaimedConverged { pair: 2, .. },
                reported: 5,
                converged: 2,
                nev: 4,
                k: 120,
                block_size: Some(2),
                ..
            } => {}
            other => panic!("expected SlepcLobpcgNotConverged, got {other:?}"),
        }

        // Iteration cap with pairs missing: the missing ones cannot be judged.
        let capped = accept(
            120,
            &req,
            &lobpcg_status(3, -1, 4),
            returned(120, &[1e-9; 3]),
        )
        .unwrap_err();
        assert!(matches!(
            capped,
            EigenError::SlepcLobpcgNotConverged {
                stop: SlepcLobpcgStop::IterationCap,
                converged: 3,
                ..
            }
        ));
        let text = capped.cli_text();
        assert!(
            text.starts_with(
                "SLEPc's LOBPCG stopped at its iteration cap (33 iterations) with 3/4 pairs \
                 converged (tol 1.0e-8). Use SLEPc's direct configuration --slepc ks-sinvert"
            ) && !text.contains("--max-iter"),
            "{text}"
        );
        // A cap below the default is worth raising; K too small for one block of 4 (SLEPc
        // needs K >= 20): that advice is left out.
        let low_cap = EigenRequest {
            max_iter: 2,
            ..req.clone()
        };
        let text = accept(19, &low_cap, &lobpcg_status(0, -1, 2), returned(19, &[]))
            .unwrap_err()
            .cli_text();
        assert!(
            text.ends_with(
                "to keep SLEPc's LOBPCG, raise --max-iter (2 now, default 1000), or ask for \
                 fewer modes"
            ),
            "{text}"
        );

        // SLEPc's own breakdown (an orthogonalization failed), with a block already large
        // enough: no block advice.
        let text = accept(
            120,
            &req,
            &lobpcg_status(2, -2, 5),
            returned(120, &[1e-9; 2]),
        )
        .unwrap_err()
        .cli_text();
        assert!(
            text.starts_with(
                "SLEPc's LOBPCG stopped after 33 iterations with 2/4 pairs converged (tol \
                 1.0e-8): it reports a breakdown (EPS_DIVERGED_BREAKDOWN: an orthogonalization \
                 failed). Use"
            ) && text.ends_with("to keep SLEPc's LOBPCG, ask for fewer modes"),
            "{text}"
        );
        let other = accept(
            120,
            &req,
            &lobpcg_status(2, -3, 4),
            returned(120, &[1e-9; 2]),
        )
        .unwrap_err()
        .cli_text();
        assert!(other.contains("2/4 pairs converged (tol 1.0e-8): EPSConvergedReason -3. Use"));

        // Any other EPS type keeps the general message, word for word.
        let ks = SolveStatus {
            eps_type: "krylovschur".to_string(),
            block_size: None,
            ..lobpcg_status(3, -1, 4)
        };
        let err = accept(120, &req, &ks, returned(120, &[1e-9, 1e-9, 1e-9])).unwrap_err();
        assert!(matches!(err, EigenError::NotConverged { converged: 3, .. }));
        assert_eq!(
            err.cli_text(),
            "eigensolver did not converge in 33 iterations: 3/4 pairs below tol 1.0e-8 (max \
             relative residual inf); raise --tol or the iteration cap"
        );
        let err = accept(120, &req, &ks, returned(120, &[1e-9, 1e-9, 1e-9, 2e-3])).unwrap_err();
        assert_eq!(
            err.cli_text(),
            "eigensolver did not converge in 33 iterations: 3/4 pairs below tol 1.0e-8 (max \
             relative residual 2.00e-3); raise --tol or the iteration cap"
        );
    }

    #[test]
    fn parse_specs() {
        assert_eq!(
            SlepcOptions::parse("lobpcg-gamg").unwrap().preset,
            SlepcPreset::LobpcgGamg
        );
        let o = SlepcOptions::parse("-eps_type jd -eps_target -0.5").unwrap();
        assert_eq!(o.preset, SlepcPreset::LobpcgGamg);
        assert_eq!(option_names(&o.petsc_options), ["-eps_type", "-eps_target"]);
        let o = SlepcOptions::parse("ks-sinvert:-st_pc_factor_mat_solver_type cholmod").unwrap();
        assert_eq!(o.petsc_options, "-st_pc_factor_mat_solver_type cholmod");
        assert!(SlepcOptions::parse("arnoldi").is_err());
    }
}
