//! The streamed middle of the pipeline: shape functions for one chunk of integration points,
//! that chunk's contribution to H_w and M ([`Accumulator`]), drop it, next chunk. Memory is
//! O(nnz(H_w) + N) instead of O(N x kernels per point); the matrices are the same bit for bit
//! for any chunk size and thread count (see [`super::assembly`]).

use super::assembly::{Accumulator, Assembled};
use super::rkpm::{
    evaluate_chunk, reproducing_error, ChunkedStats, Kernels, ReproducingError,
    ShapeFunctionOptions, ShapeStats,
};
use crate::eigen::RowPencil;
use crate::error::check_cancelled;
use crate::progress::Progress;
use crate::report::Stopwatch;
use crate::{Error, Point3, Result};

/// Outcome of [`assemble_streamed`] when every point was well covered (`A` = [`Assembled`]),
/// or of [`assemble_streamed_rows`] (`A` = [`RowPencil`]).
#[derive(Debug, Clone)]
pub struct StreamedAssembly<A = Assembled> {
    /// H_w (Pa m) and M (m^3): K x K, or the wanted rows.
    pub assembled: A,
    /// Shape-function figures over all points (point indices in the order given).
    pub stats: ShapeStats,
    /// Largest violation of the reproducing identities over all points.
    pub reproducing: ReproducingError,
    /// Bytes of the largest chunk's shape functions (what the stream holds at once).
    pub largest_chunk_bytes: usize,
    /// Seconds spent finding covering kernels.
    pub neighbors_s: f64,
    /// Seconds spent evaluating shape functions (and checking their identities).
    pub shape_functions_s: f64,
    /// Seconds spent accumulating and mirroring H_w and M.
    pub assembly_s: f64,
}

/// What [`assemble_streamed`] returns.
#[derive(Debug, Clone)]
pub enum Streamed<A = Assembled> {
    /// Every point was covered: the matrices.
    Assembled(Box<StreamedAssembly<A>>),
    /// Some points failed the moment-matrix check; the figures list all of them (indices in
    /// the order given). Assembly stops at the first failing chunk; the remaining chunks are
    /// still evaluated so that the list is complete.
    Uncovered(ChunkedStats),
}

/// Stream over `points` (N x 3, metres; best in Morton order, so chunks are compact) in
/// chunks of `chunk` points: shape functions of `kernels` with `opts`, accumulated into H_w
/// and M with volumes `volumes` (N, m^3) and Hessian weights `weights` (N, lambda + 4 mu,
/// Pa). Checks `progress` for cancellation between chunks.
///
/// # Errors
/// [`Error::LengthMismatch`] for volumes or weights of the wrong length,
/// [`Error::InvalidParameter`] for `chunk == 0`, [`Error::NonFinite`] for non-finite sums,
/// [`Error::Cancelled`].
pub fn assemble_streamed(
    kernels: &Kernels,
    points: &[Point3],
    volumes: &[f64],
    weights: &[f64],
    opts: &ShapeFunctionOptions,
    chunk: usize,
    progress: &dyn Progress,
) -> Result<Streamed> {
    let acc = Accumulator::new(kernels.len())?;
    stream(
        acc,
        kernels,
        points,
        volumes,
        weights,
        opts,
        chunk,
        progress,
        Accumulator::finish,
    )
}

/// [`assemble_streamed`] with H_w and M stored as upper triangles
/// ([`Accumulator::finish_upper`]).
///
/// # Errors
/// As [`assemble_streamed`].
pub fn assemble_streamed_upper(
    kernels: &Kernels,
    points: &[Point3],
    volumes: &[f64],
    weights: &[f64],
    opts: &ShapeFunctionOptions,
    chunk: usize,
    progress: &dyn Progress,
) -> Result<Streamed> {
    let acc = Accumulator::new(kernels.len())?;
    stream(
        acc,
        kernels,
        points,
        volumes,
        weights,
        opts,
        chunk,
        progress,
        Accumulator::finish_upper,
    )
}

/// [`assemble_streamed`] for rows `own` of H_w and M only ([`Accumulator::for_rows`]): one
/// MPI rank's block, complete when `points` are all points of those kernels' supports.
///
/// # Errors
/// As [`assemble_streamed`]; [`Error::InvalidParameter`] for a range outside 0..K.
#[allow(clippy::too_many_arguments)]
pub fn assemble_streamed_rows(
    kernels: &Kernels,
    points: &[Point3],
    volumes: &[f64],
    weights: &[f64],
    opts: &ShapeFunctionOptions,
    chunk: usize,
    own: std::ops::Range<usize>,
    progress: &dyn Progress,
) -> Result<Streamed<RowPencil>> {
    let acc = Accumulator::for_rows(kernels.len(), own)?;
    stream(
        acc,
        kernels,
        points,
        volumes,
        weights,
        opts,
        chunk,
        progress,
        Accumulator::finish_rows,
    )
}

#[allow(clippy::too_many_arguments)]
fn stream<A>(
    mut acc: Accumulator,
    kernels: &Kernels,
    points: &[Point3],
    volumes: &[f64],
    weights: &[f64],
    opts: &ShapeFunctionOptions,
    chunk: usize,
    progress: &dyn Progress,
    finish: impl FnOnce(Accumulator) -> Result<A>,
) -> Result<Streamed<A>> {
    let n = points.len();
    super::assembly::check_point_lengths(n, volumes, weights)?;
    if chunk == 0 {
        return Err(Error::param(
            "chunk",
            0,
            "need at least one point per chunk",
        ));
    }
    let mut stats = ChunkedStats::default();
    let mut repro = ReproducingError::default();
    let (mut neighbors_s, mut shape_functions_s, mut assembly_s) = (0.0, 0.0, 0.0);
    progress.begin("shape functions + assembly", Some(n as u64));
    for start in (0..n).step_by(chunk) {
        // A cancelled run stops before a chunk's shape functions.
        check_cancelled(progress, "shape functions")?;
        let end = (start + chunk).min(n);
        let clock = Stopwatch::start();
        let (sf, st, neighbors) = evaluate_chunk(kernels, &points[start..end], opts);
        stats.add(&sf, &st, |i| start + i);
        if stats.any_failed() {
            // The sums are useless now; only the list of failed points is still wanted.
            neighbors_s += neighbors;
            shape_functions_s += clock.elapsed() - neighbors;
            progress.set_position(end as u64);
            continue;
        }
        let r = reproducing_error(kernels, &points[start..end], &sf);
        repro = ReproducingError {
            partition_of_unity: repro.partition_of_unity.max(r.partition_of_unity),
            linear: repro.linear.max(r.linear),
            gradient_sum: repro.gradient_sum.max(r.gradient_sum),
            gradient_linear: repro.gradient_linear.max(r.gradient_linear),
        };
        let evaluated = clock.elapsed();
        neighbors_s += neighbors;
        shape_functions_s += evaluated - neighbors;
        acc.add(&sf, &volumes[start..end], &weights[start..end])?;
        assembly_s += clock.elapsed() - evaluated;
        progress.set_position(end as u64);
    }
    progress.finish();
    if stats.any_failed() {
        return Ok(Streamed::Uncovered(stats));
    }
    let clock = Stopwatch::start();
    let assembled = finish(acc)?;
    assembly_s += clock.elapsed();
    Ok(Streamed::Assembled(Box::new(StreamedAssembly {
        assembled,
        stats: stats.stats(),
        reproducing: repro,
        largest_chunk_bytes: stats.largest_chunk_bytes,
        neighbors_s,
        shape_functions_s,
        assembly_s,
    })))
}
