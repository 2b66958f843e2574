//! The scene description: what `freeform run` reads from TOML and what the builder API
//! ([`super::SceneBuilder`]) produces. Unknown keys are errors; every default is stated
//! here and in docs/scenes.md.

use super::shape::{ObjectShape, ShapeSource};
use crate::io::image::ImageValueKind;
use crate::material::{Material, MaterialOverride};
use crate::precompute::rkpm::{KernelType, SupportOptions};
use crate::precompute::sampling::CloudVolumeOptions;
use crate::precompute::table::{self, OptionTable, Value};
use crate::precompute::GapPolicy;
use crate::precompute::{BasisOptions, BoundaryModes, DensityBands, KernelDensity, SolverConfig};
use crate::sim::contact::ContactSettings;
use crate::sim::newton::{HessianStrategy, InitialGuess, Precision};
use crate::sim::{Boundary, Collider, NewtonOptions, Placement};
use crate::{Error, Result};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::PathBuf;

/// A whole scene.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Scene {
    /// Time stepping and gravity.
    pub simulation: Simulation,
    /// Per-step solver settings (defaults: see [`SolverSettings`]).
    #[serde(default)]
    pub solver: SolverSettings,
    /// What to write.
    #[serde(default)]
    pub output: OutputSettings,
    /// The basis cache.
    #[serde(default)]
    pub cache: CacheSettings,
    /// The objects (`[[object]]` tables); they do not interact with each other.
    #[serde(default, rename = "object")]
    pub objects: Vec<ObjectSpec>,
    /// Obstacles shared by all objects, static or kinematic (`[[collider]]` tables).
    #[serde(default, rename = "collider", skip_serializing_if = "Vec::is_empty")]
    pub colliders: Vec<Collider>,
    /// Named materials (`[materials.NAME]` tables) that voxel-image labels refer to
    /// (`image.labels`).
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub materials: BTreeMap<String, Material>,
    /// Object-object contact (`[contact]`); absent: objects pass through each other and no
    /// contact code runs.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub contact: Option<ContactSettings>,
}

/// Time stepping.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Simulation {
    /// Time step h, seconds.
    pub dt: f64,
    /// Number of steps.
    pub steps: usize,
    /// Gravity, m/s^2; absent means no gravity term at all.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub gravity: Option<[f64; 3]>,
}

/// Per-step solver settings.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SolverSettings {
    /// Hessian strategy: "lbfgs" (default), "newton" or "fixed".
    pub hessian: HessianStrategy,
    /// Convergence tolerance (RMS Newton step / object diagonal), default 1e-6.
    pub tol: f64,
    /// Iteration cap per step, default 100.
    pub max_iter: usize,
    /// L-BFGS history length, default 8.
    pub lbfgs_history: usize,
    /// L-BFGS Hessian refresh period in iterations (0: never), default 10.
    pub refresh_iterations: usize,
    /// L-BFGS refresh: every n-th cubature point builds the new base, default 1 (all).
    pub refresh_stride: usize,
    /// L-BFGS refresh: arithmetic of the base's dense products, `single` (default) or
    /// `double`.
    pub refresh_precision: Precision,
    /// Start of each step's minimisation, `extrapolate` (default) or `velocity`.
    pub initial_guess: InitialGuess,
    /// Cubature points for the elastic energy, default 5000 (all points if fewer).
    pub cubature: usize,
}

impl Default for SolverSettings {
    fn default() -> Self {
        let n = NewtonOptions::default();
        Self {
            hessian: n.hessian,
            tol: n.tol,
            max_iter: n.max_iter,
            lbfgs_history: n.lbfgs_history,
            refresh_iterations: n.refresh_iterations,
            refresh_stride: n.refresh_stride,
            refresh_precision: n.refresh_precision,
            initial_guess: n.initial_guess,
            cubature: crate::sim::cubature::DEFAULT_CUBATURE,
        }
    }
}

impl SolverSettings {
    /// The Newton options these settings describe.
    pub fn newton(&self) -> NewtonOptions {
        NewtonOptions {
            hessian: self.hessian,
            tol: self.tol,
            max_iter: self.max_iter,
            lbfgs_history: self.lbfgs_history,
            refresh_iterations: self.refresh_iterations,
            refresh_stride: self.refresh_stride,
            refresh_precision: self.refresh_precision,
            initial_guess: self.initial_guess,
        }
    }
}

/// Output file formats.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Format {
    /// VTK XML PolyData per frame plus a `.pvd` collection (ParaView).
    Vtk,
    /// Binary PLY per frame (points, or the deformed mesh for mesh inputs, or the deformed
    /// splats in the input's 3DGS layout for splat inputs).
    Ply,
    /// One time-sampled USD stage for the run, `<out>/run.usda` (meshes, points, Gaussian
    /// splats, colliders, stress; Kaolin's physics schemas; docs/usd.md).
    Usd,
}

/// What is written per frame.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct OutputSettings {
    /// Write a frame every this many steps (frame 0, the initial state, is always written).
    /// Default 1.
    pub every: usize,
    /// Formats, default ["vtk", "ply"].
    pub formats: Vec<Format>,
    /// For objects whose shape is a 3DGS splat PLY: rotate each splat's SH colour (degrees
    /// 1-3) by the rotation of its deformation gradient in the `.ply` frames. Default true
    /// (view-dependent colour turns with the material); false copies the coefficients.
    pub rotate_splat_sh: bool,
    /// Write the Cauchy stress at the render points into the VTK frames (and the USD stage's
    /// `primvars:`): `stress` (3 x 3, Pa), `principal_stress` (sigma_1 >= sigma_2 >=
    /// sigma_3, Pa) and `von_mises` (Pa).
    /// Default false (it costs a deformation gradient and an eigendecomposition per point).
    pub stress: bool,
    /// With `"usd"` among the formats: write Kaolin's physics schemas
    /// (`KaolinPhysicsMaterialAPI`, `KaolinSkinnedPhysicsAPI`: materials and skinning weights)
    /// on each object's prim, so that Kaolin can load the basis. Default true.
    pub usd_physics: bool,
}

impl Default for OutputSettings {
    fn default() -> Self {
        Self {
            every: 1,
            formats: vec![Format::Vtk, Format::Ply],
            rotate_splat_sh: true,
            stress: false,
            usd_physics: true,
        }
    }
}

/// The basis cache: a basis computed once is stored under a key made of everything that
/// produced it and reused by later runs.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct CacheSettings {
    /// Use the cache (default true).
    pub enabled: bool,
    /// Directory; relative paths are relative to the scene file. Default `.freeform-cache`.
    pub dir: PathBuf,
}

impl Default for CacheSettings {
    fn default() -> Self {
        Self {
            enabled: true,
            dir: PathBuf::from(".freeform-cache"),
        }
    }
}

/// One object: its shape, material, basis settings, boundary conditions and placement.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ObjectSpec {
    /// Name, used for output file names (letters, digits, '-', '_').
    pub name: String,
    /// Shape: `box:LX,LY,LZ`, `sphere:R`, a mesh / point-cloud / NIfTI image file (relative to
    /// the scene file), or `image`: the filled voxels of the `[object.image]` table's image.
    /// Parsed when the scene is read; written back as it was given.
    pub shape: ObjectShape,
    /// Accept a mesh with holes.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub allow_open_mesh: bool,
    /// Base material (default: E 5e6 Pa, nu 0.45, rho 1000 kg/m^3).
    #[serde(default)]
    pub material: Material,
    /// Materials inside regions, applied in order (`[[object.region_material]]`).
    #[serde(
        default,
        rename = "region_material",
        skip_serializing_if = "Vec::is_empty"
    )]
    pub overrides: Vec<MaterialOverride>,
    /// A voxel image giving the object's materials (and its shape when `shape = "image"`);
    /// applied before the region overrides.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub image: Option<ImageSpec>,
    /// Basis settings.
    #[serde(default)]
    pub basis: BasisSettings,
    /// Boundary conditions (`[[object.boundary]]`).
    #[serde(default, rename = "boundary", skip_serializing_if = "Vec::is_empty")]
    pub boundaries: Vec<Boundary>,
    /// Initial placement and velocity.
    #[serde(default)]
    pub placement: Placement,
    /// Cubature points for this object (default: the solver setting).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub cubature: Option<usize>,
    /// Render inputs drawn with the object's deformation map and written next to its own
    /// frames: meshes (OBJ, STL, OFF, PLY; every vertex kept, need not be closed), point clouds or
    /// 3DGS splat PLYs, in the object's rest frame (relative to the scene file).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub render: Vec<String>,
    /// Contact samples on this object's surface (with `[contact]`; default from its size or
    /// `contact.samples`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub contact_samples: Option<usize>,
    /// Self-contact of this object (with `[contact]`; default `contact.self_contact`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub self_contact: Option<bool>,
}

/// An object's voxel image (`[object.image]`): a NIfTI (`.nii`, `.nii.gz`) or NumPy (`.npy`)
/// image of material labels or Young's moduli; see docs/scenes.md.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ImageSpec {
    /// The image file, relative to the scene file.
    pub file: String,
    /// Voxel edge per axis, metres; replaces the file's (required for `.npy`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub spacing: Option<[f64; 3]>,
    /// Centre of voxel [0, 0, 0], metres; replaces the file's (`.npy` default: 0).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub origin: Option<[f64; 3]>,
    /// What the voxels hold: `auto` (default: integer data are labels, floating-point data
    /// moduli), `labels` or `moduli`.
    #[serde(default)]
    pub values: ImageValueKind,
    /// Label value (a whole number, as a TOML key) to material name (a `[materials.NAME]`
    /// table). Every label of a filled voxel needs one; label 0 may be mapped to fill empty
    /// voxels inside a mesh shape.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub labels: BTreeMap<String, String>,
    /// Points inside the shape that fall outside the image or in empty voxels: `error`
    /// (default) or `material` (the object's own material).
    #[serde(default)]
    pub gaps: GapPolicy,
}

impl ImageSpec {
    /// The label map with its names resolved in `materials`.
    ///
    /// # Errors
    /// [`Error::Scene`] for a key that is not a whole number or a name with no
    /// `[materials.NAME]` table.
    pub fn label_materials(
        &self,
        materials: &BTreeMap<String, Material>,
    ) -> Result<BTreeMap<i64, Material>> {
        let mut out = BTreeMap::new();
        for (key, name) in &self.labels {
            let label: i64 = key.trim().parse().map_err(|_| {
                scene_err(format!(
                    "image.labels key '{key}' is not a whole-number label (write labels = {{ 1 = \"bone\" }})"
                ))
            })?;
            let m = materials.get(name).ok_or_else(|| {
                let known: Vec<&str> = materials.keys().map(String::as_str).collect();
                scene_err(format!(
                    "image label {label} maps to material '{name}', but there is no \
                     [materials.{name}] table (named materials: {known:?})"
                ))
            })?;
            out.insert(label, *m);
        }
        Ok(out)
    }
}

/// Basis precomputation settings of an object (see `freeform modes --help`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct BasisSettings {
    /// RKPM kernels K, default 1000.
    pub kernels: usize,
    /// Modes m (m + 1 handles), default 16.
    pub modes: usize,
    /// Integration points (default 50 K clamped to 20,000..2,000,000).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub points: Option<usize>,
    /// Integration grid spacing, metres (instead of `points`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub spacing: Option<f64>,
    /// Kernel window, default "cubic".
    pub kernel: KernelType,
    /// Support factor, default 2.0.
    pub support: f64,
    /// Support neighbour, default 4.
    pub support_neighbor: usize,
    /// Eigensolver, default "lobpcg"; also "dense", "slepc" or "slepc:CONFIG", or a table
    /// with LOBPCG settings (the string forms of [`SolverConfig`]).
    pub eigensolver: SolverConfig,
    /// Eigensolver tolerance, default 1e-8.
    pub eigen_tol: f64,
    /// Point clouds: total volume, m^3.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub volume: Option<f64>,
    /// Point clouds: voxel edge, metres.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub voxel: Option<f64>,
    /// How the basis treats the object's boundary regions: "aware" (default: one lift per
    /// region and free modes that vanish on the regions) or "free" (global modes, regions held
    /// by the penalty alone). Objects without boundaries get the same basis either way.
    pub boundaries: BoundaryModes,
    /// Kernel spacing factor near the boundaries' regions (docs/accuracy.md, "Kernel
    /// density"); 1 is uniform placement.
    pub density_boundaries: f64,
    /// Kernel spacing factor near material interfaces; 1 is uniform placement.
    pub density_interfaces: f64,
    /// Half-width of the refined bands, in kernel spacings (V / K)^(1/3).
    pub density_band: f64,
    /// Largest kernel spacing factor on thin parts; 1 is uniform placement.
    pub density_thin: f64,
}

impl Default for BasisSettings {
    fn default() -> Self {
        let b = BasisOptions::default();
        Self {
            kernels: b.kernels,
            modes: b.modes,
            points: None,
            spacing: None,
            kernel: b.kernel,
            support: b.support.factor,
            support_neighbor: b.support.neighbor,
            eigensolver: b.solver,
            eigen_tol: b.tol,
            volume: None,
            voxel: None,
            boundaries: BoundaryModes::default(),
            density_boundaries: b.density.bands.boundaries,
            density_interfaces: b.density.bands.interfaces,
            density_band: b.density.bands.band,
            density_thin: b.density.bands.thin,
        }
    }
}

/// The boundaries' regions, each once (two boundaries on one region pin it once).
fn distinct_regions(boundaries: &[Boundary]) -> Vec<crate::material::Region> {
    let mut out: Vec<crate::material::Region> = Vec::new();
    for b in boundaries {
        if !out.contains(&b.region) {
            out.push(b.region);
        }
    }
    out
}

impl ObjectSpec {
    /// The basis options of this object.
    pub fn basis_options(&self) -> Result<BasisOptions> {
        let b = &self.basis;
        // The integration grid through the option table's rows (one conflict check, one
        // mapping to a Resolution for every front end).
        let grid = [
            b.points.map(|n| (&table::POINTS, Value::Count(n))),
            b.spacing.map(|h| (&table::SPACING, Value::Number(h))),
        ];
        let resolution = OptionTable::basis()
            .apply(grid.into_iter().flatten().collect())?
            .options
            .resolution;
        let opts = BasisOptions {
            kernels: b.kernels,
            modes: b.modes,
            resolution,
            kernel: b.kernel,
            support: SupportOptions {
                factor: b.support,
                neighbor: b.support_neighbor,
            },
            material: self.material,
            overrides: self.overrides.clone(),
            solver: b.eigensolver.clone(),
            tol: b.eigen_tol,
            cloud: CloudVolumeOptions {
                voxel: b.voxel,
                total_volume: b.volume,
            },
            boundary_regions: match b.boundaries {
                BoundaryModes::Free => Vec::new(),
                BoundaryModes::Aware => distinct_regions(&self.boundaries),
            },
            density: KernelDensity::bands(DensityBands {
                boundaries: b.density_boundaries,
                interfaces: b.density_interfaces,
                band: b.density_band,
                thin: b.density_thin,
            }),
            ..BasisOptions::default()
        };
        opts.validate()?;
        Ok(opts)
    }
}

impl Scene {
    /// Parse a scene from TOML text. Syntax errors, unknown keys and wrong types are
    /// reported with their line and column.
    pub fn from_toml(text: &str) -> Result<Scene> {
        let scene: Scene = toml::from_str(text).map_err(|e| Error::Scene {
            message: e.to_string(),
        })?;
        scene.validate()?;
        Ok(scene)
    }

    /// The scene as TOML text (round-trips through [`Scene::from_toml`]).
    pub fn to_toml(&self) -> Result<String> {
        toml::to_string(self).map_err(|e| Error::Scene {
            message: format!("cannot write the scene as TOML: {e}"),
        })
    }

    /// Check every value that parsing cannot (ranges, names, consistency), and that the scene
    /// has at least one object.
    pub fn validate(&self) -> Result<()> {
        if self.objects.is_empty() {
            return Err(scene_err(
                "the scene has no [[object]]: add at least one object".into(),
            ));
        }
        self.validate_settings()
    }

    /// [`Scene::validate`] without requiring an object: for a scene whose objects are added
    /// in code ([`super::World::with_objects`]).
    pub fn validate_settings(&self) -> Result<()> {
        // A scene built in code may hold integers TOML cannot (a u64 seed past i64::MAX);
        // its floats then get the field checks below only.
        if let Ok(serialized) = toml::Value::try_from(self) {
            super::numbers::check(&serialized)?;
        }
        let s = &self.simulation;
        if !(s.dt > 0.0 && s.dt.is_finite()) {
            return Err(scene_err(format!(
                "simulation.dt = {} must be a positive number of seconds (e.g. 0.01)",
                s.dt
            )));
        }
        if s.steps == 0 {
            return Err(scene_err("simulation.steps must be at least 1".to_string()));
        }
        if s.steps > MAX_STEPS {
            return Err(scene_err(format!(
                "simulation.steps = {} is more than {MAX_STEPS}: the run would take days and its \
                 per-step summary alone gigabytes; split it into shorter runs or use a larger dt",
                s.steps
            )));
        }
        if let Some(g) = s.gravity {
            if let Some(why) = crate::sim::environment::gravity_problem(g) {
                return Err(scene_err(format!("simulation.gravity = {g:?}: {why}")));
            }
        }
        self.solver.newton().validate()?;
        check_cubature("solver.cubature", self.solver.cubature)?;
        if self.output.every == 0 {
            return Err(scene_err("output.every must be at least 1".into()));
        }
        let mut names = std::collections::HashSet::new();
        for (index, o) in self.objects.iter().enumerate() {
            // An object's errors keep their type inside the object's (as at set-up).
            let in_object = |source: Error| Error::Object {
                index,
                name: o.name.clone(),
                source: Box::new(source),
            };
            let ok = !o.name.is_empty()
                && o.name
                    .chars()
                    .all(|c| c.is_ascii_alphanumeric() || c == '-' || c == '_');
            if !ok {
                return Err(scene_err(format!(
                    "object name '{}' must be non-empty and use only letters, digits, '-' and '_' \
                     (it names the output files)",
                    o.name
                )));
            }
            if !names.insert(o.name.clone()) {
                return Err(scene_err(format!("two objects are named '{}'", o.name)));
            }
            // Boundaries first: an aware basis's options carry their regions.
            for (i, b) in o.boundaries.iter().enumerate() {
                let in_boundary = |source: Error| {
                    in_object(Error::Boundary {
                        index: i,
                        source: Box::new(source),
                    })
                };
                b.validate().map_err(in_boundary)?;
            }
            let tol = o.basis.eigen_tol;
            if !(tol > 0.0 && tol < 1.0) {
                return Err(in_object(scene_err(format!(
                    "basis.eigen_tol = {} must lie in (0, 1), e.g. 1e-8",
                    crate::error::readable_number(tol)
                ))));
            }
            let _checked = o.basis_options().map_err(in_object)?;
            self.validate_image(o).map_err(in_object)?;
            if let Some(n) = o.cubature {
                check_cubature("cubature", n).map_err(in_object)?;
            }
            if let Some(count) = o.contact_samples {
                crate::sim::contact::samples::check_count("contact_samples", count)
                    .map_err(in_object)?;
            }
        }
        let object_steps = self.simulation.steps.saturating_mul(self.objects.len());
        if object_steps > MAX_OBJECT_STEPS {
            return Err(scene_err(format!(
                "simulation.steps x objects = {} x {} = {object_steps} is more than \
                 {MAX_OBJECT_STEPS}: the summary keeps a row per object and step (about 150 \
                 bytes each); split the run or use fewer steps",
                self.simulation.steps,
                self.objects.len()
            )));
        }
        for (name, m) in &self.materials {
            m.validate().map_err(|e| Error::NamedMaterial {
                name: name.clone(),
                source: Box::new(e),
            })?;
        }
        crate::sim::collider::validate_colliders(&self.colliders)?;
        if let Some(c) = &self.contact {
            c.validate()?;
        }
        for (i, c) in self.colliders.iter().enumerate() {
            let stem = collider_stem(i, c.name.as_deref());
            if let Some(o) = self.objects.iter().find(|o| o.name == stem) {
                return Err(scene_err(format!(
                    "object '{}' has the frame name of collider {i}; rename one of them",
                    o.name
                )));
            }
        }
        Ok(())
    }
}

impl Scene {
    /// An object's image table: its numbers and its label map (the file is read later).
    fn validate_image(&self, o: &ObjectSpec) -> Result<()> {
        let Some(im) = &o.image else {
            if *o.shape.source() == ShapeSource::Image {
                return Err(scene_err(
                    "shape = \"image\" needs an [object.image] table with the image file".into(),
                ));
            }
            return Ok(());
        };
        if let Some(s) = im.spacing {
            if !s.iter().all(|v| v.is_finite() && *v > 0.0) {
                return Err(scene_err(format!(
                    "image.spacing = {s:?} must be finite and > 0 on every axis (metres)"
                )));
            }
        }
        if let Some(o) = im.origin {
            if !o.iter().all(|v| v.is_finite()) {
                return Err(scene_err(format!("image.origin = {o:?} must be finite")));
            }
        }
        im.label_materials(&self.materials)?;
        Ok(())
    }
}

/// Most time steps a scene may ask for (the summary keeps one row per step).
pub const MAX_STEPS: usize = 10_000_000;

/// Most object-steps (steps x objects) a scene may ask for: the summary keeps a row of about
/// 150 bytes per object and step, so 20,000,000 rows are about 3 GB.
pub const MAX_OBJECT_STEPS: usize = 20_000_000;

/// A cubature point count `n` (field `name`): at least 1, at most
/// [`crate::sim::cubature::MAX_CUBATURE`].
fn check_cubature(name: &str, n: usize) -> Result<()> {
    use crate::sim::cubature::{DEFAULT_CUBATURE, MAX_CUBATURE};
    if n == 0 {
        return Err(scene_err(format!("{name} must be at least 1")));
    }
    if n > MAX_CUBATURE {
        return Err(scene_err(format!(
            "{name} = {n} is more than {MAX_CUBATURE}: every step evaluates every cubature \
             point, and the default {DEFAULT_CUBATURE} already resolves the modes; use fewer"
        )));
    }
    Ok(())
}

fn scene_err(message: String) -> Error {
    Error::Scene { message }
}

/// The frame name of collider `index` (`collider-<name>`, or `collider-<index>` without a
/// name): its `.pvd` collection and the stem of its frames in `<out>/colliders/`.
pub fn collider_stem(index: usize, name: Option<&str>) -> String {
    match name {
        Some(n) => format!("collider-{n}"),
        None => format!("collider-{index}"),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn with_basis(basis: &str) -> Result<Scene> {
        Scene::from_toml(&format!(
            "[simulation]\ndt = 0.01\nsteps = 1\n[[object]]\nname = \"a\"\nshape = \
             \"box:1,1,1\"\nbasis = {basis}\n"
        ))
    }

    #[test]
    fn steps_times_objects_beyond_the_limit_is_refused() {
        let object = |name: &str| format!("[[object]]\nname = \"{name}\"\nshape = \"box:1,1,1\"\n");
        let scene = |steps: usize, n: usize| {
            let objects: String = (0..n).map(|i| object(&format!("o{i}"))).collect();
            Scene::from_toml(&format!(
                "[simulation]\ndt = 0.01\nsteps = {steps}\n{objects}"
            ))
        };
        scene(MAX_STEPS, 2).unwrap();
        let err = scene(MAX_STEPS, 3).unwrap_err().to_string();
        assert!(err.contains("simulation.steps x objects"), "{err}");
    }

    #[test]
    fn gravity_beyond_the_limit_is_refused_naming_the_field() {
        let scene = |g: &str| {
            Scene::from_toml(&format!(
                "[simulation]\ndt = 0.01\nsteps = 1\ngravity = {g}\n[[object]]\nname = \"a\"\n\
                 shape = \"box:1,1,1\"\n"
            ))
        };
        scene("[0, -9.81, 0]").unwrap();
        let err = scene("[0, -1e12, 0]").unwrap_err().to_string();
        assert!(
            err.contains("simulation.gravity") && err.contains("above the limit"),
            "{err}"
        );
    }

    #[test]
    fn eigensolver_takes_every_solver_config() {
        use crate::eigen::lobpcg::{LobpcgOptions, PreconditionerKind};
        for (text, config) in [
            (r#"{ eigensolver = "lobpcg" }"#, SolverConfig::lobpcg()),
            (r#"{ eigensolver = "dense" }"#, SolverConfig::Dense),
            (
                r#"{ eigensolver = "slepc:lobpcg-gamg:-eps_max_it 50" }"#,
                SolverConfig::slepc("lobpcg-gamg", "-eps_max_it 50").unwrap(),
            ),
            (
                r#"{ eigensolver = { lobpcg = { preconditioner = "jacobi" } } }"#,
                SolverConfig::Lobpcg(LobpcgOptions {
                    preconditioner: PreconditionerKind::Jacobi,
                    ..LobpcgOptions::default()
                }),
            ),
        ] {
            let scene = with_basis(text).unwrap_or_else(|e| panic!("{text}: {e}"));
            let o = &scene.objects[0];
            assert_eq!(o.basis.eigensolver, config, "{text}");
            assert_eq!(o.basis_options().unwrap().solver, config, "{text}");
            // And back through TOML.
            let again = Scene::from_toml(&scene.to_toml().unwrap()).unwrap();
            assert_eq!(again.objects[0].basis.eigensolver, config, "{text}");
        }
        let err = with_basis(r#"{ eigensolver = "arnoldi" }"#)
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("invalid solver = \"arnoldi\"") && err.contains("use lobpcg, dense"),
            "{err}"
        );
        let err = with_basis(r#"{ eigensolver = "slepc:bogus" }"#)
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("unknown SLEPc configuration \"bogus\""),
            "{err}"
        );
    }
}
