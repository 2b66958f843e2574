//! Mesh topology: edge use counts (watertightness, orientation consistency) and exact vertex
//! welding.

use crate::Point3;
use std::collections::HashMap;

/// How the undirected edges of a triangle mesh are used.
///
/// A closed, consistently oriented 2-manifold has every edge used by exactly two triangles,
/// once in each direction: all three counts are zero.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct EdgeReport {
    /// Number of distinct undirected edges.
    pub edges: usize,
    /// Edges used by exactly one triangle (holes).
    pub boundary_edges: usize,
    /// Edges used by three or more triangles.
    pub nonmanifold_edges: usize,
    /// Edges used by exactly two triangles that traverse it in the same direction.
    pub misoriented_edges: usize,
}

impl EdgeReport {
    /// Count edge uses of `triangles` (F x 3 vertex indices). Triangles must not repeat a
    /// vertex (a repeated index is counted as a zero-length edge like any other).
    pub fn of(triangles: &[[u32; 3]]) -> EdgeReport {
        let half = half_edges(triangles);
        let mut report = EdgeReport::default();
        for uses in half.chunk_by(|a, b| a.key == b.key) {
            let dir_sum: i64 = uses.iter().map(|h| i64::from(h.dir)).sum();
            report.edges += 1;
            match uses.len() {
                1 => report.boundary_edges += 1,
                2 if dir_sum != 0 => report.misoriented_edges += 1,
                2 => {}
                _ => report.nonmanifold_edges += 1,
            }
        }
        report
    }

    /// No boundary and no non-manifold edges.
    pub fn is_closed(&self) -> bool {
        self.boundary_edges == 0 && self.nonmanifold_edges == 0
    }
}

/// One use of an undirected edge by a triangle.
struct HalfEdge {
    /// (min << 32) | max of the edge's vertex indices.
    key: u64,
    /// +1 if the triangle traverses it from min to max, -1 otherwise.
    dir: i8,
    /// The triangle's index.
    triangle: u32,
}

/// Every half-edge of `triangles`, sorted by undirected edge (the uses of one edge adjacent).
fn half_edges(triangles: &[[u32; 3]]) -> Vec<HalfEdge> {
    let mut half = Vec::with_capacity(3 * triangles.len());
    for (f, t) in triangles.iter().enumerate() {
        for k in 0..3 {
            let (a, b) = (t[k], t[(k + 1) % 3]);
            let (lo, hi, dir) = if a < b { (a, b, 1) } else { (b, a, -1) };
            half.push(HalfEdge {
                key: (u64::from(lo) << 32) | u64::from(hi),
                dir,
                triangle: f as u32,
            });
        }
    }
    half.sort_unstable_by_key(|h| h.key);
    half
}

/// The boundary edges of `triangles` (F x 3 vertex indices): edges used by one triangle, as
/// (smaller vertex index, larger, the triangle's index), in edge order.
pub fn boundary_edges(triangles: &[[u32; 3]]) -> Vec<(u32, u32, u32)> {
    half_edges(triangles)
        .chunk_by(|a, b| a.key == b.key)
        .filter_map(|uses| match uses {
            [h] => Some(((h.key >> 32) as u32, h.key as u32, h.triangle)),
            _ => None,
        })
        .collect()
}

/// Merge vertices with bit-identical coordinates (after mapping `-0.0` to `0.0`) and drop
/// triangles that then repeat a vertex.
///
/// `vertices` is V x 3 (metres), `triangles` F x 3 indices into it (must be in range). Returns
/// the welded vertices (first occurrence order) and re-indexed triangles. This is what STL
/// needs (it stores a triangle soup) and what OBJ/PLY readers use so that seams between
/// groups or duplicated vertices do not count as holes.
pub fn weld_exact(vertices: &[Point3], triangles: &[[u32; 3]]) -> (Vec<Point3>, Vec<[u32; 3]>) {
    let mut map: HashMap<[u64; 3], u32> = HashMap::with_capacity(vertices.len());
    let mut new_vertices = Vec::with_capacity(vertices.len());
    let remap: Vec<u32> = vertices
        .iter()
        .map(|p| {
            // `x + 0.0` turns -0.0 into +0.0 and leaves every other value unchanged.
            let key = p.map(|c| (c + 0.0).to_bits());
            *map.entry(key).or_insert_with(|| {
                new_vertices.push(*p);
                (new_vertices.len() - 1) as u32
            })
        })
        .collect();
    let new_triangles = triangles
        .iter()
        .map(|t| t.map(|i| remap[i as usize]))
        .filter(|t| t[0] != t[1] && t[1] != t[2] && t[0] != t[2])
        .collect();
    (new_vertices, new_triangles)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_open_tetrahedron_has_the_missing_face_edges_as_boundary() {
        let t = [[0, 2, 1], [0, 1, 3], [1, 2, 3], [0, 3, 2]];
        assert!(boundary_edges(&t).is_empty());
        // Without face [1, 2, 3]: its three edges, each now used by one remaining triangle.
        let open = [t[0], t[1], t[3]];
        assert_eq!(boundary_edges(&open), [(1, 2, 0), (1, 3, 1), (2, 3, 2)]);
        assert_eq!(EdgeReport::of(&open).boundary_edges, 3);
    }

    #[test]
    fn tetrahedron_is_closed_and_consistent() {
        let t = [[0, 2, 1], [0, 1, 3], [1, 2, 3], [0, 3, 2]];
        let r = EdgeReport::of(&t);
        assert_eq!(
            r,
            EdgeReport {
                edges: 6,
                ..Default::default()
            }
        );
        assert!(r.is_closed());
    }

    #[test]
    fn counts_boundary_nonmanifold_and_misoriented() {
        // Open: one triangle missing from the tetrahedron -> 3 boundary edges.
        let r = EdgeReport::of(&[[0, 2, 1], [0, 1, 3], [1, 2, 3]]);
        assert_eq!(
            (r.boundary_edges, r.nonmanifold_edges, r.misoriented_edges),
            (3, 0, 0)
        );
        // One face flipped -> its 3 edges are misoriented.
        let r = EdgeReport::of(&[[0, 1, 2], [0, 1, 3], [1, 2, 3], [0, 3, 2]]);
        assert_eq!(
            (r.boundary_edges, r.nonmanifold_edges, r.misoriented_edges),
            (0, 0, 3)
        );
        // Three triangles on edge 0-1.
        let r = EdgeReport::of(&[[0, 1, 2], [1, 0, 3], [0, 1, 4]]);
        assert_eq!(r.nonmanifold_edges, 1);
    }

    #[test]
    fn weld_merges_signed_zero_and_drops_collapsed() {
        let v = [
            [0.0, 0.0, 0.0],
            [-0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
        ];
        let (wv, wt) = weld_exact(&v, &[[0, 2, 3], [1, 3, 2], [0, 1, 2]]);
        assert_eq!(wv.len(), 3);
        assert_eq!(wt, vec![[0, 1, 2], [0, 2, 1]]);
    }
}
