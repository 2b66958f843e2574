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
//! # the same on the first 100 frames only
//! FEM_FRAMES=100 cargo run --release --example fem_convergence -- convergence twist 1q,2q,4q /tmp/ffcache
//! # per-frame difference between two cached levels (every 10th frame)
//! cargo run --release --example fem_convergence -- frames twist 4,8 /tmp/ffcache
//! # displacement of the free-end corner (5, 0, 0) per level: extreme and at frames 100, 200
//! cargo run --release --example fem_convergence -- tip bend 1,2,4,8 /tmp/ffcache
//! ```

use freeform::fem::{
    fe_nodes, nested_difference, run_beam_reference, BeamTest, ElementOrder, FemBeamConfig,
    FemSolver, OrderingKind, TetMaterials,
};
use freeform::progress::Progress;
use std::path::PathBuf;
use std::time::Instant;

/// A refinement level: cubes per metre and element order ("8" linear, "4q" quadratic).
#[derive(Clone, Copy)]
struct Level {
    r: usize,
    order: ElementOrder,
}

impl std::fmt::Display for Level {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self.order {
            ElementOrder::Linear => write!(f, "{} (P1)", self.r),
            ElementOrder::Quadratic => write!(f, "{} (P2)", self.r),
        }
    }
}

fn parse_level(s: &str) -> Result<Level, std::num::ParseIntError> {
    Ok(match s.strip_suffix('q') {
        Some(r) => Level {
            r: r.parse()?,
            order: ElementOrder::Quadratic,
        },
        None => Level {
            r: s.parse()?,
            order: ElementOrder::Linear,
        },
    })
}

fn config(test: BeamTest, level: Level) -> FemBeamConfig {
    let mut c = FemBeamConfig::standard(test, level.r);
    c.solver.order = level.order;
    // FEM_MAXIT=n: Newton iteration cap (part of the cache key; the study's first runs used
    // 100, which no step reached).
    if let Some(n) = std::env::var("FEM_MAXIT").ok().and_then(|v| v.parse().ok()) {
        c.solver.max_newton_iterations = n;
    }
    c
}

/// Prints every 20th step to standard error (works when redirected to a file).
struct Log;
impl Progress for Log {
    fn begin(&self, stage: &str, total: Option<u64>) {
        eprintln!("{stage}: {total:?} steps");
    }
    fn set_position(&self, done: u64) {
        if done.is_multiple_of(20) {
            eprintln!("  step {done}");
        }
    }
    fn message(&self, msg: &str) {
        if msg.starts_with("warning") {
            eprintln!("{msg}");
        }
    }
}

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
    let levels: Vec<Level> = args[2]
        .split(',')
        .map(parse_level)
        .collect::<Result<_, _>>()?;
    match args[0].as_str() {
        "convergence" => convergence(test, &levels, args.get(3).map(PathBuf::from)),
        "ordering" => ordering(test, &levels),
        "frames" => frames(test, &levels, args.get(3).map(PathBuf::from)),
        "tip" => tip(test, &levels, args.get(3).map(PathBuf::from)),
        _ => Err(usage.into()),
    }
}

fn convergence(
    test: BeamTest,
    levels: &[Level],
    cache: Option<PathBuf>,
) -> Result<(), Box<dyn std::error::Error>> {
    let progress = Log;
    let mut refs = Vec::new();
    println!("| r | nodes | tets | DoFs | mean step ms | Newton its/step (mean, max) | cache |");
    println!("|---|---|---|---|---|---|---|");
    for &r in levels {
        let cfg = config(test, r);
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
    // FEM_FRAMES=n: compare only the first n frames (e.g. the twist before it buckles).
    if let Some(n) = std::env::var("FEM_FRAMES")
        .ok()
        .and_then(|v| v.parse::<usize>().ok())
    {
        println!();
        println!("(differences over frames 1-{n} only)");
        for r in &mut refs {
            r.frames.truncate(n);
        }
    }
    println!();
    println!("| r vs 2r | normalized MSE | RMS / D | max error | observed order (RMS) |");
    println!("|---|---|---|---|---|");
    let mut prev: Option<f64> = None;
    for (k, w) in refs.windows(2).enumerate() {
        let (c, f) = if w[0].rest.len() <= w[1].rest.len() {
            (&w[0], &w[1])
        } else {
            (&w[1], &w[0])
        };
        let e = nested_difference(c, f)?;
        let rms = e.normalized_mse.sqrt();
        let order = prev.map_or("-".to_string(), |p| format!("{:.2}", (p / rms).log2()));
        println!(
            "| {} vs {} | {:.3e} | {:.3e} | {:.3e} | {order} |",
            levels[k],
            levels[k + 1],
            e.normalized_mse,
            rms,
            e.max_error
        );
        prev = Some(rms);
    }
    Ok(())
}

fn frames(
    test: BeamTest,
    levels: &[Level],
    cache: Option<PathBuf>,
) -> Result<(), Box<dyn std::error::Error>> {
    let progress = Log;
    let [a, b] = levels else {
        return Err("frames needs two levels".into());
    };
    let ra = run_beam_reference(&config(test, *a), cache.as_deref(), &progress)?;
    let rb = run_beam_reference(&config(test, *b), cache.as_deref(), &progress)?;
    println!("| frame | RMS / D (r={a} vs r={b}) | max / D | Newton its r={b} |");
    println!("|---|---|---|---|");
    for f in (9..ra.frames.len()).step_by(10) {
        let mut one_a = ra.clone();
        one_a.frames = vec![ra.frames[f].clone()];
        let mut one_b = rb.clone();
        one_b.frames = vec![rb.frames[f].clone()];
        let e = nested_difference(&one_a, &one_b)?;
        println!(
            "| {} | {:.3e} | {:.3e} | {} |",
            f + 1,
            e.normalized_mse.sqrt(),
            e.max_error,
            rb.newton_iterations[f]
        );
    }
    Ok(())
}

fn tip(
    test: BeamTest,
    levels: &[Level],
    cache: Option<PathBuf>,
) -> Result<(), Box<dyn std::error::Error>> {
    println!(
        "| r | min y-displacement of (5,0,0), m (frame) | at frame 100, m | at frame 200, m |"
    );
    println!("|---|---|---|---|");
    for &r in levels {
        let reference = run_beam_reference(&config(test, r), cache.as_deref(), &Log)?;
        let a = reference
            .rest
            .iter()
            .position(|p| p[0] == 5.0 && p[1] == 0.0 && p[2] == 0.0)
            .ok_or("no corner node")?;
        let dy: Vec<f64> = reference.frames.iter().map(|f| f[a][1]).collect();
        let (fmin, min) =
            dy.iter().enumerate().fold(
                (0, f64::INFINITY),
                |m, (i, &v)| if v < m.1 { (i, v) } else { m },
            );
        println!(
            "| {r} | {min:.4} ({}) | {:.4} | {:.4} |",
            fmin + 1,
            dy[99],
            dy[dy.len() - 1]
        );
    }
    Ok(())
}

fn ordering(test: BeamTest, levels: &[Level]) -> Result<(), Box<dyn std::error::Error>> {
    println!("| r | free DoFs | ordering | factor entries | symbolic s | first step s | of which numeric factorizations s | Newton its |");
    println!("|---|---|---|---|---|---|---|---|");
    for &r in levels {
        for kind in [OrderingKind::Amd, OrderingKind::NestedDissection] {
            let mut cfg = config(test, r);
            cfg.solver.ordering = kind;
            let mesh = cfg.mesh()?;
            let mats = TetMaterials::homogeneous(&mesh, &cfg.material)?;
            let (fe, _) = fe_nodes(&mesh, cfg.solver.order);
            let fixed: Vec<usize> = (0..fe.len())
                .filter(|&i| fe[i][0] <= cfg.held_length + 1e-9)
                .collect();
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
