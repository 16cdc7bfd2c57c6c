//! The `material-nn tabulate` command line: outputs, and one-line errors with exit code 2.

use crate::common::{error_line, path_str};
use std::path::PathBuf;
use std::process::{Command, Output};

fn material_nn(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_material-nn"))
        .args(args)
        .output()
        .expect("material-nn runs")
}

fn nbrdf_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../shared/data/nbrdf/merl")
}

#[test]
fn analytic_and_median_tables_are_written() {
    let dir = tempfile::tempdir().unwrap();
    let (a, b) = (dir.path().join("a.binary"), dir.path().join("b.binary"));
    for (kind, path) in [("ggx", &a), ("oren-nayar", &b)] {
        let out = material_nn(&[
            "tabulate",
            "--analytic",
            kind,
            "--albedo",
            "0.5,0.3,0.1",
            "--out",
            path_str(path),
        ]);
        assert!(out.status.success(), "{out:?}");
        assert_eq!(
            std::fs::metadata(path).unwrap().len(),
            renderer::formats::merl::FILE_BYTES
        );
    }
    let median = dir.path().join("median.binary");
    let out = material_nn(&[
        "tabulate",
        "--median",
        "--out",
        path_str(&median),
        path_str(&a),
        path_str(&b),
    ]);
    assert!(out.status.success(), "{out:?}");
    let m = renderer::formats::merl::MerlTable::read(&median).unwrap();
    let (ta, tb) = (
        renderer::formats::merl::MerlTable::read(&a).unwrap(),
        renderer::formats::merl::MerlTable::read(&b).unwrap(),
    );
    let i = renderer::formats::merl::bin_index(30, 40, 50);
    let (va, vb, vm) = (ta.value(i), tb.value(i), m.value(i));
    assert!((vm[0] - 0.5 * (va[0] + vb[0])).abs() < 1e-12, "{vm:?}");
}

#[test]
fn errors_are_one_line_with_exit_code_2() {
    let dir = tempfile::tempdir().unwrap();
    let bad = dir.path().join("short.binary");
    let mut bytes: Vec<u8> = [90i32, 90, 180]
        .iter()
        .flat_map(|d| d.to_le_bytes())
        .collect();
    bytes.extend_from_slice(&[0u8; 28]);
    std::fs::write(&bad, bytes).unwrap();
    let out_file = dir.path().join("m.binary");
    let e = error_line(&material_nn(&[
        "tabulate",
        "--median",
        "--out",
        path_str(&out_file),
        path_str(&bad),
    ]));
    assert!(e.contains("short.binary") && e.contains("truncated"), "{e}");
    assert!(!out_file.exists());

    let e = error_line(&material_nn(&[
        "tabulate",
        "--nbrdf",
        path_str(&nbrdf_dir()),
        "--materials",
        "chrome,no-such-material",
        "--out",
        path_str(dir.path()),
    ]));
    assert!(e.contains("no-such-material"), "{e}");

    let e = error_line(&material_nn(&[
        "tabulate",
        "--nbrdf",
        path_str(dir.path()),
        "--out",
        path_str(dir.path()),
    ]));
    assert!(e.contains("no NBRDF networks"), "{e}");

    // Usage errors (clap) also exit with 2.
    let out = material_nn(&["tabulate", "--analytic", "phong", "--out", "x.binary"]);
    assert_eq!(out.status.code(), Some(2));
}

/// With its standard output closed early (`material-nn … | head -c 0`), the command still
/// writes its table and ends quietly (killed by SIGPIPE, as Unix tools are), without the
/// panic of `println!` on a broken pipe.
#[cfg(unix)]
#[test]
fn a_closed_stdout_ends_the_command_quietly() {
    use std::os::unix::process::ExitStatusExt;
    use std::process::Stdio;
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("ggx.binary");
    let mut child = Command::new(env!("CARGO_BIN_EXE_material-nn"))
        .args(["tabulate", "--analytic", "ggx", "--albedo", "0.5,0.3,0.1", "--out", path_str(&path)])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("material-nn runs");
    drop(child.stdout.take());
    let out = child.wait_with_output().expect("material-nn ends");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!stderr.contains("panicked"), "{stderr}");
    const SIGPIPE: i32 = 13;
    assert!(out.status.success() || out.status.signal() == Some(SIGPIPE), "{out:?}");
    assert_eq!(std::fs::metadata(&path).unwrap().len(), renderer::formats::merl::FILE_BYTES);
}
