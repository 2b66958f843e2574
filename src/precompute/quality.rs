//! The quality figures of a precomputation: the `modes` report ([`ModesReport`]), its coverage
//! figures, and the warnings raised when a monitor leaves its healthy range.

use super::boundary_modes::BoundaryRegionReport;
use super::memory::MemoryEstimate;
use super::options::BasisOptions;
use super::rkpm::{KernelType, ReproducingError, SupportOptions};
use crate::eigen::{EigenInfo, EigenSolution};
use crate::report::{peak_memory_bytes, Monitors, Timings};
use serde::Serialize;

/// Quality and size figures of the shape-function stage.
#[derive(Debug, Clone, Default, PartialEq, Serialize, serde::Deserialize)]
pub struct CoverageReport {
    /// Smallest reciprocal condition number of any moment matrix.
    pub min_moment_rcond: f64,
    /// Fewest / mean / most kernels covering an integration point.
    pub min_cover: usize,
    /// Mean kernels per point.
    pub mean_cover: f64,
    /// Most kernels per point.
    pub max_cover: usize,
    /// Kernels whose support was enlarged by the coverage repair.
    pub enlarged_kernels: usize,
    /// Bytes held by the shape functions.
    pub shape_function_bytes: usize,
    /// Points on the shape's surface whose coverage was checked and repaired before the
    /// assembly ([`crate::geometry::Shape::surface_probes`]; 0 for given points).
    #[serde(default)]
    pub surface_points: usize,
    /// Of those, the ones still badly covered (the basis cannot be evaluated there; a
    /// warning names the worst).
    #[serde(default)]
    pub uncovered_surface_points: usize,
}

/// The JSON report of `freeform modes` (design.md section 6). Deserializing (a report stored
/// in basis metadata by the scene cache) needs every field but `monitors` and `warnings`.
#[derive(Debug, Clone, PartialEq, Serialize, serde::Deserialize)]
pub struct ModesReport {
    /// Kernels K.
    pub kernels: usize,
    /// Integration points N.
    pub points: usize,
    /// Non-constant modes m.
    pub modes: usize,
    /// Non-zeros of H_w.
    pub nnz_hessian: usize,
    /// Non-zeros of M.
    pub nnz_mass: usize,
    /// Eigensolver name.
    pub solver: String,
    /// Eigenvalues, m + 1, ascending, Pa / m^2.
    pub eigenvalues: Vec<f64>,
    /// Largest relative eigen-residual (recomputed).
    pub max_relative_residual: f64,
    /// max |c^T M c - I| (recomputed).
    pub orthonormality_error: f64,
    /// Largest violation of the reproducing identities at the integration points.
    pub reproducing_error: f64,
    /// The four reproducing identities separately.
    pub reproducing_detail: ReproducingError,
    /// Stage timings, seconds.
    pub timings_s: Timings,
    /// Peak resident memory of the process, bytes (0 if unknown).
    pub peak_memory_bytes: u64,
    /// Object volume (sum of the integration weights), m^3.
    pub volume: f64,
    /// Kernel window function.
    pub kernel: KernelType,
    /// Support rule used.
    pub support: SupportOptions,
    /// Coverage figures.
    pub coverage: CoverageReport,
    /// Eigensolver diagnostics (iterations, restarts, per-pair residuals, notes).
    pub eigen: EigenInfo,
    /// Tolerance asked for.
    pub tol: f64,
    /// Warnings worth a look (none means none). Strict mode ([`crate::error::check_strict`])
    /// turns them into errors.
    #[serde(default)]
    pub warnings: Vec<String>,
    /// Conditioning and convergence monitors (the same keys as in `run` and `beam`).
    #[serde(default)]
    pub monitors: Monitors,
    /// Boundary regions of a boundary-aware basis, one per lift (empty for a free basis).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub boundaries: Vec<BoundaryRegionReport>,
    /// The peak memory estimated before the run and the memory available then (compare with
    /// `peak_memory_bytes`).
    #[serde(default)]
    pub memory_estimate: MemoryEstimate,
}

/// A moment matrix with a reciprocal condition number below this is reported: 100 times
/// the default acceptance threshold (`ShapeFunctionOptions::min_rcond` = 1e-6); a
/// well-covered interior point measures ~1e-2 and a box corner ~1e-3.
pub const RCOND_WARNING: f64 = 1e-4;

/// Reproducing identities violated by more than this are reported (well-conditioned moment
/// matrices give ~1e-13).
pub const REPRODUCING_WARNING: f64 = 1e-8;

/// max |c^T M c - I| above this is reported (the solvers reach ~1e-14).
pub const ORTHONORMALITY_WARNING: f64 = 1e-8;

/// What a solve path knows about its own run, for [`ModesReport::of_solve`].
#[derive(Debug, Clone)]
pub struct SolveFacts {
    /// Solver name.
    pub solver: String,
    /// Non-zeros of H_w and of M.
    pub nnz: (usize, usize),
    /// Stage timings, s.
    pub timings: Timings,
    /// Shape-function coverage figures.
    pub coverage: CoverageReport,
    /// Warnings raised before the solve (e.g. enlarged supports).
    pub warnings: Vec<String>,
    /// The memory estimate made before the run.
    pub memory: MemoryEstimate,
}

impl ModesReport {
    /// The report of a finished precomputation on `points` integration points (of total volume
    /// `volume`, m^3) with `kernels` kernels: sizes and
    /// options, the solution's eigenvalues and residuals, the reproducing error, the peak
    /// memory so far, then the monitors and warnings of [`check_quality`].
    pub fn of_solve(
        opts: &BasisOptions,
        kernels: usize,
        points: usize,
        volume: f64,
        solution: &EigenSolution,
        reproducing: ReproducingError,
        facts: SolveFacts,
    ) -> ModesReport {
        let mut report = ModesReport {
            kernels,
            points,
            modes: opts.modes,
            nnz_hessian: facts.nnz.0,
            nnz_mass: facts.nnz.1,
            solver: facts.solver,
            eigenvalues: solution.values.clone(),
            max_relative_residual: solution.info.max_relative_residual,
            orthonormality_error: solution.info.orthonormality_error,
            reproducing_error: reproducing.max(),
            reproducing_detail: reproducing,
            timings_s: facts.timings,
            peak_memory_bytes: peak_memory_bytes().unwrap_or(0),
            volume,
            kernel: opts.kernel,
            support: opts.support,
            coverage: facts.coverage,
            eigen: solution.info.clone(),
            tol: opts.tol,
            warnings: facts.warnings,
            monitors: Monitors::default(),
            boundaries: Vec::new(),
            memory_estimate: facts.memory,
        };
        check_quality(&mut report);
        report
    }
}

/// Fill `report.monitors` and add a warning for each monitor outside its healthy range:
/// a moment matrix close to singular, reproducing identities violated, an eigensolve that did
/// not converge, eigen-residuals above the tolerance asked for, M-orthonormality lost.
pub fn check_quality(report: &mut ModesReport) {
    report.monitors = basis_monitors(&report.coverage, report.reproducing_error, &report.eigen);
    let w = &mut report.warnings;
    let rc = report.coverage.min_moment_rcond;
    if rc < RCOND_WARNING {
        w.push(format!(
            "smallest moment-matrix reciprocal condition number {rc:.1e} is below {RCOND_WARNING:.0e}: \
             some points are covered by nearly coplanar kernels (thin features or too few kernels \
             across them); use more kernels or more integration points there, or a larger {}",
            crate::options::SUPPORT_FACTOR
        ));
    }
    if report.reproducing_error > REPRODUCING_WARNING {
        w.push(format!(
            "reproducing error {:.2e} is above {REPRODUCING_WARNING:.0e}: the moment matrices are poorly conditioned",
            report.reproducing_error
        ));
    }
    if let Some((converged, nev)) = report.eigen.status.converged_pairs() {
        w.push(format!(
            "the eigensolver did not converge: {converged}/{nev} pairs below the tolerance \
             {:.1e}; the modes are its partial result",
            report.tol
        ));
    }
    if report.max_relative_residual > report.tol {
        w.push(format!(
            "largest relative eigen-residual {:.2e} is above the tolerance {:.1e}",
            report.max_relative_residual, report.tol
        ));
    }
    if report.orthonormality_error > ORTHONORMALITY_WARNING {
        w.push(format!(
            "M-orthonormality error {:.2e} is above {ORTHONORMALITY_WARNING:.0e}: the modes are not an orthonormal basis",
            report.orthonormality_error
        ));
    }
}

/// The precomputation monitors of a `modes` report.
pub fn basis_monitors(
    coverage: &CoverageReport,
    reproducing_error: f64,
    eigen: &EigenInfo,
) -> Monitors {
    Monitors {
        min_moment_rcond: Some(coverage.min_moment_rcond),
        enlarged_kernels: Some(coverage.enlarged_kernels),
        reproducing_error: Some(reproducing_error),
        eigen_iterations: Some(eigen.iterations),
        eigen_restarts: Some(eigen.restarts),
        eigen_locked: Some(eigen.locked),
        eigen_max_relative_residual: Some(eigen.max_relative_residual),
        eigen_orthonormality_error: Some(eigen.orthonormality_error),
        ..Monitors::default()
    }
}
