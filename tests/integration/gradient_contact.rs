//! Gradients through steps solved as islands (object-object contact, lagged pair friction)
//! against central differences of the same scene re-simulated: a box dropped onto another
//! that rests on a floor, both pushing each other within the recorded steps.

use freeform::progress::Silent;
use freeform::scene::{RunSettings, Scene, World, WorldGradients};

const STEPS: usize = 6;

/// The scene: pair friction `mu`, pair stiffness `kappa` (Pa/m^2), gravity `g` (m/s^2, along
/// -y); every step solved by Newton far below the default tolerance.
fn scene(mu: f64, kappa: f64, g: f64) -> Scene {
    scene_with(mu, kappa, g, "")
}

/// [`scene`] with `extra` lines in its `[contact]` section.
fn scene_with(mu: f64, kappa: f64, g: f64, extra: &str) -> Scene {
    let text = format!(
        r#"
[simulation]
dt = 0.01
steps = {STEPS}
gravity = [0.0, {gy}, 0.0]

[solver]
cubature = 150
hessian = "newton"
tol = 1e-12
max_iter = 200

[cache]
enabled = false

[contact]
friction = 0.3
friction_velocity = 0.01
stiffness = {kappa}
{extra}

[[contact.pair]]
between = ["low", "high"]
friction = {mu}

[[object]]
name = "low"
shape = "box:0.2,0.2,0.2"
material = {{ youngs = 1e6, poisson = 0.3, density = 500.0 }}
basis = {{ kernels = 30, modes = 3, points = 1500 }}
contact_samples = 200
placement = {{ translation = [0.0, 0.0, 0.0] }}

[[object]]
name = "high"
shape = "box:0.2,0.2,0.2"
material = {{ youngs = 1e6, poisson = 0.3, density = 500.0 }}
basis = {{ kernels = 30, modes = 3, points = 1500 }}
contact_samples = 200
placement = {{ translation = [0.03, 0.205, 0.01], velocity = [0.3, -0.5, 0.2], angular_velocity = [0.5, 0.3, -1.0] }}

[[collider]]
shape = {{ plane = {{ point = [0.0, 0.0, 0.0], normal = [0.0, 1.0, 0.0] }} }}
stiffness = 1e8
"#,
        gy = -g
    );
    Scene::from_toml(&text).unwrap()
}

fn world(s: &Scene) -> World {
    World::new(s, &RunSettings::default(), &Silent).unwrap()
}

/// Fixed loss weights for object `i`: L = sum over frames and objects of c_i . z_i(t).
fn weights(i: usize, n: usize) -> Vec<f64> {
    (0..n)
        .map(|k| ((k * 7 + i * 13) % 11) as f64 / 11.0 - 0.45)
        .collect()
}

fn loss_at(w: &World) -> f64 {
    (0..w.objects().len())
        .map(|i| {
            let z = w.object(i).sim().z();
            weights(i, z.len())
                .iter()
                .zip(z)
                .map(|(c, v)| c * v)
                .sum::<f64>()
        })
        .sum()
}

/// The loss of a plain run from the world's current state.
fn run_loss(mut w: World) -> f64 {
    let mut total = loss_at(&w);
    for _ in 0..STEPS {
        w.step().unwrap();
        total += loss_at(&w);
    }
    total
}

/// The recorded run's gradients, and the largest island it solved.
fn record(mut w: World) -> (WorldGradients, usize, World) {
    let mut rec = w.record(STEPS).unwrap();
    for _ in 0..STEPS {
        w.step_recorded(&mut rec).unwrap();
    }
    let island = rec.largest_island();
    let dl: Vec<Vec<Vec<f64>>> = (0..w.objects().len())
        .map(|i| vec![weights(i, w.object(i).sim().z().len()); STEPS + 1])
        .collect();
    let g = rec.backward(&w, &dl).unwrap();
    (g, island, w)
}

fn rel(a: f64, b: f64) -> f64 {
    (a - b).abs() / b.abs().max(1e-300)
}

/// dL/dmu and dL/dkappa of the pair, dL/dg and the initial state's gradient of both objects
/// (along fixed directions) against central differences. Bounds: 1e-5, the bound of the
/// objects stepping alone (docs/gradients.md); measured 1e-9..2e-8 here. The steps are solved
/// to 1e-12, the run is checked for its island and for no stiffness raise (a jump), and the
/// differences' steps are small enough that no contact switches within them: the loss has a
/// kink between 1e-4 and 1e-3 from mu = 0.4 (central differences with h = 1e-3 read a quarter
/// of the slope, with h = 1e-4 the slope to 1e-5, with h = 1e-5 to 7e-8).
#[test]
fn island_gradients_match_finite_differences() {
    let (mu, kappa, g) = (0.4, 1e9, 9.81);
    let (grads, island, w) = record(world(&scene(mu, kappa, g)));
    assert_eq!(island, 2, "the boxes must be solved together");
    let summary = w.contact_summary().unwrap();
    assert!(summary.steps.iter().all(|r| r.stiffened == 0));
    assert!(
        summary
            .steps
            .iter()
            .filter(|r| r.sample_pairs_active > 0)
            .count()
            >= 3
    );

    let fd = |f: &dyn Fn(f64) -> f64, h: f64| (f(h) - f(-h)) / (2.0 * h);
    let pair = |m: &[f64]| {
        assert_eq!(m[1], m[2], "the pair matrices are symmetric");
        m[1]
    };

    let d_mu = fd(&|h| run_loss(world(&scene(mu + h, kappa, g))), 1e-5);
    let got = pair(&grads.contact_friction);
    // The kink near mu (the docs' figures): `--nocapture` prints the wider differences.
    for h in [1e-3, 1e-4] {
        let wide = fd(&|h| run_loss(world(&scene(mu + h, kappa, g))), h);
        eprintln!(
            "dL/dmu: h {h:e}: central difference / gradient = {:.6}",
            wide / got
        );
    }
    assert!(d_mu.abs() > 1e-6, "friction must matter: {d_mu}");
    assert!(rel(got, d_mu) < 1e-5, "dL/dmu {got} vs {d_mu}");

    let d_kappa = fd(&|h| run_loss(world(&scene(mu, kappa * (1.0 + h), g))), 1e-5) / kappa;
    let got = pair(&grads.contact_stiffness);
    assert!(rel(got, d_kappa) < 1e-5, "dL/dkappa {got} vs {d_kappa}");

    // Gravity along -y with magnitude g: dL/dg = -sum over objects of dL/dg_y.
    let d_g = fd(&|h| run_loss(world(&scene(mu, kappa, g + h))), 1e-5);
    let got: f64 = grads.objects.iter().map(|o| -o.gravity.unwrap()[1]).sum();
    assert!(rel(got, d_g) < 1e-5, "dL/dg {got} vs {d_g}");

    // The start state: z0 and zdot0 of both objects along fixed directions.
    for i in 0..2 {
        let base = world(&scene(mu, kappa, g));
        let (z0, v0) = (
            base.object(i).sim().z().to_vec(),
            base.object(i).sim().zdot().to_vec(),
        );
        let dir: Vec<f64> = (0..z0.len())
            .map(|k| ((k * 5 + 3 * i + 1) % 9) as f64 / 9.0 - 0.5)
            .collect();
        let moved = |dz: f64, dv: f64| {
            let mut w = world(&scene(mu, kappa, g));
            let z: Vec<f64> = z0.iter().zip(&dir).map(|(a, d)| a + dz * d).collect();
            let v: Vec<f64> = v0.iter().zip(&dir).map(|(a, d)| a + dv * d).collect();
            w.object_mut(i).sim_mut().set_state(&z, &v).unwrap();
            run_loss(w)
        };
        let dot = |a: &[f64]| a.iter().zip(&dir).map(|(x, y)| x * y).sum::<f64>();
        let d_z = fd(&|h| moved(h, 0.0), 1e-6);
        let got = dot(&grads.objects[i].z0);
        assert!(rel(got, d_z) < 1e-5, "object {i}: dL/dz0 {got} vs {d_z}");
        let d_v = fd(&|h| moved(0.0, h), 1e-5);
        let got = dot(&grads.objects[i].zdot0);
        assert!(rel(got, d_v) < 1e-5, "object {i}: dL/dzdot0 {got} vs {d_v}");
    }
}

/// Frictionless pairs keep their contacts in the reverse pass with a zero force: dL/dmu at
/// mu = 0 is the one-sided derivative as friction is switched on, checked against a forward
/// difference (its O(h) truncation at h = 1e-6 is far below the 1e-4 bound).
#[test]
fn a_frictionless_pair_gives_the_one_sided_friction_gradient() {
    let (kappa, g) = (1e9, 9.81);
    let (grads, island, _) = record(world(&scene(0.0, kappa, g)));
    assert_eq!(island, 2);
    let h = 1e-6;
    let forward =
        (run_loss(world(&scene(h, kappa, g))) - run_loss(world(&scene(0.0, kappa, g)))) / h;
    let got = grads.contact_friction[1];
    assert!(forward.abs() > 1e-6, "friction must matter: {forward}");
    assert!(rel(got, forward) < 1e-4, "dL/dmu at 0: {got} vs {forward}");
}

/// The island's adjoint solved by block conjugate gradients (the default `blocks` solver, to
/// a relative residual of 1e-11) equals the dense factor's (`solver = "dense"`): bound 1e-7,
/// the two forward runs' own difference (each solved to 1e-12) included; measured 2e-13 to
/// 3e-11.
#[test]
fn block_and_dense_island_adjoints_agree() {
    let (mu, kappa, g) = (0.4, 1e9, 9.81);
    let (blocks, _, _) = record(world(&scene(mu, kappa, g)));
    let (dense, island, _) = record(world(&scene_with(mu, kappa, g, r#"solver = "dense""#)));
    assert_eq!(island, 2);
    let close = |a: &[f64], b: &[f64], what: &str| {
        let d: f64 = a
            .iter()
            .zip(b)
            .map(|(x, y)| (x - y) * (x - y))
            .sum::<f64>()
            .sqrt();
        let n: f64 = b.iter().map(|y| y * y).sum::<f64>().sqrt();
        assert!(d <= 1e-7 * n, "{what}: {d:e} of {n:e}");
    };
    close(&blocks.contact_friction, &dense.contact_friction, "dL/dmu");
    close(
        &blocks.contact_stiffness,
        &dense.contact_stiffness,
        "dL/dkappa",
    );
    for (a, b) in blocks.objects.iter().zip(&dense.objects) {
        close(&a.z0, &b.z0, "dL/dz0");
        close(&a.zdot0, &b.zdot0, "dL/dzdot0");
        close(&a.youngs, &b.youngs, "dL/dE");
    }
}

/// An island that went deeper than the tolerance is solved again with its pairs stiffer: the
/// gradient is that of the raised model, the raises held as factors, so dL/dkappa of the
/// stiffness as given sums each step's dL/dkappa times its factor. Against central differences
/// that keep every raise (checked: the same raises at kappa (1 +- h)); bound 1e-5.
#[test]
fn gradients_through_stiffness_raises_match_finite_differences() {
    let (mu, kappa, g) = (0.4, 1e9, 9.81);
    let tight = "penetration_tolerance = 0.003";
    let raises = |w: &World| -> Vec<usize> {
        w.contact_summary()
            .unwrap()
            .steps
            .iter()
            .map(|r| r.stiffened)
            .collect()
    };
    let (grads, island, w) = record(world(&scene_with(mu, kappa, g, tight)));
    assert_eq!(island, 2);
    let base = raises(&w);
    assert!(
        base.iter().sum::<usize>() > 0,
        "the island must be stiffened: {base:?}"
    );
    let h = 1e-5;
    let run = |k: f64| {
        let mut w = world(&scene_with(mu, k, g, tight));
        let mut total = loss_at(&w);
        for _ in 0..STEPS {
            w.step().unwrap();
            total += loss_at(&w);
        }
        assert_eq!(raises(&w), base, "a raise switched within the difference");
        total
    };
    let d_kappa = (run(kappa * (1.0 + h)) - run(kappa * (1.0 - h))) / (2.0 * h * kappa);
    let got = grads.contact_stiffness[1];
    assert!(rel(got, d_kappa) < 1e-5, "dL/dkappa {got} vs {d_kappa}");
    let d_g = {
        let at = |gg: f64| run_loss(world(&scene_with(mu, kappa, gg, tight)));
        (at(g + h) - at(g - h)) / (2.0 * h)
    };
    let got: f64 = grads.objects.iter().map(|o| -o.gravity.unwrap()[1]).sum();
    assert!(rel(got, d_g) < 1e-5, "dL/dg {got} vs {d_g}");
}

/// The clip of examples/self_contact.toml (its upper arm sagging onto its lower arm; K = 300,
/// m = 10, Newton to 1e-12) with `[contact] friction = mu`.
struct Clip {
    scene: Scene,
    settings: RunSettings,
}

/// Steps before the recording (the arms touch from then on) and steps recorded.
const CLIP_PRE: usize = 12;
const CLIP_STEPS: usize = 4;
/// Rest points whose heights, summed over the frames, are the loss.
const CLIP_POINTS: [[f64; 3]; 3] = [[0.25, 0.12, 0.02], [0.45, 0.13, 0.03], [0.4, 0.02, 0.02]];

impl Clip {
    fn new(mu: f64) -> Clip {
        let path = concat!(env!("CARGO_MANIFEST_DIR"), "/examples/self_contact.toml");
        let text = std::fs::read_to_string(path)
            .unwrap()
            .replace(
                "hessian = \"newton\"",
                "hessian = \"newton\"\ntol = 1e-12\nmax_iter = 300\ncubature = 400",
            )
            .replace(
                "basis = { kernels = 600, modes = 16 }",
                "basis = { kernels = 300, modes = 10, points = 6000 }",
            )
            .replace("friction = 0.3", &format!("friction = {mu:?}"))
            .replace("[contact]", "[cache]\nenabled = false\n\n[contact]");
        Clip {
            scene: Scene::from_toml(&text).unwrap(),
            settings: RunSettings::for_scene_file(std::path::Path::new(path)),
        }
    }

    /// The world after the unrecorded steps.
    fn world(&self) -> World {
        let mut w = World::new(&self.scene, &self.settings, &Silent).unwrap();
        for _ in 0..CLIP_PRE {
            w.step().unwrap();
        }
        w
    }

    /// The summed heights of the loss's points at the world's state.
    fn heights(w: &World) -> f64 {
        let o = w.object(0);
        let weights = o.basis().weights(&CLIP_POINTS).unwrap();
        let sim = o.sim();
        freeform::sim::object::map_points(sim.layout(), sim.z(), &CLIP_POINTS, &weights)
            .iter()
            .map(|p| p[1])
            .sum()
    }

    /// The loss of the recorded steps' plain run from `w`.
    fn loss(mut w: World) -> f64 {
        let mut total = Clip::heights(&w);
        for _ in 0..CLIP_STEPS {
            w.step().unwrap();
            total += Clip::heights(&w);
        }
        total
    }

    /// The recorded steps' gradients from `w`, each step checked to be an island of one with
    /// its own sample pairs active.
    fn gradients(mut w: World) -> freeform::sim::gradient::Gradients {
        let row = {
            let o = w.object(0);
            let weights = o.basis().weights(&CLIP_POINTS).unwrap();
            freeform::sim::gradient::positions_adjoint(
                o.sim().layout(),
                &CLIP_POINTS,
                &weights,
                &[[0.0, 1.0, 0.0]; 3],
            )
            .unwrap()
        };
        let mut rec = w.record(CLIP_STEPS).unwrap();
        for _ in 0..CLIP_STEPS {
            w.step_recorded(&mut rec).unwrap();
            let row = w.contact_summary().unwrap().steps.last().unwrap().clone();
            assert!(row.islands == [1] && row.sample_pairs_active > 0, "{row:?}");
        }
        let mut g = rec.backward(&w, &[vec![row; CLIP_STEPS + 1]]).unwrap();
        g.objects.remove(0)
    }
}

/// Self-contact: the clip stepped until its arms touch, then 4 recorded steps, each an island
/// of one with its own sample pairs active. dL/dg (gravity set after the unrecorded steps, so
/// only the recorded steps see the change) against central differences: bound 1e-5 (measured
/// 7e-9).
#[test]
fn self_contact_gradients_match_finite_differences() {
    let clip = Clip::new(0.3);
    let grads = Clip::gradients(clip.world());
    let at = |g: f64| {
        let mut w = clip.world();
        w.set_gravity(Some([0.0, -g, 0.0])).unwrap();
        Clip::loss(w)
    };
    let h = 1e-5;
    let fd = (at(9.81 + h) - at(9.81 - h)) / (2.0 * h);
    let got = -grads.gravity.unwrap()[1];
    assert!(rel(got, fd) < 1e-5, "dL/dg {got} vs {fd}");
}

/// The frictionless clip's start state: hundreds of its sample pairs switch within 1e-6 of it,
/// so central differences along a fixed direction see the gradient only at h = 1e-7 (bound
/// 1e-3; the kinks' O(h) error and the solver's 1e-12 / h noise meet there). `--nocapture`
/// prints the differences at h = 1e-5, 1e-6 and 1e-7 against the gradient.
#[test]
fn self_contact_start_state_gradient_needs_a_small_step() {
    let clip = Clip::new(0.0);
    let base = clip.world();
    let (z0, v0) = (
        base.object(0).sim().z().to_vec(),
        base.object(0).sim().zdot().to_vec(),
    );
    let grads = Clip::gradients(base);
    let dir: Vec<f64> = (0..z0.len()).map(|k| (1.7 * k as f64).sin()).collect();
    let got: f64 = grads.z0.iter().zip(&dir).map(|(a, b)| a * b).sum();
    let moved = |dz: f64| {
        let mut w = clip.world();
        let z: Vec<f64> = z0.iter().zip(&dir).map(|(a, d)| a + dz * d).collect();
        w.set_state(0, &z, &v0).unwrap();
        Clip::loss(w)
    };
    let mut last = f64::NAN;
    for h in [1e-5, 1e-6, 1e-7] {
        last = (moved(h) - moved(-h)) / (2.0 * h);
        eprintln!("h {h:e}: central difference / gradient = {:.6}", last / got);
    }
    assert!(rel(got, last) < 1e-3, "dL/dz0 along d: {got} vs {last}");
}
