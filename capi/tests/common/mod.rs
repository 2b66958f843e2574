//! Building and running the C examples against the static library, shared by the C tests.

use std::path::{Path, PathBuf};
use std::process::Command;

/// The repository root.
pub fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// The static library cargo built next to this test binary (target/<profile>/deps/, or
/// target/<profile>/ after a plain `cargo build`).
fn static_lib() -> PathBuf {
    let exe = std::env::current_exe().expect("test binary path");
    let deps = exe.parent().expect("target/<profile>/deps");
    let name = "libfreeform_capi.a";
    [deps.join(name), deps.join("..").join(name)]
        .into_iter()
        .find(|p| p.is_file())
        .unwrap_or_else(|| panic!("{name} not found next to {}", exe.display()))
}

/// Compile `examples/<name>.c` with the system C compiler (`$CC`, else `cc`; C99, every
/// warning an error) against the static library into `dir`, run it with `args`, and return
/// its standard output; panics with the compiler's or the program's output if either fails.
pub fn compile_and_run(name: &str, dir: &Path, args: &[&Path]) -> String {
    let root = root();
    let exe = dir.join(name);
    let cc = std::env::var("CC").unwrap_or_else(|_| "cc".into());
    let out = Command::new(&cc)
        .arg(root.join(format!("examples/{name}.c")))
        .arg("-I")
        .arg(root.join("ffi/include"))
        .args(["-std=c99", "-Wall", "-Wextra", "-Werror", "-o"])
        .arg(&exe)
        .arg(static_lib())
        .args(["-lm", "-lpthread", "-ldl"])
        .output()
        .expect("run the C compiler");
    assert!(
        out.status.success(),
        "cc failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let run = Command::new(&exe)
        .args(args)
        .output()
        .expect("run the example");
    let stdout = String::from_utf8_lossy(&run.stdout).into_owned();
    assert!(
        run.status.success(),
        "example failed: {stdout}\n{}",
        String::from_utf8_lossy(&run.stderr)
    );
    stdout
}
