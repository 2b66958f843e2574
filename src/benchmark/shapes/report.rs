//! A folder of shapes through the protocol: per-shape results, the shapes that failed with
//! their reason, averages per (test, basis), and the CSV.

use super::eval::{evaluate_shape, EvalOptions, ShapeEval};
use super::protocol::ShapeTest;
use crate::precompute::BoundaryModes;
use crate::progress::Progress;
use crate::report::Stopwatch;
use crate::{Error, Result};
use serde::Serialize;
use std::path::{Path, PathBuf};

/// A shape that could not be evaluated.
#[derive(Debug, Clone, Serialize)]
pub struct ShapeFailure {
    /// File stem.
    pub name: String,
    /// Why (the error message).
    pub reason: String,
}

/// Means over the shapes that ran one (test, basis) pair.
#[derive(Debug, Clone, Serialize)]
pub struct Average {
    /// The boundary condition.
    pub test: ShapeTest,
    /// Free or boundary-aware basis.
    pub boundaries: BoundaryModes,
    /// Shapes averaged.
    pub shapes: usize,
    /// Mean normalized MSE (dimensionless).
    pub normalized_mse: f64,
    /// Mean max error / D.
    pub max_error: f64,
    /// Mean basis fitting residual, mean |r|^2 / D^2.
    pub fit_mse: f64,
    /// Mean basis fitting residual, max |r| / D.
    pub fit_max: f64,
    /// Mean precompute time, s.
    pub precompute_s_mean: f64,
    /// Its standard deviation over the shapes, s (population).
    pub precompute_s_std: f64,
    /// Mean reduced step, ms.
    pub reduced_step_ms_mean: f64,
}

/// The report of `freeform eval`.
#[derive(Debug, Clone, Serialize)]
pub struct EvalReport {
    /// The settings.
    pub options: EvalOptions,
    /// The shapes evaluated (possibly with some (test, basis) failures each).
    pub shapes: Vec<ShapeEval>,
    /// The shapes that could not be evaluated at all.
    pub failures: Vec<ShapeFailure>,
    /// Means per (test, basis).
    pub averages: Vec<Average>,
    /// Wall time of the whole run, s.
    pub total_s: f64,
}

/// The shape files of `dir` (extensions off, obj, stl, ply), sorted by name; with `only`,
/// just the stems listed there, in the order listed.
///
/// # Errors
/// [`Error::Io`] when the folder cannot be read; [`Error::InvalidParameter`] when it holds
/// no shape file, or a name of `only` matches none (the error lists them).
pub fn shape_files(dir: &Path, only: &[String]) -> Result<Vec<PathBuf>> {
    let entries = std::fs::read_dir(dir).map_err(|source| Error::Io {
        path: dir.to_path_buf(),
        source,
    })?;
    let mut files: Vec<PathBuf> = entries
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| {
            let ext = p.extension().map(|e| e.to_string_lossy().to_lowercase());
            matches!(ext.as_deref(), Some("off" | "obj" | "stl" | "ply"))
        })
        .collect();
    files.sort();
    if files.is_empty() {
        return Err(Error::param(
            "shapes",
            dir.display().to_string(),
            "no shape file (.off, .obj, .stl, .ply) to evaluate there",
        ));
    }
    if only.is_empty() {
        return Ok(files);
    }
    let stem = |p: &PathBuf| p.file_stem().map(|s| s.to_string_lossy().into_owned());
    let mut chosen = Vec::new();
    let mut missing = Vec::new();
    for name in only {
        let matching: Vec<&PathBuf> = files
            .iter()
            .filter(|p| stem(p).as_deref() == Some(name.as_str()))
            .collect();
        if matching.is_empty() {
            missing.push(name.as_str());
        }
        chosen.extend(matching.into_iter().cloned());
    }
    if !missing.is_empty() {
        return Err(Error::param(
            "only",
            missing.join(","),
            format!(
                "no shape file with that name in {} (names are file stems, e.g. bunny for bunny.off)",
                dir.display()
            ),
        ));
    }
    Ok(chosen)
}

/// Evaluate every file of `files` ([`evaluate_shape`]) in order; a shape that fails is
/// listed in [`EvalReport::failures`] with its reason and the others go on. TetGen works in
/// `work_dir`; FEM references are cached in `cache_dir`. `after_each` sees the report of the
/// shapes done so far after every shape (a long run can write its outputs as it goes).
pub fn evaluate_dir(
    files: &[PathBuf],
    opts: &EvalOptions,
    cache_dir: Option<&Path>,
    work_dir: &Path,
    progress: &dyn Progress,
    after_each: &mut dyn FnMut(&EvalReport),
) -> EvalReport {
    let clock = Stopwatch::start();
    let mut report = EvalReport {
        options: opts.clone(),
        shapes: Vec::new(),
        failures: Vec::new(),
        averages: Vec::new(),
        total_s: 0.0,
    };
    for (i, f) in files.iter().enumerate() {
        let name = f
            .file_stem()
            .map_or("shape".into(), |s| s.to_string_lossy().into_owned());
        progress.message(&format!("shape {}/{}: {name}", i + 1, files.len()));
        match evaluate_shape(f, opts, cache_dir, work_dir, progress) {
            Ok(s) => report.shapes.push(s),
            Err(e) => report.failures.push(ShapeFailure {
                name,
                reason: e.to_string(),
            }),
        }
        report.averages = averages(&report.shapes, opts);
        report.total_s = clock.elapsed();
        after_each(&report);
    }
    report
}

fn averages(shapes: &[ShapeEval], opts: &EvalOptions) -> Vec<Average> {
    let mut out = Vec::new();
    for &test in &opts.tests {
        for &b in &opts.boundaries {
            let runs: Vec<_> = shapes
                .iter()
                .flat_map(|s| &s.runs)
                .filter(|r| r.test == test && r.boundaries == b)
                .collect();
            if runs.is_empty() {
                continue;
            }
            let n = runs.len() as f64;
            let mean =
                |f: &dyn Fn(&super::ShapeRun) -> f64| runs.iter().map(|r| f(r)).sum::<f64>() / n;
            let pre = mean(&|r| r.precompute_s);
            out.push(Average {
                test,
                boundaries: b,
                shapes: runs.len(),
                normalized_mse: mean(&|r| r.normalized_mse),
                max_error: mean(&|r| r.max_error),
                fit_mse: mean(&|r| r.fit_mse),
                fit_max: mean(&|r| r.fit_max),
                precompute_s_mean: pre,
                precompute_s_std: mean(&|r| (r.precompute_s - pre).powi(2)).sqrt(),
                reduced_step_ms_mean: mean(&|r| r.reduced_step_ms_mean),
            });
        }
    }
    out
}

impl EvalReport {
    /// One CSV row per (shape, test, basis), then one per failure (metrics empty).
    pub fn to_csv(&self) -> String {
        let mut s = String::from(
            "shape,test,boundaries,normalized_mse,max_error,fit_mse,fit_max,precompute_s,basis_s,reduced_step_ms,nonconverged_steps,points,fem_nodes,fem_tets,fem_step_ms,error\n",
        );
        for sh in &self.shapes {
            for r in &sh.runs {
                s += &format!(
                    "{},{},{},{:.6e},{:.6e},{:.6e},{:.6e},{:.4},{:.4},{:.4},{},{},{},{},{:.3},\n",
                    sh.name,
                    r.test.name(),
                    r.boundaries.name(),
                    r.normalized_mse,
                    r.max_error,
                    r.fit_mse,
                    r.fit_max,
                    r.precompute_s,
                    r.basis_s,
                    r.reduced_step_ms_mean,
                    r.reduced_nonconverged_steps,
                    r.points,
                    sh.fem_nodes,
                    sh.fem_tets,
                    r.fem_step_ms_mean
                );
            }
            for f in &sh.failures {
                s += &format!("{},,,,,,,,,,,,,,,\"{}\"\n", sh.name, f.replace('"', "'"));
            }
        }
        for f in &self.failures {
            s += &format!(
                "{},,,,,,,,,,,,,,,\"{}\"\n",
                f.name,
                f.reason.replace('"', "'")
            );
        }
        s
    }
}
