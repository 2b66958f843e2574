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
//! | `metadata` | uint8, (bytes,) | UTF-8 JSON: every parameter that produced the basis ([`BasisMetadata`]) |
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
use crate::precompute::{BasisOptions, ModesReport, MAX_KERNELS};
use crate::report::Monitors;
use crate::{Error, Point3, Result};
use faer::Mat;
use npyz::WriterBuilder;
use serde::Serialize;
use serde_json::{Map, Value};
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

/// The metadata of a basis file: what produced the basis, stored as JSON in the `metadata`
/// array. The CLI (`freeform modes`, [`BasisMetadata::for_modes`]) and the scene cache
/// ([`BasisMetadata::for_cache`]) write it; [`load`] reads it back.
///
/// Reading is tolerant ([`BasisMetadata::from_json`]): a file written by an older or newer
/// freeform or by Python with any JSON still loads. A known key whose value does not fit its
/// field's type is left in [`BasisMetadata::extra`] (the field stays `None`), as is every
/// unknown key; the metadata exactly as stored is [`LoadedBasis::raw_metadata`].
///
/// Written JSON (keys sorted, absent fields left out), e.g. by `freeform modes`:
/// `{"freeform_version": "0.1.0", "max_relative_residual": 3e-10, "options": {...},
/// "orthonormality_error": 2e-15, "points": 30000, "shape": "box:5,1,1", "volume": 5.0}`;
/// Python: `json.loads(bytes(numpy.load("basis.npz")["metadata"]))["options"]`.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct BasisMetadata {
    /// Version of the freeform that wrote the file.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub freeform_version: Option<String>,
    /// The shape specification (`box:5,1,1`, `sphere:0.5`, a mesh or point-cloud path).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub shape: Option<String>,
    /// Every option of the precomputation, the eigensolver's configuration included.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub options: Option<BasisOptions>,
    /// Integration points N (`freeform modes`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub points: Option<usize>,
    /// Object volume, m^3 (`freeform modes`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub volume: Option<f64>,
    /// Largest recomputed relative eigen-residual (`freeform modes`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub max_relative_residual: Option<f64>,
    /// max |c^T M c - I| (`freeform modes`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub orthonormality_error: Option<f64>,
    /// The whole precomputation report (the scene cache).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub report: Option<ModesReport>,
    /// Every other key, as stored, and known keys whose value did not fit their field. Written
    /// after the fields: a key here that names a field overrides it.
    #[serde(flatten)]
    pub extra: Map<String, Value>,
}

impl BasisMetadata {
    /// What `freeform modes` writes: this freeform's version, the shape specification, the
    /// options, and the run's N, volume, largest relative residual and orthonormality error.
    pub fn for_modes(shape: &str, options: &BasisOptions, report: &ModesReport) -> Self {
        Self {
            points: Some(report.points),
            volume: Some(report.volume),
            max_relative_residual: Some(report.max_relative_residual),
            orthonormality_error: Some(report.orthonormality_error),
            ..Self::written_now(shape, options)
        }
    }

    /// What the scene cache writes: this freeform's version, the shape specification, the
    /// options and the whole report (its warnings and monitors apply to every later use).
    pub fn for_cache(shape: &str, options: &BasisOptions, report: &ModesReport) -> Self {
        Self {
            report: Some(report.clone()),
            ..Self::written_now(shape, options)
        }
    }

    fn written_now(shape: &str, options: &BasisOptions) -> Self {
        Self {
            freeform_version: Some(env!("CARGO_PKG_VERSION").to_string()),
            shape: Some(shape.to_string()),
            options: Some(options.clone()),
            ..Self::default()
        }
    }

    /// Read any JSON without failing: each known key of an object that parses into its field's
    /// type fills the field; every other key (unknown, or known with a value of another type)
    /// goes to [`BasisMetadata::extra`] unchanged. Anything but an object gives empty metadata.
    pub fn from_json(value: Value) -> Self {
        let Value::Object(mut extra) = value else {
            return Self::default();
        };
        fn take<T: serde::de::DeserializeOwned>(
            map: &mut Map<String, Value>,
            key: &str,
        ) -> Option<T> {
            let parsed = serde_json::from_value(map.get(key)?.clone()).ok()?;
            map.remove(key);
            Some(parsed)
        }
        Self {
            freeform_version: take(&mut extra, "freeform_version"),
            shape: take(&mut extra, "shape"),
            options: take(&mut extra, "options"),
            points: take(&mut extra, "points"),
            volume: take(&mut extra, "volume"),
            max_relative_residual: take(&mut extra, "max_relative_residual"),
            orthonormality_error: take(&mut extra, "orthonormality_error"),
            report: take(&mut extra, "report"),
            extra,
        }
    }

    /// The JSON object [`save`] writes (keys sorted).
    pub fn to_json(&self) -> Value {
        // Serializing plain data into a Value cannot fail (map keys are strings).
        serde_json::to_value(self).unwrap_or_default()
    }

    /// The warnings of the run that produced the basis (`report.warnings`), which still apply
    /// to every use of it; read from the stored JSON when the report did not parse as a whole.
    pub fn warnings(&self) -> Vec<String> {
        match (&self.report, self.extra.get("report")) {
            (Some(report), _) => report.warnings.clone(),
            (None, Some(raw)) => raw
                .get("warnings")
                .and_then(Value::as_array)
                .into_iter()
                .flatten()
                .filter_map(|w| w.as_str().map(str::to_string))
                .collect(),
            (None, None) => Vec::new(),
        }
    }

    /// The precomputation monitors of the run that produced the basis (`report.monitors`); all
    /// `None` when absent (e.g. metadata written by `freeform modes`, which has no report).
    pub fn monitors(&self) -> Monitors {
        match (&self.report, self.extra.get("report")) {
            (Some(report), _) => report.monitors.clone(),
            (None, Some(raw)) => raw
                .get("monitors")
                .and_then(|m| serde_json::from_value(m.clone()).ok())
                .unwrap_or_default(),
            (None, None) => Monitors::default(),
        }
    }
}

impl<'de> serde::Deserialize<'de> for BasisMetadata {
    /// Tolerant, as [`BasisMetadata::from_json`]: any JSON value deserializes.
    fn deserialize<D: serde::Deserializer<'de>>(
        deserializer: D,
    ) -> std::result::Result<Self, D::Error> {
        Value::deserialize(deserializer).map(Self::from_json)
    }
}

impl From<Value> for BasisMetadata {
    fn from(value: Value) -> Self {
        Self::from_json(value)
    }
}

/// Write `basis` and its metadata to `path` atomically: the archive is written to a temporary
/// file next to it and renamed, so a failed write never leaves a half-written basis behind.
/// The metadata is [`BasisMetadata::to_json`], pretty-printed.
pub fn save(path: &Path, basis: &Basis, metadata: &BasisMetadata) -> Result<()> {
    save_json(path, basis, &metadata.to_json())
}

/// [`save`] with any JSON value as the metadata.
fn save_json(path: &Path, basis: &Basis, metadata: &Value) -> Result<()> {
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
    super::file::write_atomically(path, |tmp| {
        let io_tmp = |source| Error::Io {
            path: tmp.to_path_buf(),
            source,
        };
        // A zip error that is an I/O error keeps its cause (out of space, read-only).
        let zip_io = |e: zip::result::ZipError| match e {
            zip::result::ZipError::Io(source) => io_tmp(source),
            other => io_tmp(std::io::Error::other(other)),
        };
        let file = std::fs::File::create(tmp).map_err(io_tmp)?;
        let writer = super::file::StopAfterError::new(std::io::BufWriter::new(file));
        let mut zip = zip::ZipWriter::new(writer);
        let opts = zip::write::SimpleFileOptions::default()
            .compression_method(zip::CompressionMethod::Stored)
            .large_file(true);
        for (name, bytes) in entries {
            zip.start_file(format!("{name}.npy"), opts)
                .map_err(zip_io)?;
            zip.write_all(&bytes).map_err(io_tmp)?;
        }
        let mut inner = zip.finish().map_err(zip_io)?.into_inner();
        inner.flush().map_err(io_tmp)
    })
}

/// A basis read back from disk, with its metadata.
#[derive(Debug, Clone)]
pub struct LoadedBasis {
    /// The basis.
    pub basis: Basis,
    /// The metadata stored with it, typed ([`BasisMetadata::from_json`]: never fails).
    pub metadata: BasisMetadata,
    /// The metadata JSON exactly as stored (any JSON value).
    pub raw_metadata: Value,
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
    let raw_metadata: Value = serde_json::from_slice(&meta_bytes)
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
        metadata: BasisMetadata::from_json(raw_metadata.clone()),
        raw_metadata,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::precompute::{build_basis, BasisRun, SolverConfig};
    use crate::progress::Silent;
    use serde_json::json;

    fn small_run() -> (BasisOptions, BasisRun) {
        let opts = BasisOptions {
            kernels: 30,
            modes: 3,
            resolution: Some(crate::precompute::sampling::Resolution::Count(3000)),
            solver: SolverConfig::Dense,
            ..BasisOptions::default()
        };
        let shape = crate::io::read_shape("box:2,1,1", &Default::default()).unwrap();
        let run = build_basis(&shape, &opts, &Silent).unwrap();
        (opts, run)
    }

    fn keys(v: &Value) -> Vec<&str> {
        v.as_object().unwrap().keys().map(String::as_str).collect()
    }

    #[test]
    fn metadata_of_both_writers_round_trips() {
        let (opts, mut run) = small_run();
        run.report
            .warnings
            .push("a warning that still applies".into());
        let dir = tempfile::tempdir().unwrap();

        // `freeform modes`: the keys it has always written, with the same values.
        let path = dir.path().join("modes.npz");
        let written = BasisMetadata::for_modes("box:2,1,1", &opts, &run.report);
        save(&path, &run.basis, &written).unwrap();
        let back = load(&path).unwrap();
        assert_eq!(back.metadata, written);
        let raw = &back.raw_metadata;
        assert_eq!(
            keys(raw),
            [
                "freeform_version",
                "max_relative_residual",
                "options",
                "orthonormality_error",
                "points",
                "shape",
                "volume"
            ]
        );
        assert_eq!(raw["options"], serde_json::to_value(&opts).unwrap());
        assert_eq!(raw["options"]["solver"], "dense");
        assert_eq!(raw["points"], run.report.points);
        assert_eq!(raw["volume"], run.report.volume);
        assert_eq!(raw["freeform_version"], env!("CARGO_PKG_VERSION"));
        assert_eq!(back.metadata.options.as_ref(), Some(&opts));
        assert!(back.metadata.warnings().is_empty());
        assert_eq!(back.metadata.monitors(), Monitors::default());

        // The scene cache: the whole report, its warnings and monitors typed.
        let path = dir.path().join("cache.npz");
        let written = BasisMetadata::for_cache("box:2,1,1", &opts, &run.report);
        save(&path, &run.basis, &written).unwrap();
        let back = load(&path).unwrap();
        assert_eq!(back.metadata, written);
        assert_eq!(back.metadata.report.as_ref(), Some(&run.report));
        assert_eq!(
            keys(&back.raw_metadata),
            ["freeform_version", "options", "report", "shape"]
        );
        assert_eq!(
            back.raw_metadata["report"],
            serde_json::to_value(&run.report).unwrap()
        );
        assert_eq!(back.metadata.warnings(), ["a warning that still applies"]);
        assert_eq!(back.metadata.monitors(), run.report.monitors);
        assert!(back.metadata.monitors().eigen_iterations.is_some());
        // Unknown keys survive a read and a write.
        let mut extended = back.metadata.clone();
        extended
            .extra
            .insert("note".into(), json!({"from": "python"}));
        save(&path, &run.basis, &extended).unwrap();
        assert_eq!(load(&path).unwrap().metadata, extended);
    }

    /// Metadata written by anyone (Python, another version) loads: what fits its field is
    /// typed, the rest is kept as stored, and nothing makes the basis unreadable.
    #[test]
    fn any_json_metadata_loads() {
        let (_, run) = small_run();
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("any.npz");
        for odd in [
            json!([1, 2, 3]),
            json!("text"),
            json!(null),
            json!(4.5),
            json!({}),
        ] {
            save_json(&path, &run.basis, &odd).unwrap();
            let back = load(&path).unwrap();
            assert_eq!(back.basis.eigenvalues, run.basis.eigenvalues);
            assert_eq!(back.raw_metadata, odd);
            assert_eq!(back.metadata, BasisMetadata::default());
            assert!(back.metadata.warnings().is_empty());
        }
        // Known keys of other types, a partial options table, a report that is not a whole
        // `ModesReport` (a residual stored as null, as JSON writes infinity) but still has
        // warnings and monitors.
        let odd = json!({
            "shape": 5,
            "points": "many",
            "volume": 2.0,
            "options": {"kernels": 30},
            "report": {
                "max_relative_residual": null,
                "warnings": ["stored warning", 7],
                "monitors": {"eigen_iterations": 12, "steps": null}
            },
            "custom": {"nested": [true]}
        });
        save_json(&path, &run.basis, &odd).unwrap();
        let back = load(&path).unwrap();
        assert_eq!(back.raw_metadata, odd);
        let m = &back.metadata;
        assert_eq!(
            (m.shape.as_deref(), m.points, m.volume),
            (None, None, Some(2.0))
        );
        assert!(m.options.is_none() && m.report.is_none());
        assert_eq!(m.extra["shape"], 5);
        assert_eq!(m.extra["points"], "many");
        assert_eq!(m.extra["options"], json!({"kernels": 30}));
        assert_eq!(m.extra["custom"], json!({"nested": [true]}));
        assert!(!m.extra.contains_key("volume"));
        assert_eq!(m.warnings(), ["stored warning"]);
        assert_eq!(m.monitors().eigen_iterations, Some(12));
        // Written back, the same JSON (keys sorted).
        assert_eq!(m.to_json(), odd);
        // Deserialize is as tolerant as from_json.
        let parsed: BasisMetadata = serde_json::from_value(odd.clone()).unwrap();
        assert_eq!(&parsed, m);

        // Metadata bytes that are not JSON at all are still an error (a damaged file).
        let mut archive = zip::ZipArchive::new(std::fs::File::open(&path).unwrap()).unwrap();
        let mut buf = Vec::new();
        {
            let mut zip = zip::ZipWriter::new(std::io::Cursor::new(&mut buf));
            for i in 0..archive.len() {
                let mut entry = archive.by_index(i).unwrap();
                let name = entry.name().to_string();
                let mut bytes = Vec::new();
                entry.read_to_end(&mut bytes).unwrap();
                if name == "metadata.npy" {
                    bytes = npy_bytes(&[9], b"{not json").unwrap();
                }
                zip.start_file(name, zip::write::SimpleFileOptions::default())
                    .unwrap();
                zip.write_all(&bytes).unwrap();
            }
            zip.finish().unwrap();
        }
        let err = load_from(&path, std::io::Cursor::new(buf)).unwrap_err();
        assert!(err.to_string().contains("metadata is not JSON"), "{err}");
    }
}
