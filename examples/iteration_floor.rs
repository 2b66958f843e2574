//! The floor of one native LOBPCG iteration on this machine, against a measured solve.
//!
//! Measures the machine (a STREAM-style triad for memory bandwidth, faer's GEMM for the
//! dense arithmetic rate, each on 1 and 2 threads), then reads a `freeform modes --json`
//! report and sets each part of the iteration against its floor:
//! - sparse products H W and M W: `matvecs x 2 nnz(H)` flops, or streaming the two matrices
//!   (indices and values) once per product call, whichever takes longer;
//! - the preconditioner's triangular solves (IC(0), or the exact factor at small K):
//!   `4 nnz(L)` flops per column (forward and backward), or streaming the factor twice per
//!   application on each thread (each thread solves its own columns);
//! - orthogonalization and Rayleigh-Ritz: their dense flops (below) at the GEMM rate.
//!
//! The block is X (nx = m + guards), P (nx) and W (nx) at the start of the iteration:
//! ns = 3 nx columns, and the counts take every column active (an upper bound on the work,
//! so a lower bound on nothing: the floor is of the work done when all columns iterate).
//!
//!     cargo run --release --example iteration_floor -- REPORT.json [--quick]
//!
//! `--quick` uses smaller arrays (CI-sized; the figures are then not the machine's).

use faer::{Mat, Par};
use rayon::prelude::*;
use std::time::Instant;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let quick = args.iter().any(|a| a == "--quick");
    let Some(path) = args.iter().find(|a| !a.starts_with("--")) else {
        return Err("usage: iteration_floor REPORT.json [--quick] (a `freeform modes --json` report of a LOBPCG run)".into());
    };
    let report: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(path)?)?;
    let run = Run::from_report(&report)?;

    let (triad_len, gemm_n) = if quick {
        (1 << 20, 256)
    } else {
        (40 << 20, 2048)
    };
    let machine = Machine {
        triad_1: on_threads(1, || triad(triad_len)),
        triad_2: on_threads(2, || triad(triad_len)),
        gemm_1: on_threads(1, || gemm(gemm_n, Par::Seq)),
        gemm_2: on_threads(2, || gemm(gemm_n, Par::rayon(2))),
    };
    println!(
        "machine: triad {:.1} GB/s (1 thread), {:.1} GB/s (2 threads); GEMM {:.1} GFLOP/s (1 thread), {:.1} GFLOP/s (2 threads)",
        machine.triad_1 * 1e-9,
        machine.triad_2 * 1e-9,
        machine.gemm_1 * 1e-9,
        machine.gemm_2 * 1e-9
    );
    println!(
        "run: K = {}, nnz(H) = {}, IC(0) entries {}, block nx = {}, {} iterations, {} product columns",
        run.k, run.nnz, run.factor_entries, run.nx, run.iterations, run.matvecs
    );
    let floor = Floor::of(&run, &machine);
    let it = run.iterations as f64;
    println!("per iteration | measured s | floor s | measured / floor | floor bound by");
    let rows = [
        ("sparse products", run.seconds.products, floor.products),
        (
            "factor solves",
            run.seconds.precondition,
            floor.precondition,
        ),
        (
            "orthogonalization + Rayleigh-Ritz",
            run.seconds.dense,
            floor.dense,
        ),
    ];
    let mut total = (0.0, 0.0);
    for (name, measured, (bound, by)) in rows {
        total.0 += measured;
        total.1 += bound;
        println!(
            "{name} | {:.4} | {:.4} | {:.1} | {by}",
            measured / it,
            bound / it,
            measured / bound
        );
    }
    println!(
        "iteration | {:.4} | {:.4} | {:.1} |",
        total.0 / it,
        total.1 / it,
        total.0 / total.1
    );
    Ok(())
}

/// Rates measured on this machine: bytes/s and flop/s.
struct Machine {
    triad_1: f64,
    triad_2: f64,
    gemm_1: f64,
    gemm_2: f64,
}

/// What a report says of one LOBPCG solve.
struct Run {
    k: f64,
    nnz: f64,
    factor_entries: f64,
    nx: f64,
    iterations: usize,
    matvecs: f64,
    seconds: PhaseSeconds,
}

/// Seconds of the iterations' parts, summed over the solve.
struct PhaseSeconds {
    precondition: f64,
    products: f64,
    dense: f64,
}

impl Run {
    fn from_report(r: &serde_json::Value) -> Result<Self, String> {
        let num = |v: &serde_json::Value, what: &str| {
            v.as_f64()
                .ok_or_else(|| format!("report: no number for {what}"))
        };
        let eigen = &r["eigen"];
        let notes: Vec<&str> = eigen["notes"]
            .as_array()
            .ok_or("report: no eigen.notes (is it a LOBPCG run's --json report?)")?
            .iter()
            .filter_map(|n| n.as_str())
            .collect();
        let note = |prefix: &str| {
            notes
                .iter()
                .find(|n| n.starts_with(prefix))
                .copied()
                .ok_or_else(|| format!("report: no note starting {prefix:?}"))
        };
        let times = note("time: preconditioner")?;
        let seconds = PhaseSeconds {
            precondition: number_after(times, "preconditioner ")?,
            products: number_after(times, "sparse products ")?,
            dense: number_after(times, "orthogonalization ")?
                + number_after(times, "Rayleigh-Ritz and updates ")?,
        };
        // IC(0) at large K; the exact sparse Cholesky where `Auto` keeps it (small K).
        let factor =
            note("preconditioner: IC(0)").or_else(|_| note("preconditioner: sparse Cholesky"))?;
        let factor_entries = number_after(factor, "): ")?;
        let block = note("block: ")?;
        let nx = number_after(block, "= ")?;
        Ok(Self {
            k: num(&r["kernels"], "kernels")?,
            nnz: num(&r["nnz_hessian"], "nnz_hessian")?,
            factor_entries,
            nx,
            iterations: eigen["iterations"]
                .as_u64()
                .ok_or("report: no eigen.iterations")? as usize,
            matvecs: num(&eigen["matvecs"], "eigen.matvecs")?,
            seconds,
        })
    }
}

/// The number that follows `key` in `text` (digits, '.', 'e', '-').
fn number_after(text: &str, key: &str) -> Result<f64, String> {
    let at = text
        .find(key)
        .ok_or_else(|| format!("report note {text:?}: no {key:?}"))?;
    let rest = &text[at + key.len()..];
    let end = rest
        .find(|c: char| !(c.is_ascii_digit() || c == '.' || c == 'e' || c == '-'))
        .unwrap_or(rest.len());
    rest[..end]
        .parse()
        .map_err(|e| format!("report note {text:?}: {key:?} not followed by a number ({e})"))
}

/// Floors of the solve's parts (seconds over the whole solve) with what bounds each.
struct Floor {
    products: (f64, &'static str),
    precondition: (f64, &'static str),
    dense: (f64, &'static str),
}

impl Floor {
    fn of(run: &Run, m: &Machine) -> Self {
        let it = run.iterations as f64;
        // Products: 2 flops per entry and column; each call streams one matrix (8-byte
        // values and indices), two calls per iteration (M W before orthogonalization, H W
        // after).
        let products = slower(
            (2.0 * run.nnz * run.matvecs / m.gemm_2, "flops"),
            (it * 2.0 * 16.0 * run.nnz / m.triad_2, "bandwidth"),
        );
        // The factor (IC(0), or the exact one): forward and backward, 2 flops per entry and
        // column each; about half the product columns are preconditioned residual columns.
        // Each of the two threads streams the factor (8-byte value, 4-byte index) forward
        // and backward.
        let precondition = slower(
            (
                4.0 * run.factor_entries * run.matvecs / 2.0 / m.gemm_2,
                "flops",
            ),
            (
                it * 2.0 * 2.0 * 12.0 * run.factor_entries / m.triad_2,
                "bandwidth",
            ),
        );
        // Dense parts per iteration, nx = n columns each of X, P and W, ns = 3 n:
        // Gram lower halves of S^T HS and S^T MS: 2 K ns^2; the update of S, HS, MS to
        // (X, P): 3 x 2 K ns (2 n); two passes of W against (X, P) (project, update W and MW:
        // 3 x 2 K (2n) n) and of W against itself (Gram K n^2, two triangular updates 2 K n^2).
        let (k, n) = (run.k, run.nx);
        let ns = 3.0 * n;
        let per_iteration = 2.0 * k * ns * ns
            + 6.0 * k * ns * 2.0 * n
            + 2.0 * (6.0 * k * 2.0 * n * n + 3.0 * k * n * n);
        let dense = (it * per_iteration / m.gemm_2, "flops");
        Self {
            products,
            precondition,
            dense,
        }
    }
}

fn slower(a: (f64, &'static str), b: (f64, &'static str)) -> (f64, &'static str) {
    if a.0 >= b.0 {
        a
    } else {
        b
    }
}

/// Run `f` on a pool of `threads` threads.
fn on_threads(threads: usize, f: impl FnOnce() -> f64 + Send) -> f64 {
    match rayon::ThreadPoolBuilder::new().num_threads(threads).build() {
        Ok(pool) => pool.install(f),
        Err(_) => f(),
    }
}

/// Best of 5 of a[i] = b[i] + 3 c[i] over `n` doubles, in bytes/s (24 bytes per element,
/// STREAM's count).
fn triad(n: usize) -> f64 {
    let b = vec![1.0f64; n];
    let c = vec![2.0f64; n];
    let mut a = vec![0.0f64; n];
    let mut best = f64::INFINITY;
    for _ in 0..5 {
        let t = Instant::now();
        a.par_chunks_mut(1 << 16)
            .zip(b.par_chunks(1 << 16))
            .zip(c.par_chunks(1 << 16))
            .for_each(|((a, b), c)| {
                for ((a, b), c) in a.iter_mut().zip(b).zip(c) {
                    *a = b + 3.0 * c;
                }
            });
        best = best.min(t.elapsed().as_secs_f64());
    }
    assert!(a[n / 2] == 7.0, "triad result");
    24.0 * n as f64 / best
}

/// Best of 3 of an n x n x n GEMM with faer, in flop/s.
fn gemm(n: usize, par: Par) -> f64 {
    let a = Mat::<f64>::from_fn(n, n, |i, j| ((i * 7 + j * 3) % 11) as f64 - 5.0);
    let b = Mat::<f64>::from_fn(n, n, |i, j| ((i * 5 + j) % 13) as f64 - 6.0);
    let mut c = Mat::<f64>::zeros(n, n);
    let mut best = f64::INFINITY;
    for _ in 0..3 {
        let t = Instant::now();
        faer::linalg::matmul::matmul(c.as_mut(), faer::Accum::Replace, &a, &b, 1.0, par);
        best = best.min(t.elapsed().as_secs_f64());
    }
    assert!(c[(0, 0)].is_finite(), "gemm result");
    2.0 * (n as f64).powi(3) / best
}
