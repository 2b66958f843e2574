//! Reduced simulation speed: one backward-Euler step of the standard bend (beam 5 x 1 x 1 m,
//! K = 1000, 5000 cubature points) for m = 16 and 32 and each Hessian strategy, one step of
//! the twist with L-BFGS, plus the per-iteration pieces (energy + gradient, full Hessian
//! assembly, dense factorization). Steps are measured on a running simulation (the state keeps
//! evolving between samples; the twist keeps turning past the 200 steps of sim_timings, so its
//! mean can differ from that example's).
//!
//!     cargo bench --bench sim

use criterion::{criterion_group, criterion_main, Criterion};
use freeform::benchmark::beam_sim_options;
use freeform::fem::beam::{BeamTest, FemBeamConfig};
use freeform::geometry::ShapeOptions;
use freeform::io::read_shape;
use freeform::precompute::{build_basis, BasisOptions, BasisRun};
use freeform::progress::Silent;
use freeform::sim::elastic::Projection;
use freeform::sim::{HessianStrategy, NewtonOptions, ReducedSim};
use std::hint::black_box;

fn beam(modes: usize) -> BasisRun {
    let shape = read_shape("box:5,1,1", &ShapeOptions::default()).expect("box");
    let opts = BasisOptions {
        kernels: 1000,
        modes,
        ..BasisOptions::default()
    };
    build_basis(&shape, &opts, &Silent).expect("basis")
}

fn bend(run: &BasisRun, hessian: HessianStrategy) -> ReducedSim {
    beam_sim(run, hessian, false)
}

/// The standard bend or twist of design.md section 3 after 20 steps.
fn beam_sim(run: &BasisRun, hessian: HessianStrategy, twist: bool) -> ReducedSim {
    let test = if twist {
        BeamTest::Twist
    } else {
        BeamTest::Bend
    };
    let newton = NewtonOptions {
        hessian,
        ..NewtonOptions::default()
    };
    // The FEM resolution does not enter the reduced model's options.
    let opts = beam_sim_options(&FemBeamConfig::standard(test, 1), 5000, newton, None);
    let mut s = ReducedSim::new(&run.basis, &run.points, &run.material, &opts).expect("sim");
    // Start from a bent, moving state, not the rest state.
    for _ in 0..20 {
        s.step();
    }
    s
}

fn steps(c: &mut Criterion) {
    let mut g = c.benchmark_group("sim_step");
    g.sample_size(20);
    for m in [16, 32] {
        let run = beam(m);
        for h in [
            HessianStrategy::Lbfgs,
            HessianStrategy::Fixed,
            HessianStrategy::Newton,
        ] {
            let mut s = bend(&run, h);
            g.bench_function(format!("bend_m{m}_{}", h.name()), |b| {
                b.iter(|| black_box(s.step()))
            });
        }
        // The twist keeps turning, so the sampled steps include L-BFGS base refreshes in
        // their natural proportion (about one step in six at m = 32).
        let mut s = beam_sim(&run, HessianStrategy::Lbfgs, true);
        g.bench_function(format!("twist_m{m}_lbfgs"), |b| {
            b.iter(|| black_box(s.step()))
        });
        let s = bend(&run, HessianStrategy::Lbfgs);
        let z = s.z().to_vec();
        let mut grad = vec![0.0; z.len()];
        g.bench_function(format!("energy_gradient_m{m}"), |b| {
            b.iter(|| black_box(s.elastic().energy_gradient(&z, &mut grad)))
        });
        g.bench_function(format!("hessian_m{m}"), |b| {
            b.iter(|| black_box(s.elastic().hessian(&z, Projection::PerPoint)))
        });
        let h = s.elastic().hessian(&z, Projection::PerPoint);
        g.bench_function(format!("cholesky_m{m}"), |b| {
            b.iter(|| black_box(h.llt(faer::Side::Lower).is_ok()))
        });
    }
    g.finish();
}

criterion_group!(benches, steps);
criterion_main!(benches);
