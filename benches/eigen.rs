//! Eigensolver benchmarks on synthetic 3D grid problems (`freeform::eigen::testing`):
//! - `spmm`: the symmetric sparse x tall-block product in the layouts we tried (row-major
//!   rayon kernel, column-major rayon kernel, faer's `sparse_dense_matmul`), K = 10,648 with
//!   a 123-point stencil, 40 columns;
//! - `solve`: LOBPCG (default options) vs the dense reference on a radius-2 grid Laplacian
//!   with an SPD kernel mass, nev = 17, tol 1e-8, K = 512 and 1,331; LOBPCG alone at
//!   K = 10,648 with nev = 33.
//!
//! `cargo bench --bench eigen`. Larger sizes (K ~ 1e5) take minutes per solve; measure them
//! with the ignored test `eigen::lobpcg::tests::measure_lobpcg` instead.

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion};
use faer::Mat;
use freeform::eigen::dense::DenseSolver;
use freeform::eigen::lobpcg::Lobpcg;
use freeform::eigen::{testing, EigenRequest, Eigensolver};
use freeform::progress::Silent;
use freeform::sparse;
use std::hint::black_box;

fn spmm(c: &mut Criterion) {
    let n = 22;
    let h = testing::grid_laplacian([n, n, n], 3.0);
    let k = h.nrows();
    let b = 40;
    let mut group = c.benchmark_group("spmm");
    group.sample_size(20);
    let x: Vec<f64> = (0..k * b)
        .map(|i| ((i * 7919) % 1000) as f64 / 1000.0)
        .collect();
    let mut y = vec![0.0; k * b];
    let label = format!("K{k}_b{b}");
    group.bench_function(BenchmarkId::new("row_major_rayon", &label), |bench| {
        bench.iter(|| sparse::sym_mul_row_major(h.as_ref(), black_box(&x), b, &mut y, b, b))
    });
    let xc = Mat::<f64>::from_fn(k, b, |i, j| x[i * b + j]);
    let mut yc = Mat::<f64>::zeros(k, b);
    group.bench_function(BenchmarkId::new("col_major_rayon", &label), |bench| {
        bench.iter(|| sparse::sym_mul_block(h.as_ref(), black_box(xc.as_ref()), yc.as_mut()))
    });
    group.bench_function(BenchmarkId::new("faer_sparse_dense", &label), |bench| {
        bench.iter(|| {
            faer::sparse::linalg::matmul::sparse_dense_matmul(
                yc.as_mut(),
                faer::Accum::Replace,
                h.as_ref(),
                black_box(xc.as_ref()),
                1.0,
                faer::Par::rayon(0),
            )
        })
    });
    group.finish();
}

fn solve(c: &mut Criterion) {
    let mut group = c.benchmark_group("solve");
    group.sample_size(10);
    for n in [8usize, 11] {
        let dims = [n, n, n];
        let h = testing::grid_laplacian(dims, 2.0);
        let m = testing::kernel_mass(dims, 2.0, 0.05, 0.5, 1);
        let req = EigenRequest {
            nev: 17,
            tol: 1e-8,
            max_iter: 1000,
        };
        let label = format!("K{}_nev17", h.nrows());
        group.bench_function(BenchmarkId::new("lobpcg", &label), |bench| {
            bench.iter(|| {
                Lobpcg::default()
                    .solve_converged(h.as_ref(), m.as_ref(), &req, &Silent)
                    .expect("lobpcg")
            })
        });
        group.bench_function(BenchmarkId::new("dense", &label), |bench| {
            bench.iter(|| {
                DenseSolver
                    .solve_converged(h.as_ref(), m.as_ref(), &req, &Silent)
                    .expect("dense")
            })
        });
    }
    let n = 22;
    let h = testing::grid_laplacian([n, n, n], 3.0);
    let m = testing::kernel_mass([n, n, n], 3.0, 0.05, 0.5, 1);
    let req = EigenRequest {
        nev: 33,
        tol: 1e-8,
        max_iter: 1000,
    };
    group.bench_function(
        BenchmarkId::new("lobpcg", format!("K{}_nev33", h.nrows())),
        |bench| {
            bench.iter(|| {
                Lobpcg::default()
                    .solve_converged(h.as_ref(), m.as_ref(), &req, &Silent)
                    .expect("lobpcg")
            })
        },
    );
    group.finish();
}

criterion_group!(benches, spmm, solve);
criterion_main!(benches);
