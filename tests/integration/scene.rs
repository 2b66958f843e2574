//! Scenes: the TOML format (round trip, line-numbered errors, the example files), the basis
//! cache, "model only what is declared", outputs, and a drop on a floor.

use crate::common::{no_cache, small_bar};
use freeform::material::{Material, Region};
use freeform::progress::Silent;
use freeform::scene::{
    run, CacheSettings, Format, ObjectSpec, OutputSettings, RunSettings, Scene, SceneBuilder,
};
use freeform::sim::motion::Motion;
use freeform::sim::terms::ColliderShape;
use freeform::sim::{Collider, Placement};
use std::path::Path;

#[test]
fn scene_round_trips_through_toml() {
    let scene = SceneBuilder::new(0.02, 7)
        .gravity([0.0, -9.81, 0.0])
        .cubature(500)
        .object(
            small_bar("a")
                .hold(Region::HalfSpace {
                    point: [0.1, 0.0, 0.0],
                    normal: [-1.0, 0.0, 0.0],
                })
                .boundary(
                    Region::Box {
                        min: [0.9, -1.0, -1.0],
                        max: [2.0, 1.0, 1.0],
                    },
                    Motion::Rotate {
                        pivot: [0.0, 0.1, 0.1],
                        axis: [1.0, 0.0, 0.0],
                        degrees_per_second: 90.0,
                    },
                )
                .region_material(
                    Region::Sphere {
                        center: [0.5, 0.1, 0.1],
                        radius: 0.05,
                    },
                    Material {
                        youngs: 1e8,
                        poisson: 0.3,
                        density: 3000.0,
                    },
                )
                .placement(Placement {
                    translation: [0.0, 1.0, 0.0],
                    velocity: [1.0, 0.0, 0.0],
                    ..Placement::default()
                }),
        )
        .collider(Collider {
            shape: ColliderShape::Plane {
                point: [0.0; 3],
                normal: [0.0, 1.0, 0.0],
            },
            stiffness: Some(1e9),
            name: None,
            motion: freeform::sim::motion::Motion::Fixed,
            parent: None,
        })
        .build()
        .unwrap();
    let text = scene.to_toml().unwrap();
    let back = Scene::from_toml(&text).unwrap();
    assert_eq!(back, scene, "{text}");
}

#[test]
fn example_scenes_parse() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("examples");
    let mut n = 0;
    for name in [
        "beam_bend.toml",
        "beam_twist.toml",
        "drop.toml",
        "heterogeneous.toml",
        "layered_sphere.toml",
        "stack.toml",
        "plinko.toml",
        "container.toml",
        "self_contact.toml",
        "plinko_splats.toml",
        "container_splats.toml",
        "pour64.toml",
    ] {
        let s = Scene::load(&dir.join(name)).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert!(!s.objects.is_empty());
        n += 1;
    }
    assert_eq!(n, 12);
    // Self-contact: on for the clip, with a thickness below half its 0.1 m slot.
    let clip = Scene::load(&dir.join("self_contact.toml")).unwrap();
    let contact = clip.contact.as_ref().unwrap();
    assert!(contact.self_contact && contact.radius.is_some_and(|r| r < 0.05));
    // Plinko: the issue's 18 objects of K = 500, m = 12, with contact, through 20 pegs.
    let plinko = Scene::load(&dir.join("plinko.toml")).unwrap();
    assert_eq!(plinko.objects.len(), 18);
    assert!(plinko
        .objects
        .iter()
        .all(|o| o.basis.kernels == 500 && o.basis.modes == 12));
    assert_eq!(plinko.contact.as_ref().map(|c| c.friction), Some(0.3));
    assert_eq!(plinko.colliders.len(), 27);
    // The container: 13 objects of five shapes, two of them the closed meshes that
    // scripts/example_meshes.py writes (they read as solids), in a one-sided mesh container.
    let c = Scene::load(&dir.join("container.toml")).unwrap();
    assert_eq!(c.objects.len(), 13);
    let mut shapes: Vec<&str> = c.objects.iter().map(|o| o.shape.text()).collect();
    shapes.sort_unstable();
    shapes.dedup();
    assert_eq!(shapes.len(), 5);
    for mesh in ["torus.obj", "ell.obj"] {
        let path = dir.join("data").join(mesh);
        let shape = freeform::io::read_shape(path.to_str().unwrap(), &Default::default())
            .unwrap_or_else(|e| panic!("{mesh}: {e}"));
        assert_eq!(shape.kind(), "mesh", "{mesh}");
    }
    assert_eq!(c.colliders.len(), 1);
    // The contact example has contact (with its friction) and three objects to touch.
    let stack = Scene::load(&dir.join("stack.toml")).unwrap();
    assert_eq!(stack.objects.len(), 3);
    assert_eq!(stack.contact.as_ref().map(|c| c.friction), Some(0.5));
    // The layered sphere: shells alternate, stiff innermost (each override wins over the ones
    // before it, so the smallest ball is the last).
    let l = Scene::load(&dir.join("layered_sphere.toml")).unwrap();
    let e: Vec<f64> = std::iter::once(l.objects[0].material.youngs)
        .chain(l.objects[0].overrides.iter().map(|o| o.material.youngs))
        .collect();
    assert_eq!(e, [3e5, 3e7, 3e5, 3e7]);
    // The twist example is the standard twist: 720 degrees after 200 steps.
    let t = Scene::load(&dir.join("beam_twist.toml")).unwrap();
    let Motion::Rotate {
        degrees_per_second, ..
    } = t.objects[0].boundaries[1].motion
    else {
        panic!("expected a rotation");
    };
    let total = degrees_per_second * t.simulation.dt * t.simulation.steps as f64;
    assert!((total - 720.0).abs() < 1e-9);
}

#[test]
fn bad_scene_files_give_located_errors() {
    let base =
        "[simulation]\ndt = 0.01\nsteps = 10\n\n[[object]]\nname = \"a\"\nshape = \"box:1,1,1\"\n";
    let cases: Vec<(String, &str)> = vec![
        // Unknown key: named, with its line.
        (base.to_string() + "colour = \"red\"\n", "line 8"),
        (base.to_string() + "colour = \"red\"\n", "colour"),
        // Wrong type.
        (base.replace("steps = 10", "steps = \"ten\""), "line 3"),
        // Syntax error.
        (base.replace("dt = 0.01", "dt = = 0.01"), "line 2"),
        // Unknown motion kind.
        (
            base.to_string()
                + "[[object.boundary]]\nregion = { sphere = { center = [0,0,0], radius = 1.0 } }\nmotion = \"wobble\"\n",
            "line 10",
        ),
        // Semantic errors name the key.
        (base.replace("dt = 0.01", "dt = -1.0"), "simulation.dt"),
        (base.replace("name = \"a\"", "name = \"a b\""), "object name"),
        (
            base.to_string() + "basis = { kernels = 10, points = 100, spacing = 0.1 }\n",
            "not both",
        ),
        ("[simulation]\ndt = 0.01\nsteps = 1\n".to_string(), "no [[object]]"),
        (
            base.to_string()
                + "[[collider]]\nshape = { plane = { point = [0,0,0], normal = [0,0,0] } }\n",
            "non-zero normal",
        ),
    ];
    for (text, want) in &cases {
        let err = Scene::from_toml(text).expect_err(text).to_string();
        assert!(
            err.contains(want),
            "expected '{want}' in: {err}\n--- scene:\n{text}"
        );
    }
}

#[test]
fn only_declared_terms_are_built_and_an_unloaded_object_stays_put() {
    // No gravity, no boundaries, no colliders: only inertia and elasticity, and nothing moves.
    let scene = SceneBuilder::new(0.01, 5)
        .cubature(400)
        .cache(no_cache())
        .object(small_bar("still"))
        .build()
        .unwrap();
    let s = run(&scene, &RunSettings::default(), &Silent).unwrap();
    let o = &s.objects[0];
    assert_eq!(o.terms, vec!["inertia", "elastic"]);
    // Every step takes its one mandatory iteration, which finds nothing to change.
    assert!(o.steps.iter().all(|r| r.converged && r.iterations == 1));
    assert!(
        o.steps.iter().all(|r| r.energy.abs() < 1e-12),
        "{:?}",
        o.steps
    );
    assert_eq!(s.files.len(), 0);
    // Declared terms do appear.
    let scene = SceneBuilder::new(0.01, 2)
        .gravity([0.0, -9.81, 0.0])
        .cubature(400)
        .cache(no_cache())
        .object(small_bar("held").hold(Region::HalfSpace {
            point: [0.1, 0.0, 0.0],
            normal: [-1.0, 0.0, 0.0],
        }))
        .collider(Collider {
            shape: ColliderShape::Plane {
                point: [0.0, -1.0, 0.0],
                normal: [0.0, 1.0, 0.0],
            },
            stiffness: None,
            name: None,
            motion: freeform::sim::motion::Motion::Fixed,
            parent: None,
        })
        .build()
        .unwrap();
    let s = run(&scene, &RunSettings::default(), &Silent).unwrap();
    let t = &s.objects[0].terms;
    assert_eq!(t.len(), 5, "{t:?}");
    assert_eq!(t[2], "gravity");
    assert!(t[3].starts_with("boundary 0") && t[4].starts_with("colliders"));
}

#[test]
fn basis_cache_is_reused_and_keyed_by_what_made_it() {
    let dir = tempfile::tempdir().unwrap();
    let cache = CacheSettings {
        enabled: true,
        dir: dir.path().join("cache"),
    };
    let mk = |m: Material| {
        SceneBuilder::new(0.01, 3)
            .gravity([0.0, -9.81, 0.0])
            .cubature(300)
            .cache(cache.clone())
            .object(small_bar("c").material(m).hold(Region::HalfSpace {
                point: [0.1, 0.0, 0.0],
                normal: [-1.0, 0.0, 0.0],
            }))
            .build()
            .unwrap()
    };
    let soft = Material {
        youngs: 1e5,
        poisson: 0.4,
        density: 1000.0,
    };
    let settings = RunSettings::default();
    let first = run(&mk(soft), &settings, &Silent).unwrap();
    let second = run(&mk(soft), &settings, &Silent).unwrap();
    assert!(!first.objects[0].basis_cached);
    assert!(second.objects[0].basis_cached);
    assert_eq!(first.objects[0].basis_file, second.objects[0].basis_file);
    // Same basis, same simulation: identical energies step by step.
    let e = |s: &freeform::scene::RunSummary| -> Vec<f64> {
        s.objects[0].steps.iter().map(|r| r.energy).collect()
    };
    assert_eq!(e(&first), e(&second));
    // A different material is a different basis.
    let stiff = Material {
        youngs: 1e6,
        ..soft
    };
    let third = run(&mk(stiff), &settings, &Silent).unwrap();
    assert!(!third.objects[0].basis_cached);
    assert_ne!(first.objects[0].basis_file, third.objects[0].basis_file);
    // A damaged cache file is replaced, with a warning.
    let f = first.objects[0].basis_file.clone().unwrap();
    std::fs::write(&f, b"not a zip").unwrap();
    let fourth = run(&mk(soft), &settings, &Silent).unwrap();
    assert!(!fourth.objects[0].basis_cached);
    assert!(fourth
        .warnings
        .iter()
        .any(|w| w.to_string().contains("cached basis")));
    assert_eq!(e(&first), e(&fourth));
}

#[test]
fn frames_are_written_for_paraview_and_a_ball_rests_on_the_floor() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    let dt = 0.01;
    let scene = SceneBuilder::new(dt, 60)
        .gravity([0.0, -9.81, 0.0])
        .cubature(600)
        .cache(no_cache())
        .output(OutputSettings {
            every: 20,
            formats: vec![Format::Vtk, Format::Ply],
            ..Default::default()
        })
        .object(
            ObjectSpec::new("ball", "sphere:0.2")
                .unwrap()
                .kernels(80)
                .modes(6)
                .points(4000)
                .material(Material {
                    youngs: 1e5,
                    poisson: 0.4,
                    density: 1000.0,
                })
                .placement(Placement {
                    translation: [0.0, 0.25, 0.0],
                    ..Placement::default()
                }),
        )
        .collider(Collider {
            shape: ColliderShape::Plane {
                point: [0.0; 3],
                normal: [0.0, 1.0, 0.0],
            },
            stiffness: None,
            name: None,
            motion: freeform::sim::motion::Motion::Fixed,
            parent: None,
        })
        .hessian(freeform::sim::HessianStrategy::Newton)
        .build()
        .unwrap();
    let s = run(
        &scene,
        &RunSettings {
            base_dir: dir.path().to_path_buf(),
            out: Some(out.clone()),
            strict: false,
        },
        &Silent,
    )
    .unwrap();
    // Frames 0, 20, 40, 60 in two formats plus the .pvd.
    assert_eq!(s.frames, 4);
    assert_eq!(s.files.len(), 9);
    let pvd = std::fs::read_to_string(out.join("ball.pvd")).unwrap();
    assert_eq!(pvd.matches("<DataSet").count(), 4);
    assert!(out.join("ball/ball_000060.vtp").exists());
    assert!(out.join("ball/ball_000060.ply").exists());
    let o = &s.objects[0];
    assert_eq!(o.nonconverged_steps, 0, "{:?}", s.warnings);
    // The ball fell 5 cm onto the floor (in 0.1 s) and was caught by the penalty: contacts
    // are active at the end.
    assert!(o.steps.last().unwrap().contacts > 0);
    // The PLY of the last frame: every point above the floor up to the penalty's give.
    // Penetration under the ball's own weight ~ rho g H / kappa with kappa >= 1e3 rho/h^2:
    // ~ g H h^2 / 1e3 ~ 4e-7 m; the dynamic impact adds more. Allow 1% of the radius.
    let ply = freeform::io::read_shape(
        out.join("ball/ball_000060.ply").to_str().unwrap(),
        &Default::default(),
    )
    .unwrap();
    let pts = ply.render_points().unwrap();
    let min_y = pts.iter().map(|p| p[1]).fold(f64::INFINITY, f64::min);
    assert!(min_y > -2e-3, "penetration {min_y}");
    assert!(
        min_y < 0.05,
        "the ball must have reached the floor: {min_y}"
    );
}

#[test]
fn mesh_and_point_cloud_objects_write_deformed_meshes_and_points() {
    use freeform::geometry::generate::icosphere;
    let dir = tempfile::tempdir().unwrap();
    let (v, t) = icosphere(0.3, 2);
    freeform::io::obj::write_obj(&dir.path().join("ball.obj"), &v, &t).unwrap();
    // A point cloud: a jittered grid inside a 0.6 m cube.
    let mut cloud = Vec::new();
    for i in 0..12 {
        for j in 0..12 {
            for k in 0..12 {
                cloud.push([i as f64 * 0.05, j as f64 * 0.05, k as f64 * 0.05]);
            }
        }
    }
    freeform::io::ply::write_ply_points(&dir.path().join("cloud.ply"), &cloud, &[]).unwrap();
    let held = |x: f64| Region::HalfSpace {
        point: [x, 0.0, 0.0],
        normal: [-1.0, 0.0, 0.0],
    };
    let scene = SceneBuilder::new(0.01, 4)
        .gravity([0.0, -9.81, 0.0])
        .cubature(400)
        .cache(no_cache())
        .output(OutputSettings {
            every: 4,
            formats: vec![Format::Vtk, Format::Ply],
            ..Default::default()
        })
        .object(
            ObjectSpec::new("ball", "ball.obj")
                .unwrap()
                .kernels(80)
                .modes(4)
                .points(4000)
                .hold(held(-0.2)),
        )
        .object(
            ObjectSpec::new("cloud", "cloud.ply")
                .unwrap()
                .kernels(80)
                .modes(4)
                .hold(held(0.1)),
        )
        .build()
        .unwrap();
    let out = dir.path().join("out");
    let s = run(
        &scene,
        &RunSettings {
            base_dir: dir.path().to_path_buf(),
            out: Some(out.clone()),
            strict: false,
        },
        &Silent,
    )
    .unwrap();
    // Render points: the mesh's vertices, the cloud's points.
    assert_eq!(s.objects[0].render_points, v.len());
    assert_eq!(s.objects[1].render_points, cloud.len());
    // The deformed mesh keeps its triangles in both formats.
    let vtp = std::fs::read(out.join("ball/ball_000004.vtp")).unwrap();
    let head = String::from_utf8_lossy(&vtp[..600.min(vtp.len())]).to_string();
    assert!(
        head.contains(&format!("NumberOfPolys=\"{}\"", t.len())),
        "{head}"
    );
    let mesh = freeform::io::read_shape(
        out.join("ball/ball_000004.ply").to_str().unwrap(),
        &Default::default(),
    )
    .unwrap();
    let freeform::geometry::Shape::Mesh(m) = mesh else {
        panic!("the ball's PLY must be a mesh");
    };
    assert_eq!(m.triangles().len(), t.len());
    // The mesh moved (gravity, held only at its far left).
    let moved = m
        .vertices()
        .iter()
        .zip(&v)
        .map(|(a, b)| (a[1] - b[1]).abs())
        .fold(0.0, f64::max);
    assert!(moved > 1e-4, "{moved}");
    let vtp = std::fs::read(out.join("cloud/cloud_000004.vtp")).unwrap();
    let head = String::from_utf8_lossy(&vtp[..600]).to_string();
    assert!(head.contains(&format!("NumberOfVerts=\"{}\"", cloud.len())));
}

/// The reference scene of docs/scenes.md (its first toml block) parses, and the solver values
/// it lists as defaults are the code's defaults: the docs cannot drift from the code.
#[test]
fn the_documented_reference_scene_parses_with_the_code_defaults() {
    let doc = std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("docs/scenes.md"))
        .unwrap();
    let start = doc.find("```toml\n").expect("a toml block") + "```toml\n".len();
    let len = doc[start..].find("```").expect("the block's end");
    let scene = Scene::from_toml(&doc[start..start + len]).unwrap_or_else(|e| panic!("{e}"));
    assert!(!scene.objects.is_empty());
    assert_eq!(scene.solver, freeform::scene::SolverSettings::default());
}
