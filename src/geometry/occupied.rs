//! The surface of the volume a point cloud or a voxel image occupies: a closed, consistently
//! oriented triangle mesh for shapes that have no surface of their own (object-object contact
//! samples are spread over it).
//!
//! The volume is a grid of cells: a cell is occupied when a point falls in it (clouds) or its
//! centre is inside (images). Gaps between a cloud's points are bridged by a morphological
//! closing (dilate, then erode, by `closing` cells), and enclosed cavities are filled (every
//! empty cell not reachable from outside is occupied): the surface is the outer boundary only.
//! Each grid node gets the fraction of its 8 cells that are occupied, and the level set at
//! [`ISO_LEVEL`] of that piecewise-linear field on the Kuhn triangulation of the grid (6
//! tetrahedra per cell along the main diagonal, the same in every cell) is the surface:
//! marching tetrahedra. A level set of a piecewise-linear field on a triangulation, at a level
//! no node takes, is a closed 2-manifold, so the mesh always passes [`TriMesh::new`]'s checks;
//! marching cubes' ambiguous faces would need a disambiguation table to promise that.

use super::{Aabb, GeometryError, ShapeOptions, TriMesh};
use crate::linalg3::{cross, sub};
use crate::Point3;
use std::collections::HashMap;

/// The level of the node field whose set is the surface. Node values are multiples of 1/8, so
/// 7/16 is never taken; below 1/2, a one-cell-thick plate (face nodes at 4/8) keeps its
/// surface, 1/16 of a cell outside the cells' faces.
pub const ISO_LEVEL: f64 = 7.0 / 16.0;

/// Most cells an occupancy grid may have (about 1 byte each plus the node field's 8 bytes a
/// node): 2^27, a 512^3 grid.
pub const MAX_CELLS: usize = 1 << 27;

/// Occupied cells of a regular grid: cell (i, j, k) is the box `origin + h [i, i+1] x ...`.
#[derive(Debug, Clone)]
pub struct OccupancyGrid {
    origin: Point3,
    h: f64,
    dims: [usize; 3],
    cells: Vec<bool>,
}

impl OccupancyGrid {
    /// An empty grid of cells of edge `h` (metres) covering `aabb` with `pad` empty cells on
    /// every side.
    ///
    /// # Errors
    /// [`GeometryError::InvalidInput`] for a cell edge that is not positive and finite, or a
    /// grid of more than [`MAX_CELLS`] cells.
    pub fn empty(aabb: &Aabb, h: f64, pad: usize) -> Result<OccupancyGrid, GeometryError> {
        if !(h > 0.0 && h.is_finite()) {
            return Err(GeometryError::InvalidInput(format!(
                "the occupancy grid's cell edge must be a positive length, not {h:e} m"
            )));
        }
        let size = aabb.size();
        let mut dims = [0usize; 3];
        let mut total = 1usize;
        for a in 0..3 {
            let n = (size[a] / h).ceil().max(1.0) + 2.0 * pad as f64;
            if !(n.is_finite() && n < MAX_CELLS as f64) {
                return Err(too_many(h, aabb));
            }
            dims[a] = n as usize;
            total = total.saturating_mul(dims[a]);
        }
        if total > MAX_CELLS {
            return Err(too_many(h, aabb));
        }
        let origin = [0, 1, 2].map(|a| aabb.min[a] - pad as f64 * h);
        Ok(OccupancyGrid {
            origin,
            h,
            dims,
            cells: vec![false; total],
        })
    }

    /// The cells holding at least one of `points` (N x 3, metres, finite), with `pad` empty
    /// cells around them.
    ///
    /// # Errors
    /// As [`OccupancyGrid::empty`]; [`GeometryError::InvalidInput`] for no points.
    pub fn from_points(
        points: &[Point3],
        h: f64,
        pad: usize,
    ) -> Result<OccupancyGrid, GeometryError> {
        let aabb = Aabb::from_points(points).ok_or_else(|| {
            GeometryError::InvalidInput("a surface cannot be derived from no points".into())
        })?;
        let mut grid = OccupancyGrid::empty(&aabb, h, pad)?;
        for p in points {
            let c = grid.cell_of(p);
            let i = grid.index(c);
            grid.cells[i] = true;
        }
        Ok(grid)
    }

    /// The cells of a grid over `aabb` whose centres `inside` says are inside (`inside` maps
    /// centres, N x 3 metres, to flags), with `pad` empty cells around.
    ///
    /// # Errors
    /// As [`OccupancyGrid::empty`].
    pub fn from_inside(
        aabb: &Aabb,
        h: f64,
        pad: usize,
        inside: impl Fn(&[Point3]) -> Vec<bool>,
    ) -> Result<OccupancyGrid, GeometryError> {
        let mut grid = OccupancyGrid::empty(aabb, h, pad)?;
        let centres: Vec<Point3> = (0..grid.cells.len())
            .map(|n| {
                let c = grid.ijk(n);
                [0, 1, 2].map(|a| grid.origin[a] + (c[a] as f64 + 0.5) * h)
            })
            .collect();
        grid.cells = inside(&centres);
        Ok(grid)
    }

    /// Number of occupied cells.
    pub fn occupied(&self) -> usize {
        self.cells.iter().filter(|&&c| c).count()
    }

    fn index(&self, c: [usize; 3]) -> usize {
        c[0] + self.dims[0] * (c[1] + self.dims[1] * c[2])
    }

    fn ijk(&self, n: usize) -> [usize; 3] {
        let (nx, ny) = (self.dims[0], self.dims[1]);
        [n % nx, (n / nx) % ny, n / (nx * ny)]
    }

    fn cell_of(&self, p: &Point3) -> [usize; 3] {
        [0, 1, 2].map(|a| {
            let f = ((p[a] - self.origin[a]) / self.h).floor();
            (f.max(0.0) as usize).min(self.dims[a] - 1)
        })
    }

    /// Morphological closing by `r` cells (a (2r + 1)^3 cube): bridges gaps up to 2r cells
    /// wide and keeps everything occupied before. The padding must be at least r + 1 cells.
    pub fn close(&mut self, r: usize) {
        if r == 0 {
            return;
        }
        self.sweep(r, true);
        self.sweep(r, false);
    }

    /// Dilation (`grow`) or erosion by a (2r + 1)^3 cube, as three passes along the axes.
    fn sweep(&mut self, r: usize, grow: bool) {
        for axis in 0..3 {
            let stride = [1, self.dims[0], self.dims[0] * self.dims[1]][axis];
            let len = self.dims[axis];
            let src = self.cells.clone();
            for n in 0..self.cells.len() {
                let i = self.ijk(n)[axis];
                let lo = i.saturating_sub(r);
                let hi = (i + r).min(len - 1);
                let base = n - i * stride;
                let mut window = (lo..=hi).map(|k| src[base + k * stride]);
                self.cells[n] = if grow {
                    window.any(|c| c)
                } else {
                    // Outside the grid counts as empty: erosion there empties the cell.
                    i >= r && i + r < len && window.all(|c| c)
                };
            }
        }
    }

    /// Occupy every empty cell that no path of face-adjacent empty cells joins to the grid's
    /// border: enclosed cavities become solid.
    pub fn fill_cavities(&mut self) {
        let mut outside = vec![false; self.cells.len()];
        let mut stack = Vec::new();
        for n in 0..self.cells.len() {
            let c = self.ijk(n);
            let border = (0..3).any(|a| c[a] == 0 || c[a] + 1 == self.dims[a]);
            if border && !self.cells[n] {
                outside[n] = true;
                stack.push(n);
            }
        }
        while let Some(n) = stack.pop() {
            let c = self.ijk(n);
            for a in 0..3 {
                for up in [false, true] {
                    let mut d = c;
                    if up && c[a] + 1 < self.dims[a] {
                        d[a] += 1;
                    } else if !up && c[a] > 0 {
                        d[a] -= 1;
                    } else {
                        continue;
                    }
                    let m = self.index(d);
                    if !self.cells[m] && !outside[m] {
                        outside[m] = true;
                        stack.push(m);
                    }
                }
            }
        }
        for (c, o) in self.cells.iter_mut().zip(outside) {
            *c = !o;
        }
    }

    /// The fraction of the (up to 8) cells around each grid node that are occupied, nodes
    /// (dims + 1) per axis, x fastest.
    fn node_field(&self) -> Vec<f64> {
        let nd = self.dims.map(|d| d + 1);
        let mut f = vec![0.0; nd[0] * nd[1] * nd[2]];
        for n in 0..self.cells.len() {
            if !self.cells[n] {
                continue;
            }
            let c = self.ijk(n);
            for corner in 0..8 {
                let v = [
                    c[0] + (corner & 1),
                    c[1] + ((corner >> 1) & 1),
                    c[2] + (corner >> 2),
                ];
                f[v[0] + nd[0] * (v[1] + nd[1] * v[2])] += 0.125;
            }
        }
        f
    }

    /// The surface of the occupied cells (see the module docs): a closed, outward-oriented
    /// mesh, vertices on the grid's edges.
    ///
    /// # Errors
    /// [`GeometryError::Degenerate`] when no surface is left (no occupied cells, or only parts
    /// thinner than a cell); the padding must keep the border cells empty.
    pub fn surface(&self) -> Result<TriMesh, GeometryError> {
        let field = self.node_field();
        let nd = self.dims.map(|d| d + 1);
        let node = |v: [usize; 3]| v[0] + nd[0] * (v[1] + nd[1] * v[2]);
        let position = |n: usize| {
            let v = [n % nd[0], (n / nd[0]) % nd[1], n / (nd[0] * nd[1])];
            [0, 1, 2].map(|a| self.origin[a] + v[a] as f64 * self.h)
        };
        let mut vertices: Vec<Point3> = Vec::new();
        let mut on_edge: HashMap<(usize, usize), u32> = HashMap::new();
        let mut triangles: Vec<[u32; 3]> = Vec::new();
        // The level set's point on the edge from node `a` (inside) to `b` (outside).
        let mut crossing = |a: usize, b: usize, vertices: &mut Vec<Point3>| -> u32 {
            let key = (a.min(b), a.max(b));
            *on_edge.entry(key).or_insert_with(|| {
                let t = (field[a] - ISO_LEVEL) / (field[a] - field[b]);
                let (pa, pb) = (position(a), position(b));
                vertices.push([0, 1, 2].map(|k| pa[k] + t * (pb[k] - pa[k])));
                (vertices.len() - 1) as u32
            })
        };
        let mean_position = |nodes: &[usize]| {
            let mut m = [0.0; 3];
            for &n in nodes {
                let p = position(n);
                (0..3).for_each(|a| m[a] += p[a] / nodes.len() as f64);
            }
            m
        };
        const PERMUTATIONS: [[usize; 3]; 6] = [
            [0, 1, 2],
            [0, 2, 1],
            [1, 0, 2],
            [1, 2, 0],
            [2, 0, 1],
            [2, 1, 0],
        ];
        let [cx, cy, cz] = self.dims;
        for k in 0..cz {
            for j in 0..cy {
                for i in 0..cx {
                    let corners: [usize; 8] = std::array::from_fn(|c| {
                        node([i + (c & 1), j + ((c >> 1) & 1), k + (c >> 2)])
                    });
                    let inside = corners.map(|n| field[n] > ISO_LEVEL);
                    if inside.iter().all(|&s| s) || inside.iter().all(|&s| !s) {
                        continue;
                    }
                    for perm in PERMUTATIONS {
                        // Kuhn tetrahedron: corner 0, then one axis step at a time, to 7.
                        let mut c = 0usize;
                        let mut tet = [0usize; 4];
                        for (s, axis) in perm.iter().enumerate() {
                            c |= 1 << axis;
                            tet[s + 1] = c;
                        }
                        let tet = tet.map(|c| corners[c]);
                        // The tetrahedron's nodes inside and outside the level set.
                        let (mut ins, mut outs) = ([0usize; 4], [0usize; 4]);
                        let (mut ni, mut no) = (0, 0);
                        for n in tet {
                            if field[n] > ISO_LEVEL {
                                (ins[ni], ni) = (n, ni + 1);
                            } else {
                                (outs[no], no) = (n, no + 1);
                            }
                        }
                        let (ins, outs) = (&ins[..ni], &outs[..no]);
                        // Its cut: a triangle (one node apart) or a quad (two and two).
                        let mut polygon = [0u32; 4];
                        let corners_of_cut: &[(usize, usize)] = match (ni, no) {
                            (1, 3) => &[(0, 0), (0, 1), (0, 2)],
                            (3, 1) => &[(0, 0), (1, 0), (2, 0)],
                            (2, 2) => &[(0, 0), (0, 1), (1, 1), (1, 0)],
                            _ => continue,
                        };
                        for (v, &(a, b)) in polygon.iter_mut().zip(corners_of_cut) {
                            *v = crossing(ins[a], outs[b], &mut vertices);
                        }
                        let polygon = &polygon[..corners_of_cut.len()];
                        // Outward: from the inside nodes' mean towards the outside nodes'.
                        let (a, b) = (mean_position(ins), mean_position(outs));
                        let out = sub(&b, &a);
                        for t in 1..polygon.len() - 1 {
                            let mut tri = [polygon[0], polygon[t], polygon[t + 1]];
                            let [a, b, c] = tri.map(|v| vertices[v as usize]);
                            let n = cross(&sub(&b, &a), &sub(&c, &a));
                            if n[0] * out[0] + n[1] * out[1] + n[2] * out[2] < 0.0 {
                                tri.swap(1, 2);
                            }
                            triangles.push(tri);
                        }
                    }
                }
            }
        }
        if triangles.is_empty() {
            return Err(GeometryError::Degenerate(format!(
                "no surface is left of the occupied volume ({} occupied cells of edge {:.3e} m): \
                 the shape is empty, or thinner than a cell everywhere",
                self.occupied(),
                self.h
            )));
        }
        TriMesh::new(vertices, triangles, &ShapeOptions::default())
    }
}

fn too_many(h: f64, aabb: &Aabb) -> GeometryError {
    GeometryError::InvalidInput(format!(
        "an occupancy grid of cell edge {h:.3e} m over a bounding box of diagonal {:.3e} m \
         would have more than {MAX_CELLS} cells; use a coarser cell",
        aabb.diagonal()
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A ball of radius 0.5 sampled on a jittered 0.05 m lattice: the surface is closed, its
    /// volume within a cell's layer of the ball's, and every point inside it.
    #[test]
    fn a_sampled_ball_gets_a_closed_surface_around_its_points() {
        let mut rng = crate::random::SplitMix64::new(7);
        let mut points = Vec::new();
        let s = 0.05;
        for i in -12..=12 {
            for j in -12..=12 {
                for k in -12..=12 {
                    let p = [i, j, k].map(|v| v as f64 * s + 0.2 * s * (rng.next_f64() - 0.5));
                    if p.iter().map(|v| v * v).sum::<f64>() <= 0.25 {
                        points.push(p);
                    }
                }
            }
        }
        let mut grid = OccupancyGrid::from_points(&points, s, 3).unwrap();
        grid.close(1);
        grid.fill_cavities();
        let mesh = grid.surface().unwrap();
        assert!(mesh.is_closed());
        // The cells reach at most one cell (s) past the outermost points, and at least the
        // points themselves: the volume lies between the balls of radius 0.5 - s and 0.5 + s.
        let v = mesh.volume().unwrap();
        let ball = |r: f64| 4.0 / 3.0 * std::f64::consts::PI * r * r * r;
        assert!(v > ball(0.5 - s) && v < ball(0.5 + s), "{v}");
        // A lone cell standing out of a face has nodes at most 2/8 occupied, so the surface
        // cuts through it: points lie inside once moved one cell towards the centre.
        let moved: Vec<Point3> = points
            .iter()
            .map(|p| {
                let r = p.iter().map(|v| v * v).sum::<f64>().sqrt().max(s);
                p.map(|v| v * (1.0 - s / r))
            })
            .collect();
        assert!(mesh.contains(&moved).iter().all(|&c| c));
    }

    /// A hollow shell of cells: the cavity is filled, so the surface is the outer one alone
    /// (its volume is the whole cube's), and a closing bridges a one-cell gap in a wall.
    #[test]
    fn cavities_are_filled_and_gaps_bridged() {
        let aabb = Aabb {
            min: [0.0; 3],
            max: [1.0; 3],
        };
        let h = 0.1;
        let wall = |p: &[Point3]| -> Vec<bool> {
            p.iter()
                .map(|q| {
                    let inb = q.iter().all(|&c| (0.0..1.0).contains(&c));
                    let on_wall = q.iter().any(|&c| !(0.1..0.9).contains(&c));
                    // A one-cell hole through the +x wall.
                    let hole =
                        q[0] > 0.9 && (q[1] - 0.55).abs() < 0.05 && (q[2] - 0.55).abs() < 0.05;
                    inb && on_wall && !hole
                })
                .collect()
        };
        let mut open = OccupancyGrid::from_inside(&aabb, h, 2, wall).unwrap();
        let mut closed = open.clone();
        open.fill_cavities();
        let leaky = open.surface().unwrap();
        // Through the hole the cavity is outside: inner and outer walls both have surfaces.
        assert!(leaky.volume().unwrap() < 0.6);
        closed.close(1);
        closed.fill_cavities();
        let solid = closed.surface().unwrap();
        assert!(solid.is_closed());
        let v = solid.volume().unwrap();
        // The surface lies within a cell of the cells' faces (the unit cube's).
        assert!(
            v > (1.0 - 2.0 * h).powi(3) && v < (1.0 + 2.0 * h).powi(3),
            "{v}"
        );
    }

    #[test]
    fn empty_and_too_thin_shapes_have_no_surface() {
        let aabb = Aabb {
            min: [0.0; 3],
            max: [1.0; 3],
        };
        let none = OccupancyGrid::from_inside(&aabb, 0.1, 2, |p| vec![false; p.len()]).unwrap();
        assert!(matches!(none.surface(), Err(GeometryError::Degenerate(_))));
        // A single isolated cell: its nodes are at most 1/8 occupied, below the level.
        let one = OccupancyGrid::from_points(&[[0.5; 3]], 0.1, 2).unwrap();
        assert!(matches!(one.surface(), Err(GeometryError::Degenerate(_))));
        assert!(OccupancyGrid::from_points(&[], 0.1, 2).is_err());
        assert!(OccupancyGrid::empty(&aabb, 0.0, 2).is_err());
        assert!(OccupancyGrid::empty(&aabb, 1e-6, 2).is_err());
    }
}
