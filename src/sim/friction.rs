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

use crate::linalg3::{dot, mat_t_vec, mat_vec, norm, Mat3};
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

/// Which curvature of the friction potential a Newton model uses ([`model_hessian`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Curvature {
    /// The exact Hessian ([`hessian`]): Newton converges quadratically once every contact
    /// stays sticking or sliding, but along s a sliding contact has no curvature, so a step
    /// can overshoot where s turns through zero (the potential's kink, smoothed over eps).
    #[default]
    Exact,
    /// The Hessian of the potential's quadratic majorizer at d ([`majorizer_hessian`]): its
    /// friction part lies on or above the friction potential along every line, so it does
    /// not carry a step across the kink; Newton then converges linearly where contacts slide.
    Majorizer,
}

/// The projector I - n n^T of a unit normal.
pub fn tangent_projector(n: &[f64; 3]) -> Mat3 {
    crate::linalg3::identity_minus_outer(n)
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

/// The Hessian of the quadratic majorizer of D at the relative displacement d: with q = |s|^2,
/// f0(sqrt q) is concave in q, so D(d') <= D(d) + mu lambda f1(y) / (2 y) (|s'|^2 - y^2) for
/// every d'; the right side's Hessian is mu lambda f1(y)/y P (positive semi-definite, at least
/// the exact Hessian along every direction).
pub fn majorizer_hessian(mu_lambda: f64, eps: f64, p: &Mat3, d: &[f64; 3]) -> Mat3 {
    let a = mu_lambda * f1_over_y(norm(&project(p, d)), eps);
    std::array::from_fn(|r| std::array::from_fn(|c| a * p[r][c]))
}

/// The friction Hessian a model of the given curvature uses.
pub fn model_hessian(
    curvature: Curvature,
    mu_lambda: f64,
    eps: f64,
    p: &Mat3,
    d: &[f64; 3],
) -> Mat3 {
    match curvature {
        Curvature::Exact => hessian(mu_lambda, eps, p, d),
        Curvature::Majorizer => majorizer_hessian(mu_lambda, eps, p, d),
    }
}

/// A collider contact at the start of a step, as lagged friction keeps it
/// ([`crate::sim::terms::ContactTerm::friction_lag`]), with the derivatives of what it keeps
/// with respect to the point's start position x0 (for the reverse pass).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ColliderLag {
    /// The cubature point (index into the term's points).
    pub point: usize,
    /// The collider (index into the environment's obstacles).
    pub obstacle: usize,
    /// The penalty's normal force kappa v d at the start of the step, N.
    pub normal_force: f64,
    /// Friction coefficient times the normal force, N.
    pub mu_lambda: f64,
    /// d(mu lambda)/dx0, N/m: mu kappa v times the depth's gradient.
    pub mu_lambda_gradient: [f64; 3],
    /// The contact normal n at the start of the step (unit).
    pub normal: [f64; 3],
    /// dn/dx0, 1/m ([`crate::sim::collider::Penetration::normal_jacobian`]).
    pub normal_jacobian: Mat3,
    /// I - n n^T.
    pub projector: Mat3,
    /// Where the obstacle would carry the point by the end of the step, metres.
    pub carried: Point3,
    /// d(carried)/dx0: the obstacle's rotation over the step, R1 R0^T.
    pub carry: Mat3,
    /// The point's position at the start of the step, x0, metres.
    pub start_position: Point3,
    /// The obstacle's pose translations at the start and the end of the step, metres (the
    /// points its pose gradients' rotations turn about).
    pub origins: [Point3; 2],
}

/// What the reverse pass of one lagged contact gives, for an adjoint `lam` (3 values, the
/// step's adjoint mapped to the contact's point) of its friction force g = mu lambda phi(s),
/// phi(s) = f1(|s|) s / |s|, s = P(n) (x - carried): dL through each lagged quantity.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LagAdjoint {
    /// lam . phi(s): -this is dL/d(mu lambda), per N.
    pub per_mu_lambda: f64,
    /// dL/dn through the projector P = I - n n^T.
    pub normal: [f64; 3],
    /// dL/d(carried), per metre.
    pub carried: [f64; 3],
    /// dL/dx0 through all three: the lag's dependence on the start position.
    pub start: [f64; 3],
}

/// The reverse pass of one lagged force g = mu lambda phi(s), phi(s) = f1(|s|) s / |s|,
/// s = P(n) d, for an adjoint `lam` (3 values) of g: (lam . phi(s), dL/dn through the
/// projector P = I - n n^T, dL/dd through P and phi). With w = Jphi(s) lam: dL/dd =
/// -mu lambda P w, and dL/dn = mu lambda ((n . d) w + (n . w) d) (from dP[d] =
/// -(dn (n . d) + n (dn . d))). Shared by collider and object-object contacts, whose d differ.
pub fn lagged_force_adjoint(
    mu_lambda: f64,
    eps: f64,
    normal: &[f64; 3],
    projector: &Mat3,
    d: &[f64; 3],
    lam: &[f64; 3],
) -> (f64, [f64; 3], [f64; 3]) {
    let s = project(projector, d);
    let identity: Mat3 = std::array::from_fn(|r| std::array::from_fn(|c| f64::from(r == c)));
    let phi = gradient(1.0, eps, &identity, &s);
    let per_mu_lambda = dot(&phi, lam);
    // w = Jphi(s) lam (Jphi symmetric).
    let w = mat_vec(&hessian(1.0, eps, &identity, &s), lam);
    let (nd, nw) = (dot(normal, d), dot(normal, &w));
    let through_normal: [f64; 3] = std::array::from_fn(|k| mu_lambda * (nd * w[k] + nw * d[k]));
    let through_d = project(projector, &w).map(|v| -mu_lambda * v);
    (per_mu_lambda, through_normal, through_d)
}

/// The reverse pass of one lagged contact at the end position `x` (metres), eps the
/// smoothing displacement: [`lagged_force_adjoint`] with d = x - carried, so dL/d(carried) =
/// -dL/dd; x0 enters through mu lambda, n (its Jacobian) and carried (the carry A).
pub fn lag_adjoint(lag: &ColliderLag, eps: f64, x: &Point3, lam: &[f64; 3]) -> LagAdjoint {
    let d: [f64; 3] = std::array::from_fn(|k| x[k] - lag.carried[k]);
    let (per_mu_lambda, normal, through_d) =
        lagged_force_adjoint(lag.mu_lambda, eps, &lag.normal, &lag.projector, &d, lam);
    let carried = through_d.map(|v| -v);
    let through_n = mat_t_vec(&lag.normal_jacobian, &normal);
    let through_carried = mat_t_vec(&lag.carry, &carried);
    let start = std::array::from_fn(|k| {
        -per_mu_lambda * lag.mu_lambda_gradient[k] + through_n[k] + through_carried[k]
    });
    LagAdjoint {
        per_mu_lambda,
        normal,
        carried,
        start,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Gradient and Hessian against central differences on both sides of eps (the shared
    /// checker, along the coordinates), and the force never above mu lambda.
    #[test]
    fn derivatives_match_finite_differences() {
        use crate::derivatives::{check_derivatives, Floors};
        let p = tangent_projector(&[0.0, 0.6, 0.8]);
        let (ml, eps) = (2.5, 1e-3);
        let coords: Vec<Vec<f64>> = (0..3)
            .map(|k| (0..3).map(|i| if i == k { 1.0 } else { 0.0 }).collect())
            .collect();
        for scale in [1e-5, 4e-4, 9e-4, 2e-3, 5e-2] {
            let d = [0.7 * scale, -0.3 * scale, 0.5 * scale];
            let g = gradient(ml, eps, &p, &d);
            let energy = |x: &[f64], grad: &mut [f64]| {
                let x = [x[0], x[1], x[2]];
                grad.copy_from_slice(&gradient(ml, eps, &p, &x));
                potential(ml, eps, &project(&p, &x))
            };
            let hess = |x: &[f64]| {
                let h = hessian(ml, eps, &p, &[x[0], x[1], x[2]]);
                faer::Mat::from_fn(3, 3, |r, c| h[r][c])
            };
            // Central differences: O(step^2) truncation, well below 1e-6 relative here. The
            // slopes are at most mu lambda, the curvature mu lambda / min(|d|, eps): the
            // floors, so the bounds are the old absolute ones (1e-6 ml, 1e-5 ml / min).
            let floors = Floors {
                gradient: ml,
                hessian: ml / scale.min(eps),
            };
            let check = check_derivatives(energy, Some(&hess), &d, &coords, 1e-4 * scale, floors);
            assert!(
                check.gradient <= 1e-6 && check.hessian <= 1e-5,
                "{scale}: {check:?}"
            );
            assert!(norm(&g) <= ml * (1.0 + 1e-12));
        }
    }

    /// The majorizer's quadratic (value and gradient of D at d, Hessian
    /// [`majorizer_hessian`]) lies on or above D at every other d', sticking or sliding at
    /// either end, and its Hessian minus the exact one is positive semi-definite.
    #[test]
    fn majorizer_bounds_the_potential() {
        let p = tangent_projector(&[0.0, 0.6, 0.8]);
        let (ml, eps) = (2.5, 1e-3);
        let dirs = [[0.7, -0.3, 0.5], [-0.2, 0.9, -0.4], [0.1, 0.2, -0.9]];
        for scale in [0.0, 3e-4, 9e-4, 2e-3, 5e-2] {
            let d = dirs[0].map(|v| v * scale);
            let e = potential(ml, eps, &project(&p, &d));
            let g = gradient(ml, eps, &p, &d);
            let hm = majorizer_hessian(ml, eps, &p, &d);
            let he = hessian(ml, eps, &p, &d);
            for dir in &dirs {
                // The difference is PSD: v^T (Hm - He) v >= 0 up to rounding of entries of
                // size mu lambda / min(y, eps).
                let gap = dot(dir, &mat_vec(&hm, dir)) - dot(dir, &mat_vec(&he, dir));
                assert!(gap >= -1e-9 * ml / eps, "{scale} {dir:?}: {gap}");
                for step in [-3e-2, -1e-3, -2e-4, 5e-5, 7e-4, 4e-3, 1e-1] {
                    let v = dir.map(|c| c * step);
                    let d2: [f64; 3] = std::array::from_fn(|k| d[k] + v[k]);
                    let quad = e + dot(&g, &v) + 0.5 * dot(&v, &mat_vec(&hm, &v));
                    let actual = potential(ml, eps, &project(&p, &d2));
                    // Rounding of the quadratic's terms, each at most ~mu lambda (|v| + eps).
                    let slack = 1e-12 * ml * (1.0 + norm(&v) / eps);
                    assert!(actual <= quad + slack, "{scale} {step}: {actual} > {quad}");
                }
            }
        }
    }
}
