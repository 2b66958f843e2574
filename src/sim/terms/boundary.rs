//! Kinematic boundary penalties: a held or driven region pulled to a prescribed rigid motion
//! of its rest positions, a quadratic in z from the region's moments ([`super::moments`]).

use super::adjoint::{ParameterAdjoint, PoseGradient};
use super::moments::{add_block_diagonal, Moments};
use super::term::{EnergySum, HessianKind, StepAt, Term, TermKind};
use crate::sim::elastic::Layout;
use crate::sim::environment::Environment;
use crate::sim::motion::{Motion, Rigid};
use crate::Point3;
use faer::Mat;

/// A region of the object pulled to a prescribed rigid motion of its rest positions by the
/// penalty kappa/2 sum_i v_i |x_i(z) - T(t) X_i|^2 over the integration points in the region.
#[derive(Debug, Clone)]
pub struct BoundaryTerm {
    /// Its index in [`crate::sim::SimOptions::boundaries`].
    pub index: usize,
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

impl Term for BoundaryTerm {
    fn kind(&self, _env: &Environment) -> TermKind {
        TermKind::Boundary {
            index: self.index,
            points: self.points.len(),
        }
    }

    fn add_energy_gradient(&self, at: &StepAt<'_>, z: &[f64], sum: &mut EnergySum<'_>) {
        let (e, size) = self.energy_gradient(at.layout, at.t, z, sum.grad);
        sum.energy += e;
        sum.add_magnitude(size);
    }

    /// The gradient is kappa-linear (the moments are kappa-weighted): dL/dkappa =
    /// -adjoint . grad / kappa. Its target enters as -bx G_r^T per row r, G = [R - I, t] the
    /// target's offset at the step's end, so dL/dG = Lambda bx (Lambda: the adjoint's rows);
    /// a small world motion (tau, delta about the target's origin t) changes G by
    /// [[delta]x R, tau], so dL/dtau = dL/dG's last column and
    /// dL/ddelta = sum_a R e_a x dL/dG e_a.
    fn add_parameter_adjoint(
        &self,
        at: &StepAt<'_>,
        z: &[f64],
        adjoint: &[f64],
        out: &mut ParameterAdjoint,
    ) {
        let n4 = at.layout.row_len();
        if out.boundary_pose.len() <= self.index {
            out.boundary_pose
                .resize(self.index + 1, PoseGradient::default());
            out.boundary_stiffness.resize(self.index + 1, 0.0);
        }
        let mut grad = vec![0.0; z.len()];
        self.energy_gradient(at.layout, at.t, z, &mut grad);
        let along: f64 = grad.iter().zip(adjoint).map(|(g, a)| g * a).sum();
        out.boundary_stiffness[self.index] -= along / self.stiffness;
        let dg: [[f64; 4]; 3] = std::array::from_fn(|r| {
            let lam = &adjoint[r * n4..(r + 1) * n4];
            std::array::from_fn(|a| (0..n4).map(|i| lam[i] * self.moments.bx[(i, a)]).sum())
        });
        let rot = self.target(at.t).rotation;
        let pose = &mut out.boundary_pose[self.index];
        for r in 0..3 {
            pose.translation[r] += dg[r][3];
        }
        for a in 0..3 {
            let ra = [rot[0][a], rot[1][a], rot[2][a]];
            let ga = [dg[0][a], dg[1][a], dg[2][a]];
            let c = crate::linalg3::cross(&ra, &ga);
            for r in 0..3 {
                pose.rotation[r] += c[r];
            }
        }
    }

    /// Quadratic in z: the moments' block on the diagonal.
    fn add_hessian(&self, at: &StepAt<'_>, _z: &[f64], _kind: HessianKind, h: &mut Mat<f64>) {
        self.add_rest_hessian(at.layout, at.dt, h);
    }

    fn add_rest_hessian(&self, layout: Layout, _dt: f64, h: &mut Mat<f64>) {
        add_block_diagonal(layout, &self.moments.bb, 1.0, h);
    }

    fn is_penalty(&self) -> bool {
        true
    }
}
