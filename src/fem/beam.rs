//! The standard beam benchmark's FEM reference (design.md section 3), cached on disk.
//!
//! Beam [0, 5] x [0, 1] x [0, 1] m, meshed by [`TetMesh::structured_box`] with `resolution`
//! cubes per metre (5r x r x r cubes, (5r + 1)(r + 1)^2 nodes, 30 r^3 tets). Material
//! E = 5e6 Pa, nu = 0.45, rho = 1000 kg/m^3; h = 0.01 s; 200 steps.
//! - **Bend**: nodes with x <= 0.5 held; gravity (0, -9.81, 0).
//! - **Twist**: nodes with x <= 0.25 held; nodes with x >= 4.75 turned about the axis
//!   y = z = 0.5 (parallel to x), counter-clockwise seen from +x (the right-hand rule about
//!   +x), by theta_n = 720 deg x n / steps after step n = 1..steps; gravity off.
//!
//! Frames: the positions after each step, `steps` frames (the rest state is not a frame).
//!
//! **Cache.** [`run_beam_reference`] keys the result by a hash (FNV-1a 64) of the canonical
//! JSON of every parameter that affects it ([`FemBeamConfig`] including the solver settings,
//! plus [`CACHE_FORMAT_VERSION`]) and stores it as `<dir>/<16 hex digits>.bin`, written to a
//! temporary file and renamed (atomic on one file system). The file repeats the key JSON and
//! ends with a checksum; a file that is short, fails the checksum or holds another key is
//! recomputed and rewritten, and the reason is reported in [`CacheStatus::Recomputed`].

use super::element::fe_nodes;
use super::metric::{trajectory_error, TrajectoryError};
use super::solver::{FemParams, FemSolver};
use super::{FemError, TetMaterials, TetMesh};
use crate::material::Material;
use crate::progress::Progress;
use crate::Point3;
use serde::{Deserialize, Serialize};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Version of the cache file layout and of the benchmark definition; bump on any change.
pub const CACHE_FORMAT_VERSION: u32 = 1;

/// Which beam test.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum BeamTest {
    /// Cantilever under gravity, held for x <= 0.5.
    Bend,
    /// Held for x <= 0.25, the end x >= 4.75 turned by 720 degrees, no gravity.
    Twist,
}

impl BeamTest {
    /// "bend" or "twist".
    pub fn name(&self) -> &'static str {
        crate::names::variant_name(self)
    }
}

/// Everything that defines a beam reference run (and its cache key).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FemBeamConfig {
    /// The test.
    pub test: BeamTest,
    /// Cubes per metre (each cut into 6 tets); 5r x r x r cubes.
    pub resolution: usize,
    /// Beam length, width and height, metres. Default [5, 1, 1].
    pub size: Point3,
    /// Material. Default E = 5e6 Pa, nu = 0.45, rho = 1000 kg/m^3.
    pub material: Material,
    /// Steps. Default 200.
    pub steps: usize,
    /// Held nodes: x <= held_length, metres. Default 0.5 (bend), 0.25 (twist).
    pub held_length: f64,
    /// Twist: nodes with `x >= size[0] - twist_length` are turned, metres. Default 0.25.
    pub twist_length: f64,
    /// Twist: total angle reached at the last step, degrees. Default 720.
    pub twist_degrees: f64,
    /// Solver settings (dt, gravity, tolerance, ...). Default [`FemParams::default`] with
    /// gravity off for the twist.
    pub solver: FemParams,
}

impl FemBeamConfig {
    /// The standard definition (design.md section 3) at `resolution` cubes per metre, with
    /// linear tets (see [`FemBeamConfig::reference`] for the recommended reference).
    pub fn standard(test: BeamTest, resolution: usize) -> Self {
        let mut solver = FemParams::default();
        if test == BeamTest::Twist {
            solver.gravity = [0.0; 3];
        }
        Self {
            test,
            resolution,
            size: [5.0, 1.0, 1.0],
            material: Material::default(),
            steps: 200,
            held_length: if test == BeamTest::Bend { 0.5 } else { 0.25 },
            twist_length: 0.25,
            twist_degrees: 720.0,
            solver,
        }
    }

    /// The recommended reference for comparisons with the reduced model: quadratic tets,
    /// r = 4 (3,321 FE nodes, 1,920 tets; ~1 s (bend) to 2.5 s (twist) per step on 2 loaded
    /// cores, 3-8 minutes per run, then cached). Chosen from the
    /// refinement study in docs/accuracy.md: linear tets lock in bending (the largest sag is
    /// still 12% short at r = 8, 3% at r = 16), quadratic ones converge at order ~3 and r = 4 is within
    /// an estimated ~1e-3 D (RMS) of the converged bend.
    pub fn reference(test: BeamTest) -> Self {
        let mut c = Self::standard(test, 4);
        c.solver.order = super::ElementOrder::Quadratic;
        c
    }

    /// The mesh: (5r x r x r cubes for the standard size), 6 tets per cube.
    ///
    /// # Errors
    /// [`FemError::Mesh`] for resolution 0.
    pub fn mesh(&self) -> Result<TetMesh, FemError> {
        let r = self.resolution as f64;
        let cells = self.size.map(|s| ((s * r).round() as usize).max(1));
        TetMesh::structured_box([0.0; 3], self.size, cells)
    }

    /// Cache key: FNV-1a 64 of the canonical JSON of (format version, config), as 16 hex
    /// digits, and the JSON itself.
    pub fn cache_key(&self) -> (String, String) {
        let json =
            serde_json::json!({ "format": CACHE_FORMAT_VERSION, "config": self }).to_string();
        (format!("{:016x}", fnv1a(json.as_bytes())), json)
    }
}

/// Where a reference came from.
#[derive(Debug, Clone, PartialEq)]
pub enum CacheStatus {
    /// Computed; no cache directory was given.
    NotCached,
    /// Loaded from this file.
    Hit(PathBuf),
    /// Computed and written to this file (no file existed).
    Written(PathBuf),
    /// A cache file existed but was unusable (the reason); recomputed and rewritten.
    Recomputed {
        /// The file.
        path: PathBuf,
        /// Why it was rejected.
        reason: String,
    },
}

/// A FEM reference trajectory: the beam's ([`run_beam_reference`]) or a real shape's
/// (`benchmark::shapes::reference`). What it was computed from is its cache key, not stored
/// here (a cache file holds only the trajectory).
#[derive(Debug, Clone)]
pub struct BeamReference {
    /// FE node rest positions, N x 3, metres: the mesh nodes, then (quadratic elements)
    /// the edge-midpoint nodes. The reduced map is evaluated at these.
    pub rest: Vec<Point3>,
    /// The mesh's tets, T x 4 indices into the first nodes of `rest` (the corners; for
    /// quadratic elements the edge nodes follow from [`super::element::fe_nodes`]).
    pub tets: Vec<[u32; 4]>,
    /// Node positions after each step, steps x N x 3, metres.
    pub frames: Vec<Vec<Point3>>,
    /// Wall time of each step when it was computed, s (2 cores here; from the cache these
    /// are the original run's times).
    pub step_seconds: Vec<f64>,
    /// Newton iterations of each step.
    pub newton_iterations: Vec<u32>,
    /// Where it came from.
    pub cache: CacheStatus,
}

impl BeamReference {
    /// Mean wall time per step, milliseconds.
    pub fn step_ms_mean(&self) -> f64 {
        1e3 * self.step_seconds.iter().sum::<f64>() / self.step_seconds.len().max(1) as f64
    }

    /// The error metric of `candidate` (frames x N x 3 on this reference's nodes, metres)
    /// against this reference.
    ///
    /// # Errors
    /// [`FemError::Trajectory`] on shape mismatch or non-finite values.
    pub fn error_of(&self, candidate: &[Vec<Point3>]) -> Result<TrajectoryError, FemError> {
        trajectory_error(&self.rest, &self.frames, candidate)
    }
}

/// Run (or load from `cache_dir`) the FEM reference of `config`.
///
/// `progress` gets one unit per step and a warning message when a cache file is rejected.
///
/// # Errors
/// Parameter and mesh errors, solver failures ([`FemError::NotConverged`] with the step),
/// and [`FemError::Io`] when the cache directory cannot be created or written. A corrupt
/// cache file is not an error (see [`CacheStatus::Recomputed`]).
pub fn run_beam_reference(
    config: &FemBeamConfig,
    cache_dir: Option<&Path>,
    progress: &dyn Progress,
) -> crate::Result<BeamReference> {
    let (hash, key) = config.cache_key();
    cached_reference(cache_dir, &hash, &key, progress, || {
        compute(config, progress)
    })
}

/// The FEM reference stored under `key` in `cache_dir/{hash}.bin`, or, when there is none or
/// it is unusable (a warning through `progress`), `compute()`'s, written there. Without a
/// cache directory `compute()` runs and nothing is written. `cache` tells which happened.
///
/// # Errors
/// `compute()`'s errors; [`FemError::Io`] when the cache file cannot be written.
pub(crate) fn cached_reference(
    cache_dir: Option<&Path>,
    hash: &str,
    key: &str,
    progress: &dyn Progress,
    compute: impl FnOnce() -> crate::Result<BeamReference>,
) -> crate::Result<BeamReference> {
    let path = cache_dir.map(|d| d.join(format!("{hash}.bin")));
    let mut rejected = None;
    if let Some(p) = path.as_ref().filter(|p| p.exists()) {
        match read_cache(p, key) {
            Ok(mut r) => {
                r.cache = CacheStatus::Hit(p.clone());
                return Ok(r);
            }
            Err(reason) => {
                progress.message(&format!(
                    "warning: FEM cache {} unusable ({reason}); recomputing",
                    p.display()
                ));
                rejected = Some(reason);
            }
        }
    }
    let mut r = compute()?;
    if let Some(p) = path {
        write_cache(&p, key, &r)?;
        r.cache = match rejected {
            Some(reason) => CacheStatus::Recomputed { path: p, reason },
            None => CacheStatus::Written(p),
        };
    }
    Ok(r)
}

fn compute(config: &FemBeamConfig, progress: &dyn Progress) -> crate::Result<BeamReference> {
    config.material.validate()?;
    if config.steps == 0 {
        return Err(crate::Error::param("steps", 0, "at least one step"));
    }
    let mesh = config.mesh()?;
    let materials = TetMaterials::homogeneous(&mesh, &config.material)?;
    let eps = 1e-9 * config.size[0];
    let (fe, _) = fe_nodes(&mesh, config.solver.order);
    let select = |f: &dyn Fn(&Point3) -> bool| -> Vec<usize> {
        (0..fe.len()).filter(|&i| f(&fe[i])).collect()
    };
    let held = select(&|p| p[0] <= config.held_length + eps);
    let turned = match config.test {
        BeamTest::Bend => Vec::new(),
        BeamTest::Twist => select(&|p| p[0] >= config.size[0] - config.twist_length - eps),
    };
    let mut fixed = held.clone();
    fixed.extend(&turned);
    let mut solver = FemSolver::new(&mesh, &materials, &fixed, config.solver.clone())?;
    let (cy, cz) = (0.5 * config.size[1], 0.5 * config.size[2]);
    let is_turned: Vec<bool> = {
        let mut v = vec![false; fe.len()];
        turned.iter().for_each(|&i| v[i] = true);
        v
    };
    let label = format!("FEM {} r={}", config.test.name(), config.resolution);
    record_trajectory(
        &mut solver,
        &mesh,
        config.steps,
        &label,
        progress,
        |n, rest, fixed| {
            if turned.is_empty() {
                return None;
            }
            let theta = (config.twist_degrees * n as f64 / config.steps as f64).to_radians();
            let (s, c) = theta.sin_cos();
            let targets = fixed
                .iter()
                .map(|&i| {
                    let p = rest[i];
                    if is_turned[i] {
                        let (y, z) = (p[1] - cy, p[2] - cz);
                        [p[0], cy + c * y - s * z, cz + s * y + c * z]
                    } else {
                        p
                    }
                })
                .collect();
            Some(targets)
        },
    )
}

/// How often a reference step that Newton cannot converge is halved before the reference
/// fails ([`FemSolver::step_substepping`]): down to 1/16 of the step.
pub const MAX_HALVINGS: u32 = 4;

/// Step `solver` `steps` times and record the reference: before step n (1-based),
/// `targets(n, rest positions, fixed nodes)` gives the fixed nodes' positions, or None to
/// leave them where they are; every step's positions, wall time and Newton iterations are
/// kept. A step Newton cannot converge is halved, up to [`MAX_HALVINGS`] times (frames stay at
/// the full steps). `label` names the work in `progress`.
pub(crate) fn record_trajectory(
    solver: &mut FemSolver,
    mesh: &TetMesh,
    steps: usize,
    label: &str,
    progress: &dyn Progress,
    mut targets: impl FnMut(usize, &[Point3], &[usize]) -> Option<Vec<Point3>>,
) -> crate::Result<BeamReference> {
    let rest = solver.rest_positions().to_vec();
    let mut frames = Vec::with_capacity(steps);
    let mut step_seconds = Vec::with_capacity(steps);
    let mut newton_iterations = Vec::with_capacity(steps);
    progress.begin(label, Some(steps as u64));
    for n in 1..=steps {
        if let Some(t) = targets(n, &rest, solver.fixed_nodes()) {
            solver.set_targets(&t)?;
        }
        let t0 = Instant::now();
        let info = solver.step_substepping(MAX_HALVINGS)?;
        step_seconds.push(t0.elapsed().as_secs_f64());
        newton_iterations.push(info.newton_iterations as u32);
        frames.push(solver.positions().to_vec());
        progress.set_position(n as u64);
        progress.message(&format!("{} Newton iterations", info.newton_iterations));
    }
    progress.finish();
    Ok(BeamReference {
        rest,
        tets: mesh.tets().to_vec(),
        frames,
        step_seconds,
        newton_iterations,
        cache: CacheStatus::NotCached,
    })
}

/// The trajectory difference between two references on nested meshes (every node of
/// `coarse` is a node of `fine`, as for structured beams at resolutions r and 2r), measured
/// with [`trajectory_error`] on the coarse nodes: the refinement study's error.
///
/// # Errors
/// [`FemError::Trajectory`] when a coarse node has no fine node within 1e-9 D, or the frame
/// counts differ.
pub fn nested_difference(
    coarse: &BeamReference,
    fine: &BeamReference,
) -> Result<TrajectoryError, FemError> {
    let d = crate::geometry::Aabb::from_points(&fine.rest).map_or(1.0, |b| b.diagonal());
    let q = |p: &Point3| p.map(|c| (c / (1e-9 * d)).round() as i64);
    let index: std::collections::HashMap<[i64; 3], usize> = fine
        .rest
        .iter()
        .enumerate()
        .map(|(i, p)| (q(p), i))
        .collect();
    let map: Vec<usize> = coarse
        .rest
        .iter()
        .enumerate()
        .map(|(a, p)| {
            index
                .get(&q(p))
                .copied()
                .ok_or_else(|| FemError::Trajectory {
                    what: "fine",
                    detail: format!("coarse node {a} at {p:?} is not a node of the fine mesh"),
                })
        })
        .collect::<Result<_, _>>()?;
    let fine_on_coarse: Vec<Vec<Point3>> = fine
        .frames
        .iter()
        .map(|f| map.iter().map(|&i| f[i]).collect())
        .collect();
    trajectory_error(&coarse.rest, &fine_on_coarse, &coarse.frames)
}

pub(crate) fn fnv1a(bytes: &[u8]) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for &b in bytes {
        h ^= b as u64;
        h = h.wrapping_mul(0x0000_0100_0000_01b3);
    }
    h
}

const MAGIC: &[u8; 8] = b"FFFEMTRJ";

pub(crate) fn write_cache(path: &Path, key: &str, r: &BeamReference) -> Result<(), FemError> {
    let io = |source| FemError::Io {
        path: path.to_path_buf(),
        source,
    };
    let mut buf: Vec<u8> = Vec::new();
    buf.extend_from_slice(MAGIC);
    buf.extend_from_slice(&CACHE_FORMAT_VERSION.to_le_bytes());
    for v in [key.len(), r.rest.len(), r.tets.len(), r.frames.len()] {
        buf.extend_from_slice(&(v as u64).to_le_bytes());
    }
    buf.extend_from_slice(key.as_bytes());
    for p in r.rest.iter().chain(r.frames.iter().flatten()) {
        for c in p {
            buf.extend_from_slice(&c.to_le_bytes());
        }
    }
    for t in &r.tets {
        for i in t {
            buf.extend_from_slice(&i.to_le_bytes());
        }
    }
    for s in &r.step_seconds {
        buf.extend_from_slice(&s.to_le_bytes());
    }
    for n in &r.newton_iterations {
        buf.extend_from_slice(&n.to_le_bytes());
    }
    let sum = fnv1a(&buf);
    buf.extend_from_slice(&sum.to_le_bytes());
    let dir = path.parent().unwrap_or(Path::new("."));
    std::fs::create_dir_all(dir).map_err(io)?;
    let tmp = path.with_extension(format!("tmp{}", std::process::id()));
    let mut f = std::fs::File::create(&tmp).map_err(io)?;
    f.write_all(&buf).map_err(io)?;
    f.sync_all().map_err(io)?;
    drop(f);
    std::fs::rename(&tmp, path).map_err(io)
}

pub(crate) fn read_cache(path: &Path, key: &str) -> Result<BeamReference, String> {
    let buf = std::fs::read(path).map_err(|e| format!("cannot read: {e}"))?;
    if buf.len() < 8 + 4 + 32 + 8 || &buf[..8] != MAGIC {
        return Err("not a freeform FEM cache file".into());
    }
    let (body, tail) = buf.split_at(buf.len() - 8);
    if fnv1a(body) != u64::from_le_bytes(tail.try_into().unwrap_or_default()) {
        return Err("checksum mismatch (truncated or corrupted)".into());
    }
    let mut at = 8;
    let mut take = |n: usize| -> Result<&[u8], String> {
        let s = body.get(at..at + n).ok_or("file too short")?;
        at += n;
        Ok(s)
    };
    let version = u32::from_le_bytes(take(4)?.try_into().map_err(|_| "short")?);
    if version != CACHE_FORMAT_VERSION {
        return Err(format!(
            "format version {version}, expected {CACHE_FORMAT_VERSION}"
        ));
    }
    let mut dims = [0usize; 4];
    for d in &mut dims {
        *d = u64::from_le_bytes(take(8)?.try_into().map_err(|_| "short")?) as usize;
    }
    let [klen, n, t, f] = dims;
    if take(klen)? != key.as_bytes() {
        return Err("the stored key differs (hash collision or edited file)".into());
    }
    let f64s = |bytes: &[u8]| -> Vec<f64> {
        bytes
            .chunks_exact(8)
            .map(|c| f64::from_le_bytes(c.try_into().unwrap_or_default()))
            .collect()
    };
    let points =
        |v: Vec<f64>| -> Vec<Point3> { v.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect() };
    let size = |a: usize, b: usize| a.checked_mul(b).ok_or("size overflow".to_string());
    let rest = points(f64s(take(size(n, 24)?)?));
    let all = points(f64s(take(size(size(n, f)?, 24)?)?));
    let tets: Vec<[u32; 4]> = take(size(t, 16)?)?
        .chunks_exact(16)
        .map(|c| {
            [0, 1, 2, 3]
                .map(|k| u32::from_le_bytes(c[4 * k..4 * k + 4].try_into().unwrap_or_default()))
        })
        .collect();
    let step_seconds = f64s(take(size(f, 8)?)?);
    let newton_iterations = take(size(f, 4)?)?
        .chunks_exact(4)
        .map(|c| u32::from_le_bytes(c.try_into().unwrap_or_default()))
        .collect();
    if at != body.len() {
        return Err("trailing bytes".into());
    }
    if !all
        .iter()
        .chain(&rest)
        .all(|p| p.iter().all(|c| c.is_finite()))
    {
        return Err("non-finite positions".into());
    }
    let frames = if n == 0 {
        vec![Vec::new(); f]
    } else {
        all.chunks(n).map(|c| c.to_vec()).collect()
    };
    Ok(BeamReference {
        rest,
        tets,
        frames,
        step_seconds,
        newton_iterations,
        cache: CacheStatus::NotCached,
    })
}
