//! The error metric between a trajectory and a reference trajectory (design.md section 3).
//!
//! Both trajectories are node positions per frame, frames x nodes x 3 (metres), on the same
//! nodes in the same order: for the reduced model, its deformation map evaluated at the
//! reference (FEM) nodes' rest positions. With D the diagonal of the rest bounding box:
//!
//! ```text
//! normalized MSE = mean over frames f and nodes a of |x_f,a - x_ref,f,a|^2 / D^2
//! max error      = max  over frames f and nodes a of |x_f,a - x_ref,f,a|   / D
//! ```

use super::FemError;
use crate::geometry::Aabb;
use crate::Point3;
use serde::{Deserialize, Serialize};

/// Errors of a trajectory against a reference, with where the largest one occurs.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct TrajectoryError {
    /// mean |x - x_ref|^2 / D^2 over frames and nodes (dimensionless).
    pub normalized_mse: f64,
    /// max |x - x_ref| / D over frames and nodes (dimensionless).
    pub max_error: f64,
    /// D, the rest bounding-box diagonal, metres.
    pub diagonal: f64,
    /// Frames compared.
    pub frames: usize,
    /// Nodes per frame.
    pub nodes: usize,
    /// Frame (0-based) of the largest error.
    pub worst_frame: usize,
    /// Node (0-based) of the largest error.
    pub worst_node: usize,
}

/// Compare `candidate` against `reference`, both frames x nodes positions (metres), on nodes
/// whose rest positions are `rest` (nodes x 3, metres; they give D).
///
/// # Errors
/// [`FemError::Trajectory`] when there are no frames or nodes, the frame counts differ, a
/// frame does not have one position per rest node, D is zero, or any value is not finite
/// (the message names the input, frame and node).
pub fn trajectory_error(
    rest: &[Point3],
    reference: &[Vec<Point3>],
    candidate: &[Vec<Point3>],
) -> Result<TrajectoryError, FemError> {
    let bad = |what: &'static str, detail: String| FemError::Trajectory { what, detail };
    let n = rest.len();
    if n == 0 {
        return Err(bad("rest", "no nodes".into()));
    }
    if let Some(a) = rest.iter().position(|p| !p.iter().all(|c| c.is_finite())) {
        return Err(bad(
            "rest",
            format!("node {a} is not finite: {:?}", rest[a]),
        ));
    }
    if reference.is_empty() {
        return Err(bad("reference", "no frames".into()));
    }
    if candidate.len() != reference.len() {
        return Err(bad(
            "candidate",
            format!(
                "{} frames, but the reference has {}",
                candidate.len(),
                reference.len()
            ),
        ));
    }
    for (what, traj) in [("reference", reference), ("candidate", candidate)] {
        for (f, frame) in traj.iter().enumerate() {
            if frame.len() != n {
                return Err(bad(
                    what,
                    format!(
                        "frame {f} has {} nodes, expected {n} (one per rest node)",
                        frame.len()
                    ),
                ));
            }
            if let Some(a) = frame.iter().position(|p| !p.iter().all(|c| c.is_finite())) {
                return Err(bad(
                    what,
                    format!("frame {f}, node {a} is not finite: {:?}", frame[a]),
                ));
            }
        }
    }
    let diagonal = Aabb::from_points(rest).map_or(0.0, |b| b.diagonal());
    if diagonal <= 0.0 {
        return Err(bad(
            "rest",
            "all rest nodes coincide: the bounding-box diagonal is 0".into(),
        ));
    }
    let (mut sum, mut worst, mut worst_frame, mut worst_node) = (0.0, -1.0, 0, 0);
    for (f, (r, c)) in reference.iter().zip(candidate).enumerate() {
        // Per-frame sums keep the accumulation error small for long runs.
        let mut frame_sum = 0.0;
        for (a, (p, q)) in r.iter().zip(c).enumerate() {
            let d2: f64 = (0..3).map(|k| (p[k] - q[k]).powi(2)).sum();
            frame_sum += d2;
            if d2 > worst {
                (worst, worst_frame, worst_node) = (d2, f, a);
            }
        }
        sum += frame_sum;
    }
    let count = (reference.len() * n) as f64;
    Ok(TrajectoryError {
        normalized_mse: sum / count / (diagonal * diagonal),
        max_error: worst.sqrt() / diagonal,
        diagonal,
        frames: reference.len(),
        nodes: n,
        worst_frame,
        worst_node,
    })
}
