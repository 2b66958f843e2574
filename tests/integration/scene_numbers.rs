//! The generated bad-number test (issue 33): every number of a fully populated scene, in
//! turn, replaced by NaN, +-Inf, 0, -1, 1e300 and 1e-300 (an integer by 0, -1 and
//! i64::MAX), and the scene read again (`Scene::from_toml`: parsing and validation, before any
//! basis is built). Each replacement must be refused with a message that names the field, or
//! be listed in [`ACCEPTED`] with the reason it is meaningful.
//!
//! The field list is not hand-written: the numbers are found by walking the parsed scene, and
//! a coverage check asks serde for every table's fields (a table given an unknown key answers
//! "expected one of ..."; an enum, "unknown variant ..., expected one of ..."), so a field
//! or variant added to the scene format fails this test until [`FULL`] holds it.

use freeform::scene::Scene;
use std::collections::{BTreeMap, BTreeSet};
use toml::Value;

/// A scene with every table, field and enum variant present (`@DIR`: a folder holding
/// `cube.obj`). [`FULL`] gives `basis.points`; [`full_scenes`] adds the same scene with
/// `basis.spacing` instead (the two exclude each other).
const FULL: &str = r#"
[simulation]
dt = 0.01
steps = 2
gravity = [0.0, -9.81, 0.0]

[solver]
hessian = "lbfgs"
tol = 1e-6
max_iter = 50
lbfgs_history = 8
refresh_iterations = 10
refresh_stride = 2
refresh_precision = "single"
initial_guess = "extrapolate"
cubature = 300

[output]
every = 2
formats = ["vtk"]
rotate_splat_sh = true
stress = false
usd_physics = true

[cache]
enabled = false
dir = "cache"

[materials.soft]
youngs = 1e5
poisson = 0.3
density = 500.0

[contact]
stiffness = 1e8
radius = 0.02
samples = 500
feature_spacing = 0.5
penetration_tolerance = 0.01
friction = 0.5
friction_velocity = 1e-3
solver = "blocks"
hessian_precision = "double"
self_contact = false
self_exclusion = 2.0

[[contact.pair]]
between = ["a", "floor"]
friction = 0.3

[[object]]
name = "a"
shape = "box:1,1,1"
allow_open_mesh = false
cubature = 200
render = ["@DIR/cube.obj"]
contact_samples = 400
self_contact = false
material = { youngs = 1e6, poisson = 0.4, density = 1000.0 }
region_material = [
  { region = { box = { min = [0.0, 0.0, 0.0], max = [0.5, 0.5, 0.5] } }, material = { youngs = 2e6, poisson = 0.3, density = 900.0 } },
  { region = { sphere = { center = [0.5, 0.5, 0.5], radius = 0.2 } }, material = { youngs = 3e6, poisson = 0.3, density = 900.0 } },
  { region = { half_space = { point = [0.9, 0.0, 0.0], normal = [1.0, 0.0, 0.0] } }, material = { youngs = 4e6, poisson = 0.3, density = 900.0 } },
]
placement = { translation = [0.0, 1.0, 0.0], rotation = { axis = [0.0, 1.0, 0.0], degrees = 10.0 }, velocity = [0.0, 0.0, 0.0], angular_velocity = [0.0, 0.0, 0.0] }
image = { file = "@DIR/img.npy", spacing = [0.1, 0.1, 0.1], origin = [0.0, 0.0, 0.0], values = "labels", labels = { 1 = "soft" }, gaps = "error" }

[object.basis]
kernels = 60
modes = 8
points = 2000
kernel = "cubic"
support = 1.5
support_neighbor = 10
eigen_tol = 1e-8
volume = 1.0
voxel = 0.05
boundaries = "aware"
density_boundaries = 1.0
density_interfaces = 1.0
density_band = 1.0
density_thin = 1.0
eigensolver = { lobpcg = { guard = 4, preconditioner = "incomplete_cholesky", shift_factor = 1e-3, max_factor_entries = 1000000, max_fill_ratio = 10.0, escalate_after = 20, recompute_every = 10, restart_tol = 1e-3, ortho_drop = 1e-10, svqb_drop = 1e-14, seed = 7 } }

[[object.boundary]]
region = { half_space = { point = [0.1, 0.0, 0.0], normal = [-1.0, 0.0, 0.0] } }
stiffness = 1e7
motion = { rotate = { pivot = [0.0, 0.5, 0.5], axis = [1.0, 0.0, 0.0], degrees_per_second = 90.0 } }

[[object.boundary]]
region = { box = { min = [0.9, 0.0, 0.0], max = [1.0, 1.0, 1.0] } }
motion = { keyframes = { pivot = [1.0, 0.5, 0.5], frames = [ { time = 0.0, translation = [0.0, 0.0, 0.0], rotation = { axis = [0.0, 0.0, 1.0], degrees = 0.0 } }, { time = 1.0, translation = [0.1, 0.0, 0.0], rotation = { axis = [0.0, 0.0, 1.0], degrees = 30.0 } } ] } }

[[object.boundary]]
region = { sphere = { center = [0.5, 1.0, 0.5], radius = 0.1 } }
motion = { translate = { velocity = [0.0, 0.1, 0.0] } }

[[object.boundary]]
region = { sphere = { center = [0.5, 0.0, 0.5], radius = 0.1 } }
motion = { pose = { rotation = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]], translation = [0.0, 0.0, 0.0] } }

[[object.boundary]]
region = { sphere = { center = [0.0, 0.0, 0.0], radius = 0.1 } }
motion = "fixed"

[[collider]]
name = "floor"
shape = { plane = { point = [0.0, -1.0, 0.0], normal = [0.0, 1.0, 0.0] } }
stiffness = 1e8

[[collider]]
name = "wall"
parent = "floor"
shape = { box = { min = [2.0, -1.0, -1.0], max = [3.0, 1.0, 1.0], rotation = { axis = [0.0, 1.0, 0.0], degrees = 5.0 } } }
motion = { translate = { velocity = [0.0, 0.0, 0.1] } }

[[collider]]
shape = { sphere = { center = [-2.0, 0.0, 0.0], radius = 0.3 } }
motion = { rotate = { pivot = [-2.0, 0.0, 0.0], axis = [0.0, 1.0, 0.0], degrees_per_second = 45.0 } }

[[collider]]
shape = { capsule = { a = [-2.0, 1.0, 0.0], b = [-2.0, 2.0, 0.0], radius = 0.2 } }
motion = { keyframes = { pivot = [-2.0, 1.5, 0.0], frames = [ { time = 0.0, translation = [0.0, 0.0, 0.0] }, { time = 0.5, translation = [0.0, 0.2, 0.0], rotation = { axis = [1.0, 0.0, 0.0], degrees = 20.0 } } ] } }

[[collider]]
shape = { sphere = { center = [-4.0, 0.0, 0.0], radius = 0.3 } }
motion = { pose = { rotation = [[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]], translation = [0.0, 0.5, 0.0] } }

[[collider]]
shape = { sphere = { center = [-6.0, 0.0, 0.0], radius = 0.3 } }
motion = "fixed"

[[collider]]
shape = { mesh = { file = "@DIR/cube.obj", sided = "solid", scale = 0.5, rotation = { axis = [0.0, 0.0, 1.0], degrees = 15.0 }, translation = [4.0, 0.0, 0.0] } }
"#;

/// Replacements that are meaningful, by the end of the field's path (indices dropped): the
/// case ("0", "-1", "inf" for +-Inf, "max" for i64::MAX) and why it is accepted.
const ACCEPTED: &[(&str, &[&str], &str)] = &[
    // Positions, directions and velocities take either sign; one component 0 leaves the
    // vector valid (zero axes and normals are refused as vectors).
    ("point[]", &["0", "-1"], "a coordinate, metres"),
    ("normal[]", &["0", "-1"], "a direction component"),
    ("center[]", &["0", "-1"], "a coordinate, metres"),
    ("min[]", &["0", "-1"], "a coordinate, metres"),
    (
        "max[]",
        &["0"],
        "a coordinate, metres (-1 is below min and refused)",
    ),
    (".a[]", &["0", "-1"], "a capsule end, metres"),
    (".b[]", &["0", "-1"], "a capsule end, metres"),
    ("pivot[]", &["0", "-1"], "a coordinate, metres"),
    ("translation[]", &["0", "-1"], "a displacement, metres"),
    ("velocity[]", &["0", "-1"], "a velocity component, m/s"),
    (
        "angular_velocity[]",
        &["0", "-1"],
        "an angular velocity component, rad/s",
    ),
    ("axis[]", &["0", "-1"], "a rotation axis component"),
    ("origin[]", &["0", "-1"], "an image origin, metres"),
    ("gravity[]", &["0", "-1"], "a gravity component, m/s^2"),
    // A box region's bounds may be infinite: a half-open slab (docs/scenes.md).
    ("region.box.min[]", &["inf"], "a half-open slab"),
    ("region.box.max[]", &["inf"], "a half-open slab"),
    (
        "degrees",
        &["0", "-1"],
        "an angle of either sign; 0 is no rotation",
    ),
    (
        "degrees_per_second",
        &["0", "-1"],
        "a rate of either sign; 0 holds the region",
    ),
    (
        "frames[].time",
        &["0", "-1"],
        "keyframes may start before the run's t = 0",
    ),
    ("friction", &["0"], "frictionless"),
    (
        "feature_spacing",
        &["0"],
        "no feature samples (the default)",
    ),
    ("poisson", &["0"], "a material without lateral contraction"),
    (
        "lobpcg.guard",
        &["0"],
        "no guard vectors (slower for clustered eigenvalues)",
    ),
    (
        "lobpcg.max_fill_ratio",
        &["0"],
        "never the exact factor by fill",
    ),
    ("lobpcg.restart_tol", &["0"], "never restart"),
    ("lobpcg.ortho_drop", &["0"], "drop no direction"),
    ("lobpcg.svqb_drop", &["0"], "drop no Gram eigenvalue"),
    (
        "lobpcg.escalate_after",
        &["0", "max"],
        "never switch to the exact factor",
    ),
    (
        "lobpcg.max_factor_entries",
        &["0", "max"],
        "the exact factor's budget: none, or any",
    ),
    (
        "lobpcg.recompute_every",
        &["max"],
        "never recompute the products explicitly",
    ),
    ("lobpcg.seed", &["0", "max"], "any seed"),
    (
        "slepc.shift",
        &["0", "-1"],
        "a SLEPc target of either sign (its default is negative)",
    ),
    ("output.every", &["max"], "only the first frame is written"),
    (
        "solver.refresh_iterations",
        &["0", "max"],
        "0 (or more than max_iter): never refresh",
    ),
    (
        "solver.refresh_stride",
        &["max"],
        "the refresh samples the first cubature point only",
    ),
];

fn full_scenes(dir: &str) -> Vec<Value> {
    let full = FULL.replace("@DIR", dir);
    // The variants FULL cannot hold at once: a grid spacing instead of a point count, SLEPc
    // instead of the native eigensolver.
    let spacing = full.replace("points = 2000\n", "spacing = 0.1\n");
    let (from, to) = full.split_at(full.find("eigensolver = { lobpcg").unwrap());
    let slepc = format!(
        "{from}eigensolver = {{ slepc = {{ preset = \"lobpcg-gamg\", petsc_options = \
         \"-eps_max_it 50\", shift = 1.0 }} }}{}",
        &to[to.find('\n').unwrap()..]
    );
    assert_ne!(full, spacing);
    [full, spacing, slepc]
        .iter()
        .map(|text| {
            if let Err(e) = Scene::from_toml(text) {
                panic!("the full scene must be valid: {e}");
            }
            toml::from_str(text).unwrap()
        })
        .collect()
}

/// One step into the document: a key or an array index.
#[derive(Clone, Debug)]
enum Step {
    Key(String),
    Index(usize),
}

/// The path with indices dropped: `object[].boundary[].motion.rotate.pivot[]`.
fn pattern(path: &[Step]) -> String {
    let mut s = String::new();
    for p in path {
        match p {
            Step::Key(k) if s.is_empty() => s.push_str(k),
            Step::Key(k) => {
                s.push('.');
                s.push_str(k);
            }
            Step::Index(_) => s.push_str("[]"),
        }
    }
    s
}

fn at<'a>(v: &'a mut Value, path: &[Step]) -> &'a mut Value {
    path.iter().fold(v, |v, p| match p {
        Step::Key(k) => v.as_table_mut().unwrap().get_mut(k).unwrap(),
        Step::Index(i) => &mut v.as_array_mut().unwrap()[*i],
    })
}

/// The paths of a document's tables, numbers and strings (with each string's value).
#[derive(Default)]
struct Paths {
    tables: Vec<Vec<Step>>,
    numbers: Vec<Vec<Step>>,
    strings: Vec<(Vec<Step>, String)>,
}

fn paths(doc: &Value) -> Paths {
    fn go(v: &Value, path: &mut Vec<Step>, out: &mut Paths) {
        match v {
            Value::Table(t) => {
                out.tables.push(path.clone());
                for (k, x) in t {
                    path.push(Step::Key(k.clone()));
                    go(x, path, out);
                    path.pop();
                }
            }
            Value::Array(a) => {
                for (i, x) in a.iter().enumerate() {
                    path.push(Step::Index(i));
                    go(x, path, out);
                    path.pop();
                }
            }
            Value::Integer(_) | Value::Float(_) => out.numbers.push(path.clone()),
            Value::String(s) => out.strings.push((path.clone(), s.clone())),
            _ => {}
        }
    }
    let mut out = Paths::default();
    go(doc, &mut Vec::new(), &mut out);
    out
}

fn read(doc: &Value) -> Result<(), String> {
    Scene::from_toml(&toml::to_string(doc).unwrap())
        .map(|_| ())
        .map_err(|e| e.to_string())
}

/// The names serde lists in "expected one of `a`, `b`", "expected `a` or `b`" or
/// "available keys: a, b".
fn listed_names(message: &str) -> Option<BTreeSet<String>> {
    if let Some((_, rest)) = message.split_once("available keys: ") {
        let line = rest.lines().next().unwrap_or("");
        return Some(line.split(", ").map(|s| s.trim().to_string()).collect());
    }
    let (_, rest) = message
        .split_once(", expected ")
        .or_else(|| message.split_once("give exactly one, "))?;
    let line = rest.lines().next().unwrap_or("");
    Some(
        line.split('`')
            .skip(1)
            .step_by(2)
            .map(str::to_string)
            .collect(),
    )
}

/// Tables whose keys are names, not fields: named materials and image labels.
const MAPS: &[&str] = &["materials", "object[].image.labels"];

/// A table that holds one enum variant (`motion = { rotate = {...} }`).
fn is_variant_wrapper(message: &str) -> bool {
    message.contains("wanted exactly 1 element")
}

#[test]
fn the_full_scenes_hold_every_field_and_variant() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("cube.obj"), CUBE_OBJ).unwrap();
    let docs = full_scenes(dir.path().to_str().unwrap());
    // Keys present at each table pattern, over the full scenes.
    let mut present: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
    let mut expected: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
    for doc in &docs {
        let found = paths(doc);
        // A unit variant is a string (`motion = "fixed"`): present at its own path.
        for (p, s) in &found.strings {
            present.entry(pattern(p)).or_default().insert(s.clone());
        }
        for t in &found.tables {
            let p = pattern(t);
            let mut d = doc.clone();
            let table = at(&mut d, t).as_table_mut().unwrap();
            present
                .entry(p.clone())
                .or_default()
                .extend(table.keys().cloned());
            if MAPS.contains(&p.as_str()) {
                continue;
            }
            table.insert("zz_unknown".into(), Value::Integer(1));
            let mut message = read(&d).expect_err(&format!("{p}: an unknown key was accepted"));
            if is_variant_wrapper(&message) {
                // Ask for the variants: a table with only an unknown one.
                let mut d = doc.clone();
                let mut only = toml::Table::new();
                only.insert("zz_unknown".into(), Value::Table(toml::Table::new()));
                *at(&mut d, t) = Value::Table(only);
                message = read(&d).unwrap_err();
            }
            let names = listed_names(&message)
                .unwrap_or_else(|| panic!("{p}: serde lists no fields: {message}"));
            expected.entry(p).or_default().extend(names);
        }
    }
    let mut missing = Vec::new();
    for (p, names) in &expected {
        for n in names.difference(&present[p]) {
            missing.push(format!("{p}.{n}"));
        }
    }
    assert!(
        missing.is_empty(),
        "the full scenes lack these fields or variants; add them to FULL so that the bad-number \
         sweep covers them: {missing:?}"
    );
}

#[test]
fn every_number_of_a_scene_is_refused_by_name_or_accepted_for_a_reason() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("cube.obj"), CUBE_OBJ).unwrap();
    let floats = [
        ("nan", f64::NAN),
        ("inf", f64::INFINITY),
        ("inf", f64::NEG_INFINITY),
        ("0", 0.0),
        ("-1", -1.0),
        ("1e300", 1e300),
        ("1e-300", 1e-300),
    ];
    let ints = [("0", 0), ("-1", -1), ("max", i64::MAX)];
    let (mut fields, mut cases, mut accepted) = (BTreeSet::new(), 0, 0);
    let mut problems = Vec::new();
    for doc in full_scenes(dir.path().to_str().unwrap()) {
        for path in &paths(&doc).numbers {
            let p = pattern(path);
            fields.insert(p.clone());
            let leaf = path
                .iter()
                .rev()
                .find_map(|s| match s {
                    Step::Key(k) => Some(k.clone()),
                    Step::Index(_) => None,
                })
                .unwrap();
            // A message names the field by its key, or in words (`support neighbor`).
            let names = [leaf.clone(), leaf.replace('_', " "), leaf.replace('_', "-")];
            let original = at(&mut doc.clone(), path).clone();
            let replacements: Vec<(&str, Value)> = match original {
                Value::Integer(_) => ints
                    .iter()
                    .map(|&(c, v)| (c, Value::Integer(v)))
                    .chain([("nan", Value::Float(f64::NAN))])
                    .collect(),
                _ => floats.iter().map(|&(c, v)| (c, Value::Float(v))).collect(),
            };
            for (case, value) in replacements {
                if value.to_string() == original.to_string() {
                    continue; // no change (a 0 entry set to 0)
                }
                cases += 1;
                let mut d = doc.clone();
                *at(&mut d, path) = value.clone();
                match read(&d) {
                    Err(m) if names.iter().any(|n| m.contains(n.as_str())) => {}
                    Err(m) => {
                        problems.push(format!("{p} = {value}: refused without naming it: {m}"))
                    }
                    Ok(()) => {
                        let listed = ACCEPTED
                            .iter()
                            .any(|(end, cs, _)| p.ends_with(end) && cs.contains(&case));
                        if listed {
                            accepted += 1;
                        } else {
                            problems.push(format!("{p} = {value}: accepted, not in ACCEPTED"));
                        }
                    }
                }
            }
        }
    }
    println!(
        "{} numeric fields, {cases} replacements, {accepted} accepted as listed",
        fields.len()
    );
    assert!(
        problems.is_empty(),
        "{} problems:\n{}",
        problems.len(),
        problems.join("\n")
    );
    // Every ACCEPTED row is used: a stale row would hide a field that changed.
    for (end, _, why) in ACCEPTED {
        assert!(
            fields.iter().any(|f| f.ends_with(end)),
            "ACCEPTED row {end:?} ({why}) matches no field"
        );
    }
}

const CUBE_OBJ: &str = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0 0 1\nv 1 0 1\nv 1 1 1\nv 0 1 1\n\
f 1 3 2\nf 1 4 3\nf 5 6 7\nf 5 7 8\nf 1 2 6\nf 1 6 5\nf 2 3 7\nf 2 7 6\nf 3 4 8\nf 3 8 7\n\
f 4 1 5\nf 4 5 8\n";
