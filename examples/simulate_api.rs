//! The simulator from Rust code: build a scene with the builder API (the standard bend of a
//! small beam and a stiff-cored twin), run it, and read the per-step report.
//!
//!     cargo run --release --example simulate_api [-- OUT_DIR]
//!
//! With OUT_DIR, frames are written there (open OUT_DIR/*.pvd in ParaView).

use freeform::material::{Material, Region};
use freeform::progress::Silent;
use freeform::scene::{run, CacheSettings, ObjectSpec, RunSettings, SceneBuilder};
use freeform::sim::HessianStrategy;

fn main() -> Result<(), freeform::Error> {
    let out = std::env::args().nth(1).map(std::path::PathBuf::from);
    let soft = Material {
        youngs: 5e6,
        poisson: 0.45,
        density: 1000.0,
    };
    let root = Region::HalfSpace {
        point: [0.5, 0.0, 0.0],
        normal: [-1.0, 0.0, 0.0],
    };
    let beam = |name: &str| {
        ObjectSpec::new(name, "box:5,1,1")
            .expect("a box")
            .kernels(500)
            .modes(12)
            .material(soft)
            .hold(root)
    };
    let scene = SceneBuilder::new(0.01, 100)
        .gravity([0.0, -9.81, 0.0])
        .hessian(HessianStrategy::Lbfgs)
        .cubature(3000)
        .cache(CacheSettings {
            enabled: false,
            ..CacheSettings::default()
        })
        .object(beam("soft"))
        .object(beam("cored").region_material(
            Region::Box {
                min: [2.0, 0.3, 0.3],
                max: [4.5, 0.7, 0.7],
            },
            Material {
                youngs: 5e9,
                ..soft
            },
        ))
        .build()?;
    let summary = run(
        &scene,
        &RunSettings {
            base_dir: ".".into(),
            out,
            strict: false,
        },
        &Silent,
    )?;
    for o in &summary.objects {
        let last = o.steps.last().map(|r| r.energy).unwrap_or(0.0);
        println!(
            "{:>6}: {} modes, {} cubature points, step {:.2} ms mean ({:.2} iterations), \
             {} not converged, final incremental potential {:.4e} J",
            o.name,
            o.modes,
            o.cubature_points,
            o.step_ms_mean,
            o.iterations_mean,
            o.nonconverged_steps,
            last
        );
    }
    Ok(())
}
