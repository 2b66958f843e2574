//! Window functions w(s) of the normalized distance s = |X - p_k| / a_k, compactly supported on
//! s < 1.

use serde::{Deserialize, Serialize};

/// Width of the truncated Gaussian in units of the support radius: w = exp(-(s/alpha)^2),
/// shifted and rescaled so that w(1) = 0. With alpha = 0.4 the untruncated tail at s = 1 is
/// exp(-6.25) = 1.9e-3, so the shift changes the shape by less than 0.2 %.
pub const GAUSSIAN_ALPHA: f64 = 0.4;

/// The kernel (window) function family.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum KernelType {
    /// Cubic B-spline: 2/3 - 4s^2 + 4s^3 for s < 1/2, 4/3 (1 - s)^3 for 1/2 <= s < 1. C2,
    /// the default.
    #[default]
    Cubic,
    /// Quartic spline 1 - 6s^2 + 8s^3 - 3s^4. C2, slightly wider than the cubic.
    Quartic,
    /// Truncated Gaussian (the paper's choice), see [`GAUSSIAN_ALPHA`]. C0 at s = 1.
    Gaussian,
}

impl KernelType {
    /// Every kernel, in the order of the C API's `kernel` codes (0 cubic, 1 quartic, 2
    /// Gaussian) and of the command line's choices.
    pub const ALL: [KernelType; 3] = [KernelType::Cubic, KernelType::Quartic, KernelType::Gaussian];

    /// Lower-case name as used on the command line and in files.
    pub fn name(self) -> &'static str {
        crate::names::variant_name(&self)
    }

    /// Parse a lower-case name.
    pub fn from_name(name: &str) -> Option<Self> {
        crate::names::from_name(name)
    }

    /// Window value w(s) and w'(s) / s for s >= 0 (both 0 for s >= 1). The ratio is finite at
    /// s = 0 for every kernel (w'(0) = 0), so the gradient
    /// grad_X w = (w'(s) / s) (X - p) / a^2 never divides by zero.
    #[inline]
    pub fn eval(self, s: f64) -> (f64, f64) {
        if s >= 1.0 {
            return (0.0, 0.0);
        }
        match self {
            KernelType::Cubic => {
                if s < 0.5 {
                    (2.0 / 3.0 - 4.0 * s * s + 4.0 * s * s * s, -8.0 + 12.0 * s)
                } else {
                    let t = 1.0 - s;
                    (4.0 / 3.0 * t * t * t, -4.0 * t * t / s)
                }
            }
            KernelType::Quartic => {
                let s2 = s * s;
                (
                    1.0 - 6.0 * s2 + 8.0 * s2 * s - 3.0 * s2 * s2,
                    -12.0 + 24.0 * s - 12.0 * s2,
                )
            }
            KernelType::Gaussian => {
                let inv_a2 = 1.0 / (GAUSSIAN_ALPHA * GAUSSIAN_ALPHA);
                let tail = (-inv_a2).exp();
                let norm = 1.0 / (1.0 - tail);
                let e = (-s * s * inv_a2).exp();
                ((e - tail) * norm, -2.0 * inv_a2 * e * norm)
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn derivative_matches_finite_difference() {
        // Central differences with step 1e-6 have truncation error ~ h^2 |w'''| ~ 1e-11 and
        // round-off ~ eps / h ~ 1e-10: 1e-7 absolute is a safe bound for w' of order 1-10.
        for kind in KernelType::ALL {
            for i in 1..100 {
                let s = i as f64 / 100.0 + 0.003;
                if s >= 1.0 - 1e-5 {
                    continue;
                }
                let h = 1e-6;
                let fd = (kind.eval(s + h).0 - kind.eval(s - h).0) / (2.0 * h);
                let an = kind.eval(s).1 * s;
                assert!((fd - an).abs() < 1e-7, "{kind:?} s={s} fd={fd} an={an}");
            }
        }
    }

    #[test]
    fn compact_support_and_continuity() {
        for kind in KernelType::ALL {
            assert_eq!(kind.eval(1.0), (0.0, 0.0));
            assert_eq!(kind.eval(3.0), (0.0, 0.0));
            // Continuous at s = 1 (to within the cubic's (1 - s)^3 decay).
            assert!(kind.eval(1.0 - 1e-9).0.abs() < 1e-8, "{kind:?}");
            assert!(kind.eval(0.0).0 > 0.0);
            assert!(kind.eval(0.0).1.is_finite());
        }
        // The cubic pieces meet at s = 1/2 in value and slope.
        let (a, da) = KernelType::Cubic.eval(0.5 - 1e-12);
        let (b, db) = KernelType::Cubic.eval(0.5);
        assert!((a - b).abs() < 1e-11 && (da - db).abs() < 1e-10);
    }

    #[test]
    fn names_round_trip() {
        for kind in KernelType::ALL {
            assert_eq!(KernelType::from_name(kind.name()), Some(kind));
        }
        assert_eq!(KernelType::from_name("wendland"), None);
    }
}
