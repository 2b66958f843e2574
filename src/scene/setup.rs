//! Setting up one object of a scene: its shape (relative paths resolved against the scene's
//! directory) and its basis, integration points and materials, from the basis cache when it
//! holds them, otherwise computed (and stored).

use super::cache;
use super::settings::RunSettings;
use super::spec::{ObjectSpec, Scene};
use crate::geometry::Shape;
use crate::geometry::VoxelValues;
use crate::io::basis::BasisMetadata;
use crate::io::image::{read_image, ImageReadOptions};
use crate::material::MaterialField;
use crate::precompute::sampling::IntegrationPoints;
use crate::precompute::skinning::Basis;
use crate::precompute::{build_basis, sample_with_material, BasisOptions};
use crate::precompute::{GapPolicy, ImageMaterial};
use crate::progress::Progress;
use crate::report::{Monitors, Warning};
use crate::Point3;
use crate::Result;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// The object's image materials: its `[object.image]` table's image (path relative to
/// `base`) with the label map resolved, or, without a table, a modulus image shape's own
/// moduli; `None` for other objects.
pub(super) fn object_image(
    spec: &ObjectSpec,
    scene: &Scene,
    shape: Option<&Shape>,
    base: &Path,
) -> Result<Option<ImageMaterial>> {
    let Some(im) = &spec.image else {
        return Ok(match shape {
            Some(Shape::Image(img)) if matches!(img.values(), VoxelValues::Moduli(_)) => Some(
                ImageMaterial::new(img.clone(), Default::default(), GapPolicy::Error)?,
            ),
            _ => None,
        });
    };
    // Relative to `base` (an absolute path stays as it is).
    let path = base.join(im.file.trim());
    let opts = ImageReadOptions {
        spacing: im.spacing,
        origin: im.origin,
        values: im.values,
    };
    let image = Arc::new(read_image(&path, &opts)?);
    let labels = im.label_materials(&scene.materials)?;
    Ok(Some(ImageMaterial::new(image, labels, im.gaps)?))
}

/// Materials at points other than the integration points (render points, N x 3 metres):
/// as the basis's, except that points outside the image's filled voxels take the object's
/// material instead of failing (render inputs may reach past the image).
pub(super) fn material_at(
    points: &[Point3],
    spec: &ObjectSpec,
    image: Option<&ImageMaterial>,
) -> Result<MaterialField> {
    let mut field = match image {
        Some(im) => im
            .with_gaps(GapPolicy::Material)
            .field(points, &spec.material)?,
        None => MaterialField::homogeneous(points.len(), &spec.material)?,
    };
    field.apply_overrides(points, &spec.overrides)?;
    Ok(field)
}

/// An object's shape with the specification it was read from.
pub(super) struct ResolvedShape {
    pub shape: Shape,
    /// The specification with relative paths resolved: the file's full path, or the text as
    /// written (the basis cache key is made from it).
    pub spec: String,
    /// The file, for file shapes.
    pub file: Option<PathBuf>,
}

/// What [`object_basis`] returns.
pub(super) struct ObjectBasis {
    pub basis: Basis,
    pub points: IntegrationPoints,
    pub material: MaterialField,
    /// Whether the basis came from the cache.
    pub cached: bool,
    /// The cache file, when caching is on.
    pub file: Option<PathBuf>,
    /// Precomputation monitors (from the cache file's metadata for a cached basis).
    pub monitors: Monitors,
}

/// Basis, integration points and materials of an object (from the cache when possible).
pub(super) fn object_basis(
    spec: &ObjectSpec,
    shape: &ResolvedShape,
    scene: &Scene,
    settings: &RunSettings,
    image: Option<&ImageMaterial>,
    progress: &dyn Progress,
    warnings: &mut Vec<Warning>,
) -> Result<ObjectBasis> {
    let opts = BasisOptions {
        image: image.cloned(),
        ..spec.basis_options()?
    };
    let cache_dir = scene.cache.enabled.then(|| {
        if scene.cache.dir.is_relative() {
            settings.base_dir.join(&scene.cache.dir)
        } else {
            scene.cache.dir.clone()
        }
    });
    let key = match &cache_dir {
        Some(_) => Some(cache::key(
            // Paths enter the key by content, not by name.
            if shape.file.is_some() {
                "file"
            } else {
                &shape.spec
            },
            shape.file.as_deref(),
            &opts,
        )?),
        None => None,
    };
    if let (Some(dir), Some(key)) = (&cache_dir, &key) {
        let mut warn = |message: String| {
            warnings.push(Warning::Cache {
                object: spec.name.clone(),
                message,
            })
        };
        if let Some(loaded) = cache::load_basis(dir, key, opts.modes, &mut warn) {
            let (points, material) = sample_with_material(&shape.shape, &opts)?;
            // The warnings of the run that produced the cached basis still apply.
            let stored = loaded.metadata.warnings();
            warnings.extend(stored.into_iter().map(|message| Warning::Monitor {
                object: Some(spec.name.clone()),
                message,
            }));
            return Ok(ObjectBasis {
                basis: loaded.basis,
                points,
                material,
                cached: true,
                file: Some(cache::path(dir, key)),
                monitors: loaded.metadata.monitors(),
            });
        }
    }
    let run = build_basis(&shape.shape, &opts, progress)?;
    warnings.extend(run.report.warnings.iter().map(|w| Warning::Monitor {
        object: Some(spec.name.clone()),
        message: w.clone(),
    }));
    let mut file_out = None;
    if let (Some(dir), Some(key)) = (&cache_dir, &key) {
        let meta = BasisMetadata::for_cache(&shape.spec, &opts, &run.report);
        file_out = Some(cache::store_basis(dir, key, &run.basis, &meta)?);
    }
    Ok(ObjectBasis {
        basis: run.basis,
        points: run.points,
        material: run.material,
        cached: false,
        file: file_out,
        monitors: run.report.monitors,
    })
}
