//! A fast small object against a thin plate does not tunnel (issue 15): a 2 cm ball at 30 m/s
//! with h = 10 ms moves 0.3 m, fifteen of its diameters and sixty plate thicknesses, per
//! step. Against a 5 mm static plate (a box collider, and the same plate as a closed mesh)
//! and against a 1 cm deformable plate object with `[contact]`, every point of the ball must
//! end on the side it came from.
//!
//! Why this can fail: the collider penalty only sees the end-of-step positions, and the
//! inertial guess of the first step already puts the ball 0.25 m past the plate, where no
//! point penetrates (no force at all), or, for a point caught inside past the plate's
//! mid-plane, the nearest surface is the far one and the penalty pushes it on through. The
//! line search's swept step bound (docs/limits.md) is what stops it.

use crate::common::no_cache;
use freeform::io::obj::write_obj;
use freeform::material::{Material, Region};
use freeform::progress::Silent;
use freeform::scene::{ObjectSpec, RunSettings, Scene, SceneBuilder, World};
use freeform::sim::collider::{ColliderShape, MeshCollider};
use freeform::sim::contact::ContactSettings;
use freeform::sim::{Collider, Placement};
use freeform::Point3;
use std::path::Path;

/// Plate top surface (y, metres) of the static plates: a 5 mm plate centred on y = 0.
const TOP: f64 = 0.0025;
const STEPS: usize = 10;

/// The 2 cm ball, 3 cm above y = 0 and falling at 30 m/s.
fn ball() -> ObjectSpec {
    ObjectSpec::new("ball", "sphere:0.01")
        .unwrap()
        .kernels(20)
        .modes(3)
        .points(800)
        .material(Material {
            youngs: 1e6,
            poisson: 0.3,
            density: 1000.0,
        })
        .placement(Placement {
            translation: [0.0, 0.03, 0.0],
            velocity: [0.0, -30.0, 0.0],
            ..Placement::default()
        })
}

fn run(scene: &Scene) -> World {
    let mut w = World::new(scene, &RunSettings::default(), &Silent).unwrap();
    for _ in 0..STEPS {
        w.step().unwrap();
    }
    w
}

/// Every integration point (the cubature points are among them) and render point of object
/// `i`, deformed.
fn all_points(w: &World, i: usize) -> Vec<Point3> {
    let o = w.object(i);
    let mut x = o.integration_positions().unwrap();
    x.extend(o.render_positions());
    x
}

/// The lowest point of the ball, metres.
fn lowest(w: &World) -> f64 {
    all_points(w, 0)
        .iter()
        .map(|p| p[1])
        .fold(f64::INFINITY, f64::min)
}

/// A thin closed box mesh [min, max] (12 outward triangles) written as OBJ.
fn slab_obj(path: &Path, min: Point3, max: Point3) {
    let v: Vec<Point3> = (0..8)
        .map(|k| {
            [
                if k & 1 == 0 { min[0] } else { max[0] },
                if k & 2 == 0 { min[1] } else { max[1] },
                if k & 4 == 0 { min[2] } else { max[2] },
            ]
        })
        .collect();
    // Faces counter-clockwise seen from outside.
    let quads = [
        [0, 2, 3, 1], // z = min
        [4, 5, 7, 6], // z = max
        [0, 1, 5, 4], // y = min
        [2, 6, 7, 3], // y = max
        [0, 4, 6, 2], // x = min
        [1, 3, 7, 5], // x = max
    ];
    let t: Vec<[u32; 3]> = quads
        .iter()
        .flat_map(|q| [[q[0], q[1], q[2]], [q[0], q[2], q[3]]])
        .collect();
    write_obj(path, &v, &t).unwrap();
}

/// The ball against a static 5 mm plate: a box collider, then the same plate as a closed
/// mesh. Without a swept bound the ball is 3 m below the plate after ten steps (30 m/s for
/// 0.1 s); it must instead stay on top: every point above the plate's mid-plane (y > 0).
/// Only the cubature points feel the penalty, and the other integration points lie up to a
/// grid spacing (about 2 mm here) beyond them, so points slightly inside the plate's top
/// half are expected; past the mid-plane the ball would be on the far side.
#[test]
fn a_fast_small_ball_does_not_tunnel_through_a_thin_static_plate() {
    let (min, max) = ([-0.1, -TOP, -0.1], [0.1, TOP, 0.1]);
    let dir = tempfile::tempdir().unwrap();
    let obj = dir.path().join("slab.obj");
    slab_obj(&obj, min, max);
    let plates = [
        (
            "box",
            ColliderShape::Box {
                min,
                max,
                rotation: None,
            },
        ),
        ("mesh", ColliderShape::Mesh(MeshCollider::new(&obj))),
    ];
    for (kind, shape) in plates {
        let scene = SceneBuilder::new(0.01, STEPS)
            .cache(no_cache())
            .cubature(150)
            .object(ball())
            .collider(Collider::new(shape))
            .build()
            .unwrap();
        let w = run(&scene);
        let low = lowest(&w);
        assert!(
            low > 0.0,
            "{kind} plate: the ball tunnelled: its lowest point is at y = {low} m (plate \
             top {TOP} m)"
        );
        // And it touched the plate: the penalty acted (a tunnelled ball never penetrates
        // at a step's end: main before the sweep reported 0 contacts in all ten steps).
        let touched = w.object(0).summary().steps.iter().any(|s| s.contacts > 0);
        assert!(touched, "{kind} plate: the ball never touched it");
    }
}

/// The ball against a deformable 1 cm plate (top at y = 5 mm) held at both ends, with
/// object-object contact: every point of the ball must stay above the plate's mid-plane
/// within the ball's footprint (|x|, |z| < 2 cm), so on the incoming side however the plate
/// bends. The island's object-object step bound already held this before the collider
/// sweep was added (main's CLI on this scene: lowest ball point 5.6 mm, 3 mm above the
/// plate's top integration points); the case guards it.
#[test]
fn a_fast_small_ball_does_not_tunnel_through_a_thin_deformable_plate() {
    let plate = ObjectSpec::new("plate", "box:0.2,0.01,0.2")
        .unwrap()
        .kernels(30)
        .modes(4)
        .points(2000)
        .contact_samples(5000)
        .material(Material {
            youngs: 1e7,
            poisson: 0.3,
            density: 1000.0,
        })
        // Regions select rest positions: a box spans [0, size], so these are its two 1 cm
        // end strips; the placement centres it on the origin.
        .hold(Region::HalfSpace {
            point: [0.01, 0.0, 0.0],
            normal: [-1.0, 0.0, 0.0],
        })
        .hold(Region::HalfSpace {
            point: [0.19, 0.0, 0.0],
            normal: [1.0, 0.0, 0.0],
        })
        .placement(Placement {
            translation: [-0.1, -0.005, -0.1],
            ..Placement::default()
        });
    let scene = SceneBuilder::new(0.01, STEPS)
        .cache(no_cache())
        .cubature(150)
        .object(ball().contact_samples(300))
        .object(plate)
        // Default thickness t = each object's sample spacing: 4.2 mm for the plate's 5000
        // samples (below its 5 mm half-thickness), 2 mm for the ball's 300; their sum 6.2 mm
        // exceeds sqrt(2) x 4.2 mm, the condition under which the object-object step bound
        // keeps a sample from slipping through the plate's sample sheet (docs/limits.md).
        .contact(ContactSettings::default())
        .build()
        .unwrap();
    let w = run(&scene);
    let low = lowest(&w);
    // The plate's mid-plane under the ball: the mean height of its points there (its
    // integration points lie symmetrically about it, at +-2.5 mm).
    let under: Vec<f64> = all_points(&w, 1)
        .iter()
        .filter(|p| p[0].abs() < 0.02 && p[2].abs() < 0.02)
        .map(|p| p[1])
        .collect();
    assert!(!under.is_empty());
    let mid = under.iter().sum::<f64>() / under.len() as f64;
    assert!(
        low > mid,
        "the ball tunnelled: its lowest point is at y = {low} m, the plate's mid-plane under \
         it at {mid} m"
    );
    let c = w.contact_summary().unwrap();
    assert!(
        c.steps.iter().any(|s| s.sample_pairs_active > 0),
        "the ball never touched the plate: {c:?}"
    );
}
