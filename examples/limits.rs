//! The measured envelope of docs/limits.md: how the pipeline and the simulator behave at the
//! extremes of issue #6, on the standard beam (5 x 1 x 1 m, K = 1000, m = 16, 5000 cubature
//! points, 50 steps of the bend unless stated). Prints markdown tables.
//!
//!     cargo run --release --example limits

use freeform::geometry::ShapeOptions;
use freeform::io::read_shape;
use freeform::material::{Material, MaterialOverride, Region};
use freeform::precompute::{build_basis, BasisOptions, BasisRun};
use freeform::progress::Silent;
use freeform::report::Stopwatch;
use freeform::sim::motion::Motion;
use freeform::sim::{Boundary, HessianStrategy, NewtonOptions, ReducedSim, SimOptions};
use std::f64::consts::PI;

const BEAM: Material = Material {
    youngs: 5e6,
    poisson: 0.45,
    density: 1000.0,
};

fn basis(spec: &str, o: &BasisOptions) -> Result<(BasisRun, f64), freeform::Error> {
    let shape = read_shape(spec, &ShapeOptions::default())?;
    let sw = Stopwatch::start();
    let run = build_basis(&shape, o, &Silent)?;
    Ok((run, sw.elapsed()))
}

fn beam_opts(material: Material, overrides: Vec<MaterialOverride>) -> BasisOptions {
    BasisOptions {
        kernels: 1000,
        modes: 16,
        material,
        overrides,
        ..BasisOptions::default()
    }
}

struct SimOutcome {
    step_ms: f64,
    iterations: f64,
    max_iterations: usize,
    nonconverged: usize,
    line_search_failures: usize,
    min_det: f64,
    tip: f64,
}

/// The bend: held at x <= 0.5, gravity, `steps` steps of `dt`.
fn bend(run: &BasisRun, dt: f64, steps: usize, hessian: HessianStrategy) -> SimOutcome {
    let o = SimOptions {
        dt,
        gravity: Some([0.0, -9.81, 0.0]),
        cubature: 5000,
        boundaries: vec![Boundary {
            region: Region::HalfSpace {
                point: [0.5, 0.0, 0.0],
                normal: [-1.0, 0.0, 0.0],
            },
            motion: Motion::Fixed,
            stiffness: None,
        }],
        newton: NewtonOptions {
            hessian,
            ..NewtonOptions::default()
        },
        ..SimOptions::default()
    };
    let mut s = ReducedSim::new(&run.basis, &run.points, &run.material, &o).expect("sim");
    let mut out = SimOutcome {
        step_ms: 0.0,
        iterations: 0.0,
        max_iterations: 0,
        nonconverged: 0,
        line_search_failures: 0,
        min_det: f64::INFINITY,
        tip: 0.0,
    };
    for _ in 0..steps {
        let r = s.step();
        out.step_ms += 1e3 * r.wall_s / steps as f64;
        out.iterations += r.solve.iterations as f64 / steps as f64;
        out.max_iterations = out.max_iterations.max(r.solve.iterations);
        out.nonconverged += usize::from(!r.solve.converged);
        out.line_search_failures += usize::from(r.solve.line_search_failed);
        out.min_det = out.min_det.min(r.solve.info.min_det);
    }
    let tip = [[5.0, 0.5, 0.5]];
    let w = run.basis.weights(&tip).expect("tip weights");
    out.tip = s.positions(&tip, &w)[0][1] - 0.5;
    out
}

fn sim_header() {
    println!("| strategy | step ms | iterations mean / max | not converged | line-search failures | min det F | tip y displacement, m |");
}

fn sim_row(label: &str, h: HessianStrategy, o: &SimOutcome) {
    println!(
        "| {label} | {h:?} | {:.2} | {:.1} / {} | {} | {} | {:.3} | {:.4} |",
        o.step_ms,
        o.iterations,
        o.max_iterations,
        o.nonconverged,
        o.line_search_failures,
        o.min_det,
        o.tip
    );
}

fn main() {
    let strategies = [HessianStrategy::Lbfgs, HessianStrategy::Newton];

    println!("### Poisson ratio (bend, 50 steps of 10 ms)\n");
    print!("| nu ");
    sim_header();
    println!("|---|---|---|---|---|---|---|---|");
    for nu in [0.0, 0.3, 0.45, 0.49, 0.499, 0.4999] {
        let (run, _) = basis(
            "box:5,1,1",
            &beam_opts(
                Material {
                    poisson: nu,
                    ..BEAM
                },
                vec![],
            ),
        )
        .expect("basis");
        for h in strategies {
            sim_row(&format!("{nu}"), h, &bend(&run, 0.01, 50, h));
        }
    }

    println!("\n### Young's modulus (bend, 50 steps of 10 ms)\n");
    print!("| E, Pa ");
    sim_header();
    println!("|---|---|---|---|---|---|---|---|");
    for e in [1e3, 1e5, 1e7, 1e9, 1e11] {
        let (run, _) = basis(
            "box:5,1,1",
            &beam_opts(Material { youngs: e, ..BEAM }, vec![]),
        )
        .expect("basis");
        for h in strategies {
            sim_row(&format!("{e:.0e}"), h, &bend(&run, 0.01, 50, h));
        }
    }

    println!("\n### Time step (bend, 0.1 s of simulated time; one step at dt = 0.1)\n");
    print!("| dt, s ");
    sim_header();
    println!("|---|---|---|---|---|---|---|---|");
    let (beam, _) = basis("box:5,1,1", &beam_opts(BEAM, vec![])).expect("basis");
    for dt in [1e-4f64, 1e-3, 1e-2, 1e-1] {
        let steps = ((0.1 / dt).round() as usize).max(1);
        for h in strategies {
            sim_row(&format!("{dt:.0e}"), h, &bend(&beam, dt, steps, h));
        }
    }

    println!("\n### Stiff core (E x c in the ball of radius 0.4 m at the beam's middle)\n");
    println!("| c | precompute s | LOBPCG iterations | restarts | max rel. residual | lambda_1 / homogeneous | bend: strategy | step ms | iterations mean / max | not converged |");
    println!("|---|---|---|---|---|---|---|---|---|---|");
    let lambda_1 = beam.report.eigenvalues[1];
    for c in [1.0, 1e2, 1e4, 1e6] {
        let core = vec![MaterialOverride {
            region: Region::Sphere {
                center: [2.5, 0.5, 0.5],
                radius: 0.4,
            },
            material: Material {
                youngs: BEAM.youngs * c,
                ..BEAM
            },
        }];
        let (run, secs) = basis("box:5,1,1", &beam_opts(BEAM, core)).expect("basis");
        let r = &run.report;
        for h in strategies {
            let o = bend(&run, 0.01, 50, h);
            println!(
                "| {c:.0e} | {secs:.2} | {} | {} | {:.1e} | {:.3} | {h:?} | {:.2} | {:.1} / {} | {} |",
                r.eigen.iterations, r.eigen.restarts, r.max_relative_residual, r.eigenvalues[1] / lambda_1,
                o.step_ms, o.iterations, o.max_iterations, o.nonconverged
            );
        }
    }

    println!("\n### Thin plates and rods (K = 1000, 50,000 points, m = 4)\n");
    println!("| shape | min moment rcond | lambda_1 / (pi^2 (lambda + 4 mu)) | outcome |");
    println!("|---|---|---|---|");
    let (l, mu) = BEAM.lame();
    for spec in [
        "box:1,1,0.1",
        "box:1,1,0.03",
        "box:1,1,0.01",
        "box:1,1,0.003",
        "box:1,0.03,0.03",
        "box:1,0.01,0.01",
    ] {
        let o = BasisOptions {
            modes: 4,
            resolution: Some(freeform::precompute::sampling::Resolution::Count(50_000)),
            ..beam_opts(BEAM, vec![])
        };
        match basis(spec, &o) {
            Ok((run, _)) => println!(
                "| {spec} | {:.1e} | {:.4} | {} |",
                run.report.coverage.min_moment_rcond,
                run.report.eigenvalues[1] / (PI * PI * (l + 4.0 * mu)),
                if run.report.warnings.is_empty() {
                    "ok".to_string()
                } else {
                    format!("{} warning(s)", run.report.warnings.len())
                }
            ),
            Err(e) => println!(
                "| {spec} | - | - | error: {} |",
                e.to_string().chars().take(90).collect::<String>()
            ),
        }
    }
}
