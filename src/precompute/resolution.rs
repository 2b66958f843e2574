//! How dense the integration points are: a leaf both `options` (the [`super::BasisOptions`]
//! fields) and `sampling` (which reads them) import; re-exported as
//! `precompute::sampling::{Resolution, CloudVolumeOptions}`.

use crate::{Error, Result};

/// How dense the integration grid is.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Resolution {
    /// Grid spacing h, metres.
    Spacing(f64),
    /// Target number of points inside the object (the grid spacing follows from the volume).
    Count(usize),
}

impl Resolution {
    /// Grid spacing for an object of volume `volume` (m^3).
    pub fn spacing(&self, volume: f64) -> Result<f64> {
        let h = match *self {
            Resolution::Spacing(h) => h,
            Resolution::Count(n) => {
                if n == 0 {
                    return Err(Error::param(
                        "points",
                        0,
                        "need at least one integration point",
                    ));
                }
                (volume / n as f64).cbrt()
            }
        };
        if !(h.is_finite() && h > 0.0) {
            return Err(Error::param(
                "spacing",
                h,
                "grid spacing must be a positive length",
            ));
        }
        Ok(h)
    }
}

/// Options for point-cloud quadrature weights.
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct CloudVolumeOptions {
    /// Voxel edge, metres. Default: 2 x the median nearest-neighbour distance (over up to
    /// 20,000 sampled points), so a voxel holds a handful of points where the cloud is solid.
    pub voxel: Option<f64>,
    /// Total volume of the object, m^3, if known; the weights are scaled to sum to it.
    pub total_volume: Option<f64>,
}
