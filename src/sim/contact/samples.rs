//! Contact samples: points spread over an object's surface, each the centre of a sphere of
//! radius t (the object's contact thickness) set t inside the surface, so the spheres' outer
//! envelope is the surface (rounded by t at convex edges). Each sample carries the surface
//! area it stands for and its skinning weights (the object's basis evaluated there, as for
//! render sets), so its position is x = X + B(X) z like any point of the object.

use crate::geometry::Shape;
use crate::linalg3::{cross, sub};
use crate::precompute::skinning::Basis;
use crate::sim::collider::{MeshObstacle, Sided};
use crate::sim::elastic::Layout;
use crate::{Error, Point3, Result};

/// Default sample spacing as a fraction of the object's bounding-box diagonal: 1/25 gives
/// about 1250 samples on a cube and 650 on a ball, and a contact thickness of 2.3% of the
/// diagonal (the spacing).
pub const DEFAULT_SPACING_FRACTION: f64 = 1.0 / 25.0;

/// Fewest and most samples an object gets by default (from its size).
pub const DEFAULT_SAMPLES_RANGE: (usize, usize) = (64, 20_000);

/// Most contact samples one object may have: 1,000,000, 50 times the default's largest
/// count, a typo guard (or a unit mistake). Whether the samples of a scene fit is decided by
/// [`sample_bytes`] against the memory available.
pub const MAX_CONTACT_SAMPLES: usize = 1_000_000;

/// `count` as the contact sample count named `name` (`contact.samples` or
/// `contact_samples`): at least 1 and at most [`MAX_CONTACT_SAMPLES`].
///
/// # Errors
/// [`Error::InvalidParameter`] naming `name` otherwise.
pub fn check_count(name: &'static str, count: usize) -> Result<()> {
    if count == 0 {
        return Err(Error::param(
            name,
            count,
            "an object in contact needs at least one contact sample",
        ));
    }
    if count > MAX_CONTACT_SAMPLES {
        return Err(Error::param(
            name,
            count,
            format!(
                "more than {MAX_CONTACT_SAMPLES} contact samples per object is a typo guard's \
                 limit (the default is {}..{} from the object's size); use fewer",
                DEFAULT_SAMPLES_RANGE.0, DEFAULT_SAMPLES_RANGE.1
            ),
        ));
    }
    Ok(())
}

/// Narrowest feature sample spacing, a fraction of the thickness: a neighbour's sphere then
/// reaches between two of them by t / 3200, and narrower adds points for nothing.
pub const MIN_FEATURE_SPACING: f64 = 0.05;

/// `spacing` as the feature samples' spacing along an edge, a fraction of the contact
/// thickness (`contact.feature_spacing`): 0 (no feature samples) or in
/// [[`MIN_FEATURE_SPACING`], 10].
///
/// # Errors
/// [`Error::InvalidParameter`] otherwise.
pub fn check_feature_spacing(spacing: f64) -> Result<()> {
    if spacing == 0.0 || (MIN_FEATURE_SPACING..=10.0).contains(&spacing) {
        return Ok(());
    }
    Err(Error::param(
        "contact.feature_spacing",
        spacing,
        format!(
            "the feature samples' spacing along an edge is a fraction of the contact \
             thickness, 0 (none, the default) or in [{MIN_FEATURE_SPACING}, 10] (0.5 is the \
             measured setting; narrower gains nothing, wider than a few thicknesses lets a \
             neighbour's sphere reach between them)"
        ),
    ))
}

/// Bytes that `count` contact samples with `handles` = m + 1 weights each hold during a run:
/// the weights, the rest and deformed centres, the area, and the broad phase's tree and
/// candidate lists (about 64 bytes a sample).
pub fn sample_bytes(count: usize, handles: usize) -> u64 {
    count as u64 * (8 * handles as u64 + 24 + 24 + 8 + 64)
}

/// The contact samples of one object.
#[derive(Debug, Clone)]
pub struct ContactSamples {
    /// Rest positions of the sample centres (set `thickness` inside the surface), N x 3,
    /// metres.
    pub rest: Vec<Point3>,
    /// Surface area each sample stands for, N, m^2.
    pub area: Vec<f64>,
    /// Contact thickness t, metres: the radius of the ordinary samples' spheres (and the
    /// largest radius of any sample).
    pub thickness: f64,
    /// Radius of each sample's sphere, N, metres: t for the ordinary samples, 0 for the
    /// feature samples (the last [`ContactSamples::features`] of them, points).
    pub radius: Vec<f64>,
    /// How many samples, at the end, are feature samples: centred on the surface's convex
    /// edges and corners ([`super::features`]).
    pub features: usize,
    /// Skinning weight values at the samples, N x (m + 1), row-major.
    weights: Vec<f64>,
    handles: usize,
}

/// Surface area of a shape, m^2 (None for point clouds and voxel images, which have no
/// surface mesh).
pub fn surface_area(shape: &Shape) -> Option<f64> {
    match shape {
        Shape::Box { size: l } => Some(2.0 * (l[0] * l[1] + l[1] * l[2] + l[0] * l[2])),
        Shape::Sphere { radius: r } => Some(4.0 * std::f64::consts::PI * r * r),
        Shape::Mesh(m) => Some(
            m.triangles()
                .iter()
                .map(|t| triangle_area(m.vertices(), t))
                .sum(),
        ),
        Shape::PointCloud(_) | Shape::Image(_) => None,
    }
}

/// The default sample count of a shape: its surface area over the squared spacing `spacing`
/// (metres; None: [`DEFAULT_SPACING_FRACTION`] of its diagonal), within
/// [`DEFAULT_SAMPLES_RANGE`].
pub fn default_count(shape: &Shape, spacing: Option<f64>) -> usize {
    let s = spacing.unwrap_or(DEFAULT_SPACING_FRACTION * shape.bounding_box().diagonal());
    let a = surface_area(shape).unwrap_or(0.0);
    let n = (a / (s * s)).round();
    let (lo, hi) = DEFAULT_SAMPLES_RANGE;
    if n.is_finite() {
        (n as usize).clamp(lo, hi)
    } else {
        hi
    }
}

fn triangle_area(v: &[Point3], t: &[u32; 3]) -> f64 {
    let n = triangle_normal(v, t);
    0.5 * (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt()
}

/// (b - a) x (c - a): twice the area along the outward normal.
fn triangle_normal(v: &[Point3], t: &[u32; 3]) -> [f64; 3] {
    let [a, b, c] = t.map(|i| v[i as usize]);
    cross(&sub(&b, &a), &sub(&c, &a))
}

impl ContactSamples {
    /// About `count` samples on the surface of `shape` (its rest frame), with contact
    /// thickness `thickness` (metres; None: the sample spacing, sqrt(area / count)), and their
    /// skinning weights from `basis`.
    ///
    /// # Errors
    /// A point cloud (no surface), a count of 0, a thickness that is not positive and finite
    /// or not below half the shape's smallest extent, or a basis that does not cover the
    /// samples.
    pub fn new(
        shape: &Shape,
        basis: &Basis,
        count: usize,
        thickness: Option<f64>,
    ) -> Result<ContactSamples> {
        check_count("contact_samples", count)?;
        let area = surface_area(shape).ok_or_else(|| {
            Error::param(
                "shape",
                shape.kind(),
                "contact samples need a surface: a box, a sphere or a closed mesh (for a \
                 point cloud, splats or a voxel image, sample the mesh that \
                 sim::contact::surface::derived_surface makes of it, as scenes do)",
            )
        })?;
        let t = thickness.unwrap_or((area / count as f64).sqrt());
        let extent = shape
            .bounding_box()
            .size()
            .iter()
            .cloned()
            .fold(f64::INFINITY, f64::min);
        if !(t > 0.0 && t.is_finite() && t < 0.5 * extent) {
            return Err(Error::param(
                "contact.radius",
                t,
                format!(
                    "the contact thickness (metres) must be positive and below half the \
                     object's smallest extent ({extent:.3e} m); use more contact samples or a \
                     smaller contact radius"
                ),
            ));
        }
        let (rest, area) = match shape {
            Shape::Box { size } => box_samples(size, count, t),
            Shape::Sphere { radius } => sphere_samples(*radius, count, t),
            Shape::Mesh(m) => mesh_samples(m.vertices(), m.triangles(), count, t)?,
            Shape::PointCloud(_) | Shape::Image(_) => {
                unreachable!("surface_area is None for point clouds and images")
            }
        };
        let w = basis.weights(&rest).map_err(|e| Error::Scene {
            message: format!(
                "the skinning weights cannot be evaluated at the contact samples ({e}); more \
                 kernels or a larger support factor cover them"
            ),
        })?;
        Ok(ContactSamples {
            radius: vec![t; rest.len()],
            rest,
            area,
            thickness: t,
            features: 0,
            weights: w.values,
            handles: w.modes,
        })
    }

    /// These samples with feature samples added: points (radius 0) on the convex edges and
    /// corners of `shape` (the shape these samples were made on) where they stand out past
    /// the ordinary spheres, `spacing` t apart along each edge
    /// ([`super::features::feature_points`]), each standing for an ordinary sample's area.
    /// `spacing` 0 adds none.
    ///
    /// # Errors
    /// A `spacing` neither 0 nor in [[`MIN_FEATURE_SPACING`], 10]; edges too long for it
    /// (more than [`super::features::MAX_FEATURE_CANDIDATES`] candidate points); or a basis
    /// that does not cover the new samples.
    pub fn with_features(
        mut self,
        shape: &Shape,
        basis: &Basis,
        spacing: f64,
    ) -> Result<ContactSamples> {
        check_feature_spacing(spacing)?;
        if spacing == 0.0 || self.features > 0 {
            return Ok(self);
        }
        let points = super::features::feature_points(
            shape,
            &self.rest,
            self.thickness,
            spacing * self.thickness,
        )
        .map_err(|candidates| {
            Error::param(
                "contact.feature_spacing",
                spacing,
                format!(
                    "the object's edges would need {candidates} feature sample candidates at \
                     this spacing and a thickness of {:.3e} m (at most {}); use a larger \
                     feature_spacing or contact.radius",
                    self.thickness,
                    super::features::MAX_FEATURE_CANDIDATES
                ),
            )
        })?;
        if points.is_empty() {
            return Ok(self);
        }
        let w = basis.weights(&points).map_err(|e| Error::Scene {
            message: format!(
                "the skinning weights cannot be evaluated at the contact samples on the \
                 object's edges and corners ({e}); more kernels or a larger support factor \
                 cover them, or contact.feature_spacing = 0 leaves them out"
            ),
        })?;
        let a = self.area.iter().sum::<f64>() / self.len().max(1) as f64;
        self.features = points.len();
        self.area.extend(std::iter::repeat_n(a, points.len()));
        self.radius.extend(std::iter::repeat_n(0.0, points.len()));
        self.rest.extend(points);
        self.weights.extend(w.values);
        Ok(self)
    }

    /// The ordinary samples' spacing, metres: sqrt(their area / their count).
    pub fn spacing(&self) -> f64 {
        let n = self.len() - self.features;
        (self.area[..n].iter().sum::<f64>() / n.max(1) as f64).sqrt()
    }

    /// Number of samples.
    pub fn len(&self) -> usize {
        self.rest.len()
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.rest.is_empty()
    }

    /// Number of handles m + 1 of the weights.
    pub fn handles(&self) -> usize {
        self.handles
    }

    /// The row b(X_i) of sample `i`, 4 (m + 1) entries: x_r = X_r + b . z_r.
    pub fn b(&self, i: usize, out: &mut [f64]) {
        let x = self.rest[i];
        let xh = [x[0], x[1], x[2], 1.0];
        let w = &self.weights[i * self.handles..(i + 1) * self.handles];
        for (j, wj) in w.iter().enumerate() {
            for a in 0..4 {
                out[4 * j + a] = wj * xh[a];
            }
        }
    }

    /// B(X_i) d for every sample: the displacement of the samples for a change `d` of z
    /// (with `rest` added when `with_rest`), N x 3, metres.
    fn apply(&self, layout: Layout, d: &[f64], with_rest: bool) -> Vec<Point3> {
        use crate::sim::deformation::{skinned_offset, skinned_position};
        let n4 = layout.row_len();
        let h = self.handles;
        (0..self.len())
            .map(|i| {
                let w = &self.weights[i * h..(i + 1) * h];
                if with_rest {
                    skinned_position(self.rest[i], w, d, n4)
                } else {
                    skinned_offset(self.rest[i], w, d, n4)
                }
            })
            .collect()
    }

    /// Deformed sample positions at `z`, N x 3, metres.
    pub fn positions(&self, layout: Layout, z: &[f64]) -> Vec<Point3> {
        self.apply(layout, z, true)
    }

    /// Sample displacements for a change `d` of z, N x 3, metres.
    pub fn displacements(&self, layout: Layout, d: &[f64]) -> Vec<Point3> {
        self.apply(layout, d, false)
    }
}

/// Clamp a surface point into the box shrunk by t: the sample centre t inside every face it
/// is within t of, so the spheres' envelope is the box with edges rounded by t.
fn box_samples(l: &[f64; 3], count: usize, t: f64) -> (Vec<Point3>, Vec<f64>) {
    let area = 2.0 * (l[0] * l[1] + l[1] * l[2] + l[0] * l[2]);
    let s = (area / count as f64).sqrt();
    let mut rest = Vec::new();
    let mut areas = Vec::new();
    for axis in 0..3 {
        let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
        let nu = ((l[u] / s).round() as usize).max(1);
        let nv = ((l[v] / s).round() as usize).max(1);
        let a = l[u] * l[v] / (nu * nv) as f64;
        for side in [0.0, l[axis]] {
            for iu in 0..nu {
                for iv in 0..nv {
                    let mut p = [0.0; 3];
                    p[axis] = side;
                    p[u] = (iu as f64 + 0.5) * l[u] / nu as f64;
                    p[v] = (iv as f64 + 0.5) * l[v] / nv as f64;
                    rest.push(std::array::from_fn(|d| p[d].clamp(t, l[d] - t)));
                    areas.push(a);
                }
            }
        }
    }
    (rest, areas)
}

/// A Fibonacci lattice on the sphere of radius r - t (equal areas).
fn sphere_samples(r: f64, count: usize, t: f64) -> (Vec<Point3>, Vec<f64>) {
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    let rest = (0..count)
        .map(|i| {
            let y = 1.0 - 2.0 * (i as f64 + 0.5) / count as f64;
            let rho = (1.0 - y * y).max(0.0).sqrt();
            let phi = golden * i as f64;
            [
                (r - t) * rho * phi.cos(),
                (r - t) * y,
                (r - t) * rho * phi.sin(),
            ]
        })
        .collect();
    let a = 4.0 * std::f64::consts::PI * r * r / count as f64;
    (rest, vec![a; count])
}

/// Area-proportional samples on a closed mesh: triangle k gets the samples whose systematic
/// positions (i + 1/2) A / N fall in its share of the cumulative area, placed by the R2
/// low-discrepancy sequence folded into the triangle; then each is pushed in along the
/// inward normal until it lies t below the surface (a few projections through the mesh's
/// BVH: at convex edges the face normal alone would leave it closer to the other face).
fn mesh_samples(
    v: &[Point3],
    tris: &[[u32; 3]],
    count: usize,
    t: f64,
) -> Result<(Vec<Point3>, Vec<f64>)> {
    let obstacle = MeshObstacle::from_triangles(
        std::path::Path::new("contact samples"),
        v.to_vec(),
        tris.to_vec(),
        Sided::Solid,
    )
    .map_err(|e| match e {
        crate::geometry::GeometryError::ColliderNotClosed {
            boundary_edges,
            nonmanifold_edges,
            misoriented_edges,
            ..
        } => Error::param(
            "shape",
            "an open mesh",
            format!(
                "object-object contact needs a closed, consistently oriented surface to tell \
                 inside from outside, and this mesh has {boundary_edges} boundary, \
                 {nonmanifold_edges} non-manifold and {misoriented_edges} misoriented edges \
                 (allow_open_mesh lets it be simulated, not touch other objects); repair the \
                 mesh, or leave the object out of the [contact] scene"
            ),
        ),
        other => other.into(),
    })?;
    let areas: Vec<f64> = tris.iter().map(|t| triangle_area(v, t)).collect();
    let total: f64 = areas.iter().sum();
    let step = total / count as f64;
    // R2 sequence constants (the plastic number).
    let g = 1.324_717_957_244_746;
    let (a1, a2) = (1.0 / g, 1.0 / (g * g));
    let mut rest = Vec::with_capacity(count);
    let mut cum = 0.0;
    let mut next = 0usize;
    for (k, tri) in tris.iter().enumerate() {
        let end = cum + areas[k];
        let mut local = 0usize;
        while next < count && (next as f64 + 0.5) * step < end {
            local += 1;
            let (mut p, mut q) = (
                (0.5 + a1 * local as f64) % 1.0,
                (0.5 + a2 * local as f64) % 1.0,
            );
            if p + q > 1.0 {
                (p, q) = (1.0 - p, 1.0 - q);
            }
            let [a, b, c] = tri.map(|i| v[i as usize]);
            let x: Point3 = std::array::from_fn(|d| a[d] + p * (b[d] - a[d]) + q * (c[d] - a[d]));
            let n = triangle_normal(v, tri);
            let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
            let mut y: Point3 = std::array::from_fn(|d| x[d] - t * n[d] / len);
            for _ in 0..4 {
                match obstacle.penetration_local(&y) {
                    Some(pen) if pen.depth < t * (1.0 - 1e-6) => {
                        let push = t - pen.depth;
                        y = std::array::from_fn(|d| y[d] - push * pen.normal[d]);
                    }
                    _ => break,
                }
            }
            rest.push(y);
            next += 1;
        }
        cum = end;
    }
    let n = rest.len();
    Ok((rest, vec![total / n.max(1) as f64; n]))
}

#[cfg(test)]
mod tests {
    use super::super::features::{box_candidates, feature_points};
    use super::*;

    /// Box samples cover the area exactly and lie t inside every face they are near.
    #[test]
    fn box_samples_carry_the_area_and_sit_t_inside() {
        let l = [0.3, 0.2, 0.1];
        let t = 0.01;
        let (p, a) = box_samples(&l, 600, t);
        let total: f64 = a.iter().sum();
        assert!((total - 2.0 * (0.06 + 0.02 + 0.03)).abs() < 1e-12);
        for x in &p {
            let depth = (0..3)
                .map(|d| x[d].min(l[d] - x[d]))
                .fold(f64::INFINITY, f64::min);
            assert!((depth - t).abs() < 1e-12, "{x:?}");
        }
    }

    /// Sphere samples are at radius r - t with equal areas summing to 4 pi r^2.
    #[test]
    fn sphere_samples_sit_t_inside() {
        let (p, a) = sphere_samples(0.5, 200, 0.05);
        for x in &p {
            let r = (x[0] * x[0] + x[1] * x[1] + x[2] * x[2]).sqrt();
            assert!((r - 0.45).abs() < 1e-12);
        }
        let total: f64 = a.iter().sum();
        assert!((total - std::f64::consts::PI).abs() < 1e-12);
    }

    /// A cube given as a mesh: every sample ends t below the surface (the convex edges
    /// included), and the count is the one asked for.
    #[test]
    fn mesh_samples_sit_t_below_the_surface() {
        let (v, f) = crate::geometry::generate::box_mesh([1.0, 1.0, 1.0]);
        let (p, a) = mesh_samples(&v, &f, 500, 0.05).unwrap();
        assert_eq!(p.len(), 500);
        assert!((a.iter().sum::<f64>() - 6.0).abs() < 1e-9);
        for x in &p {
            let depth = (0..3)
                .map(|d| x[d].min(1.0 - x[d]))
                .fold(f64::INFINITY, f64::min);
            // The BVH projection is exact to rounding; 1e-6 t is the stop test's slack.
            assert!((depth - 0.05).abs() < 1e-6, "{x:?} depth {depth}");
        }
    }

    /// Every point of a box's edges is within 3/4 of the spacing of a feature point, every
    /// corner is one, and every feature point lies on an edge.
    #[test]
    fn box_edges_are_covered_by_feature_points() {
        let l = [0.3, 0.2, 0.1];
        let t = 0.01;
        let (centres, _) = box_samples(&l, 2200, t); // spacing t
        let spacing = 0.5 * t;
        let r = 0.75 * spacing;
        let f = feature_points(&Shape::Box { size: l }, &centres, t, spacing).unwrap();
        assert!(!f.is_empty());
        // Every corner is a feature centre.
        for c in &box_candidates(&l, 1.0)[..8] {
            assert!(f.iter().any(|p| p == c), "corner {c:?}");
        }
        // Dense points on the edges: each within r of a kept point (the greedy keeps a
        // candidate, walking along the edge, unless a kept one lies within r; a point
        // between two candidates is nearer than the next candidate to every kept point
        // behind it).
        for p in box_candidates(&l, 0.1 * r) {
            let best = f
                .iter()
                .map(|q| (0..3).map(|d| (p[d] - q[d]).powi(2)).sum::<f64>().sqrt())
                .fold(f64::INFINITY, f64::min);
            assert!(best <= r * (1.0 + 1e-9), "{p:?}: {best}");
        }
        // Every feature lies on an edge: two of its coordinates on the box's faces.
        for p in &f {
            let on = (0..3)
                .filter(|&d| p[d].abs() < 1e-12 || (p[d] - l[d]).abs() < 1e-12)
                .count();
            assert!(on >= 2, "{p:?}");
        }
    }

    /// A cube given as a mesh (two triangles a face): its corners are feature points and
    /// every feature point lies on an edge, or on a face diagonal (a mesh edge too) within t
    /// of a corner, where the face itself stands out of the samples clamped t inside.
    #[test]
    fn a_mesh_cube_gets_features_on_its_edges_and_corners() {
        let (v, f) = crate::geometry::generate::box_mesh([1.0, 1.0, 1.0]);
        let mesh =
            crate::geometry::TriMesh::new(v, f, &crate::geometry::ShapeOptions::default()).unwrap();
        let t = 0.04;
        let (centres, _) = box_samples(&[1.0; 3], 3750, t); // spacing t
        let f = feature_points(&Shape::Mesh(mesh), &centres, t, 0.5 * t).unwrap();
        for c in box_candidates(&[1.0; 3], 1.0).iter().take(8) {
            assert!(f.iter().any(|p| p == c), "corner {c:?}");
        }
        for p in &f {
            let on = (0..3)
                .filter(|&d| p[d].abs() < 1e-12 || (p[d] - 1.0).abs() < 1e-12)
                .count();
            let corner = (0..3)
                .map(|d| p[d].min(1.0 - p[d]).powi(2))
                .sum::<f64>()
                .sqrt();
            assert!(on >= 2 || corner <= t, "{p:?}");
        }
        // About 12 edges / (0.75-1 spacing) points each.
        assert!((12 * 50..=12 * 70).contains(&f.len()), "{}", f.len());
    }
}
