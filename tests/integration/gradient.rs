//! Gradients through a recorded run (sim::gradient) against central finite differences of
//! the same discrete model, re-simulated with each parameter moved; the refusals of
//! recordings that cannot give a gradient.

use crate::common::{bar_basis, held_left, rubber};
use freeform::material::{Material, MaterialField};
use freeform::precompute::BasisRun;
use freeform::random::SplitMix64;
use freeform::sim::gradient::{positions_adjoint, Gradients, Recording};
use freeform::sim::{Boundary, Collider, HessianStrategy, NewtonOptions, ReducedSim, SimOptions};
use freeform::{Error, Point3};

pub(super) const STEPS: usize = 6;

/// A 1 x 0.2 x 0.2 m bar, E = 1e5 Pa, nu = 0.4, rho = 1000 kg/m^3.
pub(super) fn bar() -> BasisRun {
    bar_basis(40, 5, 1500, rubber())
}

/// Held at its left end with a fixed penalty stiffness (the default one scales with E and
/// rho, which would make it a parameter too), under gravity, each step solved by Newton far
/// below the default tolerance so that the finite differences see the minimiser.
pub(super) fn options(gravity: [f64; 3]) -> SimOptions {
    SimOptions {
        dt: 0.02,
        gravity: Some(gravity),
        cubature: 200,
        boundaries: vec![Boundary {
            stiffness: Some(1e8),
            ..held_left()
        }],
        newton: NewtonOptions {
            hessian: HessianStrategy::Newton,
            tol: 1e-12,
            max_iter: 200,
            ..NewtonOptions::default()
        },
        ..SimOptions::default()
    }
}

/// Per point: the left half (x < 0.5 m) is region 0, the right half region 1.
pub(super) fn regions(run: &BasisRun) -> Vec<usize> {
    run.points
        .points
        .iter()
        .map(|p| usize::from(p[0] >= 0.5))
        .collect()
}

/// A material with E, nu, rho per region.
pub(super) fn material(run: &BasisRun, e: [f64; 2], nu: [f64; 2], rho: [f64; 2]) -> MaterialField {
    let r = regions(run);
    MaterialField::from_arrays(
        r.iter().map(|&i| e[i]).collect(),
        r.iter().map(|&i| nu[i]).collect(),
        r.iter().map(|&i| rho[i]).collect(),
    )
    .unwrap()
}

pub(super) const E: [f64; 2] = [1e5, 3e5];
pub(super) const NU: [f64; 2] = [0.4, 0.3];
pub(super) const RHO: [f64; 2] = [1000.0, 1500.0];
pub(super) const G: [f64; 3] = [0.0, -9.81, 0.0];

/// The loss's coefficients: L = sum_t c_t . z_t, from dL/dx at 20 integration points drawn
/// at random, on every second frame (so frames without a loss are covered too).
pub(super) fn loss_coefficients(run: &BasisRun, dofs: usize) -> Vec<Vec<f64>> {
    let mut rng = SplitMix64::new(7);
    let picks: Vec<usize> = (0..20)
        .map(|_| (rng.next_f64() * run.points.len() as f64) as usize)
        .collect();
    let rest: Vec<Point3> = picks.iter().map(|&i| run.points.points[i]).collect();
    let w = run.basis.weights(&rest).unwrap();
    let layout = freeform::sim::elastic::Layout { handles: dofs / 12 };
    (0..=STEPS)
        .map(|t| {
            if t % 2 == 1 {
                return Vec::new();
            }
            let dl_dx: Vec<Point3> = (0..rest.len())
                .map(|_| {
                    [
                        rng.next_f64() - 0.5,
                        rng.next_f64() - 0.5,
                        rng.next_f64() - 0.5,
                    ]
                })
                .collect();
            positions_adjoint(layout, &rest, &w, &dl_dx).unwrap()
        })
        .collect()
}

/// The loss of `STEPS` plain steps of `s` from its current state.
pub(super) fn run_loss(s: &mut ReducedSim, c: &[Vec<f64>]) -> f64 {
    let mut states = vec![s.z().to_vec()];
    for _ in 0..STEPS {
        assert!(s.step().solve.converged);
        states.push(s.z().to_vec());
    }
    loss(&states, c)
}

pub(super) fn loss(states: &[Vec<f64>], c: &[Vec<f64>]) -> f64 {
    states
        .iter()
        .zip(c)
        .map(|(z, ct)| z.iter().zip(ct).map(|(a, b)| a * b).sum::<f64>())
        .sum()
}

/// Record `STEPS` converged steps of `s` and take the reverse pass of the loss `c`; also the
/// number of (point, collider) contacts the steps ended with.
pub(super) fn record(s: &mut ReducedSim, c: &[Vec<f64>]) -> (Gradients, usize) {
    let mut rec = Recording::start(s, STEPS).unwrap();
    let mut contacts = 0;
    for _ in 0..STEPS {
        let r = rec.step(s).unwrap();
        assert!(r.solve.converged);
        contacts += r.solve.info.contacts;
    }
    (rec.backward(s, c).unwrap(), contacts)
}

/// What a forward run starts from and how it is built.
pub(super) struct Case {
    pub(super) e: [f64; 2],
    pub(super) nu: [f64; 2],
    pub(super) rho: [f64; 2],
    pub(super) g: [f64; 3],
    pub(super) zdot0: Vec<f64>,
}

impl Case {
    pub(super) fn sim(&self, run: &BasisRun) -> ReducedSim {
        let m = material(run, self.e, self.nu, self.rho);
        let mut s = ReducedSim::new(&run.basis, &run.points, &m, &options(self.g)).unwrap();
        if !self.zdot0.is_empty() {
            let z0 = s.z().to_vec();
            s.set_state(&z0, &self.zdot0).unwrap();
        }
        s
    }

    /// The loss of a plain run (no recording).
    fn loss(&self, run: &BasisRun, c: &[Vec<f64>]) -> f64 {
        run_loss(&mut self.sim(run), c)
    }

    fn gradients(&self, run: &BasisRun, c: &[Vec<f64>]) -> Gradients {
        let mut s = self.sim(run);
        let mut rec = Recording::start(&s, STEPS).unwrap();
        for _ in 0..STEPS {
            rec.step(&mut s).unwrap();
        }
        rec.backward(&s, c).unwrap()
    }
}

pub(super) fn base_case(dofs: usize) -> Case {
    let mut rng = SplitMix64::new(3);
    Case {
        e: E,
        nu: NU,
        rho: RHO,
        g: G,
        zdot0: (0..dofs).map(|_| 0.2 * (rng.next_f64() - 0.5)).collect(),
    }
}

/// Central differences of the loss along each of `moves` (each builds a case moved by +h
/// or -h of its parameter), step `h`.
fn central(run: &BasisRun, c: &[Vec<f64>], moves: &[&dyn Fn(f64) -> Case], h: f64) -> Vec<f64> {
    moves
        .iter()
        .map(|m| (m(h).loss(run, c) - m(-h).loss(run, c)) / (2.0 * h))
        .collect()
}

/// |a - b| / |b| in the 2-norm.
pub(super) fn relative_error(a: &[f64], b: &[f64]) -> f64 {
    let d: f64 = a.iter().zip(b).map(|(x, y)| (x - y) * (x - y)).sum();
    let n: f64 = b.iter().map(|y| y * y).sum();
    (d / n).sqrt()
}

/// Each step is solved to 1e-12 D, so the losses carry errors of about 1e-12 of their size;
/// central differences with relative steps of 1e-4 then err by about 1e-8 from that and
/// O(h^2) = 1e-8 from truncation: 1e-5 (the bound) leaves a factor 100.
const TOLERANCE: f64 = 1e-5;

#[test]
fn material_gradients_per_region_match_finite_differences() {
    let run = bar();
    let probe = base_case(0).sim(&run);
    let dofs = probe.z().len();
    let c = loss_coefficients(&run, dofs);
    let base = base_case(dofs);
    let grads = base.gradients(&run, &c);
    let reg = regions(&run);
    let n = run.points.len();
    let sum_region = |per_point: &[f64], r: usize| -> f64 {
        per_point
            .iter()
            .zip(&reg)
            .filter(|(_, k)| **k == r)
            .map(|(v, _)| v)
            .sum()
    };
    let ye = grads.youngs_at_points(n).unwrap();
    let pn = grads.poisson_at_points(n).unwrap();
    let w = run.basis.weights(&run.points.points).unwrap();
    let rh = grads.density(&run.points, &w).unwrap();
    let got = [
        sum_region(&ye, 0) * E[0],
        sum_region(&ye, 1) * E[1],
        sum_region(&pn, 0),
        sum_region(&pn, 1),
        sum_region(&rh, 0) * RHO[0],
        sum_region(&rh, 1) * RHO[1],
    ];
    // Relative moves for E and rho (gradients scaled by the value), absolute for nu.
    let moves: [&dyn Fn(f64) -> Case; 6] = [
        &|h| Case {
            e: [E[0] * (1.0 + h), E[1]],
            ..base_case(dofs)
        },
        &|h| Case {
            e: [E[0], E[1] * (1.0 + h)],
            ..base_case(dofs)
        },
        &|h| Case {
            nu: [NU[0] + h, NU[1]],
            ..base_case(dofs)
        },
        &|h| Case {
            nu: [NU[0], NU[1] + h],
            ..base_case(dofs)
        },
        &|h| Case {
            rho: [RHO[0] * (1.0 + h), RHO[1]],
            ..base_case(dofs)
        },
        &|h| Case {
            rho: [RHO[0], RHO[1] * (1.0 + h)],
            ..base_case(dofs)
        },
    ];
    let fd = central(&run, &c, &moves, 1e-4);
    for (k, (a, b)) in got.iter().zip(&fd).enumerate() {
        let rel = (a - b).abs() / b.abs().max(1e-30);
        println!(
            "parameter {k}: adjoint {a:.10e}, central differences {b:.10e}, relative {rel:.2e}"
        );
    }
    let rel = relative_error(&got, &fd);
    assert!(rel < TOLERANCE, "materials: relative error {rel:e}");
    // Every gradient is a real signal (a zero one would pass the norm check trivially).
    assert!(fd.iter().all(|v| v.abs() > 1e-12), "{fd:?}");
}

#[test]
fn gravity_and_initial_state_gradients_match_finite_differences() {
    let run = bar();
    let dofs = base_case(0).sim(&run).z().len();
    let c = loss_coefficients(&run, dofs);
    let grads = base_case(dofs).gradients(&run, &c);
    let gravity = grads.gravity.expect("the run has gravity");
    let moves: [&dyn Fn(f64) -> Case; 3] = [
        &|h| Case {
            g: [G[0] + h, G[1], G[2]],
            ..base_case(dofs)
        },
        &|h| Case {
            g: [G[0], G[1] + h, G[2]],
            ..base_case(dofs)
        },
        &|h| Case {
            g: [G[0], G[1], G[2] + h],
            ..base_case(dofs)
        },
    ];
    let fd = central(&run, &c, &moves, 1e-3);
    let rel = relative_error(&gravity, &fd);
    println!("gravity: adjoint {gravity:?}, central differences {fd:?}");
    assert!(rel < TOLERANCE, "gravity: relative error {rel:e}");

    // The initial velocity along a random direction, and the initial state along another
    // (set through set_state before the run).
    let mut rng = SplitMix64::new(11);
    let dv: Vec<f64> = (0..dofs).map(|_| rng.next_f64() - 0.5).collect();
    let dz: Vec<f64> = (0..dofs).map(|_| 1e-2 * (rng.next_f64() - 0.5)).collect();
    let along_v = |h: f64| {
        let mut case = base_case(dofs);
        case.zdot0
            .iter_mut()
            .zip(&dv)
            .for_each(|(v, d)| *v += h * d);
        case.loss(&run, &c)
    };
    let along_z = |h: f64| {
        let case = base_case(dofs);
        let mut s = case.sim(&run);
        let z0: Vec<f64> = s.z().iter().zip(&dz).map(|(z, d)| z + h * d).collect();
        s.set_state(&z0, &case.zdot0).unwrap();
        let mut states = vec![s.z().to_vec()];
        for _ in 0..STEPS {
            assert!(s.step().solve.converged);
            states.push(s.z().to_vec());
        }
        loss(&states, &c)
    };
    let dot = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(x, y)| x * y).sum::<f64>();
    let h = 1e-3;
    let fd = [
        (along_v(h) - along_v(-h)) / (2.0 * h),
        (along_z(h) - along_z(-h)) / (2.0 * h),
    ];
    let got = [dot(&grads.zdot0, &dv), dot(&grads.z0, &dz)];
    println!("initial state: adjoint {got:?}, central differences {fd:?}");
    let rel = relative_error(&got, &fd);
    assert!(rel < TOLERANCE, "initial state: relative error {rel:e}");
}

/// The default reverse pass (conjugate gradients on matrix-free products, preconditioned by
/// an earlier step's factor) against the one that forms and factorizes H at every step: the
/// same gradients to the conjugate gradients' tolerance (a relative residual of 1e-10 in the
/// preconditioner's norm; bound 1e-8), and it formed fewer Hessians. The same with the loss
/// scaled by 1e-12 (an adjoint of 1e-12: the products keep their relative precision, so the
/// agreement does not depend on the loss's units).
#[test]
fn conjugate_gradient_reverse_pass_equals_the_direct_one() {
    let run = bar();
    let dofs = base_case(0).sim(&run).z().len();
    let c = loss_coefficients(&run, dofs);
    let mut s = base_case(dofs).sim(&run);
    let mut rec = Recording::start(&s, STEPS).unwrap();
    for _ in 0..STEPS {
        rec.step(&mut s).unwrap();
    }
    for scale in [1.0, 1e-12] {
        let cs: Vec<Vec<f64>> = c
            .iter()
            .map(|f| f.iter().map(|v| v * scale).collect())
            .collect();
        let direct = rec.clone().backward_direct(&s, &cs).unwrap();
        let g = rec.clone().backward(&s, &cs).unwrap();
        assert_eq!(direct.exact_hessians, STEPS);
        assert!(g.exact_hessians < STEPS && g.hessian_products > 0, "{g:?}");
        let pairs = [
            (g.youngs.clone(), direct.youngs.clone()),
            (g.poisson.clone(), direct.poisson.clone()),
            (g.z0.clone(), direct.z0.clone()),
            (g.zdot0.clone(), direct.zdot0.clone()),
            (
                g.gravity.unwrap().to_vec(),
                direct.gravity.unwrap().to_vec(),
            ),
        ];
        for (k, (a, b)) in pairs.iter().enumerate() {
            let rel = relative_error(a, b);
            println!("loss x {scale:e}, quantity {k}: relative difference {rel:.2e}");
            assert!(rel < 1e-8, "loss x {scale:e}, quantity {k}: {rel:e}");
        }
    }
}

#[test]
fn positions_adjoint_is_the_transpose_of_the_map() {
    let run = bar();
    let s = base_case(0).sim(&run);
    let layout = s.layout();
    let mut rng = SplitMix64::new(5);
    let rest: Vec<Point3> = run.points.points.iter().step_by(37).copied().collect();
    let w = run.basis.weights(&rest).unwrap();
    let z: Vec<f64> = (0..layout.dofs()).map(|_| rng.next_f64() - 0.5).collect();
    let g: Vec<Point3> = rest
        .iter()
        .map(|_| [rng.next_f64(), rng.next_f64(), rng.next_f64()])
        .collect();
    let x = freeform::sim::object::map_points(layout, &z, &rest, &w);
    // <g, x(z) - X> = <B^T g, z>: the same bilinear form summed two ways (rounding only).
    let lhs: f64 = x
        .iter()
        .zip(&rest)
        .zip(&g)
        .map(|((xi, xr), gi)| (0..3).map(|r| gi[r] * (xi[r] - xr[r])).sum::<f64>())
        .sum();
    let bt = positions_adjoint(layout, &rest, &w, &g).unwrap();
    let rhs: f64 = bt.iter().zip(&z).map(|(a, b)| a * b).sum();
    assert!(
        (lhs - rhs).abs() <= 1e-12 * lhs.abs().max(1.0),
        "{lhs} vs {rhs}"
    );
    // Bad shapes and NaN are refused.
    assert!(positions_adjoint(layout, &rest, &w, &g[1..]).is_err());
    let mut bad = g.clone();
    bad[3][1] = f64::NAN;
    let e = positions_adjoint(layout, &rest, &w, &bad).unwrap_err();
    assert!(e.to_string().contains("point 3"), "{e}");
}

#[test]
fn recordings_that_cannot_give_a_gradient_are_refused() {
    let run = bar();
    let case = base_case(0);
    let mut s = case.sim(&run);
    let dofs = s.z().len();
    let frames = |n: usize| vec![vec![1.0; dofs]; n];

    // A loss of the wrong shape or with NaN.
    let mut rec = Recording::start(&s, 2).unwrap();
    rec.step(&mut s).unwrap();
    rec.step(&mut s).unwrap();
    let e = rec.clone().backward(&s, &frames(2)).unwrap_err();
    assert!(
        e.to_string().contains("has 2 frames; the recording has 3"),
        "{e}"
    );
    let mut f = frames(3);
    f[1] = vec![1.0; dofs - 1];
    let e = rec.clone().backward(&s, &f).unwrap_err();
    assert!(e.to_string().contains("frame 1 has"), "{e}");
    f[1] = vec![f64::NAN; dofs];
    let e = rec.clone().backward(&s, &f).unwrap_err();
    assert!(e.to_string().contains("frame 1 is not finite"), "{e}");

    // The object changed between forward and backward: a setter, or a step outside it.
    let mut changed = case.sim(&run);
    let mut rec2 = Recording::start(&changed, 1).unwrap();
    rec2.step(&mut changed).unwrap();
    changed.set_gravity(Some([0.0, -1.0, 0.0])).unwrap();
    let e = rec2.backward(&changed, &frames(2)).unwrap_err();
    assert!(e.to_string().contains("changed since"), "{e}");
    s.step();
    let e = rec.clone().backward(&s, &frames(3)).unwrap_err();
    assert!(matches!(e, Error::Gradient(_)), "{e}");
    let e = rec.step(&mut s).unwrap_err();
    assert!(e.to_string().contains("changed since"), "{e}");

    // An unconverged step is named.
    let mut opts = options(G);
    opts.newton.max_iter = 1;
    let m = material(&run, E, NU, RHO);
    let mut tight = ReducedSim::new(&run.basis, &run.points, &m, &opts).unwrap();
    let mut rec3 = Recording::start(&tight, 1).unwrap();
    assert!(!rec3.step(&mut tight).unwrap().solve.converged);
    let e = rec3.backward(&tight, &frames(2)).unwrap_err();
    assert!(
        e.to_string().contains("recorded step 1 did not converge"),
        "{e}"
    );
}

/// A homogeneous object's modes depend on neither E nor nu (H_w is weighted by lambda + 4 mu,
/// the same at every point): two bases of the bar at different (E, nu) span the same space at
/// the integration points (up to the eigensolver's tolerance), so holding the basis fixed is
/// exact for a homogeneous object's material gradients.
#[test]
fn homogeneous_modes_do_not_depend_on_the_material() {
    let basis = |youngs: f64, poisson: f64| {
        bar_basis(
            40,
            5,
            1500,
            Material {
                youngs,
                poisson,
                density: 1000.0,
            },
        )
    };
    let a = basis(1e5, 0.4);
    let b = basis(7e6, 0.25);
    let wa = a.basis.weights(&a.points.points).unwrap();
    let wb = b.basis.weights(&a.points.points).unwrap();
    let (n, k) = (a.points.len(), wa.modes);
    let col = |w: &freeform::precompute::skinning::SkinningWeights, j: usize| -> Vec<f64> {
        (0..n).map(|i| w.values[i * k + j]).collect()
    };
    let dot = |x: &[f64], y: &[f64]| x.iter().zip(y).map(|(p, q)| p * q).sum::<f64>();
    // Least squares of each of b's columns on a's (normal equations, k = 6).
    let ca: Vec<Vec<f64>> = (0..k).map(|j| col(&wa, j)).collect();
    let gram = faer::Mat::from_fn(k, k, |i, j| dot(&ca[i], &ca[j]));
    let llt = faer::linalg::solvers::Llt::new(gram.as_ref(), faer::Side::Lower).unwrap();
    let mut worst: f64 = 0.0;
    for j in 0..k {
        let cb = col(&wb, j);
        let mut x = faer::Mat::from_fn(k, 1, |i, _| dot(&ca[i], &cb));
        faer::linalg::solvers::Solve::solve_in_place(&llt, x.as_mut());
        let residual: f64 = (0..n)
            .map(|p| {
                let fit: f64 = (0..k).map(|i| x[(i, 0)] * ca[i][p]).sum();
                (cb[p] - fit).powi(2)
            })
            .sum();
        worst = worst.max((residual / dot(&cb, &cb)).sqrt());
    }
    // The dense solver's eigenvectors are accurate to ~1e-12; 1e-8 bounds the subspace angle
    // far below anything a material gradient would notice.
    assert!(worst < 1e-8, "mode subspaces differ by {worst:e}");
}

/// With a frictionless plane collider pressing into the bar's underside, the collider's
/// penalty is part of the exact Hessian: E and gravity gradients still match central
/// differences. Contact sets can switch between the perturbed runs (a point crossing the
/// plane), where the loss is only C1; the bound with contact away from switches is
/// 1e-3.
#[test]
fn gradients_with_a_frictionless_collider_match_finite_differences() {
    let run = bar();
    let dofs = base_case(0).sim(&run).z().len();
    let c = loss_coefficients(&run, dofs);
    let with_plane = |case: &Case| {
        let m = material(&run, case.e, case.nu, case.rho);
        let mut opts = options(case.g);
        opts.colliders = vec![Collider {
            shape: freeform::sim::terms::ColliderShape::Plane {
                point: [0.0, 0.03, 0.0],
                normal: [0.0, 1.0, 0.0],
            },
            stiffness: Some(1e7),
            name: None,
            motion: freeform::sim::motion::Motion::Fixed,
            parent: None,
        }];
        let mut s = ReducedSim::new(&run.basis, &run.points, &m, &opts).unwrap();
        let z0 = s.z().to_vec();
        s.set_state(&z0, &case.zdot0).unwrap();
        s
    };
    let base = base_case(dofs);
    let mut s = with_plane(&base);
    assert!(s.contacts().is_some());
    let mut rec = Recording::start(&s, STEPS).unwrap();
    for _ in 0..STEPS {
        assert!(rec.step(&mut s).unwrap().solve.converged);
    }
    let g = rec.backward(&s, &c).unwrap();
    // Both regions' E scaled together: the sum of dL/dE_i E_i.
    let scaled: f64 = g
        .youngs_at_points(run.points.len())
        .unwrap()
        .iter()
        .zip(regions(&run))
        .map(|(d, r)| d * E[r])
        .sum();
    let got = [scaled, g.gravity.unwrap()[1]];
    let loss_of = |case: Case| run_loss(&mut with_plane(&case), &c);
    let h = 1e-4;
    let fd = [
        (loss_of(Case {
            e: [E[0] * (1.0 + h), E[1] * (1.0 + h)],
            ..base_case(dofs)
        }) - loss_of(Case {
            e: [E[0] * (1.0 - h), E[1] * (1.0 - h)],
            ..base_case(dofs)
        })) / (2.0 * h),
        (loss_of(Case {
            g: [G[0], G[1] + 1e-3, G[2]],
            ..base_case(dofs)
        }) - loss_of(Case {
            g: [G[0], G[1] - 1e-3, G[2]],
            ..base_case(dofs)
        })) / 2e-3,
    ];
    println!("with a plane: adjoint {got:?}, central differences {fd:?}");
    let rel = relative_error(&got, &fd);
    assert!(rel < 1e-3, "with a collider: relative error {rel:e}");
}

/// The bar's left end driven along a velocity and its right end turned about the bar's axis:
/// the per-step target pose gradients, chained to the velocity and the turning rate, and the
/// two penalty stiffnesses, against central differences (relative moves of 1e-4; bound 1e-5,
/// the bound without contact).
#[test]
fn boundary_motion_gradients_match_finite_differences() {
    use freeform::sim::motion::Motion;
    let run = bar();
    let dofs = base_case(0).sim(&run).z().len();
    let c = loss_coefficients(&run, dofs);
    let pivot = [1.0, 0.1, 0.1];
    let axis = [1.0, 0.0, 0.0];
    let sim = |velocity: [f64; 3], rate: f64, stiffness: [f64; 2]| {
        let case = base_case(dofs);
        let m = material(&run, case.e, case.nu, case.rho);
        let mut opts = options(case.g);
        opts.boundaries = vec![
            Boundary {
                motion: Motion::Translate { velocity },
                stiffness: Some(stiffness[0]),
                ..held_left()
            },
            Boundary {
                region: freeform::material::Region::HalfSpace {
                    point: [0.9, 0.0, 0.0],
                    normal: [1.0, 0.0, 0.0],
                },
                motion: Motion::Rotate {
                    pivot,
                    axis,
                    degrees_per_second: rate,
                },
                stiffness: Some(stiffness[1]),
            },
        ];
        let mut s = ReducedSim::new(&run.basis, &run.points, &m, &opts).unwrap();
        let z0 = s.z().to_vec();
        s.set_state(&z0, &case.zdot0).unwrap();
        s
    };
    let (v, rate, k) = ([0.0, 0.2, 0.1], 60.0, [1e8, 5e7]);
    let mut s = sim(v, rate, k);
    let mut rec = Recording::start(&s, STEPS).unwrap();
    for _ in 0..STEPS {
        assert!(rec.step(&mut s).unwrap().solve.converged);
    }
    let g = rec.backward(&s, &c).unwrap();
    let dt = options(G).dt;
    let turn = Motion::Rotate {
        pivot,
        axis,
        degrees_per_second: rate,
    };
    let mut got = [0.0; 5];
    for (k, poses) in g.boundary_poses.iter().enumerate() {
        let t = (k + 1) as f64 * dt;
        // The left target is translated by t v.
        got[0] += t * poses[0].translation[1] * v[1];
        got[1] += t * poses[0].translation[2] * v[2];
        // A turn dtheta about the axis through the pivot: the rotation dtheta a about the
        // target's origin o plus the translation dtheta a x (o - pivot); theta = rate t.
        let o = turn.at(t).translation;
        let shift = [0.0, -(o[2] - pivot[2]), o[1] - pivot[1]];
        let dtheta = poses[1].rotation[0]
            + (0..3)
                .map(|d| shift[d] * poses[1].translation[d])
                .sum::<f64>();
        got[2] += t.to_radians() * dtheta * rate;
    }
    got[3] = g.boundary_stiffness[0] * k[0];
    got[4] = g.boundary_stiffness[1] * k[1];
    let loss_of = |v: [f64; 3], rate: f64, k: [f64; 2]| run_loss(&mut sim(v, rate, k), &c);
    let h = 1e-4;
    let fd = [
        (loss_of([0.0, v[1] * (1.0 + h), v[2]], rate, k)
            - loss_of([0.0, v[1] * (1.0 - h), v[2]], rate, k))
            / (2.0 * h),
        (loss_of([0.0, v[1], v[2] * (1.0 + h)], rate, k)
            - loss_of([0.0, v[1], v[2] * (1.0 - h)], rate, k))
            / (2.0 * h),
        (loss_of(v, rate * (1.0 + h), k) - loss_of(v, rate * (1.0 - h), k)) / (2.0 * h),
        (loss_of(v, rate, [k[0] * (1.0 + h), k[1]]) - loss_of(v, rate, [k[0] * (1.0 - h), k[1]]))
            / (2.0 * h),
        (loss_of(v, rate, [k[0], k[1] * (1.0 + h)]) - loss_of(v, rate, [k[0], k[1] * (1.0 - h)]))
            / (2.0 * h),
    ];
    for (name, (a, b)) in ["v_y", "v_z", "rate", "kappa left", "kappa right"]
        .iter()
        .zip(got.iter().zip(&fd))
    {
        let rel = (a - b).abs() / b.abs().max(1e-30);
        println!("{name}: adjoint {a:.10e}, central differences {b:.10e}, relative {rel:.2e}");
        assert!(b.abs() > 1e-9, "{name}: no signal");
        assert!(rel < 1e-5, "{name}: relative error {rel:e}");
    }
}

/// The same bar with a boundary-aware basis (its held end a lift weight, the free modes zero
/// there): E of both regions together, gravity and the initial velocity against central
/// differences (bound 1e-5, the bound without contact).
#[test]
fn gradients_with_an_aware_basis_match_finite_differences() {
    let shape = freeform::io::read_shape(
        "box:1,0.2,0.2",
        &freeform::geometry::ShapeOptions::default(),
    )
    .unwrap();
    let opts = freeform::precompute::BasisOptions {
        kernels: 40,
        modes: 5,
        resolution: Some(freeform::precompute::sampling::Resolution::Count(1500)),
        solver: freeform::precompute::SolverConfig::Dense,
        material: rubber(),
        boundary_regions: vec![held_left().region],
        ..freeform::precompute::BasisOptions::default()
    };
    let run =
        freeform::precompute::build_basis(&shape, &opts, &freeform::progress::Silent).unwrap();
    let dofs = base_case(0).sim(&run).z().len();
    let c = loss_coefficients(&run, dofs);
    let (g, _) = record(&mut base_case(dofs).sim(&run), &c);
    let scaled: f64 = g
        .youngs_at_points(run.points.len())
        .unwrap()
        .iter()
        .zip(regions(&run))
        .map(|(d, r)| d * E[r])
        .sum();
    let mut rng = SplitMix64::new(23);
    let dv: Vec<f64> = (0..dofs).map(|_| rng.next_f64() - 0.5).collect();
    let along_v: f64 = g.zdot0.iter().zip(&dv).map(|(a, b)| a * b).sum();
    let got = [scaled, g.gravity.unwrap()[1], along_v];
    let h = 1e-4;
    let moves: [&dyn Fn(f64) -> Case; 3] = [
        &|h| Case {
            e: [E[0] * (1.0 + h), E[1] * (1.0 + h)],
            ..base_case(dofs)
        },
        &|h| Case {
            g: [G[0], G[1] + 10.0 * h, G[2]],
            ..base_case(dofs)
        },
        &|h| {
            let mut case = base_case(dofs);
            case.zdot0
                .iter_mut()
                .zip(&dv)
                .for_each(|(v, d)| *v += h * d);
            case
        },
    ];
    let mut fd = central(&run, &c, &moves, h);
    fd[1] /= 10.0;
    for (name, (a, b)) in ["E", "g_y", "zdot0"].iter().zip(got.iter().zip(&fd)) {
        let rel = (a - b).abs() / b.abs().max(1e-30);
        println!(
            "aware {name}: adjoint {a:.10e}, central differences {b:.10e}, relative {rel:.2e}"
        );
        assert!(b.abs() > 1e-9, "{name}: no signal");
        assert!(rel < TOLERANCE, "{name}: relative error {rel:e}");
    }
}
