//! Where the kernels go: a kernel density field over the integration points, as a scale s(X)
//! per point that weighted farthest point sampling turns into a local spacing of about h0 / s
//! ([`super::centers::farthest_point_sampling_scaled`]). K stays the user's; the density only
//! moves kernels: finer within a band around boundary regions (held and driven parts, where
//! an aware basis's free modes ramp up) and at material interfaces, coarser in the bulk.
//! Support radii follow the local spacing by themselves (the n-th nearest centre).
//!
//! h0 = (V / K)^(1/3) is the spacing K kernels would have spread evenly over the volume V;
//! bands are measured in it, so a band means the same at every K.

use super::ball_max::BallMax;
use crate::material::{MaterialField, Region};
use crate::{Error, Point3, Result};
use kiddo::{ImmutableKdTree, SquaredEuclidean};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

/// A user region with its own density factor: the kernel spacing inside it is h0 / `factor`
/// (factor 2: twice as fine, 8x the kernels per volume; 0.5: twice as coarse).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct DensityRegion {
    /// The region, rest coordinates, metres.
    pub region: Region,
    /// Spacing factor inside it: positive and finite.
    pub factor: f64,
}

impl std::str::FromStr for DensityRegion {
    type Err = Error;

    /// `REGION@FACTOR`: a region as [`Region`] parses it, then the spacing factor
    /// (`sphere:0,0,0,0.2@2`); validated.
    fn from_str(s: &str) -> Result<Self> {
        let Some((region, factor)) = s.rsplit_once('@') else {
            return Err(Error::param(
                "density region",
                s,
                "write REGION@FACTOR, e.g. sphere:0,0,0,0.2@2 (twice as fine inside)",
            ));
        };
        let factor: f64 = factor.trim().parse().map_err(|_| {
            Error::param(
                "density region",
                s,
                "the factor after @ must be a number, e.g. @2",
            )
        })?;
        let out = DensityRegion {
            region: region.parse()?,
            factor,
        };
        KernelDensity {
            bands: DensityBands::off(),
            regions: vec![out],
        }
        .validate()?;
        Ok(out)
    }
}

/// The refined bands of a [`KernelDensity`]: around boundary regions and material
/// interfaces. [`DensityBands::off`] refines nothing.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct DensityBands {
    /// Spacing factor within `band` of a boundary region's surface (the held and driven
    /// parts of an aware basis): the kernel spacing there is h0 / `boundaries`. 1 is off.
    pub boundaries: f64,
    /// Spacing factor within `band` of a material interface (neighbouring integration points
    /// whose Young's modulus or density differ by more than [`INTERFACE_CONTRAST`] times, or
    /// whose Poisson ratios differ by more than 0.05). 1 is off.
    pub interfaces: f64,
    /// Half-width of the refined bands, in units of h0. The factor falls linearly back to 1
    /// over one more band width, so the spacing grades instead of jumping; where the two bands
    /// overlap their factors multiply.
    pub band: f64,
    /// Thin parts: the largest spacing factor given to parts thinner than [`THIN_ACROSS`]
    /// spacings h0, so that about that many kernels lie across them (local thickness from
    /// the integration points' distance to the object's surface). 1 is off.
    #[serde(default = "one")]
    pub thin: f64,
}

fn one() -> f64 {
    1.0
}

/// Kernels wanted across a thin part: parts thinner than this many spacings h0 get a finer
/// spacing (up to [`DensityBands::thin`]), so their kernels do not lie on one line or plane.
pub const THIN_ACROSS: f64 = 3.0;

impl Default for DensityBands {
    /// The default bands of every basis: see docs/accuracy.md ("Kernel density").
    fn default() -> Self {
        Self::off()
    }
}

impl DensityBands {
    /// No refined band.
    pub fn off() -> Self {
        Self {
            boundaries: 1.0,
            interfaces: 1.0,
            band: 1.0,
            thin: 1.0,
        }
    }
}

/// The kernel density options of a basis. [`KernelDensity::off`] is uniform farthest point
/// sampling (every basis before this option existed).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct KernelDensity {
    /// Refined bands around boundary regions and material interfaces.
    pub bands: DensityBands,
    /// User regions with their own factors, applied after the bands (the last region that
    /// holds a point wins, as material overrides do); the bands' factor is multiplied by it.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub regions: Vec<DensityRegion>,
}

/// Neighbouring points whose Young's moduli or densities differ by more than this ratio lie
/// on a material interface (a modulus image's gentle gradients do not).
pub const INTERFACE_CONTRAST: f64 = 1.5;

/// Narrowest band accepted, in kernel spacings.
pub const MIN_BAND: f64 = 0.1;

/// Largest factor accepted: 8 (512x the kernels per volume).
pub const MAX_DENSITY_FACTOR: f64 = 8.0;

impl KernelDensity {
    /// Uniform sampling: no bands, no regions.
    pub fn off() -> Self {
        Self {
            bands: DensityBands::off(),
            regions: Vec::new(),
        }
    }

    /// Only the bands `bands`, no user region.
    pub fn bands(bands: DensityBands) -> Self {
        Self {
            bands,
            regions: Vec::new(),
        }
    }

    /// True when the density changes nothing (uniform farthest point sampling).
    pub fn is_off(&self) -> bool {
        self.bands.boundaries == 1.0
            && self.bands.interfaces == 1.0
            && self.bands.thin == 1.0
            && self.regions.is_empty()
    }

    /// Check the ranges: factors finite and in [1/8, 8], band in [0.1, 100].
    pub fn validate(&self) -> Result<()> {
        for (name, f) in [
            ("density boundaries", self.bands.boundaries),
            ("density interfaces", self.bands.interfaces),
            ("density thin", self.bands.thin),
        ] {
            if !factor_in_range(f) {
                return Err(Error::param(
                    name,
                    f,
                    format!(
                        "a band's spacing factor must be a number in [1/{MAX_DENSITY_FACTOR}, \
                         {MAX_DENSITY_FACTOR}] (1 is off; 2 halves the spacing)"
                    ),
                ));
            }
        }
        if !(self.bands.band.is_finite() && (MIN_BAND..=100.0).contains(&self.bands.band)) {
            return Err(Error::param(
                "density band",
                self.bands.band,
                format!(
                    "the band half-width is in kernel spacings h0 = (V / K)^(1/3) and must lie \
                     in [{MIN_BAND}, 100] (default 1): a narrower band holds hardly a kernel"
                ),
            ));
        }
        for (i, r) in self.regions.iter().enumerate() {
            r.region.validate()?;
            let f = r.factor;
            if !factor_in_range(f) {
                return Err(Error::param(
                    "density region",
                    format!("{i} ({:?}): factor {f}", r.region),
                    format!(
                        "the spacing factor of a density region must be a number in \
                         [1/{MAX_DENSITY_FACTOR}, {MAX_DENSITY_FACTOR}] (not NaN, zero or \
                         negative)"
                    ),
                ));
            }
        }
        Ok(())
    }
}

/// A spacing factor in [1/8, 8] (so also finite, not NaN, positive).
fn factor_in_range(f: f64) -> bool {
    (1.0 / MAX_DENSITY_FACTOR..=MAX_DENSITY_FACTOR).contains(&f)
}

/// The spacing K kernels would have spread evenly over `volume` (m^3): (V / K)^(1/3), metres.
pub fn bulk_spacing(volume: f64, kernels: usize) -> f64 {
    (volume / kernels.max(1) as f64).cbrt()
}

/// Distance from `x` to the surface of `region`, metres (0 on it, positive on both sides).
pub fn distance_to_surface(region: &Region, x: &Point3) -> f64 {
    match region {
        Region::HalfSpace { point, normal } => {
            let n = (normal[0] * normal[0] + normal[1] * normal[1] + normal[2] * normal[2]).sqrt();
            ((0..3).map(|d| (x[d] - point[d]) * normal[d]).sum::<f64>() / n).abs()
        }
        Region::Sphere { center, radius } => {
            let r = (0..3)
                .map(|d| (x[d] - center[d]).powi(2))
                .sum::<f64>()
                .sqrt();
            (r - radius).abs()
        }
        Region::Box { min, max } => {
            // Outside: distance to the box; inside: to the nearest face (infinite faces of a
            // half-open slab are never nearest).
            let out: f64 = (0..3)
                .map(|d| (min[d] - x[d]).max(x[d] - max[d]).max(0.0).powi(2))
                .sum::<f64>()
                .sqrt();
            if out > 0.0 {
                out
            } else {
                (0..3)
                    .map(|d| (x[d] - min[d]).min(max[d] - x[d]))
                    .fold(f64::INFINITY, f64::min)
            }
        }
    }
}

/// The band's factor at distance `d` from a surface: `factor` within `band`, falling linearly
/// to 1 at twice the band, 1 beyond.
fn taper(factor: f64, band: f64, d: f64) -> f64 {
    if d <= band {
        factor
    } else if d >= 2.0 * band {
        1.0
    } else {
        factor + (1.0 - factor) * (d - band) / band
    }
}

/// The scale s(X) at every point (N, dimensionless), or None when `density` is off.
///
/// `volume` is the object's volume (m^3), `boundary_regions` the aware basis's regions,
/// `whole` the per-point materials and volumes (needed only for interface and thin-part
/// refinement; None across MPI ranks, where a point's neighbours may live on another rank).
///
/// # Errors
/// Invalid options; a band wider than the object; interface refinement asked for on an object
/// without an interface, or without the materials; boundary refinement with no boundary
/// region; a density region that holds no integration point.
pub fn kernel_scale(
    points: &[Point3],
    volume: f64,
    kernels: usize,
    density: &KernelDensity,
    boundary_regions: &[Region],
    whole: Option<WholeObject<'_>>,
) -> Result<Option<Vec<f64>>> {
    let part = kernel_scale_part(points, volume, kernels, density, boundary_regions, whole)?;
    Ok(match part {
        Some((scale, held)) => {
            check_regions_hold_points(&density.regions, &held)?;
            Some(scale)
        }
        None => None,
    })
}

/// [`kernel_scale`] on one MPI rank's part of the points: the scale, and how many of these
/// points each density region holds (to be summed over the ranks and checked with
/// [`check_regions_hold_points`]). `volume` is the whole object's.
///
/// # Errors
/// As [`kernel_scale`], but for the region check.
pub fn kernel_scale_part(
    points: &[Point3],
    volume: f64,
    kernels: usize,
    density: &KernelDensity,
    boundary_regions: &[Region],
    whole: Option<WholeObject<'_>>,
) -> Result<Option<(Vec<f64>, Vec<usize>)>> {
    density.validate()?;
    if density.is_off() {
        return Ok(None);
    }
    let band = density.bands.band * bulk_spacing(volume, kernels);
    check_band(volume, band, density.bands.band)?;
    let mut scale = vec![1.0; points.len()];
    if density.bands.boundaries != 1.0 {
        if boundary_regions.is_empty() {
            return Err(Error::param(
                "density boundaries",
                density.bands.boundaries,
                "refining near boundary regions needs a boundary-aware basis with at least one \
                 region; set the factor to 1 or add a region",
            ));
        }
        scale
            .par_iter_mut()
            .zip(points)
            .for_each(|(s, x): (&mut f64, _)| {
                let d = boundary_regions
                    .iter()
                    .map(|r| distance_to_surface(r, x))
                    .fold(f64::INFINITY, f64::min);
                *s *= taper(density.bands.boundaries, band, d);
            });
    }
    let needs_whole = |name: &'static str, value: f64| {
        whole.ok_or_else(|| {
            Error::param(
                name,
                value,
                "interface and thin-part refinement are not available across MPI ranks (a \
                 point's neighbours may live on another rank); run in one process or set them \
                 to 1",
            )
        })
    };
    // Both neighbour searches run on one index of all points, built when either needs it.
    let needs_index = density.bands.thin != 1.0 || density.bands.interfaces != 1.0;
    let all = if needs_index && whole.is_some() {
        Some(index(points, "kernel density", "integration points")?)
    } else {
        None
    };
    if density.bands.thin != 1.0 {
        let w = needs_whole("density thin", density.bands.thin)?;
        let all = all
            .as_ref()
            .expect("built when thin refinement has the whole object");
        let h0 = bulk_spacing(volume, kernels);
        let t = local_thickness(points, all, w.volumes, h0)?;
        scale
            .par_iter_mut()
            .zip(t)
            .for_each(|(s, t): (&mut f64, f64)| {
                *s *= thin_factor(density.bands.thin, h0, t);
            });
    }
    if density.bands.interfaces != 1.0 {
        let material = needs_whole("density interfaces", density.bands.interfaces)?.material;
        let all = all
            .as_ref()
            .expect("built when interface refinement has the whole object");
        let d = interface_distance(points, all, material)?;
        scale
            .par_iter_mut()
            .zip(d)
            .for_each(|(s, d): (&mut f64, f64)| {
                *s *= taper(density.bands.interfaces, band, d);
            });
    }
    let held = apply_regions(points, &density.regions, &mut scale);
    Ok(Some((scale, held)))
}

/// A band that spans the whole object refines nothing relative to the rest: refuse a band
/// wider than the side of a cube of the object's volume (the same figure on every MPI rank).
fn check_band(volume: f64, band: f64, in_spacings: f64) -> Result<()> {
    let side = volume.cbrt();
    if band >= side {
        return Err(Error::param(
            "density band",
            in_spacings,
            format!(
                "the band is {band:.3e} m wide, as wide as the object (the cube of its volume \
                 has sides of {side:.3e} m): it would refine the whole object; use a band of a \
                 few kernel spacings (default 1) or more kernels"
            ),
        ));
    }
    Ok(())
}

/// Multiply each point's scale by the factor of the last density region that holds it;
/// returns how many points each region holds.
fn apply_regions(points: &[Point3], regions: &[DensityRegion], scale: &mut [f64]) -> Vec<usize> {
    let mut held = vec![0usize; regions.len()];
    for (x, s) in points.iter().zip(scale.iter_mut()) {
        if let Some(i) = regions.iter().rposition(|r| r.region.contains(x)) {
            *s *= regions[i].factor;
            held[i] += 1;
        }
    }
    held
}

/// A density region holding no integration point at all (`held`: points per region, over the
/// whole object) is refused as a likely mistake in its coordinates.
///
/// # Errors
/// [`Error::InvalidParameter`] naming the first empty region.
pub fn check_regions_hold_points(regions: &[DensityRegion], held: &[usize]) -> Result<()> {
    if let Some(i) = held.iter().position(|&n| n == 0) {
        return Err(Error::param(
            "density region",
            format!("{i} ({:?})", regions[i].region),
            "holds no integration point of the object (or only points a later region takes); \
             check its coordinates (rest pose, metres)",
        ));
    }
    Ok(())
}

/// What interface and thin-part refinement need of the whole object in one process: every
/// point's material and volume (N each, in the points' order).
#[derive(Debug, Clone, Copy)]
pub struct WholeObject<'a> {
    /// Per-point materials.
    pub material: &'a MaterialField,
    /// Per-point volumes, m^3.
    pub volumes: &'a [f64],
}

/// The thin-part factor at local thickness `t` (metres): enough to put [`THIN_ACROSS`]
/// kernels across it, between 1 and `max`.
fn thin_factor(max: f64, h0: f64, t: f64) -> f64 {
    if max <= 1.0 {
        // A factor below 1 coarsens thin parts by it, wherever they are thinner than the
        // target (a user's choice; 1 is off).
        return if t < THIN_ACROSS * h0 { max } else { 1.0 };
    }
    (THIN_ACROSS * h0 / t).clamp(1.0, max)
}

/// Local thickness at every point, metres: twice the largest distance to the surface found
/// within 1.5 h0 (a thin part's medial axis is that close to each of its points). The surface
/// is where integration points lack a neighbour: a grid point with fewer than 6 others within
/// 1.2 of its spacing (its volume's cube root) lies in the outer layer, half a spacing inside.
fn local_thickness(
    points: &[Point3],
    tree: &ImmutableKdTree<f64, 3>,
    volumes: &[f64],
    h0: f64,
) -> Result<Vec<f64>> {
    let seven = std::num::NonZero::new(7).expect("7 > 0");
    let spacing: Vec<f64> = volumes.iter().map(|v| v.cbrt()).collect();
    let outer: Vec<Point3> = (0..points.len())
        .into_par_iter()
        .filter(|&i| {
            let r2 = (1.2 * spacing[i]).powi(2);
            let near = tree
                .query(&points[i])
                .nearest_n::<SquaredEuclidean<f64>>(seven)
                .execute()
                .iter()
                .filter(|n| n.item as usize != i && n.distance <= r2)
                .count();
            near < 6
        })
        .map(|i| points[i])
        .collect();
    if outer.is_empty() {
        return Err(Error::param(
            "density thin",
            points.len(),
            "no integration point lies at the object's surface (every point has all 6 grid \
             neighbours), so there is no thickness to estimate: thin-part refinement needs a \
             solid sampled on a grid (a mesh, primitive or image); set it to 1",
        ));
    }
    let depth: Vec<f64> = distance_to(&outer, points, "density thin")?
        .into_iter()
        .zip(&spacing)
        .map(|(d, h)| d + 0.5 * h)
        .collect();
    let deepest = BallMax::new(points, &depth, 1.5 * h0);
    let thickness: Vec<f64> = points
        .par_iter()
        .map(|p| 2.0 * deepest.max_within(p).max(0.0))
        .collect();
    if let Some(i) = thickness.iter().position(|t| !(t.is_finite() && *t > 0.0)) {
        return Err(Error::param(
            "density thin",
            thickness[i],
            format!(
                "the thickness estimate failed at integration point {i} ({:?}): check the \
                 shape (an open or degenerate mesh) or set the thin-part factor to 1",
                points[i]
            ),
        ));
    }
    Ok(thickness)
}

/// Whether two materials differ across an interface ([`INTERFACE_CONTRAST`]).
fn differs(m: &MaterialField, a: usize, b: usize) -> bool {
    let ratio = |x: f64, y: f64| x.max(y) / x.min(y);
    ratio(m.youngs[a], m.youngs[b]) > INTERFACE_CONTRAST
        || ratio(m.density[a], m.density[b]) > INTERFACE_CONTRAST
        || (m.poisson[a] - m.poisson[b]).abs() > 0.05
}

/// Neighbours checked per point for a material change: the 6 face neighbours of a grid point
/// and a few more for scattered clouds.
const INTERFACE_NEIGHBORS: usize = 8;

/// Distance from every point to the nearest point on a material interface (a point with a
/// neighbour of another material), metres.
fn interface_distance(
    points: &[Point3],
    tree: &ImmutableKdTree<f64, 3>,
    material: &MaterialField,
) -> Result<Vec<f64>> {
    let want = std::num::NonZero::new(INTERFACE_NEIGHBORS + 1).expect("9 > 0");
    let on_interface: Vec<Point3> = (0..points.len())
        .into_par_iter()
        .filter(|&i| {
            tree.query(&points[i])
                .nearest_n::<SquaredEuclidean<f64>>(want)
                .execute()
                .iter()
                .any(|n| differs(material, i, n.item as usize))
        })
        .map(|i| points[i])
        .collect();
    if on_interface.is_empty() {
        return Err(Error::param(
            "density interfaces",
            "no interface",
            format!(
                "the object has one material throughout (no neighbouring points differ by more \
                 than {INTERFACE_CONTRAST}x in modulus or density, e.g. a label image with a \
                 single label): there is no interface to refine; set the factor to 1"
            ),
        ));
    }
    distance_to(&on_interface, points, "density interfaces")
}

/// A k-d tree over `points` for the neighbour searches of `option` (`what` names the points
/// in the error).
fn index(points: &[Point3], option: &'static str, what: &str) -> Result<ImmutableKdTree<f64, 3>> {
    ImmutableKdTree::new_from_slice(points).map_err(|e| {
        Error::param(
            option,
            points.len(),
            format!("cannot index the {what}: {e:?}"),
        )
    })
}

/// Distance from every one of `points` to the nearest of `marked` (not empty), metres.
fn distance_to(marked: &[Point3], points: &[Point3], option: &'static str) -> Result<Vec<f64>> {
    const ONE: std::num::NonZero<usize> = std::num::NonZero::<usize>::MIN;
    let near = index(marked, option, "marked points")?;
    Ok(points
        .par_iter()
        .map(|p| {
            near.query(p)
                .nearest_n::<SquaredEuclidean<f64>>(ONE)
                .execute()
                .first()
                .map_or(f64::INFINITY, |n| n.distance.sqrt())
        })
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn grid(n: usize, len: f64) -> Vec<Point3> {
        let h = 1.0 / n as f64;
        let mut v = Vec::new();
        for k in 0..n {
            for j in 0..n {
                for i in 0..(len * n as f64) as usize {
                    v.push([
                        (i as f64 + 0.5) * h,
                        (j as f64 + 0.5) * h,
                        (k as f64 + 0.5) * h,
                    ]);
                }
            }
        }
        v
    }

    #[test]
    fn distances_to_region_surfaces_are_exact() {
        let half = Region::HalfSpace {
            point: [0.5, 0.0, 0.0],
            normal: [-2.0, 0.0, 0.0],
        };
        assert!((distance_to_surface(&half, &[0.2, 7.0, 1.0]) - 0.3).abs() < 1e-15);
        assert!((distance_to_surface(&half, &[0.9, 0.0, 0.0]) - 0.4).abs() < 1e-15);
        let ball = Region::Sphere {
            center: [0.0; 3],
            radius: 1.0,
        };
        assert!((distance_to_surface(&ball, &[0.0, 0.25, 0.0]) - 0.75).abs() < 1e-15);
        assert!((distance_to_surface(&ball, &[0.0, 0.0, 3.0]) - 2.0).abs() < 1e-15);
        let b = Region::Box {
            min: [0.0; 3],
            max: [1.0, 2.0, f64::INFINITY],
        };
        // Inside: the nearest finite face; outside: the Euclidean distance to the box.
        assert!((distance_to_surface(&b, &[0.5, 1.9, 5.0]) - 0.1).abs() < 1e-12);
        assert!((distance_to_surface(&b, &[-3.0, 6.0, 1.0]) - 5.0).abs() < 1e-12);
    }

    #[test]
    fn boundary_bands_grade_from_the_factor_to_one() {
        let pts = grid(8, 4.0);
        let held = Region::HalfSpace {
            point: [1.0, 0.0, 0.0],
            normal: [-1.0, 0.0, 0.0],
        };
        let d = KernelDensity::bands(DensityBands {
            boundaries: 2.0,
            band: 1.0,
            ..DensityBands::off()
        });
        // V = 4, K = 32: h0 = 0.5 m, so the factor is 2 within 0.5 m of x = 1 and 1 past 1 m.
        let s = kernel_scale(&pts, 4.0, 32, &d, &[held], None)
            .unwrap()
            .unwrap();
        for (p, s) in pts.iter().zip(&s) {
            let dist = (p[0] - 1.0).abs();
            let want = if dist <= 0.5 {
                2.0
            } else if dist >= 1.0 {
                1.0
            } else {
                2.0 - (dist - 0.5) / 0.5
            };
            assert!((s - want).abs() < 1e-12, "{p:?}: {s} vs {want}");
        }
        assert!(
            kernel_scale(&pts, 4.0, 32, &KernelDensity::off(), &[held], None)
                .unwrap()
                .is_none()
        );
    }

    #[test]
    fn thin_parts_are_found_by_their_depth_below_the_surface() {
        // A 1 m cube with a 0.25 m thick fin beside it, on a grid of 1/16 m.
        let h = 1.0 / 16.0;
        let mut pts = Vec::new();
        for i in 0..32 {
            for j in 0..16 {
                for k in 0..16 {
                    let p = [
                        (i as f64 + 0.5) * h,
                        (j as f64 + 0.5) * h,
                        (k as f64 + 0.5) * h,
                    ];
                    if p[0] < 1.0 || p[2] < 0.25 {
                        pts.push(p);
                    }
                }
            }
        }
        let volumes = vec![h * h * h; pts.len()];
        let h0 = 0.3;
        let all = index(&pts, "test", "points").unwrap();
        let t = local_thickness(&pts, &all, &volumes, h0).unwrap();
        for (p, t) in pts.iter().zip(&t) {
            if p[0] > 1.5 {
                // The fin, away from the cube: its thickness to within a grid spacing (an even
                // number of layers, 4 here, has no point on the mid-plane: 0.1875 m).
                assert!((t - 0.25).abs() <= h, "{p:?}: {t}");
                // 3 kernels across 0.25 m want a spacing of 0.083 m: 3.6x finer than h0 (4.8x
                // from the estimate 0.1875 m).
                let f = thin_factor(8.0, h0, *t);
                assert!((3.0..=4.8).contains(&f), "{p:?}: {f}");
            }
            if (0..3).all(|d| (p[d] - 0.5).abs() < 0.2) {
                // The cube's core: at least twice the reach of the estimate, no refinement.
                assert!(*t >= 0.9, "{p:?}: {t}");
                assert_eq!(thin_factor(8.0, h0, *t), 1.0);
            }
        }
        // A single sheet of grid points: every point is in the outer layer, so the sheet is
        // one spacing thick.
        let sheet: Vec<Point3> = (0..100)
            .map(|i| [(i % 10) as f64 * h, (i / 10) as f64 * h, 0.0])
            .collect();
        let all = index(&sheet, "test", "points").unwrap();
        let t = local_thickness(&sheet, &all, &vec![h * h * h; 100], h0).unwrap();
        assert!(t.iter().all(|t| (t - h).abs() < 1e-12), "{t:?}");
    }

    #[test]
    fn interfaces_are_found_between_materials_only() {
        let pts = grid(6, 2.0);
        let m = crate::material::Material::default();
        let mut field = MaterialField::homogeneous(pts.len(), &m).unwrap();
        for (i, p) in pts.iter().enumerate() {
            if p[0] > 1.0 {
                field.youngs[i] *= 100.0;
            }
        }
        let all = index(&pts, "test", "points").unwrap();
        let d = interface_distance(&pts, &all, &field).unwrap();
        for (p, d) in pts.iter().zip(&d) {
            // The points next to x = 1 (at 1 -/+ h/2) are on the interface.
            let want = ((p[0] - 1.0).abs() - 1.0 / 12.0).max(0.0);
            assert!((d - want).abs() < 1e-9, "{p:?}: {d} vs {want}");
        }
    }

    #[test]
    fn bad_densities_name_what_is_wrong() {
        let pts = grid(4, 2.0);
        let m = crate::material::Material::default();
        let one = MaterialField::homogeneous(pts.len(), &m).unwrap();
        let volumes = vec![1.0 / 64.0; pts.len()];
        let whole = WholeObject {
            material: &one,
            volumes: &volumes,
        };
        let run = |d: &KernelDensity, regions: &[Region]| {
            kernel_scale(&pts, 2.0, 16, d, regions, Some(whole))
                .unwrap_err()
                .to_string()
        };
        let held = Region::HalfSpace {
            point: [0.5, 0.0, 0.0],
            normal: [-1.0, 0.0, 0.0],
        };
        for f in [f64::NAN, 0.0, -1.0, 0.1, 100.0] {
            let e = run(
                &KernelDensity::bands(DensityBands {
                    boundaries: f,
                    ..DensityBands::off()
                }),
                &[held],
            );
            assert!(e.contains("density boundaries"), "{e}");
        }
        for f in [f64::NAN, 0.0, -2.0] {
            let d = KernelDensity {
                regions: vec![DensityRegion {
                    region: held,
                    factor: f,
                }],
                ..KernelDensity::off()
            };
            assert!(run(&d, &[]).contains("density region"));
        }
        let far = KernelDensity {
            regions: vec![DensityRegion {
                region: Region::Sphere {
                    center: [9.0; 3],
                    radius: 1.0,
                },
                factor: 2.0,
            }],
            ..KernelDensity::off()
        };
        assert!(run(&far, &[]).contains("holds no integration point"));
        let interfaces = KernelDensity::bands(DensityBands {
            interfaces: 2.0,
            ..DensityBands::off()
        });
        assert!(run(&interfaces, &[]).contains("one material throughout"));
        let wide = KernelDensity::bands(DensityBands {
            boundaries: 2.0,
            band: 50.0,
            ..DensityBands::off()
        });
        assert!(run(&wide, &[held]).contains("as wide as the object"));
        let no_region = KernelDensity::bands(DensityBands {
            boundaries: 2.0,
            ..DensityBands::off()
        });
        assert!(run(&no_region, &[]).contains("boundary-aware"));
    }
}
