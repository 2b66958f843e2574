//! Shape files: [`read_shape`] turns a shape spec into a [`Shape`], reading the file it names
//! with the reader of its format.

use super::{image, obj, off, ply, stl};
use crate::geometry::{GeometryError, Shape, ShapeFileFormat, ShapeOptions, ShapeSpec};

/// The shape a spec names: `box:LX,LY,LZ` or `sphere:R` (positive finite numbers, metres;
/// prefix case-insensitive), or a path to a `.obj`, `.stl` (ASCII or binary), `.off`, `.ply`
/// or NIfTI (`.nii`, `.nii.gz`) file (extension case-insensitive), read with
/// [`obj::read_obj`], [`stl::read_stl`], [`off::read_off`], [`ply::read_ply`] or
/// [`image::read_image`] (an image's filled voxels are the shape; a `.npy` image needs the
/// spacing a scene gives, so it is refused here). A PLY with a non-empty `face` element is a mesh, otherwise a point cloud
/// (Gaussian splat files included: only x, y, z are read; a scene reads a 3DGS file whole with
/// [`super::splat::read_splats`] and writes 3DGS frames).
///
/// ```
/// use freeform::geometry::ShapeOptions;
/// let beam = freeform::io::read_shape("box:2,1,1", &ShapeOptions::default())?;
/// assert_eq!(beam.volume(), Some(2.0));
/// # Ok::<(), freeform::geometry::GeometryError>(())
/// ```
///
/// # Errors
/// The [`ShapeSpec::parse`] errors ([`GeometryError::BadPrimitive`],
/// [`GeometryError::UnknownSpec`]); the file readers' errors (`Io`, `Parse`, `NotWatertight`,
/// ...).
pub fn read_shape(spec: &str, opts: &ShapeOptions) -> Result<Shape, GeometryError> {
    read_shape_spec(&ShapeSpec::parse(spec)?, opts)
}

/// The shape of an already parsed spec: the primitive itself, or the file read by the reader of
/// its format (as [`read_shape`]).
///
/// # Errors
/// The file readers' errors (`Io`, `Parse`, `NotWatertight`, ...); none for primitives.
pub fn read_shape_spec(spec: &ShapeSpec, opts: &ShapeOptions) -> Result<Shape, GeometryError> {
    match spec {
        ShapeSpec::Box { size } => Ok(Shape::Box { size: *size }),
        ShapeSpec::Sphere { radius } => Ok(Shape::Sphere { radius: *radius }),
        ShapeSpec::File { path, format } => match format {
            ShapeFileFormat::Obj => Ok(Shape::Mesh(obj::read_obj(path, opts)?)),
            ShapeFileFormat::Stl => Ok(Shape::Mesh(stl::read_stl(path, opts)?)),
            ShapeFileFormat::Off => Ok(Shape::Mesh(off::read_off(path, opts)?)),
            ShapeFileFormat::Ply => ply::read_ply(path, opts),
        },
        ShapeSpec::Usd { path, prim, time } => {
            super::usd::read_usd_shape(path, prim.as_deref(), *time, opts)
        }
        ShapeSpec::Image { path } => Ok(Shape::Image(std::sync::Arc::new(image::read_image(
            path,
            &Default::default(),
        )?))),
    }
}
