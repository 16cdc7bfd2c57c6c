//! MERL-layout tables made from other BRDF representations: NBRDF networks evaluated at the
//! bin centres, the per-bin median of a set of tables (the f_ref of the log-relative mapping,
//! Nielsen et al. 2015) and analytic models. Files are written atomically
//! ([`MerlTable::write`]), so an interrupted run never leaves a partial
//! table under a final name.

use crate::{Error, Result};
use rayon::prelude::*;
use renderer::analytic::AnalyticBrdf;
use renderer::formats::merl::{MerlReader, MerlTable, BIN_COUNT, FILE_BYTES};
use renderer::neural::nbrdf::{list_networks, NbrdfNetwork};


use std::path::{Path, PathBuf};

/// Extension of MERL table files.
pub const TABLE_EXTENSION: &str = "binary";

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
            let path = out_dir.join(format!("{name}.{TABLE_EXTENSION}"));
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

/// The `.binary` files of a directory, sorted, leaving out `exclude` (e.g. the output).
pub fn tables_in(dir: &Path, exclude: Option<&Path>) -> Result<Vec<PathBuf>> {
    let exclude = exclude.and_then(|p| p.canonicalize().ok());
    let mut paths = Vec::new();
    for entry in std::fs::read_dir(dir).map_err(|e| Error::io(dir, e))? {
        let path = entry.map_err(|e| Error::io(dir, e))?.path();
        if path.extension().is_some_and(|e| e == TABLE_EXTENSION)
            && path.is_file()
            && (exclude.is_none() || path.canonicalize().ok() != exclude)
        {
            paths.push(path);
        }
    }
    paths.sort();
    if paths.is_empty() {
        return Err(Error::invalid_file(
            dir,
            "no .binary tables in this directory",
        ));
    }
    Ok(paths)
}

/// Median of the non-negative (measured) values; −1 (unmeasured) when there are none. The
/// mean of the two middle values for an even count. Reorders `values`.
pub fn median_of_measured(values: &mut Vec<f64>) -> f64 {
    values.retain(|&v| v >= 0.0);
    let n = values.len();
    if n == 0 {
        return -1.0;
    }
    let (lower, upper, _) = values.select_nth_unstable_by(n / 2, f64::total_cmp);
    let upper = *upper;
    if n % 2 == 1 {
        upper
    } else {
        let below = lower.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        0.5 * (below + upper)
    }
}

/// Values per chunk of the streamed median (per file: 512 KiB).
const MEDIAN_CHUNK: usize = 1 << 16;

/// The per-bin, per-channel median of the tables at `paths`, unmeasured (negative) entries
/// left out (a bin unmeasured in every table stays unmeasured). The files are validated
/// first and then streamed in chunks, so memory stays at about 0.5 MiB per table.
/// `progress(done, total)` reports chunks.
pub fn median_table(paths: &[PathBuf], progress: impl Fn(usize, usize)) -> Result<MerlTable> {
    if paths.is_empty() {
        return Err(Error::Invalid(
            "median of no tables: give at least one input table".to_string(),
        ));
    }
    let mut readers = paths
        .iter()
        .map(MerlReader::open)
        .collect::<renderer::Result<Vec<_>>>()?;
    let total = 3 * BIN_COUNT;
    let chunks = total.div_ceil(MEDIAN_CHUNK);
    let mut raw = vec![0f64; total];
    let mut buffers = vec![vec![0f64; MEDIAN_CHUNK]; readers.len()];
    for (chunk, out) in raw.chunks_mut(MEDIAN_CHUNK).enumerate() {
        let first = chunk * MEDIAN_CHUNK;
        for (reader, buffer) in readers.iter_mut().zip(buffers.iter_mut()) {
            reader.read_raw(first, &mut buffer[..out.len()])?;
        }
        out.par_iter_mut().enumerate().for_each_init(
            || Vec::with_capacity(buffers.len()),
            |values, (k, o)| {
                values.clear();
                values.extend(buffers.iter().map(|b| b[k]));
                *o = median_of_measured(values);
            },
        );
        progress(chunk + 1, chunks);
    }
    Ok(MerlTable::from_raw(raw, "median table")?)
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
    fn median_of_measured_values() {
        assert_eq!(median_of_measured(&mut vec![3.0, -1.0, 1.0, 2.0]), 2.0);
        assert_eq!(median_of_measured(&mut vec![4.0, 1.0, -1.0, 2.0, 3.0]), 2.5);
        assert_eq!(median_of_measured(&mut vec![-1.0, -2.0]), -1.0);
        assert_eq!(median_of_measured(&mut vec![0.0]), 0.0);
    }

    #[test]
    fn median_table_of_three_and_unmeasured_bins() {
        let dir = tempfile::tempdir().unwrap();
        let mut paths = Vec::new();
        for (k, v) in [0.1f32, 0.3, 0.2].into_iter().enumerate() {
            let t = MerlTable::from_fn(move |th, _, _| {
                if th > 1.0 && k > 0 {
                    Rgb::splat(-1.0)
                } else {
                    Rgb::splat(v)
                }
            });
            let p = dir.path().join(format!("t{k}.binary"));
            t.write(&p).unwrap();
            paths.push(p);
        }
        let median = median_table(&paths, |_, _| {}).unwrap();
        let low = median.value(bin_index(10, 10, 10));
        assert!(
            (low[0] - 0.2).abs() < 1e-7 && (low[2] - 0.2).abs() < 1e-7,
            "{low:?}"
        );
        // Above θh = 1 only table 0 is measured.
        let high = median.value(bin_index(89, 10, 10));
        assert!((high[1] - 0.1).abs() < 1e-7, "{high:?}");
        assert_eq!(
            tables_in(dir.path(), Some(&paths[0])).unwrap(),
            paths[1..].to_vec()
        );
    }

    #[test]
    fn median_rejects_bad_input_naming_it() {
        let dir = tempfile::tempdir().unwrap();
        let bad = dir.path().join("bad.binary");
        std::fs::write(&bad, [1u8; 64]).unwrap();
        let e = median_table(&[bad], |_, _| {}).unwrap_err().to_string();
        assert!(e.contains("bad.binary"), "{e}");
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
