//! The run's sample log: (time, torque, angle) in a fixed buffer that never drops the end of a run.
//!
//! When the buffer is full the log halves itself (keeps every other sample) and from then on
//! records every second tick — then every fourth, and so on. A run of any length therefore ends up
//! whole in the log, at the coarsest rate needed, and the jam (always near the end) is never lost.
//!
//! # Halving a little each tick
//!
//! Moving half the buffer at once (1024 samples) would cost one control tick some 9.5k
//! instructions, as much as two ramping steps. So the halving is spread over the next few
//! recorded ticks: each moves at most [`SampleLog::MOVES_PER_TICK`] samples into place, and the
//! samples kept meanwhile wait in a small staging area until the kept half is compact. Reading the
//! log is exact throughout ([`SampleLog::chunk`], [`SampleLog::len`]); [`SampleLog::as_slice`]
//! shows the compact part only until the halving is done, which [`SampleLog::settle`] finishes at
//! once (the controller calls it as a run ends).

use kerfmeter_protocol::{SAMPLES_PER_CHUNK, Sample, SampleChunk, heapless};

/// Samples kept while a halving is under way, at most.
const STAGED: usize = 8;

/// A halving under way: slots `[0, next)` hold their samples; the kept sample `i` for
/// `next ≤ i < kept` still sits at slot `2·i`; later ones are staged.
#[derive(Debug, Clone, Copy)]
struct Halving {
    next: usize,
    kept: usize,
}

/// A bounded log of `N` samples with decimation.
pub struct SampleLog<const N: usize> {
    samples: [Sample; N],
    /// Samples in the log, staged ones included.
    len: usize,
    ticks_per_sample: u16,
    tick: u32,
    halving: Option<Halving>,
    staged: [Sample; STAGED],
    staged_len: usize,
}

impl<const N: usize> Default for SampleLog<N> {
    fn default() -> Self {
        Self::new()
    }
}

const EMPTY: Sample = Sample {
    t_ms: 0,
    torque_nm: 0.0,
    angle_deg: 0.0,
};

impl<const N: usize> SampleLog<N> {
    /// Samples moved into place per recorded tick while halving: the halving takes at most 8
    /// ticks, during which at most 5 samples are kept (one every second tick at least), within
    /// the staging area.
    pub const MOVES_PER_TICK: usize = N / 16 + 1;

    /// An empty log recording every tick.
    pub const fn new() -> Self {
        Self {
            samples: [EMPTY; N],
            len: 0,
            ticks_per_sample: 1,
            tick: 0,
            halving: None,
            staged: [EMPTY; STAGED],
            staged_len: 0,
        }
    }

    /// Forget everything (a new run).
    pub fn clear(&mut self) {
        self.len = 0;
        self.ticks_per_sample = 1;
        self.tick = 0;
        self.halving = None;
        self.staged_len = 0;
    }

    /// Offer this tick's sample; it is kept when the tick falls on the current rate.
    pub fn record(&mut self, sample: Sample) {
        let keep = self.tick.is_multiple_of(u32::from(self.ticks_per_sample));
        self.tick = self.tick.wrapping_add(1);
        self.compact(Self::MOVES_PER_TICK);
        if !keep {
            return;
        }
        if self.halving.is_none() && self.len == N {
            self.start_halving();
            // After halving, this tick may no longer fall on the rate.
            if !(self.tick - 1).is_multiple_of(u32::from(self.ticks_per_sample)) {
                return;
            }
        }
        if self.halving.is_some() {
            if self.staged_len == STAGED {
                // Not reached with the rates above; stay exact if it were.
                self.settle();
            } else {
                self.staged[self.staged_len] = sample;
                self.staged_len += 1;
                self.len += 1;
                return;
            }
        }
        self.samples[self.len] = sample;
        self.len += 1;
    }

    /// Keep every other sample from now on; the moves happen over the next ticks.
    fn start_halving(&mut self) {
        let kept = self.len.div_ceil(2);
        self.halving = Some(Halving { next: 1, kept });
        self.len = kept;
        self.ticks_per_sample = self.ticks_per_sample.saturating_mul(2);
    }

    /// Move up to `moves` kept samples into place; once all are, append the staged ones.
    fn compact(&mut self, moves: usize) {
        let Some(mut h) = self.halving else { return };
        let end = h.kept.min(h.next.saturating_add(moves));
        for i in h.next..end {
            self.samples[i] = self.samples[2 * i];
        }
        h.next = end;
        if h.next < h.kept {
            self.halving = Some(h);
            return;
        }
        self.samples[h.kept..h.kept + self.staged_len]
            .copy_from_slice(&self.staged[..self.staged_len]);
        self.staged_len = 0;
        self.halving = None;
    }

    /// Finish a halving under way now (the log is then one slice again).
    pub fn settle(&mut self) {
        self.compact(N);
    }

    /// Samples recorded.
    pub fn len(&self) -> usize {
        self.len
    }

    /// True when nothing is recorded.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// Control ticks per kept sample.
    pub fn ticks_per_sample(&self) -> u16 {
        self.ticks_per_sample
    }

    /// The recorded samples, oldest first; while a halving is under way, only its compact part
    /// (a prefix of the log: [`SampleLog::settle`] first for the whole).
    pub fn as_slice(&self) -> &[Sample] {
        match self.halving {
            Some(h) => &self.samples[..h.next],
            None => &self.samples[..self.len],
        }
    }

    /// Sample `i` of the log (`i < len`), wherever a halving under way has it.
    fn get(&self, i: usize) -> Sample {
        match self.halving {
            Some(h) if i >= h.kept => self.staged[i - h.kept],
            Some(h) if i >= h.next => self.samples[2 * i],
            _ => self.samples[i],
        }
    }

    /// Up to [`SAMPLES_PER_CHUNK`] samples from index `from`; `None` past the end.
    pub fn chunk(&self, run_id: u32, from: u16) -> Option<SampleChunk> {
        let from_index = usize::from(from);
        if from_index > self.len {
            return None;
        }
        let end = (from_index + SAMPLES_PER_CHUNK).min(self.len);
        let mut samples = heapless::Vec::new();
        for i in from_index..end {
            // Cannot fail: at most SAMPLES_PER_CHUNK are pushed.
            let _ = samples.push(self.get(i));
        }
        Some(SampleChunk {
            run_id,
            from,
            total: self.len as u16,
            ticks_per_sample: self.ticks_per_sample,
            samples,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn s(t: u32) -> Sample {
        Sample {
            t_ms: t,
            torque_nm: t as f32,
            angle_deg: 0.0,
        }
    }

    #[test]
    fn a_short_run_is_kept_whole() {
        let mut log = SampleLog::<16>::new();
        for t in 0..10 {
            log.record(s(t));
        }
        assert_eq!(log.len(), 10);
        assert_eq!(log.ticks_per_sample(), 1);
    }

    #[test]
    fn a_long_run_is_decimated_and_its_end_is_kept() {
        let mut log = SampleLog::<16>::new();
        for t in 0..100 {
            log.record(s(t));
        }
        let kept = log.as_slice();
        assert_eq!(log.ticks_per_sample(), 8);
        assert!(kept.len() <= 16 && kept.len() >= 8);
        // Evenly spaced from the start...
        for w in kept.windows(2) {
            assert_eq!(w[1].t_ms - w[0].t_ms, 8);
        }
        assert_eq!(kept[0].t_ms, 0);
        // ...and reaching the end of the run within one sample period.
        assert!(kept.last().unwrap().t_ms >= 99 - 8, "{:?}", kept.last());
    }

    /// The log as it was before the halving was spread: everything moved on the tick it fills.
    struct InstantLog<const N: usize> {
        samples: Vec<Sample>,
        ticks_per_sample: u32,
        tick: u32,
    }

    impl<const N: usize> InstantLog<N> {
        fn record(&mut self, sample: Sample) {
            let keep = self.tick.is_multiple_of(self.ticks_per_sample);
            self.tick += 1;
            if !keep {
                return;
            }
            if self.samples.len() == N {
                self.samples = self.samples.iter().step_by(2).copied().collect();
                self.ticks_per_sample *= 2;
                if !(self.tick - 1).is_multiple_of(self.ticks_per_sample) {
                    return;
                }
            }
            self.samples.push(sample);
        }
    }

    /// Every sample of `log`, read in chunks as the host does.
    fn read_all<const N: usize>(log: &SampleLog<N>) -> Vec<Sample> {
        let mut all = Vec::new();
        while let Some(c) = log.chunk(1, all.len() as u16) {
            if c.samples.is_empty() {
                break;
            }
            all.extend(c.samples.iter().copied());
        }
        all
    }

    fn same_as_instant<const N: usize>(ticks: u32) {
        let mut log = SampleLog::<N>::new();
        let mut reference = InstantLog::<N> {
            samples: Vec::new(),
            ticks_per_sample: 1,
            tick: 0,
        };
        for t in 0..ticks {
            log.record(s(t));
            reference.record(s(t));
            // Exact at every tick, through chunks; the slice is a prefix of it.
            assert_eq!(read_all(&log), reference.samples, "N = {N}, tick {t}");
            assert_eq!(log.len(), reference.samples.len());
            assert_eq!(
                u32::from(log.ticks_per_sample()),
                reference.ticks_per_sample
            );
            let prefix = log.as_slice();
            assert_eq!(prefix, &reference.samples[..prefix.len()]);
        }
        log.settle();
        assert_eq!(log.as_slice(), reference.samples.as_slice());
    }

    #[test]
    fn halving_over_several_ticks_keeps_the_same_samples_as_halving_at_once() {
        same_as_instant::<16>(2_000);
        same_as_instant::<100>(3_000);
        same_as_instant::<2048>(9_000);
    }

    #[test]
    fn a_halving_moves_a_bounded_number_of_samples_a_tick() {
        let mut log = SampleLog::<2048>::new();
        for t in 0..2048 {
            log.record(s(t));
        }
        // The tick that finds the log full starts the halving and moves nothing; each of the
        // next ticks moves its share.
        log.record(s(2048));
        assert_eq!(log.as_slice().len(), 1);
        for (i, t) in (2049..2052).enumerate() {
            log.record(s(t));
            assert_eq!(
                log.as_slice().len(),
                1 + (i + 1) * SampleLog::<2048>::MOVES_PER_TICK
            );
        }
        log.settle();
        assert_eq!(log.as_slice().len(), log.len());
    }

    #[test]
    fn chunks_page_through_the_log() {
        let mut log = SampleLog::<100>::new();
        for t in 0..70 {
            log.record(s(t));
        }
        let a = log.chunk(1, 0).unwrap();
        assert_eq!(
            (a.from, a.total, a.samples.len()),
            (0, 70, SAMPLES_PER_CHUNK)
        );
        let c = log.chunk(1, 64).unwrap();
        assert_eq!(c.samples.len(), 6);
        assert_eq!(log.chunk(1, 70).unwrap().samples.len(), 0);
        assert!(log.chunk(1, 71).is_none());
    }
}
