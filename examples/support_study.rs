//! Measures how the kernel support rule (factor x distance to the n-th nearest centre) and the
//! window function trade accuracy against cost and conditioning. Prints one table row per
//! setting: first Neumann eigenvalues of the 2 x 1 x 1 box against the analytic ones, the
//! smallest moment-matrix reciprocal condition number, cond(M), kernels per point and H nnz.
//!
//! Run: `cargo run --release --example support_study` (numbers in docs/math.md).

#![allow(clippy::needless_range_loop)] // index loops mirror the formulas

use freeform::eigen::dense::DenseSolver;
use freeform::eigen::{EigenRequest, Eigensolver};
use freeform::geometry::Aabb;
use freeform::material::{Material, MaterialField};
use freeform::precompute::assembly::assemble;
use freeform::precompute::centers::farthest_point_sampling;
use freeform::precompute::rkpm::{
    evaluate, reproducing_error, support_radii, KernelType, Kernels, ShapeFunctionOptions,
    SupportOptions,
};
use freeform::precompute::sampling::grid_points;
use freeform::progress::Silent;
use freeform::Point3;
use std::f64::consts::PI;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let k = 600;
    let aabb = Aabb {
        min: [0.0; 3],
        max: [2.0, 1.0, 1.0],
    };
    let ip = grid_points(
        &aabb,
        (2.0f64 / 30_000.0).cbrt(),
        None,
        &|p: &[Point3]| vec![true; p.len()],
    )?;
    let idx = farthest_point_sampling(&ip.points, k)?;
    let centers: Vec<Point3> = idx.iter().map(|&i| ip.points[i]).collect();
    let mat = MaterialField::homogeneous(ip.len(), &Material::default())?;
    let (l, m) = Material::default().lame();
    let exact = [
        PI * PI / 4.0,
        PI * PI,
        PI * PI,
        PI * PI,
        1.25 * PI * PI,
        1.25 * PI * PI,
    ];
    println!("box 2x1x1, K = {k}, N = {} grid points; eigenvalue errors relative to the analytic Neumann values", ip.len());
    println!("| kernel | factor | n | err lambda1 | max err lambda1..6 | min rcond | cond(M) | kernels/point | H nnz/row | repro err |");
    println!("|---|---|---|---|---|---|---|---|---|---|");
    let settings: Vec<(KernelType, f64, usize)> = vec![
        (KernelType::Cubic, 1.5, 4),
        (KernelType::Cubic, 1.75, 4),
        (KernelType::Cubic, 2.0, 4),
        (KernelType::Cubic, 2.5, 4),
        (KernelType::Cubic, 3.0, 4),
        (KernelType::Cubic, 2.0, 1),
        (KernelType::Cubic, 1.5, 8),
        (KernelType::Quartic, 2.0, 4),
        (KernelType::Gaussian, 2.0, 4),
        (KernelType::Gaussian, 2.5, 4),
    ];
    for (kind, factor, neighbor) in settings {
        let radii = support_radii(&centers, &SupportOptions { factor, neighbor })?;
        let kernels = Kernels {
            centers: centers.clone(),
            radii,
            kind,
        };
        let (sf, stats) = evaluate(
            &kernels,
            &ip.points,
            &ShapeFunctionOptions { min_rcond: 1e-300 },
        );
        if !stats.failed.is_empty() || stats.min_rcond < 1e-12 {
            println!("| {} | {factor} | {neighbor} | - | - | {:.1e} | - | {:.1} | - | singular at {} points |", kind.name(), stats.min_rcond, stats.mean_cover, stats.failed.len());
            continue;
        }
        let repro = reproducing_error(&kernels, &ip.points, &sf);
        let a = assemble(&sf, &ip.volumes, &mat.hessian_weights(), k)?;
        let sol = DenseSolver.solve(
            a.hessian(),
            a.mass(),
            &EigenRequest {
                nev: 7,
                tol: 1e-10,
                max_iter: 1,
            },
            &Silent,
        )?;
        let ev: Vec<f64> = sol.values.iter().map(|v| v / (l + 4.0 * m)).collect();
        let errs: Vec<f64> = (0..6).map(|i| (ev[i + 1] - exact[i]) / exact[i]).collect();
        let md = a.mass().to_dense();
        let em = md
            .self_adjoint_eigenvalues(faer::Side::Lower)
            .map_err(|e| format!("{e:?}"))?;
        println!(
            "| {} | {factor} | {neighbor} | {:+.2e} | {:.2e} | {:.1e} | {:.1e} | {:.1} | {:.0} | {:.0e} |",
            kind.name(),
            errs[0],
            errs.iter().fold(0.0f64, |x, e| x.max(e.abs())),
            stats.min_rcond,
            em[em.len() - 1] / em[0],
            stats.mean_cover,
            a.hessian().compute_nnz() as f64 / k as f64,
            repro.max()
        );
    }
    Ok(())
}
