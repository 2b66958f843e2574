//! Which eigensolver a precomputation runs, with its settings: [`SolverConfig`].

use crate::eigen::dense::DenseSolver;
use crate::eigen::lobpcg::{Lobpcg, LobpcgOptions};
use crate::eigen::{Eigensolver, SlepcOptions};
use crate::{Error, Result};
use serde::{Deserialize, Serialize};

/// Which eigensolver runs, and how: the one description of a solver choice that the
/// command line, scene files, the C API and basis metadata share. [`SolverConfig::build`] makes
/// the solver.
///
/// String form ([`std::str::FromStr`] and [`std::fmt::Display`], also its serialized form):
///
/// | string | solver |
/// |---|---|
/// | `lobpcg` | native sparse LOBPCG at [`LobpcgOptions::default`] (the default) |
/// | `dense` | dense reference solver |
/// | `slepc` | SLEPc, preset `lobpcg-gamg` |
/// | `slepc:CONFIG` | SLEPc; CONFIG as [`SlepcOptions::parse`] reads it: `ks-sinvert`, `lobpcg-gamg`, `lobpcg-hypre`, PETSc options starting with `-`, or `preset:options` |
///
/// Display gives `slepc:` followed by [`SlepcOptions::spec`] (`slepc:ks-sinvert`,
/// `slepc:lobpcg-gamg:-eps_lobpcg_blocksize 18`), which parses back to the same
/// configuration. LOBPCG settings other than the defaults and a SLEPc shift have no string
/// form: they serialize as a table (`{"lobpcg": {...}}`, `{"slepc": {...}}`), which
/// deserializes too. So `"lobpcg"` and `"dense"` serialize exactly as before SLEPc joined
/// this type, and the scene cache keys of existing scenes are unchanged.
///
/// ```
/// use freeform::precompute::SolverConfig;
/// let c: SolverConfig = "slepc:lobpcg-gamg".parse()?;
/// assert_eq!(c.name(), "slepc");
/// assert_eq!(c.to_string(), "slepc:lobpcg-gamg");
/// assert_eq!("lobpcg".parse::<SolverConfig>()?, SolverConfig::default());
/// assert!("arnoldi".parse::<SolverConfig>().is_err());
/// # Ok::<(), freeform::Error>(())
/// ```
#[derive(Debug, Clone, PartialEq)]
pub enum SolverConfig {
    /// Native sparse LOBPCG (default): any K.
    Lobpcg(LobpcgOptions),
    /// Dense reference: exact to round-off, K up to a few thousand.
    Dense,
    /// SLEPc through PETSc (feature `slepc`; without it [`SolverConfig::build`] fails with
    /// [`crate::eigen::EigenError::SlepcUnavailable`]).
    Slepc(SlepcOptions),
}

impl Default for SolverConfig {
    fn default() -> Self {
        SolverConfig::Lobpcg(LobpcgOptions::default())
    }
}

/// What [`SolverConfig::from_str`](std::str::FromStr) accepts, for its error message.
const SOLVER_STRINGS: &str = "use lobpcg, dense, slepc, slepc:CONFIG with CONFIG ks-sinvert, \
     lobpcg-gamg, lobpcg-hypre, PETSc options starting with '-', or preset:options, or \
     lobpcg:KEY=VALUE,... for LOBPCG settings";

impl SolverConfig {
    /// Native LOBPCG at its default settings (the default configuration).
    pub fn lobpcg() -> Self {
        Self::default()
    }

    /// A SLEPc configuration from a spec as [`SlepcOptions::parse`] reads it, with
    /// `extra_petsc_options` applied after the spec's own options (empty for none).
    ///
    /// # Errors
    /// [`crate::eigen::EigenError::InvalidRequest`] (inside [`Error::Eigen`]) for an unknown
    /// preset name.
    pub fn slepc(spec: &str, extra_petsc_options: &str) -> Result<Self> {
        Ok(SolverConfig::Slepc(
            SlepcOptions::parse(spec)?.with_petsc_options(extra_petsc_options),
        ))
    }

    /// Short solver name, the [`Eigensolver::name`] of the solver it builds: "lobpcg",
    /// "dense" or "slepc".
    pub fn name(&self) -> &'static str {
        match self {
            SolverConfig::Lobpcg(_) => "lobpcg",
            SolverConfig::Dense => "dense",
            SolverConfig::Slepc(_) => "slepc",
        }
    }

    /// The eigensolver this configuration describes.
    ///
    /// # Errors
    /// [`crate::eigen::EigenError::SlepcUnavailable`] (inside [`Error::Eigen`]) for a SLEPc
    /// configuration in a build without the `slepc` feature.
    pub fn build(&self) -> Result<Box<dyn Eigensolver>> {
        Ok(match self {
            SolverConfig::Lobpcg(options) => Box::new(Lobpcg::new(options.clone())),
            SolverConfig::Dense => Box::new(DenseSolver),
            #[cfg(feature = "slepc")]
            SolverConfig::Slepc(options) => {
                Box::new(crate::eigen::slepc::SlepcSolver::new(options.clone()))
            }
            #[cfg(not(feature = "slepc"))]
            SolverConfig::Slepc(_) => return Err(crate::eigen::EigenError::SlepcUnavailable.into()),
        })
    }

    /// Whether serialization writes the string form ([`std::fmt::Display`]): default LOBPCG
    /// settings (other settings keep their table, the scene files' form, though the string
    /// describes them too); SLEPc options that parse back from their spec (no shift, options
    /// without surrounding blanks).
    fn has_string_form(&self) -> bool {
        match self {
            SolverConfig::Lobpcg(options) => *options == LobpcgOptions::default(),
            SolverConfig::Dense => true,
            SolverConfig::Slepc(options) => {
                SlepcOptions::parse(&options.spec()).ok().as_ref() == Some(options)
            }
        }
    }
}

impl std::fmt::Display for SolverConfig {
    /// `lobpcg`, `lobpcg:` + [`LobpcgOptions::spec`] for settings other than the defaults,
    /// `dense` or `slepc:` + [`SlepcOptions::spec`] (a SLEPc shift is not part of it).
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            SolverConfig::Lobpcg(options) if *options != LobpcgOptions::default() => {
                write!(f, "lobpcg:{}", options.spec())
            }
            SolverConfig::Slepc(options) => write!(f, "slepc:{}", options.spec()),
            other => f.write_str(other.name()),
        }
    }
}

impl std::str::FromStr for SolverConfig {
    type Err = Error;

    /// Parse the string form (table in [`SolverConfig`]).
    ///
    /// # Errors
    /// [`Error::InvalidParameter`] (name `solver`) for an unknown solver name;
    /// [`crate::eigen::EigenError::InvalidRequest`] (inside [`Error::Eigen`]) for an unknown
    /// SLEPc preset.
    fn from_str(s: &str) -> Result<Self> {
        let s = s.trim();
        match s {
            "lobpcg" => return Ok(SolverConfig::lobpcg()),
            "dense" => return Ok(SolverConfig::Dense),
            "slepc" => return Ok(SolverConfig::Slepc(SlepcOptions::default())),
            _ => {}
        }
        match s.split_once(':') {
            Some(("slepc", spec)) => SolverConfig::slepc(spec, ""),
            Some(("lobpcg", spec)) => Ok(SolverConfig::Lobpcg(
                LobpcgOptions::parse(spec).map_err(Error::from)?,
            )),
            _ => Err(Error::param("solver", format!("{s:?}"), SOLVER_STRINGS)),
        }
    }
}

/// The serialized form: the string when it says everything, a one-key table otherwise.
impl Serialize for SolverConfig {
    fn serialize<S: serde::Serializer>(
        &self,
        serializer: S,
    ) -> std::result::Result<S::Ok, S::Error> {
        match self {
            SolverConfig::Lobpcg(options) if !self.has_string_form() => {
                one_key_table(serializer, "lobpcg", options)
            }
            SolverConfig::Slepc(options) if !self.has_string_form() => {
                one_key_table(serializer, "slepc", options)
            }
            _ => serializer.serialize_str(&self.to_string()),
        }
    }
}

/// `{key: value}`.
fn one_key_table<S: serde::Serializer, T: Serialize>(
    serializer: S,
    key: &str,
    value: &T,
) -> std::result::Result<S::Ok, S::Error> {
    use serde::ser::SerializeMap;
    let mut map = serializer.serialize_map(Some(1))?;
    map.serialize_entry(key, value)?;
    map.end()
}

impl<'de> Deserialize<'de> for SolverConfig {
    fn deserialize<D: serde::Deserializer<'de>>(
        deserializer: D,
    ) -> std::result::Result<Self, D::Error> {
        deserializer.deserialize_any(ConfigVisitor)
    }
}

/// Reads the string form or a one-key table `lobpcg = {...}` / `slepc = {...}`.
struct ConfigVisitor;

impl<'de> serde::de::Visitor<'de> for ConfigVisitor {
    type Value = SolverConfig;

    fn expecting(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(
            "a solver string (lobpcg, dense, slepc, slepc:CONFIG) or a table with one key, \
             lobpcg or slepc",
        )
    }

    fn visit_str<E: serde::de::Error>(self, s: &str) -> std::result::Result<SolverConfig, E> {
        s.parse().map_err(E::custom)
    }

    fn visit_map<A: serde::de::MapAccess<'de>>(
        self,
        mut map: A,
    ) -> std::result::Result<SolverConfig, A::Error> {
        use serde::de::Error as _;
        let Some(key) = map.next_key::<String>()? else {
            return Err(A::Error::custom(
                "empty solver table: give one key, lobpcg or slepc",
            ));
        };
        let config = match key.as_str() {
            "lobpcg" => SolverConfig::Lobpcg(map.next_value()?),
            "slepc" => SolverConfig::Slepc(map.next_value()?),
            other => {
                return Err(A::Error::custom(format!(
                    "unknown solver table key {other:?}: use lobpcg or slepc (settings), or a \
                     solver string"
                )))
            }
        };
        if let Some(extra) = map.next_key::<String>()? {
            return Err(A::Error::custom(format!(
                "solver table with a second key {extra:?}: give exactly one, `lobpcg` or `slepc`"
            )));
        }
        Ok(config)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::eigen::lobpcg::PreconditionerKind;
    use crate::eigen::{EigenError, SlepcPreset};

    #[test]
    fn strings_round_trip() {
        for s in [
            "lobpcg",
            "dense",
            "slepc:ks-sinvert",
            "slepc:lobpcg-gamg",
            "slepc:lobpcg-hypre",
            "slepc:ks-sinvert:-st_pc_factor_mat_solver_type cholmod",
            "slepc:lobpcg-gamg:-eps_lobpcg_blocksize 18 -eps_max_it 50",
        ] {
            let c: SolverConfig = s.parse().unwrap();
            assert_eq!(c.to_string(), s);
            assert_eq!(c.to_string().parse::<SolverConfig>().unwrap(), c);
            // Serialized: the same string, and back.
            let json = serde_json::to_value(&c).unwrap();
            assert_eq!(json, serde_json::Value::String(s.to_string()));
            assert_eq!(serde_json::from_value::<SolverConfig>(json).unwrap(), c);
        }
        // Short forms name their canonical one.
        for (short, canonical) in [
            ("slepc", "slepc:lobpcg-gamg"),
            (" slepc:-eps_type jd ", "slepc:lobpcg-gamg:-eps_type jd"),
            ("slepc:lobpcg-gamg:", "slepc:lobpcg-gamg"),
        ] {
            let c: SolverConfig = short.parse().unwrap();
            assert_eq!(c.to_string(), canonical);
            assert_eq!(canonical.parse::<SolverConfig>().unwrap(), c);
        }
        assert_eq!(
            "slepc:lobpcg-gamg:-x 1".parse::<SolverConfig>().unwrap(),
            SolverConfig::slepc("lobpcg-gamg", "-x 1").unwrap()
        );
        assert_eq!(
            SolverConfig::slepc("-a 1", "-b 2").unwrap(),
            SolverConfig::Slepc(SlepcOptions {
                preset: SlepcPreset::LobpcgGamg,
                petsc_options: "-a 1 -b 2".into(),
                shift: None,
            })
        );
    }

    #[test]
    fn lobpcg_settings_have_a_string_form() {
        let c: SolverConfig = "lobpcg:guard=16, shift_factor=1e-3,preconditioner=jacobi"
            .parse()
            .unwrap();
        let want = LobpcgOptions {
            guard: Some(16),
            shift_factor: 1e-3,
            preconditioner: PreconditionerKind::Jacobi,
            ..LobpcgOptions::default()
        };
        assert_eq!(c, SolverConfig::Lobpcg(want.clone()));
        // Written back in alphabetical order, only what differs from the defaults, and read
        // back to the same settings; serialized as the scene files' table, as before.
        let text = c.to_string();
        assert_eq!(
            text,
            "lobpcg:guard=16,preconditioner=jacobi,shift_factor=0.001"
        );
        assert_eq!(text.parse::<SolverConfig>().unwrap(), c);
        assert!(serde_json::to_value(&c).unwrap().is_object());
        // Every field survives the round trip, 0 meaning "never" included.
        let all = LobpcgOptions {
            guard: Some(3),
            preconditioner: PreconditionerKind::Identity,
            shift_factor: 2.5e-7,
            max_factor_entries: 12,
            max_fill_ratio: 0.0,
            escalate_after: None,
            recompute_every: 4,
            restart_tol: 1.0,
            ortho_drop: 0.5,
            svqb_drop: 0.0,
            seed: 99,
        };
        assert_eq!(LobpcgOptions::parse(&all.spec()).unwrap(), all);
        assert_eq!(LobpcgOptions::parse("").unwrap(), LobpcgOptions::default());
        assert_eq!(
            "lobpcg:".parse::<SolverConfig>().unwrap().to_string(),
            "lobpcg"
        );
        // Bad input: each message names what is wrong.
        for (bad, says) in [
            ("guard", "has no '='"),
            ("gaurd=3", "unknown field"),
            ("guard=x", "invalid type"),
            ("preconditioner=ilu", "unknown variant"),
            ("shift_factor=0", "must be positive and finite"),
            ("shift_factor=NaN", "must be positive and finite"),
            ("guard=3\nseed=1", "a key is a name"),
            ("seed=\"1\"", "a key is a name"),
            ("jacobi", "has no '='"),
        ] {
            let e = LobpcgOptions::parse(bad).unwrap_err().to_string();
            assert!(e.contains(says), "{bad:?}: {e}");
        }
    }

    /// Every LOBPCG setting survives a scene file (TOML has no null: "never escalate" is 0).
    #[test]
    fn lobpcg_settings_round_trip_through_toml() {
        #[derive(serde::Serialize, serde::Deserialize)]
        struct Basis {
            eigensolver: SolverConfig,
        }
        for escalate_after in [None, Some(1), Some(60), Some(500)] {
            let config = SolverConfig::Lobpcg(crate::eigen::lobpcg::LobpcgOptions {
                escalate_after,
                ..Default::default()
            });
            let text = toml::to_string(&Basis {
                eigensolver: config.clone(),
            })
            .unwrap();
            let back: Basis = toml::from_str(&text).unwrap();
            assert_eq!(back.eigensolver, config, "{text}");
        }
    }

    /// The cache keys of existing scenes hash `"solver": "lobpcg"` / `"dense"`.
    #[test]
    fn lobpcg_and_dense_serialize_as_before() {
        assert_eq!(
            serde_json::to_string(&SolverConfig::default()).unwrap(),
            "\"lobpcg\""
        );
        assert_eq!(
            serde_json::to_string(&SolverConfig::Dense).unwrap(),
            "\"dense\""
        );
    }

    #[test]
    fn settings_without_a_string_form_serialize_as_a_table() {
        let lob = SolverConfig::Lobpcg(LobpcgOptions {
            preconditioner: PreconditionerKind::Jacobi,
            ..LobpcgOptions::default()
        });
        assert_eq!(lob.to_string(), "lobpcg:preconditioner=jacobi");
        let json = serde_json::to_value(&lob).unwrap();
        assert_eq!(json["lobpcg"]["preconditioner"], "jacobi");
        assert_eq!(serde_json::from_value::<SolverConfig>(json).unwrap(), lob);
        let shifted = SolverConfig::Slepc(SlepcOptions {
            shift: Some(-2.5),
            ..SlepcOptions::parse("lobpcg-hypre").unwrap()
        });
        let json = serde_json::to_value(&shifted).unwrap();
        assert_eq!(json["slepc"]["shift"], -2.5);
        assert_eq!(json["slepc"]["preset"], "lobpcg-hypre");
        assert_eq!(
            serde_json::from_value::<SolverConfig>(json).unwrap(),
            shifted
        );
        // Options set by hand with stray blanks: the table keeps them exactly.
        let blanks = SolverConfig::Slepc(SlepcOptions {
            petsc_options: " -eps_ncv 20 ".into(),
            ..SlepcOptions::default()
        });
        let json = serde_json::to_value(&blanks).unwrap();
        assert_eq!(json["slepc"]["petsc_options"], " -eps_ncv 20 ");
        assert_eq!(
            serde_json::from_value::<SolverConfig>(json).unwrap(),
            blanks
        );
        // A partial table takes the defaults for the rest, as in a scene file.
        let partial: SolverConfig = serde_json::from_str(r#"{"lobpcg": {"seed": 7}}"#).unwrap();
        assert_eq!(
            partial,
            SolverConfig::Lobpcg(LobpcgOptions {
                seed: 7,
                ..LobpcgOptions::default()
            })
        );
    }

    #[test]
    fn bad_strings_are_clear_errors() {
        for bad in ["", "arnoldi", "LOBPCG", "dense:x", "slepcx"] {
            let e = bad.parse::<SolverConfig>().unwrap_err().to_string();
            assert!(
                e.starts_with("invalid solver = ") && e.contains("use lobpcg, dense, slepc"),
                "{bad:?}: {e}"
            );
        }
        let e = "slepc:arnoldi"
            .parse::<SolverConfig>()
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("unknown SLEPc configuration \"arnoldi\"") && e.contains("ks-sinvert"),
            "{e}"
        );
        // Serialized forms report the same through serde.
        let e = serde_json::from_str::<SolverConfig>("\"arnoldi\"")
            .unwrap_err()
            .to_string();
        assert!(e.contains("use lobpcg, dense, slepc"), "{e}");
        assert!(serde_json::from_str::<SolverConfig>(r#"{"dense": {}}"#).is_err());
        assert!(serde_json::from_str::<SolverConfig>(r#"{"lobpcg": {"bogus": 1}}"#).is_err());
    }

    #[test]
    fn build_names_the_solver() {
        assert_eq!(SolverConfig::default().build().unwrap().name(), "lobpcg");
        assert_eq!(SolverConfig::Dense.build().unwrap().name(), "dense");
        let slepc = SolverConfig::slepc("lobpcg-gamg", "").unwrap().build();
        if cfg!(feature = "slepc") {
            assert_eq!(slepc.unwrap().name(), "slepc");
        } else {
            let e = slepc.err().expect("no SLEPc in this build");
            assert!(matches!(e, Error::Eigen(EigenError::SlepcUnavailable)));
            assert_eq!(
                e.to_string(),
                "this freeform was built without SLEPc: rebuild with `cargo build --release \
                 --features slepc` (needs libslepc-real-dev, see docs/slepc.md)"
            );
        }
    }
}
