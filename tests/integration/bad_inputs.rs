//! Bad input on every path (issue #6, part 3): the CLI (`modes`, `run`, `export`,
//! `modes --from-matrices`) and the library API, driven by the committed corpus in
//! `tests/data/bad/` (written by its `make.py`). Every case must exit non-zero within a few
//! seconds, print a specific message, never panic, and leave no `--out` file behind.
//!
//! The second half replays the fuzzing seed corpus and every fuzzer finding
//! (`fuzz/corpus/<target>/`, see docs/fuzzing.md) through the same parse functions the fuzz
//! targets call, on stable, so a fixed crash stays fixed.

use freeform::geometry::{GeometryError, PointCloud, ShapeOptions, TriMesh};
use freeform::io::matrix_market::read_matrix_market_from;
use freeform::io::read_shape;
use freeform::io::{obj, ply, stl};
use freeform::precompute::BasisOptions;
use freeform::scene::{RunSettings, Scene};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// Small sizes so a case that wrongly succeeds still finishes fast.
const SMALL: &[&str] = &["--kernels", "50", "--modes", "4", "--points", "2000"];

/// Longest a bad input may take to be rejected (the binary is optimized in the test profile;
/// huge requests must fail before allocating, not after).
const DEADLINE: Duration = Duration::from_secs(20);

/// One CLI case: arguments (`@rel` is a path in the corpus copy), expected phrase in stderr
/// (case-insensitive). `--out` is appended by [`run_case`].
type Case = (&'static [&'static str], &'static str);

#[rustfmt::skip]
const MODES_FILES: &[Case] = &[
    // PLY
    (&["@ply/empty.ply"], "empty file"),
    (&["@ply/garbage.ply"], "garbage.ply: PLY"),
    (&["@ply/header_only.ply"], "header_only.ply: PLY"),
    (&["@ply/no_end_header.ply"], "no_end_header.ply: PLY"),
    (&["@ply/truncated_ascii.ply"], "expected 8, got 3"),
    (&["@ply/truncated_binary.ply"], "truncated_binary.ply: PLY"),
    (&["@ply/nan_ascii.ply"], "nan_ascii.ply: PLY line 11: vertex 1 has a non-finite coordinate x = 'nan'; remove or fix that vertex"),
    (&["@ply/inf_binary.ply"], "inf_binary.ply: PLY vertex 1 has a non-finite coordinate y = inf; remove or fix that vertex"),
    (&["@ply/nan_binary.ply"], "nan_binary.ply: PLY vertex 2 has a non-finite coordinate z = NaN; remove or fix that vertex"),
    (&["@ply/missing_z.ply"], "no `z` property"),
    (&["@ply/face_out_of_range.ply"], "face 11 refers to vertex 99, but the file has 8 vertices"),
    (&["@ply/face_negative_index.ply"], "face 11 refers to vertex -7"),
    (&["@ply/face_two_vertices.ply"], "face 11 has 2 vertices, needs at least 3"),
    (&["@ply/too_few_faces.ply"], "expected 20, got 12"),
    (&["@ply/too_many_vertices_declared.ply"], "too_many_vertices_declared.ply: PLY"),
    (&["@ply/huge_vertex_count.ply"], "expected 1000000000000000, got 8"),
    (&["@ply/open_mesh.ply"], "not watertight (4 boundary edges"),
    (&["@ply/flat_mesh.ply"], "encloses no volume"),
    (&["@ply/huge_coordinates.ply"], "coordinates are too large"),
    (&["@ply/no_vertices.ply"], "point cloud has no points"),
    (&["@ply/coincident_points.ply"], "all points coincide"),
    (&["@ply/huge_point_cloud.ply"], "rescale the point cloud"),
    (&["@ply/tiny_point_cloud.ply"], "rescale the point cloud"),
    // Voxel images (NIfTI, .npy)
    (&["@image/zero_spacing.nii"], "zero_spacing.nii: voxel spacing [0.10000000149011612, 0.0, 0.10000000149011612] m"),
    (&["@image/negative_spacing.nii"], "negative_spacing.nii: voxel spacing [0.10000000149011612, 0.10000000149011612, -0.10000000149011612] m"),
    (&["@image/nan_spacing.nii"], "nan_spacing.nii: voxel spacing [NaN,"),
    (&["@image/zero_sform.nii"], "zero_sform.nii: voxel spacing [0.10000000149011612, 0.0,"),
    (&["@image/rotated.nii"], "rotates or shears the grid"),
    (&["@image/nan_sform.nii"], "nan_sform.nii: NIfTI: the voxel-to-world map [[0.10000000149011612, NaN, 0.0, 0.0]"),
    (&["@image/nan_modulus.nii"], "nan_modulus.nii: voxel [1, 0, 0] has Young's modulus NaN Pa"),
    (&["@image/negative_modulus.nii"], "negative_modulus.nii: voxel [0, 1, 1] has Young's modulus -200000 Pa"),
    (&["@image/two_d.nii"], "two_d.nii: NIfTI: the image has shape [4, 4] (2D); a material image must be 3D"),
    (&["@image/four_d.nii"], "four_d.nii: NIfTI: the image has shape [2, 2, 2, 3] (4D); a material image must be 3D"),
    (&["@image/truncated.nii"], "truncated.nii: NIfTI: the file is truncated: 362 bytes"),
    (&["@image/truncated_header.nii"], "truncated_header.nii: NIfTI: the file is truncated"),
    (&["@image/empty.nii"], "empty.nii: voxel image: the [2, 2, 2] image has no filled voxel"),
    (&["@image/zero_dims.nii"], "zero_dims.nii: NIfTI: the image has shape [2, 0, 2]: it has no voxels"),
    (&["@image/complex.nii"], "complex.nii: NIfTI: data type Complex64 is not supported"),
    (&["@image/labels.npy"], "labels.npy: NPY: a .npy array has no voxel spacing"),
    // OBJ
    (&["@obj/empty.obj"], "empty.obj: empty file"),
    (&["@obj/binary.obj"], "not a text OBJ file"),
    (&["@obj/words.obj"], "no faces (0 vertices)"),
    (&["@obj/no_faces.obj"], "no faces (8 vertices)"),
    (&["@obj/face_out_of_range.obj"], "line 20: face refers to vertex 9, but only 8 are defined"),
    (&["@obj/nan_vertex.obj"], "line 8: non-finite vertex coordinate `nan`"),
    (&["@obj/short_vertex.obj"], "line 1: vertex needs 3 coordinates, got 2"),
    (&["@obj/open_box.obj"], "not watertight"),
    (&["@obj/misoriented.obj"], "orientation is inconsistent"),
    (&["@obj/flat.obj"], "encloses no volume"),
    (&["@obj/huge_coordinates.obj"], "coordinates are too large"),
    // OFF
    (&["@off/garbled_header.off"], "garbled_header.off: OFF line 1: missing or garbled header"),
    (&["@off/too_few_faces.off"], "the file ends after 12 of the 14 faces the counts line (line 2) declares"),
    (&["@off/face_out_of_range.off"], "OFF line 22: face 11 refers to vertex 8, but the file has 8 vertices"),
    (&["@off/nan_vertex.off"], "OFF line 10: vertex 7 has a non-finite coordinate y = `nan`"),
    (&["@off/trailing_garbage.off"], "OFF line 23: unexpected content `3 0 1 2`"),
    (&["@off/open_box.off"], "not watertight"),
    // STL
    (&["@stl/empty.stl"], "empty.stl: empty file"),
    (&["@stl/short.stl"], "too short for a binary STL"),
    (&["@stl/garbage.stl"], "garbage.stl"),
    (&["@stl/truncated_binary.stl"], "truncated binary STL: the header declares 12 triangles"),
    (&["@stl/trailing_binary.stl"], "trailing data"),
    (&["@stl/huge_count_binary.stl"], "declares 4294967295 triangles"),
    (&["@stl/nan_binary.stl"], "STL triangle 11 has a non-finite coordinate"),
    (&["@stl/open_binary.stl"], "not watertight"),
    (&["@stl/bad_ascii.stl"], "bad_ascii.stl"),
    (&["@stl/no_triangles.stl"], "no triangles"),
    // Shape specs and paths
    (&["@does/not/exist.ply"], "exist.ply"),
    (&["@ply"], "unknown shape"),
    (&["box:-1,1,1"], "`-1` is not positive"),
    (&["box:0,1,1"], "`0` is not positive"),
    (&["box:1e300,1,1"], "`1e300` is out of range"),
    (&["sphere:1e-300"], "`1e-300` is out of range"),
    (&["box:inf,1,1"], "`inf` is not finite"),
    (&["box:1,1"], "too few numbers"),
    (&["cylinder:1,2"], "unknown shape"),
];

#[rustfmt::skip]
const MODES_FLAGS: &[Case] = &[
    (&["box:1,1,1", "--kernels", "1000000000000"], "more than 10000000 kernels"),
    (&["box:1,1,1", "--kernels", "18446744073709551615", "--modes", "4"], "kernels"),
    (&["box:1,1,1", "--kernels", "1e12"], "invalid value '1e12' for '--kernels"),
    (&["box:1,1,1", "--kernels", "-5"], "--kernels"),
    (&["box:1,1,1", "--kernels", "50", "--points", "1000000000000"], "more than 100000000 integration points"),
    (&["box:1,1,1", "--kernels", "50", "--modes", "18446744073709551615"], "m must be smaller than K - 1"),
    (&["box:1,1,1", "--kernels", "50", "--spacing", "1e-7"], "grid cells"),
    (&["box:1,1,1", "--kernels", "50", "--spacing", "nan"], "spacing"),
    (&["box:1,1,1", "--kernels", "50", "--support", "inf"], "support factor"),
    (&["box:1,1,1", "--kernels", "50", "--support", "1e300"], "must be at most 50"),
    (&["box:1,1,1", "--kernels", "50", "--support-neighbor", "0"], "support neighbor"),
    (&["box:1,1,1", "--kernels", "50", "--support-neighbor", "1000"], "need more than 1000 kernels"),
    (&["box:1,1,1", "--youngs", "nan"], "youngs"),
    (&["box:1,1,1", "--youngs", "inf"], "youngs"),
    (&["box:1,1,1", "--kernels", "50", "--points", "2000", "--youngs", "1e308"], "invalid youngs = 1e308: Young's modulus must be a positive number of pascals, at most 1e100"),
    (&["box:1,1,1", "--density", "-1"], "density"),
    (&["box:1,1,1", "--poisson", "nan"], "poisson"),
    (&["box:1,1,1", "--tol", "nan"], "tol"),
    (&["box:1,1,1", "--max-iter", "0"], "max_iter"),
    (&["box:1,1,1", "--threads", "0"], "--threads must be at least 1"),
    (&["box:1,1,1", "--threads", "1000000"], "more than 1024"),
    (&["@ply/coincident_points.ply", "--voxel", "-1"], "voxel"),
    // Both the file and the volume are bad: the options are checked before any file is read.
    (&["@ply/inf_binary.ply", "--volume", "0"], "invalid volume = 0"),
    (&["--kernels", "50"], "required"),
];

#[rustfmt::skip]
const RUN_SCENES: &[Case] = &[
    (&["@scene/empty.toml"], "missing field `simulation`"),
    (&["@scene/garbage.toml"], "garbage.toml"),
    (&["@scene/not_toml.toml"], "line 1"),
    (&["@scene/unknown_top_key.toml"], "unknown field `rendering`"),
    (&["@scene/unknown_object_key.toml"], "unknown field `kernals`"),
    (&["@scene/wrong_type_steps.toml"], "invalid type: string \"two\""),
    (&["@scene/negative_steps.toml"], "steps"),
    (&["@scene/negative_dt.toml"], "simulation.dt = -0.01 must be a positive number of seconds"),
    (&["@scene/nan_dt.toml"], "simulation.dt = NaN"),
    (&["@scene/inf_gravity.toml"], "gravity"),
    (&["@scene/missing_simulation.toml"], "missing field `simulation`"),
    (&["@scene/no_objects.toml"], "no [[object]]"),
    (&["@scene/duplicate_names.toml"], "two objects are named 'bar'"),
    (&["@scene/bad_name.toml"], "object name '../escape'"),
    (&["@scene/negative_box.toml"], "`-1` is not positive"),
    (&["@scene/huge_box.toml"], "`1e300` is out of range"),
    (&["@scene/missing_mesh.toml"], "does_not_exist.obj"),
    (&["@scene/huge_kernels.toml"], "more than 10000000 kernels"),
    (&["@scene/huge_points.toml"], "more than 100000000 integration points"),
    (&["@scene/huge_steps.toml"], "simulation.steps = 1000000000000 is more than 10000000"),
    (&["@scene/negative_youngs.toml"], "youngs"),
    (&["@scene/bad_poisson.toml"], "poisson"),
    (&["@scene/zero_every.toml"], "output.every must be at least 1"),
    (&["@scene/bad_format.toml"], "unknown variant `gif`"),
    (&["@scene/bad_hessian.toml"], "unknown variant `magic`"),
    (&["@scene/nan_placement.toml"], "object[0].placement.translation[0] = NaN is not a number"),
    (&["@scene/nan_boundary_region.toml"], "object[0].boundary[0].region.sphere.center[0] = NaN"),
    (&["@scene/zero_normal_boundary.toml"], "finite non-zero normal"),
    (&["@scene/overlapping_boundaries.toml"], "boundary regions = 0 and 1: overlap"),
    (&["@scene/boundary_covers_object.toml"], "cover (nearly) the whole object"),
    (&["@scene/bad_boundaries_mode.toml"], "unknown variant `sometimes`"),
    (&["@scene/negative_stiffness.toml"], "stiffness (Pa/m^2) must be positive"),
    (&["@scene/inverted_region_material.toml"], "a box needs min <= max"),
    (&["@scene/huge_youngs.toml"], "object[0].material.youngs = 1e308 is out of range"),
    (&["@scene/zero_normal_collider.toml"], "a plane needs a finite point and a non-zero normal"),
    (&["@scene/collider_open_solid.toml"], "open_box.obj: a solid collider mesh must be closed"),
    (&["@scene/collider_open_off.toml"], "open_box.off: a solid collider mesh must be closed"),
    (&["@scene/collider_degenerate.toml"], "collider_flat.obj: triangle 1 (0-based, in the file's triangle order) has zero area"),
    (&["@scene/collider_point_cloud.toml"], "collider_points.ply: the PLY file has no faces"),
    (&["@scene/collider_missing_mesh.toml"], "nowhere_collider.stl"),
    (&["@scene/collider_zero_radius.toml"], "collider 0 'ball': invalid radius = 0"),
    (&["@scene/collider_nan_pose.toml"], "collider[0].motion.pose.translation[0] = NaN"),
    (&["@scene/collider_bad_parent.toml"], "no collider listed before this one has that name"),
    (&["@scene/contact_overlap.toml"], "objects 'bar' and 'other' start interpenetrating: their surfaces overlap"),
    (&["@scene/contact_inside.toml"], "objects 'other' and 'bar' start interpenetrating: a surface point of 'other'"),
    (&["@scene/contact_negative_stiffness.toml"], "contact.stiffness = -1: the contact penalty stiffness (Pa/m^2) must be positive"),
    (&["@scene/contact_zero_samples.toml"], "invalid contact_samples = 0: an object in contact needs at least one contact sample"),
    (&["@scene/contact_bad_tolerance.toml"], "contact.penetration_tolerance = 2"),
    (&["@scene/contact_self_exclusion.toml"], "contact.self_exclusion = 0.5: the self-contact exclusion is a multiple of the contact distance, above 1"),
    (&["@scene/contact_feature_spacing.toml"], "contact.feature_spacing = -1: the feature samples' spacing along an edge is a fraction of the contact thickness"),
    (&["@scene/contact_huge_radius.toml"], "below half the object's smallest extent"),
    (&["@scene/contact_negative_friction.toml"], "contact.friction = -0.2: a friction coefficient must be >= 0"),
    (&["@scene/contact_nan_friction.toml"], "contact.pair[0].friction = NaN is not a number"),
    (&["@scene/contact_unknown_pair.toml"], "'nobody': names no object and no collider"),
    (&["@scene/contact_negative_pair_friction.toml"], "contact.pair.friction = -1: a friction coefficient must be >= 0"),
    (&["@scene/collider_misoriented.toml"], "misoriented.obj: a solid collider mesh must be closed and consistently oriented, and this one has 0 boundary, 0 non-manifold and"),
    (&["@scene/collider_nan_vertex.toml"], "nan_vertex.obj"),
    (&["@scene/collider_fin_surface.toml"], "collider_fin.obj: a one-sided collider surface needs manifold, consistently oriented triangles (its normals say which side is free), and this one has 1 non-manifold"),
    (&["@scene/contact_unknown_solver.toml"], "unknown variant `sparse`"),
    (&["@scene/does_not_exist.toml"], "does_not_exist.toml"),
    (&["@scene/splats_zero_quat.toml"], "splats_zero_quat.ply: splat PLY element `vertex` 7 property `rot_0..rot_3` = (0, 0, 0, 0) is a zero or non-finite quaternion"),
    (&["@scene/splats_nan_scale.toml"], "splats_nan_scale.ply: splat PLY element `vertex` 3 property `scale_1` = NaN is not finite"),
    (&["@scene/splats_no_rot_2.toml"], "splats_no_rot_2.ply: splat PLY element `vertex` has no property `rot_2`"),
    (&["@scene/render_outside.toml"], "far_render.obj: 3 of its 3 points are not covered by the object's kernels"),
    (&["@scene/render_missing.toml"], "nowhere.obj"),
    (&["@scene/image_unknown_label.toml"], "voxel image label 3 (first at voxel [1, 2, 3]) has no material"),
    (&["@scene/image_unknown_material.toml"], "image label 2 maps to material 'bone', but there is no [materials.bone] table"),
    (&["@scene/image_bad_label_key.toml"], "image.labels key 'one' is not a whole-number label"),
    (&["@scene/image_gap.toml"], "material gap: integration point"),
    (&["@scene/image_zero_spacing.toml"], "image.spacing = [0.0, 0.25, 0.25] must be finite and > 0"),
    (&["@scene/image_nan_origin.toml"], "object[0].image.origin[0] = NaN is not a number"),
    (&["@scene/image_npy_no_spacing.toml"], "labels_4.npy: NPY: a .npy array has no voxel spacing"),
    (&["@scene/image_npy_two_d.toml"], "two_d.npy: NPY: the array has shape [4, 16] (2D); a material image must be 3D"),
    (&["@scene/image_npy_truncated.toml"], "truncated.npy: NPY: the file is truncated"),
    (&["@scene/image_modulus_with_labels.toml"], "labels apply to label images only"),
    (&["@scene/image_no_table.toml"], "shape = \"image\" needs an [object.image] table"),
    (&["@scene/image_missing_file.toml"], "nowhere.nii"),
    (&["@scene/image_bad_material.toml"], "material 'stiff': invalid youngs"),
];

#[rustfmt::skip]
const EXPORT: &[Case] = &[
    (&["@ply/truncated_binary.ply"], "truncated_binary.ply"),
    (&["@obj/open_box.obj"], "not watertight"),
    (&["@stl/nan_binary.stl"], "non-finite"),
    (&["box:-1,1,1"], "not positive"),
    (&["box:1,1,1", "--kernels", "1000000000000"], "more than 10000000 kernels"),
    (&["box:1,1,1", "--kernels", "50", "--points", "1000000000000"], "integration points"),
];

#[rustfmt::skip]
const FROM_MATRICES: &[Case] = &[
    (&["@mtx/missing_mass"], "mass.mtx"),
    (&["@mtx/does_not_exist"], "hessian.mtx"),
    (&["@mtx/empty"], "empty file"),
    (&["@mtx/garbage"], "not a text file"),
    (&["@mtx/array"], "'array' format is not supported"),
    (&["@mtx/complex"], "field 'complex' is not supported"),
    (&["@mtx/not_square"], "must be square"),
    (&["@mtx/nan_value"], "value 'nan' is not a finite number"),
    (&["@mtx/index_out_of_range"], "index '7' outside 1..=6"),
    (&["@mtx/too_few_entries"], "5 entries read, 6 announced"),
    (&["@mtx/huge_size"], "some rows are empty"),
    (&["@mtx/huge_entry_count"], "3 entries read, 1000000000000000 announced"),
    (&["@mtx/size_mismatch"], "H is 6 x 6 and M is 7 x 7"),
    (&["@mtx/indefinite_mass"], "positive definite"),
];

/// `freeform eval`: bad folders and flags fail before any work (a bad shape inside a good
/// folder is listed per shape instead: tests/integration/eval_shapes.rs).
#[rustfmt::skip]
const EVAL_CASES: &[Case] = &[
    (&["@no_such_dir"], "no_such_dir"),
    (&["@off", "--only", "nothing"], "no shape file"),
    (&["@off", "--steps", "0"], "at least one step"),
    (&["@off", "--youngs=-1"], "Young's modulus"),
];

/// A private copy of the corpus (runs may write caches next to scene files).
fn corpus() -> tempfile::TempDir {
    let dir = tempfile::tempdir().expect("temp dir");
    copy_dir(
        &Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/bad"),
        dir.path(),
    );
    dir
}

fn copy_dir(from: &Path, to: &Path) {
    std::fs::create_dir_all(to).unwrap();
    for entry in std::fs::read_dir(from).unwrap() {
        let entry = entry.unwrap();
        let target = to.join(entry.file_name());
        if entry.file_type().unwrap().is_dir() {
            copy_dir(&entry.path(), &target);
        } else {
            std::fs::copy(entry.path(), &target).unwrap();
        }
    }
}

/// Run `freeform` with a deadline; returns (exit code, stderr). A hang fails the test.
fn freeform(args: &[String]) -> (Option<i32>, String) {
    let mut child = Command::new(env!("CARGO_BIN_EXE_freeform"))
        .args(args)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("run freeform");
    let mut stderr = child.stderr.take().expect("stderr");
    let reader = std::thread::spawn(move || {
        let mut s = String::new();
        std::io::Read::read_to_string(&mut stderr, &mut s).ok();
        s
    });
    let start = Instant::now();
    let status = loop {
        if let Some(status) = child.try_wait().expect("wait") {
            break status;
        }
        if start.elapsed() > DEADLINE {
            child.kill().ok();
            child.wait().ok();
            panic!("{args:?} still running after {DEADLINE:?}");
        }
        std::thread::sleep(Duration::from_millis(5));
    };
    (status.code(), reader.join().expect("stderr reader"))
}

/// `@rel` becomes a path in the corpus copy.
fn expand(arg: &str, root: &Path) -> String {
    match arg.strip_prefix('@') {
        Some(rel) => root.join(rel).display().to_string(),
        None => arg.to_string(),
    }
}

/// Run one case with `--out out`; `Err` says which of the four promises it broke.
fn run_case(
    prefix: &[&str],
    args: &[&str],
    needle: &str,
    root: &Path,
    out: &Path,
) -> Result<(), String> {
    let mut full: Vec<String> = prefix.iter().map(|s| s.to_string()).collect();
    full.extend(args.iter().map(|a| expand(a, root)));
    full.extend(["--out".to_string(), out.display().to_string()]);
    let (code, err) = freeform(&full);
    if code.is_none_or(|c| c == 0) {
        return Err(format!("{full:?} should fail, exit {code:?}: {err}"));
    }
    if err.contains("panicked") {
        return Err(format!("{full:?} panicked: {err}"));
    }
    if !err.to_lowercase().contains(&needle.to_lowercase()) {
        return Err(format!("{full:?}: expected `{needle}` in: {err}"));
    }
    if out.exists() {
        return Err(format!("{full:?} left {} behind", out.display()));
    }
    Ok(())
}

/// Run a table: `extra` flag pairs are added unless the case sets them itself; every case
/// gets a fresh `--out` name in the corpus copy. Reports every failing case at once.
fn run_table(prefix: &[&str], extra: &[&str], table: &[Case], out_name: &str) {
    let dir = corpus();
    let mut failures = Vec::new();
    for (i, (args, needle)) in table.iter().enumerate() {
        let mut all: Vec<&str> = args.to_vec();
        for pair in extra.chunks(2) {
            if !args.contains(&pair[0]) {
                all.extend_from_slice(pair);
            }
        }
        let out = dir.path().join(format!("{i}-{out_name}"));
        if let Err(e) = run_case(prefix, &all, needle, dir.path(), &out) {
            failures.push(e);
        }
    }
    assert!(
        failures.is_empty(),
        "{} of {} cases failed:\n{}",
        failures.len(),
        table.len(),
        failures.join("\n\n")
    );
}

#[test]
fn modes_rejects_every_bad_shape_file() {
    run_table(&["modes"], SMALL, MODES_FILES, "basis.npz");
}

#[test]
fn eval_rejects_bad_folders_and_flags() {
    run_table(&["eval"], &[], EVAL_CASES, "eval");
}

#[test]
fn modes_rejects_bad_and_huge_flags() {
    run_table(&["modes"], &[], MODES_FLAGS, "basis.npz");
}

#[test]
fn run_rejects_every_bad_scene() {
    run_table(&["run", "--no-cache"], &[], RUN_SCENES, "frames");
}

#[test]
fn export_rejects_bad_shapes() {
    run_table(&["export"], SMALL, EXPORT, "matrices");
}

#[test]
fn from_matrices_rejects_bad_matrix_files() {
    run_table(
        &["modes", "--modes", "1", "--from-matrices"],
        &[],
        FROM_MATRICES,
        "eigenvectors.mtx",
    );
}

/// The library gives the same typed errors as the CLI: every file case of `modes` through
/// [`read_shape`], every scene case through [`Scene::load`] + [`freeform::scene::run`].
#[test]
fn library_api_gives_the_same_errors() {
    let dir = corpus();
    let root = dir.path();
    let mut failures = Vec::new();
    for (args, needle) in MODES_FILES {
        let spec = expand(args[0], root);
        let err = match read_shape(&spec, &ShapeOptions::default()) {
            Ok(shape) => {
                // Point clouds fail later, when their volumes are estimated.
                let opts = BasisOptions {
                    kernels: 50,
                    modes: 4,
                    ..BasisOptions::default()
                };
                match freeform::precompute::Problem::from_shape(
                    &shape,
                    &opts,
                    &freeform::progress::Silent,
                ) {
                    Ok(_) => "accepted".to_string(),
                    Err(e) => e.to_string(),
                }
            }
            Err(e) => e.to_string(),
        };
        if !err.to_lowercase().contains(&needle.to_lowercase()) {
            failures.push(format!("{spec}: expected `{needle}` in: {err}"));
        }
    }
    for (args, needle) in RUN_SCENES {
        let path = PathBuf::from(expand(args[0], root));
        let out = root.join("frames");
        let err = match Scene::load(&path) {
            Ok(scene) => {
                let settings = RunSettings {
                    base_dir: root.join("scene"),
                    out: Some(out.clone()),
                    strict: false,
                };
                let mut scene = scene;
                scene.cache.enabled = false;
                match freeform::scene::run(&scene, &settings, &freeform::progress::Silent) {
                    Ok(_) => "accepted".to_string(),
                    Err(e) => e.to_string(),
                }
            }
            Err(e) => e.to_string(),
        };
        if !err.to_lowercase().contains(&needle.to_lowercase()) {
            failures.push(format!("{}: expected `{needle}` in: {err}", path.display()));
        }
        if out.exists() {
            failures.push(format!("{}: frames written", path.display()));
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n\n"));
}

/// In-memory entry points reject bad arrays with typed errors.
#[test]
fn library_constructors_reject_bad_arrays() {
    let opts = ShapeOptions::default();
    let (v, t) = freeform::geometry::generate::box_mesh([1.0, 1.0, 1.0]);
    let mut bad_t = t.clone();
    bad_t[3] = [0, 1, 8];
    assert!(matches!(
        TriMesh::new(v.clone(), bad_t, &opts),
        Err(GeometryError::Degenerate(m)) if m.contains("refers to vertex 8")
    ));
    let mut nan_v = v.clone();
    nan_v[2][1] = f64::NAN;
    assert!(matches!(
        TriMesh::new(nan_v, t.clone(), &opts),
        Err(GeometryError::Degenerate(m)) if m.contains("non-finite")
    ));
    let huge: Vec<_> = v.iter().map(|p| p.map(|c| c * 1e200)).collect();
    assert!(matches!(
        TriMesh::new(huge, t.clone(), &opts),
        Err(GeometryError::Degenerate(m)) if m.contains("too large")
    ));
    assert!(matches!(
        TriMesh::new(v.clone(), t[..11].to_vec(), &opts),
        Err(GeometryError::NotWatertight {
            boundary_edges: 3,
            ..
        })
    ));
    assert!(PointCloud::new(Vec::new()).is_err());
    assert!(PointCloud::new(vec![[0.0, f64::INFINITY, 0.0]]).is_err());
    for (opts, needle) in [
        (
            BasisOptions {
                kernels: usize::MAX,
                ..BasisOptions::default()
            },
            "kernels",
        ),
        (
            BasisOptions {
                modes: usize::MAX,
                ..BasisOptions::default()
            },
            "modes",
        ),
        (
            BasisOptions {
                resolution: Some(freeform::precompute::sampling::Resolution::Count(
                    usize::MAX,
                )),
                ..BasisOptions::default()
            },
            "points",
        ),
    ] {
        let err = opts.validate().expect_err(needle).to_string();
        assert!(err.contains(needle), "{err}");
    }
    assert_eq!(
        freeform::precompute::default_points(usize::MAX),
        freeform::precompute::MAX_POINTS
    );
    let text = "%%MatrixMarket matrix coordinate real general\n\
                18446744073709551615 18446744073709551615 18446744073709551615\n1 1 1\n";
    let err = read_matrix_market_from(Path::new("m.mtx"), text.as_bytes()).unwrap_err();
    assert!(err.to_string().contains("announced"), "{err}");
}

/// Every file under `fuzz/corpus/<target>/` (seeds and minimized findings).
fn fuzz_inputs(target: &str) -> Vec<(PathBuf, Vec<u8>)> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("fuzz/corpus")
        .join(target);
    let mut files: Vec<PathBuf> = std::fs::read_dir(&dir)
        .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
        .map(|e| e.unwrap().path())
        .filter(|p| p.is_file())
        .collect();
    files.sort();
    assert!(!files.is_empty(), "no fuzz corpus in {}", dir.display());
    files
        .into_iter()
        .map(|p| {
            let bytes = std::fs::read(&p).unwrap();
            (p, bytes)
        })
        .collect()
}

/// The fuzz targets' bodies, on stable: parse, never panic (a panic fails this test).
#[test]
fn fuzz_corpus_and_findings_replay_without_panics() {
    for allow_open_mesh in [false, true] {
        let opts = ShapeOptions {
            allow_open_mesh,
            ..ShapeOptions::default()
        };
        for (path, bytes) in fuzz_inputs("ply") {
            let _ = ply::parse_ply_bytes(&path, &bytes, &opts);
        }
        for (path, bytes) in fuzz_inputs("obj") {
            let _ = obj::parse_obj_bytes(&path, &bytes, &opts);
        }
        for (path, bytes) in fuzz_inputs("stl") {
            let _ = stl::parse_stl_bytes(&path, &bytes, &opts);
        }
    }
    for (path, bytes) in fuzz_inputs("scene") {
        let Ok(text) = std::str::from_utf8(&bytes) else {
            continue;
        };
        if let Ok(scene) = Scene::from_toml(text) {
            let again = scene.to_toml().unwrap();
            if let Err(e) = Scene::from_toml(&again) {
                panic!("{}: round trip failed: {e}\n{again}", path.display());
            }
        }
    }
    for (path, bytes) in fuzz_inputs("matrix_market") {
        let _ = read_matrix_market_from(&path, bytes.as_slice());
    }
    for (path, bytes) in fuzz_inputs("basis") {
        let _ = freeform::io::basis::load_from(&path, std::io::Cursor::new(bytes));
    }
    for (path, bytes) in fuzz_inputs("splat") {
        let _ = freeform::io::splat::read_splats_from(&path, &mut std::io::Cursor::new(bytes));
    }
}

/// The parse-from-memory functions agree with the file readers on the corpus.
#[test]
fn byte_parsers_match_file_readers() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data");
    let opts = ShapeOptions::default();
    for name in [
        "tetra_ascii.ply",
        "points_ascii.ply",
        "splats_3dgs_tiny.ply",
    ] {
        let path = root.join(name);
        let bytes = std::fs::read(&path).unwrap();
        let a = ply::read_ply(&path, &opts).unwrap();
        let b = ply::parse_ply_bytes(&path, &bytes, &opts).unwrap();
        assert_eq!(a.render_points(), b.render_points(), "{name}");
    }
    let path = root.join("cube_quads.obj");
    let a = obj::read_obj(&path, &opts).unwrap();
    let b = obj::parse_obj_bytes(&path, &std::fs::read(&path).unwrap(), &opts).unwrap();
    assert_eq!(a.vertices(), b.vertices());
    assert_eq!(a.triangles(), b.triangles());
}

/// A basis of K = 4 kernels (the origin and the unit points on the axes, radius 1.5) and
/// m + 1 = 2 columns with coefficients `offset + i + 3 j`.
fn tiny_basis(
    kind: freeform::precompute::rkpm::KernelType,
    offset: f64,
) -> freeform::precompute::skinning::Basis {
    freeform::precompute::skinning::Basis {
        kernels: freeform::precompute::rkpm::Kernels {
            centers: vec![
                [0.0, 0.0, 0.0],
                [1.0, 0.0, 0.0],
                [0.0, 1.0, 0.0],
                [0.0, 0.0, 1.0],
            ],
            radii: vec![1.5; 4],
            kind,
        },
        coefficients: faer::Mat::from_fn(4, 2, |i, j| offset + (i + 3 * j) as f64),
        eigenvalues: vec![0.0, 2.5],
    }
}

/// A damaged basis file (the scene cache, `modes --out`) gives `Error::BasisFile` or
/// `Error::Io`, never a panic: garbage, every truncation, and byte flips all through the file.
#[test]
fn damaged_basis_files_are_rejected() {
    use freeform::precompute::rkpm::KernelType;
    let dir = tempfile::tempdir().unwrap();
    let good = dir.path().join("good.npz");
    let basis = tiny_basis(KernelType::Cubic, 0.0);
    freeform::io::basis::save(&good, &basis, &serde_json::json!({"test": true}).into()).unwrap();
    let bytes = std::fs::read(&good).unwrap();
    assert!(freeform::io::basis::load(&good).is_ok());
    let bad = dir.path().join("bad.npz");
    let check = |data: &[u8], what: &str| {
        std::fs::write(&bad, data).unwrap();
        if let Err(e) = freeform::io::basis::load(&bad) {
            let msg = e.to_string();
            assert!(msg.contains("bad.npz"), "{what}: {msg}");
        }
    };
    check(b"", "empty");
    check(&[0x50, 0x4b, 0x03, 0x04, 0xff, 0xff], "zip magic only");
    for len in (0..bytes.len()).step_by(3) {
        check(&bytes[..len], &format!("truncated to {len}"));
    }
    for i in 0..bytes.len() {
        let mut flipped = bytes.clone();
        flipped[i] ^= 0x5a;
        check(&flipped, &format!("byte {i} flipped"));
    }
}

/// The entries of a basis archive, in order: (name, uncompressed bytes).
fn zip_entries(bytes: &[u8]) -> Vec<(String, Vec<u8>)> {
    use std::io::Read;
    let mut zip = zip::ZipArchive::new(std::io::Cursor::new(bytes)).unwrap();
    (0..zip.len())
        .map(|i| {
            let mut entry = zip.by_index(i).unwrap();
            let mut data = Vec::new();
            entry.read_to_end(&mut data).unwrap();
            (entry.name().to_string(), data)
        })
        .collect()
}

/// A zip of `entries`, each deflated (as `numpy.savez_compressed` writes).
fn deflated_zip(entries: &[(String, Vec<u8>)]) -> Vec<u8> {
    use std::io::Write;
    let mut zip = zip::ZipWriter::new(std::io::Cursor::new(Vec::new()));
    let opts = zip::write::SimpleFileOptions::default()
        .compression_method(zip::CompressionMethod::Deflated);
    for (name, data) in entries {
        zip.start_file(name.as_str(), opts).unwrap();
        zip.write_all(data).unwrap();
    }
    zip.finish().unwrap().into_inner()
}

/// Overwrite the uncompressed size that the local header and the central directory declare for
/// entry `name` (classic 32-bit fields: the archives here are small).
fn set_declared_size(archive: &mut [u8], name: &str, size: u32) {
    let mut patched = 0;
    // (signature, offset of the uncompressed size, offset of the name length, offset of the name)
    for (sig, size_at, len_at, name_at) in
        [(*b"PK\x03\x04", 22, 26, 30), (*b"PK\x01\x02", 24, 28, 46)]
    {
        for i in 0..archive.len().saturating_sub(name_at) {
            if archive[i..i + 4] != sig {
                continue;
            }
            let len = u16::from_le_bytes([archive[i + len_at], archive[i + len_at + 1]]) as usize;
            if archive.get(i + name_at..i + name_at + len) == Some(name.as_bytes()) {
                archive[i + size_at..i + size_at + 4].copy_from_slice(&size.to_le_bytes());
                patched += 1;
            }
        }
    }
    assert_eq!(
        patched, 2,
        "{name}: local header and central directory entry"
    );
}

/// A basis archive whose entry expands beyond what its array can hold ("zip bomb") is rejected
/// with `Error::BasisArrayTooLarge` naming the file, the array and the limit, whether the archive
/// declares the true size or understates it; the same basis within the limits, stored or
/// deflated, loads unchanged.
#[test]
fn basis_array_beyond_its_limit_is_rejected() {
    use freeform::io::basis;
    use freeform::precompute::rkpm::KernelType;
    let dir = tempfile::tempdir().unwrap();
    let good = dir.path().join("good.npz");
    let original = tiny_basis(KernelType::Quartic, 0.25);
    basis::save(&good, &original, &serde_json::json!({"test": true}).into()).unwrap();
    let entries = zip_entries(&std::fs::read(&good).unwrap());
    let load = |name: &str, archive: &[u8]| {
        let path = dir.path().join(name);
        std::fs::write(&path, archive).unwrap();
        basis::load(&path)
    };
    let same = |loaded: basis::LoadedBasis, what: &str| {
        assert_eq!(loaded.basis.kernels, original.kernels, "{what}");
        assert_eq!(loaded.basis.coefficients, original.coefficients, "{what}");
        assert_eq!(loaded.basis.eigenvalues, original.eigenvalues, "{what}");
        assert_eq!(loaded.metadata.extra["test"], true, "{what}");
    };
    same(basis::load(&good).unwrap(), "stored, as saved");
    same(
        load("deflated.npz", &deflated_zip(&entries)).unwrap(),
        "deflated",
    );

    // Limits worked out by hand: the 128 KiB header allowance plus the data bytes, 8 for
    // `format_version` (one int64) and 8 K^2 = 128 for `coefficients` (K = 4).
    const VERSION_LIMIT: u64 = 128 * 1024 + 8;
    const COEFFICIENT_LIMIT: u64 = 128 * 1024 + 8 * 4 * 4;
    // `name` padded with zeros to `len` bytes, every other entry as saved.
    let padded = |name: &str, len: u64| -> Vec<(String, Vec<u8>)> {
        let mut e = entries.clone();
        let entry = e.iter_mut().find(|(n, _)| n == name).unwrap();
        entry.1.resize(len as usize, 0);
        e
    };
    let check = |result: freeform::Result<basis::LoadedBasis>,
                 file: &str,
                 array: &str,
                 limit: u64,
                 declared: u64| {
        let e = match result {
            Err(e) => e,
            Ok(_) => panic!("{file}: loaded, expected BasisArrayTooLarge"),
        };
        let msg = e.to_string();
        match e {
            freeform::Error::BasisArrayTooLarge {
                path,
                array: a,
                limit: l,
                declared: d,
            } => {
                assert_eq!(path, dir.path().join(file));
                assert_eq!((a, l, d), (array, limit, declared), "{msg}");
                let expected = format!(
                    "{}: array `{array}` of the basis file is larger than its limit of {limit} \
                     bytes (the archive declares {declared} bytes); the file is damaged or not \
                     a freeform basis",
                    path.display()
                );
                assert_eq!(msg, expected);
            }
            other => panic!("{file}: expected BasisArrayTooLarge, got {other:?}"),
        }
    };

    // 1 MiB of `format_version`, honestly declared: rejected before decompressing. Deflate makes
    // it a bomb: the archive is far smaller than what it expands to.
    let bomb = deflated_zip(&padded("format_version.npy", 1 << 20));
    assert!(
        bomb.len() < (1 << 20) / 50,
        "archive of {} bytes",
        bomb.len()
    );
    check(
        load("bomb.npz", &bomb),
        "bomb.npz",
        "format_version",
        VERSION_LIMIT,
        1 << 20,
    );

    // `coefficients` at exactly its limit passes the size check (and is then read as the
    // K x 2 array its header announces); one byte more is rejected, although the archive
    // understates it as the original entry's size: caught while decompressing.
    let at_limit = deflated_zip(&padded("coefficients.npy", COEFFICIENT_LIMIT));
    same(
        load("at_limit.npz", &at_limit).unwrap(),
        "coefficients at the limit",
    );
    let honest_len = entries
        .iter()
        .find(|(n, _)| n == "coefficients.npy")
        .map(|(_, d)| d.len() as u32)
        .unwrap();
    let mut liar = deflated_zip(&padded("coefficients.npy", COEFFICIENT_LIMIT + 1));
    set_declared_size(&mut liar, "coefficients.npy", honest_len);
    check(
        load("liar.npz", &liar),
        "liar.npz",
        "coefficients",
        COEFFICIENT_LIMIT,
        u64::from(honest_len),
    );
    // A big liar, 64 MiB of zeros in a small file, is stopped the same way.
    let mut big = deflated_zip(&padded("coefficients.npy", 64 << 20));
    set_declared_size(&mut big, "coefficients.npy", honest_len);
    assert!(big.len() < 1 << 20, "archive of {} bytes", big.len());
    check(
        load("big_liar.npz", &big),
        "big_liar.npz",
        "coefficients",
        COEFFICIENT_LIMIT,
        u64::from(honest_len),
    );
}

/// Zero friction is valid (frictionless), not bad input: the keys that refuse -0.2 and NaN
/// (the corpus above) accept 0, for every contact and for a pair.
#[test]
fn zero_friction_is_frictionless_not_an_error() {
    let text = "[simulation]\ndt = 0.01\nsteps = 2\n[[object]]\nname = \"bar\"\n\
                shape = \"box:1,0.2,0.2\"\n[[collider]]\nname = \"floor\"\n\
                shape = { plane = { point = [0, -1, 0], normal = [0, 1, 0] } }\n\
                [contact]\nfriction = 0.0\n[[contact.pair]]\nbetween = [\"bar\", \"floor\"]\n\
                friction = 0.0\n";
    let scene = Scene::from_toml(text).unwrap();
    let c = scene.contact.as_ref().unwrap();
    assert_eq!(c.friction, 0.0);
    assert_eq!(c.friction_between(Some("bar"), Some("floor")), 0.0);
}
