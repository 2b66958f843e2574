//! The camera: a view looking at the centre of some bounds from a direction given by azimuth
//! and elevation about an up axis, placed so the bounds fit the viewport with a margin.

use crate::geometry::Aabb;
use crate::linalg3::{cross, dot, normalize, sub};
use crate::Point3;

/// Perspective (a field of view) or orthographic projection.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Projection {
    /// Perspective with this full field of view across the shorter side of the viewport,
    /// degrees (0 < fov < 180).
    Perspective {
        /// Field of view, degrees.
        fov_deg: f64,
    },
    /// Parallel projection.
    Orthographic,
}

/// How a camera is placed around bounds. Every default is chosen for a first look at an
/// object that stands along +y (the scenes' gravity is -y).
#[derive(Debug, Clone, Copy, PartialEq)]
#[must_use]
pub struct CameraOptions {
    /// Angle around the up axis from the +z side towards +x, degrees. Default 30: a
    /// three-quarter view that shows two side faces of a box.
    pub azimuth_deg: f64,
    /// Angle above the horizontal plane, degrees (|elevation| < 90). Default 20: the top
    /// face shows, the object still reads as standing.
    pub elevation_deg: f64,
    /// The up axis (need not be unit length). Default +y.
    pub up: [f64; 3],
    /// Projection. Default perspective with a 30 degree field of view: mild foreshortening.
    pub projection: Projection,
    /// Scale of the fitted view: 2 shows the object twice as large (and may crop it).
    /// Default 1: the bounds' circumscribed sphere with [`CameraOptions::margin`] fits.
    pub zoom: f64,
    /// Extra room around the bounding sphere, as a fraction of its radius. Default 0.05.
    pub margin: f64,
}

impl Default for CameraOptions {
    fn default() -> Self {
        CameraOptions {
            azimuth_deg: 30.0,
            elevation_deg: 20.0,
            up: [0.0, 1.0, 0.0],
            projection: Projection::Perspective { fov_deg: 30.0 },
            zoom: 1.0,
            margin: 0.05,
        }
    }
}

/// A placed camera: eye, orthonormal frame (right, up, forward) and the projection scale.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Camera {
    /// Eye position, metres.
    pub eye: Point3,
    /// Unit vector to the right of the image.
    pub right: [f64; 3],
    /// Unit vector up the image.
    pub up: [f64; 3],
    /// Unit viewing direction (into the image).
    pub forward: [f64; 3],
    /// Projection.
    pub projection: Projection,
    /// Perspective: 1 / tan(fov / 2) / zoom-corrected; orthographic: the half-extent (metres)
    /// seen across the shorter side of the viewport.
    scale: f64,
}

impl Camera {
    /// A camera looking at the centre of `bounds` along `options`' direction, at the distance
    /// (perspective) or extent (orthographic) where the bounds' circumscribed sphere, enlarged
    /// by the margin, fits the shorter side of the viewport: every point of the bounds then
    /// projects inside the viewport (for `zoom <= 1`). Bad options (zero up axis, non-finite
    /// angles) fall back to the defaults for that field.
    pub fn fit(bounds: &Aabb, options: &CameraOptions) -> Camera {
        let d = CameraOptions::default();
        let up = normalize(options.up).unwrap_or(d.up);
        // Horizontal reference axes: +z projected off the up axis (or +x when up is along z).
        let h0 = normalize(sub(&[0.0, 0.0, 1.0], &scaled(up, up[2])))
            .or_else(|| normalize(sub(&[1.0, 0.0, 0.0], &scaled(up, up[0]))))
            .unwrap_or([1.0, 0.0, 0.0]);
        let h1 = cross(&up, &h0);
        let finite = |v: f64, dflt: f64| if v.is_finite() { v } else { dflt };
        let az = finite(options.azimuth_deg, d.azimuth_deg).to_radians();
        let el = finite(options.elevation_deg, d.elevation_deg)
            .clamp(-89.0, 89.0)
            .to_radians();
        // Direction from the centre to the eye.
        let to_eye =
            [0, 1, 2].map(|i| el.cos() * (az.cos() * h0[i] + az.sin() * h1[i]) + el.sin() * up[i]);
        let forward = scaled(to_eye, -1.0);
        let right = normalize(cross(&forward, &up)).unwrap_or(h1);
        let cam_up = cross(&right, &forward);
        let centre = [0, 1, 2].map(|i| 0.5 * (bounds.min[i] + bounds.max[i]));
        let half = [0, 1, 2].map(|i| 0.5 * (bounds.max[i] - bounds.min[i]));
        let mut radius = dot(&half, &half).sqrt();
        if !(radius > 0.0 && radius.is_finite()) {
            radius = 1.0;
        }
        let margin = if options.margin.is_finite() && options.margin >= 0.0 {
            options.margin
        } else {
            d.margin
        };
        let zoom = if options.zoom.is_finite() && options.zoom > 0.0 {
            options.zoom
        } else {
            1.0
        };
        let r = radius * (1.0 + margin);
        let (projection, dist, scale) = match options.projection {
            Projection::Perspective { fov_deg } => {
                let fov = if fov_deg.is_finite() && fov_deg > 0.0 && fov_deg < 179.0 {
                    fov_deg
                } else {
                    30.0
                };
                let half_fov = 0.5 * fov.to_radians();
                // The sphere of radius r at distance D fits the cone: r / D = sin(half_fov).
                let dist = r / half_fov.sin();
                (
                    Projection::Perspective { fov_deg: fov },
                    dist,
                    zoom / half_fov.tan(),
                )
            }
            Projection::Orthographic => (Projection::Orthographic, 3.0 * r, r / zoom),
        };
        Camera {
            eye: [0, 1, 2].map(|i| centre[i] + dist * to_eye[i]),
            right,
            up: cam_up,
            forward,
            projection,
            scale,
        }
    }

    /// Project `p` into `viewport` (width, height in pixels, origin top-left): (column, row,
    /// depth along the view direction in metres). Columns and rows are continuous (pixel
    /// centres at +0.5); None for a point at or behind the eye.
    pub fn project(&self, p: Point3, width: f64, height: f64) -> Option<(f64, f64, f64)> {
        let v = sub(&p, &self.eye);
        let depth = dot(&v, &self.forward);
        let (x, y) = (dot(&v, &self.right), dot(&v, &self.up));
        let half = 0.5 * width.min(height);
        let (nx, ny) = match self.projection {
            Projection::Perspective { .. } => {
                if depth <= 1e-12 {
                    return None;
                }
                (x * self.scale / depth, y * self.scale / depth)
            }
            Projection::Orthographic => (x / self.scale, y / self.scale),
        };
        Some((0.5 * width + nx * half, 0.5 * height - ny * half, depth))
    }

    /// The Jacobian of [`Camera::project`]'s (column, row) with respect to the world point,
    /// at `p`: 2 x 3, pixels per metre (rows: column, row). The local linear map that turns a
    /// world covariance at `p` into a screen covariance (EWA splatting). None where `project`
    /// is None.
    pub fn jacobian(&self, p: Point3, width: f64, height: f64) -> Option<[[f64; 3]; 2]> {
        let v = sub(&p, &self.eye);
        let depth = dot(&v, &self.forward);
        let half = 0.5 * width.min(height);
        match self.projection {
            Projection::Perspective { .. } => {
                if depth <= 1e-12 {
                    return None;
                }
                // column = c + f x / z, row = c' - f y / z with (x, y, z) in the camera frame.
                let f = half * self.scale / depth;
                let (x, y) = (dot(&v, &self.right) / depth, dot(&v, &self.up) / depth);
                Some([
                    [0, 1, 2].map(|k| f * (self.right[k] - x * self.forward[k])),
                    [0, 1, 2].map(|k| -f * (self.up[k] - y * self.forward[k])),
                ])
            }
            Projection::Orthographic => {
                let f = half / self.scale;
                Some([
                    [0, 1, 2].map(|k| f * self.right[k]),
                    [0, 1, 2].map(|k| -f * self.up[k]),
                ])
            }
        }
    }

    /// Pixels per metre at `depth` in a viewport whose shorter side is `short` pixels.
    pub fn pixels_per_metre(&self, depth: f64, short: f64) -> f64 {
        match self.projection {
            Projection::Perspective { .. } => 0.5 * short * self.scale / depth.max(1e-12),
            Projection::Orthographic => 0.5 * short / self.scale,
        }
    }

    /// Whether this is a perspective camera.
    pub fn is_perspective(&self) -> bool {
        matches!(self.projection, Projection::Perspective { .. })
    }
}

fn scaled(a: [f64; 3], s: f64) -> [f64; 3] {
    [a[0] * s, a[1] * s, a[2] * s]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fitted_camera_sees_every_corner_and_looks_at_the_centre() {
        let b = Aabb {
            min: [-1.0, 0.0, 2.0],
            max: [4.0, 1.0, 3.5],
        };
        for projection in [
            Projection::Perspective { fov_deg: 30.0 },
            Projection::Perspective { fov_deg: 90.0 },
            Projection::Orthographic,
        ] {
            for (az, el) in [(30.0, 20.0), (0.0, 0.0), (-120.0, 80.0), (200.0, -45.0)] {
                for up in [[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [1.0, 1.0, 0.0]] {
                    let cam = Camera::fit(
                        &b,
                        &CameraOptions {
                            azimuth_deg: az,
                            elevation_deg: el,
                            up,
                            projection,
                            ..Default::default()
                        },
                    );
                    let (w, h) = (320.0, 200.0);
                    let c = cam.project([1.5, 0.5, 2.75], w, h).unwrap();
                    assert!((c.0 - 160.0).abs() < 1e-9 && (c.1 - 100.0).abs() < 1e-9);
                    for i in 0..8 {
                        let p =
                            [0, 1, 2].map(|k| if i >> k & 1 == 1 { b.max[k] } else { b.min[k] });
                        let (x, y, _) = cam.project(p, w, h).unwrap();
                        assert!(
                            (0.0..=w).contains(&x) && (0.0..=h).contains(&y),
                            "{p:?} -> {x}, {y}"
                        );
                    }
                }
            }
        }
    }

    #[test]
    fn jacobian_matches_central_differences_of_the_projection() {
        let b = Aabb {
            min: [-1.0, 0.0, 2.0],
            max: [4.0, 1.0, 3.5],
        };
        for projection in [
            Projection::Perspective { fov_deg: 40.0 },
            Projection::Orthographic,
        ] {
            let cam = Camera::fit(
                &b,
                &CameraOptions {
                    azimuth_deg: 35.0,
                    elevation_deg: 25.0,
                    projection,
                    ..Default::default()
                },
            );
            let p = [3.0, 0.2, 2.2];
            let j = cam.jacobian(p, 320.0, 200.0).unwrap();
            let h = 1e-6;
            for k in 0..3 {
                let mut a = p;
                let mut c = p;
                a[k] += h;
                c[k] -= h;
                let (pa, pc) = (
                    cam.project(a, 320.0, 200.0).unwrap(),
                    cam.project(c, 320.0, 200.0).unwrap(),
                );
                let d = [(pa.0 - pc.0) / (2.0 * h), (pa.1 - pc.1) / (2.0 * h)];
                for r in 0..2 {
                    assert!(
                        (d[r] - j[r][k]).abs() < 1e-5 * (1.0 + d[r].abs()),
                        "{d:?} {j:?}"
                    );
                }
            }
        }
    }

    #[test]
    fn default_view_shows_plus_y_up_and_plus_x_to_the_right() {
        let b = Aabb {
            min: [-1.0; 3],
            max: [1.0; 3],
        };
        let cam = Camera::fit(&b, &CameraOptions::default());
        let (_, y_top, _) = cam.project([0.0, 1.0, 0.0], 100.0, 100.0).unwrap();
        let (x_right, _, _) = cam.project([1.0, 0.0, 0.0], 100.0, 100.0).unwrap();
        assert!(y_top < 50.0 && x_right > 50.0);
    }
}
