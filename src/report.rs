//! Machine-readable reports: per-stage timing counters and the `modes` JSON report
//! (design.md section 6). Every pipeline stage records into one [`Timings`] struct.

use serde::Serialize;
use std::time::Instant;

/// Wall time per pipeline stage, seconds.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, serde::Deserialize)]
pub struct Timings {
    /// Shape reading plus integration points and volumes (for a box, sphere or image also
    /// the second sampling after the eigensolve, which does not hold the points).
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

/// Hand freed memory back to the system. Millions of small freed allocations (the assembly's
/// rows, the exact factor's analysis) stay in glibc's heaps otherwise, resident through the
/// eigensolve (~4 GB at K = 1,000,000 after the assembly; docs/performance.md). A no-op
/// elsewhere than Linux with glibc.
pub fn release_freed_memory() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: malloc_trim only returns free pages of malloc's own heaps to the system; it
    // touches no live allocation and is thread-safe (it locks each arena).
    unsafe {
        libc::malloc_trim(0);
    }
}

/// User + system CPU seconds of this process so far (all threads), from /proc/self/stat
/// (Linux; clock ticks of 1/100 s), or None elsewhere. Less sensitive than wall time to other
/// processes sharing the cores.
pub fn process_cpu_seconds() -> Option<f64> {
    let stat = std::fs::read_to_string("/proc/self/stat").ok()?;
    // Fields after the command name (which may contain spaces) end with ')'.
    let rest = stat.rsplit_once(')')?.1;
    let f: Vec<&str> = rest.split_whitespace().collect();
    // utime and stime are fields 14 and 15 of the whole line: 12 and 13 after ')'.
    let utime: f64 = f.get(11)?.parse().ok()?;
    let stime: f64 = f.get(12)?.parse().ok()?;
    Some((utime + stime) / 100.0)
}

/// Conditioning and convergence monitors, with the same keys in every report (`modes`,
/// `run`, `beam`; issue #6). A field is `None` when its stage did not run in this process
/// and was not recorded (for example a basis loaded from an old cache file).
#[derive(Debug, Clone, Default, PartialEq, Serialize, serde::Deserialize)]
pub struct Monitors {
    /// Smallest reciprocal condition number (1-norm) of the scaled RKPM moment matrices over
    /// the integration points (dimensionless; ~1e-2 in the interior, ~1e-3 at box corners;
    /// points below `min_rcond`, default 1e-6, trigger support enlargement or an error).
    pub min_moment_rcond: Option<f64>,
    /// Kernels whose support was enlarged to cover badly conditioned points.
    pub enlarged_kernels: Option<usize>,
    /// Largest violation of the linear reproducing conditions (m, relative to the support).
    pub reproducing_error: Option<f64>,
    /// Eigensolver outer iterations.
    pub eigen_iterations: Option<usize>,
    /// LOBPCG restarts (iterations that dropped the search directions for conditioning).
    pub eigen_restarts: Option<usize>,
    /// Eigenpairs locked at exit.
    pub eigen_locked: Option<usize>,
    /// Largest recomputed relative eigen-residual.
    pub eigen_max_relative_residual: Option<f64>,
    /// max |c^T M c - I|, recomputed.
    pub eigen_orthonormality_error: Option<f64>,
    /// Time steps simulated.
    pub steps: Option<usize>,
    /// Steps that did not meet the Newton tolerance.
    pub newton_nonconverged_steps: Option<usize>,
    /// Times a Newton Hessian was not positive definite and the rest matrix was used.
    pub newton_cholesky_fallbacks: Option<usize>,
    /// Steps whose line search could not decrease the energy.
    pub line_search_failures: Option<usize>,
    /// Line-search step halvings over the run.
    pub line_search_cutbacks: Option<usize>,
    /// Smallest det F at any cubature point at the end of any step (<= 0: inverted).
    pub min_det: Option<f64>,
}

/// Something a run found worth a look that is not an error: the run goes on (strict mode,
/// [`crate::Error::Strict`], stops at the first one instead). `Display` is the message the
/// reports, the CLI and the bindings show; JSON reports hold that text.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub enum Warning {
    /// A quality monitor's message, as its stage words it: the precomputation's (conditioning,
    /// coverage, eigen residuals; from the build or stored with a cached basis) or a
    /// benchmark's (a rank-deficient fit, a reduced step that did not converge).
    Monitor {
        /// The scene object, if any.
        object: Option<String>,
        /// The monitor's message.
        message: String,
    },
    /// A cached basis could not be used (it is computed again).
    Cache {
        /// The scene object.
        object: String,
        /// What was wrong with the cache entry.
        message: String,
    },
    /// A step's minimisation stopped before its tolerance.
    NotConverged {
        /// The object.
        object: String,
        /// The step (from 1).
        step: usize,
        /// Iterations taken.
        iterations: usize,
        /// Final convergence measure.
        residual: f64,
        /// Whether the line search failed.
        line_search_failed: bool,
    },
    /// Cubature points inverted (det F <= 0); raised once per object.
    Inverted {
        /// The object.
        object: String,
        /// The step (from 1).
        step: usize,
        /// Inverted cubature points.
        points: usize,
        /// Smallest det F.
        min_det: f64,
    },
    /// Newton Hessians that were not positive definite, replaced by the rest Hessian.
    HessianFallback {
        /// The object.
        object: String,
        /// The step (from 1).
        step: usize,
        /// Hessians replaced.
        count: usize,
    },
    /// Object-object penetration above the contact tolerance (raised once per pair; `first ==
    /// second` for self-contact).
    Penetration {
        /// The deeper pair's first object.
        first: String,
        /// Its second object (the same for self-penetration).
        second: String,
        /// The step (from 1).
        step: usize,
        /// Depth, metres.
        depth: f64,
        /// Depth as a fraction of the smaller diagonal.
        fraction: f64,
        /// The tolerance, as a fraction.
        tolerance: f64,
    },
}

impl std::fmt::Display for Warning {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Warning::Monitor { object, message } => match object {
                Some(o) => write!(f, "object '{o}': {message}"),
                None => f.write_str(message),
            },
            Warning::Cache { object, message } => write!(f, "object '{object}': {message}"),
            Warning::NotConverged {
                object,
                step,
                iterations,
                residual,
                line_search_failed,
            } => write!(
                f,
                "object '{object}': step {step} did not converge ({iterations} iterations, \
                 residual {residual:.2e}{})",
                if *line_search_failed {
                    ", line search failed"
                } else {
                    ""
                }
            ),
            Warning::Inverted {
                object,
                step,
                points,
                min_det,
            } => write!(
                f,
                "object '{object}': step {step}: {points} cubature point(s) inverted (det F = \
                 {min_det:.2} <= 0); the material is too soft for the load or the time step too \
                 large (later inversions are counted in the monitors' min_det and each step's \
                 `inverted`)"
            ),
            Warning::HessianFallback {
                object,
                step,
                count,
            } => write!(
                f,
                "object '{object}': step {step}: {count} Newton Hessian(s) were not positive \
                 definite; the rest Hessian was used instead"
            ),
            Warning::Penetration {
                first,
                second,
                step,
                depth,
                fraction,
                tolerance,
            } => {
                let (pct, tol) = (100.0 * fraction, 100.0 * tolerance);
                if first == second {
                    write!(
                        f,
                        "object '{first}': step {step}: self-penetration {depth:.3e} m, \
                         {pct:.2}% of its diagonal, above the tolerance ({tol:.2}%); raise \
                         contact.stiffness or shorten the time step"
                    )
                } else {
                    write!(
                        f,
                        "objects '{first}' and '{second}': step {step}: penetration {depth:.3e} \
                         m, {pct:.2}% of the smaller diagonal, above the tolerance ({tol:.2}%); \
                         raise contact.stiffness or shorten the time step"
                    )
                }
            }
        }
    }
}

impl Warning {
    /// A monitor's message with no object ([`Warning::Monitor`]).
    pub fn monitor(message: impl Into<String>) -> Warning {
        Warning::Monitor {
            object: None,
            message: message.into(),
        }
    }
}

impl Serialize for Warning {
    /// As its message.
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.collect_str(self)
    }
}
