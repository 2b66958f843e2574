//! The object-object contact energy of an island: a one-sided quadratic penalty on every
//! pair of samples of two different objects (or, with self-contact, of one object's samples
//! far apart at rest) closer than their contact distance d = t_a + t_b,
//!
//!   E = sum_pairs kappa_ab / 2 w_ij (d - r_ij)^2,  w_ij = A_i A_j / (pi d),  r_ij = |x_i - x_j|,
//!
//! with kappa_ab in Pa/m^2 (as the collider penalties), A the samples' areas (m^2), so w is
//! a volume (m^3) and E is in joules. Two flat sheets of samples pressed together by delta
//! feel the pressure kappa delta^2 (docs/math.md derives it). Positions are x = X + B z per
//! object, so the gradient and Hessian in the stacked z of the island follow from the pair
//! terms by the chain rule; the step bound keeps every pair from closing by more than half
//! its distance within one line-search segment.

use super::pairs::{candidates, self_candidates, BroadStats, Candidate};
use super::samples::ContactSamples;
use super::system::BlockHessian;
use crate::linalg3::Mat3;
use crate::sim::elastic::Layout;
use crate::sim::friction::{self, Curvature};
use crate::sim::terms::add_outer_blocks;
use crate::Point3;
use faer::prelude::ReborrowMut;
use faer::{Accum, Mat, Par};

/// Fraction of a pair's distance (or of its contact distance, if smaller) that one
/// line-search segment may close at most ([`PairContact::max_step`]).
pub const STEP_FLOOR: f64 = 0.5;

/// Largest distance, as a fraction of the smallest rest diagonal of an island's bodies, that
/// one line-search segment may move any contact sample ([`PairContact::max_step`]).
pub const SEGMENT_REACH: f64 = 0.5;

/// One object of an island as the contact energy sees it.
#[derive(Debug, Clone, Copy)]
pub struct Body<'a> {
    /// Its contact samples.
    pub samples: &'a ContactSamples,
    /// The layout of its z.
    pub layout: Layout,
    /// Where its z starts in the island's stacked coordinates.
    pub offset: usize,
    /// Its rest bounding-box diagonal, metres (penetrations are reported relative to the
    /// smaller of a pair's).
    pub diagonal: f64,
    /// Self-contact: pairs of its own samples at least this far apart at rest (metres) are
    /// penalized like pairs of two objects. None: no self-contact.
    pub self_exclusion: Option<f64>,
}

/// Which Hessian of the pair penalties to build.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PairHessian {
    /// kappa w u u^T per pair (the positive semi-definite part, for Newton).
    Psd,
    /// The exact Hessian kappa w (u u^T - (d - r)/r (I - u u^T)) (tests).
    Exact,
}

/// What one evaluation of the contact energy found.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ContactStats {
    /// Contact energy, J.
    pub energy: f64,
    /// Object pairs tested (box against box) and those whose samples were searched.
    pub broad: BroadStats,
    /// Sample pairs closer than their contact distance.
    pub active: usize,
    /// The deepest penetration d - r over the active pairs, metres (0 without contact).
    pub deepest: f64,
    /// The deepest penetration relative to the smaller rest diagonal of its two objects.
    pub deepest_fraction: f64,
    /// The bodies (a, b) of the pair with the largest `deepest_fraction`.
    pub deepest_pair: Option<(usize, usize)>,
}

/// A sample pair in contact at the start of a step, as lagged friction keeps it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PairLag {
    /// The pair.
    pub c: Candidate,
    /// I - u u^T of its direction then.
    pub projector: Mat3,
    /// x_i - x_j then, metres.
    pub start: [f64; 3],
    /// Its direction u = (x_i - x_j) / r then (the normal the projector removes).
    pub normal: [f64; 3],
    /// r = |x_i - x_j| then, metres.
    pub distance: f64,
    /// Its penetration d - r then, metres.
    pub depth: f64,
    /// Its penalty kappa w, N/m^2 (the normal force is kappa w (d - r)).
    pub kw: f64,
    /// Its friction coefficient.
    pub mu: f64,
}

impl PairLag {
    /// Friction coefficient times the pair's normal force then, mu kappa w (d - r), N.
    pub fn mu_lambda(&self) -> f64 {
        self.mu * self.kw * self.depth
    }

    /// The relative displacement of the pair since the start, at positions `x`.
    pub fn displacement(&self, x: &[Vec<Point3>]) -> [f64; 3] {
        let (xi, xj) = (x[self.c.a][self.c.i], x[self.c.b][self.c.j]);
        std::array::from_fn(|k| xi[k] - xj[k] - self.start[k])
    }
}

/// The contact energy between the bodies of an island.
pub struct PairContact<'a> {
    bodies: Vec<Body<'a>>,
    stiffness: Vec<f64>,
}

/// An active pair: its candidate, unit direction u = (x_i - x_j)/r, distance r, contact
/// distance d and kappa w.
pub(super) struct Active {
    pub(super) c: Candidate,
    pub(super) u: [f64; 3],
    pub(super) r: f64,
    pub(super) d: f64,
    pub(super) kw: f64,
}

impl<'a> PairContact<'a> {
    /// The bodies of an island with the penalty stiffness `stiffness[a * n + b]` (Pa/m^2,
    /// symmetric, n = bodies.len()) of each pair.
    pub fn new(bodies: Vec<Body<'a>>, stiffness: Vec<f64>) -> PairContact<'a> {
        assert_eq!(stiffness.len(), bodies.len() * bodies.len());
        PairContact { bodies, stiffness }
    }

    /// The bodies.
    pub fn bodies(&self) -> &[Body<'a>] {
        &self.bodies
    }

    /// The largest contact distance of a sample of body `a` and one of body `b`, metres.
    fn distance(&self, a: usize, b: usize) -> f64 {
        self.bodies[a].samples.thickness + self.bodies[b].samples.thickness
    }

    /// The contact distance of a candidate pair: the sum of its samples' radii, metres.
    fn pair_distance(&self, c: &Candidate) -> f64 {
        self.bodies[c.a].samples.radius[c.i] + self.bodies[c.b].samples.radius[c.j]
    }

    fn slice<'z>(&self, a: usize, z: &'z [f64]) -> &'z [f64] {
        let b = &self.bodies[a];
        &z[b.offset..b.offset + b.layout.dofs()]
    }

    /// Sample pairs closer than `reach(a, b)` metres at positions `x`: those of two bodies
    /// (the broad phase), then those of each body with self-contact, in a fixed order.
    fn candidates(
        &self,
        x: &[Vec<Point3>],
        reach: &dyn Fn(usize, usize) -> f64,
    ) -> (Vec<Candidate>, BroadStats) {
        let (mut cands, broad) = candidates(x, reach);
        for (a, body) in self.bodies.iter().enumerate() {
            if let Some(ex) = body.self_exclusion {
                cands.extend(self_candidates(
                    a,
                    &x[a],
                    &body.samples.rest,
                    reach(a, a),
                    ex,
                ));
            }
        }
        (cands, broad)
    }

    /// Deformed sample positions of every body at the stacked `z`, metres.
    pub fn positions(&self, z: &[f64]) -> Vec<Vec<Point3>> {
        (0..self.bodies.len())
            .map(|a| {
                let b = &self.bodies[a];
                b.samples.positions(b.layout, self.slice(a, z))
            })
            .collect()
    }

    /// The pairs closer than their contact distance at positions `x`, and the statistics.
    pub(super) fn active(&self, x: &[Vec<Point3>]) -> (Vec<Active>, ContactStats) {
        let (cands, broad) = self.candidates(x, &|a, b| self.distance(a, b));
        let n = self.bodies.len();
        let mut stats = ContactStats {
            broad,
            ..ContactStats::default()
        };
        let mut out = Vec::new();
        for c in cands {
            let d = self.pair_distance(&c);
            let (xi, xj) = (x[c.a][c.i], x[c.b][c.j]);
            let v: [f64; 3] = std::array::from_fn(|k| xi[k] - xj[k]);
            let r = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
            if r >= d {
                continue;
            }
            // Coincident samples have no direction; any unit vector keeps E's value and a
            // gradient that pushes them apart.
            let u = if r > 0.0 {
                v.map(|k| k / r)
            } else {
                [0.0, 1.0, 0.0]
            };
            let (sa, sb) = (self.bodies[c.a].samples, self.bodies[c.b].samples);
            let w = sa.area[c.i] * sb.area[c.j] / (std::f64::consts::PI * d);
            let kw = self.stiffness[c.a * n + c.b] * w;
            stats.active += 1;
            stats.energy += 0.5 * kw * (d - r) * (d - r);
            if d - r > stats.deepest {
                stats.deepest = d - r;
            }
            let diag = self.bodies[c.a].diagonal.min(self.bodies[c.b].diagonal);
            if (d - r) / diag > stats.deepest_fraction {
                stats.deepest_fraction = (d - r) / diag;
                stats.deepest_pair = Some((c.a, c.b));
            }
            out.push(Active { c, u, r, d, kw });
        }
        (out, stats)
    }

    /// Energy statistics at `z` (no gradient).
    pub fn stats(&self, z: &[f64]) -> ContactStats {
        self.active(&self.positions(z)).1
    }

    /// The body pairs (a < b) with a sample pair at `z` deeper than `tolerance` times the
    /// smaller rest diagonal of the two bodies.
    pub fn pairs_deeper_than(&self, z: &[f64], tolerance: f64) -> Vec<(usize, usize)> {
        let (act, _) = self.active(&self.positions(z));
        let mut out: Vec<(usize, usize)> = act
            .iter()
            .filter(|p| {
                let diag = self.bodies[p.c.a].diagonal.min(self.bodies[p.c.b].diagonal);
                p.d - p.r > tolerance * diag
            })
            .map(|p| (p.c.a.min(p.c.b), p.c.a.max(p.c.b)))
            .collect();
        out.sort_unstable();
        out.dedup();
        out
    }

    /// Energy (J) and statistics at the stacked `z`, gradient added to `grad`.
    pub fn energy_gradient(&self, z: &[f64], grad: &mut [f64]) -> ContactStats {
        let x = self.positions(z);
        let (act, stats) = self.active(&x);
        // dE/dx per sample, then through b into z.
        let mut gx: Vec<Vec<[f64; 3]>> = x.iter().map(|p| vec![[0.0; 3]; p.len()]).collect();
        for p in &act {
            let f = p.kw * (p.d - p.r);
            for k in 0..3 {
                gx[p.c.a][p.c.i][k] -= f * p.u[k];
                gx[p.c.b][p.c.j][k] += f * p.u[k];
            }
        }
        self.scatter(&gx, grad);
        stats
    }

    /// Add per-sample derivatives `gx` (dE/dx, one list per body) through the b rows into the
    /// stacked gradient `grad`.
    pub fn scatter(&self, gx: &[Vec<[f64; 3]>], grad: &mut [f64]) {
        for (a, g) in gx.iter().enumerate() {
            let body = &self.bodies[a];
            let n4 = body.layout.row_len();
            let mut b = vec![0.0; n4];
            for (i, gi) in g.iter().enumerate() {
                if *gi == [0.0; 3] {
                    continue;
                }
                body.samples.b(i, &mut b);
                for r in 0..3 {
                    let row = &mut grad[body.offset + r * n4..body.offset + (r + 1) * n4];
                    for (gk, bk) in row.iter_mut().zip(&b) {
                        *gk += gi[r] * bk;
                    }
                }
            }
        }
    }

    /// The contacts active at `z` (the start of a step) as lagged friction keeps them: per
    /// pair with coefficient `mu[a * n + b]` > 0, mu times its penalty force
    /// kappa w (d - r) (N), the tangent projector of its direction and x_i - x_j then.
    pub fn friction_lag(&self, z: &[f64], mu: &[f64]) -> Vec<PairLag> {
        self.lagged_pairs(z, mu, false)
    }

    /// [`PairContact::friction_lag`], with the frictionless pairs too when `frictionless`
    /// (their force is zero; the reverse pass reads dL/dmu from them).
    pub fn lagged_pairs(&self, z: &[f64], mu: &[f64], frictionless: bool) -> Vec<PairLag> {
        let n = self.bodies.len();
        let x = self.positions(z);
        let (act, _) = self.active(&x);
        act.iter()
            .filter(|p| frictionless || mu[p.c.a * n + p.c.b] > 0.0)
            .map(|p| {
                let mu = mu[p.c.a * n + p.c.b];
                PairLag {
                    c: p.c,
                    projector: friction::tangent_projector(&p.u),
                    start: std::array::from_fn(|k| x[p.c.a][p.c.i][k] - x[p.c.b][p.c.j][k]),
                    normal: p.u,
                    distance: p.r,
                    depth: p.d - p.r,
                    kw: p.kw,
                    mu,
                }
            })
            .collect()
    }

    /// The friction potential (J) of the lagged pairs at `z` (smoothing displacement `eps`,
    /// metres), gradient added to `grad`.
    pub fn friction_energy_gradient(
        &self,
        lag: &[PairLag],
        eps: f64,
        z: &[f64],
        grad: &mut [f64],
    ) -> f64 {
        if lag.is_empty() {
            return 0.0;
        }
        let x = self.positions(z);
        let mut gx: Vec<Vec<[f64; 3]>> = x.iter().map(|p| vec![[0.0; 3]; p.len()]).collect();
        let mut e = 0.0;
        for l in lag {
            let d = l.displacement(&x);
            e += friction::potential(l.mu_lambda(), eps, &friction::project(&l.projector, &d));
            let g = friction::gradient(l.mu_lambda(), eps, &l.projector, &d);
            for k in 0..3 {
                gx[l.c.a][l.c.i][k] += g[k];
                gx[l.c.b][l.c.j][k] -= g[k];
            }
        }
        self.scatter(&gx, grad);
        e
    }

    /// Add the exact Hessian of the friction potential at `z` to `h` (square, the island's
    /// size).
    pub fn add_friction_hessian(&self, lag: &[PairLag], eps: f64, z: &[f64], h: &mut Mat<f64>) {
        let mut blocks = self.empty_blocks();
        self.add_friction_hessian_blocks(lag, eps, z, Curvature::Exact, &mut blocks);
        self.add_dense(&blocks, h);
    }

    /// Add the Hessian of the friction potential at `z` to the island's block matrix `h`,
    /// exact or its majorizer's (`curvature`).
    pub fn add_friction_hessian_blocks(
        &self,
        lag: &[PairLag],
        eps: f64,
        z: &[f64],
        curvature: Curvature,
        h: &mut BlockHessian,
    ) {
        if lag.is_empty() {
            return;
        }
        let x = self.positions(z);
        let blocks: Vec<(Candidate, Mat3)> = lag
            .iter()
            .map(|l| {
                let d = l.displacement(&x);
                (
                    l.c,
                    friction::model_hessian(curvature, l.mu_lambda(), eps, &l.projector, &d),
                )
            })
            .collect();
        self.add_pair_blocks(&blocks, h);
    }

    /// Add the Hessian of the energy at the stacked `z` to `h` (square, the island's size).
    pub fn add_hessian(&self, z: &[f64], which: PairHessian, h: &mut Mat<f64>) {
        let mut blocks = self.empty_blocks();
        self.add_hessian_blocks(z, which, &mut blocks);
        self.add_dense(&blocks, h);
    }

    /// Zero blocks, one per body.
    fn empty_blocks(&self) -> BlockHessian {
        let sizes: Vec<usize> = self.bodies.iter().map(|b| b.layout.dofs()).collect();
        BlockHessian::zeros(&sizes)
    }

    /// Add `blocks` into the dense `h` at the bodies' offsets.
    fn add_dense(&self, blocks: &BlockHessian, h: &mut Mat<f64>) {
        let mut at = 0;
        for b in &self.bodies {
            assert_eq!(b.offset, at, "bodies are stacked in order");
            at += b.layout.dofs();
        }
        blocks.add_to_dense(h);
    }

    /// Add the Hessian of the energy at the stacked `z` to the island's block matrix `h`
    /// (one block per body, in body order).
    pub fn add_hessian_blocks(&self, z: &[f64], which: PairHessian, h: &mut BlockHessian) {
        let x = self.positions(z);
        let (act, _) = self.active(&x);
        let blocks: Vec<(Candidate, Mat3)> = act
            .iter()
            .map(|p| {
                let c = match which {
                    PairHessian::Psd => 0.0,
                    PairHessian::Exact if p.r > 0.0 => -(p.d - p.r) / p.r,
                    PairHessian::Exact => 0.0,
                };
                let hp = std::array::from_fn(|r| {
                    std::array::from_fn(|s| {
                        let uu = p.u[r] * p.u[s];
                        let id = if r == s { 1.0 } else { 0.0 };
                        p.kw * (uu + c * (id - uu))
                    })
                });
                (p.c, hp)
            })
            .collect();
        self.add_pair_blocks(&blocks, h);
    }

    /// Add sum over `blocks` of the Hessian of a function of x_i - x_j whose 3 x 3 Hessian is
    /// H: [[H, -H], [-H, H]] in (x_i, x_j), through the samples' b rows into z: into each
    /// body's diagonal block and the coupling block of each pair of bodies in contact (a
    /// body's own pairs couple within its diagonal block).
    pub fn add_pair_blocks(&self, blocks: &[(Candidate, Mat3)], h: &mut BlockHessian) {
        if blocks.is_empty() {
            return;
        }
        // Diagonal blocks: per sample, the sum of its pairs' 3 x 3 blocks.
        let mut own: Vec<std::collections::BTreeMap<usize, Mat3>> =
            (0..self.bodies.len()).map(|_| Default::default()).collect();
        for (c, hp) in blocks {
            for (body, s) in [(c.a, c.i), (c.b, c.j)] {
                let e = own[body].entry(s).or_insert([[0.0; 3]; 3]);
                for r in 0..3 {
                    for q in 0..3 {
                        e[r][q] += hp[r][q];
                    }
                }
            }
        }
        for (a, samples) in own.iter().enumerate() {
            if samples.is_empty() {
                continue;
            }
            let rows = self.b_rows(a, samples.keys().copied());
            let blocks: Vec<Mat3> = samples.values().copied().collect();
            add_outer_blocks(h.block_mut(a, a), rows.as_ref(), &blocks);
        }
        // Coupling blocks, per pair of bodies (a <= b): -sum_pairs H_p[r][s] b_i b_j^T,
        // formed as B_a^T C with C's row for sample i = sum_j H_p[r][s] b_j.
        let mut by_bodies: std::collections::BTreeMap<(usize, usize), Vec<&(Candidate, Mat3)>> =
            Default::default();
        for p in blocks {
            by_bodies.entry((p.0.a, p.0.b)).or_default().push(p);
        }
        for ((a, b), pairs) in by_bodies {
            let (ba, bb) = (&self.bodies[a], &self.bodies[b]);
            let (n4a, n4b) = (ba.layout.row_len(), bb.layout.row_len());
            let mut index = std::collections::BTreeMap::new();
            for (cand, _) in &pairs {
                let next = index.len();
                index.entry(cand.i).or_insert(next);
            }
            let mut order: Vec<(usize, usize)> = index.iter().map(|(&i, &row)| (row, i)).collect();
            order.sort_unstable();
            let rows_a = self.b_rows(a, order.iter().map(|&(_, i)| i));
            let mut bj = vec![0.0; n4b];
            let mut c: Vec<Mat<f64>> = (0..9).map(|_| Mat::zeros(order.len(), n4b)).collect();
            for (cand, hp) in &pairs {
                let row = index[&cand.i];
                bb.samples.b(cand.j, &mut bj);
                for r in 0..3 {
                    for s in 0..3 {
                        let cm = &mut c[3 * r + s];
                        for (k, v) in bj.iter().enumerate() {
                            cm[(row, k)] += hp[r][s] * v;
                        }
                    }
                }
            }
            // Pairs of one body's own samples (self-contact): the coupling -b_i b_j^T (x) H
            // lands in its diagonal block together with its transpose -b_j b_i^T (x) H.
            let mut own_coupling = (a == b).then(|| Mat::<f64>::zeros(3 * n4a, 3 * n4b));
            let mut target = match own_coupling.as_mut() {
                Some(m) => m.as_mut(),
                None => h.block_mut(a, b),
            };
            for r in 0..3 {
                for s in 0..3 {
                    faer::linalg::matmul::matmul(
                        target.rb_mut().submatrix_mut(r * n4a, s * n4b, n4a, n4b),
                        Accum::Add,
                        rows_a.transpose(),
                        c[3 * r + s].as_ref(),
                        -1.0,
                        Par::Seq,
                    );
                }
            }
            if let Some(m) = own_coupling {
                let mut block = h.block_mut(a, a);
                block += m.as_ref();
                block += m.transpose();
            }
        }
    }

    /// Rows b(X_i) of body `a`'s samples `ids`, one row each.
    fn b_rows(&self, a: usize, ids: impl Iterator<Item = usize>) -> Mat<f64> {
        let body = &self.bodies[a];
        let n4 = body.layout.row_len();
        let ids: Vec<usize> = ids.collect();
        let mut m = Mat::zeros(ids.len(), n4);
        let mut b = vec![0.0; n4];
        for (p, &i) in ids.iter().enumerate() {
            body.samples.b(i, &mut b);
            for (k, v) in b.iter().enumerate() {
                m[(p, k)] = *v;
            }
        }
        m
    }

    /// The largest alpha such that along z + alpha' dir, 0 <= alpha' <= alpha, no sample pair
    /// of two bodies (or of one body's own, with self-contact) comes closer than [`STEP_FLOOR`] times the smaller of its distance at
    /// `z` and its contact distance (infinite when nothing limits the step). Sample paths are
    /// straight lines in alpha, so the distance along the segment is exact: the first alpha
    /// where |x_i - x_j + alpha (dx_i - dx_j)| reaches the floor is a root of a quadratic.
    /// Also at most the alpha at which two samples' relative motion reaches
    /// [`SEGMENT_REACH`] of the smallest body's diagonal.
    pub fn max_step(&self, z: &[f64], dir: &[f64]) -> f64 {
        let x = self.positions(z);
        let dx: Vec<Vec<Point3>> = (0..self.bodies.len())
            .map(|a| {
                let b = &self.bodies[a];
                b.samples.displacements(b.layout, self.slice(a, dir))
            })
            .collect();
        let moved: Vec<f64> = dx
            .iter()
            .map(|d| {
                d.iter()
                    .map(|v| (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt())
                    .fold(0.0, f64::max)
            })
            .collect();
        // A segment may move samples by at most SEGMENT_REACH of the smallest body's
        // diagonal: a near-singular Newton system can ask for far more, and then every
        // sample of every neighbour would be a candidate (millions of pairs, hundreds of MB).
        let smallest = self
            .bodies
            .iter()
            .map(|b| b.diagonal)
            .fold(f64::INFINITY, f64::min);
        let largest = moved.iter().fold(0.0, |m: f64, &v| m.max(v));
        let mut bound = if 2.0 * largest > SEGMENT_REACH * smallest {
            SEGMENT_REACH * smallest / (2.0 * largest)
        } else {
            f64::INFINITY
        };
        let scale = bound.min(1.0);
        // Pairs that can come within their contact distance along the (capped) segment.
        let (cands, _) = self.candidates(&x, &|a, b| {
            self.distance(a, b) + scale * (moved[a] + moved[b])
        });
        for c in cands {
            let d0: [f64; 3] = std::array::from_fn(|k| x[c.a][c.i][k] - x[c.b][c.j][k]);
            let v: [f64; 3] = std::array::from_fn(|k| dx[c.a][c.i][k] - dx[c.b][c.j][k]);
            let r0 = (d0[0] * d0[0] + d0[1] * d0[1] + d0[2] * d0[2]).sqrt();
            let qa = v[0] * v[0] + v[1] * v[1] + v[2] * v[2];
            let d = self.pair_distance(&c);
            // Two feature points (radius 0) never touch.
            if r0 == 0.0 || qa == 0.0 || d == 0.0 {
                continue;
            }
            let floor = STEP_FLOOR * r0.min(d);
            let qb = 2.0 * (d0[0] * v[0] + d0[1] * v[1] + d0[2] * v[2]);
            let qc = r0 * r0 - floor * floor;
            let disc = qb * qb - 4.0 * qa * qc;
            if disc < 0.0 || qb >= 0.0 {
                // Never reaches the floor, or moving apart (qc > 0 makes both roots
                // negative then).
                continue;
            }
            // The smaller root, in the cancellation-free form 2c / (-b + sqrt(disc)).
            let alpha = 2.0 * qc / (-qb + disc.sqrt());
            bound = bound.min(alpha);
        }
        bound
    }
}
