//! Where a run reads relative paths from and writes to, and whether it stops at a warning
//! ([`RunSettings`]): an input of every object's set-up and of the batch run.

use std::path::PathBuf;

/// Where a run reads relative paths from and writes to.
#[derive(Debug, Clone, Default)]
pub struct RunSettings {
    /// Directory that relative shape paths and the cache directory are resolved against
    /// (the scene file's directory for `freeform run`).
    pub base_dir: PathBuf,
    /// Output directory for frames (None: simulate and summarise only).
    pub out: Option<PathBuf>,
    /// Stop with [`crate::Error::Strict`] at the first warning (a poorly conditioned basis, a
    /// step that did not converge, a failed line search, a Cholesky fallback) instead of
    /// reporting it in the summary. Frames already written stay; the `.pvd` collection is
    /// only written by a complete run.
    pub strict: bool,
}

impl RunSettings {
    /// The settings `freeform run` uses for a scene file: relative paths (shapes, the basis
    /// cache) resolve against the file's directory; no frames; not strict.
    pub fn for_scene_file(path: &std::path::Path) -> RunSettings {
        RunSettings {
            base_dir: path.parent().map(PathBuf::from).unwrap_or_default(),
            out: None,
            strict: false,
        }
    }
}
