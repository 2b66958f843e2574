//! The standard beam benchmark (design.md section 3): the reduced model against the FEM
//! reference on the same definition, with the error metric and both sides' costs.

use crate::fem::beam::{run_beam_reference, BeamReference, BeamTest, FemBeamConfig};
use crate::material::Region;
use crate::precompute::sampling::Resolution;
use crate::precompute::{
    build_basis, BasisOptions, BasisRun, BoundaryModes, DensityBands, KernelDensity,
};
use crate::progress::Progress;
use crate::report::{Monitors, Stopwatch};
use crate::sim::motion::Motion;
use crate::sim::{Boundary, HessianStrategy, NewtonOptions, ReducedSim, SimOptions};
use crate::{Error, Point3, Result};
use serde::Serialize;
use std::path::Path;

pub mod fit;
pub mod pareto;
pub mod shapes;
pub mod sweep;

pub use fit::{fit_residual, fit_residual_from_weights, FitResidual};

/// The reduced model's settings for a beam run.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct ReducedBeamOptions {
    /// Modes m.
    pub modes: usize,
    /// Kernels K.
    pub kernels: usize,
    /// Integration grid: a point count or a spacing (None: the pipeline default,
    /// [`crate::precompute::default_points`]).
    pub resolution: Option<Resolution>,
    /// Cubature points.
    pub cubature: usize,
    /// Newton settings.
    pub newton: NewtonOptions,
    /// Compare over the first `frames` steps only (the reduced model runs that many steps;
    /// the FEM reference is the full run, so the motion is the benchmark's). None: all.
    pub frames: Option<usize>,
    /// Penalty stiffness of the held (and twisted) ends, Pa/m^2 (None: the simulator's
    /// default, `PENALTY_FACTOR` x max(rho/h^2, E/D^2)). The FEM reference holds its nodes
    /// exactly (Dirichlet); a stiffer penalty approaches that.
    pub hold_stiffness: Option<f64>,
    /// Free or boundary-aware basis (the held and twisted ends are the regions).
    pub boundaries: BoundaryModes,
    /// Also fit the FEM frames compared onto the basis by least squares and report the
    /// residual ([`BeamComparison::fit`], paper Table 6). Default false.
    pub fit: bool,
    /// Where the kernels go (refined bands; the basis default when not changed).
    pub density: DensityBands,
}

impl Default for ReducedBeamOptions {
    fn default() -> Self {
        Self {
            modes: 16,
            kernels: 1000,
            resolution: None,
            cubature: crate::sim::cubature::DEFAULT_CUBATURE,
            newton: NewtonOptions::default(),
            frames: None,
            hold_stiffness: None,
            boundaries: BoundaryModes::default(),
            fit: false,
            density: BasisOptions::default().density.bands,
        }
    }
}

/// The report of `freeform beam`.
#[derive(Debug, Clone, Serialize)]
pub struct BeamComparison {
    /// "bend" or "twist".
    pub test: &'static str,
    /// Modes m.
    pub modes: usize,
    /// Kernels K.
    pub kernels: usize,
    /// Integration points.
    pub points: usize,
    /// Cubature points.
    pub cubature_points: usize,
    /// Hessian strategy.
    pub hessian: HessianStrategy,
    /// Newton tolerance.
    pub tol: f64,
    /// Frames compared (steps run by the reduced model).
    pub frames: usize,
    /// Free or boundary-aware basis.
    pub boundaries: BoundaryModes,
    /// mean |x_red - x_fem|^2 / D^2 over frames and FEM nodes.
    pub normalized_mse: f64,
    /// max |x_red - x_fem| / D.
    pub max_error: f64,
    /// The same over the first half of the frames (before the twist buckles, see
    /// docs/accuracy.md).
    pub normalized_mse_first_half: f64,
    /// max error over the first half of the frames.
    pub max_error_first_half: f64,
    /// Basis precomputation plus reduced-model setup, s.
    pub precompute_s: f64,
    /// The basis part of `precompute_s`, s (measured once for runs that share a basis).
    pub basis_s: f64,
    /// Mean reduced step, ms.
    pub reduced_step_ms_mean: f64,
    /// Reduced steps that did not converge.
    pub reduced_nonconverged_steps: usize,
    /// Mean FEM step, ms (from the run that produced the cached reference).
    pub fem_step_ms_mean: f64,
    /// FEM nodes.
    pub fem_nodes: usize,
    /// FEM tetrahedra.
    pub fem_tets: usize,
    /// FEM resolution (cubes per metre).
    pub fem_resolution: usize,
    /// Whether the FEM reference came from the cache.
    pub fem_cached: bool,
    /// Conditioning and convergence monitors of the reduced run (the same keys as in the
    /// `modes` and `run` reports).
    pub monitors: Monitors,
    /// The basis warnings and one per non-converged reduced step (strict mode,
    /// [`crate::error::check_strict`], makes them an error).
    pub warnings: Vec<String>,
    /// The basis fitting residual of the FEM frames compared (paper Table 6), when
    /// [`ReducedBeamOptions::fit`] asked for it.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub fit: Option<FitResidual>,
}

/// Run the reduced model on the beam test `fem.test` and compare it with the FEM reference
/// (computed or loaded from `cache_dir`).
pub fn compare_beam(
    fem: &FemBeamConfig,
    opts: &ReducedBeamOptions,
    cache_dir: Option<&Path>,
    progress: &dyn Progress,
) -> Result<BeamComparison> {
    progress.begin("FEM reference", Some(fem.steps as u64));
    let reference: BeamReference = run_beam_reference(fem, cache_dir, progress)?;
    progress.finish();
    let basis = beam_basis(fem, opts, progress)?;
    simulate_beam(fem, &reference, &basis, opts, progress)
}

/// The reduced model's precomputation on a beam (integration points, material and skinning
/// basis), with its wall time: built once by [`beam_basis`] and shared by every
/// [`simulate_beam`] run that differs only in simulation settings (cubature, Hessian
/// strategy, Newton tolerance, frames).
#[derive(Debug)]
pub struct BeamBasis {
    /// Basis, integration points and material.
    pub run: BasisRun,
    /// Wall time of the build, s.
    pub seconds: f64,
    /// The (modes, kernels, resolution) it was built for.
    pub key: BasisKey,
}

/// What a [`BeamBasis`] depends on among [`ReducedBeamOptions`].
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct BasisKey {
    /// Modes m.
    pub modes: usize,
    /// Kernels K.
    pub kernels: usize,
    /// Integration grid (None: the default).
    pub resolution: Option<Resolution>,
    /// Free or boundary-aware basis.
    pub boundaries: BoundaryModes,
    /// Kernel density bands.
    pub density: DensityBands,
}

impl ReducedBeamOptions {
    /// The settings the basis depends on.
    pub fn basis_key(&self) -> BasisKey {
        BasisKey {
            modes: self.modes,
            kernels: self.kernels,
            resolution: self.resolution,
            boundaries: self.boundaries,
            density: self.density,
        }
    }

    /// The pipeline settings of the basis on the beam `fem`.
    pub fn basis_options(&self, fem: &FemBeamConfig) -> BasisOptions {
        BasisOptions {
            kernels: self.kernels,
            modes: self.modes,
            resolution: self.resolution,
            material: fem.material,
            boundary_regions: match self.boundaries {
                BoundaryModes::Free => Vec::new(),
                BoundaryModes::Aware => beam_regions(fem),
            },
            density: KernelDensity::bands(self.density),
            ..BasisOptions::default()
        }
    }

    /// Check every setting before any work is done (the basis options, cubature, Newton
    /// settings, frames against `fem.steps`).
    pub fn validate(&self, fem: &FemBeamConfig) -> Result<()> {
        self.basis_options(fem).validate()?;
        self.newton.validate()?;
        if let Some(r @ Resolution::Spacing(_)) = self.resolution {
            r.spacing(1.0)?;
        }
        if self.cubature == 0 {
            return Err(Error::param(
                "cubature",
                0,
                "need at least one cubature point",
            ));
        }
        if let Some(f) = self.frames {
            if f == 0 || f > fem.steps {
                return Err(Error::param(
                    "frames",
                    f,
                    format!("must lie in 1..={} (the reference's steps)", fem.steps),
                ));
            }
        }
        Ok(())
    }
}

/// Build the reduced model's basis for `opts` on the beam `fem` (the box of `fem.size`, its
/// material), timed.
pub fn beam_basis(
    fem: &FemBeamConfig,
    opts: &ReducedBeamOptions,
    progress: &dyn Progress,
) -> Result<BeamBasis> {
    let clock = Stopwatch::start();
    let spec = format!("box:{},{},{}", fem.size[0], fem.size[1], fem.size[2]);
    let shape = crate::io::read_shape(&spec, &Default::default())?;
    let run = build_basis(&shape, &opts.basis_options(fem), progress)?;
    Ok(BeamBasis {
        run,
        seconds: clock.elapsed(),
        key: opts.basis_key(),
    })
}

/// The beam's boundary regions, rest coordinates: the held left end and, for the twist, the
/// turned right end.
pub fn beam_regions(fem: &FemBeamConfig) -> Vec<Region> {
    beam_sim_options(fem, 1, NewtonOptions::default(), None)
        .boundaries
        .iter()
        .map(|b| b.region)
        .collect()
}

/// The reduced simulation of the beam test `fem.test` (design.md section 3): time step and
/// gravity of `fem.solver`, the left `held_length` metres held and, for the twist, the right
/// `twist_length` metres turned about the beam's axis by `twist_degrees` over `fem.steps`
/// steps; penalty stiffness `stiffness` (Pa/m^2; None: the default that scales with the
/// material and the step), `cubature` points, solver `newton`.
pub fn beam_sim_options(
    fem: &FemBeamConfig,
    cubature: usize,
    newton: NewtonOptions,
    stiffness: Option<f64>,
) -> SimOptions {
    let mut boundaries = vec![Boundary {
        region: Region::HalfSpace {
            point: [fem.held_length, 0.0, 0.0],
            normal: [-1.0, 0.0, 0.0],
        },
        motion: Motion::Fixed,
        stiffness,
    }];
    let dt = fem.solver.dt;
    if fem.test == BeamTest::Twist {
        boundaries.push(Boundary {
            region: Region::HalfSpace {
                point: [fem.size[0] - fem.twist_length, 0.0, 0.0],
                normal: [1.0, 0.0, 0.0],
            },
            motion: Motion::Rotate {
                pivot: [0.0, 0.5 * fem.size[1], 0.5 * fem.size[2]],
                axis: [1.0, 0.0, 0.0],
                degrees_per_second: fem.twist_degrees / (fem.steps as f64 * dt),
            },
            stiffness,
        });
    }
    let g = fem.solver.gravity;
    SimOptions {
        dt,
        gravity: g.iter().any(|v| *v != 0.0).then_some(g),
        cubature,
        newton,
        boundaries,
        ..SimOptions::default()
    }
}

/// Simulate the beam test `fem.test` with the reduced model on `basis` and compare with
/// `reference` (made from `fem`). `precompute_s` in the result is the basis build time plus
/// this run's model setup. `opts` must match the basis ([`BasisKey`]).
pub fn simulate_beam(
    fem: &FemBeamConfig,
    reference: &BeamReference,
    basis: &BeamBasis,
    opts: &ReducedBeamOptions,
    progress: &dyn Progress,
) -> Result<BeamComparison> {
    if basis.key != opts.basis_key() {
        return Err(Error::param(
            "basis",
            format!("{:?}", basis.key),
            format!("built for other settings than {:?}", opts.basis_key()),
        ));
    }
    let steps = opts.frames.unwrap_or(fem.steps).min(reference.frames.len());
    let clock = Stopwatch::start();
    let run = &basis.run;
    let sim_opts = beam_sim_options(fem, opts.cubature, opts.newton, opts.hold_stiffness);
    let mut sim = ReducedSim::new(&run.basis, &run.points, &run.material, &sim_opts)?;
    let weights = run.basis.weights(&reference.rest)?;
    let precompute_s = basis.seconds + clock.elapsed();
    progress.begin("reduced steps", Some(steps as u64));
    let mut frames: Vec<Vec<Point3>> = Vec::with_capacity(steps);
    let mut step_s = 0.0;
    let mut monitors = run.report.monitors.clone();
    let mut warnings = run.report.warnings.clone();
    for k in 0..steps {
        let r = sim.step();
        step_s += r.wall_s;
        monitors.add_step(&r.solve);
        if !r.solve.converged {
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
    let metric = |e: crate::fem::FemError| Error::param("beam", fem.test.name(), e.to_string());
    let rest = &reference.rest;
    let err = crate::fem::metric::trajectory_error(rest, &reference.frames[..steps], &frames)
        .map_err(metric)?;
    let half = (frames.len() / 2).max(1).min(frames.len());
    let first =
        crate::fem::metric::trajectory_error(rest, &reference.frames[..half], &frames[..half])
            .map_err(metric)?;
    let fit = if opts.fit {
        Some(fit_residual_from_weights(
            &weights,
            rest,
            &reference.frames[..steps],
        )?)
    } else {
        None
    };
    if let Some(f) = fit.filter(FitResidual::rank_deficient) {
        warnings.push(format!(
            "basis fit: the design matrix at the FEM nodes has rank {} of {} columns",
            f.rank, f.columns
        ));
    }
    Ok(BeamComparison {
        test: fem.test.name(),
        modes: opts.modes,
        kernels: opts.kernels,
        points: run.points.len(),
        cubature_points: sim.cubature().len(),
        hessian: opts.newton.hessian,
        tol: opts.newton.tol,
        frames: steps,
        boundaries: opts.boundaries,
        normalized_mse: err.normalized_mse,
        max_error: err.max_error,
        normalized_mse_first_half: first.normalized_mse,
        max_error_first_half: first.max_error,
        precompute_s,
        basis_s: basis.seconds,
        reduced_step_ms_mean: 1e3 * step_s / steps.max(1) as f64,
        reduced_nonconverged_steps: monitors.newton_nonconverged_steps.unwrap_or(0),
        fem_step_ms_mean: reference.step_ms_mean(),
        fem_nodes: reference.rest.len(),
        fem_tets: reference.tets.len(),
        fem_resolution: fem.resolution,
        fem_cached: matches!(reference.cache, crate::fem::beam::CacheStatus::Hit(_)),
        monitors,
        warnings,
        fit,
    })
}
