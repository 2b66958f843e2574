//! The option table (issue 27): library messages name every option as the front end that
//! prints them sets it, and the scene keys and Python's keywords are the table's (the command
//! line's flags are checked in `src/bin/freeform/problem.rs`, the C fields in `capi`).

use freeform::geometry::GeometryError;
use freeform::material::Material;
use freeform::options::{self, Front};
use freeform::precompute::table::BASIS_OPTIONS;
use freeform::precompute::{BasisChoices, BasisOption, OptionTable, Value, ValueKind};
use freeform::scene::{BasisSettings, Scene};
use std::collections::BTreeSet;

/// The library's errors read on the command line word for word as they did when the library
/// named the flags itself (the texts of db35e11), and name scene keys for `freeform run`
/// (these checks were the CLI's `messages.rs` tests, which replaced library names in the text).
#[test]
fn library_messages_name_options_as_each_front_end_sets_them() {
    let open = GeometryError::NotWatertight {
        path: "m.obj".into(),
        boundary_edges: 4,
        nonmanifold_edges: 0,
    };
    assert_eq!(
        Front::Flags.render(&open),
        "m.obj: mesh is not watertight (4 boundary edges, 0 non-manifold edges); repair it, or \
         pass --allow-open-mesh to decide inside by winding number"
    );
    assert!(Front::Library
        .render(&open)
        .ends_with("or pass ShapeOptions::allow_open_mesh to decide inside by winding number"));
    let flipped = GeometryError::Misoriented {
        path: "m.obj".into(),
        misoriented_edges: 3,
    };
    assert!(Front::Scene
        .render(&flipped)
        .ends_with("or pass allow_open_mesh to use the winding number anyway"));
    let coverage = freeform::Error::Coverage {
        count: 2,
        index: 7,
        position: [0.0, 1.0, 2.0],
        covering: 3,
        rcond: 0.0,
        min_rcond: 1e-9,
    };
    for (front, name) in [
        (Front::Flags, "--support"),
        (Front::Scene, "basis.support"),
        (Front::Python, "support_factor"),
        (Front::C, "support_factor"),
        (Front::Library, "BasisOptions::support.factor"),
    ] {
        assert!(
            front.render(&coverage).ends_with(&format!(
                "increase the support factor ({name}), the number of kernels, or check for \
                 isolated points"
            )),
            "{front:?}"
        );
    }
    let dense = freeform::eigen::EigenError::TooLarge {
        solver: "dense",
        k: 9000,
        limit: 4000,
    };
    assert_eq!(
        Front::Flags.render(&dense),
        "the dense solver refuses K = 9000 (limit 4000); use --solver lobpcg"
    );
    assert_eq!(
        Front::Scene.render(&dense),
        "the dense solver refuses K = 9000 (limit 4000); use basis.eigensolver = \"lobpcg\""
    );
    // A message made where it is raised (eager text) follows the front of the thread that
    // raises it: too few integration points for the kernels.
    let few: Vec<[f64; 3]> = (0..5).map(|i| [i as f64, 0.0, 0.0]).collect();
    let err = |front: Front| {
        front.scope(|| {
            let e = freeform::precompute::centers::farthest_point_sampling(&few, 10).unwrap_err();
            e.to_string()
        })
    };
    assert!(
        err(Front::Flags).ends_with("(--points / --spacing)"),
        "{}",
        err(Front::Flags)
    );
    assert!(err(Front::Scene).ends_with("(basis.points / basis.spacing)"));
}

/// A value of `row`'s kind that the scene and the table both accept, away from the default.
fn sample(row: &BasisOption) -> Value {
    match (row.kind, (row.default)(&BasisChoices::default())) {
        (ValueKind::Count, Some(Value::Count(d))) => Value::Count(d + 2),
        (ValueKind::Count, _) => Value::Count(50_000),
        (ValueKind::Number, Some(Value::Number(d))) => Value::Number(0.8 * d),
        (ValueKind::Number, _) => Value::Number(0.05),
        (ValueKind::Switch, _) => Value::Switch(true),
        (ValueKind::Choice(names), _) => Value::Text(names().last().unwrap().to_string()),
        (ValueKind::Text, _) => Value::Text("dense".into()),
        (ValueKind::Texts, _) => Value::Texts(vec!["box:0,0,0,1,1,0.1".into()]),
    }
}

/// The value as a TOML value.
fn toml_value(v: &Value) -> String {
    match v {
        Value::Count(n) => n.to_string(),
        Value::Number(x) => format!("{x:e}"),
        Value::Switch(b) => b.to_string(),
        Value::Text(s) => format!("\"{s}\""),
        Value::Texts(v) => format!("{v:?}"),
    }
}

#[test]
fn the_scene_keys_are_the_option_tables() {
    // Every key of an object's `basis` table is a row's scene key, and the other way round.
    let full = BasisSettings {
        points: Some(1),
        spacing: Some(0.1),
        volume: Some(1.0),
        voxel: Some(0.1),
        ..BasisSettings::default()
    };
    let keys = |value: serde_json::Value, table: &str| -> BTreeSet<String> {
        let serde_json::Value::Object(map) = value else {
            panic!("{table}: not a table")
        };
        map.keys().map(|k| format!("{table}.{k}")).collect()
    };
    let in_table = |prefix: &str| -> BTreeSet<String> {
        options::ALL
            .iter()
            .filter_map(|o| o.scene)
            .filter(|k| k.starts_with(prefix))
            .map(String::from)
            .collect()
    };
    assert_eq!(
        keys(serde_json::to_value(&full).unwrap(), "basis"),
        in_table("basis.")
    );
    assert_eq!(
        keys(
            serde_json::to_value(Material::default()).unwrap(),
            "material"
        ),
        in_table("material.")
    );
    // A scene key sets what the table's row sets with the same value.
    let table = OptionTable::basis();
    let mut checked = 0;
    for row in BASIS_OPTIONS {
        let Some(key) = row.name.scene else { continue };
        let value = sample(row);
        let text = format!(
            "[simulation]\ndt = 0.01\nsteps = 1\n[[object]]\nname = \"a\"\nshape = \
             \"box:1,1,1\"\n{key} = {}\n",
            toml_value(&value)
        );
        let scene = Scene::from_toml(&text).unwrap_or_else(|e| panic!("{key}: {e}"));
        let object = &scene.objects[0];
        let want = table.apply(vec![(row, value)]).unwrap();
        assert_eq!(object.basis_options().unwrap(), want.options, "{key}");
        assert_eq!(object.allow_open_mesh, want.shape.allow_open_mesh, "{key}");
        assert_ne!(
            want,
            BasisChoices::default(),
            "{key}: the sample is the default"
        );
        checked += 1;
    }
    assert_eq!(checked, 19);
    // The defaults are the same: an object without a basis table has the table's defaults.
    let bare = Scene::from_toml(
        "[simulation]\ndt = 0.01\nsteps = 1\n[[object]]\nname = \"a\"\nshape = \"box:1,1,1\"\n",
    )
    .unwrap();
    assert_eq!(
        bare.objects[0].basis_options().unwrap(),
        BasisChoices::default().options
    );
}

#[test]
fn the_python_keywords_are_the_option_tables_and_documented() {
    let python = OptionTable::basis().names(Front::Python);
    let doc =
        std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/docs/python.md")).unwrap();
    for keyword in &python {
        assert!(
            doc.contains(&format!("`{keyword}`")),
            "docs/python.md: {keyword}"
        );
    }
    // One keyword per row, and every row has one.
    assert_eq!(python.len(), BASIS_OPTIONS.len());
    let distinct: BTreeSet<_> = python.iter().collect();
    assert_eq!(distinct.len(), python.len());
}
