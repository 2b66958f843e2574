//! Frame output as observers of a [`World`]: [`FrameWriter`] writes VTK (`.vtp` per frame
//! and a `.pvd` collection per object, for ParaView) and PLY files (3DGS splat PLY for splat
//! objects).

use super::spec::Format;
use super::world::{SceneObject, World};
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
/// `<object>_<frame:06>.vtp` (VTK PolyData with the displacement) and/or `.ply`, and at the
/// end `<out>/<object>.pvd` collections of the VTK frames with their times.
#[derive(Debug)]
pub struct FrameWriter {
    out: PathBuf,
    formats: Vec<Format>,
    /// Per object: (time, relative file) of each VTK frame.
    pvd: Vec<Vec<(f64, String)>>,
    files: Vec<String>,
    frames: usize,
    rotate_splat_sh: bool,
    stress: bool,
}

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

    /// Write one frame of one object.
    fn write_object(&mut self, index: usize, object: &SceneObject, frame: usize) -> Result<()> {
        let name = object.name();
        let dir = self.out.join(name);
        std::fs::create_dir_all(&dir).map_err(|source| Error::Io {
            path: dir.clone(),
            source,
        })?;
        let rest = object.render_rest();
        let x = object.render_positions();
        let disp: Vec<[f64; 3]> = x
            .iter()
            .zip(rest)
            .map(|(a, b)| [a[0] - b[0], a[1] - b[1], a[2] - b[2]])
            .collect();
        let stem = format!("{name}_{frame:06}");
        if self.pvd.len() <= index {
            self.pvd.resize_with(index + 1, Vec::new);
        }
        for f in &self.formats {
            match f {
                Format::Vtk => {
                    let path = dir.join(format!("{stem}.vtp"));
                    let stress = match self.stress {
                        true => Some(StressArrays::of(object)?),
                        false => None,
                    };
                    let mut data = vec![PointData::Vector("displacement", &disp)];
                    if let Some(s) = &stress {
                        data.push(PointData::Tensor("stress", &s.tensor));
                        data.push(PointData::Vector("principal_stress", &s.principal));
                        data.push(PointData::Scalar("von_mises", &s.von_mises));
                    }
                    vtk::write_vtp(&path, &x, object.triangles(), &data)?;
                    self.pvd[index].push((object.sim().time, format!("{name}/{stem}.vtp")));
                    self.files.push(path.display().to_string());
                }
                Format::Ply => {
                    let path = dir.join(format!("{stem}.ply"));
                    if let (Some(base), Some(moved)) = (
                        object.splats(),
                        object.splat_frame(x.clone(), self.rotate_splat_sh),
                    ) {
                        crate::io::splat::write_splats_moved(&path, base, &moved)?;
                        self.files.push(path.display().to_string());
                        continue;
                    }
                    crate::io::write_atomically(&path, |tmp| {
                        match object.triangles() {
                            Some(t) => crate::io::ply::write_ply_mesh(
                                tmp,
                                &x,
                                t,
                                crate::io::ply::PlyWriteOptions::default(),
                            )?,
                            None => crate::io::ply::write_ply_points(tmp, &x, &[])?,
                        }
                        Ok(())
                    })?;
                    self.files.push(path.display().to_string());
                }
            }
        }
        Ok(())
    }
}

/// The stress point arrays of one frame of one object, Pa.
struct StressArrays {
    tensor: Vec<[f64; 9]>,
    principal: Vec<[f64; 3]>,
    von_mises: Vec<f64>,
}

impl StressArrays {
    fn of(object: &SceneObject) -> Result<StressArrays> {
        let sigma = object.render_stress()?;
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
        Ok(StressArrays {
            tensor: sigma
                .iter()
                .map(|s| std::array::from_fn(|k| s[k / 3][k % 3]))
                .collect(),
            principal,
            von_mises,
        })
    }
}

impl FrameObserver for FrameWriter {
    fn frame(&mut self, world: &World, frame: usize) -> Result<()> {
        for (index, object) in world.objects().iter().enumerate() {
            self.write_object(index, object, frame)?;
        }
        self.frames += 1;
        Ok(())
    }

    fn finish(&mut self, world: &World) -> Result<()> {
        if self.formats.contains(&Format::Vtk) {
            for (index, object) in world.objects().iter().enumerate() {
                let path = self.out.join(format!("{}.pvd", object.name()));
                let entries = self.pvd.get(index).map(Vec::as_slice).unwrap_or(&[]);
                vtk::write_pvd(&path, entries)?;
                self.files.push(path.display().to_string());
            }
        }
        Ok(())
    }
}
