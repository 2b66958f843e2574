//! USD in and out (docs/usd.md): a run's stage read back against its PLY frames, Kaolin's
//! physics schemas on it, USD prims as shapes and colliders (transforms composed up the
//! hierarchy, references, usdz, units and up axis, quads, time samples) against values
//! computed by hand, and the errors for bad stages. The check against Pixar's own reader
//! (usd-core) is python/tests/test_usd.py.

use freeform::geometry::{GeometryError, Shape, ShapeOptions, UpAxis};
use freeform::io::splat::{read_splats, write_splats, Splats};
use freeform::io::usd::kaolin::{read_kaolin, DEFAULT_INSTANCE};
use freeform::io::usd::{read_usd_geometry, UsdPrimKind};
use freeform::progress::Silent;
use freeform::random::SplitMix64;
use freeform::scene::{run, RunSettings, Scene};
use std::path::Path;

/// `n` splats with SH degree 1 in a ball of radius 0.2 m around the origin.
fn ball_splats(n: usize) -> Splats {
    let mut rng = SplitMix64::new(3);
    let mut means = Vec::new();
    while means.len() < n {
        let p: [f64; 3] = std::array::from_fn(|_| rng.uniform(-0.2, 0.2));
        if p.iter().map(|c| c * c).sum::<f64>() < 0.04 {
            means.push(p);
        }
    }
    let q = |rng: &mut SplitMix64| {
        let q: [f64; 4] = std::array::from_fn(|_| rng.uniform(-1.0, 1.0));
        let s = q.iter().map(|c| c * c).sum::<f64>().sqrt();
        q.map(|c| c / s)
    };
    Splats::new(
        means,
        (0..n).map(|_| [-4.0, -4.5, -5.0]).collect(),
        (0..n).map(|_| q(&mut rng)).collect(),
        (0..n).map(|_| rng.uniform(-2.0, 2.0)).collect(),
        (0..n).map(|_| [0.5, 0.1, -0.2]).collect(),
        (0..n * 9).map(|_| rng.uniform(-0.1, 0.1)).collect(),
        1,
    )
    .unwrap()
}

const TORUS: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/examples/data/torus.obj");

fn run_scene(dir: &Path, text: &str) -> freeform::scene::RunSummary {
    let scene = Scene::from_toml(text).unwrap();
    let settings = RunSettings {
        base_dir: dir.to_path_buf(),
        out: Some(dir.join("out")),
        strict: false,
    };
    run(&scene, &settings, &Silent).unwrap()
}

fn f32_bits(p: &[[f64; 3]]) -> Vec<[u32; 3]> {
    p.iter().map(|q| q.map(|c| (c as f32).to_bits())).collect()
}

#[test]
fn a_run_stage_holds_every_frame_of_its_ply_files_and_kaolin_physics() {
    let dir = tempfile::tempdir().unwrap();
    write_splats(&dir.path().join("blob.ply"), &ball_splats(300)).unwrap();
    let text = format!(
        r#"
[simulation]
dt = 0.01
steps = 4
gravity = [0.0, -9.81, 0.0]
[output]
every = 2
formats = ["usd", "ply"]
stress = true
[cache]
enabled = false
[[object]]
name = "block-1"
shape = "box:0.4,0.2,0.2"
basis = {{ kernels = 60, modes = 4 }}
placement = {{ translation = [0.0, 0.5, 0.0] }}
[[object]]
name = "blob"
shape = "blob.ply"
basis = {{ kernels = 60, modes = 4 }}
placement = {{ translation = [1.0, 0.5, 0.0] }}
[[object]]
name = "torus"
shape = "{TORUS}"
basis = {{ kernels = 60, modes = 4 }}
placement = {{ translation = [-1.5, 0.8, 0.0] }}
[[collider]]
name = "floor"
shape = {{ plane = {{ point = [0.0, 0.0, 0.0], normal = [0.0, 1.0, 0.0] }} }}
[[collider]]
shape = {{ sphere = {{ center = [3.0, 0.2, 0.0], radius = 0.2 }} }}
"#
    );
    let summary = run_scene(dir.path(), &text);
    let stage = dir.path().join("out/run.usda");
    assert!(summary.files.iter().any(|f| f.ends_with("run.usda")));
    for frame in [0usize, 2, 4] {
        let t = Some(frame as f64);
        // A primitive's points (its integration points), named by the mapping rule.
        let g = read_usd_geometry(&stage, Some("/World/block_1/points"), t, UpAxis::Y).unwrap();
        assert_eq!(g.kind, UsdPrimKind::Points);
        let ply = freeform::io::ply::read_ply_data(
            &dir.path()
                .join(format!("out/block-1/block-1_{frame:06}.ply")),
        )
        .unwrap();
        assert_eq!(f32_bits(&g.points), f32_bits(&ply.points), "frame {frame}");
        // A mesh: points per frame, the same triangles.
        let g = read_usd_geometry(&stage, Some("/World/torus/surface"), t, UpAxis::Y).unwrap();
        let ply = freeform::io::ply::read_ply_data(
            &dir.path().join(format!("out/torus/torus_{frame:06}.ply")),
        )
        .unwrap();
        assert_eq!(f32_bits(&g.points), f32_bits(&ply.points), "frame {frame}");
        assert_eq!(g.triangles, ply.triangles);
        // Splats: the centres of the 3DGS frame.
        let g = read_usd_geometry(&stage, Some("/World/blob/splats"), t, UpAxis::Y).unwrap();
        assert_eq!(g.kind, UsdPrimKind::GaussianSplats);
        let s = read_splats(&dir.path().join(format!("out/blob/blob_{frame:06}.ply"))).unwrap();
        assert_eq!(f32_bits(&g.points), f32_bits(&s.means), "frame {frame}");
    }
    // Kaolin's schemas: the material at every integration point, the weights at the
    // cubature and the render points, the constant handle last (ones, gradient 0).
    let k = read_kaolin(&stage, "/World/block_1/points", DEFAULT_INSTANCE, None).unwrap();
    let material = k.material.expect("KaolinPhysicsMaterialAPI");
    let volume = 0.4 * 0.2 * 0.2;
    // f32 storage of a volume summed in f64: 1e-6 relative is far above f32's 6e-8.
    assert!((material.volume - volume).abs() < 1e-6 * volume);
    assert!(material.youngs.iter().all(|&e| e == 5e6));
    let (cub, w) = k.skinned.expect("KaolinSkinnedPhysicsAPI");
    assert_eq!(w.handles, 5);
    assert_eq!(w.values.len(), cub.points.len() * 5);
    assert_eq!(w.gradients.len(), cub.points.len() * 15);
    assert!(w.values.chunks(5).all(|row| row[4] == 1.0));
    assert!(w.gradients.chunks(15).all(|row| row[12..] == [0.0; 3]));
    // The modes are freeform's: M-orthonormal, so the weights at the cubature points, with
    // their volumes, are close to orthonormal; mode 1 is not constant.
    assert!(w
        .values
        .chunks(5)
        .any(|row| (row[0] - w.values[0]).abs() > 1e-3));
    let render = w.render.expect("renderable_skinning_weights");
    let ip =
        read_usd_geometry(&stage, Some("/World/block_1/points"), Some(0.0), UpAxis::Y).unwrap();
    assert_eq!(render.len(), ip.points.len() * 5);
}

/// A unit cube of 6 quads (outward), side 1 around the origin, in a layer of its own.
const CUBE_LAYER: &str = r#"#usda 1.0
(
    defaultPrim = "Cube"
)
def Mesh "Cube"
{
    int[] faceVertexCounts = [4, 4, 4, 4, 4, 4]
    int[] faceVertexIndices = [0, 3, 2, 1, 4, 5, 6, 7, 0, 1, 5, 4, 1, 2, 6, 5, 2, 3, 7, 6, 3, 0, 4, 7]
    point3f[] points = [(-0.5, -0.5, -0.5), (0.5, -0.5, -0.5), (0.5, 0.5, -0.5), (-0.5, 0.5, -0.5), (-0.5, -0.5, 0.5), (0.5, -0.5, 0.5), (0.5, 0.5, 0.5), (-0.5, 0.5, 0.5)]
}
"#;

/// The cube's corners, in the order of its points.
const CORNERS: [[f64; 3]; 8] = [
    [-0.5, -0.5, -0.5],
    [0.5, -0.5, -0.5],
    [0.5, 0.5, -0.5],
    [-0.5, 0.5, -0.5],
    [-0.5, -0.5, 0.5],
    [0.5, -0.5, 0.5],
    [0.5, 0.5, 0.5],
    [-0.5, 0.5, 0.5],
];

/// A Z-up stage in centimetres referencing the cube under two transformed prims.
fn scene_layer(reference: &str) -> String {
    format!(
        r#"#usda 1.0
(
    defaultPrim = "World"
    metersPerUnit = 0.01
    upAxis = "Z"
)
def Xform "World"
{{
    def Xform "Parent"
    {{
        double3 xformOp:translate = (100, 0, 50)
        float xformOp:rotateZ = 90
        uniform token[] xformOpOrder = ["xformOp:translate", "xformOp:rotateZ"]
        def "Part" (
            prepend references = @{reference}@
        )
        {{
            float3 xformOp:scale = (20, 20, 20)
            uniform token[] xformOpOrder = ["xformOp:scale"]
        }}
    }}
    def "Other" (
        prepend references = @{reference}@
    )
    {{
        double3 xformOp:translate = (0, 0, 300)
        float3 xformOp:scale = (30, 30, 30)
        uniform token[] xformOpOrder = ["xformOp:translate", "xformOp:scale"]
    }}
}}
"#
    )
}

/// Write `cube.usda` and the `scene.usda` that references it into `dir`.
fn cube_stage(dir: &Path) {
    std::fs::write(dir.join("cube.usda"), CUBE_LAYER).unwrap();
    std::fs::write(dir.join("scene.usda"), scene_layer("./cube.usda")).unwrap();
}

/// Where the cube's corner `c` (its own units) lands: scale 20, turn 90 degrees about z,
/// move by (100, 0, 50) cm, to metres, then Z-up to Y-up ((x, y, z) -> (x, z, -y)).
fn expected(c: [f64; 3]) -> [f64; 3] {
    let s = c.map(|v| 20.0 * v);
    let r = [-s[1], s[0], s[2]];
    let t = [r[0] + 100.0, r[1], r[2] + 50.0].map(|v| v * 0.01);
    [t[0], t[2], -t[1]]
}

#[test]
fn usd_inputs_compose_references_transforms_units_and_up_axis() {
    let dir = tempfile::tempdir().unwrap();
    cube_stage(dir.path());
    let scene = dir.path().join("scene.usda");
    let g = read_usd_geometry(&scene, Some("/World/Parent/Part"), None, UpAxis::Y).unwrap();
    assert_eq!(g.kind, UsdPrimKind::Mesh);
    for (p, c) in g.points.iter().zip(CORNERS) {
        let e = expected(c);
        // Exact inputs, one 90-degree rotation (cos 90 rounds to 6e-17): 1e-12 m.
        assert!(
            (0..3).all(|d| (p[d] - e[d]).abs() < 1e-12),
            "{p:?} vs {e:?}"
        );
    }
    // Six quads, two triangles each.
    assert_eq!(g.triangles.as_ref().map(Vec::len), Some(12));
    // As a shape: a closed, outward mesh of side 0.2 m (its volume by the divergence theorem).
    let spec = format!("{}:/World/Parent/Part", scene.display());
    let shape = freeform::io::read_shape(&spec, &ShapeOptions::default()).unwrap();
    let Shape::Mesh(m) = &shape else {
        panic!("{shape:?}")
    };
    assert!((m.volume().unwrap() - 0.008).abs() < 1e-12);
    // Read into a Z-up frame instead, nothing turns.
    let z = read_usd_geometry(&scene, Some("/World/Parent/Part"), None, UpAxis::Z).unwrap();
    let e = expected(CORNERS[6]);
    assert!((z.points[6][2] - e[1]).abs() < 1e-12 && (z.points[6][1] + e[2]).abs() < 1e-12);
    // The referenced layer alone: its only mesh, no prim path needed; no metersPerUnit is
    // USD's fallback, centimetres.
    let own = read_usd_geometry(&dir.path().join("cube.usda"), None, None, UpAxis::Y).unwrap();
    assert_eq!(own.prim, "/Cube");
    assert_eq!(own.points[6], [0.005, 0.005, 0.005]);
    // A left-handed mesh winds the other way: its triangles are turned to face outward.
    let left = dir.path().join("left.usda");
    let text = CUBE_LAYER.replace(
        "    int[] faceVertexCounts",
        "    uniform token orientation = \"leftHanded\"\n    int[] faceVertexCounts",
    );
    std::fs::write(&left, text).unwrap();
    let l = read_usd_geometry(&left, None, None, UpAxis::Y).unwrap();
    let turned: Vec<[u32; 3]> = own
        .triangles
        .unwrap()
        .iter()
        .map(|t| [t[0], t[2], t[1]])
        .collect();
    assert_eq!(l.triangles.unwrap(), turned);
}

#[test]
fn a_usdz_package_is_read_like_its_layer() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("cube.usdz");
    let mut w = openusd::usdz::ArchiveWriter::create(&path).unwrap();
    w.add_layer("cube.usda", CUBE_LAYER.as_bytes()).unwrap();
    w.finish().unwrap();
    let g = read_usd_geometry(&path, Some("/Cube"), None, UpAxis::Y).unwrap();
    assert_eq!(g.points.len(), 8);
    assert_eq!(g.points[0], [-0.005, -0.005, -0.005]);
}

#[test]
fn a_time_sampled_mesh_is_read_at_the_stated_time_code() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("anim.usda");
    std::fs::write(
        &path,
        r#"#usda 1.0
(
    metersPerUnit = 1
)
def Points "P"
{
    point3f[] points.timeSamples = {
        0: [(0, 0, 0), (1, 0, 0)],
        10: [(0, 2, 0), (1, 2, 0)],
    }
}
"#,
    )
    .unwrap();
    let at = |t: f64| {
        read_usd_geometry(&path, Some("/P"), Some(t), UpAxis::Y)
            .unwrap()
            .points
    };
    assert_eq!(at(10.0), vec![[0.0, 2.0, 0.0], [1.0, 2.0, 0.0]]);
    // USD interpolates linearly between samples.
    assert_eq!(at(5.0), vec![[0.0, 1.0, 0.0], [1.0, 1.0, 0.0]]);
    let spec = format!("{}:/P@10", path.display());
    let shape = freeform::io::read_shape(&spec, &ShapeOptions::default()).unwrap();
    assert!(matches!(shape, Shape::PointCloud(_)));
    // Without a time code there is no value to read: the error says which to name.
    let e = read_usd_geometry(&path, Some("/P"), None, UpAxis::Y).unwrap_err();
    let text = e.to_string();
    assert!(
        text.contains("/P.points") && text.contains("2 time samples (0 to 10)"),
        "{text}"
    );
    assert!(text.contains("FILE:/P@0"), "{text}");
}

/// Write `body` as a stage and read prim `prim`; the error's text.
fn bad_stage(name: &str, body: &str, prim: Option<&str>) -> String {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join(name);
    std::fs::write(&path, body).unwrap();
    match read_usd_geometry(&path, prim, None, UpAxis::Y) {
        Err(e @ GeometryError::Usd { .. }) => e.to_string(),
        other => panic!("{name}: expected a Usd error, got {other:?}"),
    }
}

#[test]
fn bad_stages_name_the_prim_and_the_attribute() {
    let head = "#usda 1.0\n(\n    metersPerUnit = 1\n)\n";
    let mesh = |counts: &str, indices: &str| {
        format!(
            "{head}def Mesh \"M\" {{\n    int[] faceVertexCounts = [{counts}]\n    \
             int[] faceVertexIndices = [{indices}]\n    \
             point3f[] points = [(0, 0, 0), (1, 0, 0), (0, 1, 0)]\n}}\n"
        )
    };
    let point = "def Points \"P\" { point3f[] points = [(0, 0, 0)] }\n";
    // (file name, stage text, prim, what the message must contain)
    let cases: Vec<(&str, String, Option<&str>, Vec<&str>)> = vec![
        (
            "garbage.usda",
            "this is not usd {".into(),
            None,
            vec!["garbage.usda: /: the stage does not open"],
        ),
        (
            "a.usda",
            format!("{head}def Mesh \"M\" {{}}\n"),
            Some("/Nope"),
            vec!["/Nope: no such prim; the stage has these mesh, points and splat prims: /M"],
        ),
        (
            "a.usda",
            format!("{head}def Mesh \"M\" {{}}\n"),
            Some("/M"),
            vec!["/M.points: the prim has no points"],
        ),
        (
            "a.usda",
            mesh("3", "0, 1, 3"),
            Some("/M"),
            vec!["/M.faceVertexIndices: face 0 indexes point 3, past the 3 points"],
        ),
        (
            "a.usda",
            mesh("3, 3", "0, 1, 2"),
            Some("/M"),
            vec!["/M.faceVertexIndices: 3 indices, fewer than the 6"],
        ),
        (
            "a.usda",
            mesh("3", "0, 1, 2, 0"),
            Some("/M"),
            vec!["more than the 3"],
        ),
        (
            "a.usda",
            mesh("2", "0, 1"),
            Some("/M"),
            vec!["/M.faceVertexCounts: face 0 has 2 vertices"],
        ),
        (
            "a.usda",
            format!("#usda 1.0\n(\n    upAxis = \"X\"\n)\n{point}"),
            Some("/P"),
            vec!["/.upAxis: `X` is not supported"],
        ),
        (
            "a.usda",
            format!("#usda 1.0\n(\n    metersPerUnit = -1\n)\n{point}"),
            Some("/P"),
            vec!["/.metersPerUnit: ", "not a positive"],
        ),
        (
            "a.usda",
            format!(
                "{head}def Points \"P\" {{\n    point3f[] points = [(0, 0, 0)]\n    \
              matrix4d xformOp:transform = ((1, 0, 0, 0.5), (0, 1, 0, 0), (0, 0, 1, 0), \
              (0, 0, 0, 1))\n    uniform token[] xformOpOrder = [\"xformOp:transform\"]\n}}\n"
            ),
            Some("/P"),
            vec!["/P.xformOpOrder: the prim's transform is not affine"],
        ),
        (
            "a.usda",
            format!("{head}def Cube \"C\" {{}}\n"),
            Some("/C"),
            vec!["/C: the prim is a `Cube`; freeform reads Mesh, Points"],
        ),
        (
            "a.usda",
            format!(
                "{head}{}{}",
                point.replace("\"P\"", "\"A\""),
                point.replace("\"P\"", "\"B\"")
            ),
            None,
            vec!["several prims to read", "/A, /B"],
        ),
        (
            "a.usda",
            format!("{head}def \"R\" (\n    prepend references = @./missing.usda@\n) {{}}\n"),
            Some("/R"),
            vec!["/R: the stage does not compose", "missing.usda"],
        ),
    ];
    for (name, body, prim, needles) in cases {
        let e = bad_stage(name, &body, prim);
        assert!(
            needles.iter().all(|n| e.contains(n)),
            "{needles:?} not in: {e}"
        );
    }
}

#[test]
fn a_scene_takes_its_object_and_collider_from_usd_prims() {
    let dir = tempfile::tempdir().unwrap();
    cube_stage(dir.path());
    // The object: the 0.2 m cube at (1, 0.5, 0) m after the stage's units and up axis; the
    // collider: the same prim as a solid obstacle moved below it.
    let text = r#"
[simulation]
dt = 0.01
steps = 2
gravity = [0.0, -9.81, 0.0]
[output]
formats = ["usd"]
[cache]
enabled = false
[[object]]
name = "cube"
shape = "scene.usda:/World/Parent/Part"
basis = { kernels = 40, modes = 4 }
[[collider]]
name = "table"
shape = { mesh = { file = "scene.usda:/World/Parent/Part", translation = [0.0, -1.0, 0.0] } }
"#;
    let summary = run_scene(dir.path(), text);
    assert_eq!(summary.frames, 3);
    let stage = dir.path().join("out/run.usda");
    // Frame 0 is the rest shape: the cube's corners where the stage puts them (f32).
    let g = read_usd_geometry(&stage, Some("/World/cube/surface"), Some(0.0), UpAxis::Y).unwrap();
    let mut got: Vec<[u32; 3]> = f32_bits(&g.points);
    let mut want: Vec<[u32; 3]> = f32_bits(&CORNERS.map(expected));
    got.sort_unstable();
    want.sort_unstable();
    assert_eq!(got, want);
    let table =
        read_usd_geometry(&stage, Some("/World/colliders/table"), Some(0.0), UpAxis::Y).unwrap();
    assert_eq!(table.triangles.map(|t| t.len()), Some(12));
}

#[test]
fn the_cli_writes_a_stage_by_flag_and_renders_it() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("s.toml");
    std::fs::write(
        &scene,
        "[simulation]\ndt = 0.01\nsteps = 4\ngravity = [0.0, -9.81, 0.0]\n\
         [solver]\ncubature = 300\n[output]\nevery = 2\n[cache]\nenabled = false\n\
         [[object]]\nname = \"bar\"\nshape = \"box:1,0.2,0.2\"\n\
         basis = { kernels = 40, modes = 4, points = 2000 }\n",
    )
    .unwrap();
    let out = dir.path().join("frames");
    let (s, o) = (scene.to_str().unwrap(), out.to_str().unwrap());
    let run = crate::common::freeform(&["run", s, "--out", o, "--format", "usd"]);
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    // The flag replaces the scene's default formats: only the stage is written.
    let names: Vec<String> = std::fs::read_dir(&out)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().to_string())
        .collect();
    assert_eq!(names, ["run.usda"]);
    let g = read_usd_geometry(
        &out.join("run.usda"),
        Some("/World/bar/points"),
        Some(4.0),
        UpAxis::Y,
    )
    .unwrap();
    assert!(!g.points.is_empty());
    let bad = crate::common::freeform(&["run", s, "--out", o, "--format", "usd,gltf"]);
    assert!(!bad.status.success());
    let text = String::from_utf8_lossy(&bad.stderr);
    assert!(
        text.contains("`gltf` is not a frame format: use vtk, ply or usd"),
        "{text}"
    );
    let png = dir.path().join("png");
    let stage = out.join("run.usda");
    let r = crate::common::freeform(&[
        "render",
        stage.to_str().unwrap(),
        "--size",
        "160x120",
        "--out",
        png.to_str().unwrap(),
    ]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    // Frames 0, 2 and 4.
    for i in 0..3 {
        assert!(png.join(format!("frame_{i:06}.png")).is_file());
    }
    assert!(!png.join("frame_000003.png").exists());
}

#[test]
fn two_prims_of_one_stage_get_their_own_cached_bases() {
    let dir = tempfile::tempdir().unwrap();
    cube_stage(dir.path());
    // Same stage file, same basis options: the key must still tell the prims apart (a
    // shared key would load one cube's kernels for the other, 3 m away).
    let text = r#"
[simulation]
dt = 0.01
steps = 1
[output]
formats = ["usd"]
[[object]]
name = "a"
shape = "scene.usda:/World/Parent/Part"
basis = { kernels = 40, modes = 4 }
[[object]]
name = "b"
shape = "scene.usda:/World/Other"
basis = { kernels = 40, modes = 4 }
"#;
    let first = run_scene(dir.path(), text);
    assert!(first.objects.iter().all(|o| !o.basis_cached));
    let again = run_scene(dir.path(), text);
    assert!(again.objects.iter().all(|o| o.basis_cached));
    let cached = std::fs::read_dir(dir.path().join(".freeform-cache"))
        .unwrap()
        .filter(|e| {
            e.as_ref()
                .unwrap()
                .path()
                .extension()
                .is_some_and(|x| x == "npz")
        })
        .count();
    assert_eq!(cached, 2);
}

#[test]
fn a_splat_prim_is_simulated_and_written_as_splats() {
    let dir = tempfile::tempdir().unwrap();
    // 6 x 6 x 6 splats 4 cm apart in a Z-up stage in centimetres, under a prim turned 90
    // degrees about z and scaled 2x.
    let mut pos = Vec::new();
    for i in 0..6 {
        for j in 0..6 {
            for k in 0..6 {
                pos.push(format!("({}, {}, {})", 4 * i, 4 * j, 4 * k));
            }
        }
    }
    let n = pos.len();
    let join = |item: &str| vec![item; n].join(", ");
    let sh: Vec<String> = (0..n)
        .map(|_| {
            "(0.5, 0.1, -0.2), (0.01, 0.02, 0.03), (0.04, 0.05, 0.06), (0.07, 0.08, 0.09)".into()
        })
        .collect();
    let stage = format!(
        "#usda 1.0\n(\n    metersPerUnit = 0.01\n    upAxis = \"Z\"\n)\n\
         def Xform \"W\"\n{{\n    float xformOp:rotateZ = 90\n    float3 xformOp:scale = (2, 2, 2)\n    \
         uniform token[] xformOpOrder = [\"xformOp:rotateZ\", \"xformOp:scale\"]\n    \
         def ParticleField3DGaussianSplat \"S\"\n    {{\n        point3f[] positions = [{}]\n        \
         quatf[] orientations = [{}]\n        float3[] scales = [{}]\n        float[] opacities = [{}]\n        \
         uniform int radiance:sphericalHarmonicsDegree = 1\n        \
         float3[] radiance:sphericalHarmonicsCoefficients = [{}]\n    }}\n}}\n",
        pos.join(", "),
        join("(1, 0, 0, 0)"),
        join("(1, 2, 3)"),
        join("0.5"),
        sh.join(", ")
    );
    std::fs::write(dir.path().join("splats.usda"), stage).unwrap();
    let text = r#"
[simulation]
dt = 0.01
steps = 1
[output]
formats = ["ply", "usd"]
[cache]
enabled = false
[[object]]
name = "toy"
shape = "splats.usda:/W/S"
basis = { kernels = 40, modes = 4 }
"#;
    run_scene(dir.path(), text);
    let s = read_splats(&dir.path().join("out/toy/toy_000000.ply")).unwrap();
    assert_eq!(s.len(), n);
    assert_eq!(s.sh_degree, 1);
    // Splat (i, j, k) = (1, 0, 0): (4, 0, 0) cm, scaled 2x, turned to (0, 8, 0) cm, to metres,
    // Z-up to Y-up ((x, y, z) -> (x, z, -y)): (0, 0, -0.08) m.
    let idx = 36;
    let e = [0.0, 0.0, -0.08];
    assert!(
        (0..3).all(|d| (s.means[idx][d] - e[d]).abs() < 1e-7),
        "{:?}",
        s.means[idx]
    );
    // Scales 2 x 0.01 x (1, 2, 3) m; the axes turned by the same rotation.
    let want = [0.02f64, 0.04, 0.06].map(f64::ln);
    assert!((0..3).all(|d| (s.log_scales[idx][d] - want[d]).abs() < 1e-6));
    // The splat's x axis (rest (1, 0, 0)) turns to the stage's y, which is freeform's -z.
    let r = freeform::linalg3::quat_to_matrix(&s.rotations[idx]);
    let x_axis = [r[0][0], r[1][0], r[2][0]];
    assert!((x_axis[2] + 1.0).abs() < 1e-6, "{x_axis:?}");
    // Opacity 0.5 is a logit of 0; SH as stored, in freeform's channel-major rows.
    assert!(s.opacities[idx].abs() < 1e-6);
    assert_eq!(s.sh_dc[idx].map(|c| c as f32), [0.5, 0.1, -0.2]);
    assert_eq!(
        s.sh_rest[idx * 9..idx * 9 + 9]
            .iter()
            .map(|&c| c as f32)
            .collect::<Vec<_>>(),
        [0.01, 0.04, 0.07, 0.02, 0.05, 0.08, 0.03, 0.06, 0.09]
    );
    // The stage writes the object's splats too.
    let g = read_usd_geometry(
        &dir.path().join("out/run.usda"),
        Some("/World/toy/splats"),
        Some(0.0),
        UpAxis::Y,
    )
    .unwrap();
    assert_eq!(f32_bits(&g.points), f32_bits(&s.means));
}

#[test]
fn freeform_modes_writes_a_basis_stage_for_kaolin() {
    let dir = tempfile::tempdir().unwrap();
    let (npz, usda) = (dir.path().join("bar.npz"), dir.path().join("bar.usda"));
    let o = crate::common::freeform(&[
        "modes",
        "box:1,0.2,0.2",
        "--kernels",
        "40",
        "--modes",
        "4",
        "--points",
        "2000",
        "--out",
        npz.to_str().unwrap(),
        "--usd",
        usda.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let k = read_kaolin(&usda, "/World/bar", DEFAULT_INSTANCE, None).unwrap();
    let m = k.material.expect("material schema");
    let (p, w) = k.skinned.expect("skinned schema");
    assert_eq!(m.points, p.points);
    assert!((m.volume - 0.04).abs() < 1e-6 * 0.04);
    // The weights are the basis file's at the (f32) points: modes 1..m, then ones.
    let basis = freeform::io::basis::load(&npz).unwrap().basis;
    let at = basis.weights(&p.points).unwrap();
    for (i, row) in w.values.chunks(5).enumerate() {
        let want: Vec<f32> = at.row(i)[1..]
            .iter()
            .map(|&v| v as f32)
            .chain([1.0])
            .collect();
        let got: Vec<f32> = row.iter().map(|&v| v as f32).collect();
        // The stage's points are float32: the weights at them differ from those at the
        // double points by the weights' gradient times 3e-8 m (1e-5 relative here).
        for (g, e) in got.iter().zip(&want) {
            assert!(
                (g - e).abs() <= 1e-5 * e.abs().max(1.0),
                "{got:?} vs {want:?}"
            );
        }
    }
}

#[test]
fn a_malformed_usd_render_input_gets_the_spec_error() {
    let dir = tempfile::tempdir().unwrap();
    cube_stage(dir.path());
    let text = r#"
[simulation]
dt = 0.01
steps = 1
[cache]
enabled = false
[[object]]
name = "cube"
shape = "scene.usda:/World/Parent/Part"
basis = { kernels = 40, modes = 4 }
render = ["scene.usda:World/Other"]
"#;
    let scene = Scene::from_toml(text).unwrap();
    let settings = RunSettings {
        base_dir: dir.path().to_path_buf(),
        out: None,
        strict: false,
    };
    let e = run(&scene, &settings, &Silent).unwrap_err().to_string();
    assert!(
        e.contains("`World/Other` is not an absolute prim path"),
        "{e}"
    );
    // A directory named like a stage holds ordinary files: read by their own reader.
    let scene =
        Scene::from_toml(&text.replace("scene.usda:World/Other", "x.usd.d/skin.obj")).unwrap();
    let e = run(&scene, &settings, &Silent).unwrap_err().to_string();
    assert!(e.contains("cannot read") && e.contains("skin.obj"), "{e}");
}
