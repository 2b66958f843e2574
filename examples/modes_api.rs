//! Compute skinning eigenmodes from Rust: a soft box with a stiff spherical core, weights at
//! your own query points, and the basis file.
//!
//! Run: `cargo run --release --example modes_api`

use freeform::geometry::ShapeOptions;
use freeform::io::read_shape;
use freeform::material::{Material, MaterialOverride, Region};
use freeform::precompute::{build_basis, BasisOptions};
use freeform::progress::Silent;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let shape = read_shape("box:2,1,1", &ShapeOptions::default())?;
    let core = MaterialOverride {
        region: Region::Sphere {
            center: [1.0, 0.5, 0.5],
            radius: 0.3,
        },
        material: Material {
            youngs: 5e9,
            poisson: 0.3,
            density: 7800.0,
        },
    };
    let opts = BasisOptions {
        kernels: 500,
        modes: 8,
        overrides: vec![core],
        ..BasisOptions::default()
    };
    let run = build_basis(&shape, &opts, &Silent)?;
    let ev: Vec<String> = run
        .basis
        .eigenvalues
        .iter()
        .map(|v| format!("{v:.4e}"))
        .collect();
    println!("eigenvalues [Pa/m^2]: {}", ev.join(" "));
    println!(
        "max relative residual {:.2e}",
        run.report.max_relative_residual
    );

    // Weights and gradients at any points inside the object (here: along the axis).
    let axis: Vec<[f64; 3]> = (0..=10).map(|i| [0.2 * i as f64, 0.5, 0.5]).collect();
    let w = run.basis.weights(&axis)?;
    for (i, x) in axis.iter().enumerate() {
        println!(
            "x = {:.1}: W_1 = {:+.4}, dW_1/dx = {:+.4}",
            x[0],
            w.row(i)[1],
            w.gradient_row(i)[1][0]
        );
    }

    let out = std::env::temp_dir().join("freeform_modes_api.npz");
    freeform::io::basis::save(
        &out,
        &run.basis,
        &serde_json::json!({ "example": "modes_api" }).into(),
    )?;
    println!("basis written to {}", out.display());
    Ok(())
}
