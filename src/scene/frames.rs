//! Frame output as observers of a [`World`]: [`FrameWriter`] writes VTK (`.vtp` per frame
//! and a `.pvd` collection per object, for ParaView) and PLY files (3DGS splat PLY for splat
//! objects).

use super::object::SceneObject;
use super::spec::{collider_stem, Format};
use super::world::World;
use crate::io::vtk::{self, PointData};
use crate::{Error, Result};
use std::path::{Path, PathBuf};

/// Something that looks at the world at output frames: frame 0 after setup, then after the
/// steps the scene's output settings select, and once at the end.
pub trait FrameObserver {
    /// Called with the world at output frame `frame` (the step number; 0 before stepping).
    fn frame(&mut self, world: &World, frame: usize) -> Result<()>;
    /// Called once after the last frame of a complete run.
    fn finish(&mut self, world: &World) -> Result<()>;
}

/// Writes each object's render points (or deformed mesh) per frame into `<out>/<object>/`:
/// `<object>_<frame:06>.vtp` (VTK PolyData with the displacement, and the stress if asked)
/// and/or `.ply`, likewise `<object>_<input>_<frame:06>.*` for each render input, and
/// `<out>/<object>.pvd` (and `<out>/<object>_<input>.pvd`) collections of the VTK frames with
/// their times: rewritten (atomically) as frames land, at most once every
/// [`PVD_INTERVAL`] and at the end, so an interrupted run opens with the frames it wrote.
#[derive(Debug)]
pub struct FrameWriter {
    out: PathBuf,
    formats: Vec<Format>,
    /// Per `.pvd` collection (an object, or an object's render input), in first-written
    /// order: its stem and the (time, relative file) of each VTK frame.
    pvd: Vec<(String, Vec<(f64, String)>)>,
    files: Vec<String>,
    frames: usize,
    rotate_splat_sh: bool,
    stress: bool,
    /// When the `.pvd` collections were last written (None: not yet).
    pvd_written: Option<std::time::Instant>,
}

/// Least time between two rewrites of the `.pvd` collections during a run: each rewrite
/// holds every frame so far, so rewriting at every frame would cost O(frames^2).
pub const PVD_INTERVAL: std::time::Duration = std::time::Duration::from_secs(1);

impl FrameWriter {
    /// A writer into directory `out` (created, with parents) in `formats`.
    pub fn new(out: &Path, formats: &[Format]) -> Result<FrameWriter> {
        std::fs::create_dir_all(out).map_err(|source| Error::Io {
            path: out.to_path_buf(),
            source,
        })?;
        Ok(FrameWriter {
            out: out.to_path_buf(),
            formats: formats.to_vec(),
            pvd: Vec::new(),
            files: Vec::new(),
            frames: 0,
            rotate_splat_sh: true,
            stress: false,
            pvd_written: None,
        })
    }

    /// Whether splat objects' `.ply` frames rotate the SH colour (default true; the scene's
    /// `output.rotate_splat_sh`).
    #[must_use]
    pub fn rotate_splat_sh(mut self, on: bool) -> FrameWriter {
        self.rotate_splat_sh = on;
        self
    }

    /// Write the Cauchy stress into the VTK frames (`stress`, `principal_stress`,
    /// `von_mises`; see `output.stress`). Default off.
    pub fn stress(mut self, on: bool) -> FrameWriter {
        self.stress = on;
        self
    }

    /// Files written so far, in order.
    pub fn files(&self) -> &[String] {
        &self.files
    }

    /// Frames written so far (per object).
    pub fn frames(&self) -> usize {
        self.frames
    }

    /// Write one frame of one object: its own render points, then each render input.
    fn write_object(&mut self, object: &SceneObject, frame: usize) -> Result<()> {
        let name = object.name();
        let dir = self.out.join(name);
        std::fs::create_dir_all(&dir).map_err(|source| Error::Io {
            path: dir.clone(),
            source,
        })?;
        let x = object.render_positions();
        let own = Drawn {
            stem: name.to_string(),
            rest: object.render_rest(),
            triangles: object.triangles(),
            splats: object
                .splats()
                .and_then(|b| Some((b, object.splat_frame(x.clone(), self.rotate_splat_sh)?))),
            stress: self.stress.then(|| object.render_stress()).transpose()?,
            x,
        };
        self.write_drawn(&dir, name, object.sim().time(), frame, own)?;
        for set in object.render_sets() {
            let x = set.positions(object.sim());
            let drawn = Drawn {
                stem: format!("{name}_{}", set.name()),
                rest: set.rest(),
                triangles: set.triangles(),
                splats: set.splats().and_then(|b| {
                    Some((
                        b,
                        set.splat_frame(object.sim(), x.clone(), self.rotate_splat_sh)?,
                    ))
                }),
                stress: self
                    .stress
                    .then(|| object.render_set_stress(set))
                    .transpose()?,
                x,
            };
            self.write_drawn(&dir, name, object.sim().time(), frame, drawn)?;
        }
        Ok(())
    }

    /// Write one frame of one drawn point set into `dir` (`<object>/`), in every format.
    fn write_drawn(
        &mut self,
        dir: &Path,
        object: &str,
        time: f64,
        frame: usize,
        d: Drawn<'_>,
    ) -> Result<()> {
        let stem = format!("{}_{frame:06}", d.stem);
        for f in self.formats.clone() {
            match f {
                Format::Vtk => {
                    let path = dir.join(format!("{stem}.vtp"));
                    let disp: Vec<[f64; 3]> =
                        d.x.iter()
                            .zip(d.rest)
                            .map(|(a, b)| [a[0] - b[0], a[1] - b[1], a[2] - b[2]])
                            .collect();
                    let stress = d.stress.as_deref().map(StressArrays::of);
                    let mut data = vec![PointData::Vector("displacement", &disp)];
                    if let Some(s) = &stress {
                        data.push(PointData::Tensor("stress", &s.tensor));
                        data.push(PointData::Vector("principal_stress", &s.principal));
                        data.push(PointData::Scalar("von_mises", &s.von_mises));
                    }
                    vtk::write_vtp(&path, &d.x, d.triangles, &data)?;
                    self.collection(&d.stem)
                        .push((time, format!("{object}/{stem}.vtp")));
                    self.files.push(path.display().to_string());
                }
                Format::Ply => {
                    let path = dir.join(format!("{stem}.ply"));
                    if let Some((base, moved)) = &d.splats {
                        crate::io::splat::write_splats_moved(&path, base, moved)?;
                        self.files.push(path.display().to_string());
                        continue;
                    }
                    crate::io::write_atomically(&path, |tmp| {
                        match d.triangles {
                            Some(t) => crate::io::ply::write_ply_mesh(
                                tmp,
                                &d.x,
                                t,
                                crate::io::ply::PlyWriteOptions::default(),
                            )?,
                            None => crate::io::ply::write_ply_points(tmp, &d.x, &[])?,
                        }
                        Ok(())
                    })?;
                    self.files.push(path.display().to_string());
                }
            }
        }
        Ok(())
    }

    /// The `.pvd` collection named `stem` (created empty on first use).
    fn collection(&mut self, stem: &str) -> &mut Vec<(f64, String)> {
        let i = match self.pvd.iter().position(|(s, _)| s == stem) {
            Some(i) => i,
            None => {
                self.pvd.push((stem.to_string(), Vec::new()));
                self.pvd.len() - 1
            }
        };
        &mut self.pvd[i].1
    }
}

/// One point set of one frame: an object's own render points or one of its render inputs.
struct Drawn<'a> {
    /// File stem: `<object>` or `<object>_<input>`.
    stem: String,
    rest: &'a [crate::Point3],
    x: Vec<crate::Point3>,
    triangles: Option<&'a [[u32; 3]]>,
    splats: Option<(&'a crate::io::splat::Splats, crate::io::splat::MovedSplats)>,
    stress: Option<Vec<crate::linalg3::Mat3>>,
}

/// The stress point arrays of one frame of one object, Pa.
struct StressArrays {
    tensor: Vec<[f64; 9]>,
    principal: Vec<[f64; 3]>,
    von_mises: Vec<f64>,
}

impl StressArrays {
    fn of(sigma: &[crate::linalg3::Mat3]) -> StressArrays {
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

impl FrameWriter {
    /// Write the surfaces of the colliders other than planes at their current poses into
    /// `<out>/colliders/<stem>_<frame:06>.vtp` (with the obstacle's `displacement` from its
    /// scene definition), collected in `<out>/<stem>.pvd`: ParaView and `freeform render`
    /// then draw the kinematic bodies with the objects. VTK only.
    fn write_colliders(&mut self, world: &World, frame: usize) -> Result<()> {
        if !self.formats.contains(&Format::Vtk) {
            return Ok(());
        }
        let poses = world.collider_poses();
        let kin = world.collider_kinematics();
        let dir = self.out.join("colliders");
        for (i, (obstacle, pose)) in kin.obstacles().iter().zip(&poses).enumerate() {
            let Some((rest, triangles)) = obstacle.surface() else {
                continue;
            };
            std::fs::create_dir_all(&dir).map_err(|source| Error::Io {
                path: dir.clone(),
                source,
            })?;
            let stem = collider_stem(i, world.colliders()[i].name.as_deref());
            let x: Vec<crate::Point3> = rest.iter().map(|p| pose.apply(p)).collect();
            let disp: Vec<[f64; 3]> = x
                .iter()
                .zip(&rest)
                .map(|(a, b)| [a[0] - b[0], a[1] - b[1], a[2] - b[2]])
                .collect();
            let file = format!("{stem}_{frame:06}.vtp");
            let path = dir.join(&file);
            vtk::write_vtp(
                &path,
                &x,
                Some(&triangles),
                &[PointData::Vector("displacement", &disp)],
            )?;
            self.collection(&stem)
                .push((world.time(), format!("colliders/{file}")));
            self.files.push(path.display().to_string());
        }
        Ok(())
    }
}

impl FrameObserver for FrameWriter {
    fn frame(&mut self, world: &World, frame: usize) -> Result<()> {
        for object in world.objects() {
            self.write_object(object, frame)?;
        }
        self.write_colliders(world, frame)?;
        self.frames += 1;
        if self.pvd_written.is_none_or(|t| t.elapsed() >= PVD_INTERVAL) {
            self.write_collections(world)?;
        }
        Ok(())
    }

    fn finish(&mut self, world: &World) -> Result<()> {
        for path in self.write_collections(world)? {
            self.files.push(path.display().to_string());
        }
        Ok(())
    }
}

impl FrameWriter {
    /// Write every `.pvd` collection as it stands (with VTK output); their paths.
    fn write_collections(&mut self, world: &World) -> Result<Vec<PathBuf>> {
        if !self.formats.contains(&Format::Vtk) {
            return Ok(Vec::new());
        }
        // Every object and render input gets its collection, even with no frames yet.
        for object in world.objects() {
            self.collection(object.name());
            for set in object.render_sets() {
                self.collection(&format!("{}_{}", object.name(), set.name()));
            }
        }
        let mut paths = Vec::new();
        for (stem, entries) in &self.pvd {
            let path = self.out.join(format!("{stem}.pvd"));
            vtk::write_pvd(&path, entries)?;
            paths.push(path);
        }
        self.pvd_written = Some(std::time::Instant::now());
        Ok(paths)
    }
}
