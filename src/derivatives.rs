//! Derivatives against central differences: the one checker of every hand-derived gradient
//! and Hessian (the energy density's in `elasticity`, every simulation term's, the obstacles',
//! the FEM reference's). A leaf (it imports nothing of the crate), so the leaves' own tests can
//! use it; `sim::terms` re-exports it.

use faer::Mat;

/// A Hessian at z: d2E/dz2, len(z) square.
pub type HessianFn<'a> = &'a dyn Fn(&[f64]) -> Mat<f64>;

/// How far an energy's gradient and Hessian are from central differences
/// ([`check_derivatives`]); the largest relative error over the directions tried.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DerivativeCheck {
    /// max over directions d of |(E(z + h d) - E(z - h d)) / 2h - g . d| / scale, with scale
    /// = max(|g . d|, |the difference quotient|, `floor.gradient`).
    pub gradient: f64,
    /// max over d of |(g(z + h d) - g(z - h d)) / 2h - H d| / max(|H d|, |the quotient|,
    /// `floor.hessian`), Euclidean norms (0 without a Hessian).
    pub hessian: f64,
}

/// The sizes below which [`check_derivatives`] measures errors absolutely: where a derivative
/// is much smaller than its typical size (a slope across the gradient, a small column of the
/// Hessian), its rounding is relative to that size, not to itself.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Floors {
    /// For the slopes g . d (energy units per unit of z times |d|).
    pub gradient: f64,
    /// For the products H d.
    pub hessian: f64,
}

impl Floors {
    /// The same floor for both.
    pub fn both(floor: f64) -> Floors {
        Floors {
            gradient: floor,
            hessian: floor,
        }
    }
}

/// Compare the gradient (and, if given, the Hessian) of `energy` at `z` with central
/// differences along each of `directions` with step `h` (in units of z). `energy(z, grad)`
/// returns E(z) and writes dE/dz to `grad`; `hessian(z)` returns d2E/dz2 (len(z) square).
/// `floor` keeps the relative errors finite where a derivative vanishes ([`Floors`]).
///
/// The central quotient's truncation error is h^2/6 times the third derivative, its rounding
/// about eps |E| / h: choose h where both are below the tolerance the caller asserts.
pub fn check_derivatives(
    energy: impl Fn(&[f64], &mut [f64]) -> f64,
    hessian: Option<HessianFn<'_>>,
    z: &[f64],
    directions: &[Vec<f64>],
    h: f64,
    floor: Floors,
) -> DerivativeCheck {
    let n = z.len();
    let mut g = vec![0.0; n];
    energy(z, &mut g);
    let hz = hessian.map(|f| f(z));
    let mut worst = DerivativeCheck {
        gradient: 0.0,
        hessian: 0.0,
    };
    let shifted =
        |d: &[f64], s: f64| -> Vec<f64> { z.iter().zip(d).map(|(a, b)| a + s * b).collect() };
    let norm = |v: &[f64]| v.iter().map(|x| x * x).sum::<f64>().sqrt();
    for d in directions {
        let (zp, zm) = (shifted(d, h), shifted(d, -h));
        let (mut gp, mut gm) = (vec![0.0; n], vec![0.0; n]);
        let (ep, em) = (energy(&zp, &mut gp), energy(&zm, &mut gm));
        let quotient = (ep - em) / (2.0 * h);
        let slope: f64 = g.iter().zip(d).map(|(a, b)| a * b).sum();
        let scale = slope.abs().max(quotient.abs()).max(floor.gradient);
        worst.gradient = worst.gradient.max((quotient - slope).abs() / scale);
        if let Some(hz) = &hz {
            let hd: Vec<f64> = (0..n)
                .map(|i| (0..n).map(|j| hz[(i, j)] * d[j]).sum())
                .collect();
            let fd: Vec<f64> = gp
                .iter()
                .zip(&gm)
                .map(|(a, b)| (a - b) / (2.0 * h))
                .collect();
            let diff: Vec<f64> = hd.iter().zip(&fd).map(|(a, b)| a - b).collect();
            let scale = norm(&hd).max(norm(&fd)).max(floor.hessian);
            worst.hessian = worst.hessian.max(norm(&diff) / scale);
        }
    }
    worst
}

#[cfg(test)]
mod tests {
    use super::*;

    /// E = sum_i c_i z_i^4 / 4: exact derivatives pass, a wrong Hessian is caught.
    #[test]
    fn catches_a_wrong_hessian() {
        let c = [1.0, 2.0, 3.0];
        let energy = |z: &[f64], g: &mut [f64]| {
            for i in 0..3 {
                g[i] = c[i] * z[i].powi(3);
            }
            (0..3).map(|i| c[i] * z[i].powi(4) / 4.0).sum()
        };
        let right = |z: &[f64]| {
            Mat::from_fn(3, 3, |i, j| {
                if i == j {
                    3.0 * c[i] * z[i] * z[i]
                } else {
                    0.0
                }
            })
        };
        let wrong = |z: &[f64]| {
            Mat::from_fn(3, 3, |i, j| {
                if i == j {
                    2.0 * c[i] * z[i] * z[i]
                } else {
                    0.0
                }
            })
        };
        let z = [0.7, -0.4, 1.1];
        let dirs = vec![vec![1.0, 0.5, -0.3], vec![0.0, 1.0, 0.0]];
        // h = 1e-4: truncation h^2 |E'''| / 6 ~ 1e-8 relative, rounding eps / h ~ 1e-12.
        let ok = check_derivatives(energy, Some(&right), &z, &dirs, 1e-4, Floors::both(1e-12));
        assert!(ok.gradient < 1e-7 && ok.hessian < 1e-7, "{ok:?}");
        let bad = check_derivatives(energy, Some(&wrong), &z, &dirs, 1e-4, Floors::both(1e-12));
        assert!(bad.hessian > 0.1, "{bad:?}");
    }
}
