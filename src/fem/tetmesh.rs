//! A validated tetrahedral mesh, and the structured mesh of a box.
//!
//! **Structured box** ([`TetMesh::structured_box`]): the box is cut into nx x ny x nz cubes
//! (cells) and every cell into the 6 tetrahedra of the Kuhn (Freudenthal) subdivision, all
//! sharing the cell diagonal from its (min, min, min) to its (max, max, max) corner. Because
//! every cell uses the same diagonal direction the faces of neighbouring cells match: the
//! mesh is conforming. Nodes are numbered x fastest: node (i, j, k) is
//! `i + (nx + 1) (j + (ny + 1) k)`.

use super::FemError;
use crate::geometry::Aabb;
use crate::Point3;

/// A tetrahedral mesh: nodes (N x 3, metres) and tets (T x 4 zero-based node indices), every
/// tet positively oriented (det[x1 - x0, x2 - x0, x3 - x0] > 0).
#[derive(Debug, Clone, PartialEq)]
pub struct TetMesh {
    nodes: Vec<Point3>,
    tets: Vec<[u32; 4]>,
    flipped: usize,
}

/// The 6 Kuhn tets of the unit cube, as corner bit patterns (bit 0: +x, bit 1: +y, bit 2: +z).
/// Each runs 0 -> one axis -> two axes -> all three; orientation is fixed by [`TetMesh::new`].
pub(crate) const KUHN: [[u8; 4]; 6] = [
    [0, 1, 3, 7],
    [0, 1, 5, 7],
    [0, 2, 3, 7],
    [0, 2, 6, 7],
    [0, 4, 5, 7],
    [0, 4, 6, 7],
];

/// Signed volume of the tet (a, b, c, d), m^3: det[b - a, c - a, d - a] / 6.
pub fn signed_volume(a: &Point3, b: &Point3, c: &Point3, d: &Point3) -> f64 {
    let u = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
    let v = [c[0] - a[0], c[1] - a[1], c[2] - a[2]];
    let w = [d[0] - a[0], d[1] - a[1], d[2] - a[2]];
    (u[0] * (v[1] * w[2] - v[2] * w[1]) - u[1] * (v[0] * w[2] - v[2] * w[0])
        + u[2] * (v[0] * w[1] - v[1] * w[0]))
        / 6.0
}

impl TetMesh {
    /// Validate a mesh and orient every tet positively (swapping its last two nodes when its
    /// signed volume is negative; [`TetMesh::flipped_tets`] counts them).
    ///
    /// `nodes`: N x 3, metres. `tets`: T x 4 zero-based indices into `nodes`.
    ///
    /// # Errors
    /// [`FemError::Mesh`] when there are no tets, a coordinate is not finite, an index is out
    /// of range or repeated within a tet, or a tet is flat (|volume| <= 1e-14 x the cube of
    /// the bounding-box diagonal).
    pub fn new(nodes: Vec<Point3>, tets: Vec<[u32; 4]>) -> Result<TetMesh, FemError> {
        if tets.is_empty() {
            return Err(FemError::Mesh("the mesh has no tetrahedra".into()));
        }
        if let Some(i) = nodes.iter().position(|p| !p.iter().all(|c| c.is_finite())) {
            return Err(FemError::Mesh(format!(
                "node {i} has a non-finite coordinate {:?}",
                nodes[i]
            )));
        }
        let n = nodes.len();
        for (t, tet) in tets.iter().enumerate() {
            if let Some(&i) = tet.iter().find(|&&i| i as usize >= n) {
                return Err(FemError::Mesh(format!(
                    "tet {t} refers to node {i}, but the mesh has {n} nodes"
                )));
            }
            for a in 0..4 {
                for b in a + 1..4 {
                    if tet[a] == tet[b] {
                        return Err(FemError::Mesh(format!(
                            "tet {t} repeats node {} ({tet:?})",
                            tet[a]
                        )));
                    }
                }
            }
        }
        let diag = Aabb::from_points(&nodes).map_or(0.0, |b| b.diagonal());
        let min_volume = 1e-14 * diag.powi(3);
        let mut tets = tets;
        let mut flipped = 0;
        for (t, tet) in tets.iter_mut().enumerate() {
            let [a, b, c, d] = tet.map(|i| nodes[i as usize]);
            let v = signed_volume(&a, &b, &c, &d);
            if v.abs() <= min_volume {
                return Err(FemError::Mesh(format!(
                    "tet {t} ({tet:?}) is flat: volume {v:.3e} m^3 for a bounding-box \
                     diagonal of {diag:.3e} m"
                )));
            }
            if v < 0.0 {
                tet.swap(2, 3);
                flipped += 1;
            }
        }
        Ok(TetMesh {
            nodes,
            tets,
            flipped,
        })
    }

    /// The conforming Kuhn mesh of the box [min, max] (metres) with `cells` = [nx, ny, nz]
    /// cubes per axis (each >= 1): (nx+1)(ny+1)(nz+1) nodes, 6 nx ny nz tets.
    ///
    /// # Errors
    /// [`FemError::Mesh`] when a cell count is 0, the box is empty or not finite, or the
    /// node count overflows u32.
    pub fn structured_box(
        min: Point3,
        max: Point3,
        cells: [usize; 3],
    ) -> Result<TetMesh, FemError> {
        if cells.contains(&0) {
            return Err(FemError::Mesh(format!(
                "cell counts must be >= 1, got {cells:?}"
            )));
        }
        if !(0..3).all(|a| min[a].is_finite() && max[a].is_finite() && max[a] > min[a]) {
            return Err(FemError::Mesh(format!(
                "box [{min:?}, {max:?}] is empty or not finite"
            )));
        }
        let [nx, ny, nz] = cells;
        let count = (nx + 1)
            .checked_mul(ny + 1)
            .and_then(|v| v.checked_mul(nz + 1))
            .filter(|&v| v <= u32::MAX as usize)
            .ok_or_else(|| FemError::Mesh(format!("{cells:?} cells: too many nodes for u32")))?;
        let mut nodes = Vec::with_capacity(count);
        for k in 0..=nz {
            for j in 0..=ny {
                for i in 0..=nx {
                    let t = [
                        i as f64 / nx as f64,
                        j as f64 / ny as f64,
                        k as f64 / nz as f64,
                    ];
                    nodes.push([0, 1, 2].map(|a| min[a] + t[a] * (max[a] - min[a])));
                }
            }
        }
        let id = |i: usize, j: usize, k: usize| (i + (nx + 1) * (j + (ny + 1) * k)) as u32;
        let mut tets = Vec::with_capacity(6 * nx * ny * nz);
        for k in 0..nz {
            for j in 0..ny {
                for i in 0..nx {
                    push_kuhn_cell(&mut tets, |bits| {
                        id(
                            i + (bits & 1) as usize,
                            j + ((bits >> 1) & 1) as usize,
                            k + ((bits >> 2) & 1) as usize,
                        )
                    });
                }
            }
        }
        TetMesh::new(nodes, tets)
    }

    /// Node rest positions, N x 3, metres.
    pub fn nodes(&self) -> &[Point3] {
        &self.nodes
    }

    /// Tets, T x 4 zero-based node indices, positively oriented.
    pub fn tets(&self) -> &[[u32; 4]] {
        &self.tets
    }

    /// Number of nodes N.
    pub fn num_nodes(&self) -> usize {
        self.nodes.len()
    }

    /// Number of tets T.
    pub fn num_tets(&self) -> usize {
        self.tets.len()
    }

    /// How many input tets were negatively oriented and had their last two nodes swapped.
    pub fn flipped_tets(&self) -> usize {
        self.flipped
    }

    /// Rest volume of each tet, T entries, m^3 (all > 0).
    pub fn tet_volumes(&self) -> Vec<f64> {
        self.tets
            .iter()
            .map(|t| {
                let [a, b, c, d] = t.map(|i| self.nodes[i as usize]);
                signed_volume(&a, &b, &c, &d)
            })
            .collect()
    }

    /// Total rest volume, m^3.
    pub fn volume(&self) -> f64 {
        self.tet_volumes().iter().sum()
    }

    /// Lumped volume per node (a quarter of each adjacent tet's volume), N entries, m^3.
    /// Nodes that belong to no tet get 0.
    pub fn node_volumes(&self) -> Vec<f64> {
        let mut v = vec![0.0; self.nodes.len()];
        for (t, vol) in self.tets.iter().zip(self.tet_volumes()) {
            for &i in t {
                v[i as usize] += 0.25 * vol;
            }
        }
        v
    }

    /// Centroid of each tet, T x 3, metres.
    pub fn centroids(&self) -> Vec<Point3> {
        self.tets
            .iter()
            .map(|t| {
                let mut c = [0.0; 3];
                for &i in t {
                    for a in 0..3 {
                        c[a] += 0.25 * self.nodes[i as usize][a];
                    }
                }
                c
            })
            .collect()
    }

    /// Bounding box of the nodes, metres.
    pub fn bounding_box(&self) -> Aabb {
        Aabb::from_points(&self.nodes).expect("a valid mesh has nodes")
    }

    /// Indices of the nodes for which `select(position)` is true, ascending.
    pub fn select_nodes(&self, select: impl Fn(&Point3) -> bool) -> Vec<usize> {
        (0..self.nodes.len())
            .filter(|&i| select(&self.nodes[i]))
            .collect()
    }
}

/// Append the 6 Kuhn tets of one cell, with `corner(bits)` the node index of a cell corner.
pub(crate) fn push_kuhn_cell(tets: &mut Vec<[u32; 4]>, corner: impl Fn(u8) -> u32) {
    for t in KUHN {
        tets.push(t.map(&corner));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn structured_box_counts_and_volume() {
        let m = TetMesh::structured_box([0.0; 3], [5.0, 1.0, 2.0], [5, 2, 3]).unwrap();
        assert_eq!(m.num_nodes(), 6 * 3 * 4);
        assert_eq!(m.num_tets(), 6 * 5 * 2 * 3);
        // Every cell is split exactly: the tet volumes sum to the box volume to round-off.
        assert!((m.volume() - 10.0).abs() < 1e-12);
        assert!((m.node_volumes().iter().sum::<f64>() - 10.0).abs() < 1e-12);
        assert!(m.tet_volumes().iter().all(|&v| v > 0.0));
    }

    #[test]
    fn structured_box_is_conforming() {
        // Conforming: every interior triangle is shared by exactly two tets, boundary
        // triangles by one, and the boundary area equals the box surface.
        let m = TetMesh::structured_box([0.0; 3], [1.0; 3], [2, 2, 2]).unwrap();
        let mut faces = std::collections::HashMap::new();
        for t in m.tets() {
            for skip in 0..4 {
                let mut f: Vec<u32> = (0..4).filter(|&i| i != skip).map(|i| t[i]).collect();
                f.sort();
                *faces.entry(f).or_insert(0) += 1;
            }
        }
        assert!(faces.values().all(|&c| c == 1 || c == 2));
        let boundary_area: f64 = faces
            .iter()
            .filter(|(_, &c)| c == 1)
            .map(|(f, _)| {
                let [a, b, c] = [0, 1, 2].map(|i| m.nodes()[f[i] as usize]);
                let u = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
                let v = [c[0] - a[0], c[1] - a[1], c[2] - a[2]];
                let n = [
                    u[1] * v[2] - u[2] * v[1],
                    u[2] * v[0] - u[0] * v[2],
                    u[0] * v[1] - u[1] * v[0],
                ];
                0.5 * (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt()
            })
            .sum();
        assert!((boundary_area - 6.0).abs() < 1e-12);
    }

    #[test]
    fn validation_rejects_bad_meshes_and_flips_orientation() {
        let nodes = vec![
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.0, 0.0, 1.0],
        ];
        let m = TetMesh::new(nodes.clone(), vec![[0, 2, 1, 3]]).unwrap();
        assert_eq!(m.flipped_tets(), 1);
        assert!((m.volume() - 1.0 / 6.0).abs() < 1e-15);
        assert!(TetMesh::new(nodes.clone(), vec![]).is_err());
        assert!(TetMesh::new(nodes.clone(), vec![[0, 1, 2, 4]]).is_err());
        assert!(TetMesh::new(nodes.clone(), vec![[0, 1, 1, 3]]).is_err());
        let mut flat = nodes.clone();
        flat[3] = [1.0, 1.0, 0.0];
        assert!(TetMesh::new(flat, vec![[0, 1, 2, 3]]).is_err());
        let mut nan = nodes;
        nan[0][1] = f64::NAN;
        assert!(TetMesh::new(nan, vec![[0, 1, 2, 3]]).is_err());
    }
}
