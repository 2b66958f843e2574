//! The synthetic Gaussian-splat toys of the splat scenes (`examples/plinko_splats.toml`,
//! `examples/container_splats.toml`): splats on a jittered 1 cm lattice filling a shape, each
//! toy centred at the origin, SH degree 0, written as 3DGS PLY files.
//!
//!     cargo run --release --example splat_toys [-- OUT_DIR]
//!
//! OUT_DIR (default `examples/data/splats`) gets `block.ply` (a 0.1 m cube with rounded
//! edges), `slab.ply` (0.14 x 0.07 x 0.1 m), `egg.ply` (an ellipsoid of radii 0.045, 0.06 and
//! 0.045 m) and `dog.ply` (a dog toy of ellipsoids and legs, 0.17 m long), the files the
//! scenes read.

use freeform::io::splat::{write_splats, Splats};
use freeform::random::SplitMix64;
use freeform::Point3;
use std::path::PathBuf;

/// Lattice spacing of the splat centres, metres.
const SPACING: f64 = 0.01;

/// Whether `p` (metres, toy frame) is inside an ellipsoid of `radii` centred at `c`.
fn in_ellipsoid(p: &Point3, c: Point3, radii: [f64; 3]) -> bool {
    (0..3)
        .map(|a| ((p[a] - c[a]) / radii[a]).powi(2))
        .sum::<f64>()
        <= 1.0
}

/// Whether `p` is inside the box of half-sizes `half` centred at the origin, its edges rounded
/// by `round` metres.
fn in_rounded_box(p: &Point3, half: [f64; 3], round: f64) -> bool {
    let q: [f64; 3] = std::array::from_fn(|a| (p[a].abs() - (half[a] - round)).max(0.0));
    q.iter().map(|v| v * v).sum::<f64>() <= round * round
}

/// A dog toy facing +x: body, head, snout, four legs and a tail.
fn in_dog(p: &Point3) -> bool {
    let leg = |x: f64, z: f64| {
        let r = ((p[0] - x).powi(2) + (p[2] - z).powi(2)).sqrt();
        r <= 0.013 && p[1] >= -0.065 && p[1] <= -0.01
    };
    in_ellipsoid(p, [0.0, 0.0, 0.0], [0.065, 0.032, 0.03])
        || in_ellipsoid(p, [0.06, 0.03, 0.0], [0.028, 0.026, 0.025])
        || in_ellipsoid(p, [0.088, 0.024, 0.0], [0.018, 0.012, 0.014])
        || leg(-0.04, -0.016)
        || leg(-0.04, 0.016)
        || leg(0.04, -0.016)
        || leg(0.04, 0.016)
        || in_ellipsoid(p, [-0.072, 0.025, 0.0], [0.02, 0.007, 0.007])
}

/// Splats on the jittered lattice points inside `inside` (within `extent` of the origin), with
/// random small scales and orientations and the colour `rgb` (SH dc).
fn toy(
    inside: impl Fn(&Point3) -> bool,
    extent: f64,
    rgb: [f64; 3],
    seed: u64,
) -> Result<Splats, Box<dyn std::error::Error>> {
    let mut rng = SplitMix64::new(seed);
    let n = (extent / SPACING).ceil() as i64;
    let mut means = Vec::new();
    for i in -n..=n {
        for j in -n..=n {
            for k in -n..=n {
                let p: Point3 = [i, j, k].map(|v| (v as f64 + 0.5) * SPACING);
                let p = p.map(|c| c + 0.2 * SPACING * rng.uniform(-1.0, 1.0));
                if inside(&p) {
                    means.push(p);
                }
            }
        }
    }
    let count = means.len();
    let log_scales = (0..count)
        .map(|_| std::array::from_fn(|_| (0.004 + 0.003 * rng.uniform(0.0, 1.0)).ln()))
        .collect();
    let rotations = (0..count)
        .map(|_| {
            let q: [f64; 4] = std::array::from_fn(|_| rng.uniform(-1.0, 1.0));
            let norm = q.iter().map(|c| c * c).sum::<f64>().sqrt().max(1e-12);
            q.map(|c| c / norm)
        })
        .collect();
    let opacities = (0..count).map(|_| rng.uniform(1.0, 4.0)).collect();
    let sh_dc = (0..count)
        .map(|_| rgb.map(|c| c + 0.15 * rng.uniform(-1.0, 1.0)))
        .collect();
    Ok(Splats::new(
        means,
        log_scales,
        rotations,
        opacities,
        sh_dc,
        Vec::new(),
        0,
    )?)
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let out = std::env::args()
        .nth(1)
        .map_or_else(|| PathBuf::from("examples/data/splats"), PathBuf::from);
    std::fs::create_dir_all(&out)?;
    let toys = [
        (
            "block",
            toy(
                |p| in_rounded_box(p, [0.05; 3], 0.01),
                0.05,
                [1.2, -0.6, -0.8],
                1,
            )?,
        ),
        (
            "slab",
            toy(
                |p| in_rounded_box(p, [0.07, 0.035, 0.05], 0.008),
                0.07,
                [-0.8, 0.9, -0.6],
                2,
            )?,
        ),
        (
            "egg",
            toy(
                |p| in_ellipsoid(p, [0.0; 3], [0.045, 0.06, 0.045]),
                0.06,
                [1.3, 1.1, -1.0],
                3,
            )?,
        ),
        ("dog", toy(in_dog, 0.1, [0.9, 0.2, -1.2], 4)?),
    ];
    for (name, splats) in &toys {
        let path = out.join(format!("{name}.ply"));
        write_splats(&path, splats)?;
        println!("{}: {} splats", path.display(), splats.len());
    }
    Ok(())
}
