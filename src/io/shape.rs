//! Shape files: [`read_shape`] turns a shape spec into a [`Shape`], reading the file it names
//! with the reader of its format; and the helpers the shape file readers and writers share.

use super::{image, obj, off, ply, stl};
use crate::geometry::{
    weld_exact, GeometryError, Shape, ShapeFileFormat, ShapeOptions, ShapeSpec, TriMesh,
};
use crate::Point3;
use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::Path;

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
        ShapeSpec::Image { path } => Ok(Shape::Image(std::sync::Arc::new(image::read_image(
            path,
            &Default::default(),
        )?))),
    }
}

/// Read a whole file; `Io` error with the path on failure, `Parse` error if it is empty.
pub(crate) fn read_nonempty(path: &Path) -> Result<Vec<u8>, GeometryError> {
    let bytes = std::fs::read(path).map_err(|e| io_error(path, e))?;
    if bytes.is_empty() {
        return Err(parse_error(path, "empty file"));
    }
    Ok(bytes)
}

pub(crate) fn io_error(path: &Path, source: std::io::Error) -> GeometryError {
    GeometryError::Io {
        path: path.to_path_buf(),
        source,
    }
}

pub(crate) fn parse_error(path: &Path, reason: impl Into<String>) -> GeometryError {
    GeometryError::Parse {
        path: path.to_path_buf(),
        reason: reason.into(),
    }
}

/// Index of the first vertex with a non-finite coordinate.
pub(crate) fn first_non_finite(vertices: &[Point3]) -> Option<usize> {
    vertices
        .iter()
        .position(|p| !p.iter().all(|c| c.is_finite()))
}

/// Weld bit-identical vertices, then validate and orient; errors carry `path`.
pub(crate) fn mesh_from_file_data(
    path: &Path,
    vertices: Vec<Point3>,
    triangles: Vec<[u32; 3]>,
    opts: &ShapeOptions,
) -> Result<TriMesh, GeometryError> {
    if triangles.is_empty() {
        return Err(parse_error(path, "the file has no triangles"));
    }
    let (vertices, triangles) = weld_exact(&vertices, &triangles);
    TriMesh::new(vertices, triangles, opts).map_err(|e| e.with_path(path))
}

/// Create (truncate) a file for writing, buffered.
pub(crate) fn create(path: &Path) -> Result<BufWriter<File>, GeometryError> {
    File::create(path)
        .map(BufWriter::new)
        .map_err(|e| io_error(path, e))
}

/// Flush a writer, mapping the error to `Io` with the path.
pub(crate) fn finish(path: &Path, mut w: impl Write) -> Result<(), GeometryError> {
    w.flush().map_err(|e| io_error(path, e))
}
