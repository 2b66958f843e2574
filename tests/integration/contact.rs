//! Object-object contact (issue 15): the pair penalty's gradient and Hessian against finite
//! differences in reduced coordinates, linear momentum through a frictionless head-on
//! collision, a stack of three blocks at rest, and that scenes without `[contact]` step as
//! before.

use crate::common::{assert_momentum_conserved, no_cache};
use freeform::geometry::Shape;
use freeform::material::Material;
use freeform::progress::Silent;
use freeform::scene::{ObjectSpec, RunSettings, Scene, SceneBuilder, World};
use freeform::sim::contact::energy::SEGMENT_REACH;
use freeform::sim::contact::{
    Body, ContactSamples, ContactSettings, IslandSolver, PairContact, PairHessian,
};
use freeform::sim::elastic::Precision;
use freeform::sim::terms::{check_derivatives, ColliderShape, Floors};
use freeform::sim::{Collider, Placement};

fn block(name: &str, size: f64, at: [f64; 3], velocity: [f64; 3]) -> ObjectSpec {
    object(name, &format!("box:{size},{size},{size}"), at, velocity)
}

/// An object of `shape` (a shape string) as [`block`] makes them.
fn object(name: &str, shape: &str, at: [f64; 3], velocity: [f64; 3]) -> ObjectSpec {
    let mut o = ObjectSpec::new(name, shape)
        .unwrap()
        .kernels(30)
        .modes(3)
        .points(1500)
        .material(Material {
            youngs: 1e6,
            poisson: 0.3,
            density: 500.0,
        });
    o.placement = Placement {
        translation: at,
        velocity,
        ..Placement::default()
    };
    o.contact_samples = Some(300);
    o
}

/// The scene of `builder` with the objects `a` and `b` in frictionless contact.
fn frictionless(builder: SceneBuilder, a: ObjectSpec, b: ObjectSpec) -> Scene {
    builder
        .object(a)
        .object(b)
        .contact(ContactSettings {
            friction: 0.0,
            ..ContactSettings::default()
        })
        .build()
        .unwrap()
}

fn world(scene: &Scene) -> World {
    World::new(scene, &RunSettings::default(), &Silent).unwrap()
}

/// The gradient `g` and exact Hessian `h` of `contact`'s energy at `z` against central
/// differences along 6 fixed directions (the shared checker).
fn assert_derivatives_match_central_differences(
    contact: &PairContact,
    z: &[f64],
    g: &[f64],
    h: &faer::Mat<f64>,
) {
    let n = z.len();
    let energy = |z: &[f64], grad: &mut [f64]| {
        grad.fill(0.0);
        contact.energy_gradient(z, grad).energy
    };
    let mut g0 = vec![0.0; n];
    energy(z, &mut g0);
    assert_eq!(g0, g, "the gradient handed in is the energy's");
    let hessian = |_: &[f64]| h.clone();
    let dirs: Vec<Vec<f64>> = (0..6)
        .map(|trial| {
            (0..n)
                .map(|k| ((k * (trial + 3)) as f64 * 1.3).cos())
                .collect()
        })
        .collect();
    // Central differences with eps = 1e-7 (z is O(0.1)): truncation ~ eps^2 E''' and
    // rounding ~ 1e-16 E / eps, both far below 1e-6 of the derivatives checked; a pair
    // crossing its contact distance within eps would show as a kink of size ~eps, and the
    // tolerance 1e-5 leaves room for a few. Hessian errors are in the Euclidean norm of
    // H v (they were entrywise against the largest entry: the same 1e-5 held).
    let check = check_derivatives(energy, Some(&hessian), z, &dirs, 1e-7, Floors::both(1e-9));
    assert!(
        check.gradient <= 1e-5 && check.hessian <= 1e-5,
        "pair energy: {check:?}"
    );
}

/// The pair energy of the two objects of `w` with these samples (one per object), penalty
/// 1e9 Pa/m^2, no self-contact.
fn pair_contact<'s>(samples: &'s [ContactSamples], w: &World) -> PairContact<'s> {
    let layout = w.object(0).sim().layout();
    let n = layout.dofs();
    let bodies = (0..2)
        .map(|i| Body {
            samples: &samples[i],
            layout,
            offset: i * n,
            diagonal: w.object(i).sim().diagonal(),
            self_exclusion: None,
        })
        .collect();
    PairContact::new(bodies, vec![1e9; 4])
}

/// The stacked z of the two objects of `w`, deformed: a small smooth perturbation of
/// `amplitude` on every coordinate.
fn deformed_state(w: &World, amplitude: f64) -> Vec<f64> {
    let mut z: Vec<f64> = (0..2)
        .flat_map(|i| w.object(i).sim().z().to_vec())
        .collect();
    for (k, v) in z.iter_mut().enumerate() {
        *v += amplitude * ((k as f64) * 0.7).sin();
    }
    z
}

/// Two 0.2 m blocks overlapping by 4 mm (the tolerance is raised so the world accepts them).
fn overlapping_blocks() -> World {
    let scene = SceneBuilder::new(0.01, 1)
        .cache(no_cache())
        .object(block("a", 0.2, [0.0, 0.0, 0.0], [0.0; 3]))
        .object(block("b", 0.2, [0.196, 0.01, 0.0], [0.0; 3]))
        .contact(ContactSettings {
            penetration_tolerance: 0.5,
            ..ContactSettings::default()
        })
        .build()
        .unwrap();
    world(&scene)
}

/// The energy's gradient and exact Hessian in the stacked reduced coordinates of two
/// overlapping blocks match central differences, the PSD Hessian is positive semi-definite,
/// the pair is found deeper than a tolerance below its depth, and the step bound caps a
/// segment that would move the samples by metres.
#[test]
fn pair_energy_gradient_and_hessian_match_finite_differences() {
    let w = overlapping_blocks();
    let shape = Shape::Box { size: [0.2; 3] };
    let samples: Vec<ContactSamples> = (0..2)
        .map(|i| ContactSamples::new(&shape, w.object(i).basis(), 300, None).unwrap())
        .collect();
    let layout = w.object(0).sim().layout();
    let n = layout.dofs();
    let contact = pair_contact(&samples, &w);
    let z = deformed_state(&w, 1e-3);
    let mut g = vec![0.0; 2 * n];
    let st = contact.energy_gradient(&z, &mut g);
    assert!(st.active > 20, "the blocks must touch: {st:?}");
    let mut h = faer::Mat::<f64>::zeros(2 * n, 2 * n);
    contact.add_hessian(&z, PairHessian::Exact, &mut h);
    assert_derivatives_match_central_differences(&contact, &z, &g, &h);
    // Lagged friction: contacts kept from z, evaluated after a sideways slide of block b
    // (both below and above the smoothing displacement eps).
    let mu = vec![0.0, 0.4, 0.4, 0.0];
    let lag = contact.friction_lag(&z, &mu);
    assert!(!lag.is_empty());
    let lb = w.object(1).sim().layout();
    for slide in [2e-6, 3e-4] {
        let eps = 1e-5;
        // Handle 0 of a free basis is constant: its translation column slides the block.
        let mut z1 = z.clone();
        z1[n + lb.index(2, 0, 3)] += slide;
        let mut g = vec![0.0; 2 * n];
        let e0 = contact.friction_energy_gradient(&lag, eps, &z1, &mut g);
        assert!(e0 > 0.0);
        let mut h = faer::Mat::<f64>::zeros(2 * n, 2 * n);
        contact.add_friction_hessian(&lag, eps, &z1, &mut h);
        let fe = |z: &[f64], grad: &mut [f64]| {
            grad.fill(0.0);
            contact.friction_energy_gradient(&lag, eps, z, grad)
        };
        let hessian = |_: &[f64]| h.clone();
        let dirs: Vec<Vec<f64>> = (0..4)
            .map(|trial| {
                (0..2 * n)
                    .map(|k| ((k * (trial + 5)) as f64 * 0.9).sin())
                    .collect()
            })
            .collect();
        // A step of 1e-9 well below the smoothing scale (eps = 1e-5 m): the potential is C2
        // there. Hessian errors in the norm of H v (they were entrywise against the largest
        // entry: the same 1e-4 held).
        let floors = Floors::both(1e-12);
        let check = check_derivatives(fe, Some(&hessian), &z1, &dirs, 1e-9, floors);
        assert!(
            check.gradient <= 1e-5 && check.hessian <= 1e-4,
            "friction {slide}: {check:?}"
        );
    }
    let mut psd = faer::Mat::<f64>::zeros(2 * n, 2 * n);
    contact.add_hessian(&z, PairHessian::Psd, &mut psd);
    let eig = psd.self_adjoint_eigenvalues(faer::Side::Lower).unwrap();
    let top = eig.iter().cloned().fold(0.0, f64::max);
    // Rounding of the assembled sum: ~1e-14 of its largest eigenvalue.
    assert!(eig.iter().all(|&l| l >= -1e-12 * top), "{eig:?}");
    // The pair of blocks is reported deeper than a tolerance below its depth, not above it.
    let depth = st.deepest_fraction;
    assert_eq!(contact.pairs_deeper_than(&z, 0.5 * depth), vec![(0, 1)]);
    assert!(contact.pairs_deeper_than(&z, 1.01 * depth).is_empty());
    // A near-singular Newton system can ask for a step of metres: the bound lets one segment
    // move samples by at most SEGMENT_REACH of the smaller diagonal. Both blocks slide
    // together along x (their translation columns), so no sample pair closes and only that
    // cap bounds the step.
    let mut huge = vec![0.0; 2 * n];
    huge[lb.index(0, 0, 3)] = 1e3;
    huge[n + lb.index(0, 0, 3)] = 1e3;
    let moved = |i: usize| {
        samples[i]
            .displacements(layout, &huge[i * n..(i + 1) * n])
            .iter()
            .map(|d| (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt())
            .fold(0.0, f64::max)
    };
    let smallest = contact.bodies()[0]
        .diagonal
        .min(contact.bodies()[1].diagonal);
    let alpha = contact.max_step(&z, &huge);
    assert!(alpha > 0.0 && moved(0) > 100.0, "{alpha} {}", moved(0));
    assert!(
        alpha * (moved(0) + moved(1)) <= SEGMENT_REACH * smallest * (1.0 + 1e-12),
        "{alpha} moves {} of {smallest}",
        alpha * (moved(0) + moved(1))
    );
}

/// Feature samples (points on the edges, contact distance t against a sphere and 0 against
/// each other) through the same energy: with them more pairs are active, and the gradient
/// and exact Hessian still match central differences.
#[test]
fn feature_point_pairs_match_finite_differences() {
    let w = overlapping_blocks();
    let shape = Shape::Box { size: [0.2; 3] };
    let layout = w.object(0).sim().layout();
    let n = layout.dofs();
    let make = |spacing: f64| -> Vec<ContactSamples> {
        (0..2)
            .map(|i| {
                ContactSamples::new(&shape, w.object(i).basis(), 300, None)
                    .and_then(|s| s.with_features(&shape, w.object(i).basis(), spacing))
                    .unwrap()
            })
            .collect()
    };
    let (plain, with) = (make(0.0), make(0.5));
    assert!(with
        .iter()
        .all(|s| s.features > 0 && s.radius.contains(&0.0)));
    let (c0, c1) = (pair_contact(&plain, &w), pair_contact(&with, &w));
    // A deformed state, as in the test above but 1.3 times larger: at that one's state a
    // feature pair lies within the differences' step of its contact distance (a kink of
    // the C1 energy, which central differences cannot see through).
    let z = deformed_state(&w, 1.3e-3);
    let mut g = vec![0.0; 2 * n];
    let st = c1.energy_gradient(&z, &mut g);
    // The edges of b lying in a's face add point pairs to the sphere pairs.
    assert!(st.active > c0.stats(&z).active, "{st:?}");
    let mut h = faer::Mat::<f64>::zeros(2 * n, 2 * n);
    c1.add_hessian(&z, PairHessian::Exact, &mut h);
    assert_derivatives_match_central_differences(&c1, &z, &g, &h);
}

/// Self-contact pairs (one body's own samples) through the same energy: gradient and exact
/// Hessian against central differences, the PSD Hessian semi-definite, and the pairs found
/// deeper than a tolerance. The exclusion is set below the sample spacing so that neighbours
/// at rest form pairs: a configuration a scene would never make, but the same algebra as a
/// fold closing, with many pairs.
#[test]
fn self_pair_energy_gradient_and_hessian_match_finite_differences() {
    let scene = SceneBuilder::new(0.01, 1)
        .cache(no_cache())
        .object(block("a", 0.2, [0.0; 3], [0.0; 3]))
        .build()
        .unwrap();
    let w = world(&scene);
    // 300 samples on the 0.24 m^2 surface are s = 28 mm apart on a grid; a thickness of
    // 0.8 s puts the contact distance 1.6 s between the grid's distances s, 1.41 s and 2 s,
    // so no pair sits on the kink at r = d where central differences would fail.
    let spacing = (0.24f64 / 300.0).sqrt();
    let shape = Shape::Box { size: [0.2; 3] };
    let samples =
        ContactSamples::new(&shape, w.object(0).basis(), 300, Some(0.8 * spacing)).unwrap();
    let layout = w.object(0).sim().layout();
    let n = layout.dofs();
    let d = 2.0 * samples.thickness;
    let body = |ex: Option<f64>| Body {
        samples: &samples,
        layout,
        offset: 0,
        diagonal: w.object(0).sim().diagonal(),
        self_exclusion: ex,
    };
    let mut z = w.object(0).sim().z().to_vec();
    for (k, v) in z.iter_mut().enumerate() {
        *v += 1e-3 * ((k as f64) * 0.7).sin();
    }
    // Without self-contact one body has no pairs at all.
    let alone = PairContact::new(vec![body(None)], vec![1e9]);
    assert_eq!(alone.stats(&z).active, 0);
    let contact = PairContact::new(vec![body(Some(0.3 * d))], vec![1e9]);
    let mut g = vec![0.0; n];
    let st = contact.energy_gradient(&z, &mut g);
    assert!(st.active > 50, "neighbours must form pairs: {st:?}");
    // Pairs nearer than the exclusion at rest are left out.
    let wide = PairContact::new(vec![body(Some(0.9 * d))], vec![1e9]);
    assert!(wide.stats(&z).active < st.active);
    let mut h = faer::Mat::<f64>::zeros(n, n);
    contact.add_hessian(&z, PairHessian::Exact, &mut h);
    assert_derivatives_match_central_differences(&contact, &z, &g, &h);
    let mut psd = faer::Mat::<f64>::zeros(n, n);
    contact.add_hessian(&z, PairHessian::Psd, &mut psd);
    let eig = psd.self_adjoint_eigenvalues(faer::Side::Lower).unwrap();
    let top = eig.iter().cloned().fold(0.0, f64::max);
    // Rounding of the assembled sum, as above.
    assert!(eig.iter().all(|&l| l >= -1e-12 * top), "{eig:?}");
    // A rigid translation moves no pair: the Hessian has it in its null space.
    let mut t = vec![0.0; n];
    t[layout.index(1, 0, 3)] = 1.0;
    let ht: f64 = (0..n)
        .map(|i| (0..n).map(|j| h[(i, j)] * t[j]).sum::<f64>().abs())
        .fold(0.0, f64::max);
    assert!(ht <= 1e-10 * top, "{ht} against {top}");
    let depth = st.deepest_fraction;
    assert_eq!(contact.pairs_deeper_than(&z, 0.5 * depth), vec![(0, 0)]);
}

/// Two free blocks meet head-on without gravity or friction and bounce apart: the total
/// linear momentum stays what it was, within the bound the solver tolerance sets.
#[test]
fn a_head_on_collision_conserves_linear_momentum() {
    let tol = 1e-9;
    // Once apart, each block steps alone, and the default L-BFGS can stall a little above
    // this test's 1e-9 on the bounce's vibration (1.7e-9 at step 19 with the islands'
    // single-precision Hessians; docs/limits.md). Newton reaches it.
    let scene = frictionless(
        SceneBuilder::new(0.01, 30)
            .cache(no_cache())
            .tol(tol)
            .hessian(freeform::sim::HessianStrategy::Newton),
        block("a", 0.2, [-0.25, 0.0, 0.0], [1.0, 0.0, 0.0]),
        block("b", 0.2, [0.1, 0.02, 0.0], [-0.6, 0.0, 0.0]),
    );
    let mut w = world(&scene);
    let before = assert_momentum_conserved(&mut w, tol, 30);
    // They did bounce: the first block now moves left or slower than before.
    let v_a = {
        let o = w.object(0);
        let x1 = o.integration_positions().unwrap();
        (x1[0][0] - before[0][0][0]) / w.dt()
    };
    assert!(v_a < 0.5, "block a still moves at {v_a} m/s");
    let c = w.contact_summary().unwrap();
    assert!(
        c.worst_penetration_fraction < c.penetration_tolerance,
        "{c:?}"
    );
}

/// Two plates 2 cm thick and 2 cm apart fly at each other at 2 m/s each, in steps of 0.02 s:
/// stepped alone, each would move 4 cm in the first step and they would end it past each
/// other, apart, no sample in contact. Their samples' paths through the step meet, so the
/// world solves them again as one island, whose line searches never carry a sample through
/// another: they stay in order.
#[test]
fn objects_that_would_pass_through_each_other_within_a_step_are_solved_together() {
    let plate =
        |name: &str, y: f64, v: f64| object(name, "box:0.1,0.02,0.1", [0.0, y, 0.0], [0.0, v, 0.0]);
    let scene = frictionless(
        SceneBuilder::new(0.02, 3).cache(no_cache()),
        plate("a", 0.0, 2.0),
        plate("b", 0.04, -2.0),
    );
    let mut w = world(&scene);
    let centre = |w: &World, i: usize| {
        let x = w.object(i).integration_positions().unwrap();
        x.iter().map(|p| p[1]).sum::<f64>() / x.len() as f64
    };
    for step in 1..=3 {
        w.step().unwrap();
        let (a, b) = (centre(&w, 0), centre(&w, 1));
        assert!(a < b, "step {step}: plate a at y = {a}, plate b at y = {b}");
        if step == 1 {
            let row = w.contact_summary().unwrap().steps[0].clone();
            assert_eq!(row.islands, vec![2], "{row:?}");
        }
    }
}

/// The island's block solve (block-Jacobi conjugate gradients) takes the same step as the
/// dense Newton solve over the whole island: two blocks collide head on, stepped once with
/// each solver from the same state (every step before the first island is the same code
/// path, bit for bit).
///
/// The block solve, with the members' elastic Hessian products in double or (the default)
/// single precision, ends where the dense double-precision solve does.
#[test]
fn the_block_island_solve_takes_the_dense_solve_step() {
    for precision in [Precision::Double, Precision::Single] {
        block_and_dense_islands_agree(precision);
    }
}

fn block_and_dense_islands_agree(precision: Precision) {
    let tol = 1e-9;
    let scene = |solver, hessian_precision| {
        SceneBuilder::new(0.01, 30)
            .cache(no_cache())
            .tol(tol)
            .object(block("a", 0.2, [-0.25, 0.0, 0.0], [1.0, 0.0, 0.0]))
            .object(block("b", 0.2, [0.1, 0.02, 0.0], [-0.6, 0.0, 0.0]))
            .contact(ContactSettings {
                solver,
                hessian_precision,
                ..ContactSettings::default()
            })
            .build()
            .unwrap()
    };
    let mut dense = world(&scene(IslandSolver::Dense, Precision::Double));
    let mut blocks = world(&scene(IslandSolver::Blocks, precision));
    let mut compared = 0;
    for _ in 0..30 {
        dense.step().unwrap();
        blocks.step().unwrap();
        let row = dense
            .contact_summary()
            .unwrap()
            .steps
            .last()
            .unwrap()
            .clone();
        if row.islands.is_empty() {
            for i in 0..2 {
                assert_eq!(dense.object(i).sim().z(), blocks.object(i).sim().z());
            }
            continue;
        }
        // Each solve stops when the remaining Newton step moves the points by less than
        // tol D (mass-weighted RMS; equal volumes and density here, so a plain RMS), and
        // near the minimiser that step is the distance to it: the two end states are within
        // 2 tol D of each other. Factor 5 for the step being measured with the previous
        // iteration's Hessian (whose single-precision products, relative errors ~1e-6, move
        // that measure by far less).
        for i in 0..2 {
            let (o0, o1) = (dense.object(i), blocks.object(i));
            let (x0, x1) = (
                o0.integration_positions().unwrap(),
                o1.integration_positions().unwrap(),
            );
            let rms = (x0
                .iter()
                .zip(&x1)
                .map(|(p, q)| (0..3).map(|d| (p[d] - q[d]).powi(2)).sum::<f64>())
                .sum::<f64>()
                / x0.len() as f64)
                .sqrt();
            let bound = 10.0 * tol * o0.sim().diagonal();
            assert!(
                rms <= bound,
                "{precision:?}, object {i}: states differ by {rms:.3e} m > {bound:.3e}"
            );
            let (r0, r1) = (
                o0.summary().steps.last().unwrap(),
                o1.summary().steps.last().unwrap(),
            );
            assert!(r0.converged && r1.converged, "{r0:?} {r1:?}");
        }
        compared += 1;
        break;
    }
    assert_eq!(compared, 1, "{precision:?}: the blocks never touched");
}

/// Three blocks stacked on a floor under gravity settle: after 0.6 s they no longer move
/// (vertical or sideways) and none has sunk into another beyond the tolerance.
#[test]
fn a_stack_of_three_blocks_comes_to_rest() {
    let s = 0.15;
    let scene = SceneBuilder::new(0.01, 80)
        .cache(no_cache())
        .gravity([0.0, -9.81, 0.0])
        .object(block("low", s, [0.0, 0.0, 0.0], [0.0; 3]))
        .object(block("mid", s, [0.0, s, 0.0], [0.0; 3]))
        .object(block("top", s, [0.0, 2.0 * s, 0.0], [0.0; 3]))
        .collider(Collider::new(ColliderShape::Plane {
            point: [0.0, 0.0, 0.0],
            normal: [0.0, 1.0, 0.0],
        }))
        .contact(ContactSettings::default())
        .build()
        .unwrap();
    let mut w = world(&scene);
    let centre = |w: &World, i: usize| -> [f64; 3] {
        let x = w.object(i).integration_positions().unwrap();
        let n = x.len() as f64;
        std::array::from_fn(|d| x.iter().map(|p| p[d]).sum::<f64>() / n)
    };
    let start: Vec<[f64; 3]> = (0..3).map(|i| centre(&w, i)).collect();
    for _ in 0..60 {
        w.step().unwrap();
    }
    let settled: Vec<[f64; 3]> = (0..3).map(|i| centre(&w, i)).collect();
    for _ in 0..20 {
        w.step().unwrap();
    }
    let end: Vec<[f64; 3]> = (0..3).map(|i| centre(&w, i)).collect();
    for i in 0..3 {
        // At rest: the last 0.2 s move each centre by less than 0.1 mm (0.07% of the size).
        let moved = (0..3)
            .map(|d| (end[i][d] - settled[i][d]).abs())
            .fold(0.0, f64::max);
        assert!(moved < 1e-4, "block {i} still moves: {moved:.3e} m");
        // Held in place sideways: without friction the blocks may slide on each other (a
        // reduced basis of 30 kernels is not exactly symmetric, so a vertical load squeezes
        // sideways a little), but not off the stack: 1% of the block's size.
        for d in [0, 2] {
            assert!(
                (end[i][d] - start[i][d]).abs() < 0.01 * s,
                "block {i} slid {:.3e} m along axis {d}",
                end[i][d] - start[i][d]
            );
        }
        // Held up: the centre sank by less than the contact thickness plus the elastic
        // squeeze (a few mm), not through the block below.
        assert!(
            start[i][1] - end[i][1] < 0.01,
            "block {i} sank by {:.3e} m",
            start[i][1] - end[i][1]
        );
    }
    // No drift of the stack as a whole: gravity and the floor push vertically and contact
    // forces cancel in pairs, so the total horizontal momentum stays 0 and the centre of
    // mass (equal blocks: the mean of the centres) stays put, up to the solver tolerance
    // (tol D per block and step, 1e-6 x 0.26 m x 80 steps = 2e-5 m).
    for d in [0, 2] {
        let moved: f64 = (0..3).map(|i| end[i][d] - start[i][d]).sum::<f64>() / 3.0;
        assert!(
            moved.abs() < 2e-5,
            "the stack drifted {moved:.3e} m along axis {d}"
        );
    }
    let c = w.contact_summary().unwrap();
    assert!(
        c.worst_penetration_fraction < c.penetration_tolerance,
        "{c:?}"
    );
    assert_eq!(c.steps.last().unwrap().islands, vec![3]);
    for o in w.objects() {
        assert_eq!(o.summary().monitors.newton_nonconverged_steps, Some(0));
    }
}

/// A cube dropped corner first onto another's face: without feature samples its corner
/// stands 0.73 t past its own spheres and sinks into the face below unseen by them (the
/// visible figure well above the tolerance); the corner's feature sample keeps it within
/// the tolerance of the face's envelope.
#[test]
fn a_corner_landing_on_a_face_stays_out_of_it() {
    let s = 0.15;
    let visible = |feature_spacing: f64| {
        let mut top = block("top", s, [0.5 * s, s + 0.005, 0.5 * s], [0.0, -1.0, 0.0]);
        // The body diagonal (1, 1, 1) turned to +y: the corner at the origin points down.
        top.placement.rotation = Some(freeform::sim::motion::AxisAngle {
            axis: [-1.0, 0.0, 1.0],
            degrees: (1.0f64 / 3f64.sqrt()).acos().to_degrees(),
        });
        let scene = SceneBuilder::new(0.01, 12)
            .cache(no_cache())
            .gravity([0.0, -9.81, 0.0])
            .object(block("low", s, [0.0, 0.0, 0.0], [0.0; 3]))
            .object(top)
            .collider(Collider::new(ColliderShape::Plane {
                point: [0.0, 0.0, 0.0],
                normal: [0.0, 1.0, 0.0],
            }))
            .contact(ContactSettings {
                feature_spacing,
                ..ContactSettings::default()
            })
            .build()
            .unwrap();
        let mut w = world(&scene);
        for _ in 0..12 {
            w.step().unwrap();
        }
        let c = w.contact_summary().unwrap();
        assert!(c.steps.iter().any(|r| r.islands == vec![2]), "they touch");
        (
            c.worst_visible_penetration_fraction,
            c.worst_penetration_fraction,
            c.penetration_tolerance,
            c.worst_visible_at.clone(),
        )
    };
    let (without, _, tol, spot) = visible(0.0);
    let (with, samples, _, _) = visible(0.5);
    assert!(without > 1.5 * tol, "without features: {without}");
    // The report says where: the top cube's lowest corner (its rest-frame origin) in the
    // block below.
    let spot = spot.expect("a visible penetration has a spot");
    assert_eq!(
        (spot.surface_object.as_str(), spot.other_object.as_str()),
        ("top", "low")
    );
    assert!(spot.rest_point.iter().all(|c| c.abs() < 1e-12), "{spot:?}");
    // The corner is a sample now, held within the tolerance by the penalty; the face's
    // envelope between its samples is what it is measured against in both figures.
    assert!(
        samples <= tol && with <= tol,
        "with features: {with}, {samples}"
    );
}

/// Without `[contact]` objects pass through each other as before; with it the same far-apart
/// objects step alone (no island) and bit for bit the same.
#[test]
fn far_apart_objects_step_as_without_contact() {
    let base = SceneBuilder::new(0.01, 10)
        .cache(no_cache())
        .gravity([0.0, -9.81, 0.0])
        .object(block("a", 0.2, [0.0, 0.0, 0.0], [0.0; 3]))
        .object(block("b", 0.2, [2.0, 0.0, 0.0], [0.0; 3]));
    let plain = base.clone().build().unwrap();
    let with = base.contact(ContactSettings::default()).build().unwrap();
    let (mut w0, mut w1) = (world(&plain), world(&with));
    for _ in 0..10 {
        w0.step().unwrap();
        w1.step().unwrap();
    }
    assert!(w0.contact_summary().is_none());
    let c = w1.contact_summary().unwrap();
    assert!(c.steps.iter().all(|r| r.islands.is_empty()));
    for i in 0..2 {
        assert_eq!(w0.object(i).sim().z(), w1.object(i).sim().z());
    }
}

/// A block on a plane tilted by theta, friction mu = 0.5: below tan(theta) = mu it sticks
/// (creeps slower than the smoothing velocity eps_v), above it slides with the acceleration
/// g (sin theta - mu cos theta). The angles are 20% off tan(theta) = mu on either side, far
/// beyond the friction model's own error once the contact has settled (the acceleration
/// comes out within 0.2%). It is measured from step 20 to 50: a block set exactly on the
/// plane has no contact to lag friction from in its first steps, and its cubature points sink
/// about half a grid spacing before the penalty holds it (docs/limits.md).
#[test]
fn a_block_on_an_incline_sticks_below_the_friction_angle_and_slides_above() {
    let mu: f64 = 0.5;
    let eps_v = 1e-3;
    // Distance down the slope at steps 20, 35 and 50.
    let run = |tan: f64| -> [f64; 3] {
        let theta = tan.atan();
        let (s, c) = theta.sin_cos();
        let mut b = block("b", 0.1, [0.0, 0.0, 0.0], [0.0; 3]);
        b.placement.rotation = Some(freeform::sim::motion::AxisAngle {
            axis: [0.0, 0.0, 1.0],
            degrees: theta.to_degrees(),
        });
        let scene = SceneBuilder::new(0.01, 50)
            .cache(no_cache())
            .gravity([0.0, -9.81, 0.0])
            .object(b)
            .collider(Collider::new(ColliderShape::Plane {
                point: [0.0, 0.0, 0.0],
                normal: [-s, c, 0.0],
            }))
            .contact(ContactSettings {
                friction: mu,
                friction_velocity: eps_v,
                ..ContactSettings::default()
            })
            .build()
            .unwrap();
        let mut w = world(&scene);
        let down = |w: &World| -> f64 {
            let x = w.object(0).integration_positions().unwrap();
            let n = x.len() as f64;
            let m: [f64; 3] = std::array::from_fn(|d| x.iter().map(|p| p[d]).sum::<f64>() / n);
            -(m[0] * c + m[1] * s)
        };
        let mut out = [0.0; 3];
        for step in 1..=50 {
            w.step().unwrap();
            match step {
                20 => out[0] = down(&w),
                35 => out[1] = down(&w),
                50 => out[2] = down(&w),
                _ => {}
            }
        }
        out
    };
    let window = 0.3;
    let stuck = run(0.8 * mu);
    let creep = stuck[2] - stuck[0];
    // Sticking: slower than eps_v (the smoothed static regime creeps at
    // eps_v (1 - sqrt(1 - tan/mu)) = 0.55 eps_v here).
    assert!(
        creep.abs() < eps_v * window,
        "stuck block crept {creep:.3e} m in {window} s"
    );
    let tan: f64 = 1.2 * mu;
    let theta = tan.atan();
    let expected = 9.81 * (theta.sin() - mu * theta.cos());
    let x = run(tan);
    let accel = (x[2] - 2.0 * x[1] + x[0]) / (0.5 * window).powi(2);
    // Sliding at the Coulomb acceleration within 5% (backward Euler's lag and the lagged
    // normal force cost well under 1%).
    assert!(
        (accel - expected).abs() < 0.05 * expected,
        "sliding block accelerates at {accel:.4} m/s^2, expected {expected:.4}"
    );
}

/// A soft U-shaped clip (examples/data/clip.obj: arms 0.5 m long, 0.04 m thick, 0.1 m apart)
/// lies on the floor; its upper arm sags under gravity onto its lower arm. With self-contact
/// the arms touch and the upper one stays above the lower within the penetration tolerance;
/// with `[contact]` but without self-contact the same upper arm sinks into the lower one, so
/// the scene does exercise what self-contact prevents.
#[test]
fn a_clip_closing_on_itself_stops_at_its_own_arm() {
    let clip = concat!(env!("CARGO_MANIFEST_DIR"), "/examples/data/clip.obj");
    let run = |self_contact: bool| -> (f64, World) {
        let mut o = ObjectSpec::new("clip", clip)
            .unwrap()
            .kernels(400)
            .modes(12)
            .points(8000)
            .material(Material {
                youngs: 1e6,
                poisson: 0.35,
                density: 1000.0,
            });
        o.placement.translation = [0.0, 0.001, 0.0];
        let scene = SceneBuilder::new(0.01, 30)
            .cache(no_cache())
            .gravity([0.0, -9.81, 0.0])
            .hessian(freeform::sim::HessianStrategy::Newton)
            .object(o)
            .collider(Collider::new(ColliderShape::Plane {
                point: [0.0; 3],
                normal: [0.0, 1.0, 0.0],
            }))
            .contact(ContactSettings {
                self_contact,
                // Below half the 0.1 m gap: the facing samples take part (docs/scenes.md).
                radius: Some(0.008),
                ..ContactSettings::default()
            })
            .build()
            .unwrap();
        let mut w = world(&scene);
        // The lowest point of the upper arm's tip minus the highest of the lower arm's tip
        // (rest x > 0.4 m; the arms' rest y are [0, 0.04] and [0.14, 0.18]), over the run.
        let rest = w.object(0).rest_points().points.clone();
        let mut gap = f64::INFINITY;
        for _ in 0..30 {
            w.step().unwrap();
            let x = w.object(0).integration_positions().unwrap();
            let tip = |lo: f64, hi: f64| {
                rest.iter()
                    .zip(&x)
                    .filter(move |(r, _)| r[0] > 0.4 && r[1] >= lo && r[1] <= hi)
                    .map(|(_, p)| p[1])
            };
            let upper = tip(0.14, 0.19).fold(f64::INFINITY, f64::min);
            let lower = tip(-0.01, 0.04).fold(f64::NEG_INFINITY, f64::max);
            gap = gap.min(upper - lower);
        }
        (gap, w)
    };
    let (gap_on, w) = run(true);
    let c = w.contact_summary().unwrap();
    assert_eq!(c.self_contact, vec![true]);
    assert!(
        c.steps
            .iter()
            .any(|r| r.sample_pairs_active > 0 && r.islands == [1]),
        "the arms never touched: {:?}",
        c.steps.last()
    );
    assert!(
        c.worst_penetration_fraction <= c.penetration_tolerance,
        "{c:?}"
    );
    assert_eq!(
        w.object(0).summary().monitors.newton_nonconverged_steps,
        Some(0)
    );
    // Integration points lie inside the arms, so touching arms leave their points apart;
    // the tolerance (1% of the 0.52 m diagonal) is all the overlap allowed.
    let diag = w.object(0).sim().diagonal();
    assert!(
        gap_on >= -c.penetration_tolerance * diag,
        "the upper arm went {:.3e} m into the lower",
        -gap_on
    );
    let (gap_off, w) = run(false);
    assert!(w
        .contact_summary()
        .unwrap()
        .steps
        .iter()
        .all(|r| r.islands.is_empty()));
    assert!(
        gap_off < -0.02,
        "without self-contact the upper arm should sink into the lower: gap {gap_off:.3e} m"
    );
}
