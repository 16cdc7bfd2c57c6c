//! The C route end to end: the committed header matches the code (cbindgen), and the C
//! example, compiled with the system C compiler against the built `libneural_brdf`, loads the
//! shipped latent file, evaluates and samples a code, opens a blend and a mixture, and gets
//! clear errors for bad input. A multi-threaded client (examples/threads.c) gets one
//! thread's results from 8 threads at once; both run under Valgrind's memcheck.

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

/// Compiles `examples/NAME.c` against the built library into `dir`.
fn compile(name: &str, dir: &Path) -> PathBuf {
    let exe = dir.join(name);
    let lib = library_dir();
    assert!(lib.join("libneural_brdf.so").is_file() || lib.join("libneural_brdf.dylib").is_file(), "no cdylib in {}", lib.display());
    let cc = std::env::var("CC").unwrap_or_else(|_| "cc".to_string());
    let compiled = Command::new(&cc)
        .args(["-std=c99", "-Wall", "-Wextra", "-Werror", "-pthread", "-I"])
        .arg(crate_dir().join("include"))
        .arg(crate_dir().join(format!("examples/{name}.c")))
        .arg("-L")
        .arg(&lib)
        .args(["-lneural_brdf", "-lm", "-o"])
        .arg(&exe)
        .output()
        .unwrap_or_else(|e| panic!("cannot run the C compiler '{cc}': {e}"));
    assert!(compiled.status.success(), "C compile of {name}.c failed:\n{}", String::from_utf8_lossy(&compiled.stderr));
    exe
}

/// Starts `program` with `args` (under `wrapper`, e.g. Valgrind, when given) with the library
/// on the loader's path, its output captured.
fn start_c(wrapper: &[&str], program: &Path, args: &[&std::ffi::OsStr]) -> std::process::Child {
    let lib = library_dir();
    let mut command = match wrapper.split_first() {
        Some((first, rest)) => {
            let mut c = Command::new(first);
            c.args(rest).arg(program);
            c
        }
        None => Command::new(program),
    };
    command
        .args(args)
        .env("LD_LIBRARY_PATH", &lib)
        .env("DYLD_LIBRARY_PATH", &lib)
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap_or_else(|e| panic!("run {}: {e}", program.display()))
}

/// Runs `program` as [`start_c`] starts it, to its end.
fn run_c(wrapper: &[&str], program: &Path, args: &[&std::ffi::OsStr]) -> std::process::Output {
    start_c(wrapper, program, args).wait_with_output().expect("wait for the C program")
}

#[test]
fn c_example_runs_against_the_shipped_latent_file() {
    let dir = tempfile::tempdir().expect("tempdir");
    let exe = compile("example", dir.path());
    let latent = crate_dir().join("../../scenes/materials/latent.bin");
    let run = |args: &[&Path]| {
        let args: Vec<&std::ffi::OsStr> = args.iter().map(|p| p.as_os_str()).collect();
        run_c(&[], &exe, &args)
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

/// Eight threads share a code and a mixture and call eval, pdf and sample 3,000 times each
/// (batches of 4 pairs): every result equals, bit for bit, what one thread got for the same
/// batch (the throughput figures in docs/fuzzing.md come from the same program at 10 M calls).
#[test]
fn eight_threads_get_one_threads_results() {
    let dir = tempfile::tempdir().expect("tempdir");
    let exe = compile("threads", dir.path());
    let latent = crate_dir().join("../../scenes/materials/latent.bin");
    let out = run_c(&[], &exe, &[latent.as_os_str(), "8".as_ref(), "3000".as_ref(), "4".as_ref()]);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success() && stdout.contains("ok"), "{stdout}\n{}", String::from_utf8_lossy(&out.stderr));
    println!("{stdout}");
}

/// The C example and the multi-threaded client under Valgrind's memcheck: no invalid read
/// or write, no use of an uninitialised value, no definite leak (exit code 99 otherwise).
/// On a cheap latent file (`renderer::testing::latent::write_cheap_latent_file`) to keep it to seconds. Needs `valgrind`
/// (`.ci/run` installs it).
#[test]
fn c_clients_are_clean_under_valgrind() {
    let dir = tempfile::tempdir().expect("tempdir");
    let (example, threads) = (compile("example", dir.path()), compile("threads", dir.path()));
    let latent = dir.path().join("cheap.bin");
    renderer::testing::latent::write_cheap_latent_file(&latent).expect("write the cheap latent file");
    let valgrind = ["valgrind", "-q", "--error-exitcode=99", "--leak-check=full", "--errors-for-leak-kinds=definite"];
    let scratch = dir.path().join("wrong-version.bin");
    // Both at once (Valgrind runs a program's threads one at a time): ~30 s on 2 cores.
    let started = std::time::Instant::now();
    let children = [
        (&example, start_c(&valgrind, &example, &[latent.as_os_str(), scratch.as_os_str()])),
        (&threads, start_c(&valgrind, &threads, &[latent.as_os_str(), "8".as_ref(), "48".as_ref(), "3".as_ref()])),
    ];
    for (exe, child) in children {
        let out = child.wait_with_output().expect("wait for valgrind");
        let (stdout, stderr) = (String::from_utf8_lossy(&out.stdout), String::from_utf8_lossy(&out.stderr));
        assert!(out.status.success() && stdout.contains("ok"), "{} under valgrind: {:?}\n{stdout}\n{stderr}", exe.display(), out.status);
        println!("{stdout}{stderr}{} under valgrind: done after {:.1} s", exe.display(), started.elapsed().as_secs_f64());
    }
}
