//! Helpers shared by the `render` command-line tests.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// Runs `render` with `args` in `dir`.
pub fn render(args: &[&str], dir: &Path) -> Output {
    Command::new(env!("CARGO_BIN_EXE_render"))
        .args(args)
        .current_dir(dir)
        .output()
        .expect("run render")
}

/// The shipped Cornell box.
pub fn cornell_box() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes/cornell-box/scene.gltf")
}

/// Asserts a failed run: exit code 2, one `error:` line on stderr containing every needle,
/// no panic, and no file named `out` in `dir`.
pub fn assert_clean_failure(out: &Output, needles: &[&str], dir: &Path) {
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "stderr: {stderr}");
    assert!(!stderr.contains("panicked"), "{stderr}");
    let lines: Vec<&str> = stderr.lines().filter(|l| !l.trim().is_empty()).collect();
    assert!(lines.len() == 1 && lines[0].starts_with("error:"), "one line expected: {stderr}");
    assert!(stderr.matches("(os error").count() <= 1, "cause repeated: {stderr}");
    for n in needles {
        assert!(stderr.contains(n), "'{n}' not in: {stderr}");
    }
    let leftovers: Vec<_> = std::fs::read_dir(dir)
        .expect("ls")
        .filter_map(|e| e.ok())
        .filter(|e| e.file_name().to_string_lossy().starts_with("out"))
        .collect();
    assert!(leftovers.is_empty(), "output written: {leftovers:?}");
}

pub fn write(dir: &Path, name: &str, text: &str) -> String {
    let path = dir.join(name);
    std::fs::write(&path, text).expect("write");
    path.to_string_lossy().into_owned()
}

/// A file of the repository, from the renderer crate's directory.
pub fn repo_file(relative: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..").join(relative)
}
