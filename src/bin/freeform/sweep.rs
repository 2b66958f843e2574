//! `freeform sweep bend|twist`: the beam benchmark over modes m x kernels K plus
//! one-at-a-time variations of the integration points, cubature and Hessian strategy around
//! a base point (design in `freeform::benchmark::sweep`), the grid once per kernel density;
//! writes `sweep.csv`, `error_vs_precompute.png`, `error_vs_step.png`, `error_vs_kernels.png`
//! (with two K or more) and, with `--json`, `sweep.json` to `--out`.

use crate::beam::{progress, BoundariesArg, FemArgs, HessianArg, TestArg};
use crate::sweep_plot as plot;
use crate::{emit, set_threads, CliResult};
use clap::Args;
use freeform::benchmark::sweep::{describe, run_sweep, SweepReport, SweepRow, SweepSpec};
use freeform::benchmark::BeamComparison;
use freeform::precompute::sampling::Resolution;
use freeform::precompute::DensityBands;
use freeform::sim::NewtonOptions;
use std::path::{Path, PathBuf};

#[derive(Args)]
pub struct SweepArgs {
    /// Which test.
    test: TestArg,
    /// Modes m of the grid (comma-separated).
    #[arg(long, value_delimiter = ',', default_value = "6,9,16,32")]
    modes: Vec<usize>,
    /// Kernels K of the grid (comma-separated).
    #[arg(long, value_delimiter = ',', default_value = "250,500,1000,2000,4000")]
    kernels: Vec<usize>,
    /// Integration point counts (comma-separated; `auto` = 50 K clamped to 20,000..2,000,000).
    /// The first is used on the grid, the others are varied at the base point.
    #[arg(
        long,
        value_delimiter = ',',
        default_value = "auto",
        conflicts_with = "spacing"
    )]
    points: Vec<String>,
    /// Integration grid spacings, metres (comma-separated), instead of --points. The first is
    /// used on the grid, the others are varied at the base point.
    #[arg(long, value_delimiter = ',')]
    spacing: Vec<f64>,
    /// Cubature points while simulating (comma-separated). The first is used on the grid,
    /// the others are varied at the base point.
    #[arg(long, value_delimiter = ',', default_value = "5000")]
    cubature: Vec<usize>,
    /// Hessian strategies (comma-separated). The first is used on the grid, the others are
    /// varied at the base point.
    #[arg(long, value_enum, value_delimiter = ',', default_value = "lbfgs")]
    hessian: Vec<HessianArg>,
    /// Modes m of the base point of the variations.
    #[arg(long, default_value_t = 16)]
    base_modes: usize,
    /// Kernels K of the base point of the variations.
    #[arg(long, default_value_t = 1000)]
    base_kernels: usize,
    /// Newton tolerance of the reduced model.
    #[arg(long, default_value_t = NewtonOptions::default().tol)]
    tol: f64,
    /// Compare over the first N frames only (the reduced model runs N steps of the
    /// reference's 200; the motion is unchanged) [default: all].
    #[arg(long)]
    frames: Option<usize>,
    /// Basis of every run: "aware" (lifts for the ends, free modes that vanish there) or
    /// "free" (global modes).
    #[arg(long, value_enum, default_value = "aware")]
    boundaries: BoundariesArg,
    /// Output directory (created if missing).
    #[arg(long, default_value = "sweep")]
    out: PathBuf,
    /// Kernel spacing factors at the held and turned ends (comma-separated; 1 = uniform
    /// placement, 2 = half the spacing there): the grid is run once per factor, the
    /// variations with the first.
    #[arg(long, value_delimiter = ',', default_value = "1")]
    density_boundaries: Vec<f64>,
    /// Half-width of the refined band, in kernel spacings h0 = (V / K)^(1/3).
    #[arg(long, default_value_t = DensityBands::default().band)]
    density_band: f64,
    #[command(flatten)]
    fem: FemArgs,
    /// Also write sweep.json and print it.
    #[arg(long)]
    json: bool,
    /// Worker threads (default: all cores).
    #[arg(long)]
    threads: Option<usize>,
}

fn resolutions(args: &SweepArgs) -> Result<Vec<Option<Resolution>>, String> {
    if !args.spacing.is_empty() {
        return Ok(args
            .spacing
            .iter()
            .map(|&h| Some(Resolution::Spacing(h)))
            .collect());
    }
    args.points
        .iter()
        .map(|p| match p.trim() {
            "auto" | "default" => Ok(None),
            s => s
                .parse::<usize>()
                .map(|n| Some(Resolution::Count(n)))
                .map_err(|_| format!("invalid --points entry {s:?}: expected a count or `auto`")),
        })
        .collect()
}

pub fn run(args: SweepArgs) -> CliResult {
    set_threads(args.threads)?;
    let fem = args.fem.config(args.test);
    let spec = SweepSpec {
        modes: args.modes.clone(),
        kernels: args.kernels.clone(),
        resolutions: resolutions(&args)?,
        cubature: args.cubature.clone(),
        hessian: args.hessian.iter().map(|&h| h.into()).collect(),
        base_modes: args.base_modes,
        base_kernels: args.base_kernels,
        newton: NewtonOptions {
            tol: args.tol,
            ..NewtonOptions::default()
        },
        frames: args.frames,
        boundaries: args.boundaries.into(),
        densities: args
            .density_boundaries
            .iter()
            .map(|&boundaries| DensityBands {
                boundaries,
                band: args.density_band,
                ..DensityBands::off()
            })
            .collect(),
    };
    let runs = spec.plan(&fem)?;
    std::fs::create_dir_all(&args.out)
        .map_err(|e| format!("cannot create {}: {e}", args.out.display()))?;
    eprintln!(
        "freeform sweep {}: {} runs, FEM reference from {}",
        fem.test.name(),
        runs.len(),
        args.fem.cache.display()
    );
    let total = runs.len();
    let mut finished = 0;
    let mut on_run = |_: usize,
                      run: &freeform::benchmark::sweep::PlannedRun,
                      outcome: &freeform::Result<BeamComparison>| {
        finished += 1;
        let what = format!(
            "[{finished}/{total}] {} {}: {}",
            fem.test.name(),
            run.axis.name(),
            describe(&run.opts)
        );
        match outcome {
            Ok(r) => eprintln!(
                "{what}: N = {}, MSE {:.3e}, max {:.3e}, precompute {:.2} s, step {:.2} ms{}",
                r.points,
                r.normalized_mse,
                r.max_error,
                r.precompute_s,
                r.reduced_step_ms_mean,
                if r.reduced_nonconverged_steps > 0 {
                    format!(" ({} steps not converged)", r.reduced_nonconverged_steps)
                } else {
                    String::new()
                }
            ),
            Err(e) => eprintln!("{what}: FAILED: {e}"),
        }
    };
    let bar = progress();
    let report = run_sweep(
        &fem,
        &spec,
        &runs,
        Some(&args.fem.cache),
        bar.as_ref(),
        &mut on_run,
    )?;
    write_outputs(&report, &args.out, args.json)?;
    if args.json {
        emit(&(serde_json::to_string_pretty(&report)? + "\n"))?;
    } else {
        emit(&summary(&report, &args.out))?;
    }
    if !report.failures.is_empty() {
        return Err(format!(
            "{} of {} runs failed (see above); the outputs hold the others",
            report.failures.len(),
            total
        )
        .into());
    }
    Ok(())
}

fn summary(report: &SweepReport, out: &Path) -> String {
    let front = |pick: fn(&SweepRow) -> bool| -> String {
        report
            .rows
            .iter()
            .filter(|r| pick(r))
            .map(|r| {
                let density = plot::refined_name(r.density.boundaries)
                    .map(|n| format!(" {n}"))
                    .unwrap_or_default();
                format!(
                    "m{} K{} N{} c{} {}{density}",
                    r.result.modes,
                    r.result.kernels,
                    r.result.points,
                    r.result.cubature_points,
                    r.result.hessian.name()
                )
            })
            .collect::<Vec<_>>()
            .join("; ")
    };
    let rises: Vec<String> = report
        .curves
        .iter()
        .filter_map(|c| {
            let (rise, at) = (c.worst_rise?, c.worst_rise_at?);
            Some(format!(
                "m{} {}: {rise:.2}x at K{at}",
                c.modes,
                plot::density_name(c.density.boundaries)
            ))
        })
        .collect();
    let mut text = format!(
        "freeform sweep {}: {} runs ({} bases) in {:.0} s, outputs in {}\n  Pareto (error vs precompute): {}\n  Pareto (error vs step): {}\n",
        report.test,
        report.rows.len(),
        report.bases_built,
        report.total_s,
        out.display(),
        front(|r| r.pareto_precompute),
        front(|r| r.pareto_step)
    );
    if !rises.is_empty() {
        text += &format!(
            "  error against K, worst point over the best at a smaller K: {}\n",
            rises.join("; ")
        );
    }
    text
}

fn write_outputs(report: &SweepReport, out: &Path, json: bool) -> CliResult {
    let text = |name: &str, body: String| {
        let path = out.join(name);
        freeform::io::write_atomically(&path, |tmp| {
            std::fs::write(tmp, body.as_bytes()).map_err(|source| freeform::Error::Io {
                path: tmp.to_path_buf(),
                source,
            })
        })
    };
    text("sweep.csv", report.to_csv())?;
    if json {
        text("sweep.json", serde_json::to_string_pretty(report)? + "\n")?;
    }
    if !report.rows.is_empty() {
        plot::write_png(
            report,
            plot::Cost::Precompute,
            &out.join("error_vs_precompute.png"),
        )?;
        plot::write_png(report, plot::Cost::Step, &out.join("error_vs_step.png"))?;
        plot::write_kernels_png(report, &out.join("error_vs_kernels.png"))?;
    }
    Ok(())
}
