//! File formats: shape inputs (OBJ, STL, OFF, PLY meshes and point clouds), 3D Gaussian splat PLY
//! files ([`splat`]), the basis file (.npz)
//! and matrix exchange (MatrixMarket, PETSc binary).
//!
//! [`read_shape`] is the entry for shapes: it parses a spec ([`crate::geometry::ShapeSpec`]) and
//! reads the file it names with the reader of its format.

pub mod basis;
pub mod image;
pub mod matrix_market;
pub mod obj;
pub mod off;
pub mod ply;
mod shape;
pub mod splat;
pub mod stl;
pub mod vtk;

pub use shape::{read_shape, read_shape_spec};

use crate::geometry::GeometryError;
use std::path::{Path, PathBuf};

/// A fresh temporary path next to `path` (same directory, so a rename is atomic).
pub(crate) fn temp_path_for(path: &Path) -> PathBuf {
    let dir = path
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    let pid = std::process::id();
    let nanos = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.as_nanos())
        .unwrap_or(0);
    let name = path.file_name().and_then(|n| n.to_str()).unwrap_or("out");
    dir.join(format!(".{name}.{pid}-{nanos}.tmp"))
}

/// Run `write` on a temporary file next to `path`, then rename it to `path`: a failed or
/// interrupted write never leaves a partial file under the final name. A `path` that exists
/// and is not a regular file (`/dev/null`, a FIFO) is written directly: renaming onto it
/// would replace the device with a plain file.
pub fn write_atomically(
    path: &Path,
    write: impl FnOnce(&Path) -> crate::Result<()>,
) -> crate::Result<()> {
    if std::fs::metadata(path).is_ok_and(|m| !m.is_file() && !m.is_dir()) {
        return write(path);
    }
    let tmp = temp_path_for(path);
    let result = write(&tmp).and_then(|()| {
        std::fs::rename(&tmp, path).map_err(|source| crate::Error::Io {
            path: path.to_path_buf(),
            source,
        })
    });
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    result
}

/// Check that every triangle of a mesh about to be written refers to one of `vertex_count`
/// vertices (and fits the signed 32-bit indices some formats store).
pub(crate) fn check_triangle_indices(
    vertex_count: usize,
    triangles: &[[u32; 3]],
) -> Result<(), GeometryError> {
    match triangles.iter().enumerate().find(|(_, t)| {
        t.iter()
            .any(|&i| i as usize >= vertex_count || i > i32::MAX as u32)
    }) {
        Some((f, t)) => Err(GeometryError::InvalidInput(format!(
            "triangle {f} = {t:?} refers past the {vertex_count} vertices"
        ))),
        None => Ok(()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `--out /dev/null` (scripts/cgal_shapes.sh does it) must not rename a file over the
    /// device: that left /dev/null a plain file for every later process on the machine.
    #[cfg(unix)]
    #[test]
    fn writing_to_a_device_keeps_the_device() {
        use std::os::unix::fs::FileTypeExt;
        let null = Path::new("/dev/null");
        let mut given = None;
        write_atomically(null, |p| {
            given = Some(p.to_path_buf());
            std::fs::write(p, b"data").map_err(|source| crate::Error::Io {
                path: p.to_path_buf(),
                source,
            })
        })
        .unwrap();
        assert_eq!(given.as_deref(), Some(null));
        assert!(std::fs::metadata(null)
            .unwrap()
            .file_type()
            .is_char_device());
    }
}
