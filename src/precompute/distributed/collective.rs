//! The collective operations the distributed precompute needs, behind one trait: MPI's under
//! `mpirun` (feature `slepc`, [`super::MpiWorld`]), or ranks on threads of one process
//! ([`run_ranks`]), which let tests check every distributed stage against the one-process
//! pipeline without MPI.
//!
//! Every operation is collective: all ranks call it, in the same order, with the same lengths.
//! A stage that can fail on some ranks only ends with [`agree`], so that all ranks leave it
//! together (one rank returning alone would leave the others waiting in the next collective).

use crate::eigen::EigenError;
use crate::{Error, Result};
use std::sync::{Barrier, Mutex};

/// Collective operations over the ranks of one run, on `f64` buffers (integers below 2^53
/// travel exactly).
pub trait Collective: Sync {
    /// This rank, 0-based.
    fn rank(&self) -> usize;
    /// Number of ranks P.
    fn size(&self) -> usize;
    /// Element-wise sum over the ranks, the result on every rank.
    fn sum(&self, values: &mut [f64]) -> Result<()>;
    /// Element-wise maximum over the ranks, the result on every rank.
    fn max(&self, values: &mut [f64]) -> Result<()>;
    /// Rank `root`'s `values` on every rank.
    fn broadcast(&self, values: &mut [f64], root: usize) -> Result<()>;
    /// Every rank's `mine` (all of the same length L), concatenated in rank order: P x L.
    fn all_gather(&self, mine: &[f64]) -> Result<Vec<f64>>;
}

/// Element-wise minimum over the ranks.
pub fn min(comm: &dyn Collective, values: &mut [f64]) -> Result<()> {
    values.iter_mut().for_each(|v| *v = -*v);
    comm.max(values)?;
    values.iter_mut().for_each(|v| *v = -*v);
    Ok(())
}

/// The largest `value` over the ranks and, among the ranks holding it, the smallest `index`,
/// with that rank's `payload` (N numbers, e.g. a position and a scale): the same answer on
/// every rank.
/// A rank with nothing to offer passes `value = -inf`.
pub fn arg_max<const N: usize>(
    comm: &dyn Collective,
    value: f64,
    index: usize,
    payload: [f64; N],
) -> Result<(f64, usize, [f64; N])> {
    // One all-gather of N + 2 numbers per rank while P is small (one latency), else a maximum, a
    // tie-break and a broadcast (3 latencies, O(1) data per rank).
    const GATHER_UP_TO: usize = 16;
    if comm.size() <= GATHER_UP_TO {
        let mut mine = vec![value, index as f64];
        mine.extend_from_slice(&payload);
        let all = comm.all_gather(&mine)?;
        let mut best = (f64::NEG_INFINITY, usize::MAX, [0.0; N]);
        for r in all.chunks_exact(N + 2) {
            let (v, i) = (r[0], r[1] as usize);
            if v > best.0 || (v == best.0 && i < best.1) {
                let mut data = [0.0; N];
                data.copy_from_slice(&r[2..]);
                best = (v, i, data);
            }
        }
        return Ok(best);
    }
    let mut top = [value];
    comm.max(&mut top)?;
    // Indices are below 2^31 and ranks below 2^21: index x P + rank is exact in an f64, and
    // its minimum names both the smallest index and the rank that holds it.
    let p = comm.size() as f64;
    let key = index as f64 * p + comm.rank() as f64;
    let mut first = [if value == top[0] {
        -key
    } else {
        f64::NEG_INFINITY
    }];
    comm.max(&mut first)?;
    let key = -first[0];
    let (winner, owner) = ((key / p).floor(), key % p);
    let mut data = payload;
    comm.broadcast(&mut data, owner as usize)?;
    Ok((top[0], winner as usize, data))
}

/// End a stage that may fail on some ranks only: when any rank's `local` is an error, every
/// rank returns an error (its own, or [`EigenError::OtherRanks`] naming the ranks that failed
/// and the stage); otherwise every rank keeps its value.
///
/// # Errors
/// As described; a failing collective itself as [`EigenError::Backend`].
pub fn agree<T>(comm: &dyn Collective, stage: &'static str, local: Result<T>) -> Result<T> {
    let mut failed = vec![0.0; comm.size()];
    failed[comm.rank()] = f64::from(u8::from(local.is_err()));
    comm.sum(&mut failed)?;
    let ranks: Vec<usize> = (0..failed.len()).filter(|&r| failed[r] > 0.0).collect();
    match local {
        Err(e) => Err(e),
        Ok(_) if !ranks.is_empty() => Err(Error::Eigen(EigenError::OtherRanks { stage, ranks })),
        Ok(v) => Ok(v),
    }
}

/// Run `work` on `size` ranks in this process, each on its own thread with a [`Collective`]
/// joining them, and return each rank's result in rank order. Deterministic: sums and maxima
/// combine the ranks' values in rank order.
///
/// # Panics
/// When `work` panics on a rank (the panic is re-raised here; the other ranks then panic at
/// their next collective, which never completes).
pub fn run_ranks<T: Send>(size: usize, work: impl Fn(&dyn Collective) -> T + Sync) -> Vec<T> {
    let size = size.max(1);
    let shared = Shared {
        slots: Mutex::new(vec![Vec::new(); size]),
        barrier: Barrier::new(size),
    };
    std::thread::scope(|scope| {
        let handles: Vec<_> = (0..size)
            .map(|rank| {
                let (shared, work) = (&shared, &work);
                scope.spawn(move || work(&ThreadRank { rank, size, shared }))
            })
            .collect();
        handles
            .into_iter()
            .map(|h| h.join().unwrap_or_else(|p| std::panic::resume_unwind(p)))
            .collect()
    })
}

struct Shared {
    slots: Mutex<Vec<Vec<f64>>>,
    barrier: Barrier,
}

struct ThreadRank<'a> {
    rank: usize,
    size: usize,
    shared: &'a Shared,
}

impl ThreadRank<'_> {
    /// Every rank's buffer, in rank order (two barriers: all written, then all read).
    fn exchange(&self, mine: &[f64]) -> Vec<Vec<f64>> {
        let slots = &self.shared.slots;
        slots.lock().unwrap_or_else(|p| p.into_inner())[self.rank] = mine.to_vec();
        self.shared.barrier.wait();
        let all = slots.lock().unwrap_or_else(|p| p.into_inner()).clone();
        self.shared.barrier.wait();
        all
    }

    fn reduce(&self, values: &mut [f64], op: fn(f64, f64) -> f64) -> Result<()> {
        let all = self.exchange(values);
        check_lengths(&all, values.len())?;
        for (i, v) in values.iter_mut().enumerate() {
            *v = all.iter().skip(1).fold(all[0][i], |acc, r| op(acc, r[i]));
        }
        Ok(())
    }
}

fn check_lengths(all: &[Vec<f64>], len: usize) -> Result<()> {
    match all.iter().position(|r| r.len() != len) {
        Some(r) => Err(Error::Eigen(EigenError::Backend {
            library: "in-process ranks",
            message: format!(
                "rank {r} passed {} values to a collective where this rank passed {len}",
                all[r].len()
            ),
        })),
        None => Ok(()),
    }
}

impl Collective for ThreadRank<'_> {
    fn rank(&self) -> usize {
        self.rank
    }

    fn size(&self) -> usize {
        self.size
    }

    fn sum(&self, values: &mut [f64]) -> Result<()> {
        self.reduce(values, |a, b| a + b)
    }

    fn max(&self, values: &mut [f64]) -> Result<()> {
        // NaN wins, as it does in MPI_MAX on this platform's comparisons: it is never hidden.
        self.reduce(values, |a, b| if a.is_nan() || b > a { b } else { a })
    }

    fn broadcast(&self, values: &mut [f64], root: usize) -> Result<()> {
        let all = self.exchange(values);
        check_lengths(&all, values.len())?;
        values.copy_from_slice(&all[root.min(self.size - 1)]);
        Ok(())
    }

    fn all_gather(&self, mine: &[f64]) -> Result<Vec<f64>> {
        let all = self.exchange(mine);
        check_lengths(&all, mine.len())?;
        Ok(all.concat())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn thread_ranks_reduce_broadcast_gather_and_agree() {
        let out = run_ranks(3, |c| {
            let r = c.rank() as f64;
            let mut s = [r, 1.0];
            c.sum(&mut s).unwrap();
            let mut m = [r, -r];
            c.max(&mut m).unwrap();
            let mut lo = [r + 5.0];
            min(c, &mut lo).unwrap();
            let mut b = [r; 2];
            c.broadcast(&mut b, 2).unwrap();
            let g = c.all_gather(&[r, 10.0 * r]).unwrap();
            // Ranks 0 and 2 hold the largest value 7; the smaller index (3, on rank 2) wins.
            let offer = match c.rank() {
                0 => (7.0, 9),
                1 => (6.0, 1),
                _ => (7.0, 3),
            };
            let best = arg_max(c, offer.0, offer.1, [r, r, r]).unwrap();
            let agreed = agree(
                c,
                "test",
                if c.rank() == 1 {
                    Err(Error::param("x", 1, "bad"))
                } else {
                    Ok(())
                },
            );
            (s, m, lo, b, g, best, agreed.map_err(|e| e.to_string()))
        });
        for (rank, (s, m, lo, b, g, best, agreed)) in out.into_iter().enumerate() {
            assert_eq!(s, [3.0, 3.0]);
            assert_eq!(m, [2.0, 0.0]);
            assert_eq!(lo, [5.0]);
            assert_eq!(b, [2.0, 2.0]);
            assert_eq!(g, vec![0.0, 0.0, 1.0, 10.0, 2.0, 20.0]);
            assert_eq!(best, (7.0, 3, [2.0; 3]));
            let e = agreed.unwrap_err();
            if rank == 1 {
                assert!(e.contains("bad"), "{e}");
            } else {
                assert!(e.contains("rank(s) [1]") && e.contains("test"), "{e}");
            }
        }
    }

    #[test]
    fn arg_max_past_the_gather_limit_takes_the_three_step_path() {
        let out = run_ranks(18, |c| {
            let r = c.rank();
            // Every even rank offers the maximum 4; the smallest index among them is rank 16's.
            let (v, i) = if r % 2 == 0 { (4.0, 100 - r) } else { (1.0, 0) };
            arg_max(c, v, i, [r as f64; 3]).unwrap()
        });
        for best in out {
            assert_eq!(best, (4.0, 84, [16.0; 3]));
        }
    }
}
