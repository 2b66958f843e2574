//! The quadratic and penalty terms of the incremental potential: inertia and gravity (exact,
//! from precomputed moments over all integration points), kinematic boundary penalties
//! (held or moving regions, also quadratic in z), and one-sided collider penalties (evaluated
//! on the cubature points).
//!
//! Every point position is x = X + B z with B = I_3 (x) b^T, b[4 j + a] = W_j(X) Xh_a, so a
//! weighted sum of |x - target|^2 over fixed points is a quadratic in z whose coefficients
//! are the moments sum c b b^T, sum c b Xh^T and sum c Xh Xh^T, computed once.

use crate::linalg3::dot;
use crate::precompute::skinning::SkinningWeights;
pub use crate::sim::collider::ColliderShape;
use crate::sim::collider::{Kinematics, Penetration};
use crate::sim::elastic::Layout;
use crate::sim::motion::{Motion, Rigid};
use crate::Point3;
use faer::prelude::ReborrowMut;
use faer::{Accum, Mat, MatMut, MatRef, Par};

/// Weighted moments of the map b over a point set.
#[derive(Debug, Clone)]
pub struct Moments {
    /// sum c b b^T, 4 (m + 1) square.
    pub bb: Mat<f64>,
    /// sum c b Xh^T, 4 (m + 1) x 4.
    pub bx: Mat<f64>,
    /// sum c Xh Xh^T, 4 x 4.
    pub xx: [[f64; 4]; 4],
    /// sum c b, 4 (m + 1).
    pub b: Vec<f64>,
    /// sum c.
    pub total: f64,
}

/// Rows of b for `points` (row i = b(X_i), 4 (m + 1) entries), each scaled by `scale[i]`.
fn b_rows(points: &[Point3], w: &SkinningWeights, idx: &[usize], scale: &[f64]) -> Mat<f64> {
    let nh = w.modes;
    Mat::from_fn(idx.len(), 4 * nh, |p, col| {
        let i = idx[p];
        let (j, a) = (col / 4, col % 4);
        let xa = if a == 3 { 1.0 } else { points[i][a] };
        scale[p] * w.values[i * nh + j] * xa
    })
}

impl Moments {
    /// Moments over the points `idx` of `points` with non-negative weights `coef` (one per
    /// index); `w` holds the skinning weights of all `points`.
    pub fn new(points: &[Point3], w: &SkinningWeights, idx: &[usize], coef: &[f64]) -> Moments {
        let n4 = 4 * w.modes;
        let mut bb = Mat::<f64>::zeros(n4, n4);
        let mut bx = Mat::<f64>::zeros(n4, 4);
        let mut xx = [[0.0; 4]; 4];
        let mut b = vec![0.0; n4];
        // Blocks of rows keep the dense scratch small for millions of points.
        for (ids, cs) in idx.chunks(4096).zip(coef.chunks(4096)) {
            let sq: Vec<f64> = cs.iter().map(|c| c.max(0.0).sqrt()).collect();
            let rows = b_rows(points, w, ids, &sq);
            faer::linalg::matmul::matmul(
                bb.as_mut(),
                Accum::Add,
                rows.transpose(),
                rows.as_ref(),
                1.0,
                Par::rayon(0),
            );
            let xh = Mat::from_fn(ids.len(), 4, |p, a| {
                sq[p] * if a == 3 { 1.0 } else { points[ids[p]][a] }
            });
            faer::linalg::matmul::matmul(
                bx.as_mut(),
                Accum::Add,
                rows.transpose(),
                xh.as_ref(),
                1.0,
                Par::Seq,
            );
            for (p, (&i, &c)) in ids.iter().zip(cs).enumerate() {
                let x = points[i];
                let h = [x[0], x[1], x[2], 1.0];
                for a in 0..4 {
                    for q in 0..4 {
                        xx[a][q] += c * h[a] * h[q];
                    }
                }
                for (col, bc) in b.iter_mut().enumerate() {
                    *bc += sq[p] * rows[(p, col)];
                }
            }
        }
        // Exact symmetry.
        for i in 0..n4 {
            for j in 0..i {
                let v = 0.5 * (bb[(i, j)] + bb[(j, i)]);
                bb[(i, j)] = v;
                bb[(j, i)] = v;
            }
        }
        Moments {
            bb,
            bx,
            xx,
            b,
            total: coef.iter().sum(),
        }
    }
}

/// y += A x for the n4 x n4 matrix A applied to each row block of z.
pub fn add_block_product(layout: Layout, a: &Mat<f64>, scale: f64, z: &[f64], y: &mut [f64]) {
    let n4 = layout.row_len();
    for r in 0..3 {
        let zr = &z[r * n4..(r + 1) * n4];
        let yr = &mut y[r * n4..(r + 1) * n4];
        for (j, zj) in zr.iter().enumerate() {
            if *zj != 0.0 {
                let col = a.col(j);
                for (i, yi) in yr.iter_mut().enumerate() {
                    *yi += scale * col[i] * zj;
                }
            }
        }
    }
}

/// Add sum_p (b_p b_p^T) (x) H_p to `target` (3 n4 x 3 n4, the layout of z): its block (r, s)
/// (n4 x n4) gains B^T diag(H_p[r][s]) B, one matrix product per block, with B = `rows`
/// (P x n4, row p = b_p) and H_p = `blocks[p]` (3 x 3). Blocks zero for every p are skipped.
pub fn add_outer_blocks(
    mut target: MatMut<'_, f64>,
    rows: MatRef<'_, f64>,
    blocks: &[crate::linalg3::Mat3],
) {
    let n4 = rows.ncols();
    for r in 0..3 {
        for s in 0..3 {
            if blocks.iter().all(|m| m[r][s] == 0.0) {
                continue;
            }
            let scaled = Mat::from_fn(rows.nrows(), n4, |p, k| blocks[p][r][s] * rows[(p, k)]);
            faer::linalg::matmul::matmul(
                target.rb_mut().submatrix_mut(r * n4, s * n4, n4, n4),
                Accum::Add,
                rows.transpose(),
                scaled.as_ref(),
                1.0,
                Par::Seq,
            );
        }
    }
}

/// Add `scale` x A to each diagonal block of the 12 (m + 1) square matrix `h`.
pub fn add_block_diagonal(layout: Layout, a: &Mat<f64>, scale: f64, h: &mut Mat<f64>) {
    let n4 = layout.row_len();
    for r in 0..3 {
        for j in 0..n4 {
            for i in 0..n4 {
                h[(r * n4 + i, r * n4 + j)] += scale * a[(i, j)];
            }
        }
    }
}

/// A region of the object pulled to a prescribed rigid motion of its rest positions by the
/// penalty kappa/2 sum_i v_i |x_i(z) - T(t) X_i|^2 over the integration points in the region.
#[derive(Debug, Clone)]
pub struct BoundaryTerm {
    /// The prescribed motion.
    pub motion: Motion,
    /// Penalty stiffness kappa, Pa/m^2 (energy per volume per squared distance).
    pub stiffness: f64,
    /// kappa-weighted moments over the region's points (coefficients kappa v_i).
    pub moments: Moments,
    /// Indices of the integration points in the region.
    pub points: Vec<usize>,
    /// The object's initial placement; the motion acts on the placed positions.
    pub placement: Rigid,
    /// For a region of a boundary-aware basis, held through its lift: the moments with every
    /// weight (those `rms_deviation` reports on). None when `moments` already are.
    pub pointwise: Option<Moments>,
}

/// 1/2 sum_i c_i |x_i - target_i|^2 over a point set with moments `m` (coefficients c_i), for
/// the target offset `g` = [R - I, t]; gradient added to `grad`; returns (E, the size of the
/// summed terms before cancellation).
fn penalty_energy(
    m: &Moments,
    g: &[[f64; 4]; 3],
    layout: Layout,
    z: &[f64],
    grad: &mut [f64],
) -> (f64, f64) {
    let n4 = layout.row_len();
    let mut e = 0.0;
    let mut scale = 0.0;
    for r in 0..3 {
        let zr = &z[r * n4..(r + 1) * n4];
        // q = bx G_r^T, the linear coefficient.
        let q: Vec<f64> = (0..n4)
            .map(|i| (0..4).map(|a| m.bx[(i, a)] * g[r][a]).sum())
            .collect();
        let mut pz = vec![0.0; n4];
        let mut pz_abs = vec![0.0; n4];
        for (j, zj) in zr.iter().enumerate() {
            if *zj != 0.0 {
                let col = m.bb.col(j);
                for (i, p) in pz.iter_mut().enumerate() {
                    *p += col[i] * zj;
                    pz_abs[i] += (col[i] * zj).abs();
                }
            }
        }
        let mut c = 0.0;
        for a in 0..4 {
            for b in 0..4 {
                c += g[r][a] * m.xx[a][b] * g[r][b];
            }
        }
        for i in 0..n4 {
            e += 0.5 * zr[i] * pz[i] - zr[i] * q[i];
            scale += 0.5 * zr[i].abs() * pz_abs[i] + (zr[i] * q[i]).abs();
            grad[r * n4 + i] += pz[i] - q[i];
        }
        e += 0.5 * c;
        scale += 0.5 * c.abs();
    }
    (e, scale)
}

impl BoundaryTerm {
    /// G = [R - I, t] for the target at time t: target - X = G Xh.
    fn offset(&self, t: f64) -> [[f64; 4]; 3] {
        let Rigid {
            rotation: r,
            translation: tr,
        } = self.target(t);
        std::array::from_fn(|i| {
            [
                r[i][0] - if i == 0 { 1.0 } else { 0.0 },
                r[i][1] - if i == 1 { 1.0 } else { 0.0 },
                r[i][2] - if i == 2 { 1.0 } else { 0.0 },
                tr[i],
            ]
        })
    }

    /// Energy (J) at time `t`, gradient added to `grad`, and the size of the summed terms
    /// before cancellation (J; a bound on E's rounding error is ~ n eps times it).
    pub fn energy_gradient(
        &self,
        layout: Layout,
        t: f64,
        z: &[f64],
        grad: &mut [f64],
    ) -> (f64, f64) {
        penalty_energy(&self.moments, &self.offset(t), layout, z, grad)
    }

    /// Volume-weighted RMS distance (m) between the region's integration points and their
    /// targets at time `t`, every weight included (for an aware region the hold acts on its
    /// lift alone, [`BoundaryTerm::pointwise`]; this is how far the whole region is off).
    pub fn rms_deviation(&self, layout: Layout, t: f64, z: &[f64]) -> f64 {
        let m = self.pointwise.as_ref().unwrap_or(&self.moments);
        let mut scratch = vec![0.0; z.len()];
        let (e, _) = penalty_energy(m, &self.offset(t), layout, z, &mut scratch);
        (2.0 * e.max(0.0) / m.total.max(f64::MIN_POSITIVE)).sqrt()
    }

    /// The target transform of rest positions at time `t`: motion(t) after the placement.
    pub fn target(&self, t: f64) -> Rigid {
        let m = self.motion.at(t);
        let p = &self.placement;
        let rotation = crate::linalg3::mul(&m.rotation, &p.rotation);
        let moved = Rigid {
            rotation: m.rotation,
            translation: [0.0; 3],
        }
        .apply(&p.translation);
        Rigid {
            rotation,
            translation: std::array::from_fn(|i| moved[i] + m.translation[i]),
        }
    }

    /// Largest distance (m) between a region point and its target at time `t`, for positions
    /// `x` of all integration points.
    pub fn max_deviation(&self, t: f64, rest: &[Point3], x: &[Point3]) -> f64 {
        let tr = self.target(t);
        self.points
            .iter()
            .map(|&i| {
                let y = tr.apply(&rest[i]);
                (0..3).map(|d| (x[i][d] - y[d]).powi(2)).sum::<f64>().sqrt()
            })
            .fold(0.0, f64::max)
    }
}

/// Path samples a cubature point's sweep follows at most per line-search direction
/// ([`ContactTerm::max_step`]): with delta = 1% of the object's diagonal, a point may move
/// 5 diagonals near an obstacle in one iterate.
pub const SWEEP_SAMPLES: usize = 1000;

/// One obstacle in [`ContactTerm::max_step`]: its index, the allowed extra depth delta
/// (metres) and its bounding sphere at its pose (None: unbounded).
#[derive(Clone, Copy)]
struct Sweep {
    obstacle: usize,
    delta: f64,
    sphere: Option<(Point3, f64)>,
}

/// Distance from `c` to the segment from `x` to `x + dx`, metres.
fn segment_distance(x: &Point3, dx: &[f64; 3], c: &Point3) -> f64 {
    let w: [f64; 3] = std::array::from_fn(|d| c[d] - x[d]);
    let len2 = dot(dx, dx);
    let s = if len2 > 0.0 {
        (dot(&w, dx) / len2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    let e: [f64; 3] = std::array::from_fn(|d| w[d] - s * dx[d]);
    dot(&e, &e).sqrt()
}

/// One-sided collider penalties kappa/2 sum_c v_c d_c^2 on the cubature points, d_c the
/// penetration depth of point c in each obstacle at the obstacles' poses at time t
/// ([`Kinematics`]).
#[derive(Debug, Clone)]
pub struct ContactTerm {
    kinematics: Kinematics,
    /// Penalty stiffness per obstacle, Pa/m^2.
    pub stiffness: Vec<f64>,
    points: Vec<Point3>,
    volumes: Vec<f64>,
    w: Vec<f64>,
    handles: usize,
}

/// A collider contact at the start of a step, as lagged friction keeps it
/// ([`ContactTerm::friction_lag`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ColliderLag {
    /// The cubature point (index into the term's points).
    pub point: usize,
    /// Friction coefficient times the normal force, N.
    pub mu_lambda: f64,
    /// I - n n^T of the contact normal at the start of the step.
    pub projector: crate::linalg3::Mat3,
    /// Where the obstacle would carry the point by the end of the step, metres.
    pub carried: Point3,
}

/// What one evaluation of the contact penalties found.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ContactInfo {
    /// Penalty energy, J.
    pub energy: f64,
    /// Penetrating (cubature point, obstacle) pairs.
    pub active: usize,
    /// Deepest penetration, metres (0 without contact).
    pub deepest: f64,
}

/// Which Hessian of the penalties to add.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ContactHessian {
    /// The positive semi-definite part (what Newton factorizes): exact for planes, boxes and
    /// meshes; for spheres and capsules the curvature part, negative inside, is left out.
    Psd,
    /// The exact Hessian of the penalty (for tests and diagnostics).
    Exact,
}

impl ContactTerm {
    /// Contacts of the cubature points `points` (volumes `volumes`, skinning weights `w`)
    /// with the obstacles of `kinematics`, one penalty stiffness (Pa/m^2) each.
    pub fn new(
        kinematics: Kinematics,
        stiffness: Vec<f64>,
        points: &[Point3],
        volumes: &[f64],
        w: &SkinningWeights,
    ) -> ContactTerm {
        ContactTerm {
            kinematics,
            stiffness,
            points: points.to_vec(),
            volumes: volumes.to_vec(),
            w: w.values.clone(),
            handles: w.modes,
        }
    }

    /// The obstacles and their motions.
    pub fn kinematics(&self) -> &Kinematics {
        &self.kinematics
    }

    /// The obstacles and their motions, mutable (to move an obstacle between steps).
    pub fn kinematics_mut(&mut self) -> &mut Kinematics {
        &mut self.kinematics
    }

    fn b(&self, c: usize) -> impl Iterator<Item = (usize, f64)> + '_ {
        let x = self.points[c];
        let xh = [x[0], x[1], x[2], 1.0];
        (0..4 * self.handles).map(move |k| (k, self.w[c * self.handles + k / 4] * xh[k % 4]))
    }

    /// Current position of cubature point `c`: X + B(X) z, handle by handle (the hot loop of
    /// every collider query).
    fn position(&self, layout: Layout, c: usize, z: &[f64]) -> Point3 {
        crate::sim::deformation::skinned_position(
            self.points[c],
            &self.w[c * self.handles..(c + 1) * self.handles],
            z,
            layout.row_len(),
        )
    }

    /// Every penetration at `z` and time `t`: (cubature point, obstacle, penetration).
    fn penetrations(&self, layout: Layout, t: f64, z: &[f64]) -> Vec<(usize, usize, Penetration)> {
        let poses = self.kinematics.poses(t);
        let obstacles = self.kinematics.obstacles();
        // Bounding spheres in world coordinates, for a cheap rejection.
        let bounds: Vec<Option<(Point3, f64)>> = obstacles
            .iter()
            .zip(&poses)
            .map(|(o, p)| o.bounding_sphere().map(|(c, r)| (p.apply(&c), r)))
            .collect();
        let point = |c: usize| {
            let x = self.position(layout, c, z);
            let mut found = Vec::new();
            for (o, ((obstacle, pose), bound)) in
                obstacles.iter().zip(&poses).zip(&bounds).enumerate()
            {
                if let Some((centre, r)) = bound {
                    let d2: f64 = (0..3).map(|d| (x[d] - centre[d]).powi(2)).sum();
                    if d2 >= r * r {
                        continue;
                    }
                }
                if let Some(p) = obstacle.penetration(pose, &x) {
                    found.push((c, o, p));
                }
            }
            found
        };
        // Mesh queries cost microseconds per point (docs/performance.md): spread the points
        // over threads. The result keeps point order, so the sums over it do not depend on
        // the thread count.
        if obstacles.iter().any(|o| o.mesh().is_some()) {
            use rayon::prelude::*;
            (0..self.points.len())
                .into_par_iter()
                .with_min_len(64)
                .flat_map_iter(point)
                .collect()
        } else {
            (0..self.points.len()).flat_map(point).collect()
        }
    }

    /// Energy (J), gradient added to `grad`, the number of penetrating (point, obstacle)
    /// pairs and the deepest penetration, with the obstacles at their poses at time `t` (s).
    pub fn energy_gradient(
        &self,
        layout: Layout,
        t: f64,
        z: &[f64],
        grad: &mut [f64],
    ) -> ContactInfo {
        let n4 = layout.row_len();
        let mut info = ContactInfo::default();
        for (c, o, p) in self.penetrations(layout, t, z) {
            let (k, v, d, u) = (self.stiffness[o], self.volumes[c], p.depth, p.normal);
            info.active += 1;
            info.deepest = info.deepest.max(d);
            info.energy += 0.5 * k * v * d * d;
            // dE/dx = -k v d u.
            for (kk, bk) in self.b(c) {
                for r in 0..3 {
                    grad[r * n4 + kk] -= k * v * d * u[r] * bk;
                }
            }
        }
        info
    }

    /// The largest step fraction alpha in [0, 1] along `dir` from `z` (infinite when
    /// nothing limits it) such that no cubature point goes deeper into an obstacle (at its
    /// pose at time `t`) than its depth at `z` plus delta, delta = min(`scale` (metres), half
    /// the obstacle's [`crate::sim::collider::Obstacle::half_thickness`]), anywhere along its
    /// straight path: a swept
    /// test, so a fast point cannot jump across a thin obstacle between iterates (the
    /// penalty alone only sees where it lands). The depth is 1-Lipschitz in the position, so
    /// it is checked at path samples delta/2 apart against depth(z) + delta/2; a path is
    /// followed for at most [`SWEEP_SAMPLES`] samples (a point moving farther near an
    /// obstacle is bounded there). Planes bound nothing.
    pub fn max_step(&self, layout: Layout, t: f64, z: &[f64], dir: &[f64], scale: f64) -> f64 {
        let poses = self.kinematics.poses(t);
        let obstacles = self.kinematics.obstacles();
        let swept: Vec<Sweep> = obstacles
            .iter()
            .zip(&poses)
            .enumerate()
            .filter_map(|(o, (obstacle, pose))| {
                let half = obstacle.half_thickness()?;
                let delta = scale.min(0.5 * half);
                let sphere = obstacle.bounding_sphere().map(|(c, r)| (pose.apply(&c), r));
                (delta > 0.0).then_some(Sweep {
                    obstacle: o,
                    delta,
                    sphere,
                })
            })
            .collect();
        if swept.is_empty() {
            return f64::INFINITY;
        }
        let n4 = layout.row_len();
        let point = |c: usize| -> f64 {
            let x = self.position(layout, c, z);
            let mut dx = [0.0; 3];
            for (k, bk) in self.b(c) {
                for (r, v) in dx.iter_mut().enumerate() {
                    *v += bk * dir[r * n4 + k];
                }
            }
            let len = dot(&dx, &dx).sqrt();
            if len == 0.0 {
                return f64::INFINITY;
            }
            let mut bound = f64::INFINITY;
            for &Sweep {
                obstacle: o,
                delta,
                sphere,
            } in &swept
            {
                if let Some((centre, r)) = sphere {
                    if segment_distance(&x, &dx, &centre) >= r {
                        continue;
                    }
                }
                let (obstacle, pose) = (&obstacles[o], &poses[o]);
                let depth = |y: &Point3| obstacle.penetration(pose, y).map_or(0.0, |p| p.depth);
                let limit = depth(&x) + 0.5 * delta;
                let sigma = 0.5 * delta / len;
                for k in 1..=SWEEP_SAMPLES {
                    let s = (k as f64 * sigma).min(1.0);
                    let y = std::array::from_fn(|d| x[d] + s * dx[d]);
                    if depth(&y) > limit {
                        // The first sample is within delta/2 of x, so within the limit but
                        // for rounding: at least that far is always allowed.
                        bound = bound.min((k - 1).max(1) as f64 * sigma);
                        break;
                    }
                    if s == 1.0 {
                        break;
                    }
                    if k == SWEEP_SAMPLES {
                        bound = bound.min(s);
                    }
                }
            }
            bound
        };
        if obstacles.iter().any(|o| o.mesh().is_some()) {
            use rayon::prelude::*;
            (0..self.points.len())
                .into_par_iter()
                .with_min_len(64)
                .map(point)
                .reduce(|| f64::INFINITY, f64::min)
        } else {
            (0..self.points.len())
                .map(point)
                .fold(f64::INFINITY, f64::min)
        }
    }

    /// The collider contacts at the start of a step (`z`, time `t0`) as friction sees them
    /// for the step to `t1`: per penetrating (point, obstacle) with friction coefficient
    /// `mu[o]` > 0, mu times the penalty force kappa v d (N), the tangent projector of the
    /// normal, and the point's position carried along by the obstacle's motion over the step
    /// (the point the obstacle's surface would take it to if it stuck).
    pub fn friction_lag(
        &self,
        layout: Layout,
        t0: f64,
        t1: f64,
        z: &[f64],
        mu: &[f64],
    ) -> Vec<ColliderLag> {
        let (p0, p1) = (self.kinematics.poses(t0), self.kinematics.poses(t1));
        self.penetrations(layout, t0, z)
            .into_iter()
            .filter(|(_, o, _)| mu[*o] > 0.0)
            .map(|(c, o, p)| {
                let x = self.position(layout, c, z);
                let (a, b) = (&p0[o], &p1[o]);
                // x in the obstacle's frame at t0, then back out at t1.
                let local: Point3 = std::array::from_fn(|k| {
                    (0..3)
                        .map(|m| a.rotation[m][k] * (x[m] - a.translation[m]))
                        .sum()
                });
                ColliderLag {
                    point: c,
                    mu_lambda: mu[o] * self.stiffness[o] * self.volumes[c] * p.depth,
                    projector: crate::sim::friction::tangent_projector(&p.normal),
                    carried: b.apply(&local),
                }
            })
            .collect()
    }

    /// The friction potential (J) of the lagged contacts `lag` at `z`, gradient added to
    /// `grad`; eps the smoothing displacement, metres.
    pub fn friction_energy_gradient(
        &self,
        layout: Layout,
        lag: &[ColliderLag],
        eps: f64,
        z: &[f64],
        grad: &mut [f64],
    ) -> f64 {
        use crate::sim::friction;
        let n4 = layout.row_len();
        let mut e = 0.0;
        for l in lag {
            let x = self.position(layout, l.point, z);
            let d: [f64; 3] = std::array::from_fn(|k| x[k] - l.carried[k]);
            e += friction::potential(l.mu_lambda, eps, &friction::project(&l.projector, &d));
            let g = friction::gradient(l.mu_lambda, eps, &l.projector, &d);
            for (kk, bk) in self.b(l.point) {
                for r in 0..3 {
                    grad[r * n4 + kk] += g[r] * bk;
                }
            }
        }
        e
    }

    /// Add the (positive semi-definite, exact) Hessian of the friction potential to `h`.
    pub fn add_friction_hessian(
        &self,
        layout: Layout,
        lag: &[ColliderLag],
        eps: f64,
        z: &[f64],
        h: &mut Mat<f64>,
    ) {
        use crate::sim::friction;
        let blocks: Vec<(usize, crate::linalg3::Mat3)> = lag
            .iter()
            .map(|l| {
                let x = self.position(layout, l.point, z);
                let d: [f64; 3] = std::array::from_fn(|k| x[k] - l.carried[k]);
                (
                    l.point,
                    friction::hessian(l.mu_lambda, eps, &l.projector, &d),
                )
            })
            .collect();
        self.add_point_blocks(layout, &blocks, h);
    }

    /// Add the Hessian of the active penalties at time `t` to `h`: k v B^T H B per
    /// penetrating point, H the exact Hessian of d^2/2 or its PSD part ([`ContactHessian`]).
    pub fn add_hessian(
        &self,
        layout: Layout,
        t: f64,
        z: &[f64],
        which: ContactHessian,
        h: &mut Mat<f64>,
    ) {
        let blocks: Vec<(usize, crate::linalg3::Mat3)> = self
            .penetrations(layout, t, z)
            .into_iter()
            .map(|(c, o, p)| {
                let kv = self.stiffness[o] * self.volumes[c];
                let hx = match which {
                    ContactHessian::Psd => p.hessian_psd,
                    ContactHessian::Exact => p.hessian,
                };
                (c, hx.map(|row| row.map(|v| kv * v)))
            })
            .collect();
        self.add_point_blocks(layout, &blocks, h);
    }

    /// Add sum over `blocks` of (b_c b_c^T) (x) H_c (H_c a 3 x 3 matrix per cubature point c)
    /// to `h` ([`add_outer_blocks`] with the b rows of the points).
    fn add_point_blocks(
        &self,
        layout: Layout,
        blocks: &[(usize, crate::linalg3::Mat3)],
        h: &mut Mat<f64>,
    ) {
        if blocks.is_empty() {
            return;
        }
        let mut rows = Mat::<f64>::zeros(blocks.len(), layout.row_len());
        for (p, &(c, _)) in blocks.iter().enumerate() {
            for (k, bk) in self.b(c) {
                rows[(p, k)] = bk;
            }
        }
        let hs: Vec<crate::linalg3::Mat3> = blocks.iter().map(|&(_, m)| m).collect();
        add_outer_blocks(h.as_mut(), rows.as_ref(), &hs);
    }
}
