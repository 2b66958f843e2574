//! Object-object contact reports through C: compiles `examples/contact.c` against the static
//! library, runs it on a two-block contact scene and checks every printed number against
//! [`World::contact_summary`] on the same scene (a separate process: the same numbers bit for
//! bit), the visible penetration (`ff_world_visible_penetration`) likewise; a scene without
//! `[contact]` reports zeros; the NULL paths of both.

use freeform::progress::Silent;
use freeform::scene::{RunSettings, Scene, World};
use freeform_capi::*;
use std::ffi::{CStr, CString};
use std::path::{Path, PathBuf};
use std::ptr::null_mut;

mod common;
use common::compile_and_run;

const STEPS: usize = 8;

/// A 0.2 m block resting on a floor and a second one 1 cm above it falling at 1 m/s: they
/// meet within two steps of 10 ms and stay in contact. Small (30 kernels, 3 modes) so the
/// test runs in about a second. `contact` false leaves out the `[contact]` section; `tilted`
/// turns the upper block 30 degrees about z (its lower corner where it was), so that it lands
/// on an edge.
fn scene(dir: &Path, contact: bool, tilted: bool) -> PathBuf {
    let name = match (contact, tilted) {
        (true, false) => "two.toml",
        (true, true) => "tilted.toml",
        (false, _) => "apart.toml",
    };
    let path = dir.join(name);
    let section = if contact {
        "[contact]\nfriction = 0.3\n"
    } else {
        ""
    };
    let rotation = if tilted {
        ", rotation = { axis = [0.0, 0.0, 1.0], degrees = 30.0 }"
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
cubature = 200
hessian = "newton"

[cache]
enabled = false

{section}
[[object]]
name = "low"
shape = "box:0.2,0.2,0.2"
material = {{ youngs = 1e6, poisson = 0.3, density = 500.0 }}
basis = {{ kernels = 30, modes = 3, points = 1500 }}
contact_samples = 300
placement = {{ translation = [0.0, 0.0, 0.0] }}

[[object]]
name = "high"
shape = "box:0.2,0.2,0.2"
material = {{ youngs = 1e6, poisson = 0.3, density = 500.0 }}
basis = {{ kernels = 30, modes = 3, points = 1500 }}
contact_samples = 300
placement = {{ translation = [0.02, 0.21, 0.0], velocity = [0.0, -1.0, 0.0]{rotation} }}

[[collider]]
shape = {{ plane = {{ point = [0.0, 0.0, 0.0], normal = [0.0, 1.0, 0.0] }} }}
"#
        ),
    )
    .unwrap();
    path
}

/// One `contact` line of examples/contact.c (or the same from the Rust world).
#[derive(Debug, PartialEq)]
struct Row {
    step: usize,
    enabled: bool,
    tested: usize,
    near: usize,
    active: usize,
    penetration: f64,
    fraction: f64,
    islands: usize,
    largest: usize,
    regrouped: usize,
    /// The `visible` line after it: step, metres, fraction.
    visible: (usize, f64, f64),
}

/// The run's worst: metres, fraction, steps over tolerance; visible metres, fraction.
type Worst = (f64, f64, usize, f64, f64);

/// The `contact` rows (each with the `visible` line after it) and the `worst` line.
fn parse(stdout: &str) -> (Vec<Row>, Worst) {
    let mut rows = Vec::new();
    let mut worst = None;
    for line in stdout.lines() {
        let f: Vec<&str> = line.split_whitespace().collect();
        let int = |i: usize| -> usize { f[i].parse().unwrap() };
        let num = |i: usize| -> f64 { f[i].parse().unwrap() };
        match f.first().copied() {
            Some("contact") => rows.push(Row {
                step: int(1),
                enabled: int(3) == 1,
                tested: int(5),
                near: int(7),
                active: int(9),
                penetration: num(11),
                fraction: num(13),
                islands: int(15),
                largest: int(17),
                regrouped: int(19),
                visible: (0, f64::NAN, f64::NAN),
            }),
            Some("visible") => {
                rows.last_mut().expect("a contact line first").visible = (int(1), num(2), num(3))
            }
            Some("worst") => worst = Some((num(1), num(2), int(4), num(6), num(7))),
            _ => {}
        }
    }
    (rows, worst.expect("a worst line"))
}

/// The same scene stepped by the Rust `World`: its contact summary as rows.
fn rust_rows(path: &Path) -> (Vec<Row>, Worst) {
    let scene = Scene::load(path).unwrap();
    let mut world = World::new(&scene, &RunSettings::for_scene_file(path), &Silent).unwrap();
    for _ in 0..STEPS {
        world.step().unwrap();
    }
    let Some(s) = world.contact_summary() else {
        let zero = |k| Row {
            step: k,
            enabled: false,
            tested: 0,
            near: 0,
            active: 0,
            penetration: 0.0,
            fraction: 0.0,
            islands: 0,
            largest: 0,
            regrouped: 0,
            visible: (0, 0.0, 0.0),
        };
        return (
            (0..STEPS).map(|_| zero(0)).collect(),
            (0.0, 0.0, 0, 0.0, 0.0),
        );
    };
    let rows = s
        .steps
        .iter()
        .map(|r| Row {
            step: r.step,
            enabled: true,
            tested: r.object_pairs_tested,
            near: r.object_pairs_near,
            active: r.sample_pairs_active,
            penetration: r.penetration,
            fraction: r.penetration_fraction,
            islands: r.islands.len(),
            largest: r.islands.iter().copied().max().unwrap_or(0),
            regrouped: r.regrouped,
            visible: (
                r.step,
                r.visible_penetration,
                r.visible_penetration_fraction,
            ),
        })
        .collect();
    (
        rows,
        (
            s.worst_penetration,
            s.worst_penetration_fraction,
            s.steps_over_tolerance,
            s.worst_visible_penetration,
            s.worst_visible_penetration_fraction,
        ),
    )
}

#[test]
fn c_contact_reports_equal_the_rust_world_and_are_zero_without_contact() {
    let dir = tempfile::tempdir().unwrap();
    let steps = STEPS.to_string();
    let with = scene(dir.path(), true, false);
    let stdout = compile_and_run("contact", dir.path(), &[&with, Path::new(&steps)]);
    let (c_rows, c_worst) = parse(&stdout);
    let (r_rows, r_worst) = rust_rows(&with);
    assert_eq!(c_rows.len(), STEPS, "{stdout}");
    // The scene does what it is for: the blocks touch, as one island of two, with one
    // object pair tested per step.
    assert!(
        c_rows.iter().all(|r| r.enabled && r.tested == 1),
        "{stdout}"
    );
    assert!(
        c_rows
            .iter()
            .any(|r| r.active > 0 && r.penetration > 0.0 && (r.islands, r.largest) == (1, 2)),
        "{stdout}"
    );
    assert!(c_worst.0 > 0.0, "{stdout}");
    // Every step reports its visible figure (equal to the Rust world's below; 0 here: the
    // faces meet flat, and the samples' envelopes stay inside them).
    assert!(
        c_rows
            .iter()
            .all(|r| r.visible.0 == r.step && r.visible.1.is_finite()),
        "{stdout}"
    );
    // Same library, same scene, same thread count, and %.17g round-trips a double: every
    // number equals the Rust world's exactly (no arithmetic differs between the paths).
    assert_eq!(c_rows, r_rows);
    assert_eq!(c_worst, r_worst);

    // Without [contact]: every field zero, enabled 0, whatever the objects do.
    let apart = scene(dir.path(), false, false);
    let stdout = compile_and_run("contact", dir.path(), &[&apart, Path::new(&steps)]);
    let (c_rows, c_worst) = parse(&stdout);
    assert_eq!((c_rows, c_worst), rust_rows(&apart), "{stdout}");
}

/// A block landing on an edge: its edge stands past its own samples' envelope, so the visible
/// figure is positive once the blocks touch; C reports it as the Rust world does, exactly.
#[test]
fn c_visible_penetration_equals_the_rust_world_on_an_edge_impact() {
    let dir = tempfile::tempdir().unwrap();
    let steps = STEPS.to_string();
    let tilted = scene(dir.path(), true, true);
    let stdout = compile_and_run("contact", dir.path(), &[&tilted, Path::new(&steps)]);
    let (c_rows, c_worst) = parse(&stdout);
    assert!(c_worst.3 > 0.0 && c_worst.4 > 0.0, "{stdout}");
    assert!(c_rows.iter().any(|r| r.visible.1 > 0.0), "{stdout}");
    assert_eq!((c_rows, c_worst), rust_rows(&tilted));
    // Where: the `spot` line (step, the two names, the point at rest) is the Rust world's
    // worst_visible_at, printed to 17 digits (so equal exactly).
    let scene = Scene::load(&tilted).unwrap();
    let mut world = World::new(&scene, &RunSettings::for_scene_file(&tilted), &Silent).unwrap();
    for _ in 0..STEPS {
        world.step().unwrap();
    }
    let v = world
        .contact_summary()
        .unwrap()
        .worst_visible_at
        .clone()
        .unwrap();
    let expected = format!(
        "spot {} {} {} {:?} {:?} {:?}",
        v.step, v.surface_object, v.other_object, v.rest_point[0], v.rest_point[1], v.rest_point[2]
    );
    let line = stdout
        .lines()
        .find(|l| l.starts_with("spot"))
        .expect("a spot line");
    let f: Vec<&str> = line.split_whitespace().collect();
    let g: Vec<&str> = expected.split_whitespace().collect();
    assert_eq!(f[..4], g[..4], "{line} / {expected}");
    for k in 4..7 {
        assert_eq!(
            f[k].parse::<f64>().unwrap(),
            g[k].parse::<f64>().unwrap(),
            "{line}"
        );
    }
}

#[test]
fn visible_penetration_checks_its_pointers_and_is_zero_before_the_first_step() {
    let dir = tempfile::tempdir().unwrap();
    let path = CString::new(scene(dir.path(), true, false).to_str().unwrap()).unwrap();
    let mut w: *mut FfWorld = null_mut();
    unsafe {
        assert_eq!(ff_world_open(path.as_ptr(), 0, &mut w), 0);
        let mut rep = FfVisiblePenetration {
            step: 99,
            penetration: 1.0,
            ..FfVisiblePenetration::default()
        };
        assert_eq!(ff_world_visible_penetration(w, &mut rep), 0);
        assert_eq!(
            rep,
            FfVisiblePenetration {
                enabled: 1,
                ..FfVisiblePenetration::default()
            }
        );
        assert_eq!(
            ff_world_visible_penetration(std::ptr::null(), &mut rep),
            Status::NullPointer as i32
        );
        let msg = CStr::from_ptr(ff_last_error()).to_string_lossy();
        assert!(
            msg.contains("ff_world_visible_penetration: world is NULL"),
            "{msg}"
        );
        assert_eq!(
            ff_world_visible_penetration(w, null_mut()),
            Status::NullPointer as i32
        );
        let msg = CStr::from_ptr(ff_last_error()).to_string_lossy();
        assert!(msg.contains("out is NULL"), "{msg}");
        // No spot before the first step; the same NULL checks.
        let mut spot = FfVisibleSpot {
            found: 7,
            step: 3,
            ..FfVisibleSpot::default()
        };
        assert_eq!(ff_world_visible_spot(w, &mut spot), 0);
        assert_eq!(spot, FfVisibleSpot::default());
        assert_eq!(
            ff_world_visible_spot(std::ptr::null(), &mut spot),
            Status::NullPointer as i32
        );
        assert_eq!(
            ff_world_visible_spot(w, null_mut()),
            Status::NullPointer as i32
        );
        ff_world_free(w);
    }
}

#[test]
fn contact_report_checks_its_pointers_and_is_zero_before_the_first_step() {
    let dir = tempfile::tempdir().unwrap();
    let path = CString::new(scene(dir.path(), true, false).to_str().unwrap()).unwrap();
    let mut w: *mut FfWorld = null_mut();
    unsafe {
        assert_eq!(ff_world_open(path.as_ptr(), 0, &mut w), 0);
        let mut rep = FfContactReport {
            step: 99,
            ..FfContactReport::default()
        };
        assert_eq!(ff_world_contact_report(w, &mut rep), 0);
        assert_eq!(
            rep,
            FfContactReport {
                enabled: 1,
                ..FfContactReport::default()
            }
        );
        assert_eq!(
            ff_world_contact_report(std::ptr::null(), &mut rep),
            Status::NullPointer as i32
        );
        let msg = CStr::from_ptr(ff_last_error()).to_string_lossy();
        assert!(
            msg.contains("ff_world_contact_report: world is NULL"),
            "{msg}"
        );
        assert_eq!(
            ff_world_contact_report(w, null_mut()),
            Status::NullPointer as i32
        );
        let msg = CStr::from_ptr(ff_last_error()).to_string_lossy();
        assert!(msg.contains("out is NULL"), "{msg}");
        ff_world_free(w);
    }
}
