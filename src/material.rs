//! Material fields: Young's modulus E (Pa), Poisson ratio nu (-) and density rho (kg/m^3) per
//! integration point, with the Lame parameters
//!
//! ```text
//! lambda = E nu / ((1 + nu)(1 - 2 nu)),   mu = E / (2 (1 + nu))
//! ```
//!
//! Homogeneous by default; heterogeneous through region overrides (later overrides win) or
//! per-point arrays.

use crate::{Error, Point3, Result};
use serde::{Deserialize, Serialize};

/// One isotropic material. In scene files a missing field takes the default's value.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Material {
    /// Young's modulus E, Pa (> 0).
    pub youngs: f64,
    /// Poisson ratio nu, dimensionless, in (-1, 0.5).
    pub poisson: f64,
    /// Density rho, kg/m^3 (> 0).
    pub density: f64,
}

impl Default for Material {
    /// The standard beam's material (design.md section 3): E = 5e6 Pa, nu = 0.45,
    /// rho = 1000 kg/m^3 (a soft rubber).
    fn default() -> Self {
        Self {
            youngs: 5e6,
            poisson: 0.45,
            density: 1000.0,
        }
    }
}

impl Material {
    /// Check E > 0, -1 < nu < 0.5, rho > 0, all finite.
    pub fn validate(&self) -> Result<()> {
        if !(self.youngs > 0.0 && crate::error::in_range(self.youngs)) {
            return Err(Error::param(
                "youngs",
                self.youngs,
                "Young's modulus must be a positive number of pascals, at most 1e100 \
                 (are the units Pa?)",
            ));
        }
        if !(self.poisson > -1.0 && self.poisson < 0.5) {
            return Err(Error::param(
                "poisson",
                self.poisson,
                "Poisson ratio must lie in (-1, 0.5); 0.5 (exactly incompressible) is not representable",
            ));
        }
        if !(self.density > 0.0 && crate::error::in_range(self.density)) {
            return Err(Error::param(
                "density",
                self.density,
                "density must be a positive number of kg/m^3, between 1e-100 and 1e100 \
                 (are the units kg/m^3?)",
            ));
        }
        Ok(())
    }

    /// Lame parameters (lambda, mu), Pa.
    pub fn lame(&self) -> (f64, f64) {
        lame(self.youngs, self.poisson)
    }
}

/// Lame parameters (lambda, mu) in Pa from E (Pa) and nu.
pub fn lame(youngs: f64, poisson: f64) -> (f64, f64) {
    let mu = youngs / (2.0 * (1.0 + poisson));
    let lambda = youngs * poisson / ((1.0 + poisson) * (1.0 - 2.0 * poisson));
    (lambda, mu)
}

/// A region of space that selects integration points.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub enum Region {
    /// Axis-aligned box [min, max], metres.
    Box {
        /// Lower corner.
        min: Point3,
        /// Upper corner.
        max: Point3,
    },
    /// Ball of `radius` around `center`, metres.
    Sphere {
        /// Centre.
        center: Point3,
        /// Radius.
        radius: f64,
    },
    /// Points X with (X - point) . normal >= 0.
    HalfSpace {
        /// A point on the plane.
        point: Point3,
        /// Normal pointing into the selected side (need not be unit).
        normal: Point3,
    },
}

impl Region {
    /// Check the region's numbers: no NaN anywhere; a box needs `min <= max` on every axis
    /// (infinite bounds are fine: half-open slabs); a sphere a positive radius; a half-space a
    /// finite point and a finite non-zero normal.
    ///
    /// # Errors
    /// [`Error::InvalidParameter`] naming the region and what to fix.
    pub fn validate(&self) -> Result<()> {
        let ok = match self {
            Region::Box { min, max } => (0..3).all(|d| min[d] <= max[d]),
            Region::Sphere { center, radius } => {
                center.iter().all(|c| c.is_finite()) && *radius > 0.0
            }
            Region::HalfSpace { point, normal } => {
                point.iter().all(|c| c.is_finite())
                    && normal.iter().all(|c| c.is_finite())
                    && normal.iter().any(|&c| c != 0.0)
            }
        };
        if ok {
            Ok(())
        } else {
            Err(Error::param(
                "region",
                format!("{self:?}"),
                "a box needs min <= max on every axis, a sphere a finite centre and a positive \
                 radius, a half-space a finite point and a finite non-zero normal (no NaN)",
            ))
        }
    }

    /// Whether `x` lies in the region (boundary included).
    pub fn contains(&self, x: &Point3) -> bool {
        match self {
            Region::Box { min, max } => (0..3).all(|d| x[d] >= min[d] && x[d] <= max[d]),
            Region::Sphere { center, radius } => {
                let d: f64 = (0..3).map(|i| (x[i] - center[i]).powi(2)).sum();
                d <= radius * radius
            }
            Region::HalfSpace { point, normal } => {
                (0..3).map(|i| (x[i] - point[i]) * normal[i]).sum::<f64>() >= 0.0
            }
        }
    }
}

impl std::str::FromStr for Region {
    type Err = Error;

    /// `box:X0,Y0,Z0,X1,Y1,Z1` (corners), `sphere:CX,CY,CZ,R` or
    /// `halfspace:PX,PY,PZ,NX,NY,NZ` (a point on the plane and the normal pointing into the
    /// region), metres; validated.
    fn from_str(spec: &str) -> Result<Self> {
        let bad = |why: String| {
            Error::param(
                "region",
                spec,
                format!(
                    "{why}; expected box:X0,Y0,Z0,X1,Y1,Z1, sphere:CX,CY,CZ,R or \
                     halfspace:PX,PY,PZ,NX,NY,NZ (metres)"
                ),
            )
        };
        let (kind, rest) = spec
            .split_once(':')
            .ok_or_else(|| bad("no kind before ':'".into()))?;
        let v: Vec<f64> = rest
            .split(',')
            .map(|t| t.trim().parse::<f64>())
            .collect::<std::result::Result<_, _>>()
            .map_err(|e| bad(format!("not a number list ({e})")))?;
        let need = |n: usize| {
            if v.len() == n {
                Ok(())
            } else {
                Err(bad(format!("{} numbers, need {n}", v.len())))
            }
        };
        let region = match kind.trim().to_ascii_lowercase().as_str() {
            "box" => {
                need(6)?;
                Region::Box {
                    min: [v[0], v[1], v[2]],
                    max: [v[3], v[4], v[5]],
                }
            }
            "sphere" => {
                need(4)?;
                Region::Sphere {
                    center: [v[0], v[1], v[2]],
                    radius: v[3],
                }
            }
            "halfspace" => {
                need(6)?;
                Region::HalfSpace {
                    point: [v[0], v[1], v[2]],
                    normal: [v[3], v[4], v[5]],
                }
            }
            other => return Err(bad(format!("unknown kind '{other}'"))),
        };
        region.validate()?;
        Ok(region)
    }
}

/// A material that applies inside a region.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MaterialOverride {
    /// Where it applies.
    pub region: Region,
    /// What applies there.
    pub material: Material,
}

/// Per-point material values, N each.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct MaterialField {
    /// Young's modulus per point, Pa.
    pub youngs: Vec<f64>,
    /// Poisson ratio per point.
    pub poisson: Vec<f64>,
    /// Density per point, kg/m^3.
    pub density: Vec<f64>,
}

impl MaterialField {
    /// The same material at `n` points.
    pub fn homogeneous(n: usize, m: &Material) -> Result<Self> {
        m.validate()?;
        Ok(Self {
            youngs: vec![m.youngs; n],
            poisson: vec![m.poisson; n],
            density: vec![m.density; n],
        })
    }

    /// `base` everywhere, then each override in order on the points inside its region.
    pub fn from_regions(
        points: &[Point3],
        base: &Material,
        overrides: &[MaterialOverride],
    ) -> Result<Self> {
        let mut f = Self::homogeneous(points.len(), base)?;
        f.apply_overrides(points, overrides)?;
        Ok(f)
    }

    /// Each override in order on the points (N x 3, metres, one per entry) inside its region.
    pub fn apply_overrides(
        &mut self,
        points: &[Point3],
        overrides: &[MaterialOverride],
    ) -> Result<()> {
        if points.len() != self.len() {
            return Err(Error::LengthMismatch {
                what: "material override points",
                expected: self.len(),
                got: points.len(),
            });
        }
        for o in overrides {
            o.material.validate()?;
            for (i, x) in points.iter().enumerate() {
                if o.region.contains(x) {
                    self.youngs[i] = o.material.youngs;
                    self.poisson[i] = o.material.poisson;
                    self.density[i] = o.material.density;
                }
            }
        }
        Ok(())
    }

    /// Per-point arrays from code (each of length n); every entry is validated.
    pub fn from_arrays(youngs: Vec<f64>, poisson: Vec<f64>, density: Vec<f64>) -> Result<Self> {
        let n = youngs.len();
        for (what, len) in [("poisson", poisson.len()), ("density", density.len())] {
            if len != n {
                return Err(Error::LengthMismatch {
                    what,
                    expected: n,
                    got: len,
                });
            }
        }
        for i in 0..n {
            Material {
                youngs: youngs[i],
                poisson: poisson[i],
                density: density[i],
            }
            .validate()
            .map_err(|e| Error::param("material", format!("point {i}"), e.to_string()))?;
        }
        Ok(Self {
            youngs,
            poisson,
            density,
        })
    }

    /// Number of points.
    pub fn len(&self) -> usize {
        self.youngs.len()
    }

    /// True when empty.
    pub fn is_empty(&self) -> bool {
        self.youngs.is_empty()
    }

    /// Lame parameters (lambda, mu) at point i, Pa.
    pub fn lame(&self, i: usize) -> (f64, f64) {
        lame(self.youngs[i], self.poisson[i])
    }

    /// Weight of the weight-space Hessian (Prop. 1) per point: lambda + 4 mu, Pa.
    pub fn hessian_weights(&self) -> Vec<f64> {
        (0..self.len())
            .map(|i| {
                let (l, m) = self.lame(i);
                l + 4.0 * m
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lame_formulas() {
        // E = 5e6, nu = 0.45: mu = 5e6 / 2.9, lambda = 5e6 * 0.45 / (1.45 * 0.1).
        let (l, m) = Material::default().lame();
        assert!((m - 1_724_137.931_034_482_8).abs() < 1e-6);
        assert!((l - 15_517_241.379_310_345).abs() < 1e-5);
        // nu = 0: lambda = 0, mu = E / 2.
        assert_eq!(lame(2.0, 0.0), (0.0, 1.0));
    }

    #[test]
    fn validation() {
        let ok = Material::default();
        assert!(ok.validate().is_ok());
        for bad in [
            Material { youngs: 0.0, ..ok },
            Material { youngs: -1.0, ..ok },
            Material {
                youngs: f64::NAN,
                ..ok
            },
            Material { poisson: 0.5, ..ok },
            Material {
                poisson: -1.0,
                ..ok
            },
            Material { density: 0.0, ..ok },
        ] {
            assert!(bad.validate().is_err(), "{bad:?}");
        }
    }

    #[test]
    fn regions_override_in_order() {
        let pts = vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [2.0, 0.0, 0.0]];
        let stiff = Material {
            youngs: 1e9,
            ..Material::default()
        };
        let soft = Material {
            youngs: 1e3,
            ..Material::default()
        };
        let f = MaterialField::from_regions(
            &pts,
            &Material::default(),
            &[
                MaterialOverride {
                    region: Region::HalfSpace {
                        point: [0.5, 0.0, 0.0],
                        normal: [1.0, 0.0, 0.0],
                    },
                    material: stiff,
                },
                MaterialOverride {
                    region: Region::Sphere {
                        center: [2.0, 0.0, 0.0],
                        radius: 0.1,
                    },
                    material: soft,
                },
            ],
        )
        .unwrap();
        assert_eq!(f.youngs, vec![5e6, 1e9, 1e3]);
        assert!(MaterialField::from_arrays(vec![1.0], vec![0.3, 0.3], vec![1.0]).is_err());
        assert!(MaterialField::from_arrays(vec![1.0], vec![0.7], vec![1.0]).is_err());
    }
}
