//! Running a scene as a batch: a loop over a [`World`] with a [`FrameWriter`] observing it,
//! and the summary of the run.

use super::frames::{FrameObserver, FrameWriter};
use super::report::RunSummary;
use super::settings::RunSettings;
use super::spec::Scene;
use super::world::World;
use crate::progress::Progress;
use crate::report::Stopwatch;
use crate::Result;

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
                .stress(scene.output.stress)
                .usd_physics(scene.output.usd_physics),
        ),
        None => None,
    };
    if let Some(w) = writer.as_mut() {
        w.frame(&world, 0)?;
    }
    let steps = scene.simulation.steps;
    progress.begin("simulate", Some(steps as u64));
    let mut stepped = || -> Result<()> {
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
        Ok(())
    };
    if let Err(e) = stepped() {
        if let Some(w) = writer.as_mut() {
            // A stopped, cancelled or failed run keeps its frames, and its collections list
            // exactly them. The run's own error is the one to report.
            let _ = w.finish(&world);
        }
        return Err(e);
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
