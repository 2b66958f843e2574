//! Scene TOML parser and validation: any text gives a scene or an `Error::Scene` /
//! `Error::InvalidParameter`, never a panic. A valid scene must also survive `to_toml` and read back.
#![no_main]

use freeform::scene::Scene;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    if let Ok(scene) = Scene::from_toml(text) {
        // A valid scene written back must read again (what `freeform` does with cache keys).
        let again = scene.to_toml().expect("a valid scene serializes");
        if let Err(e) = Scene::from_toml(&again) {
            panic!("round trip failed: {e}\n--- written ---\n{again}");
        }
    }
});
