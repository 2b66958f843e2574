//! `freeform run`: simulate a scene file and write frames for ParaView.

use crate::{emit, set_threads, CliResult};
use clap::Args;
use freeform::progress::{Progress, Silent, TerminalProgress};
use freeform::scene::{run as run_scene, Format, RunSettings, RunSummary, Scene};
use std::io::IsTerminal;
use std::path::PathBuf;

#[derive(Args)]
pub struct RunArgs {
    /// The scene file (TOML; see docs/scenes.md and examples/*.toml).
    scene: PathBuf,
    /// Directory for the frames (VTK .vtp + .pvd, PLY, a USD stage); none: simulate without
    /// writing frames.
    #[arg(long)]
    out: Option<PathBuf>,
    /// Print the JSON summary (per-step wall time, iterations, energy, line-search failures).
    #[arg(long)]
    json: bool,
    /// Ignore and do not write the basis cache.
    #[arg(long)]
    no_cache: bool,
    /// Worker threads (default: all cores).
    #[arg(long)]
    threads: Option<usize>,
    /// Turn warnings (poorly conditioned basis, a step that did not converge, a failed line
    /// search, a Newton Hessian fallback) into an error: stop at the first one, exit code 1.
    #[arg(long)]
    strict: bool,
    /// Number of time steps, overriding the scene's `simulation.steps` (shorten an example
    /// without copying its file).
    #[arg(long)]
    steps: Option<usize>,
    /// Time step, seconds, overriding the scene's `simulation.dt`.
    #[arg(long)]
    dt: Option<f64>,
    /// Frame formats, overriding the scene's `output.formats`: any of vtk, ply, usd
    /// (comma-separated or repeated; usd writes one stage, <out>/run.usda; docs/usd.md).
    #[arg(long = "format", value_delimiter = ',', value_parser = parse_format)]
    formats: Vec<Format>,
}

fn parse_format(s: &str) -> Result<Format, String> {
    match s.trim().to_ascii_lowercase().as_str() {
        "vtk" => Ok(Format::Vtk),
        "ply" => Ok(Format::Ply),
        "usd" | "usda" => Ok(Format::Usd),
        other => Err(format!(
            "`{other}` is not a frame format: use vtk, ply or usd"
        )),
    }
}

pub fn run(args: RunArgs) -> CliResult {
    set_threads(args.threads)?;
    let mut scene = Scene::load(&args.scene)?;
    if args.no_cache {
        scene.cache.enabled = false;
    }
    if let Some(steps) = args.steps {
        scene.simulation.steps = steps;
    }
    if let Some(dt) = args.dt {
        scene.simulation.dt = dt;
    }
    if !args.formats.is_empty() {
        scene.output.formats = args.formats.clone();
    }
    if args.steps.is_some() || args.dt.is_some() {
        // The scene was checked as read; check the overridden one (the flags name the fields).
        scene.validate()?;
    }
    let settings = RunSettings {
        out: args.out.clone(),
        strict: args.strict,
        ..RunSettings::for_scene_file(&args.scene)
    };
    let bar = TerminalProgress::new();
    let progress: &dyn Progress = if std::io::stderr().is_terminal() {
        &bar
    } else {
        &Silent
    };
    let summary = run_scene(&scene, &settings, progress)?;
    if args.json {
        let mut v = serde_json::to_value(&summary)?;
        v["scene"] = serde_json::Value::String(args.scene.display().to_string());
        emit(&(serde_json::to_string_pretty(&v)? + "\n"))?;
    } else {
        emit(&text_summary(&summary, &args))?;
    }
    Ok(())
}

fn text_summary(s: &RunSummary, args: &RunArgs) -> String {
    let mut lines = vec![format!(
        "freeform run {}: {} steps of {} s in {:.2} s",
        args.scene.display(),
        s.steps,
        s.dt,
        s.total_s
    )];
    for o in &s.objects {
        lines.push(format!(
            "  {}: {} kernels, {} modes, {} integration / {} cubature points; basis {} ({:.2} s)",
            o.name,
            o.kernels,
            o.modes,
            o.points,
            o.cubature_points,
            if o.basis_cached {
                "from cache"
            } else {
                "computed"
            },
            o.precompute_s
        ));
        lines.push(format!(
            "    step {:.2} ms mean, {:.2} ms max; {:.2} iterations mean, {} max; {} not converged; {} line-search failures",
            o.step_ms_mean,
            o.step_ms_max,
            o.iterations_mean,
            o.iterations_max,
            o.nonconverged_steps,
            o.line_search_failures
        ));
    }
    if let Some(out) = &args.out {
        lines.push(format!(
            "  {} frames, {} files in {}",
            s.frames,
            s.files.len(),
            out.display()
        ));
    }
    let shown = s.warnings.len().min(10);
    lines.extend(
        s.warnings[..shown]
            .iter()
            .map(|w| format!("  warning: {w}")),
    );
    if s.warnings.len() > shown {
        lines.push(format!(
            "  ... and {} more warnings (see --json)",
            s.warnings.len() - shown
        ));
    }
    lines.join("\n") + "\n"
}
