//! Small fixtures shared by the integration tests.
#![allow(dead_code)]

use freeform::geometry::Aabb;
use freeform::material::Material;
use freeform::precompute::centers::farthest_point_sampling;
use freeform::precompute::rkpm::{support_radii, KernelType, Kernels, SupportOptions};
use freeform::precompute::sampling::Resolution;
use freeform::precompute::sampling::{grid_points, IntegrationPoints};
use freeform::precompute::{build_basis, BasisOptions, BasisRun, SolverConfig};
use freeform::scene::{CacheSettings, ObjectSpec, World};
use freeform::Point3;

/// Grid points filling the box [0, size] at spacing h.
pub fn box_points(size: [f64; 3], h: f64) -> IntegrationPoints {
    let aabb = Aabb {
        min: [0.0; 3],
        max: size,
    };
    grid_points(&aabb, h, None, &|p: &[Point3]| vec![true; p.len()]).expect("box grid")
}

/// K kernels by FPS over the points, default supports.
pub fn kernels_for(ip: &IntegrationPoints, k: usize, kind: KernelType) -> Kernels {
    let idx = farthest_point_sampling(&ip.points, k).expect("fps");
    let centers: Vec<Point3> = idx.iter().map(|&i| ip.points[i]).collect();
    let radii = support_radii(&centers, &SupportOptions::default()).expect("radii");
    Kernels {
        centers,
        radii,
        kind,
    }
}

/// Run the `freeform` binary with `args` and collect its output.
pub fn freeform(args: &[&str]) -> std::process::Output {
    std::process::Command::new(env!("CARGO_BIN_EXE_freeform"))
        .args(args)
        .output()
        .expect("run freeform")
}

/// The bar of tests/integration/sim.rs and extremes.rs held at its left end (x <= 0.1 m).
pub fn held_left() -> freeform::sim::Boundary {
    freeform::sim::Boundary {
        region: freeform::material::Region::HalfSpace {
            point: [0.1, 0.0, 0.0],
            normal: [-1.0, 0.0, 0.0],
        },
        motion: freeform::sim::motion::Motion::Fixed,
        stiffness: None,
    }
}

/// A small, fast object: a 1 x 0.2 x 0.2 bar with few kernels.
pub fn small_bar(name: &str) -> ObjectSpec {
    ObjectSpec::new(name, "box:1,0.2,0.2")
        .unwrap()
        .kernels(60)
        .modes(6)
        .points(3000)
        .material(Material {
            youngs: 1e5,
            poisson: 0.4,
            density: 1000.0,
        })
}

/// Scene cache settings with the cache off.
pub fn no_cache() -> CacheSettings {
    CacheSettings {
        enabled: false,
        ..CacheSettings::default()
    }
}

/// The basis of the 1 x 0.2 x 0.2 m bar of the simulation tests (dense eigensolver) with
/// `kernels`, `modes`, `points` integration points and a homogeneous `material`.
pub fn bar_basis(kernels: usize, modes: usize, points: usize, material: Material) -> BasisRun {
    let shape = freeform::io::read_shape(
        "box:1,0.2,0.2",
        &freeform::geometry::ShapeOptions::default(),
    )
    .unwrap();
    let opts = BasisOptions {
        kernels,
        modes,
        resolution: Some(Resolution::Count(points)),
        solver: SolverConfig::Dense,
        material,
        ..BasisOptions::default()
    };
    build_basis(&shape, &opts, &freeform::progress::Silent).unwrap()
}

/// The simulation tests' rubber-like material: E = 1e5 Pa, nu = 0.4, rho = 1000 kg/m^3.
pub fn rubber() -> Material {
    Material {
        youngs: 1e5,
        poisson: 0.4,
        density: 1000.0,
    }
}

/// Every object's integration-point positions, metres.
pub fn world_positions(w: &World) -> Vec<Vec<Point3>> {
    w.objects()
        .iter()
        .map(|o| o.integration_positions().unwrap())
        .collect()
}

/// Linear momentum of every object, sum rho v xdot over the integration points, from the
/// positions before and after the last step (kg m/s).
pub fn world_momentum(w: &World, before: &[Vec<Point3>]) -> [f64; 3] {
    let mut p = [0.0; 3];
    for (o, x0) in w.objects().iter().zip(before) {
        let x1 = o.integration_positions().unwrap();
        let rho = o.spec().material.density;
        for ((a, b), v) in x0.iter().zip(&x1).zip(&o.rest_points().volumes) {
            for d in 0..3 {
                p[d] += rho * v * (b[d] - a[d]) / w.dt();
            }
        }
    }
    p
}

/// Step a world of free objects (no gravity, no friction, solved to `tol`) `steps` times and
/// assert that its objects touched on at least two steps, every step converged, and the
/// total linear momentum after the first step stayed what it was within the solver's bound:
/// at a converged step the remaining Newton step has a mass-weighted RMS length below tol D
/// per object, so each object's momentum is off by at most M tol D / h per step. Returns the
/// positions before the last step.
pub fn assert_momentum_conserved(w: &mut World, tol: f64, steps: usize) -> Vec<Vec<Point3>> {
    let bound_per_step: f64 = w
        .objects()
        .iter()
        .map(|o| o.sim().total_mass() * tol * o.sim().diagonal() / w.dt())
        .sum();
    let mut before = world_positions(w);
    w.step().unwrap();
    let p0 = world_momentum(w, &before);
    let mut touched = 0;
    for _ in 1..steps {
        before = world_positions(w);
        w.step().unwrap();
        let row = w.contact_summary().unwrap().steps.last().unwrap().clone();
        touched += usize::from(row.sample_pairs_active > 0);
    }
    let p1 = world_momentum(w, &before);
    assert!(touched >= 2, "the objects never touched");
    for r in w.objects().iter().flat_map(|o| o.summary().steps.iter()) {
        assert!(r.converged, "{r:?}");
    }
    let err = (0..3).map(|d| (p1[d] - p0[d]).abs()).fold(0.0, f64::max);
    let bound = steps as f64 * bound_per_step;
    assert!(
        err <= bound,
        "momentum {p0:?} -> {p1:?}: change {err:.3e} > {bound:.3e}"
    );
    before
}
