//! The check that an object does not start deep inside a collider: the penalty would push it
//! out over many slow, stiff steps (35 s each in one report) instead of the user moving it.

use crate::sim::collider::{Collider, Obstacle, Sided};
use crate::sim::environment::Environment;
use crate::sim::motion::Rigid;
use crate::{Error, Point3, Result};

/// Deepest start inside a collider, as a fraction of the object's diagonal: a tenth. Less is
/// a contact the penalty resolves in a step or two (a scripted arm that starts touching);
/// more is a misplaced object.
pub const START_DEPTH_FRACTION: f64 = 0.1;

/// Refuse an object whose points `points` (rest coordinates, moved by `placement`; its
/// integration points) start deeper than [`START_DEPTH_FRACTION`] x `diagonal` (metres)
/// inside a solid collider of `env` at t = 0. One-sided mesh surfaces are not checked: what
/// lies behind them is unbounded, and a scene may mean it.
///
/// # Errors
/// [`Error::Collider`] (index and name from `colliders`) around an
/// [`Error::InvalidParameter`] that names the deepest point and the way out.
pub fn check_start_outside_colliders(
    env: &Environment,
    colliders: &[Collider],
    points: &[Point3],
    placement: &Rigid,
    diagonal: f64,
) -> Result<()> {
    let kin = env.kinematics();
    if kin.is_empty() {
        return Ok(());
    }
    let poses = kin.poses(0.0);
    let placed: Vec<Point3> = points.iter().map(|p| placement.apply(p)).collect();
    for (i, (obstacle, pose)) in kin.obstacles().iter().zip(&poses).enumerate() {
        if matches!(obstacle, Obstacle::Mesh(m) if m.sided() == Sided::Outside) {
            continue;
        }
        let deepest = placed
            .iter()
            .filter_map(|x| obstacle.penetration(pose, x).map(|pen| (pen.depth, *x)))
            .max_by(|a, b| a.0.total_cmp(&b.0));
        let limit = START_DEPTH_FRACTION * diagonal;
        if let Some((depth, x)) = deepest.filter(|(d, _)| *d > limit) {
            let e = Error::param(
                "placement",
                format!("{:?}", placement.translation),
                format!(
                    "the object starts inside this {} collider: its point ({:.4}, {:.4}, \
                     {:.4}) m is {depth:.3e} m deep, more than {START_DEPTH_FRACTION} of the \
                     object's diagonal ({limit:.3e} m); move the object out \
                     (placement.translation) or the collider",
                    obstacle.kind(),
                    x[0],
                    x[1],
                    x[2],
                ),
            );
            return Err(match colliders.get(i) {
                Some(c) => c.error(i, e),
                None => e,
            });
        }
    }
    Ok(())
}
