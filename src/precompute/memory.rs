//! Peak memory of a precomputation, estimated before it runs, and the check that refuses a
//! run that would not fit ([`Error::OutOfMemory`]) instead of letting it be killed halfway.
//!
//! The estimate adds the parts that live at the peak (see docs/performance.md, "Memory", for
//! the figures measured against it):
//! - per integration point: positions, volumes, materials, the Morton-ordered copies and the
//!   farthest-point-sampling distances (~200 bytes);
//! - the stream: one chunk's shape functions and their transpose;
//! - H_w and M: nnz ~ 8 x the kernels covering a point (the pairs of kernels whose supports
//!   overlap), ~280 per row at the default support, scaling with the support volume; one
//!   pattern of u32 indices shared by both matrices, 20 bytes per non-zero with both
//!   triangles (plus the upper triangle they are mirrored from while they are built), 10 with
//!   the upper triangle alone ([`BasisOptions::upper_triangle_storage`]; plus the accumulated rows while
//!   they are transposed);
//! - the eigensolve (while H_w and M are held): LOBPCG's IC(0) factor and its dense
//!   K x 3 (m + 1) blocks; SLEPc's copies; the dense solver's K x K matrices.

use super::options::{default_points, BasisOptions};
use super::rkpm::CHUNK_POINTS;
use super::sampling::Resolution;
use super::solver::SolverConfig;
use crate::geometry::Shape;
use crate::{Error, Result};
use serde::{Deserialize, Serialize};

/// Environment variable that sets the memory available to a precomputation, in GB (10^9
/// bytes), instead of the system's MemAvailable: to refuse earlier on a shared machine, or to
/// test the refusal.
pub const MEMORY_LIMIT_ENV: &str = "FREEFORM_MEMORY_LIMIT";

/// Bytes per integration point held through the run (positions 24, volume 8, material 24,
/// Morton order and sorted copies 56, FPS distances and cells ~40, sampling slack).
const BYTES_PER_POINT: f64 = 200.0;

/// Kernels covering a point at the default support (factor 2 x the 4th-neighbour distance):
/// measured 32-37 on the beam at K = 1,000 to 100,000.
const COVER_AT_DEFAULT: f64 = 36.0;

/// Bytes per (point, kernel) pair of one chunk: phi 8, grad 24, kernel index 4, local index 4,
/// transpose 8, neighbour lists 4.
const BYTES_PER_PAIR: f64 = 52.0;

/// Bytes per integration point a rank of the distributed precomputation holds for each point
/// it owns: the positions and farthest-point distances of its part (~40), and the points of its
/// kernels' supports with volumes, materials and sorted copies (~110 each, about 1.5 times as
/// many as it owns: the halo).
const BYTES_PER_OWN_POINT: f64 = 200.0;

/// Bytes per kernel every rank of the distributed precomputation holds: all centres and radii
/// (32), the farthest-point choices and their sort (40), the accumulator's empty rows (48).
const BYTES_PER_KERNEL_ON_EVERY_RANK: f64 = 120.0;

/// One rank's share of SLEPc's storage: `own` entries of each of H_w and M on this rank, `rows`
/// rows, `nev` pairs. Shift-and-invert holds a Cholesky factor (MUMPS: about 17 x the entries
/// of H_w at K = 100,000, growing as K^(1/3) in 3D, 12 bytes each); the preconditioned solvers
/// an AMG hierarchy (about twice the entries of H_w) and blocks of vectors. Neither holds a
/// shifted copy of H_w: SLEPc is given H_w - sigma M in place of H_w (`eigen::slepc`).
fn slepc_bytes(opts: &BasisOptions, own: f64, rows: f64, nev: f64) -> f64 {
    use crate::eigen::SlepcPreset;
    match &opts.solver {
        SolverConfig::Slepc(s) if s.preset == SlepcPreset::KsSinvert => {
            let fill = 17.0 * (opts.kernels as f64 / 1e5).cbrt().max(0.5);
            12.0 * fill * own + 8.0 * rows * 3.0 * nev
        }
        _ => 24.0 * own + 8.0 * rows * 10.0 * nev,
    }
}

/// Peak memory of a precomputation, estimated before it runs, by part (bytes).
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct MemoryEstimate {
    /// Integration points N the estimate is for.
    pub points: usize,
    /// Kernels K.
    pub kernels: usize,
    /// Expected non-zeros of H_w (and of M).
    pub nnz: u64,
    /// Integration points, materials and their sorted copies.
    pub points_bytes: u64,
    /// One chunk of the streamed shape functions.
    pub stream_bytes: u64,
    /// H_w and M (and the upper triangle while they are mirrored).
    pub matrices_bytes: u64,
    /// The eigensolver's own storage.
    pub eigensolver_bytes: u64,
    /// Estimated peak, bytes.
    pub total_bytes: u64,
    /// Memory available at the check (MemAvailable or the [`MEMORY_LIMIT_ENV`] limit), bytes;
    /// 0 when unknown (no check was made).
    pub available_bytes: u64,
    /// The estimate is for H_w and M stored as upper triangles
    /// ([`BasisOptions::upper_triangle_storage`]).
    #[serde(default)]
    pub upper_triangle: bool,
}

/// Bytes of H_w and M at rest, and while they are built from the accumulated rows (the rows,
/// 20 bytes an upper entry, and the arrays they become): `nnz` entries of each matrix with
/// both triangles, `k` kernels.
fn matrices_bytes(nnz: f64, k: f64, upper: bool) -> (f64, f64) {
    if upper {
        // Half the entries; the transpose into CSC holds the rows and the new arrays.
        (10.0 * nnz + 8.0 * k, 10.0 * nnz + 10.0 * nnz)
    } else {
        // Two CSC matrices sharing one pattern of u32 row indices (8 + 8 + 4 bytes per
        // entry); while mirroring, the upper triangle (u32 + 2 f64 per entry, half the
        // entries) and the mirrored arrays.
        (20.0 * nnz + 4.0 * k, 10.0 * nnz + 20.0 * nnz)
    }
}

impl MemoryEstimate {
    /// The estimate for `opts` with `points` integration points.
    pub fn new(opts: &BasisOptions, points: usize) -> Self {
        let k = opts.kernels as f64;
        let n = points as f64;
        let s = &opts.support;
        // Cover grows with the support volume: factor^3, and the n-th neighbour distance^3 ~ n.
        let cover = COVER_AT_DEFAULT * (s.factor / 2.0).powi(3) * (s.neighbor as f64 / 4.0);
        let cover = cover.clamp(1.0, k.max(1.0));
        // Sums in f64 (requests far beyond any machine must not overflow), then bytes.
        let nnz = (8.0 * cover).min(k) * k;
        let points_bytes = BYTES_PER_POINT * n;
        let chunk = n.min(CHUNK_POINTS as f64);
        let stream_bytes = chunk * cover * BYTES_PER_PAIR + 16.0 * k;
        let upper = opts.upper_triangle_storage();
        let (matrices, building) = matrices_bytes(nnz, k, upper);
        let nev = opts.modes as f64 + 1.0;
        let eigensolver = match opts.solver {
            SolverConfig::Dense => 5.0 * 8.0 * k * k,
            // The IC(0) factor (lower triangle, 8 bytes per entry: its indices are the
            // pencil's; H + sigma M is not formed), S, H S, M S of K x 3 (m + 1) and the
            // preconditioner's scratch of K x (m + 1).
            SolverConfig::Lobpcg(_) => 4.0 * nnz + 8.0 * k * (9.0 + 1.0) * nev,
            // SLEPc in one process: PETSc holds its own copies of the matrices; the figure the
            // native path had before it stopped forming H + sigma M.
            SolverConfig::Slepc(_) => 16.0 * nnz + 6.0 * nnz + 5.0 * 8.0 * k * 3.0 * nev,
        };
        let total = points_bytes + (stream_bytes + building).max(matrices + eigensolver);
        // `as u64` saturates.
        Self {
            points,
            kernels: opts.kernels,
            nnz: nnz as u64,
            points_bytes: points_bytes as u64,
            stream_bytes: stream_bytes as u64,
            matrices_bytes: matrices as u64,
            eigensolver_bytes: eigensolver as u64,
            total_bytes: total as u64,
            available_bytes: 0,
            upper_triangle: upper,
        }
    }

    /// The estimate for one of `ranks` MPI ranks of the distributed precomputation
    /// ([`crate::precompute::distributed`]) with `points` integration points in all: its share
    /// of the points and of their halo, the kernels every rank holds, one stream chunk, its
    /// rows of H_w and M (its own copy and PETSc's while PETSc takes them), and its share of
    /// the SLEPc solver's storage.
    pub fn per_rank(opts: &BasisOptions, points: usize, ranks: usize) -> Self {
        let one = Self::new(opts, points);
        let p = ranks.max(1) as f64;
        let (k, n, nnz) = (opts.kernels as f64, points as f64, one.nnz as f64);
        let own = nnz / p;
        let points_bytes = BYTES_PER_OWN_POINT * n / p + BYTES_PER_KERNEL_ON_EVERY_RANK * k;
        // The rows as assembled (20 bytes per entry for both matrices) and PETSc's AIJ copies
        // (12 bytes per entry each), both alive while PETSc takes them.
        let matrices = 44.0 * own + 16.0 * k / p;
        let nev = opts.modes as f64 + 1.0;
        let eigensolver = slepc_bytes(opts, own, k / p, nev);
        let accumulating = 30.0 * own;
        let total = points_bytes
            + (one.stream_bytes as f64 + accumulating).max(matrices.max(24.0 * own + eigensolver));
        Self {
            points,
            kernels: opts.kernels,
            nnz: one.nnz,
            points_bytes: points_bytes as u64,
            stream_bytes: one.stream_bytes,
            matrices_bytes: matrices as u64,
            eigensolver_bytes: eigensolver as u64,
            total_bytes: total as u64,
            available_bytes: 0,
            upper_triangle: false,
        }
    }

    /// The parts, formatted in GB.
    pub fn breakdown(&self) -> String {
        let gb = |b: u64| b as f64 / 1e9;
        format!(
            "{:.2} GB for {} points, {:.2} GB for H_w and M with ~{} non-zeros, {:.2} GB for \
             the eigensolver, {:.2} GB per streamed chunk",
            gb(self.points_bytes),
            self.points,
            gb(self.matrices_bytes),
            self.nnz,
            gb(self.eigensolver_bytes),
            gb(self.stream_bytes)
        )
    }

    /// Compare with the memory available (the [`MEMORY_LIMIT_ENV`] limit if set, else the
    /// system's MemAvailable) and record it; a run that would not fit is an error.
    ///
    /// # Errors
    /// [`Error::OutOfMemory`] with the estimate, the memory available and what to reduce;
    /// [`Error::InvalidParameter`] for an unreadable [`MEMORY_LIMIT_ENV`].
    pub fn check(&mut self) -> Result<()> {
        match available_memory()? {
            Some((available, source)) => self.check_against(available, &source),
            None => Ok(()),
        }
    }

    /// [`MemoryEstimate::check`] against `available` bytes (described by `source`).
    ///
    /// # Errors
    /// [`Error::OutOfMemory`] when the estimate exceeds `available`.
    pub fn check_against(&mut self, available: u64, source: &str) -> Result<()> {
        self.available_bytes = available;
        if self.total_bytes <= available {
            return Ok(());
        }
        let advice = format!(
            "use fewer integration points ({}; {} now), fewer kernels ({}; {} now), fewer \
             modes, or a smaller support factor (H_w's non-zeros grow as its cube){}",
            crate::options::POINTS,
            self.points,
            crate::options::KERNELS,
            self.kernels,
            if self.upper_triangle {
                " (H_w and M are already stored as upper triangles)"
            } else {
                ""
            }
        );
        Err(Error::OutOfMemory {
            estimate_bytes: self.total_bytes,
            available_bytes: available,
            limit_from: source.to_string(),
            breakdown: self.breakdown(),
            advice,
        })
    }
}

/// The memory a run may use, bytes, and where the figure comes from: the
/// [`MEMORY_LIMIT_ENV`] limit (GB) if set, else MemAvailable of /proc/meminfo; None when
/// neither is known.
///
/// # Errors
/// [`Error::InvalidParameter`] when the variable is set but is not a positive number.
pub fn available_memory() -> Result<Option<(u64, String)>> {
    if let Ok(v) = std::env::var(MEMORY_LIMIT_ENV) {
        let gb: f64 = v.trim().parse().unwrap_or(f64::NAN);
        if !(gb.is_finite() && gb > 0.0) {
            return Err(Error::param(
                "FREEFORM_MEMORY_LIMIT",
                v,
                "must be a positive number of GB (e.g. 16), or unset to use MemAvailable",
            ));
        }
        return Ok(Some((
            (gb * 1e9) as u64,
            format!("{MEMORY_LIMIT_ENV}={}", v.trim()),
        )));
    }
    let Ok(info) = std::fs::read_to_string("/proc/meminfo") else {
        return Ok(None);
    };
    let kb = info
        .lines()
        .find(|l| l.starts_with("MemAvailable:"))
        .and_then(|l| l.split_whitespace().nth(1))
        .and_then(|v| v.parse::<u64>().ok());
    Ok(kb.map(|kb| (kb * 1024, "MemAvailable of /proc/meminfo".to_string())))
}

/// The number of integration points [`super::sample_with_material`] will give `shape` with
/// `opts` (approximately for a grid: the cells inside), without sampling.
pub fn expected_points(shape: &Shape, opts: &BasisOptions) -> usize {
    let resolution = opts
        .resolution
        .unwrap_or(Resolution::Count(default_points(opts.kernels)));
    match (shape, resolution) {
        (Shape::PointCloud(pc), Resolution::Count(n)) => n.min(pc.points().len()),
        (Shape::PointCloud(pc), Resolution::Spacing(_)) => pc.points().len(),
        (_, Resolution::Count(n)) => n,
        (solid, Resolution::Spacing(h)) => {
            let b = solid.bounding_box();
            let size = b.size();
            let volume = solid.volume().unwrap_or(size[0] * size[1] * size[2]);
            let n = volume / (h * h * h);
            if n.is_finite() && n >= 0.0 {
                n.min(usize::MAX as f64) as usize
            } else {
                0
            }
        }
    }
}
