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

/// A spike: a tetrahedron 2 m tall on a 1 m base. Its apex lies far outside the integration
/// points (cell centres, which thin out towards the tip), and the kernels placed among them do
/// not reach it. Before the surface repair, evaluating the basis at the apex failed; the
/// repair grows the supports of the kernels nearest the badly covered vertices before the
/// assembly, and the reproducing identities then hold at every vertex.
#[test]
fn surface_repair_covers_a_spike_tip() {
    use freeform::geometry::{Shape, ShapeOptions, TriMesh};
    use freeform::precompute::{build_basis, place_kernels, sample_with_material, BasisOptions};
    let vertices: Vec<Point3> = vec![
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.2, 0.2, 2.0],
    ];
    let triangles = vec![[0, 2, 1], [0, 1, 3], [1, 2, 3], [2, 0, 3]];
    let mesh = TriMesh::new(vertices.clone(), triangles, &ShapeOptions::default()).unwrap();
    let shape = Shape::Mesh(mesh);
    let opts = BasisOptions {
        kernels: 200,
        modes: 6,
        ..BasisOptions::default()
    };
    let sfo = ShapeFunctionOptions::default();

    // The placement alone (the same centres and radii the pipeline starts from) leaves a
    // vertex badly covered: the repair below is what this test exercises.
    let (ip, _) = sample_with_material(&shape, &opts).unwrap();
    let placed = place_kernels(&ip.points, None, &opts).unwrap();
    let (_, before) = evaluate(&placed, &vertices, &sfo);
    assert!(!before.failed.is_empty(), "no bare vertex: {before:?}");

    let run = build_basis(&shape, &opts, &freeform::progress::Silent).unwrap();
    let cover = &run.report.coverage;
    // The probes: the vertices and grids on the faces at half the bulk spacing.
    let volume: f64 = ip.volumes.iter().sum();
    let probes =
        shape.surface_probes(0.5 * freeform::precompute::density::bulk_spacing(volume, 200));
    assert_eq!(cover.surface_points, probes.len(), "{cover:?}");
    assert!(probes.len() > 100, "{}", probes.len());
    assert_eq!(cover.uncovered_surface_points, 0, "{cover:?}");
    assert!(cover.enlarged_kernels > 0, "{cover:?}");
    let (_, on_faces) = evaluate(&run.basis.kernels, &probes, &sfo);
    assert!(on_faces.failed.is_empty(), "{on_faces:?}");
    let (sf, after) = evaluate(&run.basis.kernels, &vertices, &sfo);
    assert!(after.failed.is_empty(), "{after:?}");
    // Partition of unity and linear reproduction are exact identities of the construction,
    // so what is left is round-off: a solve with the moment matrix and a sum of ~30 terms,
    // ~30 eps cond for the values; the gradients solve with it twice (grad b = -M^-1 (grad
    // M) b), ~30 eps cond^2. cond = 1 / rcond of the worst vertex; bounds at 10x those.
    let err = reproducing_error(&run.basis.kernels, &vertices, &sf);
    let cond = 1.0 / after.min_rcond;
    let values = 300.0 * f64::EPSILON * cond;
    let gradients = values * cond;
    eprintln!("vertices: cond {cond:.3e}, {err:?}");
    assert!(err.partition_of_unity.max(err.linear) < values, "{err:?}");
    assert!(
        err.gradient_sum.max(err.gradient_linear) < gradients,
        "{err:?}"
    );
    assert!(run.basis.weights(&vertices).is_ok());
}

/// A wedge whose cross-section thins to a knife edge (a 1 m prism of the triangle (0, 0),
/// (1, 0), (0, 0.2) in y, z), K = 300. By the rim the covering kernels lie nearly in one
/// plane, and growing the nearest ones (which already reach the rim) kept them there: with
/// that rule the basis failed (18 integration points with rcond down to 5e-10; checked with
/// the previous build). The repair grows the nearest kernels that do not reach the point yet,
/// from other directions: every integration point and every surface probe is covered.
#[test]
fn thin_rim_is_covered_by_kernels_from_other_directions() {
    use freeform::geometry::{Shape, ShapeOptions, TriMesh};
    use freeform::precompute::{build_basis, sample_with_material, BasisOptions};
    let t = 0.2;
    let vertices: Vec<Point3> = vec![
        [0.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.0, 0.0, t],
        [1.0, 0.0, 0.0],
        [1.0, 1.0, 0.0],
        [1.0, 0.0, t],
    ];
    let triangles = vec![
        [0, 2, 1],
        [3, 4, 5],
        [0, 1, 4],
        [0, 4, 3],
        [1, 2, 5],
        [1, 5, 4],
        [2, 0, 3],
        [2, 3, 5],
    ];
    let mesh = TriMesh::new(vertices, triangles, &ShapeOptions::default()).unwrap();
    let shape = Shape::Mesh(mesh);
    let opts = BasisOptions {
        kernels: 300,
        modes: 6,
        ..BasisOptions::default()
    };
    let run = build_basis(&shape, &opts, &freeform::progress::Silent).unwrap();
    let cover = &run.report.coverage;
    assert!(cover.enlarged_kernels > 0, "{cover:?}");
    assert_eq!(cover.uncovered_surface_points, 0, "{cover:?}");
    let (ip, _) = sample_with_material(&shape, &opts).unwrap();
    let volume: f64 = ip.volumes.iter().sum();
    let probes =
        shape.surface_probes(0.5 * freeform::precompute::density::bulk_spacing(volume, 300));
    let sfo = ShapeFunctionOptions::default();
    let (_, on_surface) = evaluate(&run.basis.kernels, &probes, &sfo);
    assert!(on_surface.failed.is_empty(), "{on_surface:?}");
}

/// The twist beam with kernels twice as fine around its held and turned ends, K = 2,000. The
/// weighted sampling measures a point's distance to a centre in the finer of their two
/// spacings, so the coarse corners beyond the refined bands get kernels of their own. (When it
/// used the point's own spacing, a plane of fine kernels, with supports sized by their fine
/// neighbours, counted as covering the corners, and the corner (0, 1, 1) had 3 covering
/// kernels: the placement alone, before any repair, failed there.)
#[test]
fn density_placement_leaves_no_corner_bare() {
    use freeform::geometry::Shape;
    use freeform::material::Region;
    use freeform::precompute::{
        place_kernels, sample_with_material, BasisOptions, DensityBands, KernelDensity,
    };
    let shape = Shape::Box {
        size: [5.0, 1.0, 1.0],
    };
    let opts = BasisOptions {
        kernels: 2000,
        modes: 6,
        boundary_regions: vec![
            Region::HalfSpace {
                point: [0.25, 0.0, 0.0],
                normal: [-1.0, 0.0, 0.0],
            },
            Region::HalfSpace {
                point: [4.75, 0.0, 0.0],
                normal: [1.0, 0.0, 0.0],
            },
        ],
        density: KernelDensity::bands(DensityBands {
            boundaries: 2.0,
            ..DensityBands::off()
        }),
        ..BasisOptions::default()
    };
    let (ip, _) = sample_with_material(&shape, &opts).unwrap();
    let volume: f64 = ip.volumes.iter().sum();
    let scale = freeform::precompute::density::kernel_scale(
        &ip.points,
        volume,
        opts.kernels,
        &opts.density,
        &opts.boundary_regions,
        None,
    )
    .unwrap();
    let placed = place_kernels(&ip.points, scale.as_deref(), &opts).unwrap();
    let corners: Vec<Point3> = (0..8)
        .map(|c| {
            [
                5.0 * (c & 1) as f64,
                ((c >> 1) & 1) as f64,
                ((c >> 2) & 1) as f64,
            ]
        })
        .collect();
    let (_, at_corners) = evaluate(&placed, &corners, &ShapeFunctionOptions::default());
    assert!(at_corners.failed.is_empty(), "{at_corners:?}");
}
