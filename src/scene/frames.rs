//! Frame output as observers of a [`World`]: [`FrameWriter`] writes VTK (`.vtp` per frame
//! and a `.pvd` collection per object, for ParaView), PLY files (3DGS splat PLY for splat
//! objects) and one USD stage for the run ([`super::usd_frames`]).

use super::object::SceneObject;
use super::spec::{collider_stem, Format};
use super::stress_arrays::StressArrays;
use super::usd_frames::{UsdDrawn, UsdFrameWriter};
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
    /// The run's USD stage, with [`Format::Usd`].
    usd: Option<UsdFrameWriter>,
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
            usd: formats
                .contains(&Format::Usd)
                .then(|| UsdFrameWriter::new(out, true)),
        })
    }

    /// Write Kaolin's physics schemas (materials, skinning weights) on each object's prim of
    /// the USD stage (default true; the scene's `output.usd_physics`). No effect without USD.
    #[must_use]
    pub fn usd_physics(mut self, on: bool) -> FrameWriter {
        if let Some(u) = self.usd.as_mut() {
            *u = UsdFrameWriter::new(&self.out, on);
        }
        self
    }

    /// Whether any per-object files (VTK, PLY) are written.
    fn per_object_files(&self) -> bool {
        self.formats
            .iter()
            .any(|f| matches!(f, Format::Vtk | Format::Ply))
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
    fn write_object(&mut self, index: usize, object: &SceneObject, frame: usize) -> Result<()> {
        let name = object.name();
        let dir = self.out.join(name);
        if self.per_object_files() {
            std::fs::create_dir_all(&dir).map_err(|source| Error::Io {
                path: dir.clone(),
                source,
            })?;
        }
        let x = object.render_positions();
        let own = Drawn {
            stem: name.to_string(),
            rest: object.render_rest(),
            triangles: object.triangles(),
            splats: object
                .splats()
                .and_then(|b| Some((b, object.splat_frame(x.clone(), self.rotate_splat_sh)?))),
            stress: self
                .stress
                .then(|| object.render_stress().map(|s| StressArrays::of(&s)))
                .transpose()?,
            x,
        };
        self.usd_drawn(index, 0, frame, &own);
        self.write_drawn(&dir, name, object.sim().time(), frame, own)?;
        for (k, set) in object.render_sets().iter().enumerate() {
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
                    .then(|| object.render_set_stress(set).map(|s| StressArrays::of(&s)))
                    .transpose()?,
                x,
            };
            self.usd_drawn(index, k + 1, frame, &drawn);
            self.write_drawn(&dir, name, object.sim().time(), frame, drawn)?;
        }
        Ok(())
    }

    /// Hand one drawn set to the USD stage, if one is written.
    fn usd_drawn(&mut self, object: usize, set: usize, frame: usize, d: &Drawn<'_>) {
        if let Some(u) = self.usd.as_mut() {
            u.drawn(
                object,
                set,
                frame,
                UsdDrawn {
                    x: &d.x,
                    splats: d.splats.as_ref().map(|(b, m)| (*b, m)),
                    stress: d.stress.as_ref(),
                },
            );
        }
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
                Format::Usd => {}
                Format::Vtk => {
                    let path = dir.join(format!("{stem}.vtp"));
                    let disp: Vec<[f64; 3]> =
                        d.x.iter()
                            .zip(d.rest)
                            .map(|(a, b)| [a[0] - b[0], a[1] - b[1], a[2] - b[2]])
                            .collect();
                    let mut data = vec![PointData::Vector("displacement", &disp)];
                    if let Some(s) = &d.stress {
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
    stress: Option<StressArrays>,
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
        if let Some(u) = self.usd.as_mut() {
            u.begin_frame(world)?;
        }
        for (i, object) in world.objects().iter().enumerate() {
            self.write_object(i, object, frame)?;
        }
        if let Some(u) = self.usd.as_mut() {
            u.end_frame(world, frame);
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
        if let Some(path) = self
            .usd
            .as_mut()
            .map(UsdFrameWriter::finish)
            .transpose()?
            .flatten()
        {
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
