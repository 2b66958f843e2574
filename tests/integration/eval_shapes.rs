//! The real-shape protocol (issue 18, `freeform::benchmark::shapes`): normalization, the
//! regions of the three boundary conditions, TetGen failures, the FEM reference's boundary
//! values, and one tiny shape end to end. Tests that need the `tetgen` program skip with a
//! printed reason when it is not installed (.ci/run installs it before the tests).

use freeform::benchmark::shapes::eval::fem_surface;
use freeform::benchmark::shapes::protocol::{
    boundary_regions, farthest_vertices, normalize, Protocol, ShapeTest,
};
use freeform::benchmark::shapes::reference::{run_shape_reference, shared_node_difference};
use freeform::benchmark::shapes::report::{evaluate_dir, shape_files};
use freeform::benchmark::shapes::tetgen::{tetrahedralize, TetgenOptions};
use freeform::benchmark::shapes::EvalOptions;
use freeform::fem::solver::FemParams;
use freeform::fem::{ElementOrder, FemError};
use freeform::geometry::generate::{box_mesh, icosphere};
use freeform::material::{Material, MaterialOverride, Region};
use freeform::precompute::sampling::Resolution;
use freeform::progress::Silent;
use freeform::sim::motion::Motion;
use freeform::Point3;
use std::path::Path;

fn tetgen_installed() -> bool {
    let ok = std::process::Command::new("tetgen")
        .arg("-h")
        .output()
        .is_ok();
    if !ok {
        eprintln!("skipping: the `tetgen` program is not installed (apt-get install tetgen)");
    }
    ok
}

fn dist(a: &Point3, b: &Point3) -> f64 {
    (0..3).map(|k| (a[k] - b[k]).powi(2)).sum::<f64>().sqrt()
}

#[test]
fn normalization_gives_a_unit_bounding_box_on_the_longest_axis() {
    let (v, t) = box_mesh([2.0, 4.0, 1.0]);
    let moved: Vec<Point3> = v
        .iter()
        .map(|p| [p[0] - 3.0, p[1] + 7.0, p[2] * 1.0])
        .collect();
    let s = normalize(&moved, &t).unwrap();
    assert_eq!(s.longest_axis, 1);
    assert_eq!(s.scale, 4.0);
    // Exact: the corners are 0 or the side, divided by a power of two.
    assert_eq!(s.extent, [0.5, 1.0, 0.25]);
    for d in 0..3 {
        let lo = s
            .vertices
            .iter()
            .map(|p| p[d])
            .fold(f64::INFINITY, f64::min);
        let hi = s
            .vertices
            .iter()
            .map(|p| p[d])
            .fold(f64::NEG_INFINITY, f64::max);
        assert_eq!((lo, hi), (0.0, s.extent[d]));
    }
    let flat = vec![[1.0, 1.0, 1.0]; 3];
    let err = normalize(&flat, &[[0, 1, 2]]).unwrap_err().to_string();
    assert!(err.contains("all vertices coincide"), "{err}");
}

#[test]
fn slabs_sit_at_the_ends_of_the_longest_axis() {
    let (v, t) = box_mesh([0.3, 0.2, 2.0]);
    let s = normalize(&v, &t).unwrap();
    assert_eq!(s.longest_axis, 2);
    let p = Protocol::default();
    let at = |z: f64| [0.05, 0.05, z];
    let fix = boundary_regions(&p, &s, ShapeTest::FixSide);
    assert_eq!(fix.len(), 1);
    assert_eq!(fix[0].1, Motion::Fixed);
    // The slab is exactly `slab` thick (boundary included, a hair beyond excluded).
    assert!(fix[0].0.contains(&at(0.0)) && fix[0].0.contains(&at(p.slab)));
    assert!(!fix[0].0.contains(&at(p.slab + 1e-9)));
    let ends = boundary_regions(&p, &s, ShapeTest::PullEnds);
    assert_eq!(ends.len(), 2);
    assert!(ends[0].0.contains(&at(0.0)) && !ends[0].0.contains(&at(p.slab + 1e-9)));
    assert!(ends[1].0.contains(&at(1.0)) && !ends[1].0.contains(&at(1.0 - p.slab - 1e-9)));
    // Pulled apart along the axis at the protocol's speed.
    let v0 = ends[0].1.at(1.0).translation;
    let v1 = ends[1].1.at(1.0).translation;
    assert_eq!(v0, [0.0, 0.0, -p.pull_speed]);
    assert_eq!(v1, [0.0, 0.0, p.pull_speed]);
}

#[test]
fn farthest_points_are_spread_surface_vertices_pulled_outwards() {
    let r = 2.0;
    let (v, t) = icosphere(r, 2);
    let s = normalize(&v, &t).unwrap();
    let picked = farthest_vertices(&s, 4);
    assert_eq!(picked.len(), 4);
    // The sphere's centre and radius after normalization (the origin mapped like a vertex).
    let lo: Vec<f64> = (0..3)
        .map(|d| v.iter().map(|p| p[d]).fold(f64::INFINITY, f64::min))
        .collect();
    let centre = [0, 1, 2].map(|d| -lo[d] / s.scale);
    let radius = r / s.scale;
    for &i in &picked {
        // On the surface: icosphere vertices lie on the sphere up to round-off.
        assert!((dist(&s.vertices[i], &centre) - radius).abs() < 1e-12 * radius);
    }
    // Greedy farthest-point property, checked by brute force: every pick after the first
    // maximizes the distance to the picks before it.
    for k in 1..4 {
        let d_to = |p: &Point3| {
            picked[..k]
                .iter()
                .map(|&j| dist(p, &s.vertices[j]))
                .fold(f64::INFINITY, f64::min)
        };
        let best = s.vertices.iter().map(d_to).fold(0.0, f64::max);
        assert_eq!(d_to(&s.vertices[picked[k]]), best);
    }
    // Far apart: continuous FPS on a sphere gives a pairwise minimum of sqrt(2) R; the
    // 2-subdivision icosphere's vertices are within half an edge (< 0.17 R) of any surface
    // point, so at least sqrt(2) R - 2 x 0.17 R > 1.05 R.
    for a in 0..4 {
        for b in a + 1..4 {
            let d = dist(&s.vertices[picked[a]], &s.vertices[picked[b]]);
            assert!(d > 1.05 * radius, "picks {a}, {b} only {d} apart");
        }
    }
    // Pulled outwards: each ball moves away from the centre, at the protocol's speed.
    let p = Protocol::default();
    for (region, motion) in boundary_regions(&p, &s, ShapeTest::PullFarthest) {
        let Region::Sphere { center, radius: rr } = region else {
            panic!("expected balls, got {region:?}");
        };
        assert_eq!(rr, p.ball_radius);
        let v = motion.at(1.0).translation;
        let out = [0, 1, 2].map(|k| center[k] - s.extent[k] / 2.0);
        assert!((0..3).map(|k| v[k] * out[k]).sum::<f64>() > 0.0);
        assert!((dist(&v, &[0.0; 3]) - p.pull_speed).abs() < 1e-12);
    }
}

#[test]
fn a_missing_or_failing_tetgen_is_a_clear_error() {
    let dir = tempfile::tempdir().unwrap();
    let (v, t) = box_mesh([1.0; 3]);
    let missing = TetgenOptions {
        program: "/nonexistent/tetgen".into(),
        ..TetgenOptions::default()
    };
    let e = tetrahedralize(&v, &t, &missing, dir.path(), "box").unwrap_err();
    assert!(matches!(e, FemError::Mesher(_)), "{e}");
    assert!(e.to_string().contains("was not found"), "{e}");
    // `false` exits 1 without output: reported as a failure with TetGen's (empty) message.
    let failing = TetgenOptions {
        program: "false".into(),
        ..TetgenOptions::default()
    };
    let e = tetrahedralize(&v, &t, &failing, dir.path(), "box").unwrap_err();
    assert!(e.to_string().contains("failed (exit status: 1)"), "{e}");
    let bad = TetgenOptions {
        max_volume: -1.0,
        ..TetgenOptions::default()
    };
    let e = tetrahedralize(&v, &t, &bad, dir.path(), "box").unwrap_err();
    assert!(e.to_string().contains("largest tet volume"), "{e}");
    if !tetgen_installed() {
        return;
    }
    // An open surface (one face removed): TetGen writes no tetrahedra.
    let e =
        tetrahedralize(&v, &t[..10], &TetgenOptions::default(), dir.path(), "open").unwrap_err();
    assert!(e.to_string().contains("wrote no tetrahedra"), "{e}");
}

/// The FEM reference holds and moves exactly the nodes of the protocol's regions.
#[test]
fn fem_reference_follows_the_regions() {
    if !tetgen_installed() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let (v, t) = box_mesh([1.0, 0.4, 0.3]);
    let s = normalize(&v, &t).unwrap();
    let tg = TetgenOptions {
        max_volume: 0.01,
        ..TetgenOptions::default()
    };
    let mesh = tetrahedralize(&s.vertices, &s.triangles, &tg, dir.path(), "box").unwrap();
    let p = Protocol {
        steps: 3,
        ..Protocol::default()
    };
    let fem = FemParams::default();
    let r =
        run_shape_reference(&mesh, &p, &s, ShapeTest::PullEnds, &[], &fem, None, &Silent).unwrap();
    let regions = boundary_regions(&p, &s, ShapeTest::PullEnds);
    let mut driven = 0;
    for (a, x0) in r.rest.iter().enumerate() {
        if let Some((_, m)) = regions.iter().find(|(reg, _)| reg.contains(x0)) {
            driven += 1;
            for (n, frame) in r.frames.iter().enumerate() {
                let want = m.at((n + 1) as f64 * p.dt).apply(x0);
                // Dirichlet values are set, not solved: exact up to the one addition.
                assert!(dist(&frame[a], &want) < 1e-14, "node {a} frame {n}");
            }
        }
    }
    assert!(driven >= 8, "the end slabs hold the box's corners at least");
    // A reference against itself differs by exactly nothing on every node.
    let (e, shared) = shared_node_difference(&r, &r).unwrap();
    assert_eq!((e.normalized_mse, shared), (0.0, r.rest.len()));
}

/// Material overrides reach the FEM reference: an override that repeats the base material
/// changes nothing (the same Lame values, so the same bits), and a half 100x stiffer drags
/// the middle of a bar pulled at both ends towards its own end, which the homogeneous bar's
/// symmetry keeps still.
#[test]
fn fem_reference_takes_material_overrides() {
    if !tetgen_installed() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    // Faces split three times: TetGen's -Y adds no node on the surface, and a 12-triangle bar this
    // thin gets no node inside either.
    let (mut v, mut t) = box_mesh([1.0, 0.2, 0.2]);
    for _ in 0..3 {
        (v, t) = split_in_four(&v, &t);
    }
    let s = normalize(&v, &t).unwrap();
    let tg = TetgenOptions {
        max_volume: 2e-4,
        ..TetgenOptions::default()
    };
    let mesh = tetrahedralize(&s.vertices, &s.triangles, &tg, dir.path(), "bar").unwrap();
    let p = Protocol {
        steps: 10,
        ..Protocol::default()
    };
    let fem = FemParams::default();
    let right_half = Region::Box {
        min: [0.5, -1.0, -1.0],
        max: [2.0, 2.0, 2.0],
    };
    let with = |overrides: &[MaterialOverride]| {
        run_shape_reference(
            &mesh,
            &p,
            &s,
            ShapeTest::PullEnds,
            overrides,
            &fem,
            None,
            &Silent,
        )
        .unwrap()
    };
    let homogeneous = with(&[]);
    let same = with(&[MaterialOverride {
        region: right_half,
        material: p.material,
    }]);
    assert_eq!(homogeneous.frames, same.frames);
    let stiff = with(&[MaterialOverride {
        region: right_half,
        material: Material {
            youngs: 100.0 * p.material.youngs,
            ..p.material
        },
    }]);
    // Mean x displacement in the last frame of the nodes within 0.1 m of the middle.
    let middle_shift = |r: &freeform::fem::beam::BeamReference| {
        let last = r.frames.last().unwrap();
        let picked: Vec<f64> = (0..r.rest.len())
            .filter(|&i| (r.rest[i][0] - 0.5).abs() < 0.1)
            .map(|i| last[i][0] - r.rest[i][0])
            .collect();
        assert!(picked.len() >= 4, "nodes near the middle");
        picked.iter().sum::<f64>() / picked.len() as f64
    };
    let end = p.pull_speed * p.steps as f64 * p.dt;
    // Homogeneous: zero up to the mesh's asymmetry (TetGen's mesh is not mirror-symmetric;
    // 1% of the end's displacement measured).
    assert!(
        middle_shift(&homogeneous).abs() < 0.05 * end,
        "{}",
        middle_shift(&homogeneous)
    );
    // Stiff right half: it moves nearly rigidly with its end (a quasi-static bar would put the
    // middle at 99/101 of the end's displacement, 96% measured; 75% leaves room for the
    // dynamics and the tets the interface cuts, and is far from the homogeneous 0).
    assert!(
        middle_shift(&stiff) > 0.75 * end,
        "{} of {end}",
        middle_shift(&stiff)
    );
}

/// The FEM mesh conforms to an inner surface: with a box's faces inside the bar as facets, no
/// tet has nodes strictly inside the box and strictly outside it; a triangle that refers past
/// its surface's vertices is refused with its index.
#[test]
fn fem_mesh_conforms_to_inner_surfaces() {
    if !tetgen_installed() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let (v, t) = box_mesh([1.0, 0.4, 0.4]);
    let (v, t) = split_in_four(&v, &t);
    let s = normalize(&v, &t).unwrap();
    let (lo, hi) = ([0.3, 0.1, 0.1], [0.7, 0.3, 0.3]);
    let (iv, it) = box_mesh([hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]]);
    // box_mesh starts at the origin: move it to [lo, hi].
    let iv: Vec<Point3> = iv
        .iter()
        .map(|p| [p[0] + lo[0], p[1] + lo[1], p[2] + lo[2]])
        .collect();
    let surface = fem_surface(&s, &[(iv.clone(), it.clone())]).unwrap();
    assert_eq!(surface.0.len(), s.vertices.len() + iv.len());
    let tg = TetgenOptions {
        max_volume: 1e-3,
        ..TetgenOptions::default()
    };
    let mesh = tetrahedralize(&surface.0, &surface.1, &tg, dir.path(), "inner").unwrap();
    // Which side of the inner box a node is on: -1 inside, 1 outside, 0 on it (1e-9 of the
    // unit box: TetGen's coordinates round-trip through its text files).
    let side = |p: &Point3| {
        let d = (0..3)
            .map(|k| (lo[k] - p[k]).max(p[k] - hi[k]))
            .fold(f64::NEG_INFINITY, f64::max);
        if d < -1e-9 {
            -1
        } else if d > 1e-9 {
            1
        } else {
            0
        }
    };
    let (mut inside, mut outside) = (0, 0);
    for tet in mesh.tets() {
        let sides: Vec<i32> = tet
            .iter()
            .map(|&i| side(&mesh.nodes()[i as usize]))
            .collect();
        assert!(
            !(sides.contains(&-1) && sides.contains(&1)),
            "a tet straddles the inner surface: {sides:?}"
        );
        if sides.iter().all(|&x| x <= 0) {
            inside += 1;
        } else {
            outside += 1;
        }
    }
    assert!(
        inside > 0 && outside > 0,
        "{inside} inside, {outside} outside"
    );
    let e = fem_surface(&s, &[(iv.clone(), vec![[0, 1, 99]])]).unwrap_err();
    assert!(e.to_string().contains("[0, 1, 99]"), "{e}");
    let mut nan = iv;
    nan[3][1] = f64::NAN;
    let e = fem_surface(&s, &[(nan, it)]).unwrap_err();
    assert!(e.to_string().contains("fem_interfaces"), "{e}");
}

/// Every triangle split in four at its edge midpoints (shared midpoints made once).
fn split_in_four(v: &[Point3], t: &[[u32; 3]]) -> (Vec<Point3>, Vec<[u32; 3]>) {
    let mut v = v.to_vec();
    let mut mid = std::collections::HashMap::new();
    let mut midpoint = |a: u32, b: u32, v: &mut Vec<Point3>| -> u32 {
        *mid.entry((a.min(b), a.max(b))).or_insert_with(|| {
            let (p, q) = (v[a as usize], v[b as usize]);
            v.push([
                0.5 * (p[0] + q[0]),
                0.5 * (p[1] + q[1]),
                0.5 * (p[2] + q[2]),
            ]);
            (v.len() - 1) as u32
        })
    };
    let mut out = Vec::with_capacity(4 * t.len());
    for &[a, b, c] in t {
        let (ab, bc, ca) = (
            midpoint(a, b, &mut v),
            midpoint(b, c, &mut v),
            midpoint(c, a, &mut v),
        );
        out.extend([[a, ab, ca], [ab, b, bc], [ca, bc, c], [ab, bc, ca]]);
    }
    (v, out)
}

#[test]
fn one_tiny_shape_end_to_end_gives_finite_metrics() {
    if !tetgen_installed() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let (v, t) = box_mesh([1.0, 0.4, 0.3]);
    freeform::io::off::write_off(&dir.path().join("slab.off"), &v, &t).unwrap();
    let mut opts = EvalOptions {
        modes: 4,
        kernels: 60,
        resolution: Some(Resolution::Count(3000)),
        ..EvalOptions::default()
    };
    opts.protocol.steps = 3;
    // Balls larger than the default 0.08 m: a 60-kernel basis has kernels ~0.1 m apart, and
    // the aware basis needs a kernel centre in every corner ball.
    opts.protocol.ball_radius = 0.2;
    opts.tetgen.max_volume = 0.01;
    opts.fem.order = ElementOrder::Linear;
    let files = shape_files(dir.path(), &[]).unwrap();
    let mut seen = Vec::new();
    let report = evaluate_dir(
        &files,
        &opts,
        None,
        &dir.path().join("tg"),
        &Silent,
        &mut |r| seen.push(r.shapes.len() + r.failures.len()),
    );
    assert_eq!(seen, vec![1], "one report after the one shape");
    assert!(report.failures.is_empty(), "{:?}", report.failures);
    let shape = &report.shapes[0];
    assert!(shape.failures.is_empty(), "{:?}", shape.failures);
    assert_eq!(shape.runs.len(), 6, "3 tests x 2 bases");
    for r in &shape.runs {
        for x in [
            r.normalized_mse,
            r.max_error,
            r.fit_mse,
            r.fit_max,
            r.precompute_s,
        ] {
            assert!(x.is_finite() && x >= 0.0, "{r:?}");
        }
        // The least-squares fit onto the basis is the best the basis can do at the FEM
        // nodes, so it never exceeds the simulation's error (frame by frame; the means
        // follow). 1e-12 relative: round-off of the two sums.
        assert!(r.fit_mse <= r.normalized_mse * (1.0 + 1e-12), "{r:?}");
    }
    assert_eq!(report.averages.len(), 6);
    let csv = report.to_csv();
    assert_eq!(csv.lines().count(), 1 + 6, "{csv}");
}

#[test]
fn bad_shapes_are_listed_with_their_reason_and_the_others_go_on() {
    let dir = tempfile::tempdir().unwrap();
    let data = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/bad");
    std::fs::copy(
        data.join("off/open_box.off"),
        dir.path().join("open_box.off"),
    )
    .unwrap();
    std::fs::copy(data.join("ply/flat_mesh.ply"), dir.path().join("flat.ply")).unwrap();
    std::fs::copy(
        data.join("ply/no_vertices.ply"),
        dir.path().join("cloud.ply"),
    )
    .unwrap();
    let opts = EvalOptions::default();
    let files = shape_files(dir.path(), &[]).unwrap();
    assert_eq!(files.len(), 3);
    // `only` keeps the order asked for; an unknown name is an error that names it.
    let stems = |names: &[&str]| -> Vec<String> { names.iter().map(|s| s.to_string()).collect() };
    let chosen = shape_files(dir.path(), &stems(&["open_box", "cloud"])).unwrap();
    assert_eq!(
        chosen,
        vec![
            dir.path().join("open_box.off"),
            dir.path().join("cloud.ply")
        ]
    );
    let e = shape_files(dir.path(), &stems(&["cloud", "bunny", "armadillo"]))
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("bunny,armadillo") && e.contains("no shape file"),
        "{e}"
    );
    let mut seen = Vec::new();
    let report = evaluate_dir(
        &files,
        &opts,
        None,
        &dir.path().join("tg"),
        &Silent,
        &mut |r| seen.push(r.failures.len()),
    );
    // One partial report after each shape, each with one more failure.
    assert_eq!(seen, vec![1, 2, 3]);
    assert!(report.shapes.is_empty());
    let reason = |n: &str| {
        report
            .failures
            .iter()
            .find(|f| f.name == n)
            .map(|f| f.reason.clone())
            .unwrap_or_default()
    };
    assert!(
        reason("open_box").contains("not watertight"),
        "{:?}",
        report.failures
    );
    assert!(
        reason("flat").contains("encloses no volume"),
        "{:?}",
        report.failures
    );
    assert!(!reason("cloud").is_empty(), "{:?}", report.failures);
    let empty = tempfile::tempdir().unwrap();
    let e = shape_files(empty.path(), &[]).unwrap_err().to_string();
    assert!(e.contains("no shape file"), "{e}");
}
