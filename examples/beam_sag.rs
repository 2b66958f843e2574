//! The bend test's largest sag of the free-end corner (5, 0, 0), FEM reference against the
//! reduced model at several K (docs/accuracy.md, "Why the bend's error rises with K").
//!
//! ```sh
//! cargo run --release --example beam_sag -- 16 500,1000,2000,4000 [DENSITY_BOUNDARIES]
//! ```
//!
//! Prints the vertical displacement of the corner every 10 frames (FEM first, then one column
//! per K) and each run's largest sag with its frame. The FEM reference comes from the cache of
//! `freeform beam` (.freeform-cache/fem), computed there when missing.

use freeform::benchmark::{beam_basis, beam_sim_options, ReducedBeamOptions};
use freeform::fem::beam::{run_beam_reference, BeamTest, FemBeamConfig};
use freeform::precompute::DensityBands;
use freeform::progress::Silent;
use freeform::sim::ReducedSim;
use std::path::Path;

type Failure = Box<dyn std::error::Error>;

fn main() -> Result<(), Failure> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let usage = "usage: beam_sag MODES K1,K2,... [DENSITY_BOUNDARIES]";
    let modes: usize = args.first().ok_or(usage)?.parse()?;
    let kernels: Vec<usize> = args
        .get(1)
        .ok_or(usage)?
        .split(',')
        .map(str::parse)
        .collect::<Result<_, _>>()?;
    let boundaries: f64 = args.get(2).map_or(Ok(1.0), |s| s.parse())?;
    let fem = FemBeamConfig::reference(BeamTest::Bend);
    let reference = run_beam_reference(&fem, Some(Path::new(".freeform-cache/fem")), &Silent)?;
    // The FE node nearest the free end's lower corner (5, 0, 0).
    let corner = |p: &[f64; 3]| (p[0] - fem.size[0]).powi(2) + p[1] * p[1] + p[2] * p[2];
    let tip = (0..reference.rest.len())
        .min_by(|&a, &b| corner(&reference.rest[a]).total_cmp(&corner(&reference.rest[b])))
        .ok_or("the reference has no nodes")?;
    let sag = |frame: &[[f64; 3]]| frame[tip][1] - reference.rest[tip][1];
    let mut runs = vec![reference
        .frames
        .iter()
        .map(|f| sag(f))
        .collect::<Vec<f64>>()];
    for &k in &kernels {
        let opts = ReducedBeamOptions {
            modes,
            kernels: k,
            density: DensityBands {
                boundaries,
                ..DensityBands::off()
            },
            ..ReducedBeamOptions::default()
        };
        let basis = beam_basis(&fem, &opts, &Silent)?;
        let sim_opts = beam_sim_options(&fem, opts.cubature, opts.newton, None);
        let run = &basis.run;
        let mut sim = ReducedSim::new(&run.basis, &run.points, &run.material, &sim_opts)?;
        let weights = run.basis.weights(&reference.rest)?;
        let mut track = Vec::with_capacity(fem.steps);
        for _ in 0..fem.steps {
            sim.step();
            track.push(sag(&sim.positions(&reference.rest, &weights)));
        }
        runs.push(track);
    }
    let names: Vec<String> = std::iter::once("FEM".to_string())
        .chain(kernels.iter().map(|k| format!("K={k}")))
        .collect();
    println!("frame {}", names.join(" "));
    for f in (0..fem.steps).step_by(10) {
        let row: Vec<String> = runs.iter().map(|r| format!("{:.4}", r[f])).collect();
        println!("{f:5} {}", row.join(" "));
    }
    for (name, r) in names.iter().zip(&runs) {
        let (frame, low) = r
            .iter()
            .enumerate()
            .fold((0, 0.0f64), |b, (i, &v)| if v < b.1 { (i, v) } else { b });
        println!("{name}: largest sag {:.3} m at frame {frame}", -low);
    }
    Ok(())
}
