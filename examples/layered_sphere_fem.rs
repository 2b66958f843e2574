//! The layered sphere (paper supplementary Fig. 7) against a FEM reference of it
//! (docs/evaluation.md, "The layered sphere", "Against a FEM reference"): an icosphere of four
//! concentric shells, stiff-soft-stiff-soft from the centre out (E = 1e7 / 1e5 Pa, the paper's
//! values and the protocol's soft material; nu = 0.4, rho = 1000 kg/m^3), through the
//! real-shape protocol's three tests (TetGen, quadratic FEM with the same shells, the aware
//! basis). Each kernel density factor around the material interfaces
//! (`EvalOptions::density_interfaces`) is one basis per test against the same cached
//! references.
//!
//! ```sh
//! cargo run --release --example layered_sphere_fem -- [K] [M] [DENSITIES] [MAX_VOLUME] \
//!     [CUBATURE] [check-fem|no-check] [centroids|conforming] [TESTS]
//! cargo run --release --example layered_sphere_fem -- 600 16 1,3 1e-4 5000 check-fem centroids
//! ```
//!
//! Defaults: 600 16 1,2,3 1e-4 5000 check-fem centroids, all tests. `centroids` gives each
//! tet the material at its centroid; `conforming` meshes the FEM with the shells' surfaces as
//! facets (no tet straddles one; a much larger mesh). TESTS: comma-separated names
//! (fix_side, pull_farthest, pull_ends).
//!
//! Prints one row per (test, density): the benchmark's normalized MSE and max error, the
//! basis fitting residual, the precompute time; then, with `check-fem`, the FEM reference's
//! own discretization error, as the difference from a reference on a mesh 8x coarser in
//! volume (the nodes they share), so the reduced errors can be read against it.

use freeform::benchmark::shapes::eval::fem_surface;
use freeform::benchmark::shapes::protocol::{normalize, Protocol, ShapeTest};
use freeform::benchmark::shapes::reference::{run_shape_reference, shared_node_difference};
use freeform::benchmark::shapes::tetgen::{tetrahedralize, TetgenOptions};
use freeform::benchmark::shapes::{evaluate_shape, EvalOptions};
use freeform::fem::ElementOrder;
use freeform::geometry::generate::icosphere;
use freeform::material::{Material, MaterialOverride, Region};
use freeform::precompute::BoundaryModes;
use std::path::Path;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let arg = |i: usize, default: &str| args.get(i).cloned().unwrap_or(default.into());
    let kernels: usize = arg(1, "600").parse()?;
    let modes: usize = arg(2, "16").parse()?;
    let densities: Vec<f64> = arg(3, "1,2,3")
        .split(',')
        .map(str::parse)
        .collect::<Result<_, _>>()?;
    let max_volume: f64 = arg(4, "1e-4").parse()?;
    let cubature: usize = arg(5, &EvalOptions::default().cubature.to_string()).parse()?;
    let choice = |i: usize, yes: &str, no: &str| -> Result<bool, Box<dyn std::error::Error>> {
        match arg(i, yes) {
            w if w == yes => Ok(true),
            w if w == no => Ok(false),
            w => Err(format!("argument {i}: `{w}`, expected `{yes}` or `{no}`").into()),
        }
    };
    let check_fem = choice(6, "check-fem", "no-check")?;
    let conforming = !choice(7, "centroids", "conforming")?;
    let tests: Vec<ShapeTest> = match args.get(8) {
        Some(only) => only
            .split(',')
            .map(|o| {
                ShapeTest::ALL
                    .into_iter()
                    .find(|t| t.name() == o)
                    .ok_or_else(|| format!("unknown test `{o}`"))
            })
            .collect::<Result<_, _>>()?,
        None => ShapeTest::ALL.to_vec(),
    };

    let work = std::env::temp_dir().join(format!("layered_sphere_{}", std::process::id()));
    std::fs::create_dir_all(&work)?;
    // 5,120 faces: edges of ~0.03 m on the unit-box sphere, finer than the shells (0.125 m).
    let (v, t) = icosphere(0.5, 4);
    let file = work.join("layered_sphere.off");
    freeform::io::off::write_off(&file, &v, &t)?;
    let shape = normalize(&v, &t)?;
    let centre = shape.extent.map(|e| 0.5 * e);
    let radius = shape
        .vertices
        .iter()
        .map(|p| {
            (0..3)
                .map(|k| (p[k] - centre[k]).powi(2))
                .sum::<f64>()
                .sqrt()
        })
        .fold(0.0, f64::max);
    let soft = Protocol::default().material;
    let stiff = Material {
        youngs: 100.0 * soft.youngs,
        ..soft
    };
    // Applied in order over the soft outer shell: each smaller ball overrides the one before.
    let overrides: Vec<MaterialOverride> = [(0.75, stiff), (0.5, soft), (0.25, stiff)]
        .into_iter()
        .map(|(f, material)| MaterialOverride {
            region: Region::Sphere {
                center: centre,
                radius: f * radius,
            },
            material,
        })
        .collect();

    let cache = Path::new(".freeform-cache/fem");
    let mut opts = EvalOptions {
        modes,
        kernels,
        boundaries: vec![BoundaryModes::Aware],
        material_overrides: overrides.clone(),
        cubature,
        tests: tests.clone(),
        ..EvalOptions::default()
    };
    if conforming {
        // The shells' surfaces as facets of the FEM mesh, about as fine as the outer one's
        // (edges ~0.03 m), so that no tet straddles an interface.
        opts.fem_interfaces = [(0.75, 4), (0.5, 3), (0.25, 2)]
            .into_iter()
            .map(|(f, level)| {
                let (v, t) = icosphere(f * radius, level);
                let v = v
                    .into_iter()
                    .map(|p| [p[0] + centre[0], p[1] + centre[1], p[2] + centre[2]])
                    .collect();
                (v, t)
            })
            .collect();
    }
    opts.tetgen.max_volume = max_volume;
    println!(
        "layered sphere: radius {radius:.4} m (unit box), shells at 1/4, 1/2, 3/4 of it, \
         E = {:.0e} / {:.0e} Pa; K = {kernels}, m = {modes}, {cubature} cubature points, \
         TetGen {}",
        stiff.youngs,
        soft.youngs,
        opts.tetgen.switches()
    );
    println!(
        "{:<14} {:>7} {:>11} {:>10} {:>11} {:>10} {:>8} {:>8}",
        "test", "density", "norm. MSE", "max err", "fit MSE", "fit max", "basis s", "unconv."
    );
    for &d in &densities {
        opts.density_interfaces = d;
        let eval = evaluate_shape(
            &file,
            &opts,
            Some(cache),
            &work,
            &freeform::progress::Silent,
        )?;
        if d == densities[0] {
            println!("FEM: {} tets, {} nodes", eval.fem_tets, eval.fem_nodes);
        }
        for f in &eval.failures {
            println!("failed: {f}");
        }
        for r in &eval.runs {
            println!(
                "{:<14} {:>7} {:>11.3e} {:>10.3e} {:>11.3e} {:>10.3e} {:>8.2} {:>8}",
                r.test.name(),
                d,
                r.normalized_mse,
                r.max_error,
                r.fit_mse,
                r.fit_max,
                r.basis_s,
                r.reduced_nonconverged_steps
            );
        }
    }

    if !check_fem {
        std::fs::remove_dir_all(&work)?;
        return Ok(());
    }
    println!("FEM reference against one on a mesh 8x coarser in volume (shared nodes):");
    let mesh_at = |vol: f64| {
        let tg = TetgenOptions {
            max_volume: vol,
            ..TetgenOptions::default()
        };
        let (v, t) = fem_surface(&shape, &opts.fem_interfaces)?;
        Ok::<_, Box<dyn std::error::Error>>(tetrahedralize(&v, &t, &tg, &work, "layered_sphere")?)
    };
    let (fine, coarse) = (mesh_at(max_volume)?, mesh_at(8.0 * max_volume)?);
    println!(
        "  tets: {} (this run), {} (coarse)",
        fine.num_tets(),
        coarse.num_tets()
    );
    let fem = freeform::fem::solver::FemParams {
        order: ElementOrder::Quadratic,
        ..opts.fem.clone()
    };
    for &test in &tests {
        let reference = |mesh| {
            run_shape_reference(
                mesh,
                &opts.protocol,
                &shape,
                test,
                &overrides,
                &fem,
                Some(cache),
                &freeform::progress::Silent,
            )
        };
        let (f, c) = (reference(&fine)?, reference(&coarse)?);
        let (e, shared) = shared_node_difference(&c, &f)?;
        println!(
            "  {:<14} normalized MSE {:.3e}, max {:.3e} over {shared} nodes",
            test.name(),
            e.normalized_mse,
            e.max_error
        );
    }
    std::fs::remove_dir_all(&work)?;
    Ok(())
}
