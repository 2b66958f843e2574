//! RKPM shape functions: reproducing identities to round-off, analytic gradients against
//! finite differences, coverage failures, unit invariance.

#![allow(clippy::needless_range_loop)] // index loops mirror the formulas

use crate::common;
use common::{box_points, kernels_for};
use freeform::precompute::rkpm::{
    evaluate, reproducing_error, KernelType, Kernels, ShapeFunctionOptions,
};
use freeform::random::SplitMix64;
use freeform::Point3;

const KINDS: [KernelType; 3] = [KernelType::Cubic, KernelType::Quartic, KernelType::Gaussian];

fn random_queries(n: usize, size: [f64; 3], seed: u64) -> Vec<Point3> {
    let mut r = SplitMix64::new(seed);
    (0..n)
        .map(|_| {
            [
                size[0] * r.next_f64(),
                size[1] * r.next_f64(),
                size[2] * r.next_f64(),
            ]
        })
        .collect()
}

#[test]
fn reproducing_conditions_hold_to_round_off() {
    let ip = box_points([2.0, 1.0, 1.0], 0.08);
    for kind in KINDS {
        let kernels = kernels_for(&ip, 120, kind);
        // Off-grid queries, including ones near faces and corners.
        let mut q = random_queries(2000, [2.0, 1.0, 1.0], 11);
        q.push([0.0, 0.0, 0.0]);
        q.push([2.0, 1.0, 1.0]);
        let (sf, stats) = evaluate(&kernels, &q, &ShapeFunctionOptions::default());
        assert!(
            stats.failed.is_empty(),
            "{kind:?}: {} points failed",
            stats.failed.len()
        );
        let err = reproducing_error(&kernels, &q, &sf);
        // Each identity is a 4x4 solve on O(1)-scaled data followed by a sum of ~30 terms:
        // round-off ~ 30 eps cond ~ 1e-12 for cond ~ 1e2; 1e-10 leaves margin for the
        // corner points where the moment matrix is worst conditioned.
        assert!(err.max() < 1e-10, "{kind:?}: {err:?}");
    }
}

#[test]
fn gradients_match_finite_differences() {
    let ip = box_points([2.0, 1.0, 1.0], 0.1);
    for kind in [KernelType::Cubic, KernelType::Quartic] {
        let kernels = kernels_for(&ip, 80, kind);
        let q = random_queries(200, [2.0, 1.0, 1.0], 5);
        let opts = ShapeFunctionOptions::default();
        let (sf, _) = evaluate(&kernels, &q, &opts);
        let h = 1e-6;
        let mut worst: f64 = 0.0;
        for (i, x) in q.iter().enumerate() {
            for d in 0..3 {
                let (mut xp, mut xm) = (*x, *x);
                xp[d] += h;
                xm[d] -= h;
                let (sp, _) = evaluate(&kernels, &[xp], &opts);
                let (sm, _) = evaluate(&kernels, &[xm], &opts);
                let value = |s: &freeform::precompute::rkpm::ShapeFunctions, k: u32| {
                    s.pattern
                        .row(0)
                        .iter()
                        .position(|&kk| kk == k)
                        .map_or(0.0, |e| s.phi[e])
                };
                for e in sf.pattern.ptr[i]..sf.pattern.ptr[i + 1] {
                    let k = sf.pattern.kernels[e];
                    let fd = (value(&sp, k) - value(&sm, k)) / (2.0 * h);
                    worst = worst.max((fd - sf.grad[e][d]).abs());
                }
            }
        }
        // C2 kernels: FD truncation ~ h^2 |phi'''| ~ 1e-12 / a^3 with a ~ 0.4; round-off
        // ~ eps / h ~ 1e-10. Gradients are O(1 / a) ~ 3, so 1e-7 is a tight absolute bound.
        assert!(worst < 1e-7, "{kind:?}: worst gradient error {worst:e}");
    }
}

#[test]
fn unit_invariance() {
    // Scaling the whole problem by s scales phi by 1 and grad phi by 1/s, to round-off.
    let ip = box_points([2.0, 1.0, 1.0], 0.1);
    let k1 = kernels_for(&ip, 80, KernelType::Cubic);
    let q = random_queries(300, [2.0, 1.0, 1.0], 9);
    let (s1, _) = evaluate(&k1, &q, &ShapeFunctionOptions::default());
    for s in [1e-3, 1e3] {
        let ks = Kernels {
            centers: k1
                .centers
                .iter()
                .map(|p| [p[0] * s, p[1] * s, p[2] * s])
                .collect(),
            radii: k1.radii.iter().map(|a| a * s).collect(),
            kind: k1.kind,
        };
        let qs: Vec<Point3> = q.iter().map(|p| [p[0] * s, p[1] * s, p[2] * s]).collect();
        let (ss, stats) = evaluate(&ks, &qs, &ShapeFunctionOptions::default());
        assert!(stats.failed.is_empty());
        assert_eq!(ss.pattern, s1.pattern);
        for e in 0..s1.nnz() {
            assert!((ss.phi[e] - s1.phi[e]).abs() < 1e-12, "phi at scale {s}");
            for d in 0..3 {
                assert!(
                    (ss.grad[e][d] * s - s1.grad[e][d]).abs() < 1e-10,
                    "grad at scale {s}"
                );
            }
        }
    }
}

#[test]
fn uncovered_points_are_reported_not_inverted() {
    let ip = box_points([2.0, 1.0, 1.0], 0.1);
    let kernels = kernels_for(&ip, 80, KernelType::Cubic);
    // Far outside every support, and just outside (covered by < 4 non-coplanar kernels).
    let q = vec![[10.0, 10.0, 10.0], [0.5, 0.5, 0.5], [f64::MAX, 0.0, 0.0]];
    let (sf, stats) = evaluate(&kernels, &q, &ShapeFunctionOptions::default());
    assert_eq!(stats.failed, vec![0, 2]);
    assert_eq!(stats.min_rcond, 0.0);
    assert!(sf.phi.iter().all(|v| v.is_finite()));
    // Too few kernels around a point: a kernel set of three coplanar kernels.
    let flat = Kernels {
        centers: vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
        radii: vec![5.0; 3],
        kind: KernelType::Cubic,
    };
    let (_, stats) = evaluate(&flat, &[[0.2, 0.2, 0.0]], &ShapeFunctionOptions::default());
    assert_eq!(stats.failed, vec![0]);
}
