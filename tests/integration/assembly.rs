//! H_w (Prop. 1) and M: against finite differences of the stable Neo-Hookean energy with an
//! RKPM displacement field, and their structural identities.

#![allow(clippy::needless_range_loop)] // index loops mirror the formulas

use crate::common;
use common::{box_points, kernels_for};
use freeform::elasticity::energy_density;
use freeform::material::{Material, MaterialField, MaterialOverride, Region};
use freeform::precompute::assembly::assemble;
use freeform::precompute::rkpm::{evaluate, KernelType, ShapeFunctionOptions, ShapeFunctions};
use freeform::sparse::SparseMatrixRef;

fn dense(a: SparseMatrixRef<'_>) -> Vec<Vec<f64>> {
    let n = a.nrows();
    let mut d = vec![vec![0.0; n]; n];
    for j in 0..n {
        let (rows, vals) = (a.row_idx_of_col_raw(j), a.val_of_col(j));
        for (r, v) in rows.iter().zip(vals) {
            d[*r as usize][j] = *v;
        }
    }
    d
}

/// Elastic energy sum_i v_i Psi(F_i) with F_i = I + sum_k d_k grad phi_k(X_i)^T.
fn energy(sf: &ShapeFunctions, vol: &[f64], mat: &MaterialField, disp: &[[f64; 3]]) -> f64 {
    (0..sf.rows())
        .map(|i| {
            let mut f = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
            for e in sf.pattern.ptr[i]..sf.pattern.ptr[i + 1] {
                let d = disp[sf.pattern.kernels[e] as usize];
                for r in 0..3 {
                    for c in 0..3 {
                        f[r][c] += d[r] * sf.grad[e][c];
                    }
                }
            }
            let (l, m) = mat.lame(i);
            vol[i] * energy_density(&f, l, m)
        })
        .sum()
}

fn setup(overrides: &[MaterialOverride]) -> (ShapeFunctions, Vec<f64>, MaterialField, usize) {
    let ip = box_points([2.0, 1.0, 1.0], 0.125);
    let kernels = kernels_for(&ip, 40, KernelType::Cubic);
    let (sf, stats) = evaluate(&kernels, &ip.points, &ShapeFunctionOptions::default());
    assert!(stats.failed.is_empty());
    let mat = MaterialField::from_regions(&ip.points, &Material::default(), overrides).unwrap();
    (sf, ip.volumes, mat, kernels.len())
}

#[test]
fn proposition_1_matches_finite_differences() {
    let stiff = Material {
        youngs: 5e8,
        poisson: 0.3,
        density: 1000.0,
    };
    let overrides = [MaterialOverride {
        region: Region::Box {
            min: [0.0; 3],
            max: [1.0, 1.0, 1.0],
        },
        material: stiff,
    }];
    let (sf, vol, mat, k) = setup(&overrides);
    let a = assemble(&sf, &vol, &mat.hessian_weights(), k).unwrap();
    let h = dense(a.hessian());
    let hmax = h.iter().flatten().fold(0.0f64, |m, v| m.max(v.abs()));
    // Second differences of the energy in d^x_k, d^x_l (+ the y and z blocks) at d = 0.
    let step = 1e-4;
    let pairs = [(0, 0), (0, 1), (3, 7), (10, 10), (5, 20), (k - 1, k - 2)];
    for &(p, q) in &pairs {
        let mut fd = 0.0;
        for s in 0..3 {
            let e = |dp: f64, dq: f64| {
                let mut d = vec![[0.0; 3]; k];
                d[p][s] += dp;
                d[q][s] += dq;
                energy(&sf, &vol, &mat, &d)
            };
            fd += (e(step, step) - e(step, -step) - e(-step, step) + e(-step, -step))
                / (4.0 * step * step);
        }
        // The energy is a polynomial of degree 6 in d: the O(step^2) truncation with
        // derivatives ~ hmax / a^4 and a ~ 0.5 is ~ 1e-7 hmax; round-off in 4 energy
        // evaluations ~ 1e-16 * E_scale / step^2 is smaller. 1e-6 relative to max |H| checks
        // Prop. 1 (a wrong weight, e.g. lambda + 2 mu, is off by ~20 %).
        assert!(
            (fd - h[p][q]).abs() < 1e-6 * hmax,
            "H[{p}][{q}] = {} but FD gives {fd}",
            h[p][q]
        );
    }
}

#[test]
fn hessian_and_mass_structure() {
    let (sf, vol, mat, k) = setup(&[]);
    let a = assemble(&sf, &vol, &mat.hessian_weights(), k).unwrap();
    let (h, m) = (dense(a.hessian()), dense(a.mass()));
    let hmax = h.iter().flatten().fold(0.0f64, |x, v| x.max(v.abs()));
    for i in 0..k {
        for j in 0..k {
            // Exactly symmetric by construction (same terms, same order).
            assert_eq!(h[i][j], h[j][i]);
            assert_eq!(m[i][j], m[j][i]);
        }
        // H 1 = 0 from sum_k grad phi_k = 0: round-off ~ 30 terms x 1e-12 relative.
        let row: f64 = h[i].iter().sum();
        assert!(row.abs() < 1e-10 * hmax, "row {i} sum {row}");
    }
    // 1^T M 1 = sum_i v_i (sum phi)^2 = volume.
    let total: f64 = m.iter().flatten().sum();
    assert!((total - 2.0).abs() < 1e-10, "1^T M 1 = {total}");
    // M SPD and H PSD: dense eigenvalues.
    let md = faer::Mat::from_fn(k, k, |i, j| m[i][j]);
    let hd = faer::Mat::from_fn(k, k, |i, j| h[i][j]);
    let em = md.self_adjoint_eigenvalues(faer::Side::Lower).unwrap();
    let eh = hd.self_adjoint_eigenvalues(faer::Side::Lower).unwrap();
    assert!(em[0] > 0.0, "M min eigenvalue {}", em[0]);
    // H's smallest eigenvalue is 0 (constant); round-off allows ~1e-12 hmax below zero.
    assert!(
        eh[0] > -1e-10 * hmax && eh[0].abs() < 1e-10 * hmax,
        "{}",
        eh[0]
    );
    assert!(
        eh[1] > 1e-6 * hmax,
        "second eigenvalue must be positive: {}",
        eh[1]
    );
}

#[test]
fn assembly_is_deterministic_across_thread_counts() {
    let (sf, vol, mat, k) = setup(&[]);
    let w = mat.hessian_weights();
    let one = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap()
        .install(|| assemble(&sf, &vol, &w, k).unwrap());
    let two = rayon::ThreadPoolBuilder::new()
        .num_threads(2)
        .build()
        .unwrap()
        .install(|| assemble(&sf, &vol, &w, k).unwrap());
    assert_eq!(one.hessian().val(), two.hessian().val());
    assert_eq!(one.mass().val(), two.mass().val());
}

#[test]
fn bad_lengths_are_errors() {
    let (sf, vol, mat, k) = setup(&[]);
    assert!(assemble(&sf, &vol[1..], &mat.hessian_weights(), k).is_err());
    assert!(assemble(&sf, &vol, &mat.hessian_weights()[1..], k).is_err());
}
