//! Small utilities both crates use, each defined once: atomic file writes, the FNV-1a
//! checksum of the binary formats, CPU-feature detection for the vectorised kernels, the
//! `WIDTHxHEIGHT` resolution argument, cache prefetches, and the command lines' handling of a
//! closed stdout.

use crate::{Error, Result};
use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

/// The temporary name a file is written under before it is renamed to `path`: hidden, in
/// the same directory (so the rename is atomic), unique per process.
fn temporary_path(path: &Path) -> PathBuf {
    let name = path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
    path.with_file_name(format!(".{name}.partial-{}", std::process::id()))
}

/// Writes `path` atomically: `write` creates and fills the temporary file it is given (see
/// [`temporary_path`]), which is then renamed over `path`. On any error the temporary file
/// is removed and `path` is left as it was, so an interrupted or failed write never leaves a
/// partial file under the requested name.
pub fn write_via_temporary(path: &Path, write: impl FnOnce(&Path) -> Result<()>) -> Result<()> {
    let tmp = temporary_path(path);
    let result = write(&tmp).and_then(|()| std::fs::rename(&tmp, path).map_err(|e| Error::io(path, e)));
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    result
}

/// [`write_via_temporary`] for content written through a buffered writer; the file is
/// synced before the rename. I/O errors name `path`.
pub fn write_atomically(path: &Path, write: impl FnOnce(&mut BufWriter<File>) -> std::io::Result<()>) -> Result<()> {
    write_via_temporary(path, |tmp| {
        let io = |e| Error::io(path, e);
        let mut w = BufWriter::with_capacity(1 << 20, File::create(tmp).map_err(io)?);
        write(&mut w).and_then(|()| w.flush()).map_err(io)?;
        w.into_inner().map_err(|e| io(e.into_error()))?.sync_all().map_err(io)
    })
}

/// Writes `bytes` to `path` atomically (see [`write_atomically`]).
pub fn write_bytes_atomically(path: &Path, bytes: &[u8]) -> Result<()> {
    write_atomically(path, |w| w.write_all(bytes))
}

/// FNV-1a, 64 bit: the checksum of `latent.bin` and of material-nn's checkpoints, and a
/// stable hash of names.
pub fn fnv1a64(bytes: &[u8]) -> u64 {
    bytes.iter().fold(0xcbf2_9ce4_8422_2325u64, |h, &b| (h ^ b as u64).wrapping_mul(0x0000_0100_0000_01b3))
}

/// Starts fetching the cache line that holds `value` into the cache, so that a look-up
/// issued later, after the prefetches of many others, overlaps their memory latencies. No
/// effect on values; a no-op where the CPU has no prefetch hint.
#[inline(always)]
pub fn prefetch<T>(value: &T) {
    #[cfg(target_arch = "x86_64")]
    // SAFETY: a prefetch of the address of a live reference; prefetches never fault.
    unsafe {
        std::arch::x86_64::_mm_prefetch::<{ std::arch::x86_64::_MM_HINT_T0 }>((value as *const T).cast())
    };
    #[cfg(not(target_arch = "x86_64"))]
    let _ = value;
}

/// CPU features the vectorised kernels dispatch on (detected by std once, then cached).
pub mod cpu {
    /// AVX2 (256-bit integer and float vectors).
    #[inline]
    pub fn has_avx2() -> bool {
        #[cfg(target_arch = "x86_64")]
        {
            std::arch::is_x86_feature_detected!("avx2")
        }
        #[cfg(not(target_arch = "x86_64"))]
        {
            false
        }
    }

    /// AVX2 and FMA.
    #[inline]
    pub fn has_avx2_fma() -> bool {
        #[cfg(target_arch = "x86_64")]
        {
            std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma")
        }
        #[cfg(not(target_arch = "x86_64"))]
        {
            false
        }
    }

    /// AVX-512F.
    #[inline]
    pub fn has_avx512f() -> bool {
        #[cfg(target_arch = "x86_64")]
        {
            std::arch::is_x86_feature_detected!("avx512f")
        }
        #[cfg(not(target_arch = "x86_64"))]
        {
            false
        }
    }
}

/// The largest image width or height the renderer makes or reads as a render's part.
pub const MAX_RESOLUTION: u32 = 16384;

/// Makes a command-line program end quietly when the reader of its standard output goes away
/// (`material-nn … | head -n 1`), as Unix tools do: the default action of SIGPIPE, which
/// Rust's runtime ignores, so that `println!` would panic on the broken pipe instead. Call
/// first thing in `main`; files the program has finished writing stay as they are (they are
/// written atomically), and none is left half-written.
pub fn exit_quietly_on_broken_pipe() {
    #[cfg(unix)]
    // SAFETY: restores the default disposition of one signal before any thread is started.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
}

/// Parses an image size `WIDTHxHEIGHT` (or `WIDTHXHEIGHT`), both in 1..=[`MAX_RESOLUTION`] pixels: the
/// `--resolution` argument of both command lines.
pub fn parse_resolution(s: &str) -> std::result::Result<(u32, u32), String> {
    let parsed = s
        .split_once(['x', 'X'])
        .and_then(|(w, h)| Some((w.trim().parse::<u32>().ok()?, h.trim().parse::<u32>().ok()?)));
    match parsed {
        Some((w, h)) if (1..=MAX_RESOLUTION).contains(&w) && (1..=MAX_RESOLUTION).contains(&h) => Ok((w, h)),
        _ => Err(format!("'{s}' is not WIDTHxHEIGHT with both in 1..={MAX_RESOLUTION} (e.g. 128x128)")),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn atomic_writes_replace_whole_files_or_nothing() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("a.bin");
        write_bytes_atomically(&path, b"first").unwrap();
        write_bytes_atomically(&path, b"second").unwrap();
        assert_eq!(std::fs::read(&path).unwrap(), b"second");
        let failed = write_atomically(&path, |w| {
            w.write_all(b"half")?;
            Err(std::io::Error::other("disk full"))
        });
        assert!(failed.unwrap_err().to_string().contains("a.bin"));
        assert_eq!(std::fs::read(&path).unwrap(), b"second");
        let names: Vec<_> = std::fs::read_dir(dir.path()).unwrap().map(|e| e.unwrap().file_name()).collect();
        assert_eq!(names, vec![std::ffi::OsString::from("a.bin")], "no temporary file is left");
    }

    #[test]
    fn fnv1a64_matches_the_reference_values() {
        // Test vectors of the FNV reference implementation.
        assert_eq!(fnv1a64(b""), 0xcbf2_9ce4_8422_2325);
        assert_eq!(fnv1a64(b"a"), 0xaf63_dc4c_8601_ec8c);
        assert_eq!(fnv1a64(b"foobar"), 0x8594_4171_f739_67e8);
    }

    #[test]
    fn resolutions_parse_within_bounds() {
        assert_eq!(parse_resolution("128x64"), Ok((128, 64)));
        assert_eq!(parse_resolution(" 3 X 4 "), Ok((3, 4)));
        for bad in ["0x4", "4x16385", "4", "ax4", "4x-1"] {
            assert!(parse_resolution(bad).unwrap_err().contains("WIDTHxHEIGHT"), "{bad}");
        }
    }
}
