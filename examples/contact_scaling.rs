//! Step time against the number of objects that touch (issues 15, 28): N = 1 to 128 soft
//! boxes and balls (K = 300, m = 10, 800 cubature points) dropped in a grid into a container of
//! four walls and a floor whose floor grows with N, so that the pile keeps the same height and
//! each object about the same number of neighbours; 60 steps of 10 ms with object-object
//! contact and friction, full Newton. Prints the markdown table of docs/performance.md (world
//! step wall time, process CPU time per step and per object-step; islands; pairs; both
//! penetration figures; unconverged steps) and draws docs/img/contact_scaling.png.
//!
//!     cargo run --release --example contact_scaling [-- quick | N N ...]
//!
//! `quick` runs N = 1, 2, 4 only, 40 steps; counts given run those; neither draws the plot.
//! The CPU time (user + system of the whole process, over the steps only) is what to compare
//! on a shared machine.

#[path = "common/scaling.rs"]
mod scaling;

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

fn main() {
    let (counts, which) = scaling::counts(&[1, 2, 4, 8, 16, 32, 64, 128], &[1, 2, 4]);
    scaling::run(
        &counts,
        which,
        [40, 60],
        scene,
        "Contact: cost per object against object count",
        "docs/img/contact_scaling.png",
    );
}
