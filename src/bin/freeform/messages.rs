//! Library messages in the command line's words. The library names an option by its library
//! name (`BasisOptions::support.factor`); where the CLI prints a library error or warning it
//! puts its own flag (`--support`) in that place, or for `freeform run` the scene key
//! (`basis.support`), since a scene file is where those users set it.
//!
//! Self-contained (outside its tests it uses only `std` and the library's warning type), so
//! library tests that check a message's advice include it with `#[path]` and see what the CLI
//! prints.

use std::error::Error;

/// Where the user sets the options a message names.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Front {
    /// Command-line flags (`freeform modes`, `export`, `beam`, ...).
    Flags,
    /// The keys of an `[[object]]` in a scene file (`freeform run`, docs/scenes.md).
    Scene,
}

/// Each option that library messages name: (library name, command-line flag, scene key).
const OPTIONS: &[(&str, &str, &str)] = &[
    ("BasisOptions::support.factor", "--support", "basis.support"),
    (
        "ShapeOptions::allow_open_mesh",
        "--allow-open-mesh",
        "allow_open_mesh",
    ),
    ("Resolution::Count", "--points", "basis.points"),
    ("Resolution::Spacing", "--spacing", "basis.spacing"),
    (
        "eigen::lobpcg::Lobpcg",
        "--solver lobpcg",
        "basis.eigensolver = \"lobpcg\"",
    ),
];

/// `message` with every library option name replaced by its flag or scene key.
pub fn localize(message: &str, front: Front) -> String {
    OPTIONS
        .iter()
        .fold(message.to_string(), |text, (library, flag, key)| {
            let ours = match front {
                Front::Flags => flag,
                Front::Scene => key,
            };
            text.replace(library, ours)
        })
}

/// [`localize`] every message of `messages` in place.
pub fn localize_all(messages: &mut [String], front: Front) {
    for m in messages.iter_mut() {
        *m = localize(m, front);
    }
}

/// [`localize`] the text of every warning of `warnings` that carries a stage's own words
/// (the monitors' and the cache's; the others name no option).
pub fn localize_warnings(warnings: &mut [freeform::report::Warning], front: Front) {
    use freeform::report::Warning;
    for w in warnings.iter_mut() {
        if let Warning::Monitor { message, .. } | Warning::Cache { message, .. } = w {
            *message = localize(message, front);
        }
    }
}

/// The text of `error` as the CLI prints it ([`localize`]d).
pub fn error_message(error: &dyn Error, front: Front) -> String {
    localize(&error.to_string(), front)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_become_flags_or_scene_keys() {
        let lib = "increase the support factor (BasisOptions::support.factor), or more points \
                   (Resolution::Count / Resolution::Spacing)";
        assert_eq!(
            localize(lib, Front::Flags),
            "increase the support factor (--support), or more points (--points / --spacing)"
        );
        assert_eq!(
            localize(lib, Front::Scene),
            "increase the support factor (basis.support), or more points (basis.points / \
             basis.spacing)"
        );
        assert_eq!(localize("no option named", Front::Flags), "no option named");
        // No library name is part of another, so the order of the replacements is irrelevant.
        for (a, ..) in OPTIONS {
            for (b, ..) in OPTIONS {
                assert!(a == b || !a.contains(b), "{a} contains {b}");
            }
        }
    }

    /// The library's errors read on the command line word for word as they did when the
    /// library named the flags itself (the texts of db35e11).
    #[test]
    fn library_errors_name_the_flags_on_the_command_line() {
        use freeform::geometry::GeometryError;
        let open = GeometryError::NotWatertight {
            path: "m.obj".into(),
            boundary_edges: 4,
            nonmanifold_edges: 0,
        };
        assert_eq!(
            error_message(&open, Front::Flags),
            "m.obj: mesh is not watertight (4 boundary edges, 0 non-manifold edges); repair it, \
             or pass --allow-open-mesh to decide inside by winding number"
        );
        let flipped = GeometryError::Misoriented {
            path: "m.obj".into(),
            misoriented_edges: 3,
        };
        assert!(error_message(&flipped, Front::Scene)
            .ends_with("or pass allow_open_mesh to use the winding number anyway"));
        let coverage = freeform::Error::Coverage {
            count: 2,
            index: 7,
            position: [0.0, 1.0, 2.0],
            covering: 3,
            rcond: 0.0,
            min_rcond: 1e-9,
        };
        assert!(error_message(&coverage, Front::Flags).ends_with(
            "increase the support factor (--support), the number of kernels, or check for \
             isolated points"
        ));
        let dense = freeform::eigen::EigenError::TooLarge {
            solver: "dense",
            k: 9000,
            limit: 4000,
        };
        assert_eq!(
            error_message(&dense, Front::Flags),
            "the dense solver refuses K = 9000 (limit 4000); use --solver lobpcg"
        );
    }
}
