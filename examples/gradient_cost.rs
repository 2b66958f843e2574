//! What a reverse pass costs against the forward run it reverses (docs/gradients.md): the
//! standard beam's bend, m = 16, K = 1,000, 200 steps, recorded, then the gradient of the
//! mean squared tip displacement with respect to E, nu, rho, gravity and the initial state.
//!
//!   cargo run --release --example gradient_cost [-- --steps 200 --modes 16 --kernels 1000]
//!
//! Prints the forward and backward wall times, the tape's bytes and the peak memory, as one
//! JSON line at the end.
//!
//! With `--scene FILE.toml` it records a scene's world instead (`--steps`: its own count by
//! default), objects in contact solved as islands, and reverses a loss on every object's z
//! (the sum over frames and objects of the mean of z): the cost of reversing island steps.
//!
//!   cargo run --release --example gradient_cost -- --scene examples/stack.toml

use freeform::benchmark::{beam_basis, beam_sim_options, ReducedBeamOptions};
use freeform::fem::beam::{BeamTest, FemBeamConfig};
use freeform::progress::Silent;
use freeform::report::peak_memory_bytes;
use freeform::sim::gradient::{positions_adjoint, Recording};
use freeform::sim::{NewtonOptions, ReducedSim};

fn arg(name: &str, default: usize) -> usize {
    let args: Vec<String> = std::env::args().collect();
    args.iter()
        .position(|a| a == name)
        .and_then(|i| args.get(i + 1))
        .map_or(default, |v| v.parse().expect("a count"))
}

fn main() -> freeform::Result<()> {
    let args: Vec<String> = std::env::args().collect();
    if let Some(i) = args.iter().position(|a| a == "--scene") {
        return scene_cost(args.get(i + 1).expect("--scene FILE.toml"));
    }
    let steps = arg("--steps", 200);
    let fem = FemBeamConfig::reference(BeamTest::Bend);
    let opts = ReducedBeamOptions {
        modes: arg("--modes", 16),
        kernels: arg("--kernels", 1000),
        boundaries: freeform::precompute::BoundaryModes::Aware,
        ..ReducedBeamOptions::default()
    };
    let basis = beam_basis(&fem, &opts, &Silent)?;
    let run = &basis.run;
    let sim_opts = beam_sim_options(&fem, opts.cubature, NewtonOptions::default(), None);
    let mut sim = ReducedSim::new(&run.basis, &run.points, &run.material, &sim_opts)?;
    // The loss: mean squared displacement of the free end's corner points.
    let tip: Vec<[f64; 3]> = vec![
        [5.0, 0.0, 0.0],
        [5.0, 1.0, 0.0],
        [5.0, 0.0, 1.0],
        [5.0, 1.0, 1.0],
    ];
    let w = run.basis.weights(&tip)?;
    let mut rec = Recording::start(&sim, steps)?;
    for _ in 0..steps {
        rec.step(&mut sim)?;
    }
    let forward_s = rec.forward_s();
    let tape_bytes = rec.tape_bytes();
    let mut dl_dz = vec![Vec::new(); steps + 1];
    for (t, slot) in dl_dz.iter_mut().enumerate().skip(1) {
        let z = rec.state(t).unwrap_or_default();
        let x = freeform::sim::object::map_points(sim.layout(), z, &tip, &w);
        let g: Vec<[f64; 3]> = x
            .iter()
            .zip(&tip)
            .map(|(xi, xr)| {
                let s = 2.0 / (steps * tip.len()) as f64;
                [
                    s * (xi[0] - xr[0]),
                    s * (xi[1] - xr[1]),
                    s * (xi[2] - xr[2]),
                ]
            })
            .collect();
        *slot = positions_adjoint(sim.layout(), &tip, &w, &g)?;
    }
    // What one step's exact Hessian costs (the reverse pass builds one per step).
    let clock = std::time::Instant::now();
    let builds = 20;
    for _ in 0..builds {
        let h = sim
            .elastic()
            .hessian(sim.z(), freeform::sim::elastic::Projection::None);
        std::hint::black_box(h);
    }
    let hessian_s = clock.elapsed().as_secs_f64() / builds as f64;
    let direct = rec.clone().backward_direct(&sim, &dl_dz)?;
    let grads = rec.backward(&sim, &dl_dz)?;
    // The default pass against the one that forms H at every step: the same gradient to the
    // conjugate gradients' tolerance.
    let rel = |a: f64, b: f64| (a - b).abs() / b.abs();
    println!(
        "against forming H at every step ({:.3} s): dL/dE differs by {:.1e}, dL/dz0 by {:.1e} \
         (relative)",
        direct.backward_s,
        rel(grads.youngs_total(), direct.youngs_total()),
        grads
            .z0
            .iter()
            .zip(&direct.z0)
            .map(|(a, b)| (a - b) * (a - b))
            .sum::<f64>()
            .sqrt()
            / direct.z0.iter().map(|b| b * b).sum::<f64>().sqrt()
    );
    let density = grads.density(&run.points, &run.basis.weights(&run.points.points)?)?;
    println!(
        "dL/dE {:.6e} per Pa, dL/dnu {:.6e}, dL/drho {:.6e}, dL/dg {:?}",
        grads.youngs_total(),
        grads.poisson_total(),
        density.iter().sum::<f64>(),
        grads.gravity
    );
    println!(
        "forward {forward_s:.3} s ({steps} steps), backward {:.3} s: {:.2}x; tape {tape_bytes} bytes",
        grads.backward_s,
        grads.backward_s / forward_s
    );
    println!(
        "the reverse pass formed {} exact Hessians and took {} Hessian-vector products",
        grads.exact_hessians, grads.hessian_products
    );
    println!(
        "the elastic term's exact Hessian: {:.2} ms per build, {:.0}% of the backward",
        1e3 * hessian_s,
        100.0 * hessian_s * grads.exact_hessians as f64 / grads.backward_s
    );
    println!(
        "{{\"steps\": {steps}, \"modes\": {}, \"kernels\": {}, \"forward_s\": {forward_s:.4}, \
         \"backward_s\": {:.4}, \"ratio\": {:.3}, \"hessian_ms\": {:.3}, \"exact_hessians\": {}, \
         \"hessian_products\": {}, \"direct_backward_s\": {:.4}, \"tape_bytes\": {tape_bytes}, \
         \"peak_memory_bytes\": {}}}",
        opts.modes,
        opts.kernels,
        grads.backward_s,
        grads.backward_s / forward_s,
        1e3 * hessian_s,
        grads.exact_hessians,
        grads.hessian_products,
        direct.backward_s,
        peak_memory_bytes().unwrap_or(0)
    );
    Ok(())
}

/// Record the world of the scene `path` and reverse a loss on every object's z.
fn scene_cost(path: &str) -> freeform::Result<()> {
    use freeform::scene::{RunSettings, Scene, World};
    // Paths in a scene are relative to its file, as for `freeform run`.
    let file = std::path::Path::new(path);
    let scene = Scene::load(file)?;
    if let Some(dir) = file.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::env::set_current_dir(dir).map_err(|source| freeform::Error::Io {
            path: dir.to_path_buf(),
            source,
        })?;
    }
    let mut world = World::new(&scene, &RunSettings::default(), &Silent)?;
    let steps = arg("--steps", scene.simulation.steps);
    let mut rec = world.record(steps)?;
    let clock = std::time::Instant::now();
    let mut island_steps = 0;
    for _ in 0..steps {
        world.step_recorded(&mut rec)?;
        let row = world.contact_summary().and_then(|c| c.steps.last());
        if row.is_some_and(|r| !r.islands.is_empty()) {
            island_steps += 1;
        }
    }
    let forward_s = clock.elapsed().as_secs_f64();
    let largest = rec.largest_island();
    let dl: Vec<Vec<Vec<f64>>> = world
        .objects()
        .iter()
        .map(|o| {
            let n = o.sim().z().len();
            vec![vec![1.0 / n as f64; n]; steps + 1]
        })
        .collect();
    let clock = std::time::Instant::now();
    let grads = rec.backward(&world, &dl)?;
    let backward_s = clock.elapsed().as_secs_f64();
    let hessians: usize = grads.objects.iter().map(|g| g.exact_hessians).sum();
    println!(
        "{path}: {} objects, {steps} steps, {island_steps} with islands (largest {largest}); \
         forward {forward_s:.3} s, backward {backward_s:.3} s: {:.2}x; {hessians} exact \
         Hessians formed for objects alone",
        world.objects().len(),
        backward_s / forward_s
    );
    println!(
        "{{\"scene\": \"{path}\", \"steps\": {steps}, \"island_steps\": {island_steps}, \
         \"largest_island\": {largest}, \"forward_s\": {forward_s:.4}, \"backward_s\": \
         {backward_s:.4}, \"ratio\": {:.3}, \"peak_memory_bytes\": {}}}",
        backward_s / forward_s,
        peak_memory_bytes().unwrap_or(0)
    );
    Ok(())
}
