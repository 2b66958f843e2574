//! Extra render inputs of an object (`render = [...]` in a scene): meshes, point clouds or 3DGS
//! splat files drawn with the object's deformation map, whatever its sampling. The math they
//! share with the object's own render points (splat frames, stress) lives here too.

use crate::error::GeometryError;
use crate::geometry::{ShapeSpec, TriMesh, UpAxis};
use crate::io::splat::{MovedSplats, Splats};
use crate::linalg3::Mat3;
use crate::material::MaterialField;
use crate::precompute::skinning::{Basis, SkinningWeights};
use crate::sim::ReducedSim;
use crate::{Error, Point3, Result};
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

/// One render input of an object: its rest positions (every vertex of a mesh, referenced or
/// not), the skinning weights there, and its triangles or splats.
#[derive(Debug)]
pub struct RenderSet {
    name: String,
    file: PathBuf,
    rest: Vec<Point3>,
    weights: SkinningWeights,
    triangles: Option<Vec<[u32; 3]>>,
    splats: Option<Splats>,
    /// Lame parameters (lambda, mu) at the rest positions, Pa (first stress request).
    lame: OnceLock<Vec<(f64, f64)>>,
}

/// The name a render file's frames carry: its file stem with anything but letters, digits,
/// '-' and '_' replaced by '_'.
pub fn set_name(file: &Path) -> String {
    let stem = file
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    let name: String = stem
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '-' || c == '_' {
                c
            } else {
                '_'
            }
        })
        .collect();
    if name.is_empty() {
        "render".into()
    } else {
        name
    }
}

impl RenderSet {
    /// Read `file` (OBJ, STL, OFF or PLY mesh, PLY point cloud, 3DGS splat PLY, or a USD prim
    /// `FILE.usda:/Prim/Path[@T]` read into a frame whose up axis is `up`; meshes need not be
    /// closed) and evaluate `basis` at its points.
    ///
    /// # Errors
    /// The reader's error for an unreadable file; an [`Error::InvalidParameter`] naming the
    /// file (`render`) when some of its points are not covered by the kernels (the input lies
    /// outside the simulated object, where the map would be extrapolated).
    pub(super) fn load(file: &Path, basis: &Basis, up: UpAxis) -> Result<RenderSet> {
        // A USD prim (a mesh: triangles; points or splats: their points). A spec that names
        // a USD file but is malformed (prim path, time code) gets the spec parser's error.
        match ShapeSpec::parse(&file.to_string_lossy()) {
            Err(e @ GeometryError::BadPrimitive { .. }) => return Err(e.into()),
            Ok(ShapeSpec::Usd { path, prim, time }) => {
                let g = crate::io::usd::read_usd_geometry(&path, prim.as_deref(), time, up)?;
                return Self::with_points(file, basis, g.points, g.triangles, None);
            }
            _ => {}
        }
        let ext = file
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase)
            .unwrap_or_default();
        let (rest, triangles, splats) = match ext.as_str() {
            "obj" => {
                let (v, t) = crate::io::obj::read_obj_raw(file)?;
                (v, Some(t), None)
            }
            "stl" => {
                let (v, t) = crate::io::stl::read_stl_soup(file)?;
                (v, Some(t), None)
            }
            "off" => {
                let (v, t) = crate::io::off::read_off_raw(file)?;
                (v, Some(t), None)
            }
            "ply" if crate::io::splat::is_splat_ply(file)? => {
                let s = crate::io::splat::read_splats(file)?;
                (s.means.clone(), None, Some(s))
            }
            "ply" => {
                let d = crate::io::ply::read_ply_data(file)?;
                (d.points, d.triangles, None)
            }
            _ => {
                return Err(GeometryError::InvalidInput(format!(
                    "{}: a render input must be an .obj, .stl, .off or .ply file, or a USD \
                     prim (FILE.usda:/Prim/Path)",
                    file.display()
                ))
                .into())
            }
        };
        Self::with_points(file, basis, rest, triangles, splats)
    }

    /// A mesh the library derived (an object's contact surface), named `name` in its frames;
    /// `basis` evaluated at its vertices.
    ///
    /// # Errors
    /// As [`RenderSet::load`] for vertices the kernels do not cover.
    pub(super) fn derived(name: &str, basis: &Basis, mesh: &TriMesh) -> Result<RenderSet> {
        let mut set = Self::with_points(
            Path::new(name),
            basis,
            mesh.vertices().to_vec(),
            Some(mesh.triangles().to_vec()),
            None,
        )?;
        set.name = name.to_string();
        Ok(set)
    }

    /// The set read from `file`: its rest points, triangles or splats, with `basis` evaluated
    /// at the points.
    fn with_points(
        file: &Path,
        basis: &Basis,
        rest: Vec<Point3>,
        triangles: Option<Vec<[u32; 3]>>,
        splats: Option<Splats>,
    ) -> Result<RenderSet> {
        if rest.is_empty() {
            return Err(GeometryError::InvalidInput(format!(
                "{}: the render input has no points",
                file.display()
            ))
            .into());
        }
        let weights = basis.weights(&rest).map_err(|e| match e {
            Error::Coverage {
                count,
                index,
                position,
                ..
            } => Error::param(
                "render",
                file.display(),
                format!(
                    "{count} of its {} points are not covered by the object's kernels (the \
                     first, point {index}, at [{:.4}, {:.4}, {:.4}]): the input lies outside \
                     the simulated object, where the deformation map would be extrapolated; \
                     place it inside or on the object (same rest frame)",
                    rest.len(),
                    position[0],
                    position[1],
                    position[2]
                ),
            ),
            other => other,
        })?;
        Ok(RenderSet {
            name: set_name(file),
            file: file.to_path_buf(),
            rest,
            weights,
            triangles,
            splats,
            lame: OnceLock::new(),
        })
    }

    /// The name its frames carry (the file stem, see [`set_name`]).
    pub fn name(&self) -> &str {
        &self.name
    }

    /// The file it was read from.
    pub fn file(&self) -> &Path {
        &self.file
    }

    /// Rest positions, N x 3, metres (all vertices of a mesh).
    pub fn rest(&self) -> &[Point3] {
        &self.rest
    }

    /// Triangles (meshes), indices into the points.
    pub fn triangles(&self) -> Option<&[[u32; 3]]> {
        self.triangles.as_deref()
    }

    /// The splats of a 3DGS input (rest state).
    pub fn splats(&self) -> Option<&Splats> {
        self.splats.as_ref()
    }

    /// Deformed positions under `sim`'s current state, N x 3, metres.
    pub fn positions(&self, sim: &ReducedSim) -> Vec<Point3> {
        sim.positions(&self.rest, &self.weights)
    }

    /// The current splat frame (None unless a 3DGS input); see [`splat_frame`].
    pub fn splat_frame(
        &self,
        sim: &ReducedSim,
        positions: Vec<Point3>,
        rotate_sh: bool,
    ) -> Option<MovedSplats> {
        let s = self.splats.as_ref()?;
        Some(splat_frame(
            sim,
            &self.rest,
            &self.weights,
            s,
            positions,
            rotate_sh,
        ))
    }

    /// Cauchy stress at the points, Pa, with the object's materials (`spec`'s, and `image`'s
    /// where given) at the rest positions; see [`stress`].
    pub fn stress(
        &self,
        sim: &ReducedSim,
        spec: &super::spec::ObjectSpec,
        image: Option<&crate::precompute::ImageMaterial>,
    ) -> Result<Vec<Mat3>> {
        let lame = match self.lame.get() {
            Some(l) => l,
            None => {
                let field = super::setup::material_at(&self.rest, spec, image)?;
                self.lame.get_or_init(|| lame_of(&field))
            }
        };
        Ok(stress(sim, &self.rest, &self.weights, lame))
    }
}

/// Lame parameters (lambda, mu) of every point of `field`, Pa.
pub(super) fn lame_of(field: &MaterialField) -> Vec<(f64, f64)> {
    (0..field.len()).map(|i| field.lame(i)).collect()
}

/// Splats moved by `sim`'s map: centres to `positions` (the deformed `rest`), covariances
/// pushed forward by the deformation gradient at each centre and re-derived as log-scales and
/// rotations, with `rotate_sh` the SH colour rotated by the polar rotation
/// ([`crate::sim::gaussian::deform_splats`]).
pub(super) fn splat_frame(
    sim: &ReducedSim,
    rest: &[Point3],
    weights: &SkinningWeights,
    splats: &Splats,
    positions: Vec<Point3>,
    rotate_sh: bool,
) -> MovedSplats {
    let f = crate::sim::deformation::deformation_gradients(sim.layout(), sim.z(), rest, weights);
    let d = crate::sim::gaussian::deform_splats(
        &f,
        &splats.log_scales,
        &splats.rotations,
        &splats.sh_rest,
        splats.sh_degree,
        rotate_sh,
    );
    MovedSplats {
        means: positions,
        log_scales: d.log_scales,
        rotations: d.rotations,
        sh_rest: d.sh_rest,
    }
}

/// Cauchy stress sigma = P(F) F^T / det F at points with rest positions `rest`, weights
/// `weights` and Lame parameters `lame` (Pa), F the gradient of `sim`'s map there; zero
/// where det F <= 0 (an inverted point has no physical true stress; the step monitors count
/// inversions).
pub(super) fn stress(
    sim: &ReducedSim,
    rest: &[Point3],
    weights: &SkinningWeights,
    lame: &[(f64, f64)],
) -> Vec<Mat3> {
    let f = crate::sim::deformation::deformation_gradients(sim.layout(), sim.z(), rest, weights);
    f.iter()
        .zip(lame)
        .map(|(f, &(lambda, mu))| {
            crate::elasticity::cauchy_stress(f, lambda, mu).unwrap_or([[0.0; 3]; 3])
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn set_names_are_file_stems_safe_for_file_names() {
        assert_eq!(set_name(Path::new("dir/hi res.obj")), "hi_res");
        assert_eq!(set_name(Path::new("splats-v2.ply")), "splats-v2");
        assert_eq!(set_name(Path::new(".ply")), "_ply");
    }
}
