//! SLEPc on a pencil whose rows are spread over the MPI ranks (feature `slepc`), with the
//! eigenvectors kept distributed: each rank hands its rows ([`RowPencil`]) to PETSc and drops
//! them, the residuals and M-orthonormality are computed on the distributed vectors (PETSc
//! products, sums over ranks), and only the m + 1 eigenvectors are gathered, on rank 0 alone.

use super::rows::RowPencil;
use super::slepc_pencil::{shift, solve_pencil};
use super::slepc_status::{backend, convergence_status, SolveStatus};
use super::SlepcOptions;
use super::{relative_residual, EigenError, EigenInfo, EigenRequest, EigenSolution};
use faer::Mat;
use freeform_ffi as petsc;

/// What [`solve_distributed`] returns: eigenvalues, residuals and status on every rank; the
/// eigenvectors on rank 0 only.
#[derive(Debug, Clone)]
pub struct DistributedSolution {
    /// Eigenvalues (Pa/m^2 for H_w, M), ascending; at most nev.
    pub values: Vec<f64>,
    /// Solver name, iterations, notes, residuals and M-orthonormality error (every rank).
    pub info: EigenInfo,
    /// How SLEPc's run ended.
    pub status: SolveStatus,
    /// Eigenvectors, K x values.len(), M-orthonormal: on rank 0; `None` on the others.
    pub vectors: Option<Mat<f64>>,
}

impl DistributedSolution {
    /// The solution with its verdict ([`convergence_status`]): on rank 0 with the
    /// eigenvectors, on the other ranks with an empty (0 x 0) vector matrix. Every rank takes
    /// the same decision: the residuals are the same on all of them.
    ///
    /// # Errors
    /// [`EigenError::NotConverged`] / [`EigenError::SlepcLobpcgNotConverged`] (with the
    /// partial result) when the pairs do not meet the tolerance.
    pub fn into_converged(
        self,
        k: usize,
        request: &EigenRequest,
    ) -> Result<EigenSolution, EigenError> {
        let mut solution = EigenSolution {
            values: self.values,
            vectors: self.vectors.unwrap_or_else(|| Mat::zeros(0, 0)),
            info: self.info,
        };
        solution.info.status = convergence_status(k, request, &self.status, &solution);
        solution.into_converged()
    }
}

/// Solve H x = lambda M x with SLEPc on `PETSC_COMM_WORLD`, this rank holding `rows` (its
/// block of both matrices; the ranks' blocks tile 0..k in rank order). Collective. `rows` is
/// consumed: its arrays are freed as soon as PETSc has its copy.
///
/// # Errors
/// As [`super::slepc::solve_rows`]; [`EigenError::NonFinite`] for a non-finite shift.
pub fn solve_distributed(
    k: usize,
    rows: RowPencil,
    request: &EigenRequest,
    options: &SlepcOptions,
) -> Result<DistributedSolution, EigenError> {
    let session = petsc::session().map_err(backend)?;
    let world = session.world();
    let (th, tm) = rows.diagonal_sums();
    let mut traces = [th, tm];
    session.allreduce_sum(world, &mut traces).map_err(backend)?;
    let sigma = shift(options, traces)?;
    let RowPencil {
        first,
        ptr,
        cols,
        hessian,
        mass,
    } = rows;
    let mut hm = petsc::Mat::aij_from_rows(&session, world, k, first, &ptr, &cols, &hessian, true)
        .map_err(backend)?;
    drop(hessian);
    let mm = petsc::Mat::aij_from_rows(&session, world, k, first, &ptr, &cols, &mass, true)
        .map_err(backend)?;
    drop((mass, cols, ptr));
    // H and M share `ptr` and `cols`.
    let solved = solve_pencil(&session, &mut hm, &mm, true, request, options, sigma)?;
    let count = solved.status.converged.min(request.nev);
    // This rank's entries of each pair's vector, ascending by eigenvalue.
    let mut x = mm.create_vector().map_err(backend)?;
    let mut pairs: Vec<(f64, Vec<f64>)> = Vec::with_capacity(count);
    for i in 0..count {
        let lambda = solved.eigenpair(i, &mut x).map_err(backend)?;
        pairs.push((lambda, x.local_values().map_err(backend)?));
    }
    let (status, notes) = solved.finish()?;
    pairs.sort_by(|a, b| a.0.total_cmp(&b.0));
    let mut info = EigenInfo {
        solver: format!("slepc:{}", options.label()),
        iterations: status.iterations,
        locked: status.converged,
        notes,
        ..EigenInfo::default()
    };
    check_distributed(&session, &hm, &mm, &pairs, &mut info)?;
    drop((hm, mm));
    // Only the m + 1 vectors, and only on rank 0 (which writes the basis).
    let rank = session.rank(world).map_err(backend)?;
    let mut vectors = (rank == 0).then(|| Mat::<f64>::zeros(k, pairs.len()));
    for (j, (_, local)) in pairs.iter().enumerate() {
        let all = session.gather_to_root(world, local, 0).map_err(backend)?;
        if let (Some(v), Some(all)) = (vectors.as_mut(), all) {
            for (i, &value) in all.iter().enumerate().take(k) {
                v[(i, j)] = value;
            }
        }
    }
    Ok(DistributedSolution {
        values: pairs.iter().map(|p| p.0).collect(),
        info,
        status,
        vectors,
    })
}

/// [`super::check_solution`] on distributed vectors: each rank forms its rows of H x and M x
/// with PETSc's products, and the residual norms, ||x|| and the Gram matrix X^T M X are summed
/// over the ranks; the 1-norms are PETSc's. Collective.
fn check_distributed(
    session: &petsc::Session,
    hm: &petsc::Mat<'_>,
    mm: &petsc::Mat<'_>,
    pairs: &[(f64, Vec<f64>)],
    info: &mut EigenInfo,
) -> Result<(), EigenError> {
    let nev = pairs.len();
    let norms = [
        hm.norm_one().map_err(backend)?,
        mm.norm_one().map_err(backend)?,
    ];
    let mut x = hm.create_vector().map_err(backend)?;
    let mut hx = hm.create_vector().map_err(backend)?;
    let mut mx = hm.create_vector().map_err(backend)?;
    // sums[j] = local ||r_j||^2, sums[nev + j] = local ||x_j||^2, then the Gram block.
    let mut sums = vec![0.0; 2 * nev + nev * nev];
    for (j, (lambda, local)) in pairs.iter().enumerate() {
        x.set_local_values(local).map_err(backend)?;
        hm.mult(&x, &mut hx).map_err(backend)?;
        mm.mult(&x, &mut mx).map_err(backend)?;
        let (h, m) = (
            hx.local_values().map_err(backend)?,
            mx.local_values().map_err(backend)?,
        );
        sums[j] = h
            .iter()
            .zip(&m)
            .map(|(a, b)| (a - lambda * b).powi(2))
            .sum();
        sums[nev + j] = local.iter().map(|v| v * v).sum();
        for (a, (_, xa)) in pairs.iter().enumerate() {
            sums[2 * nev + a * nev + j] = xa.iter().zip(&m).map(|(u, v)| u * v).sum();
        }
    }
    session
        .allreduce_sum(session.world(), &mut sums)
        .map_err(backend)?;
    info.residuals = (0..nev)
        .map(|j| {
            relative_residual(
                sums[j].sqrt(),
                pairs[j].0,
                norms[0],
                norms[1],
                sums[nev + j].sqrt(),
            )
        })
        .collect();
    info.max_relative_residual = info.residuals.iter().copied().fold(0.0, f64::max);
    let mut err = 0.0f64;
    for a in 0..nev {
        for b in 0..nev {
            let e = (sums[2 * nev + a * nev + b] - if a == b { 1.0 } else { 0.0 }).abs();
            err = if e.is_nan() {
                f64::INFINITY
            } else {
                err.max(e)
            };
        }
    }
    info.orthonormality_error = err;
    Ok(())
}
