//! Cost of one mesh-collider query: parry's BVH (what the simulator uses) against the O(F)
//! brute force the tests compare it with, on icospheres of 80 to 20480 triangles.
//!
//! `cargo run --release --example collider_query` prints one row per mesh: triangles, BVH
//! build time, ns per signed-distance query (BVH and brute force) for points spread over the
//! mesh's bounding box padded by 20 %, and the largest difference between the two distances.
//! Then the same ball dropped on a large sphere, the sphere given analytically or as an
//! icosphere mesh of 1280 or 20480 triangles: mean step time over 100 steps.
//! docs/performance.md ("Mesh colliders") quotes the numbers.

use freeform::geometry::generate::{icosphere, torus};
use freeform::geometry::ShapeOptions;
use freeform::io::read_shape;
use freeform::material::Material;
use freeform::precompute::{build_basis, BasisOptions};
use freeform::progress::Silent;
use freeform::sim::collider::{ColliderShape, MeshCollider, MeshObstacle, Sided};
use freeform::sim::{Collider, Placement, ReducedSim, SimOptions};
use freeform::Point3;
use std::path::Path;
use std::sync::Arc;
use std::time::Instant;

/// Vertices (V x 3, metres) and triangles of a mesh.
type Surface = (Vec<Point3>, Vec<[u32; 3]>);

fn points(lo: Point3, hi: Point3, n: usize) -> Vec<Point3> {
    let mut rng = freeform::random::SplitMix64::new(0x9E3779B97F4A7C15);
    (0..n)
        .map(|_| std::array::from_fn(|d| rng.uniform(lo[d], hi[d])))
        .collect()
}

fn main() {
    println!(
        "{:>10} {:>10} {:>12} {:>14} {:>14} {:>12} {:>10}",
        "mesh", "triangles", "build_ms", "bvh_ns/query", "brute_ns/query", "max|diff| m", "inside"
    );
    let mut meshes: Vec<(String, Surface)> = (1..=5)
        .map(|s| (format!("ico{s}"), icosphere(0.5, s)))
        .collect();
    meshes.push(("torus".into(), torus(1.0, 0.3, 64, 24)));
    for (name, (v, t)) in meshes {
        let nt = t.len();
        let clock = Instant::now();
        let mesh = MeshObstacle::from_triangles(Path::new(&name), v, t, Sided::Solid).unwrap();
        let build = clock.elapsed().as_secs_f64() * 1e3;
        let b = mesh.bounding_box();
        let pad = 0.2 * b.diagonal();
        let q = points(b.min.map(|c| c - pad), b.max.map(|c| c + pad), 20000);
        let clock = Instant::now();
        let fast: Vec<f64> = q.iter().map(|y| mesh.signed_distance(y)).collect();
        let bvh_ns = clock.elapsed().as_secs_f64() * 1e9 / q.len() as f64;
        // Brute force (and its exact winding-number sign) on fewer points for large meshes.
        let nb = (2_000_000 / nt).clamp(200, q.len());
        let clock = Instant::now();
        let slow: Vec<f64> = q[..nb]
            .iter()
            .map(|y| mesh.signed_distance_brute_force(y))
            .collect();
        let brute_ns = clock.elapsed().as_secs_f64() * 1e9 / nb as f64;
        let diff = fast[..nb]
            .iter()
            .zip(&slow)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        let inside = fast.iter().filter(|d| **d < 0.0).count();
        println!(
            "{name:>10} {nt:>10} {build:>12.2} {bvh_ns:>14.0} {brute_ns:>14.0} {diff:>12.1e} {:>9.1}%",
            100.0 * inside as f64 / q.len() as f64
        );
        // The penetration query the contact term runs (solids reject points outside the
        // bounding box before asking the BVH): the cost per cubature point.
        let clock = Instant::now();
        let hits = q.iter().filter_map(|y| mesh.penetration_local(y)).count();
        let pen_ns = clock.elapsed().as_secs_f64() * 1e9 / q.len() as f64;
        println!(
            "{:>10} penetration_local: {pen_ns:.0} ns per point ({hits} inside)",
            ""
        );
    }
    drop_on_a_sphere();
}

/// A soft ball (radius 0.3 m, 1000 cubature points) dropped on a sphere of radius 2 m.
fn drop_on_a_sphere() {
    let shape = read_shape("sphere:0.3", &ShapeOptions::default()).unwrap();
    let opts = BasisOptions {
        kernels: 200,
        modes: 8,
        material: Material {
            youngs: 2e5,
            poisson: 0.4,
            density: 1000.0,
        },
        ..BasisOptions::default()
    };
    let run = build_basis(&shape, &opts, &Silent).unwrap();
    let centre = [0.0, -2.0, 0.0];
    let mut obstacles = vec![(
        "analytic sphere".to_string(),
        ColliderShape::Sphere {
            center: centre,
            radius: 2.0,
        },
    )];
    for s in [3, 5] {
        let (v, t) = icosphere(2.0, s);
        let v = v.iter().map(|p| [p[0], p[1] - 2.0, p[2]]).collect();
        let nt = t.len();
        let mesh = MeshObstacle::from_triangles(Path::new("ico"), v, t, Sided::Solid).unwrap();
        obstacles.push((
            format!("mesh, {nt} triangles"),
            ColliderShape::Mesh(MeshCollider {
                loaded: Some(Arc::new(mesh)),
                ..MeshCollider::new("ico")
            }),
        ));
    }
    println!(
        "\nball (1000 cubature points, m = 8, newton) dropped on a sphere, 100 steps of 5 ms:"
    );
    for (name, shape) in obstacles {
        let sim_opts = SimOptions {
            dt: 0.005,
            gravity: Some([0.0, -9.81, 0.0]),
            cubature: 1000,
            newton: freeform::sim::NewtonOptions {
                hessian: freeform::sim::HessianStrategy::Newton,
                ..Default::default()
            },
            colliders: vec![Collider::new(shape)],
            placement: Placement {
                translation: [0.0, 0.35, 0.0],
                ..Placement::default()
            },
            ..SimOptions::default()
        };
        let mut sim = ReducedSim::new(&run.basis, &run.points, &run.material, &sim_opts).unwrap();
        let (mut ms, mut evals, mut contacts, mut deepest) = (0.0, 0, 0, 0.0f64);
        for _ in 0..100 {
            let r = sim.step();
            ms += r.wall_s * 1e3;
            evals += r.solve.evaluations;
            contacts = contacts.max(r.solve.info.contacts);
            deepest = deepest.max(r.solve.info.penetration);
        }
        println!(
            "{name:>24}: {:.2} ms per step, {:.1} evaluations per step, up to {contacts} contacts, \
             deepest {deepest:.1e} m",
            ms / 100.0,
            evals as f64 / 100.0
        );
    }
}
