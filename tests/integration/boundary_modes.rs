//! Boundary-aware bases (docs/math.md, "Boundary-aware modes"): the lifts are exactly 1 / 0 on
//! the regions and sum to 1, the free modes vanish on the regions and are the restricted
//! pencil's eigenpairs (against a dense solve), placement and bad regions.

use faer::Mat;
use freeform::material::Region;
use freeform::precompute::sampling::Resolution;
use freeform::precompute::{BasisOptions, Problem, SolverConfig};
use freeform::progress::Silent;
use freeform::sparse::{to_dense, SparseMatrix};

const LEFT: Region = Region::HalfSpace {
    point: [0.5, 0.0, 0.0],
    normal: [-1.0, 0.0, 0.0],
};
const RIGHT: Region = Region::HalfSpace {
    point: [1.5, 0.0, 0.0],
    normal: [1.0, 0.0, 0.0],
};

fn options(regions: Vec<Region>, solver: SolverConfig) -> BasisOptions {
    BasisOptions {
        kernels: 160,
        modes: 6,
        resolution: Some(Resolution::Count(8000)),
        solver,
        boundary_regions: regions,
        ..BasisOptions::default()
    }
}

/// The basis and the full H_w, M it was built from.
fn build(opts: &BasisOptions) -> (freeform::precompute::BasisRun, SparseMatrix, SparseMatrix) {
    let shape = freeform::io::read_shape("box:2,0.5,0.5", &Default::default()).unwrap();
    let problem = Problem::from_shape(&shape, opts, &Silent).unwrap();
    let (h, m) = problem.matrices().clone().into_pair();
    (problem.solve(&Silent).unwrap(), h, m)
}

#[test]
fn lifts_and_free_modes_follow_the_regions_exactly() {
    for solver in [SolverConfig::Dense, SolverConfig::default()] {
        let (run, h, m) = build(&options(vec![LEFT, RIGHT], solver.clone()));
        let basis = &run.basis;
        assert_eq!(basis.modes(), 7, "2 lifts + 5 free modes");
        let pts = &run.points.points;
        let w = basis.weights(pts).unwrap();
        let cover = freeform::precompute::rkpm::covering_kernels(&basis.kernels, pts);
        // The core of a region: points covered only by kernels centred in it.
        let core = |i: usize, r: &Region| {
            (cover.ptr[i]..cover.ptr[i + 1])
                .all(|e| r.contains(&basis.kernels.centers[cover.kernels[e] as usize]))
        };
        let (mut left, mut right) = (0, 0);
        // Rounding of RKPM sums of ~30 terms of size ~1: 1e-10 leaves four orders of margin.
        // On a core the values are exact: every coefficient involved is exactly 1 or 0.
        for (i, p) in pts.iter().enumerate() {
            let row = w.row(i);
            assert!(
                (row[0] + row[1] - 1.0).abs() < 1e-10,
                "lifts sum to 1 at {p:?}"
            );
            let (in_left, in_right) = (core(i, &LEFT), core(i, &RIGHT));
            if in_left {
                left += 1;
                assert!((row[0] - 1.0).abs() < 1e-12 && row[1] == 0.0, "{row:?}");
            }
            if in_right {
                right += 1;
                assert!(row[0] == 0.0 && (row[1] - 1.0).abs() < 1e-12, "{row:?}");
            }
            if in_left || in_right {
                for (j, v) in row[2..].iter().enumerate() {
                    assert!(
                        *v == 0.0,
                        "free mode {j} = {v:e} on a region's core at {p:?}"
                    );
                }
            }
        }
        let report = &run.report.boundaries;
        assert_eq!(report.len(), 2);
        let count = |r: &Region| pts.iter().filter(|p| r.contains(p)).count();
        assert_eq!(report[0].points, count(&LEFT));
        assert_eq!(report[1].points, count(&RIGHT));
        for (b, r) in [LEFT, RIGHT].iter().enumerate() {
            assert_eq!(
                freeform::precompute::boundary_modes::lift_column(basis, r),
                Some(b),
                "the simulator finds lift {b}"
            );
        }
        assert!(left > 10 && right > 10, "core points: {left} {right}");

        // Free kernels: those where every lift is strictly between 0 and 1 or the free modes
        // are non-zero; recover them from the coefficients (pinned rows are exactly 0 / 1 in
        // the lifts and 0 in the free modes).
        let c = &basis.coefficients;
        let k = c.nrows();
        let free: Vec<usize> = (0..k)
            .filter(|&i| (2..7).any(|j| c[(i, j)] != 0.0))
            .collect();
        assert_eq!(
            free.len() + report[0].kernels + report[1].kernels,
            k,
            "every kernel is free or pinned to one region"
        );
        for &i in &free {
            let x = &basis.kernels.centers[i];
            assert!(
                !LEFT.contains(x) && !RIGHT.contains(x),
                "free kernel {i} in a region"
            );
        }
        let hd = to_dense(h.as_ref());
        let md = to_dense(m.as_ref());
        let sub = |a: &Mat<f64>| Mat::from_fn(free.len(), free.len(), |i, j| a[(free[i], free[j])]);
        let (hff, mff) = (sub(&hd), sub(&md));
        let y = Mat::from_fn(free.len(), 5, |i, j| c[(free[i], 2 + j)]);
        // M_FF-orthonormal and H_FF y = lambda M_FF y (the solver's tolerance is 1e-8).
        let gram = y.transpose() * &mff * &y;
        for i in 0..5 {
            for j in 0..5 {
                let e = if i == j { 1.0 } else { 0.0 };
                assert!(
                    (gram[(i, j)] - e).abs() < 1e-8,
                    "gram {i} {j} {}",
                    gram[(i, j)]
                );
            }
        }
        let hy = &hff * &y;
        let my = &mff * &y;
        let (hnorm, mnorm) = (hff.norm_l2(), mff.norm_l2());
        for j in 0..5 {
            let lambda = basis.eigenvalues[2 + j];
            let r = (hy.col(j) - my.col(j) * lambda).norm_l2();
            // The solver's relative residual (tolerance 1e-8) uses ||.||_1 of the grounded
            // matrices; with Frobenius norms here the same residual can read up to ~10x
            // larger (the ratio of the two norms for ~100 nonzeros per row): 1e-6 bounds it.
            let rel = r / ((hnorm + lambda.abs() * mnorm) * y.col(j).norm_l2());
            assert!(rel <= 1e-6, "pair {j}: relative residual {rel:e}");
        }
        // The eigenvalues are the smallest of the restricted pencil: a dense reference
        // (M_FF^-1/2 H_FF M_FF^-1/2 from the symmetric eigendecomposition of M_FF).
        let me = mff.self_adjoint_eigen(faer::Side::Lower).unwrap();
        let (u, d) = (me.U(), me.S());
        let n = free.len();
        let s_inv = Mat::from_fn(n, n, |i, j| {
            (0..n)
                .map(|q| u[(i, q)] * u[(j, q)] / d[q].sqrt())
                .sum::<f64>()
        });
        let cmat = &s_inv * &hff * &s_inv;
        let cs = (&cmat + cmat.transpose()) * 0.5;
        let mut ev: Vec<f64> = cs.self_adjoint_eigenvalues(faer::Side::Lower).unwrap();
        ev.sort_by(f64::total_cmp);
        for (j, want) in ev.iter().take(5).enumerate() {
            let got = basis.eigenvalues[2 + j];
            // Eigenvalues converge with the square of the 1e-8 residual; the dense reference
            // itself is accurate to ~1e-12 relative: 1e-8 is loose for both.
            assert!(
                (got - want).abs() <= 1e-8 * want.abs(),
                "eigenvalue {j}: {got:e} vs dense {want:e}"
            );
        }
        // The lifts are H_w-harmonic on the free kernels: (H c)_F = 0.
        for b in 0..2 {
            let lift = Mat::from_fn(k, 1, |i, _| c[(i, b)]);
            let hl = &hd * &lift;
            let worst = free.iter().map(|&i| hl[(i, 0)].abs()).fold(0.0, f64::max);
            assert!(worst <= 1e-9 * hnorm, "lift {b}: (H c)_F up to {worst:e}");
        }
    }
}

#[test]
fn one_region_lift_is_the_constant_and_free_basis_is_unchanged() {
    let (run, ..) = build(&options(vec![LEFT], SolverConfig::default()));
    let c = &run.basis.coefficients;
    assert_eq!(run.basis.modes(), 7, "1 lift + 6 free modes");
    for i in 0..c.nrows() {
        assert_eq!(c[(i, 0)], 1.0, "the single lift is exactly the constant");
    }
    // No regions: exactly the free basis of the same options.
    let (free, ..) = build(&options(vec![], SolverConfig::default()));
    let opts = options(vec![], SolverConfig::default());
    let shape = freeform::io::read_shape("box:2,0.5,0.5", &Default::default()).unwrap();
    let again = freeform::precompute::build_basis(&shape, &opts, &Silent).unwrap();
    assert_eq!(free.basis.coefficients, again.basis.coefficients);
    assert!(free.report.boundaries.is_empty());
}

#[test]
fn bad_regions_are_named() {
    let shape = freeform::io::read_shape("box:2,0.5,0.5", &Default::default()).unwrap();
    let err = |regions: Vec<Region>| {
        let opts = options(regions, SolverConfig::default());
        freeform::precompute::build_basis(&shape, &opts, &Silent)
            .unwrap_err()
            .to_string()
    };
    let outside = Region::Sphere {
        center: [5.0, 5.0, 5.0],
        radius: 0.1,
    };
    let e = err(vec![LEFT, outside]);
    assert!(
        e.contains("boundary region") && e.contains("no integration point"),
        "{e}"
    );
    let overlapping = Region::HalfSpace {
        point: [0.6, 0.0, 0.0],
        normal: [-1.0, 0.0, 0.0],
    };
    let e = err(vec![LEFT, overlapping]);
    assert!(e.contains("0 and 1") && e.contains("overlap"), "{e}");
    // A tiny ball around an integration point that is no kernel centre.
    let free = freeform::precompute::build_basis(
        &shape,
        &options(vec![], SolverConfig::default()),
        &Silent,
    )
    .unwrap();
    let lonely = free
        .points
        .points
        .iter()
        .find(|p| {
            free.basis
                .kernels
                .centers
                .iter()
                .all(|c| (0..3).map(|d| (c[d] - p[d]).powi(2)).sum::<f64>() > 1e-4)
        })
        .unwrap();
    let thin = Region::Sphere {
        center: *lonely,
        radius: 1e-3,
    };
    let e = err(vec![thin]);
    assert!(e.contains("no kernel centre"), "{e}");
    let everything = Region::Box {
        min: [-1.0; 3],
        max: [3.0; 3],
    };
    let e = err(vec![everything]);
    assert!(e.contains("whole object"), "{e}");
    let mut opts = options(vec![LEFT, RIGHT], SolverConfig::default());
    opts.modes = 1;
    let e = freeform::precompute::build_basis(&shape, &opts, &Silent)
        .unwrap_err()
        .to_string();
    assert!(e.contains("2 lifts") && e.contains("m >= 2"), "{e}");
    let nan = Region::Sphere {
        center: [f64::NAN, 0.0, 0.0],
        radius: 0.1,
    };
    assert!(err(vec![nan]).contains("NaN"));
}

#[test]
fn aware_basis_is_placed_rigidly() {
    use freeform::sim::motion::AxisAngle;
    use freeform::sim::{Placement, ReducedSim, SimOptions};
    let (run, ..) = build(&options(vec![LEFT, RIGHT], SolverConfig::default()));
    let placement = Placement {
        translation: [0.3, -1.0, 2.0],
        rotation: Some(AxisAngle {
            axis: [1.0, 2.0, 0.5],
            degrees: 70.0,
        }),
        ..Placement::default()
    };
    let opts = SimOptions {
        placement,
        ..SimOptions::default()
    };
    let sim = ReducedSim::new(&run.basis, &run.points, &run.material, &opts).unwrap();
    let w = run.basis.weights(&run.points.points).unwrap();
    let x = sim.positions(&run.points.points, &w);
    let n = (1.0f64 + 4.0 + 0.25).sqrt();
    let r =
        freeform::sim::motion::rotation_matrix(&[1.0 / n, 2.0 / n, 0.5 / n], 70f64.to_radians());
    // The lifts sum to 1 to ~1e-12 (one sparse solve); positions are O(2 m): 1e-9 m.
    for (p, q) in run.points.points.iter().zip(&x) {
        let want: [f64; 3] = std::array::from_fn(|i| {
            (0..3).map(|k| r[i][k] * p[k]).sum::<f64>() + placement.translation[i]
        });
        for d in 0..3 {
            assert!((q[d] - want[d]).abs() < 1e-9, "{q:?} vs {want:?}");
        }
    }
}

#[test]
fn small_aware_beam_does_not_depend_on_the_hold_stiffness() {
    use freeform::benchmark::{beam_basis, simulate_beam, ReducedBeamOptions};
    use freeform::fem::beam::{run_beam_reference, BeamTest, FemBeamConfig};
    use freeform::precompute::BoundaryModes;
    let mut fem = FemBeamConfig::standard(BeamTest::Bend, 2);
    fem.steps = 30;
    let reference = run_beam_reference(&fem, None, &Silent).unwrap();
    let mut errors = Vec::new();
    for boundaries in [BoundaryModes::Free, BoundaryModes::Aware] {
        let mut opts = ReducedBeamOptions {
            modes: 9,
            kernels: 300,
            cubature: 2000,
            boundaries,
            ..ReducedBeamOptions::default()
        };
        let basis = beam_basis(&fem, &opts, &Silent).unwrap();
        for k in [1e10, 1e12] {
            opts.hold_stiffness = Some(k);
            let r = simulate_beam(&fem, &reference, &basis, &opts, &Silent).unwrap();
            assert_eq!(r.reduced_nonconverged_steps, 0);
            errors.push(r.normalized_mse);
        }
    }
    // Measured: free 5.9e-6 / 1.2e-5, aware 2.18e-5 / 2.18e-5. An aware region is held
    // through its lift's handle only, so a 100x stiffer hold moves the region by ~load/kappa
    // (~1e-5 m against centimetre errors): the error changes by well under 2 %. The free
    // basis locks under the stiffer hold (2x): the test can tell the two apart.
    let change = |a: f64, b: f64| (a - b).abs() / a.min(b);
    assert!(change(errors[2], errors[3]) < 0.02, "aware {errors:?}");
    assert!(change(errors[0], errors[1]) > 0.5, "free {errors:?}");
    // Against the FEM reference (P2, r = 2, 30 steps): 5x above the measured 2.2e-5.
    assert!(errors[2] < 1e-4, "aware {errors:?}");
}

#[test]
fn steps_report_how_far_each_region_is_from_its_target() {
    use freeform::sim::motion::Motion;
    use freeform::sim::{Boundary, ReducedSim, SimOptions};
    let (run, ..) = build(&options(vec![LEFT, RIGHT], SolverConfig::default()));
    let opts = SimOptions {
        gravity: Some([0.0, -9.81, 0.0]),
        boundaries: vec![
            Boundary {
                region: LEFT,
                motion: Motion::Fixed,
                stiffness: None,
            },
            Boundary {
                region: RIGHT,
                motion: Motion::Translate {
                    velocity: [0.0, 1.0, 0.0],
                },
                stiffness: None,
            },
        ],
        ..SimOptions::default()
    };
    let mut sim = ReducedSim::new(&run.basis, &run.points, &run.material, &opts).unwrap();
    let pts = &run.points.points;
    let vol = &run.points.volumes;
    let w = run.basis.weights(pts).unwrap();
    for _ in 0..5 {
        let r = sim.step();
        let x = sim.positions(pts, &w);
        // Independent: the RMS over each region's points from their positions.
        let rms = |region: &Region, offset: f64| {
            let (mut s, mut v) = (0.0, 0.0);
            for (i, p) in pts.iter().enumerate() {
                if region.contains(p) {
                    let d = [x[i][0] - p[0], x[i][1] - p[1] - offset, x[i][2] - p[2]];
                    s += vol[i] * (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
                    v += vol[i];
                }
            }
            (s / v).sqrt()
        };
        let want = rms(&LEFT, 0.0).max(rms(&RIGHT, r.time));
        let got = r.boundary_rms_deviation.unwrap();
        // Moments against a direct sum: the same quantity by two roundings; the energy form
        // cancels terms of size ~|x - X|^2 ~ (1 cm)^2, so ~1e-7 of the lift (1e-9 m here).
        assert!(
            (got - want).abs() <= 1e-9 + 1e-6 * want,
            "{got:e} vs {want:e}"
        );
        assert!(got > 0.0 && got < 0.01, "{got:e}");
    }
}

#[test]
fn the_basis_cache_keys_on_the_regions() {
    use crate::common::small_bar;
    use freeform::precompute::BoundaryModes;
    use freeform::scene::{CacheSettings, RunSettings, SceneBuilder, World};
    let dir = tempfile::tempdir().unwrap();
    let held = Region::HalfSpace {
        point: [0.3, 0.0, 0.0],
        normal: [-1.0, 0.0, 0.0],
    };
    let scene = |modes: BoundaryModes| {
        let mut s = SceneBuilder::new(0.01, 1)
            .cubature(300)
            .cache(CacheSettings {
                enabled: true,
                dir: dir.path().to_path_buf(),
            })
            .object(small_bar("bar").hold(held))
            .build()
            .unwrap();
        s.objects[0].basis.boundaries = modes;
        s
    };
    let open = |modes| World::new(&scene(modes), &RunSettings::default(), &Silent).unwrap();
    let first = open(BoundaryModes::Aware);
    assert!(!first.object(0).summary().basis_cached);
    let again = open(BoundaryModes::Aware);
    assert!(
        again.object(0).summary().basis_cached,
        "the same regions hit the cache"
    );
    let free = open(BoundaryModes::Free);
    assert!(
        !free.object(0).summary().basis_cached,
        "a free basis is another key"
    );
    assert_ne!(
        free.object(0).basis().coefficients,
        first.object(0).basis().coefficients
    );
    // A cached aware basis steps bit for bit like the fresh one (the hold finds its lift).
    let (mut a, mut b) = (first, again);
    for _ in 0..3 {
        a.step().unwrap();
        b.step().unwrap();
    }
    assert_eq!(a.object(0).sim().z(), b.object(0).sim().z());
}
