//! Lagged, smoothed Coulomb friction (IPC style, Li et al. 2020): each contact that was
//! active at the start of the step keeps its normal force lambda (N) and its normal n from
//! then, and resists the tangential relative displacement s = P (dx_1 - dx_2 - shift) over the
//! step (P = I - n n^T) with the dissipative potential
//!
//!   D = mu lambda f0(|s|),  f0(y) = -y^3 / (3 eps^2) + y^2 / eps + eps / 3  (y < eps),  y  (y >= eps),
//!
//! eps = eps_v h the sliding displacement below which friction acts as a stiff spring
//! (static friction, smoothed). f0 is C2 at eps (f0' = f1 = 2 y/eps - y^2/eps^2, then 1), so
//! the force mu lambda f1(y) s / y never exceeds mu lambda, and its Hessian
//!
//!   y < eps:  mu lambda ((2/eps - y/eps^2) P - s s^T / (eps^2 y)),
//!   y >= eps: mu lambda (P - s s^T / y^2) / y
//!
//! is positive semi-definite (eigenvalues mu lambda (2/eps - 2y/eps^2) >= 0 along s, mu lambda
//! f1/y across it, 0 along n): Newton needs no projection.

use crate::linalg3::{norm, Mat3};
use crate::Point3;

/// The smoothed friction potential of one contact: its lagged mu lambda (N), normal
/// projector P and the tangential displacement s it sees.
pub fn potential(mu_lambda: f64, eps: f64, s: &[f64; 3]) -> f64 {
    let y = norm(s);
    mu_lambda * f0(y, eps)
}

fn f0(y: f64, eps: f64) -> f64 {
    if y < eps {
        -y * y * y / (3.0 * eps * eps) + y * y / eps + eps / 3.0
    } else {
        y
    }
}

/// f1(y) / y, finite at y = 0 (2 / eps).
fn f1_over_y(y: f64, eps: f64) -> f64 {
    if y < eps {
        2.0 / eps - y / (eps * eps)
    } else {
        1.0 / y
    }
}

/// The projector I - n n^T of a unit normal.
pub fn tangent_projector(n: &[f64; 3]) -> Mat3 {
    std::array::from_fn(|r| std::array::from_fn(|c| if r == c { 1.0 } else { 0.0 } - n[r] * n[c]))
}

/// P d.
pub fn project(p: &Mat3, d: &[f64; 3]) -> [f64; 3] {
    std::array::from_fn(|r| p[r][0] * d[0] + p[r][1] * d[1] + p[r][2] * d[2])
}

/// dD/dd for the relative displacement d (s = P d): mu lambda f1(y)/y s.
pub fn gradient(mu_lambda: f64, eps: f64, p: &Mat3, d: &[f64; 3]) -> [f64; 3] {
    let s = project(p, d);
    let c = mu_lambda * f1_over_y(norm(&s), eps);
    s.map(|v| c * v)
}

/// d^2 D / dd^2 (positive semi-definite, exact).
pub fn hessian(mu_lambda: f64, eps: f64, p: &Mat3, d: &[f64; 3]) -> Mat3 {
    let s = project(p, d);
    let y = norm(&s);
    let (a, b) = if y < eps {
        (
            2.0 / eps - y / (eps * eps),
            if y > 0.0 { -1.0 / (eps * eps * y) } else { 0.0 },
        )
    } else {
        (1.0 / y, -1.0 / (y * y * y))
    };
    std::array::from_fn(|r| std::array::from_fn(|c| mu_lambda * (a * p[r][c] + b * s[r] * s[c])))
}

/// A collider contact at the start of a step, as lagged friction keeps it
/// ([`crate::sim::terms::ContactTerm::friction_lag`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ColliderLag {
    /// The cubature point (index into the term's points).
    pub point: usize,
    /// Friction coefficient times the normal force, N.
    pub mu_lambda: f64,
    /// I - n n^T of the contact normal at the start of the step.
    pub projector: Mat3,
    /// Where the obstacle would carry the point by the end of the step, metres.
    pub carried: Point3,
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Gradient and Hessian against central differences on both sides of eps, and the force
    /// never above mu lambda.
    #[test]
    fn derivatives_match_finite_differences() {
        let p = tangent_projector(&[0.0, 0.6, 0.8]);
        let (ml, eps) = (2.5, 1e-3);
        for scale in [1e-5, 4e-4, 9e-4, 2e-3, 5e-2] {
            let d = [0.7 * scale, -0.3 * scale, 0.5 * scale];
            let g = gradient(ml, eps, &p, &d);
            let h = hessian(ml, eps, &p, &d);
            let e = |d: &[f64; 3]| potential(ml, eps, &project(&p, d));
            let step = 1e-4 * scale;
            for k in 0..3 {
                let mut a = d;
                let mut b = d;
                a[k] += step;
                b[k] -= step;
                // Central differences: O(step^2) truncation, well below 1e-6 relative here.
                let fd = (e(&a) - e(&b)) / (2.0 * step);
                assert!((fd - g[k]).abs() <= 1e-6 * ml, "{scale}: {fd} vs {}", g[k]);
                let (ga, gb) = (gradient(ml, eps, &p, &a), gradient(ml, eps, &p, &b));
                for r in 0..3 {
                    let fd = (ga[r] - gb[r]) / (2.0 * step);
                    let tol = 1e-5 * ml / scale.min(eps);
                    assert!((fd - h[r][k]).abs() <= tol, "{scale}: {fd} vs {}", h[r][k]);
                }
            }
            assert!(norm(&g) <= ml * (1.0 + 1e-12));
        }
    }
}
