//! The native LOBPCG's settings ([`LobpcgOptions`]) and its preconditioner choice
//! ([`PreconditionerKind`]), with their documented defaults.

/// Which preconditioner LOBPCG applies to the residuals.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum PreconditionerKind {
    /// Sparse Cholesky of H + sigma M when its factor is small, otherwise
    /// [`PreconditionerKind::IncompleteCholesky`]. "Small": at most
    /// [`LobpcgOptions::max_factor_entries`] entries and at most
    /// [`LobpcgOptions::max_fill_ratio`] times the entries of the lower triangle of
    /// H + sigma M, both known from the symbolic analysis before any numeric work. The
    /// analysis is sequential, so IC(0) is factored on another thread meanwhile and used when
    /// the analysis rejects the exact factor (the same factor as `IncompleteCholesky`).
    Auto,
    /// Sparse Cholesky of H + sigma M (AMD ordering), whatever its size.
    Cholesky,
    /// Zero-fill incomplete Cholesky IC(0) of H + sigma M: as many entries as the lower
    /// triangle of H + sigma M, sequential triangular solves. On breakdown the diagonal is
    /// raised (alpha = 1e-3 ... 1 times diag), then Jacobi is used.
    IncompleteCholesky,
    /// diag(H + sigma M)^-1.
    Jacobi,
    /// No preconditioner.
    Identity,
}

/// `Option<usize>` serialized as a number with 0 for `None` (TOML has no null).
mod zero_is_never {
    use serde::{Deserialize, Deserializer, Serializer};

    pub fn serialize<S: Serializer>(v: &Option<usize>, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_u64(v.unwrap_or(0) as u64)
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Option<usize>, D::Error> {
        let n = usize::deserialize(d)?;
        Ok((n > 0).then_some(n))
    }
}

/// LOBPCG settings. Every field has a documented default ([`LobpcgOptions::default`]); in
/// serialized form (scene files, basis metadata) a missing field takes its default.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct LobpcgOptions {
    /// Guard vectors: extra block columns beyond the nev - 1 wanted non-constant pairs.
    /// `None`: `max(8, ceil((nev - 1) / 4))`. Convergence of pair j goes like
    /// lambda_j / lambda_{block + 1}, so guards speed up the last wanted pairs, and at least
    /// 5 are needed for a 6-fold eigenvalue (cubes) at the cut to fit entirely in the block.
    pub guard: Option<usize>,
    /// Preconditioner. Default [`PreconditionerKind::Auto`].
    pub preconditioner: PreconditionerKind,
    /// Shift rule: sigma = `shift_factor` * tr(H) / tr(M). tr(H)/tr(M) is the mean
    /// eigenvalue, a cheap scale of the spectrum. Default 1e-4 (well below the first non-zero
    /// eigenvalue for K up to ~1e5, where lambda_1 / mean ~ 1e-3; a shift below lambda_1
    /// makes T close to the ideal shift-invert operator on the wanted end while keeping
    /// H + sigma M safely positive definite: condition number ~ 1e4 * (lambda_max / mean)).
    pub shift_factor: f64,
    /// Budget for [`PreconditionerKind::Auto`]: most entries allowed in the Cholesky factor.
    /// Default 2^27 = 134M entries (1.07 GB).
    pub max_factor_entries: usize,
    /// Second budget for [`PreconditionerKind::Auto`]: most fill allowed, as factor entries over
    /// entries of the lower triangle of H + sigma M. Default 8. Measured (nev = 33): the exact
    /// factor and IC(0) need about the same iterations (14-16 vs 16-21), an exact solve costs
    /// ~fill/2 times an IC(0) solve, so above ~8x IC(0) wins: RKPM beam K = 4,000 (fill 5.5x)
    /// Cholesky 1.6 s vs IC(0) 1.9 s; K = 10,000 (8.9x) 5.6 s vs 5.7 s; K = 50,000 (24.8x)
    /// 56 s vs 34 s; 3D grid K = 10,648 (31x) 3.2 s vs 2.1 s.
    pub max_fill_ratio: f64,
    /// For [`PreconditionerKind::Auto`] runs that chose IC(0): after this many iterations
    /// without convergence, switch to the exact Cholesky if its factor holds at most
    /// `max_factor_entries` entries (ignoring `max_fill_ratio`). Default `Some(60)`: IC(0)
    /// converges in 16-26 iterations on well-conditioned problems but degrades when M is
    /// ill-conditioned (RKPM beam, K = 2,000, support factor 4, cond(M) = 7.8e6: IC(0) 255
    /// iterations, 34 s; exact Cholesky 15 iterations, 1.8 s). `None` never switches; in
    /// serialized form (scene files, metadata) `None` is written and read as 0, since TOML has
    /// no null and a missing key means the default.
    #[serde(with = "zero_is_never")]
    pub escalate_after: Option<usize>,
    /// Recompute H X, M X, H P, M P explicitly every this many iterations (the implicit
    /// updates accumulate round-off). Default 10.
    pub recompute_every: usize,
    /// Restart (drop P) when min/max eigenvalue of the basis M-Gram matrix falls below this.
    /// Default 1e-10 (the basis is M-orthonormalized, so this only triggers on real loss of
    /// orthogonality between P and the rest).
    pub restart_tol: f64,
    /// Drop a new direction when the projection against [X | P] leaves less than this fraction
    /// of its M-norm (what remains would be mostly round-off). Default 1e-10.
    pub ortho_drop: f64,
    /// SVQB drop tolerance: eigenvalues of the scaled Gram matrix below this times the largest
    /// are dropped (directions that cannot be resolved from the Gram matrix). Default 1e-14.
    pub svqb_drop: f64,
    /// Seed of the start block. Default 0x5eed.
    pub seed: u64,
}

/// Most guard vectors [`LobpcgOptions::validate`] accepts: 10,000 (a typo guard; the default
/// is 8 to 16).
pub const MAX_GUARD: usize = 10_000;

impl LobpcgOptions {
    /// Check the ranges: `guard` at most [`MAX_GUARD`]; `shift_factor` positive and finite;
    /// `max_fill_ratio` and `restart_tol` finite and >= 0 (0: never the exact factor by fill,
    /// never restart; `restart_tol` >= 1 restarts at every step); `ortho_drop` and `svqb_drop`
    /// in [0, 1); `recompute_every` at least 1. `max_factor_entries` = 0 (never the exact
    /// factor) and `escalate_after` = 0 (never switch) are valid.
    ///
    /// # Errors
    /// [`crate::Error::InvalidParameter`] naming the first field out of range.
    pub fn validate(&self) -> Result<(), crate::eigen::EigenError> {
        let param = |name: &str, value: &dyn std::fmt::Display, reason: String| {
            crate::eigen::EigenError::InvalidRequest(format!(
                "invalid lobpcg {name} = {value}: {reason}"
            ))
        };
        if let Some(g) = self.guard.filter(|&g| g > MAX_GUARD) {
            return Err(param(
                "guard",
                &g,
                format!("at most {MAX_GUARD} guard vectors (default max(8, (nev - 1) / 4))"),
            ));
        }
        if !(self.shift_factor > 0.0 && self.shift_factor.is_finite()) {
            return Err(param(
                "shift_factor",
                &self.shift_factor,
                "must be positive and finite (default 1e-4): sigma = 0 leaves H + sigma M \
                 singular"
                    .into(),
            ));
        }
        for (name, v, default) in [
            ("max_fill_ratio", self.max_fill_ratio, "8"),
            ("restart_tol", self.restart_tol, "1e-10"),
        ] {
            if !(v >= 0.0 && v.is_finite()) {
                return Err(param(
                    name,
                    &v,
                    format!("must be finite and >= 0 (default {default})"),
                ));
            }
        }
        for (name, v, default) in [
            ("ortho_drop", self.ortho_drop, "1e-10"),
            ("svqb_drop", self.svqb_drop, "1e-14"),
        ] {
            if !(0.0..1.0).contains(&v) {
                return Err(param(
                    name,
                    &v,
                    format!("must lie in [0, 1) (default {default})"),
                ));
            }
        }
        if self.recompute_every == 0 {
            return Err(param(
                "recompute_every",
                &0,
                "must be at least 1 (default 10)".into(),
            ));
        }
        Ok(())
    }
}

impl Default for LobpcgOptions {
    fn default() -> Self {
        Self {
            guard: None,
            preconditioner: PreconditionerKind::Auto,
            shift_factor: 1e-4,
            max_factor_entries: 1 << 27,
            max_fill_ratio: 8.0,
            escalate_after: Some(60),
            recompute_every: 10,
            restart_tol: 1e-10,
            ortho_drop: 1e-10,
            svqb_drop: 1e-14,
            seed: 0x5eed,
        }
    }
}

impl LobpcgOptions {
    /// The settings that differ from the defaults as `KEY=VALUE` pairs joined by commas, by
    /// their serialized (scene-file) names in alphabetical order, e.g.
    /// `guard=16,shift_factor=0.001`; empty at the defaults. [`LobpcgOptions::parse`] reads it
    /// back to the same settings.
    pub fn spec(&self) -> String {
        let table = |o: &LobpcgOptions| toml::Table::try_from(o).unwrap_or_default();
        let (mine, default) = (table(self), table(&LobpcgOptions::default()));
        mine.iter()
            .filter(|(k, v)| default.get(*k) != Some(*v))
            .map(|(k, v)| match v {
                toml::Value::String(text) => format!("{k}={text}"),
                other => format!("{k}={other}"),
            })
            .collect::<Vec<_>>()
            .join(",")
    }

    /// Settings from `KEY=VALUE` pairs separated by commas (the form [`LobpcgOptions::spec`]
    /// writes), the keys the serialized names of the fields; the others keep their defaults.
    /// Validated.
    ///
    /// # Errors
    /// [`crate::eigen::EigenError::InvalidRequest`] for a pair without `=`, an unknown key, a
    /// value of the wrong type, or settings out of range ([`LobpcgOptions::validate`]).
    pub fn parse(spec: &str) -> Result<Self, crate::eigen::EigenError> {
        let invalid = |why: String| {
            crate::eigen::EigenError::InvalidRequest(format!(
                "invalid lobpcg settings {spec:?}: {why}; give KEY=VALUE pairs separated by \
                 commas, e.g. guard=16,shift_factor=1e-3, the keys LobpcgOptions' field names"
            ))
        };
        let mut doc = String::new();
        for pair in spec.split(',').map(str::trim).filter(|p| !p.is_empty()) {
            let Some((key, value)) = pair.split_once('=') else {
                return Err(invalid(format!("{pair:?} has no '='")));
            };
            let (key, value) = (key.trim(), value.trim());
            let word = |t: &str, extra: &str| {
                !t.is_empty()
                    && t.chars()
                        .all(|c| c.is_ascii_alphanumeric() || c == '_' || extra.contains(c))
            };
            if !word(key, "") || !word(value, ".+-") {
                return Err(invalid(format!(
                    "{pair:?}: a key is a name and a value a number or a name"
                )));
            }
            // Numbers stay numbers (written as TOML reads them: "5.", ".5" or "NaN" are numbers
            // to Rust, and the range check names a non-finite one); a name (a preconditioner)
            // becomes a TOML string.
            let literal = if let Ok(i) = value.parse::<i64>() {
                i.to_string()
            } else if let Ok(x) = value.parse::<f64>() {
                match x {
                    x if x.is_nan() => "nan".to_string(),
                    x if x.is_infinite() => if x > 0.0 { "inf" } else { "-inf" }.to_string(),
                    x => format!("{x:?}"),
                }
            } else {
                format!("\"{value}\"")
            };
            doc.push_str(&format!("{key} = {literal}\n"));
        }
        let options: LobpcgOptions =
            toml::from_str(&doc).map_err(|e| invalid(e.message().to_string()))?;
        options.validate()?;
        Ok(options)
    }

    /// Guard vectors for `nwant` wanted non-constant pairs.
    pub fn guard_for(&self, nwant: usize) -> usize {
        self.guard.unwrap_or_else(|| 8.max(nwant.div_ceil(4)))
    }
}
