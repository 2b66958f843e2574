//! Object-object contact: the objects of a scene pushing each other (issue 15).
//!
//! - [`samples`]: contact samples on each object's surface with their skinning weights.
//! - [`features`]: point samples on convex edges and corners, which the thickness leaves out.
//! - [`surface`]: the surface of the volume a point cloud or image occupies, for its samples.
//! - [`visible`]: how deep an object's own surface points reach into another object.
//! - [`pairs`]: the broad phase (object boxes, then a k-d tree over the samples; an object's
//!   own samples for self-contact).
//! - [`energy`]: the pair penalty with its gradient, Hessian and line-search step bound, in
//!   the stacked reduced coordinates of an island.
//! - [`island`]: objects that can touch within a step, solved together by Newton.
//! - [`system`]: the island's Newton system in blocks, solved by conjugate gradients
//!   preconditioned by block Jacobi and [`coarse`], a coarse level over the objects' affine
//!   motions.
//! - [`forest`]: union-find over objects (which share an island).
//! - [`step`]: one step of every object, in stages (sweep, group, solve, regroup, stiffen,
//!   report); `scene` keeps only the adaptor to its objects, warnings and report.
//!
//! Only scenes with a `[contact]` section build any of it ([`ContactSettings`]); without one
//! every object steps alone, as before.

pub mod adjoint;
pub mod coarse;
pub mod energy;
pub mod features;
pub mod forest;
pub mod island;
pub mod pairs;
pub mod samples;
pub mod step;
pub mod surface;
pub mod system;
pub mod visible;

pub use energy::{Body, ContactStats, PairContact, PairHessian};
pub use samples::ContactSamples;

use crate::sim::elastic::Precision;
use crate::{Error, Result};
use serde::{Deserialize, Serialize};

/// Default penetration tolerance: 1% of the smaller rest bounding-box diagonal of the two
/// objects.
pub const DEFAULT_PENETRATION_TOLERANCE: f64 = 0.01;

/// The `[contact]` section of a scene: object-object contact settings. Every field has a
/// default (docs/scenes.md).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ContactSettings {
    /// Penalty stiffness kappa of object pairs, Pa/m^2 (default: the larger of the two
    /// objects' default penalty, [`crate::sim::object::PENALTY_FACTOR`] x max(rho/h^2, E/D^2)).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub stiffness: Option<f64>,
    /// Contact thickness t of every object, metres: its samples are spheres of this radius
    /// set t inside the surface, and two objects touch when samples come within t_a + t_b.
    /// Default: each object's sample spacing, sqrt(surface area / samples).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub radius: Option<f64>,
    /// Contact samples per object (default: from its size, surface area / spacing^2 with the
    /// spacing `radius` if given, else 1/25 of its diagonal, within 64..20,000). An object's
    /// `contact_samples` overrides it.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub samples: Option<usize>,
    /// Feature samples: points on the convex edges and corners of each object's surface,
    /// which stand out past its ordinary samples (a cube's corners by 0.73 t), this many
    /// thicknesses t apart along an edge (default 0: none; 0.5 is the measured setting,
    /// [`features::MEASURED_FEATURE_SPACING`]). They keep those edges out of neighbours'
    /// spheres: the visible penetration of the example scenes halves, and a world step costs
    /// 25-85% more (docs/performance.md).
    pub feature_spacing: f64,
    /// Penetration tolerance as a fraction of the smaller rest diagonal of the two objects
    /// (default 0.01): deeper penetrations are warnings (errors with `--strict`), and
    /// objects that start deeper than it are refused.
    pub penetration_tolerance: f64,
    /// Coulomb friction coefficient of every contact, object-object and object-collider
    /// (default 0.5; 0: frictionless). `pair` tables override it.
    pub friction: f64,
    /// Friction smoothing velocity eps_v, m/s (default 1e-3): tangential sliding slower
    /// than it is resisted like a stiff spring (static friction, smoothed).
    pub friction_velocity: f64,
    /// Per-pair friction coefficients (`[[contact.pair]]`), later ones winning.
    #[serde(rename = "pair", skip_serializing_if = "Vec::is_empty")]
    pub pairs: Vec<FrictionPair>,
    /// How an island's Newton systems are solved (default `blocks`).
    pub solver: IslandSolver,
    /// The arithmetic of the island members' elastic Hessian products in those systems
    /// (default `single`: the islands' Newton iterations are unchanged and the world step
    /// of `plinko.toml` 18% faster, docs/performance.md; `double` for the Hessian to
    /// rounding, the bits of before). Objects stepping alone keep their own `hessian` settings.
    pub hessian_precision: Precision,
    /// Self-contact for every object (default false): an object's own surface samples
    /// push each other apart like two objects' (folds, coils, arms closing). An object's
    /// `self_contact` overrides it.
    pub self_contact: bool,
    /// Self-contact exclusion, in multiples of the object's contact distance 2t (default 2,
    /// more than 1): two samples of one object nearer than this at rest never form a
    /// self-contact pair (the material between them already holds them apart). Two facing
    /// surfaces of one object take part only where their rest gap is at least
    /// (self_exclusion - 1) 2t: set `radius` below gap / 2 for narrow gaps.
    pub self_exclusion: f64,
}

/// Default self-contact exclusion, multiples of the contact distance: a patch of surface
/// must shrink 2-fold before its own samples would touch, and facing surfaces 2t apart
/// at rest already take part.
pub const DEFAULT_SELF_EXCLUSION: f64 = 2.0;

/// How the Newton system of an island of objects in contact is solved.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum IslandSolver {
    /// In its block structure by block-Jacobi preconditioned conjugate gradients
    /// ([`system`]): cost linear in the objects and their contacts. Default.
    #[default]
    Blocks,
    /// The dense Hessian over the whole island, Cholesky-factorized: cost cubic in the
    /// island's size (the reference the block solve is tested against).
    Dense,
}

/// A friction coefficient for one pair of objects or of an object and a named collider.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FrictionPair {
    /// The two names (objects or colliders, in any order).
    pub between: [String; 2],
    /// Coulomb friction coefficient (>= 0).
    pub friction: f64,
}

/// Default friction coefficient (rubber on wood, wood on wood are 0.3-0.7).
pub const DEFAULT_FRICTION: f64 = 0.5;

/// Default friction smoothing velocity, m/s (IPC's choice for metre-scale scenes).
pub const DEFAULT_FRICTION_VELOCITY: f64 = 1e-3;

impl Default for ContactSettings {
    fn default() -> Self {
        ContactSettings {
            stiffness: None,
            radius: None,
            samples: None,
            feature_spacing: 0.0,
            penetration_tolerance: DEFAULT_PENETRATION_TOLERANCE,
            friction: DEFAULT_FRICTION,
            friction_velocity: DEFAULT_FRICTION_VELOCITY,
            pairs: Vec::new(),
            solver: IslandSolver::default(),
            hessian_precision: Precision::Single,
            self_contact: false,
            self_exclusion: DEFAULT_SELF_EXCLUSION,
        }
    }
}

impl ContactSettings {
    /// The friction coefficient between the things named `a` and `b` (None: an unnamed
    /// collider, which takes the default).
    pub fn friction_between(&self, a: Option<&str>, b: Option<&str>) -> f64 {
        let (Some(a), Some(b)) = (a, b) else {
            return self.friction;
        };
        self.pairs
            .iter()
            .rev()
            .find(|p| {
                (p.between[0] == a && p.between[1] == b) || (p.between[0] == b && p.between[1] == a)
            })
            .map_or(self.friction, |p| p.friction)
    }
}

impl ContactSettings {
    /// Check the ranges.
    pub fn validate(&self) -> Result<()> {
        let positive = |name: &'static str, v: Option<f64>, what: &str| match v {
            Some(x) if !(x > 0.0 && x.is_finite()) => Err(Error::param(
                name,
                x,
                format!("{what} must be positive and finite"),
            )),
            _ => Ok(()),
        };
        positive(
            "contact.stiffness",
            self.stiffness,
            "the contact penalty stiffness (Pa/m^2)",
        )?;
        positive("contact.radius", self.radius, "the contact radius (metres)")?;
        if let Some(count) = self.samples {
            samples::check_count("contact.samples", count)?;
        }
        let mus = std::iter::once(("contact.friction", self.friction)).chain(
            self.pairs
                .iter()
                .map(|p| ("contact.pair.friction", p.friction)),
        );
        for (name, mu) in mus {
            if !(mu >= 0.0 && mu.is_finite()) {
                return Err(Error::param(
                    name,
                    mu,
                    "a friction coefficient must be >= 0 and finite (0: frictionless)",
                ));
            }
        }
        let v = self.friction_velocity;
        if !(v > 0.0 && v.is_finite()) {
            return Err(Error::param(
                "contact.friction_velocity",
                v,
                "the friction smoothing velocity (m/s) must be positive and finite (default 1e-3)",
            ));
        }
        let ex = self.self_exclusion;
        if !(ex > 1.0 && ex.is_finite()) {
            return Err(Error::param(
                "contact.self_exclusion",
                ex,
                "the self-contact exclusion is a multiple of the contact distance, above 1 \
                 (nearer samples would touch at rest; default 2)",
            ));
        }
        samples::check_feature_spacing(self.feature_spacing)?;
        let tol = self.penetration_tolerance;
        if !(tol > 0.0 && tol < 1.0) {
            return Err(Error::param(
                "contact.penetration_tolerance",
                tol,
                "the penetration tolerance is a fraction of the smaller object diagonal, in \
                 (0, 1) (default 0.01)",
            ));
        }
        Ok(())
    }
}
