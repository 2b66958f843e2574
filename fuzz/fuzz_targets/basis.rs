//! Basis archive reader (`.npz`, also the scene cache): any bytes give a basis or an
//! `Error::BasisFile`, never a panic.
#![no_main]

use libfuzzer_sys::fuzz_target;
use std::path::Path;

fuzz_target!(|data: &[u8]| {
    let _ = freeform::io::basis::load_from(Path::new("fuzz.npz"), std::io::Cursor::new(data));
});
