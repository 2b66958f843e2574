//! What the terms give the reverse pass of a step ([`ParameterAdjoint`]): the step's
//! converged state z* minimises the potential, so dL/dp = -lambda^T d(grad E)/dp with
//! H lambda = dL/dz* (the implicit function theorem; H the exact Hessian at z*). Each term adds
//! -lambda^T d(its gradient)/dp for the parameters it depends on.

use faer::Mat;

/// dL/d(pose) of a rigid pose: along a small world translation tau (metres) and a small
/// rotation delta (radians, world axes) about the pose's origin (its translation), applied
/// on top of the pose.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct PoseGradient {
    /// dL/dtau, the loss's unit per metre.
    pub translation: [f64; 3],
    /// dL/ddelta, the loss's unit per radian.
    pub rotation: [f64; 3],
}

/// dL/d(pose) of one collider in one step: at the pose the step began with (which lagged
/// friction reads) and the pose at its end (the penalties' and the carried points').
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct StepPoseGradient {
    /// At the step's start time.
    pub start: PoseGradient,
    /// At the step's end time.
    pub end: PoseGradient,
}

/// The parameter adjoints of a run, summed over its steps by the terms
/// ([`super::Term::add_parameter_adjoint`]).
#[derive(Debug, Clone)]
pub struct ParameterAdjoint {
    /// dL/dz_pred of the step being reversed, 12 (m + 1) (set to zero before each step).
    pub zpred: Vec<f64>,
    /// dL/dz_n of the step being reversed through what the step lags from its start z_n
    /// (collider friction's normal forces, normals and carried points), 12 (m + 1) (set to
    /// zero before each step).
    pub start: Vec<f64>,
    /// dL/dmu per collider (friction coefficient; empty until a collider term with friction
    /// adds it), the loss's unit.
    pub friction: Vec<f64>,
    /// dL/dkappa per collider (penalty stiffness; empty until a collider term adds it), the
    /// loss's unit per Pa/m^2.
    pub collider_stiffness: Vec<f64>,
    /// dL/d(pose) per collider at the start and the end of the step being reversed (empty
    /// until a collider term adds it; set to zero before each step).
    pub collider_pose: Vec<StepPoseGradient>,
    /// dL/d(target pose) per held region (index in the boundaries) at the end of the step
    /// being reversed (empty until a boundary term adds it; set to zero before each step).
    pub boundary_pose: Vec<PoseGradient>,
    /// dL/dkappa per held region, the loss's unit per Pa/m^2 (empty until a boundary term
    /// adds it).
    pub boundary_stiffness: Vec<f64>,
    /// dL/dmu per cubature point, 1/Pa times the loss's unit.
    pub mu: Vec<f64>,
    /// dL/dlambda per cubature point, 1/Pa times the loss's unit.
    pub lambda: Vec<f64>,
    /// The density's bilinear form Q, 4 (m + 1) square: dL/drho_i = v_i (b_i^T Q b_i + q . b_i)
    /// for an integration point with volume v_i and map row b_i (the mass moments' b).
    pub density_quadratic: Mat<f64>,
    /// The density's linear form q, 4 (m + 1) (see `density_quadratic`).
    pub density_linear: Vec<f64>,
    /// dL/dg, (m/s^2)^-1 times the loss's unit (None until a gravity term adds it).
    pub gravity: Option<[f64; 3]>,
    /// Cubature points with det F <= 0 at the step being reversed (the elastic term counts
    /// them; set to zero before each step).
    pub inverted: usize,
}

impl ParameterAdjoint {
    /// Zero adjoints for `dofs` = 12 (m + 1) coordinates and `cubature` points.
    pub fn new(dofs: usize, cubature: usize) -> ParameterAdjoint {
        let n4 = dofs / 3;
        ParameterAdjoint {
            zpred: vec![0.0; dofs],
            start: vec![0.0; dofs],
            friction: Vec::new(),
            collider_stiffness: Vec::new(),
            collider_pose: Vec::new(),
            boundary_pose: Vec::new(),
            boundary_stiffness: Vec::new(),
            mu: vec![0.0; cubature],
            lambda: vec![0.0; cubature],
            density_quadratic: Mat::zeros(n4, n4),
            density_linear: vec![0.0; n4],
            gravity: None,
            inverted: 0,
        }
    }
}
