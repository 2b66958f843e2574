//! Simple closed meshes built in code: boxes and icospheres, for tests, examples and
//! benchmarks. Both return raw `(vertices V x 3 metres, triangles F x 3)` so callers can also
//! damage them on purpose (remove faces, flip triangles) before building a
//! [`crate::geometry::TriMesh`].

use crate::Point3;
use std::collections::HashMap;

/// The box `[0, size[0]] x [0, size[1]] x [0, size[2]]` (metres) as 8 vertices and 12
/// outward-oriented triangles.
pub fn box_mesh(size: [f64; 3]) -> (Vec<Point3>, Vec<[u32; 3]>) {
    let [lx, ly, lz] = size;
    // Vertex i has x = bit 0, y = bit 1, z = bit 2.
    let vertices = (0..8)
        .map(|i| {
            [
                if i & 1 != 0 { lx } else { 0.0 },
                if i & 2 != 0 { ly } else { 0.0 },
                if i & 4 != 0 { lz } else { 0.0 },
            ]
        })
        .collect();
    #[rustfmt::skip]
    let triangles = vec![
        [0, 2, 3], [0, 3, 1], // z = 0, normal -z
        [4, 5, 7], [4, 7, 6], // z = lz, normal +z
        [0, 1, 5], [0, 5, 4], // y = 0, normal -y
        [2, 6, 7], [2, 7, 3], // y = ly, normal +y
        [0, 4, 6], [0, 6, 2], // x = 0, normal -x
        [1, 3, 7], [1, 7, 5], // x = lx, normal +x
    ];
    (vertices, triangles)
}

/// Icosphere of `radius` (metres) centred at the origin: the icosahedron with every triangle
/// split in four `subdivisions` times, new vertices projected onto the sphere. It has
/// `20 * 4^subdivisions` outward-oriented triangles and `10 * 4^subdivisions + 2` vertices
/// (5 subdivisions: 20480 triangles). All vertices lie exactly on the sphere up to round-off,
/// so the polyhedron is inscribed in it.
pub fn icosphere(radius: f64, subdivisions: u32) -> (Vec<Point3>, Vec<[u32; 3]>) {
    let t = (1.0 + 5f64.sqrt()) / 2.0;
    #[rustfmt::skip]
    let mut vertices: Vec<Point3> = [
        [-1.0, t, 0.0], [1.0, t, 0.0], [-1.0, -t, 0.0], [1.0, -t, 0.0],
        [0.0, -1.0, t], [0.0, 1.0, t], [0.0, -1.0, -t], [0.0, 1.0, -t],
        [t, 0.0, -1.0], [t, 0.0, 1.0], [-t, 0.0, -1.0], [-t, 0.0, 1.0],
    ]
    .into_iter()
    .map(|p| project(p, radius))
    .collect();
    #[rustfmt::skip]
    let mut triangles: Vec<[u32; 3]> = vec![
        [0, 11, 5], [0, 5, 1], [0, 1, 7], [0, 7, 10], [0, 10, 11],
        [1, 5, 9], [5, 11, 4], [11, 10, 2], [10, 7, 6], [7, 1, 8],
        [3, 9, 4], [3, 4, 2], [3, 2, 6], [3, 6, 8], [3, 8, 9],
        [4, 9, 5], [2, 4, 11], [6, 2, 10], [8, 6, 7], [9, 8, 1],
    ];
    for _ in 0..subdivisions {
        let mut midpoint: HashMap<(u32, u32), u32> = HashMap::new();
        let mut mid = |a: u32, b: u32, vertices: &mut Vec<Point3>| -> u32 {
            let key = (a.min(b), a.max(b));
            *midpoint.entry(key).or_insert_with(|| {
                let (p, q) = (vertices[a as usize], vertices[b as usize]);
                vertices.push(project([0, 1, 2].map(|k| 0.5 * (p[k] + q[k])), radius));
                (vertices.len() - 1) as u32
            })
        };
        let mut next = Vec::with_capacity(4 * triangles.len());
        for &[a, b, c] in &triangles {
            let ab = mid(a, b, &mut vertices);
            let bc = mid(b, c, &mut vertices);
            let ca = mid(c, a, &mut vertices);
            next.extend_from_slice(&[[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]);
        }
        triangles = next;
    }
    (vertices, triangles)
}

fn project(p: Point3, radius: f64) -> Point3 {
    let n = (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt();
    p.map(|x| x * radius / n)
}

/// Torus around the z axis centred at the origin: tube centre radius `major`, tube radius
/// `minor` (metres, `0 < minor < major`), `n` segments around z and `m` around the tube
/// (each at least 3). `2 n m` outward-oriented triangles; non-convex with a hole, which makes
/// it a good inside-test case.
pub fn torus(major: f64, minor: f64, n: u32, m: u32) -> (Vec<Point3>, Vec<[u32; 3]>) {
    let (n, m) = (n.max(3), m.max(3));
    let tau = std::f64::consts::TAU;
    let mut vertices = Vec::with_capacity((n * m) as usize);
    for i in 0..n {
        let u = tau * f64::from(i) / f64::from(n);
        for j in 0..m {
            let v = tau * f64::from(j) / f64::from(m);
            let rho = major + minor * v.cos();
            vertices.push([rho * u.cos(), rho * u.sin(), minor * v.sin()]);
        }
    }
    let id = |i: u32, j: u32| (i % n) * m + (j % m);
    let mut triangles = Vec::with_capacity((2 * n * m) as usize);
    for i in 0..n {
        for j in 0..m {
            let (a, b, c, d) = (id(i, j), id(i + 1, j), id(i + 1, j + 1), id(i, j + 1));
            triangles.push([a, b, c]);
            triangles.push([a, c, d]);
        }
    }
    (vertices, triangles)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn icosphere_counts_and_radius() {
        for s in 0..4 {
            let (v, t) = icosphere(3.0, s);
            assert_eq!(t.len(), 20 * 4usize.pow(s));
            assert_eq!(v.len(), 10 * 4usize.pow(s) + 2);
            for p in &v {
                let r = (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt();
                assert!((r - 3.0).abs() < 1e-14);
            }
        }
    }
}
