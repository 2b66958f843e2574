//! What a run reports: one row per step of each object ([`StepRow`]), each object's
//! summary ([`ObjectSummary`]), the contact rows and summary, and the run's
//! ([`RunSummary`]). Plain data, serialized as the `--json` reports.

use crate::report::{Monitors, Warning};
use crate::sim::StepReport;
use serde::Serialize;

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
    /// Newton models whose friction took its majorizer's curvature (after a cut-back).
    pub majorized_models: usize,
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
            majorized_models: s.majorized_models,
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
    pub warnings: Vec<Warning>,
    /// Object-object contact: per step the pairs tested and active, the deepest penetration
    /// and the islands; the run's worst penetration (absent without `[contact]`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub contact: Option<ContactSummary>,
}

/// One step of object-object contact in the run summary.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ContactStepRow {
    /// Step number (1-based).
    pub step: usize,
    /// Wall time of the whole world step, ms.
    pub wall_ms: f64,
    /// Object pairs whose grown sample boxes were compared (n (n - 1) / 2).
    pub object_pairs_tested: usize,
    /// Object pairs whose grown boxes met (their samples were then tested; those within
    /// reach were put in one island).
    pub object_pairs_near: usize,
    /// Sample pairs within contact distance at the end of the step.
    pub sample_pairs_active: usize,
    /// Deepest object-object penetration at the end of the step, metres.
    pub penetration: f64,
    /// The same relative to the smaller rest diagonal of the two objects.
    pub penetration_fraction: f64,
    /// Deepest reach of a point of an object's own surface (edges and corners included; the
    /// derived surface of a cloud, splat or image object) into another object's sample
    /// envelope at the end of the step, metres (0 when none reaches in).
    pub visible_penetration: f64,
    /// The same relative to the smaller rest diagonal of the two objects.
    pub visible_penetration_fraction: f64,
    /// Sizes of the islands solved together (two or more objects, or one object in
    /// self-contact), largest first.
    pub islands: Vec<usize>,
    /// Objects solved again because they ended in contact with another island's.
    pub regrouped: usize,
    /// Islands solved again with a raised pair stiffness (penetration above the tolerance),
    /// counted once per raise.
    pub stiffened: usize,
}

impl ContactStepRow {
    /// Islands of two or more objects solved this step.
    pub fn island_count(&self) -> usize {
        self.islands.len()
    }

    /// Objects in the largest island (0 without islands).
    pub fn largest_island(&self) -> usize {
        self.islands.first().copied().unwrap_or(0)
    }
}

/// Where a visible penetration was: which object's surface point reached into which object,
/// at which step, and where the point lies on its own object at rest.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct VisibleSpot {
    /// The step it was measured after (as the rows' `step`).
    pub step: usize,
    /// The object whose surface point it is.
    pub surface_object: String,
    /// Its index in the scene's objects.
    pub surface_index: usize,
    /// The object whose sample envelope the point reached into.
    pub other_object: String,
    /// Its index in the scene's objects.
    pub other_index: usize,
    /// The point in its object's rest frame (before placement), metres: an edge or corner
    /// of a box shows as coordinates at 0 or the box's size.
    pub rest_point: [f64; 3],
}

/// Object-object contact over a run.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ContactSummary {
    /// The penetration tolerance, a fraction of the smaller diagonal.
    pub penetration_tolerance: f64,
    /// Contact samples per object, in object order.
    pub samples: Vec<usize>,
    /// Of those, the feature samples (points on convex edges and corners) per object.
    pub feature_samples: Vec<usize>,
    /// Triangles of each object's derived contact surface (point clouds, splats and images;
    /// written as its `contact_surface` render set), None for shapes with their own surface.
    pub derived_surface_triangles: Vec<Option<usize>>,
    /// Contact thickness per object, metres.
    pub thickness: Vec<f64>,
    /// Whether each object has self-contact, in object order.
    pub self_contact: Vec<bool>,
    /// Penalty stiffness of each object pair at the end of the run, Pa/m^2 (row-major,
    /// objects x objects; raised where a pair went deeper than the tolerance).
    pub stiffness: Vec<f64>,
    /// Worst penetration of the run, metres.
    pub worst_penetration: f64,
    /// Worst penetration relative to the smaller diagonal of its two objects.
    pub worst_penetration_fraction: f64,
    /// Worst visible penetration of the run (a surface point into another object, see
    /// [`ContactStepRow::visible_penetration`]), metres.
    pub worst_visible_penetration: f64,
    /// The same relative to the smaller diagonal of its two objects.
    pub worst_visible_penetration_fraction: f64,
    /// Where the worst visible penetration (by fraction) was, None if nothing reached in.
    pub worst_visible_at: Option<VisibleSpot>,
    /// Surface points per object the visible penetration is measured at (0: its surface is
    /// not covered by its kernels, so it is not measured).
    pub surface_points: Vec<usize>,
    /// Steps whose deepest penetration exceeded the tolerance.
    pub steps_over_tolerance: usize,
    /// Mean world step wall time, ms.
    pub step_ms_mean: f64,
    /// One row per step.
    pub steps: Vec<ContactStepRow>,
}

/// `s` with its means, maxima and counts filled from its rows and monitors.
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
