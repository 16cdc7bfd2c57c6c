//! The C route end to end: the committed header matches the code (cbindgen), and the C
//! example, compiled with the system C compiler against the built `libneural_brdf`, loads the
//! shipped latent file, evaluates and samples a code, opens a blend and a mixture, and gets
//! clear errors for bad input.

use std::path::{Path, PathBuf};
use std::process::Command;

fn crate_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// Where `cargo test` put `libneural_brdf` (the cdylib example, see examples/cdylib.rs; the
/// test binary lives in `deps/` beside `examples/`).
fn library_dir() -> PathBuf {
    let exe = std::env::current_exe().expect("test executable");
    exe.parent().and_then(Path::parent).expect("target directory").join("examples")
}

#[test]
fn header_is_up_to_date() {
    let config = cbindgen::Config::from_file(crate_dir().join("cbindgen.toml")).expect("cbindgen.toml");
    let bindings = cbindgen::Builder::new()
        .with_crate(crate_dir())
        .with_config(config)
        .generate()
        .expect("cbindgen generates the header");
    let mut generated = Vec::new();
    bindings.write(&mut generated);
    let path = crate_dir().join("include/neural_brdf.h");
    if std::env::var_os("BLESS").is_some() {
        std::fs::write(&path, &generated).expect("write the header");
    }
    let committed = std::fs::read(&path).expect("include/neural_brdf.h");
    assert!(
        committed == generated,
        "include/neural_brdf.h differs from what cbindgen makes of src/lib.rs; regenerate it with BLESS=1 cargo test -p neural-brdf-c --test c_example header"
    );
}

#[test]
fn c_example_runs_against_the_shipped_latent_file() {
    let dir = tempfile::tempdir().expect("tempdir");
    let exe = dir.path().join("example");
    let lib = library_dir();
    assert!(lib.join("libneural_brdf.so").is_file() || lib.join("libneural_brdf.dylib").is_file(), "no cdylib in {}", lib.display());
    let cc = std::env::var("CC").unwrap_or_else(|_| "cc".to_string());
    let compiled = Command::new(&cc)
        .args(["-std=c99", "-Wall", "-Wextra", "-Werror", "-I"])
        .arg(crate_dir().join("include"))
        .arg(crate_dir().join("examples/example.c"))
        .arg("-L")
        .arg(&lib)
        .args(["-lneural_brdf", "-lm", "-o"])
        .arg(&exe)
        .output()
        .unwrap_or_else(|e| panic!("cannot run the C compiler '{cc}': {e}"));
    assert!(compiled.status.success(), "C compile failed:\n{}", String::from_utf8_lossy(&compiled.stderr));

    let latent = crate_dir().join("../../scenes/materials/latent.bin");
    let run = |args: &[&Path]| {
        Command::new(&exe)
            .args(args)
            .env("LD_LIBRARY_PATH", &lib)
            .env("DYLD_LIBRARY_PATH", &lib)
            .output()
            .expect("run the C example")
    };
    let scratch = dir.path().join("wrong-version.bin");
    let out = run(&[&latent, &scratch]);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{stdout}\n{}", String::from_utf8_lossy(&out.stderr));
    println!("{stdout}");
    for line in ["missing file -> /nonexistent/latent.bin", "unknown name -> latent code 'no-such-material' not found", "wrong version ->", "NaN direction -> invalid value for wo", "NULL output -> invalid value for f: NULL",
        "f(mirror): blend at t = 0.25",
        "blend at t NaN -> invalid value for t: NaN is not in [0, 1]",
        "blend at t 1.5 -> invalid value for t: 1.5 is not in [0, 1]",
        "blend of an unknown code -> latent code 'no-such-material' not found",
        "mix of 5 -> invalid value for count: a mixture has 1 to 4 parts, not 5",
        "negative weight -> invalid value for weights: weight 1 is -1",
        "NaN weight -> invalid value for weights: weight 0 is NaN",
        "NULL part -> invalid value for parts[1]: NULL",
        "NULL parts -> invalid value for parts: NULL",
        "ok"] {
        assert!(stdout.contains(line), "missing '{line}' in\n{stdout}");
    }

    // A missing latent file as the argument: non-zero exit, the message names it.
    let out = run(&[Path::new("/nonexistent/latent.bin")]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && stderr.contains("/nonexistent/latent.bin"), "{stderr}");
}
