//! What the file readers and writers of this folder share: whole-file reads, the `Io` and
//! `Parse` errors with the path, mesh validation of read data, buffered creation, atomic
//! writes through a temporary file, and index checks before a mesh is written.

use crate::geometry::{weld_exact, GeometryError, ShapeOptions, TriMesh};
use crate::Point3;
use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

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
    result.map_err(|e| named_as(e, &tmp, path))
}

/// `e` with the temporary file `tmp` it names replaced by `path`, the file the caller asked
/// for (a read-only or full target must not be reported as `.name.1234-5678.tmp`).
fn named_as(e: crate::Error, tmp: &Path, path: &Path) -> crate::Error {
    use crate::geometry::GeometryError;
    match e {
        crate::Error::Io { path: p, source } if p == tmp => crate::Error::Io {
            path: path.to_path_buf(),
            source,
        },
        crate::Error::Geometry(GeometryError::Io { path: p, source }) if p == tmp => {
            crate::Error::Geometry(GeometryError::Io {
                path: path.to_path_buf(),
                source,
            })
        }
        other => other,
    }
}

/// A writer that, after its first error, accepts and drops everything: a writer wrapped in
/// it (a zip archive) may be dropped after a failed write without a second failure (the zip
/// crate's `Drop` finalizes the archive and prints its error to stderr). The first error
/// still reaches the caller, which discards the file.
pub(crate) struct StopAfterError<W> {
    inner: W,
    failed: bool,
}

impl<W> StopAfterError<W> {
    /// Wrap `inner`.
    pub(crate) fn new(inner: W) -> Self {
        StopAfterError {
            inner,
            failed: false,
        }
    }

    /// The wrapped writer.
    pub(crate) fn into_inner(self) -> W {
        self.inner
    }
}

impl<W: Write> Write for StopAfterError<W> {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        if self.failed {
            return Ok(buf.len());
        }
        self.inner
            .write(buf)
            .inspect_err(|e| self.failed = e.kind() != std::io::ErrorKind::Interrupted)
    }
    fn flush(&mut self) -> std::io::Result<()> {
        if self.failed {
            return Ok(());
        }
        self.inner
            .flush()
            .inspect_err(|e| self.failed = e.kind() != std::io::ErrorKind::Interrupted)
    }
}

impl<W: std::io::Seek> std::io::Seek for StopAfterError<W> {
    fn seek(&mut self, pos: std::io::SeekFrom) -> std::io::Result<u64> {
        if self.failed {
            return Ok(0);
        }
        self.inner
            .seek(pos)
            .inspect_err(|e| self.failed = e.kind() != std::io::ErrorKind::Interrupted)
    }
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
