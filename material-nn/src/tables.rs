//! The table files of a data directory: MERL-layout `.binary` tables named after their
//! material, listed, named and combined (the per-bin median that becomes f_ref).

use crate::{Error, Result};
use rayon::prelude::*;
use renderer::formats::merl::{MerlReader, MerlTable, BIN_COUNT};
use std::path::{Path, PathBuf};

/// Extension of MERL table files.
pub const TABLE_EXTENSION: &str = "binary";

/// The table of material `name` in directory `dir`: `DIR/NAME.binary`.
pub fn table_path(dir: &Path, name: &str) -> PathBuf {
    dir.join(format!("{name}.{TABLE_EXTENSION}"))
}

/// The material name of a table path (its file stem).
pub fn material_name(path: &Path) -> Result<String> {
    path.file_stem()
        .and_then(|s| s.to_str())
        .map(str::to_string)
        .ok_or_else(|| Error::invalid_file(path, "table file name is not valid UTF-8"))
}

/// The `.binary` tables of a directory, sorted by name, leaving out `exclude` (e.g. an
/// output file in the same directory). Errors if there are none.
pub fn list_tables(dir: &Path, exclude: Option<&Path>) -> Result<Vec<PathBuf>> {
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
    if paths.is_empty() {
        return Err(Error::invalid_file(dir, "no MERL tables (*.binary) in this directory"));
    }
    paths.sort();
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
/// first and then streamed in chunks, so memory stays at about 0.5 MiB per table and no
/// file stays open.
/// `progress(done, total)` reports chunks.
pub fn median_table(paths: &[PathBuf], progress: impl Fn(usize, usize)) -> Result<MerlTable> {
    let raw = median_values(paths, |_, v| v, progress)?;
    Ok(MerlTable::from_raw(raw, "median table")?)
}

/// The per-entry median of `value(channel, raw)` over the tables at `paths`, in the files'
/// channel-major order, negative values (unmeasured) left out and −1 where every table's is
/// negative; streamed as [`median_table`] describes.
pub fn median_values(
    paths: &[PathBuf],
    value: impl Fn(usize, f64) -> f64 + Sync,
    progress: impl Fn(usize, usize),
) -> Result<Vec<f64>> {
    if paths.is_empty() {
        return Err(Error::Invalid(
            "median of no tables: give at least one input table".to_string(),
        ));
    }
    // Every file is checked before any work; each chunk then opens them again, so a median
    // of more tables than the process may hold open works.
    paths.iter().try_for_each(|p| MerlReader::open(p).map(|_| ()))?;
    let total = 3 * BIN_COUNT;
    let chunks = total.div_ceil(MEDIAN_CHUNK);
    let mut out = vec![0f64; total];
    let mut buffers = vec![vec![0f64; MEDIAN_CHUNK]; paths.len()];
    for (chunk, out) in out.chunks_mut(MEDIAN_CHUNK).enumerate() {
        let first = chunk * MEDIAN_CHUNK;
        for (path, buffer) in paths.iter().zip(buffers.iter_mut()) {
            MerlReader::open(path)?.read_raw(first, &mut buffer[..out.len()])?;
        }
        out.par_iter_mut().enumerate().for_each_init(
            || Vec::with_capacity(buffers.len()),
            |values, (k, o)| {
                let channel = (first + k) / BIN_COUNT;
                values.clear();
                values.extend(buffers.iter().map(|b| value(channel, b[k])));
                *o = median_of_measured(values);
            },
        );
        progress(chunk + 1, chunks);
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use renderer::formats::merl::bin_index;
    use renderer::Rgb;

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
            list_tables(dir.path(), Some(&paths[0])).unwrap(),
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
}
