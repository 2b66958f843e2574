//! Running a scene: per object, the basis (from the cache or computed), the reduced model,
//! the render points and their weights; then the time loop, frame output and the summary.

use super::cache;
use super::spec::{Format, ObjectSpec, Scene};
use crate::error::check_strict;
use crate::geometry::{Shape, ShapeOptions};
use crate::io::vtk::{self, PointData};
use crate::material::MaterialField;
use crate::precompute::sampling::IntegrationPoints;
use crate::precompute::skinning::{Basis, SkinningWeights};
use crate::precompute::{build_basis, sample_with_material, BasisOptions};
use crate::progress::Progress;
use crate::report::{Monitors, Stopwatch};
use crate::sim::{ReducedSim, SimOptions, StepReport};
use crate::{Error, Point3, Result};
use serde::Serialize;
use std::path::{Path, PathBuf};

/// Where a run reads relative paths from and writes to.
#[derive(Debug, Clone, Default)]
pub struct RunSettings {
    /// Directory that relative shape paths and the cache directory are resolved against
    /// (the scene file's directory for `freeform run`).
    pub base_dir: PathBuf,
    /// Output directory for frames (None: simulate and summarise only).
    pub out: Option<PathBuf>,
    /// Stop with [`Error::Strict`] at the first warning (a poorly conditioned basis, a
    /// step that did not converge, a failed line search, a Cholesky fallback) instead of
    /// reporting it in the summary. Frames already written stay; the `.pvd` collection is
    /// only written by a complete run.
    pub strict: bool,
}

/// One step of one object in the summary.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct StepRow {
    /// Step number (1-based).
    pub step: usize,
    /// Wall time, ms.
    pub wall_ms: f64,
    /// Solver iterations.
    pub iterations: usize,
    /// Energy/gradient evaluations.
    pub evaluations: usize,
    /// Whether the step met the tolerance.
    pub converged: bool,
    /// Final convergence measure.
    pub residual: f64,
    /// Incremental potential at the end of the step, J.
    pub energy: f64,
    /// Line-search step halvings.
    pub line_search_cutbacks: usize,
    /// Whether the line search failed.
    pub line_search_failed: bool,
    /// Smallest det F over the cubature points.
    pub min_det: f64,
    /// Cubature points with det F <= 0.
    pub inverted: usize,
    /// Collider penetrations at the end of the step.
    pub contacts: usize,
}

impl From<&StepReport> for StepRow {
    fn from(r: &StepReport) -> Self {
        let s = &r.solve;
        StepRow {
            step: r.step,
            wall_ms: r.wall_s * 1e3,
            iterations: s.iterations,
            evaluations: s.evaluations,
            converged: s.converged,
            residual: s.residual,
            energy: s.energy,
            line_search_cutbacks: s.line_search_cutbacks,
            line_search_failed: s.line_search_failed,
            min_det: s.info.min_det,
            inverted: s.info.inverted,
            contacts: s.info.contacts,
        }
    }
}

/// Summary of one object's run.
#[derive(Debug, Clone, Serialize)]
pub struct ObjectSummary {
    /// Object name.
    pub name: String,
    /// Shape specification.
    pub shape: String,
    /// Kernels K.
    pub kernels: usize,
    /// Modes m.
    pub modes: usize,
    /// Integration points.
    pub points: usize,
    /// Cubature points.
    pub cubature_points: usize,
    /// Render points written per frame.
    pub render_points: usize,
    /// The terms of the incremental potential that were built.
    pub terms: Vec<String>,
    /// Whether the basis came from the cache.
    pub basis_cached: bool,
    /// The cached basis file, if caching is on.
    pub basis_file: Option<String>,
    /// Basis precomputation (or cache load) time, s.
    pub precompute_s: f64,
    /// Reduced-model setup time (weights, moments, rest factorization), s.
    pub setup_s: f64,
    /// Mean and max step wall time, ms.
    pub step_ms_mean: f64,
    /// Max step wall time, ms.
    pub step_ms_max: f64,
    /// Mean solver iterations per step.
    pub iterations_mean: f64,
    /// Max solver iterations in one step.
    pub iterations_max: usize,
    /// Steps that did not meet the tolerance.
    pub nonconverged_steps: usize,
    /// Steps whose line search failed.
    pub line_search_failures: usize,
    /// Line-search step halvings over the run.
    pub line_search_cutbacks: usize,
    /// Smallest det F seen.
    pub min_det: f64,
    /// Conditioning and convergence monitors (the same keys as in `modes` and `beam`); the
    /// precomputation ones come from the cache file's metadata when the basis was cached.
    pub monitors: Monitors,
    /// Per-step rows.
    pub steps: Vec<StepRow>,
}

/// Summary of a scene run.
#[derive(Debug, Clone, Serialize)]
pub struct RunSummary {
    /// Time step, s.
    pub dt: f64,
    /// Steps simulated.
    pub steps: usize,
    /// Frames written per object (0 without an output directory).
    pub frames: usize,
    /// Output files written.
    pub files: Vec<String>,
    /// Per-object summaries.
    pub objects: Vec<ObjectSummary>,
    /// Total wall time, s.
    pub total_s: f64,
    /// Warnings (non-converged steps, cache problems...).
    pub warnings: Vec<String>,
}

/// An object ready to step.
struct Prepared {
    spec: ObjectSpec,
    sim: ReducedSim,
    render: Vec<Point3>,
    triangles: Option<Vec<[u32; 3]>>,
    weights: SkinningWeights,
    summary: ObjectSummary,
    pvd: Vec<(f64, String)>,
    /// Whether the inversion warning was given.
    warned_inverted: bool,
}

fn is_primitive(spec: &str) -> bool {
    let t = spec.trim().to_ascii_lowercase();
    t.starts_with("box:") || t.starts_with("sphere:")
}

/// Resolve a relative shape path against `base`.
fn resolve_shape(spec: &str, base: &Path) -> (String, Option<PathBuf>) {
    if is_primitive(spec) {
        return (spec.to_string(), None);
    }
    let p = Path::new(spec.trim());
    let full = if p.is_relative() {
        base.join(p)
    } else {
        p.to_path_buf()
    };
    (full.display().to_string(), Some(full))
}

/// An object's shape with the specification it was read from.
struct ResolvedShape {
    shape: Shape,
    /// The specification with relative paths resolved.
    spec: String,
    /// The file, for file shapes.
    file: Option<PathBuf>,
}

/// What [`object_basis`] returns.
struct ObjectBasis {
    basis: Basis,
    points: IntegrationPoints,
    material: MaterialField,
    cached: bool,
    file: Option<PathBuf>,
    /// Precomputation monitors (from the cache file's metadata for a cached basis).
    monitors: Monitors,
}

/// Basis, integration points and materials of an object (from the cache when possible).
fn object_basis(
    spec: &ObjectSpec,
    shape: &ResolvedShape,
    scene: &Scene,
    settings: &RunSettings,
    progress: &dyn Progress,
    warnings: &mut Vec<String>,
) -> Result<ObjectBasis> {
    let opts: BasisOptions = spec.basis_options()?;
    let cache_dir = scene.cache.enabled.then(|| {
        if scene.cache.dir.is_relative() {
            settings.base_dir.join(&scene.cache.dir)
        } else {
            scene.cache.dir.clone()
        }
    });
    let key = match &cache_dir {
        Some(_) => Some(cache::key(
            // Paths enter the key by content, not by name.
            if shape.file.is_some() {
                "file"
            } else {
                &shape.spec
            },
            shape.file.as_deref(),
            &opts,
        )?),
        None => None,
    };
    if let (Some(dir), Some(key)) = (&cache_dir, &key) {
        let mut warn = |w: String| warnings.push(format!("object '{}': {w}", spec.name));
        if let Some((basis, metadata)) = cache::load(dir, key, opts.modes, &mut warn) {
            let (points, material) = sample_with_material(&shape.shape, &opts)?;
            // The warnings of the run that produced the cached basis still apply.
            let stored = metadata
                .get("report")
                .and_then(|r| r.get("warnings"))
                .and_then(|w| w.as_array())
                .into_iter()
                .flatten()
                .filter_map(|w| w.as_str());
            warnings.extend(stored.map(|w| format!("object '{}': {w}", spec.name)));
            return Ok(ObjectBasis {
                basis,
                points,
                material,
                cached: true,
                file: Some(cache::path(dir, key)),
                monitors: Monitors::from_metadata(&metadata),
            });
        }
    }
    let run = build_basis(&shape.shape, &opts, progress)?;
    warnings.extend(
        run.report
            .warnings
            .iter()
            .map(|w| format!("object '{}': {w}", spec.name)),
    );
    let mut file_out = None;
    if let (Some(dir), Some(key)) = (&cache_dir, &key) {
        let meta = serde_json::json!({
            "freeform_version": env!("CARGO_PKG_VERSION"),
            "shape": shape.spec,
            "options": opts,
            "report": run.report,
        });
        file_out = Some(cache::store(dir, key, &run.basis, &meta)?);
    }
    Ok(ObjectBasis {
        basis: run.basis,
        points: run.points,
        material: run.material,
        cached: false,
        file: file_out,
        monitors: run.report.monitors,
    })
}

fn prepare(
    spec: &ObjectSpec,
    scene: &Scene,
    settings: &RunSettings,
    progress: &dyn Progress,
    warnings: &mut Vec<String>,
) -> Result<Prepared> {
    let ctx = |e: Error| Error::Scene {
        message: format!("object '{}': {e}", spec.name),
    };
    let (shape_spec, file) = resolve_shape(&spec.shape, &settings.base_dir);
    let shape = crate::io::read_shape(
        &shape_spec,
        &ShapeOptions {
            allow_open_mesh: spec.allow_open_mesh,
        },
    )
    .map_err(|e| ctx(e.into()))?;
    let resolved = ResolvedShape {
        shape,
        spec: shape_spec,
        file,
    };
    let clock = Stopwatch::start();
    let ObjectBasis {
        basis,
        points,
        material,
        cached,
        file: basis_file,
        monitors,
    } = object_basis(spec, &resolved, scene, settings, progress, warnings).map_err(ctx)?;
    let shape = resolved.shape;
    let precompute_s = clock.elapsed();
    let clock = Stopwatch::start();
    progress.begin(&format!("setup {}", spec.name), None);
    let opts = SimOptions {
        dt: scene.simulation.dt,
        gravity: scene.simulation.gravity,
        cubature: spec.cubature.unwrap_or(scene.solver.cubature),
        newton: scene.solver.newton(),
        boundaries: spec.boundaries.clone(),
        colliders: scene.colliders.clone(),
        placement: spec.placement,
    };
    // The weights at the integration points feed the simulator; a primitive is also drawn
    // at those points, so it reuses them instead of evaluating the basis twice.
    let ip_weights = basis.weights(&points.points).map_err(ctx)?;
    let sim =
        ReducedSim::with_weights(&basis, &points, &material, &ip_weights, &opts).map_err(ctx)?;
    let (render, triangles, own) = match &shape {
        Shape::Mesh(m) => (m.vertices().to_vec(), Some(m.triangles().to_vec()), true),
        other => match other.render_points() {
            Some(p) => (p.to_vec(), None, true),
            None => (points.points.clone(), None, false),
        },
    };
    let weights = if own {
        basis.weights(&render).map_err(|e| {
            ctx(Error::Scene {
                message: format!(
                    "the skinning weights cannot be evaluated at the render points ({e}); \
                     more kernels or a larger support factor cover them"
                ),
            })
        })?
    } else {
        ip_weights
    };
    progress.finish();
    let summary = ObjectSummary {
        name: spec.name.clone(),
        shape: spec.shape.clone(),
        kernels: basis.kernels.len(),
        modes: basis.modes() - 1,
        points: points.len(),
        cubature_points: sim.cubature().len(),
        render_points: render.len(),
        terms: sim.terms(),
        basis_cached: cached,
        basis_file: basis_file.map(|p| p.display().to_string()),
        precompute_s,
        setup_s: clock.elapsed(),
        step_ms_mean: 0.0,
        step_ms_max: 0.0,
        iterations_mean: 0.0,
        iterations_max: 0,
        nonconverged_steps: 0,
        line_search_failures: 0,
        line_search_cutbacks: 0,
        min_det: f64::INFINITY,
        monitors,
        steps: Vec::new(),
    };
    Ok(Prepared {
        spec: spec.clone(),
        sim,
        render,
        triangles,
        weights,
        summary,
        pvd: Vec::new(),
        warned_inverted: false,
    })
}

/// Write one frame of an object; returns the files written.
fn write_frame(
    p: &mut Prepared,
    out: &Path,
    frame: usize,
    formats: &[Format],
) -> Result<Vec<String>> {
    let dir = out.join(&p.spec.name);
    std::fs::create_dir_all(&dir).map_err(|source| Error::Io {
        path: dir.clone(),
        source,
    })?;
    let x = p.sim.positions(&p.render, &p.weights);
    let disp: Vec<[f64; 3]> = x
        .iter()
        .zip(&p.render)
        .map(|(a, b)| [a[0] - b[0], a[1] - b[1], a[2] - b[2]])
        .collect();
    let stem = format!("{}_{frame:06}", p.spec.name);
    let mut files = Vec::new();
    for f in formats {
        match f {
            Format::Vtk => {
                let path = dir.join(format!("{stem}.vtp"));
                vtk::write_vtp(
                    &path,
                    &x,
                    p.triangles.as_deref(),
                    &[PointData::Vector("displacement", &disp)],
                )?;
                p.pvd
                    .push((p.sim.time, format!("{}/{stem}.vtp", p.spec.name)));
                files.push(path.display().to_string());
            }
            Format::Ply => {
                let path = dir.join(format!("{stem}.ply"));
                crate::io::write_atomically(&path, |tmp| {
                    match &p.triangles {
                        Some(t) => crate::io::ply::write_ply_mesh(
                            tmp,
                            &x,
                            t,
                            crate::io::ply::PlyWriteOptions::default(),
                        )?,
                        None => crate::io::ply::write_ply_points(tmp, &x, &[])?,
                    }
                    Ok(())
                })?;
                files.push(path.display().to_string());
            }
        }
    }
    Ok(files)
}

/// Run `scene`: precompute (or load) every object's basis, simulate all steps, write frames
/// to `settings.out` and return the summary. Non-converged steps are reported in the
/// summary and its warnings, never hidden; the state always stays finite.
pub fn run(scene: &Scene, settings: &RunSettings, progress: &dyn Progress) -> Result<RunSummary> {
    scene.validate()?;
    let total = Stopwatch::start();
    let mut warnings = Vec::new();
    let mut objects = Vec::new();
    for spec in &scene.objects {
        objects.push(prepare(spec, scene, settings, progress, &mut warnings)?);
    }
    check_strict(settings.strict, &warnings)?;
    let formats = &scene.output.formats;
    let mut files = Vec::new();
    let mut frames = 0;
    if let Some(out) = &settings.out {
        std::fs::create_dir_all(out).map_err(|source| Error::Io {
            path: out.clone(),
            source,
        })?;
        for p in objects.iter_mut() {
            files.extend(write_frame(p, out, 0, formats)?);
        }
        frames = 1;
    }
    let steps = scene.simulation.steps;
    progress.begin("simulate", Some(steps as u64));
    for step in 1..=steps {
        for p in objects.iter_mut() {
            let rep = p.sim.step();
            if !rep.solve.converged {
                warnings.push(format!(
                    "object '{}': step {step} did not converge ({} iterations, residual {:.2e}{})",
                    p.spec.name,
                    rep.solve.iterations,
                    rep.solve.residual,
                    if rep.solve.line_search_failed {
                        ", line search failed"
                    } else {
                        ""
                    }
                ));
            }
            p.summary.steps.push(StepRow::from(&rep));
            p.summary.monitors.add_step(&rep.solve);
            if rep.solve.info.inverted > 0 && !p.warned_inverted {
                // Once per object: the stable Neo-Hookean energy stays finite through
                // inversion, but the result is rarely what the user meant.
                p.warned_inverted = true;
                warnings.push(format!(
                    "object '{}': step {step}: {} cubature point(s) inverted (det F = {:.2} <= 0); \
                     the material is too soft for the load or the time step too large \
                     (later inversions are counted in the monitors' min_det and each step's `inverted`)",
                    p.spec.name, rep.solve.info.inverted, rep.solve.info.min_det
                ));
            }
            if rep.solve.cholesky_fallbacks > 0 {
                warnings.push(format!(
                    "object '{}': step {step}: {} Newton Hessian(s) were not positive definite; \
                     the rest Hessian was used instead",
                    p.spec.name, rep.solve.cholesky_fallbacks
                ));
            }
            check_strict(settings.strict, &warnings)?;
        }
        if let Some(out) = &settings.out {
            if step % scene.output.every == 0 || step == steps {
                for p in objects.iter_mut() {
                    files.extend(write_frame(p, out, step, formats)?);
                }
                frames += 1;
            }
        }
        progress.set_position(step as u64);
    }
    progress.finish();
    if let Some(out) = &settings.out {
        if formats.contains(&Format::Vtk) {
            for p in &objects {
                let path = out.join(format!("{}.pvd", p.spec.name));
                vtk::write_pvd(&path, &p.pvd)?;
                files.push(path.display().to_string());
            }
        }
    }
    let objects = objects
        .into_iter()
        .map(|p| finish_summary(p.summary))
        .collect();
    Ok(RunSummary {
        dt: scene.simulation.dt,
        steps,
        frames,
        files,
        objects,
        total_s: total.elapsed(),
        warnings,
    })
}

fn finish_summary(mut s: ObjectSummary) -> ObjectSummary {
    let n = s.steps.len().max(1) as f64;
    s.step_ms_mean = s.steps.iter().map(|r| r.wall_ms).sum::<f64>() / n;
    s.step_ms_max = s.steps.iter().map(|r| r.wall_ms).fold(0.0, f64::max);
    s.iterations_mean = s.steps.iter().map(|r| r.iterations as f64).sum::<f64>() / n;
    s.iterations_max = s.steps.iter().map(|r| r.iterations).max().unwrap_or(0);
    // The counts were kept step by step in the monitors (`Monitors::add_step`).
    let m = &s.monitors;
    s.nonconverged_steps = m.newton_nonconverged_steps.unwrap_or(0);
    s.line_search_failures = m.line_search_failures.unwrap_or(0);
    s.line_search_cutbacks = m.line_search_cutbacks.unwrap_or(0);
    s.min_det = m.min_det.unwrap_or(f64::INFINITY);
    s
}
