//! MPI-distributed precomputation (feature `slepc`): every rank of `mpirun -n P` assembles only
//! its own rows of H_w and M and SLEPc solves the distributed pencil.
//!
//! Per rank:
//! 1. sampling, kernel centres (FPS), Morton order and support radii, redundantly (cheap next
//!    to the shape functions, and deterministic, so every rank has the same kernels);
//! 2. its block of kernels ([`crate::eigen::slepc::block_range`] over the Morton order, so the
//!    block is spatially compact);
//! 3. its integration points: those inside the support of one of its kernels (a bounding-box
//!    filter, then the exact cover test against its kernels only);
//! 4. shape functions at those points (with all kernels covering them) and assembly, streamed
//!    over chunks of the local points ([`super::stream`]: one chunk's shape functions in
//!    memory at a time): the rows of its kernels are complete, because every point of their
//!    supports is local, and are bit-identical to a one-process assembly (each entry sums the
//!    same points in the same Morton order);
//! 5. SLEPc on the row blocks (MPIAIJ), eigenvectors gathered on every rank;
//! 6. residuals and M-orthonormality recomputed from the local rows and reduced over ranks.
//!
//! Limitation: the coverage repair of [`crate::precompute`] (enlarging supports around badly
//! covered points) needs every point's shape functions, so it is not run here; a coverage
//! failure on any rank is an error on all ranks (run without MPI, or raise
//! [`BasisOptions::support`](super::BasisOptions::support)'s factor).

use super::centers::morton_order;
use super::rkpm::{covering_kernels, Kernels, ReproducingError, CHUNK_POINTS};
use super::skinning::Basis;
use super::stream::{assemble_streamed, Streamed, StreamedAssembly};
use super::{
    place_kernels, sample_with_material, BasisOptions, BasisRun, CoverageReport, ModesReport,
};
use crate::eigen::slepc::{
    allreduce_max, allreduce_sum, block_range, convergence_status, solve_rows, world_rank,
    RowBlock, SlepcOptions,
};
use crate::eigen::{relative_residual, EigenError, EigenInfo, EigenRequest, EigenSolution};
use crate::geometry::Shape;
use crate::progress::Progress;
use crate::report::{Stopwatch, Timings};
use crate::{Point3, Result};
use faer::Mat;

/// Figures of a distributed run, beside the usual report.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize)]
pub struct DistributedReport {
    /// MPI ranks.
    pub ranks: usize,
    /// This rank.
    pub rank: usize,
    /// Kernels (rows) per rank, in rank order.
    pub rows_per_rank: Vec<usize>,
    /// Integration points each rank evaluated (its kernels' supports), in rank order.
    pub points_per_rank: Vec<usize>,
    /// Each rank's peak resident memory (bytes, VmHWM) at the end of the computation, in
    /// rank order; 0 where the operating system does not tell.
    pub peak_memory_bytes_per_rank: Vec<u64>,
    /// The stage times' minimum over ranks, seconds (the report's timings are the maximum):
    /// a stage whose minimum and maximum differ much is unbalanced.
    pub timings_min: Timings,
}

/// [`super::build_basis`] across the ranks of `mpirun` with the SLEPc backend (see
/// the module docs). Collective: every rank calls it with the same arguments; every rank gets
/// the whole basis back (only one should write it). Stage timings in the report are the
/// maximum over ranks.
///
/// # Errors
/// As [`super::build_basis`]; PETSc/MPI failures as
/// [`EigenError::Backend`]. A coverage failure on any rank is reported on all of them.
pub fn build_basis_mpi(
    shape: &Shape,
    opts: &BasisOptions,
    slepc: &SlepcOptions,
    progress: &dyn Progress,
) -> Result<(BasisRun, DistributedReport)> {
    opts.validate()?;
    if !opts.boundary_regions.is_empty() {
        // Every rank returns the same error: the call stays collective.
        return Err(crate::Error::param(
            "region",
            opts.boundary_regions.len(),
            format!(
                "boundary-aware bases are not built on the MPI path yet; build it in one process \
                 (SLEPc works there too: {}) or leave out the regions",
                crate::options::SOLVER.with("slepc")
            ),
        ));
    }
    let (rank, size) = world_rank()?;
    // Every rank samples all points and holds its rows of H_w and M (and, for the checks,
    // its block of the full matrices): the one-process estimate is an upper bound per rank.
    let expected = super::memory::expected_points(shape, opts);
    let mut memory = super::MemoryEstimate::new(opts, expected);
    if expected as u128 <= super::sampling::MAX_GRID_CELLS {
        check_memory_on_all_ranks(&mut memory)?;
    }
    let mut timings = Timings::default();
    let total = Stopwatch::start();
    let mut clock = Stopwatch::start();

    progress.begin("sampling", None);
    let (points, material) = sample_with_material(shape, opts)?;
    progress.finish();
    timings.sampling = clock.lap();
    let n = points.len();

    progress.begin("centers", Some(opts.kernels as u64));
    let kernels = place_kernels(&points.points, opts)?;
    progress.finish();
    timings.centers = clock.lap();
    let k = kernels.len();

    // This rank's kernels and the integration points in their supports (Morton order).
    let mine = block_range(k, rank, size);
    let mut order: Vec<usize> = (0..n).collect();
    morton_order(&points.points, &mut order);
    let own = Kernels {
        centers: kernels.centers[mine.clone()].to_vec(),
        radii: kernels.radii[mine.clone()].to_vec(),
        kind: kernels.kind,
    };
    let (lo, hi) = support_box(&own);
    let candidates: Vec<usize> = order
        .iter()
        .copied()
        .filter(|&i| {
            let p = points.points[i];
            (0..3).all(|d| p[d] >= lo[d] && p[d] <= hi[d])
        })
        .collect();
    let cand_points: Vec<Point3> = candidates.iter().map(|&i| points.points[i]).collect();
    let own_cover = covering_kernels(&own, &cand_points);
    let local: Vec<usize> = (0..candidates.len())
        .filter(|&c| !own_cover.row(c).is_empty())
        .map(|c| candidates[c])
        .collect();
    drop((own_cover, cand_points, candidates));
    let local_points: Vec<Point3> = local.iter().map(|&i| points.points[i]).collect();
    let all_weights = material.hessian_weights();
    let volumes: Vec<f64> = local.iter().map(|&i| points.volumes[i]).collect();
    let weights: Vec<f64> = local.iter().map(|&i| all_weights[i]).collect();
    drop(all_weights);
    timings.neighbors = clock.lap();

    // Shape functions and assembly streamed over chunks of the local points.
    let streamed = assemble_streamed(
        &kernels,
        &local_points,
        &volumes,
        &weights,
        &opts.shape_functions,
        CHUNK_POINTS,
        progress,
    )?;
    drop((volumes, weights));
    // Every rank must agree before the collective solve: reduce the failure count first.
    let local_failed = match &streamed {
        Streamed::Assembled(_) => 0,
        Streamed::Uncovered(stats) => stats.stats().failed.len(),
    };
    let mut failed = [local_failed as f64];
    allreduce_sum(&mut failed)?;
    let done = match streamed {
        Streamed::Assembled(done) if failed[0] == 0.0 => done,
        other => {
            if let Streamed::Uncovered(stats) = other {
                stats.coverage_error(|i| local_points[i], opts.shape_functions.min_rcond)?;
            }
            return Err(crate::Error::param(
                "support",
                opts.support.factor,
                format!(
                    "{} point(s) on other MPI ranks are not covered by enough kernels; the \
                     distributed run does not repair coverage: raise {} or run without MPI",
                    failed[0],
                    crate::options::SUPPORT_FACTOR
                ),
            ));
        }
    };
    let StreamedAssembly {
        assembled,
        stats,
        reproducing: repro,
        largest_chunk_bytes: sf_bytes,
        neighbors_s,
        shape_functions_s,
        assembly_s,
    } = *done;
    timings.neighbors += neighbors_s;
    timings.shape_functions = shape_functions_s;
    timings.assembly = assembly_s;
    progress.begin("assembly", None);
    let h_rows = RowBlock::from_symmetric(&assembled.hessian, mine.clone());
    let m_rows = RowBlock::from_symmetric(&assembled.mass, mine.clone());
    drop(assembled);
    progress.finish();
    timings.assembly += clock.lap() - neighbors_s - shape_functions_s - assembly_s;

    let request = EigenRequest {
        nev: opts.modes + 1,
        tol: opts.tol,
        max_iter: opts.max_iter,
    };
    progress.begin("eigen (slepc, distributed)", None);
    let rs = solve_rows(k, &h_rows, &m_rows, &request, slepc);
    progress.finish();
    let rs = rs?;
    let mut info = EigenInfo {
        solver: format!("slepc:{}", slepc.label()),
        iterations: rs.status.iterations,
        locked: rs.status.converged,
        notes: rs.notes,
        ..EigenInfo::default()
    };
    info.notes.push(format!(
        "distributed assembly: {size} rank(s), rows {mine:?} here"
    ));
    check_rows(&h_rows, &m_rows, &rs.values, &rs.vectors, &mut info)?;
    timings.eigensolve = clock.lap();
    timings.total = total.elapsed();

    // Report figures reduced over ranks.
    let mut t = [
        timings.sampling,
        timings.centers,
        timings.neighbors,
        timings.shape_functions,
        timings.assembly,
        timings.eigensolve,
        timings.total,
        repro.partition_of_unity,
        repro.linear,
        repro.gradient_sum,
        repro.gradient_linear,
        stats.max_cover as f64,
        -(stats.min_cover as f64),
        -stats.min_rcond,
    ];
    // The minimum over ranks of the seven stage times, as the maximum of their negatives.
    let mut least: Vec<f64> = t[..7].iter().map(|v| -v).collect();
    allreduce_max(&mut least)?;
    allreduce_max(&mut t)?;
    let timings_min = Timings {
        sampling: -least[0],
        centers: -least[1],
        neighbors: -least[2],
        shape_functions: -least[3],
        assembly: -least[4],
        eigensolve: -least[5],
        total: -least[6],
    };
    let timings = Timings {
        sampling: t[0],
        centers: t[1],
        neighbors: t[2],
        shape_functions: t[3],
        assembly: t[4],
        eigensolve: t[5],
        total: t[6],
    };
    let repro = ReproducingError {
        partition_of_unity: t[7],
        linear: t[8],
        gradient_sum: t[9],
        gradient_linear: t[10],
    };
    let mut counts = vec![0.0; 4 * size];
    counts[4 * rank] = mine.len() as f64;
    counts[4 * rank + 1] = local.len() as f64;
    counts[4 * rank + 2] = h_rows.cols.len() as f64;
    // Bytes as f64 are exact below 2^53 (9 PB).
    counts[4 * rank + 3] = crate::report::peak_memory_bytes().unwrap_or(0) as f64;
    allreduce_sum(&mut counts)?;
    let nnz = (0..size).map(|r| counts[4 * r + 2] as usize).sum::<usize>();
    let dist = DistributedReport {
        ranks: size,
        rank,
        rows_per_rank: (0..size).map(|r| counts[4 * r] as usize).collect(),
        points_per_rank: (0..size).map(|r| counts[4 * r + 1] as usize).collect(),
        peak_memory_bytes_per_rank: (0..size).map(|r| counts[4 * r + 3] as u64).collect(),
        timings_min,
    };

    // Every rank holds the same reduced residuals, so all take the same decision; as
    // `build_basis`, a solve that did not converge is an error here.
    let mut solution = EigenSolution {
        values: rs.values,
        vectors: rs.vectors,
        info,
    };
    solution.info.status = convergence_status(k, &request, &rs.status, &solution);
    let solution = solution.into_converged()?;
    let facts = super::SolveFacts {
        solver: "slepc".into(),
        nnz: (nnz, nnz),
        timings,
        coverage: CoverageReport {
            min_moment_rcond: -t[13],
            min_cover: (-t[12]) as usize,
            mean_cover: stats.mean_cover,
            max_cover: t[11] as usize,
            enlarged_kernels: 0,
            shape_function_bytes: sf_bytes,
        },
        warnings: Vec::new(),
        memory,
    };
    let report = ModesReport::of_solve(opts, k, &points, &solution, repro, facts);
    let basis = Basis {
        kernels,
        coefficients: solution.vectors,
        eigenvalues: solution.values,
    };
    Ok((
        BasisRun {
            basis,
            points,
            material,
            report,
        },
        dist,
    ))
}

/// The ranks of a node share its memory, and all ranks must take the same decision (one that
/// stopped alone would leave the others waiting in a collective call): every rank checks the
/// estimate against the least share any rank sees, the memory available divided among the
/// ranks on its node.
fn check_memory_on_all_ranks(memory: &mut super::MemoryEstimate) -> Result<()> {
    let local = ranks_on_this_node();
    let found = super::memory::available_memory()?;
    let share = found
        .as_ref()
        .map_or(f64::INFINITY, |(bytes, _)| *bytes as f64 / local as f64);
    let mut least = [-share];
    allreduce_max(&mut least)?;
    let least = -least[0];
    if !least.is_finite() {
        return Ok(());
    }
    let source = match found {
        Some((_, source)) if local > 1 => format!("{source}, shared by {local} ranks on this node"),
        Some((_, source)) => source,
        None => "the least memory another rank sees".to_string(),
    };
    memory.check_against(least as u64, &source)
}

/// How many ranks of this job run on this node, from the launcher's environment (Open MPI's
/// `OMPI_COMM_WORLD_LOCAL_SIZE`, MPICH's `MPI_LOCALNRANKS`); 1 when neither is set.
fn ranks_on_this_node() -> u64 {
    ["OMPI_COMM_WORLD_LOCAL_SIZE", "MPI_LOCALNRANKS"]
        .iter()
        .find_map(|name| std::env::var(name).ok()?.trim().parse::<u64>().ok())
        .filter(|&n| n > 0)
        .unwrap_or(1)
}

/// Bounding box of the kernels' supports (centre +- radius).
fn support_box(k: &Kernels) -> (Point3, Point3) {
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for (c, &r) in k.centers.iter().zip(&k.radii) {
        for d in 0..3 {
            lo[d] = lo[d].min(c[d] - r);
            hi[d] = hi[d].max(c[d] + r);
        }
    }
    (lo, hi)
}

/// [`crate::eigen::check_solution`] for row-distributed H and M: each rank forms its rows of
/// H x and M x from the gathered vectors, and the residual norms, 1-norms (max absolute row
/// sums, = column sums for symmetric matrices) and the Gram matrix X^T M X are reduced over
/// the ranks. Collective.
fn check_rows(
    h: &RowBlock,
    m: &RowBlock,
    values: &[f64],
    x: &Mat<f64>,
    info: &mut EigenInfo,
) -> Result<(), EigenError> {
    let nev = values.len();
    let rows = h.rows();
    let row_mul = |a: &RowBlock, r: usize, j: usize| -> f64 {
        (a.ptr[r]..a.ptr[r + 1])
            .map(|e| a.vals[e] * x[(a.cols[e], j)])
            .sum()
    };
    let abs_sum = |a: &RowBlock, r: usize| -> f64 {
        a.vals[a.ptr[r]..a.ptr[r + 1]].iter().map(|v| v.abs()).sum()
    };
    let mut norms = [0.0f64, 0.0];
    for r in 0..rows {
        norms[0] = norms[0].max(abs_sum(h, r));
        norms[1] = norms[1].max(abs_sum(m, r));
    }
    allreduce_max(&mut norms)?;
    // sums[j] = ||r_j||^2 over local rows; gram[a * nev + b] = local part of x_a^T M x_b.
    let mut sums = vec![0.0; nev + nev * nev];
    for r in 0..rows {
        let g = m.first + r;
        let mx: Vec<f64> = (0..nev).map(|j| row_mul(m, r, j)).collect();
        for j in 0..nev {
            let res = row_mul(h, r, j) - values[j] * mx[j];
            sums[j] += res * res;
            for a in 0..nev {
                sums[nev + a * nev + j] += x[(g, a)] * mx[j];
            }
        }
    }
    allreduce_sum(&mut sums)?;
    info.residuals = (0..nev)
        .map(|j| {
            let xn = (0..x.nrows())
                .map(|i| x[(i, j)].powi(2))
                .sum::<f64>()
                .sqrt();
            relative_residual(sums[j].sqrt(), values[j], norms[0], norms[1], xn)
        })
        .collect();
    info.max_relative_residual = info.residuals.iter().copied().fold(0.0, f64::max);
    let mut err = 0.0f64;
    for a in 0..nev {
        for b in 0..nev {
            let e = (sums[nev + a * nev + b] - if a == b { 1.0 } else { 0.0 }).abs();
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
