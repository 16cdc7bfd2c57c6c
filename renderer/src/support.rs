//! Small utilities both crates use, each defined once: atomic file writes, the FNV-1a
//! checksum of the binary formats, CPU-feature detection for the vectorised kernels, the
//! `WIDTHxHEIGHT` resolution argument, cache prefetches, huge pages for large tables, and the
//! command lines' handling of a closed stdout.

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

/// Tables smaller than this are left on ordinary pages by [`collect_on_huge_pages`]: one
/// huge page (2 MiB on x86-64).
const HUGE_PAGE_BYTES: usize = 2 << 20;

/// `len` values made by `value(i)`, in a vector whose memory the kernel is asked to back with
/// transparent huge pages before it is first written (Linux: `madvise(MADV_HUGEPAGE)` over
/// the allocation's whole pages, where THP is in `madvise` mode as Debian ships it). For
/// the large tables looked up at random while rendering: with 4 KiB pages each look-up into
/// a 17.5 MB table also misses the TLB. Advice only: where the kernel declines, elsewhere,
/// and for tables under 2 MiB, an ordinary vector with the same values.
pub fn collect_on_huge_pages<T>(len: usize, value: impl FnMut(usize) -> T) -> Vec<T> {
    let mut values = Vec::with_capacity(len);
    if len * std::mem::size_of::<T>() >= HUGE_PAGE_BYTES {
        advise_huge_pages(values.spare_capacity_mut());
    }
    values.extend((0..len).map(value));
    values
}

/// Asks for transparent huge pages over the whole 4 KiB pages of `memory` (not yet written).
fn advise_huge_pages<T>(memory: &mut [std::mem::MaybeUninit<T>]) {
    #[cfg(target_os = "linux")]
    {
        const PAGE: usize = 4096;
        let start = memory.as_mut_ptr() as usize;
        let end = start + std::mem::size_of_val(memory);
        let first = start.next_multiple_of(PAGE);
        if end >= first + PAGE {
            // SAFETY: advice over whole pages inside an allocation the caller owns and has
            // not written; it changes no contents (a refusal is harmless and ignored).
            unsafe { libc::madvise(first as *mut libc::c_void, (end - first) / PAGE * PAGE, libc::MADV_HUGEPAGE) };
        }
    }
    #[cfg(not(target_os = "linux"))]
    let _ = memory;
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

    /// The instruction-set features this build was compiled to assume everywhere (the
    /// workspace's `.cargo/config.toml` builds x86-64 for `target-cpu=x86-64-v3`) that the
    /// running CPU lacks, by their `target_feature` names: empty where the build runs.
    pub fn missing_build_features() -> Vec<&'static str> {
        build_features().into_iter().filter(|&(_, built, present)| built && !present).map(|(name, ..)| name).collect()
    }

    /// Every x86-64 feature a build may assume beyond the baseline: its `target_feature` name,
    /// whether this build was compiled with it, and whether the running CPU has it. Read from
    /// CPUID itself, not `is_x86_feature_detected!`, which answers "present" for every feature
    /// enabled at compile time.
    #[cfg(target_arch = "x86_64")]
    pub(super) fn build_features() -> [(&'static str, bool, bool); 16] {
        use raw_cpuid::{CpuId, ExtendedFeatures, ExtendedProcessorFeatureIdentifiers, FeatureInfo};
        let cpuid = CpuId::new();
        let (basic, extended, amd) = (
            cpuid.get_feature_info(),
            cpuid.get_extended_feature_info(),
            cpuid.get_extended_processor_and_feature_identifiers(),
        );
        let basic = |has: fn(&FeatureInfo) -> bool| basic.as_ref().is_some_and(has);
        let extended = |has: fn(&ExtendedFeatures) -> bool| extended.as_ref().is_some_and(has);
        let amd = |has: fn(&ExtendedProcessorFeatureIdentifiers) -> bool| amd.as_ref().is_some_and(has);
        // AVX needs the operating system to save the YMM registers too (XCR0 bits 1, 2),
        // AVX-512 also the opmask and ZMM registers (bits 5, 6, 7).
        // SAFETY: XCR0 is read only where CPUID reports OSXSAVE.
        let xcr0 = if basic(FeatureInfo::has_oxsave) { unsafe { enabled_register_state() } } else { 0 };
        let avx = basic(FeatureInfo::has_avx) && xcr0 & 0b110 == 0b110;
        let avx512 = avx && xcr0 & 0b1110_0000 == 0b1110_0000;
        [
            ("sse3", cfg!(target_feature = "sse3"), basic(FeatureInfo::has_sse3)),
            ("ssse3", cfg!(target_feature = "ssse3"), basic(FeatureInfo::has_ssse3)),
            ("sse4.1", cfg!(target_feature = "sse4.1"), basic(FeatureInfo::has_sse41)),
            ("sse4.2", cfg!(target_feature = "sse4.2"), basic(FeatureInfo::has_sse42)),
            ("popcnt", cfg!(target_feature = "popcnt"), basic(FeatureInfo::has_popcnt)),
            ("cmpxchg16b", cfg!(target_feature = "cmpxchg16b"), basic(FeatureInfo::has_cmpxchg16b)),
            ("movbe", cfg!(target_feature = "movbe"), basic(FeatureInfo::has_movbe)),
            ("xsave", cfg!(target_feature = "xsave"), basic(FeatureInfo::has_xsave)),
            ("avx", cfg!(target_feature = "avx"), avx),
            ("f16c", cfg!(target_feature = "f16c"), basic(FeatureInfo::has_f16c)),
            ("fma", cfg!(target_feature = "fma"), basic(FeatureInfo::has_fma)),
            ("avx2", cfg!(target_feature = "avx2"), avx && extended(ExtendedFeatures::has_avx2)),
            ("bmi1", cfg!(target_feature = "bmi1"), extended(ExtendedFeatures::has_bmi1)),
            ("bmi2", cfg!(target_feature = "bmi2"), extended(ExtendedFeatures::has_bmi2)),
            ("lzcnt", cfg!(target_feature = "lzcnt"), amd(ExtendedProcessorFeatureIdentifiers::has_lzcnt)),
            ("avx512f", cfg!(target_feature = "avx512f"), avx512 && extended(ExtendedFeatures::has_avx512f)),
        ]
    }

    #[cfg(not(target_arch = "x86_64"))]
    pub(super) fn build_features() -> [(&'static str, bool, bool); 0] {
        []
    }

    /// XCR0: the register state the operating system saves (bit 1 SSE, 2 AVX, 5–7
    /// AVX-512).
    ///
    /// # Safety
    /// CPUID must report OSXSAVE (XGETBV and XSAVE are available then).
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "xsave")]
    unsafe fn enabled_register_state() -> u64 {
        // SAFETY: the caller has checked OSXSAVE.
        unsafe { std::arch::x86_64::_xgetbv(0) }
    }

    /// An error naming the features this build needs and the CPU lacks
    /// ([`missing_build_features`]), or `Ok`. Programs and plugin entry points call it first,
    /// so a CPU older than the build's target gets a one-line error instead of an illegal
    /// instruction.
    pub fn check_build_features() -> crate::Result<()> {
        let missing = missing_build_features();
        if missing.is_empty() {
            Ok(())
        } else {
            Err(crate::Error::UnsupportedCpu { missing })
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

    /// A table on huge pages holds exactly the values asked for, below and above the size
    /// from which huge pages are asked for (and whether the kernel grants them or not).
    #[test]
    fn tables_on_huge_pages_hold_their_values() {
        for len in [0, 1, 1000, HUGE_PAGE_BYTES / 12 + 7, 3 * HUGE_PAGE_BYTES / 12] {
            let table = collect_on_huge_pages(len, |i| [i as u32, (i as u32).wrapping_mul(2_654_435_761), !(i as u32)]);
            assert_eq!(table.len(), len);
            assert!(table.iter().enumerate().all(|(i, v)| *v == [i as u32, (i as u32).wrapping_mul(2_654_435_761), !(i as u32)]));
        }
    }

    /// CPUID is read right: every feature agrees with the kernel's own list in
    /// /proc/cpuinfo, the CPU running the tests has what the build assumes, and a CPU that
    /// lacks features gets a message naming them and how to rebuild.
    #[test]
    fn build_features_are_read_from_cpuid() {
        assert_eq!(cpu::missing_build_features(), Vec::<&str>::new());
        assert!(cpu::check_build_features().is_ok());
        #[cfg(all(target_arch = "x86_64", target_os = "linux"))]
        {
            let cpuinfo = std::fs::read_to_string("/proc/cpuinfo").unwrap();
            let flags: Vec<&str> = cpuinfo.lines().find(|l| l.starts_with("flags")).unwrap().split_whitespace().collect();
            for (name, _, present) in cpu::build_features() {
                let flag = match name {
                    "sse3" => "pni",
                    "sse4.1" => "sse4_1",
                    "sse4.2" => "sse4_2",
                    "cmpxchg16b" => "cx16",
                    "lzcnt" => "abm",
                    other => other,
                };
                assert_eq!(present, flags.contains(&flag), "{name} (/proc/cpuinfo flag {flag})");
            }
        }
        let message = Error::UnsupportedCpu { missing: vec!["avx2", "fma"] }.to_string();
        assert!(message.contains("lacks avx2, fma") && message.contains("target-cpu=native"), "{message}");
    }

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
