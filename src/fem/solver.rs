//! Backward Euler for linear tetrahedra as minimisation of the incremental potential,
//! Newton with backtracking line search, sparse Cholesky (faer) on the free DoFs.
//!
//! For node positions x (N x 3, m), lumped masses m_a (kg), time step h (s), prediction
//! x_pred = x_n + h v_n, gravity g (m/s^2) and an optional one-sided plane penalty:
//!
//! ```text
//! E(x) = sum_a m_a / (2 h^2) |x_a - x_pred,a|^2 + sum_e V_e Psi(F_e) - sum_a m_a g . x_a
//!        + sum_a V_a kappa / 2 max(0, c - n . x_a)^2
//! ```
//!
//! x_{n+1} = argmin E over the free nodes; Dirichlet nodes sit at their targets (held: rest
//! positions; prescribed: whatever [`FemSolver::set_targets`] gave); v_{n+1} = (x_{n+1} - x_n) / h
//! for every node. A static solve ([`FemSolver::solve_static`]) drops the inertia term.
//!
//! Newton: the Hessian sums the element Hessians, the diagonal mass term and the penalty's
//! V_a kappa n n^T. By default ([`HessianMode::ExactFirst`]) the exact Hessian is factorized
//! and, when it is not positive definite, the one with every element Hessian projected to
//! PSD (SPD whenever inertia or enough held nodes are present). The sparsity pattern of the free-DoF system and its symbolic
//! Cholesky factorization (with the chosen [`OrderingKind`]) are built once in
//! [`FemSolver::new`] and reused by every iteration of every step; only the numeric
//! factorization is redone. Line search: backtracking (halving) with the Armijo condition
//! E(x + a dx) <= E(x) + 1e-4 a g.dx, allowing 1e-12 |E(x)| of round-off.
//!
//! Convergence (scale invariant): the largest nodal Newton update max_a |dx_a| <=
//! `tolerance` x D, with D the rest bounding-box diagonal. After `max_newton_iterations`
//! without it, [`FemError::NotConverged`] is returned (the state holds the last iterate);
//! a NaN anywhere gives [`FemError::NonFinite`]. Nothing non-finite is ever returned as a state.

use super::element::{ElementOrder, Elements};
use super::ordering::{nested_dissection, OrderingKind};
use super::tetmesh::TetMesh;
use super::{FemError, TetMaterials};
use crate::Point3;
use faer::dyn_stack::{MemBuffer, MemStack, StackReq};
use faer::perm::PermRef;
use faer::sparse::linalg::cholesky::{
    factorize_symbolic_cholesky, LltRef, SymbolicCholesky, SymmetricOrdering,
};
use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};
use faer::{Conj, MatMut, Par, Side};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::time::Instant;

/// A one-sided plane (floor) penalty: nodes with n . x < c are pushed out with energy
/// V_a kappa / 2 (c - n . x_a)^2, the same form as the reduced model's.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PlanePenalty {
    /// Unit normal n pointing to the allowed side (normalised by [`FemSolver::new`]).
    pub normal: Point3,
    /// Offset c, metres: the plane is n . x = c.
    pub offset: f64,
    /// Stiffness kappa, Pa/m^2 (energy per node volume per squared penetration depth).
    pub stiffness: f64,
}

/// Solver settings. Every field has a documented default.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FemParams {
    /// Time step h, s. Default 0.01 (the beam benchmark's).
    pub dt: f64,
    /// Gravity, m/s^2. Default (0, -9.81, 0).
    pub gravity: Point3,
    /// Newton stops when max_a |dx_a| <= tolerance x (rest bounding-box diagonal).
    /// Default 1e-6: 5.2e-6 m on the 5 m beam, three orders below the smallest RMS error the
    /// reduced model is asked to reach against it (Table 1, twist m = 16: 1e-2 m).
    pub tolerance: f64,
    /// Newton iteration cap per step. Default 200: the beam needs 2-5 per step, but up to
    /// 82 in the step where the twisted beam buckles (docs/performance.md).
    pub max_newton_iterations: usize,
    /// Which Hessian Newton factorizes. Default [`HessianMode::ExactFirst`].
    pub hessian: HessianMode,
    /// Fill-reducing ordering of the sparse Cholesky. Default nested dissection (less fill
    /// and faster than AMD from 8 cubes per metre up; docs/performance.md).
    pub ordering: OrderingKind,
    /// Optional floor penalty. Default none.
    pub plane: Option<PlanePenalty>,
    /// Element order. Default linear (see docs/accuracy.md for what quadratic buys).
    /// Not serialized when linear, so cache keys of linear runs are those of the versions
    /// before this field existed.
    #[serde(default, skip_serializing_if = "is_linear")]
    pub order: ElementOrder,
}

impl Default for FemParams {
    fn default() -> Self {
        Self {
            dt: 0.01,
            gravity: [0.0, -9.81, 0.0],
            tolerance: 1e-6,
            max_newton_iterations: 200,
            hessian: HessianMode::ExactFirst,
            ordering: OrderingKind::NestedDissection,
            plane: None,
            order: ElementOrder::Linear,
        }
    }
}

/// Which Hessian the Newton iterations factorize.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum HessianMode {
    /// The exact Hessian; if its Cholesky factorization fails (indefinite), the one with
    /// every element Hessian projected to PSD (always SPD with inertia or enough held
    /// nodes). Quadratic convergence near a stable equilibrium, robust far from it.
    #[default]
    ExactFirst,
    /// Always the PSD-projected Hessian: a descent direction every time, but it
    /// overestimates the curvature where elements are strongly twisted or compressed, which
    /// slows Newton to linear convergence there.
    Projected,
    /// Always the exact Hessian; an indefinite system is a [`FemError::Factorization`].
    Exact,
}

/// Diagnostics of one step (or one static solve).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct StepInfo {
    /// Newton iterations taken.
    pub newton_iterations: usize,
    /// Line-search halvings, summed over the iterations.
    pub line_search_halvings: usize,
    /// max_a |dx_a| of the last Newton update, metres.
    pub step_norm: f64,
    /// Largest nodal gradient of the incremental potential over free nodes before the last
    /// update, N.
    pub gradient_norm: f64,
    /// Wall time of the step, s.
    pub seconds: f64,
    /// Of which Hessian assembly and numeric Cholesky factorization, s.
    pub factor_seconds: f64,
    /// Iterations that fell back to the PSD-projected Hessian ([`HessianMode::ExactFirst`]).
    pub projected_iterations: usize,
    /// Backward Euler steps the step was taken as: 1, or more where
    /// [`FemSolver::step_substepping`] halved it.
    #[serde(default)]
    pub substeps: usize,
}

const NONE: u32 = u32::MAX;

/// The FEM solver: mesh data, state (positions, velocities), Dirichlet nodes, and the reusable
/// sparse system with its symbolic factorization.
pub struct FemSolver {
    elements: Elements,
    rest: Vec<Point3>,
    x: Vec<Point3>,
    v: Vec<Point3>,
    fixed_nodes: Vec<usize>,
    targets: Vec<Point3>,
    /// Free DoF index of (node, axis) is 3 free_rank[node] + axis; NONE for Dirichlet nodes.
    free_rank: Vec<u32>,
    col_ptr: Vec<usize>,
    row_idx: Vec<usize>,
    values: Vec<f64>,
    /// Per element, (3 npe)^2 positions into `values` (NONE: constrained DoF or upper
    /// triangle).
    scatter: Vec<u32>,
    symbolic: SymbolicCholesky<usize>,
    l_values: Vec<f64>,
    mem: MemBuffer,
    params: FemParams,
    plane: Option<PlanePenalty>,
    diag: f64,
    steps: usize,
    symbolic_seconds: f64,
}

impl std::fmt::Debug for FemSolver {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("FemSolver")
            .field("nodes", &self.rest.len())
            .field("tets", &self.elements.len())
            .field("fixed_nodes", &self.fixed_nodes.len())
            .field("factor_entries", &self.l_values.len())
            .field("steps", &self.steps)
            .finish()
    }
}

impl FemSolver {
    /// Set up a solver at rest (x = rest positions, v = 0) with the FE nodes in `fixed`
    /// (indices, any order, duplicates ignored) held at their rest positions until
    /// [`FemSolver::set_targets`] moves them. FE nodes are the mesh nodes (same indices)
    /// followed, for quadratic elements, by the edge nodes ([`super::element::fe_nodes`]
    /// lists them all, to select Dirichlet nodes by position).
    ///
    /// # Errors
    /// [`crate::Error::InvalidParameter`] for a non-positive or non-finite `dt`, `tolerance`,
    /// a zero plane normal or negative stiffness; [`FemError::Mesh`] for a fixed index out of
    /// range or materials of the wrong length; [`FemError::Factorization`] if the symbolic
    /// analysis fails.
    pub fn new(
        mesh: &TetMesh,
        materials: &TetMaterials,
        fixed: &[usize],
        params: FemParams,
    ) -> crate::Result<Self> {
        validate_params(&params)?;
        let plane = match params.plane {
            Some(p) => {
                let len = p.normal.iter().map(|c| c * c).sum::<f64>().sqrt();
                if !(len > 0.0 && len.is_finite()) {
                    return Err(crate::Error::param(
                        "plane.normal",
                        format!("{:?}", p.normal),
                        "the plane normal must be a non-zero finite vector",
                    ));
                }
                if !(p.stiffness >= 0.0 && p.stiffness.is_finite() && p.offset.is_finite()) {
                    return Err(crate::Error::param(
                        "plane.stiffness",
                        p.stiffness,
                        "the penalty stiffness must be finite and >= 0 (Pa/m^2)",
                    ));
                }
                Some(PlanePenalty {
                    normal: p.normal.map(|c| c / len),
                    ..p
                })
            }
            None => None,
        };
        let elements = Elements::new(mesh, materials, params.order)?;
        let n = elements.rest_nodes().len();
        let mut is_fixed = vec![false; n];
        for &i in fixed {
            if i >= n {
                return Err(
                    FemError::Mesh(format!("fixed node {i} is out of range ({n} nodes)")).into(),
                );
            }
            is_fixed[i] = true;
        }
        if let Some(i) = (0..n).find(|&i| !is_fixed[i] && elements.masses()[i] <= 0.0) {
            return Err(FemError::Mesh(format!(
                "node {i} belongs to no element (no mass, no stiffness); remove it or hold it"
            ))
            .into());
        }
        let fixed_nodes: Vec<usize> = (0..n).filter(|&i| is_fixed[i]).collect();
        let rest = elements.rest_nodes().to_vec();
        let targets = fixed_nodes.iter().map(|&i| rest[i]).collect();

        // Node adjacency over free nodes (including each node itself).
        let free_nodes: Vec<usize> = (0..n).filter(|&i| !is_fixed[i]).collect();
        let mut adjacency = vec![Vec::new(); n];
        for e in 0..elements.len() {
            let conn = elements.connectivity(e);
            for &a in conn {
                for &b in conn {
                    if a != b && !is_fixed[a as usize] && !is_fixed[b as usize] {
                        adjacency[a as usize].push(b as usize);
                    }
                }
            }
        }
        adjacency.par_iter_mut().for_each(|l| {
            l.sort_unstable();
            l.dedup();
        });
        let mut free_rank = vec![NONE; n];
        for (r, &i) in free_nodes.iter().enumerate() {
            free_rank[i] = r as u32;
        }

        // Lower-triangular CSC pattern over free DoFs (natural order: rank, then axis).
        let ndof = 3 * free_nodes.len();
        let mut col_ptr = Vec::with_capacity(ndof + 1);
        let mut row_idx = Vec::new();
        col_ptr.push(0);
        for &p in &free_nodes {
            let fp = free_rank[p] as usize;
            let mut rows_nodes: Vec<usize> = adjacency[p]
                .iter()
                .map(|&q| free_rank[q] as usize)
                .filter(|&fq| fq > fp)
                .collect();
            rows_nodes.sort_unstable();
            for s in 0..3 {
                for r in s..3 {
                    row_idx.push(3 * fp + r);
                }
                for &fq in &rows_nodes {
                    for r in 0..3 {
                        row_idx.push(3 * fq + r);
                    }
                }
                col_ptr.push(row_idx.len());
            }
        }
        if row_idx.len() > NONE as usize {
            return Err(
                FemError::Mesh("system matrix too large for u32 scatter indices".into()).into(),
            );
        }
        let scatter = build_scatter(&elements, &free_rank, &col_ptr, &row_idx);

        let t0 = Instant::now();
        let sym = SymbolicSparseColMatRef::new_checked(ndof, ndof, &col_ptr, None, &row_idx);
        let symbolic = match params.ordering {
            OrderingKind::Amd => factorize_symbolic_cholesky(
                sym,
                Side::Lower,
                SymmetricOrdering::Amd,
                Default::default(),
            ),
            OrderingKind::NestedDissection => {
                let pos: Vec<Point3> = free_nodes.iter().map(|&i| rest[i]).collect();
                let adj: Vec<Vec<usize>> = free_nodes
                    .iter()
                    .map(|&i| {
                        adjacency[i]
                            .iter()
                            .map(|&q| free_rank[q] as usize)
                            .collect()
                    })
                    .collect();
                let node_order = nested_dissection(&pos, &adj);
                let fwd: Vec<usize> = node_order
                    .iter()
                    .flat_map(|&k| [3 * k, 3 * k + 1, 3 * k + 2])
                    .collect();
                let mut inv = vec![0; ndof];
                for (new, &old) in fwd.iter().enumerate() {
                    inv[old] = new;
                }
                factorize_symbolic_cholesky(
                    sym,
                    Side::Lower,
                    SymmetricOrdering::Custom(PermRef::new_checked(&fwd, &inv, ndof)),
                    Default::default(),
                )
            }
        }
        .map_err(|e| FemError::Factorization(format!("symbolic analysis: {e:?}")))?;
        let symbolic_seconds = t0.elapsed().as_secs_f64();
        let l_values = vec![0.0; symbolic.len_val()];
        let par = Par::rayon(0);
        let req = StackReq::any_of(&[
            symbolic.factorize_numeric_llt_scratch::<f64>(par, Default::default()),
            symbolic.solve_in_place_scratch::<f64>(1, par),
        ]);
        let mem = MemBuffer::try_new(req).map_err(|_| {
            FemError::Factorization("out of memory for the Cholesky scratch".into())
        })?;
        let values = vec![0.0; row_idx.len()];
        let diag = mesh.bounding_box().diagonal();
        Ok(Self {
            elements,
            x: rest.clone(),
            v: vec![[0.0; 3]; n],
            rest,
            fixed_nodes,
            targets,
            free_rank,
            col_ptr,
            row_idx,
            values,
            scatter,
            symbolic,
            l_values,
            mem,
            params,
            plane,
            diag,
            steps: 0,
            symbolic_seconds,
        })
    }

    /// Node positions, N x 3, metres.
    pub fn positions(&self) -> &[Point3] {
        &self.x
    }

    /// Node velocities, N x 3, m/s.
    pub fn velocities(&self) -> &[Point3] {
        &self.v
    }

    /// Rest positions, N x 3, metres.
    pub fn rest_positions(&self) -> &[Point3] {
        &self.rest
    }

    /// The Dirichlet nodes, ascending.
    pub fn fixed_nodes(&self) -> &[usize] {
        &self.fixed_nodes
    }

    /// The element data (volumes, masses, energy evaluation).
    pub fn elements(&self) -> &Elements {
        &self.elements
    }

    /// The settings.
    pub fn params(&self) -> &FemParams {
        &self.params
    }

    /// Steps taken so far.
    pub fn steps_taken(&self) -> usize {
        self.steps
    }

    /// Stored entries of the Cholesky factor (fill), and seconds of the symbolic analysis.
    pub fn factor_stats(&self) -> (usize, f64) {
        (self.l_values.len(), self.symbolic_seconds)
    }

    /// Number of free DoFs (3 x free nodes), the size of the Newton system.
    pub fn free_dofs(&self) -> usize {
        self.col_ptr.len() - 1
    }

    /// Free DoF index of (node, axis), or `None` for a Dirichlet node.
    pub fn free_dof(&self, node: usize, axis: usize) -> Option<usize> {
        let r = self.free_rank[node];
        (r != NONE).then(|| 3 * r as usize + axis)
    }

    /// Replace the state: positions and velocities, N x 3 each (metres, m/s).
    ///
    /// # Errors
    /// [`crate::Error::LengthMismatch`] or [`crate::Error::NonFinite`].
    pub fn set_state(&mut self, x: &[Point3], v: &[Point3]) -> crate::Result<()> {
        for (what, a) in [("positions", x), ("velocities", v)] {
            if a.len() != self.rest.len() {
                return Err(crate::Error::LengthMismatch {
                    what,
                    expected: self.rest.len(),
                    got: a.len(),
                });
            }
            crate::error::check_finite_points(what, a)?;
        }
        self.x.copy_from_slice(x);
        self.v.copy_from_slice(v);
        Ok(())
    }

    /// Dirichlet targets for the next step: one position per fixed node, in the order of
    /// [`FemSolver::fixed_nodes`], metres. They stay in force until replaced.
    ///
    /// # Errors
    /// [`crate::Error::LengthMismatch`] or [`crate::Error::NonFinite`].
    pub fn set_targets(&mut self, targets: &[Point3]) -> crate::Result<()> {
        if targets.len() != self.fixed_nodes.len() {
            return Err(crate::Error::LengthMismatch {
                what: "Dirichlet targets",
                expected: self.fixed_nodes.len(),
                got: targets.len(),
            });
        }
        crate::error::check_finite_points("Dirichlet targets", targets)?;
        self.targets.copy_from_slice(targets);
        Ok(())
    }

    /// One backward Euler step of size `params.dt`.
    ///
    /// # Errors
    /// [`FemError::NotConverged`], [`FemError::LineSearch`], [`FemError::NonFinite`],
    /// [`FemError::Factorization`]; the state then holds the last finite iterate with
    /// v unchanged.
    pub fn step(&mut self) -> Result<StepInfo, FemError> {
        let h = self.params.dt;
        let x_pred: Vec<Point3> = self
            .x
            .iter()
            .zip(&self.v)
            .map(|(x, v)| [0, 1, 2].map(|r| x[r] + h * v[r]))
            .collect();
        let x_old = self.x.clone();
        let mut x = x_pred.clone();
        for (&i, t) in self.fixed_nodes.iter().zip(&self.targets) {
            x[i] = *t;
        }
        let info = self.minimize(&mut x, &x_pred, 1.0 / (h * h));
        match info {
            Ok(info) => {
                for a in 0..x.len() {
                    self.v[a] = [0, 1, 2].map(|r| (x[a][r] - x_old[a][r]) / h);
                }
                self.x = x;
                self.steps += 1;
                Ok(info)
            }
            Err(e) => {
                if x.iter().all(|p| p.iter().all(|c| c.is_finite())) {
                    self.x = x;
                }
                Err(e)
            }
        }
    }

    /// One step of size `params.dt` that halves itself where Newton fails: a step that does
    /// not converge (or whose line search fails) is undone and taken as two steps of half the
    /// size, the fixed nodes' targets halfway at the first, up to `max_halvings` times deep.
    /// Where every step converges this is [`FemSolver::step`] bit for bit; where it sub-steps
    /// the result is backward Euler at the smaller step there, a finer and converged reference.
    /// The returned info sums the sub-steps' iterations and counts them in `substeps`.
    ///
    /// # Errors
    /// As [`FemSolver::step`], from the deepest sub-step that still failed; the state then
    /// holds the start of the full step.
    pub fn step_substepping(&mut self, max_halvings: u32) -> Result<StepInfo, FemError> {
        let (x0, v0, steps0) = (self.x.clone(), self.v.clone(), self.steps);
        match self.step() {
            Ok(info) => Ok(info),
            Err(FemError::NotConverged { .. } | FemError::LineSearch { .. })
                if max_halvings > 0 =>
            {
                self.x.copy_from_slice(&x0);
                self.v.copy_from_slice(&v0);
                let end = self.targets.clone();
                let half: Vec<Point3> = self
                    .fixed_nodes
                    .iter()
                    .zip(&end)
                    .map(|(&i, t)| [0, 1, 2].map(|r| 0.5 * (x0[i][r] + t[r])))
                    .collect();
                let h = self.params.dt;
                self.params.dt = 0.5 * h;
                self.targets.copy_from_slice(&half);
                let first = self.step_substepping(max_halvings - 1);
                self.targets.copy_from_slice(&end);
                let both = first.and_then(|a| Ok((a, self.step_substepping(max_halvings - 1)?)));
                self.params.dt = h;
                match both {
                    Ok((a, b)) => {
                        // Two half steps make one step of the caller's count.
                        self.steps = steps0 + 1;
                        Ok(StepInfo {
                            newton_iterations: a.newton_iterations + b.newton_iterations,
                            line_search_halvings: a.line_search_halvings + b.line_search_halvings,
                            step_norm: b.step_norm,
                            gradient_norm: b.gradient_norm,
                            seconds: a.seconds + b.seconds,
                            factor_seconds: a.factor_seconds + b.factor_seconds,
                            projected_iterations: a.projected_iterations + b.projected_iterations,
                            substeps: a.substeps + b.substeps,
                        })
                    }
                    Err(e) => {
                        self.x.copy_from_slice(&x0);
                        self.v.copy_from_slice(&v0);
                        self.steps = steps0;
                        Err(e)
                    }
                }
            }
            Err(e) => Err(e),
        }
    }

    /// Static equilibrium from the current positions (no inertia; gravity, Dirichlet targets
    /// and plane penalty apply); sets v = 0. Needs enough held nodes to remove rigid motions.
    ///
    /// # Errors
    /// As [`FemSolver::step`]; [`FemError::Factorization`] when rigid motions are free.
    pub fn solve_static(&mut self) -> Result<StepInfo, FemError> {
        let mut x = self.x.clone();
        for (&i, t) in self.fixed_nodes.iter().zip(&self.targets) {
            x[i] = *t;
        }
        let x_pred = x.clone();
        let res = self.minimize(&mut x, &x_pred, 0.0);
        if x.iter().all(|p| p.iter().all(|c| c.is_finite())) {
            self.x = x;
        }
        self.v.iter_mut().for_each(|v| *v = [0.0; 3]);
        res
    }

    /// The incremental potential E(x) (J) for positions `x` and prediction `x_pred` (N x 3
    /// each, metres) with inertia weight 1/h^2 (`params.dt`).
    pub fn incremental_potential(&self, x: &[Point3], x_pred: &[Point3]) -> f64 {
        let h = self.params.dt;
        self.potential(x, x_pred, 1.0 / (h * h))
    }

    /// dE/dx (N x 3, newtons, all nodes including Dirichlet ones) of
    /// [`FemSolver::incremental_potential`].
    pub fn incremental_gradient(&self, x: &[Point3], x_pred: &[Point3]) -> Vec<Point3> {
        let h = self.params.dt;
        self.gradient(x, x_pred, 1.0 / (h * h))
    }

    /// The assembled Newton matrix of [`FemSolver::incremental_potential`] at `x` over the free
    /// DoFs, as lower-triangle triplets (row, col, value) in the numbering of
    /// [`FemSolver::free_dof`] (row >= col), N/m.
    pub fn incremental_hessian(&mut self, x: &[Point3]) -> Vec<(usize, usize, f64)> {
        let h = self.params.dt;
        let project = self.params.hessian == HessianMode::Projected;
        self.assemble(x, 1.0 / (h * h), project);
        let mut t = Vec::with_capacity(self.values.len());
        for c in 0..self.free_dofs() {
            for k in self.col_ptr[c]..self.col_ptr[c + 1] {
                t.push((self.row_idx[k], c, self.values[k]));
            }
        }
        t
    }

    fn potential(&self, x: &[Point3], x_pred: &[Point3], w: f64) -> f64 {
        let m = self.elements.masses();
        let vol = self.elements.node_volumes();
        let g = self.params.gravity;
        let mut e = self.elements.energy(x);
        let mut nodal = 0.0;
        for a in 0..x.len() {
            let d2: f64 = (0..3).map(|r| (x[a][r] - x_pred[a][r]).powi(2)).sum();
            let gx: f64 = (0..3).map(|r| g[r] * x[a][r]).sum();
            nodal += 0.5 * w * m[a] * d2 - m[a] * gx;
            if let Some(p) = &self.plane {
                let d = penetration(p, &x[a]);
                nodal += 0.5 * vol[a] * p.stiffness * d * d;
            }
        }
        e += nodal;
        e
    }

    fn gradient(&self, x: &[Point3], x_pred: &[Point3], w: f64) -> Vec<Point3> {
        let m = self.elements.masses();
        let vol = self.elements.node_volumes();
        let g = self.params.gravity;
        let mut grad: Vec<Point3> = (0..x.len())
            .map(|a| [0, 1, 2].map(|r| w * m[a] * (x[a][r] - x_pred[a][r]) - m[a] * g[r]))
            .collect();
        if let Some(p) = &self.plane {
            for a in 0..x.len() {
                let d = penetration(p, &x[a]);
                if d > 0.0 {
                    for r in 0..3 {
                        grad[a][r] -= vol[a] * p.stiffness * d * p.normal[r];
                    }
                }
            }
        }
        self.elements.add_gradient(x, &mut grad);
        grad
    }

    /// Fill `values` with the free-DoF Newton matrix at `x`.
    fn assemble(&mut self, x: &[Point3], w: f64, project: bool) {
        self.values.fill(0.0);
        const CHUNK: usize = 1024;
        let nt = self.elements.len();
        let nn = (3 * self.elements.nodes_per_element()).pow(2);
        for start in (0..nt).step_by(CHUNK) {
            let end = (start + CHUNK).min(nt);
            let elements = &self.elements;
            let local: Vec<Vec<f64>> = (start..end)
                .into_par_iter()
                .map(|e| elements.element_hessian(e, x, project))
                .collect();
            for (e, k) in (start..end).zip(&local) {
                let sc = &self.scatter[nn * e..nn * (e + 1)];
                for (&p, &v) in sc.iter().zip(k) {
                    if p != NONE {
                        self.values[p as usize] += v;
                    }
                }
            }
        }
        let m = self.elements.masses();
        let vol = self.elements.node_volumes();
        for a in 0..x.len() {
            let r = self.free_rank[a];
            if r == NONE {
                continue;
            }
            let base = 3 * r as usize;
            for s in 0..3 {
                // Column base + s starts with rows base + s, base + s + 1, ..., base + 2.
                self.values[self.col_ptr[base + s]] += w * m[a];
            }
            if let Some(p) = &self.plane {
                if penetration(p, &x[a]) > 0.0 {
                    let k = vol[a] * p.stiffness;
                    for s in 0..3 {
                        for r2 in s..3 {
                            self.values[self.col_ptr[base + s] + (r2 - s)] +=
                                k * p.normal[r2] * p.normal[s];
                        }
                    }
                }
            }
        }
    }

    /// Newton on E with inertia weight `w`, starting from `x` (Dirichlet nodes already at
    /// their targets), updating `x` in place.
    fn minimize(
        &mut self,
        x: &mut [Point3],
        x_pred: &[Point3],
        w: f64,
    ) -> Result<StepInfo, FemError> {
        let t0 = Instant::now();
        let step = self.steps;
        let tol = self.params.tolerance * self.diag;
        let mut info = StepInfo {
            substeps: 1,
            ..StepInfo::default()
        };
        let ndof = self.free_dofs();
        let mut rhs = vec![0.0; ndof];
        let mut trial = x.to_vec();
        let par = Par::rayon(0);
        for it in 0..self.params.max_newton_iterations {
            let grad = self.gradient(x, x_pred, w);
            let mut gmax = 0.0f64;
            for (a, ga) in grad.iter().enumerate() {
                let r = self.free_rank[a];
                if r == NONE {
                    continue;
                }
                for s in 0..3 {
                    rhs[3 * r as usize + s] = -ga[s];
                }
                gmax = gmax.max(ga.iter().map(|c| c * c).sum::<f64>().sqrt());
            }
            if !gmax.is_finite() {
                return Err(FemError::NonFinite {
                    what: "gradient",
                    step,
                    iteration: it,
                });
            }
            info.gradient_norm = gmax;
            let tf = Instant::now();
            let factored = match self.params.hessian {
                HessianMode::Exact => self.factor(x, w, false),
                HessianMode::Projected => self.factor(x, w, true),
                HessianMode::ExactFirst => match self.factor(x, w, false) {
                    Ok(()) => Ok(()),
                    Err(_) => {
                        info.projected_iterations += 1;
                        self.factor(x, w, true)
                    }
                },
            };
            factored.map_err(|e| {
                FemError::Factorization(format!(
                    "numeric factorization in step {step}, iteration {it}: {e} (the \
                     system is not positive definite: are rigid motions held?)"
                ))
            })?;
            info.factor_seconds += tf.elapsed().as_secs_f64();
            let llt = LltRef::new(&self.symbolic, &self.l_values);
            llt.solve_in_place_with_conj(
                Conj::No,
                MatMut::from_column_major_slice_mut(&mut rhs, ndof, 1),
                par,
                MemStack::new(&mut self.mem),
            );
            let dx = &rhs;
            if !dx.iter().all(|v| v.is_finite()) {
                return Err(FemError::NonFinite {
                    what: "Newton direction",
                    step,
                    iteration: it,
                });
            }
            let step_norm = dx
                .chunks_exact(3)
                .map(|d| (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt())
                .fold(0.0, f64::max);
            info.newton_iterations = it + 1;
            info.step_norm = step_norm;
            // rhs now holds dx; the slope g . dx comes from the gradient.
            let mut slope = 0.0;
            for (a, ga) in grad.iter().enumerate() {
                let r = self.free_rank[a];
                if r != NONE {
                    for c in 0..3 {
                        slope += ga[c] * dx[3 * r as usize + c];
                    }
                }
            }
            if step_norm <= tol {
                apply(x, &self.free_rank, dx, 1.0);
                info.seconds = t0.elapsed().as_secs_f64();
                return Ok(info);
            }
            let e0 = self.potential(x, x_pred, w);
            if !e0.is_finite() {
                return Err(FemError::NonFinite {
                    what: "energy",
                    step,
                    iteration: it,
                });
            }
            let slack = 1e-12 * e0.abs();
            let mut alpha = 1.0;
            let mut accepted = false;
            let mut tried = Vec::new();
            for _ in 0..40 {
                trial.copy_from_slice(x);
                apply(&mut trial, &self.free_rank, dx, alpha);
                let e = self.potential(&trial, x_pred, w);
                if e.is_finite() && e <= e0 + 1e-4 * alpha * slope + slack {
                    accepted = true;
                    break;
                }
                if tried.len() < 4 {
                    tried.push(format!("E({alpha:.3e}) = {e:.9e}"));
                }
                alpha *= 0.5;
                info.line_search_halvings += 1;
            }
            if !accepted {
                return Err(FemError::LineSearch {
                    step,
                    iteration: it,
                    detail: format!(
                        "E(0) = {e0:.9e} J, slope g.dx = {slope:.3e} J, max |dx| = {step_norm:.3e} m; \
                         tried {}",
                        tried.join(", ")
                    ),
                });
            }
            x.copy_from_slice(&trial);
        }
        Err(FemError::NotConverged {
            step,
            iterations: info.newton_iterations,
            step_norm: info.step_norm,
            tolerance: tol,
            gradient_norm: info.gradient_norm,
        })
    }
}

impl FemSolver {
    /// Assemble the Newton matrix at `x` (element Hessians projected to PSD or not) and
    /// factorize it numerically into `l_values`.
    fn factor(&mut self, x: &[Point3], w: f64, project: bool) -> Result<(), String> {
        self.assemble(x, w, project);
        let ndof = self.free_dofs();
        let sym =
            SymbolicSparseColMatRef::new_checked(ndof, ndof, &self.col_ptr, None, &self.row_idx);
        let a = SparseColMatRef::new(sym, &self.values);
        self.symbolic
            .factorize_numeric_llt(
                &mut self.l_values,
                a,
                Side::Lower,
                Default::default(),
                Par::rayon(0),
                MemStack::new(&mut self.mem),
                Default::default(),
            )
            .map(|_| ())
            .map_err(|e| format!("{e:?}"))
    }
}

fn is_linear(order: &ElementOrder) -> bool {
    *order == ElementOrder::Linear
}

fn validate_params(p: &FemParams) -> crate::Result<()> {
    if !(p.dt.is_finite() && p.dt > 0.0) {
        return Err(crate::Error::param(
            "dt",
            p.dt,
            "the time step must be > 0 seconds",
        ));
    }
    if !(p.tolerance.is_finite() && p.tolerance > 0.0) {
        return Err(crate::Error::param(
            "tolerance",
            p.tolerance,
            "the Newton tolerance (relative to the bounding-box diagonal) must be > 0",
        ));
    }
    if p.max_newton_iterations == 0 {
        return Err(crate::Error::param(
            "max_newton_iterations",
            0,
            "must be >= 1",
        ));
    }
    if !p.gravity.iter().all(|g| g.is_finite()) {
        return Err(crate::Error::param(
            "gravity",
            format!("{:?}", p.gravity),
            "gravity must be finite (m/s^2)",
        ));
    }
    Ok(())
}

#[inline]
fn penetration(p: &PlanePenalty, x: &Point3) -> f64 {
    (p.offset - (0..3).map(|r| p.normal[r] * x[r]).sum::<f64>()).max(0.0)
}

/// x_a += alpha dx over free nodes.
fn apply(x: &mut [Point3], free_rank: &[u32], dx: &[f64], alpha: f64) {
    for (a, xa) in x.iter_mut().enumerate() {
        let r = free_rank[a];
        if r != NONE {
            for s in 0..3 {
                xa[s] += alpha * dx[3 * r as usize + s];
            }
        }
    }
}

/// Per element, (3 npe)^2 positions (local i, j -> 3 npe i + j) into the lower-triangular
/// CSC values.
fn build_scatter(
    elements: &Elements,
    free_rank: &[u32],
    col_ptr: &[usize],
    row_idx: &[usize],
) -> Vec<u32> {
    let nl = 3 * elements.nodes_per_element();
    let mut scatter = vec![NONE; nl * nl * elements.len()];
    scatter
        .par_chunks_mut(nl * nl)
        .enumerate()
        .for_each(|(e, sc)| {
            let conn = elements.connectivity(e);
            let dof = |l: usize| {
                let r = free_rank[conn[l / 3] as usize];
                (r != NONE).then(|| 3 * r as usize + l % 3)
            };
            for i in 0..nl {
                for j in 0..nl {
                    if let (Some(gi), Some(gj)) = (dof(i), dof(j)) {
                        if gi >= gj {
                            let col = &row_idx[col_ptr[gj]..col_ptr[gj + 1]];
                            let k = col
                                .binary_search(&gi)
                                .expect("pattern contains every element coupling");
                            sc[nl * i + j] = (col_ptr[gj] + k) as u32;
                        }
                    }
                }
            }
        });
    scatter
}
