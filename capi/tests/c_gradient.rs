//! Gradients through C: compiles `examples/gradient.c` against the static library, runs it on
//! two blocks that meet and are solved as an island, and checks every printed number against
//! the Rust API's for the same scene (a separate process: the same numbers bit for bit); then
//! the refusals of the `ff_recording_*` and `ff_gradients_*` functions, called from Rust.

use freeform::progress::Silent;
use freeform::scene::{RunSettings, Scene, World};
use freeform::sim::gradient::positions_adjoint;
use freeform::sim::object::map_points;
use freeform_capi::*;
use std::ffi::{CStr, CString};
use std::path::{Path, PathBuf};
use std::ptr::{null, null_mut};

mod common;
use common::compile_and_run;

const STEPS: usize = 5;
const POINTS: usize = 4;

/// A block resting on a floor and a second one falling onto it (they are solved together
/// from the second step), Newton steps to 1e-12; `contact` false leaves out `[contact]`.
fn scene(dir: &Path, contact: bool) -> PathBuf {
    let path = dir.join(if contact { "two.toml" } else { "apart.toml" });
    let section = if contact {
        "[contact]\nfriction = 0.3\n"
    } else {
        ""
    };
    std::fs::write(
        &path,
        format!(
            r#"
[simulation]
dt = 0.01
steps = {STEPS}
gravity = [0.0, -9.81, 0.0]

[solver]
cubature = 150
hessian = "newton"
tol = 1e-12
max_iter = 200

[cache]
enabled = false

{section}
[[object]]
name = "low"
shape = "box:0.2,0.2,0.2"
material = {{ youngs = 1e6, poisson = 0.3, density = 500.0 }}
basis = {{ kernels = 30, modes = 3, points = 1500 }}
contact_samples = 200

[[object]]
name = "high"
shape = "box:0.2,0.2,0.2"
material = {{ youngs = 1e6, poisson = 0.3, density = 500.0 }}
basis = {{ kernels = 30, modes = 3, points = 1500 }}
contact_samples = 200
placement = {{ translation = [0.03, 0.205, 0.01], velocity = [0.3, -0.5, 0.2] }}

[[collider]]
shape = {{ plane = {{ point = [0.0, 0.0, 0.0], normal = [0.0, 1.0, 0.0] }} }}
stiffness = 1e8
"#
        ),
    )
    .unwrap();
    path
}

/// Every line of examples/gradient.c's output as its key words and numbers.
fn parse(stdout: &str) -> Vec<(String, Vec<f64>)> {
    stdout
        .lines()
        .map(|line| {
            let mut f = line.split_whitespace();
            let key = f.next().unwrap_or_default().to_string();
            (key, f.map(|v| v.parse().unwrap()).collect())
        })
        .collect()
}

/// examples/gradient.c's computation through the Rust API.
fn rust_lines(path: &Path) -> Vec<(String, Vec<f64>)> {
    let scene = Scene::load(path).unwrap();
    let mut world = World::new(&scene, &RunSettings::for_scene_file(path), &Silent).unwrap();
    let n = world.objects().len();
    let rest: Vec<Vec<[f64; 3]>> = world
        .objects()
        .iter()
        .map(|o| o.render_rest()[..POINTS].to_vec())
        .collect();
    let weights: Vec<_> = world
        .objects()
        .iter()
        .zip(&rest)
        .map(|(o, r)| o.basis().weights(r).unwrap())
        .collect();
    let mut loss = 0.0;
    let mut rec = world.record(STEPS).unwrap();
    for t in 0..=STEPS {
        if t > 0 {
            world.step_recorded(&mut rec).unwrap();
        }
        for i in 0..n {
            let sim = world.object(i).sim();
            let x = map_points(sim.layout(), sim.z(), &rest[i], &weights[i]);
            for p in &x {
                loss += p[1];
            }
        }
    }
    let mut lines = vec![("loss".to_string(), vec![loss])];
    let dl: Vec<Vec<Vec<f64>>> = (0..n)
        .map(|i| {
            let sim = world.object(i).sim();
            let row = positions_adjoint(
                sim.layout(),
                &rest[i],
                &weights[i],
                &[[0.0, 1.0, 0.0]; POINTS],
            )
            .unwrap();
            vec![row; STEPS + 1]
        })
        .collect();
    let g = rec.backward(&world, &dl).unwrap();
    let idx = |i: usize| i as f64;
    for (i, o) in g.objects.iter().enumerate() {
        lines.push((
            "material".into(),
            vec![idx(i), o.youngs_total(), o.poisson_total()],
        ));
        if let Some(gr) = o.gravity {
            lines.push(("gravity".into(), vec![idx(i), gr[0], gr[1], gr[2]]));
        }
        let sum = |v: &[f64]| v.iter().fold(0.0, |a, b| a + b);
        lines.push(("state".into(), vec![idx(i), sum(&o.z0), sum(&o.zdot0)]));
        for (c, kappa) in o.collider_stiffness.iter().enumerate() {
            let mu = o.friction.as_ref().map_or(0.0, |f| f[c]);
            lines.push(("collider".into(), vec![idx(i), idx(c), mu, *kappa]));
        }
        if !g.contact_stiffness.is_empty() {
            for b in i + 1..n {
                let k = i * n + b;
                lines.push((
                    "pair".into(),
                    vec![
                        idx(i),
                        idx(b),
                        g.contact_stiffness[k],
                        g.contact_friction[k],
                    ],
                ));
            }
        }
    }
    lines
}

#[test]
fn c_gradients_equal_the_rust_apis() {
    let dir = tempfile::tempdir().unwrap();
    for contact in [true, false] {
        let path = scene(dir.path(), contact);
        let steps = STEPS.to_string();
        let c = parse(&compile_and_run(
            "gradient",
            dir.path(),
            &[&path, Path::new(&steps)],
        ));
        let rust = rust_lines(&path);
        assert_eq!(c, rust, "contact {contact}");
        let pairs = c.iter().filter(|(k, _)| k == "pair").count();
        assert_eq!(pairs, usize::from(contact));
        if contact {
            // The island's pair gradients are there, and the blocks did touch.
            let pair = &c.iter().find(|(k, _)| k == "pair").unwrap().1;
            assert!(pair[2] != 0.0 && pair[3] != 0.0, "{pair:?}");
        }
    }
}

fn last_error() -> String {
    unsafe { CStr::from_ptr(ff_last_error()) }
        .to_string_lossy()
        .into_owned()
}

#[test]
fn gradient_calls_refuse_bad_input() {
    let dir = tempfile::tempdir().unwrap();
    let path = CString::new(scene(dir.path(), false).to_str().unwrap()).unwrap();
    unsafe {
        let mut w = null_mut();
        assert_eq!(ff_world_open(path.as_ptr(), 0, &mut w), 0);
        // NULLs.
        let mut rec = null_mut();
        assert_eq!(
            ff_recording_start(null(), 2, &mut rec),
            Status::NullPointer as i32
        );
        assert_eq!(
            ff_recording_start(w, 2, null_mut()),
            Status::NullPointer as i32
        );
        assert_eq!(ff_recording_step(null_mut(), w), Status::NullPointer as i32);
        assert_eq!(ff_recording_steps(null()), 0);
        assert_eq!(ff_recording_start(w, 2, &mut rec), 0);
        assert_eq!(ff_recording_step(rec, w), 0);
        assert_eq!(ff_recording_steps(rec), 1);
        let len = ff_world_state_len(w, 0);
        let good = vec![0.5; 2 * len];
        let mut bad = good.clone();
        bad[3] = f64::NAN;
        let mut g = null_mut();
        // The wrong object count, NaN: refused, the tape kept.
        let one = [good.as_ptr()];
        assert_eq!(
            ff_recording_backward(rec, w, one.as_ptr(), 1, &mut g),
            Status::InvalidArgument as i32
        );
        assert!(
            last_error().contains("dl_dz has 1 entries; the world has 2"),
            "{}",
            last_error()
        );
        let nan = [bad.as_ptr(), null()];
        assert_eq!(
            ff_recording_backward(rec, w, nan.as_ptr(), 2, &mut g),
            Status::InvalidArgument as i32
        );
        assert!(last_error().contains("not finite"), "{}", last_error());
        assert_eq!(ff_recording_steps(rec), 1);
        let loss = [good.as_ptr(), null()];
        assert_eq!(ff_recording_backward(rec, w, loss.as_ptr(), 2, &mut g), 0);
        // Consumed: a second pass is refused.
        let mut g2 = null_mut();
        assert_eq!(
            ff_recording_backward(rec, w, loss.as_ptr(), 2, &mut g2),
            Status::InvalidArgument as i32
        );
        assert!(last_error().contains("already taken"), "{}", last_error());
        assert_eq!(ff_recording_step(rec, w), Status::InvalidArgument as i32);
        // Reading: bad indices, small buffers, no [contact].
        let mut out = [0.0; 3];
        assert_eq!(
            ff_gradients_material(g, 5, out.as_mut_ptr()),
            Status::InvalidArgument as i32
        );
        assert!(last_error().contains("object index 5"), "{}", last_error());
        assert_eq!(ff_gradients_material(g, 0, out.as_mut_ptr()), 0);
        assert!(out[0] != 0.0 && out[0].is_finite());
        assert_eq!(
            ff_gradients_collider(g, 0, 3, out.as_mut_ptr()),
            Status::InvalidArgument as i32
        );
        assert_eq!(
            ff_gradients_contact_pair(g, 0, 1, out.as_mut_ptr()),
            Status::InvalidArgument as i32
        );
        assert!(last_error().contains("no [contact]"), "{}", last_error());
        let mut z0 = vec![0.0; len - 1];
        let mut v0 = vec![0.0; len];
        assert_eq!(
            ff_gradients_state(g, 0, z0.as_mut_ptr(), v0.as_mut_ptr(), len - 1),
            Status::BufferTooSmall as i32
        );
        z0.push(0.0);
        assert_eq!(
            ff_gradients_state(g, 0, z0.as_mut_ptr(), v0.as_mut_ptr(), len),
            0
        );
        assert_eq!(
            ff_gradients_material(null(), 0, out.as_mut_ptr()),
            Status::NullPointer as i32
        );
        // A loss on points: NaN refused, a small buffer refused.
        let pts = [0.1, 0.1, 0.1];
        let mut row = vec![0.0; len];
        let nan3 = [0.0, f64::NAN, 0.0];
        assert_eq!(
            ff_world_positions_adjoint(w, 0, pts.as_ptr(), 1, nan3.as_ptr(), row.as_mut_ptr(), len),
            Status::InvalidArgument as i32
        );
        assert_eq!(
            ff_world_map_points(w, 0, pts.as_ptr(), 1, row.as_mut_ptr(), 2),
            Status::BufferTooSmall as i32
        );
        assert_eq!(
            ff_world_map_points(w, 0, pts.as_ptr(), usize::MAX, row.as_mut_ptr(), len),
            Status::InvalidArgument as i32
        );
        assert!(last_error().contains("too large"), "{}", last_error());
        ff_gradients_free(g);
        ff_recording_free(rec);
        ff_gradients_free(null_mut());
        ff_recording_free(null_mut());
        ff_world_free(w);
    }
}
