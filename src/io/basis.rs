//! The basis file: a NumPy `.npz` archive (a zip of `.npy` arrays, uncompressed, as
//! `numpy.savez` writes) that the simulator and Python read.
//!
//! | array | dtype, shape | content |
//! |---|---|---|
//! | `format_version` | int64, (1,) | 1 |
//! | `centers` | float64, (K, 3) | kernel centres p_k, metres |
//! | `radii` | float64, (K,) | support radii a_k, metres |
//! | `kernel_type` | int64, (1,) | 0 cubic, 1 quartic, 2 gaussian |
//! | `coefficients` | float64, (K, m+1) | c, column 0 the constant mode, c^T M c = I |
//! | `eigenvalues` | float64, (m+1,) | ascending, first 0 |
//! | `metadata` | uint8, (bytes,) | UTF-8 JSON: every parameter that produced the basis |
//!
//! Python: `z = numpy.load("basis.npz"); json.loads(bytes(z["metadata"]))`.
//!
//! Reading bounds every array before it is decompressed, so a damaged archive or a "zip bomb"
//! (a small deflated entry that expands without end) cannot exhaust memory: each entry may hold
//! an `.npy` header of at most [`NPY_HEADER_ALLOWANCE`] bytes plus the data its shape can
//! legitimately need, given the arrays read before it:
//!
//! | array | data bytes at most |
//! |---|---|
//! | `format_version`, `kernel_type` | 8 |
//! | `centers` | 24 x [`MAX_KERNELS`] (240 MB) |
//! | `radii` | 8 K |
//! | `coefficients` | min(8 K^2, [`MAX_COEFFICIENT_BYTES`]) (16 GiB) |
//! | `eigenvalues` | 8 (m+1) |
//! | `metadata` | [`MAX_METADATA_BYTES`] (64 MiB) |
//!
//! An entry whose declared size is above its limit, or whose data runs past it whatever the
//! archive declares, gives [`Error::BasisArrayTooLarge`].

use crate::precompute::rkpm::{KernelType, Kernels};
use crate::precompute::skinning::Basis;
use crate::precompute::MAX_KERNELS;
use crate::{Error, Point3, Result};
use faer::Mat;
use npyz::WriterBuilder;
use std::io::{Read, Write};
use std::path::Path;

/// Version written into `format_version`.
pub const FORMAT_VERSION: i64 = 1;

/// Bytes allowed for the `.npy` header of each array, on top of its data: 128 KiB. npyz writes
/// 128 bytes for each of these arrays (magic, version, length and a short dictionary padded to
/// 64-byte alignment, as numpy does); a version-1 header is at most 10 + 65,535 bytes, so this
/// admits any version-1 header and a version-2 or -3 header of the same size.
pub const NPY_HEADER_ALLOWANCE: u64 = 128 * 1024;

/// Most bytes of `coefficients` data: 16 GiB, e.g. K = 1,000,000 kernels with m + 1 = 2,147
/// columns or K = 10,000,000 with 214. The coefficients are the one array whose size the others
/// do not fix (m + 1 <= K is the only other bound: c^T M c = I needs independent columns), and a
/// basis beyond this could not have been computed where it is read: LOBPCG holds at least three
/// K x (m+1) blocks and the RKPM operators ~48 kB per kernel (docs/limits.md).
pub const MAX_COEFFICIENT_BYTES: u64 = 16 << 30;

// A K = 1,000,000 basis with 500 modes (4 GB of coefficients) must load.
const _: () = assert!(8 * 1_000_000 * 501 <= MAX_COEFFICIENT_BYTES);

/// Most bytes of the `metadata` array: 64 MiB. The CLI writes about 1 kB of JSON (the options
/// and a few diagnostics); the margin leaves room for whatever a user stores from Python.
pub const MAX_METADATA_BYTES: u64 = 64 << 20;

fn kernel_code(k: KernelType) -> i64 {
    match k {
        KernelType::Cubic => 0,
        KernelType::Quartic => 1,
        KernelType::Gaussian => 2,
    }
}

fn npy_bytes<T: npyz::Serialize + npyz::AutoSerialize + Copy>(
    shape: &[u64],
    data: &[T],
) -> std::io::Result<Vec<u8>> {
    let mut buf = Vec::new();
    {
        let mut w = npyz::WriteOptions::<T>::new()
            .default_dtype()
            .shape(shape)
            .writer(&mut buf)
            .begin_nd()?;
        w.extend(data.iter().copied())?;
        w.finish()?;
    }
    Ok(buf)
}

/// Write `basis` and its metadata (any JSON value) to `path` atomically: the archive is
/// written to a temporary file next to it and renamed, so a failed write never leaves a
/// half-written basis behind.
pub fn save(path: &Path, basis: &Basis, metadata: &serde_json::Value) -> Result<()> {
    let io_err = |source| Error::Io {
        path: path.to_path_buf(),
        source,
    };
    let k = basis.kernels.len();
    let m1 = basis.modes();
    let centers: Vec<f64> = basis.kernels.centers.iter().flatten().copied().collect();
    let mut coef = Vec::with_capacity(k * m1);
    for i in 0..k {
        for j in 0..m1 {
            coef.push(basis.coefficients[(i, j)]);
        }
    }
    let meta = serde_json::to_vec_pretty(metadata).map_err(|e| io_err(std::io::Error::other(e)))?;
    let entries: Vec<(&str, Vec<u8>)> = vec![
        (
            "format_version",
            npy_bytes(&[1], &[FORMAT_VERSION]).map_err(io_err)?,
        ),
        (
            "centers",
            npy_bytes(&[k as u64, 3], &centers).map_err(io_err)?,
        ),
        (
            "radii",
            npy_bytes(&[k as u64], &basis.kernels.radii).map_err(io_err)?,
        ),
        (
            "kernel_type",
            npy_bytes(&[1], &[kernel_code(basis.kernels.kind)]).map_err(io_err)?,
        ),
        (
            "coefficients",
            npy_bytes(&[k as u64, m1 as u64], &coef).map_err(io_err)?,
        ),
        (
            "eigenvalues",
            npy_bytes(&[m1 as u64], &basis.eigenvalues).map_err(io_err)?,
        ),
        (
            "metadata",
            npy_bytes(&[meta.len() as u64], &meta).map_err(io_err)?,
        ),
    ];
    super::write_atomically(path, |tmp| {
        let io_tmp = |source| Error::Io {
            path: tmp.to_path_buf(),
            source,
        };
        let file = std::fs::File::create(tmp).map_err(io_tmp)?;
        let mut zip = zip::ZipWriter::new(std::io::BufWriter::new(file));
        let opts = zip::write::SimpleFileOptions::default()
            .compression_method(zip::CompressionMethod::Stored)
            .large_file(true);
        for (name, bytes) in entries {
            zip.start_file(format!("{name}.npy"), opts)
                .map_err(|e| io_tmp(std::io::Error::other(e)))?;
            zip.write_all(&bytes).map_err(io_tmp)?;
        }
        let mut inner = zip.finish().map_err(|e| io_tmp(std::io::Error::other(e)))?;
        inner.flush().map_err(io_tmp)
    })
}

/// A basis read back from disk, with its metadata.
#[derive(Debug, Clone)]
pub struct LoadedBasis {
    /// The basis.
    pub basis: Basis,
    /// The metadata JSON stored with it.
    pub metadata: serde_json::Value,
}

/// Read a basis written by [`save`] (or by Python with the same arrays).
pub fn load(path: &Path) -> Result<LoadedBasis> {
    let file = std::fs::File::open(path).map_err(|source| Error::Io {
        path: path.to_path_buf(),
        source,
    })?;
    load_from(path, std::io::BufReader::new(file))
}

/// Read a basis from `reader` as [`load`] reads a file; `path` only labels the errors.
///
/// # Errors
/// [`Error::BasisArrayTooLarge`] for an array larger than its limit (see the module
/// documentation); [`Error::BasisFile`] for anything else that is not a complete, consistent
/// basis archive.
pub fn load_from(path: &Path, reader: impl std::io::Read + std::io::Seek) -> Result<LoadedBasis> {
    let bad = |reason: String| Error::BasisFile {
        path: path.to_path_buf(),
        reason,
    };
    let mut zip =
        zip::ZipArchive::new(reader).map_err(|e| bad(format!("not a zip/npz archive ({e})")))?;
    // `max_data`: the most data bytes the array can legitimately hold (module documentation).
    let mut read = |name: &'static str, max_data: u64| -> Result<(Vec<u64>, Vec<u8>)> {
        let entry = zip
            .by_name(&format!("{name}.npy"))
            .map_err(|_| bad(format!("missing array `{name}`")))?;
        let limit = NPY_HEADER_ALLOWANCE.saturating_add(max_data);
        let declared = entry.size();
        let too_large = || Error::BasisArrayTooLarge {
            path: path.to_path_buf(),
            array: name,
            limit,
            declared,
        };
        if declared > limit {
            return Err(too_large());
        }
        // The declared size may lie: read at most one byte past the limit and look. Nothing is
        // reserved from the declared size, so memory follows the bytes actually decompressed.
        let mut bytes = Vec::new();
        entry
            .take(limit.saturating_add(1))
            .read_to_end(&mut bytes)
            .map_err(|e| bad(format!("array `{name}`: {e}")))?;
        if bytes.len() as u64 > limit {
            return Err(too_large());
        }
        let npy =
            npyz::NpyFile::new(&bytes[..]).map_err(|e| bad(format!("array `{name}`: {e}")))?;
        Ok((npy.shape().to_vec(), bytes))
    };
    fn decode<T: npyz::Deserialize>(bytes: &[u8]) -> std::io::Result<Vec<T>> {
        npyz::NpyFile::new(bytes)?.into_vec::<T>()
    }
    let f64s = |name: &str, bytes: &[u8]| {
        decode::<f64>(bytes).map_err(|e| bad(format!("array `{name}` is not float64: {e}")))
    };
    let i64s = |name: &str, bytes: &[u8]| {
        decode::<i64>(bytes).map_err(|e| bad(format!("array `{name}` is not int64: {e}")))
    };

    let (_, b) = read("format_version", 8)?;
    let version = i64s("format_version", &b)?;
    if version.first() != Some(&FORMAT_VERSION) {
        return Err(bad(format!(
            "format_version {version:?}; this build reads version {FORMAT_VERSION}"
        )));
    }
    let (cs, b) = read("centers", 24 * MAX_KERNELS as u64)?;
    let centers = f64s("centers", &b)?;
    if cs.len() != 2 || cs[1] != 3 {
        return Err(bad(format!("centers has shape {cs:?}, expected (K, 3)")));
    }
    let k = cs[0] as usize;
    let k64 = k as u64;
    let (_, b) = read("radii", k64.saturating_mul(8))?;
    let radii = f64s("radii", &b)?;
    if radii.len() != k {
        return Err(bad(format!(
            "radii has {} entries for {k} centres",
            radii.len()
        )));
    }
    let (_, b) = read("kernel_type", 8)?;
    let kind = match i64s("kernel_type", &b)?.first() {
        Some(0) => KernelType::Cubic,
        Some(1) => KernelType::Quartic,
        Some(2) => KernelType::Gaussian,
        other => return Err(bad(format!("unknown kernel_type {other:?}"))),
    };
    let coefficient_bytes = k64
        .saturating_mul(k64)
        .saturating_mul(8)
        .min(MAX_COEFFICIENT_BYTES);
    let (shape, b) = read("coefficients", coefficient_bytes)?;
    let coef = f64s("coefficients", &b)?;
    if shape.len() != 2 || shape[0] as usize != k {
        return Err(bad(format!(
            "coefficients has shape {shape:?}, expected ({k}, m+1)"
        )));
    }
    let m1 = shape[1] as usize;
    let (_, b) = read("eigenvalues", (m1 as u64).saturating_mul(8))?;
    let eigenvalues = f64s("eigenvalues", &b)?;
    if eigenvalues.len() != m1 {
        return Err(bad(format!(
            "{} eigenvalues for {m1} coefficient columns",
            eigenvalues.len()
        )));
    }
    let (_, b) = read("metadata", MAX_METADATA_BYTES)?;
    let meta_bytes = decode::<u8>(&b).map_err(|e| bad(format!("metadata: {e}")))?;
    let metadata = serde_json::from_slice(&meta_bytes)
        .map_err(|e| bad(format!("metadata is not JSON: {e}")))?;
    if centers
        .iter()
        .chain(&radii)
        .chain(&coef)
        .chain(&eigenvalues)
        .any(|v| !v.is_finite())
    {
        return Err(bad("contains NaN or infinite values".into()));
    }
    // npyz reads exactly the elements the shapes announce; checked again so that no shape
    // arithmetic can make the indexing below go out of range.
    if Some(centers.len()) != k.checked_mul(3) || Some(coef.len()) != k.checked_mul(m1) {
        return Err(bad(format!(
            "{} centre coordinates and {} coefficients do not fit K = {k}, m + 1 = {m1}",
            centers.len(),
            coef.len()
        )));
    }
    let centers: Vec<Point3> = centers
        .chunks_exact(3)
        .map(|c| [c[0], c[1], c[2]])
        .collect();
    let coefficients = Mat::from_fn(k, m1, |i, j| coef[i * m1 + j]);
    Ok(LoadedBasis {
        basis: Basis {
            kernels: Kernels {
                centers,
                radii,
                kind,
            },
            coefficients,
            eigenvalues,
        },
        metadata,
    })
}
