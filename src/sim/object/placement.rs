//! The rigid placement of an object: the combination of its modes that is 1 everywhere, and
//! the reduced state of a rigidly moved and spinning rest shape.

use super::options::Placement;
use crate::sim::elastic::Layout;
use crate::sim::motion::Rigid;
use crate::sim::terms::Moments;
use crate::{Error, Point3, Result};
use faer::linalg::solvers::Solve;

/// The combination of the weights that is 1 everywhere, alpha with sum_j alpha_j W_j = 1
/// (m^(3/2)): a free basis has it in mode 0 alone, a boundary-aware one in its lifts. It is
/// the mass-weighted least-squares fit G alpha = g over the integration points (G_jk = sum
/// rho v W_j W_k, g_j = sum rho v W_j, from the mass moments `b`), checked to reproduce 1.
fn unity(layout: Layout, b: &Moments) -> Result<Vec<f64>> {
    let nh = layout.handles;
    let g = faer::Mat::from_fn(nh, nh, |j, k| b.bb[(4 * j + 3, 4 * k + 3)]);
    let rhs = faer::Mat::from_fn(nh, 1, |j, _| b.b[4 * j + 3]);
    let fail = |detail: String| {
        Error::param(
            "basis",
            nh,
            format!(
                "no combination of the modes is constant ({detail}): a rigid placement needs one"
            ),
        )
    };
    // sum rho v (alpha^T W - 1)^2 / total = (alpha^T G alpha - 2 alpha^T g + total) / total:
    // 0 for a basis that holds the constant; 1e-8 is far above the rounding of the
    // cancellation (~1e-16 times the Gram matrix's condition number, ~1e3 here).
    let misfit = |alpha: &[f64]| {
        let quad: f64 = (0..nh)
            .map(|j| {
                (0..nh)
                    .map(|k| alpha[j] * g[(j, k)] * alpha[k])
                    .sum::<f64>()
            })
            .sum();
        let lin: f64 = (0..nh).map(|j| alpha[j] * rhs[(j, 0)]).sum();
        (quad - 2.0 * lin + b.total) / b.total
    };
    let ok = |alpha: &[f64]| misfit(alpha).abs() <= 1e-8 && alpha.iter().all(|a| a.is_finite());
    // A free basis: mode 0 alone (exactly as the constant mode's value says).
    let mut alpha = vec![0.0; nh];
    alpha[0] = b.total / b.b[3];
    if ok(&alpha) {
        return Ok(alpha);
    }
    let llt = g
        .llt(faer::Side::Lower)
        .map_err(|e| fail(format!("weight Gram matrix: {e:?}")))?;
    let sol = llt.solve(&rhs);
    let alpha: Vec<f64> = (0..nh).map(|j| sol[(j, 0)]).collect();
    if !ok(&alpha) {
        return Err(fail(format!("relative misfit {:.2e}", misfit(&alpha))));
    }
    Ok(alpha)
}

/// The object's affine motions x -> x + A [x; 1] in reduced coordinates, 12 (m + 1) x 12:
/// column 4 r + a is A = e_r e_a^T, z = alpha_j at (r, j, a) for the constant combination
/// alpha of [`unity`] (mode 0 alone when no combination is constant: still twelve
/// independent whole-body motions).
pub(super) fn affine_motions(layout: Layout, mass: &Moments) -> faer::Mat<f64> {
    let alpha = unity(layout, mass).unwrap_or_else(|_| {
        let mut e0 = vec![0.0; layout.handles];
        e0[0] = 1.0;
        e0
    });
    let mut p = faer::Mat::zeros(layout.dofs(), 12);
    for (j, &aj) in alpha.iter().enumerate() {
        for r in 0..3 {
            for a in 0..4 {
                p[(layout.index(r, j, a), 4 * r + a)] = aj;
            }
        }
    }
    p
}

/// Write into `z` and `zdot` (both zero on entry) the rest shape moved by `rigid` with the
/// placement's initial velocities `p`, for an object with mass moments `mass`. Nothing is
/// written when the placement is the identity at rest.
pub(super) fn place(
    layout: Layout,
    mass: &Moments,
    p: &Placement,
    rigid: &Rigid,
    z: &mut [f64],
    zdot: &mut [f64],
) -> Result<()> {
    let nonzero = rigid != &Rigid::IDENTITY
        || p.velocity
            .iter()
            .chain(&p.angular_velocity)
            .any(|v| *v != 0.0);
    if !nonzero {
        return Ok(());
    }
    for v in p.velocity.iter().chain(&p.angular_velocity) {
        if v.is_nan() || v.abs() > crate::error::MAX_MAGNITUDE {
            return Err(Error::param(
                "velocity",
                v,
                "must be finite, at most 1e100 in magnitude (m/s, rad/s)",
            ));
        }
    }
    let alpha = unity(layout, mass)?;
    let l = layout;
    let r = &rigid.rotation;
    // Velocity v + w x (x - c) at x = R X + t, with c the placed centre of mass.
    let com0: Point3 = std::array::from_fn(|d| mass.xx[d][3] / mass.total);
    let com = rigid.apply(&com0);
    let w = p.angular_velocity;
    let wx = [[0.0, -w[2], w[1]], [w[2], 0.0, -w[0]], [-w[1], w[0], 0.0]];
    for (j, &aj) in alpha.iter().enumerate() {
        for row in 0..3 {
            for a in 0..3 {
                let id = if row == a { 1.0 } else { 0.0 };
                z[l.index(row, j, a)] = aj * (r[row][a] - id);
                let v: f64 = (0..3).map(|k| wx[row][k] * r[k][a]).sum();
                zdot[l.index(row, j, a)] = aj * v;
            }
            z[l.index(row, j, 3)] = aj * rigid.translation[row];
            let wt: f64 = (0..3)
                .map(|k| wx[row][k] * (rigid.translation[k] - com[k]))
                .sum();
            zdot[l.index(row, j, 3)] = aj * (p.velocity[row] + wt);
        }
    }
    Ok(())
}

/// dL/d(placement) of a loss whose gradients at the placed state are dL/dz_0 and dL/dzdot_0
/// ([`place_adjoint`]). Units: the loss's unit per metre, per radian, per m/s, per rad/s.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct PlacementGradient {
    /// dL/dt, the translation.
    pub translation: [f64; 3],
    /// dL/ddelta for a small rotation delta (radians, world axes) applied on top of the
    /// placement's rotation about the origin: R -> exp([delta]x) R.
    pub rotation: [f64; 3],
    /// dL/dv, the initial linear velocity.
    pub velocity: [f64; 3],
    /// dL/dw, the initial angular velocity about the placed centre of mass.
    pub angular_velocity: [f64; 3],
}

fn cross(a: &[f64; 3], b: &[f64; 3]) -> [f64; 3] {
    crate::linalg3::cross(a, b)
}

/// The reverse of [`place`]: dL/d(placement) from `zbar` = dL/dz_0 and `zdotbar` = dL/dzdot_0
/// (12 (m + 1) each) at the state `place` wrote for `p` (rigid transform `rigid`). Per handle
/// j (alpha_j of [`unity`]), column a of Z_j is alpha_j (R e_a - e_a), its last column
/// alpha_j t; zdot's are alpha_j w x R e_a and alpha_j (v - w x R c0) (c0 the rest centre of
/// mass), so with w x y . b = w . (y x b) every derivative is a sum of cross products.
pub(super) fn place_adjoint(
    layout: Layout,
    mass: &Moments,
    p: &Placement,
    rigid: &Rigid,
    zbar: &[f64],
    zdotbar: &[f64],
) -> Result<PlacementGradient> {
    let alpha = unity(layout, mass)?;
    let r = &rigid.rotation;
    let com0: Point3 = std::array::from_fn(|d| mass.xx[d][3] / mass.total);
    // R c0: the centre of mass's offset from the translation.
    let rc: Point3 = std::array::from_fn(|i| (0..3).map(|k| r[i][k] * com0[k]).sum());
    let w = p.angular_velocity;
    let mut out = PlacementGradient::default();
    let add = |acc: &mut [f64; 3], v: [f64; 3], s: f64| {
        for d in 0..3 {
            acc[d] += s * v[d];
        }
    };
    for (j, &aj) in alpha.iter().enumerate() {
        let col = |v: &[f64], a: usize| -> [f64; 3] {
            std::array::from_fn(|row| v[layout.index(row, j, a)])
        };
        let (zt, vt) = (col(zbar, 3), col(zdotbar, 3));
        add(&mut out.translation, zt, aj);
        add(&mut out.velocity, vt, aj);
        // zdot's last column: -w x (R c0).
        add(&mut out.angular_velocity, cross(&rc, &vt), -aj);
        add(&mut out.rotation, cross(&rc, &cross(&vt, &w)), -aj);
        for a in 0..3 {
            let ra: [f64; 3] = std::array::from_fn(|row| r[row][a]);
            let (za, va) = (col(zbar, a), col(zdotbar, a));
            add(&mut out.angular_velocity, cross(&ra, &va), aj);
            add(&mut out.rotation, cross(&ra, &za), aj);
            add(&mut out.rotation, cross(&ra, &cross(&va, &w)), aj);
        }
    }
    Ok(out)
}
