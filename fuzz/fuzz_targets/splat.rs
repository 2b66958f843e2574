//! 3DGS splat PLY reader: any bytes give splats or a `GeometryError`, never a panic.
#![no_main]

use libfuzzer_sys::fuzz_target;
use std::path::Path;

fuzz_target!(|data: &[u8]| {
    let _ = freeform::io::splat::read_splats_from(
        Path::new("fuzz.ply"),
        &mut std::io::Cursor::new(data),
    );
});
