//! Colliders (issue 15, parts 2 and 3): sphere, capsule, rotated box and triangle-mesh
//! penalties against finite differences in z; mesh distances against brute force; a
//! kinematic pusher; a pose set between steps against the same motion scripted; bad input.

use crate::common;

use common::{no_cache, small_bar};
use freeform::error::GeometryError;
use freeform::geometry::generate::{icosphere, torus};
use freeform::io::obj::write_obj;
use freeform::material::Material;
use freeform::precompute::BasisRun;
use freeform::progress::Silent;
use freeform::random::SplitMix64;
use freeform::scene::{ObjectSpec, RunSettings, Scene, SceneBuilder, World};
use freeform::sim::collider::{ColliderShape, MeshCollider, MeshObstacle, Sided};
use freeform::sim::motion::{AxisAngle, Keyframe, Motion};
use freeform::sim::terms::{check_derivatives, ContactHessian, Floors};
use freeform::sim::{Collider, ReducedSim, SimOptions};
use freeform::{Error, Point3};
use std::path::{Path, PathBuf};

/// Basis of a 1 x 0.2 x 0.2 m bar (as tests/integration/sim.rs).
fn bar() -> BasisRun {
    crate::common::bar_basis(40, 4, 2000, crate::common::rubber())
}

fn random(n: usize, scale: f64, seed: u64) -> Vec<f64> {
    let mut rng = SplitMix64::new(seed);
    (0..n).map(|_| scale * (rng.next_f64() - 0.5)).collect()
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// An icosphere collider mesh written to `dir` as OBJ.
fn ball_obj(dir: &Path, radius: f64, subdivisions: u32) -> PathBuf {
    let (v, t) = icosphere(radius, subdivisions);
    let path = dir.join(format!("ball_{subdivisions}.obj"));
    write_obj(&path, &v, &t).unwrap();
    path
}

fn mesh(file: &Path, sided: Sided, translation: [f64; 3]) -> ColliderShape {
    ColliderShape::Mesh(MeshCollider {
        sided,
        translation,
        ..MeshCollider::new(file)
    })
}

#[test]
fn collider_penalties_match_finite_differences_in_z() {
    let run = bar();
    let dir = tempfile::tempdir().unwrap();
    let ball = ball_obj(dir.path(), 0.12, 2);
    let turned_box = ColliderShape::Box {
        min: [0.3, 0.0, 0.0],
        max: [0.55, 0.15, 0.3],
        rotation: Some(AxisAngle {
            axis: [1.0, 1.0, 0.0],
            degrees: 30.0,
        }),
    };
    let cases: Vec<(&str, Collider)> = vec![
        (
            "sphere",
            Collider::new(ColliderShape::Sphere {
                center: [0.5, 0.12, 0.1],
                radius: 0.15,
            }),
        ),
        (
            "capsule",
            Collider::new(ColliderShape::Capsule {
                a: [0.2, 0.1, -0.1],
                b: [0.6, 0.15, 0.3],
                radius: 0.08,
            }),
        ),
        ("rotated box", Collider::new(turned_box.clone())),
        (
            // The same box also turned by its pose (the kinematic path).
            "rotated box, rotated pose",
            Collider::new(turned_box).motion(Motion::Pose {
                rotation: freeform::sim::motion::rotation_matrix(&[0.0, 0.0, 1.0], 0.1),
                translation: [0.05, -0.04, 0.0],
            }),
        ),
        (
            "mesh",
            Collider::new(mesh(&ball, Sided::Solid, [0.6, 0.1, 0.1])),
        ),
    ];
    for (what, collider) in cases {
        let opts = SimOptions {
            cubature: 300,
            colliders: vec![collider.stiffness(1e7)],
            ..SimOptions::default()
        };
        let sim = ReducedSim::new(&run.basis, &run.points, &run.material, &opts).unwrap();
        let contact = sim.contacts().unwrap();
        let layout = sim.layout();
        let n = layout.dofs();
        // A small deformation, so that points move relative to the obstacle in every
        // direction; t matters for the kinematic case only.
        let z = random(n, 0.005, 11);
        let t = 0.3;
        let eval = |z: &[f64]| {
            let mut g = vec![0.0; n];
            let info =
                contact.energy_gradient(sim.environment().kinematics(), layout, t, z, &mut g);
            (info, g)
        };
        let (info, g) = eval(&z);
        assert!(info.active >= 10, "{what}: only {} contacts", info.active);
        let mut exact = faer::Mat::<f64>::zeros(n, n);
        contact.add_penalty_hessian(
            sim.environment().kinematics(),
            layout,
            t,
            &z,
            ContactHessian::Exact,
            &mut exact,
        );
        let mut psd = faer::Mat::<f64>::zeros(n, n);
        contact.add_penalty_hessian(
            sim.environment().kinematics(),
            layout,
            t,
            &z,
            ContactHessian::Psd,
            &mut psd,
        );
        let gnorm = dot(&g, &g).sqrt();
        let hnorm = exact.norm_l2();
        // Four random unit directions; errors relative to |g| and |H| (the floors), which
        // bound every slope and every H d.
        let dirs: Vec<Vec<f64>> = (0..4)
            .map(|seed| {
                let dz = random(n, 1.0, 100 + seed);
                let dn = dot(&dz, &dz).sqrt();
                dz.iter().map(|v| v / dn).collect()
            })
            .collect();
        let energy = |z: &[f64], grad: &mut [f64]| {
            let (info, g) = eval(z);
            grad.copy_from_slice(&g);
            info.energy
        };
        let hessian = |_: &[f64]| exact.clone();
        let floors = Floors {
            gradient: gnorm,
            hessian: hnorm,
        };
        // Central differences of a piecewise quadratic-in-x energy: truncation O(h^2) where
        // smooth, rounding ~1e-16 E / h; 1e-6 relative leaves room for both but not for a
        // missing or wrong term (those are O(1) relative). The Hessian is the one at z: the
        // checker compares it with the differences of the gradient around z.
        let check = check_derivatives(energy, Some(&hessian), &z, &dirs, 1e-6, floors);
        assert!(
            check.gradient <= 1e-6 && check.hessian <= 1e-6,
            "{what}: {check:?}"
        );
        // The PSD Hessian is the exact one where that is PSD (planes, boxes, meshes); for
        // the round shapes it drops the (negative) curvature part.
        let diff = (&exact - &psd).norm_l2();
        if what == "sphere" || what == "capsule" {
            assert!(diff > 1e-3 * hnorm, "{what}: no curvature part ({diff:e})");
        } else {
            assert!(diff <= 1e-12 * hnorm, "{what}: {diff:e}");
        }
        let evd = psd.self_adjoint_eigen(faer::Side::Lower).unwrap();
        let min = (0..n).map(|k| evd.S()[k]).fold(f64::INFINITY, f64::min);
        assert!(
            min >= -1e-10 * hnorm,
            "{what}: PSD Hessian has eigenvalue {min:e}"
        );
    }
}

/// Deterministic points in the box [lo, hi].
fn points_in(lo: Point3, hi: Point3, n: usize, seed: u64) -> Vec<Point3> {
    let mut rng = SplitMix64::new(seed);
    (0..n)
        .map(|_| std::array::from_fn(|d| lo[d] + (hi[d] - lo[d]) * rng.next_f64()))
        .collect()
}

#[test]
fn mesh_signed_distance_matches_brute_force() {
    let dir = tempfile::tempdir().unwrap();
    // A torus (non-convex, with a hole), placed by scale, rotation and translation.
    let (v, t) = torus(1.0, 0.35, 24, 12);
    let file = dir.path().join("torus.obj");
    write_obj(&file, &v, &t).unwrap();
    let mut solid = ColliderShape::Mesh(MeshCollider {
        scale: 0.5,
        rotation: Some(AxisAngle {
            axis: [1.0, 0.2, 0.0],
            degrees: 70.0,
        }),
        translation: [0.3, -0.2, 1.0],
        ..MeshCollider::new("torus.obj")
    });
    solid.load(dir.path()).unwrap();
    // An open, bumpy terrain (a height field, normals up) as a one-sided surface.
    let (n, size) = (12, 2.0);
    let mut tv = Vec::new();
    for i in 0..=n {
        for j in 0..=n {
            let (x, z) = (size * i as f64 / n as f64, size * j as f64 / n as f64);
            tv.push([x, 0.2 * (2.0 * x).sin() * (3.0 * z).cos(), z]);
        }
    }
    let mut tt = Vec::new();
    let id = |i: usize, j: usize| (i * (n + 1) + j) as u32;
    for i in 0..n {
        for j in 0..n {
            // Counter-clockwise seen from above (+y): (x, z) -> (x, z + 1) -> (x + 1, z).
            tt.push([id(i, j), id(i, j + 1), id(i + 1, j)]);
            tt.push([id(i + 1, j), id(i, j + 1), id(i + 1, j + 1)]);
        }
    }
    write_obj(&dir.path().join("terrain.obj"), &tv, &tt).unwrap();
    let mut terrain = ColliderShape::Mesh(MeshCollider {
        sided: Sided::Outside,
        ..MeshCollider::new("terrain.obj")
    });
    terrain.load(dir.path()).unwrap();
    for (what, shape) in [("torus", &solid), ("terrain", &terrain)] {
        let ColliderShape::Mesh(MeshCollider {
            loaded: Some(m), ..
        }) = shape
        else {
            panic!("not loaded");
        };
        let b = m.bounding_box();
        let pad = 0.1 * b.diagonal();
        let lo = b.min.map(|c| c - pad);
        let hi = b.max.map(|c| c + pad);
        let (mut inside, mut outside) = (0, 0);
        for y in points_in(lo, hi, 3000, 5) {
            let (fast, slow) = (m.signed_distance(&y), m.signed_distance_brute_force(&y));
            // The same closest distance to round-off (1e-12 of the mesh size), and the same
            // side: the BVH's pseudo-normal test against the winding number (torus) or our
            // own pseudo-normals (terrain).
            assert!(
                (fast - slow).abs() <= 1e-12 * b.diagonal(),
                "{what} at {y:?}: {fast} vs {slow}"
            );
            if slow < 0.0 {
                inside += 1;
                let p = m.penetration_local(&y).expect("inside");
                assert!((p.depth + slow).abs() <= 1e-12 * b.diagonal());
            } else {
                outside += 1;
            }
        }
        assert!(inside > 50 && outside > 50, "{what}: {inside} / {outside}");
    }
}

/// An open-top container (the unit box without its top face, normals inward) as a
/// one-sided surface: its rim (y = 1) is an open boundary.
fn open_container() -> MeshObstacle {
    // [0, 1]^3 moved to x, z in [-0.5, 0.5].
    let (v, t) = freeform::geometry::generate::box_mesh([1.0, 1.0, 1.0]);
    let v: Vec<Point3> = v.iter().map(|p| [p[0] - 0.5, p[1], p[2] - 0.5]).collect();
    // The box's triangles face outwards: flip them so the inside of the container is free,
    // and drop the two of the top face.
    let t: Vec<[u32; 3]> = t
        .iter()
        .filter(|f| !f.iter().all(|&i| v[i as usize][1] == 1.0))
        .map(|&[a, b, c]| [a, c, b])
        .collect();
    assert_eq!(t.len(), 10);
    MeshObstacle::from_triangles(Path::new("container.obj"), v, t, Sided::Outside).unwrap()
}

#[test]
fn a_one_sided_surface_penetrates_continuously_beyond_its_open_boundary() {
    let m = open_container();
    let depth = |y: &Point3| m.penetration_local(y).map_or(0.0, |p| p.depth);
    let slow = |y: &Point3| m.penetration_brute_force(y).map_or(0.0, |p| p.depth);
    // The wall x = 0.5 (free side x < 0.5). 0.2 m above the rim, 1 mm outside the wall's
    // plane: behind the plane the rim's triangles continue by 1 mm, not by the point's 0.2 m
    // to the rim edge (which made the penalty jump across the plane).
    let out = [0.501, 1.2, 0.1];
    assert!((depth(&out) - 0.001).abs() < 1e-12, "{}", depth(&out));
    assert!(m.penetration_local(&[0.499, 1.2, 0.1]).is_none());
    let p = m.penetration_local(&out).unwrap();
    assert!((p.normal[0] + 1.0).abs() < 1e-12, "{:?}", p.normal);
    // Behind both walls with the rim corner (x = z = 0.5) nearest: the distance to the
    // walls' corner line continued upwards, as below the rim.
    let corner = [0.503, 1.2, 0.502];
    assert!((depth(&corner) - 0.003f64.hypot(0.002)).abs() < 1e-12);
    assert!((depth(&[0.503, 0.9, 0.502]) - depth(&corner)).abs() < 1e-12);
    // Along lines through the rim, its corners and the walls' planes, above and below the
    // rim: the depth is 1-Lipschitz (a distance to a surface or to a plane; a jump would
    // break it), by the BVH and by brute force alike.
    let lines: [(Point3, Point3); 5] = [
        ([0.3, 1.2, 0.1], [0.7, 1.2, 0.1]),
        ([0.6, 0.7, 0.1], [0.6, 1.4, 0.1]),
        ([0.3, 1.1, 0.3], [0.7, 1.1, 0.7]),
        ([0.6, 0.8, 0.6], [0.6, 1.3, 0.6]),
        ([0.7, 0.9, -0.7], [0.3, 1.3, 0.7]),
    ];
    let n = 4000;
    for (a, b) in lines {
        let at = |i: usize| -> Point3 {
            let s = i as f64 / n as f64;
            std::array::from_fn(|d| a[d] + s * (b[d] - a[d]))
        };
        let step = (0..3).map(|d| (b[d] - a[d]).powi(2)).sum::<f64>().sqrt() / n as f64;
        let mut touched = 0;
        for i in 0..n {
            let (y0, y1) = (at(i), at(i + 1));
            assert!((depth(&y0) - slow(&y0)).abs() < 1e-12, "{y0:?}");
            // 1-Lipschitz, with round-off's room.
            assert!(
                (depth(&y1) - depth(&y0)).abs() <= step * (1.0 + 1e-9),
                "{a:?} -> {b:?} at {y0:?}: {} then {}",
                depth(&y0),
                depth(&y1)
            );
            touched += usize::from(depth(&y0) > 0.0);
        }
        // Every line runs behind a wall for part of its length (the second and fourth all of
        // it: they cross the rim's height behind the wall and behind the corner).
        assert!(touched > 100, "{a:?} -> {b:?}: {touched}");
    }
}

/// A 0.2 m cube (4 kg) on a frictionless slope: gravity pulls it back along -x at
/// `slope_g` m/s^2, so whatever pushes it keeps touching it.
fn block_scene(pusher: Collider, steps: usize, slope_g: f64) -> Scene {
    SceneBuilder::new(0.01, steps)
        .gravity([-slope_g, 0.0, 0.0])
        .cubature(600)
        .cache(no_cache())
        .object(
            ObjectSpec::new("block", "box:0.2,0.2,0.2")
                .unwrap()
                .kernels(40)
                .modes(4)
                .points(3000)
                .material(Material {
                    youngs: 1e6,
                    poisson: 0.3,
                    density: 500.0,
                }),
        )
        .collider(pusher)
        .build()
        .unwrap()
}

fn mean_x(world: &World) -> f64 {
    let x = world.object(0).integration_positions().unwrap();
    x.iter().map(|p| p[0]).sum::<f64>() / x.len() as f64
}

#[test]
fn a_kinematic_pusher_moves_a_block_by_the_expected_distance() {
    // A wall-like box pusher whose face starts at x = 0, touching the block [0, 0.2]^3,
    // moves 0.2 m in +x at 0.5 m/s and stops. No friction; gravity along -x (2 m/s^2: a
    // frictionless slope) keeps the block against the pusher. (Without it the block leaves
    // the pusher after the first contact, 2.7% faster than it: backward Euler leaves a little
    // restitution in the penalty impact, and the distance would measure that instead.)
    let (speed, push, slope_g) = (0.5, 0.2, 2.0);
    let pusher = Collider::new(ColliderShape::Box {
        min: [-0.3, -0.1, -0.1],
        max: [0.0, 0.3, 0.3],
        rotation: None,
    })
    .named("pusher")
    .motion(Motion::Keyframes {
        pivot: [0.0; 3],
        frames: vec![
            Keyframe {
                time: 0.0,
                translation: [0.0; 3],
                rotation: None,
            },
            Keyframe {
                time: push / speed,
                translation: [push, 0.0, 0.0],
                rotation: None,
            },
        ],
    });
    let steps = (push / speed / 0.01).round() as usize;
    let scene = block_scene(pusher, steps + 20, slope_g);
    let mut world = World::new(&scene, &RunSettings::default(), &Silent).unwrap();
    let x0 = mean_x(&world);
    // The penalty acts on cubature points: the pusher's face touches the block once it
    // reaches the first layer of them.
    let first_layer = world
        .object(0)
        .sim()
        .cubature()
        .points
        .iter()
        .map(|p| p[0])
        .fold(f64::INFINITY, f64::min);
    let expected = push - first_layer;
    let mut contacts = 0;
    let mut deepest: f64 = 0.0;
    for step in 1..=steps {
        let r = world.step().unwrap();
        assert!(r[0].solve.converged, "step {step}");
        contacts += r[0].solve.info.contacts;
        deepest = deepest.max(r[0].solve.info.penetration);
    }
    // The block trails the pusher's face by the penetration that carries its weight on the
    // slope (m g / penalty, about 2e-6 m); the elastic compression under that load, about
    // m g L / (2 A E) = 2e-5 m, is the rest: 1e-4 m bounds it with room for the vibration
    // the start of the push excites.
    let pen = world.object(0).summary().steps.last().unwrap().penetration;
    let moved = mean_x(&world) - x0;
    println!("moved {moved:.6} m, expected {expected:.6} - {pen:.2e} m");
    assert!(pen > 0.0, "the block left the pusher");
    assert!(
        (moved - (expected - pen)).abs() <= 1e-4,
        "moved {moved} m, expected {expected} m - penetration {pen} m"
    );
    // The pusher stops; the block slides on at 0.5 m/s up the slope and slows down: after N
    // more backward-Euler steps it has gone sum_k h (v - g h k) = N h v - g h^2 N (N + 1) / 2
    // (0.058 m for N = 20). 5e-4 m allows for a release speed off by 1e-3 m/s (the
    // penetration's own rate and the vibration) over the 0.2 s.
    let (n, h) = (20.0, 0.01);
    let ballistic = n * h * speed - slope_g * h * h * n * (n + 1.0) / 2.0;
    let at_release = mean_x(&world);
    for _ in 0..20 {
        world.step().unwrap();
    }
    let coast = mean_x(&world) - at_release;
    println!("coasted {coast:.6} m, ballistic {ballistic:.6} m");
    assert!(
        (coast - ballistic).abs() <= 5e-4,
        "coasted {coast} m, ballistic {ballistic} m"
    );
    assert!(contacts > 0);
    assert!(
        deepest < 0.01 * 0.2,
        "penetration {deepest} m is over 1% of the block"
    );
}

/// Two capsules of an arm (the second a child of the first) and a box turning about z.
fn arm(scripted: bool) -> Vec<(Collider, Motion)> {
    let shoulder = Motion::Keyframes {
        pivot: [0.2, 0.5, 0.1],
        frames: vec![
            Keyframe {
                time: 0.0,
                translation: [0.0; 3],
                rotation: None,
            },
            Keyframe {
                time: 0.1,
                translation: [0.0, -0.05, 0.0],
                rotation: Some(AxisAngle {
                    axis: [0.0, 0.0, 1.0],
                    degrees: -40.0,
                }),
            },
        ],
    };
    let elbow = Motion::Rotate {
        pivot: [0.6, 0.5, 0.1],
        axis: [0.0, 0.0, 1.0],
        degrees_per_second: -300.0,
    };
    let spin = Motion::Rotate {
        pivot: [0.8, -0.1, 0.1],
        axis: [0.3, 0.0, 1.0],
        degrees_per_second: 200.0,
    };
    let upper = Collider::new(ColliderShape::Capsule {
        a: [0.2, 0.5, 0.1],
        b: [0.6, 0.5, 0.1],
        radius: 0.06,
    })
    .named("upper");
    let fore = Collider::new(ColliderShape::Capsule {
        a: [0.6, 0.5, 0.1],
        b: [0.9, 0.5, 0.1],
        radius: 0.05,
    })
    .named("fore")
    .parent("upper");
    let block = Collider::new(ColliderShape::Box {
        min: [0.7, -0.2, -0.1],
        max: [0.9, 0.03, 0.3],
        rotation: Some(AxisAngle {
            axis: [0.0, 1.0, 0.0],
            degrees: 10.0,
        }),
    });
    [(upper, shoulder), (fore, elbow), (block, spin)]
        .into_iter()
        .map(|(c, m)| {
            if scripted {
                (c.motion(m.clone()), m)
            } else {
                (c, m)
            }
        })
        .collect()
}

#[test]
fn a_collider_pose_set_between_steps_matches_the_same_motion_scripted() {
    let worlds: Vec<(World, Vec<Motion>)> = [true, false]
        .into_iter()
        .map(|scripted| {
            let mut b = SceneBuilder::new(0.01, 1)
                .gravity([0.0, -9.81, 0.0])
                .cubature(400)
                .cache(no_cache())
                .object(
                    small_bar("bar").hold(freeform::material::Region::HalfSpace {
                        point: [0.1, 0.0, 0.0],
                        normal: [-1.0, 0.0, 0.0],
                    }),
                );
            let mut motions = Vec::new();
            for (c, m) in arm(scripted) {
                b = b.collider(c);
                motions.push(m);
            }
            let scene = b.build().unwrap();
            let world = World::new(&scene, &RunSettings::default(), &Silent).unwrap();
            (world, motions)
        })
        .collect();
    let [(mut scripted, _), (mut live, motions)] = <[_; 2]>::try_from(worlds).unwrap();
    let mut contacts = 0;
    for _ in 0..20 {
        // The potential of a step is evaluated at its end time.
        let t = live.time() + live.dt();
        for (i, m) in motions.iter().enumerate() {
            live.set_collider_pose(i, &m.at(t)).unwrap();
        }
        let a = scripted.step().unwrap();
        let b = live.step().unwrap();
        contacts += a[0].solve.info.contacts;
        assert_eq!(a[0].solve.info.contacts, b[0].solve.info.contacts);
        assert_eq!(scripted.collider_poses(), live.collider_poses());
    }
    // Bit for bit: the same poses give the same potential, the same iterates.
    assert!(contacts > 0, "the arm never touched the bar");
    assert_eq!(scripted.object(0).sim().z(), live.object(0).sim().z());
}

fn collider_error(scene: &Scene, base: &Path) -> Error {
    let settings = RunSettings {
        base_dir: base.to_path_buf(),
        ..RunSettings::default()
    };
    World::new(scene, &settings, &Silent).unwrap_err()
}

fn one_object(c: Collider) -> Scene {
    SceneBuilder::new(0.01, 1)
        .cubature(100)
        .cache(no_cache())
        .object(small_bar("bar"))
        .collider(c)
        .build()
        .unwrap()
}

#[test]
fn bad_collider_meshes_are_typed_errors_naming_file_and_triangle() {
    let data = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data");
    let dir = tempfile::tempdir().unwrap();
    // An open cube as a solid: refused, naming the collider, the file and the way out.
    let open = Collider::new(ColliderShape::Mesh(MeshCollider::new("cube_open.obj"))).named("lid");
    let e = collider_error(&one_object(open.clone()), &data);
    let msg = e.to_string();
    match &e {
        Error::Collider {
            index: 0,
            name,
            source,
        } => {
            assert_eq!(name.as_deref(), Some("lid"));
            assert!(
                matches!(
                    **source,
                    Error::Geometry(GeometryError::ColliderNotClosed { boundary_edges, .. })
                        if boundary_edges > 0
                ),
                "{source:?}"
            );
        }
        other => panic!("{other:?}"),
    }
    assert!(
        msg.contains("collider 0 'lid'")
            && msg.contains("cube_open.obj")
            && msg.contains("sided = \"outside\""),
        "{msg}"
    );
    // The same file as a one-sided surface is fine.
    let mut surface = open;
    surface.shape = ColliderShape::Mesh(MeshCollider {
        sided: Sided::Outside,
        ..MeshCollider::new("cube_open.obj")
    });
    let settings = RunSettings {
        base_dir: data.clone(),
        ..RunSettings::default()
    };
    World::new(&one_object(surface), &settings, &Silent).unwrap();

    // Degenerate triangles: a cube whose triangle 5 is collapsed onto a line.
    let (mut v, t) = freeform::geometry::generate::box_mesh([1.0, 1.0, 1.0]);
    let [a, b, c] = t[5];
    let mid: Point3 = std::array::from_fn(|d| 0.5 * (v[a as usize][d] + v[b as usize][d]));
    v[c as usize] = mid; // also flattens the triangles sharing c: all are reported
    write_obj(&dir.path().join("flat.obj"), &v, &t).unwrap();
    let e = collider_error(
        &one_object(Collider::new(ColliderShape::Mesh(MeshCollider::new(
            "flat.obj",
        )))),
        dir.path(),
    );
    let Error::Collider { source, .. } = &e else {
        panic!("{e:?}")
    };
    let Error::Geometry(GeometryError::DegenerateTriangle {
        triangle, count, ..
    }) = **source
    else {
        panic!("{source:?}")
    };
    assert!(triangle <= 5 && count >= 1, "{e}");
    assert!(
        e.to_string().contains("flat.obj")
            && e.to_string().contains(&format!("triangle {triangle}"))
    );

    // Every triangle degenerate (all on a line), an empty file, a point cloud, a missing file.
    std::fs::write(
        dir.path().join("line.obj"),
        "v 0 0 0\nv 1 0 0\nv 2 0 0\nv 3 0 0\nf 1 2 3\nf 2 3 4\n",
    )
    .unwrap();
    std::fs::write(dir.path().join("empty.obj"), "").unwrap();
    for (file, needle) in [
        ("line.obj", "triangle 0"),
        ("empty.obj", "empty"),
        ("nowhere.obj", "nowhere.obj"),
    ] {
        let e = collider_error(
            &one_object(Collider::new(ColliderShape::Mesh(MeshCollider::new(file)))),
            dir.path(),
        );
        let msg = e.to_string();
        assert!(matches!(e, Error::Collider { .. }), "{e:?}");
        assert!(msg.contains(needle) && msg.contains(file), "{file}: {msg}");
    }
    let e = collider_error(
        &one_object(Collider::new(ColliderShape::Mesh(MeshCollider::new(
            "points_ascii.ply",
        )))),
        &data,
    );
    assert!(e.to_string().contains("no faces"), "{e}");
    // The in-memory constructor: NaN vertices.
    let (mut v, t) = icosphere(1.0, 1);
    v[3][1] = f64::NAN;
    let e = MeshObstacle::from_triangles(Path::new("mem"), v, t, Sided::Solid).unwrap_err();
    assert!(e.to_string().contains("vertex 3"), "{e}");
}

#[test]
fn bad_collider_numbers_are_scene_errors_naming_the_collider() {
    let base =
        "[simulation]\ndt = 0.01\nsteps = 1\n[[object]]\nname = \"a\"\nshape = \"box:1,1,1\"\n";
    for (collider, needle) in [
        ("name = \"ball\"\nshape = { sphere = { center = [0, 0, 0], radius = 0.0 } }", "collider 0 'ball'"),
        ("shape = { sphere = { center = [0, 0, 0], radius = 0.0 } }", "radius"),
        ("shape = { capsule = { a = [0, 0, 0], b = [1, 0, 0], radius = -1 } }", "radius"),
        ("shape = { capsule = { a = [0, nan, 0], b = [1, 0, 0], radius = 1 } }", "collider[0].shape.capsule.a[1] = NaN"),
        ("shape = { box = { min = [0, 0, 0], max = [1, 1, 1], rotation = { axis = [0, 0, 0], degrees = 3 } } }", "non-zero axis"),
        ("shape = { mesh = { file = \"m.obj\", scale = 0 } }", "scale"),
        ("shape = { mesh = { file = \"m.obj\", sided = \"inside\" } }", "unknown variant `inside`"),
        ("shape = { sphere = { center = [0, 0, 0], radius = 1 } }\nparent = \"nobody\"", "no collider listed before"),
        ("shape = { sphere = { center = [0, 0, 0], radius = 1 } }\nmotion = { translate = { velocity = [nan, 0, 0] } }", "collider[0].motion.translate.velocity[0] = NaN"),
        ("shape = { sphere = { center = [0, 0, 0], radius = 1 } }\nmotion = { pose = { rotation = [[1, 0, 0], [0, 1, 0], [0, 0, 1]], translation = [0, nan, 0] } }", "collider[0].motion.pose.translation[1] = NaN"),
        ("shape = { sphere = { center = [0, 0, 0], radius = 1 } }\nstiffness = -5", "stiffness"),
        ("shape = { cone = { radius = 1 } }", "unknown variant `cone`"),
    ] {
        let text = format!("{base}[[collider]]\n{collider}\n");
        let msg = Scene::from_toml(&text).unwrap_err().to_string();
        assert!(msg.contains(needle), "{collider}: {msg}");
    }
    // Two colliders of the same name.
    let twice = format!(
        "{base}[[collider]]\nname = \"x\"\nshape = {{ sphere = {{ center = [0, 0, 0], radius = 1 }} }}\n\
         [[collider]]\nname = \"x\"\nshape = {{ sphere = {{ center = [0, 0, 0], radius = 1 }} }}\n"
    );
    let msg = Scene::from_toml(&twice).unwrap_err().to_string();
    assert!(
        msg.contains("collider 1 'x'") && msg.contains("two colliders"),
        "{msg}"
    );
}

#[test]
fn every_collider_key_round_trips_through_toml() {
    let text = r#"
[simulation]
dt = 0.01
steps = 1
[[object]]
name = "a"
shape = "box:1,1,1"
[[collider]]
shape = { plane = { point = [0, 0, 0], normal = [0, 1, 0] } }
[[collider]]
name = "crate"
shape = { box = { min = [0, 0, 0], max = [1, 1, 1], rotation = { axis = [0, 1, 0], degrees = 30 } } }
stiffness = 1e9
[[collider]]
name = "upper"
shape = { capsule = { a = [0, 1, 0], b = [1, 1, 0], radius = 0.1 } }
motion = { keyframes = { pivot = [0, 1, 0], frames = [
    { time = 0.0 }, { time = 1.0, rotation = { axis = [0, 0, 1], degrees = -30 } } ] } }
[[collider]]
name = "fore"
parent = "upper"
shape = { capsule = { a = [1, 1, 0], b = [2, 1, 0], radius = 0.1 } }
motion = { rotate = { pivot = [1, 1, 0], axis = [0, 0, 1], degrees_per_second = 20 } }
[[collider]]
shape = { sphere = { center = [3, 0, 0], radius = 0.5 } }
motion = { translate = { velocity = [0, 0, 1] } }
[[collider]]
shape = { mesh = { file = "terrain.obj", sided = "outside", scale = 0.01, rotation = { axis = [1, 0, 0], degrees = -90 }, translation = [0, -1, 0] } }
"#;
    let scene = Scene::from_toml(text).unwrap();
    assert_eq!(scene.colliders.len(), 6);
    assert_eq!(scene.colliders[3].parent.as_deref(), Some("upper"));
    let kinds: Vec<&str> = scene.colliders.iter().map(|c| c.shape.kind()).collect();
    assert_eq!(
        kinds,
        ["plane", "box", "capsule", "capsule", "sphere", "mesh"]
    );
    let again = Scene::from_toml(&scene.to_toml().unwrap()).unwrap();
    assert_eq!(again, scene);
}

#[test]
fn the_robot_push_example_parses_and_its_arm_is_a_chain() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/robot_push.toml");
    let scene = Scene::load(&path).unwrap();
    assert_eq!(scene.objects.len(), 3);
    let capsules: Vec<_> = scene
        .colliders
        .iter()
        .filter(|c| c.shape.kind() == "capsule")
        .collect();
    assert!((2..=3).contains(&capsules.len()));
    assert!(capsules[1..].iter().all(|c| c.parent.is_some()));
}

#[test]
fn an_object_that_starts_inside_a_solid_collider_is_refused() {
    // The bar (box:1,0.2,0.2 from the origin) with its far half inside a solid box.
    let wall = Collider::new(ColliderShape::Box {
        min: [0.5, -1.0, -1.0],
        max: [2.0, 1.0, 1.0],
        rotation: None,
    })
    .named("wall");
    let e = collider_error(&one_object(wall), Path::new("."));
    let msg = e.to_string();
    assert!(
        msg.contains("collider 0 'wall'")
            && msg.contains("starts inside this box collider")
            && msg.contains("placement.translation"),
        "{msg}"
    );
    // Resting on a floor at its bottom face is no start inside (the depth is 0).
    let floor = Collider::new(ColliderShape::Plane {
        point: [0.0, 0.0, 0.0],
        normal: [0.0, 1.0, 0.0],
    });
    let settings = RunSettings::default();
    World::new(&one_object(floor), &settings, &Silent).unwrap();
}
