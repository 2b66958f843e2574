//! Basis fitting residual (the paper's supplement, Sec. 9.1, Eq. 36, Tables 6 and 7): how well
//! a skinning basis can express given deformed frames, with the dynamics factored out.
//!
//! The map x(X) = X + sum_j W_j(X) Z_j [X; 1] is linear in z, and each output coordinate d
//! separates: x_d(X_i) - X_i,d = sum_{j,a} G[i, 4 j + a] Z_j[d, a] with the design matrix
//!
//! ```text
//! G[i, 4 j + a] = W_j(X_i) Xh_a(X_i),   Xh = [X; 1],   N nodes x 4 (m + 1).
//! ```
//!
//! Every frame and coordinate is one right-hand side of the same least-squares problem
//! min_z |G z - (x_d - X_d)|; the optimum leaves the residual r = (I - P) (x_d - X_d), with P
//! the orthogonal projector onto the column space of G. With r_t,i the 3-vector residual of
//! node i in frame t and D the rest bounding-box diagonal, [`FitResidual`] reports
//!
//! ```text
//! mean_abs_over_diagonal      = mean over t, i of |r_t,i| / D        (the formula printed under Eq. 36)
//! mean_squared_over_diagonal2 = mean over t, i of |r_t,i|^2 / D^2    (design.md's normalized MSE, applied to the fit)
//! max_over_diagonal           = max  over t, i of |r_t,i| / D
//! ```
//!
//! The paper's Table 6 holds the second (its printed formula lacks the square): on the bend
//! our basis gives 0.82-0.93 x its values in mean_squared_over_diagonal2 and falls with m by
//! the same factors, while mean_abs_over_diagonal is ~1e3 x larger; the evidence is in
//! docs/accuracy.md ("Basis fitting residual (Table 6)").
//!
//! Nothing is assumed about the basis beyond its weights at the nodes: its columns need not
//! be M-orthonormal, and no column needs to be the constant (bases with boundary handles).

use crate::geometry::Aabb;
use crate::precompute::skinning::{Basis, SkinningWeights};
use crate::{Error, Point3, Result};
use faer::linalg::matmul::matmul;
use faer::{Accum, Mat, Par};
use serde::{Deserialize, Serialize};

/// Right-hand sides are solved in blocks of at most this many entries (N x 3 x frames per
/// block; 2^23 doubles = 64 MiB), so 200 frames of 50k nodes never need the whole
/// N x 600 matrix at once. Small problems take every frame in one block.
const BLOCK_ENTRIES: usize = 1 << 23;

/// The least-squares fit of frames onto a basis: residuals over all frames and nodes, and
/// how well-posed the fit was.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct FitResidual {
    /// mean over frames t and nodes i of |r_t,i| / D (dimensionless): the average residual
    /// as printed under the paper's Eq. 36.
    pub mean_abs_over_diagonal: f64,
    /// mean over frames and nodes of |r_t,i|^2 / D^2 (dimensionless): the normalized MSE of
    /// design.md section 3 applied to the best fit, so directly comparable with the
    /// simulation's `normalized_mse` (it can never exceed it for the same basis and frames).
    pub mean_squared_over_diagonal2: f64,
    /// max over frames and nodes of |r_t,i| / D (dimensionless).
    pub max_over_diagonal: f64,
    /// Frame (0-based) of the largest residual.
    pub worst_frame: usize,
    /// Node (0-based) of the largest residual.
    pub worst_node: usize,
    /// D, the rest bounding-box diagonal of the nodes, metres.
    pub diagonal: f64,
    /// Frames fitted T.
    pub frames: usize,
    /// Nodes per frame N.
    pub nodes: usize,
    /// Columns of the design matrix G, 4 (m + 1).
    pub columns: usize,
    /// Numerical rank of G: singular values above `rank_tolerance` x the largest (of G with
    /// unit-norm columns). Below `columns`, some handle combinations are indistinguishable
    /// at the nodes; the fit is then the minimum-norm one and the residual is still the
    /// distance to the column space.
    pub rank: usize,
    /// Largest over smallest singular value of G with unit-norm columns (infinite, `null` in
    /// JSON, when G is exactly singular or has fewer rows than columns).
    pub condition_number: f64,
    /// The relative singular value threshold of `rank`: max(N, columns) x machine epsilon
    /// (LAPACK's and NumPy's `lstsq` default).
    pub rank_tolerance: f64,
}

impl FitResidual {
    /// Whether G is rank-deficient at the nodes (`rank < columns`).
    pub fn rank_deficient(&self) -> bool {
        self.rank < self.columns
    }
}

/// Fit every frame of `frames` (T frames x N positions, metres) onto `basis` by least
/// squares and report the residual. `rest` (N x 3, metres) are the nodes' rest positions
/// (for the beam benchmark, the FEM nodes); the basis weights are evaluated there.
///
/// # Errors
/// As [`fit_residual_from_weights`], plus [`Error::Coverage`] when a node lies outside the
/// basis's kernels.
pub fn fit_residual(basis: &Basis, rest: &[Point3], frames: &[Vec<Point3>]) -> Result<FitResidual> {
    check_inputs(rest, frames)?;
    let weights = basis.weights(rest)?;
    fit_residual_from_weights(&weights, rest, frames)
}

/// [`fit_residual`] with the weights at the nodes already evaluated (`weights.points()` must
/// be N, one row of m + 1 weights per rest node, m^(-3/2)).
///
/// # Errors
/// [`Error::InvalidParameter`] when there are no nodes or no frames, or all rest nodes
/// coincide (D = 0); [`Error::LengthMismatch`] when a frame or the weights do not have one
/// entry per rest node; [`Error::NonFinite`] when a rest position, a frame position (index
/// frame x N + node) or a weight (index: node) is NaN or infinite; [`Error::InvalidParameter`]
/// when the SVD does not converge.
pub fn fit_residual_from_weights(
    weights: &SkinningWeights,
    rest: &[Point3],
    frames: &[Vec<Point3>],
) -> Result<FitResidual> {
    fit_in_blocks(weights, rest, frames, BLOCK_ENTRIES)
}

/// [`fit_residual_from_weights`] with right-hand sides in blocks of at most `block_entries`
/// (at least one frame per block).
fn fit_in_blocks(
    weights: &SkinningWeights,
    rest: &[Point3],
    frames: &[Vec<Point3>],
    block_entries: usize,
) -> Result<FitResidual> {
    check_inputs(rest, frames)?;
    let n = rest.len();
    if weights.points() != n || weights.values.len() != n * weights.modes {
        return Err(Error::LengthMismatch {
            what: "fit_residual weights (rows, one per rest node)",
            expected: n,
            got: weights.points(),
        });
    }
    if let Some(k) = weights.values.iter().position(|w| !w.is_finite()) {
        return Err(Error::NonFinite {
            what: "fit_residual skinning weights at the rest nodes",
            index: k / weights.modes.max(1),
        });
    }
    let aabb = Aabb::from_points(rest).expect("rest is not empty");
    let diagonal = aabb.diagonal();
    if diagonal <= 0.0 {
        return Err(Error::param(
            "rest",
            format!("{n} nodes at one point"),
            "the rest bounding-box diagonal is 0; the residual cannot be normalized",
        ));
    }
    let columns = 4 * weights.modes;
    let basis = ColumnSpace::new(design_matrix(weights, rest, aabb.center(), diagonal))?;
    let u = basis.u.subcols(0, basis.rank);

    // Residual sums per frame (one partial sum per frame keeps the accumulation error small).
    let (mut sum_abs, mut sum_sq) = (0.0, 0.0);
    let (mut worst, mut worst_frame, mut worst_node) = (-1.0_f64, 0, 0);
    let per_block = (block_entries / (3 * n)).max(1);
    for (b, block) in frames.chunks(per_block).enumerate() {
        // Y: displacements x - X, one column per (frame, coordinate), then Y - U (U^T Y).
        let mut y = Mat::from_fn(n, 3 * block.len(), |i, c| {
            block[c / 3][i][c % 3] - rest[i][c % 3]
        });
        let mut coef = Mat::<f64>::zeros(basis.rank, y.ncols());
        matmul(
            coef.as_mut(),
            Accum::Replace,
            u.transpose(),
            y.as_ref(),
            1.0,
            Par::rayon(0),
        );
        matmul(
            y.as_mut(),
            Accum::Add,
            u,
            coef.as_ref(),
            -1.0,
            Par::rayon(0),
        );
        for f in 0..block.len() {
            let col = |d: usize| y.col(3 * f + d).try_as_col_major().unwrap().as_slice();
            let (rx, ry, rz) = (col(0), col(1), col(2));
            let (mut frame_abs, mut frame_sq) = (0.0, 0.0);
            for i in 0..n {
                let r2 = rx[i] * rx[i] + ry[i] * ry[i] + rz[i] * rz[i];
                frame_sq += r2;
                frame_abs += r2.sqrt();
                if r2 > worst {
                    (worst, worst_frame, worst_node) = (r2, b * per_block + f, i);
                }
            }
            sum_abs += frame_abs;
            sum_sq += frame_sq;
        }
    }
    let count = (frames.len() * n) as f64;
    Ok(FitResidual {
        mean_abs_over_diagonal: sum_abs / count / diagonal,
        mean_squared_over_diagonal2: sum_sq / count / (diagonal * diagonal),
        max_over_diagonal: worst.sqrt() / diagonal,
        worst_frame,
        worst_node,
        diagonal,
        frames: frames.len(),
        nodes: n,
        columns,
        rank: basis.rank,
        condition_number: basis.condition_number,
        rank_tolerance: basis.rank_tolerance,
    })
}

/// Non-empty, finite, one position per rest node in every frame.
fn check_inputs(rest: &[Point3], frames: &[Vec<Point3>]) -> Result<()> {
    let n = rest.len();
    if n == 0 {
        return Err(Error::param("rest", 0, "need at least one node to fit"));
    }
    if frames.is_empty() {
        return Err(Error::param("frames", 0, "need at least one frame to fit"));
    }
    crate::error::check_finite_points("fit_residual rest positions", rest)?;
    for (f, frame) in frames.iter().enumerate() {
        if frame.len() != n {
            return Err(Error::LengthMismatch {
                what: "fit_residual frame (positions, one per rest node)",
                expected: n,
                got: frame.len(),
            });
        }
        if let Some(i) = frame.iter().position(|p| !p.iter().all(|c| c.is_finite())) {
            return Err(Error::NonFinite {
                what: "fit_residual frames (index = frame x nodes + node)",
                index: f * n + i,
            });
        }
    }
    Ok(())
}

/// G with the homogeneous coordinates centred and scaled, [(X - c) / D; 1], and every column
/// scaled to unit norm (a zero column stays zero). Both are invertible changes of the
/// unknowns (per handle a 4 x 4 affine change, then a diagonal scaling), so the column space
/// and the residual are those of [W_j(X) X_a, W_j(X)]; they only keep the rank decision and
/// the condition number free of the object's position, size and unit.
fn design_matrix(w: &SkinningWeights, rest: &[Point3], center: Point3, diagonal: f64) -> Mat<f64> {
    let modes = w.modes;
    let mut g = Mat::from_fn(rest.len(), 4 * modes, |i, col| {
        let (j, a) = (col / 4, col % 4);
        let xa = if a == 3 {
            1.0
        } else {
            (rest[i][a] - center[a]) / diagonal
        };
        w.values[i * modes + j] * xa
    });
    for c in 0..g.ncols() {
        let norm = g.col(c).norm_l2();
        if norm > 0.0 {
            let s = 1.0 / norm;
            g.col_mut(c).iter_mut().for_each(|v| *v *= s);
        }
    }
    g
}

/// An orthonormal basis of the numerical column space of G, from its thin SVD.
///
/// Why the SVD and not the normal equations G^T G z = G^T y: forming G^T G squares the
/// condition number (beam weights at m = 32 give G well above 1e3 even after column scaling,
/// and bases with boundary handles can be nearly dependent at the nodes), while the residuals
/// of interest are ~1e-4 of the displacements, so the normal equations would lose the digits
/// that are being measured. The SVD (faer's is a Householder QR followed by the SVD of R for
/// a tall G) is backward stable, reveals the rank, and gives the residual as
/// y - U_r (U_r^T y), accurate to ~ eps |y| whatever the conditioning.
struct ColumnSpace {
    /// Left singular vectors, N x min(N, columns), by decreasing singular value.
    u: Mat<f64>,
    rank: usize,
    condition_number: f64,
    rank_tolerance: f64,
}

impl ColumnSpace {
    fn new(g: Mat<f64>) -> Result<Self> {
        let (rows, cols) = (g.nrows(), g.ncols());
        let svd = g.thin_svd().map_err(|e| {
            Error::param(
                "fit_residual",
                format!("{rows} x {cols} design matrix"),
                format!("its SVD failed: {e:?}"),
            )
        })?;
        let s: Vec<f64> = svd.S().column_vector().iter().copied().collect();
        let rank_tolerance = rows.max(cols) as f64 * f64::EPSILON;
        let smax = s.first().copied().unwrap_or(0.0);
        let rank = s.iter().filter(|&&v| v > rank_tolerance * smax).count();
        let smin = if s.len() < cols {
            0.0
        } else {
            s.last().copied().unwrap_or(0.0)
        };
        Ok(ColumnSpace {
            u: svd.U().to_owned(),
            rank,
            condition_number: if smin > 0.0 {
                smax / smin
            } else {
                f64::INFINITY
            },
            rank_tolerance,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::eigen::SplitMix64;
    use crate::precompute::sampling::Resolution;
    use crate::precompute::{build_basis, BasisOptions, SolverConfig};
    use crate::progress::Silent;

    /// A basis of a 2 x 1 x 1 m box: `kernels` kernels, m = `modes`, dense eigensolver.
    fn box_basis(kernels: usize, modes: usize) -> Basis {
        let shape = crate::io::read_shape("box:2,1,1", &Default::default()).unwrap();
        let opts = BasisOptions {
            kernels,
            modes,
            resolution: Some(Resolution::Count(4000)),
            solver: SolverConfig::Dense,
            ..BasisOptions::default()
        };
        build_basis(&shape, &opts, &Silent).unwrap().basis
    }

    /// Nodes of a regular (nx + 1) x (ny + 1) x (nz + 1) lattice in the box, pulled 2% inside
    /// so every node is well covered, jiggled by a seeded 1% so no symmetry is exact.
    fn nodes(n: [usize; 3], seed: u64) -> Vec<Point3> {
        let size = [2.0, 1.0, 1.0];
        let mut rng = SplitMix64::new(seed);
        let mut out = Vec::new();
        for i in 0..=n[0] {
            for j in 0..=n[1] {
                for k in 0..=n[2] {
                    let t = [i, j, k];
                    out.push(std::array::from_fn(|a| {
                        let u = t[a] as f64 / n[a] as f64;
                        let jiggle = 0.01 * (rng.next_f64() - 0.5) / n[a] as f64;
                        size[a] * (0.02 + 0.96 * (u + jiggle).clamp(0.0, 1.0))
                    }));
                }
            }
        }
        out
    }

    /// x = X + B z at `rest` (the map of sim/terms.rs: b[4 j + a] = W_j(X) Xh_a, row d of
    /// z is the d-th block of 4 (m + 1)).
    fn map(w: &SkinningWeights, rest: &[Point3], z: &[f64]) -> Vec<Point3> {
        let n4 = 4 * w.modes;
        rest.iter()
            .enumerate()
            .map(|(i, x)| {
                let xh = [x[0], x[1], x[2], 1.0];
                std::array::from_fn(|d| {
                    let mut v = x[d];
                    for j in 0..w.modes {
                        for a in 0..4 {
                            v += w.values[i * w.modes + j] * xh[a] * z[d * n4 + 4 * j + a];
                        }
                    }
                    v
                })
            })
            .collect()
    }

    /// The same basis with its columns mixed by a seeded random matrix (plus the identity,
    /// so it is invertible): no column is the constant, none is M-orthonormal.
    fn mixed(basis: &Basis, seed: u64) -> Basis {
        let n = basis.modes();
        let mut rng = SplitMix64::new(seed);
        let mix = Mat::from_fn(n, n, |i, j| {
            (if i == j { 2.0 } else { 0.0 }) + rng.next_f64() - 0.5
        });
        Basis {
            coefficients: &basis.coefficients * &mix,
            ..basis.clone()
        }
    }

    /// (a) Frames the basis produces itself (random z, displacements ~0.1 D) fit to round-off.
    /// The residual is y - U (U^T y) with U orthonormal to ~ c n eps (n = 4 (m + 1) = 24
    /// columns), so |r| <= ~ n eps |y|_2 per column, |y|_2 <= sqrt(N) max|y|: with N = 200 and
    /// max|y| ~ 0.2 D that is ~1e-14 D. 1e-11 D leaves three orders for the constant c and
    /// still fails for any wrong design matrix (a missing X_a column leaves ~1e-2 D).
    #[test]
    fn frames_made_by_the_basis_fit_to_round_off() {
        let basis = box_basis(60, 5);
        let rest = nodes([9, 4, 3], 1);
        let w = basis.weights(&rest).unwrap();
        let n4 = 4 * basis.modes();
        let mut rng = SplitMix64::new(7);
        let frames: Vec<Vec<Point3>> = (0..5)
            .map(|_| {
                // W ~ V^(-1/2) = 0.7 m^(-3/2), Xh <= 2, 24 terms: |B z| ~ 0.1 D.
                let z: Vec<f64> = (0..3 * n4).map(|_| 0.2 * (rng.next_f64() - 0.5)).collect();
                map(&w, &rest, &z)
            })
            .collect();
        let moved = frames[0]
            .iter()
            .zip(&rest)
            .map(|(p, q)| (0..3).map(|d| (p[d] - q[d]).powi(2)).sum::<f64>().sqrt())
            .fold(0.0, f64::max);
        let d = Aabb::from_points(&rest).unwrap().diagonal();
        assert!(moved > 0.02 * d, "the frames must move: {moved}");
        let fit = fit_residual(&basis, &rest, &frames).unwrap();
        assert_eq!((fit.frames, fit.nodes, fit.columns), (5, rest.len(), n4));
        assert_eq!(fit.rank, n4, "full rank expected: {fit:?}");
        assert!(fit.max_over_diagonal < 1e-11, "{fit:?}");
        assert!(fit.mean_abs_over_diagonal <= fit.max_over_diagonal);
        assert!(fit.mean_squared_over_diagonal2 < 1e-22, "{fit:?}");
        // The same for a basis whose columns are mixed (no constant column, not orthonormal).
        let fit = fit_residual(&mixed(&basis, 3), &rest, &frames).unwrap();
        assert!(fit.max_over_diagonal < 1e-11, "{fit:?}");
    }

    /// (b) An affine deformation (finite stretch, shear, rotation, translation) is reproduced
    /// by any basis whose span holds the constant (RKPM reproduces linear fields): the
    /// constant mode, or a mixture of it with the others. Tolerance as in (a).
    #[test]
    fn affine_frames_fit_to_round_off() {
        let basis = box_basis(60, 3);
        let rest = nodes([9, 4, 3], 2);
        let a = [[1.1, 0.2, -0.1], [-0.3, 0.9, 0.25], [0.05, -0.2, 1.2]];
        let t = [0.3, -0.5, 0.2];
        let frame: Vec<Point3> = rest
            .iter()
            .map(|x| std::array::from_fn(|d| (0..3).map(|k| a[d][k] * x[k]).sum::<f64>() + t[d]))
            .collect();
        for b in [basis.clone(), mixed(&basis, 11)] {
            let fit = fit_residual(&b, &rest, std::slice::from_ref(&frame)).unwrap();
            assert!(fit.max_over_diagonal < 1e-11, "{fit:?}");
        }
        // Whereas a basis without the constant in its span (drop the constant column) cannot:
        // a pure translation is then not reproduced.
        let dropped = Basis {
            coefficients: basis.coefficients.subcols(1, basis.modes() - 1).to_owned(),
            ..basis.clone()
        };
        let fit = fit_residual(&dropped, &rest, std::slice::from_ref(&frame)).unwrap();
        assert!(fit.max_over_diagonal > 1e-5, "{fit:?}");
    }

    /// (c) A deformation outside the basis (a sine bend of short wavelength plus seeded
    /// noise): the residual equals the one of an independent solve, the normal equations in
    /// the raw map (b rows of sim/terms.rs, no centring or scaling) by Cholesky, then
    /// r = y - G z node by node. The problem is small and well conditioned (G with unit
    /// columns: ~50; raw G: below 1e3), so the normal equations' error in r is at most
    /// ~ cond^2 eps |y| / |r| ~ 1e6 x 2e-16 x 10 = 2e-9 relative: agreement to 1e-8 (measured
    /// 1e-15).
    #[test]
    fn residual_matches_an_independent_normal_equation_solve() {
        let basis = box_basis(40, 2);
        let rest = nodes([7, 3, 3], 3);
        let mut rng = SplitMix64::new(5);
        let frames: Vec<Vec<Point3>> = (1..=3)
            .map(|f| {
                let amp = 0.05 * f as f64;
                rest.iter()
                    .map(|x| {
                        let bend = amp * (4.0 * x[0]).sin() * (3.0 * x[2]).cos();
                        [
                            x[0] + 0.01 * (rng.next_f64() - 0.5),
                            x[1] + bend,
                            x[2] - 0.5 * bend + 0.01 * (rng.next_f64() - 0.5),
                        ]
                    })
                    .collect()
            })
            .collect();
        let fit = fit_residual(&basis, &rest, &frames).unwrap();

        let w = basis.weights(&rest).unwrap();
        let (n, n4) = (rest.len(), 4 * w.modes);
        let g = Mat::from_fn(n, n4, |i, c| {
            let xa = if c % 4 == 3 { 1.0 } else { rest[i][c % 4] };
            w.values[i * w.modes + c / 4] * xa
        });
        let gtg = g.transpose() * &g;
        let llt = gtg.llt(faer::Side::Lower).unwrap();
        let d = Aabb::from_points(&rest).unwrap().diagonal();
        let (mut sum_abs, mut sum_sq, mut max) = (0.0, 0.0, 0.0_f64);
        for frame in &frames {
            let y = Mat::from_fn(n, 3, |i, c| frame[i][c] - rest[i][c]);
            let z = faer::linalg::solvers::Solve::solve(&llt, g.transpose() * &y);
            let r = &y - &g * &z;
            for i in 0..n {
                let r2: f64 = (0..3).map(|c| r[(i, c)].powi(2)).sum();
                sum_abs += r2.sqrt();
                sum_sq += r2;
                max = max.max(r2.sqrt());
            }
        }
        let count = (frames.len() * n) as f64;
        let expected = [sum_abs / count / d, sum_sq / count / (d * d), max / d];
        let got = [
            fit.mean_abs_over_diagonal,
            fit.mean_squared_over_diagonal2,
            fit.max_over_diagonal,
        ];
        assert!(
            expected[0] > 1e-3,
            "the deformation must be outside the basis: {expected:?}"
        );
        for (e, g) in expected.iter().zip(&got) {
            assert!(
                (e - g).abs() <= 1e-8 * e,
                "expected {expected:?}, got {got:?}"
            );
        }
        assert_eq!(fit.rank, n4);
        assert!(fit.condition_number.is_finite() && fit.condition_number >= 1.0);
    }

    /// A basis with a repeated column is rank-deficient by 4 (one handle's 4 columns); the
    /// rank says so and the residual is that of the basis without the repeat.
    #[test]
    fn a_repeated_column_is_reported_and_does_not_change_the_residual() {
        let basis = box_basis(40, 2);
        let rest = nodes([7, 3, 3], 4);
        let frame: Vec<Point3> = rest
            .iter()
            .map(|x| [x[0], x[1] + 0.1 * (3.0 * x[0]).sin(), x[2]])
            .collect();
        let frames = vec![frame];
        let k = basis.coefficients.nrows();
        let m1 = basis.modes();
        let repeated = Basis {
            coefficients: Mat::from_fn(k, m1 + 1, |i, j| basis.coefficients[(i, j.min(m1 - 1))]),
            ..basis.clone()
        };
        let a = fit_residual(&basis, &rest, &frames).unwrap();
        let b = fit_residual(&repeated, &rest, &frames).unwrap();
        assert!(!a.rank_deficient());
        assert!(b.rank_deficient(), "{b:?}");
        assert_eq!((b.rank, b.columns), (4 * m1, 4 * (m1 + 1)));
        assert!(b.condition_number > 1e12, "{b:?}");
        let rel = (a.mean_squared_over_diagonal2 - b.mean_squared_over_diagonal2).abs()
            / a.mean_squared_over_diagonal2;
        assert!(rel < 1e-8, "{a:?} {b:?}");
        assert!(a.mean_squared_over_diagonal2 > 1e-8);
    }

    /// (d) Bad input gives typed errors, never a panic.
    #[test]
    fn bad_input_gives_typed_errors() {
        let basis = box_basis(40, 2);
        let rest = nodes([3, 2, 2], 6);
        let good = vec![rest.clone(); 2];
        assert!(fit_residual(&basis, &rest, &good).is_ok());

        let mut short = good.clone();
        short[1].pop();
        let e = fit_residual(&basis, &rest, &short).unwrap_err();
        assert!(
            matches!(e, Error::LengthMismatch { expected, got, .. } if expected == rest.len() && got == rest.len() - 1),
            "{e}"
        );

        let mut nan = good.clone();
        nan[1][3][2] = f64::NAN;
        let e = fit_residual(&basis, &rest, &nan).unwrap_err();
        assert!(
            matches!(e, Error::NonFinite { index, .. } if index == rest.len() + 3),
            "{e}"
        );

        let mut bad_rest = rest.clone();
        bad_rest[2][0] = f64::INFINITY;
        let e = fit_residual(&basis, &bad_rest, &good).unwrap_err();
        assert!(matches!(e, Error::NonFinite { index: 2, .. }), "{e}");

        let e = fit_residual(&basis, &rest, &[]).unwrap_err();
        assert!(
            matches!(e, Error::InvalidParameter { name: "frames", .. }),
            "{e}"
        );
        let e = fit_residual(&basis, &[], &[vec![]]).unwrap_err();
        assert!(
            matches!(e, Error::InvalidParameter { name: "rest", .. }),
            "{e}"
        );

        let one = vec![[1.0, 0.5, 0.5]; 3];
        let e = fit_residual(&basis, &one, std::slice::from_ref(&one)).unwrap_err();
        assert!(
            matches!(e, Error::InvalidParameter { name: "rest", .. }),
            "{e}"
        );

        // Weights of another node count, or with a NaN (a hand-made basis).
        let w = basis.weights(&rest).unwrap();
        let e = fit_residual_from_weights(&w, &rest[1..], &[rest[1..].to_vec()]).unwrap_err();
        assert!(matches!(e, Error::LengthMismatch { .. }), "{e}");
        let mut wn = w.clone();
        wn.values[2 * wn.modes + 1] = f64::NAN;
        let e = fit_residual_from_weights(&wn, &rest, &good).unwrap_err();
        assert!(matches!(e, Error::NonFinite { index: 2, .. }), "{e}");

        // A node far outside the kernels.
        let mut far = rest.clone();
        far[0] = [50.0, 0.0, 0.0];
        let e = fit_residual(&basis, &far, std::slice::from_ref(&far)).unwrap_err();
        assert!(matches!(e, Error::Coverage { .. }), "{e}");
    }

    /// Frames in many blocks (two per block, the last one short) give what one block gives.
    #[test]
    fn frames_in_blocks_match_one_block() {
        let basis = box_basis(40, 2);
        let rest = nodes([5, 2, 2], 8);
        let n = rest.len();
        let frames: Vec<Vec<Point3>> = (0..7)
            .map(|f| {
                let s = 0.02 * f as f64;
                rest.iter()
                    .map(|x| [x[0], x[1] + s * (5.0 * x[0]).sin(), x[2] + s * s])
                    .collect()
            })
            .collect();
        let w = basis.weights(&rest).unwrap();
        let one = fit_in_blocks(&w, &rest, &frames, usize::MAX).unwrap();
        let many = fit_in_blocks(&w, &rest, &frames, 2 * 3 * n).unwrap();
        assert_eq!(
            (one.worst_frame, one.worst_node),
            (many.worst_frame, many.worst_node)
        );
        assert_eq!(
            one.worst_frame, 6,
            "the largest bend is the last frame: {one:?}"
        );
        for (a, b) in [
            (one.mean_abs_over_diagonal, many.mean_abs_over_diagonal),
            (
                one.mean_squared_over_diagonal2,
                many.mean_squared_over_diagonal2,
            ),
            (one.max_over_diagonal, many.max_over_diagonal),
        ] {
            assert!(a > 0.0 && (a - b).abs() <= 1e-12 * a, "{one:?} {many:?}");
        }
    }
}
