//! The stress arrays a frame carries (VTK point data, USD primvars): the tensor, the principal
//! stresses and the von Mises stress at each point.

/// The stress point arrays of one frame of one object, Pa.
pub(super) struct StressArrays {
    /// The tensor, 9 values row-major per point.
    pub(super) tensor: Vec<[f64; 9]>,
    /// Principal stresses, sigma_1 >= sigma_2 >= sigma_3 per point.
    pub(super) principal: Vec<[f64; 3]>,
    /// Von Mises stress per point.
    pub(super) von_mises: Vec<f64>,
}

impl StressArrays {
    /// The arrays of the Cauchy stresses `sigma` (N, Pa).
    pub(super) fn of(sigma: &[crate::linalg3::Mat3]) -> StressArrays {
        let principal: Vec<[f64; 3]> = sigma
            .iter()
            .map(crate::elasticity::principal_stresses)
            .collect();
        let von_mises = principal
            .iter()
            .map(|p| {
                (0.5 * ((p[0] - p[1]).powi(2) + (p[1] - p[2]).powi(2) + (p[2] - p[0]).powi(2)))
                    .sqrt()
            })
            .collect();
        StressArrays {
            tensor: sigma
                .iter()
                .map(|s| std::array::from_fn(|k| s[k / 3][k % 3]))
                .collect(),
            principal,
            von_mises,
        }
    }
}
