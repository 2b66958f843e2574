//! Voxel image files: NIfTI-1 (`.nii`, `.nii.gz`, read by the `nifti` crate) and NumPy `.npy`
//! (read by `npyz`), into a [`VoxelImage`] of labels or Young's moduli.
//!
//! NIfTI geometry: the sform when `sform_code > 0`, else the qform when `qform_code > 0`, else
//! `pixdim` with the origin at 0; lengths in the header's spatial unit (metres, millimetres or
//! micrometres; "unknown" is taken as metres). Only axis-aligned grids are read: a rotated or
//! sheared affine is refused (resample the image); a negative axis (a flip) is undone by
//! reversing the voxels along it, so spacing is always positive. A `.npy` array of shape
//! (nx, ny, nz) (axis 0 is x) has no geometry: the caller gives spacing and origin.

use super::file::parse_error;
use crate::geometry::{GeometryError, VoxelImage, VoxelValues, MAX_VOXELS};
use crate::Point3;
use nifti::{NiftiObject, NiftiType};
use std::path::Path;

/// How to read an image file.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct ImageReadOptions {
    /// Voxel edge per axis, metres, replacing the file's (required for `.npy`).
    pub spacing: Option<[f64; 3]>,
    /// Centre of voxel [0, 0, 0], metres, replacing the file's (default for `.npy`: 0).
    pub origin: Option<Point3>,
    /// What the voxels hold (default: by data type).
    pub values: ImageValueKind,
}

/// What an image's voxels hold.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ImageValueKind {
    /// Integer data types are labels, floating-point ones Young's moduli (Pa).
    #[default]
    Auto,
    /// Material labels (floating-point data must hold whole numbers).
    Labels,
    /// Young's moduli, Pa.
    Moduli,
}

/// Whether `path` names a voxel image by its extension: `.nii`, `.nii.gz` or `.npy`
/// (case-insensitive).
pub fn is_image_file(path: &Path) -> bool {
    let name = path
        .file_name()
        .and_then(|n| n.to_str())
        .unwrap_or("")
        .to_ascii_lowercase();
    name.ends_with(".nii") || name.ends_with(".nii.gz") || name.ends_with(".npy")
}

/// Read a `.nii`, `.nii.gz` or `.npy` image (by extension).
///
/// # Errors
/// [`GeometryError::Io`] when the file cannot be read; [`GeometryError::Parse`] naming the file
/// for everything else: malformed, truncated or unsupported content (wrong dimensionality,
/// rotated grids, complex data) and the [`VoxelImage::new`] errors (spacing, bad moduli, empty
/// image) as their messages.
pub fn read_image(path: &Path, opts: &ImageReadOptions) -> Result<VoxelImage, GeometryError> {
    let name = path.to_string_lossy().to_ascii_lowercase();
    if name.ends_with(".npy") {
        read_npy(path, opts)
    } else {
        read_nifti(path, opts)
    }
}

/// Errors about the image's content name the file (as a [`GeometryError::Parse`]).
fn in_file(path: &Path, e: GeometryError) -> GeometryError {
    match e {
        e @ (GeometryError::Io { .. } | GeometryError::Parse { .. }) => e,
        other => parse_error(path, other.to_string()),
    }
}

/// Raw voxel values before they become labels or moduli.
enum Raw {
    Int(Vec<i64>),
    Float(Vec<f64>),
}

/// Read a NIfTI-1 image (`.nii`, or gzip-compressed `.nii.gz`).
///
/// # Errors
/// As [`read_image`].
pub fn read_nifti(path: &Path, opts: &ImageReadOptions) -> Result<VoxelImage, GeometryError> {
    let bad = |why: String| parse_error(path, format!("NIfTI: {why}"));
    let meta = std::fs::metadata(path).map_err(|e| super::file::io_error(path, e))?;
    let header = nifti::NiftiHeader::from_file(path).map_err(|e| bad(nifti_message(e)))?;
    if &header.magic != b"n+1\0" {
        return Err(bad(format!(
            "magic {:?} is not a single-file NIfTI-1 image (\"n+1\"); .hdr/.img pairs and \
             NIfTI-2 are not read: convert to a .nii file",
            String::from_utf8_lossy(&header.magic)
        )));
    }
    let dims = spatial_dims(&header.dim).map_err(&bad)?;
    let count: usize = dims.iter().product();
    let dtype = header
        .data_type()
        .map_err(|e| bad(format!("unknown data type code {}: {e}", header.datatype)))?;
    // Refuse a truncated uncompressed file before the reader allocates for it.
    let gz = path.to_string_lossy().to_ascii_lowercase().ends_with(".gz");
    let need = (header.vox_offset.max(352.0) as u64)
        .saturating_add((count as u64).saturating_mul(dtype.size_of() as u64));
    if !gz && meta.len() < need {
        return Err(bad(format!(
            "the file is truncated: {} bytes, the header's {dims:?} voxels of {dtype:?} need {need}",
            meta.len()
        )));
    }
    let (spacing, origin, flips) = nifti_geometry(&header, &bad).map_err(|e| in_file(path, e))?;
    let object = nifti::ReaderOptions::new()
        .read_file(path)
        .map_err(|e| bad(nifti_message(e)))?;
    let volume = object.into_volume();
    let raw = typed(volume, dtype).map_err(&bad)?;
    let (slope, inter) = (f64::from(header.scl_slope), f64::from(header.scl_inter));
    let scaled = slope != 0.0 && (slope != 1.0 || inter != 0.0);
    let raw = match (raw, scaled) {
        (raw, false) => raw,
        (Raw::Int(v), true) => {
            Raw::Float(v.into_iter().map(|x| x as f64 * slope + inter).collect())
        }
        (Raw::Float(v), true) => Raw::Float(v.into_iter().map(|x| x * slope + inter).collect()),
    };
    let mut values = to_values(raw, opts.values).map_err(&bad)?;
    flip(&mut values, dims, flips);
    let spacing = opts.spacing.unwrap_or(spacing);
    let origin = opts.origin.unwrap_or(origin);
    VoxelImage::new(dims, spacing, origin, values).map_err(|e| in_file(path, e))
}

/// The nifti crate's error as text (its `Display` names the problem; a short read is the
/// usual cause of an I/O error here).
fn nifti_message(e: nifti::NiftiError) -> String {
    match e {
        nifti::NiftiError::Io(io) if io.kind() == std::io::ErrorKind::UnexpectedEof => {
            "the file is truncated (it ends inside the header or the voxel data)".into()
        }
        nifti::NiftiError::IncompatibleLength(got, need) => {
            format!("the file is truncated: {got} bytes of voxel data, the header needs {need}")
        }
        other => other.to_string(),
    }
}

/// The three spatial dimensions of a NIfTI `dim` array: rank 3, or a higher rank whose extra
/// dimensions are all 1 (a single-volume 4D file).
fn spatial_dims(dim: &[u16; 8]) -> Result<[usize; 3], String> {
    let rank = usize::from(dim[0]);
    if !(1..=7).contains(&rank) {
        return Err(format!("dim[0] = {rank} is not a rank between 1 and 7"));
    }
    if rank < 3 || dim[4..=rank.max(3)].iter().any(|&d| d > 1) {
        let shape: Vec<u16> = dim[1..=rank].to_vec();
        return Err(format!(
            "the image has shape {shape:?} ({rank}D); a material image must be 3D (one volume)"
        ));
    }
    let dims = [
        usize::from(dim[1]),
        usize::from(dim[2]),
        usize::from(dim[3]),
    ];
    let count = dims.iter().product::<usize>();
    if count == 0 {
        return Err(format!("the image has shape {dims:?}: it has no voxels"));
    }
    if count > MAX_VOXELS {
        return Err(format!(
            "{dims:?} is more than {MAX_VOXELS} voxels; crop or downsample the image"
        ));
    }
    Ok(dims)
}

/// Spacing (metres, > 0), origin (metres, the centre of the first stored voxel after flips)
/// and the axes to reverse, from the header's sform, qform or pixdim.
/// The qform and pixdim methods need pixdim[1..3] > 0 (the standard's requirement; an
/// orientation flip belongs in the quaternion, qfac or sform).
fn nifti_geometry(
    h: &nifti::NiftiHeader,
    bad: &dyn Fn(String) -> GeometryError,
) -> Result<([f64; 3], Point3, [bool; 3]), GeometryError> {
    let unit = match h.xyzt_units & 0x07 {
        1 => 1.0,
        2 => 1e-3,
        3 => 1e-6,
        _ => 1.0,
    };
    let f = |v: f32| f64::from(v);
    let pixdim = [1, 2, 3].map(|i| f(h.pixdim[i]) * unit);
    if h.sform_code <= 0 && !pixdim.iter().all(|p| p.is_finite() && *p > 0.0) {
        let origin = if h.qform_code > 0 {
            [h.quatern_x, h.quatern_y, h.quatern_z].map(|v| f(v) * unit)
        } else {
            [0.0; 3]
        };
        return Err(GeometryError::ImageSpacing {
            spacing: pixdim,
            origin,
        });
    }
    // Rows of the 3 x 4 voxel-to-world map.
    let rows: [[f64; 4]; 3] = if h.sform_code > 0 {
        [h.srow_x, h.srow_y, h.srow_z].map(|r| r.map(f))
    } else if h.qform_code > 0 {
        let (b, c, d) = (f(h.quatern_b), f(h.quatern_c), f(h.quatern_d));
        let a = (1.0 - (b * b + c * c + d * d)).max(0.0).sqrt();
        let r = [
            [
                a * a + b * b - c * c - d * d,
                2.0 * (b * c - a * d),
                2.0 * (b * d + a * c),
            ],
            [
                2.0 * (b * c + a * d),
                a * a + c * c - b * b - d * d,
                2.0 * (c * d - a * b),
            ],
            [
                2.0 * (b * d - a * c),
                2.0 * (c * d + a * b),
                a * a + d * d - c * c - b * b,
            ],
        ];
        let qfac = if h.pixdim[0] < 0.0 { -1.0 } else { 1.0 };
        let s = [f(h.pixdim[1]), f(h.pixdim[2]), qfac * f(h.pixdim[3])];
        let t = [f(h.quatern_x), f(h.quatern_y), f(h.quatern_z)];
        [0, 1, 2].map(|i| [r[i][0] * s[0], r[i][1] * s[1], r[i][2] * s[2], t[i]])
    } else {
        let p = &h.pixdim;
        [
            [f(p[1]), 0.0, 0.0, 0.0],
            [0.0, f(p[2]), 0.0, 0.0],
            [0.0, 0.0, f(p[3]), 0.0],
        ]
    };
    if let Some(v) = rows.iter().flatten().find(|v| !v.is_finite()) {
        return Err(bad(format!(
            "the voxel-to-world map {rows:?} has a non-finite entry ({v}); fix the header's \
             sform/qform"
        )));
    }
    let scale = (0..3).map(|i| rows[i][i].abs()).fold(0.0, f64::max);
    for (i, row) in rows.iter().enumerate() {
        for (j, &v) in row.iter().take(3).enumerate() {
            // Round-off of a float32 quaternion is ~1e-7 of the scale.
            if i != j && v.abs() > 1e-5 * scale {
                return Err(bad(format!(
                    "the voxel-to-world map {rows:?} rotates or shears the grid; only \
                     axis-aligned images are supported: resample the image onto an axis-aligned \
                     grid"
                )));
            }
        }
    }
    let dims = spatial_dims(&h.dim).map_err(bad)?;
    let mut spacing = [0.0; 3];
    let mut origin = [0.0; 3];
    let mut flips = [false; 3];
    for a in 0..3 {
        let d = rows[a][a] * unit;
        let t = rows[a][3] * unit;
        spacing[a] = d.abs();
        flips[a] = d < 0.0;
        // After reversing a flipped axis, the first voxel is the old last one.
        origin[a] = if flips[a] {
            t + d * (dims[a] - 1) as f64
        } else {
            t
        };
    }
    Ok((spacing, origin, flips))
}

/// The volume's voxels in its own data type, widened.
fn typed(volume: nifti::InMemNiftiVolume, dtype: NiftiType) -> Result<Raw, String> {
    let e = |e: nifti::NiftiError| e.to_string();
    let int = |v: Vec<i64>| Ok(Raw::Int(v));
    match dtype {
        NiftiType::Uint8 => int(widen(volume.into_nifti_typed_data::<u8>().map_err(e)?)),
        NiftiType::Int8 => int(widen(volume.into_nifti_typed_data::<i8>().map_err(e)?)),
        NiftiType::Uint16 => int(widen(volume.into_nifti_typed_data::<u16>().map_err(e)?)),
        NiftiType::Int16 => int(widen(volume.into_nifti_typed_data::<i16>().map_err(e)?)),
        NiftiType::Uint32 => int(widen(volume.into_nifti_typed_data::<u32>().map_err(e)?)),
        NiftiType::Int32 => int(widen(volume.into_nifti_typed_data::<i32>().map_err(e)?)),
        NiftiType::Int64 => int(volume.into_nifti_typed_data::<i64>().map_err(e)?),
        NiftiType::Uint64 => {
            let v = volume.into_nifti_typed_data::<u64>().map_err(e)?;
            v.into_iter()
                .map(|x| i64::try_from(x).map_err(|_| format!("label {x} does not fit in i64")))
                .collect::<Result<_, _>>()
                .map(Raw::Int)
        }
        NiftiType::Float32 => Ok(Raw::Float(
            volume
                .into_nifti_typed_data::<f32>()
                .map_err(e)?
                .into_iter()
                .map(f64::from)
                .collect(),
        )),
        NiftiType::Float64 => Ok(Raw::Float(
            volume.into_nifti_typed_data::<f64>().map_err(e)?,
        )),
        other => Err(format!(
            "data type {other:?} is not supported; store labels as integers or moduli as \
             float32/float64"
        )),
    }
}

fn widen<T: Into<i64>>(v: Vec<T>) -> Vec<i64> {
    v.into_iter().map(Into::into).collect()
}

/// Labels or moduli from raw values, as `kind` asks.
fn to_values(raw: Raw, kind: ImageValueKind) -> Result<VoxelValues, String> {
    match (raw, kind) {
        (Raw::Int(v), ImageValueKind::Auto | ImageValueKind::Labels) => Ok(VoxelValues::Labels(v)),
        (Raw::Int(v), ImageValueKind::Moduli) => Ok(VoxelValues::Moduli(
            v.into_iter().map(|x| x as f64).collect(),
        )),
        (Raw::Float(v), ImageValueKind::Auto | ImageValueKind::Moduli) => {
            Ok(VoxelValues::Moduli(v))
        }
        (Raw::Float(v), ImageValueKind::Labels) => {
            let mut out = Vec::with_capacity(v.len());
            for (n, x) in v.into_iter().enumerate() {
                // Whole numbers within i64 convert exactly.
                if x.fract() != 0.0 || !x.is_finite() || x.abs() > 9.0e15 {
                    return Err(format!(
                        "voxel {n} (flat index, x fastest) holds {x}, not a whole-number label"
                    ));
                }
                out.push(x as i64);
            }
            Ok(VoxelValues::Labels(out))
        }
    }
}

/// Reverse the voxels along the flagged axes (x-fastest storage).
fn flip(values: &mut VoxelValues, dims: [usize; 3], flips: [bool; 3]) {
    fn apply<T: Copy>(v: &mut [T], dims: [usize; 3], flips: [bool; 3]) {
        if !flips.iter().any(|&f| f) {
            return;
        }
        let src = v.to_vec();
        let [nx, ny, nz] = dims;
        for k in 0..nz {
            let kk = if flips[2] { nz - 1 - k } else { k };
            for j in 0..ny {
                let jj = if flips[1] { ny - 1 - j } else { j };
                for i in 0..nx {
                    let ii = if flips[0] { nx - 1 - i } else { i };
                    v[i + nx * (j + ny * k)] = src[ii + nx * (jj + ny * kk)];
                }
            }
        }
    }
    match values {
        VoxelValues::Labels(v) => apply(v, dims, flips),
        VoxelValues::Moduli(v) => apply(v, dims, flips),
    }
}

/// Read a NumPy `.npy` image: a 3D array of shape (nx, ny, nz), axis 0 = x, in C or Fortran
/// order; integer or boolean data are labels, floating-point data moduli (unless
/// `opts.values` says otherwise). `opts.spacing` is required; `opts.origin` defaults to 0.
///
/// # Errors
/// As [`read_image`]; also a missing spacing.
pub fn read_npy(path: &Path, opts: &ImageReadOptions) -> Result<VoxelImage, GeometryError> {
    let bad = |why: String| parse_error(path, format!("NPY: {why}"));
    let Some(spacing) = opts.spacing else {
        return Err(bad(
            "a .npy array has no voxel spacing: give image.spacing = [sx, sy, sz] (metres) in \
             the scene's [object.image] table"
                .into(),
        ));
    };
    let bytes = super::file::read_nonempty(path)?;
    let mut rest: &[u8] = &bytes;
    let header = npyz::NpyHeader::from_reader(&mut rest).map_err(|e| bad(e.to_string()))?;
    let data_bytes = rest.len();
    let npy = npyz::NpyFile::with_header(header, rest);
    let shape = npy.shape().to_vec();
    if shape.len() != 3 {
        return Err(bad(format!(
            "the array has shape {shape:?} ({}D); a material image must be 3D (nx, ny, nz)",
            shape.len()
        )));
    }
    let dims = [0, 1, 2].map(|a| usize::try_from(shape[a]).unwrap_or(usize::MAX));
    let count = dims
        .iter()
        .try_fold(1usize, |acc, &d| acc.checked_mul(d))
        .filter(|&n| n <= MAX_VOXELS)
        .ok_or_else(|| {
            bad(format!(
                "{shape:?} is more than {MAX_VOXELS} voxels; crop or downsample the image"
            ))
        })?;
    if count == 0 {
        return Err(bad(format!(
            "the array has shape {shape:?}: it has no voxels"
        )));
    }
    let npyz::DType::Plain(ts) = npy.dtype() else {
        return Err(bad(
            "structured arrays are not supported; save a plain numeric array".into(),
        ));
    };
    let size = ts.num_bytes().unwrap_or(0);
    if data_bytes < count.saturating_mul(size) {
        return Err(bad(format!(
            "the file is truncated: {data_bytes} bytes of data, shape {shape:?} of {ts} needs {}",
            count.saturating_mul(size)
        )));
    }
    let fortran = matches!(npy.order(), npyz::Order::Fortran);
    let io = |e: std::io::Error| bad(e.to_string());
    use npyz::TypeChar as C;
    let raw = match (ts.type_char(), size) {
        (C::Bool, 1) => Raw::Int(
            npy.into_vec::<bool>()
                .map_err(io)?
                .into_iter()
                .map(i64::from)
                .collect(),
        ),
        (C::Int, 1) => Raw::Int(widen(npy.into_vec::<i8>().map_err(io)?)),
        (C::Int, 2) => Raw::Int(widen(npy.into_vec::<i16>().map_err(io)?)),
        (C::Int, 4) => Raw::Int(widen(npy.into_vec::<i32>().map_err(io)?)),
        (C::Int, 8) => Raw::Int(npy.into_vec::<i64>().map_err(io)?),
        (C::Uint, 1) => Raw::Int(widen(npy.into_vec::<u8>().map_err(io)?)),
        (C::Uint, 2) => Raw::Int(widen(npy.into_vec::<u16>().map_err(io)?)),
        (C::Uint, 4) => Raw::Int(widen(npy.into_vec::<u32>().map_err(io)?)),
        (C::Float, 4) => Raw::Float(
            npy.into_vec::<f32>()
                .map_err(io)?
                .into_iter()
                .map(f64::from)
                .collect(),
        ),
        (C::Float, 8) => Raw::Float(npy.into_vec::<f64>().map_err(io)?),
        _ => {
            return Err(bad(format!(
                "data type {ts} is not supported; store labels as integers or moduli as \
                 float32/float64"
            )))
        }
    };
    let raw = if fortran {
        raw
    } else {
        // C order: [i, j, k] is at (i ny + j) nz + k; store x fastest.
        let [nx, ny, nz] = dims;
        let reorder = |n: usize| {
            let (i, j, k) = (n % nx, (n / nx) % ny, n / (nx * ny));
            (i * ny + j) * nz + k
        };
        match raw {
            Raw::Int(v) => Raw::Int((0..count).map(|n| v[reorder(n)]).collect()),
            Raw::Float(v) => Raw::Float((0..count).map(|n| v[reorder(n)]).collect()),
        }
    };
    let values = to_values(raw, opts.values).map_err(&bad)?;
    VoxelImage::new(dims, spacing, opts.origin.unwrap_or([0.0; 3]), values)
        .map_err(|e| in_file(path, e))
}
