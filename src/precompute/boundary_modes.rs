//! Boundary-aware skinning modes (docs/math.md, "Boundary-aware modes"): with B boundary
//! regions the m + 1 weights are B *lifts* (lift b is 1 on region b's kernels, 0 on the other
//! regions' and H_w-harmonic elsewhere; together they sum to 1) followed by m + 1 - B *free
//! modes*, the smallest eigenpairs of H_w c = lambda M c restricted to fields whose
//! coefficients vanish on every region's kernels.
//!
//! A kernel is *pinned* to a region when its centre lies in it, as the nodes of a FEM
//! Dirichlet boundary are the nodes in the held region. On the region's *core* (the points
//! covered by its pinned kernels only) a lift is exactly 1 or 0 (RKPM reproduces constants)
//! and the free modes exactly 0; within one kernel support of the region's edge the free modes
//! ramp up, as the elements straddling a Dirichlet boundary do. The simulator holds an aware
//! region through its lift's handle ([`lift_column`]), so the hold never touches the free
//! modes: the locking of free-floating modes under a stiff hold (docs/accuracy.md) is gone.
//!
//! The restricted eigenproblem (H_FF, M_FF) has no null space, while every eigensolver here
//! deflates the constant. It is handed to them *grounded*: one extra unknown g with the map
//! Q [y; g] = y - g 1, H' = Q^T H_FF Q (null vector exactly 1) and
//! M' = Q^T M_FF Q + alpha e_g e_g^T (SPD). M'-orthogonality to 1 forces g = 0, and there
//! the pencil (H', M') is (H_FF, M_FF): the solvers return the constant and then exactly the
//! restricted eigenpairs, with no change to LOBPCG, the dense solver or SLEPc.

use super::rkpm::Kernels;
use super::sampling::IntegrationPoints;
use super::skinning::Basis;
use crate::eigen::EigenSolution;
use crate::material::Region;
use crate::sparse::{self, SparseMatrix, SparseMatrixRef};
use crate::{Error, Result};
use faer::Mat;
use serde::{Deserialize, Serialize};

/// How a basis treats an object's boundary regions (held, translated, rotated, keyframed).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum BoundaryModes {
    /// One lift weight per region and free modes that vanish on every region: the basis
    /// follows each region exactly without spending its free combinations (the default, chosen
    /// by the beam measurements in docs/accuracy.md).
    #[default]
    Aware,
    /// Global, free-floating modes (the constant and the smallest eigenpairs of H_w); regions
    /// are held only by the simulator's penalty.
    Free,
}

impl BoundaryModes {
    /// "aware" or "free".
    pub fn name(&self) -> &'static str {
        crate::names::variant_name(self)
    }
}

impl std::fmt::Display for BoundaryModes {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl std::str::FromStr for BoundaryModes {
    type Err = Error;
    fn from_str(s: &str) -> Result<Self> {
        match s.trim().to_ascii_lowercase().as_str() {
            "aware" => Ok(BoundaryModes::Aware),
            "free" => Ok(BoundaryModes::Free),
            other => Err(Error::param(
                "boundaries",
                other,
                "expected \"aware\" or \"free\"",
            )),
        }
    }
}

/// What one boundary region does to the basis (part of the `modes` report).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct BoundaryRegionReport {
    /// The region, rest coordinates, metres.
    pub region: Region,
    /// Integration points inside it.
    pub points: usize,
    /// Kernels pinned to it (centred in it).
    pub kernels: usize,
    /// H_w energy of its lift over its M norm, c^T H c / c^T M c, Pa / m^2.
    pub lift_rayleigh: f64,
}

/// Which kernels the boundary regions pin.
#[derive(Debug, Clone, PartialEq)]
pub struct RegionPartition {
    /// Per kernel (K): the region it is pinned to, or None for a free kernel.
    pub owner: Vec<Option<usize>>,
    /// The free kernels, ascending.
    pub free: Vec<usize>,
    /// Per region: integration points inside.
    pub points: Vec<usize>,
    /// Per region: kernels pinned.
    pub kernels: Vec<usize>,
}

impl RegionPartition {
    /// Number of regions B.
    pub fn regions(&self) -> usize {
        self.points.len()
    }
}

/// Pin every kernel whose centre lies in a region to that region (the RKPM analogue of the
/// nodes of a FEM Dirichlet boundary).
///
/// # Errors
/// [`Error::InvalidParameter`] for an invalid region, a region with no integration point or
/// no kernel centre (thinner than the kernel spacing), overlapping regions (a kernel centre in
/// both), or regions that leave fewer than `free_modes + 1` kernels free.
pub fn partition(
    kernels: &Kernels,
    points: &IntegrationPoints,
    regions: &[Region],
    free_modes: usize,
) -> Result<RegionPartition> {
    let k = kernels.len();
    let mut owner: Vec<Option<usize>> = vec![None; k];
    let mut counts = Vec::with_capacity(regions.len());
    let mut pinned = Vec::with_capacity(regions.len());
    for (b, region) in regions.iter().enumerate() {
        region.validate()?;
        let inside = points.points.iter().filter(|p| region.contains(p)).count();
        if inside == 0 {
            return Err(Error::param(
                "boundary region",
                b,
                format!(
                    "{region:?} contains no integration point of the object; move it onto the \
                     object (rest coordinates) or remove it"
                ),
            ));
        }
        let mut n = 0;
        for kk in 0..k {
            if !region.contains(&kernels.centers[kk]) {
                continue;
            }
            if let Some(o) = owner[kk] {
                return Err(Error::param(
                    "boundary regions",
                    format!("{o} and {b}"),
                    format!(
                        "overlap (kernel centre {:?} lies in both): a basis cannot be 1 on one \
                         and 0 on the other; make them disjoint or merge them",
                        kernels.centers[kk]
                    ),
                ));
            }
            owner[kk] = Some(b);
            n += 1;
        }
        if n == 0 {
            let spacing = kernels.radii.iter().sum::<f64>() / k.max(1) as f64;
            return Err(Error::param(
                "boundary region",
                b,
                format!(
                    "{region:?} holds {inside} integration points but no kernel centre: it is \
                     thinner than the kernel spacing (supports ~{spacing:.3e} m); enlarge it, \
                     use more kernels, or use basis.boundaries = \"free\""
                ),
            ));
        }
        counts.push(inside);
        pinned.push(n);
    }
    let free: Vec<usize> = (0..k).filter(|&i| owner[i].is_none()).collect();
    if free.len() < free_modes + 1 {
        return Err(Error::param(
            "boundary regions",
            regions.len(),
            format!(
                "pin {} of the {k} kernels, leaving {} free; {free_modes} free modes need at \
                 least {}: the regions cover (nearly) the whole object; shrink them, use more \
                 kernels, or use basis.boundaries = \"free\"",
                k - free.len(),
                free.len(),
                free_modes + 1
            ),
        ));
    }
    Ok(RegionPartition {
        owner,
        free,
        points: counts,
        kernels: pinned,
    })
}

/// The lift of `region` in `basis`, if the basis is boundary-aware for it: the column that is
/// exactly 1 on every kernel centred in the region while every other column is exactly 0
/// there (values set by construction, so the test is exact). None for a free basis or a
/// region the basis was not built for. The simulator holds such a region through this
/// column's handle alone.
pub fn lift_column(basis: &Basis, region: &Region) -> Option<usize> {
    let c = &basis.coefficients;
    let inside: Vec<usize> = (0..basis.kernels.len())
        .filter(|&k| region.contains(&basis.kernels.centers[k]))
        .collect();
    let &first = inside.first()?;
    let j = (0..c.ncols()).find(|&j| c[(first, j)] == 1.0)?;
    let exact = inside
        .iter()
        .all(|&k| (0..c.ncols()).all(|i| c[(k, i)] == if i == j { 1.0 } else { 0.0 }));
    exact.then_some(j)
}

/// Index of each kernel among the free ones (usize::MAX for pinned kernels).
fn free_index(part: &RegionPartition) -> Vec<usize> {
    let mut idx = vec![usize::MAX; part.owner.len()];
    for (i, &k) in part.free.iter().enumerate() {
        idx[k] = i;
    }
    idx
}

/// How [`restricted`] grounds its matrix.
#[derive(Clone, Copy, PartialEq)]
enum Ground {
    /// The principal submatrix A_FF alone.
    None,
    /// Q^T A_FF Q (for H_FF).
    Plain,
    /// Q^T A_FF Q + alpha e_g e_g^T with alpha the mean row sum of A_FF (for M_FF: a kernel's
    /// volume, so the extra direction is scaled like the others).
    WithMeanRowSum,
}

/// The principal submatrix A_FF (n x n), or the grounded (n + 1) x (n + 1) matrix with
/// Q [y; g] = y - g 1 (see [`Ground`]). It holds at most nnz(A) + 2 n + 1 entries, which the
/// assembly keeps within a [`SparseMatrix`]'s u32 range.
fn restricted(a: SparseMatrixRef<'_>, part: &RegionPartition, ground: Ground) -> SparseMatrix {
    let map = free_index(part);
    let n = part.free.len();
    let (ptr, idx, val) = (a.col_ptr(), a.row_idx(), a.val());
    let mut out_ptr = Vec::with_capacity(n + 2);
    let mut out_idx = Vec::new();
    let mut out_val = Vec::new();
    out_ptr.push(0u32);
    let entries = |len: usize| {
        u32::try_from(len).expect("restricted: more entries than a SparseMatrix addresses")
    };
    // Row sums over the free rows: (A_FF 1)_j per free column j (A is symmetric).
    let mut sums = vec![0.0; n];
    for (j, &kj) in part.free.iter().enumerate() {
        let mut s = 0.0;
        for e in ptr[kj] as usize..ptr[kj + 1] as usize {
            let i = map[idx[e] as usize];
            if i != usize::MAX {
                // i < n <= K, addressed by u32 like A's own indices.
                out_idx.push(i as u32);
                out_val.push(val[e]);
                s += val[e];
            }
        }
        sums[j] = s;
        if ground != Ground::None {
            out_idx.push(n as u32);
            out_val.push(-s);
        }
        out_ptr.push(entries(out_idx.len()));
    }
    if ground == Ground::None {
        return sparse::from_compressed(n, out_ptr, out_idx, out_val);
    }
    let total: f64 = sums.iter().sum();
    let alpha = match ground {
        Ground::WithMeanRowSum => (total / n.max(1) as f64).max(f64::MIN_POSITIVE),
        _ => 0.0,
    };
    for (j, s) in sums.iter().enumerate() {
        out_idx.push(j as u32);
        out_val.push(-s);
    }
    out_idx.push(n as u32);
    out_val.push(total + alpha);
    out_ptr.push(entries(out_idx.len()));
    sparse::from_compressed(n + 1, out_ptr, out_idx, out_val)
}

/// The grounded pencil (H', M') of the restricted problem, (n + 1) square with n the free
/// kernels: hand it to any [`crate::eigen::Eigensolver`] with nev = free modes + 1.
pub fn grounded_problem(
    h: SparseMatrixRef<'_>,
    m: SparseMatrixRef<'_>,
    part: &RegionPartition,
) -> (SparseMatrix, SparseMatrix) {
    (
        restricted(h, part, Ground::Plain),
        restricted(m, part, Ground::WithMeanRowSum),
    )
}

/// The aware basis from the grounded solution: coefficients K x (B + f) (the B lifts, then the
/// f = `solution` pairs beyond its constant, embedded with zeros on pinned kernels), their
/// values (lift Rayleigh quotients, then the free eigenvalues) and one report per region.
///
/// # Errors
/// [`Error::InvalidParameter`] when the lift solve fails (H_FF not positive definite).
pub fn assemble_aware(
    h: SparseMatrixRef<'_>,
    m: SparseMatrixRef<'_>,
    part: &RegionPartition,
    regions: &[Region],
    solution: &EigenSolution,
) -> Result<(Mat<f64>, Vec<f64>, Vec<BoundaryRegionReport>)> {
    let k = part.owner.len();
    let b = part.regions();
    let lifts = lifts(h, part)?;
    let free_pairs = solution.vectors.ncols().saturating_sub(1);
    let n = part.free.len();
    let mut coef = Mat::<f64>::zeros(k, b + free_pairs);
    for r in 0..b {
        coef.col_mut(r).copy_from(lifts.col(r));
    }
    for j in 0..free_pairs {
        let x = solution.vectors.col(j + 1);
        // y = Q x = x_F - x_g 1 (x_g is zero to rounding).
        let g = x[n];
        for (i, &kk) in part.free.iter().enumerate() {
            coef[(kk, b + j)] = x[i] - g;
        }
    }
    let mut values = Vec::with_capacity(b + free_pairs);
    let mut reports = Vec::with_capacity(b);
    for r in 0..b {
        let c = lifts.col(r);
        let rq = quadratic(h, c) / quadratic(m, c).max(f64::MIN_POSITIVE);
        values.push(rq);
        reports.push(BoundaryRegionReport {
            region: regions[r],
            points: part.points[r],
            kernels: part.kernels[r],
            lift_rayleigh: rq,
        });
    }
    values.extend_from_slice(&solution.values[1..=free_pairs]);
    Ok((coef, values, reports))
}

/// c^T A c.
fn quadratic(a: SparseMatrixRef<'_>, c: faer::ColRef<'_, f64>) -> f64 {
    let x: Vec<f64> = c.iter().copied().collect();
    let mut y = vec![0.0; x.len()];
    sparse::sym_mul_row_major(a, &x, 1, &mut y, 1, 1);
    x.iter().zip(&y).map(|(a, b)| a * b).sum()
}

/// The B lifts, K x B: lift b is 1 on region b's kernels, 0 on the other pinned kernels and
/// solves H_FF c_F = -H_FC e_b on the free ones. Lift 0 is 1 minus the others, so the lifts
/// sum to the constant exactly (with one region it is the constant).
fn lifts(h: SparseMatrixRef<'_>, part: &RegionPartition) -> Result<Mat<f64>> {
    let k = part.owner.len();
    let b = part.regions();
    let mut out = Mat::<f64>::zeros(k, b);
    if b == 0 {
        return Ok(out);
    }
    if b > 1 {
        let hff = restricted(h, part, Ground::None);
        let map = free_index(part);
        let n = part.free.len();
        let mut rhs = Mat::<f64>::zeros(n, b - 1);
        let (ptr, idx, val) = (h.col_ptr(), h.row_idx(), h.val());
        for kk in 0..k {
            if let Some(r @ 1..) = part.owner[kk] {
                for e in ptr[kk] as usize..ptr[kk + 1] as usize {
                    let i = map[idx[e] as usize];
                    if i != usize::MAX {
                        rhs[(i, r - 1)] -= val[e];
                    }
                }
            }
        }
        let llt = hff.sp_cholesky(faer::Side::Lower).map_err(|e| {
            Error::param(
                "boundary regions",
                b,
                format!(
                    "H_w restricted to the {n} free kernels is not positive definite ({e:?}); \
                     the free kernels do not form a connected elastic body"
                ),
            )
        })?;
        use faer::linalg::solvers::Solve;
        let mut x = rhs.clone();
        llt.solve_in_place(x.as_mut());
        if !x.col_iter().all(|c| c.iter().all(|v| v.is_finite())) {
            return Err(Error::param(
                "boundary regions",
                b,
                "the lift solve produced non-finite values (H_w restricted to the free kernels \
                 is singular)",
            ));
        }
        for (i, &kk) in part.free.iter().enumerate() {
            for r in 1..b {
                out[(kk, r)] = x[(i, r - 1)];
            }
        }
        for kk in 0..k {
            if let Some(r @ 1..) = part.owner[kk] {
                out[(kk, r)] = 1.0;
            }
        }
    }
    for kk in 0..k {
        let others: f64 = (1..b).map(|r| out[(kk, r)]).sum();
        out[(kk, 0)] = 1.0 - others;
    }
    Ok(out)
}
