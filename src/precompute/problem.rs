//! The precomputation as one object: a [`Problem`] is built from a shape or from points
//! (sampled, kernels placed, shape functions evaluated, H_w and M assembled), then solved with
//! a chosen eigensolver into a [`BasisRun`] (the basis and its report).

use super::assembly::Assembled;
use super::boundary_modes;
use super::centers::{farthest_point_sampling_scaled, morton_order};
use super::coverage::{cover_shape_surface, enlarge_near};
use super::density::{kernel_scale, WholeObject};
use super::memory::{expected_points, MemoryEstimate};
use super::options::BasisOptions;
use super::quality::{CoverageReport, ModesReport, SolveFacts};
use super::rkpm::{self, support_radii, Kernels, ReproducingError};
use super::sampling::MAX_GRID_CELLS;
use super::sampling::{sample_with_material, IntegrationPoints};
use super::skinning::Basis;
use super::stream::{assemble_streamed, assemble_streamed_upper, Streamed, StreamedAssembly};
use crate::eigen::{EigenError, EigenRequest, Eigensolver, OperatorProblem};
use crate::error::check_cancelled;
use crate::geometry::Shape;
use crate::material::MaterialField;
use crate::progress::Progress;
use crate::report::{Stopwatch, Timings};
use crate::{Error, Point3, Result};
use std::collections::BTreeSet;

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

/// Run the whole precomputation on a shape with `opts.solver`: the one-liner for
/// `Problem::from_shape(shape, opts, progress)?.solve(progress)`.
///
/// ```
/// use freeform::geometry::Shape;
/// use freeform::precompute::{build_basis, BasisOptions};
/// let shape = freeform::io::read_shape("box:2,1,1", &Default::default())?;
/// let opts = BasisOptions { kernels: 60, modes: 4, ..BasisOptions::default() };
/// let run = build_basis(&shape, &opts, &freeform::progress::Silent)?;
/// assert_eq!(run.basis.modes(), 5); // m + 1 handles, the first the constant mode
/// assert!(run.report.max_relative_residual < 1e-6);
/// # Ok::<(), freeform::Error>(())
/// ```
pub fn build_basis(
    shape: &Shape,
    opts: &BasisOptions,
    progress: &dyn Progress,
) -> Result<BasisRun> {
    // A solver this build cannot run (SLEPc without the feature) fails before sampling.
    let solver = opts.solver.build()?;
    Problem::from_shape(shape, opts, progress)?.solve_inner(solver.as_ref(), progress, true)
}

/// The assembled generalized eigenproblem H_w c = lambda M c of one object, with everything
/// needed to turn its solution into a basis and a report. Built by [`Problem::from_shape`] or
/// [`Problem::from_points`]; solved by [`Problem::solve`] (the solver `options.solver` names)
/// or [`Problem::solve_with`] (any [`Eigensolver`], e.g. SLEPc). [`Problem::matrices`] is what
/// `freeform export` writes and `freeform compare` hands to each solver.
///
/// ```
/// use freeform::geometry::Shape;
/// use freeform::precompute::{BasisOptions, Problem};
/// use freeform::eigen::dense::DenseSolver;
/// let shape = freeform::io::read_shape("sphere:0.5", &Default::default())?;
/// let opts = BasisOptions { kernels: 50, modes: 3, ..BasisOptions::default() };
/// let problem = Problem::from_shape(&shape, &opts, &freeform::progress::Silent)?;
/// assert_eq!(problem.matrices().hessian().nrows(), 50); // K x K
/// let run = problem.solve_with(&DenseSolver, &freeform::progress::Silent)?;
/// assert_eq!(run.report.solver, "dense");
/// # Ok::<(), freeform::Error>(())
/// ```
#[derive(Debug, Clone)]
pub struct Problem {
    options: BasisOptions,
    kernels: Kernels,
    assembled: Assembled,
    points: IntegrationPoints,
    material: MaterialField,
    timings: Timings,
    reproducing: ReproducingError,
    coverage: CoverageReport,
    warnings: Vec<String>,
    memory: MemoryEstimate,
    /// The shape the points were sampled from, when sampling it again is cheap and gives the
    /// same points bit for bit (box, sphere, image): the points and materials are then not
    /// held while the eigensolver runs, and are sampled again for the result.
    resample: Option<Shape>,
}

/// The integration points through the eigensolve: held, or to be sampled again from the shape.
enum Points<'a> {
    Held(IntegrationPoints, MaterialField),
    SampleAgain(&'a Shape),
}

/// The shape to sample again after the eigensolve instead of holding its points through it:
/// primitives and images (grid sampling: deterministic, and fast next to the solve). Meshes
/// (a winding-number test per point) and point clouds (the points are the shape) are held.
fn resample_source(shape: &Shape) -> Option<Shape> {
    match shape {
        Shape::Box { .. } | Shape::Sphere { .. } | Shape::Image(_) => Some(shape.clone()),
        Shape::Mesh(_) | Shape::PointCloud(_) => None,
    }
}

/// Kernel centres by farthest point sampling of `points` (N x 3, metres), weighted by `scale`
/// (N factors from [`super::density::kernel_scale`], None for uniform), in Morton order (the
/// row and column order of H_w and M), with support radii by `opts.support`: the stage that
/// the pipeline and the MPI path share, so every rank places the same kernels.
pub fn place_kernels(
    points: &[Point3],
    scale: Option<&[f64]>,
    opts: &BasisOptions,
) -> Result<Kernels> {
    let n = points.len();
    if n < opts.kernels {
        return Err(Error::param(
            "kernels",
            opts.kernels,
            format!("only {n} integration points; use fewer kernels or more points"),
        ));
    }
    let mut idx = farthest_point_sampling_scaled(points, scale, opts.kernels)?;
    morton_order(points, &mut idx);
    let centers: Vec<Point3> = idx.iter().map(|&i| points[i]).collect();
    let radii = support_radii(&centers, &opts.support)?;
    Ok(Kernels {
        centers,
        radii,
        kind: opts.kernel,
    })
}

impl Problem {
    /// Sample `shape` ([`sample_with_material`]: `opts.resolution`, `opts.material`,
    /// `opts.overrides`) and assemble its eigenproblem.
    pub fn from_shape(shape: &Shape, opts: &BasisOptions, progress: &dyn Progress) -> Result<Self> {
        opts.validate()?;
        // Refuse a run that would not fit before anything is allocated. A grid of more cells
        // than sampling allows is refused by sampling's own guard, with its message; the
        // estimate is then checked after sampling, with the exact count.
        let expected = expected_points(shape, opts);
        let mut memory = MemoryEstimate::new(opts, expected);
        let checked = if expected as u128 <= MAX_GRID_CELLS {
            memory.check()?;
            Some(memory)
        } else {
            None
        };
        let clock = Stopwatch::start();
        progress.begin("sampling", None);
        let (points, material) = sample_with_material(shape, opts)?;
        progress.finish();
        check_cancelled(progress, "sampling")?;
        let sampling = clock.elapsed();
        let mut problem = Self::assemble(points, material, opts, progress, checked, Some(shape))?;
        problem.timings.sampling = sampling;
        problem.timings.total += sampling;
        problem.resample = resample_source(shape);
        Ok(problem)
    }

    /// Assemble the eigenproblem on given integration points (N x 3, metres, with volumes,
    /// m^3) and per-point materials (N entries). `opts.resolution`, `opts.material`,
    /// `opts.overrides` and `opts.cloud` are not used here (the caller made those choices).
    pub fn from_points(
        points: IntegrationPoints,
        material: MaterialField,
        opts: &BasisOptions,
        progress: &dyn Progress,
    ) -> Result<Self> {
        Self::assemble(points, material, opts, progress, None, None)
    }

    /// [`Problem::from_points`] with the memory estimate already checked (`memory`), or
    /// checked here (None), and the shape whose surface's coverage is repaired before the
    /// assembly ([`cover_shape_surface`]; None for given points).
    fn assemble(
        points: IntegrationPoints,
        material: MaterialField,
        opts: &BasisOptions,
        progress: &dyn Progress,
        memory: Option<MemoryEstimate>,
        shape: Option<&Shape>,
    ) -> Result<Self> {
        opts.validate()?;
        points.check(&material)?;
        let n = points.len();
        let memory = match memory {
            Some(m) => m,
            None => {
                let mut m = MemoryEstimate::new(opts, n);
                m.check()?;
                m
            }
        };
        let mut timings = Timings::default();
        let mut clock = Stopwatch::start();
        let total_clock = Stopwatch::start();
        let mut warnings = Vec::new();

        progress.begin("centers", Some(opts.kernels as u64));
        let volume: f64 = points.volumes.iter().sum();
        let scale = kernel_scale(
            &points.points,
            volume,
            opts.kernels,
            &opts.density,
            &opts.boundary_regions,
            Some(WholeObject {
                material: &material,
                volumes: &points.volumes,
            }),
        )?;
        let mut kernels = place_kernels(&points.points, scale.as_deref(), opts)?;
        drop(scale);
        let mut surface = cover_shape_surface(&mut kernels, shape, volume, opts)?;
        warnings.extend(surface.warning(opts.coverage_repair_rounds));
        progress.finish();
        check_cancelled(progress, "centers")?;
        timings.centers = clock.lap();

        // Shape functions and assembly run on the points in Morton order: the points of one
        // kernel's support are then close in memory (and a chunk of points is compact), which
        // speeds assembly up severalfold at large N. Only the order of the sums changes; the
        // caller's point order is untouched.
        let mut order: Vec<usize> = (0..n).collect();
        morton_order(&points.points, &mut order);
        let sorted: Vec<Point3> = order.iter().map(|&i| points.points[i]).collect();
        let all_weights = material.hessian_weights();
        let volumes: Vec<f64> = order.iter().map(|&i| points.volumes[i]).collect();
        let weights: Vec<f64> = order.iter().map(|&i| all_weights[i]).collect();
        drop(all_weights);
        let (streamed, enlarged) = stream_with_repair(
            &mut kernels,
            &sorted,
            &volumes,
            &weights,
            opts,
            opts.upper_triangle_storage(),
            progress,
            std::mem::take(&mut surface.enlarged),
        )
        .map_err(|e| match e {
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
        drop((sorted, volumes, weights, order));
        check_cancelled(progress, "assembly")?;
        let StreamedAssembly {
            assembled,
            stats,
            reproducing,
            largest_chunk_bytes,
            neighbors_s,
            shape_functions_s,
            assembly_s,
        } = *streamed;
        timings.neighbors = neighbors_s;
        timings.shape_functions = shape_functions_s;
        timings.assembly = assembly_s;
        if enlarged > 0 {
            warnings.push(format!(
                "{enlarged} kernel supports were enlarged to cover badly conditioned points"
            ));
        }

        timings.total = total_clock.elapsed();
        Ok(Self {
            options: opts.clone(),
            kernels,
            assembled,
            points,
            material,
            timings,
            reproducing,
            coverage: CoverageReport {
                min_moment_rcond: stats.min_rcond,
                min_cover: stats.min_cover,
                mean_cover: stats.mean_cover,
                max_cover: stats.max_cover,
                enlarged_kernels: enlarged,
                shape_function_bytes: largest_chunk_bytes,
                surface_points: surface.points,
                uncovered_surface_points: surface.uncovered,
            },
            warnings,
            memory,
            resample: None,
        })
    }

    /// The options the problem was built with.
    pub fn options(&self) -> &BasisOptions {
        &self.options
    }

    /// H_w (Pa m) and M (m^3), K x K, rows and columns in the kernels' (Morton) order.
    pub fn matrices(&self) -> &Assembled {
        &self.assembled
    }

    /// The matrices, without the rest of the problem.
    pub fn into_matrices(self) -> Assembled {
        self.assembled
    }

    /// The kernels (Morton order: the row and column order of the matrices).
    pub fn kernels(&self) -> &Kernels {
        &self.kernels
    }

    /// Integration points (N x 3, metres) and volumes (N, m^3), in the caller's order.
    pub fn points(&self) -> &IntegrationPoints {
        &self.points
    }

    /// Material per integration point.
    pub fn material(&self) -> &MaterialField {
        &self.material
    }

    /// Stage timings so far (sampling to assembly; the eigensolve is not yet run), seconds.
    pub fn timings(&self) -> &Timings {
        &self.timings
    }

    /// Coverage figures of the shape-function stage.
    pub fn coverage(&self) -> &CoverageReport {
        &self.coverage
    }

    /// The eigenproblem's request: m + 1 pairs at the options' tolerance and iteration cap.
    pub fn request(&self) -> EigenRequest {
        EigenRequest {
            nev: self.options.modes + 1,
            tol: self.options.tol,
            max_iter: self.options.max_iter,
        }
    }

    /// Solve with the eigensolver `options.solver` describes.
    ///
    /// # Errors
    /// [`crate::eigen::EigenError::SlepcUnavailable`] for SLEPc in a build without it; the
    /// solver's own errors.
    /// A solve that does not converge is an error here
    /// ([`crate::eigen::EigenError::NotConverged`] with the partial result), as in
    /// [`build_basis`].
    pub fn solve(self, progress: &dyn Progress) -> Result<BasisRun> {
        let solver = self.options.solver.build()?;
        self.solve_inner(solver.as_ref(), progress, true)
    }

    /// Solve with `solver` and build the basis and its report (the report names the solver
    /// that ran). A solve that stops before convergence still gives the run, built from the
    /// pairs the solver has (possibly fewer than m + 1 from an external solver): its
    /// `report.eigen.status` says how it stopped and `report.warnings` says it did not
    /// converge. [`Problem::solve`] makes that an error instead.
    pub fn solve_with(self, solver: &dyn Eigensolver, progress: &dyn Progress) -> Result<BasisRun> {
        self.solve_inner(solver, progress, false)
    }

    /// The eigensolve and the basis; `require_converged`: a not-converged status is an error.
    fn solve_inner(
        self,
        solver: &dyn Eigensolver,
        progress: &dyn Progress,
        require_converged: bool,
    ) -> Result<BasisRun> {
        let request = self.request();
        let Problem {
            options: opts,
            kernels,
            assembled,
            points,
            material,
            mut timings,
            reproducing: repro,
            coverage,
            warnings,
            memory,
            resample,
        } = self;
        let clock = Stopwatch::start();
        check_cancelled(progress, "eigensolve")?;
        let regions = &opts.boundary_regions;
        // A solver that reads both triangles gets them in place of the upper triangle (not
        // beside it).
        let assembled = match assembled.upper() {
            Some(_) if !regions.is_empty() || !solver.solves_upper_triangles() => {
                assembled.into_full()
            }
            _ => assembled,
        };
        // A boundary-aware basis solves the grounded restricted problem (boundary_modes.rs)
        // for the free modes; the lifts come after the solve.
        let aware = if regions.is_empty() {
            None
        } else {
            let free_modes = request.nev - regions.len();
            let part = boundary_modes::partition(&kernels, &points, regions, free_modes)?;
            let (h, m) =
                boundary_modes::grounded_problem(assembled.hessian(), assembled.mass(), &part);
            Some((part, h, m, free_modes))
        };
        // Points the shape gives again bit for bit are not held through the solve (0.56 GB
        // of points and materials at K = 1,000,000).
        let points = match &resample {
            Some(shape) if aware.is_none() => {
                drop((points, material));
                Points::SampleAgain(shape)
            }
            _ => Points::Held(points, material),
        };
        // Upper-triangle storage goes to a solver that takes it as is; any other gets both
        // triangles (mirrored on first use by `assembled.hessian()`).
        let solved = match (assembled.upper(), &aware) {
            (Some(upper), None) if solver.solves_upper_triangles() => {
                let (hu, mu) = (upper.first(), upper.second());
                solver.solve_operators(&OperatorProblem::new(&hu, &mu), &request, progress)
            }
            (_, None) => solver.solve(assembled.hessian(), assembled.mass(), &request, progress),
            (_, Some((_, h, m, free_modes))) => {
                let request = EigenRequest {
                    nev: free_modes + 1,
                    ..request
                };
                solver.solve(h.as_ref(), m.as_ref(), &request, progress)
            }
        };
        let mut solution = solved.map_err(|e| match e {
            EigenError::Cancelled { iterations } => Error::Cancelled {
                stage: format!("eigensolve ({iterations} iterations)"),
            },
            other => other.into(),
        })?;
        if require_converged {
            solution = solution.into_converged()?;
        }
        let mut boundaries = Vec::new();
        if let Some((part, ..)) = &aware {
            let (coefficients, values, reports) = boundary_modes::assemble_aware(
                assembled.hessian(),
                assembled.mass(),
                part,
                regions,
                &solution,
            )?;
            solution.info.notes.push(format!(
                "boundary-aware: {} lifts, {} free modes on {} of {} kernels (residuals and \
                 orthonormality are those of the restricted problem)",
                part.regions(),
                values.len() - part.regions(),
                part.free.len(),
                kernels.len()
            ));
            solution.vectors = coefficients;
            solution.values = values;
            boundaries = reports;
        }
        timings.eigensolve = clock.elapsed();
        timings.total += timings.eigensolve;
        let (points, material) = match points {
            Points::Held(points, material) => (points, material),
            Points::SampleAgain(shape) => {
                let clock = Stopwatch::start();
                let again = sample_with_material(shape, &opts)?;
                let seconds = clock.elapsed();
                timings.sampling += seconds;
                timings.total += seconds;
                again
            }
        };
        let facts = SolveFacts {
            solver: solver.name().to_string(),
            nnz: (assembled.nnz(), assembled.nnz()),
            timings,
            coverage,
            warnings,
            memory,
        };
        let mut report = ModesReport::of_solve(
            &opts,
            kernels.len(),
            points.len(),
            points.total_volume(),
            &solution,
            repro,
            facts,
        );
        report.boundaries = boundaries;
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
}

/// Points per chunk of the streamed assembly in the pipeline.
const CHUNK: usize = rkpm::CHUNK_POINTS;

/// The streamed shape functions and assembly ([`assemble_streamed`], or
/// [`assemble_streamed_upper`] with `upper_triangle`) on the points (Morton order), enlarging the supports of kernels near badly covered points for up to
/// `opts.coverage_repair_rounds` rounds (each round streams again). Returns the assembly and
/// the number of enlarged kernels (with those already in `enlarged`); the stage times of
/// failed rounds are counted in.
#[allow(clippy::too_many_arguments)]
fn stream_with_repair(
    kernels: &mut Kernels,
    points: &[Point3],
    volumes: &[f64],
    weights: &[f64],
    opts: &BasisOptions,
    upper_triangle: bool,
    progress: &dyn Progress,
    mut enlarged: BTreeSet<usize>,
) -> Result<(Box<StreamedAssembly>, usize)> {
    let mut round = 0;
    let mut lost = 0.0;
    let assemble = if upper_triangle {
        assemble_streamed_upper
    } else {
        assemble_streamed
    };
    loop {
        let clock = Stopwatch::start();
        let chunked = match assemble(
            kernels,
            points,
            volumes,
            weights,
            &opts.shape_functions,
            CHUNK,
            progress,
        )? {
            Streamed::Assembled(mut done) => {
                done.shape_functions_s += lost;
                return Ok((done, enlarged.len()));
            }
            Streamed::Uncovered(chunked) => chunked,
        };
        lost += clock.elapsed();
        if round == opts.coverage_repair_rounds {
            chunked.coverage_error(|i| points[i], opts.shape_functions.min_rcond)?;
        }
        round += 1;
        let failed: Vec<Point3> = chunked.stats().failed.iter().map(|&i| points[i]).collect();
        enlarged.extend(enlarge_near(kernels, &failed)?);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::{VoxelImage, VoxelValues};
    use crate::progress::Silent;

    /// The points and materials a solved run returns for shapes that are sampled again after
    /// the eigensolve are the very ones the problem was assembled on (`Problem::points` before
    /// the solve), bit for bit, and the basis is the one of a run that holds them.
    #[test]
    fn points_sampled_again_after_the_solve_are_the_assembled_ones() {
        let image = VoxelImage::new(
            [6, 4, 3],
            [0.1, 0.1, 0.1],
            [0.0; 3],
            VoxelValues::Moduli((0..72).map(|i| 1e5 * (1 + i % 3) as f64).collect()),
        )
        .unwrap();
        for shape in [
            Shape::Box {
                size: [2.0, 1.0, 0.5],
            },
            Shape::Sphere { radius: 0.4 },
            Shape::Image(std::sync::Arc::new(image)),
        ] {
            let opts = BasisOptions {
                kernels: 40,
                modes: 4,
                ..BasisOptions::default()
            };
            let problem = Problem::from_shape(&shape, &opts, &Silent).unwrap();
            assert!(problem.resample.is_some(), "{}", shape.kind());
            let (points, material) = (problem.points().clone(), problem.material().clone());
            let mut held = problem.clone();
            held.resample = None;
            let run = problem.solve(&Silent).unwrap();
            assert_eq!(run.points, points, "{}", shape.kind());
            assert_eq!(run.material, material, "{}", shape.kind());
            let kept = held.solve(&Silent).unwrap();
            assert_eq!(run.basis.coefficients, kept.basis.coefficients);
        }
    }
}
