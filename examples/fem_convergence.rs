//! FEM reference studies on the standard beam (design.md section 3); the numbers in
//! docs/accuracy.md ("FEM reference: convergence") and docs/performance.md ("FEM reference")
//! come from here.
//!
//! ```sh
//! # refinement study: runs (or loads from the cache) every level, then compares successive
//! # levels on the coarse nodes with the benchmark's error metric
//! cargo run --release --example fem_convergence -- convergence bend 2,4,8,16 /tmp/ffcache
//! # fill-reducing orderings: fill and factorization time, AMD vs nested dissection
//! cargo run --release --example fem_convergence -- ordering bend 4,8,16
//! ```

use freeform::fem::{
    nested_difference, run_beam_reference, BeamTest, FemBeamConfig, FemSolver, OrderingKind,
    TetMaterials,
};
use freeform::progress::TerminalProgress;
use std::path::PathBuf;
use std::time::Instant;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let usage = "usage: fem_convergence (convergence|ordering) (bend|twist) r1,r2,... [cache-dir]";
    if args.len() < 3 {
        return Err(usage.into());
    }
    let test = match args[1].as_str() {
        "bend" => BeamTest::Bend,
        "twist" => BeamTest::Twist,
        _ => return Err(usage.into()),
    };
    let levels: Vec<usize> = args[2]
        .split(',')
        .map(|s| s.parse())
        .collect::<Result<_, _>>()?;
    match args[0].as_str() {
        "convergence" => convergence(test, &levels, args.get(3).map(PathBuf::from)),
        "ordering" => ordering(test, &levels),
        _ => Err(usage.into()),
    }
}

fn convergence(
    test: BeamTest,
    levels: &[usize],
    cache: Option<PathBuf>,
) -> Result<(), Box<dyn std::error::Error>> {
    let progress = TerminalProgress::new();
    let mut refs = Vec::new();
    println!(
        "| r | nodes | tets | DoFs | mean step ms | Newton its/step (mean, max) | cache |"
    );
    println!("|---|---|---|---|---|---|---|");
    for &r in levels {
        let cfg = FemBeamConfig::standard(test, r);
        let t0 = Instant::now();
        let reference = run_beam_reference(&cfg, cache.as_deref(), &progress)?;
        let its = &reference.newton_iterations;
        println!(
            "| {r} | {} | {} | {} | {:.1} | {:.2}, {} | {} ({:.1} s) |",
            reference.rest.len(),
            reference.tets.len(),
            3 * reference.rest.len(),
            reference.step_ms_mean(),
            its.iter().map(|&i| i as f64).sum::<f64>() / its.len() as f64,
            its.iter().max().copied().unwrap_or(0),
            match &reference.cache {
                freeform::fem::CacheStatus::Hit(_) => "hit",
                _ => "computed",
            },
            t0.elapsed().as_secs_f64()
        );
        refs.push(reference);
    }
    println!();
    println!("| r vs 2r | normalized MSE | RMS / D | max error | observed order (RMS) |");
    println!("|---|---|---|---|---|");
    let mut prev: Option<f64> = None;
    for w in refs.windows(2) {
        let e = nested_difference(&w[0], &w[1])?;
        let rms = e.normalized_mse.sqrt();
        let order = prev.map_or("-".to_string(), |p| format!("{:.2}", (p / rms).log2()));
        println!(
            "| {} vs {} | {:.3e} | {:.3e} | {:.3e} | {order} |",
            w[0].config.resolution, w[1].config.resolution, e.normalized_mse, rms, e.max_error
        );
        prev = Some(rms);
    }
    Ok(())
}

fn ordering(test: BeamTest, levels: &[usize]) -> Result<(), Box<dyn std::error::Error>> {
    println!("| r | free DoFs | ordering | factor entries | symbolic s | first step s | of which numeric factorizations s | Newton its |");
    println!("|---|---|---|---|---|---|---|---|");
    for &r in levels {
        for kind in [OrderingKind::Amd, OrderingKind::NestedDissection] {
            let mut cfg = FemBeamConfig::standard(test, r);
            cfg.solver.ordering = kind;
            let mesh = cfg.mesh()?;
            let mats = TetMaterials::homogeneous(&mesh, &cfg.material)?;
            let fixed = mesh.select_nodes(|p| p[0] <= cfg.held_length + 1e-9);
            let mut solver = FemSolver::new(&mesh, &mats, &fixed, cfg.solver.clone())?;
            let (entries, sym_s) = solver.factor_stats();
            let info = solver.step()?;
            println!(
                "| {r} | {} | {kind:?} | {entries} | {sym_s:.3} | {:.3} | {:.3} | {} |",
                solver.free_dofs(),
                info.seconds,
                info.factor_seconds,
                info.newton_iterations
            );
        }
    }
    Ok(())
}
