//! Is the real-shape FEM reference converged? (docs/evaluation.md, "FEM reference:
//! convergence"). For one shape and each of the protocol's tests, runs (or loads from the
//! cache) the reference on TetGen meshes at the levels given, as `[FILE@]<max volume>[q]`
//! (q: quadratic elements; FILE: another surface of the same solid for that level, e.g. the
//! shape with every triangle split in four at its edge midpoints, which refines the surface
//! that `-Y` keeps without changing the geometry), and compares each level with the last on
//! the nodes they share (every original surface vertex) with the benchmark's metric. An
//! optional third argument limits the tests (comma-separated names).
//!
//! ```sh
//! cargo run --release --example shape_convergence -- /work/shapes/anchor.off 1e-3,1e-3q,2.5e-4q
//! cargo run --release --example shape_convergence -- rotor.off 1e-3q,rotor4.off@1.25e-4q fix_side
//! ```

use freeform::benchmark::shapes::protocol::{normalize, Protocol, ShapeTest};
use freeform::benchmark::shapes::reference::{run_shape_reference, shared_node_difference};
use freeform::benchmark::shapes::tetgen::{tetrahedralize, TetgenOptions};
use freeform::fem::solver::FemParams;
use freeform::fem::ElementOrder;
use freeform::geometry::{Shape, ShapeOptions};
use std::path::Path;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let (Some(path), Some(levels)) = (args.get(1), args.get(2)) else {
        return Err("usage: shape_convergence SHAPE.off VOLUME[q],VOLUME[q],...".into());
    };
    let cache = Path::new(".freeform-cache/fem");
    let read = |path: &str| -> Result<_, Box<dyn std::error::Error>> {
        let Shape::Mesh(m) = freeform::io::read_shape(path, &ShapeOptions::default())? else {
            return Err("not a triangle mesh".into());
        };
        Ok(normalize(m.vertices(), m.triangles())?)
    };
    let tests: Vec<ShapeTest> = ShapeTest::ALL
        .into_iter()
        .filter(|t| {
            args.get(3)
                .is_none_or(|only| only.split(',').any(|o| o == t.name()))
        })
        .collect();
    let protocol = Protocol::default();
    let work = std::env::temp_dir().join(format!("shape_convergence_{}", std::process::id()));
    let mut meshes = Vec::new();
    for level in levels.split(',') {
        let (file, spec) = level.split_once('@').unwrap_or((path.as_str(), level));
        let shape = read(file)?;
        let (vol, order) = match spec.strip_suffix('q') {
            Some(v) => (v.parse::<f64>()?, ElementOrder::Quadratic),
            None => (spec.parse::<f64>()?, ElementOrder::Linear),
        };
        let tg = TetgenOptions {
            max_volume: vol,
            ..TetgenOptions::default()
        };
        let mesh = tetrahedralize(&shape.vertices, &shape.triangles, &tg, &work, "shape")?;
        let fem = FemParams {
            order,
            ..FemParams::default()
        };
        meshes.push((level.to_string(), mesh, fem, shape));
    }
    for test in tests {
        let mut refs = Vec::new();
        for (label, mesh, fem, shape) in &meshes {
            let t0 = std::time::Instant::now();
            let r = run_shape_reference(
                mesh,
                &protocol,
                shape,
                test,
                &[],
                fem,
                Some(cache),
                &freeform::progress::Silent,
            )?;
            println!(
                "{} {label}: {} tets, {} FE nodes, {:.1} s ({:?})",
                test.name(),
                mesh.num_tets(),
                r.rest.len(),
                t0.elapsed().as_secs_f64(),
                r.cache
            );
            refs.push((label.clone(), r));
        }
        let (last_label, last) = refs.last().ok_or("no levels")?;
        for (label, r) in &refs[..refs.len() - 1] {
            let (e, shared) = shared_node_difference(r, last)?;
            println!(
                "{} {label} vs {last_label}: normalized MSE {:.3e}, max {:.3e} over {shared} shared nodes",
                test.name(),
                e.normalized_mse,
                e.max_error
            );
        }
    }
    Ok(())
}
