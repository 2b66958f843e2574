//! The fused products H X and M X with both triangles stored (`sparse::SharedPattern`) and
//! with the upper triangle only (`triangle::mul_pair_row_major`) on the RKPM beam pencil: the
//! time per product pair, block width 40 (the LOBPCG block at m = 32), best of `repeat`.
//!
//!     cargo run --release --example upper_products -- [kernels] [repeat]

use freeform::io::read_shape;
use freeform::precompute::{BasisOptions, MatrixStorage, Problem};
use freeform::progress::Silent;
use freeform::report::Stopwatch;
use freeform::sparse;
use freeform::triangle::{self, UpperPattern, UpperRef};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<usize> = std::env::args()
        .skip(1)
        .map(|a| a.parse())
        .collect::<Result<_, _>>()?;
    let kernels = args.first().copied().unwrap_or(100_000);
    let repeat = args.get(1).copied().unwrap_or(20).max(1);
    let shape = read_shape("box:5,1,1", &Default::default())?;
    let opts = BasisOptions {
        kernels,
        matrix_storage: MatrixStorage::Full,
        ..BasisOptions::default()
    };
    let problem = Problem::from_shape(&shape, &opts, &Silent)?;
    let (h, m) = (problem.matrices().hessian(), problem.matrices().mass());
    let k = h.nrows();
    let sym = h.symbolic();
    let (mut ptr, mut idx, mut vh, mut vm) = (vec![0u32], Vec::new(), Vec::new(), Vec::new());
    for j in 0..k {
        for p in sym.col_range(j) {
            if sym.row_idx()[p] as usize <= j {
                idx.push(sym.row_idx()[p]);
                vh.push(h.val()[p]);
                vm.push(m.val()[p]);
            }
        }
        ptr.push(idx.len() as u32);
    }
    let pattern = UpperPattern::new(k, ptr, idx)?;
    let (uh, um) = (UpperRef::new(&pattern, &vh), UpperRef::new(&pattern, &vm));
    let nc = 40;
    let x: Vec<f64> = (0..k * nc)
        .map(|i| ((i * 7919) % 1000) as f64 / 1000.0)
        .collect();
    let (mut ya, mut yb) = (vec![0.0; k * nc], vec![0.0; k * nc]);
    let pair = sparse::SharedPattern::new(h, m).ok_or("one pattern")?;
    let (mut full, mut upper) = (f64::INFINITY, f64::INFINITY);
    for _ in 0..repeat {
        let sw = Stopwatch::start();
        pair.mul_row_major(&x, nc, &mut ya, &mut yb, nc, nc);
        full = full.min(sw.elapsed());
        let sw = Stopwatch::start();
        triangle::mul_pair_row_major(uh, um, &x, nc, &mut ya, &mut yb, nc, nc);
        upper = upper.min(sw.elapsed());
    }
    println!(
        "K = {k}, nnz full {} upper {} ({:.1}% in the second pass), {} threads: both triangles {:.4} s, upper {:.4} s ({:.2}x)",
        h.val().len(),
        pattern.nnz(),
        100.0 * pattern.cross_fraction(),
        rayon::current_num_threads(),
        full,
        upper,
        upper / full
    );
    Ok(())
}
