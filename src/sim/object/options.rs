//! What defines one object's simulation besides its basis ([`SimOptions`]: time step,
//! gravity, boundaries, colliders, placement, solver) and what one step reports
//! ([`StepReport`]).

use crate::material::Region;
use crate::sim::collider::Collider;
use crate::sim::cubature::DEFAULT_CUBATURE;
use crate::sim::motion::{rotation_matrix, AxisAngle, Motion, Rigid};
use crate::sim::newton::{NewtonOptions, SolveReport};
use crate::{Error, Result};
use serde::{Deserialize, Serialize};

/// Default penalty factor: a penalty stiffness is this factor times the larger of the
/// inertial (rho / h^2) and elastic (E / D^2) stiffness densities, so it dominates both and
/// scales with the units, the material and the time step.
pub const PENALTY_FACTOR: f64 = 1e3;

/// How much deeper into an obstacle a cubature point may go along one line-search step,
/// as a fraction of the object's rest diagonal: small enough that a plate a few percent of
/// the object's size cannot be jumped across, large enough that an object settling into
/// contact is not held back (the penalty's depth at rest is far smaller).
pub const SWEEP_DEPTH: f64 = 0.01;

/// A region of the object driven by a prescribed motion (held when the motion is `Fixed`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Boundary {
    /// Which integration points (rest positions) are driven.
    pub region: Region,
    /// The motion of their rest positions (default: held in place).
    #[serde(default = "fixed")]
    pub motion: Motion,
    /// Penalty stiffness, Pa/m^2 (default: [`PENALTY_FACTOR`] x max(rho/h^2, E/D^2)).
    #[serde(default)]
    pub stiffness: Option<f64>,
}

fn fixed() -> Motion {
    Motion::Fixed
}

impl Boundary {
    /// Check the region, the motion and the stiffness (positive and finite when given).
    ///
    /// # Errors
    /// The region's and the motion's errors; [`Error::InvalidParameter`] for the stiffness.
    pub fn validate(&self) -> Result<()> {
        self.region.validate()?;
        self.motion.validate()?;
        match self.stiffness {
            Some(k) if !(k > 0.0 && k.is_finite()) => Err(Error::param(
                "stiffness",
                k,
                "a boundary penalty stiffness (Pa/m^2) must be positive and finite",
            )),
            _ => Ok(()),
        }
    }
}

/// Initial placement and velocity of an object (applied to its rest shape).
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Placement {
    /// Translation, metres.
    pub translation: [f64; 3],
    /// Rotation about the origin, applied before the translation.
    pub rotation: Option<AxisAngle>,
    /// Initial linear velocity, m/s.
    pub velocity: [f64; 3],
    /// Initial angular velocity about the placed centre of mass, rad/s.
    pub angular_velocity: [f64; 3],
}

/// Everything that defines the simulation of one object besides its basis.
#[derive(Debug, Clone, PartialEq)]
pub struct SimOptions {
    /// Time step h, seconds.
    pub dt: f64,
    /// Gravity, m/s^2 (None: no gravity term at all).
    pub gravity: Option<[f64; 3]>,
    /// Cubature points for the elastic energy (default 5000; all points if fewer).
    pub cubature: usize,
    /// Per-step solver settings.
    pub newton: NewtonOptions,
    /// Kinematic boundary conditions.
    pub boundaries: Vec<Boundary>,
    /// Obstacles (static or kinematic; meshes loaded by [`ColliderShape::load`] are shared,
    /// others are read here).
    pub colliders: Vec<Collider>,
    /// Initial placement and velocity.
    pub placement: Placement,
}

impl Default for SimOptions {
    fn default() -> Self {
        Self {
            dt: 0.01,
            gravity: None,
            cubature: DEFAULT_CUBATURE,
            newton: NewtonOptions::default(),
            boundaries: Vec::new(),
            colliders: Vec::new(),
            placement: Placement::default(),
        }
    }
}

/// Report of one time step.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct StepReport {
    /// Step number (1-based).
    pub step: usize,
    /// Time at the end of the step, s.
    pub time: f64,
    /// Wall time of the step, s.
    pub wall_s: f64,
    /// The minimisation's report.
    #[serde(flatten)]
    pub solve: SolveReport,
    /// The largest over the boundary regions of the volume-weighted RMS distance of a
    /// region's integration points from their targets at the end of the step, metres (None
    /// without boundaries). A free basis holds every point, an aware one its lift, so an aware
    /// region's edge band shows here, as does a region the basis cannot follow.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub boundary_rms_deviation: Option<f64>,
}

impl Placement {
    /// The rigid transform x -> R x + t of the placement (rest to world), its values checked.
    ///
    /// # Errors
    /// A translation or rotation that is not finite, or a zero rotation axis.
    pub fn transform(&self) -> Result<Rigid> {
        placement_transform(self)
    }
}

/// The rigid transform x -> R x + t of a placement, its values checked.
pub(super) fn placement_transform(p: &Placement) -> Result<Rigid> {
    if !p
        .translation
        .iter()
        .all(|v| v.abs() <= crate::error::MAX_MAGNITUDE)
    {
        return Err(Error::param(
            "translation",
            format!("{:?}", p.translation),
            "must be finite, at most 1e100 m in magnitude",
        ));
    }
    let rotation = match &p.rotation {
        None => Rigid::IDENTITY.rotation,
        Some(a) => {
            let n = a.axis.iter().map(|v| v * v).sum::<f64>().sqrt();
            if !(n > 0.0 && n.is_finite() && a.degrees.is_finite()) {
                return Err(Error::param(
                    "rotation",
                    format!("{a:?}"),
                    "needs a finite non-zero axis and a finite angle",
                ));
            }
            rotation_matrix(&a.axis.map(|v| v / n), a.degrees.to_radians())
        }
    };
    Ok(Rigid {
        rotation,
        translation: p.translation,
    })
}
