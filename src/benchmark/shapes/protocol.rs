//! The real-shape protocol (paper Sec. 4, Table 2; docs/evaluation.md): a surface normalized
//! to a unit bounding box, one homogeneous material, and three boundary conditions given as
//! regions with rigid motions, the same for the FEM reference and the reduced model.

use crate::material::{Material, Region};
use crate::sim::motion::Motion;
use crate::sim::{Boundary, NewtonOptions, SimOptions};
use crate::{Error, Point3, Result};
use serde::Serialize;

/// One of the three boundary conditions of the protocol.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum ShapeTest {
    /// The slab at the low end of the longest axis held, the rest hanging under gravity.
    FixSide,
    /// Small balls around the 4 farthest-point-sampled surface vertices pulled outwards
    /// (each away from the bounding-box centre); no gravity.
    PullFarthest,
    /// The slabs at both ends of the longest axis pulled apart along it; no gravity.
    PullEnds,
}

impl ShapeTest {
    /// All three, in the paper's order.
    pub const ALL: [ShapeTest; 3] = [
        ShapeTest::FixSide,
        ShapeTest::PullFarthest,
        ShapeTest::PullEnds,
    ];

    /// "fix_side", "pull_farthest" or "pull_ends".
    pub fn name(&self) -> &'static str {
        crate::names::variant_name(self)
    }
}

/// The protocol's numbers. Every field has a documented default (the values of
/// docs/evaluation.md).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Protocol {
    /// The material of every shape. Default E = 1e5 Pa, nu = 0.4, rho = 1000 kg/m^3 (the
    /// paper's organic value for all shapes: under gravity a stiffer one barely moves).
    pub material: Material,
    /// Time step, s. Default 0.01.
    pub dt: f64,
    /// Steps. Default 50 (0.5 s).
    pub steps: usize,
    /// Thickness of the held and pulled slabs, as a fraction of the longest side (= 1 m
    /// after normalization). Default 0.1.
    pub slab: f64,
    /// Radius of the balls around the farthest points, metres. Default 0.08.
    pub ball_radius: f64,
    /// Speed of every pulled region, m/s. Default 0.2 (0.1 m, a tenth of the box, over the
    /// default run).
    pub pull_speed: f64,
    /// Gravity of the fix-side test, m/s^2 (along [`gravity_axis`]). Default 9.81.
    pub gravity: f64,
}

impl Default for Protocol {
    fn default() -> Self {
        Self {
            material: Material {
                youngs: 1e5,
                poisson: 0.4,
                density: 1000.0,
            },
            dt: 0.01,
            steps: 50,
            slab: 0.1,
            ball_radius: 0.08,
            pull_speed: 0.2,
            gravity: 9.81,
        }
    }
}

impl Protocol {
    /// Check every number.
    ///
    /// # Errors
    /// [`Error::InvalidParameter`] naming the field.
    pub fn validate(&self) -> Result<()> {
        self.material.validate()?;
        let positive = |name: &'static str, v: f64| {
            if v.is_finite() && v > 0.0 {
                Ok(())
            } else {
                Err(Error::param(name, v, "must be a positive finite number"))
            }
        };
        positive("dt", self.dt)?;
        positive("ball_radius", self.ball_radius)?;
        positive("pull_speed", self.pull_speed)?;
        if !(self.slab > 0.0 && self.slab < 0.5) {
            return Err(Error::param(
                "slab",
                self.slab,
                "the slab fraction must lie in (0, 0.5) so the two end slabs do not meet",
            ));
        }
        if !(self.gravity.is_finite() && self.gravity >= 0.0) {
            return Err(Error::param(
                "gravity",
                self.gravity,
                "must be finite, >= 0",
            ));
        }
        if self.steps == 0 {
            return Err(Error::param("steps", 0, "at least one step"));
        }
        Ok(())
    }
}

/// A closed surface scaled and moved so that its bounding box is [0, 1] along its longest
/// axis and starts at 0 along the others (every side <= 1 m).
#[derive(Debug, Clone)]
pub struct NormalizedShape {
    /// Vertices, V x 3, metres (normalized).
    pub vertices: Vec<Point3>,
    /// Triangles, F x 3 zero-based indices.
    pub triangles: Vec<[u32; 3]>,
    /// The longest axis (0, 1 or 2; the first of equal ones).
    pub longest_axis: usize,
    /// Original length of the longest side (the divisor), in the file's units.
    pub scale: f64,
    /// Sides of the normalized bounding box, metres (the longest is 1).
    pub extent: Point3,
}

/// Normalize a surface (see [`NormalizedShape`]).
///
/// # Errors
/// [`Error::InvalidParameter`] for no vertices or triangles, a non-finite coordinate, or all
/// vertices coinciding (no longest side to scale by).
pub fn normalize(vertices: &[Point3], triangles: &[[u32; 3]]) -> Result<NormalizedShape> {
    crate::error::check_finite_points("shape vertices", vertices)?;
    if triangles.is_empty() {
        return Err(Error::param(
            "shape",
            "0 triangles",
            "the surface has no triangles",
        ));
    }
    let bb = crate::geometry::Aabb::from_points(vertices)
        .ok_or_else(|| Error::param("shape", "0 vertices", "the surface has no vertices"))?;
    let side = [0, 1, 2].map(|d| bb.max[d] - bb.min[d]);
    let longest_axis = (0..3).fold(0, |a, d| if side[d] > side[a] { d } else { a });
    let scale = side[longest_axis];
    if scale <= 0.0 {
        return Err(Error::param(
            "shape",
            "all vertices coincide",
            "the surface has no extent to normalize; check the file",
        ));
    }
    let vertices = vertices
        .iter()
        .map(|p| [0, 1, 2].map(|d| (p[d] - bb.min[d]) / scale))
        .collect();
    Ok(NormalizedShape {
        vertices,
        triangles: triangles.to_vec(),
        longest_axis,
        scale,
        extent: side.map(|s| s / scale),
    })
}

/// The axis gravity acts along (downwards) in the fix-side test: y, or z when y is the
/// longest axis, so it always bends the shape across its length.
pub fn gravity_axis(longest_axis: usize) -> usize {
    if longest_axis == 1 {
        2
    } else {
        1
    }
}

/// The gravity vector of `test` on `shape`, m/s^2 (zero for the pull tests).
pub fn gravity(protocol: &Protocol, shape: &NormalizedShape, test: ShapeTest) -> Point3 {
    let mut g = [0.0; 3];
    if test == ShapeTest::FixSide {
        g[gravity_axis(shape.longest_axis)] = -protocol.gravity;
    }
    g
}

/// `count` surface vertices by farthest-point sampling: first the vertex farthest from the
/// bounding-box centre, then repeatedly the vertex farthest from those chosen (Euclidean).
/// Returns indices into `shape.vertices` (fewer when there are fewer distinct vertices).
pub fn farthest_vertices(shape: &NormalizedShape, count: usize) -> Vec<usize> {
    let v = &shape.vertices;
    let centre = shape.extent.map(|e| 0.5 * e);
    let d2 = |a: &Point3, b: &Point3| (0..3).map(|k| (a[k] - b[k]).powi(2)).sum::<f64>();
    let mut chosen = Vec::with_capacity(count);
    let Some(first) =
        (0..v.len()).max_by(|&a, &b| d2(&v[a], &centre).total_cmp(&d2(&v[b], &centre)))
    else {
        return chosen;
    };
    let mut nearest: Vec<f64> = v.iter().map(|p| d2(p, &v[first])).collect();
    chosen.push(first);
    while chosen.len() < count {
        let (next, far) =
            nearest.iter().enumerate().fold(
                (0, -1.0),
                |(i, m), (j, &d)| if d > m { (j, d) } else { (i, m) },
            );
        if far <= 0.0 {
            break;
        }
        chosen.push(next);
        for (n, p) in nearest.iter_mut().zip(v) {
            *n = n.min(d2(p, &v[next]));
        }
    }
    chosen
}

/// The driven regions of `test` on `shape` with their motions (rest coordinates, metres):
/// the FEM reference holds or moves its nodes in them, the reduced model its integration
/// points (and, for boundary-aware bases, builds lifts for them).
pub fn boundary_regions(
    protocol: &Protocol,
    shape: &NormalizedShape,
    test: ShapeTest,
) -> Vec<(Region, Motion)> {
    let a = shape.longest_axis;
    let unit = |sign: f64| {
        let mut e = [0.0; 3];
        e[a] = sign;
        e
    };
    let slab = |at_low: bool| {
        let mut point = [0.0; 3];
        point[a] = if at_low {
            protocol.slab
        } else {
            1.0 - protocol.slab
        };
        Region::HalfSpace {
            point,
            normal: unit(if at_low { -1.0 } else { 1.0 }),
        }
    };
    let pull = |dir: Point3| Motion::Translate {
        velocity: dir.map(|c| c * protocol.pull_speed),
    };
    match test {
        ShapeTest::FixSide => vec![(slab(true), Motion::Fixed)],
        ShapeTest::PullEnds => vec![
            (slab(true), pull(unit(-1.0))),
            (slab(false), pull(unit(1.0))),
        ],
        ShapeTest::PullFarthest => {
            let centre = shape.extent.map(|e| 0.5 * e);
            farthest_vertices(shape, 4)
                .into_iter()
                .map(|i| {
                    let p = shape.vertices[i];
                    let d = [0, 1, 2].map(|k| p[k] - centre[k]);
                    let len = d.iter().map(|c| c * c).sum::<f64>().sqrt();
                    let dir = if len > 1e-9 {
                        d.map(|c| c / len)
                    } else {
                        unit(1.0)
                    };
                    let region = Region::Sphere {
                        center: p,
                        radius: protocol.ball_radius,
                    };
                    (region, pull(dir))
                })
                .collect()
        }
    }
}

/// The reduced simulation of `test`: the protocol's step and gravity, its regions as
/// penalty boundaries (default stiffness), `cubature` points, solver `newton`.
pub fn sim_options(
    protocol: &Protocol,
    shape: &NormalizedShape,
    test: ShapeTest,
    cubature: usize,
    newton: NewtonOptions,
) -> SimOptions {
    let g = gravity(protocol, shape, test);
    SimOptions {
        dt: protocol.dt,
        gravity: g.iter().any(|v| *v != 0.0).then_some(g),
        cubature,
        newton,
        boundaries: boundary_regions(protocol, shape, test)
            .into_iter()
            .map(|(region, motion)| Boundary {
                region,
                motion,
                stiffness: None,
            })
            .collect(),
        ..SimOptions::default()
    }
}
