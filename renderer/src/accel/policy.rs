//! Chooses by measurement whether batches of rays are traced in packets or one ray at a
//! time. Neither wins everywhere: packets are several times faster where a packet's rays
//! visit the same nodes (small or open scenes), single rays where rays scatter through a
//! dense tree, and which wins can change across an image. Both give the same hits bit for
//! bit, so the choice changes only the speed.

use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Instant;

/// One batch in this many is traced both ways (and each of the first `SAMPLE_EVERY`).
const SAMPLE_EVERY: u64 = 32;

/// The traversal mode of one kind of query. Every `SAMPLE_EVERY`-th batch, spread over the
/// whole render (parts of an image differ: rays under a ceiling light are not rays across
/// the room), is traced both ways, which way first alternating, so the timings compare the
/// same rays; the other batches use the mode with the smaller total time so far. A sampled
/// batch costs one extra traversal: about 1/32 more traversal time.
#[derive(Debug)]
pub struct TracePolicy {
    packets_available: bool,
    batches: AtomicU64,
    /// Nanoseconds spent per mode (single, packets) on the sampled batches.
    nanos: [AtomicU64; 2],
}

impl TracePolicy {
    /// A policy that compares both modes when `packets_available`, else always traces single
    /// rays.
    pub fn new(packets_available: bool) -> Self {
        TracePolicy {
            packets_available,
            batches: AtomicU64::new(0),
            nanos: Default::default(),
        }
    }

    /// Traces a batch with `trace(packets)`: in the faster mode so far, or on a sampled
    /// batch in both.
    #[inline]
    pub fn trace(&self, trace: impl FnMut(bool)) {
        self.trace_timed(trace, |packets, trace| {
            let start = Instant::now();
            trace(packets);
            start.elapsed().as_nanos() as u64
        });
    }

    /// As [`TracePolicy::trace`], with `time(packets, trace)` running `trace(packets)` and
    /// returning the nanoseconds it took.
    #[inline]
    fn trace_timed(&self, mut trace: impl FnMut(bool), mut time: impl FnMut(bool, &mut dyn FnMut(bool)) -> u64) {
        if !self.packets_available {
            return trace(false);
        }
        let n = self.batches.fetch_add(1, Ordering::Relaxed);
        if n < SAMPLE_EVERY || n.is_multiple_of(SAMPLE_EVERY) {
            let first = (n / if n < SAMPLE_EVERY { 1 } else { SAMPLE_EVERY }) % 2 == 1;
            for packets in [first, !first] {
                let nanos = time(packets, &mut trace);
                self.nanos[packets as usize].fetch_add(nanos, Ordering::Relaxed);
            }
        } else {
            trace(self.choice() != Some(false));
        }
    }

    /// The mode used now (true: packets), or `None` before the first measurement.
    pub fn choice(&self) -> Option<bool> {
        if !self.packets_available {
            return Some(false);
        }
        let [single, packets] = [0, 1].map(|m| self.nanos[m].load(Ordering::Relaxed));
        (single + packets > 0).then_some(packets <= single)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn settles_on_the_faster_mode_and_only_tries_what_exists() {
        let policy = TracePolicy::new(true);
        assert_eq!(policy.choice(), None);
        let mut traced = [0u64; 2];
        let batches = 4 * SAMPLE_EVERY;
        for _ in 0..batches {
            // Packets take 100 µs per batch here, single rays 200 µs (a fixed clock: sleeps
            // overshoot by more than that on a loaded machine).
            policy.trace_timed(
                |packets| traced[packets as usize] += 1,
                |packets, trace| {
                    trace(packets);
                    if packets { 100_000 } else { 200_000 }
                },
            );
        }
        assert_eq!(policy.choice(), Some(true));
        let sampled = SAMPLE_EVERY + 3;
        assert_eq!(traced, [sampled, batches], "sampled batches both ways, the others in packets");
        let single_only = TracePolicy::new(false);
        single_only.trace(|packets| assert!(!packets));
        assert_eq!(single_only.choice(), Some(false));
    }
}
