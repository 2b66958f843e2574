//! What an object's step sees of the world around it: gravity and the colliders with their
//! kinematics. One [`Environment`] is owned by whoever steps the objects (a
//! [`crate::scene::World`] shares its one with every object, a stand-alone
//! [`crate::sim::ReducedSim`] owns its own) and passed into every step's terms
//! ([`crate::sim::terms::StepAt::env`]); nothing else keeps a copy.

use crate::sim::collider::{self, Collider, ColliderShape, Kinematics, Obstacle};
use crate::sim::motion::Motion;
use crate::{Error, Result};

/// Gravity and the colliders' obstacles, motions and parents.
#[derive(Debug, Clone)]
pub struct Environment {
    gravity: Option<[f64; 3]>,
    colliders: Kinematics,
}

impl Environment {
    /// Gravity `gravity` (m/s^2, finite; None: none) and the colliders `colliders` (meshes
    /// loaded or read here, parents resolved).
    pub fn new(gravity: Option<[f64; 3]>, colliders: &[Collider]) -> Result<Environment> {
        check_gravity(gravity)?;
        Ok(Environment {
            gravity,
            colliders: collider::kinematics(colliders)?,
        })
    }

    /// Gravity, m/s^2 (None: no gravity).
    pub fn gravity(&self) -> Option<[f64; 3]> {
        self.gravity
    }

    /// Gravity from the next step on, m/s^2 (finite; None: none).
    pub fn set_gravity(&mut self, gravity: Option<[f64; 3]>) -> Result<()> {
        check_gravity(gravity)?;
        self.gravity = gravity;
        Ok(())
    }

    /// The colliders' obstacles, motions and parents.
    pub fn kinematics(&self) -> &Kinematics {
        &self.colliders
    }

    /// A new motion for collider `index` (relative to its parent's frame if it has one).
    pub fn set_collider_motion(&mut self, index: usize, motion: Motion) -> Result<()> {
        self.colliders.set_motion(index, motion)
    }

    /// A new shape for collider `index` (a mesh not yet loaded is read here); its motion and
    /// parent stay.
    pub fn set_collider_shape(&mut self, index: usize, shape: &ColliderShape) -> Result<()> {
        let obstacle = Obstacle::new(shape)?;
        self.colliders.set_obstacle(index, obstacle)
    }
}

/// Largest gravity magnitude accepted, m/s^2 (1e8 g, beyond any centrifuge). Far larger
/// values overflow the incremental potential's squares and the step reports a frozen object
/// as converged.
pub const MAX_GRAVITY: f64 = 1e9;

/// Why `g` (m/s^2) is not a usable gravity, if it is not: the one check of it.
pub fn gravity_problem(g: [f64; 3]) -> Option<String> {
    if !g.iter().all(|v| v.is_finite()) {
        return Some("must be finite".into());
    }
    let magnitude = g.iter().map(|v| v * v).sum::<f64>().sqrt();
    (magnitude > MAX_GRAVITY).then(|| {
        format!("its magnitude {magnitude:.3e} m/s^2 is above the limit {MAX_GRAVITY:.0e} m/s^2")
    })
}

/// Gravity, if any, passes [`gravity_problem`].
pub(crate) fn check_gravity(gravity: Option<[f64; 3]>) -> Result<()> {
    match gravity.and_then(|g| gravity_problem(g).map(|why| (g, why))) {
        Some((g, why)) => Err(Error::param("gravity", format!("{g:?}"), why)),
        None => Ok(()),
    }
}
