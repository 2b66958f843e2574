//! Geometry stage, end to end: shape specs, primitives, mesh volumes, the inside test against
//! analytic answers and the exact winding number, open and inverted meshes, and the OBJ / STL /
//! OFF / PLY readers and writers on good, bad and hostile files.

use freeform::geometry::winding::winding_numbers_exact;
use freeform::geometry::{
    generate, Aabb, GeometryError, Shape, ShapeOptions, TriMesh, WindingParams, WindingTree,
};
use freeform::io::obj::{read_obj, write_obj};
use freeform::io::off::{read_off, read_off_raw, write_off};
use freeform::io::ply::{
    read_ply, read_ply_points, write_ply_mesh, write_ply_points, write_ply_points_with, PlyFormat,
    PlyScalar, PlyWriteOptions,
};
use freeform::io::read_shape;
use freeform::io::stl::{read_stl, write_stl, StlFormat};
use freeform::random::SplitMix64;
use freeform::Point3;
use std::f64::consts::PI;
use std::path::{Path, PathBuf};

// ---------------------------------------------------------------------------------------------
// helpers

fn data(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data")
        .join(name)
}

fn closed() -> ShapeOptions {
    ShapeOptions::default()
}

fn open_ok() -> ShapeOptions {
    ShapeOptions {
        allow_open_mesh: true,
        ..ShapeOptions::default()
    }
}

/// A point uniform in [lo, hi)^3 from the library's generator (these tests moved to it from
/// their own linear congruential one: other random inputs, the same checks).
fn point_in(rng: &mut SplitMix64, lo: f64, hi: f64) -> Point3 {
    [0, 1, 2].map(|_| rng.uniform(lo, hi))
}

/// `n^3` cell-centred grid points filling the cube [lo, hi]^3.
fn grid(n: usize, lo: f64, hi: f64) -> Vec<Point3> {
    (0..n * n * n)
        .map(|i| {
            [i % n, (i / n) % n, i / (n * n)].map(|c| lo + (hi - lo) * (c as f64 + 0.5) / n as f64)
        })
        .collect()
}

fn mesh(vt: (Vec<Point3>, Vec<[u32; 3]>)) -> TriMesh {
    TriMesh::new(vt.0, vt.1, &closed()).expect("valid mesh")
}

/// Signed distance to the convex polyhedron `m` (max over face planes; exact inside, a lower
/// bound outside), and whether the point is inside.
fn convex_plane_distance(m: &TriMesh, p: &Point3) -> f64 {
    let v = m.vertices();
    m.triangles()
        .iter()
        .map(|t| {
            let [a, b, c] = t.map(|i| v[i as usize]);
            let e1 = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
            let e2 = [c[0] - a[0], c[1] - a[1], c[2] - a[2]];
            let n = [
                e1[1] * e2[2] - e1[2] * e2[1],
                e1[2] * e2[0] - e1[0] * e2[2],
                e1[0] * e2[1] - e1[1] * e2[0],
            ];
            let l = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
            ((p[0] - a[0]) * n[0] + (p[1] - a[1]) * n[1] + (p[2] - a[2]) * n[2]) / l
        })
        .fold(f64::NEG_INFINITY, f64::max)
}

fn tmp() -> tempfile::TempDir {
    tempfile::tempdir().expect("temp dir")
}

fn write(dir: &Path, name: &str, bytes: &[u8]) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, bytes).unwrap();
    p
}

fn parse(path: &Path) -> Result<Shape, GeometryError> {
    read_shape(path.to_str().unwrap(), &closed())
}

fn expect_parse_error(path: &Path, needle: &str) {
    match parse(path) {
        Err(GeometryError::Parse { path: p, reason }) => {
            assert_eq!(p, path);
            assert!(
                reason.contains(needle),
                "{}: reason `{reason}` lacks `{needle}`",
                path.display()
            );
        }
        other => panic!(
            "{}: expected Parse error with `{needle}`, got {other:?}",
            path.display()
        ),
    }
}

// ---------------------------------------------------------------------------------------------
// primitives and specs

#[test]
fn primitive_volumes_boxes_and_inside() {
    let b = read_shape("box:2,3,4", &closed()).unwrap();
    assert_eq!(b.volume(), Some(24.0));
    assert_eq!(
        b.bounding_box(),
        Aabb {
            min: [0.0; 3],
            max: [2.0, 3.0, 4.0]
        }
    );
    assert!(b.is_solid());
    assert!(b.render_points().is_none());
    let inside = b.contains(&[
        [1.0, 1.0, 1.0],
        [0.0, 0.0, 0.0],
        [2.0, 3.0, 4.0],
        [2.1, 1.0, 1.0],
    ]);
    assert_eq!(inside, Some(vec![true, true, true, false]));

    let s = read_shape("sphere:1.5", &closed()).unwrap();
    let v = s.volume().unwrap();
    assert!((v - 4.0 / 3.0 * PI * 1.5f64.powi(3)).abs() < 1e-13 * v);
    assert_eq!(
        s.bounding_box(),
        Aabb {
            min: [-1.5; 3],
            max: [1.5; 3]
        }
    );
    let inside = s.contains(&[
        [0.0; 3],
        [1.5, 0.0, 0.0],
        [1.0, 1.0, 1.0],
        [0.0, -1.49, 0.0],
    ]);
    assert_eq!(inside, Some(vec![true, true, false, true]));
}

#[test]
fn spec_errors_name_the_problem() {
    let bad = |spec: &str, needle: &str| match read_shape(spec, &closed()) {
        Err(GeometryError::BadPrimitive { spec: s, reason }) => {
            assert_eq!(s, spec);
            assert!(
                reason.contains(needle),
                "{spec}: `{reason}` lacks `{needle}`"
            );
        }
        other => panic!("{spec}: expected BadPrimitive, got {other:?}"),
    };
    bad("box:1,2", "too few numbers");
    bad("box:1,2,3,4", "too many numbers");
    bad("box:1,-2,3", "not positive");
    bad("box:0,1,1", "not positive");
    bad("sphere:NaN", "not finite");
    bad("sphere:-inf", "not finite");
    bad("sphere:r", "not a number");
    bad("sphere:", "no numbers given");
    for spec in ["torus:1,2", "model.step", "model", "model.obj.gz"] {
        assert!(
            matches!(read_shape(spec, &closed()), Err(GeometryError::UnknownSpec(s)) if s == spec),
            "{spec}"
        );
    }
    // A supported extension that does not exist is an I/O error with the path.
    match read_shape("/nonexistent/dir/model.OBJ", &closed()) {
        Err(GeometryError::Io { path, .. }) => assert!(path.ends_with("model.OBJ")),
        other => panic!("{other:?}"),
    }
}

// ---------------------------------------------------------------------------------------------
// mesh volumes

#[test]
fn cube_mesh_volume_and_translation_invariance() {
    let m = mesh(generate::box_mesh([1.0, 2.0, 3.0]));
    assert!((m.volume().unwrap() - 6.0).abs() < 1e-14);
    // Far from the origin the divergence-theorem sum is taken about the box centre, so it stays
    // accurate.
    let (v, t) = generate::box_mesh([1.0, 2.0, 3.0]);
    let shifted: Vec<Point3> = v
        .iter()
        .map(|p| [p[0] + 1e6, p[1] - 2e6, p[2] + 3e5])
        .collect();
    let m = TriMesh::new(shifted, t, &closed()).unwrap();
    assert!(
        (m.volume().unwrap() - 6.0).abs() < 1e-9,
        "{}",
        m.volume().unwrap()
    );
}

#[test]
fn icosphere_volume_matches_polyhedron_and_converges_to_ball() {
    let mut deficits = vec![];
    for s in 1..=5 {
        let (v, t) = generate::icosphere(2.0, s);
        // Independent exact polyhedron volume: sum of pyramids from the centre,
        // area x (distance of the face plane from the origin) / 3.
        let pyramids: f64 = t
            .iter()
            .map(|tri| {
                let [a, b, c] = tri.map(|i| v[i as usize]);
                let e1 = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
                let e2 = [c[0] - a[0], c[1] - a[1], c[2] - a[2]];
                let n = [
                    e1[1] * e2[2] - e1[2] * e2[1],
                    e1[2] * e2[0] - e1[0] * e2[2],
                    e1[0] * e2[1] - e1[1] * e2[0],
                ];
                let l = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
                let area = 0.5 * l;
                let h = (a[0] * n[0] + a[1] * n[1] + a[2] * n[2]) / l;
                area * h / 3.0
            })
            .sum();
        let m = TriMesh::new(v, t, &closed()).unwrap();
        let vol = m.volume().unwrap();
        assert!(
            (vol - pyramids).abs() < 1e-12 * pyramids,
            "s={s}: {vol} vs {pyramids}"
        );
        let ball = 4.0 / 3.0 * PI * 8.0;
        assert!(vol < ball);
        deficits.push((ball - vol) / ball);
    }
    // Inscribed polyhedron: the relative volume deficit falls ~4x per subdivision (O(h^2)).
    for w in deficits.windows(2) {
        let ratio = w[0] / w[1];
        assert!((3.5..4.5).contains(&ratio), "{deficits:?}");
    }
    assert!(deficits[4] < 2e-3, "{deficits:?}");
}

// ---------------------------------------------------------------------------------------------
// inside test vs analytic answers

#[test]
fn cube_mesh_inside_matches_analytic_on_grid() {
    let size = [1.0, 2.0, 3.0];
    let m = mesh(generate::box_mesh(size));
    // 31^3 grid over a slightly larger box: many points lie exactly on the faces' planes or
    // within round-off of them; those are skipped.
    let n = 31;
    let pts: Vec<Point3> = (0..n * n * n)
        .map(|i| {
            let c = [i % n, (i / n) % n, i / (n * n)];
            [0, 1, 2].map(|a| -0.25 * size[a] + 1.5 * size[a] * c[a] as f64 / (n - 1) as f64)
        })
        .collect();
    let got = m.contains(&pts);
    let mut compared = 0;
    for (p, g) in pts.iter().zip(&got) {
        let d = (0..3)
            .map(|a| (p[a]).abs().min((p[a] - size[a]).abs()))
            .fold(f64::INFINITY, f64::min);
        if d <= 1e-6 * 3.0 {
            continue;
        }
        let want = (0..3).all(|a| p[a] > 0.0 && p[a] < size[a]);
        assert_eq!(*g, want, "{p:?}");
        compared += 1;
    }
    assert!(compared > 20_000, "{compared}");
    assert_eq!(Shape::Mesh(m).contains(&pts), Some(got));
}

#[test]
fn icosphere_inside_matches_analytic_on_grid() {
    let m = mesh(generate::icosphere(1.0, 4));
    let pts = grid(41, -1.2, 1.2);
    let got = m.contains(&pts);
    let mut compared = 0;
    for (p, g) in pts.iter().zip(&got) {
        let d = convex_plane_distance(&m, p);
        if d.abs() <= 1e-6 {
            continue;
        }
        assert_eq!(*g, d < 0.0, "{p:?} d={d}");
        // Also against the true ball, away from the band between polyhedron and sphere.
        let r = (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt();
        if !(0.995..=1.0).contains(&r) {
            assert_eq!(*g, r < 1.0, "{p:?}");
        }
        compared += 1;
    }
    assert!(compared > 60_000);
}

#[test]
fn torus_inside_matches_analytic_away_from_surface() {
    let (major, minor) = (2.0, 0.75);
    let m = mesh(generate::torus(major, minor, 96, 48));
    let pts = grid(36, -3.0, 3.0);
    let got = m.contains(&pts);
    // The polygonal torus lies within `sag` of the smooth one.
    let sag = minor * (1.0 - (PI / 48.0).cos()) + (major + minor) * (1.0 - (PI / 96.0).cos());
    let mut compared = 0;
    for (p, g) in pts.iter().zip(&got) {
        let rho = (p[0] * p[0] + p[1] * p[1]).sqrt();
        let d = ((rho - major).powi(2) + p[2] * p[2]).sqrt() - minor;
        if d.abs() <= 2.0 * sag + 1e-6 {
            continue;
        }
        assert_eq!(*g, d < 0.0, "{p:?}");
        compared += 1;
    }
    assert!(compared > 40_000);
}

// ---------------------------------------------------------------------------------------------
// hierarchical vs exact winding number

/// Points that stress the evaluation: uniform in a box around the mesh, plus pairs just inside
/// and just outside every triangle's centroid (1e-4 of the size), plus the vertices' neighbours.
fn stress_points(m: &TriMesh, rng: &mut SplitMix64, n_random: usize) -> Vec<Point3> {
    let b = m.bounding_box();
    let diag = b.diagonal();
    let mut pts: Vec<Point3> = (0..n_random)
        .map(|_| {
            let u = point_in(rng, -0.1, 1.1);
            [0, 1, 2].map(|a| b.min[a] + u[a] * (b.max[a] - b.min[a]))
        })
        .collect();
    let v = m.vertices();
    for t in m.triangles().iter().step_by(7) {
        let [a, bb, c] = t.map(|i| v[i as usize]);
        let e1 = [bb[0] - a[0], bb[1] - a[1], bb[2] - a[2]];
        let e2 = [c[0] - a[0], c[1] - a[1], c[2] - a[2]];
        let n = [
            e1[1] * e2[2] - e1[2] * e2[1],
            e1[2] * e2[0] - e1[0] * e2[2],
            e1[0] * e2[1] - e1[1] * e2[0],
        ];
        let l = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
        let cen = [0, 1, 2].map(|k| (a[k] + bb[k] + c[k]) / 3.0);
        for s in [-1e-4, 1e-4, -1e-2, 1e-2] {
            pts.push([0, 1, 2].map(|k| cen[k] + s * diag * n[k] / l));
        }
    }
    pts
}

#[test]
fn fast_winding_number_agrees_with_exact_sum() {
    let mut hollow = generate::box_mesh([4.0, 4.0, 4.0]);
    // A cavity: an inner box [1,3]^3 facing inward (its triangles reversed).
    let (iv, it) = generate::box_mesh([2.0, 2.0, 2.0]);
    let base = hollow.0.len() as u32;
    hollow
        .0
        .extend(iv.iter().map(|p| [p[0] + 1.0, p[1] + 1.0, p[2] + 1.0]));
    hollow
        .1
        .extend(it.iter().map(|t| [t[0] + base, t[2] + base, t[1] + base]));
    let meshes = [
        ("cube", mesh(generate::box_mesh([1.0, 2.0, 3.0]))),
        ("icosphere", mesh(generate::icosphere(1.0, 4))),
        ("torus", mesh(generate::torus(2.0, 0.6, 64, 32))),
        ("hollow box", mesh(hollow)),
    ];
    let mut rng = SplitMix64::new(42);
    for (name, m) in &meshes {
        let pts = stress_points(m, &mut rng, 3000);
        let exact = m.winding_numbers_exact(&pts);
        let fast = m.winding_numbers(&pts);
        let inside = m.contains(&pts);
        let per_point = m.winding_tree().contains(&pts);
        let mut max_err: f64 = 0.0;
        for i in 0..pts.len() {
            max_err = max_err.max((fast[i] - exact[i]).abs());
            // Watertight: the exact value is an integer off the surface.
            assert!(
                (exact[i] - exact[i].round()).abs() < 1e-9,
                "{name} {:?}",
                pts[i]
            );
            assert_eq!(
                inside[i],
                exact[i] >= 0.5,
                "{name}: {:?} w={}",
                pts[i],
                exact[i]
            );
            assert_eq!(per_point[i], exact[i] >= 0.5, "{name}: {:?}", pts[i]);
        }
        assert!(
            max_err < 1e-2,
            "{name}: max |w_fast - w_exact| = {max_err:e}"
        );
        eprintln!(
            "{name}: {} points, max |w_fast - w_exact| = {max_err:.2e}",
            pts.len()
        );
    }
    // Non-finite queries are outside, alone or inside a batch of inside points.
    let m = &meshes[1].1;
    let mut pts = vec![[0.0, 0.0, 0.1]; 50];
    pts[7] = [f64::NAN, 0.0, 0.0];
    pts[30] = [0.0, f64::INFINITY, 0.0];
    let got = m.contains(&pts);
    assert!(!got[7] && !got[30] && got.iter().filter(|&&b| b).count() == 48);
    assert!(!m.winding_tree().contains(&pts)[7]);
    // The hollow box's cavity is outside, its volume is the difference.
    let hollow = &meshes[3].1;
    assert!((hollow.volume().unwrap() - 56.0).abs() < 1e-12);
    assert_eq!(
        hollow.contains(&[[2.0, 2.0, 2.0], [0.5, 2.0, 2.0]]),
        vec![false, true]
    );
}

#[test]
fn accuracy_parameter_trades_error() {
    let m = mesh(generate::icosphere(1.0, 4));
    let mut rng = SplitMix64::new(3);
    let pts = stress_points(&m, &mut rng, 500);
    let exact = winding_numbers_exact(m.vertices(), m.triangles(), &pts);
    let err = |beta: f64| {
        let tree = WindingTree::new(
            m.vertices(),
            m.triangles(),
            WindingParams { beta, leaf_size: 8 },
        );
        let w = tree.winding_numbers(&pts);
        w.iter()
            .zip(&exact)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max)
    };
    let (e15, e2, e4) = (err(1.5), err(2.0), err(4.0));
    assert!(e4 < e2 && e2 < e15, "{e15:e} {e2:e} {e4:e}");
    assert!(e2 < 1e-2, "{e2:e}");
}

/// Throughput of the inside test; run with
/// `cargo test --release --test integration -- --ignored --nocapture geometry::winding_throughput`.
#[test]
#[ignore = "timing: run explicitly"]
fn winding_throughput_icosphere_20k() {
    use std::time::Instant;
    let m = mesh(generate::icosphere(1.0, 5));
    assert_eq!(m.triangles().len(), 20480);
    let t0 = Instant::now();
    let tree = m.winding_tree();
    let build = t0.elapsed().as_secs_f64();
    let mut rng = SplitMix64::new(11);
    let random: Vec<Point3> = (0..200_000)
        .map(|_| point_in(&mut rng, -1.2, 1.2))
        .collect();
    let g = grid(59, -1.1, 1.1); // 205,379 points
    let time = |f: &dyn Fn() -> Vec<bool>| {
        let t = Instant::now();
        let r = f();
        (t.elapsed().as_secs_f64(), r)
    };
    let threads = rayon::current_num_threads();
    eprintln!(
        "icosphere 20480 triangles, tree build {:.1} ms, {threads} threads",
        build * 1e3
    );
    for (name, pts) in [("200k random", &random), ("59^3 grid", &g)] {
        let (t_pp, a) = time(&|| tree.contains(pts));
        let (t_b, b) = time(&|| tree.contains_closed(pts));
        assert_eq!(a, b);
        eprintln!(
            "{name}: per-point {:.0} pts/s ({:.3} s), batch (closed) {:.0} pts/s ({:.3} s)",
            pts.len() as f64 / t_pp,
            t_pp,
            pts.len() as f64 / t_b,
            t_b
        );
    }
    let sub = &random[..2000];
    let (t_ex, _) = time(&|| {
        m.winding_numbers_exact(sub)
            .iter()
            .map(|w| *w >= 0.5)
            .collect()
    });
    eprintln!("exact O(F) sum: {:.0} pts/s", sub.len() as f64 / t_ex);
}

// ---------------------------------------------------------------------------------------------
// open, inverted and misoriented meshes

#[test]
fn open_mesh_rejected_with_edge_counts_and_accepted_on_opt_in() {
    let path = data("cube_open.obj");
    match parse(&path) {
        Err(GeometryError::NotWatertight {
            path: p,
            boundary_edges,
            nonmanifold_edges,
        }) => {
            assert_eq!(p, path);
            assert_eq!((boundary_edges, nonmanifold_edges), (4, 0));
        }
        other => panic!("{other:?}"),
    }
    let shape = read_shape(path.to_str().unwrap(), &open_ok()).unwrap();
    let Shape::Mesh(m) = &shape else {
        panic!("not a mesh")
    };
    assert_eq!(m.edge_report().boundary_edges, 4);
    assert_eq!(shape.volume(), None);
    assert!(shape.is_solid());
    // Cube centre: 5 of 6 faces present, w = 5/6.
    let w = m.winding_numbers_exact(&[[0.5, 0.5, 0.5]])[0];
    assert!((w - 5.0 / 6.0).abs() < 1e-12, "{w}");
    let w = m.winding_numbers(&[[0.5, 0.5, 0.5]])[0];
    assert!((w - 5.0 / 6.0).abs() < 1e-2, "{w}");
    // Just below the hole w ~ 0.509 (inside), just above it w ~ 0.491 (outside).
    let pts = [
        [0.5, 0.5, 0.5],
        [0.5, 0.5, 0.1],
        [0.5, 0.5, 0.99],
        [0.5, 0.5, 1.01],
        [2.0, 0.5, 0.5],
    ];
    assert_eq!(
        shape.contains(&pts),
        Some(vec![true, true, true, false, false])
    );
}

#[test]
fn inverted_mesh_is_flipped_and_behaves_the_same() {
    let (v, t) = generate::icosphere(1.0, 3);
    let inv: Vec<[u32; 3]> = t.iter().map(|t| [t[0], t[2], t[1]]).collect();
    let a = TriMesh::new(v.clone(), t, &closed()).unwrap();
    let b = TriMesh::new(v, inv, &closed()).unwrap();
    assert!(!a.was_flipped() && b.was_flipped());
    assert!((a.volume().unwrap() - b.volume().unwrap()).abs() < 1e-14);
    assert_eq!(a.triangles(), b.triangles());
    let pts = grid(15, -1.1, 1.1);
    assert_eq!(a.contains(&pts), b.contains(&pts));
    // Through a file too.
    let dir = tmp();
    let p = dir.path().join("inverted.obj");
    let (v, t) = generate::box_mesh([1.0, 1.0, 1.0]);
    let inv: Vec<[u32; 3]> = t.iter().map(|t| [t[1], t[0], t[2]]).collect();
    write_obj(&p, &v, &inv).unwrap();
    let m = read_obj(&p, &closed()).unwrap();
    assert!(m.was_flipped());
    assert!((m.volume().unwrap() - 1.0).abs() < 1e-15);
}

#[test]
fn misoriented_and_nonmanifold_meshes() {
    let dir = tmp();
    let (v, mut t) = generate::box_mesh([1.0, 1.0, 1.0]);
    t[4].swap(0, 1);
    let p = dir.path().join("misoriented.ply");
    write_ply_mesh(&p, &v, &t, PlyWriteOptions::default()).unwrap();
    match parse(&p) {
        Err(GeometryError::Misoriented {
            path,
            misoriented_edges: 3,
        }) => assert_eq!(path, p),
        other => panic!("{other:?}"),
    }
    // Two cubes sharing an edge (welded): 1 non-manifold edge, used by 4 triangles.
    let (v1, t1) = generate::box_mesh([1.0, 1.0, 1.0]);
    let mut v2 = v1.clone();
    let mut t2 = t1.clone();
    for p in v1.iter() {
        v2.push([p[0] + 1.0, p[1] + 1.0, p[2]]);
    }
    t2.extend(t1.iter().map(|t| t.map(|i| i + 8)));
    let p = dir.path().join("two_cubes.stl");
    write_stl(&p, &v2, &t2, StlFormat::Binary).unwrap();
    match parse(&p) {
        Err(GeometryError::NotWatertight {
            boundary_edges: 0,
            nonmanifold_edges: 1,
            ..
        }) => {}
        other => panic!("{other:?}"),
    }
    let m = read_stl(&p, &open_ok()).unwrap();
    assert_eq!(
        m.contains(&[[0.5, 0.5, 0.5], [1.5, 1.5, 0.5], [1.5, 0.5, 0.5]]),
        vec![true, true, false]
    );
}

// ---------------------------------------------------------------------------------------------
// readers: good files

/// The OFF cube of quads is the OBJ cube of quads: same vertices, same fan triangles, same
/// volume, through the spec dispatch (`read_shape`) and the raw reader colliders use.
#[test]
fn off_cube_matches_the_obj_cube() {
    let (Shape::Mesh(off), Shape::Mesh(obj)) = (
        parse(&data("cube_quads.off")).unwrap(),
        parse(&data("cube_quads.obj")).unwrap(),
    ) else {
        panic!("not meshes")
    };
    assert_eq!(off.vertices(), obj.vertices());
    assert_eq!(off.triangles(), obj.triangles());
    assert_eq!(off.volume(), Some(1.0));
    assert_eq!(off.volume(), obj.volume());
    let (v, t) = read_off_raw(&data("cube_quads.off")).unwrap();
    assert_eq!((v.len(), t.len()), (8, 12));
    // Upper-case extension, and a write / read round trip of an icosphere.
    let dir = tmp();
    let upper = dir.path().join("CUBE.OFF");
    std::fs::copy(data("cube_quads.off"), &upper).unwrap();
    assert_eq!(parse(&upper).unwrap().volume(), Some(1.0));
    let (v, t) = generate::icosphere(0.7, 2);
    let p = dir.path().join("ico.off");
    write_off(&p, &v, &t).unwrap();
    let m = read_off(&p, &closed()).unwrap();
    assert_eq!(m.vertices(), &v[..]);
    assert!((m.volume().unwrap() - mesh((v, t)).volume().unwrap()).abs() < 1e-15);
}

#[test]
fn obj_quads_groups_and_relative_indices() {
    let shape = parse(&data("cube_quads.obj")).unwrap();
    let Shape::Mesh(m) = &shape else {
        panic!("not a mesh")
    };
    assert_eq!(m.vertices().len(), 8);
    assert_eq!(m.triangles().len(), 12);
    assert!(m.is_closed() && !m.was_flipped());
    assert_eq!(shape.volume(), Some(1.0));
    assert_eq!(
        shape.bounding_box(),
        Aabb {
            min: [0.0; 3],
            max: [1.0; 3]
        }
    );
    assert_eq!(shape.render_points().unwrap().len(), 8);
    // The same file with a byte order mark and CRLF line ends.
    let text = std::fs::read_to_string(data("cube_quads.obj")).unwrap();
    let dir = tmp();
    let crlf = format!("\u{feff}{}", text.replace('\n', "\r\n"));
    let p = write(dir.path(), "bom_crlf.obj", crlf.as_bytes());
    assert_eq!(parse(&p).unwrap().volume(), Some(1.0));
}

#[test]
fn obj_round_trip_is_exact() {
    let dir = tmp();
    let (v, t) = generate::icosphere(0.7, 2);
    let p = dir.path().join("ico.obj");
    write_obj(&p, &v, &t).unwrap();
    let m = read_obj(&p, &closed()).unwrap();
    assert_eq!(m.vertices().len(), v.len());
    assert_eq!(m.triangles().len(), t.len());
    // tobj (with `use_f64`) parses doubles but numbers vertices in order of first use by a
    // face: compare as sets of exact bit patterns (the writer prints round-trip precision).
    let key = |p: &Point3| p.map(|c| c.to_bits());
    let want: std::collections::HashSet<[u64; 3]> = v.iter().map(key).collect();
    for a in m.vertices() {
        assert!(want.contains(&key(a)));
    }
    assert!((m.volume().unwrap() - mesh((v, t)).volume().unwrap()).abs() < 1e-12);
}

#[test]
fn stl_binary_and_ascii_read_the_same_mesh() {
    let dir = tmp();
    let (v, t) = generate::icosphere(1.0, 3);
    let exact = TriMesh::new(v.clone(), t.clone(), &closed())
        .unwrap()
        .volume()
        .unwrap();
    let mut volumes = vec![];
    for (name, fmt) in [
        ("ico_bin.stl", StlFormat::Binary),
        ("ico_ascii.STL", StlFormat::Ascii),
    ] {
        let p = dir.path().join(name);
        write_stl(&p, &v, &t, fmt).unwrap();
        let shape = parse(&p).unwrap();
        let Shape::Mesh(m) = &shape else { panic!() };
        assert_eq!(
            m.vertices().len(),
            v.len(),
            "{name}: welding restores the shared vertices"
        );
        assert_eq!(m.triangles().len(), t.len());
        assert!(m.is_closed());
        volumes.push(m.volume().unwrap());
    }
    assert_eq!(volumes[0], volumes[1]);
    assert!((volumes[0] - exact).abs() < 1e-6 * exact);

    // Binary STL whose 80-byte header starts with "solid" (common exporter habit).
    let p = dir.path().join("solid_header.stl");
    write_stl(&p, &v, &t, StlFormat::Binary).unwrap();
    let mut bytes = std::fs::read(&p).unwrap();
    bytes[..12].copy_from_slice(b"solid cube  ");
    std::fs::write(&p, &bytes).unwrap();
    let m = read_stl(&p, &closed()).unwrap();
    assert_eq!(m.triangles().len(), t.len());

    // ASCII STL whose first line is just "solid", with CRLF line ends.
    let p = dir.path().join("ascii_crlf.stl");
    write_stl(&p, &v, &t, StlFormat::Ascii).unwrap();
    let text = std::fs::read_to_string(&p)
        .unwrap()
        .replacen("solid freeform", "solid", 1);
    std::fs::write(&p, text.replace('\n', "\r\n")).unwrap();
    let m = read_stl(&p, &closed()).unwrap();
    assert_eq!(m.triangles().len(), t.len());
}

#[test]
fn ply_meshes_ascii_and_binary() {
    let shape = parse(&data("tetra_ascii.ply")).unwrap();
    let Shape::Mesh(m) = &shape else {
        panic!("not a mesh")
    };
    assert!((m.volume().unwrap() - 1.0 / 6.0).abs() < 1e-15);

    let dir = tmp();
    let (v, t) = generate::torus(1.0, 0.3, 32, 16);
    for (name, format, scalar) in [
        ("t_ascii.ply", PlyFormat::Ascii, PlyScalar::Double),
        (
            "t_bin.ply",
            PlyFormat::BinaryLittleEndian,
            PlyScalar::Double,
        ),
        (
            "t_bin_f32.PLY",
            PlyFormat::BinaryLittleEndian,
            PlyScalar::Float,
        ),
    ] {
        let p = dir.path().join(name);
        write_ply_mesh(&p, &v, &t, PlyWriteOptions { format, scalar }).unwrap();
        let Shape::Mesh(m) = parse(&p).unwrap() else {
            panic!("{name}: not a mesh")
        };
        assert_eq!(m.triangles(), &t[..], "{name}");
        if scalar == PlyScalar::Double {
            assert_eq!(m.vertices(), &v[..], "{name}: doubles round-trip exactly");
        }
    }
}

#[test]
fn ply_without_faces_is_a_point_cloud() {
    let shape = parse(&data("points_ascii.ply")).unwrap();
    let Shape::PointCloud(c) = &shape else {
        panic!("not a point cloud")
    };
    assert_eq!(c.len(), 5);
    assert_eq!(c.points()[4], [0.5, 0.25, -1.5]);
    assert!(!shape.is_solid());
    assert_eq!(shape.volume(), None);
    assert_eq!(shape.contains(&[[0.0; 3]]), None);
    assert_eq!(
        shape.bounding_box(),
        Aabb {
            min: [0.0, 0.0, -1.5],
            max: [1.0, 2.0, 3.0]
        }
    );
    assert_eq!(shape.render_points().unwrap(), c.points());
    let direct = read_ply(&data("points_ascii.ply"), &closed()).unwrap();
    assert!(matches!(direct, Shape::PointCloud(d) if d.points() == c.points()));
}

/// A binary 3D Gaussian splat file, built byte by byte here (not with our writer).
fn splat_bytes(xyz: &[Point3]) -> Vec<u8> {
    let mut props = vec![
        "x", "y", "z", "nx", "ny", "nz", "f_dc_0", "f_dc_1", "f_dc_2",
    ];
    let rest: Vec<String> = (0..45).map(|i| format!("f_rest_{i}")).collect();
    props.extend(rest.iter().map(String::as_str));
    props.extend([
        "opacity", "scale_0", "scale_1", "scale_2", "rot_0", "rot_1", "rot_2", "rot_3",
    ]);
    let mut out = format!(
        "ply\nformat binary_little_endian 1.0\nelement vertex {}\n",
        xyz.len()
    );
    for p in &props {
        out.push_str(&format!("property float {p}\n"));
    }
    out.push_str("end_header\n");
    let mut bytes = out.into_bytes();
    for (i, p) in xyz.iter().enumerate() {
        for (k, _) in props.iter().enumerate() {
            let v = if k < 3 {
                p[k] as f32
            } else {
                (i * 1000 + k) as f32 * 0.5
            };
            bytes.extend_from_slice(&v.to_le_bytes());
        }
    }
    bytes
}

#[test]
fn gaussian_splat_ply_reads_xyz_exactly_and_skips_the_rest() {
    // Checked-in file: 4 splats, 17 float properties.
    let shape = parse(&data("splats_3dgs_tiny.ply")).unwrap();
    let Shape::PointCloud(c) = shape else {
        panic!("not a point cloud")
    };
    assert_eq!(
        c.points(),
        &[
            [0.5, -1.25, 3.0],
            [0.125, 2.0, -0.75],
            [-4.5, 0.0625, 1.5],
            [1.0, 1.0, 1.0]
        ]
    );
    // Generated: full 62-property layout, values that are exact in f32.
    let mut rng = SplitMix64::new(5);
    let xyz: Vec<Point3> = (0..500)
        .map(|_| point_in(&mut rng, -10.0, 10.0).map(|x| x as f32 as f64))
        .collect();
    let dir = tmp();
    let p = write(dir.path(), "scene.ply", &splat_bytes(&xyz));
    assert_eq!(read_ply_points(&p).unwrap().points(), &xyz[..]);
    // Truncating the payload mid-record is reported, not panicked on.
    let bytes = splat_bytes(&xyz);
    let cut = write(dir.path(), "cut.ply", &bytes[..bytes.len() - 100]);
    expect_parse_error(&cut, "PLY");
}

/// Three-vertex ASCII PLY point cloud (`float` x y z) whose second vertex
/// line (file line 10) is `bad`.
fn ascii_points_with(bad: &str) -> Vec<u8> {
    format!(
        "ply\nformat ascii 1.0\ncomment three points\nelement vertex 3\nproperty float x\n\
         property float y\nproperty float z\nend_header\n0 0 0\n{bad}\n1 1 1\n"
    )
    .into_bytes()
}

/// The reason of a `GeometryError::Parse` for `bytes` written to `name`, checking the path.
fn parse_reason(name: &str, bytes: &[u8]) -> String {
    let dir = tmp();
    let p = write(dir.path(), name, bytes);
    match parse(&p) {
        Err(GeometryError::Parse { path, reason }) => {
            assert_eq!(path, p);
            reason
        }
        other => panic!("{name}: expected a Parse error, got {other:?}"),
    }
}

#[test]
fn ply_ascii_non_numbers_name_the_line_vertex_and_value() {
    // The header has 8 lines, so vertex 1 is on line 10. Expected texts written out by hand.
    for (line, expected) in [
        (
            "nan 1 1",
            "PLY line 10: vertex 1 has a non-finite coordinate x = 'nan'; remove or fix that vertex",
        ),
        (
            "1 -inf 1",
            "PLY line 10: vertex 1 has a non-finite coordinate y = '-inf'; remove or fix that \
             vertex",
        ),
        (
            "1 1 NaN",
            "PLY line 10: vertex 1 has a non-finite coordinate z = 'NaN'; remove or fix that vertex",
        ),
        (
            "1 abc 1",
            "PLY line 10: vertex 1 has a non-numeric coordinate y = 'abc'; remove or fix that \
             vertex",
        ),
        // Valid grammar, but beyond f32: ply-rs-bw reads it as infinity.
        (
            "1e39 1 1",
            "PLY line 10: vertex 1 has a non-finite coordinate x = '1e39'; remove or fix that \
             vertex",
        ),
        (
            "1 1",
            "PLY line 10: vertex 1 ends before its property z; give every vertex all 3 properties",
        ),
    ] {
        let reason = parse_reason("bad_vertex.ply", &ascii_points_with(line));
        assert_eq!(reason, expected, "line `{line}`");
    }
    // A bad face index is named the same way (9 header lines, 4 vertices: face 1 is line 15).
    let mesh = "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\n\
                property float z\nelement face 2\nproperty list uchar int vertex_indices\n\
                end_header\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n3 0 2 1\n3 0 one 3\n";
    assert_eq!(
        parse_reason("bad_face.ply", mesh.as_bytes()),
        "PLY line 15: face 1 has a non-numeric value vertex_indices = 'one'; remove or fix that \
         face"
    );
    // The same file with good numbers still reads (the check is not over-eager).
    let dir = tmp();
    let good = write(dir.path(), "good.ply", &ascii_points_with("0.5 -2 3e2"));
    let cloud = read_ply_points(&good).unwrap();
    assert_eq!(cloud.points()[1], [0.5, -2.0, 300.0]);
}

/// Binary little-endian PLY point cloud with `double` coordinates, built byte by byte.
fn binary_points(points: &[Point3]) -> Vec<u8> {
    let mut bytes = format!(
        "ply\nformat binary_little_endian 1.0\nelement vertex {}\nproperty double x\n\
         property double y\nproperty double z\nend_header\n",
        points.len()
    )
    .into_bytes();
    for p in points {
        for c in p {
            bytes.extend_from_slice(&c.to_le_bytes());
        }
    }
    bytes
}

#[test]
fn ply_binary_nan_names_the_vertex_axis_and_value() {
    let mut points = vec![
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.0, 0.0, 1.0],
    ];
    points[2][2] = f64::NAN;
    assert_eq!(
        parse_reason("nan.ply", &binary_points(&points)),
        "PLY vertex 2 has a non-finite coordinate z = NaN; remove or fix that vertex"
    );
    points[2][2] = 0.0;
    points[3][0] = f64::NEG_INFINITY;
    assert_eq!(
        parse_reason("inf.ply", &binary_points(&points)),
        "PLY vertex 3 has a non-finite coordinate x = -inf; remove or fix that vertex"
    );
    // Our own float writer: a NaN point written as binary `float` is caught on reading too.
    let dir = tmp();
    let p = dir.path().join("written.ply");
    write_ply_points(&p, &[[0.0; 3], [f64::NAN, 1.0, 2.0]], &[]).unwrap();
    match read_ply_points(&p) {
        Err(GeometryError::Parse { reason, .. }) => assert_eq!(
            reason,
            "PLY vertex 1 has a non-finite coordinate x = NaN; remove or fix that vertex"
        ),
        other => panic!("expected a Parse error, got {other:?}"),
    }
}

#[test]
fn ply_writer_round_trips_and_validates() {
    let dir = tmp();
    let pts: Vec<Point3> = vec![[0.1, 0.2, 0.3], [1.0, -2.0, 3.5], [1e-3, 4e3, -7.25]];
    let opacity = [0.5, 0.25, 1.0];
    let scale = [-1.0, -2.0, -3.0];
    let p = dir.path().join("frame.ply");
    write_ply_points(&p, &pts, &[("opacity", &opacity), ("scale_0", &scale)]).unwrap();
    let header = std::fs::read(&p).unwrap();
    let text = String::from_utf8_lossy(&header);
    assert!(text.contains("format binary_little_endian 1.0"));
    assert!(text.contains("property float opacity\nproperty float scale_0\nend_header"));
    let back = read_ply_points(&p).unwrap();
    for (a, b) in back.points().iter().zip(&pts) {
        for k in 0..3 {
            assert_eq!(a[k], b[k] as f32 as f64);
        }
    }
    for (format, scalar) in [
        (PlyFormat::Ascii, PlyScalar::Double),
        (PlyFormat::BinaryLittleEndian, PlyScalar::Double),
    ] {
        write_ply_points_with(
            &p,
            &pts,
            &[("t", &opacity)],
            PlyWriteOptions { format, scalar },
        )
        .unwrap();
        assert_eq!(read_ply_points(&p).unwrap().points(), &pts[..]);
    }
    let invalid =
        |r: Result<(), GeometryError>| assert!(matches!(r, Err(GeometryError::InvalidInput(_))));
    invalid(write_ply_points(&p, &pts, &[("opacity", &opacity[..2])]));
    invalid(write_ply_points(&p, &pts, &[("x", &opacity)]));
    invalid(write_ply_points(&p, &pts, &[("a b", &opacity)]));
    invalid(write_ply_points(
        &p,
        &pts,
        &[("o", &opacity), ("o", &scale)],
    ));
    let unwritable = dir.path().join("no/such/dir/out.ply");
    assert!(matches!(
        write_ply_points(&unwritable, &pts, &[]),
        Err(GeometryError::Io { .. })
    ));
}

// ---------------------------------------------------------------------------------------------
// readers: bad files

#[test]
fn bad_files_give_the_right_error() {
    let dir = tmp();
    let d = dir.path();
    let (cv, ct) = generate::box_mesh([1.0, 1.0, 1.0]);

    // Empty and garbage files of every kind.
    for name in ["empty.obj", "empty.stl", "empty.ply"] {
        expect_parse_error(&write(d, name, b""), "empty file");
    }
    expect_parse_error(
        &write(d, "bin.obj", &[0xff, 0xfe, 0x00, 0x81, 0x92]),
        "invalid UTF-8",
    );
    expect_parse_error(&data("garbage.stl"), "STL");
    expect_parse_error(&write(d, "garbage.ply", &[7u8; 300]), "PLY");
    expect_parse_error(&write(d, "text.stl", b"hello, this is not an STL file at all; it is plain text that goes on and on and on and on and on."), "neither ASCII STL");
    expect_parse_error(&write(d, "short.stl", b"\x01\x02"), "too short");

    // OBJ content errors carry the line number.
    expect_parse_error(
        &write(d, "nan.obj", b"v 0 0 0\nv 1 0 nan\nv 0 1 0\nf 1 2 3\n"),
        "line 2: non-finite",
    );
    expect_parse_error(
        &write(d, "short_v.obj", b"v 0 0\n"),
        "line 1: vertex needs 3 coordinates",
    );
    expect_parse_error(
        &write(d, "word.obj", b"v 0 0 zero\n"),
        "`zero` is not a number",
    );
    expect_parse_error(
        &write(d, "range.obj", b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n"),
        "line 4: face refers to vertex 4, but only 3",
    );
    expect_parse_error(
        &write(d, "zero.obj", b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n"),
        "vertex 0",
    );
    expect_parse_error(
        &write(
            d,
            "neg.obj",
            b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf -1 -2 -9223372036854775808\n",
        ),
        "vertex -9223372036854775808",
    );
    expect_parse_error(
        &write(
            d,
            "huge.obj",
            b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 99999999999999999999999\n",
        ),
        "bad face vertex",
    );
    expect_parse_error(
        &write(d, "vt.obj", b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1/5 2/1 3/1\n"),
        "texture coordinate 5",
    );
    expect_parse_error(
        &write(d, "two.obj", b"v 0 0 0\nv 1 0 0\nf 1 2\n"),
        "face has 2 vertices",
    );
    expect_parse_error(
        &write(d, "noface.obj", b"v 0 0 0\nv 1 0 0\nv 0 1 0\n"),
        "no faces (3 vertices)",
    );
    expect_parse_error(
        &write(d, "f32.obj", b"v 0 0 0\nv 1 0 0\nv 0 1e400 0\nf 1 2 3\n"),
        "non-finite",
    );

    // STL content errors.
    let p = d.join("nan_ascii.stl");
    write_stl(&p, &cv, &ct, StlFormat::Ascii).unwrap();
    let text = std::fs::read_to_string(&p).unwrap();
    let first_vertex = text
        .lines()
        .find(|l| l.trim_start().starts_with("vertex"))
        .unwrap()
        .to_string();
    std::fs::write(&p, text.replacen(&first_vertex, "vertex nan 0 0", 1)).unwrap();
    expect_parse_error(&p, "STL triangle 0");
    std::fs::write(&p, &text[..text.len() / 2]).unwrap();
    expect_parse_error(&p, "STL triangle");
    let p = d.join("bin.stl");
    write_stl(&p, &cv, &ct, StlFormat::Binary).unwrap();
    let full = std::fs::read(&p).unwrap();
    expect_parse_error(&write(d, "trunc.stl", &full[..full.len() - 10]), "truncated binary STL: the header declares 12 triangles (684 bytes), the file has 674 bytes");
    let mut nan = full.clone();
    nan[84 + 50 * 3 + 16..84 + 50 * 3 + 20].copy_from_slice(&f32::NAN.to_le_bytes());
    expect_parse_error(
        &write(d, "nan_bin.stl", &nan),
        "STL triangle 3 has a non-finite",
    );
    let mut zero = full[..84].to_vec();
    zero[80..84].copy_from_slice(&0u32.to_le_bytes());
    expect_parse_error(&write(d, "zero.stl", &zero), "no triangles");
    let mut long = full.clone();
    long.extend_from_slice(&[0u8; 7]);
    expect_parse_error(&write(d, "long.stl", &long), "trailing data");

    // PLY content errors.
    let ply = |body: &str| format!("ply\nformat ascii 1.0\n{body}");
    let hdr = "element vertex 3\nproperty float x\nproperty float y\nproperty float z\n";
    expect_parse_error(
        &write(
            d,
            "few.ply",
            ply(&format!("{hdr}end_header\n0 0 0\n1 0 0\n")).as_bytes(),
        ),
        "PLY",
    );
    expect_parse_error(
        &write(
            d,
            "nan.ply",
            ply(&format!("{hdr}end_header\n0 0 0\n1 nan 0\n0 1 0\n")).as_bytes(),
        ),
        "PLY",
    );
    let p = d.join("nan_bin.ply");
    write_ply_points(&p, &[[0.0; 3], [1.0, f64::NAN, 0.0]], &[]).unwrap();
    expect_parse_error(&p, "PLY vertex 1 has a non-finite");
    expect_parse_error(
        &write(
            d,
            "noz.ply",
            ply("element vertex 1\nproperty float x\nproperty float y\nend_header\n0 0\n")
                .as_bytes(),
        ),
        "no `z` property",
    );
    expect_parse_error(
        &write(
            d,
            "novert.ply",
            ply("element point 1\nproperty float x\nend_header\n0\n").as_bytes(),
        ),
        "no `vertex` element",
    );
    let faces = |f: &str| {
        ply(&format!("{hdr}element face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n{f}\n"))
    };
    expect_parse_error(
        &write(d, "frange.ply", faces("3 0 1 3").as_bytes()),
        "face 0 refers to vertex 3, but the file has 3",
    );
    expect_parse_error(
        &write(d, "fneg.ply", faces("3 0 -1 2").as_bytes()),
        "refers to vertex -1",
    );
    expect_parse_error(
        &write(d, "ftwo.ply", faces("2 0 1").as_bytes()),
        "face 0 has 2 vertices",
    );
    expect_parse_error(&write(d, "fcount.ply", faces("4 0 1 2").as_bytes()), "PLY");
    expect_parse_error(
        &write(
            d,
            "nolist.ply",
            ply(&format!(
                "{hdr}element face 1\nproperty int a\nend_header\n0 0 0\n1 0 0\n0 1 0\n5\n"
            ))
            .as_bytes(),
        ),
        "no `vertex_indices`",
    );
    expect_parse_error(
        &write(
            d,
            "header.ply",
            b"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\n",
        ),
        "PLY",
    );
    let p = d.join("bin_mesh.ply");
    write_ply_mesh(&p, &cv, &ct, PlyWriteOptions::default()).unwrap();
    let full = std::fs::read(&p).unwrap();
    expect_parse_error(&write(d, "trunc.ply", &full[..full.len() - 5]), "PLY");
    let mut bad_idx = full.clone();
    let n = bad_idx.len();
    bad_idx[n - 4..].copy_from_slice(&1000i32.to_le_bytes());
    expect_parse_error(&write(d, "bad_idx.ply", &bad_idx), "refers to vertex 1000");
    // An empty point cloud is degenerate.
    match parse(&write(
        d,
        "nopoints.ply",
        ply("element vertex 0\nproperty float x\nproperty float y\nproperty float z\nend_header\n")
            .as_bytes(),
    )) {
        Err(GeometryError::Degenerate(msg)) => assert!(
            msg.contains("nopoints.ply") && msg.contains("no points"),
            "{msg}"
        ),
        other => panic!("{other:?}"),
    }
    // A flat closed mesh (two back-to-back triangles) encloses nothing.
    let p = d.join("flat.obj");
    std::fs::write(&p, "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nf 1 3 2\n").unwrap();
    match parse(&p) {
        Err(GeometryError::Degenerate(msg)) => assert!(
            msg.contains("flat.obj") && msg.contains("no volume"),
            "{msg}"
        ),
        other => panic!("{other:?}"),
    }
    // Not a file: a directory with a mesh extension, and a missing file.
    let sub = d.join("dir.stl");
    std::fs::create_dir(&sub).unwrap();
    for p in [sub, d.join("missing.ply"), d.join("missing.obj")] {
        assert!(
            matches!(parse(&p), Err(GeometryError::Io { .. })),
            "{}",
            p.display()
        );
    }
}

/// Mutated copies of valid files (truncated, bytes flipped, bytes inserted, numbers replaced)
/// must give `Ok` or an error, never a panic.
#[test]
fn hostile_files_never_panic() {
    let dir = tmp();
    let d = dir.path();
    let (v, t) = generate::icosphere(1.0, 1);
    let mut seeds: Vec<(&str, Vec<u8>)> = vec![];
    for (ext, f) in [("obj", 0), ("stl", 1), ("stl", 2), ("ply", 3), ("ply", 4)] {
        let p = d.join(format!("seed{f}.{ext}"));
        match f {
            0 => write_obj(&p, &v, &t).unwrap(),
            1 => write_stl(&p, &v, &t, StlFormat::Ascii).unwrap(),
            2 => write_stl(&p, &v, &t, StlFormat::Binary).unwrap(),
            3 => write_ply_mesh(
                &p,
                &v,
                &t,
                PlyWriteOptions {
                    format: PlyFormat::Ascii,
                    scalar: PlyScalar::Float,
                },
            )
            .unwrap(),
            _ => write_ply_mesh(&p, &v, &t, PlyWriteOptions::default()).unwrap(),
        }
        seeds.push((ext, std::fs::read(&p).unwrap()));
    }
    seeds.push(("ply", splat_bytes(&[[1.0, 2.0, 3.0], [4.0, 5.0, 6.0]])));
    seeds.push(("obj", std::fs::read(data("cube_quads.obj")).unwrap()));
    seeds.push(("off", std::fs::read(data("cube_quads.off")).unwrap()));
    let tokens: [&[u8]; 10] = [
        b"-1",
        b"0",
        b"nan",
        b"1e999",
        b"4294967295",
        b"-2147483648",
        b"\n",
        b" ",
        b"/",
        b"f",
    ];
    let mut rng = SplitMix64::new(2024);
    let mut outcomes = [0usize; 2];
    for case in 0..1200 {
        let (ext, seed) = &seeds[case % seeds.len()];
        let mut b = seed.clone();
        for _ in 0..1 + rng.below(4) {
            if b.is_empty() {
                break;
            }
            let at = rng.below(b.len());
            match rng.below(5) {
                0 => b.truncate(at),
                1 => b[at] = rng.below(256) as u8,
                2 => b.insert(at, rng.below(256) as u8),
                3 => {
                    let tok = tokens[rng.below(tokens.len())];
                    let end = (at + 1 + rng.below(6)).min(b.len());
                    b.splice(at..end, tok.iter().copied());
                }
                _ => {
                    // Overwrite 4 bytes with an extreme little-endian count or float.
                    let word: [u8; 4] = match rng.below(3) {
                        0 => u32::MAX.to_le_bytes(),
                        1 => f32::NAN.to_le_bytes(),
                        _ => 0x7fff_fff0u32.to_le_bytes(),
                    };
                    for (k, w) in word.iter().enumerate() {
                        if at + k < b.len() {
                            b[at + k] = *w;
                        }
                    }
                }
            }
        }
        let p = write(d, &format!("case{case}.{ext}"), &b);
        let ok = read_shape(p.to_str().unwrap(), &open_ok()).is_ok();
        outcomes[ok as usize] += 1;
    }
    eprintln!(
        "hostile files: {} rejected, {} accepted",
        outcomes[0], outcomes[1]
    );
    assert!(outcomes[0] > 100);
}

#[test]
fn surface_probes_lie_on_the_surface_and_leave_no_gap() {
    let size = [2.0, 1.0, 0.5];
    let h = 0.1;
    let b = Shape::Box { size }.surface_probes(h);
    // Every probe on a face; the 8 corners in; the nodes 0.1 apart on each axis, so a 21 x 11
    // x 6 grid: all nodes minus the 19 x 9 x 4 inside.
    assert_eq!(b.len(), 21 * 11 * 6 - 19 * 9 * 4);
    for p in &b {
        let on_face = (0..3).any(|a| p[a] == 0.0 || p[a] == size[a]);
        let inside = (0..3).all(|a| p[a] >= 0.0 && p[a] <= size[a]);
        assert!(on_face && inside, "{p:?}");
    }
    for c in 0..8 {
        let corner = [0, 1, 2].map(|a| if c >> a & 1 == 1 { size[a] } else { 0.0 });
        assert!(b.contains(&corner), "{corner:?}");
    }
    // The sphere's lattice: on the sphere, about one point per h^2 of surface, and no point of
    // the surface farther than h from a probe (checked on random directions).
    let r = 0.7;
    let s = Shape::Sphere { radius: r }.surface_probes(h);
    let area = 4.0 * PI * r * r;
    assert_eq!(s.len(), (area / (h * h)).ceil() as usize);
    for p in &s {
        assert!(((p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt() - r).abs() < 1e-12);
    }
    let mut rng = SplitMix64::new(5);
    for _ in 0..200 {
        let d = point_in(&mut rng, -1.0, 1.0);
        let n = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
        let q = d.map(|x| r * x / n);
        let gap = s
            .iter()
            .map(|p| ((p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2) + (p[2] - q[2]).powi(2)).sqrt())
            .fold(f64::INFINITY, f64::min);
        assert!(gap < h, "{q:?}: nearest probe {gap}");
    }
    // A mesh: its vertices, then grids on its faces; every probe on a face, and no point of
    // a face farther than h from a probe (random points on each face). The tetrahedron's
    // edges are 1 to 2.2 m, so each face gets a grid of 10 to 22 divisions per edge.
    let vertices: Vec<[f64; 3]> = vec![
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.2, 0.2, 2.0],
    ];
    let triangles = vec![[0, 2, 1], [0, 1, 3], [1, 2, 3], [2, 0, 3]];
    let mesh = freeform::geometry::TriMesh::new(
        vertices.clone(),
        triangles.clone(),
        &freeform::geometry::ShapeOptions::default(),
    )
    .unwrap();
    let m = Shape::Mesh(mesh).surface_probes(h);
    assert_eq!(&m[..4], &vertices[..]);
    let sub = |a: [f64; 3], b: [f64; 3]| [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
    let dist = |a: [f64; 3], b: [f64; 3]| {
        let d = sub(a, b);
        (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt()
    };
    let faces: Vec<[[f64; 3]; 3]> = triangles
        .iter()
        .map(|t: &[u32; 3]| t.map(|i| vertices[i as usize]))
        .collect();
    // On a face: inside its plane and triangle (barycentric coordinates from least squares on
    // the two edge vectors; 1e-12 is round-off on unit-size coordinates).
    let on_face = |p: [f64; 3], f: &[[f64; 3]; 3]| {
        let (e1, e2, d) = (sub(f[1], f[0]), sub(f[2], f[0]), sub(p, f[0]));
        let dot = |a: [f64; 3], b: [f64; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
        let (a11, a12, a22) = (dot(e1, e1), dot(e1, e2), dot(e2, e2));
        let (b1, b2) = (dot(d, e1), dot(d, e2));
        let det = a11 * a22 - a12 * a12;
        let (u, v) = ((b1 * a22 - b2 * a12) / det, (a11 * b2 - a12 * b1) / det);
        let q = [0, 1, 2].map(|c| f[0][c] + u * e1[c] + v * e2[c]);
        dist(p, q) < 1e-12 && u >= -1e-12 && v >= -1e-12 && u + v <= 1.0 + 1e-12
    };
    for p in &m {
        assert!(faces.iter().any(|f| on_face(*p, f)), "{p:?}");
    }
    for f in &faces {
        for _ in 0..100 {
            let (mut u, mut v) = (rng.next_f64(), rng.next_f64());
            if u + v > 1.0 {
                (u, v) = (1.0 - u, 1.0 - v);
            }
            let q = [0, 1, 2].map(|c| f[0][c] + u * (f[1][c] - f[0][c]) + v * (f[2][c] - f[0][c]));
            let gap = m.iter().map(|p| dist(*p, q)).fold(f64::INFINITY, f64::min);
            assert!(gap < h, "{q:?}: nearest probe {gap}");
        }
    }
    // A spacing that is not positive and finite gives none.
    assert!(Shape::Box { size }.surface_probes(0.0).is_empty());
    assert!(Shape::Box { size }.surface_probes(f64::NAN).is_empty());
}
