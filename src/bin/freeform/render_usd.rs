//! `freeform render run.usda`: PNG pictures of a USD stage's point-based prims, frame by frame
//! (its meshes, points and Gaussian splats at each time code; docs/usd.md).

use crate::render::{ground_below, parse_size, RenderArgs, OBJECT_COLOURS, WHITE};
use crate::{emit, CliResult};
use freeform::geometry::{Aabb, UpAxis};
use freeform::io::usd::{UsdPrimKind, UsdStage};
use freeform::render::{
    disc_radius_from_spacing, draw, draw_text, Camera, DrawOptions, Gaussians, Image, Item, Rect,
    SH_C0,
};
use std::path::Path;

/// Whether `path` names a USD stage (by its extension).
pub fn is_usd(path: &Path) -> bool {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    matches!(ext.as_deref(), Some("usd" | "usda" | "usdc" | "usdz"))
}

/// One prim of one frame, read.
enum Drawn {
    Geometry {
        points: Vec<[f64; 3]>,
        triangles: Option<Vec<[u32; 3]>>,
    },
    Splats(Gaussians),
}

fn read_frame(
    stage: &UsdStage,
    prims: &[(String, UsdPrimKind)],
    time: Option<f64>,
    up: UpAxis,
) -> Result<Vec<Drawn>, Box<dyn std::error::Error>> {
    let mut out = Vec::new();
    for (prim, kind) in prims {
        if *kind == UsdPrimKind::GaussianSplats {
            let s = stage.splats(prim, time, up)?;
            out.push(Drawn::Splats(Gaussians {
                colours: s
                    .sh_dc
                    .iter()
                    .map(|dc| dc.map(|c| (0.5 + SH_C0 * c).clamp(0.0, 1.0)))
                    .collect(),
                means: s.means,
                covariances: s.covariances,
                opacities: s.opacities,
            }));
        } else {
            let g = stage.geometry(Some(prim), time, up)?;
            out.push(Drawn::Geometry {
                points: g.points,
                triangles: g.triangles,
            });
        }
    }
    Ok(out)
}

/// Draw every `--every`-th time code of the stage at `args.dir` into `frame_<n>.png`: meshes
/// shaded in one colour per prim, points as discs, splats as ellipses (their own colours).
pub fn run(args: &RenderArgs) -> CliResult {
    let stage = args.dir.as_path();
    let (w, h) = parse_size(&args.size, "--size")?;
    let opened = UsdStage::open(stage)?;
    // The stage is read into the picture's up axis (`--up z` keeps a Z-up run as it is; x
    // has no USD counterpart and reads Y-up).
    let up = if args.view.up_axis() == 2 {
        UpAxis::Z
    } else {
        UpAxis::Y
    };
    let frames = opened.frames()?;
    let prims: Vec<(String, UsdPrimKind)> = frames
        .prims
        .iter()
        .filter(|(p, _)| args.object.as_deref().is_none_or(|o| p.contains(o)))
        .cloned()
        .collect();
    if prims.is_empty() {
        return Err(format!("{}: no mesh, points or splat prim to draw", stage.display()).into());
    }
    let times: Vec<Option<f64>> = if frames.times.is_empty() {
        vec![None]
    } else {
        frames
            .times
            .iter()
            .step_by(args.every.max(1))
            .map(|&t| Some(t))
            .collect()
    };
    let clock = std::time::Instant::now();
    // The bounds over every selected frame (a fixed camera), each points prim's disc radius
    // from its first frame.
    let mut bounds: Option<Aabb> = None;
    let mut radii: Vec<Option<f64>> = vec![None; prims.len()];
    for &t in &times {
        for (k, d) in read_frame(&opened, &prims, t, up)?.iter().enumerate() {
            let points = match d {
                Drawn::Geometry { points, triangles } => {
                    if triangles.is_none() && radii[k].is_none() {
                        radii[k] = Some(
                            args.radius
                                .unwrap_or_else(|| disc_radius_from_spacing(points)),
                        );
                    }
                    points
                }
                Drawn::Splats(g) => &g.means,
            };
            crate::render::grow(&mut bounds, points);
        }
    }
    let Some(bounds) = bounds else {
        return Err(format!("{}: the prims hold no points", stage.display()).into());
    };
    let camera = Camera::fit(&bounds, &args.view.options()?);
    let options = DrawOptions {
        ground: args
            .ground
            .map(|height| ground_below(&bounds, args.view.up_axis(), height)),
        ..Default::default()
    };
    let out = args
        .out
        .clone()
        .unwrap_or_else(|| stage.with_extension("png"));
    std::fs::create_dir_all(&out).map_err(|e| format!("{}: {e}", out.display()))?;
    let view = Rect {
        x: 0,
        y: 0,
        width: w,
        height: h,
    };
    for (i, &t) in times.iter().enumerate() {
        let drawn = read_frame(&opened, &prims, t, up)?;
        let items: Vec<Item> = drawn
            .iter()
            .enumerate()
            .map(|(k, d)| match d {
                Drawn::Splats(g) => Item::Splats {
                    gaussians: g,
                    scalars: None,
                },
                Drawn::Geometry {
                    points,
                    triangles: Some(t),
                } => Item::Triangles {
                    positions: points,
                    triangles: t,
                    scalars: None,
                    colour: OBJECT_COLOURS[k % OBJECT_COLOURS.len()],
                },
                Drawn::Geometry { points, .. } => Item::Points {
                    positions: points,
                    radius: radii[k].unwrap_or(0.01),
                    scalars: None,
                    colour: OBJECT_COLOURS[k % OBJECT_COLOURS.len()],
                },
            })
            .collect();
        let mut image = Image::new(w, h, WHITE);
        draw(&mut image, view, &camera, &items, &options)?;
        let seconds = t.unwrap_or(0.0) / frames.time_codes_per_second;
        draw_text(
            &mut image,
            10,
            8,
            16.0,
            [0, 0, 0],
            &format!("t = {seconds:.3} s"),
        )?;
        image.write_png(&out.join(format!("frame_{i:06}.png")))?;
    }
    let secs = clock.elapsed().as_secs_f64();
    emit(&format!(
        "freeform render {}\n  prims {}  frames {}  size {w}x{h}\n  time {secs:.2} s ({:.1} ms per frame, reading included)\n  written to {}/frame_<n>.png\n",
        stage.display(),
        prims.iter().map(|(p, _)| p.as_str()).collect::<Vec<_>>().join(", "),
        times.len(),
        1e3 * secs / times.len() as f64,
        out.display()
    ))?;
    Ok(())
}
