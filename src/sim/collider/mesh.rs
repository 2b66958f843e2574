//! Triangle-mesh obstacles: a closed solid or a one-sided surface, read from OBJ, STL, OFF or
//! PLY with the readers of [`crate::io`], validated, and queried through parry's BVH.
//!
//! **Queries.** [`MeshObstacle::penetration_local`] asks parry (`TriMesh` with the `ORIENTED`
//! flag, `project_local_point_and_get_location` with `solid = false`) for the closest surface
//! point, the feature it lies on (face, edge or vertex of a triangle) and the inside test by
//! the angle-weighted pseudo-normal of that feature (Baerentzen and Aanaes 2005), which is
//! exact for a closed, consistently oriented mesh. [`MeshObstacle::penetration_brute_force`]
//! is the O(F) reference the tests compare against: every triangle's closest point, and the
//! sign from the generalized winding number (solids) or its own pseudo-normals (surfaces).
//!
//! **Modes** ([`Sided`]). `solid`: the mesh must be closed and consistently oriented; its
//! inside is the obstacle (an inward-facing file is flipped as a whole, as for object meshes).
//! `outside`: a one-sided surface that may be open (terrain, an open container): the side its
//! triangle normals ((b - a) x (c - a), counter-clockwise seen from that side) point to is
//! free; a point behind the surface's nearest feature penetrates, however far. Beyond an open
//! boundary the surface continues as the planes of its boundary triangles
//! ([`super::open_boundary`]): a point whose nearest feature is on the boundary penetrates by
//! its distance to the free side of those planes, so the depth is continuous across them (an
//! object reaching over a container's rim is pushed back in, smoothly); keep objects from
//! reaching round behind.
//!
//! **Bad input** is refused with the file and what is wrong: no triangles (a point-cloud PLY),
//! a zero-area triangle (its index in the file's triangle order; fan-triangulated faces count
//! one triangle each), a solid mesh that is open, non-manifold or inconsistently oriented, a
//! surface with non-manifold or inconsistently oriented edges.

use super::open_boundary::{behind_planes, OpenBoundary, Plane};
use super::penetration::Penetration;
use crate::error::GeometryError;
use crate::geometry::{
    weld_exact, Aabb, EdgeReport, ShapeFileFormat, ShapeOptions, ShapeSpec, UpAxis,
};
use crate::linalg3::{cross, dot, identity_minus_outer, norm, outer, sub};
use crate::sim::motion::Rigid;
use crate::{Error, Point3, Result};
use parry3d_f64::math::Vector;
use parry3d_f64::query::PointQueryWithLocation;
use parry3d_f64::shape::{TriMesh as ParryMesh, TriMeshFlags, TrianglePointLocation};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// Which side of a mesh collider is the obstacle.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Sided {
    /// A closed, consistently oriented mesh; its inside is the obstacle (default).
    #[default]
    Solid,
    /// A one-sided surface, possibly open: the side the triangle normals point to is free,
    /// the other side is the obstacle.
    Outside,
}

impl Sided {
    /// The scene-file name: "solid" or "outside".
    pub fn name(self) -> &'static str {
        crate::names::variant_name(&self)
    }
}

/// A loaded, validated triangle-mesh obstacle with its BVH, in its rest frame.
pub struct MeshObstacle {
    path: PathBuf,
    sided: Sided,
    vertices: Vec<Point3>,
    triangles: Vec<[u32; 3]>,
    aabb: Aabb,
    bvh: ParryMesh,
    /// The open boundary (none for solids).
    boundary: OpenBoundary,
}

impl std::fmt::Debug for MeshObstacle {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("MeshObstacle")
            .field("path", &self.path)
            .field("sided", &self.sided)
            .field("vertices", &self.vertices.len())
            .field("triangles", &self.triangles.len())
            .field("aabb", &self.aabb)
            .field("boundary_edges", &self.boundary.edges())
            .finish_non_exhaustive()
    }
}

/// Relative area below which a triangle counts as degenerate: |(b - a) x (c - a)| <=
/// 1e-10 x (longest edge)^2, i.e. its smallest angle is below ~1e-10 rad, where its normal
/// (and so the pseudo-normals of its edges and vertices) is no longer defined to working
/// accuracy.
const DEGENERATE_AREA: f64 = 1e-10;

fn to_vec(p: &Point3) -> Vector {
    Vector::new(p[0], p[1], p[2])
}

fn from_vec(v: Vector) -> Point3 {
    [v.x, v.y, v.z]
}

impl MeshObstacle {
    /// Read and validate the mesh file at `path`, its coordinates scaled by `scale` and then
    /// moved by `pose`.
    ///
    /// # Errors
    /// The readers' `Io` and `Parse` errors (a PLY without faces is a `Parse` error); the
    /// mesh checks of [`MeshObstacle::from_triangles`].
    pub fn read(path: &Path, scale: f64, pose: &Rigid, sided: Sided) -> Result<MeshObstacle> {
        Self::read_in(path, scale, pose, sided, UpAxis::Y)
    }

    /// As [`Self::read`], a USD stage's mesh prim (`scene.usda:/World/Table`) read into a
    /// frame whose up axis is `up`, in metres (the stage's units) before `scale`.
    ///
    /// # Errors
    /// As [`Self::read`]; [`GeometryError::Usd`] for a prim that is not a mesh.
    pub fn read_in(
        path: &Path,
        scale: f64,
        pose: &Rigid,
        sided: Sided,
        up: UpAxis,
    ) -> Result<MeshObstacle> {
        let (vertices, triangles) = read_triangles(path, up)?;
        let vertices = vertices
            .iter()
            .map(|p| pose.apply(&p.map(|c| c * scale)))
            .collect();
        Ok(MeshObstacle::from_triangles(
            path, vertices, triangles, sided,
        )?)
    }

    /// Validate a mesh (`vertices` V x 3, metres; `triangles` F x 3 zero-based) and build its
    /// BVH; `path` labels the errors.
    ///
    /// # Errors
    /// - [`GeometryError::Parse`]: no triangles, or an index out of range.
    /// - [`GeometryError::Degenerate`]: a non-finite vertex; a solid that encloses no volume.
    /// - [`GeometryError::DegenerateTriangle`]: a triangle of (near-)zero area.
    /// - [`GeometryError::ColliderNotClosed`]: a solid that is open, non-manifold or
    ///   inconsistently oriented.
    /// - [`GeometryError::ColliderSurface`]: a surface with non-manifold or inconsistently
    ///   oriented edges.
    pub fn from_triangles(
        path: &Path,
        vertices: Vec<Point3>,
        triangles: Vec<[u32; 3]>,
        sided: Sided,
    ) -> std::result::Result<MeshObstacle, GeometryError> {
        let parse = |reason: String| GeometryError::Parse {
            path: path.to_path_buf(),
            reason,
        };
        if triangles.is_empty() {
            return Err(parse(
                "a collider mesh needs triangles, and the file has none".into(),
            ));
        }
        if let Some(i) = vertices
            .iter()
            .position(|p| !p.iter().all(|c| c.is_finite()))
        {
            return Err(GeometryError::Degenerate(format!(
                "{}: vertex {i} has a non-finite coordinate {:?}",
                path.display(),
                vertices[i]
            )));
        }
        let nv = vertices.len();
        if let Some((f, t)) = triangles
            .iter()
            .enumerate()
            .find(|(_, t)| t.iter().any(|&i| i as usize >= nv))
        {
            return Err(parse(format!(
                "triangle {f} = {t:?} refers past the {nv} vertices"
            )));
        }
        let degenerate: Vec<usize> = triangles
            .iter()
            .enumerate()
            .filter(|(_, t)| {
                let [a, b, c] = t.map(|i| vertices[i as usize]);
                let (ab, ac, bc) = (sub(&b, &a), sub(&c, &a), sub(&c, &b));
                let longest = norm(&ab).max(norm(&ac)).max(norm(&bc));
                norm(&cross(&ab, &ac)).partial_cmp(&(DEGENERATE_AREA * longest * longest))
                    != Some(std::cmp::Ordering::Greater)
            })
            .map(|(f, _)| f)
            .collect();
        if let Some(&first) = degenerate.first() {
            return Err(GeometryError::DegenerateTriangle {
                path: path.to_path_buf(),
                triangle: first,
                count: degenerate.len(),
                total: triangles.len(),
            });
        }
        let (vertices, triangles) = weld_exact(&vertices, &triangles);
        let edges = EdgeReport::of(&triangles);
        let (vertices, triangles) = match sided {
            Sided::Solid => {
                if !edges.is_closed() || edges.misoriented_edges > 0 {
                    return Err(GeometryError::ColliderNotClosed {
                        path: path.to_path_buf(),
                        boundary_edges: edges.boundary_edges,
                        nonmanifold_edges: edges.nonmanifold_edges,
                        misoriented_edges: edges.misoriented_edges,
                    });
                }
                // Orientation (an inward-facing file is flipped) and the volume check.
                crate::geometry::TriMesh::new(vertices, triangles, &ShapeOptions::default())
                    .map_err(|e| e.with_path(path))?
                    .into_parts()
            }
            Sided::Outside => {
                if edges.nonmanifold_edges > 0 || edges.misoriented_edges > 0 {
                    return Err(GeometryError::ColliderSurface {
                        path: path.to_path_buf(),
                        nonmanifold_edges: edges.nonmanifold_edges,
                        misoriented_edges: edges.misoriented_edges,
                    });
                }
                (vertices, triangles)
            }
        };
        let used: Vec<Point3> = triangles
            .iter()
            .flat_map(|t| t.map(|i| vertices[i as usize]))
            .collect();
        let aabb = Aabb::from_points(&used).expect("at least one triangle");
        let bvh = ParryMesh::with_flags(
            vertices.iter().map(to_vec).collect(),
            triangles.clone(),
            TriMeshFlags::ORIENTED,
        )
        .map_err(|e| parse(format!("parry could not build the mesh: {e:?}")))?;
        let boundary = OpenBoundary::of(&triangles);
        Ok(MeshObstacle {
            path: path.to_path_buf(),
            sided,
            vertices,
            triangles,
            aabb,
            bvh,
            boundary,
        })
    }

    /// The file it was read from (or the label given).
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Solid or one-sided surface.
    pub fn sided(&self) -> Sided {
        self.sided
    }

    /// Vertices after welding and placement, V x 3, metres.
    pub fn vertices(&self) -> &[Point3] {
        &self.vertices
    }

    /// Triangles, F x 3 zero-based, oriented with normals towards the free side.
    pub fn triangles(&self) -> &[[u32; 3]] {
        &self.triangles
    }

    /// Bounding box of the triangles, metres.
    pub fn bounding_box(&self) -> Aabb {
        self.aabb
    }

    /// A sphere holding every point that can penetrate (solids: the bounding box's), None
    /// for a one-sided surface (unbounded behind).
    pub fn bounding_sphere(&self) -> Option<(Point3, f64)> {
        match self.sided {
            Sided::Solid => Some((self.aabb.center(), 0.5 * self.aabb.diagonal())),
            Sided::Outside => None,
        }
    }

    /// The penetration of the point `y` (rest frame, metres), through parry's BVH.
    pub fn penetration_local(&self, y: &Point3) -> Option<Penetration> {
        if self.sided == Sided::Solid && !self.aabb.contains(y) {
            return None;
        }
        let (proj, (tri, location)) = self
            .bvh
            .project_local_point_and_get_location(to_vec(y), false);
        let feature = self.feature(tri, location);
        if let Some(beyond) = self.beyond_boundary(y, feature) {
            return beyond;
        }
        if !proj.is_inside {
            return None;
        }
        self.penetration_at(y, &from_vec(proj.point), feature)
    }

    /// The feature of triangle `tri` that parry located a closest point on.
    fn feature(&self, tri: u32, location: TrianglePointLocation) -> Feature {
        let t = self.triangles[tri as usize];
        match location {
            TrianglePointLocation::OnVertex(i) => Feature::Vertex(t[i as usize]),
            // Parry numbers the edges AB, BC, AC.
            TrianglePointLocation::OnEdge(i, _) => match i {
                0 => Feature::Edge(t[0], t[1]),
                1 => Feature::Edge(t[1], t[2]),
                _ => Feature::Edge(t[0], t[2]),
            },
            TrianglePointLocation::OnFace(..) | TrianglePointLocation::OnSolid => {
                Feature::Face(tri)
            }
        }
    }

    /// For a closest point on the open boundary (`feature` a boundary edge or vertex): the
    /// penetration of `y` behind the planes of the boundary triangles there (`Some(None)`: in
    /// front of them). None for any other feature, whose pseudo-normal decides.
    fn beyond_boundary(&self, y: &Point3, feature: Feature) -> Option<Option<Penetration>> {
        // Every plane passes through `at` (a vertex of its triangle): at a vertex, the point
        // where they meet.
        let (planes, at) = match feature {
            Feature::Edge(a, b) => (self.boundary.edge_planes(a, b)?, a),
            Feature::Vertex(v) => (self.boundary.vertex_planes(v)?, v),
            Feature::Face(_) => return None,
        };
        let plane = |t: u32| {
            let [a, b, c] = self.triangles[t as usize].map(|i| self.vertices[i as usize]);
            Plane {
                on: self.vertices[at as usize],
                normal: self.face_normal(t as usize),
                centroid: std::array::from_fn(|k| (a[k] + b[k] + c[k]) / 3.0),
            }
        };
        // One or two planes almost always (this runs for every point nearest the boundary):
        // no allocation for those.
        Some(match *planes {
            [t] => behind_planes(y, &[plane(t)]),
            [t1, t2] => behind_planes(y, &[plane(t1), plane(t2)]),
            _ => behind_planes(y, &planes.iter().map(|&t| plane(t)).collect::<Vec<_>>()),
        })
    }

    /// The signed distance of `y` given its closest point `c` on `feature` and whether the
    /// pseudo-normal test put it behind: beyond the open boundary, minus the depth behind
    /// the boundary planes.
    fn signed(&self, y: &Point3, c: &Point3, feature: Feature, behind: bool) -> f64 {
        let d = norm(&sub(c, y));
        match self.beyond_boundary(y, feature) {
            Some(Some(p)) => -p.depth,
            Some(None) => d,
            None if behind => -d,
            None => d,
        }
    }

    /// The penetration of `y` from its closest surface point `c` on `feature`.
    fn penetration_at(&self, y: &Point3, c: &Point3, feature: Feature) -> Option<Penetration> {
        let v = sub(c, y);
        let depth = norm(&v);
        // Zero (on the surface) or NaN: no penetration.
        if depth.is_nan() || depth <= 0.0 {
            return None;
        }
        let normal = v.map(|x| x / depth);
        let hessian = match feature {
            Feature::Face(t) => {
                let n = self.face_normal(t as usize);
                outer(&n)
            }
            Feature::Edge(a, b) => {
                let e = sub(&self.vertices[b as usize], &self.vertices[a as usize]);
                let l = norm(&e);
                identity_minus_outer(&e.map(|x| x / l))
            }
            Feature::Vertex(_) => identity_minus_outer(&[0.0; 3]),
        };
        Some(Penetration {
            depth,
            normal,
            hessian,
            hessian_psd: hessian,
        })
    }

    fn face_normal(&self, t: usize) -> [f64; 3] {
        let [a, b, c] = self.triangles[t].map(|i| self.vertices[i as usize]);
        let n = cross(&sub(&b, &a), &sub(&c, &a));
        let l = norm(&n);
        n.map(|x| x / l)
    }

    /// Signed distance of `y` (rest frame, metres) through the BVH: positive on the free
    /// side, negative inside (solid) or behind (surface; beyond its open boundary, minus the
    /// depth behind the boundary planes, as [`MeshObstacle::penetration_local`] has it).
    pub fn signed_distance(&self, y: &Point3) -> f64 {
        let (proj, (tri, location)) = self
            .bvh
            .project_local_point_and_get_location(to_vec(y), false);
        let feature = self.feature(tri, location);
        self.signed(y, &from_vec(proj.point), feature, proj.is_inside)
    }

    /// [`MeshObstacle::signed_distance`] by brute force, O(F): the closest point over every
    /// triangle; the sign from the generalized winding number (solids: inside where it is at
    /// least 1/2) or from the angle-weighted pseudo-normal of the closest feature (surfaces),
    /// computed here independently of parry.
    pub fn signed_distance_brute_force(&self, y: &Point3) -> f64 {
        let (c, feature) = self.closest_brute_force(y);
        self.signed(y, &c, feature, self.inside_brute_force(y, &c, feature))
    }

    /// [`MeshObstacle::penetration_local`] by brute force (see
    /// [`MeshObstacle::signed_distance_brute_force`]).
    pub fn penetration_brute_force(&self, y: &Point3) -> Option<Penetration> {
        let (c, feature) = self.closest_brute_force(y);
        if let Some(beyond) = self.beyond_boundary(y, feature) {
            return beyond;
        }
        if !self.inside_brute_force(y, &c, feature) {
            return None;
        }
        self.penetration_at(y, &c, feature)
    }

    fn inside_brute_force(&self, y: &Point3, c: &Point3, feature: Feature) -> bool {
        match self.sided {
            Sided::Solid => {
                crate::geometry::winding::winding_numbers_exact(
                    &self.vertices,
                    &self.triangles,
                    &[*y],
                )[0] >= 0.5
            }
            Sided::Outside => dot(&sub(y, c), &self.pseudo_normal(feature, c)) <= 0.0,
        }
    }

    /// The angle-weighted pseudo-normal of a feature (not normalized), by scanning every
    /// triangle; `c` locates the vertex of a vertex feature.
    fn pseudo_normal(&self, feature: Feature, c: &Point3) -> [f64; 3] {
        match feature {
            Feature::Face(t) => self.face_normal(t as usize),
            Feature::Edge(a, b) => {
                let mut n = [0.0; 3];
                for (t, tri) in self.triangles.iter().enumerate() {
                    if tri.contains(&a) && tri.contains(&b) {
                        let f = self.face_normal(t);
                        n = std::array::from_fn(|d| n[d] + f[d]);
                    }
                }
                n
            }
            Feature::Vertex(_) => {
                let mut n = [0.0; 3];
                for (t, tri) in self.triangles.iter().enumerate() {
                    for k in 0..3 {
                        let p = self.vertices[tri[k] as usize];
                        if p != *c {
                            continue;
                        }
                        let e1 = sub(&self.vertices[tri[(k + 1) % 3] as usize], &p);
                        let e2 = sub(&self.vertices[tri[(k + 2) % 3] as usize], &p);
                        let cos = (dot(&e1, &e2) / (norm(&e1) * norm(&e2))).clamp(-1.0, 1.0);
                        let f = self.face_normal(t);
                        n = std::array::from_fn(|d| n[d] + cos.acos() * f[d]);
                    }
                }
                n
            }
        }
    }

    /// The closest surface point to `y` over every triangle, and its feature.
    fn closest_brute_force(&self, y: &Point3) -> (Point3, Feature) {
        let mut best = (f64::INFINITY, [0.0; 3], Feature::Face(0));
        for (t, tri) in self.triangles.iter().enumerate() {
            let [a, b, c] = tri.map(|i| self.vertices[i as usize]);
            let (p, region) = closest_on_triangle(y, &a, &b, &c);
            let d2 = dot(&sub(&p, y), &sub(&p, y));
            if d2 < best.0 {
                let feature = match region {
                    Region::Face => Feature::Face(t as u32),
                    Region::Edge(i, j) => Feature::Edge(tri[i], tri[j]),
                    Region::Vertex(k) => Feature::Vertex(tri[k]),
                };
                best = (d2, p, feature);
            }
        }
        (best.1, best.2)
    }
}

/// The feature of the mesh a closest point lies on.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Feature {
    /// Inside triangle t.
    Face(u32),
    /// On the edge between two vertices.
    Edge(u32, u32),
    /// On a vertex.
    Vertex(u32),
}

/// Where the closest point of a triangle lies: its face, an edge (corner indices), a corner.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Region {
    Face,
    Edge(usize, usize),
    Vertex(usize),
}

/// The closest point of triangle abc to p (Ericson, Real-Time Collision Detection, 5.1.5).
fn closest_on_triangle(p: &Point3, a: &Point3, b: &Point3, c: &Point3) -> (Point3, Region) {
    let ab = sub(b, a);
    let ac = sub(c, a);
    let ap = sub(p, a);
    let d1 = dot(&ab, &ap);
    let d2 = dot(&ac, &ap);
    if d1 <= 0.0 && d2 <= 0.0 {
        return (*a, Region::Vertex(0));
    }
    let bp = sub(p, b);
    let d3 = dot(&ab, &bp);
    let d4 = dot(&ac, &bp);
    if d3 >= 0.0 && d4 <= d3 {
        return (*b, Region::Vertex(1));
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        let v = d1 / (d1 - d3);
        return (
            std::array::from_fn(|i| a[i] + v * ab[i]),
            Region::Edge(0, 1),
        );
    }
    let cp = sub(p, c);
    let d5 = dot(&ab, &cp);
    let d6 = dot(&ac, &cp);
    if d6 >= 0.0 && d5 <= d6 {
        return (*c, Region::Vertex(2));
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        let w = d2 / (d2 - d6);
        return (
            std::array::from_fn(|i| a[i] + w * ac[i]),
            Region::Edge(0, 2),
        );
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        let w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        return (
            std::array::from_fn(|i| b[i] + w * (c[i] - b[i])),
            Region::Edge(1, 2),
        );
    }
    let denom = 1.0 / (va + vb + vc);
    let v = vb * denom;
    let w = vc * denom;
    (
        std::array::from_fn(|i| a[i] + ab[i] * v + ac[i] * w),
        Region::Face,
    )
}

/// Vertices (V x 3, metres) and triangles (F x 3, file order) of a mesh file, by extension.
fn read_triangles(path: &Path, up: UpAxis) -> Result<(Vec<Point3>, Vec<[u32; 3]>)> {
    let spec = ShapeSpec::parse(&path.to_string_lossy())?;
    if let ShapeSpec::Usd { path, prim, time } = &spec {
        let g = crate::io::usd::read_usd_geometry(path, prim.as_deref(), *time, up)?;
        let Some(t) = g.triangles else {
            return Err(GeometryError::Usd {
                path: path.clone(),
                prim: g.prim,
                attribute: None,
                reason: "a mesh collider needs a Mesh prim (this one has no faces)".into(),
            }
            .into());
        };
        return Ok((g.points, t));
    }
    let ShapeSpec::File { format, .. } = spec else {
        return Err(Error::param(
            "file",
            path.display(),
            "a mesh collider needs a .obj, .stl, .off or .ply file, or a USD mesh prim",
        ));
    };
    Ok(match format {
        ShapeFileFormat::Obj => crate::io::obj::read_obj_raw(path)?,
        ShapeFileFormat::Stl => crate::io::stl::read_stl_soup(path)?,
        ShapeFileFormat::Off => crate::io::off::read_off_raw(path)?,
        ShapeFileFormat::Ply => {
            let data = crate::io::ply::read_ply_data(path)?;
            let triangles = data.triangles.ok_or_else(|| GeometryError::Parse {
                path: path.to_path_buf(),
                reason: "the PLY file has no faces (a point cloud); a collider mesh needs \
                         triangles"
                    .into(),
            })?;
            (data.points, triangles)
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::generate::{box_mesh, icosphere};

    fn solid(v: Vec<Point3>, t: Vec<[u32; 3]>) -> MeshObstacle {
        MeshObstacle::from_triangles(Path::new("test.obj"), v, t, Sided::Solid).unwrap()
    }

    /// Deterministic points in [-s, s]^3 (the library's generator; this test moved to it
    /// from its own linear congruential one: other points, the same checks).
    fn points(n: usize, s: f64) -> Vec<Point3> {
        let mut r = crate::random::SplitMix64::new(12345);
        (0..n)
            .map(|_| std::array::from_fn(|_| r.uniform(-s, s)))
            .collect()
    }

    #[test]
    fn bvh_matches_brute_force_on_a_sphere_and_a_box() {
        let (v, t) = icosphere(0.5, 2);
        let sphere = solid(v, t);
        let (mut v, t) = box_mesh([1.0, 0.6, 0.8]);
        for p in &mut v {
            *p = [p[0] - 0.5, p[1] - 0.3, p[2] - 0.4];
        }
        let cube = solid(v, t);
        for mesh in [&sphere, &cube] {
            let mut inside = 0;
            for y in points(400, 0.7) {
                let (fast, slow) = (
                    mesh.signed_distance(&y),
                    mesh.signed_distance_brute_force(&y),
                );
                // Same closest distance to round-off (1e-12 m on a unit mesh), same sign.
                assert!((fast - slow).abs() < 1e-12, "{y:?}: {fast} vs {slow}");
                let (p, q) = (mesh.penetration_local(&y), mesh.penetration_brute_force(&y));
                assert_eq!(p.is_some(), q.is_some(), "{y:?}");
                if let (Some(p), Some(q)) = (p, q) {
                    inside += 1;
                    assert!((p.depth - q.depth).abs() < 1e-12);
                    for d in 0..3 {
                        assert!((p.normal[d] - q.normal[d]).abs() < 1e-9, "{y:?}");
                    }
                }
            }
            assert!(inside > 50, "{inside}");
        }
    }
}
