//! MatrixMarket reader (`freeform modes --from-matrices`): any bytes give a matrix or a
//! `MatrixFileError`, never a panic, and memory stays bounded by the input size.
#![no_main]

use libfuzzer_sys::fuzz_target;
use std::path::Path;

fuzz_target!(|data: &[u8]| {
    let _ = freeform::io::matrix_market::read_matrix_market_from(Path::new("fuzz.mtx"), data);
});
