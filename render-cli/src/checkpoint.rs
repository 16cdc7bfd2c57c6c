//! `render --checkpoint FILE [--checkpoint-every SECONDS]`: the render's state is written to
//! FILE ([`renderer::formats::checkpoint`]) at pass boundaries once SECONDS have passed since
//! the last write (or since the start), and when Ctrl-C or SIGTERM stops the render; a render
//! started again with the same settings and an existing FILE continues from it and ends with
//! the uninterrupted render's image bit for bit. FILE is removed once the output is written.
//!
//! What decides the pixels is recorded as settings ([`settings`]): a checkpoint of other
//! settings, or one that is truncated or corrupted, is refused (exit code 2). A sweep keeps one
//! FILE for its chunk of frames; it records which frame (and whether the neural or the table
//! render) it holds, and a resumed sweep skips the frames of its range before that one, which
//! the interrupted run wrote.

use super::{parts, Args, Job};
use anyhow::{Context, Result};
use renderer::film::Region;
use renderer::formats::checkpoint::{self, sha256_hex, Checkpoint, CheckpointError, CheckpointProblem};
use renderer::render::{Budget, RenderState};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::time::{Duration, Instant};

/// Exit code of a render stopped by Ctrl-C or SIGTERM after writing its checkpoint
/// (EX_TEMPFAIL of sysexits.h: run the same command again to resume).
pub const INTERRUPTED_EXIT: u8 = 75;

/// The error that ends an interrupted render whose checkpoint was written: `main` exits
/// with [`INTERRUPTED_EXIT`] for it.
#[derive(Debug)]
pub struct Interrupted(pub String);

impl std::fmt::Display for Interrupted {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for Interrupted {}

/// Settings key of the frame a sweep's checkpoint holds ("K neural" or "K table").
const FRAME_KEY: &str = "frame";

/// A `--checkpoint` file in use by one invocation of `render`.
pub struct Checkpointing {
    pub path: PathBuf,
    every: Duration,
    /// The settings of this invocation (without the sweep frame).
    settings: BTreeMap<String, String>,
    last_write: Mutex<Instant>,
    /// The checkpoint found at start-up, until the render it belongs to takes it.
    pending: Mutex<Option<Checkpoint>>,
    /// A checkpoint that could not be written (the render is stopped and this reported).
    failure: Mutex<Option<CheckpointError>>,
}

/// A file's name and the SHA-256 of its bytes.
fn file_hash(path: &Path) -> Result<String> {
    let bytes = std::fs::read(path).with_context(|| format!("{}: cannot read", path.display()))?;
    Ok(format!("{} sha256:{}", path.display(), sha256_hex(&bytes)))
}

/// The files a `--bind` binding reads: `merl:PATH`'s table, `nbrdf:PREFIX`'s `PREFIX*` files.
fn binding_files(binding: &str) -> Vec<PathBuf> {
    if let Some(path) = binding.strip_prefix("merl:") {
        return vec![PathBuf::from(path)];
    }
    let Some(prefix) = binding.strip_prefix("nbrdf:") else { return Vec::new() };
    let prefix = Path::new(prefix);
    let (dir, stem) = match (prefix.parent(), prefix.file_name()) {
        (Some(d), Some(s)) => (if d.as_os_str().is_empty() { Path::new(".") } else { d }, s.to_string_lossy().into_owned()),
        _ => return Vec::new(),
    };
    let mut files: Vec<PathBuf> = std::fs::read_dir(dir)
        .map(|entries| {
            entries
                .filter_map(|e| e.ok().map(|e| e.path()))
                .filter(|p| p.is_file() && p.file_name().is_some_and(|n| n.to_string_lossy().starts_with(&stem)))
                .collect()
        })
        .unwrap_or_default();
    files.sort();
    files
}

/// The settings that decide the film of this invocation: those a part records
/// ([`parts::settings`]) plus the SHA-256 of the scene, latent and bound files, the region,
/// and for sweeps the sweep, its tables, frame range and output directory.
pub fn settings(args: &Args, job: &Job) -> Result<BTreeMap<String, String>> {
    let mut s = parts::settings(args, job)?;
    s.insert("scene sha256".into(), file_hash(&args.scene)?);
    let materials: Vec<String> = args.material.iter().map(|p| file_hash(p)).collect::<Result<_>>()?;
    s.insert("materials sha256".into(), materials.join("; "));
    let bound: Vec<String> = args.bind.iter().flat_map(|(_, b)| binding_files(b)).map(|p| file_hash(&p)).collect::<Result<_>>()?;
    s.insert("bound files sha256".into(), bound.join("; "));
    s.insert("region".into(), job.region.to_string());
    if let Some(sweep) = &args.sweep {
        s.insert("sweep".into(), format!("{}:{}:{}", sweep.from, sweep.to, sweep.steps));
        s.insert("frames".into(), args.frames.map_or_else(|| "all".to_string(), |f| f.to_string()));
        s.insert("output".into(), args.output.display().to_string());
        let tables = match &args.tables {
            Some(dir) => [&sweep.from, &sweep.to].iter().map(|n| file_hash(&dir.join(format!("{n}.binary")))).collect::<Result<Vec<_>>>()?.join("; "),
            None => String::new(),
        };
        s.insert("tables sha256".into(), tables);
    }
    Ok(s)
}

impl Checkpointing {
    /// Opens `path` for a render of `region` of a `width` × `height` image with `settings`:
    /// an existing file must be an intact checkpoint of these settings (any frame of a sweep).
    pub fn open(path: &Path, every: Duration, settings: BTreeMap<String, String>, width: u32, height: u32, region: Region, budget: Budget) -> Result<Self> {
        let pending = if path.exists() {
            let found = Checkpoint::read(path)?;
            let mut recorded = found.settings.clone();
            recorded.remove(FRAME_KEY);
            checkpoint::check_settings(path, &recorded, &settings)?;
            let film = &found.state.film;
            let malformed = |reason: String| CheckpointError { path: path.to_path_buf(), problem: CheckpointProblem::Malformed(reason) };
            if (film.full_width, film.full_height, film.region) != (width, height, region) {
                return Err(malformed(format!("its film is region {} of {}x{}", film.region, film.full_width, film.full_height)).into());
            }
            if let Budget::Spp(spp) = budget {
                if found.state.samples_done > spp {
                    return Err(malformed(format!("{} samples per pixel done of {spp}", found.state.samples_done)).into());
                }
            }
            Some(found)
        } else {
            // Farm tasks checkpoint into a shared directory that the first of them may have
            // to create.
            if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
                std::fs::create_dir_all(dir).with_context(|| format!("{}: cannot create the directory for the checkpoint", dir.display()))?;
            }
            None
        };
        Ok(Checkpointing {
            path: path.to_path_buf(),
            every,
            settings,
            last_write: Mutex::new(Instant::now()),
            pending: Mutex::new(pending),
            failure: Mutex::new(None),
        })
    }

    /// The frame ("K neural" or "K table") that the checkpoint found at start-up holds.
    pub fn resume_frame(&self) -> Option<(usize, bool)> {
        let pending = self.pending.lock().expect("lock");
        let frame = pending.as_ref()?.settings.get(FRAME_KEY)?;
        let (k, kind) = frame.split_once(' ')?;
        Some((k.parse().ok()?, kind == "table"))
    }

    /// The state to start the render of `frame` from: the checkpoint found at start-up if it
    /// holds this render, else an empty film.
    pub fn start(&self, frame: Option<&str>, width: u32, height: u32, region: Region) -> RenderState {
        let mut pending = self.pending.lock().expect("lock");
        if pending.as_ref().is_some_and(|c| c.settings.get(FRAME_KEY).map(String::as_str) == frame) {
            let found = pending.take().expect("checked");
            eprintln!("resuming from {} at {} spp", self.path.display(), found.state.samples_done);
            return found.state;
        }
        RenderState::new(width, height, region)
    }

    /// At a pass boundary of the render of `frame`: writes the checkpoint when the render was
    /// interrupted or the interval has passed. Returns false when the write failed (kept for
    /// [`Checkpointing::take_failure`]).
    pub fn at_boundary(&self, frame: Option<&str>, state: &RenderState, interrupted: bool) -> bool {
        let mut last = self.last_write.lock().expect("lock");
        if !interrupted && last.elapsed() < self.every {
            return true;
        }
        let mut settings = self.settings.clone();
        if let Some(frame) = frame {
            settings.insert(FRAME_KEY.into(), frame.into());
        }
        match checkpoint::write(&self.path, &settings, state) {
            Ok(()) => {
                *last = Instant::now();
                true
            }
            Err(e) => {
                *self.failure.lock().expect("lock") = Some(e);
                false
            }
        }
    }

    /// The error of a checkpoint that could not be written, if any.
    pub fn take_failure(&self) -> Option<CheckpointError> {
        self.failure.lock().expect("lock").take()
    }

    /// Removes the checkpoint once the output is written.
    pub fn finish(&self) -> Result<()> {
        match std::fs::remove_file(&self.path) {
            Ok(()) => Ok(()),
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(()),
            Err(e) => Err(e).with_context(|| format!("{}: cannot remove the checkpoint", self.path.display())),
        }
    }
}

/// Installs a SIGTERM handler that sets `cancel`, as Ctrl-C does (only with `--checkpoint`:
/// without one SIGTERM ends `render` at once, as it always has).
#[cfg(unix)]
pub fn cancel_on_sigterm(cancel: &std::sync::Arc<std::sync::atomic::AtomicBool>) -> Result<()> {
    use std::sync::atomic::{AtomicBool, AtomicPtr, Ordering};
    static CANCEL: AtomicPtr<AtomicBool> = AtomicPtr::new(std::ptr::null_mut());
    extern "C" fn on_sigterm(_: libc::c_int) {
        // Async-signal-safe: two atomic operations.
        let flag = CANCEL.load(Ordering::Acquire);
        if !flag.is_null() {
            // SAFETY: the pointer comes from a leaked Arc that is never freed.
            unsafe { (*flag).store(true, Ordering::Relaxed) };
        }
    }
    CANCEL.store(std::sync::Arc::into_raw(cancel.clone()) as *mut AtomicBool, Ordering::Release);
    // SAFETY: a zeroed sigaction with a handler set and an empty mask is a valid argument.
    let installed = unsafe {
        let mut action: libc::sigaction = std::mem::zeroed();
        action.sa_sigaction = on_sigterm as extern "C" fn(libc::c_int) as libc::sighandler_t;
        action.sa_flags = libc::SA_RESTART;
        libc::sigemptyset(&mut action.sa_mask);
        libc::sigaction(libc::SIGTERM, &action, std::ptr::null_mut()) == 0
    };
    anyhow::ensure!(installed, "cannot install the SIGTERM handler: {}", std::io::Error::last_os_error());
    Ok(())
}

#[cfg(not(unix))]
pub fn cancel_on_sigterm(_: &std::sync::Arc<std::sync::atomic::AtomicBool>) -> Result<()> {
    Ok(())
}
