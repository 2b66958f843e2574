//! Streamed assembly (issue #19): H_w and M summed over chunks of integration points must be
//! the same, bit for bit, as an independent dense assembly from all shape functions at once,
//! for any chunk size and thread count; the pipeline and the skinning weights, which stream
//! too, must match one-shot evaluations exactly.
//!
//! Exact equality is the right tolerance here: every entry is one running sum over the points
//! in the same order, and each term is computed with the same expression, so any difference is
//! a bug (a lost, duplicated or reordered contribution), not round-off.

use crate::common::{box_points, kernels_for};
use freeform::material::{Material, MaterialField, MaterialOverride, Region};
use freeform::precompute::centers::morton_order;
use freeform::precompute::rkpm::{evaluate, KernelType, Kernels, ShapeFunctionOptions};
use freeform::precompute::sampling::IntegrationPoints;
use freeform::precompute::stream::{assemble_streamed, Streamed};
use freeform::precompute::{BasisOptions, Problem};
use freeform::progress::Silent;
use freeform::random::SplitMix64;
use freeform::sparse::SparseMatrixRef;
use freeform::Point3;

/// Dense K x K H_w and M, and which entries any point touched, from all shape functions at
/// once: for each point (in the given order), every pair of its kernels (k <= l), mirrored.
type Dense = (Vec<Vec<f64>>, Vec<Vec<f64>>, Vec<Vec<bool>>);
fn dense_reference(kernels: &Kernels, points: &[Point3], vol: &[f64], w: &[f64]) -> Dense {
    let k = kernels.len();
    let (sf, stats) = evaluate(kernels, points, &ShapeFunctionOptions::default());
    assert!(stats.failed.is_empty());
    let mut h = vec![vec![0.0; k]; k];
    let mut m = vec![vec![0.0; k]; k];
    let mut hit = vec![vec![false; k]; k];
    for p in 0..sf.rows() {
        let (wh, wm) = (vol[p] * w[p], vol[p]);
        for a in sf.pattern.ptr[p]..sf.pattern.ptr[p + 1] {
            for b in sf.pattern.ptr[p]..sf.pattern.ptr[p + 1] {
                let (i, j) = (
                    sf.pattern.kernels[a] as usize,
                    sf.pattern.kernels[b] as usize,
                );
                if i > j {
                    continue;
                }
                let (gi, gj) = (sf.grad[a], sf.grad[b]);
                h[i][j] += wh * (gi[0] * gj[0] + gi[1] * gj[1] + gi[2] * gj[2]);
                m[i][j] += wm * (sf.phi[a] * sf.phi[b]);
                hit[i][j] = true;
            }
        }
    }
    for i in 0..k {
        for j in 0..i {
            h[i][j] = h[j][i];
            m[i][j] = m[j][i];
            hit[i][j] = hit[j][i];
        }
    }
    (h, m, hit)
}

/// Entry-wise exact comparison of a sparse matrix with a dense one, and of its pattern.
fn assert_same(a: SparseMatrixRef<'_>, dense: &[Vec<f64>], hit: &[Vec<bool>], what: &str) {
    let k = dense.len();
    let mut stored = vec![vec![false; k]; k];
    for j in 0..k {
        for (&i, &v) in a.row_idx_of_col_raw(j).iter().zip(a.val_of_col(j)) {
            let i = i as usize;
            assert_eq!(
                v.to_bits(),
                dense[i][j].to_bits(),
                "{what}({i}, {j}): {v:e} vs {:e}",
                dense[i][j]
            );
            stored[i][j] = true;
        }
    }
    assert_eq!(stored, hit, "{what}: sparsity pattern differs");
}

/// A graded, heterogeneous box: points in Morton order (as the pipeline streams them),
/// kernels, volumes and Hessian weights with a 100x stiffer half.
fn fixture() -> (Kernels, Vec<Point3>, Vec<f64>, Vec<f64>) {
    let ip = box_points([2.0, 1.0, 1.0], 0.08);
    let kernels = kernels_for(&ip, 70, KernelType::Cubic);
    let stiff = MaterialOverride {
        region: Region::Box {
            min: [1.0, 0.0, 0.0],
            max: [2.0, 1.0, 1.0],
        },
        material: Material {
            youngs: 5e8,
            ..Material::default()
        },
    };
    let mat = MaterialField::from_regions(&ip.points, &Material::default(), &[stiff]).unwrap();
    let w = mat.hessian_weights();
    let mut order: Vec<usize> = (0..ip.len()).collect();
    morton_order(&ip.points, &mut order);
    // Volumes vary per point so that a misplaced volume would show.
    let mut rng = SplitMix64::new(7);
    let vol: Vec<f64> = order
        .iter()
        .map(|&i| ip.volumes[i] * (0.5 + rng.next_f64()))
        .collect();
    let points = order.iter().map(|&i| ip.points[i]).collect();
    let w = order.iter().map(|&i| w[i]).collect();
    (kernels, points, vol, w)
}

#[test]
fn streamed_assembly_equals_dense_reference_for_any_chunk_and_thread_count() {
    let (kernels, points, vol, w) = fixture();
    let n = points.len();
    let (h, m, hit) = dense_reference(&kernels, &points, &vol, &w);
    // One point per chunk, odd sizes that split supports anywhere, and everything at once.
    for chunk in [1, 97, 1000, n] {
        for threads in [1, 2] {
            let run = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap()
                .install(|| {
                    assemble_streamed(
                        &kernels,
                        &points,
                        &vol,
                        &w,
                        &ShapeFunctionOptions::default(),
                        chunk,
                        &Silent,
                    )
                    .unwrap()
                });
            let Streamed::Assembled(done) = run else {
                panic!("every point of the box is covered");
            };
            let what = format!("chunk {chunk}, {threads} threads");
            assert_same(done.assembled.hessian(), &h, &hit, &format!("H {what}"));
            assert_same(done.assembled.mass(), &m, &hit, &format!("M {what}"));
            assert_eq!(done.stats.mean_cover, {
                let (sf, _) = evaluate(&kernels, &points, &ShapeFunctionOptions::default());
                sf.nnz() as f64 / n as f64
            });
            assert!(done.largest_chunk_bytes > 0);
        }
    }
}

#[test]
fn streamed_assembly_lists_every_badly_covered_point() {
    let (kernels, mut points, vol, w) = fixture();
    // Two points far outside every support, in different chunks.
    points[5] = [50.0, 0.0, 0.0];
    let last = points.len() - 1;
    points[last] = [0.0, 60.0, 0.0];
    let opts = ShapeFunctionOptions::default();
    let Streamed::Uncovered(stats) =
        assemble_streamed(&kernels, &points, &vol, &w, &opts, 100, &Silent).unwrap()
    else {
        panic!("two points are not covered");
    };
    assert_eq!(stats.stats().failed, vec![5, last]);
    let err = stats
        .coverage_error(|i| points[i], opts.min_rcond)
        .unwrap_err();
    assert!(
        matches!(
            err,
            freeform::Error::Coverage {
                count: 2,
                index: 5,
                covering: 0,
                ..
            }
        ),
        "{err}"
    );
    assert!(assemble_streamed(&kernels, &points, &vol, &w, &opts, 0, &Silent).is_err());
    assert!(assemble_streamed(&kernels, &points, &vol[1..], &w, &opts, 10, &Silent).is_err());
}

#[test]
fn pipeline_streams_over_several_chunks_to_the_one_shot_matrices() {
    // More points than one chunk of the pipeline (65,536), so chunk boundaries are crossed.
    let ip = box_points([2.0, 1.0, 1.0], 0.022);
    assert!(ip.len() > 2 * freeform::precompute::rkpm::CHUNK_POINTS);
    let mat = MaterialField::homogeneous(ip.len(), &Material::default()).unwrap();
    let opts = BasisOptions {
        kernels: 200,
        modes: 4,
        ..BasisOptions::default()
    };
    let problem = Problem::from_points(ip.clone(), mat.clone(), &opts, &Silent).unwrap();
    let mut order: Vec<usize> = (0..ip.len()).collect();
    morton_order(&ip.points, &mut order);
    let sorted: Vec<Point3> = order.iter().map(|&i| ip.points[i]).collect();
    let vol: Vec<f64> = order.iter().map(|&i| ip.volumes[i]).collect();
    let w0 = mat.hessian_weights();
    let w: Vec<f64> = order.iter().map(|&i| w0[i]).collect();
    let (sf, _) = evaluate(problem.kernels(), &sorted, &ShapeFunctionOptions::default());
    let one = freeform::precompute::assembly::assemble(&sf, &vol, &w, 200).unwrap();
    let a = problem.matrices();
    assert_eq!(a.hessian().val(), one.hessian().val());
    assert_eq!(a.mass().val(), one.mass().val());
    assert_eq!(a.hessian().row_idx(), one.hessian().row_idx());
    assert_eq!(a.hessian().col_ptr(), one.hessian().col_ptr());
    // The report's shape-function bytes are one chunk's, not all points'.
    assert!(problem.coverage().shape_function_bytes < sf.memory_bytes() / 2);
}

#[test]
fn chunked_skinning_weights_equal_one_shot_evaluation() {
    let ip: IntegrationPoints = box_points([2.0, 1.0, 1.0], 0.1);
    let mat = MaterialField::homogeneous(ip.len(), &Material::default()).unwrap();
    let opts = BasisOptions {
        kernels: 60,
        modes: 3,
        ..BasisOptions::default()
    };
    let basis = Problem::from_points(ip, mat, &opts, &Silent)
        .unwrap()
        .solve(&Silent)
        .unwrap()
        .basis;
    // Random queries in the box, more than one chunk, in no spatial order.
    let mut rng = SplitMix64::new(11);
    let queries: Vec<Point3> = (0..freeform::precompute::rkpm::CHUNK_POINTS + 3000)
        .map(|_| [2.0 * rng.next_f64(), rng.next_f64(), rng.next_f64()])
        .collect();
    let w = basis.weights(&queries).unwrap();
    let (sf, stats) = evaluate(&basis.kernels, &queries, &ShapeFunctionOptions::default());
    assert!(stats.failed.is_empty());
    let modes = basis.modes();
    for i in (0..queries.len()).step_by(7) {
        let mut v = vec![0.0; modes];
        let mut g = vec![[0.0; 3]; modes];
        for e in sf.pattern.ptr[i]..sf.pattern.ptr[i + 1] {
            let k = sf.pattern.kernels[e] as usize;
            for j in 0..modes {
                let c = basis.coefficients[(k, j)];
                v[j] += sf.phi[e] * c;
                for (gd, dd) in g[j].iter_mut().zip(sf.grad[e]) {
                    *gd += dd * c;
                }
            }
        }
        assert_eq!(w.row(i), &v[..], "weights at query {i}");
        assert_eq!(w.gradient_row(i), &g[..], "gradients at query {i}");
    }
    // A query outside the object is named by its index in the caller's order.
    let mut far = queries.clone();
    far[68_000] = [40.0, 0.0, 0.0];
    let err = basis.weights(&far).unwrap_err();
    assert!(
        matches!(err, freeform::Error::Coverage { index: 68_000, .. }),
        "{err}"
    );
}

#[test]
fn memory_estimate_refuses_with_the_figures_and_scales_with_the_run() {
    use freeform::precompute::{default_points, MemoryEstimate};
    let opts = BasisOptions {
        kernels: 100_000,
        modes: 32,
        ..BasisOptions::default()
    };
    let mut est = MemoryEstimate::new(&opts, 2_000_000);
    // Accepted when it fits; the memory it was checked against is recorded.
    est.check_against(u64::MAX, "test").unwrap();
    assert_eq!(est.available_bytes, u64::MAX);
    let err = est
        .check_against(1_000_000_000, "a 1 GB test limit")
        .unwrap_err();
    let text = err.to_string();
    assert!(
        matches!(
            err,
            freeform::Error::OutOfMemory {
                available_bytes: 1_000_000_000,
                ..
            }
        ),
        "{text}"
    );
    for needle in [
        "1.0 GB is available",
        "a 1 GB test limit",
        "fewer integration points",
        "2000000",
    ] {
        assert!(text.contains(needle), "missing {needle:?}: {text}");
    }
    // The parts add up, and each grows with what it is made of.
    let sum = est.points_bytes + est.matrices_bytes + est.eigensolver_bytes;
    assert!(est.total_bytes >= sum && est.total_bytes <= sum + est.stream_bytes + 12 * est.nnz);
    let more_points = MemoryEstimate::new(&opts, 4_000_000);
    assert_eq!(more_points.points_bytes, 2 * est.points_bytes);
    assert_eq!(more_points.matrices_bytes, est.matrices_bytes);
    let wider = BasisOptions {
        support: freeform::precompute::rkpm::SupportOptions {
            factor: 2.5,
            ..Default::default()
        },
        ..opts.clone()
    };
    assert!(MemoryEstimate::new(&wider, 2_000_000).nnz > est.nnz);
    // The default point count: 50 per kernel up to the 2M plateau, 10 per kernel beyond
    // K = 200,000, never more than the typo guard.
    assert_eq!(default_points(1_000), 50_000);
    assert_eq!(default_points(100_000), 2_000_000);
    assert_eq!(default_points(200_000), 2_000_000);
    assert_eq!(default_points(1_000_000), 10_000_000);
    assert_eq!(default_points(usize::MAX), freeform::precompute::MAX_POINTS);
}

#[test]
fn upper_triangle_storage_holds_the_same_sums_and_gives_the_same_basis() {
    use freeform::precompute::stream::assemble_streamed_upper;
    use freeform::precompute::{MatrixStorage, SolverConfig};
    // The same sums as both-triangle storage, bit for bit: each entry is the same running
    // sum, only moved into another layout.
    let (kernels, points, vol, w) = fixture();
    let run = |upper: bool| {
        let assemble = if upper {
            assemble_streamed_upper
        } else {
            assemble_streamed
        };
        let opts = ShapeFunctionOptions::default();
        let Streamed::Assembled(done) =
            assemble(&kernels, &points, &vol, &w, &opts, 97, &Silent).unwrap()
        else {
            panic!("every point of the box is covered");
        };
        done.assembled
    };
    let (full, upper) = (run(false), run(true));
    assert!(full.upper().is_none());
    let pencil = upper.upper().expect("stored as upper triangles");
    assert_eq!(2 * pencil.pattern().nnz() - kernels.len(), full.nnz());
    assert_eq!(upper.nnz(), full.nnz());
    // Mirrored on first use: the both-triangle matrices exactly.
    for (a, b) in [
        (upper.hessian(), full.hessian()),
        (upper.mass(), full.mass()),
    ] {
        assert_eq!(a.col_ptr(), b.col_ptr());
        assert_eq!(a.row_idx(), b.row_idx());
        assert_eq!(a.val(), b.val());
    }

    // The whole precomputation gives the same basis, bit for bit, with the IC(0)
    // preconditioner (the one both storages use at large K; at this size `Auto` factors both
    // triangles exactly): the upper-triangle products add each row's terms in the
    // both-triangle kernel's order (eigen::lobpcg's tests), and the factor gets the same
    // values.
    use freeform::eigen::lobpcg::{LobpcgOptions, PreconditionerKind};
    let ip = box_points([2.0, 1.0, 1.0], 0.08);
    let mat = MaterialField::homogeneous(ip.len(), &Material::default()).unwrap();
    let basis = |storage: MatrixStorage| {
        let opts = BasisOptions {
            kernels: 120,
            modes: 6,
            matrix_storage: storage,
            solver: SolverConfig::Lobpcg(LobpcgOptions {
                preconditioner: PreconditionerKind::IncompleteCholesky,
                ..LobpcgOptions::default()
            }),
            ..BasisOptions::default()
        };
        Problem::from_points(ip.clone(), mat.clone(), &opts, &Silent)
            .unwrap()
            .solve(&Silent)
            .unwrap()
    };
    let (a, b) = (basis(MatrixStorage::Full), basis(MatrixStorage::Upper));
    assert!(!a.report.memory_estimate.upper_triangle);
    assert!(b.report.memory_estimate.upper_triangle);
    assert_eq!(a.basis.eigenvalues, b.basis.eigenvalues);
    assert_eq!(a.basis.coefficients, b.basis.coefficients);

    // A problem stored as the upper triangle (the default for the native solver), solved by
    // a solver that reads both triangles: they are mirrored for it, and it finds the same
    // pairs (to the dense solver's agreement with LOBPCG: the tolerance, 1e-8, relative).
    let auto = BasisOptions {
        kernels: 120,
        modes: 6,
        ..BasisOptions::default()
    };
    let problem = Problem::from_points(ip.clone(), mat.clone(), &auto, &Silent).unwrap();
    assert!(problem.matrices().upper().is_some());
    let dense = problem
        .solve_with(&freeform::eigen::dense::DenseSolver, &Silent)
        .unwrap();
    for (x, y) in dense.basis.eigenvalues.iter().zip(&a.basis.eigenvalues) {
        assert!((x - y).abs() <= 1e-8 * y.abs(), "{x} vs {y}");
    }

    // Only the native solver takes the triangle, and not with boundary regions.
    let dense = BasisOptions {
        matrix_storage: MatrixStorage::Upper,
        solver: SolverConfig::Dense,
        ..BasisOptions::default()
    };
    let err = dense.validate().unwrap_err().to_string();
    assert!(
        err.contains("matrix_storage") && err.contains("LOBPCG"),
        "{err}"
    );
}

#[test]
fn auto_storage_is_the_upper_triangle_where_the_solver_takes_it() {
    use freeform::precompute::{MatrixStorage, MemoryEstimate, SolverConfig};
    let opts = |storage| BasisOptions {
        kernels: 100_000,
        modes: 32,
        matrix_storage: storage,
        ..BasisOptions::default()
    };
    let full = MemoryEstimate::new(&opts(MatrixStorage::Full), 2_000_000);
    let upper = MemoryEstimate::new(&opts(MatrixStorage::Upper), 2_000_000);
    assert!(upper.upper_triangle && !full.upper_triangle);
    // Half the matrices (10 of 20 bytes a both-triangle entry).
    assert!(upper.matrices_bytes < full.matrices_bytes * 11 / 20);
    assert!(upper.total_bytes < full.total_bytes);
    // Auto: the upper triangle for the native solver, both triangles for any other and for a
    // boundary-aware basis (which restricts both).
    let auto = MemoryEstimate::new(&opts(MatrixStorage::Auto), 2_000_000);
    assert_eq!(auto, upper);
    assert!(opts(MatrixStorage::Auto).upper_triangle_storage());
    let dense = BasisOptions {
        solver: SolverConfig::Dense,
        ..opts(MatrixStorage::Auto)
    };
    assert!(!dense.upper_triangle_storage());
    let aware = BasisOptions {
        boundary_regions: vec![Region::Box {
            min: [0.0; 3],
            max: [0.1; 3],
        }],
        ..opts(MatrixStorage::Auto)
    };
    assert!(!aware.upper_triangle_storage());
    assert!(!MemoryEstimate::new(&aware, 2_000_000).upper_triangle);
}
