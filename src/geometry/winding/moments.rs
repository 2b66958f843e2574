//! Multipole moments of a set of triangles and their far-field solid angle.
//!
//! With K(r) = r / |r|^3, the solid angle of a surface patch P seen from q is
//! `Omega(q) = integral over P of K(x - q) . n(x) dA`. Expanding K about the patch centre p,
//! with d = p - q and s = x - p,
//!
//! ```text
//! Omega ~ K_i(d) N_i + dK_i/dr_j(d) M_ij + 1/2 d2K_i/dr_j dr_k(d) C_ijk
//! N_i    = integral n_i dA                 (vector area)
//! M_ij   = integral n_i s_j dA
//! C_ijk  = integral n_i s_j s_k dA         (symmetric in j, k)
//! ```
//!
//! The truncation error is O((r / |d|)^3) relative to the leading term (r: patch radius).

// Index loops over the three coordinates read like the tensor formulas above.
#![allow(clippy::needless_range_loop)]

use super::dot;
use crate::Point3;

/// Index of the symmetric pair (j, k) in the 6-vector [xx, yy, zz, xy, xz, yz].
const SYM: [[usize; 3]; 3] = [[0, 3, 4], [3, 1, 5], [4, 5, 2]];

/// Moments about some centre (the owner knows which).
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct Moments {
    /// `N_i`, m^2.
    pub n: Point3,
    /// `M_ij` at `3 i + j`, m^3.
    pub m: [f64; 9],
    /// `C_ijk` at `[i][SYM[j][k]]`, m^4.
    pub c: [[f64; 6]; 3],
}

impl Moments {
    /// Add a triangle with vertices `tri` relative to the centre (metres): its vector area
    /// times its first and second area moments.
    pub fn add_triangle(&mut self, tri: &[Point3; 3], varea: &Point3, area: f64) {
        let [u0, u1, u2] = tri;
        let uc = [0, 1, 2].map(|k| (u0[k] + u1[k] + u2[k]) / 3.0);
        // Second moment of the triangle about the centre:
        // integral s s^T dA = A/12 (sum_v u_v u_v^T + 9 uc uc^T).
        let mut s = [0.0; 6];
        for (j, row) in SYM.iter().enumerate() {
            for (k, &idx) in row.iter().enumerate().skip(j) {
                let sum = u0[j] * u0[k] + u1[j] * u1[k] + u2[j] * u2[k] + 9.0 * uc[j] * uc[k];
                s[idx] = area / 12.0 * sum;
            }
        }
        // Unit normal times these integrals = vector area / area times them.
        let unit = if area > 0.0 {
            varea.map(|x| x / area)
        } else {
            [0.0; 3]
        };
        for i in 0..3 {
            self.n[i] += varea[i];
            for j in 0..3 {
                self.m[3 * i + j] += varea[i] * uc[j];
            }
            for (acc, sv) in self.c[i].iter_mut().zip(&s) {
                *acc += unit[i] * sv;
            }
        }
    }

    /// Add `child`, whose moments are about a centre `shift` (child centre minus this centre,
    /// metres) away from this one's.
    pub fn add_shifted(&mut self, child: &Moments, shift: &Point3) {
        let e = shift;
        for i in 0..3 {
            self.n[i] += child.n[i];
            for j in 0..3 {
                self.m[3 * i + j] += child.m[3 * i + j] + child.n[i] * e[j];
            }
            // C'_ijk = C_ijk + M_ij e_k + M_ik e_j + N_i e_j e_k.
            for (j, row) in SYM.iter().enumerate() {
                for (k, &idx) in row.iter().enumerate().skip(j) {
                    self.c[i][idx] += child.c[i][idx]
                        + child.m[3 * i + j] * e[k]
                        + child.m[3 * i + k] * e[j]
                        + child.n[i] * e[j] * e[k];
                }
            }
        }
    }

    /// Far-field solid angle (steradians) seen from q, with `d` = centre - q and `d2 = |d|^2`.
    #[inline]
    pub fn far_field(&self, d: &Point3, d2: f64) -> f64 {
        let inv2 = 1.0 / d2;
        let inv3 = inv2 * inv2.sqrt();
        let m = &self.m;
        // Dipole: d.N / |d|^3.
        let t1 = dot(d, &self.n);
        // Quadrupole: tr(M) / |d|^3 - 3 d^T M d / |d|^5.
        let md = [
            m[0] * d[0] + m[1] * d[1] + m[2] * d[2],
            m[3] * d[0] + m[4] * d[1] + m[5] * d[2],
            m[6] * d[0] + m[7] * d[1] + m[8] * d[2],
        ];
        let t2 = (m[0] + m[4] + m[8]) - 3.0 * dot(d, &md) * inv2;
        // Octupole: 1/2 [-3 (2 a + b) / |d|^5 + 15 e / |d|^7] with
        // a = C_iik d_k, b = d_i C_ijj, e = C_ijk d_i d_j d_k.
        let (mut a, mut b, mut e) = (0.0, 0.0, 0.0);
        for i in 0..3 {
            let c = &self.c[i];
            // (C_i d)_j = C_ijk d_k
            let cd = [
                c[0] * d[0] + c[3] * d[1] + c[4] * d[2],
                c[3] * d[0] + c[1] * d[1] + c[5] * d[2],
                c[4] * d[0] + c[5] * d[1] + c[2] * d[2],
            ];
            a += cd[i];
            b += d[i] * (c[0] + c[1] + c[2]);
            e += d[i] * dot(d, &cd);
        }
        let t3 = 0.5 * (-3.0 * (2.0 * a + b) + 15.0 * e * inv2) * inv2;
        (t1 + t2 + t3) * inv3
    }
}

#[cfg(test)]
mod tests {
    use super::super::{cross, solid_angle, sub};
    use super::*;

    /// A small patch far away: the expansion error must fall like (r / |d|)^4 once the third
    /// term is in (error of the truncated series is O(r^3 / d^5) vs a leading O(r^2 / d^2)).
    #[test]
    fn expansion_converges_at_third_order() {
        let tris = [
            [[0.0, 0.0, 0.0], [1.0, 0.1, 0.2], [0.2, 1.0, -0.1]],
            [[1.0, 0.1, 0.2], [1.1, 1.2, 0.3], [0.2, 1.0, -0.1]],
            [[0.2, 1.0, -0.1], [1.1, 1.2, 0.3], [0.0, 0.7, 0.9]],
        ];
        let center = [0.5, 0.6, 0.2];
        let mut mom = Moments::default();
        for t in &tris {
            let rel = t.map(|v| sub(&v, &center));
            let varea = cross(&sub(&t[1], &t[0]), &sub(&t[2], &t[0])).map(|x| 0.5 * x);
            let area = dot(&varea, &varea).sqrt();
            mom.add_triangle(&rel, &varea, area);
        }
        let dir = [0.3, -0.5, 0.81];
        let mut errs = vec![];
        for dist in [8.0, 16.0, 32.0] {
            let q = [0, 1, 2].map(|k| center[k] + dist * dir[k]);
            let exact: f64 = tris
                .iter()
                .map(|t| solid_angle(&t[0], &t[1], &t[2], &q))
                .sum();
            let approx =
                mom.far_field(&sub(&center, &q), dot(&sub(&center, &q), &sub(&center, &q)));
            errs.push((exact - approx).abs());
        }
        // Halving r/d should divide the error by about 2^5 = 32 (absolute error O(d^-5)).
        assert!(
            errs[0] / errs[1] > 20.0 && errs[1] / errs[2] > 20.0,
            "{errs:?}"
        );
    }

    /// Shifting moments to a new centre must equal computing them there directly.
    #[test]
    fn shift_matches_direct() {
        let t = [[0.0, 0.0, 0.0], [1.0, 0.1, 0.2], [0.2, 1.0, -0.1]];
        let varea = cross(&sub(&t[1], &t[0]), &sub(&t[2], &t[0])).map(|x| 0.5 * x);
        let area = dot(&varea, &varea).sqrt();
        let (p, p2) = ([0.3, 0.2, 0.1], [-0.4, 0.5, 0.9]);
        let mut at_p = Moments::default();
        at_p.add_triangle(&t.map(|v| sub(&v, &p)), &varea, area);
        let mut direct = Moments::default();
        direct.add_triangle(&t.map(|v| sub(&v, &p2)), &varea, area);
        let mut shifted = Moments::default();
        shifted.add_shifted(&at_p, &sub(&p, &p2));
        for i in 0..3 {
            for j in 0..9 {
                assert!((shifted.m[j] - direct.m[j]).abs() < 1e-14);
            }
            for k in 0..6 {
                assert!((shifted.c[i][k] - direct.c[i][k]).abs() < 1e-14, "{i} {k}");
            }
        }
    }
}
