//! Scenes: objects, boundary conditions, colliders, time stepping and outputs, from a TOML
//! file (`freeform run scene.toml`) or built in code with [`SceneBuilder`]. A [`World`] is a
//! scene being simulated: step it, read every object's state and deformed points, change
//! gravity, boundary motions, placements and collider poses between steps; observers such as
//! [`FrameWriter`] write its frames; [`run`] is the batch loop over both. docs/scenes.md
//! documents the format with every default.
//!
//! - `spec`: the scene description and its validation; `settings`: where a run reads and
//!   writes; `report`: the rows and summaries a run reports; `setup`: an object's shape and
//!   basis (through the `cache`); `render_set`: extra render inputs; `object`: one live
//!   object; `contact`: object-object contact between objects; `world`: the live simulation;
//!   `gradient`: a world's run recorded for gradients; `frames`: frame output; `run`: the
//!   batch loop.
//!
//! ```no_run
//! use freeform::material::Region;
//! use freeform::scene::{run, ObjectSpec, RunSettings, SceneBuilder};
//! let scene = SceneBuilder::new(0.01, 200)
//!     .gravity([0.0, -9.81, 0.0])
//!     .object(
//!         ObjectSpec::new("beam", "box:5,1,1")?
//!             .kernels(1000)
//!             .modes(16)
//!             .hold(Region::HalfSpace { point: [0.5, 0.0, 0.0], normal: [-1.0, 0.0, 0.0] }),
//!     )
//!     .build()?;
//! let summary = run(&scene, &RunSettings::default(), &freeform::progress::Silent)?;
//! println!("mean step {:.2} ms", summary.objects[0].step_ms_mean);
//! # Ok::<(), freeform::Error>(())
//! ```

mod cache;
mod contact;
mod frames;
mod gradient;
mod numbers;
mod object;
mod render_set;
mod report;
mod run;
mod settings;
mod setup;
mod shape;
mod spec;
mod stress_arrays;
mod usd_frames;
mod world;

pub use frames::{FrameObserver, FrameWriter};
pub use gradient::{WorldGradients, WorldRecording};
pub use object::{PreparedObject, SceneObject, CONTACT_SURFACE_SET};
pub use render_set::RenderSet;
pub use report::{ContactStepRow, ContactSummary, ObjectSummary, RunSummary, StepRow, VisibleSpot};
pub use run::run;
pub use settings::RunSettings;
pub use shape::{ObjectShape, ShapeSource};
pub use spec::{
    BasisSettings, CacheSettings, Format, ObjectSpec, OutputSettings, Scene, Simulation,
    SolverSettings, MAX_OBJECT_STEPS, MAX_STEPS,
};
pub use usd_frames::{UsdFrameWriter, STAGE_FILE};
pub use world::World;

use crate::material::{Material, MaterialOverride, Region};
use crate::sim::motion::Motion;
use crate::sim::newton::HessianStrategy;
use crate::sim::{Boundary, Collider, Placement};
use crate::{Error, Result};
use std::path::Path;

impl Scene {
    /// Read and validate a scene file.
    pub fn load(path: &Path) -> Result<Scene> {
        let text = std::fs::read_to_string(path).map_err(|source| Error::Io {
            path: path.to_path_buf(),
            source,
        })?;
        Scene::from_toml(&text).map_err(|e| match e {
            Error::Scene { message } => Error::Scene {
                message: format!("{}: {message}", path.display()),
            },
            other => other,
        })
    }
}

/// Builds a [`Scene`] in code; [`SceneBuilder::build`] validates it like a scene file.
#[derive(Debug, Clone)]
pub struct SceneBuilder {
    scene: Scene,
}

impl SceneBuilder {
    /// A scene with time step `dt` (seconds) and `steps` steps, no gravity, no objects.
    pub fn new(dt: f64, steps: usize) -> Self {
        Self {
            scene: Scene {
                simulation: Simulation {
                    dt,
                    steps,
                    gravity: None,
                },
                solver: SolverSettings::default(),
                output: OutputSettings::default(),
                cache: CacheSettings::default(),
                objects: Vec::new(),
                colliders: Vec::new(),
                materials: Default::default(),
                contact: None,
            },
        }
    }
    /// Gravity, m/s^2.
    pub fn gravity(mut self, g: [f64; 3]) -> Self {
        self.scene.simulation.gravity = Some(g);
        self
    }
    /// Per-step solver settings.
    pub fn solver(mut self, s: SolverSettings) -> Self {
        self.scene.solver = s;
        self
    }
    /// Hessian strategy.
    pub fn hessian(mut self, h: HessianStrategy) -> Self {
        self.scene.solver.hessian = h;
        self
    }
    /// Newton tolerance.
    pub fn tol(mut self, tol: f64) -> Self {
        self.scene.solver.tol = tol;
        self
    }
    /// Cubature points per object.
    pub fn cubature(mut self, n: usize) -> Self {
        self.scene.solver.cubature = n;
        self
    }
    /// Output settings.
    pub fn output(mut self, o: OutputSettings) -> Self {
        self.scene.output = o;
        self
    }
    /// Basis cache settings.
    pub fn cache(mut self, c: CacheSettings) -> Self {
        self.scene.cache = c;
        self
    }
    /// Add an object.
    pub fn object(mut self, o: ObjectSpec) -> Self {
        self.scene.objects.push(o);
        self
    }
    /// Add a static obstacle.
    pub fn collider(mut self, c: Collider) -> Self {
        self.scene.colliders.push(c);
        self
    }
    /// Object-object contact with these settings.
    pub fn contact(mut self, c: crate::sim::contact::ContactSettings) -> Self {
        self.scene.contact = Some(c);
        self
    }
    /// Validate and return the scene.
    pub fn build(self) -> Result<Scene> {
        self.scene.validate()?;
        Ok(self.scene)
    }
}

impl ObjectSpec {
    /// An object named `name` with shape `shape` (see [`ObjectSpec::shape`]) and defaults
    /// for everything else.
    ///
    /// # Errors
    /// A malformed shape ([`ObjectShape::parse`]).
    pub fn new(name: &str, shape: &str) -> Result<Self> {
        Ok(Self::with_shape(name, ObjectShape::parse(shape)?))
    }

    /// An object named `name` with an already parsed shape (or an object from arrays,
    /// [`ObjectShape::arrays`]) and defaults for everything else.
    pub fn with_shape(name: &str, shape: ObjectShape) -> Self {
        Self {
            name: name.to_string(),
            shape,
            allow_open_mesh: false,
            material: Material::default(),
            overrides: Vec::new(),
            image: None,
            basis: BasisSettings::default(),
            boundaries: Vec::new(),
            placement: Placement::default(),
            cubature: None,
            render: Vec::new(),
            contact_samples: None,
            self_contact: None,
        }
    }

    /// Contact samples on the surface (with object-object contact).
    pub fn contact_samples(mut self, n: usize) -> Self {
        self.contact_samples = Some(n);
        self
    }

    /// Add a render input (a mesh, point cloud or splat file drawn with the object's map).
    pub fn render(mut self, file: &str) -> Self {
        self.render.push(file.to_string());
        self
    }
    /// Number of kernels K.
    pub fn kernels(mut self, k: usize) -> Self {
        self.basis.kernels = k;
        self
    }
    /// Number of modes m.
    pub fn modes(mut self, m: usize) -> Self {
        self.basis.modes = m;
        self
    }
    /// Integration points.
    pub fn points(mut self, n: usize) -> Self {
        self.basis.points = Some(n);
        self
    }
    /// All basis settings at once.
    pub fn basis(mut self, b: BasisSettings) -> Self {
        self.basis = b;
        self
    }
    /// Base material.
    pub fn material(mut self, m: Material) -> Self {
        self.material = m;
        self
    }
    /// A different material inside `region`.
    pub fn region_material(mut self, region: Region, material: Material) -> Self {
        self.overrides.push(MaterialOverride { region, material });
        self
    }
    /// Hold the points in `region` in place.
    pub fn hold(self, region: Region) -> Self {
        self.boundary(region, Motion::Fixed)
    }
    /// Drive the points in `region` with a prescribed motion.
    pub fn boundary(mut self, region: Region, motion: Motion) -> Self {
        self.boundaries.push(Boundary {
            region,
            motion,
            stiffness: None,
        });
        self
    }
    /// Initial placement and velocity.
    pub fn placement(mut self, p: Placement) -> Self {
        self.placement = p;
        self
    }
}
