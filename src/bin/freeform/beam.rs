//! `freeform beam bend|twist`: the reduced model against the cached FEM reference on the
//! standard beam (design.md section 3).

use crate::{emit, set_threads, CliResult};
use clap::{Args, ValueEnum};
use freeform::benchmark::{compare_beam, ReducedBeamOptions};
use freeform::fem::beam::{BeamTest, FemBeamConfig};
use freeform::fem::ElementOrder;
use freeform::progress::{Progress, Silent, TerminalProgress};
use freeform::sim::{HessianStrategy, NewtonOptions};
use std::io::IsTerminal;
use std::path::PathBuf;

#[derive(Clone, Copy, ValueEnum)]
enum TestArg {
    Bend,
    Twist,
}

#[derive(Clone, Copy, ValueEnum)]
enum HessianArg {
    Lbfgs,
    Newton,
    Fixed,
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
    #[arg(long, default_value_t = 16)]
    modes: usize,
    /// Kernels K.
    #[arg(long, default_value_t = 1000)]
    kernels: usize,
    /// Integration points [default: 50 K clamped to 20,000..2,000,000].
    #[arg(long)]
    points: Option<usize>,
    /// Cubature points while simulating.
    #[arg(long, default_value_t = 5000)]
    cubature: usize,
    /// Hessian strategy of the reduced model.
    #[arg(long, value_enum, default_value = "lbfgs")]
    hessian: HessianArg,
    /// Newton tolerance of the reduced model.
    #[arg(long, default_value_t = NewtonOptions::default().tol)]
    tol: f64,
    /// FEM resolution (cubes per metre; 6 tets per cube) [default: the reference, 4].
    #[arg(long)]
    fem_resolution: Option<usize>,
    /// FEM element order [default: quadratic, the reference].
    #[arg(long, value_enum)]
    fem_order: Option<OrderArg>,
    /// Cache directory for FEM references.
    #[arg(long, default_value = ".freeform-cache/fem")]
    cache: PathBuf,
    /// Print the JSON report.
    #[arg(long)]
    json: bool,
    /// Worker threads (default: all cores).
    #[arg(long)]
    threads: Option<usize>,
}

pub fn run(args: BeamArgs) -> CliResult {
    set_threads(args.threads)?;
    let test = match args.test {
        TestArg::Bend => BeamTest::Bend,
        TestArg::Twist => BeamTest::Twist,
    };
    let mut fem = FemBeamConfig::reference(test);
    if let Some(r) = args.fem_resolution {
        fem.resolution = r;
    }
    if let Some(o) = args.fem_order {
        fem.solver.order = match o {
            OrderArg::Linear => ElementOrder::Linear,
            OrderArg::Quadratic => ElementOrder::Quadratic,
        };
    }
    let opts = ReducedBeamOptions {
        modes: args.modes,
        kernels: args.kernels,
        points: args.points,
        cubature: args.cubature,
        newton: NewtonOptions {
            hessian: match args.hessian {
                HessianArg::Lbfgs => HessianStrategy::Lbfgs,
                HessianArg::Newton => HessianStrategy::Newton,
                HessianArg::Fixed => HessianStrategy::Fixed,
            },
            tol: args.tol,
            ..NewtonOptions::default()
        },
    };
    let bar = TerminalProgress::new();
    let progress: &dyn Progress = if std::io::stderr().is_terminal() {
        &bar
    } else {
        &Silent
    };
    let r = compare_beam(&fem, &opts, Some(&args.cache), progress)?;
    if args.json {
        emit(&(serde_json::to_string_pretty(&r)? + "\n"))?;
    } else {
        emit(&format!(
            "freeform beam {}: m = {}, K = {}, {} cubature points ({})\n  normalized MSE {:.3e}, max error {:.3e} (of the diagonal)\n  precompute {:.2} s, reduced step {:.2} ms ({} not converged), FEM step {:.1} ms ({} nodes, {} tets{})\n",
            r.test,
            r.modes,
            r.kernels,
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
    }
    Ok(())
}
