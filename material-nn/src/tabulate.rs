//! MERL-layout tables made from other BRDF representations: NBRDF networks evaluated at the
//! bin centres, the per-bin median of a set of tables (the f_ref of the log-relative mapping,
//! Nielsen et al. 2015) and analytic models. Files are written atomically
//! ([`MerlTable::write`]), so an interrupted run never leaves a partial
//! table under a final name.

use crate::{Error, Result};
use rayon::prelude::*;
use renderer::analytic::AnalyticBrdf;
use renderer::formats::merl::{MerlTable, FILE_BYTES};
use renderer::neural::nbrdf::{list_networks, NbrdfNetwork};


use std::path::{Path, PathBuf};

/// The table of an NBRDF network: f_r at every bin centre (φd ∈ (0, π), as the networks were
/// trained), including the configurations below the horizon, where the network extrapolates.
pub fn table_from_network(network: &NbrdfNetwork) -> MerlTable {
    MerlTable::from_fn(|th, td, pd| network.eval_angles(th, td, pd))
}

/// The table of an analytic model at every bin centre. Bins whose configuration puts wi or
/// wo below the horizon (θh + θd beyond π/2 for some φd), where the model is undefined, are
/// marked unmeasured (−1), as a measurement would leave them.
pub fn table_from_analytic(brdf: &AnalyticBrdf) -> MerlTable {
    MerlTable::from_fn(|theta_h, theta_d, phi_d| {
        let angles = renderer::brdf_coords::HalfDiffAngles {
            theta_h,
            phi_h: 0.0,
            theta_d,
            phi_d,
        };
        let (wi, wo) = renderer::brdf_coords::directions_from_angles(&angles);
        if wi.z > 0.0 && wo.z > 0.0 {
            brdf.eval(wo, wi)
        } else {
            renderer::Rgb::splat(-1.0)
        }
    })
}

/// The networks to tabulate: all of `dir`, or the `selected` names (each must exist).
pub fn select_networks(dir: &Path, selected: Option<&[String]>) -> Result<Vec<String>> {
    let available = list_networks(dir)?;
    if available.is_empty() {
        return Err(Error::invalid_file(
            dir,
            "no NBRDF networks (*_fc1.npy) in this directory",
        ));
    }
    let Some(selected) = selected else {
        return Ok(available);
    };
    for name in selected {
        if !available.contains(name) {
            return Err(renderer::Error::UnknownName {
                what: "NBRDF network",
                name: dir.join(name).display().to_string(),
                available,
            }
            .into());
        }
    }
    Ok(selected.to_vec())
}

/// What happened to one table of [`tabulate_networks`].
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum TableOutcome {
    /// Written now.
    Written(PathBuf),
    /// Already present with the right size; left as it was.
    Skipped(PathBuf),
}

/// Whether `path` holds a table of the right size (what an atomic write leaves).
fn table_present(path: &Path) -> bool {
    std::fs::metadata(path).is_ok_and(|m| m.is_file() && m.len() == FILE_BYTES)
}

/// Tabulates the networks `names` of `nbrdf_dir` into `out_dir/NAME.binary` (in parallel),
/// skipping tables already present so an interrupted run resumes. `progress` is called once
/// per table as it completes. The first error stops the run (tables already written stay).
pub fn tabulate_networks(
    nbrdf_dir: &Path,
    names: &[String],
    out_dir: &Path,
    progress: impl Fn(&TableOutcome) + Sync,
) -> Result<Vec<TableOutcome>> {
    std::fs::create_dir_all(out_dir).map_err(|e| Error::io(out_dir, e))?;
    names
        .par_iter()
        .with_max_len(1)
        .map(|name| {
            let path = crate::tables::table_path(out_dir, name);
            let outcome = if table_present(&path) {
                TableOutcome::Skipped(path)
            } else {
                let network = NbrdfNetwork::load(nbrdf_dir.join(name))?;
                table_from_network(&network).write(&path)?;
                TableOutcome::Written(path)
            };
            progress(&outcome);
            Ok(outcome)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use renderer::formats::merl::{bin_centre, bin_index};
    use renderer::Rgb;

    fn data_dir() -> PathBuf {
        PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../shared/data/nbrdf/merl")
    }

    #[test]
    fn networks_are_tabulated_resumably() {
        let out = tempfile::tempdir().unwrap();
        let names = select_networks(&data_dir(), Some(&["chrome".to_string()])).unwrap();
        let first = tabulate_networks(&data_dir(), &names, out.path(), |_| {}).unwrap();
        let path = out.path().join("chrome.binary");
        assert_eq!(first, vec![TableOutcome::Written(path.clone())]);
        let leftovers: Vec<_> = std::fs::read_dir(out.path()).unwrap().map(|e| e.unwrap().file_name()).filter(|n| n.to_string_lossy().contains("partial")).collect();
        assert!(leftovers.is_empty(), "{leftovers:?}");
        let table = MerlTable::read(&path).unwrap();
        let net = NbrdfNetwork::load(data_dir().join("chrome")).unwrap();
        let i = bin_index(0, 17, 0);
        let [th, td, pd] = bin_centre(i);
        let want = net.eval_angles(th as f32, td as f32, pd as f32);
        assert_eq!(table.value(i).map(|v| v as f32), want.to_array());
        let second = tabulate_networks(&data_dir(), &names, out.path(), |_| {}).unwrap();
        assert_eq!(second, vec![TableOutcome::Skipped(path)]);
    }

    #[test]
    fn analytic_tables_mark_below_horizon_bins_unmeasured() {
        let brdf = AnalyticBrdf::OrenNayar {
            albedo: Rgb::splat(0.5),
            sigma: 0.0,
        };
        let table = table_from_analytic(&brdf);
        // θh = θd ≈ 0: both directions near the normal, Lambert 0.5/π.
        let v = table.value(bin_index(0, 0, 0));
        assert!((v[0] - 0.5 / std::f64::consts::PI).abs() < 1e-6, "{v:?}");
        // θh ≈ θd ≈ 80°, φd ≈ 0: wi.z = cos(θh + θd) < 0. At φd ≈ 90° both are above.
        assert!(!table.is_measured(bin_index(85, 80, 0)));
        assert!(table.is_measured(bin_index(85, 80, 90)));
        assert!(table.unmeasured_count() > 0);
    }

    #[test]
    fn unknown_network_names_the_directory() {
        let e = select_networks(&data_dir(), Some(&["chrom".to_string()]))
            .unwrap_err()
            .to_string();
        assert!(e.contains("merl/chrom'") && e.contains("chrome"), "{e}");
    }
}
