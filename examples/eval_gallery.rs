//! One contact sheet of the real-shape evaluation (docs/evaluation.md): per shape, its
//! normalized surface at rest and at the end of each test (t = steps * dt) as the FEM
//! reference moves it, coloured by displacement. The references come from the cache that
//! `freeform eval` filled (same defaults: TetGen `-pYq1.414a1e-3`, P2); a missing one is
//! computed, which is slow. Prints each test's largest displacement over the run (/ D, the
//! bounding-box diagonal, as the error metric).
//!
//! ```sh
//! cargo run --release --example eval_gallery -- /work/shapes anchor,pinion,rotor \
//!     .freeform-cache/fem docs/img/eval_gallery.png
//! ```

use freeform::benchmark::shapes::protocol::{gravity_axis, normalize, Protocol, ShapeTest};
use freeform::benchmark::shapes::reference::run_shape_reference;
use freeform::benchmark::shapes::tetgen::{tetrahedralize, TetgenOptions};
use freeform::fem::solver::FemParams;
use freeform::fem::ElementOrder;
use freeform::geometry::{Aabb, Shape, ShapeOptions};
use freeform::render::{
    draw, draw_colorbar, draw_text, Camera, CameraOptions, ColorMap, DrawOptions, Image, Item,
    Rect, Scalars,
};
use freeform::Point3;
use std::collections::HashMap;
use std::path::Path;

/// Panel size, pixels; two shapes (4 panels each) per row.
const PANEL: u32 = 150;
const PER_ROW: u32 = 2;
/// Displacement colour range, metres (of the unit-size shapes).
const RANGE: [f64; 2] = [0.0, 0.3];

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let [_, dir, names, cache, out] = args.as_slice() else {
        return Err("usage: eval_gallery SHAPES_DIR NAME,NAME,... CACHE_DIR OUT.png".into());
    };
    let names: Vec<&str> = names.split(',').collect();
    let protocol = Protocol::default();
    let fem = FemParams {
        order: ElementOrder::Quadratic,
        ..FemParams::default()
    };
    let work = std::env::temp_dir().join(format!("eval_gallery_{}", std::process::id()));
    let label_h = 18;
    let tile_w = 4 * PANEL;
    let tile_h = PANEL + label_h;
    let rows = (names.len() as u32).div_ceil(PER_ROW);
    let bar_w = 90;
    let mut image = Image::new(PER_ROW * tile_w + bar_w, rows * tile_h, [255, 255, 255]);
    for (i, name) in names.iter().enumerate() {
        let path = Path::new(dir).join(format!("{name}.off"));
        let Shape::Mesh(m) =
            freeform::io::read_shape(&path.to_string_lossy(), &ShapeOptions::default())?
        else {
            return Err(format!("{name}: not a triangle mesh").into());
        };
        let shape = normalize(m.vertices(), m.triangles())?;
        let tets = tetrahedralize(
            &shape.vertices,
            &shape.triangles,
            &TetgenOptions::default(),
            &work,
            name,
        )?;
        let mut frames: Vec<(String, Vec<Point3>)> = Vec::new();
        let mut node_of: Option<Vec<usize>> = None;
        for test in ShapeTest::ALL {
            let r = run_shape_reference(
                &tets,
                &protocol,
                &shape,
                test,
                &[],
                &fem,
                Some(Path::new(cache)),
                &freeform::progress::Silent,
            )?;
            // The largest displacement over the run, for reading the error metric (/ D).
            let d = Aabb::from_points(&r.rest).map_or(1.0, |b| b.diagonal());
            let umax = r
                .frames
                .iter()
                .flat_map(|f| f.iter().zip(&r.rest))
                .map(|(a, b)| ((0..3).map(|k| (a[k] - b[k]).powi(2)).sum::<f64>()).sqrt())
                .fold(0.0, f64::max);
            println!(
                "{name} {}: max |u| / D = {:.3e} ({:?})",
                test.name(),
                umax / d,
                r.cache
            );
            let map = match &node_of {
                Some(m) => m.clone(),
                None => {
                    let m = surface_nodes(&shape.vertices, &r.rest)?;
                    node_of = Some(m.clone());
                    m
                }
            };
            let last = r.frames.last().ok_or("empty reference")?;
            frames.push((
                test.name().replace('_', " "),
                map.iter().map(|&k| last[k]).collect(),
            ));
        }
        // One camera for the four panels of a shape: rest and deformed all fit.
        let mut all = shape.vertices.clone();
        for (_, f) in &frames {
            all.extend_from_slice(f);
        }
        let bounds = Aabb::from_points(&all).ok_or("no points")?;
        let mut up = [0.0; 3];
        up[gravity_axis(shape.longest_axis)] = 1.0;
        let camera = Camera::fit(
            &bounds,
            &CameraOptions {
                up,
                ..CameraOptions::default()
            },
        );
        let (tx, ty) = ((i as u32 % PER_ROW) * tile_w, (i as u32 / PER_ROW) * tile_h);
        let panels = std::iter::once(("rest".to_string(), shape.vertices.clone())).chain(frames);
        for (p, (label, pos)) in panels.enumerate() {
            let disp: Vec<f64> = pos
                .iter()
                .zip(&shape.vertices)
                .map(|(a, b)| ((0..3).map(|d| (a[d] - b[d]).powi(2)).sum::<f64>()).sqrt())
                .collect();
            let rect = Rect {
                x: tx + p as u32 * PANEL,
                y: ty + label_h,
                width: PANEL,
                height: PANEL,
            };
            draw(
                &mut image,
                rect,
                &camera,
                &[Item::Triangles {
                    positions: &pos,
                    triangles: &shape.triangles,
                    scalars: (p > 0).then_some(disp.as_slice()),
                    colour: [190, 190, 190],
                }],
                &DrawOptions {
                    scalars: Some(Scalars {
                        map: ColorMap::Viridis,
                        range: RANGE,
                    }),
                    ..DrawOptions::default()
                },
            )?;
            let text = if p == 0 { name.to_string() } else { label };
            draw_text(
                &mut image,
                rect.x as i32 + 4,
                ty as i32 + 2,
                13.0,
                [0, 0, 0],
                &text,
            )?;
        }
    }
    draw_colorbar(
        &mut image,
        Rect {
            x: PER_ROW * tile_w + 10,
            y: 10,
            width: bar_w - 14,
            height: 260.min(rows * tile_h - 10),
        },
        ColorMap::Viridis,
        RANGE,
        "|u| m",
    )?;
    image.write_png(Path::new(out))?;
    println!("{out}: {} shapes", names.len());
    Ok(())
}

/// For each surface vertex, the FE node at the same rest position (TetGen's `-Y` keeps every
/// surface vertex as a mesh node).
fn surface_nodes(
    surface: &[Point3],
    rest: &[Point3],
) -> Result<Vec<usize>, Box<dyn std::error::Error>> {
    let q = |p: &Point3| p.map(|c| (c * 1e9).round() as i64);
    let index: HashMap<[i64; 3], usize> = rest.iter().enumerate().map(|(i, p)| (q(p), i)).collect();
    surface
        .iter()
        .map(|p| {
            index
                .get(&q(p))
                .copied()
                .ok_or_else(|| format!("surface vertex {p:?} is not a FE node").into())
        })
        .collect()
}
