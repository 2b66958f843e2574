//! Step time against the number of objects that touch (issue 15): N = 1, 2, 4, 8, 16, 32 soft
//! boxes and balls (K = 300, m = 10, 800 cubature points) dropped in a grid into a container of
//! four walls and a floor whose floor grows with N, so that the pile keeps the same height and
//! each object about the same number of neighbours; 60 steps of 10 ms with object-object
//! contact and friction, full Newton. Prints the markdown table of docs/performance.md (world
//! step wall time, process CPU time per step, both per object; islands; pairs; the deepest
//! penetration; unconverged steps) and draws docs/img/contact_scaling.png.
//!
//!     cargo run --release --example contact_scaling [-- quick]
//!
//! `quick` runs N = 1, 2, 4 only, 40 steps. The CPU time (user + system of the whole process,
//! over the steps only) is what to compare on a shared machine.

use freeform::progress::Silent;
use freeform::scene::{RunSettings, Scene, World};
use plotters::prelude::*;
use std::time::Instant;

/// Edge of one grid cell the objects are dropped from, metres.
const CELL: f64 = 0.16;

/// The scene for `n` objects: a near-square grid of cells on two levels.
fn scene(n: usize, steps: usize) -> String {
    let per_level = n.div_ceil(2).max(1);
    let cols = (per_level as f64).sqrt().ceil() as usize;
    let rows = per_level.div_ceil(cols);
    let (lx, lz) = (cols as f64 * CELL, rows as f64 * CELL);
    let mut s = format!(
        "[simulation]\ndt = 0.01\nsteps = {steps}\ngravity = [0.0, -9.81, 0.0]\n\n\
         [solver]\nhessian = \"newton\"\ncubature = 800\n\n[cache]\nenabled = false\n\n\
         [contact]\nfriction = 0.4\n\n\
         [[collider]]\nshape = {{ plane = {{ point = [0.0, 0.0, 0.0], normal = [0.0, 1.0, 0.0] }} }}\n"
    );
    for (p, nrm) in [
        ([0.0, 0.0, 0.0], [1.0, 0.0, 0.0]),
        ([lx, 0.0, 0.0], [-1.0, 0.0, 0.0]),
        ([0.0, 0.0, 0.0], [0.0, 0.0, 1.0]),
        ([0.0, 0.0, lz], [0.0, 0.0, -1.0]),
    ] {
        s +=
            &format!("[[collider]]\nshape = {{ plane = {{ point = {p:?}, normal = {nrm:?} }} }}\n");
    }
    for i in 0..n {
        let level = i / per_level;
        let j = i % per_level;
        let (cx, cz) = (
            (j % cols) as f64 * CELL + CELL / 2.0,
            (j / cols) as f64 * CELL + CELL / 2.0,
        );
        let cy = 0.12 + level as f64 * 0.2;
        // Alternate boxes (placed by their lower corner) and balls (by their centre), with a
        // small sideways velocity so that they meet.
        let (shape, at) = if i % 2 == 0 {
            ("box:0.1,0.1,0.1", [cx - 0.05, cy - 0.05, cz - 0.05])
        } else {
            ("sphere:0.05", [cx, cy, cz])
        };
        let vx = if (i / 2) % 2 == 0 { 0.2 } else { -0.2 };
        s += &format!(
            "\n[[object]]\nname = \"o{i:02}\"\nshape = \"{shape}\"\n\
             material = {{ youngs = 2e5, poisson = 0.4, density = 500.0 }}\n\
             basis = {{ kernels = 300, modes = 10 }}\n\
             placement = {{ translation = [{:.4}, {:.4}, {:.4}], velocity = [{vx}, 0.0, 0.0] }}\n",
            at[0], at[1], at[2]
        );
    }
    s
}

/// User + system CPU seconds of this process so far.
fn cpu_seconds() -> f64 {
    // SAFETY: getrusage only writes the struct it is given.
    let mut u: libc::rusage = unsafe { std::mem::zeroed() };
    unsafe { libc::getrusage(libc::RUSAGE_SELF, &mut u) };
    let t = |v: libc::timeval| v.tv_sec as f64 + v.tv_usec as f64 * 1e-6;
    t(u.ru_utime) + t(u.ru_stime)
}

struct Row {
    n: usize,
    step_ms: f64,
    step_ms_max: f64,
    cpu_ms: f64,
    islands_mean: f64,
    island_max: usize,
    pairs_mean: f64,
    penetration: f64,
    over_tolerance: usize,
    unconverged: usize,
}

fn measure(n: usize, steps: usize) -> Row {
    let text = scene(n, steps);
    let scene = Scene::from_toml(&text).expect("the generated scene parses");
    let settings = RunSettings::default();
    // The setup (bases, cubature, contact samples) is timed apart from the steps.
    let c0 = cpu_seconds();
    let mut world = World::new(&scene, &settings, &Silent).expect("setup");
    let setup_cpu = cpu_seconds() - c0;
    let (c1, t1) = (cpu_seconds(), Instant::now());
    let mut unconverged = 0;
    for _ in 0..steps {
        let reports = world.step().expect("step");
        unconverged += reports.iter().filter(|r| !r.solve.converged).count();
    }
    let cpu = cpu_seconds() - c1;
    let wall = t1.elapsed().as_secs_f64();
    let contact = world.contact_summary().expect("the scene has [contact]");
    let rows = &contact.steps;
    let step_ms_max = rows.iter().map(|r| r.wall_ms).fold(0.0, f64::max);
    let islands_mean =
        rows.iter().map(|r| r.islands.len() as f64).sum::<f64>() / rows.len().max(1) as f64;
    let island_max = rows
        .iter()
        .filter_map(|r| r.islands.first().copied())
        .max()
        .unwrap_or(1);
    let pairs_mean = rows
        .iter()
        .map(|r| r.sample_pairs_active as f64)
        .sum::<f64>()
        / rows.len().max(1) as f64;
    eprintln!(
        "N = {n}: setup CPU {setup_cpu:.2} s; {:.1} ms per world step ({wall:.2} s wall), CPU {:.1} ms",
        contact.step_ms_mean,
        cpu * 1e3 / steps as f64
    );
    Row {
        n,
        step_ms: contact.step_ms_mean,
        step_ms_max,
        cpu_ms: cpu * 1e3 / steps as f64,
        islands_mean,
        island_max,
        pairs_mean,
        penetration: contact.worst_penetration_fraction,
        over_tolerance: contact.steps_over_tolerance,
        unconverged,
    }
}

fn plot(rows: &[Row], path: &str) -> Result<(), Box<dyn std::error::Error>> {
    let font = freeform::render::register_font()?;
    let (w, h) = (720u32, 480u32);
    let mut rgb = vec![255u8; (w * h * 3) as usize];
    draw(rows, font, &mut rgb, (w, h)).map_err(|e| e.to_string())?;
    freeform::render::write_png_rgb(std::path::Path::new(path), w, h, &rgb)?;
    Ok(())
}

fn draw<'a>(
    rows: &[Row],
    font: &str,
    rgb: &'a mut [u8],
    size: (u32, u32),
) -> Result<(), Box<dyn std::error::Error + 'a>> {
    let root = BitMapBackend::with_buffer(rgb, size).into_drawing_area();
    root.fill(&WHITE)?;
    let nmax = rows.iter().map(|r| r.n).max().unwrap_or(1) as f64;
    let ymax = rows
        .iter()
        .map(|r| r.cpu_ms.max(r.step_ms))
        .fold(1.0, f64::max);
    let mut chart = ChartBuilder::on(&root)
        .caption("Step time against object count (contact)", (font, 22))
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(60)
        .build_cartesian_2d(
            (0.8..nmax * 1.25).log_scale(),
            (0.5..ymax * 2.0).log_scale(),
        )?;
    chart
        .configure_mesh()
        .x_desc("objects N")
        .x_label_formatter(&|x| format!("{x:.0}"))
        .y_desc("ms per world step")
        .draw()?;
    let wall: Vec<(f64, f64)> = rows.iter().map(|r| (r.n as f64, r.step_ms)).collect();
    let cpu: Vec<(f64, f64)> = rows.iter().map(|r| (r.n as f64, r.cpu_ms)).collect();
    // Linear growth from the first count with contact (N = 4: one object alone has none).
    let base = rows.iter().find(|r| r.n >= 4).or(rows.first());
    let (n0, c0) = base.map_or((1.0, 1.0), |r| (r.n as f64, r.cpu_ms));
    let linear: Vec<(f64, f64)> = [n0, nmax].iter().map(|&n| (n, c0 * n / n0)).collect();
    chart
        .draw_series(LineSeries::new(wall.clone(), BLUE.stroke_width(2)))?
        .label("wall (2 threads)")
        .legend(|(x, y)| PathElement::new([(x, y), (x + 20, y)], BLUE));
    chart.draw_series(wall.iter().map(|&p| Circle::new(p, 4, BLUE.filled())))?;
    chart
        .draw_series(LineSeries::new(cpu.clone(), RED.stroke_width(2)))?
        .label("CPU (user + system)")
        .legend(|(x, y)| PathElement::new([(x, y), (x + 20, y)], RED));
    chart.draw_series(cpu.iter().map(|&p| Circle::new(p, 4, RED.filled())))?;
    chart
        .draw_series(LineSeries::new(linear, BLACK.stroke_width(1)))?
        .label("linear from N = 4 (CPU)")
        .legend(|(x, y)| PathElement::new([(x, y), (x + 20, y)], BLACK));
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::UpperLeft)
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .draw()?;
    root.present()?;
    Ok(())
}

fn main() {
    let quick = std::env::args().any(|a| a == "quick");
    let (counts, steps): (&[usize], usize) = if quick {
        (&[1, 2, 4], 40)
    } else {
        (&[1, 2, 4, 8, 16, 32], 60)
    };
    let rows: Vec<Row> = counts.iter().map(|&n| measure(n, steps)).collect();
    println!(
        "| N | world step, ms (mean) | max | CPU ms per step | CPU ms per object | islands (mean) | largest island | sample pairs active (mean) | worst penetration (of the smaller diagonal) | steps over the tolerance | unconverged object steps |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|---|");
    for r in &rows {
        println!(
            "| {} | {:.1} | {:.1} | {:.1} | {:.2} | {:.1} | {} | {:.0} | {:.3}% | {} | {} |",
            r.n,
            r.step_ms,
            r.step_ms_max,
            r.cpu_ms,
            r.cpu_ms / r.n as f64,
            r.islands_mean,
            r.island_max,
            r.pairs_mean,
            100.0 * r.penetration,
            r.over_tolerance,
            r.unconverged
        );
    }
    if !quick {
        if let Err(e) = plot(&rows, "docs/img/contact_scaling.png") {
            eprintln!("plot: {e}");
        }
    }
}
