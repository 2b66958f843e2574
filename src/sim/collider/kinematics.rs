//! Obstacles in motion: each one's scripted or caller-set [`Motion`] and optional parent,
//! composed into poses at any time ([`Kinematics`]).

use super::obstacle::Obstacle;
use crate::linalg3::mul;
use crate::sim::motion::{Motion, Rigid};
use crate::{Error, Result};

/// The composition `outer` after `inner`: x -> outer(inner(x)).
pub fn compose(outer: &Rigid, inner: &Rigid) -> Rigid {
    let t = outer.apply(&inner.translation);
    Rigid {
        rotation: mul(&outer.rotation, &inner.rotation),
        translation: t,
    }
}

/// The obstacles of a scene with their kinematics: each one's [`Motion`] (scripted, or a
/// [`Motion::Pose`] set by the caller) and optional parent, whose pose it follows
/// (articulated chains: a child's motion is relative to its parent's frame).
#[derive(Debug, Clone)]
pub struct Kinematics {
    obstacles: Vec<Obstacle>,
    motions: Vec<Motion>,
    parents: Vec<Option<usize>>,
}

impl Kinematics {
    /// Obstacles with their motions and parents (indices of earlier obstacles).
    ///
    /// # Errors
    /// Lengths that differ, an invalid motion, or a parent that is not an earlier obstacle.
    pub fn new(
        obstacles: Vec<Obstacle>,
        motions: Vec<Motion>,
        parents: Vec<Option<usize>>,
    ) -> Result<Kinematics> {
        if motions.len() != obstacles.len() || parents.len() != obstacles.len() {
            return Err(Error::LengthMismatch {
                what: "collider motions and parents (one per collider)",
                expected: obstacles.len(),
                got: motions.len().min(parents.len()),
            });
        }
        for (i, (m, p)) in motions.iter().zip(&parents).enumerate() {
            m.validate()?;
            if let Some(p) = p {
                if *p >= i {
                    return Err(Error::param(
                        "parent",
                        p,
                        format!(
                            "collider {i}: a parent must be a collider listed before its child"
                        ),
                    ));
                }
            }
        }
        Ok(Kinematics {
            obstacles,
            motions,
            parents,
        })
    }

    /// Number of obstacles.
    pub fn len(&self) -> usize {
        self.obstacles.len()
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.obstacles.is_empty()
    }

    /// The obstacles, rest frames.
    pub fn obstacles(&self) -> &[Obstacle] {
        &self.obstacles
    }

    /// Each obstacle's own motion (relative to its parent's frame when it has one).
    pub fn motions(&self) -> &[Motion] {
        &self.motions
    }

    /// Each obstacle's parent.
    pub fn parents(&self) -> &[Option<usize>] {
        &self.parents
    }

    /// The pose of every obstacle at time `t` (seconds): its motion at `t`, after its
    /// parent's pose.
    pub fn poses(&self, t: f64) -> Vec<Rigid> {
        let mut poses: Vec<Rigid> = Vec::with_capacity(self.len());
        for (m, p) in self.motions.iter().zip(&self.parents) {
            let own = m.at(t);
            let pose = match p {
                Some(p) => compose(&poses[*p], &own),
                None => own,
            };
            poses.push(pose);
        }
        poses
    }

    /// Replace obstacle `index`'s motion from now on.
    ///
    /// # Errors
    /// An index out of range or an invalid motion.
    pub fn set_motion(&mut self, index: usize, motion: Motion) -> Result<()> {
        motion.validate()?;
        let count = self.len();
        let m = self.motions.get_mut(index).ok_or_else(|| {
            Error::param(
                "collider",
                index,
                format!("there are {count} colliders (indices from 0)"),
            )
        })?;
        *m = motion;
        Ok(())
    }

    /// Replace obstacle `index`'s geometry (its motion and parent stay).
    ///
    /// # Errors
    /// An index out of range.
    pub fn set_obstacle(&mut self, index: usize, obstacle: Obstacle) -> Result<()> {
        let count = self.len();
        let o = self.obstacles.get_mut(index).ok_or_else(|| {
            Error::param(
                "collider",
                index,
                format!("there are {count} colliders (indices from 0)"),
            )
        })?;
        *o = obstacle;
        Ok(())
    }
}
