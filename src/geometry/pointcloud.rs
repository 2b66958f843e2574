//! Point clouds (scans, Gaussian splat centres): points without connectivity.

use super::{Aabb, GeometryError};
use crate::Point3;

/// A non-empty set of points with finite coordinates (duplicates allowed). It has a bounding
/// box but no volume and no inside test: the sampling stage uses the points themselves.
#[derive(Debug, Clone, PartialEq)]
pub struct PointCloud {
    points: Vec<Point3>,
    aabb: Aabb,
}

impl PointCloud {
    /// Validate `points` (N x 3, metres).
    ///
    /// # Errors
    /// [`GeometryError::Degenerate`] if `points` is empty or has a NaN or infinite coordinate.
    pub fn new(points: Vec<Point3>) -> Result<PointCloud, GeometryError> {
        if let Some(i) = points.iter().position(|p| !p.iter().all(|c| c.is_finite())) {
            return Err(GeometryError::Degenerate(format!(
                "point {i} has a non-finite coordinate {:?}",
                points[i]
            )));
        }
        let aabb = Aabb::from_points(&points)
            .ok_or_else(|| GeometryError::Degenerate("point cloud has no points".into()))?;
        Ok(PointCloud { points, aabb })
    }

    /// The points, N x 3, metres.
    pub fn points(&self) -> &[Point3] {
        &self.points
    }

    /// Number of points (at least 1).
    pub fn len(&self) -> usize {
        self.points.len()
    }

    /// Always false (a point cloud has at least one point); present for API symmetry.
    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }

    /// Bounding box of the points, metres.
    pub fn bounding_box(&self) -> Aabb {
        self.aabb
    }

    /// Give back the points, N x 3, metres.
    pub fn into_points(self) -> Vec<Point3> {
        self.points
    }
}
