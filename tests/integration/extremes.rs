//! The extremes (issue #6): nearly incompressible and auxetic materials, moduli from 1e3 to
//! 1e11 Pa, material contrasts up to 1e6, objects from a millimetre to a kilometre, thin
//! plates and rods, very few and many kernels, 1 to 64 modes, degenerate point sets, and
//! violent simulations. Every case checks numbers against an independent reference (an
//! exact invariance, the dense solver, an analytic eigenvalue) or a bound that follows from
//! the method, not only the absence of a panic. The envelope these tests pin down is
//! described, with measured costs, in docs/limits.md.

#![allow(clippy::needless_range_loop)] // index loops mirror the formulas

use crate::common;
use common::held_left;
use freeform::eigen::compare::{max_eigenvalue_rel_diff, max_subspace_angle};
use freeform::geometry::ShapeOptions;
use freeform::io::read_shape;
use freeform::material::{Material, MaterialField, MaterialOverride, Region};
use freeform::precompute::assembly::assemble;
use freeform::precompute::rkpm::{evaluate, ShapeFunctionOptions};
use freeform::precompute::sampling::{IntegrationPoints, Resolution};
use freeform::precompute::{build_basis, BasisOptions, BasisRun, Problem, SolverConfig};
use freeform::progress::Silent;
use freeform::random::SplitMix64;
use freeform::sim::motion::Motion;
use freeform::sim::newton::SolveReport;
use freeform::sim::{Boundary, HessianStrategy, NewtonOptions, ReducedSim, SimOptions};
use freeform::sparse::to_dense;
use freeform::{Error, Point3};
// Coverage errors name the support factor through the option table: `--support` where the
// command line prints them (`Front::Flags`).
use freeform::options::Front;
use std::f64::consts::PI;

fn opts(k: usize, m: usize, n: usize, material: Material, solver: SolverConfig) -> BasisOptions {
    BasisOptions {
        kernels: k,
        modes: m,
        resolution: Some(Resolution::Count(n)),
        solver,
        material,
        ..BasisOptions::default()
    }
}

fn basis(spec: &str, o: &BasisOptions) -> Result<BasisRun, Error> {
    let shape = read_shape(spec, &ShapeOptions::default()).unwrap();
    build_basis(&shape, o, &Silent)
}

fn rubber(poisson: f64) -> Material {
    Material {
        youngs: 1e5,
        poisson,
        density: 1000.0,
    }
}

/// lambda + 4 mu, the weight of H_w for a homogeneous material (design.md, Prop. 1).
fn c_weight(m: &Material) -> f64 {
    let (l, mu) = m.lame();
    l + 4.0 * mu
}

/// The report's own quality figures are within what the solver promises: residuals at the
/// tolerance asked for, M-orthonormal modes, reproducing identities to round-off, finite
/// ascending eigenvalues with the constant mode's at 0.
fn assert_healthy(run: &BasisRun, what: &str) {
    let r = &run.report;
    let ev = &r.eigenvalues;
    assert!(ev.iter().all(|v| v.is_finite()), "{what}: {ev:?}");
    assert!(
        ev.windows(2).all(|w| w[0] <= w[1]),
        "{what}: not ascending {ev:?}"
    );
    // The constant mode: H 1 = 0 up to round-off of the assembly (1e-10 of the next one).
    assert!(
        ev[0].abs() <= 1e-10 * ev[1],
        "{what}: constant mode {} vs {}",
        ev[0],
        ev[1]
    );
    assert!(ev[1] > 0.0, "{what}: {ev:?}");
    assert!(
        r.max_relative_residual <= r.tol,
        "{what}: residual {:.2e}",
        r.max_relative_residual
    );
    // Both solvers M-orthonormalize in the end (Cholesky-QR / dense); 1e-10 leaves room for
    // cond(M) ~ 1e4 times round-off.
    assert!(
        r.orthonormality_error <= 1e-10,
        "{what}: orthonormality {:.2e}",
        r.orthonormality_error
    );
    assert!(
        r.reproducing_error <= 1e-8,
        "{what}: reproducing {:.2e}",
        r.reproducing_error
    );
    assert_eq!(
        r.monitors.min_moment_rcond,
        Some(r.coverage.min_moment_rcond)
    );
}

/// Largest principal angle between the modes of two runs on the same kernels and points.
fn angle(a: &BasisRun, b: &BasisRun) -> f64 {
    let (sf, stats) = evaluate(
        &a.basis.kernels,
        &a.points.points,
        &ShapeFunctionOptions::default(),
    );
    assert!(stats.failed.is_empty());
    let w = vec![1.0; a.points.len()];
    let assembled = assemble(&sf, &a.points.volumes, &w, a.basis.kernels.len()).unwrap();
    let mass = assembled.mass();
    // M is m^3 (no density): c^T M c = I as computed.
    let (ca, cb) = (&a.basis.coefficients, &b.basis.coefficients);
    let n = ca.ncols();
    // Skip the constant mode (its sign is arbitrary but it is alone in its cluster).
    max_subspace_angle(
        mass,
        &a.basis.eigenvalues[1..],
        &ca.subcols(1, n - 1).to_owned(),
        &b.basis.eigenvalues[1..],
        &cb.subcols(1, n - 1).to_owned(),
        1e-4,
    )
    .unwrap()
}

#[test]
fn poisson_ratio_from_0_to_0_4999_scales_the_spectrum_exactly() {
    // Homogeneous material: H_w = (lambda + 4 mu) L and M = rho M0, so eigenvalues divided
    // by lambda + 4 mu and the modes must not depend on nu, even where lambda / mu = 5000.
    let nus = [0.0, 0.3, 0.45, 0.49, 0.499, 0.4999, -0.5];
    let runs: Vec<BasisRun> = nus
        .iter()
        .map(|&nu| {
            basis(
                "box:2,1,1",
                &opts(150, 8, 6000, rubber(nu), SolverConfig::lobpcg()),
            )
            .unwrap()
        })
        .collect();
    let reference: Vec<f64> = runs[0]
        .report
        .eigenvalues
        .iter()
        .map(|v| v / c_weight(&rubber(0.0)))
        .collect();
    for (nu, run) in nus.iter().zip(&runs) {
        assert_healthy(run, &format!("nu = {nu}"));
        let scaled: Vec<f64> = run
            .report
            .eigenvalues
            .iter()
            .map(|v| v / c_weight(&rubber(*nu)))
            .collect();
        // Relative residual 1e-8 bounds the eigenvalue error by ~1e-16 relative (quadratic)
        // for separated pairs; clusters are looser: 1e-9.
        let d = max_eigenvalue_rel_diff(&reference[1..], &scaled[1..]);
        assert!(d < 1e-9, "nu = {nu}: eigenvalues differ by {d:.2e}");
        // Angles: residual 1e-8 / relative gap ~1e-1 -> 1e-7 rad.
        let a = angle(&runs[0], run);
        assert!(a < 1e-6, "nu = {nu}: modes differ by {a:.2e} rad");
    }
}

#[test]
fn youngs_modulus_from_1e3_to_1e11_scales_eigenvalues_linearly() {
    let base = basis(
        "box:2,1,1",
        &opts(120, 6, 4000, rubber(0.3), SolverConfig::lobpcg()),
    )
    .unwrap();
    for e in [1e3, 1e7, 1e11] {
        let mat = Material {
            youngs: e,
            ..rubber(0.3)
        };
        let run = basis(
            "box:2,1,1",
            &opts(120, 6, 4000, mat, SolverConfig::lobpcg()),
        )
        .unwrap();
        assert_healthy(&run, &format!("E = {e}"));
        for i in 1..7 {
            let predicted = base.report.eigenvalues[i] * e / 1e5;
            // LOBPCG tolerance 1e-8 on the residual: eigenvalues to ~1e-12 relative.
            assert!(
                (run.report.eigenvalues[i] / predicted - 1.0).abs() < 1e-9,
                "E = {e}, {i}"
            );
        }
    }
}

/// Soft box with a stiff ball (or the reverse) at contrast `c`: E_ball = c E_box.
fn inclusion(c: f64, k: usize, solver: SolverConfig, tol: f64) -> BasisRun {
    let mut o = opts(k, 8, 5000, rubber(0.3), solver);
    o.tol = tol;
    o.overrides = vec![MaterialOverride {
        region: Region::Sphere {
            center: [1.0, 0.5, 0.5],
            radius: 0.35,
        },
        material: Material {
            youngs: 1e5 * c,
            ..rubber(0.3)
        },
    }];
    basis("box:2,1,1", &o).unwrap()
}

#[test]
fn material_contrast_up_to_1e6_matches_the_dense_solver() {
    // The relative residual is measured against ||H||, which the stiff part dominates: at a
    // contrast c the soft (low) modes are resolved to about c times less relative accuracy
    // at the same tol. Measured against the dense oracle (eigenvalue difference, largest
    // principal angle): c = 1: 2e-14, 1e-8 rad; c = 1e3: 2e-11, 2e-6 rad; c = 1e6 at
    // tol 1e-8: 2e-7, 1.5e-4 rad; c = 1e6 at tol 1e-10: 6e-11, 1.6e-6 rad; soft inclusions
    // (c = 1e-3, 1e-6) behave like c = 1. Hence docs/limits.md: tol 1e-10 above c = 1e4.
    for (c, tol, max_diff, max_angle) in [
        (1.0, 1e-8, 1e-10, 1e-6),
        (1e3, 1e-8, 1e-9, 1e-5),
        (1e6, 1e-8, 2e-6, 1e-3),
        (1e6, 1e-10, 1e-9, 1e-5),
        (1e-3, 1e-8, 1e-10, 1e-6),
        (1e-6, 1e-8, 1e-10, 1e-6),
    ] {
        let lob = inclusion(c, 150, SolverConfig::lobpcg(), tol);
        let dense = inclusion(c, 150, SolverConfig::Dense, tol);
        assert_healthy(&lob, &format!("contrast {c}"));
        assert_healthy(&dense, &format!("contrast {c}, dense"));
        let d =
            max_eigenvalue_rel_diff(&lob.report.eigenvalues[1..], &dense.report.eigenvalues[1..]);
        let a = angle(&lob, &dense);
        assert!(
            d < max_diff,
            "contrast {c}, tol {tol}: eigenvalues differ by {d:.2e}"
        );
        assert!(
            a < max_angle,
            "contrast {c}, tol {tol}: modes differ by {a:.2e} rad"
        );
    }
}

#[test]
fn a_sharp_interface_at_contrast_1e6_keeps_the_soft_side_moving() {
    // Left half soft, right half 1e6 times stiffer: the low modes live in the soft half.
    let mut o = opts(150, 6, 6000, rubber(0.3), SolverConfig::lobpcg());
    o.overrides = vec![MaterialOverride {
        region: Region::HalfSpace {
            point: [1.0, 0.0, 0.0],
            normal: [1.0, 0.0, 0.0],
        },
        material: Material {
            youngs: 1e11,
            ..rubber(0.3)
        },
    }];
    let run = basis("box:2,1,1", &o).unwrap();
    assert_healthy(&run, "interface");
    let w = run.basis.weights(&run.points.points).unwrap();
    // Share of int |grad W_1|^2 on the stiff side.
    let (mut soft, mut stiff) = (0.0, 0.0);
    for (i, p) in run.points.points.iter().enumerate() {
        let g = w.gradient_row(i)[1];
        let e = run.points.volumes[i] * (g[0] * g[0] + g[1] * g[1] + g[2] * g[2]);
        if p[0] >= 1.0 {
            stiff += e;
        } else {
            soft += e;
        }
    }
    let share = stiff / (soft + stiff);
    eprintln!("stiff-side share of the first mode's gradient energy: {share:.2e}");
    // The first non-constant mode's Rayleigh quotient puts its energy where E is small: a
    // contrast of 1e6 leaves about 1e-6 of it (times the smoothing of the kernels across
    // the interface) on the stiff side.
    assert!(share < 1e-3, "{share}");
    // Continuum limit (rigid right half): u = cos(k x) on the soft half, constant on the
    // rigid one, orthogonal to constants: tan k = -k, k = 2.02876, eigenvalue k^2 (l + 4 mu).
    // The RKPM space is a Ritz subspace, so its eigenvalue is above that; at K = 150 the
    // kernels (support ~0.5 m) cannot bend sharply at the interface and stiffen the mode
    // (measured 1.97 times the limit). The bound says the mode is the soft-half one.
    let limit = 2.028_757_838f64.powi(2) * c_weight(&rubber(0.3));
    let ratio = run.report.eigenvalues[1] / limit;
    eprintln!("first eigenvalue / continuum limit: {ratio:.3}");
    assert!(ratio > 0.999 && ratio < 2.5, "{ratio}");
}

#[test]
fn objects_from_a_millimetre_to_a_kilometre_have_the_same_modes() {
    // Through the whole pipeline (grid, FPS, supports, LOBPCG): eigenvalues scale as L^-2.
    // Scales are powers of two (2^-10 m ~ 1 mm, 2^10 m ~ 1 km) so that the grid and the
    // farthest point sampling see exactly scaled coordinates: FPS breaks distance ties of
    // the grid by rounding, and 1e-3 scaling would break them differently (measured: a
    // different but equally good kernel set, eigenvalues 4e-3 apart).
    let reference = basis(
        "box:2,1,1",
        &opts(120, 6, 4000, rubber(0.3), SolverConfig::lobpcg()),
    )
    .unwrap();
    for s in [2f64.powi(-10), 2f64.powi(10)] {
        let run = basis(
            &format!("box:{},{},{}", 2.0 * s, s, s),
            &opts(120, 6, 4000, rubber(0.3), SolverConfig::lobpcg()),
        )
        .unwrap();
        assert_healthy(&run, &format!("size {s}"));
        assert_eq!(run.points.len(), reference.points.len());
        let scaled: Vec<f64> = run.report.eigenvalues.iter().map(|v| v * s * s).collect();
        let d = max_eigenvalue_rel_diff(&reference.report.eigenvalues[1..], &scaled[1..]);
        assert!(d < 1e-9, "size {s}: {d:.2e}");
        // Centres scale with the object (FPS is scale invariant up to ties broken by
        // rounding; none here).
        for (a, b) in reference
            .basis
            .kernels
            .centers
            .iter()
            .zip(&run.basis.kernels.centers)
        {
            for k in 0..3 {
                assert!(
                    (b[k] / s - a[k]).abs() < 1e-9,
                    "size {s}: centre {a:?} vs {b:?}"
                );
            }
        }
    }
}

#[test]
fn thin_plates_and_rods_reproduce_the_neumann_laplacian_or_say_why_not() {
    // Lowest Neumann Laplacian eigenvalue of a 1 m plate or rod: (pi / 1)^2, the in-plane
    // (along-axis) cosine. The thin direction only adds higher modes.
    for (spec, k, n) in [("box:1,1,0.01", 400, 40_000), ("box:1,0.01,0.01", 80, 8000)] {
        let o = opts(k, 4, n, rubber(0.0), SolverConfig::lobpcg());
        match basis(spec, &o) {
            Ok(run) => {
                assert_healthy(&run, spec);
                let lap = run.report.eigenvalues[1] / c_weight(&rubber(0.0));
                eprintln!("{spec}: first Laplacian eigenvalue {lap:.4} vs pi^2 = {:.4}; rcond {:.1e}; warnings {:?}", PI * PI, run.report.coverage.min_moment_rcond, run.report.warnings);
                // RKPM with a few kernels across the length: within 5% of pi^2.
                assert!((lap / (PI * PI) - 1.0).abs() < 0.05, "{spec}: {lap}");
            }
            Err(e) => {
                let msg = Front::Flags.render(&e);
                eprintln!("{spec}: {msg}");
                assert!(matches!(e, Error::Coverage { .. }), "{spec}: {msg}");
                assert!(
                    msg.contains("--support") && msg.contains("kernels"),
                    "{msg}"
                );
            }
        }
    }
}

#[test]
fn few_and_many_kernels_and_modes() {
    // K = 10 (the fewest that cover a box with linear reproduction at the default support)
    // to m = 64.
    let few = basis(
        "box:2,1,1",
        &opts(10, 3, 3000, rubber(0.3), SolverConfig::lobpcg()),
    );
    match few {
        Ok(run) => assert_healthy(&run, "K = 10"),
        Err(e) => panic!("K = 10: {e}"),
    }
    let one = basis(
        "box:2,1,1",
        &opts(300, 1, 8000, rubber(0.3), SolverConfig::lobpcg()),
    )
    .unwrap();
    assert_healthy(&one, "m = 1");
    let many = basis(
        "box:2,1,1",
        &opts(300, 64, 8000, rubber(0.3), SolverConfig::lobpcg()),
    )
    .unwrap();
    assert_healthy(&many, "m = 64");
    let dense = basis(
        "box:2,1,1",
        &opts(300, 64, 8000, rubber(0.3), SolverConfig::Dense),
    )
    .unwrap();
    // Eigenvalues against the dense oracle at m = 64 (the largest cluster-rich block).
    let d = max_eigenvalue_rel_diff(
        &many.report.eigenvalues[1..],
        &dense.report.eigenvalues[1..],
    );
    assert!(d < 1e-8, "m = 64: {d:.2e}");
    assert!((one.report.eigenvalues[1] / many.report.eigenvalues[1] - 1.0).abs() < 1e-9);
}

fn grid(min: Point3, max: Point3, h: f64) -> Vec<Point3> {
    let n: Vec<usize> = (0..3)
        .map(|k| ((max[k] - min[k]) / h).round() as usize)
        .collect();
    let mut out = Vec::new();
    for i in 0..n[0] {
        for j in 0..n[1] {
            for k in 0..n[2] {
                out.push([
                    min[0] + (i as f64 + 0.5) * h,
                    min[1] + (j as f64 + 0.5) * h,
                    min[2] + (k as f64 + 0.5) * h,
                ]);
            }
        }
    }
    out
}

fn from_points(points: Vec<Point3>, volumes: Vec<f64>, k: usize) -> Result<BasisRun, Error> {
    let ip = IntegrationPoints { points, volumes };
    let mat = MaterialField::homogeneous(ip.len(), &rubber(0.3)).unwrap();
    let o = BasisOptions {
        resolution: None,
        ..opts(k, 6, k, rubber(0.3), SolverConfig::lobpcg())
    };
    Problem::from_points(ip, mat, &o, &Silent)?.solve(&Silent)
}

#[test]
fn duplicated_points_change_nothing() {
    let p = grid([0.0; 3], [2.0, 1.0, 1.0], 0.1);
    let v = vec![1e-3; p.len()];
    let single = from_points(p.clone(), v.clone(), 120).unwrap();
    // Every point twice with half its volume.
    let mut p2 = p.clone();
    p2.extend(p.iter().copied());
    let v2 = vec![0.5e-3; p2.len()];
    // On the same kernels H_w and M are exactly the same matrices (up to summation order).
    let k = &single.basis.kernels;
    let w1 = vec![1.0; p.len()];
    let w2 = vec![1.0; p2.len()];
    let (sf1, _) = evaluate(k, &p, &ShapeFunctionOptions::default());
    let (sf2, _) = evaluate(k, &p2, &ShapeFunctionOptions::default());
    let a1 = assemble(&sf1, &v, &w1, k.len()).unwrap();
    let a2 = assemble(&sf2, &v2, &w2, k.len()).unwrap();
    for (x, y) in [(a1.hessian(), a2.hessian()), (a1.mass(), a2.mass())] {
        let (dx, dy) = (to_dense(x.as_ref()), to_dense(y.as_ref()));
        let scale = dx.norm_max();
        assert!((&dx - &dy).norm_max() <= 1e-13 * scale);
    }
    // Through the pipeline: farthest point sampling never picks a duplicate twice (that
    // would make two kernels identical and M singular), and the spectrum is that of the
    // single set up to the choice of kernels (FPS breaks ties by index, and the duplicates
    // shift indices): 1%.
    let double = from_points(p2, v2, 120).unwrap();
    assert_healthy(&double, "duplicates");
    let c = &double.basis.kernels.centers;
    for i in 0..c.len() {
        for j in 0..i {
            assert!(c[i] != c[j], "kernels {i} and {j} share a centre");
        }
    }
    let d = max_eigenvalue_rel_diff(
        &single.report.eigenvalues[1..],
        &double.report.eigenvalues[1..],
    );
    assert!(d < 1e-2, "duplicates: {d:.2e}");
}

#[test]
fn huge_density_variation_keeps_the_volume_and_the_spectrum() {
    // Left half sampled 64 times denser (spacing 0.025 vs 0.1), each point carrying its cell
    // volume: the same object, so the same Laplacian spectrum up to discretization.
    let mut p = grid([0.0; 3], [1.0, 1.0, 1.0], 0.025);
    let mut v = vec![0.025f64.powi(3); p.len()];
    let coarse = grid([1.0, 0.0, 0.0], [2.0, 1.0, 1.0], 0.1);
    v.extend(std::iter::repeat_n(1e-3, coarse.len()));
    p.extend(coarse);
    let run = from_points(p, v, 150).unwrap();
    assert_healthy(&run, "density variation");
    // 65,000 summed volumes: round-off 1e-12.
    assert!(
        (run.report.volume - 2.0).abs() < 1e-10,
        "{}",
        run.report.volume
    );
    let uniform = from_points(
        grid([0.0; 3], [2.0, 1.0, 1.0], 0.05),
        vec![0.05f64.powi(3); 16_000],
        150,
    )
    .unwrap();
    let a = run.report.eigenvalues[1];
    let b = uniform.report.eigenvalues[1];
    eprintln!("density variation: first eigenvalue {a:.4e} vs uniform {b:.4e}");
    // The Neumann Laplacian of the 2:1:1 box: (pi / 2)^2 (l + 4 mu) / rho; both within 5%.
    let exact = (PI / 2.0).powi(2) * c_weight(&rubber(0.3));
    assert!((a / exact - 1.0).abs() < 0.05, "{a} vs {exact}");
    assert!((b / exact - 1.0).abs() < 0.05, "{b} vs {exact}");
}

#[test]
fn nearly_coplanar_points_are_an_error_that_names_the_place() {
    // A slab whose points all lie within 1e-9 m of the plane z = 0: the moment matrices are
    // singular in z. The pipeline must say so, not return garbage.
    let mut rng = SplitMix64::new(7);
    let p: Vec<Point3> = (0..3000)
        .map(|_| [rng.next_f64(), rng.next_f64(), 1e-9 * rng.next_f64()])
        .collect();
    let v = vec![1e-3 / 3000.0; p.len()];
    let err = from_points(p, v, 60).unwrap_err();
    let msg = Front::Flags.render(&err);
    assert!(matches!(err, Error::Coverage { .. }), "{msg}");
    assert!(
        msg.contains("position") && msg.contains("--support"),
        "{msg}"
    );
}

// ---------------------------------------------------------------- simulation extremes

fn bar_basis(mat: Material, modes: usize) -> BasisRun {
    basis(
        "box:1,0.2,0.2",
        &opts(60, modes, 3000, mat, SolverConfig::Dense),
    )
    .unwrap()
}

/// Every step: finite state, energy never above the predictor's, no accepted iteration that
/// raised the energy beyond its rounding level, and non-convergence reported.
fn assert_step_sane(rep: &SolveReport, cap: usize, what: &str) {
    assert!(
        rep.energy.is_finite() && rep.initial_energy.is_finite(),
        "{what}: {rep:?}"
    );
    let noise = 1e-9 * rep.initial_energy.abs().max(rep.energy.abs()) + 1e-300;
    assert!(
        rep.energy <= rep.initial_energy + noise,
        "{what}: energy rose {rep:?}"
    );
    assert!(
        rep.max_energy_rise <= noise,
        "{what}: an iteration raised the energy {rep:?}"
    );
    assert!(
        rep.converged || rep.iterations == cap || rep.line_search_failed,
        "{what}: {rep:?}"
    );
}

fn static_tip(run: &BasisRun, gravity: f64, strategy: HessianStrategy) -> (f64, SolveReport) {
    let o = SimOptions {
        // h = 1e6 s: the inertia term rho / h^2 is 1e-9 Pa / m^2, far below E / D^2 even
        // for E = 1e3 Pa; this step is the static solve.
        dt: 1e6,
        gravity: Some([0.0, -gravity, 0.0]),
        cubature: 1500,
        boundaries: vec![held_left()],
        newton: NewtonOptions {
            hessian: strategy,
            tol: 1e-9,
            max_iter: 200,
            ..NewtonOptions::default()
        },
        ..SimOptions::default()
    };
    let mut s = ReducedSim::new(&run.basis, &run.points, &run.material, &o).unwrap();
    let rep = s.step();
    let tip = [[1.0, 0.1, 0.1]];
    let w = run.basis.weights(&tip).unwrap();
    (s.positions(&tip, &w)[0][1] - 0.1, rep.solve)
}

#[test]
fn static_sag_is_invariant_when_load_and_modulus_scale_together() {
    // Elastic energy and the default penalty scale with E; gravity scaled with E leaves the
    // static minimiser unchanged. From 1e3 to 1e11 Pa the tip must agree to the Newton
    // tolerance (1e-9 of the bar's diagonal ~ 1e-9 m), i.e. 1e-6 relative of a ~2 mm sag.
    let mut tips = Vec::new();
    for e in [1e3, 1e5, 1e8, 1e11] {
        let mat = Material {
            youngs: e,
            ..rubber(0.3)
        };
        let run = bar_basis(mat, 6);
        let (tip, rep) = static_tip(&run, 0.1 * e / 1e5, HessianStrategy::Newton);
        assert_step_sane(&rep, 200, &format!("E = {e}"));
        assert!(rep.converged, "E = {e}: {rep:?}");
        tips.push(tip);
    }
    eprintln!("tips {tips:?}");
    for t in &tips {
        assert!((t / tips[0] - 1.0).abs() < 1e-5, "{tips:?}");
    }
}

#[test]
fn nearly_incompressible_bar_converges_and_keeps_its_volume() {
    for nu in [0.45, 0.49, 0.499, 0.4999] {
        let run = bar_basis(rubber(nu), 6);
        for strategy in [HessianStrategy::Newton, HessianStrategy::Lbfgs] {
            let (tip, rep) = static_tip(&run, 0.5, strategy);
            assert_step_sane(&rep, 200, &format!("nu = {nu}, {strategy:?}"));
            assert!(rep.converged, "nu = {nu}, {strategy:?}: {rep:?}");
            eprintln!(
                "nu = {nu} {strategy:?}: tip {tip:.4e}, iterations {}, min det {:.4}",
                rep.iterations, rep.info.min_det
            );
            // A sag of centimetres bends, it does not compress: det F stays within 2% of 1
            // (the volumetric stiffness lambda is >= 10 mu here).
            assert!(rep.info.min_det > 0.98, "nu = {nu}: {:?}", rep.info);
        }
    }
}

#[test]
fn time_steps_from_1e_4_to_0_1_s_stay_finite_and_converge() {
    let run = bar_basis(rubber(0.4), 6);
    for dt in [1e-4, 1e-3, 1e-2, 1e-1] {
        let o = SimOptions {
            dt,
            gravity: Some([0.0, -9.81, 0.0]),
            cubature: 1000,
            boundaries: vec![held_left()],
            ..SimOptions::default()
        };
        let mut s = ReducedSim::new(&run.basis, &run.points, &run.material, &o).unwrap();
        for _ in 0..5 {
            let rep = s.step();
            assert_step_sane(&rep.solve, o.newton.max_iter, &format!("dt = {dt}"));
            assert!(rep.solve.converged, "dt = {dt}: {:?}", rep.solve);
        }
        assert!(s.z().iter().chain(s.zdot()).all(|v| v.is_finite()));
    }
}

#[test]
fn huge_penalties_and_violent_twists_never_give_a_nan_state() {
    let run = bar_basis(rubber(0.4), 8);
    let twist = Boundary {
        region: Region::HalfSpace {
            point: [0.9, 0.0, 0.0],
            normal: [1.0, 0.0, 0.0],
        },
        motion: Motion::Rotate {
            pivot: [0.0, 0.1, 0.1],
            axis: [1.0, 0.0, 0.0],
            degrees_per_second: 3600.0,
        },
        // 1e6 times the default (~1e11 for this bar): the penalty dominates everything.
        stiffness: Some(1e17),
    };
    let mut held = held_left();
    held.stiffness = Some(1e17);
    let o = SimOptions {
        dt: 0.05, // 180 degrees per step, 720 in all
        gravity: Some([0.0, -9.81, 0.0]),
        cubature: 800,
        boundaries: vec![held, twist],
        newton: NewtonOptions {
            max_iter: 40,
            ..NewtonOptions::default()
        },
        ..SimOptions::default()
    };
    for strategy in [
        HessianStrategy::Newton,
        HessianStrategy::Lbfgs,
        HessianStrategy::Fixed,
    ] {
        let mut oo = o.clone();
        oo.newton.hessian = strategy;
        let mut s = ReducedSim::new(&run.basis, &run.points, &run.material, &oo).unwrap();
        for _ in 0..4 {
            let rep = s.step();
            assert_step_sane(&rep.solve, 40, &format!("{strategy:?}"));
            eprintln!(
                "{strategy:?}: converged {}, iterations {}, min det {:.3}, inverted {}",
                rep.solve.converged,
                rep.solve.iterations,
                rep.solve.info.min_det,
                rep.solve.info.inverted
            );
        }
        assert!(
            s.z().iter().chain(s.zdot()).all(|v| v.is_finite()),
            "{strategy:?}"
        );
    }
}

#[test]
fn inverted_cubature_points_are_pulled_back_or_reported() {
    // Start from a state crushed through itself: a huge initial velocity that maps the bar
    // to its mirror image in one step (det F < 0 everywhere at the predictor).
    let run = bar_basis(rubber(0.3), 4);
    let o = SimOptions {
        dt: 1e-2,
        cubature: 800,
        newton: NewtonOptions {
            hessian: HessianStrategy::Newton,
            max_iter: 100,
            ..NewtonOptions::default()
        },
        ..SimOptions::default()
    };
    let mut s = ReducedSim::new(&run.basis, &run.points, &run.material, &o).unwrap();
    // The constant mode's affine block: x = X + A X; A = -2 e_y e_y^T mirrors y.
    let l = s.layout();
    let mut z = s.z().to_vec();
    z[l.index(1, 0, 1)] = -2.0 / common_constant(&run);
    let zdot = s.zdot().to_vec();
    s.set_state(&z, &zdot).unwrap();
    let mut first = None;
    for k in 0..10 {
        let rep = s.step();
        if k == 0 {
            first = Some(rep.solve);
        }
        assert_step_sane(&rep.solve, 100, &format!("step {k}"));
    }
    let first = first.unwrap();
    eprintln!("inverted start: first step {:?}", first);
    assert!(first.initial_energy.is_finite());
    assert!(s.z().iter().chain(s.zdot()).all(|v| v.is_finite()));
}

/// Value of the constant mode's weight (W_0 = 1 / sqrt(total mass)).
fn common_constant(run: &BasisRun) -> f64 {
    let w = run.basis.weights(&run.points.points[..1]).unwrap();
    w.row(0)[0]
}
