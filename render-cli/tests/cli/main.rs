//! The `render` binary end to end, in one test binary: each file under tests/ would be a
//! binary of its own, linked against the whole renderer, and cargo runs test binaries one
//! after another, so one slow test left a core idle. Modules, one per feature; run one with
//! `cargo test -p render-cli --test cli -- MODULE::`.

mod basics;
mod blender_addon;
mod checkpoint;
mod common;
mod farm_jobs;
mod neural;
mod parts;
mod report;
