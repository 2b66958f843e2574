//! Every knob of the precomputation ([`BasisOptions`]) with its default and its valid range.

use super::density::{DensityBands, KernelDensity};
use super::image_material::{GapPolicy, ImageMaterial};
use super::resolution::{CloudVolumeOptions, Resolution};
use super::rkpm::{KernelType, ShapeFunctionOptions, SupportOptions};
use super::solver::SolverConfig;
use crate::geometry::{Shape, VoxelValues};
use crate::material::{Material, MaterialField, MaterialOverride, Region};
use crate::{Error, Point3, Result};
use serde::Serialize;

/// Every knob of the precomputation, with documented defaults (see docs/guide.md).
/// Deserializing (basis metadata) needs every field: missing ones are not invented.
#[derive(Debug, Clone, PartialEq, Serialize, serde::Deserialize)]
#[must_use]
pub struct BasisOptions {
    /// Number of kernels K. Default 1000 (the paper's choice for the beam).
    pub kernels: usize,
    /// Number of non-constant modes m (m + 1 handles are computed). Default 16.
    pub modes: usize,
    /// Integration grid density; None means [`default_points`] of K points.
    pub resolution: Option<Resolution>,
    /// Window function. Default cubic B-spline.
    pub kernel: KernelType,
    /// Support radius rule.
    pub support: SupportOptions,
    /// Moment-matrix conditioning threshold.
    pub shape_functions: ShapeFunctionOptions,
    /// Base material. Default: the standard beam's (E = 5e6 Pa, nu = 0.45, rho = 1000).
    pub material: Material,
    /// Region overrides applied in order on top of `material` (and of `image`).
    pub overrides: Vec<MaterialOverride>,
    /// Materials from a voxel image (nearest voxel per point), applied before `overrides`.
    /// Default none. Serialized as the image's SHA-256 and label map, and left out when
    /// absent (cache keys of other objects are unchanged); not read back from metadata.
    #[serde(default, skip_deserializing, skip_serializing_if = "Option::is_none")]
    pub image: Option<ImageMaterial>,
    /// Eigensolver and its settings. Default native LOBPCG at its default settings.
    pub solver: SolverConfig,
    /// Relative eigen-residual tolerance. Default 1e-8.
    pub tol: f64,
    /// Eigensolver iteration cap. Default 1000.
    pub max_iter: usize,
    /// Point-cloud quadrature options (voxel size, total volume).
    pub cloud: CloudVolumeOptions,
    /// Rounds of local support enlargement (x1.25 on the 4 kernels nearest each badly covered
    /// point) before giving up with a coverage error. Default 3.
    pub coverage_repair_rounds: usize,
    /// Boundary regions the basis follows exactly, rest coordinates (a boundary-aware basis,
    /// [`super::boundary_modes`]): B regions give B lifts and m + 1 - B free modes, so at most
    /// m regions. Empty (the default): the free basis, the constant and m eigenmodes. Left out
    /// of the serialized options when empty, so cache keys of free bases are unchanged.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub boundary_regions: Vec<Region>,
    /// Where the kernels go ([`KernelDensity`]): finer near boundary regions and material
    /// interfaces, or per user region. Left out of the serialized options when off, so cache
    /// keys of uniformly placed bases are unchanged.
    #[serde(
        default = "KernelDensity::off",
        skip_serializing_if = "KernelDensity::is_off"
    )]
    pub density: KernelDensity,
    /// How H_w and M are stored ([`MatrixStorage`]). Default `Auto`: the upper triangle for the
    /// native LOBPCG solver without boundary regions, both triangles otherwise. Left out of
    /// the serialized options when `Auto`, so cache keys are unchanged.
    #[serde(default, skip_serializing_if = "MatrixStorage::is_auto")]
    pub matrix_storage: MatrixStorage,
}

/// How the assembled H_w and M are stored.
///
/// Both triangles take 20 bytes a stored entry (two f64 values and a shared u32 index); the
/// upper triangle alone (`crate::triangle`) half that. The native LOBPCG solves the triangle
/// with the same bits as both triangles: its products are 1.1-1.3x slower, which the assembly
/// (no mirror) and the preconditioner's solves win back (docs/performance.md, "The upper
/// triangle as storage"). Other solvers and the boundary-aware restriction read both
/// triangles (mirrored on demand from the upper triangle, the memory of both on top).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum MatrixStorage {
    /// The upper triangle for the native LOBPCG solver without boundary regions, both
    /// triangles otherwise.
    #[default]
    Auto,
    /// Both triangles.
    Full,
    /// The upper triangle only (native LOBPCG solver and no boundary regions).
    Upper,
}

impl MatrixStorage {
    /// Every storage, in the command line's order of choices.
    pub const ALL: [MatrixStorage; 3] = [
        MatrixStorage::Auto,
        MatrixStorage::Full,
        MatrixStorage::Upper,
    ];

    /// The default (`Auto`), for `skip_serializing_if`.
    pub fn is_auto(&self) -> bool {
        *self == MatrixStorage::Auto
    }

    /// Lower-case name as used on the command line and in files.
    pub fn name(self) -> &'static str {
        crate::names::variant_name(&self)
    }

    /// Parse a lower-case name.
    pub fn from_name(name: &str) -> Option<Self> {
        crate::names::from_name(name)
    }
}

impl Default for BasisOptions {
    fn default() -> Self {
        Self {
            kernels: 1000,
            modes: 16,
            resolution: None,
            kernel: KernelType::Cubic,
            support: SupportOptions::default(),
            shape_functions: ShapeFunctionOptions::default(),
            material: Material::default(),
            overrides: Vec::new(),
            image: None,
            solver: SolverConfig::default(),
            tol: 1e-8,
            max_iter: 1000,
            cloud: CloudVolumeOptions::default(),
            coverage_repair_rounds: 3,
            boundary_regions: Vec::new(),
            density: KernelDensity::bands(DensityBands::default()),
            matrix_storage: MatrixStorage::Auto,
        }
    }
}

/// Default integration point count for K kernels: 50 K, at least 20,000; above 40,000
/// kernels 2,000,000 until 10 per kernel is more (K > 200,000), then 10 K (at most
/// [`MAX_POINTS`]). 50 points per kernel resolves each support (~30 kernels overlap a point,
/// ~1,500 points lie in a support) so quadrature error stays below the kernel approximation
/// error; at large K the streamed assembly holds only O(N) per point, and 10 per kernel
/// (~350 points in a support) keeps the point count, and the time of the shape-function
/// stage, proportional to K (docs/performance.md: K = 1,000,000 with 10M points).
pub fn default_points(kernels: usize) -> usize {
    kernels
        .saturating_mul(50)
        .clamp(20_000, 2_000_000)
        .max(kernels.saturating_mul(10))
        .min(MAX_POINTS)
}

/// Most kernels [`BasisOptions::validate`] accepts: 10 million, a typo guard (or a unit
/// mistake): H_w and M alone would need ~90 GB there (about 9 KB per kernel,
/// [`super::memory`]). Whether a run fits is decided by the memory estimate.
pub const MAX_KERNELS: usize = 10_000_000;

/// Most integration points [`BasisOptions::validate`] accepts: 100 million, a typo guard.
/// The shape functions are streamed, so points cost ~200 bytes each (20 GB here); whether a
/// run fits is decided by the memory estimate ([`super::memory`]).
pub const MAX_POINTS: usize = 100_000_000;

impl BasisOptions {
    /// The material at each of `points` (N x 3, metres) of `shape`: `material`, replaced by
    /// `image`'s where given (or, with no `image`, by a modulus image shape's own moduli), then
    /// `overrides` in order.
    ///
    /// # Errors
    /// Invalid materials; the [`ImageMaterial::field`] errors (material gaps).
    pub fn material_field(&self, shape: &Shape, points: &[Point3]) -> Result<MaterialField> {
        let mut field = match (&self.image, shape) {
            (Some(image), _) => image.field(points, &self.material)?,
            (None, Shape::Image(img)) if matches!(img.values(), VoxelValues::Moduli(_)) => {
                ImageMaterial::new(img.clone(), Default::default(), GapPolicy::Error)?
                    .field(points, &self.material)?
            }
            _ => MaterialField::homogeneous(points.len(), &self.material)?,
        };
        field.apply_overrides(points, &self.overrides)?;
        Ok(field)
    }

    /// Whether H_w and M are stored as upper triangles: `matrix_storage = "upper"`, or
    /// `"auto"` with the native LOBPCG solver and no boundary regions (the solver takes the
    /// triangle as is, with the same bits; every other consumer reads both triangles).
    pub fn upper_triangle_storage(&self) -> bool {
        match self.matrix_storage {
            MatrixStorage::Upper => true,
            MatrixStorage::Full => false,
            MatrixStorage::Auto => {
                matches!(self.solver, SolverConfig::Lobpcg(_)) && self.boundary_regions.is_empty()
            }
        }
    }

    /// Check every parameter's range (before any work is done).
    pub fn validate(&self) -> Result<()> {
        if self.matrix_storage == MatrixStorage::Upper {
            if !matches!(self.solver, SolverConfig::Lobpcg(_)) {
                return Err(Error::param(
                    "matrix_storage",
                    "upper",
                    format!(
                        "only the native LOBPCG solver works on the upper triangle alone (solver \
                         is {}): use matrix_storage = \"full\" or solver = \"lobpcg\"",
                        self.solver.name()
                    ),
                ));
            }
            if !self.boundary_regions.is_empty() {
                return Err(Error::param(
                    "matrix_storage",
                    "upper",
                    "a boundary-aware basis restricts both triangles of H_w and M: use \
                     matrix_storage = \"full\" (or \"auto\")",
                ));
            }
        }
        if self.kernels < 10 {
            return Err(Error::param(
                "kernels",
                self.kernels,
                "need at least 10 kernels",
            ));
        }
        if self.modes == 0 {
            return Err(Error::param(
                "modes",
                0,
                "ask for at least one non-constant mode",
            ));
        }
        if self.kernels > MAX_KERNELS {
            return Err(Error::param(
                "kernels",
                self.kernels,
                format!(
                    "more than {MAX_KERNELS} kernels would need far more memory than any \
                     machine has; use at most a few 100,000 (default 1000)"
                ),
            ));
        }
        if self.modes.saturating_add(1) >= self.kernels {
            return Err(Error::param(
                "modes",
                self.modes,
                format!(
                    "m must be smaller than K - 1 = {} (K = {} kernels)",
                    self.kernels - 1,
                    self.kernels
                ),
            ));
        }
        if !(self.tol.is_finite() && self.tol > 0.0 && self.tol < 1.0) {
            return Err(Error::param(
                "tol",
                self.tol,
                "tolerance must lie in (0, 1), e.g. 1e-8",
            ));
        }
        if self.max_iter == 0 {
            return Err(Error::param("max_iter", 0, "need at least one iteration"));
        }
        if let Some(Resolution::Spacing(h)) = self.resolution {
            if !(h.is_finite() && h > 0.0) {
                return Err(Error::param(
                    "spacing",
                    h,
                    "the grid spacing must be a positive length, metres",
                ));
            }
        }
        if let Some(Resolution::Count(n)) = self.resolution {
            if n < self.kernels {
                return Err(Error::param(
                    "points",
                    n,
                    format!("fewer integration points than kernels ({})", self.kernels),
                ));
            }
            if n > MAX_POINTS {
                return Err(Error::param(
                    "points",
                    n,
                    format!(
                        "more than {MAX_POINTS} integration points would need far more memory \
                         than any machine has; 50 per kernel is plenty (the default)"
                    ),
                ));
            }
        }
        self.support.validate()?;
        if let SolverConfig::Lobpcg(options) = &self.solver {
            options.validate()?;
        }
        for (name, v) in [
            ("voxel", self.cloud.voxel),
            ("volume", self.cloud.total_volume),
        ] {
            if let Some(v) = v.filter(|v| !(*v > 0.0 && crate::error::in_range(*v))) {
                return Err(Error::param(
                    name,
                    v,
                    "a point cloud's voxel edge (metres) and total volume (m^3) must be \
                     positive, between 1e-100 and 1e100",
                ));
            }
        }
        if !(self.shape_functions.min_rcond > 0.0 && self.shape_functions.min_rcond < 1.0) {
            return Err(Error::param(
                "min_rcond",
                self.shape_functions.min_rcond,
                "must lie in (0, 1)",
            ));
        }
        self.material.validate()?;
        for o in &self.overrides {
            o.region.validate()?;
            o.material.validate()?;
        }
        for r in &self.boundary_regions {
            r.validate()?;
        }
        self.density.validate()?;
        if self.boundary_regions.len() > self.modes {
            return Err(Error::param(
                "modes",
                self.modes,
                format!(
                    "a boundary-aware basis with {} regions has {} lifts and needs m >= {} to \
                     keep at least one free mode; raise {} or use {}",
                    self.boundary_regions.len(),
                    self.boundary_regions.len(),
                    self.boundary_regions.len(),
                    crate::options::MODES,
                    crate::options::BOUNDARIES.with("free")
                ),
            ));
        }
        Ok(())
    }
}
