//! Running a scene as a batch: a loop over a [`World`] with a [`FrameWriter`] observing it,
//! and the summary of the run.

use super::frames::{FrameObserver, FrameWriter};
use super::spec::Scene;
use super::world::World;
use crate::progress::Progress;
use crate::report::{Monitors, Stopwatch};
use crate::sim::StepReport;
use crate::Result;
use serde::Serialize;
use std::path::PathBuf;

/// Where a run reads relative paths from and writes to.
#[derive(Debug, Clone, Default)]
pub struct RunSettings {
    /// Directory that relative shape paths and the cache directory are resolved against
    /// (the scene file's directory for `freeform run`).
    pub base_dir: PathBuf,
    /// Output directory for frames (None: simulate and summarise only).
    pub out: Option<PathBuf>,
    /// Stop with [`crate::Error::Strict`] at the first warning (a poorly conditioned basis, a
    /// step that did not converge, a failed line search, a Cholesky fallback) instead of
    /// reporting it in the summary. Frames already written stay; the `.pvd` collection is
    /// only written by a complete run.
    pub strict: bool,
}

impl RunSettings {
    /// The settings `freeform run` uses for a scene file: relative paths (shapes, the basis
    /// cache) resolve against the file's directory; no frames; not strict.
    pub fn for_scene_file(path: &std::path::Path) -> RunSettings {
        RunSettings {
            base_dir: path.parent().map(PathBuf::from).unwrap_or_default(),
            out: None,
            strict: false,
        }
    }
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
    /// Collider penetrations at the end of the step: penetrating (cubature point, collider)
    /// pairs, every collider kind counted.
    pub contacts: usize,
    /// Deepest collider penetration at the end of the step, metres (0 without contact).
    pub penetration: f64,
    /// Largest RMS distance of a boundary region's points from their target, metres (absent
    /// without boundaries; [`StepReport::boundary_rms_deviation`]).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub boundary_rms_deviation: Option<f64>,
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
            penetration: s.info.penetration,
            boundary_rms_deviation: r.boundary_rms_deviation,
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
    /// Object-object contact: per step the pairs tested and active, the deepest penetration
    /// and the islands; the run's worst penetration (absent without `[contact]`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub contact: Option<super::ContactSummary>,
}

/// Run `scene`: set up a [`World`] (every object's basis from the cache or computed),
/// step it `scene.simulation.steps` times, write frames to `settings.out` through a
/// [`FrameWriter`] and return the summary. Non-converged steps are reported in the summary
/// and its warnings, never hidden; the state always stays finite.
pub fn run(scene: &Scene, settings: &RunSettings, progress: &dyn Progress) -> Result<RunSummary> {
    let total = Stopwatch::start();
    let mut world = World::new(scene, settings, progress)?;
    let mut writer = match &settings.out {
        Some(out) => Some(
            FrameWriter::new(out, &scene.output.formats)?
                .rotate_splat_sh(scene.output.rotate_splat_sh)
                .stress(scene.output.stress),
        ),
        None => None,
    };
    if let Some(w) = writer.as_mut() {
        w.frame(&world, 0)?;
    }
    let steps = scene.simulation.steps;
    progress.begin("simulate", Some(steps as u64));
    for step in 1..=steps {
        crate::error::check_cancelled(progress, "simulate")?;
        world.step()?;
        if let Some(w) = writer.as_mut() {
            if step % scene.output.every == 0 || step == steps {
                w.frame(&world, step)?;
            }
        }
        progress.set_position(step as u64);
    }
    progress.finish();
    let (frames, files) = match writer.as_mut() {
        Some(w) => {
            w.finish(&world)?;
            (w.frames(), w.files().to_vec())
        }
        None => (0, Vec::new()),
    };
    Ok(RunSummary {
        dt: scene.simulation.dt,
        steps,
        frames,
        files,
        objects: world.summaries(),
        total_s: total.elapsed(),
        warnings: world.warnings().to_vec(),
        contact: world.contact_summary().cloned(),
    })
}

pub(super) fn finish_summary(mut s: ObjectSummary) -> ObjectSummary {
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
