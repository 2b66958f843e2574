//! A world's run recorded for gradients: one [`Recording`] per object and, in a `[contact]`
//! scene, the islands each step solved (docs/gradients.md). The reverse pass runs the objects'
//! passes together, a step at a time: an object that stepped alone is solved alone, the
//! members of an island jointly ([`ContactWorld::island_adjoint`]), which also gives the
//! gradients of the object-object contact (pair stiffness and friction).

use crate::sim::contact::step::{ContactWorld, IslandSolve};
use crate::sim::gradient::{Gradients, ObjectReverse, Recording};
use crate::sim::{ReducedSim, StepReport};
use crate::{Error, Result};

use super::world::World;

/// The tapes of a world's objects, in object order ([`World::record`]), and the islands of
/// each recorded step.
#[derive(Debug, Clone)]
pub struct WorldRecording {
    objects: Vec<Recording>,
    /// Per recorded step, the islands' final solves (empty where every object stepped alone).
    islands: Vec<Vec<IslandSolve>>,
}

/// The reverse pass of a world: every object's gradients, and those of the object-object
/// contact in a `[contact]` scene.
#[derive(Debug, Clone)]
pub struct WorldGradients {
    /// Each object's gradients, in object order.
    pub objects: Vec<Gradients>,
    /// dL/dkappa of each pair of objects' penalty stiffness as the scene gives it (row-major,
    /// objects x objects, symmetric: a pair's value at (a, b) and at (b, a); self-contact on
    /// the diagonal; a raise within a step held as a factor), per Pa/m^2. Empty without
    /// `[contact]`.
    pub contact_stiffness: Vec<f64>,
    /// dL/dmu of each pair of objects' friction coefficient, laid out as
    /// `contact_stiffness` (one-sided at mu = 0). Empty without `[contact]`.
    pub contact_friction: Vec<f64>,
}

impl World {
    /// Start recording every object from its current state for about `steps` steps (the
    /// tapes' memory is checked first, [`Recording::start`]). A `[contact]` scene is
    /// recorded too, with the islands of each step: [`WorldRecording::backward`] reverses
    /// the steps objects took alone one by one and those they took together jointly.
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
            islands: Vec::new(),
        })
    }

    /// One [`World::step`], recorded in `rec`: every object is checked against its tape
    /// before the step (nothing moves when one was changed), and the islands the step solved
    /// are kept.
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
        for (i, (r, o)) in rec.objects.iter().zip(self.objects()).enumerate() {
            r.check_object(o.sim())
                .map_err(|e| self.object_error(i, e))?;
        }
        let reports = self.step()?;
        for (i, (r, rep)) in rec.objects.iter_mut().zip(&reports).enumerate() {
            r.record_step(self.objects()[i].sim(), rep)
                .map_err(|e| self.object_error(i, e))?;
        }
        let islands = self
            .contact_state()
            .map(|c| c.last_islands.clone())
            .unwrap_or_default();
        rec.islands.push(islands);
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

    /// Objects solved together as an island at some recorded step (the largest island).
    pub fn largest_island(&self) -> usize {
        self.islands
            .iter()
            .flatten()
            .map(|s| s.members.len())
            .max()
            .unwrap_or(0)
    }

    /// The reverse pass of every object: `dl_dz[i]` is object i's loss gradient as
    /// [`Recording::backward`] takes it (steps + 1 frames, each empty or 12 (m + 1) values);
    /// an empty list for an object the loss does not see. Steps solved as islands are
    /// reversed jointly. Consumes the recording.
    ///
    /// # Errors
    /// [`Recording::backward`]'s, naming the object; a list of the wrong length; an island
    /// whose exact Hessian is not positive definite (naming its objects and the step).
    pub fn backward(self, world: &World, dl_dz: &[Vec<Vec<f64>>]) -> Result<WorldGradients> {
        let n = self.objects.len();
        if dl_dz.len() != n {
            return Err(Error::Gradient(format!(
                "the loss gradient has {} dl_dz entries, the world {n} objects",
                dl_dz.len()
            )));
        }
        let steps = self.steps();
        let none = vec![Vec::new(); steps + 1];
        let mut passes = self
            .objects
            .into_iter()
            .zip(dl_dz)
            .enumerate()
            .map(|(i, (r, g))| {
                let g = if g.is_empty() { &none } else { g };
                ObjectReverse::new(r, world.objects()[i].sim(), g, false)
                    .map_err(|e| world.object_error(i, e))
            })
            .collect::<Result<Vec<_>>>()?;
        let contact = world.contact_state().map(|c| c.contact_world());
        let pairs = if contact.is_some() { n * n } else { 0 };
        let mut stiffness = vec![0.0; pairs];
        let mut friction = vec![0.0; pairs];
        for t in (1..=steps).rev() {
            let begun: Vec<_> = passes.iter_mut().map(|p| p.begin(t)).collect();
            let mut lambdas: Vec<Option<Vec<f64>>> = vec![None; n];
            let mut lagged: Vec<Option<Vec<f64>>> = vec![None; n];
            if let Some(cw) = contact {
                for island in &self.islands[t - 1] {
                    let out = reverse_island(cw, island, &passes, &begun, t)
                        .map_err(|e| island_error(world, island, e))?;
                    let m = island.members.len();
                    let mut at = 0;
                    for (p, &a) in island.members.iter().enumerate() {
                        let dofs = passes[a].state(t).len();
                        lambdas[a] = Some(out.lambda[at..at + dofs].to_vec());
                        lagged[a] = Some(out.start[at..at + dofs].to_vec());
                        at += dofs;
                        for (q, &b) in island.members.iter().enumerate() {
                            stiffness[a * n + b] += out.stiffness[p * m + q];
                            friction[a * n + b] += out.friction[p * m + q];
                        }
                    }
                }
            }
            for (i, (pass, (start, rhs))) in passes.iter_mut().zip(&begun).enumerate() {
                let lambda = match lambdas[i].take() {
                    Some(l) => l,
                    None => pass
                        .solve_alone(start, t, rhs)
                        .map_err(|e| world.object_error(i, e))?,
                };
                pass.finish_step(t, start, &lambda, lagged[i].as_deref())
                    .map_err(|e| world.object_error(i, e))?;
            }
        }
        Ok(WorldGradients {
            objects: passes.into_iter().map(ObjectReverse::finish).collect(),
            contact_stiffness: stiffness,
            contact_friction: friction,
        })
    }
}

/// The joint adjoint solve of `island` at recorded step `t`, from its members' passes and
/// their steps' starts and right-hand sides (`begun`, per object).
fn reverse_island(
    cw: &ContactWorld,
    island: &IslandSolve,
    passes: &[ObjectReverse<'_>],
    begun: &[(crate::sim::object::StepStart, Vec<f64>)],
    t: usize,
) -> Result<crate::sim::contact::adjoint::IslandAdjoint> {
    let members = &island.members;
    let sims: Vec<&ReducedSim> = members.iter().map(|&i| passes[i].sim()).collect();
    let starts: Vec<_> = members.iter().map(|&i| &begun[i].0).collect();
    let stack = |f: &dyn Fn(usize) -> Vec<f64>| -> Vec<f64> {
        members.iter().flat_map(|&i| f(i)).collect()
    };
    let z = stack(&|i| passes[i].state(t).to_vec());
    let z0 = stack(&|i| passes[i].state(t - 1).to_vec());
    let rhs = stack(&|i| begun[i].1.clone());
    cw.island_adjoint(island, &sims, &starts, &z, &z0, &rhs, t)
}

/// An island's failure, naming its objects.
fn island_error(world: &World, island: &IslandSolve, e: Error) -> Error {
    let names: Vec<&str> = island
        .members
        .iter()
        .map(|&i| world.objects()[i].name())
        .collect();
    match e {
        Error::Gradient(m) => Error::Gradient(format!("{m} (objects {})", names.join(", "))),
        other => other,
    }
}
