//! The FEM reference of one shape and boundary condition: the protocol's regions select the
//! held and moved FE nodes of the TetGen mesh, [`FemSolver`] runs the protocol's steps, and
//! the trajectory is cached like the beam's (`.freeform-cache/fem`, keyed by the mesh and
//! every setting).

use super::protocol::{boundary_regions, gravity, NormalizedShape, Protocol, ShapeTest};
use crate::fem::beam::{cached_reference, fnv1a, record_trajectory, BeamReference};
use crate::fem::element::fe_nodes;
use crate::fem::solver::{FemParams, FemSolver};
use crate::fem::{FemError, TetMaterials, TetMesh};
use crate::material::MaterialOverride;
use crate::progress::Progress;
use crate::{Error, Point3, Result};
use std::path::Path;

/// Cache key of a shape reference: FNV-1a 64 of the canonical JSON of the mesh's hash and
/// the settings, as 16 hex digits, and the JSON itself.
pub fn cache_key(
    mesh: &TetMesh,
    protocol: &Protocol,
    shape: &NormalizedShape,
    test: ShapeTest,
    overrides: &[MaterialOverride],
    params: &FemParams,
) -> (String, String) {
    let mut bytes: Vec<u8> = mesh
        .nodes()
        .iter()
        .flatten()
        .flat_map(|c| c.to_le_bytes())
        .collect();
    for t in mesh.tets() {
        for i in t {
            bytes.extend_from_slice(&i.to_le_bytes());
        }
    }
    let mut json = serde_json::json!({
        "format": crate::fem::beam::CACHE_FORMAT_VERSION,
        "kind": "shape",
        "mesh": format!("{:016x}", fnv1a(&bytes)),
        "nodes": mesh.num_nodes(),
        "tets": mesh.num_tets(),
        "protocol": protocol,
        "test": test,
        "regions": boundary_regions(protocol, shape, test),
        "solver": params,
    });
    // Homogeneous references keep the keys they had before overrides existed.
    if !overrides.is_empty() {
        json["overrides"] = serde_json::json!(overrides);
    }
    let json = json.to_string();
    (format!("{:016x}", fnv1a(json.as_bytes())), json)
}

/// The solver settings of `test`: `base` (tolerance, order, ...) with the protocol's time
/// step and the test's gravity.
pub fn fem_params(
    base: &FemParams,
    protocol: &Protocol,
    shape: &NormalizedShape,
    test: ShapeTest,
) -> FemParams {
    FemParams {
        dt: protocol.dt,
        gravity: gravity(protocol, shape, test),
        ..base.clone()
    }
}

/// Run (or load from `cache_dir`) the FEM reference of `test` on `mesh` (the TetGen mesh of
/// `shape`), of [`Protocol::material`] with `overrides` applied in order to the tets whose
/// centroid lies in their region (normalized frame; empty: homogeneous).
///
/// The arguments are the case (mesh, protocol, shape, test, materials), the solver and where
/// the run is cached and reported: grouping them would only name the call's own parts.
///
/// # Errors
/// A region that holds no FE node ([`Error::InvalidParameter`]), the solver's errors
/// ([`FemError::NotConverged`] with the step), cache write failures.
#[allow(clippy::too_many_arguments)]
pub fn run_shape_reference(
    mesh: &TetMesh,
    protocol: &Protocol,
    shape: &NormalizedShape,
    test: ShapeTest,
    overrides: &[MaterialOverride],
    base: &FemParams,
    cache_dir: Option<&Path>,
    progress: &dyn Progress,
) -> Result<BeamReference> {
    protocol.validate()?;
    let params = fem_params(base, protocol, shape, test);
    let (hash, key) = cache_key(mesh, protocol, shape, test, overrides, &params);
    cached_reference(cache_dir, &hash, &key, progress, || {
        let materials = TetMaterials::from_regions(mesh, &protocol.material, overrides)?;
        compute(mesh, &materials, protocol, shape, test, params, progress)
    })
}

fn compute(
    mesh: &TetMesh,
    materials: &TetMaterials,
    protocol: &Protocol,
    shape: &NormalizedShape,
    test: ShapeTest,
    params: FemParams,
    progress: &dyn Progress,
) -> Result<BeamReference> {
    let (fe, _) = fe_nodes(mesh, params.order);
    let regions = boundary_regions(protocol, shape, test);
    // Each FE node follows the first region that contains it.
    let mut owner: Vec<Option<usize>> = vec![None; fe.len()];
    for (r, (region, motion)) in regions.iter().enumerate() {
        region.validate()?;
        motion.validate()?;
        let mut any = false;
        for (o, p) in owner.iter_mut().zip(&fe) {
            if region.contains(p) {
                any = true;
                o.get_or_insert(r);
            }
        }
        if !any {
            return Err(Error::param(
                "region",
                format!("{region:?}"),
                format!(
                    "{}: the region holds no FE node of the TetGen mesh; refine the mesh \
                     (smaller largest tet volume) or enlarge the region",
                    test.name()
                ),
            ));
        }
    }
    let fixed: Vec<usize> = (0..fe.len()).filter(|&i| owner[i].is_some()).collect();
    let steps = protocol.steps;
    let mut solver = FemSolver::new(mesh, materials, &fixed, params)?;
    let moving = regions
        .iter()
        .any(|(_, m)| *m != crate::sim::motion::Motion::Fixed);
    let label = format!("FEM {}", test.name());
    record_trajectory(
        &mut solver,
        mesh,
        steps,
        &label,
        progress,
        |n, rest, fixed| {
            let t = n as f64 * protocol.dt;
            moving.then(|| {
                fixed
                    .iter()
                    .map(|&i| match owner[i] {
                        Some(r) => regions[r].1.at(t).apply(&rest[i]),
                        None => rest[i],
                    })
                    .collect()
            })
        },
    )
}

/// The trajectory difference between two references of the same shape and test on two
/// meshes that share nodes (TetGen with `-Y` keeps every surface vertex at every
/// refinement): [`crate::fem::metric::trajectory_error`] of `coarse` against `fine` over the
/// nodes present in both (matched by rest position within 1e-9 D). Returns the error and
/// the number of shared nodes.
///
/// # Errors
/// [`FemError::Trajectory`] when no node is shared or the frame counts differ.
pub fn shared_node_difference(
    coarse: &BeamReference,
    fine: &BeamReference,
) -> std::result::Result<(crate::fem::metric::TrajectoryError, usize), FemError> {
    let d = crate::geometry::Aabb::from_points(&fine.rest).map_or(1.0, |b| b.diagonal());
    let q = |p: &Point3| p.map(|c| (c / (1e-9 * d)).round() as i64);
    let index: std::collections::HashMap<[i64; 3], usize> = fine
        .rest
        .iter()
        .enumerate()
        .map(|(i, p)| (q(p), i))
        .collect();
    let pairs: Vec<(usize, usize)> = coarse
        .rest
        .iter()
        .enumerate()
        .filter_map(|(a, p)| index.get(&q(p)).map(|&b| (a, b)))
        .collect();
    if pairs.is_empty() || coarse.frames.len() != fine.frames.len() {
        return Err(FemError::Trajectory {
            what: "fine",
            detail: format!(
                "{} shared nodes, {} and {} frames: nothing to compare",
                pairs.len(),
                coarse.frames.len(),
                fine.frames.len()
            ),
        });
    }
    let pick = |frames: &[Vec<Point3>], fine_side: bool| -> Vec<Vec<Point3>> {
        frames
            .iter()
            .map(|f| {
                pairs
                    .iter()
                    .map(|&(a, b)| f[if fine_side { b } else { a }])
                    .collect()
            })
            .collect()
    };
    let rest: Vec<Point3> = pairs.iter().map(|&(a, _)| coarse.rest[a]).collect();
    let err = crate::fem::metric::trajectory_error(
        &rest,
        &pick(&fine.frames, true),
        &pick(&coarse.frames, false),
    )?;
    Ok((err, pairs.len()))
}
