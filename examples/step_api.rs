//! The live simulation API: step the cantilever bend scene (examples/beam_bend.toml), print
//! the beam tip's position after every step, and half-way through raise the held end by
//! 0.5 m over 0.5 s by giving its boundary a new keyframed motion.
//!
//!   cargo run --release --example step_api
//!
//! The basis is cached next to the scene (`examples/.freeform-cache`), as with
//! `freeform run examples/beam_bend.toml`.

use freeform::progress::Silent;
use freeform::scene::{RunSettings, Scene, World};
use freeform::sim::motion::{Keyframe, Motion};
use std::path::Path;

fn main() -> Result<(), freeform::Error> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("examples");
    let scene = Scene::load(&dir.join("beam_bend.toml"))?;
    let settings = RunSettings {
        base_dir: dir,
        ..RunSettings::default()
    };
    let mut world = World::new(&scene, &settings, &Silent)?;
    let beam = world
        .object_index("beam")
        .expect("the bend scene has a beam");

    // The render point nearest the free end's centre, (5, 0.5, 0.5) m at rest.
    let rest = world.object(beam).render_rest();
    let dist = |p: &[f64; 3]| (p[0] - 5.0).powi(2) + (p[1] - 0.5).powi(2) + (p[2] - 0.5).powi(2);
    let tip = (0..rest.len())
        .min_by(|&a, &b| dist(&rest[a]).total_cmp(&dist(&rest[b])))
        .expect("the beam has render points");
    let tip_rest = rest[tip];
    println!(
        "tip at rest: ({:.3}, {:.3}, {:.3}) m",
        tip_rest[0], tip_rest[1], tip_rest[2]
    );
    println!("step   time [s]   tip x [m]   tip y [m]   tip z [m]   iterations");

    let steps = scene.simulation.steps;
    for step in 1..=steps {
        if step == steps / 2 + 1 {
            // Raise the held end: from where it is now to 0.5 m higher over 0.5 s, then hold.
            let now = world.time();
            let keyframe = |time: f64, lift: f64| Keyframe {
                time,
                translation: [0.0, lift, 0.0],
                rotation: None,
            };
            world.set_boundary_motion(
                beam,
                0,
                Motion::Keyframes {
                    pivot: [0.0; 3],
                    frames: vec![keyframe(now, 0.0), keyframe(now + 0.5, 0.5)],
                },
            )?;
            println!("-- t = {now:.2} s: the held end starts rising by 0.5 m over 0.5 s");
        }
        let reports = world.step()?;
        let x = world.object(beam).render_positions()[tip];
        println!(
            "{step:4}   {:8.3}   {:9.4}   {:9.4}   {:9.4}   {:10}",
            world.time(),
            x[0],
            x[1],
            x[2],
            reports[beam].solve.iterations
        );
    }
    for w in world.warnings() {
        println!("warning: {w}");
    }
    Ok(())
}
