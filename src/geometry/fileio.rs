//! Helpers shared by the shape file readers and writers in [`crate::io`].

use super::{weld_exact, GeometryError, ShapeOptions, TriMesh};
use crate::Point3;
use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::Path;

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
