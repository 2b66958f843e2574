//! The whole precomputation: shape -> integration points -> kernel centres and radii ->
//! shape functions -> H_w and M -> eigenmodes, with timings and quality figures.
//!
//! [`build_basis`] starts from a [`Shape`]; [`build_basis_from_points`] starts from your own
//! integration points and per-point materials.

use crate::assembly::assemble;
use crate::centers::{farthest_point_sampling, morton_order};
use crate::eigen::dense::DenseSolver;
use crate::eigen::lobpcg::{Lobpcg, LobpcgOptions};
use crate::eigen::{EigenRequest, Eigensolver};
use crate::geometry::Shape;
use crate::material::{Material, MaterialField, MaterialOverride};
use crate::progress::Progress;
use crate::report::Monitors;
use crate::report::{peak_memory_bytes, Stopwatch, Timings};
use crate::rkpm::{
    self, support_radii, KernelType, Kernels, ReproducingError, ShapeFunctionOptions,
    ShapeFunctions, ShapeStats, SupportOptions,
};
use crate::sampling::{
    cloud_volumes, grid_points, CloudVolumeOptions, IntegrationPoints, Resolution,
};
use crate::skinning::Basis;
use crate::{Error, Point3, Result};
use serde::Serialize;

/// Which eigensolver runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum SolverChoice {
    /// Native sparse LOBPCG (default): any K.
    #[default]
    Lobpcg,
    /// Dense reference: exact to round-off, K up to a few thousand.
    Dense,
}

impl SolverChoice {
    /// Lower-case name.
    pub fn name(self) -> &'static str {
        match self {
            SolverChoice::Lobpcg => "lobpcg",
            SolverChoice::Dense => "dense",
        }
    }
}

/// Every knob of the precomputation, with documented defaults (see docs/guide.md).
#[derive(Debug, Clone, PartialEq, Serialize)]
#[must_use]
pub struct BasisOptions {
    /// Number of kernels K. Default 1000 (the paper's choice for the beam).
    pub kernels: usize,
    /// Number of non-constant modes m (m + 1 handles are computed). Default 16.
    pub modes: usize,
    /// Integration grid density; None means [`default_points`] of K points.
    pub resolution: Option<Resolution>,
    /// Window function. Default cubic B-spline.
    pub kernel: KernelType,
    /// Support radius rule.
    pub support: SupportOptions,
    /// Moment-matrix conditioning threshold.
    pub shape_functions: ShapeFunctionOptions,
    /// Base material. Default: the standard beam's (E = 5e6 Pa, nu = 0.45, rho = 1000).
    pub material: Material,
    /// Region overrides applied in order on top of `material`.
    pub overrides: Vec<MaterialOverride>,
    /// Eigensolver. Default LOBPCG.
    pub solver: SolverChoice,
    /// Relative eigen-residual tolerance. Default 1e-8.
    pub tol: f64,
    /// Eigensolver iteration cap. Default 1000.
    pub max_iter: usize,
    /// Point-cloud quadrature options (voxel size, total volume).
    pub cloud: CloudVolumeOptions,
    /// Rounds of local support enlargement (x1.25 on the 4 kernels nearest each badly covered
    /// point) before giving up with a coverage error. Default 3.
    pub coverage_repair_rounds: usize,
}

impl Default for BasisOptions {
    fn default() -> Self {
        Self {
            kernels: 1000,
            modes: 16,
            resolution: None,
            kernel: KernelType::Cubic,
            support: SupportOptions::default(),
            shape_functions: ShapeFunctionOptions::default(),
            material: Material::default(),
            overrides: Vec::new(),
            solver: SolverChoice::Lobpcg,
            tol: 1e-8,
            max_iter: 1000,
            cloud: CloudVolumeOptions::default(),
            coverage_repair_rounds: 3,
        }
    }
}

/// Default integration point count for K kernels: 50 K, clamped to [20,000, 2,000,000].
/// 50 points per kernel resolves each support (~30 kernels overlap a point, ~1,500 points lie
/// in a support) so quadrature error stays below the kernel approximation error; the cap keeps
/// K = 100,000 within memory (the 2M-point sizing).
pub fn default_points(kernels: usize) -> usize {
    kernels.saturating_mul(50).clamp(20_000, 2_000_000)
}

/// Most kernels [`BasisOptions::validate`] accepts: 10 million. K = 100,000 peaks at 4.75 GB
/// (docs/performance.md), so 10 million would need ~500 GB; a larger request is a typo (or a
/// unit mistake) and is rejected before anything is allocated.
pub const MAX_KERNELS: usize = 10_000_000;

/// Most integration points [`BasisOptions::validate`] accepts: 100 million (each point holds
/// ~30 shape-function values and gradients, so this is already ~100 GB).
pub const MAX_POINTS: usize = 100_000_000;

impl BasisOptions {
    /// Check every parameter's range (before any work is done).
    pub fn validate(&self) -> Result<()> {
        if self.kernels < 10 {
            return Err(Error::param(
                "kernels",
                self.kernels,
                "need at least 10 kernels",
            ));
        }
        if self.modes == 0 {
            return Err(Error::param(
                "modes",
                0,
                "ask for at least one non-constant mode",
            ));
        }
        if self.kernels > MAX_KERNELS {
            return Err(Error::param(
                "kernels",
                self.kernels,
                format!(
                    "more than {MAX_KERNELS} kernels would need far more memory than any \
                     machine has; use at most a few 100,000 (default 1000)"
                ),
            ));
        }
        if self.modes.saturating_add(1) >= self.kernels {
            return Err(Error::param(
                "modes",
                self.modes,
                format!(
                    "m must be smaller than K - 1 = {} (K = {} kernels)",
                    self.kernels - 1,
                    self.kernels
                ),
            ));
        }
        if !(self.tol.is_finite() && self.tol > 0.0 && self.tol < 1.0) {
            return Err(Error::param(
                "tol",
                self.tol,
                "tolerance must lie in (0, 1), e.g. 1e-8",
            ));
        }
        if self.max_iter == 0 {
            return Err(Error::param("max_iter", 0, "need at least one iteration"));
        }
        if let Some(Resolution::Count(n)) = self.resolution {
            if n < self.kernels {
                return Err(Error::param(
                    "points",
                    n,
                    format!("fewer integration points than kernels ({})", self.kernels),
                ));
            }
            if n > MAX_POINTS {
                return Err(Error::param(
                    "points",
                    n,
                    format!(
                        "more than {MAX_POINTS} integration points would need far more memory \
                         than any machine has; 50 per kernel is plenty (the default)"
                    ),
                ));
            }
        }
        self.support.validate()?;
        if !(self.shape_functions.min_rcond > 0.0 && self.shape_functions.min_rcond < 1.0) {
            return Err(Error::param(
                "min_rcond",
                self.shape_functions.min_rcond,
                "must lie in (0, 1)",
            ));
        }
        self.material.validate()?;
        for o in &self.overrides {
            o.region.validate()?;
            o.material.validate()?;
        }
        Ok(())
    }
}

/// Quality and size figures of the shape-function stage.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
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
}

/// The JSON report of `freeform modes` (design.md section 6).
#[derive(Debug, Clone, Serialize)]
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
    pub eigen: crate::eigen::EigenInfo,
    /// Tolerance asked for.
    pub tol: f64,
    /// Warnings worth a look (none means none). `--strict` turns them into errors.
    pub warnings: Vec<String>,
    /// Conditioning and convergence monitors (the same keys as in `run` and `beam`).
    pub monitors: Monitors,
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

/// Fill `report.monitors` and add a warning for each monitor outside its healthy range:
/// a moment matrix close to singular, reproducing identities violated, eigen-residuals
/// above the tolerance asked for, M-orthonormality lost.
pub fn check_quality(report: &mut ModesReport) {
    report.monitors =
        Monitors::from_basis(&report.coverage, report.reproducing_error, &report.eigen);
    let w = &mut report.warnings;
    let rc = report.coverage.min_moment_rcond;
    if rc < RCOND_WARNING {
        w.push(format!(
            "smallest moment-matrix reciprocal condition number {rc:.1e} is below {RCOND_WARNING:.0e}: \
             some points are covered by nearly coplanar kernels (thin features or too few kernels \
             across them); use more kernels or more integration points there, or a larger --support"
        ));
    }
    if report.reproducing_error > REPRODUCING_WARNING {
        w.push(format!(
            "reproducing error {:.2e} is above {REPRODUCING_WARNING:.0e}: the moment matrices are poorly conditioned",
            report.reproducing_error
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

/// Everything a precomputation produces.
#[derive(Debug, Clone)]
pub struct BasisRun {
    /// The skinning basis.
    pub basis: Basis,
    /// Integration points and volumes used.
    pub points: IntegrationPoints,
    /// Material per integration point.
    pub material: MaterialField,
    /// Report.
    pub report: ModesReport,
}

/// Integration points for a shape: a grid inside solids, the (optionally downsampled) points
/// of a point cloud with voxel-occupancy volumes.
pub fn sample_shape(
    shape: &Shape,
    resolution: Resolution,
    cloud: &CloudVolumeOptions,
) -> Result<IntegrationPoints> {
    match shape {
        Shape::PointCloud(pc) => {
            let all = pc.points();
            let points = match resolution {
                Resolution::Count(n) if n < all.len() => downsample(all, n),
                Resolution::Count(_) => all.to_vec(),
                Resolution::Spacing(h) => {
                    return Err(Error::param("spacing", h, "a point cloud's points are its integration points; use --points N to downsample"))
                }
            };
            let (volumes, _) = cloud_volumes(&points, cloud)?;
            Ok(IntegrationPoints { points, volumes })
        }
        solid => {
            let aabb = solid.bounding_box();
            let exact = solid.volume();
            let size = [
                aabb.max[0] - aabb.min[0],
                aabb.max[1] - aabb.min[1],
                aabb.max[2] - aabb.min[2],
            ];
            let vol = exact.unwrap_or(size[0] * size[1] * size[2]);
            let h = resolution.spacing(vol)?;
            let inside = |p: &[Point3]| solid.contains(p).unwrap_or_else(|| vec![true; p.len()]);
            grid_points(&aabb, h, exact, &inside)
        }
    }
}

/// A deterministic, spatially unbiased subset of `n` points (seeded partial Fisher-Yates),
/// returned in input order.
fn downsample(points: &[Point3], n: usize) -> Vec<Point3> {
    let mut idx: Vec<usize> = (0..points.len()).collect();
    let mut state = 0x5EED_F1EE_u64;
    for i in 0..n {
        state = state.wrapping_add(0x9E3779B97F4A7C15);
        let mut z = state;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58476D1CE4E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D049BB133111EB);
        z ^= z >> 31;
        let j = i + (z % (points.len() - i) as u64) as usize;
        idx.swap(i, j);
    }
    let mut keep = idx[..n].to_vec();
    keep.sort_unstable();
    keep.into_iter().map(|i| points[i]).collect()
}

/// Run the whole precomputation on a shape.
pub fn build_basis(
    shape: &Shape,
    opts: &BasisOptions,
    progress: &dyn Progress,
) -> Result<BasisRun> {
    let solver = default_solver(opts.solver);
    build_basis_with(shape, opts, solver.as_ref(), progress)
}

/// The eigensolver [`SolverChoice`] names, with default settings.
pub fn default_solver(choice: SolverChoice) -> Box<dyn Eigensolver> {
    match choice {
        SolverChoice::Lobpcg => Box::new(Lobpcg::new(LobpcgOptions::default())),
        SolverChoice::Dense => Box::new(DenseSolver),
    }
}

/// [`build_basis`] with a caller-supplied eigensolver (e.g. the SLEPc backend) instead of
/// `opts.solver`.
pub fn build_basis_with(
    shape: &Shape,
    opts: &BasisOptions,
    solver: &dyn Eigensolver,
    progress: &dyn Progress,
) -> Result<BasisRun> {
    let prepared = prepare(shape, opts, progress)?;
    solve_prepared(prepared, opts, solver, progress)
}

/// Sample a shape and run the precomputation up to the assembled H_w and M (no eigensolve):
/// [`prepare_from_points`] after the sampling stage.
pub fn prepare(shape: &Shape, opts: &BasisOptions, progress: &dyn Progress) -> Result<Prepared> {
    opts.validate()?;
    let mut clock = Stopwatch::start();
    progress.begin("sampling", None);
    let resolution = opts
        .resolution
        .unwrap_or(Resolution::Count(default_points(opts.kernels)));
    let points = sample_shape(shape, resolution, &opts.cloud)?;
    progress.finish();
    let material = MaterialField::from_regions(&points.points, &opts.material, &opts.overrides)?;
    let sampling = clock.lap();
    let mut prepared = prepare_from_points(points, material, opts, progress)?;
    prepared.timings.sampling = sampling;
    prepared.timings.total += sampling;
    Ok(prepared)
}

/// Run the precomputation from given integration points (N x 3, metres), volumes (N, m^3)
/// and per-point materials. `opts.resolution`, `opts.material` and `opts.overrides` are not
/// used here (the caller made those choices).
pub fn build_basis_from_points(
    points: IntegrationPoints,
    material: MaterialField,
    opts: &BasisOptions,
    progress: &dyn Progress,
) -> Result<BasisRun> {
    let prepared = prepare_from_points(points, material, opts, progress)?;
    let solver = default_solver(opts.solver);
    solve_prepared(prepared, opts, solver.as_ref(), progress)
}

/// Everything before the eigensolve: kernels, the assembled H_w and M, and the figures the
/// report needs. Made by [`prepare`] / [`prepare_from_points`], consumed by
/// [`solve_prepared`]; `assembled` is what `freeform export` writes.
#[derive(Debug, Clone)]
pub struct Prepared {
    /// Kernels (Morton order: the row/column order of H_w and M).
    pub kernels: Kernels,
    /// H_w (Pa m) and M (m^3), K x K.
    pub assembled: crate::assembly::Assembled,
    /// Integration points and volumes, in the caller's order.
    pub points: IntegrationPoints,
    /// Material per integration point.
    pub material: MaterialField,
    /// Stage timings so far (eigensolve and total not yet filled), seconds.
    pub timings: Timings,
    /// Reproducing-identity errors at the integration points.
    pub reproducing: ReproducingError,
    /// Coverage figures.
    pub coverage: CoverageReport,
    /// Warnings so far.
    pub warnings: Vec<String>,
}

/// [`build_basis_from_points`] up to the assembled matrices (no eigensolve).
pub fn prepare_from_points(
    points: IntegrationPoints,
    material: MaterialField,
    opts: &BasisOptions,
    progress: &dyn Progress,
) -> Result<Prepared> {
    opts.validate()?;
    let n = points.len();
    if points.volumes.len() != n {
        return Err(Error::LengthMismatch {
            what: "volumes",
            expected: n,
            got: points.volumes.len(),
        });
    }
    if material.len() != n {
        return Err(Error::LengthMismatch {
            what: "material values",
            expected: n,
            got: material.len(),
        });
    }
    crate::error::check_finite_points("integration points", &points.points)?;
    if let Some(i) = points
        .volumes
        .iter()
        .position(|v| !(v.is_finite() && *v > 0.0))
    {
        return Err(Error::param(
            "volumes",
            format!("{} at point {i}", points.volumes[i]),
            "every integration volume must be positive and finite",
        ));
    }
    if n < opts.kernels {
        return Err(Error::param(
            "kernels",
            opts.kernels,
            format!("only {n} integration points; use fewer kernels or more points"),
        ));
    }
    let mut timings = Timings::default();
    let mut clock = Stopwatch::start();
    let total_clock = Stopwatch::start();
    let mut warnings = Vec::new();

    progress.begin("centers", Some(opts.kernels as u64));
    let mut idx = farthest_point_sampling(&points.points, opts.kernels)?;
    morton_order(&points.points, &mut idx);
    let centers: Vec<Point3> = idx.iter().map(|&i| points.points[i]).collect();
    let radii = support_radii(&centers, &opts.support)?;
    let mut kernels = Kernels {
        centers,
        radii,
        kind: opts.kernel,
    };
    progress.finish();
    timings.centers = clock.lap();

    // Shape functions and assembly run on the points in Morton order: the points of one
    // kernel's support are then close in memory, which speeds assembly up severalfold at
    // large N. Only the order of the sums changes; the caller's point order is untouched.
    let mut order: Vec<usize> = (0..n).collect();
    morton_order(&points.points, &mut order);
    let sorted: Vec<Point3> = order.iter().map(|&i| points.points[i]).collect();
    progress.begin("shape functions", None);
    let (sf, stats, enlarged, neighbor_time) =
        shape_functions_with_repair(&mut kernels, &sorted, opts).map_err(|e| match e {
            // Report the caller's point index, not the sorted one.
            Error::Coverage {
                count,
                index,
                position,
                covering,
                rcond,
                min_rcond,
            } => Error::Coverage {
                count,
                index: order[index],
                position,
                covering,
                rcond,
                min_rcond,
            },
            other => other,
        })?;
    progress.finish();
    timings.neighbors = neighbor_time;
    timings.shape_functions = clock.lap() - neighbor_time;
    let repro = rkpm::reproducing_error(&kernels, &sorted, &sf);
    if enlarged > 0 {
        warnings.push(format!(
            "{enlarged} kernel supports were enlarged to cover badly conditioned points"
        ));
    }

    progress.begin("assembly", None);
    let all_weights = material.hessian_weights();
    let volumes: Vec<f64> = order.iter().map(|&i| points.volumes[i]).collect();
    let weights: Vec<f64> = order.iter().map(|&i| all_weights[i]).collect();
    let assembled = assemble(&sf, &volumes, &weights, kernels.len())?;
    let sf_bytes = sf.memory_bytes();
    drop((sf, sorted, volumes, weights, all_weights));
    progress.finish();
    timings.assembly = clock.lap();

    timings.total = total_clock.elapsed();
    Ok(Prepared {
        kernels,
        assembled,
        points,
        material,
        timings,
        reproducing: repro,
        coverage: CoverageReport {
            min_moment_rcond: stats.min_rcond,
            min_cover: stats.min_cover,
            mean_cover: stats.mean_cover,
            max_cover: stats.max_cover,
            enlarged_kernels: enlarged,
            shape_function_bytes: sf_bytes,
        },
        warnings,
    })
}

/// The eigensolve on prepared matrices with `solver`, and the report.
pub fn solve_prepared(
    prepared: Prepared,
    opts: &BasisOptions,
    solver: &dyn Eigensolver,
    progress: &dyn Progress,
) -> Result<BasisRun> {
    let Prepared {
        kernels,
        assembled,
        points,
        material,
        mut timings,
        reproducing: repro,
        coverage,
        warnings,
    } = prepared;
    let n = points.len();
    let clock = Stopwatch::start();
    let request = EigenRequest {
        nev: opts.modes + 1,
        tol: opts.tol,
        max_iter: opts.max_iter,
    };
    let solution = solver.solve(&assembled.hessian, &assembled.mass, &request, progress)?;
    timings.eigensolve = clock.elapsed();
    timings.total += timings.eigensolve;
    let mut report = ModesReport {
        kernels: kernels.len(),
        points: n,
        modes: opts.modes,
        nnz_hessian: assembled.hessian.compute_nnz(),
        nnz_mass: assembled.mass.compute_nnz(),
        solver: solver.name().to_string(),
        eigenvalues: solution.values.clone(),
        max_relative_residual: solution.info.max_relative_residual,
        orthonormality_error: solution.info.orthonormality_error,
        reproducing_error: repro.max(),
        reproducing_detail: repro,
        timings_s: timings,
        peak_memory_bytes: peak_memory_bytes().unwrap_or(0),
        volume: points.total_volume(),
        kernel: opts.kernel,
        support: opts.support,
        coverage,
        eigen: solution.info.clone(),
        tol: opts.tol,
        warnings,
        monitors: Monitors::default(),
    };
    check_quality(&mut report);
    let basis = Basis {
        kernels,
        coefficients: solution.vectors,
        eigenvalues: solution.values,
    };
    Ok(BasisRun {
        basis,
        points,
        material,
        report,
    })
}

/// Shape functions at the integration points, enlarging the supports of kernels near badly
/// covered points for up to `opts.coverage_repair_rounds` rounds. Returns the shape functions,
/// their stats, the number of enlarged kernels and the neighbour-search time (s).
fn shape_functions_with_repair(
    kernels: &mut Kernels,
    points: &[Point3],
    opts: &BasisOptions,
) -> Result<(ShapeFunctions, ShapeStats, usize, f64)> {
    use kiddo::{ImmutableKdTree, SquaredEuclidean};
    let mut enlarged = std::collections::BTreeSet::new();
    let mut neighbor_time = 0.0;
    let mut round = 0;
    loop {
        let t = Stopwatch::start();
        let pattern = rkpm::covering_kernels(kernels, points);
        neighbor_time += t.elapsed();
        let (sf, stats) = rkpm::evaluate_on(kernels, points, pattern, &opts.shape_functions);
        if stats.failed.is_empty() {
            return Ok((sf, stats, enlarged.len(), neighbor_time));
        }
        if round == opts.coverage_repair_rounds {
            rkpm::coverage_error(points, &sf, &stats, opts.shape_functions.min_rcond)?;
        }
        round += 1;
        let tree: ImmutableKdTree<f64, 3> = ImmutableKdTree::new_from_slice(&kernels.centers)
            .map_err(|e| Error::param("kernels", kernels.len(), format!("k-d tree: {e:?}")))?;
        let four = std::num::NonZero::new(4).expect("4 > 0");
        let mut grow = std::collections::BTreeSet::new();
        for &i in &stats.failed {
            for r in tree
                .query(&points[i])
                .nearest_n::<SquaredEuclidean<f64>>(four)
                .execute()
            {
                grow.insert(r.item as usize);
            }
        }
        for &k in &grow {
            kernels.radii[k] *= 1.25;
        }
        enlarged.extend(grow);
    }
}
