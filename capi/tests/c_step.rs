//! The live simulation through C: compiles `examples/step.c` against the static library, runs
//! it on `examples/step.toml` and checks every printed number against the same calls on the
//! Rust `World`; then the error paths of the `ff_world_*` functions, called from Rust.

use freeform::progress::Silent;
use freeform::scene::{RunSettings, Scene, World};
use freeform::sim::motion::Rigid;
use freeform_capi::*;
use std::collections::BTreeMap;
use std::ffi::{c_int, CStr, CString};
use std::path::{Path, PathBuf};

mod common;
use common::{compile_and_run, root};
use std::ptr::{null, null_mut};

/// What examples/step.c prints, keyed by line kind and step.
#[derive(Debug, Default, PartialEq)]
struct Trace {
    /// Per step: time (s), iterations, converged, contacts.
    steps: Vec<(f64, usize, bool, usize)>,
    /// (step, point index) -> deformed position, metres.
    points: BTreeMap<(usize, usize), [f64; 3]>,
    /// step -> mean of the render points, metres.
    means: BTreeMap<usize, [f64; 3]>,
}

fn parse_c(stdout: &str) -> Trace {
    let mut t = Trace::default();
    for line in stdout.lines() {
        let f: Vec<&str> = line.split_whitespace().collect();
        let num = |i: usize| -> f64 { f[i].parse().unwrap() };
        let int = |i: usize| -> usize { f[i].parse().unwrap() };
        match f.first().copied() {
            Some("step") => {
                assert_eq!(int(1), t.steps.len() + 1, "{line}");
                t.steps.push((num(3), int(5), int(7) == 1, int(9)));
            }
            Some("points") => {
                t.points.insert((int(1), int(2)), [num(3), num(4), num(5)]);
            }
            Some("mean") => {
                t.means.insert(int(1), [num(2), num(3), num(4)]);
            }
            _ => {}
        }
    }
    t
}

/// examples/step.c's loop on the Rust `World`: the same calls with the same arithmetic.
fn rust_trace(scene_path: &Path) -> Trace {
    let scene = Scene::load(scene_path).unwrap();
    let settings = RunSettings {
        base_dir: scene_path.parent().unwrap().to_path_buf(),
        ..RunSettings::default()
    };
    let mut world = World::new(&scene, &settings, &Silent).unwrap();
    let bar = world.object_index("bar").unwrap();
    let mut t = Trace::default();
    for k in 1..=30usize {
        let a = k as f64 * std::f64::consts::PI / 180.0;
        let (c, s) = (a.cos(), a.sin());
        let r = [[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]];
        let p = [0.0, 0.1, 0.1];
        let mut tr = [0.0; 3];
        for i in 0..3 {
            tr[i] = p[i] - (r[i][0] * p[0] + r[i][1] * p[1] + r[i][2] * p[2]);
        }
        tr[1] += 0.002 * k as f64;
        let held = Rigid {
            rotation: r,
            translation: tr,
        };
        world.set_boundary_pose(bar, 0, &held).unwrap();
        let floor = Rigid {
            translation: [0.0, 0.003 * k as f64, 0.0],
            ..Rigid::IDENTITY
        };
        world.set_collider_pose(0, &floor).unwrap();
        if k == 21 {
            world.set_gravity(None).unwrap();
        }
        let reports = world.step().unwrap();
        let rep = &reports[bar];
        t.steps.push((
            world.time(),
            rep.solve.iterations,
            rep.solve.converged,
            rep.solve.info.contacts,
        ));
        if k % 10 == 0 {
            let x = world.object(bar).render_positions();
            let n = x.len();
            for i in [0, n / 2, n - 1] {
                t.points.insert((k, i), x[i]);
            }
            // Summed in point order, as the C program does.
            let mut m = [0.0; 3];
            for q in &x {
                for d in 0..3 {
                    m[d] += q[d];
                }
            }
            t.means.insert(k, m.map(|v| v / n as f64));
        }
    }
    t
}

#[test]
fn c_step_example_compiles_runs_and_matches_the_rust_world() {
    let dir = tempfile::tempdir().unwrap();
    let scene = root().join("examples/step.toml");
    let stdout = compile_and_run("step", dir.path(), &[&scene]);
    assert_eq!(stdout.lines().last(), Some("OK"), "{stdout}");
    assert!(stdout.contains("restored yes"), "{stdout}");
    assert!(
        stdout.contains(
            "bad object: code 2: ff_world_positions: invalid object = 7: the scene has 1 objects"
        ),
        "{stdout}"
    );
    assert!(
        stdout.contains("small buffer: code 5: ff_world_positions: out holds 3 doubles"),
        "{stdout}"
    );
    assert!(
        stdout.contains("reflection: code 2: ff_world_set_boundary_pose: invalid pose")
            && stdout.contains("proper rotation"),
        "{stdout}"
    );

    let c = parse_c(&stdout);
    let r = rust_trace(&scene);
    assert_eq!(c.steps.len(), 30, "{stdout}");
    assert_eq!(c.means.len(), 3, "{stdout}");
    assert_eq!(c.points.len(), 9, "{stdout}");
    // The floor is reached: the contact path is exercised.
    assert!(c.steps.iter().any(|s| s.3 > 0), "{stdout}");
    // Same library, same code path, same thread count (rayon's default in both processes),
    // and %.17g round-trips a double: the numbers should be bit-identical. The tolerance,
    // 1e-12 relative to the metre scale of the scene, only leaves room for the C and Rust
    // sin/cos of the twist angle differing in the last bit (a 1e-16 perturbation of the
    // target, which the solves carry through at a similar relative size); any real
    // difference in the calls (a pose, a step, the gravity switch) is millimetres.
    let close = |a: f64, b: f64| (a - b).abs() <= 1e-12 * b.abs().max(1.0);
    for (k, (cs, rs)) in c.steps.iter().zip(&r.steps).enumerate() {
        assert!(
            close(cs.0, rs.0),
            "step {}: time {} vs {}",
            k + 1,
            cs.0,
            rs.0
        );
        assert_eq!((cs.1, cs.2, cs.3), (rs.1, rs.2, rs.3), "step {}", k + 1);
    }
    assert_eq!(
        c.points.keys().collect::<Vec<_>>(),
        r.points.keys().collect::<Vec<_>>()
    );
    for (key, x) in &c.points {
        let y = r.points[key];
        assert!((0..3).all(|d| close(x[d], y[d])), "{key:?}: {x:?} vs {y:?}");
    }
    for (k, x) in &c.means {
        let y = r.means[k];
        assert!(
            (0..3).all(|d| close(x[d], y[d])),
            "mean {k}: {x:?} vs {y:?}"
        );
    }
}

fn last_error() -> String {
    // SAFETY: ff_last_error returns a valid NUL-terminated string.
    unsafe { CStr::from_ptr(ff_last_error()) }
        .to_string_lossy()
        .into_owned()
}

/// `code` is `want` and the message contains every piece of `says`.
#[track_caller]
fn check(code: c_int, want: Status, says: &[&str]) {
    let msg = last_error();
    assert_eq!(code, want as c_int, "{msg}");
    for s in says {
        assert!(msg.contains(s), "{msg:?} does not say {s:?}");
    }
}

fn open(path: &Path, strict: bool) -> (c_int, *mut FfWorld) {
    let p = CString::new(path.to_str().unwrap()).unwrap();
    let mut w: *mut FfWorld = null_mut();
    let code = unsafe { ff_world_open(p.as_ptr(), strict.into(), &mut w) };
    (code, w)
}

/// A small scene in `dir`: a held bar and a floor, with the solver settings `solver`.
fn small_scene(dir: &Path, solver: &str) -> PathBuf {
    let path = dir.join("small.toml");
    std::fs::write(
        &path,
        format!(
            r#"
[simulation]
dt = 0.01
steps = 5
gravity = [0.0, -9.81, 0.0]

[solver]
cubature = 200
{solver}

[cache]
enabled = false

[[object]]
name = "bar"
shape = "box:1,0.2,0.2"
material = {{ youngs = 1e6, poisson = 0.4, density = 1000.0 }}
basis = {{ kernels = 40, modes = 4, points = 1500 }}

[[object.boundary]]
region = {{ half_space = {{ point = [0.1, 0.0, 0.0], normal = [-1.0, 0.0, 0.0] }} }}

[[collider]]
shape = {{ plane = {{ point = [0.0, -0.5, 0.0], normal = [0.0, 1.0, 0.0] }} }}
"#
        ),
    )
    .unwrap();
    path
}

#[test]
fn opening_errors_are_codes_with_messages() {
    let dir = tempfile::tempdir().unwrap();
    // *out is NULL after any failure, whatever it held before.
    let mut w = std::ptr::NonNull::<FfWorld>::dangling().as_ptr();
    let code = unsafe { ff_world_open(null(), 0, &mut w) };
    check(
        code,
        Status::NullPointer,
        &["ff_world_open: scene_path is NULL"],
    );
    assert!(w.is_null());
    let p = CString::new("x.toml").unwrap();
    let code = unsafe { ff_world_open(p.as_ptr(), 0, null_mut()) };
    check(code, Status::NullPointer, &["ff_world_open: out is NULL"]);

    let missing = dir.path().join("missing.toml");
    let (code, w) = open(&missing, false);
    check(code, Status::Io, &["missing.toml"]);
    assert!(w.is_null());

    let bad = dir.path().join("bad.toml");
    std::fs::write(&bad, "[simulation]\ndt = 0.01\nsteps = 5\nwobble = 1\n").unwrap();
    let (code, w) = open(&bad, false);
    check(code, Status::InvalidArgument, &["bad.toml", "wobble"]);
    assert!(w.is_null());

    // A shape file that is not there: the object is named, the cause is a read error.
    let scene = small_scene(dir.path(), "");
    let text = std::fs::read_to_string(&scene)
        .unwrap()
        .replace("box:1,0.2,0.2", "nowhere.obj");
    std::fs::write(&scene, text).unwrap();
    let (code, w) = open(&scene, false);
    check(code, Status::Io, &["'bar'", "nowhere.obj"]);
    assert!(w.is_null());

    unsafe { ff_world_free(null_mut()) };
}

#[test]
fn world_calls_check_pointers_indices_buffers_and_rotations() {
    let dir = tempfile::tempdir().unwrap();
    let (code, w) = open(&small_scene(dir.path(), ""), false);
    assert_eq!(code, 0, "{}", last_error());
    let cw = w as *const FfWorld;
    unsafe {
        // Counts and reads.
        assert_eq!(ff_world_object_count(cw), 1);
        assert_eq!(ff_world_collider_count(cw), 1);
        assert_eq!(ff_world_boundary_count(cw, 0), 1);
        assert_eq!(ff_world_boundary_count(cw, 1), 0);
        assert_eq!(ff_world_object_count(null()), 0);
        assert_eq!(ff_world_time(null()), 0.0);
        assert_eq!(ff_world_point_count(cw, 1), 0);
        assert!(ff_world_object_name(cw, 1).is_null());
        assert_eq!(
            CStr::from_ptr(ff_world_object_name(cw, 0)).to_str(),
            Ok("bar")
        );
        let n = ff_world_point_count(cw, 0);
        let len = ff_world_state_len(cw, 0);
        assert_eq!(len, 12 * 5);
        assert!(n > 0);
        let mut idx = 9;
        let name = CString::new("bar").unwrap();
        assert_eq!(ff_world_object_index(cw, name.as_ptr(), &mut idx), 0);
        assert_eq!(idx, 0);
        let other = CString::new("ball").unwrap();
        check(
            ff_world_object_index(cw, other.as_ptr(), &mut idx),
            Status::InvalidArgument,
            &["no object named 'ball'", "bar"],
        );
        check(
            ff_world_object_index(cw, null(), &mut idx),
            Status::NullPointer,
            &["name or out"],
        );

        // Positions: NULL world, NULL buffer, bad object, small buffer.
        let mut x = vec![0.0; 3 * n];
        check(
            ff_world_positions(null(), 0, x.as_mut_ptr(), 3 * n),
            Status::NullPointer,
            &["ff_world_positions: world is NULL"],
        );
        check(
            ff_world_positions(cw, 0, null_mut(), 3 * n),
            Status::NullPointer,
            &["out is NULL"],
        );
        check(
            ff_world_positions(cw, 3, x.as_mut_ptr(), 3 * n),
            Status::InvalidArgument,
            &["object = 3", "1 objects"],
        );
        let need = format!("{} needed", 3 * n);
        check(
            ff_world_positions(cw, 0, x.as_mut_ptr(), 3 * n - 1),
            Status::BufferTooSmall,
            &[&need],
        );
        check(
            ff_world_rest_positions(cw, 0, x.as_mut_ptr(), 2),
            Status::BufferTooSmall,
            &[&need],
        );
        assert_eq!(ff_world_rest_positions(cw, 0, x.as_mut_ptr(), 3 * n), 0);

        // Step report before the first step, then after it.
        let mut rep = FfStepReport::default();
        check(
            ff_world_step_report(cw, 0, &mut rep),
            Status::InvalidArgument,
            &["ff_world_step_report: object 0 ('bar') has taken no step yet"],
        );
        check(
            ff_world_step(null_mut()),
            Status::NullPointer,
            &["ff_world_step"],
        );
        assert_eq!(ff_world_step(w), 0, "{}", last_error());
        assert_eq!(ff_world_step_report(cw, 0, &mut rep), 0);
        assert_eq!(rep.step, 1);
        assert!(rep.iterations > 0 && rep.converged == 1 && rep.wall_ms > 0.0);
        check(
            ff_world_step_report(cw, 2, &mut rep),
            Status::InvalidArgument,
            &["object = 2"],
        );
        check(
            ff_world_step_report(cw, 0, null_mut()),
            Status::NullPointer,
            &["out is NULL"],
        );
        assert_eq!(ff_world_steps(cw), 1);
        assert!((ff_world_time(cw) - 0.01).abs() < 1e-15);

        // Poses: NULL translation, bad object / boundary / collider, improper rotations.
        let t = [0.0, 0.1, 0.0];
        check(
            ff_world_set_boundary_pose(w, 0, 0, null(), null()),
            Status::NullPointer,
            &["translation is NULL"],
        );
        check(
            ff_world_set_boundary_pose(w, 4, 0, null(), t.as_ptr()),
            Status::InvalidArgument,
            &["object = 4", "1 objects"],
        );
        check(
            ff_world_set_boundary_pose(w, 0, 2, null(), t.as_ptr()),
            Status::InvalidArgument,
            &[
                "ff_world_set_boundary_pose: invalid boundary = 2",
                "1 boundaries",
            ],
        );
        let mirror = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, -1.0];
        check(
            ff_world_set_boundary_pose(w, 0, 0, mirror.as_ptr(), t.as_ptr()),
            Status::InvalidArgument,
            &["proper rotation", "det"],
        );
        let scaled = [2.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0];
        check(
            ff_world_set_collider_pose(w, 0, scaled.as_ptr(), t.as_ptr()),
            Status::InvalidArgument,
            &["proper rotation"],
        );
        check(
            ff_world_set_collider_pose(w, 1, null(), t.as_ptr()),
            Status::InvalidArgument,
            &[
                "ff_world_set_collider_pose: invalid collider = 1",
                "1 colliders",
            ],
        );
        let nan = [0.0, f64::NAN, 0.0];
        check(
            ff_world_set_collider_pose(w, 0, null(), nan.as_ptr()),
            Status::InvalidArgument,
            &["finite"],
        );
        assert_eq!(ff_world_set_boundary_pose(w, 0, 0, null(), t.as_ptr()), 0);
        assert_eq!(ff_world_set_collider_pose(w, 0, null(), t.as_ptr()), 0);

        // Gravity.
        check(
            ff_world_set_gravity(w, nan.as_ptr()),
            Status::InvalidArgument,
            &["gravity", "finite"],
        );
        check(
            ff_world_set_gravity(null_mut(), null()),
            Status::NullPointer,
            &["ff_world_set_gravity"],
        );
        assert_eq!(ff_world_set_gravity(w, null()), 0);

        // State: small buffers, wrong length, non-finite values (all or nothing), round trip.
        let (mut z, mut zd) = (vec![0.0; len], vec![0.0; len]);
        let need = format!("{len} needed");
        check(
            ff_world_get_state(cw, 0, z.as_mut_ptr(), zd.as_mut_ptr(), len - 1),
            Status::BufferTooSmall,
            &[&need],
        );
        check(
            ff_world_get_state(cw, 0, z.as_mut_ptr(), null_mut(), len),
            Status::NullPointer,
            &["zdot is NULL"],
        );
        check(
            ff_world_get_state(cw, 1, z.as_mut_ptr(), zd.as_mut_ptr(), len),
            Status::InvalidArgument,
            &["object = 1"],
        );
        assert_eq!(
            ff_world_get_state(cw, 0, z.as_mut_ptr(), zd.as_mut_ptr(), len),
            0
        );
        let want = format!("{len} values");
        check(
            ff_world_set_state(w, 0, z.as_ptr(), zd.as_ptr(), len - 12),
            Status::InvalidArgument,
            &[&want],
        );
        check(
            ff_world_set_state(w, 0, z.as_ptr(), null(), len),
            Status::NullPointer,
            &["z or zdot is NULL"],
        );
        let mut bad = z.clone();
        bad[3] = f64::INFINITY;
        check(
            ff_world_set_state(w, 0, bad.as_ptr(), zd.as_ptr(), len),
            Status::InvalidArgument,
            &["ff_world_set_state: invalid z = inf: value 3 is not finite"],
        );
        let (mut z2, mut zd2) = (vec![0.0; len], vec![0.0; len]);
        ff_world_get_state(cw, 0, z2.as_mut_ptr(), zd2.as_mut_ptr(), len);
        assert_eq!((&z2, &zd2), (&z, &zd), "a refused state changed the object");
        zd2.iter_mut().for_each(|v| *v = 0.0);
        assert_eq!(ff_world_set_state(w, 0, z.as_ptr(), zd2.as_ptr(), len), 0);
        ff_world_get_state(cw, 0, z2.as_mut_ptr(), zd.as_mut_ptr(), len);
        assert_eq!(z2, z);
        assert!(zd.iter().all(|&v| v == 0.0));

        assert_eq!(ff_world_warning_count(cw), 0);
        assert!(ff_world_warning(cw, 0).is_null());
        ff_world_free(w);
    }
}

#[test]
fn a_step_that_does_not_converge_is_a_status_or_in_strict_mode_stops_the_world() {
    let dir = tempfile::tempdir().unwrap();
    // One iteration cannot meet a tolerance of 1e-14 under gravity.
    let scene = small_scene(dir.path(), "max_iter = 1\ntol = 1e-14");
    let (code, w) = open(&scene, false);
    assert_eq!(code, 0, "{}", last_error());
    unsafe {
        assert_eq!(ff_world_step(w), 0, "{}", last_error());
        let mut rep = FfStepReport::default();
        assert_eq!(ff_world_step_report(w, 0, &mut rep), 0);
        assert_eq!((rep.converged, rep.iterations), (0, 1));
        assert_eq!(ff_world_nonconverged_steps(w, 0), 1);
        assert_eq!(ff_world_warning_count(w), 1);
        let text = CStr::from_ptr(ff_world_warning(w, 0)).to_string_lossy();
        assert!(text.contains("did not converge"), "{text}");
        ff_world_free(w);
    }

    let (code, w) = open(&scene, true);
    assert_eq!(code, 0, "{}", last_error());
    unsafe {
        check(
            ff_world_step(w),
            Status::Strict,
            &["strict mode", "did not converge"],
        );
        check(
            ff_world_step(w),
            Status::Strict,
            &["ff_world_step: the world has stopped (at step 1: strict mode"],
        );
        // Reading still works.
        let n = ff_world_point_count(w, 0);
        let mut x = vec![0.0; 3 * n];
        assert_eq!(ff_world_positions(w, 0, x.as_mut_ptr(), x.len()), 0);
        assert!(x.iter().all(|v| v.is_finite()));
        ff_world_free(w);
    }
}
