//! A world's run recorded for gradients: one [`Recording`] per object
//! (docs/gradients.md). Objects that step alone are recorded, in a `[contact]` scene too (with
//! its collider friction); a step that solved objects together as an island (object-object
//! contact) is not differentiated yet, and the reverse pass refuses it, naming the step.

use crate::sim::gradient::{Gradients, Recording};
use crate::sim::StepReport;
use crate::{Error, Result};

use super::world::World;

/// The tapes of a world's objects, in object order ([`World::record`]).
#[derive(Debug, Clone)]
pub struct WorldRecording {
    objects: Vec<Recording>,
    /// The first recorded step (1-based) that solved objects as an island, and their count.
    island_step: Option<(usize, usize)>,
}

impl World {
    /// Start recording every object from its current state for about `steps` steps (the
    /// tapes' memory is checked first, [`Recording::start`]). A `[contact]` scene is
    /// recorded too: its objects' steps are differentiated where they stepped alone (collider
    /// contact and friction included), and [`WorldRecording::backward`] refuses a run with a
    /// step that solved objects together.
    ///
    /// # Errors
    /// [`Error::Gradient`]: tapes that would not fit in memory.
    pub fn record(&self, steps: usize) -> Result<WorldRecording> {
        let objects = self
            .objects()
            .iter()
            .enumerate()
            .map(|(i, o)| Recording::start(o.sim(), steps).map_err(|e| self.object_error(i, e)))
            .collect::<Result<Vec<_>>>()?;
        Ok(WorldRecording {
            objects,
            island_step: None,
        })
    }

    /// One [`World::step`], recorded in `rec`: every object is checked against its tape
    /// before the step (nothing moves when one was changed). A step that solves objects
    /// together as an island is taken but ends the recording: later calls and
    /// [`WorldRecording::backward`] refuse it, naming the step.
    ///
    /// # Errors
    /// [`Error::Gradient`] for a recording of another world or of objects changed since;
    /// [`World::step`]'s errors.
    pub fn step_recorded(&mut self, rec: &mut WorldRecording) -> Result<Vec<StepReport>> {
        if rec.objects.len() != self.objects().len() {
            return Err(Error::Gradient(format!(
                "the recording has {} objects, the world {}",
                rec.objects.len(),
                self.objects().len()
            )));
        }
        if let Some(island) = rec.island_step {
            return Err(island_error(island));
        }
        for (i, (r, o)) in rec.objects.iter().zip(self.objects()).enumerate() {
            r.check_object(o.sim())
                .map_err(|e| self.object_error(i, e))?;
        }
        let reports = self.step()?;
        let island = self
            .contact_summary()
            .and_then(|c| c.steps.last())
            .and_then(|row| row.islands.first().copied());
        if let Some(size) = island {
            // Not recorded (an island's solve may have undone and redone its members'
            // steps): the recording ends here, and backward refuses it, naming the step.
            rec.island_step = Some((rec.steps() + 1, size));
            return Ok(reports);
        }
        for (i, (r, rep)) in rec.objects.iter_mut().zip(&reports).enumerate() {
            r.record_step(self.objects()[i].sim(), rep)
                .map_err(|e| self.object_error(i, e))?;
        }
        Ok(reports)
    }

    fn object_error(&self, index: usize, e: Error) -> Error {
        Error::Object {
            index,
            name: self.objects()[index].name().to_string(),
            source: Box::new(e),
        }
    }
}

/// The refusal of a recording whose step `step` (1-based) solved `size` objects together.
fn island_error((step, size): (usize, usize)) -> Error {
    Error::Gradient(format!(
        "recorded step {step} solved {size} objects together as an island (object-object \
         contact, or an object touching itself), whose solve the reverse pass does not \
         differentiate yet; the recording ended there: record a run whose objects do not touch \
         each other"
    ))
}

impl WorldRecording {
    /// Steps recorded.
    pub fn steps(&self) -> usize {
        self.objects.first().map_or(0, Recording::steps)
    }

    /// Each object's tape, in object order.
    pub fn objects(&self) -> &[Recording] {
        &self.objects
    }

    /// Bytes the tapes hold.
    pub fn tape_bytes(&self) -> u64 {
        self.objects.iter().map(Recording::tape_bytes).sum()
    }

    /// The reverse pass of every object: `dl_dz[i]` is object i's loss gradient as
    /// [`Recording::backward`] takes it (steps + 1 frames, each empty or 12 (m + 1) values);
    /// an empty list for an object the loss does not see. Consumes the recording.
    ///
    /// # Errors
    /// [`Recording::backward`]'s, naming the object; a list of the wrong length; a run with a
    /// step that solved objects together as an island (named).
    pub fn backward(self, world: &World, dl_dz: &[Vec<Vec<f64>>]) -> Result<Vec<Gradients>> {
        if let Some(island) = self.island_step {
            return Err(island_error(island));
        }
        if dl_dz.len() != self.objects.len() {
            return Err(Error::Gradient(format!(
                "the loss gradient has {} objects, the world {}",
                dl_dz.len(),
                self.objects.len()
            )));
        }
        let frames = self.steps() + 1;
        self.objects
            .into_iter()
            .zip(dl_dz)
            .enumerate()
            .map(|(i, (r, g))| {
                let none = vec![Vec::new(); frames];
                let g = if g.is_empty() { &none } else { g };
                r.backward(world.objects()[i].sim(), g)
                    .map_err(|e| world.object_error(i, e))
            })
            .collect()
    }
}
