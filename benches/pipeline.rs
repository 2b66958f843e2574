//! Per-stage benchmarks of the precomputation on the standard beam (box 5 x 1 x 1), at
//! K = 250, 1000, 4000 kernels with N = 50 K integration points, to show how each stage
//! grows with K and N. `cargo bench --bench pipeline`; numbers in docs/performance.md.

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion};
use freeform::geometry::ShapeOptions;
use freeform::io::read_shape;
use freeform::material::{Material, MaterialField};
use freeform::precompute::assembly::assemble;
use freeform::precompute::centers::{farthest_point_sampling, morton_order};
use freeform::precompute::rkpm::{
    covering_kernels, evaluate_on, support_radii, KernelType, Kernels, ShapeFunctionOptions,
    SupportOptions,
};
use freeform::precompute::sampling::{CloudVolumeOptions, Resolution};
use freeform::precompute::{default_points, sample_shape};
use freeform::Point3;
use std::hint::black_box;

fn stages(c: &mut Criterion) {
    let shape = read_shape("box:5,1,1", &ShapeOptions::default()).expect("beam");
    let mut group = c.benchmark_group("stages");
    group.sample_size(10);
    for k in [250usize, 1000, 4000] {
        let n = default_points(k).max(50 * k);
        let ip = sample_shape(&shape, Resolution::Count(n), &CloudVolumeOptions::default())
            .expect("sampling");
        let label = format!("K{k}_N{}", ip.len());
        group.bench_function(BenchmarkId::new("sampling", &label), |b| {
            b.iter(|| {
                sample_shape(&shape, Resolution::Count(n), &CloudVolumeOptions::default())
                    .expect("sampling")
            })
        });
        group.bench_function(BenchmarkId::new("fps", &label), |b| {
            b.iter(|| farthest_point_sampling(black_box(&ip.points), k).expect("fps"))
        });
        let mut idx = farthest_point_sampling(&ip.points, k).expect("fps");
        morton_order(&ip.points, &mut idx);
        let centers: Vec<Point3> = idx.iter().map(|&i| ip.points[i]).collect();
        let radii = support_radii(&centers, &SupportOptions::default()).expect("radii");
        let kernels = Kernels {
            centers,
            radii,
            kind: KernelType::Cubic,
        };
        group.bench_function(BenchmarkId::new("neighbors", &label), |b| {
            b.iter(|| covering_kernels(&kernels, black_box(&ip.points)))
        });
        let pattern = covering_kernels(&kernels, &ip.points);
        let opts = ShapeFunctionOptions::default();
        group.bench_function(BenchmarkId::new("shape_functions", &label), |b| {
            b.iter(|| evaluate_on(&kernels, &ip.points, pattern.clone(), &opts))
        });
        let (sf, _) = evaluate_on(&kernels, &ip.points, pattern, &opts);
        let w = MaterialField::homogeneous(ip.len(), &Material::default())
            .expect("material")
            .hessian_weights();
        group.bench_function(BenchmarkId::new("assembly", &label), |b| {
            b.iter(|| assemble(&sf, &ip.volumes, &w, k).expect("assembly"))
        });
    }
    group.finish();
}

criterion_group!(benches, stages);
criterion_main!(benches);
