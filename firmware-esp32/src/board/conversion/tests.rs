//! The schedule, and a stalled conversion given up, against a fake one-shot ADC.

use super::*;
use crate::board::current::MotorCurrent;

/// A one-shot ADC whose conversions finish by the next poll, unless one is made to stall: it
/// then never finishes until the ADC is restarted (the board builds its driver afresh).
#[derive(Default)]
struct FakeAdc {
    running: Option<Channel>,
    /// The next conversion started stalls.
    stall_next: bool,
    stalled: bool,
    restarts: u32,
}

impl FakeAdc {
    fn restart(&mut self) {
        self.running = None;
        self.stalled = false;
        self.restarts += 1;
    }
}

impl OneShot for FakeAdc {
    fn poll(&mut self, channel: Channel) -> Option<u16> {
        match self.running {
            None => {
                self.running = Some(channel);
                self.stalled = core::mem::take(&mut self.stall_next);
                None
            }
            Some(running) if running != channel || self.stalled => None,
            Some(_) => {
                self.running = None;
                Some(match channel {
                    Channel::CurrentSense => 50,
                    // 12 V through the divider.
                    Channel::Supply => 912,
                })
            }
        }
    }
}

/// Run `ticks` ticks as the board does (collect, restart if told, start the next), the
/// conversion started at tick `stall_at` stalling; the current sense's readings.
fn run(ticks: u32, stall_at: Option<u32>) -> (Vec<Option<u16>>, FakeAdc, Conversions) {
    let mut adc = FakeAdc::default();
    let mut conversions = Conversions::new();
    let mut cs = Vec::new();
    for tick in 0..ticks {
        let readings = conversions.read(&mut adc);
        cs.push(readings.cs_mv);
        if readings.restart {
            adc.restart();
        }
        adc.stall_next = stall_at == Some(tick);
        conversions.start_next(&mut adc);
    }
    (cs, adc, conversions)
}

#[test]
fn the_current_sense_is_read_every_tick_but_after_a_supply_conversion() {
    let (cs, adc, conversions) = run(40, None);
    let missing: Vec<usize> = (0..cs.len()).filter(|&t| cs[t].is_none()).collect();
    // The first tick has nothing yet; then one tick in ten gives the supply instead.
    assert_eq!(missing, [0, 10, 20, 30]);
    assert_eq!(adc.restarts, 0);
    assert_eq!(conversions.restarts(), 0);
}

/// A conversion that never finishes is given up at its third collection and the ADC restarted;
/// the current never counts as unknown. (Waiting for it, as the driver did, no reading ever
/// came again: the current was unknown from the tenth tick on, until a reboot.)
#[test]
fn a_stalled_conversion_is_given_up_and_the_adc_restarted() {
    let (cs, adc, conversions) = run(60, Some(20));
    assert_eq!(adc.restarts, 1);
    assert_eq!(conversions.restarts(), 1);
    let missing: Vec<usize> = (15..40).filter(|&t| cs[t].is_none()).collect();
    // Tick 20 reads the supply; ticks 21–23 find the stalled one unfinished, the third gives it
    // up, and the conversion started after the restart is read at tick 24. The supply's turn
    // moves on by the two ticks nothing could be started (from 30 to 32).
    assert_eq!(missing, [20, 21, 22, 23, 32]);
    let mut current = MotorCurrent::new();
    for (tick, reading) in cs.iter().enumerate().skip(1) {
        assert!(current.current_a(*reading).is_some(), "tick {tick}");
    }
}
