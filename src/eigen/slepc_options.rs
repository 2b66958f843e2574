//! The SLEPc configuration ([`SlepcOptions`], [`SlepcPreset`]) and its string form. It exists
//! in every build, so a configuration can be parsed, stored in basis metadata and compared
//! without the `slepc` feature; only solving with it (`slepc::SlepcSolver`) needs the feature.

use super::EigenError;

/// A named SLEPc configuration.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum SlepcPreset {
    /// Krylov-Schur + shift-and-invert + MUMPS Cholesky: a direct factor, fast to K ~ 100,000
    /// on one process, but its memory and its sequential analysis grow faster than K.
    KsSinvert,
    /// LOBPCG preconditioned by PETSc's GAMG (SOR smoothers), one block for every pair: the
    /// default, because its iterations do not grow with the ranks and only slowly with K
    /// (docs/slepc.md, "Scaling").
    #[default]
    LobpcgGamg,
    /// LOBPCG preconditioned by hypre BoomerAMG.
    LobpcgHypre,
}

impl SlepcPreset {
    /// Name as used on the command line ("ks-sinvert", "lobpcg-gamg", "lobpcg-hypre").
    pub fn name(self) -> &'static str {
        crate::names::variant_name(&self)
    }

    /// Parse a preset name.
    pub fn from_name(name: &str) -> Option<Self> {
        crate::names::from_name(name)
    }

    /// The PETSc options the preset sets through the options database (applied before
    /// [`SlepcOptions::petsc_options`], which override them); the rest of the preset is set
    /// by calls (`eigen::slepc`).
    pub fn petsc_options(self) -> &'static str {
        match self {
            SlepcPreset::KsSinvert | SlepcPreset::LobpcgHypre => "",
            // Richardson + SOR on every multigrid level instead of GAMG's Chebyshev + Jacobi:
            // fewer LOBPCG iterations at the same cost per application. No squared graph on
            // the first level (GAMG squares the ~250-entry-a-row graph to coarsen faster):
            // without it the peak per rank is 4-16 % lower, with as many or fewer
            // iterations (docs/slepc.md, "Scaling").
            SlepcPreset::LobpcgGamg => {
                "-st_mg_levels_ksp_type richardson -st_mg_levels_pc_type sor \
                 -st_pc_gamg_square_graph 0"
            }
        }
    }
}

/// How the SLEPc backend runs. Its string form is [`SlepcOptions::spec`], read back by
/// [`SlepcOptions::parse`].
#[derive(Debug, Clone, PartialEq, Default, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SlepcOptions {
    /// Starting configuration. Default [`SlepcPreset::LobpcgGamg`].
    pub preset: SlepcPreset,
    /// PETSc options applied on top of the preset, e.g. `"-eps_type jd -st_pc_type gamg"`
    /// (inserted with `PetscOptionsInsertString`, so values starting with `-` work; removed
    /// again after the solve). Default empty.
    pub petsc_options: String,
    /// Target / preconditioner shift sigma (units of the eigenvalues, Pa/m^2). `None`
    /// (default): -1e-4 tr(H)/tr(M).
    pub shift: Option<f64>,
}

impl SlepcOptions {
    /// Parse a configuration spec: a preset name (`ks-sinvert`, `lobpcg-gamg`,
    /// `lobpcg-hypre`), or raw PETSc options starting with `-` (applied on top of the default
    /// preset), or `preset:options` (e.g. `ks-sinvert:-st_pc_factor_mat_solver_type cholmod`).
    ///
    /// # Errors
    /// [`EigenError::InvalidRequest`] for an unknown preset name.
    pub fn parse(spec: &str) -> Result<Self, EigenError> {
        let spec = spec.trim();
        if spec.starts_with('-') {
            return Ok(SlepcOptions {
                petsc_options: spec.to_string(),
                ..SlepcOptions::default()
            });
        }
        let (name, options) = spec.split_once(':').unwrap_or((spec, ""));
        let preset = SlepcPreset::from_name(name.trim()).ok_or_else(|| {
            EigenError::InvalidRequest(format!(
                "unknown SLEPc configuration {name:?}: use ks-sinvert, lobpcg-gamg, \
                 lobpcg-hypre, or PETSc options starting with '-'"
            ))
        })?;
        Ok(SlepcOptions {
            preset,
            petsc_options: options.trim().to_string(),
            shift: None,
        })
    }

    /// These options with `extra` PETSc options applied after the ones already set (later
    /// options win in PETSc's database), e.g. a preset from one setting and options from
    /// another.
    pub fn with_petsc_options(mut self, extra: &str) -> Self {
        if !extra.trim().is_empty() {
            self.petsc_options = format!("{} {}", self.petsc_options, extra.trim())
                .trim()
                .to_string();
        }
        self
    }

    /// The configuration as the string [`SlepcOptions::parse`] reads: `preset` or
    /// `preset:options` (e.g. `ks-sinvert:-eps_type jd`). The shift has no string form.
    pub fn spec(&self) -> String {
        if self.petsc_options.is_empty() {
            self.preset.name().to_string()
        } else {
            format!("{}:{}", self.preset.name(), self.petsc_options)
        }
    }

    /// A short label for reports: the preset name, plus the options if any.
    pub fn label(&self) -> String {
        if self.petsc_options.is_empty() {
            self.preset.name().to_string()
        } else {
            format!("{} {}", self.preset.name(), self.petsc_options)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn specs_round_trip() {
        for spec in [
            "ks-sinvert",
            "lobpcg-gamg",
            "lobpcg-hypre",
            "ks-sinvert:-st_pc_factor_mat_solver_type cholmod",
            "lobpcg-gamg:-eps_lobpcg_blocksize 18",
        ] {
            let o = SlepcOptions::parse(spec).unwrap();
            assert_eq!(o.spec(), spec);
            assert_eq!(SlepcOptions::parse(&o.spec()).unwrap(), o);
        }
        // Raw options sit on the default preset; their spec names it.
        let o = SlepcOptions::parse(" -eps_type jd ").unwrap();
        assert_eq!(o.spec(), "lobpcg-gamg:-eps_type jd");
        assert_eq!(SlepcOptions::parse(&o.spec()).unwrap(), o);
        // Extra options go after the preset's own.
        let o = SlepcOptions::parse("lobpcg-gamg:-a 1")
            .unwrap()
            .with_petsc_options(" -b 2 ");
        assert_eq!(o.petsc_options, "-a 1 -b 2");
        assert_eq!(
            SlepcOptions::parse("lobpcg-gamg")
                .unwrap()
                .with_petsc_options(""),
            SlepcOptions::default()
        );
        let err = SlepcOptions::parse("arnoldi").unwrap_err().to_string();
        assert!(
            err.contains("unknown SLEPc configuration \"arnoldi\""),
            "{err}"
        );
    }
}
