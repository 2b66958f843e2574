//! OBJ reader: any bytes give a mesh or a `GeometryError`, never a panic.
#![no_main]

use freeform::geometry::ShapeOptions;
use libfuzzer_sys::fuzz_target;
use std::path::Path;

fuzz_target!(|data: &[u8]| {
    for allow_open_mesh in [false, true] {
        let opts = ShapeOptions {
            allow_open_mesh,
            ..ShapeOptions::default()
        };
        let _ = freeform::io::obj::parse_obj_bytes(Path::new("fuzz.obj"), data, &opts);
    }
});
