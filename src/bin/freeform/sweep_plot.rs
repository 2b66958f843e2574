//! The plots of `freeform sweep`: normalized MSE against precompute time and against step
//! time (every run, the Pareto front joined), and against K (the grid's curves, one per
//! density and m, with the paper's Table 1 where the protocol matches).

use freeform::benchmark::pareto::front_by_cost;
use freeform::benchmark::sweep::{paper_table1, KernelCurve, SweepAxis, SweepReport, SweepRow};
use freeform::precompute::sampling::Resolution;
use plotters::element::{DashedPathElement, Drawable, PointCollection};
use plotters::prelude::*;
use plotters_backend::{BackendCoord, DrawingErrorKind};
use std::path::Path;

type PlotResult<T> = Result<T, Box<dyn std::error::Error>>;

const WIDTH: u32 = 1100;
const HEIGHT: u32 = 760;
/// The embedded DejaVu Sans, registered by the library's renderer.
const FONT: &str = freeform::render::FONT_FAMILY;
/// Colours by m (the first 10 of a common categorical palette), cycled.
const COLOURS: [(u8, u8, u8); 10] = [
    (31, 119, 180),
    (255, 127, 14),
    (44, 160, 44),
    (214, 39, 40),
    (148, 103, 189),
    (140, 86, 75),
    (227, 119, 194),
    (127, 127, 127),
    (188, 189, 34),
    (23, 190, 207),
];

/// Which cost goes on the x axis.
#[derive(Clone, Copy)]
pub enum Cost {
    /// Basis + model setup, s.
    Precompute,
    /// Mean reduced step, ms.
    Step,
}

impl Cost {
    fn of(self, r: &SweepRow) -> f64 {
        match self {
            Cost::Precompute => r.result.precompute_s,
            Cost::Step => r.result.reduced_step_ms_mean,
        }
    }
    fn on_front(self, r: &SweepRow) -> bool {
        match self {
            Cost::Precompute => r.pareto_precompute,
            Cost::Step => r.pareto_step,
        }
    }
    fn label(self) -> &'static str {
        match self {
            Cost::Precompute => "precompute time: basis + model setup (s)",
            Cost::Step => "mean reduced step time (ms)",
        }
    }
    fn title(self) -> &'static str {
        match self {
            Cost::Precompute => "error against precompute time",
            Cost::Step => "error against step time",
        }
    }
}

fn register_font() -> PlotResult<()> {
    freeform::render::register_font()?;
    Ok(())
}

/// A marker of shape `shape` (by K: filled circle, filled triangle, filled square,
/// cross, open circle, cycled), `size` pixels, at `at`.
struct Marker<C> {
    at: C,
    shape: usize,
    size: i32,
    colour: RGBColor,
}

impl<'a, C> PointCollection<'a, C> for &'a Marker<C> {
    type Point = &'a C;
    type IntoIter = std::iter::Once<&'a C>;
    fn point_iter(self) -> Self::IntoIter {
        std::iter::once(&self.at)
    }
}

impl<C, DB: DrawingBackend> Drawable<DB> for Marker<C> {
    fn draw<I: Iterator<Item = BackendCoord>>(
        &self,
        mut points: I,
        backend: &mut DB,
        _: (u32, u32),
    ) -> Result<(), DrawingErrorKind<DB::ErrorType>> {
        let Some((x, y)) = points.next() else {
            return Ok(());
        };
        let (s, fill, line) = (self.size, self.colour.filled(), self.colour.stroke_width(2));
        match self.shape % 5 {
            0 => backend.draw_circle((x, y), s as u32, &fill, true),
            1 => backend.fill_polygon(
                [(x, y - s - 2), (x - s - 1, y + s), (x + s + 1, y + s)],
                &fill,
            ),
            2 => backend.draw_rect((x - s, y - s), (x + s, y + s), &fill, true),
            3 => backend
                .draw_line((x - s, y - s), (x + s, y + s), &line)
                .and_then(|()| backend.draw_line((x - s, y + s), (x + s, y - s), &line)),
            _ => backend.draw_circle((x, y), s as u32, &line, false),
        }
    }
}

fn variation_label(r: &SweepRow) -> Option<String> {
    match r.axis {
        SweepAxis::Grid | SweepAxis::Base => refined_name(r.density.boundaries),
        SweepAxis::Points => Some(match r.resolution {
            Some(Resolution::Spacing(h)) => format!("h {h} m"),
            _ => format!("N {}", r.result.points),
        }),
        SweepAxis::Cubature => Some(format!("cub {}", r.result.cubature_points)),
        SweepAxis::Hessian => Some(r.result.hessian.name().to_string()),
    }
}

/// Vertical text offsets (pixels) of labels at pixel positions `at` with `chars`
/// characters each: every label goes right of its point, at the first offset from a
/// fixed list where its box overlaps no label placed before it, so near-coincident
/// variations (e.g. the cubature runs, which share a basis and so a precompute time) do
/// not overprint.
fn label_offsets(at: &[(i32, i32)], chars: &[usize]) -> Vec<i32> {
    const CANDIDATES: [i32; 8] = [-16, 2, -30, 16, -44, 30, -58, 44];
    const LINE: i32 = 14;
    let boxes = |(x, y): (i32, i32), n: usize, dy: i32| {
        (x + 8, y + dy, x + 8 + 7 * n as i32, y + dy + LINE)
    };
    let overlap = |a: (i32, i32, i32, i32), b: (i32, i32, i32, i32)| {
        a.0 < b.2 && b.0 < a.2 && a.1 < b.3 && b.1 < a.3
    };
    let mut placed: Vec<(i32, i32, i32, i32)> = Vec::with_capacity(at.len());
    let mut out = Vec::with_capacity(at.len());
    for (&p, &n) in at.iter().zip(chars) {
        let dy = CANDIDATES
            .iter()
            .copied()
            .find(|&dy| !placed.iter().any(|&q| overlap(boxes(p, n, dy), q)))
            .unwrap_or(CANDIDATES[0]);
        placed.push(boxes(p, n, dy));
        out.push(dy);
    }
    out
}

fn log_range(values: impl Iterator<Item = f64>) -> std::ops::Range<f64> {
    let (lo, hi) = values
        .filter(|v| v.is_finite() && *v > 0.0)
        .fold((f64::INFINITY, 0.0f64), |(lo, hi), v| {
            (lo.min(v), hi.max(v))
        });
    if !lo.is_finite() {
        return 0.1..10.0;
    }
    // Whole decades, so that both ends carry a labelled power of ten.
    let lo = 10f64.powf((lo / 1.2).log10().floor());
    let hi = 10f64.powf((hi * 1.2).log10().ceil());
    // A little beyond them, so the end ticks are drawn.
    lo * 0.92..hi * 1.08
}

/// A tick label: two significant digits, plain between 0.01 and 10^4.
fn tick(v: f64) -> String {
    let r: f64 = format!("{v:.1e}").parse().unwrap_or(v);
    if r != 0.0 && (1e-2..1e4).contains(&r.abs()) {
        format!("{r}")
    } else {
        format!("{r:.0e}")
    }
}

fn sorted_unique(v: impl Iterator<Item = usize>) -> Vec<usize> {
    let mut v: Vec<usize> = v.collect();
    v.sort_unstable();
    v.dedup();
    v
}

/// A log-log chart on a bitmap.
type LogLogChart<'a, 'b> =
    ChartContext<'a, BitMapBackend<'b>, Cartesian2d<LogCoord<f64>, LogCoord<f64>>>;

/// A chart of normalized MSE (log) against `x_desc` (log) on `root`, its mesh drawn.
fn log_log_chart<'a, 'b>(
    root: &'a DrawingArea<BitMapBackend<'b>, plotters::coord::Shift>,
    caption: String,
    x: std::ops::Range<f64>,
    y: std::ops::Range<f64>,
    x_desc: &str,
) -> PlotResult<LogLogChart<'a, 'b>> {
    let mut chart = ChartBuilder::on(root)
        .caption(caption, (FONT, 24))
        .margin(18)
        .x_label_area_size(55)
        .y_label_area_size(85)
        .build_cartesian_2d(x.log_scale(), y.log_scale())?;
    chart
        .configure_mesh()
        .x_desc(x_desc)
        .y_desc("normalized MSE vs FEM (mean |x_red - x_fem|^2 / D^2)")
        .label_style((FONT, 15))
        .axis_desc_style((FONT, 17))
        .x_labels(12)
        .y_labels(12)
        .light_line_style(RGBColor(238, 238, 238))
        .x_label_formatter(&|v| tick(*v))
        .y_label_formatter(&|v| format!("{v:.0e}"))
        .draw()?;
    Ok(chart)
}

/// The colour of m among the plot's `ms` (ascending).
fn mode_colour(ms: &[usize], m: usize) -> RGBColor {
    let (r, g, b) = COLOURS[ms.iter().position(|&v| v == m).unwrap_or(0) % 10];
    RGBColor(r, g, b)
}

/// One legend entry per m: its colour.
fn legend_modes<'a, 'b: 'a>(chart: &mut LogLogChart<'a, 'b>, ms: &[usize]) -> PlotResult<()> {
    for &m in ms {
        let c = mode_colour(ms, m);
        chart
            .draw_series(std::iter::empty::<Circle<(f64, f64), i32>>())?
            .label(format!("m = {m}"))
            .legend(move |(x, y)| Circle::new((x, y), 5, c.filled()));
    }
    Ok(())
}

/// The series' legend at `position`.
fn draw_legend<'a, 'b: 'a>(
    chart: &mut LogLogChart<'a, 'b>,
    position: SeriesLabelPosition,
) -> PlotResult<()> {
    chart
        .configure_series_labels()
        .label_font((FONT, 15))
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .position(position)
        .draw()?;
    Ok(())
}

/// Draw the plot of normalized MSE against `cost` and write it as PNG to `path`
/// (atomically).
pub fn write_png(report: &SweepReport, cost: Cost, path: &Path) -> PlotResult<()> {
    register_font()?;
    let mut rgb = vec![255u8; (WIDTH * HEIGHT * 3) as usize];
    draw(report, cost, &mut rgb)?;
    freeform::render::write_png_rgb(path, WIDTH, HEIGHT, &rgb)?;
    Ok(())
}

fn draw(report: &SweepReport, cost: Cost, rgb: &mut [u8]) -> PlotResult<()> {
    let rows: Vec<&SweepRow> = report
        .rows
        .iter()
        .filter(|r| {
            let (x, y) = (cost.of(r), r.result.normalized_mse);
            x.is_finite() && x > 0.0 && y.is_finite() && y > 0.0
        })
        .collect();
    let ms = sorted_unique(rows.iter().map(|r| r.result.modes));
    let ks = sorted_unique(rows.iter().map(|r| r.result.kernels));
    let colour = |m: usize| mode_colour(&ms, m);
    let shape = |k: usize| ks.iter().position(|&v| v == k).unwrap_or(0);
    let root = BitMapBackend::with_buffer(rgb, (WIDTH, HEIGHT)).into_drawing_area();
    root.fill(&WHITE)?;
    let frames = report.rows.first().map_or(0, |r| r.result.frames);
    let mut chart = log_log_chart(
        &root,
        format!(
            "freeform sweep {}: {} ({} frames)",
            report.test,
            cost.title(),
            frames
        ),
        log_range(rows.iter().map(|r| cost.of(r))),
        log_range(rows.iter().map(|r| r.result.normalized_mse)),
        cost.label(),
    )?;
    // The front as a line from the cheapest to the most accurate run.
    let pts: Vec<[f64; 2]> = rows
        .iter()
        .map(|r| [cost.of(r), r.result.normalized_mse])
        .collect();
    let flags: Vec<bool> = rows.iter().map(|r| cost.on_front(r)).collect();
    let line: Vec<(f64, f64)> = front_by_cost(&pts, &flags)
        .into_iter()
        .map(|i| (pts[i][0], pts[i][1]))
        .collect();
    chart
        .draw_series(LineSeries::new(line, BLACK.stroke_width(2)))?
        .label("Pareto front")
        .legend(|(x, y)| {
            EmptyElement::at((x, y))
                + PathElement::new(vec![(-10, 0), (10, 0)], BLACK.stroke_width(2))
                + Circle::new((0, 0), 9, BLACK.stroke_width(2))
        });
    chart.draw_series(rows.iter().filter(|r| cost.on_front(r)).map(|r| {
        Circle::new(
            (cost.of(r), r.result.normalized_mse),
            10,
            BLACK.stroke_width(2),
        )
    }))?;
    chart.draw_series(rows.iter().map(|r| Marker {
        at: (cost.of(r), r.result.normalized_mse),
        shape: shape(r.result.kernels),
        size: 5,
        colour: colour(r.result.modes),
    }))?;
    let labels: Vec<((f64, f64), String)> = rows
        .iter()
        .filter_map(|r| variation_label(r).map(|t| ((cost.of(r), r.result.normalized_mse), t)))
        .collect();
    let pixels: Vec<(i32, i32)> = labels.iter().map(|l| chart.backend_coord(&l.0)).collect();
    let chars: Vec<usize> = labels.iter().map(|l| l.1.chars().count()).collect();
    let offsets = label_offsets(&pixels, &chars);
    chart.draw_series(labels.into_iter().zip(offsets).map(|((at, t), dy)| {
        EmptyElement::at(at) + Text::new(t, (8, dy), (FONT, 13).into_font().color(&BLACK))
    }))?;
    legend_modes(&mut chart, &ms)?;
    for &k in &ks {
        let s = shape(k);
        chart
            .draw_series(std::iter::empty::<Circle<(f64, f64), i32>>())?
            .label(format!("K = {k}"))
            .legend(move |at| Marker {
                at,
                shape: s,
                size: 5,
                colour: RGBColor(60, 60, 60),
            });
    }
    draw_legend(&mut chart, SeriesLabelPosition::UpperRight)?;
    root.present()?;
    Ok(())
}

/// A short name of a curve's density: "uniform" or "ends x2".
pub fn density_name(boundaries: f64) -> String {
    refined_name(boundaries).unwrap_or_else(|| "uniform".to_string())
}

/// "ends x2" for refined ends, `None` for uniform placement (factor 1).
pub fn refined_name(boundaries: f64) -> Option<String> {
    (boundaries != 1.0).then(|| format!("ends x{boundaries}"))
}

/// Draw the grid's normalized MSE against K (one line per density and m: colour = m, line
/// and marker = density; the paper's Table 1 dotted where [`paper_table1`] has it; the legend
/// upper left, where the axis's whole decade below the smallest K leaves room) and write it
/// as PNG to `path` (atomically). Nothing is written when the grid has one K.
pub fn write_kernels_png(report: &SweepReport, path: &Path) -> PlotResult<()> {
    // Each curve with its drawable points (K, MSE), MSE finite and positive for the log axis.
    let lines: Vec<(&KernelCurve, Vec<(f64, f64)>)> = report
        .curves
        .iter()
        .filter(|c| c.kernels.len() >= 2)
        .map(|c| {
            let pts = c
                .kernels
                .iter()
                .zip(&c.normalized_mse)
                .filter(|(_, &e)| e.is_finite() && e > 0.0)
                .map(|(&k, &e)| (k as f64, e))
                .collect();
            (c, pts)
        })
        .collect();
    if lines.is_empty() {
        return Ok(());
    }
    register_font()?;
    let mut rgb = vec![255u8; (WIDTH * HEIGHT * 3) as usize];
    draw_kernels(report, &lines, &mut rgb)?;
    freeform::render::write_png_rgb(path, WIDTH, HEIGHT, &rgb)?;
    Ok(())
}

fn draw_kernels(
    report: &SweepReport,
    lines: &[(&KernelCurve, Vec<(f64, f64)>)],
    rgb: &mut [u8],
) -> PlotResult<()> {
    let frames = report.rows.first().map_or(0, |r| r.result.frames);
    let ms = sorted_unique(lines.iter().map(|(c, _)| c.modes));
    let mut densities: Vec<f64> = Vec::new();
    for (c, _) in lines {
        if !densities.contains(&c.density.boundaries) {
            densities.push(c.density.boundaries);
        }
    }
    let colour = |m: usize| mode_colour(&ms, m);
    let style = |d: f64| densities.iter().position(|&v| v == d).unwrap_or(0);
    let paper: Vec<(usize, f64)> = ms
        .iter()
        .filter_map(|&m| paper_table1(report.test, m, frames).map(|e| (m, e)))
        .collect();
    let points = || lines.iter().flat_map(|(_, pts)| pts.iter().copied());
    let x_range = log_range(points().map(|p| p.0));
    let y_range = log_range(points().map(|p| p.1).chain(paper.iter().map(|p| p.1)));
    let root = BitMapBackend::with_buffer(rgb, (WIDTH, HEIGHT)).into_drawing_area();
    root.fill(&WHITE)?;
    let mut chart = log_log_chart(
        &root,
        format!(
            "freeform sweep {}: error against kernels K ({} frames)",
            report.test, frames
        ),
        x_range.clone(),
        y_range,
        "kernels K",
    )?;
    for &(m, e) in &paper {
        let line = [(x_range.start, e), (x_range.end, e)];
        chart.draw_series(DashedLineSeries::new(line, 2, 6, colour(m).stroke_width(2)))?;
    }
    for (c, pts) in lines {
        let (col, s) = (colour(c.modes), style(c.density.boundaries));
        if s == 0 {
            chart.draw_series(LineSeries::new(pts.iter().copied(), col.stroke_width(2)))?;
        } else {
            chart.draw_series(DashedLineSeries::new(
                pts.iter().copied(),
                10,
                6,
                col.stroke_width(2),
            ))?;
        }
        chart.draw_series(pts.iter().map(|&at| Marker {
            at,
            shape: s,
            size: 5,
            colour: col,
        }))?;
    }
    legend_modes(&mut chart, &ms)?;
    let grey = RGBColor(60, 60, 60);
    for (s, &d) in densities.iter().enumerate() {
        chart
            .draw_series(std::iter::empty::<Circle<(f64, f64), i32>>())?
            .label(density_name(d))
            .legend(move |(x, y)| {
                // A solid line through the marker, or two short dashes beside it; a few
                // pixels right of the legend's anchor so the lines stay inside its box.
                let (a, b) = if s == 0 { (10, 0) } else { (11, 6) };
                EmptyElement::at((x + 4, y))
                    + PathElement::new(vec![(-a, 0), (-b, 0)], grey.stroke_width(2))
                    + PathElement::new(vec![(b, 0), (a, 0)], grey.stroke_width(2))
                    + Marker {
                        at: (0, 0),
                        shape: s,
                        size: 5,
                        colour: grey,
                    }
            });
    }
    if !paper.is_empty() {
        chart
            .draw_series(std::iter::empty::<Circle<(f64, f64), i32>>())?
            .label("paper, Table 1")
            .legend(move |(x, y)| {
                DashedPathElement::new(vec![(x - 6, y), (x + 14, y)], 2, 6, grey.stroke_width(2))
            });
    }
    draw_legend(&mut chart, SeriesLabelPosition::UpperLeft)?;
    root.present()?;
    Ok(())
}
