//! Support radii: a_k = factor x (distance from p_k to its n-th nearest other centre).

use crate::{Error, Point3, Result};
use kiddo::{ImmutableKdTree, SquaredEuclidean};
use rayon::prelude::*;
use std::num::NonZero;

/// Largest support factor accepted by [`SupportOptions::validate`]. At 50 (default neighbour
/// 4) a support spans ~80 kernel spacings, i.e. every kernel of any practical K; far beyond,
/// the window is flat over the whole object and the moment matrices are singular in floating
/// point, and the coverage error would wrongly advise a larger factor.
pub const MAX_SUPPORT_FACTOR: f64 = 50.0;

/// Largest [`SupportOptions::neighbor`]: 1,000 (the default is 4).
pub const MAX_SUPPORT_NEIGHBOR: usize = 1000;

/// How support radii are chosen.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct SupportOptions {
    /// Multiplier on the n-th neighbour distance. Default 2.0: see docs/math.md ("Support
    /// radii") for the measurement behind it: with FPS centres it puts ~30 kernels over each
    /// point, keeps every moment matrix well conditioned (reciprocal condition > 1e-3 on the
    /// standard beam) and cond(M) in the 1e2-1e3 range, while the Neumann Laplacian
    /// eigenvalues of the box stay within a few per mille of the analytic ones.
    pub factor: f64,
    /// Which neighbour (1 = nearest other centre). Default 4: robust to the occasional pair of
    /// very close centres that FPS can produce near the boundary.
    pub neighbor: usize,
}

impl Default for SupportOptions {
    fn default() -> Self {
        Self {
            factor: 2.0,
            neighbor: 4,
        }
    }
}

impl SupportOptions {
    /// Check the ranges: factor finite, > 0 and at most [`MAX_SUPPORT_FACTOR`], neighbour >= 1.
    pub fn validate(&self) -> Result<()> {
        if !(self.factor.is_finite() && self.factor > 0.0) {
            return Err(Error::param(
                "support factor",
                self.factor,
                "must be a positive number (default 2.0)",
            ));
        }
        if self.factor > MAX_SUPPORT_FACTOR {
            return Err(Error::param(
                "support factor",
                self.factor,
                format!(
                    "must be at most {MAX_SUPPORT_FACTOR}: larger supports cover (almost) every \
                     kernel, so the matrices turn dense and the moment matrices lose precision; \
                     use 1.5 to 4 (default 2.0)"
                ),
            ));
        }
        if self.neighbor == 0 || self.neighbor > MAX_SUPPORT_NEIGHBOR {
            return Err(Error::param(
                "support neighbor",
                self.neighbor,
                format!(
                    "must be between 1 and {MAX_SUPPORT_NEIGHBOR} (default 4): the support \
                     radius reaches the n-th nearest kernel, so far more neighbours make every \
                     support cover the object and the matrices dense"
                ),
            ));
        }
        Ok(())
    }
}

/// Support radius of every centre (K, metres). Needs at least `neighbor + 1` centres.
pub fn support_radii(centers: &[Point3], opts: &SupportOptions) -> Result<Vec<f64>> {
    opts.validate()?;
    let k = centers.len();
    if k <= opts.neighbor {
        return Err(Error::param(
            "kernels",
            k,
            format!(
                "need more than {} kernels to size supports by the {}-th neighbour",
                opts.neighbor, opts.neighbor
            ),
        ));
    }
    let tree: ImmutableKdTree<f64, 3> = ImmutableKdTree::new_from_slice(centers)
        .map_err(|e| Error::param("kernels", k, format!("cannot build a k-d tree: {e:?}")))?;
    let want = NonZero::new(opts.neighbor + 1).expect("neighbor + 1 >= 2");
    let radii: Vec<f64> = centers
        .par_iter()
        .map(|p| {
            let found = tree
                .query(p)
                .nearest_n::<SquaredEuclidean<f64>>(want)
                .execute();
            // The query point itself is the nearest (distance 0); duplicates of it also count
            // as neighbours at distance 0, which the zero check below catches.
            let d2 = found.last().map_or(0.0, |r| r.distance);
            opts.factor * d2.sqrt()
        })
        .collect();
    if let Some(i) = radii.iter().position(|&a| !(a > 0.0 && a.is_finite())) {
        return Err(Error::param(
            "kernels",
            k,
            format!(
                "kernel {i} at {:?} has {} or more coincident centres, so its support radius is 0; \
                 remove duplicate points or use fewer kernels",
                centers[i], opts.neighbor
            ),
        ));
    }
    Ok(radii)
}
