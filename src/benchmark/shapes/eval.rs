//! One shape through the whole protocol: read and normalize, TetGen, the FEM reference of
//! each boundary condition, and the reduced model with free and boundary-aware bases against
//! it (error metric, basis fitting residual, precompute and step time).

use super::protocol::{boundary_regions, normalize, sim_options, Protocol, ShapeTest};
use super::reference::run_shape_reference;
use super::tetgen::{tetrahedralize, TetgenOptions};
use crate::benchmark::fit::fit_residual_from_weights;
use crate::fem::beam::{BeamReference, CacheStatus};
use crate::fem::solver::FemParams;
use crate::fem::ElementOrder;
use crate::geometry::{Shape, ShapeOptions, TriMesh};
use crate::material::MaterialOverride;
use crate::precompute::sampling::Resolution;
use crate::precompute::{
    build_basis, BasisOptions, BasisRun, BoundaryModes, DensityBands, KernelDensity,
};
use crate::progress::Progress;
use crate::report::Stopwatch;
use crate::sim::{NewtonOptions, ReducedSim};
use crate::{Error, Point3, Result};
use serde::Serialize;
use std::path::Path;

/// Everything an evaluation run depends on.
#[derive(Debug, Clone, Serialize)]
pub struct EvalOptions {
    /// Normalization, material, steps, regions and speeds.
    pub protocol: Protocol,
    /// The FEM mesh.
    pub tetgen: TetgenOptions,
    /// FEM solver settings (element order, tolerance; dt and gravity come from the
    /// protocol). Default: [`FemParams::default`] with quadratic elements.
    pub fem: FemParams,
    /// Modes m. Default 32 (the paper's Table 2).
    pub modes: usize,
    /// Kernels K. Default 1000.
    pub kernels: usize,
    /// Integration grid (None: the pipeline default, 50 K points).
    pub resolution: Option<Resolution>,
    /// Cubature points of the reduced simulation.
    pub cubature: usize,
    /// Newton settings of the reduced simulation.
    pub newton: NewtonOptions,
    /// The boundary conditions run.
    pub tests: Vec<ShapeTest>,
    /// The bases compared.
    pub boundaries: Vec<BoundaryModes>,
    /// The largest kernel spacing factor on thin parts ([`DensityBands::thin`]). Default 1
    /// (uniform placement).
    pub density_thin: f64,
    /// Material overrides over [`Protocol::material`], applied in order in the normalized
    /// shape's frame (metres, bounding box side 1): to the FEM tets by their centroids and to
    /// the reduced model's integration points, the same region rules. Default none
    /// (homogeneous).
    pub material_overrides: Vec<MaterialOverride>,
    /// The kernel spacing factor around material interfaces
    /// ([`DensityBands::interfaces`]). Default 1 (uniform placement).
    pub density_interfaces: f64,
    /// Closed surfaces inside the shape that the FEM mesh conforms to (vertices V x 3 in the
    /// normalized frame, metres; triangles F x 3, zero-based), e.g. the material interfaces of
    /// `material_overrides`, so that no tet straddles one. Passed to TetGen as further facets
    /// (kept unsplit by `-Y`); the reduced model does not see them. Default none. Not in the
    /// report (the FEM cache key holds the mesh they make).
    #[serde(skip)]
    pub fem_interfaces: Vec<(Vec<Point3>, Vec<[u32; 3]>)>,
}

impl Default for EvalOptions {
    fn default() -> Self {
        Self {
            protocol: Protocol::default(),
            tetgen: TetgenOptions::default(),
            fem: FemParams {
                order: ElementOrder::Quadratic,
                ..FemParams::default()
            },
            modes: 32,
            kernels: 1000,
            resolution: None,
            cubature: crate::sim::cubature::DEFAULT_CUBATURE,
            newton: NewtonOptions::default(),
            tests: ShapeTest::ALL.to_vec(),
            boundaries: vec![BoundaryModes::Free, BoundaryModes::Aware],
            density_thin: 1.0,
            material_overrides: Vec::new(),
            density_interfaces: 1.0,
            fem_interfaces: Vec::new(),
        }
    }
}

/// The reduced model against the FEM on one shape, test and basis.
#[derive(Debug, Clone, Serialize)]
pub struct ShapeRun {
    /// The boundary condition.
    pub test: ShapeTest,
    /// Free or boundary-aware basis.
    pub boundaries: BoundaryModes,
    /// mean |x_red - x_fem|^2 / D^2 over frames and FE nodes.
    pub normalized_mse: f64,
    /// max |x_red - x_fem| / D.
    pub max_error: f64,
    /// Basis fitting residual of the FEM frames: mean |r|^2 / D^2 (paper Table 7, MSE).
    pub fit_mse: f64,
    /// Basis fitting residual: max |r| / D (paper Table 7, max).
    pub fit_max: f64,
    /// Basis build plus reduced-model setup, s.
    pub precompute_s: f64,
    /// The basis build alone, s.
    pub basis_s: f64,
    /// Mean reduced step, ms.
    pub reduced_step_ms_mean: f64,
    /// Reduced steps that did not converge.
    pub reduced_nonconverged_steps: usize,
    /// Integration points.
    pub points: usize,
    /// Mean FEM step, ms (of the run that made the cached reference).
    pub fem_step_ms_mean: f64,
    /// Whether the FEM reference came from the cache.
    pub fem_cached: bool,
    /// Basis warnings and non-converged steps.
    pub warnings: Vec<String>,
}

/// One shape's results.
#[derive(Debug, Clone, Serialize)]
pub struct ShapeEval {
    /// File stem.
    pub name: String,
    /// Surface triangles (after welding).
    pub faces: usize,
    /// FE nodes (with edge nodes for quadratic elements).
    pub fem_nodes: usize,
    /// Tetrahedra of the TetGen mesh.
    pub fem_tets: usize,
    /// One per (test, basis) that ran.
    pub runs: Vec<ShapeRun>,
    /// The (test, basis) pairs that failed, with the reason.
    pub failures: Vec<String>,
}

/// Run the protocol on the shape file `path`: TetGen works in `work_dir`, FEM references
/// are cached in `cache_dir` (None: not cached).
///
/// # Errors
/// Reading, normalizing or meshing the shape, or a FEM reference failing for every test;
/// a failure of one (test, basis) pair is listed in [`ShapeEval::failures`] instead.
pub fn evaluate_shape(
    path: &Path,
    opts: &EvalOptions,
    cache_dir: Option<&Path>,
    work_dir: &Path,
    progress: &dyn Progress,
) -> Result<ShapeEval> {
    opts.protocol.validate()?;
    let name = path
        .file_stem()
        .map_or("shape".into(), |s| s.to_string_lossy().into_owned());
    let spec = path.to_string_lossy();
    let Shape::Mesh(mesh) = crate::io::read_shape(&spec, &ShapeOptions::default())? else {
        return Err(Error::param(
            "shape",
            spec.into_owned(),
            "the evaluation needs a closed triangle mesh (OFF, OBJ, STL or PLY)",
        ));
    };
    let shape = normalize(mesh.vertices(), mesh.triangles())?;
    let solid = Shape::Mesh(TriMesh::new(
        shape.vertices.clone(),
        shape.triangles.clone(),
        &ShapeOptions::default(),
    )?);
    progress.begin(&format!("{name}: TetGen"), None);
    let (fem_vertices, fem_triangles) = fem_surface(&shape, &opts.fem_interfaces)?;
    let tets = tetrahedralize(&fem_vertices, &fem_triangles, &opts.tetgen, work_dir, &name)?;
    progress.finish();
    let mut out = ShapeEval {
        name: name.clone(),
        faces: shape.triangles.len(),
        fem_nodes: 0,
        fem_tets: tets.num_tets(),
        runs: Vec::new(),
        failures: Vec::new(),
    };
    let mut free_basis: Option<(BasisRun, f64)> = None;
    for &test in &opts.tests {
        let reference = match run_shape_reference(
            &tets,
            &opts.protocol,
            &shape,
            test,
            &opts.material_overrides,
            &opts.fem,
            cache_dir,
            progress,
        ) {
            Ok(r) => r,
            Err(e) => {
                out.failures
                    .push(format!("{} FEM reference: {e}", test.name()));
                continue;
            }
        };
        out.fem_nodes = reference.rest.len();
        for &b in &opts.boundaries {
            let run = (|| -> Result<ShapeRun> {
                let built;
                let (basis, seconds) = match b {
                    BoundaryModes::Free => {
                        if free_basis.is_none() {
                            free_basis = Some(timed_basis(&solid, opts, Vec::new(), progress)?);
                        }
                        let (r, s) = free_basis.as_ref().ok_or_else(|| {
                            Error::param("basis", "free", "not built (internal error)")
                        })?;
                        (r, *s)
                    }
                    BoundaryModes::Aware => {
                        let regions = boundary_regions(&opts.protocol, &shape, test)
                            .into_iter()
                            .map(|(r, _)| r)
                            .collect();
                        built = timed_basis(&solid, opts, regions, progress)?;
                        (&built.0, built.1)
                    }
                };
                simulate(&shape, test, b, basis, seconds, &reference, opts, progress)
            })();
            match run {
                Ok(r) => out.runs.push(r),
                Err(e) => out
                    .failures
                    .push(format!("{} {} basis: {e}", test.name(), b.name())),
            }
        }
    }
    if out.runs.is_empty() && !out.failures.is_empty() {
        return Err(Error::param("shape", name, out.failures.join("; ")));
    }
    Ok(out)
}

/// The surface TetGen meshes: the shape's, then each of `interfaces` (closed surfaces inside
/// it, [`EvalOptions::fem_interfaces`]) with its indices moved past the vertices before it.
///
/// # Errors
/// [`Error::NonFinite`] for a non-finite interface vertex; [`Error::InvalidParameter`] for an
/// interface triangle that refers past its vertices.
pub fn fem_surface(
    shape: &super::protocol::NormalizedShape,
    interfaces: &[(Vec<Point3>, Vec<[u32; 3]>)],
) -> Result<(Vec<Point3>, Vec<[u32; 3]>)> {
    let (mut vertices, mut triangles) = (shape.vertices.clone(), shape.triangles.clone());
    for (v, t) in interfaces {
        crate::error::check_finite_points("fem_interfaces vertices", v)?;
        if let Some(f) = t
            .iter()
            .position(|f| f.iter().any(|&i| i as usize >= v.len()))
        {
            return Err(Error::param(
                "fem_interfaces",
                format!("triangle {f} = {:?}", t[f]),
                format!("refers past the surface's {} vertices", v.len()),
            ));
        }
        let offset = vertices.len() as u32;
        vertices.extend_from_slice(v);
        triangles.extend(t.iter().map(|f| f.map(|i| i + offset)));
    }
    Ok((vertices, triangles))
}

fn timed_basis(
    solid: &Shape,
    opts: &EvalOptions,
    regions: Vec<crate::material::Region>,
    progress: &dyn Progress,
) -> Result<(BasisRun, f64)> {
    let clock = Stopwatch::start();
    let basis_opts = BasisOptions {
        kernels: opts.kernels,
        modes: opts.modes,
        resolution: opts.resolution,
        material: opts.protocol.material,
        overrides: opts.material_overrides.clone(),
        boundary_regions: regions,
        density: KernelDensity::bands(DensityBands {
            thin: opts.density_thin,
            interfaces: opts.density_interfaces,
            ..DensityBands::off()
        }),
        ..BasisOptions::default()
    };
    let run = build_basis(solid, &basis_opts, progress)?;
    Ok((run, clock.elapsed()))
}

#[allow(clippy::too_many_arguments)]
fn simulate(
    shape: &super::protocol::NormalizedShape,
    test: ShapeTest,
    boundaries: BoundaryModes,
    run: &BasisRun,
    basis_s: f64,
    reference: &BeamReference,
    opts: &EvalOptions,
    progress: &dyn Progress,
) -> Result<ShapeRun> {
    let clock = Stopwatch::start();
    let sim_opts = sim_options(&opts.protocol, shape, test, opts.cubature, opts.newton);
    let mut sim = ReducedSim::new(&run.basis, &run.points, &run.material, &sim_opts)?;
    let weights = run.basis.weights(&reference.rest)?;
    let precompute_s = basis_s + clock.elapsed();
    let steps = reference.frames.len();
    progress.begin(
        &format!("reduced {} {}", test.name(), boundaries.name()),
        Some(steps as u64),
    );
    let mut frames: Vec<Vec<Point3>> = Vec::with_capacity(steps);
    let (mut step_s, mut nonconverged) = (0.0, 0);
    let mut warnings = run.report.warnings.clone();
    for k in 0..steps {
        let r = sim.step();
        step_s += r.wall_s;
        if !r.solve.converged {
            nonconverged += 1;
            warnings.push(format!(
                "reduced step {} did not converge ({} iterations, residual {:.2e})",
                k + 1,
                r.solve.iterations,
                r.solve.residual
            ));
        }
        frames.push(sim.positions(&reference.rest, &weights));
        progress.set_position(k as u64 + 1);
    }
    progress.finish();
    let err = reference.error_of(&frames)?;
    let fit = fit_residual_from_weights(&weights, &reference.rest, &reference.frames)?;
    Ok(ShapeRun {
        test,
        boundaries,
        normalized_mse: err.normalized_mse,
        max_error: err.max_error,
        fit_mse: fit.mean_squared_over_diagonal2,
        fit_max: fit.max_over_diagonal,
        precompute_s,
        basis_s,
        reduced_step_ms_mean: 1e3 * step_s / steps.max(1) as f64,
        reduced_nonconverged_steps: nonconverged,
        points: run.points.len(),
        fem_step_ms_mean: reference.step_ms_mean(),
        fem_cached: matches!(reference.cache, CacheStatus::Hit(_)),
        warnings,
    })
}
