//! The run's sample log: (time, torque, angle) in a fixed buffer that never drops the end of a run.
//!
//! When the buffer is full the log halves itself (keeps every other sample) and from then on
//! records every second tick — then every fourth, and so on. A run of any length therefore ends up
//! whole in the log, at the coarsest rate needed, and the jam (always near the end) is never lost.

use kerfmeter_protocol::{SAMPLES_PER_CHUNK, Sample, SampleChunk, heapless};

/// A bounded log of `N` samples with decimation.
pub struct SampleLog<const N: usize> {
    samples: [Sample; N],
    len: usize,
    ticks_per_sample: u16,
    tick: u32,
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
    /// An empty log recording every tick.
    pub const fn new() -> Self {
        Self {
            samples: [EMPTY; N],
            len: 0,
            ticks_per_sample: 1,
            tick: 0,
        }
    }

    /// Forget everything (a new run).
    pub fn clear(&mut self) {
        self.len = 0;
        self.ticks_per_sample = 1;
        self.tick = 0;
    }

    /// Offer this tick's sample; it is kept when the tick falls on the current rate.
    pub fn record(&mut self, sample: Sample) {
        let keep = self.tick.is_multiple_of(u32::from(self.ticks_per_sample));
        self.tick = self.tick.wrapping_add(1);
        if !keep {
            return;
        }
        if self.len == N {
            self.decimate();
            // After halving, this tick may no longer fall on the rate.
            if !(self.tick - 1).is_multiple_of(u32::from(self.ticks_per_sample)) {
                return;
            }
        }
        self.samples[self.len] = sample;
        self.len += 1;
    }

    fn decimate(&mut self) {
        let kept = self.len.div_ceil(2);
        for i in 0..kept {
            self.samples[i] = self.samples[2 * i];
        }
        self.len = kept;
        self.ticks_per_sample = self.ticks_per_sample.saturating_mul(2);
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

    /// The recorded samples, oldest first.
    pub fn as_slice(&self) -> &[Sample] {
        &self.samples[..self.len]
    }

    /// Up to [`SAMPLES_PER_CHUNK`] samples from index `from`; `None` past the end.
    pub fn chunk(&self, run_id: u32, from: u16) -> Option<SampleChunk> {
        let from_index = usize::from(from);
        if from_index > self.len {
            return None;
        }
        let end = (from_index + SAMPLES_PER_CHUNK).min(self.len);
        let mut samples = heapless::Vec::new();
        for s in &self.samples[from_index..end] {
            // Cannot fail: at most SAMPLES_PER_CHUNK are pushed.
            let _ = samples.push(*s);
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
