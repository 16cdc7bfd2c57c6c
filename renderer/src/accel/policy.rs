//! Chooses by measurement whether batches of rays are traced in packets or one ray at a
//! time. Neither wins everywhere: packets are several times faster where a packet's rays
//! visit the same nodes (small or open scenes), single rays where rays scatter through a
//! dense tree. Both give the same hits bit for bit, so the choice changes only the speed.

use std::sync::atomic::{AtomicU64, AtomicU8, Ordering};
use std::time::Instant;

/// Batches timed in each mode before choosing.
const TRIAL_BATCHES: u64 = 64;

const TRIAL: u8 = 0;
const SINGLE: u8 = 1;
const PACKETS: u8 = 2;

/// The traversal mode of one kind of query, settled after a trial that alternates modes.
#[derive(Debug)]
pub struct TracePolicy {
    choice: AtomicU8,
    started: AtomicU64,
    /// Per mode (single, packets): batches, nanoseconds and rays timed.
    batches: [AtomicU64; 2],
    nanos: [AtomicU64; 2],
    rays: [AtomicU64; 2],
}

impl TracePolicy {
    /// A policy that tries both modes when `packets_available`, else always traces single
    /// rays.
    pub fn new(packets_available: bool) -> Self {
        TracePolicy {
            choice: AtomicU8::new(if packets_available { TRIAL } else { SINGLE }),
            started: AtomicU64::new(0),
            batches: Default::default(),
            nanos: Default::default(),
            rays: Default::default(),
        }
    }

    /// The mode for the next batch (true: packets) and, during the trial, the time it starts.
    #[inline]
    pub fn pick(&self) -> (bool, Option<Instant>) {
        match self.choice.load(Ordering::Relaxed) {
            SINGLE => (false, None),
            PACKETS => (true, None),
            _ => (self.started.fetch_add(1, Ordering::Relaxed) % 2 == 1, Some(Instant::now())),
        }
    }

    /// Records a timed trial batch of `rays` rays; settles the choice once both modes have
    /// been timed on enough batches.
    pub fn report(&self, packets: bool, start: Instant, rays: usize) {
        let mode = packets as usize;
        self.nanos[mode].fetch_add(start.elapsed().as_nanos() as u64, Ordering::Relaxed);
        self.rays[mode].fetch_add(rays as u64, Ordering::Relaxed);
        self.batches[mode].fetch_add(1, Ordering::Relaxed);
        if self.batches.iter().all(|b| b.load(Ordering::Relaxed) >= TRIAL_BATCHES) {
            let cost = |m: usize| self.nanos[m].load(Ordering::Relaxed) as f64 / self.rays[m].load(Ordering::Relaxed).max(1) as f64;
            let choice = if cost(1) < cost(0) { PACKETS } else { SINGLE };
            let _ = self.choice.compare_exchange(TRIAL, choice, Ordering::Relaxed, Ordering::Relaxed);
        }
    }

    /// The settled mode (true: packets), or `None` during the trial.
    pub fn choice(&self) -> Option<bool> {
        match self.choice.load(Ordering::Relaxed) {
            SINGLE => Some(false),
            PACKETS => Some(true),
            _ => None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::time::Duration;

    #[test]
    fn settles_on_the_faster_mode_and_only_tries_what_exists() {
        let policy = TracePolicy::new(true);
        for _ in 0..4 * TRIAL_BATCHES {
            let (packets, start) = policy.pick();
            let Some(start) = start else { break };
            // Packets take 1 µs per ray here, single rays 2 µs.
            std::thread::sleep(Duration::from_micros(if packets { 100 } else { 200 }));
            policy.report(packets, start, 100);
        }
        assert_eq!(policy.choice(), Some(true));
        assert_eq!(policy.pick(), (true, None));
        assert_eq!(TracePolicy::new(false).pick(), (false, None));
    }
}
