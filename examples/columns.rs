//! Cost per object against the object count on the scene Kaolin's Simplicits was run beside
//! freeform on (issue 28): N / 2 columns in a row, each a soft box on the floor with a ball
//! dropped just past its right edge; the ball clips the edge, rolls off and wedges in the
//! 6 cm gap to the next box (the last one against a wall as far away). Boxes and balls as in
//! `contact_scaling` (K = 300, m = 10, 800 cubature points, E = 200 kPa, full Newton,
//! friction 0.4); 80 steps of 10 ms. The contacts form one chain along the row, so the
//! largest island grows with N. Prints the markdown table of docs/performance.md and draws
//! docs/img/columns_scaling.png.
//!
//!     cargo run --release --example columns [-- quick | N N ... | scene N]
//!
//! `quick` runs N = 2 and 4, 40 steps; counts given (even) run those; neither draws the
//! plot. `scene N` prints the scene file for N objects instead, for `freeform run`.

#[path = "common/scaling.rs"]
mod scaling;

/// Box edge, ball radius and the distance from one box's left face to the next's, metres.
const BOX: f64 = 0.1;
const BALL: f64 = 0.04;
const PITCH: f64 = 0.16;

/// The scene for `n` objects (`n` even).
fn scene(n: usize, steps: usize) -> String {
    let columns = n / 2;
    let wall = (columns - 1) as f64 * PITCH + PITCH;
    let mut s = format!(
        "# {n} objects: {columns} columns of a box and a ball dropped past its edge\n\
         # (cargo run --release --example columns -- scene {n}).\n\n\
         [simulation]\ndt = 0.01\nsteps = {steps}\ngravity = [0.0, -9.81, 0.0]\n\n\
         [solver]\nhessian = \"newton\"\ncubature = 800\n\n\
         [contact]\nfriction = 0.4\n\n\
         [[collider]]\nshape = {{ plane = {{ point = [0.0, 0.0, 0.0], normal = [0.0, 1.0, 0.0] }} }}\n\
         [[collider]]\nshape = {{ plane = {{ point = [{wall:.4}, 0.0, 0.0], normal = [-1.0, 0.0, 0.0] }} }}\n"
    );
    let material = "material = { youngs = 2e5, poisson = 0.4, density = 500.0 }\n\
                    basis = { kernels = 300, modes = 10 }\n";
    for c in 0..columns {
        let x = c as f64 * PITCH;
        // The box 2 mm above the floor (it settles in the first steps); the ball's centre 1 cm
        // past the box's right face and 6 cm above its top.
        s += &format!(
            "\n[[object]]\nname = \"box{c:02}\"\nshape = \"box:{BOX},{BOX},{BOX}\"\n{material}\
             placement = {{ translation = [{x:.4}, 0.002, 0.0] }}\n"
        );
        let (bx, by, bz) = (x + BOX + 0.01, BOX + BALL + 0.06, BOX / 2.0);
        s += &format!(
            "\n[[object]]\nname = \"ball{c:02}\"\nshape = \"sphere:{BALL}\"\n{material}\
             placement = {{ translation = [{bx:.4}, {by:.4}, {bz:.4}] }}\n"
        );
    }
    s
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if let [cmd, n] = args.as_slice() {
        if cmd == "scene" {
            match n.parse::<usize>() {
                Ok(n) if n >= 2 && n % 2 == 0 => print!("{}", scene(n, 80)),
                _ => eprintln!("scene N: N must be an even object count of at least 2"),
            }
            return;
        }
    }
    let (counts, which) = scaling::counts(&[2, 4, 8, 18, 32], &[2, 4]);
    if let Some(n) = counts.iter().find(|&&n| n < 2 || n % 2 == 1) {
        eprintln!("{n} objects: the columns scene needs an even count of at least 2");
        std::process::exit(2);
    }
    scaling::run(
        &counts,
        which,
        [40, 80],
        scene,
        "Columns: cost per object against object count",
        "docs/img/columns_scaling.png",
    );
}
