//! `freeform eval SHAPES_DIR`: the real-shape protocol (issue 18, docs/evaluation.md) over a
//! folder of closed meshes against TetGen FEM references; writes `eval.csv`, `eval.json` and
//! `eval_mse.png` to `--out`, rewritten after every shape.

use crate::beam::{progress, BoundariesArg};
use crate::{emit, set_threads, CliResult};
use clap::{Args, ValueEnum};
use freeform::benchmark::shapes::report::{evaluate_dir, shape_files};
use freeform::benchmark::shapes::{EvalOptions, EvalReport, ShapeTest};
use freeform::fem::ElementOrder;
use freeform::precompute::sampling::Resolution;
use std::path::{Path, PathBuf};

#[derive(Clone, Copy, ValueEnum)]
enum TestArg {
    FixSide,
    PullFarthest,
    PullEnds,
}

#[derive(Clone, Copy, ValueEnum)]
enum OrderArg {
    Linear,
    Quadratic,
}

#[derive(Args)]
pub struct EvalArgs {
    /// Folder of closed surface meshes (.off, .obj, .stl, .ply), e.g. the output of
    /// scripts/cgal_shapes.sh.
    shapes: PathBuf,
    /// Only these shapes, in this order (file stems, comma-separated) [default: all, by name].
    #[arg(long, value_delimiter = ',')]
    only: Vec<String>,
    /// Boundary conditions (comma-separated).
    #[arg(
        long,
        value_enum,
        value_delimiter = ',',
        default_value = "fix-side,pull-farthest,pull-ends"
    )]
    tests: Vec<TestArg>,
    /// Bases compared (comma-separated).
    #[arg(long, value_enum, value_delimiter = ',', default_value = "free,aware")]
    boundaries: Vec<BoundariesArg>,
    /// Modes m.
    #[arg(long, default_value_t = 32)]
    modes: usize,
    /// Kernels K.
    #[arg(long, default_value_t = 1000)]
    kernels: usize,
    /// Integration points [default: 50 K].
    #[arg(long)]
    points: Option<usize>,
    /// Largest kernel spacing factor on thin parts (about 3 kernels across parts thinner than
    /// 3 kernel spacings); 1 is uniform placement.
    #[arg(long, default_value_t = 1.0)]
    density_thin: f64,
    /// Steps of every test (dt 0.01 s).
    #[arg(long, default_value_t = 50)]
    steps: usize,
    /// Young's modulus of every shape, Pa.
    #[arg(long, default_value_t = 1e5)]
    youngs: f64,
    /// TetGen's largest tet volume (-a), m^3 of the unit-box shape.
    #[arg(long, default_value_t = 1e-3)]
    max_volume: f64,
    /// TetGen's radius-edge bound (-q).
    #[arg(long, default_value_t = 1.414)]
    quality: f64,
    /// The TetGen program.
    #[arg(long, default_value = "tetgen")]
    tetgen: PathBuf,
    /// FEM element order.
    #[arg(long, value_enum, default_value = "quadratic")]
    fem_order: OrderArg,
    /// Cache directory for FEM references.
    #[arg(long, default_value = ".freeform-cache/fem")]
    cache: PathBuf,
    /// Output directory (created if missing); TetGen's files go to its `tetgen/`.
    #[arg(long, default_value = "eval")]
    out: PathBuf,
    /// Print the JSON report.
    #[arg(long)]
    json: bool,
    /// Worker threads (default: all cores).
    #[arg(long)]
    threads: Option<usize>,
}

pub fn run(args: EvalArgs) -> CliResult {
    set_threads(args.threads)?;
    let mut opts = EvalOptions {
        modes: args.modes,
        kernels: args.kernels,
        resolution: args.points.map(Resolution::Count),
        tests: args
            .tests
            .iter()
            .map(|t| match t {
                TestArg::FixSide => ShapeTest::FixSide,
                TestArg::PullFarthest => ShapeTest::PullFarthest,
                TestArg::PullEnds => ShapeTest::PullEnds,
            })
            .collect(),
        boundaries: args.boundaries.iter().map(|&b| b.into()).collect(),
        density_thin: args.density_thin,
        ..EvalOptions::default()
    };
    opts.protocol.steps = args.steps;
    opts.protocol.material.youngs = args.youngs;
    opts.protocol.validate()?;
    opts.tetgen.max_volume = args.max_volume;
    opts.tetgen.quality = args.quality;
    opts.tetgen.program = args.tetgen.clone();
    opts.fem.order = match args.fem_order {
        OrderArg::Linear => ElementOrder::Linear,
        OrderArg::Quadratic => ElementOrder::Quadratic,
    };
    let files = shape_files(&args.shapes, &args.only)?;
    std::fs::create_dir_all(&args.out)
        .map_err(|e| format!("cannot create {}: {e}", args.out.display()))?;
    eprintln!(
        "freeform eval: {} shapes, TetGen {}, FEM references cached in {}",
        files.len(),
        opts.tetgen.switches(),
        args.cache.display()
    );
    let bar = progress();
    // The outputs are rewritten (atomically) after every shape: an interrupted run keeps what
    // it finished, and a long one can be watched.
    let mut written: CliResult = Ok(());
    let report = evaluate_dir(
        &files,
        &opts,
        Some(&args.cache),
        &args.out.join("tetgen"),
        bar.as_ref(),
        &mut |partial| {
            if written.is_ok() {
                written = write_outputs(partial, &args.out);
            }
        },
    );
    written?;
    if args.json {
        emit(&(serde_json::to_string_pretty(&report)? + "\n"))?;
    } else {
        emit(&summary(&report, &args.out))?;
    }
    let failed = report.failures.len()
        + report
            .shapes
            .iter()
            .filter(|s| !s.failures.is_empty())
            .count();
    if failed > 0 {
        return Err(format!(
            "{failed} of {} shapes failed in whole or in part (listed above); the outputs hold the rest",
            files.len()
        )
        .into());
    }
    Ok(())
}

fn summary(report: &EvalReport, out: &Path) -> String {
    let mut s = format!(
        "freeform eval: {} shapes evaluated, {} failed, {:.0} s; {}/eval.csv\n",
        report.shapes.len(),
        report.failures.len(),
        report.total_s,
        out.display()
    );
    s += "  test           basis  shapes  MSE        max        fit MSE    fit max    precompute s\n";
    for a in &report.averages {
        s += &format!(
            "  {:<14} {:<6} {:>6}  {:.3e}  {:.3e}  {:.3e}  {:.3e}  {:.2} +- {:.2}\n",
            a.test.name(),
            a.boundaries.name(),
            a.shapes,
            a.normalized_mse,
            a.max_error,
            a.fit_mse,
            a.fit_max,
            a.precompute_s_mean,
            a.precompute_s_std
        );
    }
    for sh in &report.shapes {
        for f in &sh.failures {
            s += &format!("  FAILED {}: {f}\n", sh.name);
        }
    }
    for f in &report.failures {
        s += &format!("  FAILED {}: {}\n", f.name, f.reason);
    }
    s
}

fn write_outputs(report: &EvalReport, out: &Path) -> CliResult {
    let text = |name: &str, body: String| {
        let path = out.join(name);
        freeform::io::write_atomically(&path, |tmp| {
            std::fs::write(tmp, body.as_bytes()).map_err(|source| freeform::Error::Io {
                path: tmp.to_path_buf(),
                source,
            })
        })
    };
    text("eval.csv", report.to_csv())?;
    text("eval.json", serde_json::to_string_pretty(report)? + "\n")?;
    if report.shapes.iter().any(|s| !s.runs.is_empty()) {
        plot::write_png(report, &out.join("eval_mse.png"))?;
    }
    Ok(())
}

/// Normalized MSE per shape, one series per (test, basis).
mod plot {
    use freeform::benchmark::shapes::EvalReport;
    use plotters::prelude::*;
    use std::path::Path;

    type PlotResult<T> = Result<T, Box<dyn std::error::Error>>;
    const WIDTH: u32 = 1100;
    const HEIGHT: u32 = 700;
    const FONT: &str = freeform::render::FONT_FAMILY;
    const COLOURS: [(u8, u8, u8); 3] = [(31, 119, 180), (255, 127, 14), (44, 160, 44)];

    pub fn write_png(report: &EvalReport, path: &Path) -> PlotResult<()> {
        freeform::render::register_font()?;
        let mut rgb = vec![255u8; (WIDTH * HEIGHT * 3) as usize];
        draw(report, &mut rgb)?;
        freeform::render::write_png_rgb(path, WIDTH, HEIGHT, &rgb)?;
        Ok(())
    }

    fn draw(report: &EvalReport, rgb: &mut [u8]) -> PlotResult<()> {
        let names: Vec<&str> = report.shapes.iter().map(|s| s.name.as_str()).collect();
        let values: Vec<f64> = report
            .shapes
            .iter()
            .flat_map(|s| s.runs.iter().map(|r| r.normalized_mse))
            .filter(|v| v.is_finite() && *v > 0.0)
            .collect();
        let lo = values.iter().copied().fold(f64::INFINITY, f64::min);
        let hi = values.iter().copied().fold(0.0, f64::max);
        let (lo, hi) = if lo.is_finite() && hi > 0.0 {
            (
                10f64.powf(lo.log10().floor()),
                10f64.powf(hi.log10().ceil()),
            )
        } else {
            (1e-8, 1.0)
        };
        let root = BitMapBackend::with_buffer(rgb, (WIDTH, HEIGHT)).into_drawing_area();
        root.fill(&WHITE)?;
        let mut chart = ChartBuilder::on(&root)
            .caption(
                "freeform eval: reduced model against TetGen FEM",
                (FONT, 24),
            )
            .margin(18)
            .x_label_area_size(60)
            .y_label_area_size(85)
            .build_cartesian_2d(-0.5f64..names.len() as f64 - 0.5, (lo..hi).log_scale())?;
        chart
            .configure_mesh()
            .x_labels(names.len().max(1))
            .x_label_formatter(&|v| {
                let i = v.round();
                if (v - i).abs() < 1e-6 && i >= 0.0 {
                    names
                        .get(i as usize)
                        .map_or(String::new(), |s| s.to_string())
                } else {
                    String::new()
                }
            })
            .y_desc("normalized MSE (mean |x_red - x_fem|^2 / D^2)")
            .y_label_formatter(&|v| format!("{v:.0e}"))
            .label_style((FONT, 15))
            .axis_desc_style((FONT, 17))
            .light_line_style(RGBColor(238, 238, 238))
            .draw()?;
        let opts = &report.options;
        for (t, &test) in opts.tests.iter().enumerate() {
            for (b, &basis) in opts.boundaries.iter().enumerate() {
                let (r, g, bl) = COLOURS[t % 3];
                let colour = RGBColor(r, g, bl);
                let dx = 0.12 * (b as f64 - 0.5);
                let pts: Vec<(f64, f64)> = report
                    .shapes
                    .iter()
                    .enumerate()
                    .flat_map(|(i, s)| {
                        s.runs
                            .iter()
                            .filter(|r| r.test == test && r.boundaries == basis)
                            .map(move |r| (i as f64 + dx, r.normalized_mse))
                    })
                    .filter(|p| p.1.is_finite() && p.1 > 0.0)
                    .collect();
                let filled = b % 2 == 1;
                chart
                    .draw_series(pts.into_iter().map(move |p| {
                        Circle::new(
                            p,
                            6,
                            if filled {
                                colour.filled()
                            } else {
                                colour.stroke_width(2)
                            },
                        )
                    }))?
                    .label(format!("{} {}", test.name(), basis.name()))
                    .legend(move |(x, y)| {
                        Circle::new(
                            (x, y),
                            6,
                            if filled {
                                colour.filled()
                            } else {
                                colour.stroke_width(2)
                            },
                        )
                    });
            }
        }
        chart
            .configure_series_labels()
            .label_font((FONT, 15))
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .position(SeriesLabelPosition::UpperRight)
            .draw()?;
        root.present()?;
        Ok(())
    }
}
