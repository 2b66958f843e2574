//! FEM reference: derivatives against finite differences, patch test, cantilever against
//! beam theory, rigid-motion invariance, mesh readers, voxel mesher, error metric, beam cache.

use freeform::derivatives::{check_derivatives, Floors};
use freeform::fem::readers::{gmsh, medit, read_tet_mesh, tetgen};
use freeform::fem::{
    fe_nodes, nested_difference, run_beam_reference, trajectory_error, voxel_tet_mesh, BeamTest,
    CacheStatus, ElementOrder, FemBeamConfig, FemError, FemParams, FemSolver, HessianMode,
    PlanePenalty, TetMaterials, TetMesh,
};
use freeform::geometry::{generate, ShapeOptions, TriMesh};
use freeform::material::Material;
use freeform::progress::Silent;
use freeform::random::SplitMix64;
use freeform::Point3;
use std::path::Path;

/// Deterministic numbers in [-1, 1) from the library's generator (these tests moved to it
/// from their own xorshift: other perturbations of the same size, the same checks).
fn signed(rng: &mut SplitMix64) -> f64 {
    rng.uniform(-1.0, 1.0)
}

fn rubber() -> Material {
    Material::default()
}

fn perturbed(rest: &[Point3], amp: f64, seed: u64) -> Vec<Point3> {
    let mut rng = SplitMix64::new(seed);
    rest.iter()
        .map(|p| p.map(|c| c + amp * signed(&mut rng)))
        .collect()
}

fn data(name: &str) -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data/fem")
        .join(name)
}

// ---------------------------------------------------------------- derivatives

#[test]
fn energy_gradient_and_hessian_match_finite_differences() {
    for order in [ElementOrder::Linear, ElementOrder::Quadratic] {
        derivatives_match_finite_differences(order);
    }
}

fn derivatives_match_finite_differences(order: ElementOrder) {
    let mesh = TetMesh::structured_box([0.0; 3], [2.0, 1.0, 1.0], [2, 1, 1]).unwrap();
    let mats = TetMaterials::homogeneous(&mesh, &rubber()).unwrap();
    // A floor that the perturbed nodes at y ~ 0 penetrate (by 0.05-0.25 m, away from the
    // penalty's kink at zero depth), gravity on, exact Hessian (no PSD projection).
    let params = FemParams {
        hessian: HessianMode::Exact,
        order,
        plane: Some(PlanePenalty {
            normal: [0.0, 2.0, 0.0],
            offset: 0.15,
            stiffness: 1e8,
        }),
        ..FemParams::default()
    };
    let fixed = [0usize];
    let solver = FemSolver::new(&mesh, &mats, &fixed, params).unwrap();
    let rest = solver.rest_positions().to_vec();
    let x = perturbed(&rest, 0.1, 7);
    let x_pred = perturbed(&rest, 0.05, 11);
    // `incremental_hessian` assembles into the solver's own buffers (`&mut`).
    let solver = std::cell::RefCell::new(solver);
    let free_dof = |node: usize, axis: usize| solver.borrow().free_dof(node, axis);
    // Every coordinate as z (node-major), and the free ones (the Hessian's rows and columns).
    let z_all: Vec<f64> = x.iter().flatten().copied().collect();
    let free: Vec<usize> = (0..z_all.len())
        .filter(|&i| free_dof(i / 3, i % 3).is_some())
        .collect();
    // The free DoFs in the Hessian's order: free_dof numbers them in node-major order.
    for (k, &i) in free.iter().enumerate() {
        assert_eq!(free_dof(i / 3, i % 3), Some(k));
    }
    let nodes =
        |z: &[f64]| -> Vec<Point3> { z.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect() };
    let with_free = |zf: &[f64]| -> Vec<f64> {
        let mut z = z_all.clone();
        for (&i, v) in free.iter().zip(zf) {
            z[i] = *v;
        }
        z
    };
    let unit = |n: usize| -> Vec<Vec<f64>> {
        (0..n)
            .map(|i| (0..n).map(|j| f64::from(u8::from(i == j))).collect())
            .collect()
    };
    let energy = |z: &[f64], g: &mut [f64]| {
        let x = nodes(z);
        for (gi, v) in g
            .chunks_exact_mut(3)
            .zip(solver.borrow().incremental_gradient(&x, &x_pred))
        {
            gi.copy_from_slice(&v);
        }
        solver.borrow().incremental_potential(&x, &x_pred)
    };
    // Central differences with step 1e-6 m: truncation ~ h^2 E''' ~ 1e-12 x (stiffness
    // 2e7 Pa x 1 m^3 / m^3) and round-off ~ eps |E| / h ~ 1e-16 x 1e6 / 1e-6 = 1e-4 N; the
    // gradient entries are ~1e6 N, so 1e-6 relative to the largest entry is safe and would
    // catch any wrong term (the smallest term, gravity, is ~1e3 N). Every coordinate (the
    // fixed node's too), as before; the shared checker's floor gmax makes its relative
    // error |fd - g_i| / max(|g_i|, |fd|, gmax) the old |fd - g_i| / gmax.
    let g = solver.borrow().incremental_gradient(&x, &x_pred);
    let gmax = g.iter().flatten().fold(0.0f64, |m, v| m.max(v.abs()));
    let h = 1e-6;
    let check = check_derivatives(
        energy,
        None,
        &z_all,
        &unit(z_all.len()),
        h,
        Floors::both(gmax),
    );
    assert!(check.gradient < 1e-6, "{order:?}: {check:?}");
    // Hessian (free DoFs) against differences of the gradient. The gradient is smooth here
    // (no node crosses the floor within h), error ~ h^2 |E''''| + eps |g| / h ~ 1e-16 x 1e6 /
    // 1e-6 = 1e-4 N/m against entries ~1e8 N/m. The old test bounded each entry by 1e-6 x
    // the largest entry hmax; the shared checker bounds each column's error norm by its bound
    // x max(|H e_j|, hmax) (floor hmax), and |H e_j| <= sqrt(n) hmax for n free DoFs, so the
    // bound 1e-6 / sqrt(n) keeps every entry within the old one (measured: below 2e-10).
    let free_energy = |zf: &[f64], gf: &mut [f64]| {
        let z = with_free(zf);
        let mut g = vec![0.0; z.len()];
        let e = energy(&z, &mut g);
        for (gi, &i) in gf.iter_mut().zip(&free) {
            *gi = g[i];
        }
        e
    };
    let hessian = |zf: &[f64]| {
        let mut dense = faer::Mat::<f64>::zeros(free.len(), free.len());
        let trip = solver
            .borrow_mut()
            .incremental_hessian(&nodes(&with_free(zf)));
        for (i, j, v) in trip {
            assert!(i >= j);
            dense[(i, j)] += v;
            if i != j {
                dense[(j, i)] += v;
            }
        }
        dense
    };
    let trip = solver.borrow_mut().incremental_hessian(&x);
    let hmax = trip.iter().fold(0.0f64, |m, t| m.max(t.2.abs()));
    let z_free: Vec<f64> = free.iter().map(|&i| z_all[i]).collect();
    let check = check_derivatives(
        free_energy,
        Some(&hessian),
        &z_free,
        &unit(free.len()),
        h,
        Floors::both(hmax),
    );
    let bound = 1e-6 / (free.len() as f64).sqrt();
    assert!(check.hessian < bound, "{order:?}: {check:?}");
    // Fixed node 0 has no free DoF.
    assert!(free_dof(0, 0).is_none());
}

#[test]
fn projected_hessian_is_positive_semidefinite_far_from_rest() {
    let mesh = TetMesh::structured_box([0.0; 3], [1.0; 3], [1, 1, 1]).unwrap();
    let mats = TetMaterials::homogeneous(&mesh, &rubber()).unwrap();
    // Static-like system: inertia is tiny with a huge dt, so the matrix is the stiffness.
    let params = FemParams {
        dt: 1e6,
        hessian: HessianMode::Projected,
        ..FemParams::default()
    };
    let mut solver = FemSolver::new(&mesh, &mats, &[], params).unwrap();
    // Large random motion: many elements strongly compressed or inverted.
    let x = perturbed(mesh.nodes(), 0.8, 3);
    let n = 3 * x.len();
    let mut a = faer::Mat::<f64>::zeros(n, n);
    let mut amax = 0.0f64;
    for (i, j, v) in solver.incremental_hessian(&x) {
        a[(i, j)] += v;
        amax = amax.max(v.abs());
    }
    let ev = a.self_adjoint_eigenvalues(faer::Side::Lower).unwrap();
    // PSD up to round-off of the eigensolver (~1e-14 relative); 1e-10 leaves room.
    assert!(ev[0] > -1e-10 * amax, "smallest eigenvalue {:e}", ev[0]);
}

// ---------------------------------------------------------------- patch test

#[test]
fn patch_test_reproduces_homogeneous_deformation() {
    for order in [ElementOrder::Linear, ElementOrder::Quadratic] {
        patch_test(order);
    }
}

fn patch_test(order: ElementOrder) {
    // 3 x 3 x 3 cells with jiggled interior nodes (irregular tets); the boundary nodes follow
    // x = A X + b; the interior must follow it too, for a finite (non-small) A.
    let mesh0 = TetMesh::structured_box([0.0; 3], [1.0; 3], [3, 3, 3]).unwrap();
    let mut rng = SplitMix64::new(5);
    let boundary = |p: &Point3| {
        p.iter()
            .any(|&c| c.abs() < 1e-12 || (c - 1.0).abs() < 1e-12)
    };
    let nodes: Vec<Point3> = mesh0
        .nodes()
        .iter()
        .map(|p| {
            if boundary(p) {
                *p
            } else {
                p.map(|c| c + 0.08 * signed(&mut rng))
            }
        })
        .collect();
    let mesh = TetMesh::new(nodes, mesh0.tets().to_vec()).unwrap();
    let mats = TetMaterials::homogeneous(&mesh, &rubber()).unwrap();
    let (fe, _) = fe_nodes(&mesh, order);
    let fixed: Vec<usize> = (0..fe.len()).filter(|&i| boundary(&fe[i])).collect();
    let params = FemParams {
        gravity: [0.0; 3],
        tolerance: 1e-12,
        order,
        ..FemParams::default()
    };
    let mut solver = FemSolver::new(&mesh, &mats, &fixed, params).unwrap();
    // Stretch, shear and a rotation; det A > 0.
    let a = [[1.2, 0.3, 0.0], [-0.2, 0.9, 0.1], [0.05, 0.0, 1.1]];
    let b = [0.3, -0.1, 0.2];
    let map = |p: &Point3| [0, 1, 2].map(|r| b[r] + (0..3).map(|c| a[r][c] * p[c]).sum::<f64>());
    let targets: Vec<Point3> = solver.fixed_nodes().iter().map(|&i| map(&fe[i])).collect();
    solver.set_targets(&targets).unwrap();
    let info = solver.solve_static().unwrap();
    // Newton converged to 1e-12 x D; the exact answer is a minimiser with a well-conditioned
    // Hessian, so the position error is at that level (1e-10 leaves room for round-off of
    // the stiffness ~1e7 Pa in the residual).
    assert_eq!(solver.positions().len(), fe.len());
    for (p, x) in fe.iter().zip(solver.positions()) {
        let want = map(p);
        for r in 0..3 {
            assert!(
                (x[r] - want[r]).abs() < 1e-10,
                "{x:?} vs {want:?} ({info:?})"
            );
        }
    }
}

// ---------------------------------------------------------------- cantilever

/// Static tip deflection of a clamped beam [0, L] x [0, 1] x [0, 1] under its own weight.
fn cantilever_tip(cells_per_m: usize, length: f64, e: f64, rho_g: f64, order: ElementOrder) -> f64 {
    let cells = [(length as usize) * cells_per_m, cells_per_m, cells_per_m];
    let mesh = TetMesh::structured_box([0.0; 3], [length, 1.0, 1.0], cells).unwrap();
    let mat = Material {
        youngs: e,
        poisson: 0.0,
        density: rho_g / 9.81,
    };
    let mats = TetMaterials::homogeneous(&mesh, &mat).unwrap();
    let (fe, _) = fe_nodes(&mesh, order);
    let fixed: Vec<usize> = (0..fe.len()).filter(|&i| fe[i][0] < 1e-9).collect();
    let params = FemParams {
        order,
        ..FemParams::default()
    };
    let mut solver = FemSolver::new(&mesh, &mats, &fixed, params).unwrap();
    solver.solve_static().unwrap();
    // Mean vertical displacement of the tip face's corner nodes.
    let tip = mesh.select_nodes(|p| (p[0] - length).abs() < 1e-9);
    tip.iter()
        .map(|&i| fe[i][1] - solver.positions()[i][1])
        .sum::<f64>()
        / tip.len() as f64
}

#[test]
fn cantilever_matches_beam_theory() {
    // L = 10 m, 1 m x 1 m section, E = 1e7 Pa, nu = 0, weight q = rho g A = 10 N/m:
    // Euler-Bernoulli tip deflection w = q L^4 / (8 E I), I = 1/12 m^4: 1.5e-2 m (1.5e-3 L,
    // so geometric nonlinearity is ~1e-6 relative). Timoshenko's shear term adds
    // q L^2 / (2 k G A) with k = 5/6, G = E / 2: w_T = w_EB (1 + 0.008).
    let (len, e, q): (f64, f64, f64) = (10.0, 1e7, 10.0);
    let w_eb = q * len.powi(4) / (8.0 * e / 12.0);
    let w_t = w_eb + q * len * len / (2.0 * (5.0 / 6.0) * (e / 2.0));
    let coarse = cantilever_tip(4, len, e, q, ElementOrder::Linear);
    let fine = cantilever_tip(8, len, e, q, ElementOrder::Linear);
    let q1 = cantilever_tip(1, len, e, q, ElementOrder::Quadratic);
    let q2 = cantilever_tip(2, len, e, q, ElementOrder::Quadratic);
    eprintln!(
        "quadratic: r=1 {:+.4}, r=2 {:+.4}",
        (q1 - w_t) / w_t,
        (q2 - w_t) / w_t
    );
    // Linear tets are too stiff in bending (shear locking), so the error is one-sided and
    // falls as O(h^2): measured -17.5% at 4 cells per metre, -5.1% at 8 (ratio 3.4). The
    // test asks for: within 7% at r = 8; a ratio > 3 (observed order > 1.58); and the
    // Richardson extrapolation with order 2, w8 + (w8 - w4) / 3, within 2% of Timoshenko
    // (measured -1.0%; the rest is higher-order terms and the 3D clamp).
    let (ec, ef) = ((coarse - w_t) / w_t, (fine - w_t) / w_t);
    let extrapolated = fine + (fine - coarse) / 3.0;
    let ee = (extrapolated - w_t) / w_t;
    let msg = format!(
        "w_T {w_t:e}, r=4: {coarse:e} ({ec:+.4}), r=8: {fine:e} ({ef:+.4}), \
         extrapolated {extrapolated:e} ({ee:+.4})"
    );
    eprintln!("cantilever: {msg}");
    assert!(ef.abs() < 0.07, "{msg}");
    assert!(ec.abs() > 3.0 * ef.abs(), "{msg}");
    assert!(ee.abs() < 0.02, "{msg}");
    // Quadratic tets do not lock: measured -0.12% with one cube through the thickness and
    // -0.00% with two. Timoshenko theory itself is good to a fraction of a percent at
    // L/h = 10, so: within 1% at r = 1 and 0.5% at r = 2.
    let (e1, e2) = ((q1 - w_t) / w_t, (q2 - w_t) / w_t);
    assert!(
        e1.abs() < 0.01 && e2.abs() < 0.005,
        "quadratic: {e1:+.4}, {e2:+.4}"
    );
    assert!(
        fine < w_t * 1.01,
        "FEM must not be softer than beam theory: {msg}"
    );
}

// ---------------------------------------------------------------- rigid motion

fn rotation(axis: Point3, angle: f64) -> [[f64; 3]; 3] {
    let n = (axis[0] * axis[0] + axis[1] * axis[1] + axis[2] * axis[2]).sqrt();
    let [x, y, z] = axis.map(|c| c / n);
    let (s, c) = angle.sin_cos();
    let t = 1.0 - c;
    [
        [c + x * x * t, x * y * t - z * s, x * z * t + y * s],
        [y * x * t + z * s, c + y * y * t, y * z * t - x * s],
        [z * x * t - y * s, z * y * t + x * s, c + z * z * t],
    ]
}

fn apply_rigid(r: &[[f64; 3]; 3], t: Point3, p: &Point3) -> Point3 {
    [0, 1, 2].map(|i| t[i] + (0..3).map(|j| r[i][j] * p[j]).sum::<f64>())
}

#[test]
fn elastic_energy_and_forces_are_rigid_motion_invariant() {
    let mesh = TetMesh::structured_box([0.0; 3], [2.0, 1.0, 1.0], [2, 2, 2]).unwrap();
    let mats = TetMaterials::homogeneous(&mesh, &rubber()).unwrap();
    let params = FemParams {
        gravity: [0.0; 3],
        ..FemParams::default()
    };
    let solver = FemSolver::new(&mesh, &mats, &[], params).unwrap();
    let el = solver.elements();
    let x = perturbed(mesh.nodes(), 0.15, 9);
    let r = rotation([1.0, -2.0, 0.5], 2.1);
    let t = [3.0, -1.0, 7.0];
    let y: Vec<Point3> = x.iter().map(|p| apply_rigid(&r, t, p)).collect();
    let (ex, ey) = (el.energy(&x), el.energy(&y));
    // Psi depends on F^T F and det F only: equal up to round-off (~1e-13 relative).
    assert!((ex - ey).abs() < 1e-10 * ex, "{ex} vs {ey}");
    let mut gx = vec![[0.0; 3]; x.len()];
    let mut gy = gx.clone();
    el.add_gradient(&x, &mut gx);
    el.add_gradient(&y, &mut gy);
    let gmax = gx.iter().flatten().fold(0.0f64, |m, v| m.max(v.abs()));
    for (a, b) in gx.iter().zip(&gy) {
        let ra = apply_rigid(&r, [0.0; 3], a);
        for k in 0..3 {
            assert!((ra[k] - b[k]).abs() < 1e-10 * gmax, "{ra:?} vs {b:?}");
        }
    }
    // At rest the energy and forces vanish.
    let mut g0 = vec![[0.0; 3]; x.len()];
    el.add_gradient(mesh.nodes(), &mut g0);
    assert!(el.energy(mesh.nodes()).abs() < 1e-6);
    assert!(g0.iter().flatten().all(|v| v.abs() < 1e-6));
}

#[test]
fn rigidly_moved_body_stays_rigid_in_a_step() {
    // A free body (no Dirichlet nodes, no gravity), rigidly rotated and moving with a
    // uniform velocity: backward Euler keeps it undeformed and moves it by h v exactly
    // (the elastic forces vanish on a rigid configuration, so x_pred is the minimiser).
    let mesh = TetMesh::structured_box([0.0; 3], [2.0, 1.0, 1.0], [2, 1, 1]).unwrap();
    let mats = TetMaterials::homogeneous(&mesh, &rubber()).unwrap();
    let params = FemParams {
        gravity: [0.0; 3],
        ..FemParams::default()
    };
    let mut solver = FemSolver::new(&mesh, &mats, &[], params).unwrap();
    let r = rotation([0.3, 1.0, -0.2], 0.7);
    let x0: Vec<Point3> = mesh
        .nodes()
        .iter()
        .map(|p| apply_rigid(&r, [1.0, 2.0, 3.0], p))
        .collect();
    let v0 = vec![[0.5, -1.0, 2.0]; x0.len()];
    solver.set_state(&x0, &v0).unwrap();
    for _ in 0..3 {
        solver.step().unwrap();
    }
    for (a, x) in solver.positions().iter().enumerate() {
        for k in 0..3 {
            let want = x0[a][k] + 0.03 * v0[a][k];
            // x_pred is the exact minimiser, so Newton stops after one update of round-off
            // size (far below the 1e-6 D tolerance).
            assert!((x[k] - want).abs() < 1e-9, "node {a}: {x:?}");
        }
    }
}

// ---------------------------------------------------------------- dynamics sanity

#[test]
fn floor_penalty_stops_a_falling_cube() {
    // A cube dropped from 0.05 m above the floor y = 0 settles on it: after 1 s, the lowest
    // node penetrates less than m g / (V_a kappa) ~ rho g h / kappa = a few 1e-4 m with
    // kappa = 1e9 Pa/m^2 (lumped node volume V_a, mass ratio m_a / V_a = rho).
    let mesh = TetMesh::structured_box([0.0, 0.05, 0.0], [0.5, 0.55, 0.5], [2, 2, 2]).unwrap();
    let mats = TetMaterials::homogeneous(&mesh, &rubber()).unwrap();
    let params = FemParams {
        plane: Some(PlanePenalty {
            normal: [0.0, 1.0, 0.0],
            offset: 0.0,
            stiffness: 1e9,
        }),
        ..FemParams::default()
    };
    let mut solver = FemSolver::new(&mesh, &mats, &[], params).unwrap();
    for _ in 0..100 {
        solver.step().unwrap();
    }
    let ymin = solver
        .positions()
        .iter()
        .map(|p| p[1])
        .fold(f64::INFINITY, f64::min);
    let ymax = solver
        .positions()
        .iter()
        .map(|p| p[1])
        .fold(f64::NEG_INFINITY, f64::max);
    assert!(ymin > -2e-3 && ymin < 1e-3, "lowest node at {ymin}");
    assert!(ymax > 0.45 && ymax < 0.51, "top at {ymax}");
}

#[test]
fn static_solve_without_supports_reports_factorization_failure() {
    let mesh = TetMesh::structured_box([0.0; 3], [1.0; 3], [1, 1, 1]).unwrap();
    let mats = TetMaterials::homogeneous(&mesh, &rubber()).unwrap();
    let mut solver = FemSolver::new(&mesh, &mats, &[], FemParams::default()).unwrap();
    // No held node: rigid motions are free, the stiffness is singular.
    let err = solver.solve_static().unwrap_err();
    assert!(matches!(err, FemError::Factorization(_)), "{err}");
    assert!(solver.positions().iter().flatten().all(|c| c.is_finite()));
}

// ---------------------------------------------------------------- readers

fn check_cube(mesh: &TetMesh) {
    assert_eq!(mesh.num_nodes(), 8, "unused nodes are dropped");
    assert_eq!(mesh.num_tets(), 6);
    assert!((mesh.volume() - 1.0).abs() < 1e-14);
}

#[test]
fn readers_load_the_unit_cube() {
    let tg = tetgen::read(&data("cube.node"), &data("cube.ele")).unwrap();
    check_cube(&tg);
    // Half of the Kuhn tets as listed are negatively oriented.
    assert_eq!(tg.flipped_tets(), 3);
    check_cube(&gmsh::read(&data("cube.msh")).unwrap());
    check_cube(&medit::read(&data("cube.mesh")).unwrap());
    check_cube(&read_tet_mesh(&data("cube.ele")).unwrap());
    // Same mesh from every reader.
    assert_eq!(
        gmsh::read(&data("cube.msh")).unwrap(),
        medit::read(&data("cube.mesh")).unwrap()
    );
}

fn parse_error_line(e: FemError) -> usize {
    match e {
        FemError::Parse { line, .. } => line,
        other => panic!("expected a parse error, got {other}"),
    }
}

#[test]
fn readers_report_line_numbers() {
    let p = Path::new("x");
    let node = "# c\n2 3 0 0\n1 0 0 0\n2 1 0 zero\n";
    let e = tetgen::parse(node, p, "1 4 0\n1 1 2 3 4\n", p).unwrap_err();
    assert_eq!(parse_error_line(e), 4);
    let node = "4 3 0 0\n1 0 0 0\n2 1 0 0\n3 0 1 0\n4 0 0 1\n";
    let e = tetgen::parse(node, p, "1 4 0\n1 1 2 3 9\n", p).unwrap_err();
    assert_eq!(parse_error_line(e), 2);
    assert!(tetgen::parse(node, p, "1 4 0\n1 1 2 3 4\n", p).is_ok());
    let e = gmsh::parse("$MeshFormat\n2.2 0 8\n$EndMeshFormat\n", p).unwrap_err();
    assert_eq!(parse_error_line(e), 2);
    let e = medit::parse(
        "MeshVersionFormatted 2\nDimension 3\nVertices\n1\n0 0 0 0\nFoo 3\n",
        p,
    )
    .unwrap_err();
    assert_eq!(parse_error_line(e), 6);
    let e = medit::parse("Dimension 3\nVertices\n2\n0 0 0 0\n", p).unwrap_err();
    assert!(e.to_string().contains("unexpected end of file"), "{e}");
    assert!(read_tet_mesh(&data("nothing.vtk")).is_err());
    assert!(matches!(
        read_tet_mesh(&data("missing.msh")).unwrap_err(),
        FemError::Io { .. }
    ));
}

// ---------------------------------------------------------------- voxel mesher

#[test]
fn voxel_mesher_fills_box_exactly_and_sphere_approximately() {
    let opts = ShapeOptions::default();
    let (v, t) = generate::box_mesh([2.0, 1.0, 1.0]);
    let boxm = TriMesh::new(v, t, &opts).unwrap();
    let vm = voxel_tet_mesh(&boxm, 0.25).unwrap();
    // The grid fits the box: 8 x 4 x 4 cubes, all inside, exact volume.
    assert_eq!(vm.voxels, 128);
    assert_eq!(vm.mesh.num_tets(), 6 * 128);
    assert_eq!(vm.mesh.num_nodes(), 9 * 5 * 5);
    assert!(vm.volume_error.abs() < 1e-12);

    let (v, t) = generate::icosphere(1.0, 3);
    let sphere = TriMesh::new(v, t, &opts).unwrap();
    let coarse = voxel_tet_mesh(&sphere, 0.25).unwrap();
    let fine = voxel_tet_mesh(&sphere, 0.125).unwrap();
    eprintln!(
        "voxel sphere volume error: spacing 0.25 {:+.4}, 0.125 {:+.4}",
        coarse.volume_error, fine.volume_error
    );
    // Staircase: volume error O(spacing). Measured +5.3% at 0.25, +2.3% at 0.125 (cube
    // centres inside decide, so the sign is not fixed); bounds leave ~50% room.
    assert!(coarse.volume_error.abs() < 0.08, "{}", coarse.volume_error);
    assert!(
        fine.volume_error.abs() < 0.04 && fine.volume_error.abs() < coarse.volume_error.abs(),
        "{}",
        fine.volume_error
    );
    // Every node lies within sqrt(3) spacings of the sphere's surface or inside.
    assert!(fine
        .mesh
        .nodes()
        .iter()
        .all(|p| (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt() < 1.0 + 0.125 * 3f64.sqrt()));
    assert!(voxel_tet_mesh(&sphere, 0.0).is_err());
    // A torus meshed by one cube whose centre is in the hole: nothing inside.
    let (v, t) = generate::torus(1.0, 0.3, 24, 12);
    let torus = TriMesh::new(v, t, &opts).unwrap();
    assert!(voxel_tet_mesh(&torus, 10.0).is_err());
}

// ---------------------------------------------------------------- error metric

#[test]
fn error_metric_on_synthetic_trajectories() {
    // Rest: the box [0,3] x [0,4] x [0,12], D = 13.
    let rest = vec![
        [0.0, 0.0, 0.0],
        [3.0, 4.0, 12.0],
        [1.0, 1.0, 1.0],
        [2.0, 0.0, 5.0],
    ];
    let reference: Vec<Vec<Point3>> = (0..5)
        .map(|f| {
            rest.iter()
                .map(|p| [p[0] + f as f64, p[1], p[2] * 0.5])
                .collect()
        })
        .collect();
    // A constant offset of length 2.6 = 0.2 D on every node and frame.
    let shifted: Vec<Vec<Point3>> = reference
        .iter()
        .map(|fr| fr.iter().map(|p| [p[0] + 2.4, p[1] + 1.0, p[2]]).collect())
        .collect();
    let m = trajectory_error(&rest, &reference, &shifted).unwrap();
    assert!((m.diagonal - 13.0).abs() < 1e-12);
    assert!((m.normalized_mse - 0.04).abs() < 1e-14);
    assert!((m.max_error - 0.2).abs() < 1e-14);
    // One node off by 13 (= D) in one frame: MSE = 1 / (5 frames x 4 nodes), max 1.
    let mut one = reference.clone();
    one[3][2][1] += 13.0;
    let m = trajectory_error(&rest, &reference, &one).unwrap();
    assert!((m.normalized_mse - 0.05).abs() < 1e-15);
    assert!((m.max_error - 1.0).abs() < 1e-15);
    assert_eq!((m.worst_frame, m.worst_node), (3, 2));
    // Identical trajectories: zero.
    let m = trajectory_error(&rest, &reference, &reference).unwrap();
    assert_eq!((m.normalized_mse, m.max_error), (0.0, 0.0));
    // Mismatches and NaN are errors that say where.
    assert!(trajectory_error(&rest, &reference, &reference[..4]).is_err());
    let mut short = reference.clone();
    short[1].pop();
    let e = trajectory_error(&rest, &reference, &short).unwrap_err();
    assert!(e.to_string().contains("frame 1"), "{e}");
    let mut nan = reference.clone();
    nan[2][3][0] = f64::NAN;
    let e = trajectory_error(&rest, &nan, &reference).unwrap_err();
    assert!(e.to_string().contains("frame 2, node 3"), "{e}");
    assert!(trajectory_error(&rest, &[], &[]).is_err());
}

// ---------------------------------------------------------------- beam reference and cache

fn tiny(test: BeamTest) -> FemBeamConfig {
    let mut c = FemBeamConfig::standard(test, 1);
    c.steps = 4;
    c
}

#[test]
fn beam_reference_is_cached_by_parameters() {
    let dir = tempfile::tempdir().unwrap();
    let cfg = tiny(BeamTest::Bend);
    let first = run_beam_reference(&cfg, Some(dir.path()), &Silent).unwrap();
    let CacheStatus::Written(path) = first.cache.clone() else {
        panic!("{:?}", first.cache)
    };
    assert_eq!(first.frames.len(), 4);
    assert_eq!(first.rest.len(), 6 * 2 * 2);
    // The bend sags: the free end moves down.
    let tip = first.rest.iter().position(|p| p[0] == 5.0).unwrap();
    assert!(first.frames[3][tip][1] < first.rest[tip][1] - 1e-4);
    let second = run_beam_reference(&cfg, Some(dir.path()), &Silent).unwrap();
    assert_eq!(second.cache, CacheStatus::Hit(path.clone()));
    assert_eq!(second.frames, first.frames);
    assert_eq!(second.step_seconds, first.step_seconds);
    assert_eq!(second.error_of(&first.frames).unwrap().normalized_mse, 0.0);
    // Any parameter change is a new key.
    let mut other = cfg.clone();
    other.solver.tolerance *= 0.5;
    assert_ne!(other.cache_key().0, cfg.cache_key().0);
    // A corrupted file is recomputed with a reason, not a crash.
    let mut bytes = std::fs::read(&path).unwrap();
    let mid = bytes.len() / 2;
    bytes[mid] ^= 0xff;
    std::fs::write(&path, &bytes).unwrap();
    let third = run_beam_reference(&cfg, Some(dir.path()), &Silent).unwrap();
    assert!(
        matches!(third.cache, CacheStatus::Recomputed { .. }),
        "{:?}",
        third.cache
    );
    assert_eq!(third.frames, first.frames);
    std::fs::write(&path, b"short").unwrap();
    let fourth = run_beam_reference(&cfg, Some(dir.path()), &Silent).unwrap();
    assert!(matches!(fourth.cache, CacheStatus::Recomputed { .. }));
}

#[test]
fn twist_turns_the_end_about_the_axis() {
    let cfg = tiny(BeamTest::Twist);
    let r = run_beam_reference(&cfg, None, &Silent).unwrap();
    assert_eq!(r.cache, CacheStatus::NotCached);
    // After 4 of 4 steps the end has turned by 720 degrees: back where it started; after
    // step 1 by 180 degrees: (y, z) -> (1 - y, 1 - z).
    for (a, p) in r.rest.iter().enumerate() {
        if p[0] >= 4.75 {
            let q = r.frames[0][a];
            assert!((q[1] - (1.0 - p[1])).abs() < 1e-12 && (q[2] - (1.0 - p[2])).abs() < 1e-12);
            let q = r.frames[3][a];
            assert!((q[1] - p[1]).abs() < 1e-12 && (q[2] - p[2]).abs() < 1e-12);
        }
        if p[0] <= 0.25 {
            assert_eq!(r.frames[2][a], *p);
        }
    }
}

#[test]
fn nested_levels_compare_on_the_coarse_nodes() {
    let coarse = run_beam_reference(&tiny(BeamTest::Bend), None, &Silent).unwrap();
    let mut fine_cfg = tiny(BeamTest::Bend);
    fine_cfg.solver.order = ElementOrder::Quadratic;
    let fine = run_beam_reference(&fine_cfg, None, &Silent).unwrap();
    // Quadratic at r = 1 has the nodes of linear at r = 2: 11 x 3 x 3.
    assert_eq!(fine.rest.len(), 99);
    assert_eq!(
        nested_difference(&coarse, &coarse).unwrap().normalized_mse,
        0.0
    );
    let d = nested_difference(&coarse, &fine).unwrap();
    assert!(d.normalized_mse > 0.0 && d.normalized_mse.is_finite());
    assert_eq!(d.nodes, coarse.rest.len());
    // The other way round, fine nodes are missing from the coarse mesh.
    assert!(nested_difference(&fine, &coarse).is_err());
}

/// A soft cantilever under gravity: 4 m x 1 m x 1 m, two cubes per metre, held at x = 0.
fn soft_cantilever(dt: f64, max_newton_iterations: usize) -> FemSolver {
    let mesh = TetMesh::structured_box([0.0; 3], [4.0, 1.0, 1.0], [8, 2, 2]).unwrap();
    let mat = Material {
        youngs: 2e4,
        poisson: 0.3,
        density: 1000.0,
    };
    let mats = TetMaterials::homogeneous(&mesh, &mat).unwrap();
    let fixed = mesh.select_nodes(|p| p[0] < 1e-9);
    let params = FemParams {
        dt,
        max_newton_iterations,
        ..FemParams::default()
    };
    FemSolver::new(&mesh, &mats, &fixed, params).unwrap()
}

#[test]
fn a_step_newton_cannot_converge_is_halved_into_converged_half_steps() {
    // Where every step converges, sub-stepping is the plain step bit for bit.
    let (mut plain, mut halving) = (soft_cantilever(0.01, 50), soft_cantilever(0.01, 50));
    for _ in 0..3 {
        plain.step().unwrap();
        let info = halving.step_substepping(4).unwrap();
        assert_eq!(info.substeps, 1);
    }
    assert_eq!(plain.positions(), halving.positions());
    assert_eq!(halving.steps_taken(), 3);

    // Large steps with a tight Newton cap: the plain step fails, the halving one converges
    // as backward Euler at the smaller steps. Where the step was taken as 2^d sub-steps (here
    // every such case split to one depth throughout), an independent solver stepping at
    // dt / 2^d reproduces it bit for bit; at least one of these settings is such a case.
    let mut compared = 0;
    for (dt, cap) in [(0.5, 3), (0.5, 4), (0.3, 3), (0.3, 2), (0.2, 2)] {
        let mut failing = soft_cantilever(dt, cap);
        if failing.step().is_ok() {
            continue;
        }
        let mut halving = soft_cantilever(dt, cap);
        let info = halving.step_substepping(4).unwrap();
        assert!(info.substeps > 1, "{info:?}");
        assert_eq!(halving.steps_taken(), 1);
        if !info.substeps.is_power_of_two() {
            continue;
        }
        let mut fine = soft_cantilever(dt / info.substeps as f64, cap);
        for _ in 0..info.substeps {
            fine.step().unwrap();
        }
        assert_eq!(fine.positions(), halving.positions(), "dt {dt}, cap {cap}");
        assert_eq!(
            fine.velocities(),
            halving.velocities(),
            "dt {dt}, cap {cap}"
        );
        compared += 1;
    }
    assert!(compared > 0);
    let dt = 0.5;
    // Not even 1/16 of the step converges in one iteration: the error, and the state is the
    // start of the step.
    let mut hopeless = soft_cantilever(dt, 1);
    let start = hopeless.positions().to_vec();
    assert!(hopeless.step_substepping(4).is_err());
    assert_eq!(hopeless.positions(), &start[..]);
    assert_eq!(hopeless.steps_taken(), 0);
}
