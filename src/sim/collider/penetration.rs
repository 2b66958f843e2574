//! What a point's query against an obstacle returns: the penetration depth, the push-out
//! direction and the Hessians of d^2/2 the contact penalty needs.

use crate::linalg3::{mat_vec, mul, outer, transpose, Mat3};

/// How deep a point is in an obstacle, and the derivatives the penalty needs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Penetration {
    /// Depth d > 0, metres (distance to the obstacle's surface).
    pub depth: f64,
    /// Unit push-out direction: the outward gradient of the signed distance.
    pub normal: [f64; 3],
    /// Exact Hessian of d^2/2 with respect to the point (3 x 3, dimensionless).
    pub hessian: Mat3,
    /// Its positive semi-definite part, for Newton (equal to `hessian` where that is PSD).
    pub hessian_psd: Mat3,
}

impl Penetration {
    /// A penetration whose d^2/2 is linear-squared along `u` (planes, boxes): Hessian u u^T.
    pub(super) fn flat(depth: f64, u: [f64; 3]) -> Penetration {
        let h = outer(&u);
        Penetration {
            depth,
            normal: u,
            hessian: h,
            hessian_psd: h,
        }
    }

    /// Depth `r - rho` from a round surface at distance `rho` from its core (a point, or a
    /// segment with unit direction `axis`), along the unit `u`.
    pub(super) fn round(r: f64, rho: f64, u: [f64; 3], axis: Option<[f64; 3]>) -> Penetration {
        let uu = outer(&u);
        // Curvature part (rho - r)/rho P, P the projector across u (and across the axis).
        let c = if rho > 0.0 { (rho - r) / rho } else { 0.0 };
        let hessian = std::array::from_fn(|i| {
            std::array::from_fn(|j| {
                let id = if i == j { 1.0 } else { 0.0 };
                let along = axis.map_or(0.0, |e| e[i] * e[j]);
                uu[i][j] + c * (id - along - uu[i][j])
            })
        });
        Penetration {
            depth: r - rho,
            normal: u,
            hessian,
            hessian_psd: uu,
        }
    }

    /// The Jacobian of the push-out direction with respect to the point, dn/dx (3 x 3, 1/m):
    /// the depth's gradient is -n and the Hessian of d^2/2 is n n^T + d Hess(d), so
    /// dn/dx = -Hess(d) = (n n^T - H) / d (zero for planes and faces; for a sphere, the
    /// projector across n over the point's distance from the centre, r - d).
    pub fn normal_jacobian(&self) -> Mat3 {
        let nn = outer(&self.normal);
        std::array::from_fn(|i| {
            std::array::from_fn(|j| (nn[i][j] - self.hessian[i][j]) / self.depth)
        })
    }

    /// The same penetration seen in the world frame of a pose with rotation `r`.
    pub(super) fn rotated(self, r: &Mat3) -> Penetration {
        let rt = transpose(r);
        let turn = |h: &Mat3| mul(&mul(r, h), &rt);
        Penetration {
            depth: self.depth,
            normal: mat_vec(r, &self.normal),
            hessian: turn(&self.hessian),
            hessian_psd: turn(&self.hessian_psd),
        }
    }
}
