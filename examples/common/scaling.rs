//! What the object-count examples (`contact_scaling`, `columns`) measure for one scene: the
//! world step's wall and CPU time per object, the islands, the active sample pairs, both
//! penetration figures and the unconverged steps; a markdown row for each count and a log-log
//! plot of the cost per object against the count.

use freeform::progress::Silent;
use freeform::scene::{RunSettings, Scene, World};
use plotters::prelude::*;
use std::time::Instant;

/// User + system CPU seconds of this process so far.
fn cpu_seconds() -> f64 {
    // SAFETY: getrusage only writes the struct it is given.
    let mut u: libc::rusage = unsafe { std::mem::zeroed() };
    unsafe { libc::getrusage(libc::RUSAGE_SELF, &mut u) };
    let t = |v: libc::timeval| v.tv_sec as f64 + v.tv_usec as f64 * 1e-6;
    t(u.ru_utime) + t(u.ru_stime)
}

/// One scene's figures over its steps (the setup is timed apart and not counted).
pub struct Row {
    /// Objects in the scene.
    pub n: usize,
    /// Mean world step, wall ms.
    pub step_ms: f64,
    /// Slowest world step, wall ms.
    pub step_ms_max: f64,
    /// Process CPU ms (user + system) per world step.
    pub cpu_ms: f64,
    pub islands_mean: f64,
    pub island_max: usize,
    pub pairs_mean: f64,
    /// Worst penetration of the contact samples, fraction of the smaller diagonal.
    pub penetration: f64,
    /// Worst visible penetration (surface points), fraction of the smaller diagonal.
    pub visible: f64,
    pub over_tolerance: usize,
    pub unconverged: usize,
    /// Newton iterations per object-step (an island's iterations count for each member).
    pub iterations: f64,
}

impl Row {
    /// CPU ms per object-step.
    pub fn cpu_per_object(&self) -> f64 {
        self.cpu_ms / self.n as f64
    }
}

/// Set up `text` (a scene with `[contact]` and `n` objects) and run `steps` steps.
fn measure(n: usize, text: &str, steps: usize) -> Row {
    let scene = Scene::from_toml(text).expect("the generated scene parses");
    let settings = RunSettings::default();
    let c0 = cpu_seconds();
    let mut world = World::new(&scene, &settings, &Silent).expect("setup");
    let setup_cpu = cpu_seconds() - c0;
    let (c1, t1) = (cpu_seconds(), Instant::now());
    let (mut unconverged, mut iterations) = (0, 0);
    for _ in 0..steps {
        let reports = world.step().expect("step");
        unconverged += reports.iter().filter(|r| !r.solve.converged).count();
        iterations += reports.iter().map(|r| r.solve.iterations).sum::<usize>();
    }
    let cpu = cpu_seconds() - c1;
    let wall = t1.elapsed().as_secs_f64();
    let contact = world.contact_summary().expect("the scene has [contact]");
    let rows = &contact.steps;
    let mean = |f: &dyn Fn(&freeform::scene::ContactStepRow) -> f64| {
        rows.iter().map(f).sum::<f64>() / rows.len().max(1) as f64
    };
    eprintln!(
        "N = {n}: setup CPU {setup_cpu:.2} s; {:.1} ms per world step ({wall:.2} s wall), CPU {:.1} ms",
        contact.step_ms_mean,
        cpu * 1e3 / steps as f64
    );
    Row {
        n,
        step_ms: contact.step_ms_mean,
        step_ms_max: rows.iter().map(|r| r.wall_ms).fold(0.0, f64::max),
        cpu_ms: cpu * 1e3 / steps as f64,
        islands_mean: mean(&|r| r.islands.len() as f64),
        island_max: rows.iter().map(|r| r.largest_island()).max().unwrap_or(1),
        pairs_mean: mean(&|r| r.sample_pairs_active as f64),
        penetration: contact.worst_penetration_fraction,
        visible: contact.worst_visible_penetration_fraction,
        over_tolerance: contact.steps_over_tolerance,
        unconverged,
        iterations: iterations as f64 / (n * steps) as f64,
    }
}

/// Measure the scene `scene(n, steps)` for each count (`steps` = [quick, otherwise] by
/// `which`), print the table and, for the full set, draw the plot titled `title` into `png`.
pub fn run(
    counts: &[usize],
    which: Counts,
    steps: [usize; 2],
    scene: impl Fn(usize, usize) -> String,
    title: &str,
    png: &str,
) {
    let steps = if which == Counts::Quick {
        steps[0]
    } else {
        steps[1]
    };
    let rows: Vec<Row> = counts
        .iter()
        .map(|&n| measure(n, &scene(n, steps), steps))
        .collect();
    print_table(&rows);
    if which == Counts::Full {
        if let Err(e) = plot(&rows, title, png) {
            eprintln!("plot: {e}");
        }
    }
}

/// The markdown table of the rows, with each count's CPU ms per object-step as a multiple of
/// the first row's.
fn print_table(rows: &[Row]) {
    println!(
        "| N | world step, ms (mean) | max | CPU ms per step | CPU ms per object | x first row | islands (mean) | largest island | sample pairs active (mean) | worst penetration, samples | visible | steps over the tolerance | unconverged object steps | Newton iterations per object-step |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|");
    let first = rows.first().map_or(1.0, Row::cpu_per_object);
    for r in rows {
        println!(
            "| {} | {:.1} | {:.1} | {:.1} | {:.2} | {:.1} | {:.1} | {} | {:.0} | {:.3}% | {:.3}% | {} | {} | {:.2} |",
            r.n,
            r.step_ms,
            r.step_ms_max,
            r.cpu_ms,
            r.cpu_per_object(),
            r.cpu_per_object() / first,
            r.islands_mean,
            r.island_max,
            r.pairs_mean,
            100.0 * r.penetration,
            100.0 * r.visible,
            r.over_tolerance,
            r.unconverged,
            r.iterations
        );
    }
}

/// Plot CPU ms per object-step against N (log-log) with `title`, and the flat line a cost
/// per object that does not grow would follow, into the PNG `path`.
fn plot(rows: &[Row], title: &str, path: &str) -> Result<(), Box<dyn std::error::Error>> {
    let font = freeform::render::register_font()?;
    let (w, h) = (720u32, 480u32);
    let mut rgb = vec![255u8; (w * h * 3) as usize];
    draw(rows, title, font, &mut rgb, (w, h)).map_err(|e| e.to_string())?;
    freeform::render::write_png_rgb(std::path::Path::new(path), w, h, &rgb)?;
    Ok(())
}

fn draw<'a>(
    rows: &[Row],
    title: &str,
    font: &str,
    rgb: &'a mut [u8],
    size: (u32, u32),
) -> Result<(), Box<dyn std::error::Error + 'a>> {
    let root = BitMapBackend::with_buffer(rgb, size).into_drawing_area();
    root.fill(&WHITE)?;
    let nmin = rows.iter().map(|r| r.n).min().unwrap_or(1) as f64;
    let nmax = rows.iter().map(|r| r.n).max().unwrap_or(1) as f64;
    let per: Vec<(f64, f64)> = rows
        .iter()
        .map(|r| (r.n as f64, r.cpu_per_object()))
        .collect();
    let ymax = per.iter().map(|p| p.1).fold(1.0, f64::max);
    let ymin = per.iter().map(|p| p.1).fold(ymax, f64::min);
    let mut chart = ChartBuilder::on(&root)
        .caption(title, (font, 22))
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(60)
        .build_cartesian_2d(
            (nmin * 0.8..nmax * 1.25).log_scale(),
            (ymin * 0.5..ymax * 2.0).log_scale(),
        )?;
    chart
        .configure_mesh()
        .x_desc("objects N")
        .x_label_formatter(&|x| format!("{x:.0}"))
        .y_desc("CPU ms per object-step")
        .draw()?;
    chart
        .draw_series(LineSeries::new(per.clone(), RED.stroke_width(2)))?
        .label("CPU (user + system) per object-step")
        .legend(|(x, y)| PathElement::new([(x, y), (x + 20, y)], RED));
    chart.draw_series(per.iter().map(|&p| Circle::new(p, 4, RED.filled())))?;
    // The first row with contact (N >= 2) sets the level a constant cost per object keeps.
    if let Some(&(n0, c0)) = per.iter().find(|p| p.0 >= 2.0) {
        chart
            .draw_series(LineSeries::new(
                [(n0, c0), (nmax, c0)],
                BLACK.stroke_width(1),
            ))?
            .label("constant cost per object")
            .legend(|(x, y)| PathElement::new([(x, y), (x + 20, y)], BLACK));
    }
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::UpperLeft)
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .draw()?;
    root.present()?;
    Ok(())
}

/// Which counts a run measures.
#[derive(Clone, Copy, PartialEq, Eq)]
pub enum Counts {
    /// The example's full set: the docs' table and plot.
    Full,
    /// `quick` on the command line: a few small counts, fewer steps, no plot.
    Quick,
    /// Counts given on the command line (`-- 2 4 8`): those, no plot.
    Given,
}

/// The counts to measure: those given on the command line, else `quick`'s with `quick`
/// among the arguments, else `full`.
pub fn counts(full: &[usize], quick: &[usize]) -> (Vec<usize>, Counts) {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if args.iter().any(|a| a == "quick") {
        return (quick.to_vec(), Counts::Quick);
    }
    let given: Vec<usize> = args.iter().filter_map(|a| a.parse().ok()).collect();
    if given.is_empty() {
        (full.to_vec(), Counts::Full)
    } else {
        (given, Counts::Given)
    }
}
