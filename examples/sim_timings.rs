//! Per-step cost of the reduced simulator on the standard beam tests (design.md section 3),
//! printed as the markdown tables of docs/performance.md:
//! strategies x m for the bend and the twist (K = 1000, 5000 cubature points, 200 steps),
//! the distance of each run's final state from a tight-tolerance reference, the growth with m
//! and with the cubature count, and the per-iteration cost split; then the L-BFGS twist repeated
//! (5 runs, each after a one-call gauge of the machine's speed) to show the run-to-run spread,
//! and both initial guesses (`NewtonOptions::initial_guess`).
//!
//!     cargo run --release --example sim_timings [-- quick]
//!
//! `quick` runs 50 steps and skips full Newton at m = 32; the full run skips `fixed` on the
//! twist (it hits the iteration cap on most steps there).

use freeform::benchmark::beam_sim_options;
use freeform::fem::beam::{BeamTest, FemBeamConfig};
use freeform::geometry::ShapeOptions;
use freeform::io::read_shape;
use freeform::precompute::{build_basis, BasisOptions, BasisRun};
use freeform::progress::Silent;
use freeform::report::Stopwatch;
use freeform::sim::elastic::{Precision, Projection};
use freeform::sim::{HessianStrategy, InitialGuess, NewtonOptions, ReducedSim, SimOptions};
use freeform::Point3;

struct Outcome {
    step_ms: f64,
    iterations: f64,
    evaluations: f64,
    nonconverged: usize,
    grad_ms: f64,
    hess_ms: f64,
    solve_ms: f64,
    cutbacks: f64,
    factorizations: f64,
    probe: Vec<Point3>,
}

fn beam(m: usize) -> BasisRun {
    let shape = read_shape("box:5,1,1", &ShapeOptions::default()).expect("box");
    let opts = BasisOptions {
        kernels: 1000,
        modes: m,
        ..BasisOptions::default()
    };
    build_basis(&shape, &opts, &Silent).expect("basis")
}

/// The standard bend or twist (design.md section 3) with strategy `h` at tolerance `tol`.
fn options(twist: bool, h: HessianStrategy, tol: f64, cubature: usize) -> SimOptions {
    let test = if twist {
        BeamTest::Twist
    } else {
        BeamTest::Bend
    };
    let newton = NewtonOptions {
        hessian: h,
        tol,
        ..NewtonOptions::default()
    };
    // The FEM resolution does not enter the reduced model's options.
    beam_sim_options(&FemBeamConfig::standard(test, 1), cubature, newton, None)
}

fn simulate(run: &BasisRun, opts: &SimOptions, steps: usize, probe: &[Point3]) -> Outcome {
    let mut s = ReducedSim::new(&run.basis, &run.points, &run.material, opts).expect("sim");
    let mut o = Outcome {
        step_ms: 0.0,
        iterations: 0.0,
        evaluations: 0.0,
        nonconverged: 0,
        grad_ms: 0.0,
        hess_ms: 0.0,
        solve_ms: 0.0,
        cutbacks: 0.0,
        factorizations: 0.0,
        probe: Vec::new(),
    };
    for _ in 0..steps {
        let r = s.step();
        o.step_ms += r.wall_s * 1e3;
        o.iterations += r.solve.iterations as f64;
        o.evaluations += r.solve.evaluations as f64;
        o.grad_ms += r.solve.gradient_s * 1e3;
        o.hess_ms += r.solve.hessian_s * 1e3;
        o.solve_ms += r.solve.solve_s * 1e3;
        o.cutbacks += r.solve.line_search_cutbacks as f64;
        o.factorizations += r.solve.factorizations as f64;
        o.nonconverged += usize::from(!r.solve.converged);
    }
    let n = steps as f64;
    for v in [
        &mut o.step_ms,
        &mut o.iterations,
        &mut o.evaluations,
        &mut o.grad_ms,
        &mut o.hess_ms,
        &mut o.solve_ms,
        &mut o.cutbacks,
        &mut o.factorizations,
    ] {
        *v /= n;
    }
    let w = run.basis.weights(probe).expect("probe weights");
    o.probe = s.positions(probe, &w);
    o
}

/// Each labelled option set of `list` simulated on the bend or twist, with its largest probe
/// distance from the tol 1e-9 L-BFGS run (the converged trajectory).
fn variants(
    run: &BasisRun,
    twist: bool,
    steps: usize,
    probe: &[Point3],
    list: &[(String, SimOptions)],
) -> Vec<(String, Outcome, f64)> {
    let reference = simulate(
        run,
        &options(twist, HessianStrategy::Lbfgs, 1e-9, 5000),
        steps,
        probe,
    );
    list.iter()
        .map(|(label, opts)| {
            let o = simulate(run, opts, steps, probe);
            let d = max_dist(&o.probe, &reference.probe);
            (label.clone(), o, d)
        })
        .collect()
}

/// Milliseconds per elastic energy + gradient of `run`'s beam (5000 cubature points) at a
/// fixed non-rest state, the mean of 50 calls after 5 warm-up calls.
fn gauge(run: &BasisRun) -> f64 {
    let s = ReducedSim::new(
        &run.basis,
        &run.points,
        &run.material,
        &options(false, HessianStrategy::Lbfgs, 1e-6, 5000),
    )
    .expect("sim");
    let z: Vec<f64> = (0..s.z().len())
        .map(|i| 1e-3 * ((i % 7) as f64 - 3.0))
        .collect();
    let mut g = vec![0.0; z.len()];
    for _ in 0..5 {
        s.elastic().energy_gradient(&z, &mut g);
    }
    let t = Stopwatch::start();
    for _ in 0..50 {
        s.elastic().energy_gradient(&z, &mut g);
    }
    t.elapsed() / 50.0 * 1e3
}

fn max_dist(a: &[Point3], b: &[Point3]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(p, q)| (0..3).map(|d| (p[d] - q[d]).powi(2)).sum::<f64>().sqrt())
        .fold(0.0, f64::max)
}

fn main() {
    let quick = std::env::args().any(|a| a == "quick");
    let steps = if quick { 50 } else { 200 };
    let probe: Vec<Point3> = (0..=10)
        .flat_map(|i| {
            let x = 0.5 * i as f64;
            [[x, 0.0, 0.0], [x, 1.0, 1.0], [x, 0.5, 0.5]]
        })
        .collect();
    let strategies = [
        HessianStrategy::Lbfgs,
        HessianStrategy::Fixed,
        HessianStrategy::Newton,
    ];
    println!("threads: {}", rayon::current_num_threads());
    println!("\n| test | m | strategy | step ms | iterations | evaluations | not converged | gradient ms | Hessian ms | solve ms | max distance to the tol 1e-9 state (m) |");
    println!("|---|---|---|---|---|---|---|---|---|---|---|");
    for m in [16, 32] {
        let run = beam(m);
        for twist in [false, true] {
            let name = if twist { "twist" } else { "bend" };
            let reference = simulate(
                &run,
                &options(twist, HessianStrategy::Lbfgs, 1e-9, 5000),
                steps,
                &probe,
            );
            for h in strategies {
                if quick && m == 32 && h == HessianStrategy::Newton {
                    continue;
                }
                // The rest Hessian alone hardly converges under the twist's large rotations
                // (most steps hit the iteration cap; see the quick run): bend only.
                if !quick && twist && h == HessianStrategy::Fixed {
                    continue;
                }
                let o = simulate(&run, &options(twist, h, 1e-6, 5000), steps, &probe);
                println!(
                    "| {name} | {m} | {} | {:.2} | {:.2} | {:.2} | {} | {:.2} | {:.2} | {:.2} | {:.1e} |",
                    h.name(),
                    o.step_ms,
                    o.iterations,
                    o.evaluations,
                    o.nonconverged,
                    o.grad_ms,
                    o.hess_ms,
                    o.solve_ms,
                    max_dist(&o.probe, &reference.probe)
                );
            }
        }
    }
    // The same run several times, each after a gauge of the machine's speed at that moment
    // (one energy + gradient at m = 32): on a shared machine the spread between runs is larger
    // than most of the differences being measured.
    let runs = if quick { 2 } else { 5 };
    println!("\nRepeatability (twist, lbfgs, tol 1e-6, {runs} runs of {steps} steps):\n");
    println!("| m | step ms per run | median | min | max | gauge ms per run (one m = 32 energy+gradient) |");
    println!("|---|---|---|---|---|---|");
    let gauge_run = beam(32);
    for m in [16, 32] {
        let run = beam(m);
        let opts = options(true, HessianStrategy::Lbfgs, 1e-6, 5000);
        let mut ms = Vec::new();
        let mut gauges = Vec::new();
        for _ in 0..runs {
            gauges.push(gauge(&gauge_run));
            ms.push(simulate(&run, &opts, steps, &probe).step_ms);
        }
        let list = |v: &[f64]| {
            v.iter()
                .map(|x| format!("{x:.2}"))
                .collect::<Vec<_>>()
                .join(", ")
        };
        let mut sorted = ms.clone();
        sorted.sort_by(f64::total_cmp);
        println!(
            "| {m} | {} | {:.2} | {:.2} | {:.2} | {} |",
            list(&ms),
            sorted[sorted.len() / 2],
            sorted[0],
            sorted[sorted.len() - 1],
            list(&gauges)
        );
    }
    println!("\nL-BFGS refresh precision (twist, tol 1e-6):\n");
    println!("| m | refresh precision | step ms | iterations | Hessian ms | max distance to the tol 1e-9 state (m) |");
    println!("|---|---|---|---|---|---|");
    for m in [16, 32] {
        let run = beam(m);
        let list = [Precision::Single, Precision::Double].map(|precision| {
            let mut opts = options(true, HessianStrategy::Lbfgs, 1e-6, 5000);
            opts.newton.refresh_precision = precision;
            (format!("{precision:?}"), opts)
        });
        for (label, o, dist) in variants(&run, true, steps, &probe, &list) {
            println!(
                "| {m} | {label} | {:.2} | {:.2} | {:.2} | {dist:.1e} |",
                o.step_ms, o.iterations, o.hess_ms,
            );
        }
    }
    println!("\nInitial guess (lbfgs, tol 1e-6):\n");
    println!("| test | m | initial guess | step ms | iterations | evaluations | line-search cutbacks | refreshes | max distance to the tol 1e-9 state (m) |");
    println!("|---|---|---|---|---|---|---|---|---|");
    for m in [16, 32] {
        let run = beam(m);
        for twist in [false, true] {
            let name = if twist { "twist" } else { "bend" };
            let list = [InitialGuess::Velocity, InitialGuess::Extrapolate].map(|guess| {
                let mut opts = options(twist, HessianStrategy::Lbfgs, 1e-6, 5000);
                opts.newton.initial_guess = guess;
                (guess.name().to_string(), opts)
            });
            for (label, o, dist) in variants(&run, twist, steps, &probe, &list) {
                println!(
                    "| {name} | {m} | {label} | {:.2} | {:.2} | {:.2} | {:.3} | {:.3} | {dist:.1e} |",
                    o.step_ms, o.iterations, o.evaluations, o.cutbacks, o.factorizations,
                );
            }
        }
    }
    println!("\nGrowth (bend, lbfgs, tol 1e-6):\n");
    println!("| m | cubature | step ms | iterations | energy+gradient ms (one) | full Hessian ms (one) | Cholesky ms (one) |");
    println!("|---|---|---|---|---|---|---|");
    let mut configs: Vec<(usize, usize)> = [6, 9, 16, 32].iter().map(|&m| (m, 5000)).collect();
    configs.extend([1000, 2500, 10000].iter().map(|&c| (16, c)));
    for (m, c) in configs {
        let run = beam(m);
        let o = simulate(
            &run,
            &options(false, HessianStrategy::Lbfgs, 1e-6, c),
            steps,
            &probe,
        );
        let s = ReducedSim::new(
            &run.basis,
            &run.points,
            &run.material,
            &options(false, HessianStrategy::Lbfgs, 1e-6, c),
        )
        .expect("sim");
        let z: Vec<f64> = (0..s.z().len())
            .map(|i| 1e-3 * ((i % 7) as f64 - 3.0))
            .collect();
        let mut g = vec![0.0; z.len()];
        let reps = 20;
        let t = Stopwatch::start();
        for _ in 0..reps {
            s.elastic().energy_gradient(&z, &mut g);
        }
        let eg = t.elapsed() / reps as f64 * 1e3;
        let t = Stopwatch::start();
        let h = s.elastic().hessian(&z, Projection::PerPoint);
        let hs = t.elapsed() * 1e3;
        let t = Stopwatch::start();
        for _ in 0..5 {
            let _ = h.llt(faer::Side::Lower);
        }
        let ch = t.elapsed() / 5.0 * 1e3;
        println!(
            "| {m} | {c} | {:.2} | {:.2} | {eg:.3} | {hs:.1} | {ch:.2} |",
            o.step_ms, o.iterations
        );
    }
}
