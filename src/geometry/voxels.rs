//! A 3D voxel image used as a shape and as a material map: integer labels or Young's moduli
//! on a regular, axis-aligned grid.
//!
//! Voxel `[i, j, k]` has its centre at `origin + [i, j, k] * spacing` and covers the cell of
//! half a spacing either side of it, so a point belongs to the voxel whose centre is nearest
//! (the cells tile space; a point on a shared face goes to the higher index). A voxel is
//! *filled* when its label is not 0 or its modulus is > 0; the filled voxels are the object
//! when the image is the shape.

use super::{Aabb, GeometryError};
use crate::Point3;
use rayon::prelude::*;

/// Most voxels an image may have: 2^31 (a 1290^3 image; 17 GB as f64 moduli), far above the
/// ~1e7-voxel CT volumes this is for. A larger header is a damaged file, refused before any
/// allocation.
pub const MAX_VOXELS: usize = 1 << 31;

/// What an image stores per voxel.
#[derive(Debug, Clone, PartialEq)]
pub enum VoxelValues {
    /// Material labels; 0 is empty (outside the object).
    Labels(Vec<i64>),
    /// Young's modulus per voxel, Pa; 0 is empty, otherwise > 0 and finite.
    Moduli(Vec<f64>),
}

impl VoxelValues {
    /// Number of voxels.
    pub fn len(&self) -> usize {
        match self {
            VoxelValues::Labels(v) => v.len(),
            VoxelValues::Moduli(v) => v.len(),
        }
    }

    /// True when there are no voxels.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// "labels" or "moduli", for messages.
    pub fn kind(&self) -> &'static str {
        match self {
            VoxelValues::Labels(_) => "labels",
            VoxelValues::Moduli(_) => "moduli",
        }
    }
}

/// A validated voxel image. Voxels are stored x fastest: voxel `[i, j, k]` is entry
/// `i + nx (j + ny k)` (NIfTI's order).
#[derive(Debug, Clone, PartialEq)]
pub struct VoxelImage {
    dims: [usize; 3],
    spacing: [f64; 3],
    origin: Point3,
    values: VoxelValues,
    filled: usize,
    /// Index bounds (inclusive) of the filled voxels.
    filled_min: [usize; 3],
    filled_max: [usize; 3],
}

impl VoxelImage {
    /// An image of `dims` = [nx, ny, nz] voxels, `spacing` (metres, > 0 per axis), `origin`
    /// (the centre of voxel [0, 0, 0], metres) and `values` (nx ny nz entries, x fastest).
    ///
    /// # Errors
    /// [`GeometryError::ImageSpacing`] for zero, negative or non-finite spacing or a
    /// non-finite origin; [`GeometryError::ImageVoxel`] naming the first voxel with a NaN,
    /// infinite or negative modulus; [`GeometryError::BadImage`] for a zero dimension, a
    /// length that disagrees with `dims`, more than [`MAX_VOXELS`] voxels, or no filled voxel.
    pub fn new(
        dims: [usize; 3],
        spacing: [f64; 3],
        origin: Point3,
        values: VoxelValues,
    ) -> Result<Self, GeometryError> {
        if !spacing
            .iter()
            .all(|s| *s > 0.0 && crate::error::in_range(*s))
            || !origin
                .iter()
                .all(|o| o.abs() <= crate::error::MAX_MAGNITUDE)
        {
            return Err(GeometryError::ImageSpacing { spacing, origin });
        }
        let count = dims
            .iter()
            .try_fold(1usize, |acc, &d| acc.checked_mul(d))
            .filter(|&n| n <= MAX_VOXELS);
        let Some(count) = count else {
            return Err(GeometryError::BadImage(format!(
                "{dims:?} voxels is more than {MAX_VOXELS}; crop or downsample the image"
            )));
        };
        if count == 0 {
            return Err(GeometryError::BadImage(format!(
                "the image has dimensions {dims:?}: it has no voxels"
            )));
        }
        if values.len() != count {
            return Err(GeometryError::BadImage(format!(
                "dimensions {dims:?} need {count} voxel values, got {}",
                values.len()
            )));
        }
        let ijk = |n: usize| {
            [
                n % dims[0],
                (n / dims[0]) % dims[1],
                n / (dims[0] * dims[1]),
            ]
        };
        if let VoxelValues::Moduli(e) = &values {
            if let Some(n) = e
                .iter()
                .position(|v| !(v.is_finite() && (0.0..=1e100).contains(v)))
            {
                return Err(GeometryError::ImageVoxel {
                    voxel: ijk(n),
                    value: e[n],
                });
            }
        }
        let mut image = Self {
            dims,
            spacing,
            origin,
            values,
            filled: 0,
            filled_min: [usize::MAX; 3],
            filled_max: [0; 3],
        };
        for n in 0..count {
            if image.is_filled(n) {
                image.filled += 1;
                let v = ijk(n);
                for a in 0..3 {
                    image.filled_min[a] = image.filled_min[a].min(v[a]);
                    image.filled_max[a] = image.filled_max[a].max(v[a]);
                }
            }
        }
        if image.filled == 0 {
            return Err(GeometryError::BadImage(format!(
                "the {dims:?} image has no filled voxel (every {} is 0): it describes no object",
                if image.values.kind() == "labels" {
                    "label"
                } else {
                    "modulus"
                }
            )));
        }
        Ok(image)
    }

    /// Voxels per axis, [nx, ny, nz].
    pub fn dims(&self) -> [usize; 3] {
        self.dims
    }

    /// Voxel edge per axis, metres.
    pub fn spacing(&self) -> [f64; 3] {
        self.spacing
    }

    /// Centre of voxel [0, 0, 0], metres.
    pub fn origin(&self) -> Point3 {
        self.origin
    }

    /// The voxel values (x fastest).
    pub fn values(&self) -> &VoxelValues {
        &self.values
    }

    /// Number of filled voxels.
    pub fn filled_count(&self) -> usize {
        self.filled
    }

    /// Volume of one voxel, m^3.
    pub fn voxel_volume(&self) -> f64 {
        self.spacing.iter().product()
    }

    /// The [i, j, k] of flat voxel index `n`.
    pub fn ijk(&self, n: usize) -> [usize; 3] {
        let d = self.dims;
        [n % d[0], (n / d[0]) % d[1], n / (d[0] * d[1])]
    }

    /// The flat index of voxel [i, j, k] (which must be inside the image).
    pub fn index(&self, v: [usize; 3]) -> usize {
        v[0] + self.dims[0] * (v[1] + self.dims[1] * v[2])
    }

    /// Whether flat voxel `n` is filled (label != 0 or modulus > 0).
    pub fn is_filled(&self, n: usize) -> bool {
        match &self.values {
            VoxelValues::Labels(l) => l[n] != 0,
            VoxelValues::Moduli(e) => e[n] > 0.0,
        }
    }

    /// The flat index of the voxel whose centre is nearest `x` (metres), `None` outside the
    /// image or for a NaN coordinate.
    pub fn voxel_at(&self, x: &Point3) -> Option<usize> {
        let mut v = [0usize; 3];
        for a in 0..3 {
            // Cell i covers [origin + (i - 1/2) s, origin + (i + 1/2) s).
            let t = ((x[a] - self.origin[a]) / self.spacing[a] + 0.5).floor();
            if !(t >= 0.0 && t < self.dims[a] as f64) {
                return None;
            }
            v[a] = t as usize;
        }
        Some(self.index(v))
    }

    /// The box of the filled voxels' cells, metres.
    pub fn bounding_box(&self) -> Aabb {
        let mut b = Aabb {
            min: [0.0; 3],
            max: [0.0; 3],
        };
        for a in 0..3 {
            let s = self.spacing[a];
            b.min[a] = self.origin[a] + (self.filled_min[a] as f64 - 0.5) * s;
            b.max[a] = self.origin[a] + (self.filled_max[a] as f64 + 0.5) * s;
        }
        b
    }

    /// Volume of the filled voxels, m^3.
    pub fn volume(&self) -> f64 {
        self.filled as f64 * self.voxel_volume()
    }

    /// Whether each of `points` (N x 3, metres) falls in a filled voxel; rayon-parallel.
    pub fn contains(&self, points: &[Point3]) -> Vec<bool> {
        points
            .par_iter()
            .map(|p| self.voxel_at(p).is_some_and(|n| self.is_filled(n)))
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn labels(dims: [usize; 3], f: impl Fn(usize, usize, usize) -> i64) -> VoxelValues {
        let mut v = Vec::new();
        for k in 0..dims[2] {
            for j in 0..dims[1] {
                for i in 0..dims[0] {
                    v.push(f(i, j, k));
                }
            }
        }
        VoxelValues::Labels(v)
    }

    #[test]
    fn nearest_voxel_and_bounds() {
        let img = VoxelImage::new(
            [4, 3, 2],
            [0.5, 1.0, 2.0],
            [1.0, 0.0, -1.0],
            labels([4, 3, 2], |i, j, _| i64::from(i >= 1 && j == 2)),
        )
        .unwrap();
        // Centre of voxel [2, 1, 1] and a point a hair off it.
        assert_eq!(img.voxel_at(&[2.0, 1.0, 1.0]), Some(img.index([2, 1, 1])));
        assert_eq!(img.voxel_at(&[2.2, 1.4, 1.9]), Some(img.index([2, 1, 1])));
        // Cell faces: x = 1.25 is the face between voxels 0 and 1; it goes to 1.
        assert_eq!(img.voxel_at(&[1.25, 0.0, -1.0]), Some(img.index([1, 0, 0])));
        // Outside: below the first cell, beyond the last, NaN.
        assert_eq!(img.voxel_at(&[0.74, 0.0, -1.0]), None);
        assert_eq!(img.voxel_at(&[2.75, 0.0, -1.0]), None);
        assert_eq!(img.voxel_at(&[f64::NAN, 0.0, -1.0]), None);
        assert_eq!(img.ijk(img.index([3, 2, 1])), [3, 2, 1]);
        // Filled: i in 1..=3, j = 2, both k: 3 * 2 voxels of 1 m^3.
        assert_eq!(img.filled_count(), 6);
        assert_eq!(img.volume(), 6.0);
        let b = img.bounding_box();
        assert_eq!(b.min, [1.25, 1.5, -2.0]);
        assert_eq!(b.max, [2.75, 2.5, 2.0]);
        assert_eq!(
            img.contains(&[[2.0, 2.0, 0.0], [2.0, 1.0, 0.0], [9.0, 2.0, 0.0]]),
            vec![true, false, false]
        );
    }

    #[test]
    fn bad_images_are_named() {
        let ok = |n| VoxelValues::Labels(vec![1; n]);
        for s in [[0.0, 1.0, 1.0], [1.0, -1.0, 1.0], [1.0, 1.0, f64::NAN]] {
            assert!(matches!(
                VoxelImage::new([1, 1, 1], s, [0.0; 3], ok(1)),
                Err(GeometryError::ImageSpacing { .. })
            ));
        }
        let e = VoxelImage::new([2, 2, 1], [1.0; 3], [0.0; 3], ok(3)).unwrap_err();
        assert!(e.to_string().contains("need 4 voxel values, got 3"), "{e}");
        let e = VoxelImage::new([0, 2, 1], [1.0; 3], [0.0; 3], ok(0)).unwrap_err();
        assert!(e.to_string().contains("no voxels"), "{e}");
        let e = VoxelImage::new(
            [2, 1, 1],
            [1.0; 3],
            [0.0; 3],
            VoxelValues::Labels(vec![0; 2]),
        )
        .unwrap_err();
        assert!(e.to_string().contains("no filled voxel"), "{e}");
        let e = VoxelImage::new(
            [2, 2, 1],
            [1.0; 3],
            [0.0; 3],
            VoxelValues::Moduli(vec![1.0, 1.0, 1.0, -3.0]),
        )
        .unwrap_err();
        assert!(e.to_string().contains("voxel [1, 1, 0]"), "{e}");
        // A modulus of 1e300 (H would overflow): named, in scientific notation.
        let e = VoxelImage::new(
            [2, 2, 1],
            [1.0; 3],
            [0.0; 3],
            VoxelValues::Moduli(vec![1.0, 1e300, 1.0, 1.0]),
        )
        .unwrap_err();
        assert!(
            e.to_string()
                .contains("voxel [1, 0, 0] has Young's modulus 1e300 Pa"),
            "{e}"
        );
        // A spacing of 1e-300 m (a unit mistake in a header): named as the image's spacing.
        let e = VoxelImage::new([2, 2, 1], [1e-300, 1.0, 1.0], [0.0; 3], ok(4)).unwrap_err();
        assert!(
            e.to_string().contains("voxel spacing [1e-300, 1.0, 1.0] m"),
            "{e}"
        );
        let e = VoxelImage::new([usize::MAX, 2, 1], [1.0; 3], [0.0; 3], ok(1)).unwrap_err();
        assert!(e.to_string().contains("crop or downsample"), "{e}");
    }
}
