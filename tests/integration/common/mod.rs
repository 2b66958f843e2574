//! Small fixtures shared by the integration tests.
#![allow(dead_code)]

use freeform::geometry::Aabb;
use freeform::material::Material;
use freeform::precompute::centers::farthest_point_sampling;
use freeform::precompute::rkpm::{support_radii, KernelType, Kernels, SupportOptions};
use freeform::precompute::sampling::Resolution;
use freeform::precompute::sampling::{grid_points, IntegrationPoints};
use freeform::precompute::{build_basis, BasisOptions, BasisRun, SolverConfig};
use freeform::scene::{CacheSettings, ObjectSpec};
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
