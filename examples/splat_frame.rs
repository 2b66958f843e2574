//! Cost of writing one deformed frame of N 3D Gaussian splats (default 1,000,000, SH degree 3,
//! 62 float properties, 248 bytes per splat) with a basis of m = 16 modes, split into: the
//! deformation map at the centres (x and F), the splat transform (covariance push-forward and
//! decomposition, SH rotation) and the file write. The numbers of docs/performance.md
//! ("Splat frames").
//!
//!     cargo run --release --example splat_frame [-- N]
//!
//! The splats fill the 5 x 1 x 1 m beam of examples/beam_bend.toml; the basis there has
//! K = 1000 kernels, here K = 300 (faster to build; a frame's cost depends on N and m, not K).
//! The skinning weights at the centres are evaluated once per object (setup, reported apart).

use freeform::geometry::ShapeOptions;
use freeform::io::read_shape;
use freeform::io::splat::{write_splats_moved, MovedSplats, Splats};
use freeform::precompute::{build_basis, BasisOptions};
use freeform::progress::Silent;
use freeform::report::Stopwatch;
use freeform::sim::deformation::deformation_gradients;
use freeform::sim::deformation::map_points;
use freeform::sim::elastic::Layout;
use freeform::sim::gaussian::deform_splats;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let n: usize = std::env::args()
        .nth(1)
        .map(|a| a.parse())
        .transpose()?
        .unwrap_or(1_000_000);
    let clock = Stopwatch::start();
    let shape = read_shape("box:5,1,1", &ShapeOptions::default())?;
    let opts = BasisOptions {
        kernels: 300,
        modes: 16,
        ..BasisOptions::default()
    };
    let basis = build_basis(&shape, &opts, &Silent)?.basis;
    println!("basis (K = 300, m = 16): {:.1} s", clock.elapsed());

    let mut rng = freeform::random::SplitMix64::new(1);
    let mut r = |lo: f64, hi: f64| lo + (hi - lo) * rng.next_f64();
    let means: Vec<[f64; 3]> = (0..n)
        .map(|_| [r(0.05, 4.95), r(0.05, 0.95), r(0.05, 0.95)])
        .collect();
    let log_scales = (0..n)
        .map(|_| [r(-5.0, -3.0), r(-5.0, -3.0), r(-5.0, -3.0)])
        .collect();
    let rotations = (0..n)
        .map(|_| {
            let q = [r(-1.0, 1.0), r(-1.0, 1.0), r(-1.0, 1.0), r(-1.0, 1.0)];
            let l = q.iter().map(|v| v * v).sum::<f64>().sqrt();
            q.map(|v| v / l)
        })
        .collect();
    let opacities = (0..n).map(|_| r(-2.0, 2.0)).collect();
    let dc = (0..n)
        .map(|_| [r(-1.0, 1.0), r(-1.0, 1.0), r(-1.0, 1.0)])
        .collect();
    let rest = (0..n * 45).map(|_| r(-0.2, 0.2)).collect();
    let splats = Splats::new(means, log_scales, rotations, opacities, dc, rest, 3)?;

    let clock = Stopwatch::start();
    let w = basis.weights(&splats.means)?;
    println!(
        "setup: skinning weights and gradients at {n} centres: {:.2} s (once per object)",
        clock.elapsed()
    );
    let layout = Layout {
        handles: basis.modes(),
    };
    let z: Vec<f64> = (0..layout.dofs()).map(|_| r(-0.02, 0.02)).collect();
    let path =
        std::env::temp_dir().join(format!("freeform_splat_frame_{}.ply", std::process::id()));
    println!(
        "| run | x and F (s) | transform, SH on (s) | transform, SH off (s) | write (s) | MB |"
    );
    println!("|---|---|---|---|---|---|");
    for run in 1..=3 {
        let clock = Stopwatch::start();
        let x = map_points(layout, &z, &splats.means, &w);
        let f = deformation_gradients(layout, &z, &splats.means, &w);
        let t_map = clock.elapsed();
        let clock = Stopwatch::start();
        let off = deform_splats(
            &f,
            &splats.log_scales,
            &splats.rotations,
            &splats.sh_rest,
            3,
            false,
        );
        let t_off = clock.elapsed();
        drop(off);
        let clock = Stopwatch::start();
        let d = deform_splats(
            &f,
            &splats.log_scales,
            &splats.rotations,
            &splats.sh_rest,
            3,
            true,
        );
        let t_on = clock.elapsed();
        let moved = MovedSplats {
            means: x,
            log_scales: d.log_scales,
            rotations: d.rotations,
            sh_rest: d.sh_rest,
        };
        let clock = Stopwatch::start();
        write_splats_moved(&path, &splats, &moved)?;
        let t_write = clock.elapsed();
        let mb = std::fs::metadata(&path)?.len() as f64 / 1e6;
        println!("| {run} | {t_map:.3} | {t_on:.3} | {t_off:.3} | {t_write:.3} | {mb:.0} |");
    }
    std::fs::remove_file(&path)?;
    Ok(())
}
