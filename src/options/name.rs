//! An option's names in every front end ([`OptionName`]), and an option with a value as a
//! message advises it ([`Setting`]).

use super::front::Front;
use std::fmt;

/// One option's names, one for each front end that sets it: a row of the option table. A
/// message names the option through this row (`format!("raise {}", options::TOL)`), and the
/// text says `--tol`, `basis.eigen_tol`, `tol` or `BasisOptions::tol` depending on the
/// [`Front`] it is formatted for. A front end without the option shows the library's name.
#[derive(Debug, PartialEq, Eq)]
pub struct OptionName {
    /// The library's field (`BasisOptions::tol`).
    pub library: &'static str,
    /// The command-line flag (`--tol`).
    pub flag: Option<&'static str>,
    /// The scene-file key (`basis.eigen_tol`; `[[object]]` keys without the table).
    pub scene: Option<&'static str>,
    /// The keyword of the Python package's `Basis` builders (`tol`).
    pub python: Option<&'static str>,
    /// The field of the C API's `ff_options` (`tol`).
    pub c: Option<&'static str>,
    /// What a value is written after in the library, scene files and Python, before the value
    /// itself: `slepc:` for a SLEPc configuration, which those give inside the eigensolver's
    /// string (`basis.eigensolver = "slepc:ks-sinvert"`); empty for most options.
    pub value_prefix: &'static str,
    /// What the option is, with units: the command line's help line.
    pub help: &'static str,
}

impl OptionName {
    /// The option's name in `front` (the library's where that front end has none).
    pub fn name_in(&self, front: Front) -> &'static str {
        self.own_name(front).unwrap_or(self.library)
    }

    /// The option's name in `front`, None where that front end does not set it.
    pub fn own_name(&self, front: Front) -> Option<&'static str> {
        match front {
            Front::Library => Some(self.library),
            Front::Flags => self.flag,
            Front::Scene => self.scene,
            Front::Python => self.python,
            Front::C => self.c,
        }
    }

    /// The option set to `value`, as advice names it (`--solver lobpcg`).
    pub fn with(&'static self, value: impl fmt::Display) -> Setting {
        Setting {
            option: self,
            value: value.to_string(),
        }
    }
}

/// The name in the current front end ([`Front::current`]).
impl fmt::Display for OptionName {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name_in(Front::current()))
    }
}

/// An option with a value, as a message advises it: `--solver lobpcg` on the command line,
/// `basis.eigensolver = "lobpcg"` in a scene file, `eigensolver="lobpcg"` in Python,
/// `BasisOptions::solver = "lobpcg"` in the library. Values are text (quoted where the front
/// end quotes text), with the option's [`OptionName::value_prefix`].
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Setting {
    /// The option.
    pub option: &'static OptionName,
    /// Its value, as the command line writes it.
    pub value: String,
}

impl fmt::Display for Setting {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let (o, v) = (self.option, &self.value);
        let front = Front::current();
        match (front, o.own_name(front)) {
            (Front::Flags, Some(flag)) if v.is_empty() || v.contains(char::is_whitespace) => {
                write!(f, "{flag} \"{v}\"")
            }
            (Front::Flags, Some(flag)) => write!(f, "{flag} {v}"),
            (Front::Python, Some(keyword)) => write!(f, "{keyword}=\"{}{v}\"", o.value_prefix),
            (Front::C, Some(field)) => write!(f, "{field} = {v}"),
            (Front::Scene, Some(key)) => write!(f, "{key} = \"{}{v}\"", o.value_prefix),
            _ => write!(f, "{} = \"{}{v}\"", o.library, o.value_prefix),
        }
    }
}
