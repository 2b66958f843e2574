//! `freeform render`: PNG pictures of a run's frames (no ParaView needed), and the view
//! flags `freeform modes --png` shares.

use crate::{emit, CliResult};
use clap::{Args, ValueEnum};
use freeform::geometry::Aabb;
use freeform::io::splat::{is_splat_ply, read_splats};
use freeform::io::vtk::{read_pvd, read_vtp, VtpData};
use freeform::progress::{Progress, Silent, TerminalProgress};
use freeform::render::{
    disc_radius_from_spacing, draw, draw_colorbar, draw_text, Camera, CameraOptions, ColorMap,
    DrawOptions, Gaussians, Ground, Image, Item, Projection, Rect, Scalars,
};
use std::io::IsTerminal;
use std::path::{Path, PathBuf};

/// The up axis of the pictures.
#[derive(Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum Axis {
    X,
    Y,
    Z,
}

impl Axis {
    fn index(self) -> usize {
        match self {
            Axis::X => 0,
            Axis::Y => 1,
            Axis::Z => 2,
        }
    }
}

/// Camera flags (docs/pictures.md).
#[derive(Args, Clone)]
#[command(allow_negative_numbers = true)]
pub struct ViewArgs {
    /// Camera angle around the up axis, from the +z side towards +x (up y), degrees.
    #[arg(long, default_value_t = 30.0)]
    azimuth: f64,
    /// Camera angle above the horizontal plane, degrees (-89..89).
    #[arg(long, default_value_t = 20.0)]
    elevation: f64,
    /// The axis that points up in the picture.
    #[arg(long, value_enum, default_value = "y")]
    up: Axis,
    /// Perspective field of view across the shorter image side, degrees.
    #[arg(long, default_value_t = 30.0)]
    fov: f64,
    /// Orthographic (parallel) projection instead of perspective.
    #[arg(long)]
    ortho: bool,
    /// Magnification of the fitted view (2: twice as large, may crop).
    #[arg(long, default_value_t = 1.0)]
    zoom: f64,
}

impl ViewArgs {
    /// The camera options these flags ask for.
    pub fn options(&self) -> Result<CameraOptions, Box<dyn std::error::Error>> {
        for (flag, v) in [("--azimuth", self.azimuth), ("--elevation", self.elevation)] {
            if !v.is_finite() {
                return Err(format!("{flag} {v} is not a finite angle").into());
            }
        }
        if self.elevation.abs() >= 90.0 {
            return Err(format!(
                "--elevation {} must be between -90 and 90 (exclusive)",
                self.elevation
            )
            .into());
        }
        if !(self.fov > 0.0 && self.fov < 179.0) {
            return Err(format!("--fov {} must be between 0 and 179 degrees", self.fov).into());
        }
        if !(self.zoom > 0.0 && self.zoom.is_finite()) {
            return Err(format!("--zoom {} must be positive", self.zoom).into());
        }
        let mut up = [0.0; 3];
        up[self.up.index()] = 1.0;
        Ok(CameraOptions {
            azimuth_deg: self.azimuth,
            elevation_deg: self.elevation,
            up,
            projection: if self.ortho {
                Projection::Orthographic
            } else {
                Projection::Perspective { fov_deg: self.fov }
            },
            zoom: self.zoom,
            ..Default::default()
        })
    }

    /// The up axis, 0..3.
    pub fn up_axis(&self) -> usize {
        self.up.index()
    }
}

/// Parse `WxH` (each 16..=8192 pixels).
pub fn parse_size(s: &str, flag: &str) -> Result<(u32, u32), Box<dyn std::error::Error>> {
    let bad =
        || format!("{flag} {s}: expected WIDTHxHEIGHT in pixels, e.g. 800x600 (each 16..8192)");
    let (w, h) = s.split_once(['x', 'X']).ok_or_else(bad)?;
    let (w, h): (u32, u32) = (
        w.trim().parse().map_err(|_| bad())?,
        h.trim().parse().map_err(|_| bad())?,
    );
    if !(16..=8192).contains(&w) || !(16..=8192).contains(&h) {
        return Err(bad().into());
    }
    Ok((w, h))
}

#[derive(Args)]
#[command(allow_negative_numbers = true)]
pub struct RenderArgs {
    /// The output directory of `freeform run` (with <object>.pvd and <object>/*.vtp), or a
    /// USD stage (`run.usda`: its meshes, points and splats at each time code; docs/usd.md).
    pub dir: PathBuf,
    /// Draw only this object [default: every object of the run in one picture].
    #[arg(long)]
    pub object: Option<String>,
    /// Colour by `displacement` (its length, m), `none` (one colour per object; splats their
    /// own), `splat` (the same), or the name of any point array of the frames (vectors by
    /// their length) [default: splat objects their own colour, others displacement].
    #[arg(long)]
    pub color: Option<String>,
    /// Image size, WIDTHxHEIGHT pixels.
    #[arg(long, default_value = "800x600")]
    pub size: String,
    #[command(flatten)]
    pub view: ViewArgs,
    /// Draw a checkered ground at this height along the up axis, metres (e.g. 0 for
    /// examples/drop.toml's floor).
    #[arg(long)]
    pub ground: Option<f64>,
    /// Disc radius of point sets, metres [default: 0.6 x the median nearest-neighbour
    /// distance of the object's first frame].
    #[arg(long)]
    pub radius: Option<f64>,
    /// Render every N-th frame.
    #[arg(long, default_value_t = 1)]
    pub every: usize,
    /// Where to write frame_<n>.png [default: DIR/png; for a stage, its name with .png].
    #[arg(long)]
    pub out: Option<PathBuf>,
}

/// One object of the run: its name and frames (time, .vtp path).
struct Track {
    name: String,
    frames: Vec<(f64, PathBuf)>,
    /// Whether its frames have a 3DGS splat `.ply` next to each `.vtp` (drawn from it).
    splat: bool,
}

/// The 3DGS `.ply` written next to a `.vtp` frame.
fn splat_frame(vtp: &Path) -> PathBuf {
    vtp.with_extension("ply")
}

/// The objects of a run directory: every `<name>.pvd`, sorted by name (or the one asked for).
fn tracks(dir: &Path, object: Option<&str>) -> Result<Vec<Track>, Box<dyn std::error::Error>> {
    if !dir.is_dir() {
        return Err(format!(
            "{}: no such directory (give the --out directory of `freeform run`)",
            dir.display()
        )
        .into());
    }
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .map_err(|e| format!("{}: {e}", dir.display()))?
        .filter_map(|e| e.ok())
        .filter_map(|e| {
            let p = e.path();
            (p.extension().and_then(|x| x.to_str()) == Some("pvd"))
                .then(|| p.file_stem().and_then(|s| s.to_str()).map(str::to_string))
                .flatten()
        })
        .collect();
    names.sort();
    if names.is_empty() {
        return Err(format!(
            "{}: no .pvd files (expected the output of `freeform run SCENE --out {}` with VTK output)",
            dir.display(),
            dir.display()
        )
        .into());
    }
    if let Some(o) = object {
        if !names.iter().any(|n| n == o) {
            return Err(format!(
                "--object {o}: no {o}.pvd in {}; objects: {}",
                dir.display(),
                names.join(", ")
            )
            .into());
        }
        names.retain(|n| n == o);
    }
    names
        .into_iter()
        .map(|name| {
            let frames = read_pvd(&dir.join(format!("{name}.pvd")))?;
            // A splat object: its first frame has a 3DGS .ply beside the .vtp.
            let splat = match frames.first() {
                Some((_, vtp)) if splat_frame(vtp).is_file() => is_splat_ply(&splat_frame(vtp))?,
                _ => false,
            };
            Ok(Track {
                name,
                frames,
                splat,
            })
        })
        .collect()
}

/// What the frames are coloured by.
enum Colour {
    /// One colour per object; splats their own (SH degree 0) colours.
    None,
    /// A point array by name (vectors by length).
    Array(String),
}

/// What an object is coloured by for `--color` (None: the default).
fn colour_of(flag: Option<&str>, splat: bool) -> Colour {
    match flag {
        None if splat => Colour::None,
        None => Colour::Array("displacement".into()),
        Some("none" | "splat") => Colour::None,
        Some(name) => Colour::Array(name.to_string()),
    }
}

fn scalars_of(data: &VtpData, colour: &Colour, path: &Path) -> Result<Option<Vec<f64>>, String> {
    match colour {
        Colour::None => Ok(None),
        Colour::Array(name) => data.scalar(name).map(Some).ok_or_else(|| {
            let have: Vec<&str> = data.point_data.iter().map(|(n, _, _)| n.as_str()).collect();
            format!(
                "{}: no point array `{name}` to colour by (arrays: {}); use --color none or one of them",
                path.display(),
                if have.is_empty() { "none".to_string() } else { have.join(", ") }
            )
        }),
    }
}

pub fn grow(b: &mut Option<Aabb>, points: &[[f64; 3]]) {
    if let Some(pb) = Aabb::from_points(points) {
        *b = Some(match b.take() {
            None => pb,
            Some(o) => Aabb {
                min: [0, 1, 2].map(|k| o.min[k].min(pb.min[k])),
                max: [0, 1, 2].map(|k| o.max[k].max(pb.max[k])),
            },
        });
    }
}

/// Colours of objects drawn without scalars (cycled).
pub const OBJECT_COLOURS: [[u8; 3]; 4] = [
    [90, 140, 200],
    [220, 130, 60],
    [110, 180, 110],
    [190, 100, 170],
];
/// Width reserved right of the picture for the colour bar, pixels.
const BAR_WIDTH: u32 = 130;
pub const WHITE: [u8; 3] = [255, 255, 255];

pub fn run(args: RenderArgs) -> CliResult {
    let (w, h) = parse_size(&args.size, "--size")?;
    if args.every == 0 {
        return Err("--every must be at least 1".into());
    }
    if let Some(r) = args.radius {
        if !(r > 0.0 && r.is_finite()) {
            return Err(format!("--radius {r} must be a positive length in metres").into());
        }
    }
    let camera_options = args.view.options()?;
    let tracks = tracks(&args.dir, args.object.as_deref())?;
    let colours: Vec<Colour> = tracks
        .iter()
        .map(|t| colour_of(args.color.as_deref(), t.splat))
        .collect();
    // The one array any object is coloured by (for the range and the bar).
    let array = colours.iter().find_map(|c| match c {
        Colour::Array(name) => Some(name.clone()),
        Colour::None => None,
    });
    let count = tracks.iter().map(|t| t.frames.len()).max().unwrap_or(0);
    let selected: Vec<usize> = (0..count).step_by(args.every).collect();
    if selected.is_empty() {
        return Err(format!("{}: the .pvd files list no frames", args.dir.display()).into());
    }
    let bar = TerminalProgress::new();
    let progress: &dyn Progress = if std::io::stderr().is_terminal() {
        &bar
    } else {
        &Silent
    };
    let clock = std::time::Instant::now();
    // Pass 1: the bounds and the scalar range over every selected frame (a fixed camera and
    // colour scale), and each object's disc radius from its first frame.
    progress.begin("reading frames", Some(selected.len() as u64));
    let mut bounds: Option<Aabb> = None;
    let mut range = [f64::INFINITY, f64::NEG_INFINITY];
    let mut radii: Vec<Option<f64>> = vec![None; tracks.len()];
    for (done, &i) in selected.iter().enumerate() {
        for (k, t) in tracks.iter().enumerate() {
            let Some((_, path)) = t.frames.get(i) else {
                continue;
            };
            let data = read_vtp(path)?;
            grow(&mut bounds, &data.points);
            if let Some(s) = scalars_of(&data, &colours[k], path)? {
                for v in s.into_iter().filter(|v| v.is_finite()) {
                    range = [range[0].min(v), range[1].max(v)];
                }
            }
            if data.triangles.is_none() && !t.splat && radii[k].is_none() {
                radii[k] = Some(
                    args.radius
                        .unwrap_or_else(|| disc_radius_from_spacing(&data.points)),
                );
            }
        }
        progress.set_position(done as u64 + 1);
    }
    progress.finish();
    let Some(bounds) = bounds else {
        return Err(format!("{}: the frames hold no points", args.dir.display()).into());
    };
    let scalars = match &array {
        None => None,
        Some(name) => {
            // A length starts at 0; a signed array spans its own range.
            let lo = if name == "displacement" {
                0.0
            } else {
                range[0]
            };
            let hi = if range[1].is_finite() { range[1] } else { 0.0 };
            Some((
                Scalars {
                    map: ColorMap::Viridis,
                    range: [lo.min(hi), hi],
                },
                name.clone(),
            ))
        }
    };
    let camera = Camera::fit(&bounds, &camera_options);
    let ground = args
        .ground
        .map(|height| ground_below(&bounds, args.view.up_axis(), height));
    let out = args.out.clone().unwrap_or_else(|| args.dir.join("png"));
    std::fs::create_dir_all(&out).map_err(|e| format!("{}: {e}", out.display()))?;
    let view = Rect {
        x: 0,
        y: 0,
        width: if scalars.is_some() {
            w.saturating_sub(BAR_WIDTH).max(16)
        } else {
            w
        },
        height: h,
    };
    let options = DrawOptions {
        scalars: scalars.as_ref().map(|s| s.0),
        ground,
        ..Default::default()
    };
    // Pass 2: draw, frames in parallel (each is independent); batches of a few frames per
    // thread let the progress bar move.
    progress.begin("rendering", Some(selected.len() as u64));
    let frame = FrameJob {
        tracks: &tracks,
        colours: &colours,
        radii: &radii,
        camera: &camera,
        view,
        options: &options,
        scalars: scalars.as_ref(),
        size: (w, h),
        out: &out,
    };
    let batch = 4 * rayon::current_num_threads();
    for (done, chunk) in selected.chunks(batch).enumerate() {
        use rayon::prelude::*;
        chunk
            .par_iter()
            .try_for_each(|&i| frame.render(i))
            .map_err(|e| -> Box<dyn std::error::Error> { e })?;
        progress.set_position(((done + 1) * batch).min(selected.len()) as u64);
    }
    progress.finish();
    let secs = clock.elapsed().as_secs_f64();
    let names: Vec<String> = tracks
        .iter()
        .map(|t| {
            if t.splat {
                format!("{} (splats as ellipses)", t.name)
            } else {
                t.name.clone()
            }
        })
        .collect();
    emit(&format!(
        "freeform render {}\n  objects {}  frames {} of {}  size {w}x{h}\n  time {secs:.2} s ({:.1} ms per frame, reading included)\n  written to {}/frame_<n>.png\n",
        args.dir.display(),
        names.join(", "),
        selected.len(),
        count,
        1e3 * secs / selected.len() as f64,
        out.display()
    ))?;
    Ok(())
}

/// A ground square at `height` along `axis`, spanning the bounds across it with a half
/// size of margin, tiles about a tenth of its larger side.
pub fn ground_below(bounds: &Aabb, axis: usize, height: f64) -> Ground {
    let others: Vec<usize> = (0..3).filter(|&k| k != axis).collect();
    let span = others
        .iter()
        .map(|&k| bounds.max[k] - bounds.min[k])
        .fold(0.0, f64::max)
        .max(1e-9)
        * 0.75;
    let extent = [others[0], others[1]].map(|k| {
        let c = 0.5 * (bounds.min[k] + bounds.max[k]);
        [c - span, c + span]
    });
    // A round tile: 1, 2 or 5 times a power of ten near a tenth of the square's side.
    let target = 0.2 * span;
    let p = 10f64.powf(target.log10().floor());
    let tile = [1.0, 2.0, 5.0, 10.0]
        .into_iter()
        .map(|m| m * p)
        .find(|&t| t >= target)
        .unwrap_or(target);
    Ground {
        axis,
        height,
        extent,
        tile,
    }
}

/// `freeform modes --png`: the first `count` non-constant modes' weights on the shape, one
/// tile of `tile` pixels each (three per row), blue (negative) to red (positive), each mode
/// scaled to its largest |W_j|. Meshes are drawn by their triangles, point clouds and
/// What `freeform modes --png` draws: how many modes, each tile's size (pixels) and whether a
/// last tile shows the kernel density.
pub struct ModesLayout {
    /// Non-constant modes drawn.
    pub count: usize,
    /// Tile width and height, pixels.
    pub tile: (u32, u32),
    /// Add the kernels coloured by support radius.
    pub density_tile: bool,
}

/// primitives as discs at `points` (a primitive's integration points, N x 3, metres).
pub fn modes_png(
    path: &Path,
    shape: &freeform::geometry::Shape,
    basis: &freeform::precompute::skinning::Basis,
    points: &[[f64; 3]],
    layout: ModesLayout,
    view: &ViewArgs,
) -> CliResult {
    use freeform::geometry::Shape;
    let ModesLayout {
        count,
        tile,
        density_tile,
    } = layout;
    let camera_options = view.options()?;
    let (positions, triangles): (&[[f64; 3]], Option<&[[u32; 3]]>) = match shape {
        Shape::Mesh(m) => (m.vertices(), Some(m.triangles())),
        Shape::PointCloud(c) => (c.points(), None),
        Shape::Box { .. } | Shape::Sphere { .. } | Shape::Image(_) => (points, None),
    };
    let modes = basis.modes();
    let count = count.min(modes.saturating_sub(1));
    if count == 0 {
        return Err(
            "--png needs at least one non-constant mode (--modes >= 1, --png-modes >= 1)".into(),
        );
    }
    let weights = basis.weights(positions)?;
    let bounds = Aabb::from_points(positions).unwrap_or_else(|| shape.bounding_box());
    let camera = Camera::fit(&bounds, &camera_options);
    let radius = disc_radius_from_spacing(positions);
    let tiles = count + usize::from(density_tile);
    let cols = tiles.min(3) as u32;
    let rows = tiles.div_ceil(3) as u32;
    let footer = 28;
    let (tw, th) = tile;
    let mut image = Image::new(cols * tw, rows * th + footer, WHITE);
    for k in 0..count {
        let j = k + 1;
        let w: Vec<f64> = (0..positions.len())
            .map(|i| weights.values[i * modes + j])
            .collect();
        let a = w.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        let options = DrawOptions {
            scalars: Some(Scalars {
                map: ColorMap::CoolWarm,
                range: [-a, a],
            }),
            ..Default::default()
        };
        let item = match triangles {
            Some(t) => Item::Triangles {
                positions,
                triangles: t,
                scalars: Some(&w),
                colour: [0; 3],
            },
            None => Item::Points {
                positions,
                radius,
                scalars: Some(&w),
                colour: [0; 3],
            },
        };
        let rect = Rect {
            x: (k as u32 % 3) * tw,
            y: (k as u32 / 3) * th,
            width: tw,
            height: th,
        };
        draw(&mut image, rect, &camera, &[item], &options)?;
        let ev = basis.eigenvalues.get(j).copied().unwrap_or(f64::NAN);
        draw_text(
            &mut image,
            rect.x as i32 + 8,
            rect.y as i32 + 6,
            14.0,
            [0, 0, 0],
            &format!("mode {j}   \u{3bb} = {ev:.3e} Pa/m\u{b2}"),
        )?;
    }
    if density_tile {
        let rect = Rect {
            x: (count as u32 % 3) * tw,
            y: (count as u32 / 3) * th,
            width: tw,
            height: th,
        };
        kernel_spacing_tile(&mut image, rect, &camera, &basis.kernels)?;
    }
    draw_text(
        &mut image,
        8,
        (rows * th + 6) as i32,
        13.0,
        [60, 60, 60],
        "skinning weight of each mode: blue < 0 < red, each scaled to its largest magnitude",
    )?;
    image.write_png(path)?;
    Ok(())
}

/// The kernel density as the kernels' support radii (metres) at their centres: small (dark)
/// where the density placed them close together.
fn kernel_spacing_tile(
    image: &mut Image,
    rect: Rect,
    camera: &Camera,
    kernels: &freeform::precompute::rkpm::Kernels,
) -> CliResult {
    let (lo, hi) = kernels
        .radii
        .iter()
        .fold((f64::INFINITY, 0.0f64), |(lo, hi), &a| {
            (lo.min(a), hi.max(a))
        });
    let options = DrawOptions {
        scalars: Some(Scalars {
            map: ColorMap::Viridis,
            range: [lo, hi.max(lo * (1.0 + 1e-12))],
        }),
        ..Default::default()
    };
    let item = Item::Points {
        positions: &kernels.centers,
        // Half the usual disc, so the close-packed refined kernels stay apart.
        radius: 0.5 * disc_radius_from_spacing(&kernels.centers),
        scalars: Some(&kernels.radii),
        colour: [0; 3],
    };
    draw(image, rect, camera, &[item], &options)?;
    draw_text(
        image,
        rect.x as i32 + 8,
        rect.y as i32 + 6,
        14.0,
        [0, 0, 0],
        &format!("kernels by support radius: {lo:.3} (dark) .. {hi:.3} m"),
    )?;
    Ok(())
}

/// What drawing one frame needs: shared by the threads that draw frames in parallel.
struct FrameJob<'a> {
    tracks: &'a [Track],
    colours: &'a [Colour],
    radii: &'a [Option<f64>],
    camera: &'a Camera,
    view: Rect,
    options: &'a DrawOptions,
    scalars: Option<&'a (Scalars, String)>,
    size: (u32, u32),
    out: &'a Path,
}

impl FrameJob<'_> {
    /// Read, draw and write frame `i` (`frame_<i>.png`).
    fn render(&self, i: usize) -> Result<(), Box<dyn std::error::Error + Send + Sync>> {
        let FrameJob {
            tracks,
            colours,
            radii,
            camera,
            view,
            options,
            scalars,
            size: (w, h),
            out,
        } = *self;
        let mut frames = Vec::new();
        let mut time = None;
        for (k, t) in tracks.iter().enumerate() {
            let Some((at, path)) = t.frames.get(i) else {
                continue;
            };
            let data = read_vtp(path)?;
            let s = scalars_of(&data, &colours[k], path)?;
            let gaussians = if t.splat {
                let ply = splat_frame(path);
                let splats = read_splats(&ply)?;
                if s.as_ref().is_some_and(|s| s.len() != splats.len()) {
                    return Err(format!(
                        "{}: {} splats, but {} has {} points to colour them by",
                        ply.display(),
                        splats.len(),
                        path.display(),
                        data.points.len()
                    )
                    .into());
                }
                Some(Gaussians::from_splats(&splats))
            } else {
                None
            };
            time.get_or_insert(*at);
            frames.push((k, data, s, gaussians));
        }
        let items: Vec<Item> = frames
            .iter()
            .map(
                |(k, data, s, gaussians)| match (&data.triangles, gaussians) {
                    (_, Some(g)) => Item::Splats {
                        gaussians: g,
                        scalars: s.as_deref(),
                    },
                    (Some(tris), None) => Item::Triangles {
                        positions: &data.points,
                        triangles: tris,
                        scalars: s.as_deref(),
                        colour: OBJECT_COLOURS[k % OBJECT_COLOURS.len()],
                    },
                    (None, None) => Item::Points {
                        positions: &data.points,
                        radius: radii[*k].unwrap_or(0.01),
                        scalars: s.as_deref(),
                        colour: OBJECT_COLOURS[k % OBJECT_COLOURS.len()],
                    },
                },
            )
            .collect();
        let mut image = Image::new(w, h, WHITE);
        draw(&mut image, view, camera, &items, options)?;
        if let Some((s, name)) = &scalars {
            let label = if name == "displacement" {
                "|displacement| (m)".to_string()
            } else {
                name.clone()
            };
            let bar_rect = Rect {
                x: view.width + 6,
                y: h / 6,
                width: BAR_WIDTH - 6,
                height: h * 2 / 3,
            };
            draw_colorbar(&mut image, bar_rect, s.map, s.range, &label)?;
        }
        draw_text(
            &mut image,
            10,
            8,
            16.0,
            [0, 0, 0],
            &format!("t = {:.3} s", time.unwrap_or(0.0)),
        )?;
        image.write_png(&out.join(format!("frame_{i:06}.png")))?;
        Ok(())
    }
}
