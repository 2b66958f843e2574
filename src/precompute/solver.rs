//! Which eigensolver a precomputation runs.

use crate::eigen::dense::DenseSolver;
use crate::eigen::lobpcg::{Lobpcg, LobpcgOptions};
use crate::eigen::Eigensolver;
use serde::Serialize;

/// Which eigensolver runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum SolverChoice {
    /// Native sparse LOBPCG (default): any K.
    #[default]
    Lobpcg,
    /// Dense reference: exact to round-off, K up to a few thousand.
    Dense,
}

impl SolverChoice {
    /// Lower-case name.
    pub fn name(self) -> &'static str {
        match self {
            SolverChoice::Lobpcg => "lobpcg",
            SolverChoice::Dense => "dense",
        }
    }
}

impl SolverChoice {
    /// The eigensolver this choice names, with its default settings.
    pub fn build(self) -> crate::Result<Box<dyn Eigensolver>> {
        Ok(match self {
            SolverChoice::Lobpcg => Box::new(Lobpcg::new(LobpcgOptions::default())),
            SolverChoice::Dense => Box::new(DenseSolver),
        })
    }
}
