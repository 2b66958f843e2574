//! Which front end a message is written for ([`Front`]), and the scope in which messages name
//! options as that front end does.

use std::cell::Cell;

/// Where a user sets the options a message names: the library's own fields, the command
/// line's flags, a scene file's keys, Python's keywords or the C API's fields. A library
/// message names an option through its [`super::OptionName`]; the text is written in the front
/// end of the thread that formats it ([`Front::scope`]; [`Front::Library`] outside any scope).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Front {
    /// Rust callers: the field of the library's option struct (`BasisOptions::tol`).
    #[default]
    Library,
    /// Command-line flags (`freeform modes`, `export`, `compare`, `beam`, ...): `--tol`.
    Flags,
    /// The keys of a scene file (`freeform run`, `World` in Python and C): `basis.eigen_tol`.
    Scene,
    /// The keyword arguments of the Python package's `Basis` builders: `tol`.
    Python,
    /// The fields of the C API's `ff_options`: `tol`.
    C,
}

thread_local! {
    static CURRENT: Cell<Front> = const { Cell::new(Front::Library) };
}

/// Puts the previous front back when a scope ends, also when it unwinds.
struct Restore(Front);

impl Drop for Restore {
    fn drop(&mut self) {
        CURRENT.with(|c| c.set(self.0));
    }
}

impl Front {
    /// The front end messages are written for on this thread now.
    pub fn current() -> Front {
        CURRENT.with(Cell::get)
    }

    /// Run `work` with every message formatted on this thread naming options as this front
    /// end does: errors and warnings displayed, reports serialized. A front end wraps its
    /// command (or call) in one scope; library messages are formatted on the caller's thread
    /// (where they are raised, outside the parallel loops, or when displayed), so they all
    /// follow it. Scopes nest; the previous front is back afterwards.
    pub fn scope<T>(self, work: impl FnOnce() -> T) -> T {
        let _restore = Restore(CURRENT.with(|c| c.replace(self)));
        work()
    }

    /// The text of `message` (an error, a warning) as this front end shows it.
    pub fn render(self, message: &(impl std::fmt::Display + ?Sized)) -> String {
        self.scope(|| message.to_string())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scopes_nest_and_restore() {
        assert_eq!(Front::current(), Front::Library);
        Front::Flags.scope(|| {
            assert_eq!(Front::current(), Front::Flags);
            Front::Scene.scope(|| assert_eq!(Front::current(), Front::Scene));
            assert_eq!(Front::current(), Front::Flags);
        });
        assert_eq!(Front::current(), Front::Library);
        let unwound = std::panic::catch_unwind(|| Front::Python.scope(|| panic!("inside")));
        assert!(unwound.is_err());
        assert_eq!(Front::current(), Front::Library);
    }
}
