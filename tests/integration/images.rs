//! Voxel-image shapes and materials (issue #19 part 2), against independent references:
//! NIfTI and `.npy` files written byte by byte here (not by the readers' crates) read back
//! with the values, spacing and origin the bytes say; an image's materials equal the region
//! overrides that describe the same object; a homogeneous image equals the plain box.

use freeform::geometry::{Shape, VoxelImage, VoxelValues};
use freeform::io::image::{read_image, ImageReadOptions, ImageValueKind};
use freeform::material::{Material, MaterialOverride, Region};
use freeform::precompute::sampling::Resolution;
use freeform::precompute::{BasisOptions, GapPolicy, ImageMaterial, Problem};
use freeform::progress::Silent;
use freeform::scene::{RunSettings, Scene};
use freeform::sparse::to_dense;
use std::collections::BTreeMap;
use std::path::Path;
use std::sync::Arc;

/// NIfTI-1 header fields a test sets (the rest are 0).
struct Header {
    dims: [i16; 3],
    datatype: i16,
    bitpix: i16,
    pixdim: [f32; 4],
    scl: [f32; 2],
    units: u8,
    qform_code: i16,
    sform_code: i16,
    quatern: [f32; 6],
    srow: [[f32; 4]; 3],
}

impl Default for Header {
    fn default() -> Self {
        Self {
            dims: [1, 1, 1],
            datatype: 2,
            bitpix: 8,
            pixdim: [1.0; 4],
            scl: [0.0, 0.0],
            units: 0,
            qform_code: 0,
            sform_code: 0,
            quatern: [0.0; 6],
            srow: [[0.0; 4]; 3],
        }
    }
}

/// A single-file NIfTI-1 image at the offsets of the NIfTI-1 standard (nifti1.h), little
/// endian: 348-byte header, 4-byte extension flag, data from byte 352.
fn nifti_bytes(h: &Header, data: &[u8]) -> Vec<u8> {
    let mut b = vec![0u8; 352];
    let put =
        |b: &mut Vec<u8>, at: usize, bytes: &[u8]| b[at..at + bytes.len()].copy_from_slice(bytes);
    put(&mut b, 0, &348i32.to_le_bytes());
    let dim = [3, h.dims[0], h.dims[1], h.dims[2], 1, 1, 1, 1];
    for (i, d) in dim.iter().enumerate() {
        put(&mut b, 40 + 2 * i, &d.to_le_bytes());
    }
    put(&mut b, 70, &h.datatype.to_le_bytes());
    put(&mut b, 72, &h.bitpix.to_le_bytes());
    for (i, p) in h.pixdim.iter().enumerate() {
        put(&mut b, 76 + 4 * i, &p.to_le_bytes());
    }
    put(&mut b, 108, &352f32.to_le_bytes());
    put(&mut b, 112, &h.scl[0].to_le_bytes());
    put(&mut b, 116, &h.scl[1].to_le_bytes());
    b[123] = h.units;
    put(&mut b, 252, &h.qform_code.to_le_bytes());
    put(&mut b, 254, &h.sform_code.to_le_bytes());
    for (i, q) in h.quatern.iter().enumerate() {
        put(&mut b, 256 + 4 * i, &q.to_le_bytes());
    }
    for (r, row) in h.srow.iter().enumerate() {
        for (i, v) in row.iter().enumerate() {
            put(&mut b, 280 + 16 * r + 4 * i, &v.to_le_bytes());
        }
    }
    put(&mut b, 344, b"n+1\0");
    b.extend_from_slice(data);
    b
}

/// Every voxel of the file (x fastest), with its world position under the voxel-to-world map
/// `world` (metres), is found by the image at that position with the file's value.
fn assert_world_lookup(
    img: &VoxelImage,
    dims: [usize; 3],
    world: impl Fn([f64; 3]) -> [f64; 3],
    value: impl Fn(usize) -> f64,
) {
    let mut n = 0;
    for k in 0..dims[2] {
        for j in 0..dims[1] {
            for i in 0..dims[0] {
                let x = world([i as f64, j as f64, k as f64]);
                let v = img
                    .voxel_at(&x)
                    .unwrap_or_else(|| panic!("file voxel [{i}, {j}, {k}] at {x:?} not found"));
                let got = match img.values() {
                    VoxelValues::Labels(l) => l[v] as f64,
                    VoxelValues::Moduli(e) => e[v],
                };
                assert_eq!(got, value(n), "file voxel [{i}, {j}, {k}]");
                n += 1;
            }
        }
    }
}

/// Equal within `rel` of the larger magnitude.
fn close(a: [f64; 3], b: [f64; 3], rel: f64) -> bool {
    (0..3).all(|i| (a[i] - b[i]).abs() <= rel * a[i].abs().max(b[i].abs()).max(1e-300))
}

#[test]
fn nifti_sform_with_a_flip_in_millimetres_reads_back_exactly() {
    let dir = tempfile::tempdir().unwrap();
    let dims = [3usize, 2, 2];
    let values: Vec<i16> = (0..12).map(|n| 100 + 7 * n as i16).collect();
    let data: Vec<u8> = values.iter().flat_map(|v| v.to_le_bytes()).collect();
    // x runs backwards (a flip), millimetres.
    let h = Header {
        dims: [3, 2, 2],
        datatype: 4,
        bitpix: 16,
        units: 2,
        sform_code: 1,
        srow: [
            [-2.0, 0.0, 0.0, 10.0],
            [0.0, 3.0, 0.0, -5.0],
            [0.0, 0.0, 4.0, 1.0],
        ],
        ..Header::default()
    };
    let path = dir.path().join("sform.nii");
    std::fs::write(&path, nifti_bytes(&h, &data)).unwrap();
    let img = read_image(&path, &ImageReadOptions::default()).unwrap();
    assert_eq!(img.dims(), dims);
    assert!(matches!(img.values(), VoxelValues::Labels(_)));
    // f32 header numbers times 1e-3: one rounding, so 1e-15 relative.
    assert!(
        close(img.spacing(), [0.002, 0.003, 0.004], 1e-15),
        "{:?}",
        img.spacing()
    );
    // The first stored voxel after the flip is file voxel x = 2: 10 - 2 * 2 = 6 mm.
    assert!(
        close(img.origin(), [0.006, -0.005, 0.001], 1e-15),
        "{:?}",
        img.origin()
    );
    let world = |v: [f64; 3]| {
        [
            (10.0 - 2.0 * v[0]) * 1e-3,
            (-5.0 + 3.0 * v[1]) * 1e-3,
            (1.0 + 4.0 * v[2]) * 1e-3,
        ]
    };
    assert_world_lookup(&img, dims, world, |n| f64::from(values[n]));
}

#[test]
fn nifti_qform_rotation_by_half_turn_and_qfac_flip_reads_back_exactly() {
    let dir = tempfile::tempdir().unwrap();
    let dims = [2usize, 3, 2];
    let values: Vec<f32> = (0..12).map(|n| 1e5 * (1.0 + n as f32)).collect();
    let data: Vec<u8> = values.iter().flat_map(|v| v.to_le_bytes()).collect();
    // Quaternion (0, 0, 1): half a turn about z, R = diag(-1, -1, 1); qfac = -1 flips z too.
    let h = Header {
        dims: [2, 3, 2],
        datatype: 16,
        bitpix: 32,
        pixdim: [-1.0, 0.5, 0.25, 2.0],
        units: 1,
        qform_code: 1,
        quatern: [0.0, 0.0, 1.0, 1.0, 2.0, 3.0],
        ..Header::default()
    };
    let path = dir.path().join("qform.nii");
    std::fs::write(&path, nifti_bytes(&h, &data)).unwrap();
    let img = read_image(&path, &ImageReadOptions::default()).unwrap();
    assert!(matches!(img.values(), VoxelValues::Moduli(_)));
    // Exact: every number here is a short binary fraction.
    assert_eq!(img.spacing(), [0.5, 0.25, 2.0]);
    assert_eq!(img.origin(), [1.0 - 0.5, 2.0 - 0.5, 3.0 - 2.0]);
    let world = |v: [f64; 3]| [1.0 - 0.5 * v[0], 2.0 - 0.25 * v[1], 3.0 - 2.0 * v[2]];
    assert_world_lookup(&img, dims, world, |n| f64::from(values[n]));
}

#[test]
fn nifti_pixdim_only_with_scaling_reads_back_exactly() {
    let dir = tempfile::tempdir().unwrap();
    let dims = [2usize, 2, 3];
    let values: Vec<f64> = (0..12).map(|n| 0.25 * n as f64).collect();
    let data: Vec<u8> = values.iter().flat_map(|v| v.to_le_bytes()).collect();
    // No qform or sform: pixdim spacing, origin 0; moduli = 4 x stored + 8 (scl_slope/inter).
    let h = Header {
        dims: [2, 2, 3],
        datatype: 64,
        bitpix: 64,
        pixdim: [1.0, 0.125, 0.5, 0.75],
        scl: [4.0, 8.0],
        ..Header::default()
    };
    let path = dir.path().join("pixdim.nii");
    std::fs::write(&path, nifti_bytes(&h, &data)).unwrap();
    let img = read_image(&path, &ImageReadOptions::default()).unwrap();
    assert_eq!(img.spacing(), [0.125, 0.5, 0.75]);
    assert_eq!(img.origin(), [0.0; 3]);
    let world = |v: [f64; 3]| [0.125 * v[0], 0.5 * v[1], 0.75 * v[2]];
    assert_world_lookup(&img, dims, world, |n| 4.0 * values[n] + 8.0);
    // The scene may replace the geometry.
    let moved = read_image(
        &path,
        &ImageReadOptions {
            spacing: Some([1.0, 2.0, 3.0]),
            origin: Some([-1.0, 0.0, 1.0]),
            values: ImageValueKind::Auto,
        },
    )
    .unwrap();
    assert_eq!(
        (moved.spacing(), moved.origin()),
        ([1.0, 2.0, 3.0], [-1.0, 0.0, 1.0])
    );
}

/// A version-1.0 `.npy` file: magic, header length, the header dict padded to 64 bytes.
fn npy_bytes(descr: &str, fortran: bool, shape: [usize; 3], data: &[u8]) -> Vec<u8> {
    let dict = format!(
        "{{'descr': '{descr}', 'fortran_order': {}, 'shape': ({}, {}, {}), }}",
        if fortran { "True" } else { "False" },
        shape[0],
        shape[1],
        shape[2]
    );
    let mut header = dict.into_bytes();
    while (10 + header.len() + 1) % 64 != 0 {
        header.push(b' ');
    }
    header.push(b'\n');
    let mut b = b"\x93NUMPY\x01\x00".to_vec();
    b.extend_from_slice(&(header.len() as u16).to_le_bytes());
    b.extend_from_slice(&header);
    b.extend_from_slice(data);
    b
}

#[test]
fn npy_in_c_and_fortran_order_reads_back_exactly() {
    let dir = tempfile::tempdir().unwrap();
    let shape = [3usize, 2, 4];
    let f = |i: usize, j: usize, k: usize| 1000.0 * i as f64 + 10.0 * j as f64 + k as f64 + 0.5;
    // C order: the last axis (z) fastest.
    let mut c = Vec::new();
    for i in 0..3 {
        for j in 0..2 {
            for k in 0..4 {
                c.extend_from_slice(&f(i, j, k).to_le_bytes());
            }
        }
    }
    let path = dir.path().join("c.npy");
    std::fs::write(&path, npy_bytes("<f8", false, shape, &c)).unwrap();
    let opts = ImageReadOptions {
        spacing: Some([0.5, 0.25, 0.125]),
        origin: Some([1.0, 2.0, 3.0]),
        values: ImageValueKind::Auto,
    };
    let img = read_image(&path, &opts).unwrap();
    assert_eq!(img.dims(), shape);
    let VoxelValues::Moduli(e) = img.values() else {
        panic!("float data are moduli");
    };
    for i in 0..3 {
        for j in 0..2 {
            for k in 0..4 {
                assert_eq!(e[img.index([i, j, k])], f(i, j, k), "[{i}, {j}, {k}]");
                let x = [
                    1.0 + 0.5 * i as f64,
                    2.0 + 0.25 * j as f64,
                    3.0 + 0.125 * k as f64,
                ];
                assert_eq!(img.voxel_at(&x), Some(img.index([i, j, k])));
            }
        }
    }
    // Fortran order, unsigned bytes: labels, x fastest.
    let mut fo = Vec::new();
    for k in 0..4 {
        for j in 0..2 {
            for i in 0..3 {
                fo.push((1 + i + 3 * j + 6 * k) as u8);
            }
        }
    }
    let path = dir.path().join("f.npy");
    std::fs::write(&path, npy_bytes("|u1", true, shape, &fo)).unwrap();
    let img = read_image(&path, &opts).unwrap();
    let VoxelValues::Labels(l) = img.values() else {
        panic!("integer data are labels");
    };
    for k in 0..4 {
        for j in 0..2 {
            for i in 0..3 {
                assert_eq!(l[img.index([i, j, k])], (1 + i + 3 * j + 6 * k) as i64);
            }
        }
    }
    assert_eq!(img.origin(), [1.0, 2.0, 3.0]);
}

fn material(youngs: f64, poisson: f64, density: f64) -> Material {
    Material {
        youngs,
        poisson,
        density,
    }
}

/// The 2 x 1 x 1 m box as 16 x 8 x 8 voxels of 1/8 m (binary fractions, so the image's
/// bounds, volume and voxel faces are exact), `label(i)` along x.
fn box_image(values: impl Fn(usize) -> (i64, f64), moduli: bool) -> Arc<VoxelImage> {
    let (mut l, mut e) = (Vec::new(), Vec::new());
    for _k in 0..8 {
        for _j in 0..8 {
            for i in 0..16 {
                let (label, youngs) = values(i);
                l.push(label);
                e.push(youngs);
            }
        }
    }
    let v = if moduli {
        VoxelValues::Moduli(e)
    } else {
        VoxelValues::Labels(l)
    };
    Arc::new(VoxelImage::new([16, 8, 8], [0.125; 3], [0.0625; 3], v).unwrap())
}

/// Options for a small basis: spacing 1/24 m puts every grid point strictly inside a voxel
/// (cell centres at (i + 1/2)/24, voxel faces at multiples of 3/24), the interface x = 1
/// included.
fn small_opts(base: Material) -> BasisOptions {
    BasisOptions {
        kernels: 60,
        modes: 4,
        resolution: Some(Resolution::Spacing(1.0 / 24.0)),
        material: base,
        ..BasisOptions::default()
    }
}

/// H_w and M of two problems agree to `rel` of their largest entry, and so do their points
/// and per-point materials (exactly).
fn assert_same_problem(a: &Problem, b: &Problem, rel: f64) {
    assert_eq!(a.points().points, b.points().points);
    assert_eq!(a.points().volumes, b.points().volumes);
    assert_eq!(a.material(), b.material());
    for (name, x, y) in [
        ("H_w", a.matrices().hessian(), b.matrices().hessian()),
        ("M", a.matrices().mass(), b.matrices().mass()),
    ] {
        let (dx, dy) = (to_dense(x.as_ref()), to_dense(y.as_ref()));
        let scale = dx.norm_max();
        let diff = (&dx - &dy).norm_max();
        assert!(
            diff <= rel * scale,
            "{name}: max difference {diff:e} of {scale:e}"
        );
    }
}

#[test]
fn two_material_image_equals_the_box_with_a_region_override() {
    let (stiff, soft) = (material(1e9, 0.3, 2000.0), material(1e5, 0.45, 1000.0));
    // Reference: a soft box with a stiff override on x <= 1.
    let reference = BasisOptions {
        overrides: vec![MaterialOverride {
            region: Region::Box {
                min: [-1.0; 3],
                max: [1.0, 2.0, 2.0],
            },
            material: stiff,
        }],
        ..small_opts(soft)
    };
    let boxed = Problem::from_shape(
        &Shape::Box {
            size: [2.0, 1.0, 1.0],
        },
        &reference,
        &Silent,
    )
    .unwrap();
    // The image knows nothing of the override: voxels with i < 8 (x < 1) are label 1.
    let labels = box_image(|i| (if i < 8 { 1 } else { 2 }, 0.0), false);
    let map = BTreeMap::from([(1, stiff), (2, soft)]);
    let opts = BasisOptions {
        image: Some(ImageMaterial::new(labels.clone(), map, GapPolicy::Error).unwrap()),
        ..small_opts(soft)
    };
    let imaged = Problem::from_shape(&Shape::Image(labels.clone()), &opts, &Silent).unwrap();
    // Both material fields mix the two materials, so the test can see a wrong lookup.
    let youngs = &imaged.material().youngs;
    assert!(youngs.contains(&1e9) && youngs.contains(&1e5));
    // Same points and materials give the same arithmetic: the matrices agree to round-off
    // (1e-13 of the largest entry; they are expected bit for bit).
    assert_same_problem(&boxed, &imaged, 1e-13);
    // A modulus image with the object's nu and rho: equal when the reference uses them too.
    let (stiff_nu, soft_nu) = (material(1e9, 0.45, 1000.0), soft);
    let reference = BasisOptions {
        overrides: vec![MaterialOverride {
            material: stiff_nu,
            ..reference.overrides[0]
        }],
        ..small_opts(soft_nu)
    };
    let boxed = Problem::from_shape(
        &Shape::Box {
            size: [2.0, 1.0, 1.0],
        },
        &reference,
        &Silent,
    )
    .unwrap();
    let moduli = box_image(|i| (0, if i < 8 { 1e9 } else { 1e5 }), true);
    // No label map: a modulus image shape gives its own moduli.
    let imaged = Problem::from_shape(&Shape::Image(moduli), &small_opts(soft_nu), &Silent).unwrap();
    assert_same_problem(&boxed, &imaged, 1e-13);
    // The image as a material map only, on the box shape.
    let on_box = Problem::from_shape(
        &Shape::Box {
            size: [2.0, 1.0, 1.0],
        },
        &opts,
        &Silent,
    )
    .unwrap();
    let reference = Problem::from_shape(
        &Shape::Box {
            size: [2.0, 1.0, 1.0],
        },
        &BasisOptions {
            overrides: vec![MaterialOverride {
                region: Region::Box {
                    min: [-1.0; 3],
                    max: [1.0, 2.0, 2.0],
                },
                material: stiff,
            }],
            ..small_opts(soft)
        },
        &Silent,
    )
    .unwrap();
    assert_same_problem(&reference, &on_box, 1e-13);
}

#[test]
fn homogeneous_image_equals_the_plain_box() {
    let m = material(3e6, 0.4, 1200.0);
    let boxed = Problem::from_shape(
        &Shape::Box {
            size: [2.0, 1.0, 1.0],
        },
        &small_opts(m),
        &Silent,
    )
    .unwrap();
    let img = box_image(|_| (5, 0.0), false);
    let opts = BasisOptions {
        image: Some(
            ImageMaterial::new(img.clone(), BTreeMap::from([(5, m)]), GapPolicy::Error).unwrap(),
        ),
        ..small_opts(material(1.0, 0.0, 1.0))
    };
    let imaged = Problem::from_shape(&Shape::Image(img), &opts, &Silent).unwrap();
    assert_same_problem(&boxed, &imaged, 1e-13);
}

/// The example scene reads its committed image, maps every label, and simulates (a few
/// steps at reduced size: the full run is the example's).
#[test]
fn ct_phantom_example_runs() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("examples");
    let mut scene = Scene::load(&dir.join("ct_phantom.toml")).unwrap();
    scene.simulation.steps = 3;
    scene.cache.enabled = false;
    scene.objects[0].basis.kernels = 150;
    scene.objects[0].basis.modes = 6;
    let tmp = tempfile::tempdir().unwrap();
    let summary = freeform::scene::run(
        &scene,
        &RunSettings {
            base_dir: dir,
            out: Some(tmp.path().join("frames")),
            strict: false,
        },
        &Silent,
    )
    .unwrap();
    let o = &summary.objects[0];
    assert_eq!(o.shape, "image");
    assert!(o.min_det > 0.0);
}
