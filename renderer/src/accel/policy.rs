//! Chooses by measurement whether batches of rays are traced in packets or one ray at a
//! time. Neither wins everywhere: packets are several times faster where a packet's rays
//! visit the same nodes (small or open scenes), single rays where rays scatter through a
//! dense tree, and which wins can change across an image. Both give the same hits bit for
//! bit, so the choice changes only the speed.

use std::sync::atomic::{AtomicI64, AtomicU64, Ordering};
use std::time::Instant;

/// Batches traced both ways at first, each of the first `SAMPLE_FIRST`.
const SAMPLE_FIRST: u64 = 8;

/// Then one batch in `SAMPLE_EVERY` until [`SETTLED_AFTER`] comparisons are made.
const SAMPLE_EVERY: u64 = 32;

/// Comparisons after which the mode is compared only one batch in [`SAMPLE_SETTLED`].
const SETTLED_AFTER: u64 = 32;

/// The sampling interval once [`SETTLED_AFTER`] comparisons are made: still spread over the
/// whole render, at 1/32 of the early cost. (Each comparison traces a batch in the slower
/// mode too, and single rays take 2–3× as long as packets where packets win: sampling one
/// batch in 32 throughout cost 2–4 % of the render.)
const SAMPLE_SETTLED: u64 = 1024;

/// The most one comparison counts, as a ratio of the two times: ln 4. A batch that the
/// system interrupted (a page fault, a preempting thread) takes milliseconds instead of
/// microseconds in whichever mode it hit, and summed times let that one batch outweigh
/// dozens of honest ones.
const MAX_LOG_RATIO: f64 = std::f64::consts::LN_2 * 2.0;

/// Fixed-point units of a ray's log ratio in [`TracePolicy::score`].
const SCORE_UNIT: f64 = 1e3;

/// The traversal mode of one kind of query. Sampled batches, spread over the whole render
/// (parts of an image differ: rays under a ceiling light are not rays across the room), are
/// traced both ways, which way first alternating, so the timings compare the same rays; the
/// other batches use the mode that has won by more in the log of the time ratio, each
/// comparison capped at ln 4 and weighted by the batch's rays (a weighted geometric mean of
/// the ratios, robust to an interrupted batch). A sampled batch costs one extra traversal:
/// about 1/32 more traversal time until 32 comparisons are made, 1/1024 after.
#[derive(Debug)]
pub struct TracePolicy {
    packets_available: bool,
    batches: AtomicU64,
    /// Comparisons made.
    comparisons: AtomicU64,
    /// Sum over comparisons of the batch's rays times ln(single time / packet time), the
    /// log capped, in [`SCORE_UNIT`]s: positive where packets are faster.
    score: AtomicI64,
}

impl TracePolicy {
    /// A policy that compares both modes when `packets_available`, else always traces single
    /// rays.
    pub fn new(packets_available: bool) -> Self {
        TracePolicy {
            packets_available,
            batches: AtomicU64::new(0),
            comparisons: AtomicU64::new(0),
            score: AtomicI64::new(0),
        }
    }

    /// Traces a batch of `rays` rays with `trace(packets)`: in the faster mode so far, or on
    /// a sampled batch in both. Empty batches (a tile whose camera rays all left the scene
    /// has no shadow rays) are neither sampled nor counted: timing nothing twice measures
    /// only which call came second.
    #[inline]
    pub fn trace(&self, rays: usize, trace: impl FnMut(bool)) {
        self.trace_timed(rays, trace, |packets, trace| {
            let start = Instant::now();
            trace(packets);
            start.elapsed().as_nanos() as u64
        });
    }

    /// Whether batch `n` (from 0) is traced both ways.
    #[inline]
    fn sampled(&self, n: u64) -> bool {
        n < SAMPLE_FIRST
            || n.is_multiple_of(if self.comparisons.load(Ordering::Relaxed) < SETTLED_AFTER {
                SAMPLE_EVERY
            } else {
                SAMPLE_SETTLED
            })
    }

    /// As [`TracePolicy::trace`], with `time(packets, trace)` running `trace(packets)` and
    /// returning the nanoseconds it took.
    #[inline]
    fn trace_timed(&self, rays: usize, mut trace: impl FnMut(bool), mut time: impl FnMut(bool, &mut dyn FnMut(bool)) -> u64) {
        if !self.packets_available || rays == 0 {
            return trace(false);
        }
        let n = self.batches.fetch_add(1, Ordering::Relaxed);
        if self.sampled(n) {
            let mut nanos = [0u64; 2];
            let first = self.comparisons.load(Ordering::Relaxed) % 2 == 1;
            for packets in [first, !first] {
                nanos[packets as usize] = time(packets, &mut trace);
            }
            // A reading of 0 (a coarse clock) counts as 1 ns, so the log stays finite; both 0
            // say nothing.
            let [single, packets] = nanos.map(|t| t.max(1) as f64);
            let log_ratio = (single / packets).ln().clamp(-MAX_LOG_RATIO, MAX_LOG_RATIO);
            self.score.fetch_add((rays as f64 * log_ratio * SCORE_UNIT) as i64, Ordering::Relaxed);
            self.comparisons.fetch_add(1, Ordering::Relaxed);
        } else {
            trace(self.choice() != Some(false));
        }
    }

    /// The mode used now (true: packets), or `None` before the first measurement (no batch
    /// with rays yet).
    pub fn choice(&self) -> Option<bool> {
        if !self.packets_available {
            return Some(false);
        }
        (self.comparisons.load(Ordering::Relaxed) > 0).then(|| self.score.load(Ordering::Relaxed) >= 0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Runs `batches` batches of `rays` rays through `policy` on a fixed clock (sleeps
    /// overshoot by more than these times on a loaded machine): `nanos(n, packets)` for
    /// batch n. Returns how many batches each mode traced (single, packets).
    fn run(policy: &TracePolicy, batches: u64, rays: usize, nanos: impl Fn(u64, bool) -> u64) -> [u64; 2] {
        let mut traced = [0u64; 2];
        for n in 0..batches {
            policy.trace_timed(
                rays,
                |packets| traced[packets as usize] += 1,
                |packets, trace| {
                    trace(packets);
                    nanos(n, packets)
                },
            );
        }
        traced
    }

    #[test]
    fn settles_on_the_faster_mode_and_only_tries_what_exists() {
        let policy = TracePolicy::new(true);
        assert_eq!(policy.choice(), None);
        // Packets take 100 µs per batch here, single rays 200 µs.
        let batches = 4 * SAMPLE_EVERY;
        let traced = run(&policy, batches, 1000, |_, packets| if packets { 100_000 } else { 200_000 });
        assert_eq!(policy.choice(), Some(true));
        // The first SAMPLE_FIRST, then batches 32, 64 and 96.
        let sampled = SAMPLE_FIRST + 3;
        assert_eq!(traced, [sampled, batches], "sampled batches both ways, the others in packets");
        let single_only = TracePolicy::new(false);
        single_only.trace(10, |packets| assert!(!packets));
        assert_eq!(single_only.choice(), Some(false));
    }

    #[test]
    fn an_interrupted_batch_does_not_outweigh_the_others() {
        // Single rays are faster (100 against 150 µs), but one sampled batch was interrupted
        // for 50 ms while traced one ray at a time: with summed times, that batch alone
        // chose packets.
        let policy = TracePolicy::new(true);
        run(&policy, 2 * SAMPLE_EVERY, 1000, |n, packets| match (n, packets) {
            (3, false) => 50_000_000,
            (_, true) => 150_000,
            (_, false) => 100_000,
        });
        assert_eq!(policy.choice(), Some(false));
    }

    #[test]
    fn comparisons_count_by_rays_and_empty_batches_not_at_all() {
        let policy = TracePolicy::new(true);
        // Empty batches: the second call is the faster, whichever it is; nothing is learnt.
        let traced = run(&policy, 100, 0, |n, packets| if packets == (n % 2 == 0) { 50 } else { 90 });
        assert_eq!(policy.choice(), None);
        assert_eq!(policy.comparisons.load(Ordering::Relaxed), 0);
        assert_eq!(traced, [100, 0], "empty batches go straight through");
        // Small batches favour single rays 2:1, one large batch packets 2:1.
        run(&policy, 4, 10, |_, packets| if packets { 2_000 } else { 1_000 });
        assert_eq!(policy.choice(), Some(false));
        run(&policy, 1, 1000, |_, packets| if packets { 100_000 } else { 200_000 });
        assert_eq!(policy.choice(), Some(true));
    }

    #[test]
    fn samples_rarely_once_settled() {
        let policy = TracePolicy::new(true);
        let batches = 4 * SAMPLE_SETTLED;
        let traced = run(&policy, batches, 1000, |_, packets| if packets { 100_000 } else { 300_000 });
        // The first SAMPLE_FIRST, one in SAMPLE_EVERY until SETTLED_AFTER comparisons (the
        // last at batch 32 · 24 = 768), then batches 1024, 2048 and 3072.
        let early = SAMPLE_FIRST + (SETTLED_AFTER - SAMPLE_FIRST);
        assert_eq!(traced, [early + 3, batches]);
        assert_eq!(policy.comparisons.load(Ordering::Relaxed), early + 3);
    }
}
