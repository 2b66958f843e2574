//! The live simulation ([`World`]): it writes the same frames as the batch runner on the
//! example scenes, and what it changes between steps (gravity, a boundary's motion, an
//! object's placement, a collider's pose) does what it says; errors name the object.

use crate::common::{no_cache, small_bar};
use freeform::material::Region;
use freeform::precompute::BoundaryModes;
use freeform::progress::Silent;
use freeform::scene::{
    run, CacheSettings, FrameObserver, FrameWriter, ObjectSpec, RunSettings, Scene, SceneBuilder,
    World,
};
use freeform::sim::motion::{AxisAngle, Keyframe, Motion, Rigid};
use freeform::sim::terms::ColliderShape;
use freeform::sim::{Collider, Placement};
use freeform::Error;
use std::path::{Path, PathBuf};

fn examples_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("examples")
}

/// Every file below `dir`, as (path relative to `dir`, bytes), sorted by path.
fn tree(dir: &Path) -> Vec<(PathBuf, Vec<u8>)> {
    let mut out = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for entry in std::fs::read_dir(&d).unwrap() {
            let p = entry.unwrap().path();
            if p.is_dir() {
                stack.push(p);
            } else {
                let bytes = std::fs::read(&p).unwrap();
                out.push((p.strip_prefix(dir).unwrap().to_path_buf(), bytes));
            }
        }
    }
    out.sort();
    out
}

/// The loop a caller of the live API writes: step, look, write frames.
fn live_frames(scene: &Scene, settings: &RunSettings, out: &Path) -> World {
    let mut world = World::new(scene, settings, &Silent).unwrap();
    let mut writer = FrameWriter::new(out, &scene.output.formats).unwrap();
    writer.frame(&world, 0).unwrap();
    if scene.output.formats.contains(&freeform::scene::Format::Vtk) {
        // The collections are written as frames land: a run stopped here opens in ParaView.
        for object in world.objects() {
            let pvd = std::fs::read_to_string(out.join(format!("{}.pvd", object.name())))
                .expect("the .pvd is written with the first frame");
            assert_eq!(pvd.matches("<DataSet").count(), 1, "{pvd}");
        }
    }
    let steps = scene.simulation.steps;
    for step in 1..=steps {
        let reports = world.step().unwrap();
        assert_eq!(reports.len(), world.objects().len());
        assert_eq!(world.steps(), step);
        if step % scene.output.every == 0 || step == steps {
            writer.frame(&world, step).unwrap();
        }
    }
    writer.finish(&world).unwrap();
    world
}

#[test]
fn live_world_writes_the_same_frames_as_the_batch_run_on_the_example_scenes() {
    for file in ["beam_bend.toml", "drop.toml"] {
        let tmp = tempfile::tempdir().unwrap();
        let mut scene = Scene::load(&examples_dir().join(file)).unwrap();
        // The batch run computes the basis and caches it; the live run loads it, so this
        // also checks that a cached basis simulates bit for bit like a fresh one.
        scene.cache = CacheSettings {
            enabled: true,
            dir: tmp.path().join("cache"),
        };
        let batch_dir = tmp.path().join("batch");
        let settings = RunSettings {
            base_dir: examples_dir(),
            out: Some(batch_dir.clone()),
            strict: false,
        };
        let summary = run(&scene, &settings, &Silent).unwrap();
        assert!(!summary.objects[0].basis_cached);
        let live_dir = tmp.path().join("live");
        let world = live_frames(
            &scene,
            &RunSettings {
                out: None,
                ..settings.clone()
            },
            &live_dir,
        );
        assert!(world.objects()[0].summary().basis_cached);
        let (batch, live) = (tree(&batch_dir), tree(&live_dir));
        // 51 frames per format plus the .pvd collection(s).
        assert!(batch.len() > 50, "{file}: {} files", batch.len());
        assert_eq!(batch.len(), live.len(), "{file}");
        for ((pb, bb), (pl, bl)) in batch.iter().zip(&live) {
            assert_eq!(pb, pl, "{file}");
            assert!(bb == bl, "{file}: {} differs", pb.display());
        }
        // The step rows agree too (wall times aside).
        let live_rows = &world.summaries()[0].steps;
        let batch_rows = &summary.objects[0].steps;
        assert_eq!(live_rows.len(), batch_rows.len());
        for (a, b) in live_rows.iter().zip(batch_rows) {
            assert_eq!(
                (
                    a.iterations,
                    a.evaluations,
                    a.energy.to_bits(),
                    a.residual.to_bits()
                ),
                (
                    b.iterations,
                    b.evaluations,
                    b.energy.to_bits(),
                    b.residual.to_bits()
                ),
                "{file}: step {}",
                a.step
            );
        }
        assert_eq!(world.warnings(), summary.warnings.as_slice(), "{file}");
        assert!((world.time() - scene.simulation.dt * scene.simulation.steps as f64).abs() < 1e-12);
        // The world keeps its own clock; it advances as every object's does, bit for bit.
        assert_eq!(world.steps(), scene.simulation.steps, "{file}");
        for o in world.objects() {
            assert_eq!(o.sim().time().to_bits(), world.time().to_bits(), "{file}");
            assert_eq!(o.sim().steps(), world.steps(), "{file}");
        }
    }
}

fn max_distance(a: &[[f64; 3]], b: &[[f64; 3]]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| (0..3).map(|d| (x[d] - y[d]).powi(2)).sum::<f64>().sqrt())
        .fold(0.0, f64::max)
}

#[test]
fn gravity_switched_on_between_steps_starts_a_free_fall() {
    let scene = SceneBuilder::new(0.01, 1)
        .cubature(400)
        .cache(no_cache())
        .object(small_bar("bar"))
        .build()
        .unwrap();
    let mut world = World::new(&scene, &RunSettings::default(), &Silent).unwrap();
    let rest = world.object(0).render_positions();
    world.step().unwrap();
    // Nothing acts on it: not a point moves (the one mandatory iteration finds nothing).
    assert_eq!(
        max_distance(&rest, &world.object(0).render_positions()),
        0.0
    );
    world.set_gravity(Some([0.0, -9.81, 0.0])).unwrap();
    assert!(world
        .object(0)
        .sim()
        .terms()
        .contains(&"gravity".to_string()));
    // The summary lists the terms built now.
    assert_eq!(
        world.object(0).summary().terms,
        world.object(0).sim().terms()
    );
    let steps = 10;
    for _ in 0..steps {
        world.step().unwrap();
    }
    // Backward Euler free fall from rest: after n steps of h the drop is g h^2 n (n + 1) / 2,
    // and an unconstrained body deforms nowhere, so every point drops by it. Each step's
    // potential is then quadratic with the rest system matrix as its Hessian, which the solver
    // factorizes, so the first iterate is exact: only rounding remains (measured 7e-15 m).
    let (g, h) = (9.81, 0.01);
    let drop = g * h * h * (steps * (steps + 1)) as f64 / 2.0;
    let now = world.object(0).render_positions();
    for (x, x0) in now.iter().zip(&rest) {
        assert!(
            (x0[1] - x[1] - drop).abs() < 1e-10,
            "drop {} vs {drop}",
            x0[1] - x[1]
        );
        assert!((x[0] - x0[0]).abs() < 1e-10 && (x[2] - x0[2]).abs() < 1e-10);
    }
    assert!(world.set_gravity(Some([0.0, f64::NAN, 0.0])).is_err());
    // Beyond MAX_GRAVITY the step's squares overflow and a frozen object reported
    // "converged": refused, naming the limit.
    let err = world.set_gravity(Some([0.0, -1e300, 0.0])).unwrap_err();
    assert!(err.to_string().contains("above the limit"), "{err}");
    // Placements from code follow the scenes' magnitude rule (at most 1e100).
    for placement in [
        Placement {
            velocity: [1e300, 0.0, 0.0],
            ..Default::default()
        },
        Placement {
            translation: [0.0, 1e300, 0.0],
            ..Default::default()
        },
    ] {
        let err = world.set_placement(0, &placement).unwrap_err();
        assert!(err.to_string().contains("1e100"), "{err}");
    }
}

#[test]
fn a_moved_boundary_target_carries_the_held_region_with_it() {
    let mut scene = SceneBuilder::new(0.01, 1)
        .cubature(400)
        .cache(no_cache())
        .object(small_bar("bar").hold(Region::HalfSpace {
            point: [0.2, 0.0, 0.0],
            normal: [-1.0, 0.0, 0.0],
        }))
        .build()
        .unwrap();
    // Every held point on its target is the free basis's pointwise hold; an aware basis
    // holds the region through its lift (its edge band follows within the kernel
    // resolution), tested in boundary_modes.rs.
    scene.objects[0].basis.boundaries = BoundaryModes::Free;
    let mut world = World::new(&scene, &RunSettings::default(), &Silent).unwrap();
    world.step().unwrap();
    let now = world.time();
    let lift = [0.0, 0.05, 0.0];
    world
        .set_boundary_motion(
            0,
            0,
            Motion::Keyframes {
                pivot: [0.0; 3],
                frames: vec![
                    Keyframe {
                        time: now,
                        translation: [0.0; 3],
                        rotation: None,
                    },
                    Keyframe {
                        time: now + 0.05,
                        translation: lift,
                        rotation: None,
                    },
                ],
            },
        )
        .unwrap();
    for _ in 0..30 {
        world.step().unwrap();
    }
    // The held integration points follow the target up to the penalty's give under the
    // inertia of the rest of the bar (measured: 1.8e-4 m at worst, 0.4% of the lift; the
    // region's mean 1e-6 m off). Bounds: 1% of the lift at worst, 0.2% on the mean.
    let object = world.object(0);
    let x = object.integration_positions().unwrap();
    let rest = &object.rest_points().points;
    let b = &object.sim().boundaries()[0];
    let dev = b.max_deviation(world.time(), rest, &x);
    assert!(dev < 0.01 * lift[1], "deviation {dev} m");
    let mean_lift: f64 =
        b.points.iter().map(|&i| x[i][1] - rest[i][1]).sum::<f64>() / b.points.len() as f64;
    assert!(
        (mean_lift - lift[1]).abs() < 0.002 * lift[1],
        "mean lift {mean_lift}"
    );
    // A boundary that does not exist, or a bad motion, is refused and changes nothing.
    assert!(world.set_boundary_motion(0, 1, Motion::Fixed).is_err());
    assert!(world.set_boundary_motion(3, 0, Motion::Fixed).is_err());
    let bad = Motion::Translate {
        velocity: [f64::INFINITY, 0.0, 0.0],
    };
    assert!(world.set_boundary_motion(0, 0, bad).is_err());
}

#[test]
fn a_boundary_pose_set_between_steps_is_where_the_held_region_goes() {
    let mut scene = SceneBuilder::new(0.01, 1)
        .cubature(400)
        .cache(no_cache())
        .object(small_bar("bar").hold(Region::HalfSpace {
            point: [0.2, 0.0, 0.0],
            normal: [-1.0, 0.0, 0.0],
        }))
        .build()
        .unwrap();
    // Every held point on its target is the free basis's pointwise hold; an aware basis
    // holds the region through its lift (its edge band follows within the kernel
    // resolution), tested in boundary_modes.rs.
    scene.objects[0].basis.boundaries = BoundaryModes::Free;
    let mut world = World::new(&scene, &RunSettings::default(), &Silent).unwrap();
    // A small turn about z through the origin plus a lift: the target is a rigid pose of the
    // held end, reached in the steps after it is set.
    let pose = Rigid {
        rotation: freeform::sim::motion::rotation_matrix(&[0.0, 0.0, 1.0], 0.02),
        translation: [0.0, 0.02, 0.0],
    };
    world.set_boundary_pose(0, 0, &pose).unwrap();
    for _ in 0..30 {
        world.step().unwrap();
    }
    let object = world.object(0);
    let x = object.integration_positions().unwrap();
    let rest = &object.rest_points().points;
    let b = &object.sim().boundaries()[0];
    let worst = b
        .points
        .iter()
        .map(|&i| {
            let target = pose.apply(&rest[i]);
            (0..3)
                .map(|d| (x[i][d] - target[d]).powi(2))
                .sum::<f64>()
                .sqrt()
        })
        .fold(0.0, f64::max);
    // The same penalty give as a keyframed target (1% of the lift, see above), here of the
    // 0.02 m lift plus the turn's up to 0.004 m.
    assert!(worst < 0.01 * 0.024, "held region {worst} m off its target");
    let mut scaled = pose;
    scaled.rotation[0][0] *= 1.5;
    let msg = world
        .set_boundary_pose(0, 0, &scaled)
        .unwrap_err()
        .to_string();
    assert!(msg.contains("proper rotation"), "{msg}");
}

#[test]
fn a_state_read_and_set_again_gives_the_same_positions() {
    let scene = SceneBuilder::new(0.01, 1)
        .gravity([0.0, -9.81, 0.0])
        .cubature(400)
        .cache(no_cache())
        .object(small_bar("bar"))
        .build()
        .unwrap();
    let mut world = World::new(&scene, &RunSettings::default(), &Silent).unwrap();
    for _ in 0..3 {
        world.step().unwrap();
    }
    let (z, zdot) = (
        world.object(0).sim().z().to_vec(),
        world.object(0).sim().zdot().to_vec(),
    );
    let saved = world.object(0).render_positions();
    for _ in 0..3 {
        world.step().unwrap();
    }
    assert_ne!(world.object(0).render_positions(), saved);
    world.set_state(0, &z, &zdot).unwrap();
    // x = sum_j W_j (A_j X + b_j) is a function of z only: exact equality.
    assert_eq!(world.object(0).render_positions(), saved);
    // Refused (length, NaN, object) and all or nothing.
    let mut nan = z.clone();
    nan[5] = f64::NAN;
    assert!(world.set_state(0, &z[1..], &zdot).is_err());
    assert!(world
        .set_state(0, &nan, &zdot)
        .unwrap_err()
        .to_string()
        .contains("value 5"));
    assert!(world.set_state(1, &z, &zdot).is_err());
    assert_eq!(world.object(0).sim().z(), z);
}

#[test]
fn a_new_placement_puts_the_rest_shape_where_asked() {
    let scene = SceneBuilder::new(0.01, 1)
        .gravity([0.0, -9.81, 0.0])
        .cubature(400)
        .cache(no_cache())
        .object(small_bar("bar"))
        .build()
        .unwrap();
    let mut world = World::new(&scene, &RunSettings::default(), &Silent).unwrap();
    for _ in 0..5 {
        world.step().unwrap();
    }
    let placement = Placement {
        translation: [1.0, 2.0, -0.5],
        rotation: Some(AxisAngle {
            axis: [0.0, 0.0, 1.0],
            degrees: 90.0,
        }),
        ..Placement::default()
    };
    world.set_placement(0, &placement).unwrap();
    let object = world.object(0);
    let rest = object.render_rest();
    let x = object.render_positions();
    // 90 degrees about z: (x, y, z) -> (-y, x, z), then the translation; exact up to the
    // rounding of cos(pi / 2) and of the reduced map (a few ulps of the coordinates).
    for (p, y) in rest.iter().zip(&x) {
        let want = [-p[1] + 1.0, p[0] + 2.0, p[2] - 0.5];
        assert!(max_distance(&[want], &[*y]) < 1e-12, "{y:?} vs {want:?}");
    }
    assert!(object.sim().zdot().iter().all(|v| *v == 0.0));
    // A bad placement is refused and leaves the state alone.
    let z = world.object(0).sim().z().to_vec();
    let bad = Placement {
        velocity: [f64::NAN, 0.0, 0.0],
        ..Placement::default()
    };
    assert!(world.set_placement(0, &bad).is_err());
    assert_eq!(world.object(0).sim().z(), z);
}

/// A fixed floor, the plane y = `y` (metres) facing up.
fn floor_at(y: f64) -> Collider {
    Collider {
        shape: ColliderShape::Plane {
            point: [0.0, y, 0.0],
            normal: [0.0, 1.0, 0.0],
        },
        stiffness: None,
        name: None,
        motion: Motion::Fixed,
        parent: None,
    }
}

#[test]
fn a_raised_floor_pushes_the_object_up_and_bad_poses_are_refused() {
    let floor = floor_at(-0.5);
    let wall = Collider {
        shape: ColliderShape::Box {
            min: [5.0, 5.0, 5.0],
            max: [6.0, 6.0, 6.0],
            rotation: None,
        },
        stiffness: None,
        name: None,
        motion: freeform::sim::motion::Motion::Fixed,
        parent: None,
    };
    let scene = SceneBuilder::new(0.01, 1)
        .cubature(400)
        .cache(no_cache())
        .object(small_bar("bar"))
        .collider(floor)
        .collider(wall)
        .build()
        .unwrap();
    let mut world = World::new(&scene, &RunSettings::default(), &Silent).unwrap();
    let reports = world.step().unwrap();
    assert_eq!(reports[0].solve.info.contacts, 0);
    // Raise the floor through the bar's lower half (the bar spans y in [0, 0.2]).
    let up = Rigid {
        translation: [0.0, 0.6, 0.0],
        ..Rigid::IDENTITY
    };
    world.set_collider_pose(0, &up).unwrap();
    let reports = world.step().unwrap();
    assert!(reports[0].solve.info.contacts > 0);
    let x = world.object(0).render_positions();
    let mean_y = x.iter().map(|p| p[1]).sum::<f64>() / x.len() as f64;
    assert!(mean_y > 0.1, "the floor pushed the bar up: mean y {mean_y}");
    // Every shape takes any rigid pose (boxes too, issue 15); improper rotations, NaN and
    // unknown colliders are refused.
    let turn = Rigid {
        rotation: [[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]],
        translation: [0.0; 3],
    };
    assert!(world.set_collider_pose(1, &up).is_ok());
    assert!(world.set_collider_pose(1, &turn).is_ok());
    assert!(world.set_collider_pose(0, &turn).is_ok());
    let mirror = Rigid {
        rotation: [[-1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
        translation: [0.0; 3],
    };
    assert!(world.set_collider_pose(1, &mirror).is_err());
    let nan = Rigid {
        translation: [f64::NAN, 0.0, 0.0],
        ..Rigid::IDENTITY
    };
    let msg = world.set_collider_pose(0, &nan).unwrap_err().to_string();
    assert!(msg.contains("finite"), "{msg}");
    assert!(world.set_collider_pose(2, &up).is_err());
}

#[test]
fn a_failing_object_is_named_by_index_and_name_with_its_own_error() {
    let scene = SceneBuilder::new(0.01, 1)
        .cache(no_cache())
        .object(small_bar("fine"))
        .object(ObjectSpec::new("missing", "no_such_file.obj").unwrap())
        .build()
        .unwrap();
    let err = World::new(&scene, &RunSettings::default(), &Silent).unwrap_err();
    match &err {
        Error::Object {
            index,
            name,
            source,
        } => {
            assert_eq!((*index, name.as_str()), (1, "missing"));
            assert!(matches!(**source, Error::Geometry(_)), "{source:?}");
        }
        other => panic!("expected Error::Object, got {other:?}"),
    }
    assert!(
        err.to_string().starts_with("scene: object 'missing': "),
        "{err}"
    );
    // The batch runner reports the same error.
    let batch = run(&scene, &RunSettings::default(), &Silent).unwrap_err();
    assert_eq!(batch.to_string(), err.to_string());
}

#[test]
fn a_prepared_object_moves_exactly_as_the_same_object_from_its_shape() {
    use freeform::precompute::{sample_with_material, Problem};
    use freeform::scene::PreparedObject;
    let spec = small_bar("bar").hold(Region::HalfSpace {
        point: [0.2, 0.0, 0.0],
        normal: [-1.0, 0.0, 0.0],
    });
    let builder = || {
        SceneBuilder::new(0.01, 1)
            .gravity([0.0, -9.81, 0.0])
            .cubature(400)
            .cache(no_cache())
    };
    let from_shape = builder().object(spec.clone()).build().unwrap();
    // What the scene computes for the object, computed here and handed over.
    let opts = spec.basis_options().unwrap();
    let shape = freeform::io::read_shape("box:1,0.2,0.2", &Default::default()).unwrap();
    let (points, material) = sample_with_material(&shape, &opts).unwrap();
    let run = Problem::from_points(points.clone(), material.clone(), &opts, &Silent)
        .and_then(|p| p.solve(&Silent))
        .unwrap();
    let prepared = PreparedObject {
        spec: spec.clone(),
        basis: run.basis,
        points,
        material,
    };
    // A scene with no objects of its own is valid for with_objects.
    let mut empty = from_shape.clone();
    empty.objects.clear();
    let settings = RunSettings::default();
    let mut a = World::new(&from_shape, &settings, &Silent).unwrap();
    let mut b = World::with_objects(&empty, &settings, vec![prepared.clone()], &Silent).unwrap();
    for _ in 0..5 {
        a.step().unwrap();
        b.step().unwrap();
    }
    // The same basis, points, materials and settings: the same arithmetic, bit for bit (a
    // primitive is drawn at its integration points, as a prepared object is).
    assert_eq!(
        a.object(0).render_positions(),
        b.object(0).render_positions()
    );

    // Mismatched arrays name the object; no objects at all is refused.
    let mut bad = prepared.clone();
    bad.points.volumes.pop();
    let msg = World::with_objects(&empty, &settings, vec![bad], &Silent)
        .unwrap_err()
        .to_string();
    assert!(
        msg.contains("object 'bar'") && msg.contains("volumes"),
        "{msg}"
    );
    let msg = World::with_objects(&empty, &settings, vec![], &Silent)
        .unwrap_err()
        .to_string();
    assert!(msg.contains("no [[object]]"), "{msg}");
    let twice = World::with_objects(&from_shape, &settings, vec![prepared], &Silent);
    assert!(twice
        .unwrap_err()
        .to_string()
        .contains("two objects are named 'bar'"));
}

#[test]
fn stress_frames_hold_the_material_law_at_a_homogeneous_deformation() {
    use freeform::io::vtk::read_vtp;
    use freeform::material::Material;
    use freeform::scene::{FrameObserver, FrameWriter};
    // A bar whose right half is 10x stiffer, stretched and sheared homogeneously.
    let stiff = Material {
        youngs: 1e6,
        poisson: 0.3,
        density: 1000.0,
    };
    let half = Region::HalfSpace {
        point: [0.5, 0.0, 0.0],
        normal: [1.0, 0.0, 0.0],
    };
    let scene = SceneBuilder::new(0.01, 1)
        .cubature(400)
        .cache(no_cache())
        .object(small_bar("bar").region_material(half, stiff))
        .build()
        .unwrap();
    let mut world = World::new(&scene, &RunSettings::default(), &Silent).unwrap();
    let f = [[1.1, 0.05, 0.0], [0.0, 0.95, 0.02], [0.01, 0.0, 0.97]];
    // x = F X + t through the constant mode alone: W_0 = w0 everywhere (RKPM partition of
    // unity), so Z_0 = [F - I | t] / w0 and every other handle is zero.
    let object = world.object(0);
    let w0 = object.basis().weights(&[[0.5, 0.1, 0.1]]).unwrap().values[0];
    let n = object.sim().z().len();
    let handles = n / 12;
    let mut z = vec![0.0; n];
    for r in 0..3 {
        for a in 0..3 {
            z[r * 4 * handles + a] = (f[r][a] - if r == a { 1.0 } else { 0.0 }) / w0;
        }
        z[r * 4 * handles + 3] = 0.1 / w0;
    }
    world.set_state(0, &z, &vec![0.0; n]).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let mut writer = FrameWriter::new(dir.path(), &[freeform::scene::Format::Vtk])
        .unwrap()
        .stress(true);
    writer.frame(&world, 0).unwrap();
    let frame = read_vtp(&dir.path().join("bar").join("bar_000000.vtp")).unwrap();
    let array = |name: &str| {
        frame
            .point_data
            .iter()
            .find(|(n, _, _)| n == name)
            .unwrap_or_else(|| panic!("no {name}"))
            .2
            .clone()
    };
    let (stress, principal, vm) = (
        array("stress"),
        array("principal_stress"),
        array("von_mises"),
    );
    let rest = world.object(0).render_rest().to_vec();
    let soft = Material {
        youngs: 1e5,
        poisson: 0.4,
        density: 1000.0,
    };
    let mut seen = [0usize; 2];
    for (i, x) in rest.iter().enumerate() {
        let m = if half.contains(x) { stiff } else { soft };
        seen[usize::from(half.contains(x))] += 1;
        let (lambda, mu) = m.lame();
        let want = freeform::elasticity::cauchy_stress(&f, lambda, mu).unwrap();
        let scale = want.iter().flatten().fold(0.0f64, |a, v| a.max(v.abs()));
        // The gradient of W_0 is zero up to the rounding of the partition of unity
        // (~1e-13 of the weights), which enters F through the handle's size (~1/w0):
        // 1e-8 of the largest stress is far above that and far below any real error.
        for k in 0..9 {
            let got = stress[9 * i + k];
            assert!(
                (got - want[k / 3][k % 3]).abs() < 1e-8 * scale,
                "point {i}: {got} vs {want:?}"
            );
        }
        let p = freeform::elasticity::principal_stresses(&want);
        for k in 0..3 {
            assert!((principal[3 * i + k] - p[k]).abs() < 1e-8 * scale);
        }
        let v =
            (0.5 * ((p[0] - p[1]).powi(2) + (p[1] - p[2]).powi(2) + (p[2] - p[0]).powi(2))).sqrt();
        assert!((vm[i] - v).abs() < 1e-8 * scale);
    }
    assert!(seen[0] > 100 && seen[1] > 100, "{seen:?}");
}

#[test]
fn render_inputs_follow_the_object_map_and_bad_ones_are_named() {
    use freeform::io::vtk::read_vtp;
    let dir = tempfile::tempdir().unwrap();
    let base = SceneBuilder::new(0.01, 3)
        .gravity([0.0, -9.81, 0.0])
        .cubature(400)
        .cache(no_cache());
    let held = small_bar("bar").hold(Region::HalfSpace {
        point: [0.2, 0.0, 0.0],
        normal: [-1.0, 0.0, 0.0],
    });
    // Render vertices at some of the object's own render points (its integration points):
    // the map there is the same arithmetic, so the render input's frames must equal the
    // object's own at those points, bit for bit. The last vertex is unreferenced and kept.
    let probe = World::new(
        &base.clone().object(held.clone()).build().unwrap(),
        &RunSettings::default(),
        &Silent,
    )
    .unwrap();
    let picks = [0usize, 7, 100, 500, 1200];
    let rest: Vec<[f64; 3]> = picks
        .iter()
        .map(|&i| probe.object(0).render_rest()[i])
        .collect();
    let mut obj = String::new();
    for p in &rest {
        obj.push_str(&format!("v {} {} {}\n", p[0], p[1], p[2]));
    }
    obj.push_str("f 1 2 3\nf 1 3 4\n");
    std::fs::write(dir.path().join("skin.obj"), obj).unwrap();
    let scene = base
        .clone()
        .object(held.clone().render("skin.obj"))
        .build()
        .unwrap();
    let settings = RunSettings {
        base_dir: dir.path().to_path_buf(),
        out: Some(dir.path().join("out")),
        strict: false,
    };
    run(&scene, &settings, &Silent).unwrap();
    let out = dir.path().join("out");
    for frame in [0, 3] {
        let own = read_vtp(&out.join(format!("bar/bar_{frame:06}.vtp"))).unwrap();
        let skin = read_vtp(&out.join(format!("bar/bar_skin_{frame:06}.vtp"))).unwrap();
        assert_eq!(
            skin.points.len(),
            5,
            "every vertex, the unreferenced one too"
        );
        assert_eq!(skin.triangles.as_deref(), Some(&[[0, 1, 2], [0, 2, 3]][..]));
        for (k, &i) in picks.iter().enumerate() {
            assert_eq!(skin.points[k], own.points[i], "frame {frame}, vertex {k}");
        }
    }
    assert!(out.join("bar_skin.pvd").is_file() && out.join("bar.pvd").is_file());

    // An input outside the object, a missing one, and two with the same name.
    std::fs::write(
        dir.path().join("far.obj"),
        "v 9 9 9\nv 9 9 10\nv 9 10 9\nf 1 2 3\n",
    )
    .unwrap();
    std::fs::create_dir_all(dir.path().join("sub")).unwrap();
    std::fs::copy(dir.path().join("skin.obj"), dir.path().join("sub/skin.obj")).unwrap();
    for (file, second, says) in [
        ("far.obj", None, "outside the simulated object"),
        ("gone.obj", None, "gone.obj"),
        ("skin.obj", Some("sub/skin.obj"), "like another"),
    ] {
        let mut spec = held.clone().render(file);
        if let Some(s) = second {
            spec = spec.render(s);
        }
        let scene = base.clone().object(spec).build().unwrap();
        let msg = World::new(&scene, &settings, &Silent)
            .unwrap_err()
            .to_string();
        assert!(msg.contains("object 'bar'") && msg.contains(says), "{msg}");
    }
}

/// The world holds gravity and the colliders once: every object steps in the same
/// environment (one allocation), before and after a setter changes it, and a refused change
/// leaves it as it was.
#[test]
fn every_object_steps_in_the_one_environment_of_its_world() {
    let floor = floor_at(-0.5);
    let mut second = small_bar("second");
    second.placement.translation = [0.0, 0.0, 2.0];
    let scene = SceneBuilder::new(0.01, 1)
        .cubature(200)
        .cache(no_cache())
        .object(small_bar("first"))
        .object(second)
        .collider(floor)
        .build()
        .unwrap();
    let mut world = World::new(&scene, &RunSettings::default(), &Silent).unwrap();
    let shared = |w: &World| {
        let (a, b) = (
            w.object(0).sim().environment(),
            w.object(1).sim().environment(),
        );
        std::ptr::eq(a, b)
    };
    assert!(shared(&world));
    world.set_gravity(Some([0.0, -9.81, 0.0])).unwrap();
    let up = Rigid {
        translation: [0.0, 0.3, 0.0],
        ..Rigid::IDENTITY
    };
    world.set_collider_pose(0, &up).unwrap();
    assert!(shared(&world));
    for i in 0..2 {
        let env = world.object(i).sim().environment();
        assert_eq!(env.gravity(), Some([0.0, -9.81, 0.0]));
        assert_eq!(env.kinematics().poses(0.0)[0].translation, [0.0, 0.3, 0.0]);
        assert!(world
            .object(i)
            .sim()
            .terms()
            .contains(&"gravity".to_string()));
    }
    assert!(world.set_gravity(Some([f64::NAN, 0.0, 0.0])).is_err());
    assert_eq!(world.object(1).sim().gravity(), Some([0.0, -9.81, 0.0]));
    world.set_gravity(None).unwrap();
    assert!(shared(&world));
    assert!(!world
        .object(0)
        .sim()
        .terms()
        .contains(&"gravity".to_string()));
}
