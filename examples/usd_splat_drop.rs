//! A ball of N Gaussian splats (default 20,000, SH degree 3) dropped on a floor for S steps
//! (default 150), its frames written once as PLY and once as one USD stage, with the SH colour
//! turned with each splat (the default) and without: the time of each run, the writing cost
//! (a run minus the same run without frames) and the bytes written. The numbers of
//! docs/usd.md ("Cost").
//!
//!     cargo run --release --example usd_splat_drop [-- N S OUT_DIR]
//!
//! OUT_DIR (default `target/usd_splat_drop`) gets the splat file, the scene, the basis cache
//! and the frames of both runs (`ply/`, `usd/run.usda`).

use freeform::io::splat::{write_splats, Splats};
use freeform::progress::Silent;
use freeform::random::SplitMix64;
use freeform::scene::{run, Format, RunSettings, Scene};
use std::path::Path;

/// N splats filling a ball of radius `r` (metres) centred at the origin.
fn ball_of_splats(n: usize, r: f64, seed: u64) -> Result<Splats, Box<dyn std::error::Error>> {
    let mut rng = SplitMix64::new(seed);
    let mut means = Vec::with_capacity(n);
    while means.len() < n {
        let p: [f64; 3] = std::array::from_fn(|_| rng.uniform(-r, r));
        if p.iter().map(|c| c * c).sum::<f64>() <= r * r {
            means.push(p);
        }
    }
    let log_scales = (0..n)
        .map(|_| std::array::from_fn(|_| (0.004 + 0.008 * rng.uniform(0.0, 1.0)).ln()))
        .collect();
    let rotations = (0..n)
        .map(|_| {
            let q: [f64; 4] = std::array::from_fn(|_| rng.uniform(-1.0, 1.0));
            let norm = q.iter().map(|c| c * c).sum::<f64>().sqrt().max(1e-12);
            q.map(|c| c / norm)
        })
        .collect();
    let opacities = (0..n).map(|_| rng.uniform(-2.0, 4.0)).collect();
    // Warm at the top, cool at the bottom: the colour shows how the ball turns and squashes.
    let sh_dc = means
        .iter()
        .map(|p| {
            let warm = (p[1] + r) / (2.0 * r);
            [2.5 * warm - 1.0, 0.3, 1.5 - 2.5 * warm]
        })
        .collect();
    let sh_rest = (0..n * 45).map(|_| 0.1 * rng.uniform(-1.0, 1.0)).collect();
    Ok(Splats::new(
        means, log_scales, rotations, opacities, sh_dc, sh_rest, 3,
    )?)
}

fn bytes_under(dir: &Path) -> u64 {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return 0;
    };
    entries
        .flatten()
        .map(|e| match e.metadata() {
            Ok(m) if m.is_dir() => bytes_under(&e.path()),
            Ok(m) => m.len(),
            Err(_) => 0,
        })
        .sum()
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let n: usize = args
        .get(1)
        .map(|a| a.parse())
        .transpose()?
        .unwrap_or(20_000);
    let steps: usize = args.get(2).map(|a| a.parse()).transpose()?.unwrap_or(150);
    let dir = Path::new(args.get(3).map_or("target/usd_splat_drop", String::as_str)).to_path_buf();
    std::fs::create_dir_all(&dir)?;
    write_splats(&dir.join("ball.ply"), &ball_of_splats(n, 0.3, 7)?)?;
    let scene_text = format!(
        "[simulation]\ndt = 0.005\nsteps = {steps}\ngravity = [0.0, -9.81, 0.0]\n\n\
         [solver]\nhessian = \"newton\"\ncubature = 2000\n\n\
         [[object]]\nname = \"splat-ball\"\nshape = \"ball.ply\"\n\
         material = {{ youngs = 2e5, poisson = 0.4, density = 1000.0 }}\n\
         basis = {{ kernels = 400, modes = 12 }}\n\
         placement = {{ translation = [0.0, 0.5, 0.0], angular_velocity = [0.0, 0.0, -2.0] }}\n\n\
         [[collider]]\nname = \"floor\"\n\
         shape = {{ plane = {{ point = [0.0, 0.0, 0.0], normal = [0.0, 1.0, 0.0] }} }}\n"
    );
    std::fs::write(dir.join("drop.toml"), &scene_text)?;
    let base = Scene::from_toml(&scene_text)?;
    let run_with = |formats: Option<Vec<Format>>,
                    rotate_sh: bool,
                    sub: &str|
     -> Result<(f64, u64), Box<dyn std::error::Error>> {
        let mut scene = base.clone();
        scene.output.rotate_splat_sh = rotate_sh;
        let out = dir.join(sub);
        let _ = std::fs::remove_dir_all(&out);
        if let Some(f) = &formats {
            scene.output.formats = f.clone();
        }
        let settings = RunSettings {
            base_dir: dir.clone(),
            out: formats.is_some().then(|| out.clone()),
            strict: false,
        };
        let summary = run(&scene, &settings, &Silent)?;
        Ok((summary.total_s, bytes_under(&out)))
    };
    // The first run fills the basis cache; the others read it.
    run_with(None, true, "none")?;
    println!(
        "{n} splats (SH degree 3), {steps} steps, {} frames",
        steps + 1
    );
    for rotate_sh in [true, false] {
        let (none_a, _) = run_with(None, rotate_sh, "none")?;
        let (ply, ply_bytes) = run_with(Some(vec![Format::Ply]), rotate_sh, "ply")?;
        let (usd, usd_bytes) = run_with(Some(vec![Format::Usd]), rotate_sh, "usd")?;
        let (none_b, _) = run_with(None, rotate_sh, "none")?;
        let none = 0.5 * (none_a + none_b);
        println!("rotate_splat_sh = {rotate_sh}:");
        println!("  no frames: {none_a:.2} s, {none_b:.2} s");
        println!(
            "  PLY frames: {ply:.2} s (writing {:.2} s), {:.1} MB",
            ply - none,
            ply_bytes as f64 / 1e6
        );
        println!(
            "  USD stage:  {usd:.2} s (writing {:.2} s), {:.1} MB",
            usd - none,
            usd_bytes as f64 / 1e6
        );
        println!(
            "  USD / PLY writing time: {:.2}",
            (usd - none) / (ply - none).max(1e-9)
        );
    }
    Ok(())
}
