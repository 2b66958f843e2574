//! Gradients with respect to an object's placement (translation, rotation, initial linear
//! and angular velocity) against central differences of the same discrete model re-built at
//! the moved placement (the helpers are `gradient.rs`'s).

use super::gradient::{bar, base_case, loss_coefficients, material, options, record, run_loss};
use freeform::linalg3::{matrix_to_quat, mul};
use freeform::precompute::BasisRun;
use freeform::sim::gradient::Recording;
use freeform::sim::motion::{rotation_matrix, AxisAngle, Motion, Rigid};
use freeform::sim::terms::ColliderShape;
use freeform::sim::{Collider, Placement, ReducedSim};

/// Lifted 2 cm and turned 3 degrees about z (its far end starts 3 cm into the floor), thrown
/// and spun: the floor's penalty and friction act within the first steps.
fn placement() -> Placement {
    Placement {
        translation: [0.05, 0.02, -0.03],
        rotation: Some(AxisAngle {
            axis: [0.1, -0.2, 1.0],
            degrees: -3.0,
        }),
        velocity: [0.5, -0.3, 0.2],
        angular_velocity: [0.3, -0.5, 1.0],
    }
}

/// The free bar (no held region) over a floor with friction.
fn sim(run: &BasisRun, p: &Placement) -> ReducedSim {
    let case = base_case(0);
    let m = material(run, case.e, case.nu, case.rho);
    let mut opts = options(case.g);
    opts.boundaries.clear();
    opts.placement = *p;
    opts.colliders = vec![Collider {
        shape: ColliderShape::Plane {
            point: [0.0, 0.0, 0.0],
            normal: [0.0, 1.0, 0.0],
        },
        stiffness: Some(1e7),
        name: None,
        motion: Motion::Fixed,
        parent: None,
    }];
    let mut s = ReducedSim::new(&run.basis, &run.points, &m, &opts).unwrap();
    s.set_collider_friction(&[0.4], 0.01).unwrap();
    s
}

/// `p` turned further by the small world rotation `delta` (radians): R -> exp([delta]x) R.
fn turned(p: &Placement, delta: [f64; 3]) -> Placement {
    let r0 = p.transform().unwrap().rotation;
    let angle = (delta.iter().map(|v| v * v).sum::<f64>()).sqrt();
    let small = if angle > 0.0 {
        rotation_matrix(&delta.map(|v| v / angle), angle)
    } else {
        Rigid::IDENTITY.rotation
    };
    let q = matrix_to_quat(&mul(&small, &r0));
    let s = (q[1] * q[1] + q[2] * q[2] + q[3] * q[3]).sqrt();
    Placement {
        rotation: Some(AxisAngle {
            axis: [q[1] / s, q[2] / s, q[3] / s],
            degrees: (2.0 * s.atan2(q[0])).to_degrees(),
        }),
        ..*p
    }
}

/// Every component of the four placement gradients: relative 2-norm error (per quantity)
/// below 1e-5, the bound without contact switches (the moves are 1e-5 m, rad, m/s, rad/s;
/// steps solved to 1e-12 D, as in gradient.rs).
#[test]
fn placement_gradients_match_finite_differences() {
    let run = bar();
    let p = placement();
    let mut s = sim(&run, &p);
    let c = loss_coefficients(&run, s.z().len());
    let (g, contacts) = record(&mut s, &c);
    assert!(contacts > 0, "the bar must touch the floor");
    let got = g.placement(&s, &p).unwrap();

    let h = 1e-5;
    let unit =
        |k: usize, v: f64| -> [f64; 3] { std::array::from_fn(|d| if d == k { v } else { 0.0 }) };
    let moved = |f: &dyn Fn(f64) -> Placement| {
        (run_loss(&mut sim(&run, &f(h)), &c) - run_loss(&mut sim(&run, &f(-h)), &c)) / (2.0 * h)
    };
    let add = |a: [f64; 3], b: [f64; 3]| -> [f64; 3] { std::array::from_fn(|d| a[d] + b[d]) };
    let fd: [[f64; 3]; 4] = [
        std::array::from_fn(|k| {
            moved(&|e| Placement {
                translation: add(p.translation, unit(k, e)),
                ..p
            })
        }),
        std::array::from_fn(|k| moved(&|e| turned(&p, unit(k, e)))),
        std::array::from_fn(|k| {
            moved(&|e| Placement {
                velocity: add(p.velocity, unit(k, e)),
                ..p
            })
        }),
        std::array::from_fn(|k| {
            moved(&|e| Placement {
                angular_velocity: add(p.angular_velocity, unit(k, e)),
                ..p
            })
        }),
    ];
    let adjoint = [
        got.translation,
        got.rotation,
        got.velocity,
        got.angular_velocity,
    ];
    for (name, (a, b)) in ["translation", "rotation", "velocity", "angular velocity"]
        .iter()
        .zip(adjoint.iter().zip(&fd))
    {
        let d: f64 = (0..3).map(|k| (a[k] - b[k]).powi(2)).sum::<f64>().sqrt();
        let n: f64 = b.iter().map(|v| v * v).sum::<f64>().sqrt();
        println!(
            "{name}: adjoint {a:?}, central differences {b:?}, relative {:.2e}",
            d / n
        );
        assert!(n > 1e-9, "{name}: no signal");
        assert!(d / n < 1e-5, "{name}: relative error {:e}", d / n);
    }
}

#[test]
fn placement_gradients_need_a_recording_from_the_placement_of_a_free_object() {
    let run = bar();
    let p = placement();
    let mut s = sim(&run, &p);
    let dofs = s.z().len();
    let frames = |n: usize| vec![vec![1.0; dofs]; n];
    s.step();
    let mut rec = Recording::start(&s, 1).unwrap();
    rec.step(&mut s).unwrap();
    let g = rec.backward(&s, &frames(2)).unwrap();
    let e = g.placement(&s, &p).unwrap_err();
    assert!(
        e.to_string().contains("did not start at this placement"),
        "{e}"
    );

    // The held bar of gradient.rs: its held region follows the placement.
    let mut held = base_case(0).sim(&run);
    let mut rec = Recording::start(&held, 1).unwrap();
    rec.step(&mut held).unwrap();
    let g = rec.backward(&held, &frames(2)).unwrap();
    let e = g.placement(&held, &Placement::default()).unwrap_err();
    assert!(e.to_string().contains("held regions"), "{e}");
}
