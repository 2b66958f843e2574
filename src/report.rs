//! Machine-readable reports: per-stage timing counters and the `modes` JSON report
//! (design.md section 6). Every pipeline stage records into one [`Timings`] struct.

use serde::Serialize;
use std::time::Instant;

/// Wall time per pipeline stage, seconds.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct Timings {
    /// Shape reading plus integration points and volumes.
    pub sampling: f64,
    /// Farthest point sampling of kernel centres, support radii.
    pub centers: f64,
    /// Neighbour search (which kernels cover which points).
    pub neighbors: f64,
    /// Shape functions and gradients (including coverage repair).
    pub shape_functions: f64,
    /// Sparse assembly of H_w and M.
    pub assembly: f64,
    /// Generalized eigensolve.
    pub eigensolve: f64,
    /// Whole pipeline.
    pub total: f64,
}

/// A running stopwatch for one stage.
#[derive(Debug)]
pub struct Stopwatch(Instant);

impl Stopwatch {
    /// Start now.
    pub fn start() -> Self {
        Self(Instant::now())
    }
    /// Seconds since start.
    pub fn elapsed(&self) -> f64 {
        self.0.elapsed().as_secs_f64()
    }
    /// Seconds since start; restarts the watch.
    pub fn lap(&mut self) -> f64 {
        let now = Instant::now();
        let s = now.duration_since(self.0).as_secs_f64();
        self.0 = now;
        s
    }
}

/// Peak resident memory of this process so far (bytes), from /proc/self/status (VmHWM).
/// None where that file is not available.
pub fn peak_memory_bytes() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb * 1024)
}
