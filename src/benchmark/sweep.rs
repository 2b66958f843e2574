//! Speed/accuracy sweeps of the beam benchmark (`freeform sweep`, design.md section 4).
//!
//! **Design.** A full Cartesian product of every knob is too expensive, so a sweep is
//! - the **grid**: every modes m x kernels K pair, with the *base* value of every other knob;
//! - **one-at-a-time variations** around the *base point* (m, K) = (`base_modes`,
//!   `base_kernels`): each further integration resolution, cubature count and Hessian
//!   strategy, with everything else at its base value.
//!
//! The base value of each of the other axes is the first entry of its list. The base point
//! itself is run even when it is not on the grid. Runs that would be identical are run once
//! (the first axis that produced them names them).
//!
//! **Reuse.** The FEM reference is computed (or loaded from the cache) once. Runs that share
//! (m, K, resolution) share one basis ([`super::beam_basis`]): cubature and Hessian variations
//! reuse the base point's basis. Their `precompute_s` counts the basis build time (measured
//! once) plus their own model setup, so it is what a user running that setting alone would
//! pay.

use super::pareto::pareto_front;
use super::{beam_basis, simulate_beam, BeamComparison, ReducedBeamOptions};
use crate::fem::beam::{run_beam_reference, FemBeamConfig};
use crate::precompute::sampling::Resolution;
use crate::precompute::{BoundaryModes, DensityBands};
use crate::progress::{Progress, Silent};
use crate::report::Stopwatch;
use crate::sim::{HessianStrategy, NewtonOptions};
use crate::{Error, Result};
use serde::Serialize;
use std::fmt::Write as _;
use std::path::Path;

/// Which part of the sweep design a run belongs to.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum SweepAxis {
    /// The m x K grid at base settings.
    Grid,
    /// The base point (m, K) when it is not on the grid.
    Base,
    /// Integration resolution varied at the base point.
    Points,
    /// Cubature count varied at the base point.
    Cubature,
    /// Hessian strategy varied at the base point.
    Hessian,
}

impl SweepAxis {
    /// Name in reports and the CSV.
    pub fn name(self) -> &'static str {
        crate::names::variant_name(&self)
    }
}

/// What to sweep. Lists must be non-empty; for `resolutions`, `cubature` and `hessian` the
/// first entry is the base value.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SweepSpec {
    /// Modes m on the grid. Issue default {6, 9, 16, 32}.
    pub modes: Vec<usize>,
    /// Kernels K on the grid. Issue default {250, 500, 1000, 2000, 4000}.
    pub kernels: Vec<usize>,
    /// Integration grids (None: the pipeline default, 50 K points clamped). Default [None].
    pub resolutions: Vec<Option<Resolution>>,
    /// Cubature counts. Default `[5000]` (the beam command's).
    pub cubature: Vec<usize>,
    /// Hessian strategies. Default [L-BFGS].
    pub hessian: Vec<HessianStrategy>,
    /// m of the base point for the variations. Default 16 (the beam command's).
    pub base_modes: usize,
    /// K of the base point for the variations. Default 1000 (the beam command's).
    pub base_kernels: usize,
    /// Newton settings (the Hessian strategy is replaced per run).
    pub newton: NewtonOptions,
    /// Compare over the first `frames` steps only (None: all of the reference's).
    pub frames: Option<usize>,
    /// Free or boundary-aware bases for every run. Default: the beam command's.
    pub boundaries: BoundaryModes,
    /// Kernel density bands: the grid is run once per entry (uniform placement is
    /// [`DensityBands::off`]), the variations with the first. Default: the beam command's
    /// alone.
    pub densities: Vec<DensityBands>,
}

impl Default for SweepSpec {
    fn default() -> Self {
        let beam = ReducedBeamOptions::default();
        Self {
            modes: vec![6, 9, 16, 32],
            kernels: vec![250, 500, 1000, 2000, 4000],
            resolutions: vec![beam.resolution],
            cubature: vec![beam.cubature],
            hessian: vec![beam.newton.hessian],
            base_modes: beam.modes,
            base_kernels: beam.kernels,
            newton: beam.newton,
            frames: None,
            boundaries: beam.boundaries,
            densities: vec![beam.density],
        }
    }
}

/// One run of a sweep.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PlannedRun {
    /// Which part of the design it belongs to.
    pub axis: SweepAxis,
    /// Its settings.
    pub opts: ReducedBeamOptions,
}

impl SweepSpec {
    /// The runs of the sweep in order (grid row by row in m, then the base point if it is
    /// off the grid, then the variations), every one validated against `fem` before any
    /// work is done.
    ///
    /// # Errors
    /// [`Error::InvalidParameter`] for an empty list or an invalid run (e.g. m >= K - 1, zero
    /// cubature points, more frames than the reference has); the message names the run.
    pub fn plan(&self, fem: &FemBeamConfig) -> Result<Vec<PlannedRun>> {
        fn nonempty<T>(name: &'static str, v: &[T]) -> Result<()> {
            if v.is_empty() {
                Err(Error::param(name, "[]", "give at least one value"))
            } else {
                Ok(())
            }
        }
        nonempty("modes", &self.modes)?;
        nonempty("kernels", &self.kernels)?;
        nonempty("points", &self.resolutions)?;
        nonempty("cubature", &self.cubature)?;
        nonempty("hessian", &self.hessian)?;
        nonempty("density", &self.densities)?;
        let base = |modes, kernels, density| ReducedBeamOptions {
            modes,
            kernels,
            resolution: self.resolutions[0],
            cubature: self.cubature[0],
            newton: NewtonOptions {
                hessian: self.hessian[0],
                ..self.newton
            },
            frames: self.frames,
            hold_stiffness: None,
            boundaries: self.boundaries,
            fit: false,
            density,
        };
        let mut runs: Vec<PlannedRun> = Vec::new();
        let mut push = |axis, opts: ReducedBeamOptions| {
            if !runs.iter().any(|r| r.opts == opts) {
                runs.push(PlannedRun { axis, opts });
            }
        };
        for &d in &self.densities {
            for &m in &self.modes {
                for &k in &self.kernels {
                    push(SweepAxis::Grid, base(m, k, d));
                }
            }
        }
        let b = base(self.base_modes, self.base_kernels, self.densities[0]);
        push(SweepAxis::Base, b);
        for &r in &self.resolutions[1..] {
            push(SweepAxis::Points, ReducedBeamOptions { resolution: r, ..b });
        }
        for &c in &self.cubature[1..] {
            push(SweepAxis::Cubature, ReducedBeamOptions { cubature: c, ..b });
        }
        for &h in &self.hessian[1..] {
            let newton = NewtonOptions {
                hessian: h,
                ..b.newton
            };
            push(SweepAxis::Hessian, ReducedBeamOptions { newton, ..b });
        }
        for r in &runs {
            r.opts.validate(fem).map_err(|e| {
                Error::param(
                    "sweep",
                    describe(&r.opts),
                    format!("{} run is invalid: {e}", r.axis.name()),
                )
            })?;
        }
        Ok(runs)
    }
}

/// "m = 16, K = 1000, points default, cubature 5000, lbfgs" (and ", density x2 at the
/// ends" when the ends are refined).
pub fn describe(o: &ReducedBeamOptions) -> String {
    let res = match o.resolution {
        None => "default".to_string(),
        Some(Resolution::Count(n)) => n.to_string(),
        Some(Resolution::Spacing(h)) => format!("spacing {h} m"),
    };
    let density = if o.density.boundaries == 1.0 {
        String::new()
    } else {
        format!(", density x{} at the ends", o.density.boundaries)
    };
    format!(
        "m = {}, K = {}, points {res}, cubature {}, {}{density}",
        o.modes,
        o.kernels,
        o.cubature,
        o.newton.hessian.name()
    )
}

/// One finished run with its Pareto flags.
#[derive(Debug, Clone, Serialize)]
pub struct SweepRow {
    /// Which part of the design it belongs to.
    pub axis: SweepAxis,
    /// Requested integration grid (None: default).
    pub resolution: Option<Resolution>,
    /// Kernel density bands of its basis.
    pub density: DensityBands,
    /// The comparison with the FEM reference.
    pub result: BeamComparison,
    /// On the Pareto front of (precompute_s, normalized_mse).
    pub pareto_precompute: bool,
    /// On the Pareto front of (reduced_step_ms_mean, normalized_mse).
    pub pareto_step: bool,
}

/// A run that failed (the sweep goes on without it).
#[derive(Debug, Clone, Serialize)]
pub struct SweepFailure {
    /// Which part of the design it belonged to.
    pub axis: SweepAxis,
    /// Its settings.
    pub opts: ReducedBeamOptions,
    /// The error.
    pub error: String,
}

/// The result of [`run_sweep`].
#[derive(Debug, Clone, Serialize)]
pub struct SweepReport {
    /// "bend" or "twist".
    pub test: &'static str,
    /// What was asked for.
    pub spec: SweepSpec,
    /// Finished runs, in plan order.
    pub rows: Vec<SweepRow>,
    /// Failed runs.
    pub failures: Vec<SweepFailure>,
    /// Bases built (fewer than runs when runs shared one).
    pub bases_built: usize,
    /// Whether the FEM reference came from the cache.
    pub fem_cached: bool,
    /// Error against K: one curve per (density, m) of the grid ([`kernel_curves`]).
    pub curves: Vec<KernelCurve>,
    /// Wall time of the whole sweep, s.
    pub total_s: f64,
}

/// The CSV columns of [`SweepReport::to_csv`].
pub const CSV_COLUMNS: [&str; 21] = [
    "test",
    "axis",
    "modes",
    "kernels",
    "points",
    "cubature",
    "hessian",
    "density_boundaries",
    "frames",
    "normalized_mse",
    "max_error",
    "normalized_mse_first_half",
    "max_error_first_half",
    "precompute_s",
    "basis_s",
    "reduced_step_ms_mean",
    "reduced_nonconverged_steps",
    "fem_step_ms_mean",
    "fem_nodes",
    "pareto_precompute",
    "pareto_step",
];

impl SweepReport {
    /// One header line ([`CSV_COLUMNS`]) and one line per finished run; numbers in Rust's
    /// shortest round-trip form, flags as `true`/`false`.
    pub fn to_csv(&self) -> String {
        let mut s = CSV_COLUMNS.join(",");
        s.push('\n');
        for row in &self.rows {
            let r = &row.result;
            let _ = writeln!(
                s,
                "{},{},{},{},{},{},{},{},{},{:e},{:e},{:e},{:e},{},{},{},{},{},{},{},{}",
                r.test,
                row.axis.name(),
                r.modes,
                r.kernels,
                r.points,
                r.cubature_points,
                r.hessian.name(),
                row.density.boundaries,
                r.frames,
                r.normalized_mse,
                r.max_error,
                r.normalized_mse_first_half,
                r.max_error_first_half,
                r.precompute_s,
                r.basis_s,
                r.reduced_step_ms_mean,
                r.reduced_nonconverged_steps,
                r.fem_step_ms_mean,
                r.fem_nodes,
                row.pareto_precompute,
                row.pareto_step
            );
        }
        s
    }
}

/// Mark the Pareto fronts of `rows` (normalized MSE against precompute time and against
/// step time) in place.
pub fn mark_pareto(rows: &mut [SweepRow]) {
    let err = |r: &SweepRow| r.result.normalized_mse;
    let pre: Vec<[f64; 2]> = rows
        .iter()
        .map(|r| [r.result.precompute_s, err(r)])
        .collect();
    let step: Vec<[f64; 2]> = rows
        .iter()
        .map(|r| [r.result.reduced_step_ms_mean, err(r)])
        .collect();
    let (fp, fs) = (pareto_front(&pre), pareto_front(&step));
    for (i, r) in rows.iter_mut().enumerate() {
        r.pareto_precompute = fp[i];
        r.pareto_step = fs[i];
    }
}

/// The normalized MSE of one (density, m) row of the grid against K, and how far it rises.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct KernelCurve {
    /// Modes m.
    pub modes: usize,
    /// Kernel density bands of its bases.
    pub density: DensityBands,
    /// Kernels K, ascending.
    pub kernels: Vec<usize>,
    /// Normalized MSE at each K.
    pub normalized_mse: Vec<f64>,
    /// The largest ratio of a point's error to the best error at a smaller K: at most 1 when
    /// the error never rises with K; issue 30's "no point more than 20% above the best at a
    /// smaller K" is at most 1.2. `None` with fewer than two K.
    pub worst_rise: Option<f64>,
    /// K of the point with [`KernelCurve::worst_rise`].
    pub worst_rise_at: Option<usize>,
}

/// The grid's curves of error against K, one per (density, m) in the order the rows first
/// give them. Variations and the off-grid base point are left out.
pub fn kernel_curves(rows: &[SweepRow]) -> Vec<KernelCurve> {
    curves_of(rows.iter().filter(|r| r.axis == SweepAxis::Grid).map(|r| {
        (
            r.result.modes,
            r.density,
            r.result.kernels,
            r.result.normalized_mse,
        )
    }))
}

/// [`kernel_curves`] of (m, density, K, normalized MSE) points.
fn curves_of(points: impl Iterator<Item = (usize, DensityBands, usize, f64)>) -> Vec<KernelCurve> {
    // (m, density) in first-seen order, each with its (K, MSE) points.
    type Group = ((usize, DensityBands), Vec<(usize, f64)>);
    let mut groups: Vec<Group> = Vec::new();
    for (modes, density, k, mse) in points {
        match groups.iter_mut().find(|(key, _)| *key == (modes, density)) {
            Some((_, pts)) => pts.push((k, mse)),
            None => groups.push(((modes, density), vec![(k, mse)])),
        }
    }
    groups
        .into_iter()
        .map(|((modes, density), mut pts)| {
            pts.sort_by_key(|p| p.0);
            let (mut worst_rise, mut worst_rise_at) = (None, None);
            let mut best = f64::INFINITY;
            for &(k, e) in &pts {
                if best.is_finite() && worst_rise.is_none_or(|w| e / best > w) {
                    worst_rise = Some(e / best);
                    worst_rise_at = Some(k);
                }
                best = best.min(e);
            }
            let (kernels, normalized_mse) = pts.into_iter().unzip();
            KernelCurve {
                modes,
                density,
                kernels,
                normalized_mse,
                worst_rise,
                worst_rise_at,
            }
        })
        .collect()
}

/// The paper's Table 1 ("Ours", normalized MSE) at m modes, when `frames` are the frames our
/// Table 1 compares (docs/accuracy.md: the bend over all 200, the twist over the first 100);
/// `None` for other tests, m or frames.
pub fn paper_table1(test: &str, modes: usize, frames: usize) -> Option<f64> {
    let (table, protocol): (&[(usize, f64)], usize) = match test {
        "bend" => (
            &[(6, 7.80e-3), (9, 4.90e-3), (16, 4.10e-4), (32, 2.93e-6)],
            200,
        ),
        "twist" => (
            &[(6, 1.56e-4), (9, 2.95e-5), (16, 3.46e-6), (32, 6.64e-6)],
            100,
        ),
        _ => return None,
    };
    if frames != protocol {
        return None;
    }
    table.iter().find(|(m, _)| *m == modes).map(|&(_, e)| e)
}

/// Run a sweep planned by [`SweepSpec::plan`] on the beam `fem`: the FEM reference once
/// (`progress` shows it; the runs themselves are silent), one basis per distinct (m, K,
/// resolution), then every run. `on_run(index, run, outcome)` is called after each run (in
/// execution order, which groups runs sharing a basis; `index` is the plan index).
///
/// # Errors
/// A failed FEM reference. A failed run is not an error: it is listed in
/// [`SweepReport::failures`].
pub fn run_sweep(
    fem: &FemBeamConfig,
    spec: &SweepSpec,
    runs: &[PlannedRun],
    cache_dir: Option<&Path>,
    progress: &dyn Progress,
    on_run: &mut dyn FnMut(usize, &PlannedRun, &Result<BeamComparison>),
) -> Result<SweepReport> {
    let clock = Stopwatch::start();
    progress.begin("FEM reference", Some(fem.steps as u64));
    let reference = run_beam_reference(fem, cache_dir, progress)?;
    progress.finish();
    let mut done: Vec<Option<std::result::Result<BeamComparison, String>>> = vec![None; runs.len()];
    let mut bases_built = 0;
    for i in 0..runs.len() {
        if done[i].is_some() {
            continue;
        }
        let key = runs[i].opts.basis_key();
        let group: Vec<usize> = (i..runs.len())
            .filter(|&j| runs[j].opts.basis_key() == key)
            .collect();
        let basis = beam_basis(fem, &runs[i].opts, &Silent);
        bases_built += usize::from(basis.is_ok());
        for &j in &group {
            let outcome = match &basis {
                Ok(b) => simulate_beam(fem, &reference, b, &runs[j].opts, &Silent),
                Err(e) => Err(Error::param(
                    "basis",
                    describe(&runs[j].opts),
                    e.to_string(),
                )),
            };
            on_run(j, &runs[j], &outcome);
            done[j] = Some(outcome.map_err(|e| e.to_string()));
        }
    }
    let mut rows = Vec::new();
    let mut failures = Vec::new();
    for (run, outcome) in runs.iter().zip(done) {
        match outcome {
            Some(Ok(result)) => rows.push(SweepRow {
                axis: run.axis,
                resolution: run.opts.resolution,
                density: run.opts.density,
                result,
                pareto_precompute: false,
                pareto_step: false,
            }),
            Some(Err(error)) => failures.push(SweepFailure {
                axis: run.axis,
                opts: run.opts,
                error,
            }),
            None => unreachable!("every run belongs to a basis group"),
        }
    }
    mark_pareto(&mut rows);
    let curves = kernel_curves(&rows);
    Ok(SweepReport {
        test: fem.test.name(),
        spec: spec.clone(),
        rows,
        failures,
        bases_built,
        curves,
        fem_cached: matches!(reference.cache, crate::fem::beam::CacheStatus::Hit(_)),
        total_s: clock.elapsed(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fem::beam::BeamTest;

    #[test]
    fn plan_is_grid_plus_one_at_a_time_variations() {
        let fem = FemBeamConfig::reference(BeamTest::Bend);
        let spec = SweepSpec {
            modes: vec![6, 16],
            kernels: vec![500, 1000],
            resolutions: vec![None, Some(Resolution::Count(20_000))],
            cubature: vec![5000, 2000, 5000],
            hessian: vec![HessianStrategy::Lbfgs, HessianStrategy::Newton],
            ..SweepSpec::default()
        };
        let runs = spec.plan(&fem).unwrap();
        let axes: Vec<_> = runs.iter().map(|r| r.axis).collect();
        use SweepAxis::*;
        // 4 grid runs (the base point (16, 1000) is one), 1 points, 1 cubature (the repeated
        // 5000 is the base), 1 Hessian.
        assert_eq!(axes, [Grid, Grid, Grid, Grid, Points, Cubature, Hessian]);
        for r in &runs[4..] {
            assert_eq!((r.opts.modes, r.opts.kernels), (16, 1000));
        }
        assert_eq!(runs[5].opts.cubature, 2000);
        assert_eq!(runs[6].opts.newton.hessian, HessianStrategy::Newton);
        assert_eq!(runs[6].opts.cubature, 5000);
        // Off-grid base point.
        let spec = SweepSpec {
            modes: vec![6],
            kernels: vec![500],
            ..SweepSpec::default()
        };
        let axes: Vec<_> = spec.plan(&fem).unwrap().iter().map(|r| r.axis).collect();
        assert_eq!(axes, [Grid, Base]);
    }

    #[test]
    fn kernel_curves_sort_by_k_and_measure_the_worst_rise() {
        let (u, r) = (
            DensityBands::off(),
            DensityBands {
                boundaries: 2.0,
                ..DensityBands::off()
            },
        );
        // Given out of order; uniform m = 16 rises at K = 2000 to 4x the best before it
        // (K = 1000), then falls; the refined curve only falls.
        let pts = [
            (16, u, 2000, 4.0e-4),
            (16, u, 500, 2.0e-4),
            (16, u, 1000, 1.0e-4),
            (16, r, 500, 3.0e-4),
            (16, u, 4000, 3.0e-4),
            (16, r, 1000, 2.0e-4),
            (9, u, 500, 1.0e-3),
        ];
        let c = curves_of(pts.into_iter());
        assert_eq!(c.len(), 3);
        assert_eq!((c[0].modes, c[0].density), (16, u));
        assert_eq!(c[0].kernels, [500, 1000, 2000, 4000]);
        assert_eq!(c[0].normalized_mse, [2.0e-4, 1.0e-4, 4.0e-4, 3.0e-4]);
        // 4e-4 / 1e-4, exactly representable ratios of the inputs.
        assert_eq!(c[0].worst_rise, Some(4.0e-4 / 1.0e-4));
        assert_eq!(c[0].worst_rise_at, Some(2000));
        assert_eq!(c[1].density, r);
        assert_eq!(c[1].worst_rise, Some(2.0e-4 / 3.0e-4));
        assert!(c[1].worst_rise.unwrap() < 1.0);
        assert_eq!(
            (c[2].modes, c[2].worst_rise, c[2].worst_rise_at),
            (9, None, None)
        );
    }

    #[test]
    fn paper_table1_only_for_its_protocol() {
        assert_eq!(paper_table1("bend", 32, 200), Some(2.93e-6));
        assert_eq!(paper_table1("twist", 16, 100), Some(3.46e-6));
        assert_eq!(paper_table1("twist", 16, 200), None);
        assert_eq!(paper_table1("bend", 12, 200), None);
        assert_eq!(paper_table1("other", 6, 200), None);
    }

    #[test]
    fn plan_rejects_bad_input() {
        let fem = FemBeamConfig::reference(BeamTest::Twist);
        let empty = SweepSpec {
            kernels: vec![],
            ..SweepSpec::default()
        };
        assert!(matches!(
            empty.plan(&fem),
            Err(Error::InvalidParameter {
                name: "kernels",
                ..
            })
        ));
        let too_many_modes = SweepSpec {
            modes: vec![6, 32],
            kernels: vec![30],
            ..SweepSpec::default()
        };
        let e = too_many_modes.plan(&fem).unwrap_err().to_string();
        assert!(e.contains("m = 32, K = 30"), "{e}");
        let frames = SweepSpec {
            frames: Some(500),
            ..SweepSpec::default()
        };
        assert!(frames.plan(&fem).is_err());
    }
}
