//! Validated, outward-oriented triangle meshes.

use super::topology::EdgeReport;
use super::winding::{self, cross, dot, sub, WindingParams, WindingTree};
use super::{Aabb, GeometryError, ShapeOptions, IN_MEMORY};
use crate::Point3;
use std::path::PathBuf;
use std::sync::OnceLock;

/// A triangle mesh that passed validation, oriented with outward normals.
///
/// Invariants (checked by [`TriMesh::new`]): at least one triangle, every index in range,
/// finite coordinates, no triangle repeating a vertex, non-zero enclosed volume, and (unless
/// [`ShapeOptions::allow_open_mesh`]) closed and consistently oriented: every undirected edge is
/// used by exactly two triangles, once in each direction.
///
/// **Orientation.** Triangles are counter-clockwise seen from outside, i.e. the normal
/// `(b - a) x (c - a)` points out. If the input's signed volume is negative (all faces facing
/// inward, a common export mistake) every triangle is flipped once, as a whole; see
/// [`TriMesh::was_flipped`]. Nested shells (cavities) keep their relative orientation.
///
/// **Inside test.** [`TriMesh::contains`] uses the generalized winding number `w >= 0.5`,
/// evaluated with a [`WindingTree`] that is built on first use and cached. For a closed mesh
/// this is exact away from the surface; for an open mesh (opt-in) it degrades gracefully.
#[derive(Clone)]
pub struct TriMesh {
    vertices: Vec<Point3>,
    triangles: Vec<[u32; 3]>,
    edges: EdgeReport,
    flipped: bool,
    signed_volume: f64,
    aabb: Aabb,
    dropped: usize,
    tree: OnceLock<WindingTree>,
}

impl TriMesh {
    /// Validate and orient a mesh.
    ///
    /// `vertices`: V x 3, metres. `triangles`: F x 3 zero-based indices into `vertices`.
    /// Triangles that repeat a vertex index (no area, no solid angle; they would only corrupt
    /// the edge counts) are dropped; [`TriMesh::dropped_triangles`] says how many.
    ///
    /// # Errors
    /// - [`GeometryError::Degenerate`]: no triangles, an index out of range, a non-finite
    ///   coordinate, or (near-)zero enclosed volume (|V| <= 1e-12 diag^3).
    /// - [`GeometryError::NotWatertight`] / [`GeometryError::Misoriented`]: open, non-manifold
    ///   or inconsistently oriented mesh, unless `opts.allow_open_mesh`. The error's path is
    ///   `<in-memory mesh>`; file readers replace it with [`GeometryError::with_path`].
    pub fn new(
        vertices: Vec<Point3>,
        triangles: Vec<[u32; 3]>,
        opts: &ShapeOptions,
    ) -> Result<TriMesh, GeometryError> {
        if let Some(i) = vertices
            .iter()
            .position(|p| !p.iter().all(|c| c.is_finite()))
        {
            return Err(GeometryError::Degenerate(format!(
                "mesh vertex {i} has a non-finite coordinate {:?}",
                vertices[i]
            )));
        }
        let nv = vertices.len();
        for (f, t) in triangles.iter().enumerate() {
            if let Some(&i) = t.iter().find(|&&i| i as usize >= nv) {
                return Err(GeometryError::Degenerate(format!(
                    "mesh triangle {f} refers to vertex {i}, but the mesh has {nv} vertices"
                )));
            }
        }
        let total = triangles.len();
        let mut triangles = triangles;
        triangles.retain(|t| t[0] != t[1] && t[1] != t[2] && t[0] != t[2]);
        let dropped = total - triangles.len();
        if triangles.is_empty() {
            return Err(GeometryError::Degenerate(format!(
                "mesh has no usable triangles ({total} given, {dropped} repeat a vertex)"
            )));
        }

        let edges = EdgeReport::of(&triangles);
        if !opts.allow_open_mesh {
            if !edges.is_closed() {
                return Err(GeometryError::NotWatertight {
                    path: PathBuf::from(IN_MEMORY),
                    boundary_edges: edges.boundary_edges,
                    nonmanifold_edges: edges.nonmanifold_edges,
                });
            }
            if edges.misoriented_edges > 0 {
                return Err(GeometryError::Misoriented {
                    path: PathBuf::from(IN_MEMORY),
                    misoriented_edges: edges.misoriented_edges,
                });
            }
        }

        // Referenced vertices only: unreferenced ones do not belong to the solid.
        let mut used = vec![false; nv];
        for t in &triangles {
            for &i in t {
                used[i as usize] = true;
            }
        }
        let referenced: Vec<Point3> = vertices
            .iter()
            .zip(&used)
            .filter(|(_, &u)| u)
            .map(|(p, _)| *p)
            .collect();
        let aabb = Aabb::from_points(&referenced).expect("at least one triangle");
        let mut signed_volume = signed_volume_about(&vertices, &triangles, &aabb.center());
        let diag = aabb.diagonal();
        if !(signed_volume.is_finite() && (diag * diag * diag).is_finite()) {
            return Err(GeometryError::Degenerate(format!(
                "mesh coordinates are too large (bounding box {:?} to {:?}): its volume \
                 overflows f64; rescale the mesh to metres",
                aabb.min, aabb.max
            )));
        }
        if signed_volume.abs() <= 1e-12 * diag * diag * diag {
            return Err(GeometryError::Degenerate(format!(
                "mesh encloses no volume (signed volume {signed_volume:.3e} m^3 with a \
                 bounding-box diagonal of {diag:.3e} m): it is flat, or its faces cancel"
            )));
        }
        let flipped = signed_volume < 0.0;
        if flipped {
            for t in &mut triangles {
                t.swap(1, 2);
            }
            signed_volume = -signed_volume;
        }
        Ok(TriMesh {
            vertices,
            triangles,
            edges,
            flipped,
            signed_volume,
            aabb,
            dropped,
            tree: OnceLock::new(),
        })
    }

    /// Vertex positions, V x 3, metres (as given, including unreferenced ones).
    pub fn vertices(&self) -> &[Point3] {
        &self.vertices
    }

    /// Triangles, F x 3 zero-based vertex indices, counter-clockwise seen from outside.
    pub fn triangles(&self) -> &[[u32; 3]] {
        &self.triangles
    }

    /// Edge-use counts of the (possibly open) mesh.
    pub fn edge_report(&self) -> EdgeReport {
        self.edges
    }

    /// Closed and consistently oriented (every edge used twice, once each way).
    pub fn is_closed(&self) -> bool {
        self.edges.is_closed() && self.edges.misoriented_edges == 0
    }

    /// Whether every triangle was flipped because the input faced inward.
    pub fn was_flipped(&self) -> bool {
        self.flipped
    }

    /// Number of input triangles dropped because they repeated a vertex index.
    pub fn dropped_triangles(&self) -> usize {
        self.dropped
    }

    /// Signed volume by the divergence theorem, `sum_t (a . (b x c)) / 6` with coordinates
    /// relative to the bounding-box centre, m^3; positive after orientation. Exact for closed
    /// meshes; for open meshes it depends on that reference point (a rough size only).
    pub fn signed_volume(&self) -> f64 {
        self.signed_volume
    }

    /// Enclosed volume, m^3: `Some` for closed meshes, `None` for open ones.
    pub fn volume(&self) -> Option<f64> {
        self.is_closed().then_some(self.signed_volume)
    }

    /// Bounding box of the vertices used by triangles, metres.
    pub fn bounding_box(&self) -> Aabb {
        self.aabb
    }

    /// The cached winding-number hierarchy (default [`WindingParams`]), built on first use.
    pub fn winding_tree(&self) -> &WindingTree {
        self.tree.get_or_init(|| {
            WindingTree::new(&self.vertices, &self.triangles, WindingParams::default())
        })
    }

    /// Fast generalized winding numbers at `points` (N x 3, metres), rayon-parallel.
    pub fn winding_numbers(&self, points: &[Point3]) -> Vec<f64> {
        self.winding_tree().winding_numbers(points)
    }

    /// Exact O(F)-per-point winding numbers at `points` (N x 3, metres): the reference the
    /// fast evaluation is tested against.
    pub fn winding_numbers_exact(&self, points: &[Point3]) -> Vec<f64> {
        winding::winding_numbers_exact(&self.vertices, &self.triangles, points)
    }

    /// Inside test for `points` (N x 3, metres): generalized winding number >= 0.5.
    /// Rayon-parallel. Closed meshes use [`WindingTree::contains_closed`] (one evaluation per
    /// group of points away from the surface), open meshes evaluate every point.
    pub fn contains(&self, points: &[Point3]) -> Vec<bool> {
        let tree = self.winding_tree();
        if self.is_closed() {
            tree.contains_closed(points)
        } else {
            tree.contains(points)
        }
    }

    /// Give back the vertices (V x 3, metres) and oriented triangles (F x 3).
    pub fn into_parts(self) -> (Vec<Point3>, Vec<[u32; 3]>) {
        (self.vertices, self.triangles)
    }
}

impl std::fmt::Debug for TriMesh {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("TriMesh")
            .field("vertices", &self.vertices.len())
            .field("triangles", &self.triangles.len())
            .field("edges", &self.edges)
            .field("flipped", &self.flipped)
            .field("signed_volume", &self.signed_volume)
            .field("aabb", &self.aabb)
            .finish_non_exhaustive()
    }
}

/// `sum_t ((a - o) . ((b - o) x (c - o))) / 6`, m^3.
fn signed_volume_about(vertices: &[Point3], triangles: &[[u32; 3]], o: &Point3) -> f64 {
    let six: f64 = triangles
        .iter()
        .map(|t| {
            let a = sub(&vertices[t[0] as usize], o);
            let b = sub(&vertices[t[1] as usize], o);
            let c = sub(&vertices[t[2] as usize], o);
            dot(&a, &cross(&b, &c))
        })
        .sum();
    six / 6.0
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::generate::{box_mesh, icosphere, torus};

    fn opts() -> ShapeOptions {
        ShapeOptions::default()
    }

    #[test]
    fn box_volume_bbox_and_orientation() {
        let (v, t) = box_mesh([2.0, 3.0, 4.0]);
        let m = TriMesh::new(v, t, &opts()).unwrap();
        assert!((m.volume().unwrap() - 24.0).abs() < 1e-13);
        assert_eq!(
            m.bounding_box(),
            Aabb {
                min: [0.0; 3],
                max: [2.0, 3.0, 4.0]
            }
        );
        assert!(!m.was_flipped());
    }

    #[test]
    fn inward_mesh_is_flipped_once() {
        let (v, mut t) = box_mesh([1.0, 1.0, 1.0]);
        for tri in &mut t {
            tri.swap(0, 1);
        }
        let m = TriMesh::new(v, t, &opts()).unwrap();
        assert!(m.was_flipped());
        assert!((m.volume().unwrap() - 1.0).abs() < 1e-14);
        assert_eq!(
            m.contains(&[[0.5, 0.5, 0.5], [1.5, 0.5, 0.5]]),
            vec![true, false]
        );
    }

    #[test]
    fn invalid_meshes_are_degenerate() {
        let (v, t) = box_mesh([1.0, 1.0, 1.0]);
        let deg = |r: Result<TriMesh, GeometryError>, what: &str| match r {
            Err(GeometryError::Degenerate(msg)) => assert!(msg.contains(what), "{msg}"),
            other => panic!("expected Degenerate({what}), got {other:?}"),
        };
        deg(
            TriMesh::new(v.clone(), vec![], &opts()),
            "no usable triangles",
        );
        let mut bad = t.clone();
        bad[3][1] = 8;
        deg(TriMesh::new(v.clone(), bad, &opts()), "refers to vertex 8");
        let mut nan = v.clone();
        nan[5][2] = f64::NAN;
        deg(
            TriMesh::new(nan, t.clone(), &opts()),
            "vertex 5 has a non-finite",
        );
        // Two copies of one triangle, opposite orientation: closed, but encloses nothing.
        let flat = vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
        deg(
            TriMesh::new(flat, vec![[0, 1, 2], [0, 2, 1]], &opts()),
            "encloses no volume",
        );
    }

    #[test]
    fn collapsed_triangles_are_dropped() {
        let (v, mut t) = box_mesh([1.0, 1.0, 1.0]);
        t.push([0, 0, 1]);
        let m = TriMesh::new(v, t, &opts()).unwrap();
        assert_eq!(m.dropped_triangles(), 1);
        assert_eq!(m.triangles().len(), 12);
    }

    #[test]
    fn open_and_misoriented_need_opt_in() {
        let (v, t) = box_mesh([1.0, 1.0, 1.0]);
        match TriMesh::new(v.clone(), t[1..].to_vec(), &opts()) {
            Err(GeometryError::NotWatertight {
                boundary_edges: 3,
                nonmanifold_edges: 0,
                ..
            }) => {}
            other => panic!("{other:?}"),
        }
        let mut mis = t.clone();
        mis[0].swap(1, 2);
        match TriMesh::new(v.clone(), mis.clone(), &opts()) {
            Err(GeometryError::Misoriented {
                misoriented_edges: 3,
                ..
            }) => {}
            other => panic!("{other:?}"),
        }
        let open = ShapeOptions {
            allow_open_mesh: true,
            ..ShapeOptions::default()
        };
        let m = TriMesh::new(v, mis, &open).unwrap();
        assert!(!m.is_closed());
        assert_eq!(m.volume(), None);
    }

    #[test]
    fn generated_meshes_are_closed_and_outward() {
        let opts = ShapeOptions::default();
        for (v, t) in [
            box_mesh([1.0, 2.0, 3.0]),
            icosphere(2.0, 2),
            torus(2.0, 0.5, 24, 12),
        ] {
            let mesh = TriMesh::new(v, t, &opts).unwrap();
            assert!(!mesh.was_flipped());
            assert!(mesh.is_closed());
        }
    }
}
