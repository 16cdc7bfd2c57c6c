//! Runs the Python package's tests (tests/test_*.py, pytest) against this checkout (the
//! cross-check with `render` included, using the `render` binary of this build): the
//! extension module `cargo test` just built (examples/native_module.rs) is put beside the
//! package's Python files in `target/*/python-plugin/`, which pytest imports first. Needs
//! python3 with numpy, pytest and mitsuba (`.ci/run` installs them) and libLLVM for
//! Mitsuba's LLVM variant (found as in DESIGN.md, or given by DRJIT_LIBLLVM_PATH).

use renderer::formats::merl::MerlTable;
use renderer::neural::nbrdf::NbrdfNetwork;
use std::path::{Path, PathBuf};
use std::process::Command;

fn crate_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// `target/<profile>`: the test binary lives in its `deps/`.
fn profile_dir() -> PathBuf {
    let exe = std::env::current_exe().expect("test executable");
    exe.parent().and_then(Path::parent).expect("target directory").to_path_buf()
}

/// Cargo's name of this build's profile (`target/debug` is the `dev` profile).
fn profile_name() -> String {
    match profile_dir().file_name().and_then(|n| n.to_str()) {
        Some("debug") | None => "dev".to_string(),
        Some(other) => other.to_string(),
    }
}

/// The package (Python sources + the freshly built extension module) in a directory to put
/// first on PYTHONPATH.
fn assemble_package() -> PathBuf {
    let root = profile_dir().join("python-plugin");
    let package = root.join("neural_brdf");
    std::fs::create_dir_all(&package).expect("create the package directory");
    let sources = crate_dir().join("python/neural_brdf");
    for entry in std::fs::read_dir(&sources).expect("python/neural_brdf") {
        let path = entry.expect("directory entry").path();
        if path.is_file() {
            std::fs::copy(&path, package.join(path.file_name().unwrap())).expect("copy a package file");
        }
    }
    let module = built(&["--example", "native_module"], "examples/libnative_module.so");
    std::fs::copy(&module, package.join("_native.abi3.so")).expect("copy the extension module");
    root
}

/// A MERL table tabulated from the shared NBRDF network of gold-metallic-paint3 (made once
/// per target directory).
fn merl_table() -> PathBuf {
    let path = profile_dir().join("python-plugin/gold-metallic-paint3.binary");
    if !path.is_file() {
        let network = crate_dir().join("../../../shared/data/nbrdf/merl/gold-metallic-paint3");
        let net = NbrdfNetwork::load(&network).expect("the shared NBRDF network");
        MerlTable::from_fn(|th, td, pd| net.eval_angles(th, td, pd)).write(&path).expect("write the table");
    }
    path
}

/// The `render` binary of this build (the cross-check renders with it): built by
/// `cargo test --workspace` already; otherwise built here, with this test's profile.
///
/// It is selected with `--workspace` so that cargo resolves dependency features over the
/// whole workspace, as `cargo test --workspace` did: `-p render-cli` alone would resolve
/// fewer features for shared dependencies (serde, half, syn, ...) and rebuild most of the
/// dependency tree under different hashes, minutes of a cold CI run.
fn render_binary() -> PathBuf {
    built(&["--bin", "render"], "render")
}

/// `target/<profile>/<path>` of the `target` (cargo's selection: `--bin render`, `--example
/// native_module`) built now with this test's profile, so that a test run alone (`cargo test
/// --test python`, which builds no example) never uses a stale one; cargo only checks it is
/// up to date after `cargo test --workspace`.
fn built(target: &[&str], path: &str) -> PathBuf {
    let path = profile_dir().join(path);
    let profile = profile_name();
    let cargo = std::env::var_os("CARGO").unwrap_or_else(|| env!("CARGO").into());
    let status = Command::new(cargo)
        .args(["build", "--quiet", "--workspace"])
        .args(target)
        .args(["--profile", &profile])
        .current_dir(crate_dir())
        .status()
        .expect("run cargo build");
    assert!(status.success() && path.is_file(), "cannot build {}", path.display());
    path
}

/// libLLVM for Dr.Jit's LLVM backend: DRJIT_LIBLLVM_PATH, else Debian's libllvm19.
fn libllvm() -> Option<PathBuf> {
    if let Some(path) = std::env::var_os("DRJIT_LIBLLVM_PATH") {
        return Some(path.into());
    }
    ["/usr/lib/x86_64-linux-gnu/libLLVM-19.so", "/usr/lib/x86_64-linux-gnu/libLLVM.so.19.1", "/usr/lib/aarch64-linux-gnu/libLLVM-19.so"]
        .iter()
        .map(PathBuf::from)
        .find(|p| p.is_file())
}

#[test]
fn pytest_suite_passes() {
    let package = assemble_package();
    let table = merl_table();
    let mut command = Command::new("python3");
    command
        .args(["-m", "pytest", "-q", "-p", "no:cacheprovider"])
        .arg(crate_dir().join("tests"))
        .env("PYTHONPATH", &package)
        .env("NEURAL_BRDF_TABLE", &table)
        .env("NEURAL_BRDF_LATENT", crate_dir().join("../../scenes/materials/latent.bin"))
        .env("NEURAL_BRDF_NETWORK", crate_dir().join("../../../shared/data/nbrdf/merl/chrome"))
        .env("NEURAL_BRDF_RENDER_BIN", render_binary());
    if let Some(llvm) = libllvm() {
        command.env("DRJIT_LIBLLVM_PATH", llvm);
    }
    let output = command.output().expect("run python3 -m pytest (python3 with numpy, pytest and mitsuba; see .ci/run)");
    let log = format!("{}{}", String::from_utf8_lossy(&output.stdout), String::from_utf8_lossy(&output.stderr));
    assert!(output.status.success(), "pytest failed:\n{log}");
    assert!(!log.contains(" skipped"), "pytest skipped tests:\n{log}");
    println!("{log}");
}

/// `pip install ./plugins/python` works: maturin builds the package from pyproject.toml into
/// a fresh directory, from which it imports and evaluates a material. It builds at the
/// unoptimised `pip-test` profile (Cargo.toml says why; users get a release build).
#[test]
fn pip_installs_the_package() {
    let dir = tempfile::tempdir().expect("tempdir");
    let profile = "pip-test";
    let output = Command::new("python3")
        .args(["-m", "pip", "install", "--quiet", "--no-deps", "--no-build-isolation", "--disable-pip-version-check", "--target"])
        .arg(dir.path())
        .arg(format!("--config-settings=build-args=--profile {profile}"))
        .arg(crate_dir())
        .env("CARGO_TARGET_DIR", profile_dir().parent().expect("target directory"))
        .output()
        .expect("run python3 -m pip (needs maturin, see .ci/run)");
    assert!(output.status.success(), "pip install failed:\n{}", String::from_utf8_lossy(&output.stderr));
    let script = "import neural_brdf, sys\n\
        m = neural_brdf.Material.open(sys.argv[1], 'alum-bronze')\n\
        f = m.eval([[0.0, 0.6, 0.8]], [[0.0, -0.6, 0.8]])\n\
        assert f.shape == (1, 3) and f.min() > 0, f\n\
        print(neural_brdf.__file__)";
    let run = Command::new("python3")
        .args(["-c", script])
        .arg(crate_dir().join("../../scenes/materials/latent.bin"))
        .env("PYTHONPATH", dir.path())
        .output()
        .expect("run python3");
    let stdout = String::from_utf8_lossy(&run.stdout);
    assert!(run.status.success(), "the installed package fails:\n{stdout}{}", String::from_utf8_lossy(&run.stderr));
    assert!(stdout.trim().starts_with(&*dir.path().to_string_lossy()), "imported from {stdout}");
}
