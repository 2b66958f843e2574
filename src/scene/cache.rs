//! The on-disk basis cache. A basis is stored as `<dir>/<key>.npz` (the ordinary basis file)
//! where the key is the SHA-256 of everything that produced it: the cache format, the
//! freeform version, the shape specification, the SHA-256 of the shape file's bytes (for
//! files) and every basis option (material and region overrides included). Integration
//! points and materials are cheap and deterministic, so they are recomputed, not stored. The
//! file's metadata is [`BasisMetadata::for_cache`]: what produced the basis and its report,
//! whose warnings and monitors apply to every later use.

use crate::io::basis::{self, BasisMetadata, LoadedBasis};
use crate::precompute::skinning::Basis;
use crate::precompute::BasisOptions;
use crate::{Error, Result};
use sha2::{Digest, Sha256};
use std::path::{Path, PathBuf};

/// Bump when the cached content or its meaning changes.
const CACHE_FORMAT: u32 = 1;

fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

/// The cache key of a basis: 64 hex digits.
pub fn key(shape_spec: &str, shape_file: Option<&Path>, opts: &BasisOptions) -> Result<String> {
    let file_hash = match shape_file {
        Some(p) => {
            let bytes = std::fs::read(p).map_err(|source| Error::Io {
                path: p.to_path_buf(),
                source,
            })?;
            Some(hex(&Sha256::digest(&bytes)))
        }
        None => None,
    };
    let desc = serde_json::json!({
        "cache_format": CACHE_FORMAT,
        "freeform_version": env!("CARGO_PKG_VERSION"),
        "shape": shape_spec,
        "shape_file_sha256": file_hash,
        "options": opts,
    });
    Ok(hex(&Sha256::digest(desc.to_string().as_bytes())))
}

/// The text a shape read from a USD prim enters the cache key as: the SHA-256 of its points
/// (and triangles) as read, so the prim, the time code, the up axis and every composed layer
/// count, not only the root layer's bytes.
pub fn geometry_text(shape: &crate::geometry::Shape) -> String {
    use crate::geometry::Shape;
    fn points(h: &mut Sha256, p: &[crate::Point3]) {
        for c in p.iter().flatten() {
            h.update(c.to_bits().to_le_bytes());
        }
    }
    let mut h = Sha256::new();
    match shape {
        Shape::Mesh(m) => {
            points(&mut h, m.vertices());
            for v in m.triangles().iter().flatten() {
                h.update(v.to_le_bytes());
            }
        }
        Shape::PointCloud(c) => points(&mut h, c.points()),
        // A USD prim reads as a mesh or a cloud only.
        Shape::Box { .. } | Shape::Sphere { .. } | Shape::Image(_) => {}
    }
    format!("usd {} sha256 {}", shape.kind(), hex(&h.finalize()))
}

/// Path of the cached basis for `key` in `dir`.
pub fn path(dir: &Path, key: &str) -> PathBuf {
    dir.join(format!("{key}.npz"))
}

/// The cached basis and its metadata, if present and readable with the expected number of
/// modes (m + 1 for `modes` = m). A damaged or mismatched file is reported through `warn` and
/// ignored (it will be rewritten).
pub fn load_basis(
    dir: &Path,
    key: &str,
    modes: usize,
    warn: &mut dyn FnMut(String),
) -> Option<LoadedBasis> {
    let p = path(dir, key);
    if !p.exists() {
        return None;
    }
    match basis::load(&p) {
        Ok(l) if l.basis.modes() == modes + 1 => Some(l),
        Ok(l) => {
            warn(format!(
                "cached basis {} has {} modes, expected {}; recomputing",
                p.display(),
                l.basis.modes(),
                modes + 1
            ));
            None
        }
        Err(e) => {
            warn(format!(
                "ignoring unreadable cached basis: {e}; recomputing"
            ));
            None
        }
    }
}

/// Store a basis under `key` with its metadata ([`BasisMetadata::for_cache`]), atomically;
/// creates `dir`. Returns the file's path.
pub fn store_basis(dir: &Path, key: &str, b: &Basis, metadata: &BasisMetadata) -> Result<PathBuf> {
    std::fs::create_dir_all(dir).map_err(|source| Error::Io {
        path: dir.to_path_buf(),
        source,
    })?;
    let p = path(dir, key);
    basis::save(&p, b, metadata)?;
    Ok(p)
}
