//! `freeform beam bend|twist`: the reduced model against the cached FEM reference on the
//! standard beam (design.md section 3).

use crate::{emit, set_threads, CliResult};
use clap::{Args, ValueEnum};
use freeform::benchmark::{compare_beam, ReducedBeamOptions};
use freeform::fem::beam::{BeamTest, FemBeamConfig};
use freeform::fem::ElementOrder;
use freeform::precompute::sampling::Resolution;
use freeform::precompute::{BasisOptions, BoundaryModes, DensityBands};
use freeform::progress::{Progress, Silent, TerminalProgress};
use freeform::sim::cubature::DEFAULT_CUBATURE;
use freeform::sim::{HessianStrategy, NewtonOptions};
use std::io::IsTerminal;
use std::path::PathBuf;

#[derive(Clone, Copy, ValueEnum)]
pub(crate) enum TestArg {
    Bend,
    Twist,
}

impl From<TestArg> for BeamTest {
    fn from(t: TestArg) -> Self {
        match t {
            TestArg::Bend => BeamTest::Bend,
            TestArg::Twist => BeamTest::Twist,
        }
    }
}

#[derive(Clone, Copy, ValueEnum)]
pub(crate) enum HessianArg {
    Lbfgs,
    Newton,
    Fixed,
}

impl From<HessianArg> for HessianStrategy {
    fn from(h: HessianArg) -> Self {
        match h {
            HessianArg::Lbfgs => HessianStrategy::Lbfgs,
            HessianArg::Newton => HessianStrategy::Newton,
            HessianArg::Fixed => HessianStrategy::Fixed,
        }
    }
}

/// `--boundaries` of `beam` and `sweep`.
#[derive(Clone, Copy, ValueEnum)]
pub(crate) enum BoundariesArg {
    Aware,
    Free,
}

impl From<BoundariesArg> for BoundaryModes {
    fn from(b: BoundariesArg) -> Self {
        match b {
            BoundariesArg::Aware => BoundaryModes::Aware,
            BoundariesArg::Free => BoundaryModes::Free,
        }
    }
}

#[derive(Clone, Copy, ValueEnum)]
enum OrderArg {
    Linear,
    Quadratic,
}

#[derive(Args)]
pub struct BeamArgs {
    /// Which test.
    test: TestArg,
    /// Modes m.
    #[arg(long, default_value_t = BasisOptions::default().modes)]
    modes: usize,
    /// Kernels K.
    #[arg(long, default_value_t = BasisOptions::default().kernels)]
    kernels: usize,
    /// Integration points [default: 50 K clamped to 20,000..2,000,000; 10 K above K = 200,000].
    #[arg(long)]
    points: Option<usize>,
    /// Cubature points while simulating.
    #[arg(long, default_value_t = DEFAULT_CUBATURE)]
    cubature: usize,
    /// Penalty stiffness of the held and twisted ends, Pa/m^2 [default: 1e3 x max(rho/h^2,
    /// E/D^2)]; the FEM holds its nodes exactly.
    #[arg(long)]
    hold_stiffness: Option<f64>,
    /// Hessian strategy of the reduced model.
    #[arg(long, value_enum, default_value = NewtonOptions::default().hessian.name())]
    hessian: HessianArg,
    /// Basis: "aware" (lifts for the held and twisted ends, free modes that vanish there) or
    /// "free" (global modes, the ends held by the penalty alone).
    #[arg(long, value_enum, default_value = BoundaryModes::default().name())]
    boundaries: BoundariesArg,
    /// Newton tolerance of the reduced model.
    #[arg(long, default_value_t = NewtonOptions::default().tol)]
    tol: f64,
    /// Also fit every FEM frame onto the basis by least squares and report the residual over
    /// frames and FEM nodes, as mean |r|/D and mean |r|^2/D^2 (paper Table 6).
    #[arg(long)]
    fit: bool,
    /// Compare (and fit) over the first N frames only (the reduced model runs N steps of the
    /// reference's 200; the motion is unchanged) [default: all].
    #[arg(long)]
    frames: Option<usize>,
    #[command(flatten)]
    density: DensityArgs,
    #[command(flatten)]
    fem: FemArgs,
    /// Print the JSON report.
    #[arg(long)]
    json: bool,
    /// Worker threads (default: all cores).
    #[arg(long)]
    threads: Option<usize>,
    /// Exit with an error (code 1, after the report) when the reduced run raised a warning:
    /// a poorly conditioned basis or a step that did not converge.
    #[arg(long)]
    strict: bool,
}

/// The kernel density options of `freeform beam` (`freeform sweep` takes a list of factors).
#[derive(Args)]
pub(crate) struct DensityArgs {
    /// Kernel spacing factor within the band around the held and turned ends (1 = uniform
    /// placement; 2 = half the spacing there).
    #[arg(long, default_value_t = DensityBands::default().boundaries)]
    density_boundaries: f64,
    /// Half-width of the refined band, in kernel spacings h0 = (V / K)^(1/3).
    #[arg(long, default_value_t = DensityBands::default().band)]
    density_band: f64,
}

impl DensityArgs {
    /// The bands given (the beam is homogeneous: no interface band).
    pub(crate) fn bands(&self) -> DensityBands {
        DensityBands {
            boundaries: self.density_boundaries,
            band: self.density_band,
            ..DensityBands::off()
        }
    }
}

/// The FEM reference options shared by `freeform beam` and `freeform sweep`.
#[derive(Args)]
pub(crate) struct FemArgs {
    /// FEM resolution (cubes per metre; 6 tets per cube) [default: the reference, 4].
    #[arg(long)]
    fem_resolution: Option<usize>,
    /// FEM element order [default: quadratic, the reference].
    #[arg(long, value_enum)]
    fem_order: Option<OrderArg>,
    /// Cache directory for FEM references.
    #[arg(long, default_value = ".freeform-cache/fem")]
    pub(crate) cache: PathBuf,
}

impl FemArgs {
    /// The reference definition of `test` with the overrides given.
    pub(crate) fn config(&self, test: TestArg) -> FemBeamConfig {
        let mut fem = FemBeamConfig::reference(test.into());
        if let Some(r) = self.fem_resolution {
            fem.resolution = r;
        }
        if let Some(o) = self.fem_order {
            fem.solver.order = match o {
                OrderArg::Linear => ElementOrder::Linear,
                OrderArg::Quadratic => ElementOrder::Quadratic,
            };
        }
        fem
    }
}

/// A progress bar on a terminal, nothing otherwise.
pub(crate) fn progress() -> Box<dyn Progress> {
    if std::io::stderr().is_terminal() {
        Box::new(TerminalProgress::new())
    } else {
        Box::new(Silent)
    }
}

pub fn run(args: BeamArgs) -> CliResult {
    set_threads(args.threads)?;
    let fem = args.fem.config(args.test);
    let opts = ReducedBeamOptions {
        modes: args.modes,
        kernels: args.kernels,
        resolution: args.points.map(Resolution::Count),
        cubature: args.cubature,
        newton: NewtonOptions {
            hessian: args.hessian.into(),
            tol: args.tol,
            ..NewtonOptions::default()
        },
        frames: args.frames,
        hold_stiffness: args.hold_stiffness,
        boundaries: args.boundaries.into(),
        fit: args.fit,
        density: args.density.bands(),
    };
    opts.validate(&fem)?;
    let r = compare_beam(&fem, &opts, Some(&args.fem.cache), progress().as_ref())?;
    if args.json {
        emit(&(serde_json::to_string_pretty(&r)? + "\n"))?;
    } else {
        emit(&format!(
            "freeform beam {}: m = {}, K = {}, {} basis, {} cubature points ({})\n  normalized MSE {:.3e}, max error {:.3e} (of the diagonal)\n  precompute {:.2} s, reduced step {:.2} ms ({} not converged), FEM step {:.1} ms ({} nodes, {} tets{})\n",
            r.test,
            r.modes,
            r.kernels,
            r.boundaries,
            r.cubature_points,
            r.hessian.name(),
            r.normalized_mse,
            r.max_error,
            r.precompute_s,
            r.reduced_step_ms_mean,
            r.reduced_nonconverged_steps,
            r.fem_step_ms_mean,
            r.fem_nodes,
            r.fem_tets,
            if r.fem_cached { ", cached" } else { "" }
        ))?;
        if let Some(f) = &r.fit {
            emit(&format!(
                "  basis fit over {} frames x {} FEM nodes: mean |r|/D {:.3e}, mean |r|^2/D^2 {:.3e}, max |r|/D {:.3e} (design matrix rank {} of {}, condition {:.2e})\n",
                f.frames,
                f.nodes,
                f.mean_abs_over_diagonal,
                f.mean_squared_over_diagonal2,
                f.max_over_diagonal,
                f.rank,
                f.columns,
                f.condition_number
            ))?;
        }
        for w in &r.warnings {
            emit(&format!("  warning: {w}\n"))?;
        }
    }
    let warnings: Vec<_> = r
        .warnings
        .iter()
        .map(freeform::report::Warning::monitor)
        .collect();
    freeform::error::check_strict(args.strict, &warnings)?;
    Ok(())
}
