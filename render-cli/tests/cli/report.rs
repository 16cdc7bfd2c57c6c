//! `render report CONFIG.toml` end to end on a tiny configuration, and its bad-input errors.

use crate::common::{assert_clean_failure, render, repo_file};
use renderer::formats::merl::MerlTable;
use renderer::neural::nbrdf::NbrdfNetwork;

#[test]
fn tiny_report_writes_csv_plot_and_table() {
    let dir = tempfile::tempdir().expect("tempdir");
    let shared = repo_file("../shared/data/nbrdf/merl");
    let net = NbrdfNetwork::load(shared.join("alum-bronze")).expect("network");
    let table = dir.path().join("alum-bronze.binary");
    MerlTable::from_fn(|th, td, pd| net.eval_angles(th, td, pd)).write(&table).expect("table");
    let config = format!(
        r#"scene = "{scene}"
material = "preview"
materials = ["alum-bronze"]
resolution = [16, 16]
reference = "merl:{dir}/{{name}}.binary"
reference_spp = 16
time_budget = 0.4
table_budgets = [0.1, 0.4]
output = "{dir}/report"

[[representations]]
label = "MERL table"
bind = "merl:{dir}/{{name}}.binary"

[[representations]]
label = "NBRDF"
bind = "nbrdf:{shared}/{{name}}"

[[representations]]
label = "FreNBRDF"
latent = "{latent}"
bind = "{{name}}"

[[representations]]
label = "missing"
latent = "{dir}/nothing.bin"
bind = "{{name}}"
optional = true
"#,
        scene = repo_file("scenes/material-preview/scene.gltf").display(),
        dir = dir.path().display(),
        shared = shared.display(),
        latent = repo_file("scenes/materials/latent.bin").display(),
    );
    std::fs::write(dir.path().join("report.toml"), config).unwrap();
    let out = render(&["report", "report.toml"], dir.path());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    assert!(stderr.contains("skipping missing"), "{stderr}");
    let report = dir.path().join("report");
    let md = std::fs::read_to_string(report.join("report.md")).unwrap();
    for label in ["MERL table", "NBRDF", "FreNBRDF"] {
        assert!(md.contains(&format!("| {label} |")), "{md}");
    }
    assert!(!md.contains("| missing |"));
    let csv = std::fs::read_to_string(report.join("errors.csv")).unwrap();
    assert!(csv.lines().count() > 3, "{csv}");
    assert!(csv.lines().skip(1).all(|l| l.split(',').nth(4).unwrap().parse::<f64>().unwrap().is_finite()));
    let plot = image::open(report.join("error-vs-time.png")).expect("plot");
    assert_eq!(plot.width(), 640);
}

#[test]
fn bad_configs_fail_cleanly() {
    let dir = tempfile::tempdir().expect("tempdir");
    std::fs::write(dir.path().join("broken.toml"), "scene = [").unwrap();
    std::fs::write(
        dir.path().join("empty.toml"),
        "scene = \"s.gltf\"\nmaterial = \"m\"\nmaterials = []\nresolution = [8, 8]\nreference = \"merl:x\"\nreference_spp = 4\ntime_budget = 1.0\ntable_budgets = [1.0]\noutput = \"out\"\nrepresentations = []\n",
    )
    .unwrap();
    for (file, needle) in [("broken.toml", "broken.toml"), ("empty.toml", "at least one"), ("missing.toml", "missing.toml")] {
        let out = render(&["report", file], dir.path());
        assert_clean_failure(&out, &[needle], dir.path());
    }
}
