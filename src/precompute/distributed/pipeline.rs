//! The distributed precomputation end to end (feature `slepc`): the stages of this folder on
//! MPI's ranks, then SLEPc on the rows, the checks on distributed vectors, and the basis on
//! rank 0.
//!
//! Limitation: the coverage repair of [`crate::precompute`] at the integration points
//! (enlarging supports around badly covered points) needs every point's shape functions, so it
//! is not run here (its repair of the shape's surface is); a coverage failure on any rank is an
//! error on all ranks (run without MPI, or raise [`BasisOptions::support`]'s factor).

use super::collective::{min, Collective};
use super::fps::place_kernels_parts;
use super::mpi::MpiWorld;
use super::partition::sample_part;
use super::rows::assemble_own_rows;
use crate::eigen::slepc::{solve_distributed, SlepcOptions};
use crate::eigen::EigenRequest;
use crate::geometry::Shape;
use crate::precompute::coverage::cover_shape_surface;
use crate::precompute::quality::{CoverageReport, ModesReport, SolveFacts};
use crate::precompute::rkpm::ReproducingError;
use crate::precompute::skinning::Basis;
use crate::precompute::{BasisOptions, MemoryEstimate};
use crate::progress::Progress;
use crate::report::{Stopwatch, Timings};
use crate::Result;

/// Figures of a distributed run, beside the usual report.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize)]
pub struct DistributedReport {
    /// MPI ranks.
    pub ranks: usize,
    /// This rank.
    pub rank: usize,
    /// Kernels (rows) per rank, in rank order.
    pub rows_per_rank: Vec<usize>,
    /// Integration points each rank owns (its block of the sampling), in rank order.
    pub points_per_rank: Vec<usize>,
    /// Integration points each rank evaluated (those in its kernels' supports, halo
    /// included), in rank order.
    pub evaluated_points_per_rank: Vec<usize>,
    /// Stored entries of each rank's rows of H_w (= of M), in rank order.
    pub nnz_per_rank: Vec<usize>,
    /// Each rank's peak resident memory (bytes, VmHWM) at the end of the computation, in
    /// rank order; 0 where the operating system does not tell.
    pub peak_memory_bytes_per_rank: Vec<u64>,
    /// Each rank's memory estimate made before the run (bytes), in rank order.
    pub estimated_bytes_per_rank: Vec<u64>,
    /// The largest peak resident memory of any rank at the end of each stage (bytes): where
    /// the peak is reached.
    pub peak_after_stage_bytes: StagePeaks,
    /// The stage times' minimum over ranks, seconds (the report's timings are the maximum):
    /// a stage whose minimum and maximum differ much is unbalanced.
    pub timings_min: Timings,
}

/// Peak resident memory (bytes, VmHWM), the largest over ranks, at the end of each stage.
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize)]
pub struct StagePeaks {
    /// After sampling this rank's part of the points.
    pub sampling: u64,
    /// After placing the kernels.
    pub centers: u64,
    /// After assembling this rank's rows.
    pub rows: u64,
    /// After the eigensolve and its checks.
    pub eigensolve: u64,
}

/// What [`build_basis_mpi`] returns on every rank.
#[derive(Debug, Clone)]
pub struct DistributedRun {
    /// The skinning basis on rank 0 (which writes it); `None` on the other ranks.
    pub basis: Option<Basis>,
    /// The report, the same on every rank but for each rank's own peak memory (stage times:
    /// the maximum over ranks).
    pub report: ModesReport,
    /// The per-rank figures.
    pub distributed: DistributedReport,
}

/// [`crate::precompute::build_basis`] across the ranks of `mpirun` with the SLEPc backend,
/// no rank holding all points, the K x K matrices or all eigenvectors (see the module docs of
/// [`super`]). Collective: every rank calls it with the same arguments. The kernels and the
/// rows of H_w and M are the one-process ones bit for bit; the eigenpairs are SLEPc's on them.
///
/// # Errors
/// As [`crate::precompute::build_basis`], on every rank alike (a rank that fails alone makes
/// the others fail with [`crate::eigen::EigenError::OtherRanks`]); PETSc/MPI failures as
/// [`crate::eigen::EigenError::Backend`]. A coverage failure on any rank is reported on all.
pub fn build_basis_mpi(
    shape: &Shape,
    opts: &BasisOptions,
    slepc: &SlepcOptions,
    progress: &dyn Progress,
) -> Result<DistributedRun> {
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
    let comm = MpiWorld::new()?;
    let (rank, size) = (comm.rank(), comm.size());
    let expected = crate::precompute::memory::expected_points(shape, opts);
    let mut memory = MemoryEstimate::per_rank(opts, expected, size);
    if expected as u128 <= crate::precompute::sampling::MAX_GRID_CELLS {
        check_memory_on_all_ranks(&mut memory, &comm)?;
    }
    let mut timings = Timings::default();
    let total = Stopwatch::start();
    let mut clock = Stopwatch::start();

    progress.begin("sampling", None);
    let part = sample_part(shape, opts, &comm);
    progress.finish();
    let part = super::collective::agree(&comm, "sampling", part)?;
    timings.sampling = clock.lap();
    let peak_now = || crate::report::peak_memory_bytes().unwrap_or(0) as f64;
    let mut stage_peaks = [peak_now(), 0.0, 0.0, 0.0];

    let mut kernels = place_kernels_parts(&part, opts, &comm, progress)?;
    // The shape's surface is repaired on every rank alike (the probes and the kernels are
    // the same everywhere), as in one process.
    let surface = cover_shape_surface(&mut kernels, Some(shape), part.total_volume(), opts)?;
    timings.centers = clock.lap();
    stage_peaks[1] = peak_now();
    let k = kernels.len();

    let own = assemble_own_rows(shape, &part, &kernels, opts, &comm, progress)?;
    let stream = own.assembly;
    timings.shape_functions = stream.shape_functions_s;
    timings.assembly = stream.assembly_s;
    timings.neighbors = clock.lap() - stream.shape_functions_s - stream.assembly_s;
    let (n, volume, owned_points) = (part.total, part.total_volume(), part.points.len());
    drop(part);
    let rows = stream.assembled;
    let (own_rows, own_nnz) = (rows.rows(), rows.nnz());
    stage_peaks[2] = peak_now();

    let request = EigenRequest {
        nev: opts.modes + 1,
        tol: opts.tol,
        max_iter: opts.max_iter,
    };
    progress.begin("eigen (slepc, distributed)", None);
    let solved = solve_distributed(k, rows, &request, slepc);
    progress.finish();
    let mut solved = solved?;
    solved.info.notes.push(format!(
        "distributed assembly: {size} rank(s), {own_rows} rows here"
    ));
    timings.eigensolve = clock.lap();
    timings.total = total.elapsed();
    stage_peaks[3] = peak_now();
    comm.max(&mut stage_peaks)?;

    // Report figures reduced over ranks: the maximum of the stage times, the minimum too.
    let stats = &stream.stats;
    let repro = &stream.reproducing;
    let stage = |t: &Timings| {
        [
            t.sampling,
            t.centers,
            t.neighbors,
            t.shape_functions,
            t.assembly,
            t.eigensolve,
            t.total,
        ]
    };
    let mut most = stage(&timings).to_vec();
    most.extend([
        repro.partition_of_unity,
        repro.linear,
        repro.gradient_sum,
        repro.gradient_linear,
        stats.max_cover as f64,
    ]);
    comm.max(&mut most)?;
    let mut least = stage(&timings).to_vec();
    least.extend([stats.min_cover as f64, stats.min_rcond]);
    min(&comm, &mut least)?;
    let timings_of = |t: &[f64]| Timings {
        sampling: t[0],
        centers: t[1],
        neighbors: t[2],
        shape_functions: t[3],
        assembly: t[4],
        eigensolve: t[5],
        total: t[6],
    };
    let per_rank = |v: f64| -> Result<Vec<f64>> { comm.all_gather(&[v]) };
    let peak = crate::report::peak_memory_bytes().unwrap_or(0);
    let as_usize = |v: Vec<f64>| v.into_iter().map(|x| x as usize).collect::<Vec<_>>();
    // Bytes and counts as f64 are exact below 2^53.
    let nnz_per_rank = as_usize(per_rank(own_nnz as f64)?);
    let dist = DistributedReport {
        ranks: size,
        rank,
        rows_per_rank: as_usize(per_rank(own_rows as f64)?),
        points_per_rank: as_usize(per_rank(owned_points as f64)?),
        evaluated_points_per_rank: as_usize(per_rank(own.points as f64)?),
        nnz_per_rank: nnz_per_rank.clone(),
        peak_memory_bytes_per_rank: per_rank(peak as f64)?
            .into_iter()
            .map(|b| b as u64)
            .collect(),
        estimated_bytes_per_rank: per_rank(memory.total_bytes as f64)?
            .into_iter()
            .map(|b| b as u64)
            .collect(),
        timings_min: timings_of(&least),
        peak_after_stage_bytes: StagePeaks {
            sampling: stage_peaks[0] as u64,
            centers: stage_peaks[1] as u64,
            rows: stage_peaks[2] as u64,
            eigensolve: stage_peaks[3] as u64,
        },
    };

    // Every rank holds the same residuals, so all take the same decision; as `build_basis`,
    // a solve that did not converge is an error here.
    let solution = solved.into_converged(k, &request)?;
    let nnz = nnz_per_rank.iter().sum::<usize>();
    let facts = SolveFacts {
        solver: "slepc".into(),
        nnz: (nnz, nnz),
        timings: timings_of(&most),
        coverage: CoverageReport {
            min_moment_rcond: least[8],
            min_cover: least[7] as usize,
            mean_cover: stats.mean_cover,
            max_cover: most[11] as usize,
            enlarged_kernels: surface.enlarged.len(),
            shape_function_bytes: stream.largest_chunk_bytes,
            surface_points: surface.points,
            uncovered_surface_points: surface.uncovered,
        },
        warnings: surface
            .warning(opts.coverage_repair_rounds)
            .into_iter()
            .collect(),
        memory,
    };
    let repro = ReproducingError {
        partition_of_unity: most[7],
        linear: most[8],
        gradient_sum: most[9],
        gradient_linear: most[10],
    };
    let report = ModesReport::of_solve(opts, k, n, volume, &solution, repro, facts);
    let basis = (rank == 0).then(|| Basis {
        kernels,
        coefficients: solution.vectors,
        eigenvalues: solution.values,
    });
    Ok(DistributedRun {
        basis,
        report,
        distributed: dist,
    })
}

/// The ranks of a node share its memory, and all ranks must take the same decision (one that
/// stopped alone would leave the others waiting in a collective call): every rank checks its
/// estimate against the least share any rank sees, the memory available divided among the
/// ranks on its node.
fn check_memory_on_all_ranks(memory: &mut MemoryEstimate, comm: &dyn Collective) -> Result<()> {
    let local = ranks_on_this_node();
    let found = crate::precompute::memory::available_memory()?;
    let share = found
        .as_ref()
        .map_or(f64::INFINITY, |(bytes, _)| *bytes as f64 / local as f64);
    let mut least = [share];
    min(comm, &mut least)?;
    let least = least[0];
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
