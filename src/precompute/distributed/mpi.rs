//! [`Collective`] over MPI's `PETSC_COMM_WORLD` (feature `slepc`).

use super::collective::Collective;
use crate::eigen::slepc;
use crate::Result;

/// The ranks of `mpirun` (all of `PETSC_COMM_WORLD`), as a [`Collective`].
#[derive(Debug, Clone, Copy)]
pub struct MpiWorld {
    rank: usize,
    size: usize,
}

impl MpiWorld {
    /// This process's rank in the world (starts PETSc/MPI if needed).
    ///
    /// # Errors
    /// [`crate::eigen::EigenError::Backend`] when PETSc/MPI cannot start.
    pub fn new() -> Result<Self> {
        let (rank, size) = slepc::world_rank()?;
        Ok(Self { rank, size })
    }
}

impl Collective for MpiWorld {
    fn rank(&self) -> usize {
        self.rank
    }

    fn size(&self) -> usize {
        self.size
    }

    fn sum(&self, values: &mut [f64]) -> Result<()> {
        Ok(slepc::allreduce_sum(values)?)
    }

    fn max(&self, values: &mut [f64]) -> Result<()> {
        Ok(slepc::allreduce_max(values)?)
    }

    fn broadcast(&self, values: &mut [f64], root: usize) -> Result<()> {
        Ok(slepc::broadcast(values, root)?)
    }

    fn all_gather(&self, mine: &[f64]) -> Result<Vec<f64>> {
        Ok(slepc::all_gather(mine)?)
    }
}
