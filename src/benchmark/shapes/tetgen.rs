//! Tetrahedralizing a closed surface with the external TetGen program (Debian package
//! `tetgen`) for the FEM reference: write the surface as OFF, run `tetgen`, read back its
//! `.node/.ele`.

use crate::fem::{FemError, TetMesh};
use crate::Point3;
use serde::Serialize;
use std::path::{Path, PathBuf};
use std::process::Command;

/// TetGen settings.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct TetgenOptions {
    /// The program: a name looked up on PATH or a path. Default "tetgen".
    pub program: PathBuf,
    /// Radius-edge ratio bound of `-q` (TetGen's default 2.0; 1.414 is its recommended
    /// quality bound). Default 1.414.
    pub quality: f64,
    /// Largest tet volume of `-a`, m^3 (of the normalized shape, bounding box side 1).
    /// Default 1e-3 (a tet edge of ~0.2 m at most; the surface's own triangles, kept by `-Y`,
    /// are usually finer).
    pub max_volume: f64,
}

impl Default for TetgenOptions {
    fn default() -> Self {
        Self {
            program: PathBuf::from("tetgen"),
            quality: 1.414,
            max_volume: 1e-3,
        }
    }
}

impl TetgenOptions {
    /// The command-line switches: `-p` (tetrahedralize a piecewise linear complex, the
    /// surface), `-Y` (keep the surface triangles, so every surface vertex is a FEM node at
    /// every refinement), `-q<quality>`, `-a<max_volume>`, `-Q` (quiet).
    pub fn switches(&self) -> String {
        format!("-pYq{}a{}Q", self.quality, self.max_volume)
    }
}

/// Tetrahedralize the closed surface (`vertices` V x 3 metres, `triangles` F x 3) with
/// TetGen, working in `work_dir` (created if needed; the files `<stem>.off`,
/// `<stem>.1.node`, `<stem>.1.ele` are left there for inspection).
///
/// # Errors
/// [`FemError::Mesher`] when the program is not found, exits with an error (its output is
/// quoted) or writes no tetrahedra (an open or self-intersecting surface); [`FemError::Io`]
/// for the work files; the reader's errors for what TetGen wrote.
pub fn tetrahedralize(
    vertices: &[Point3],
    triangles: &[[u32; 3]],
    options: &TetgenOptions,
    work_dir: &Path,
    stem: &str,
) -> Result<TetMesh, FemError> {
    if !(options.quality >= 1.0 && options.quality.is_finite()) {
        return Err(FemError::Mesher(format!(
            "quality bound {} must be a finite radius-edge ratio >= 1 (TetGen's -q)",
            options.quality
        )));
    }
    if !(options.max_volume > 0.0 && options.max_volume.is_finite()) {
        return Err(FemError::Mesher(format!(
            "largest tet volume {} must be positive and finite (TetGen's -a)",
            options.max_volume
        )));
    }
    std::fs::create_dir_all(work_dir).map_err(|source| FemError::Io {
        path: work_dir.to_path_buf(),
        source,
    })?;
    let off = work_dir.join(format!("{stem}.off"));
    let node = work_dir.join(format!("{stem}.1.node"));
    let ele = work_dir.join(format!("{stem}.1.ele"));
    for stale in [&node, &ele] {
        // A leftover from an earlier run must not pass for this run's output.
        let _ = std::fs::remove_file(stale);
    }
    write_plain_off(&off, vertices, triangles)?;
    let output = Command::new(&options.program)
        .arg(options.switches())
        .arg(&off)
        .output()
        .map_err(|e| {
            FemError::Mesher(if e.kind() == std::io::ErrorKind::NotFound {
                format!(
                    "the program `{}` was not found; install TetGen (Debian: apt-get install \
                     tetgen) or give its path",
                    options.program.display()
                )
            } else {
                format!("cannot run `{}`: {e}", options.program.display())
            })
        })?;
    let said = || {
        let text = format!(
            "{}{}",
            String::from_utf8_lossy(&output.stdout),
            String::from_utf8_lossy(&output.stderr)
        );
        let lines: Vec<&str> = text.lines().filter(|l| !l.trim().is_empty()).collect();
        let tail = lines[lines.len().saturating_sub(6)..].join(" | ");
        if tail.is_empty() {
            "no message".to_string()
        } else {
            tail
        }
    };
    if !output.status.success() {
        return Err(FemError::Mesher(format!(
            "`{} {} {}` failed ({}): {}",
            options.program.display(),
            options.switches(),
            off.display(),
            output.status,
            said()
        )));
    }
    if !ele.exists() {
        return Err(FemError::Mesher(format!(
            "`{} {} {}` wrote no tetrahedra (is the surface closed and free of \
             self-intersections? check with `tetgen -d`): {}",
            options.program.display(),
            options.switches(),
            off.display(),
            said()
        )));
    }
    crate::fem::readers::tetgen::read(&node, &ele)
}

/// OFF without comment lines (TetGen's reader aborts on the `#` line that
/// [`crate::io::off::write_off`] writes). Coordinates in Rust's shortest round-trip form.
fn write_plain_off(
    path: &Path,
    vertices: &[Point3],
    triangles: &[[u32; 3]],
) -> Result<(), FemError> {
    let n = vertices.len();
    if let Some(t) = triangles
        .iter()
        .find(|t| t.iter().any(|&i| i as usize >= n))
    {
        return Err(FemError::Mesh(format!(
            "surface triangle {t:?} indexes past the {n} vertices"
        )));
    }
    let mut text = format!("OFF\n{} {} 0\n", n, triangles.len());
    for p in vertices {
        text += &format!("{} {} {}\n", p[0], p[1], p[2]);
    }
    for t in triangles {
        text += &format!("3 {} {} {}\n", t[0], t[1], t[2]);
    }
    std::fs::write(path, text).map_err(|source| FemError::Io {
        path: path.to_path_buf(),
        source,
    })
}
