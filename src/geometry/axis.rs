//! The up axis of a USD stage: which coordinate axis points up (USD allows Y and Z).

/// The up axis of a USD stage (`upAxis` metadata). USD allows only Y and Z; a stage that
/// states neither has Y (USD's fallback).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum UpAxis {
    /// +Y is up (USD's fallback, and freeform's examples: gravity along -Y).
    #[default]
    Y,
    /// +Z is up (common in Omniverse and robotics stages).
    Z,
}

impl UpAxis {
    /// The up axis a scene's gravity implies: Z when gravity's largest component is along z,
    /// otherwise (no gravity included) Y.
    pub fn from_gravity(gravity: Option<[f64; 3]>) -> UpAxis {
        match gravity {
            Some(g) if g[2].abs() > g[0].abs() && g[2].abs() > g[1].abs() => UpAxis::Z,
            _ => UpAxis::Y,
        }
    }

    /// The `upAxis` token: `"Y"` or `"Z"`.
    pub fn token(self) -> &'static str {
        match self {
            UpAxis::Y => "Y",
            UpAxis::Z => "Z",
        }
    }

    /// The axis a `upAxis` token names (`"Y"` or `"Z"`, as USD writes them); None otherwise.
    pub fn from_token(token: &str) -> Option<UpAxis> {
        match token {
            "Y" => Some(UpAxis::Y),
            "Z" => Some(UpAxis::Z),
            _ => None,
        }
    }

    /// Point `p` of a frame whose up axis is `self` in a frame whose up axis is `to`: a
    /// rotation by 90 degrees about x (Z-up to Y-up: (x, y, z) -> (x, z, -y)), or `p` itself.
    pub fn convert(self, to: UpAxis, p: [f64; 3]) -> [f64; 3] {
        match (self, to) {
            (UpAxis::Z, UpAxis::Y) => [p[0], p[2], -p[1]],
            (UpAxis::Y, UpAxis::Z) => [p[0], -p[2], p[1]],
            _ => p,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn conversions_take_up_to_up_and_invert_each_other() {
        assert_eq!(
            UpAxis::Z.convert(UpAxis::Y, [0.0, 0.0, 1.0]),
            [0.0, 1.0, 0.0]
        );
        assert_eq!(
            UpAxis::Y.convert(UpAxis::Z, [0.0, 1.0, 0.0]),
            [0.0, 0.0, 1.0]
        );
        let p = [0.3, -1.5, 2.25];
        assert_eq!(
            UpAxis::Y.convert(UpAxis::Z, UpAxis::Z.convert(UpAxis::Y, p)),
            p
        );
        // A rotation keeps handedness: x cross y = z in both frames.
        let (x, y) = ([1.0, 0.0, 0.0], [0.0, 1.0, 0.0]);
        let (cx, cy) = (
            UpAxis::Z.convert(UpAxis::Y, x),
            UpAxis::Z.convert(UpAxis::Y, y),
        );
        let cross = [
            cx[1] * cy[2] - cx[2] * cy[1],
            cx[2] * cy[0] - cx[0] * cy[2],
            cx[0] * cy[1] - cx[1] * cy[0],
        ];
        assert_eq!(cross, UpAxis::Z.convert(UpAxis::Y, [0.0, 0.0, 1.0]));
        assert_eq!(UpAxis::from_gravity(Some([0.0, 0.0, -9.81])), UpAxis::Z);
        assert_eq!(UpAxis::from_gravity(Some([0.0, -9.81, 0.0])), UpAxis::Y);
        assert_eq!(UpAxis::from_gravity(None), UpAxis::Y);
    }
}
