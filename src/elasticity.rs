//! The stable Neo-Hookean energy density that the eigenmodes and the simulator share
//! (design.md section 2, fixing the paper's Eq. 16):
//!
//! ```text
//! Psi(F) = mu/2 (tr(F^T F) - 3) + (lambda + mu)/2 (det F - gamma)^2 - (lambda + mu)/2 (1 - gamma)^2
//! gamma  = 1 + mu / (lambda + mu)
//! ```
//!
//! Psi(I) = 0, P(I) = 0 (stress free at rest), and its Hessian at F = I is the linear
//! elasticity tensor with Lame parameters lambda, mu.

/// A 3 x 3 matrix, row-major: `f[r][c]`.
pub type Mat3 = [[f64; 3]; 3];

/// det F.
#[inline]
pub fn det3(f: &Mat3) -> f64 {
    f[0][0] * (f[1][1] * f[2][2] - f[1][2] * f[2][1])
        - f[0][1] * (f[1][0] * f[2][2] - f[1][2] * f[2][0])
        + f[0][2] * (f[1][0] * f[2][1] - f[1][1] * f[2][0])
}

/// Cofactor matrix of F (= det(F) F^-T), the derivative of det F with respect to F.
#[inline]
pub fn cofactor3(f: &Mat3) -> Mat3 {
    [
        [
            f[1][1] * f[2][2] - f[1][2] * f[2][1],
            f[1][2] * f[2][0] - f[1][0] * f[2][2],
            f[1][0] * f[2][1] - f[1][1] * f[2][0],
        ],
        [
            f[0][2] * f[2][1] - f[0][1] * f[2][2],
            f[0][0] * f[2][2] - f[0][2] * f[2][0],
            f[0][1] * f[2][0] - f[0][0] * f[2][1],
        ],
        [
            f[0][1] * f[1][2] - f[0][2] * f[1][1],
            f[0][2] * f[1][0] - f[0][0] * f[1][2],
            f[0][0] * f[1][1] - f[0][1] * f[1][0],
        ],
    ]
}

/// Energy density Psi(F), J/m^3, for Lame parameters `lambda`, `mu` (Pa).
#[inline]
pub fn energy_density(f: &Mat3, lambda: f64, mu: f64) -> f64 {
    let lm = lambda + mu;
    let gamma = 1.0 + mu / lm;
    let tr: f64 = f.iter().flatten().map(|v| v * v).sum();
    let j = det3(f);
    0.5 * mu * (tr - 3.0) + 0.5 * lm * ((j - gamma).powi(2) - (1.0 - gamma).powi(2))
}

/// First Piola-Kirchhoff stress P = dPsi/dF = mu F + (lambda + mu)(J - gamma) cof(F), Pa.
#[inline]
pub fn first_piola(f: &Mat3, lambda: f64, mu: f64) -> Mat3 {
    let lm = lambda + mu;
    let gamma = 1.0 + mu / lm;
    let s = lm * (det3(f) - gamma);
    let c = cofactor3(f);
    let mut p = [[0.0; 3]; 3];
    for r in 0..3 {
        for col in 0..3 {
            p[r][col] = mu * f[r][col] + s * c[r][col];
        }
    }
    p
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rest_state_is_stress_free_and_piola_matches_fd() {
        let (l, m) = (3.0e6, 1.2e6);
        let id = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
        assert_eq!(energy_density(&id, l, m), 0.0);
        assert!(first_piola(&id, l, m)
            .iter()
            .flatten()
            .all(|v| v.abs() < 1e-9 * m));
        let f = [[1.1, 0.2, -0.05], [0.03, 0.9, 0.1], [-0.2, 0.05, 1.2]];
        let p = first_piola(&f, l, m);
        // Central differences, step 1e-6 on O(1) entries: error ~ h^2 Psi''' ~ 1e-12 (l + m),
        // round-off ~ eps Psi / h ~ 1e-10 (l + m): 1e-6 relative to lambda + mu is safe.
        for r in 0..3 {
            for c in 0..3 {
                let h = 1e-6;
                let (mut fp, mut fm) = (f, f);
                fp[r][c] += h;
                fm[r][c] -= h;
                let fd = (energy_density(&fp, l, m) - energy_density(&fm, l, m)) / (2.0 * h);
                assert!(
                    (fd - p[r][c]).abs() < 1e-6 * (l + m),
                    "{r}{c}: {fd} vs {}",
                    p[r][c]
                );
            }
        }
    }

    #[test]
    fn small_strain_limit_is_linear_elasticity() {
        // Psi(I + eps G) ~ eps^2 (mu |sym G|^2 + lambda/2 tr(G)^2) for symmetric G.
        let (l, m) = (2.0, 0.7);
        let g = [[0.3, 0.1, 0.0], [0.1, -0.2, 0.4], [0.0, 0.4, 0.5]];
        let eps = 1e-5;
        let mut f = [[0.0; 3]; 3];
        for r in 0..3 {
            for c in 0..3 {
                f[r][c] = if r == c { 1.0 } else { 0.0 } + eps * g[r][c];
            }
        }
        let tr = g[0][0] + g[1][1] + g[2][2];
        let gg: f64 = g.iter().flatten().map(|v| v * v).sum();
        let linear = eps * eps * (m * gg + 0.5 * l * tr * tr);
        // Relative error O(eps) from the cubic terms.
        assert!((energy_density(&f, l, m) / linear - 1.0).abs() < 1e-4);
    }
}
