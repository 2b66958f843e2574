//! Prescribed rigid motions for kinematic boundary conditions: x(t) = pivot + R(t)(X - pivot)
//! + translation(t).

use crate::linalg3::Mat3;
use crate::{Error, Point3, Result};
use serde::{Deserialize, Serialize};

/// A rotation given as an axis (need not be unit) and an angle in degrees.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AxisAngle {
    /// Rotation axis (any non-zero length).
    pub axis: [f64; 3],
    /// Angle, degrees, counter-clockwise about the axis.
    pub degrees: f64,
}

/// One keyframe of a keyframed rigid motion.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Keyframe {
    /// Time, seconds.
    pub time: f64,
    /// Translation, metres.
    #[serde(default)]
    pub translation: [f64; 3],
    /// Rotation about the motion's pivot (none: identity).
    #[serde(default)]
    pub rotation: Option<AxisAngle>,
}

/// How a boundary region moves.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub enum Motion {
    /// Held at the rest position.
    Fixed,
    /// Constant velocity, m/s.
    Translate {
        /// Velocity, m/s.
        velocity: [f64; 3],
    },
    /// Rotation about the axis through `pivot` at a constant rate (the twist test:
    /// pivot [0, 0.5, 0.5], axis [1, 0, 0], 360 degrees per second).
    Rotate {
        /// A point on the axis, metres.
        pivot: Point3,
        /// Axis direction (any non-zero length).
        axis: [f64; 3],
        /// Rate, degrees per second.
        degrees_per_second: f64,
    },
    /// Piecewise motion through keyframes (linear translation, spherical-linear rotation
    /// about `pivot`); held at the first keyframe before it and at the last after it.
    Keyframes {
        /// Rotation centre, metres.
        #[serde(default)]
        pivot: Point3,
        /// Keyframes in increasing time.
        frames: Vec<Keyframe>,
    },
    /// Held at one rigid pose x = rotation X + translation (X: the placed rest position),
    /// whatever the time: a target set between steps by a caller (the live API, Python, C).
    Pose {
        /// Proper rotation, row-major (orthonormal, det +1).
        rotation: Mat3,
        /// Translation, metres.
        translation: [f64; 3],
    },
}

/// A rigid transform x -> rotation x + translation.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Rigid {
    /// Rotation matrix, row-major.
    pub rotation: Mat3,
    /// Translation, metres.
    pub translation: [f64; 3],
}

impl Rigid {
    /// The identity.
    pub const IDENTITY: Rigid = Rigid {
        rotation: [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
        translation: [0.0; 3],
    };

    /// The pose given as flat arrays, as the C and Python bindings receive it: `rotation` R,
    /// 9 values row-major (None: the identity); `translation` t, 3 values, metres (None:
    /// zero). Not validated here: [`Rigid::validate`] runs where the pose is used.
    ///
    /// # Errors
    /// [`Error::LengthMismatch`] for a rotation of other than 9 values or a translation of
    /// other than 3.
    pub fn from_arrays(rotation: Option<&[f64]>, translation: Option<&[f64]>) -> Result<Rigid> {
        let mut pose = Rigid::IDENTITY;
        if let Some(r) = rotation {
            if r.len() != 9 {
                return Err(Error::LengthMismatch {
                    what: "rotation (3 x 3, row-major)",
                    expected: 9,
                    got: r.len(),
                });
            }
            for (row, values) in pose.rotation.iter_mut().zip(r.chunks_exact(3)) {
                row.copy_from_slice(values);
            }
        }
        if let Some(t) = translation {
            if t.len() != 3 {
                return Err(Error::LengthMismatch {
                    what: "translation",
                    expected: 3,
                    got: t.len(),
                });
            }
            pose.translation.copy_from_slice(t);
        }
        Ok(pose)
    }

    /// Apply to a point.
    pub fn apply(&self, x: &Point3) -> Point3 {
        let r = &self.rotation;
        std::array::from_fn(|i| {
            r[i][0] * x[0] + r[i][1] * x[1] + r[i][2] * x[2] + self.translation[i]
        })
    }

    /// Check that the values are finite and the rotation is proper (R^T R = I and det R = +1
    /// to 1e-9: rounding of a matrix built in double precision, far below any scaling or
    /// reflection a caller could mean).
    pub fn validate(&self) -> Result<()> {
        let r = &self.rotation;
        let bad = |why: &str| {
            Err(Error::param(
                "pose",
                format!("rotation {r:?}, translation {:?}", self.translation),
                why.to_string(),
            ))
        };
        if !r
            .iter()
            .flatten()
            .chain(&self.translation)
            .all(|v| v.is_finite())
        {
            return bad("the rotation and translation must be finite");
        }
        if !self
            .translation
            .iter()
            .all(|t| t.abs() <= crate::error::MAX_MAGNITUDE)
        {
            return bad("the translation must be at most 1e100 m in magnitude");
        }
        let mut off = 0.0f64;
        for i in 0..3 {
            for j in 0..3 {
                let dot: f64 = (0..3).map(|k| r[k][i] * r[k][j]).sum();
                off = off.max((dot - if i == j { 1.0 } else { 0.0 }).abs());
            }
        }
        if off > 1e-9 || crate::linalg3::det3(r) <= 0.0 {
            return bad(&format!(
                "the rotation must be a proper rotation matrix (orthonormal, det +1; \
                 largest error of R^T R - I: {off:.1e}, det {:.6})",
                crate::linalg3::det3(r)
            ));
        }
        Ok(())
    }

    /// Rotation `r` about `pivot` followed by translation `t`.
    pub fn about(pivot: &Point3, r: Mat3, t: [f64; 3]) -> Rigid {
        let rp = Rigid {
            rotation: r,
            translation: [0.0; 3],
        }
        .apply(pivot);
        Rigid {
            rotation: r,
            translation: std::array::from_fn(|i| pivot[i] - rp[i] + t[i]),
        }
    }
}

fn unit(axis: &[f64; 3], what: &str) -> Result<[f64; 3]> {
    let n = (axis[0] * axis[0] + axis[1] * axis[1] + axis[2] * axis[2]).sqrt();
    if !(n > 0.0 && n.is_finite()) {
        return Err(Error::param(
            "axis",
            format!("{axis:?}"),
            format!("{what}: the rotation axis must be a finite, non-zero vector"),
        ));
    }
    Ok([axis[0] / n, axis[1] / n, axis[2] / n])
}

/// Rotation matrix for `radians` about the unit axis `u` (Rodrigues).
pub fn rotation_matrix(u: &[f64; 3], radians: f64) -> Mat3 {
    let (s, c) = radians.sin_cos();
    let t = 1.0 - c;
    [
        [
            c + u[0] * u[0] * t,
            u[0] * u[1] * t - u[2] * s,
            u[0] * u[2] * t + u[1] * s,
        ],
        [
            u[1] * u[0] * t + u[2] * s,
            c + u[1] * u[1] * t,
            u[1] * u[2] * t - u[0] * s,
        ],
        [
            u[2] * u[0] * t - u[1] * s,
            u[2] * u[1] * t + u[0] * s,
            c + u[2] * u[2] * t,
        ],
    ]
}

/// Unit quaternion (w, x, y, z) of an axis-angle rotation.
fn quaternion(a: &Option<AxisAngle>) -> Result<[f64; 4]> {
    match a {
        None => Ok([1.0, 0.0, 0.0, 0.0]),
        Some(a) => {
            let u = unit(&a.axis, "keyframe rotation")?;
            if !a.degrees.is_finite() {
                return Err(Error::param(
                    "degrees",
                    a.degrees,
                    "keyframe rotation: the angle must be a finite number of degrees",
                ));
            }
            let h = 0.5 * a.degrees.to_radians();
            Ok([h.cos(), u[0] * h.sin(), u[1] * h.sin(), u[2] * h.sin()])
        }
    }
}

fn slerp(a: &[f64; 4], b: &[f64; 4], s: f64) -> [f64; 4] {
    let mut d: f64 = (0..4).map(|i| a[i] * b[i]).sum();
    let mut b = *b;
    if d < 0.0 {
        // Take the short way round.
        d = -d;
        b = b.map(|v| -v);
    }
    let (wa, wb) = if d > 0.9995 {
        (1.0 - s, s)
    } else {
        let th = d.clamp(-1.0, 1.0).acos();
        (((1.0 - s) * th).sin() / th.sin(), (s * th).sin() / th.sin())
    };
    let q: [f64; 4] = std::array::from_fn(|i| wa * a[i] + wb * b[i]);
    let n = (0..4).map(|i| q[i] * q[i]).sum::<f64>().sqrt();
    q.map(|v| v / n)
}

impl Motion {
    /// Check the parameters (finite values, non-zero axes, increasing keyframe times).
    pub fn validate(&self) -> Result<()> {
        let finite = |v: &[f64], what: &str| -> Result<()> {
            if v.iter().all(|x| x.abs() <= crate::error::MAX_MAGNITUDE) {
                Ok(())
            } else {
                Err(Error::param(
                    "motion",
                    format!("{v:?}"),
                    format!("{what} must be finite, at most 1e100 in magnitude"),
                ))
            }
        };
        match self {
            Motion::Fixed => Ok(()),
            Motion::Translate { velocity } => finite(velocity, "velocity"),
            Motion::Rotate {
                pivot,
                axis,
                degrees_per_second,
            } => {
                finite(pivot, "pivot")?;
                finite(&[*degrees_per_second], "degrees_per_second")?;
                unit(axis, "rotate").map(|_| ())
            }
            Motion::Keyframes { pivot, frames } => {
                finite(pivot, "pivot")?;
                if frames.is_empty() {
                    return Err(Error::param(
                        "frames",
                        0,
                        "a keyframed motion needs at least one keyframe",
                    ));
                }
                for (i, k) in frames.iter().enumerate() {
                    finite(&[k.time], "keyframe time")?;
                    finite(&k.translation, "keyframe translation")?;
                    quaternion(&k.rotation)?;
                    if i > 0 && k.time <= frames[i - 1].time {
                        return Err(Error::param(
                            "keyframe time",
                            k.time,
                            format!(
                                "keyframe times must increase: frames[{i}] at {} s follows \
                                 frames[{}] at {} s",
                                k.time,
                                i - 1,
                                frames[i - 1].time
                            ),
                        ));
                    }
                }
                Ok(())
            }
            Motion::Pose { .. } => self.at(0.0).validate(),
        }
    }

    /// The rigid transform at time `t` (seconds). Call [`Motion::validate`] first.
    pub fn at(&self, t: f64) -> Rigid {
        match self {
            Motion::Fixed => Rigid::IDENTITY,
            Motion::Translate { velocity } => Rigid {
                rotation: Rigid::IDENTITY.rotation,
                translation: velocity.map(|v| v * t),
            },
            Motion::Rotate {
                pivot,
                axis,
                degrees_per_second,
            } => {
                let u = unit(axis, "rotate").unwrap_or([1.0, 0.0, 0.0]);
                let r = rotation_matrix(&u, (degrees_per_second * t).to_radians());
                Rigid::about(pivot, r, [0.0; 3])
            }
            Motion::Keyframes { pivot, frames } => {
                let q = |k: &Keyframe| quaternion(&k.rotation).unwrap_or([1.0, 0.0, 0.0, 0.0]);
                let (Some(first), Some(last)) = (frames.first(), frames.last()) else {
                    return Rigid::IDENTITY;
                };
                let (rot, tr) = if t <= first.time {
                    (q(first), first.translation)
                } else if t >= last.time {
                    (q(last), last.translation)
                } else {
                    let i = frames.partition_point(|k| k.time <= t);
                    let (a, b) = (&frames[i - 1], &frames[i]);
                    let s = (t - a.time) / (b.time - a.time);
                    (
                        slerp(&q(a), &q(b), s),
                        std::array::from_fn(|d| {
                            a.translation[d] + s * (b.translation[d] - a.translation[d])
                        }),
                    )
                };
                Rigid::about(pivot, crate::linalg3::quat_to_matrix(&rot), tr)
            }
            Motion::Pose {
                rotation,
                translation,
            } => Rigid {
                rotation: *rotation,
                translation: *translation,
            },
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pose_accepts_proper_rotations_only() {
        let r = rotation_matrix(&[0.0, 0.6, 0.8], 1.234);
        let pose = |rotation: Mat3| Motion::Pose {
            rotation,
            translation: [1.0, 2.0, 3.0],
        };
        pose(r).validate().unwrap();
        assert_eq!(pose(r).at(7.0).apply(&[0.0; 3]), [1.0, 2.0, 3.0]);
        let scaled = r.map(|row| row.map(|v| 1.01 * v));
        let reflected = [r[0], r[1], r[2].map(|v| -v)];
        let mut nan = r;
        nan[1][1] = f64::NAN;
        for bad in [scaled, reflected, nan] {
            let msg = pose(bad).validate().unwrap_err().to_string();
            assert!(msg.contains("rotation"), "{msg}");
        }
    }

    #[test]
    fn a_pose_from_arrays_is_row_major_with_identity_defaults() {
        let r = rotation_matrix(&[0.0, 0.6, 0.8], 1.234);
        let flat: Vec<f64> = r.iter().flatten().copied().collect();
        let pose = Rigid::from_arrays(Some(&flat), Some(&[1.0, 2.0, 3.0])).unwrap();
        assert_eq!(pose.rotation, r);
        assert_eq!(pose.translation, [1.0, 2.0, 3.0]);
        assert_eq!(Rigid::from_arrays(None, None).unwrap(), Rigid::IDENTITY);
        let moved = Rigid::from_arrays(None, Some(&[0.0, 0.0, 1.0])).unwrap();
        assert_eq!(moved.apply(&[1.0, 0.0, 0.0]), [1.0, 0.0, 1.0]);
        for (rotation, translation) in [(Some(&flat[..8]), None), (None, Some(&flat[..2]))] {
            let e = Rigid::from_arrays(rotation, translation).unwrap_err();
            assert!(matches!(e, Error::LengthMismatch { .. }), "{e}");
        }
    }

    #[test]
    fn rotate_turns_about_the_axis() {
        let m = Motion::Rotate {
            pivot: [0.0, 0.5, 0.5],
            axis: [2.0, 0.0, 0.0],
            degrees_per_second: 360.0,
        };
        m.validate().unwrap();
        // A quarter second: 90 degrees about x through (., 0.5, 0.5).
        let x = m.at(0.25).apply(&[3.0, 1.0, 0.5]);
        for (a, b) in x.iter().zip([3.0, 0.5, 1.0]) {
            assert!((a - b).abs() < 1e-14, "{x:?}");
        }
        // Points on the axis do not move, at any time.
        let y = m.at(1.7).apply(&[4.0, 0.5, 0.5]);
        assert!((y[1] - 0.5).abs() < 1e-14 && (y[2] - 0.5).abs() < 1e-14);
    }

    #[test]
    fn keyframes_interpolate_and_clamp() {
        let m = Motion::Keyframes {
            pivot: [0.0; 3],
            frames: vec![
                Keyframe {
                    time: 0.0,
                    translation: [0.0; 3],
                    rotation: None,
                },
                Keyframe {
                    time: 1.0,
                    translation: [2.0, 0.0, 0.0],
                    rotation: Some(AxisAngle {
                        axis: [0.0, 0.0, 1.0],
                        degrees: 90.0,
                    }),
                },
            ],
        };
        m.validate().unwrap();
        // Halfway: translation 1, rotation 45 degrees.
        let x = m.at(0.5).apply(&[1.0, 0.0, 0.0]);
        let h = std::f64::consts::FRAC_1_SQRT_2;
        assert!((x[0] - (1.0 + h)).abs() < 1e-12 && (x[1] - h).abs() < 1e-12);
        // After the last keyframe the motion holds.
        assert_eq!(m.at(5.0), m.at(1.0));
        let bad = Motion::Keyframes {
            pivot: [0.0; 3],
            frames: vec![
                Keyframe {
                    time: 1.0,
                    translation: [0.0; 3],
                    rotation: None,
                },
                Keyframe {
                    time: 1.0,
                    translation: [0.0; 3],
                    rotation: None,
                },
            ],
        };
        assert!(bad.validate().unwrap_err().to_string().contains("increase"));
    }

    #[test]
    fn a_keyframe_angle_that_is_not_finite_is_refused() {
        for degrees in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
            let m = Motion::Keyframes {
                pivot: [0.0; 3],
                frames: vec![Keyframe {
                    time: 0.0,
                    translation: [0.0; 3],
                    rotation: Some(AxisAngle {
                        axis: [0.0, 0.0, 1.0],
                        degrees,
                    }),
                }],
            };
            let e = m.validate().unwrap_err();
            assert!(e.to_string().contains("degrees"), "{e}");
        }
    }
}
