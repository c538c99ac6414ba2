//! The hardware watchdog as the firmware uses it, and the flash operations that need it longer.
//!
//! A [`Watchdog`] is fed with the timeout to run from that moment: the chip resets unless it is
//! fed again within it. Two timeouts are used:
//!
//! - [`WATCHDOG_TIMEOUT_MS`] (50 ms) in normal running, fed by the control tick and by nothing
//!   else, so that a stalled control loop resets the chip;
//! - [`FLASH_WATCHDOG_TIMEOUT_MS`] (2 s) for one flash erase or write, which stalls the core for
//!   up to hundreds of milliseconds (the SPI flash is the code's memory too).
//!
//! [`WatchdogFlash`] wraps the configuration's flash: every erase (one sector at a time) and every
//! write runs in its own long window, and the normal timeout is restored as soon as it returns.
//! A save that erases several sectors is therefore fed between them, and the loop goes back to
//! the 50 ms timeout the moment the flash is done, whatever called it. The device writes flash
//! only with the motor asleep (`device`), so the long window never covers a driven motor.
//!
//! The board implements [`Watchdog`] on TIMG1's MWDT (`board::watchdog`); the digital twin on
//! its model of the same watchdog, so that a flash stall resets the twin exactly when it would
//! reset the board.

use embedded_storage_async::nor_flash::{ErrorType, NorFlash, ReadNorFlash};

pub use crate::build::{FLASH_WATCHDOG_TIMEOUT_MS, WATCHDOG_TIMEOUT_MS};

// The timeouts' reasons, checked at compile time: the normal one at least five times the
// longest gap the controller rides through (8 periods) yet at most 100 ms; the flash window at least four
// times the slowest sector erase of a C3 module's flash (400 ms).
const _: () = {
    use crate::controller::{MAX_GAP_PERIODS, PERIOD_US};
    assert!(WATCHDOG_TIMEOUT_MS * 1000 >= 5 * MAX_GAP_PERIODS * PERIOD_US);
    assert!(WATCHDOG_TIMEOUT_MS <= 100);
    assert!(FLASH_WATCHDOG_TIMEOUT_MS >= 4 * 400);
};

/// A hardware watchdog.
pub trait Watchdog {
    /// Restart the countdown: the chip resets unless fed again within `timeout_ms`.
    fn feed_ms(&mut self, timeout_ms: u64);
}

/// No watchdog (host tests, tools).
impl Watchdog for () {
    fn feed_ms(&mut self, _: u64) {}
}

/// A flash whose every erase and write runs in its own [`FLASH_WATCHDOG_TIMEOUT_MS`] window of
/// `W`, with [`WATCHDOG_TIMEOUT_MS`] restored after it. Reads pass straight through.
pub struct WatchdogFlash<F, W> {
    flash: F,
    watchdog: W,
}

impl<F: NorFlash, W: Watchdog> WatchdogFlash<F, W> {
    /// `flash`, guarded by `watchdog`.
    pub fn new(flash: F, watchdog: W) -> Self {
        Self { flash, watchdog }
    }

    /// The flash, without the guard.
    pub fn into_inner(self) -> F {
        self.flash
    }

    /// The flash.
    pub fn inner(&self) -> &F {
        &self.flash
    }

    /// The watchdog.
    pub fn watchdog(&self) -> &W {
        &self.watchdog
    }
}

impl<F: ErrorType, W> ErrorType for WatchdogFlash<F, W> {
    type Error = F::Error;
}

impl<F: ReadNorFlash, W> ReadNorFlash for WatchdogFlash<F, W> {
    const READ_SIZE: usize = F::READ_SIZE;

    async fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), Self::Error> {
        self.flash.read(offset, bytes).await
    }

    fn capacity(&self) -> usize {
        self.flash.capacity()
    }
}

impl<F: NorFlash, W: Watchdog> NorFlash for WatchdogFlash<F, W> {
    const WRITE_SIZE: usize = F::WRITE_SIZE;
    const ERASE_SIZE: usize = F::ERASE_SIZE;

    /// One sector at a time, each in its own window. A misaligned range goes to the flash whole
    /// (in one window), which refuses it.
    async fn erase(&mut self, from: u32, to: u32) -> Result<(), Self::Error> {
        let sector = F::ERASE_SIZE as u32;
        if to <= from || !from.is_multiple_of(sector) || !to.is_multiple_of(sector) {
            self.watchdog.feed_ms(FLASH_WATCHDOG_TIMEOUT_MS);
            let result = self.flash.erase(from, to).await;
            self.watchdog.feed_ms(WATCHDOG_TIMEOUT_MS);
            return result;
        }
        for start in (from..to).step_by(F::ERASE_SIZE) {
            self.watchdog.feed_ms(FLASH_WATCHDOG_TIMEOUT_MS);
            let result = self.flash.erase(start, start + sector).await;
            self.watchdog.feed_ms(WATCHDOG_TIMEOUT_MS);
            result?;
        }
        Ok(())
    }

    async fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), Self::Error> {
        self.watchdog.feed_ms(FLASH_WATCHDOG_TIMEOUT_MS);
        let result = self.flash.write(offset, bytes).await;
        self.watchdog.feed_ms(WATCHDOG_TIMEOUT_MS);
        result
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fakes::flash::{FlashClock, RamFlash};
    use std::cell::RefCell;
    use std::rc::Rc;

    /// What happened, in order: feeds (with their timeout) and flash time spent between them.
    #[derive(Debug, Clone, PartialEq, Eq)]
    enum Event {
        Fed(u64),
        FlashUs(u64),
    }

    /// A watchdog that logs its feeds and, at each, the flash time spent since the last one.
    #[derive(Clone)]
    struct Log(Rc<RefCell<Vec<Event>>>, FlashClock);

    impl Watchdog for Log {
        fn feed_ms(&mut self, timeout_ms: u64) {
            let spent = self.1.take_spent_us();
            let mut log = self.0.borrow_mut();
            if spent > 0 {
                log.push(Event::FlashUs(spent));
            }
            log.push(Event::Fed(timeout_ms));
        }
    }

    fn guarded() -> (WatchdogFlash<RamFlash, Log>, Log) {
        let clock = FlashClock::new(400_000, 3_000, 1);
        let log = Log(Rc::default(), clock.clone());
        let flash = RamFlash::new(4).with_clock(clock);
        (WatchdogFlash::new(flash, log.clone()), log)
    }

    #[test]
    fn each_sector_erase_runs_in_its_own_long_window_and_the_short_one_follows() {
        let (mut flash, log) = guarded();
        embassy_futures::block_on(flash.erase(0, 2 * RamFlash::PAGE)).unwrap();
        let window = [
            Event::Fed(FLASH_WATCHDOG_TIMEOUT_MS),
            Event::FlashUs(400_000),
            Event::Fed(WATCHDOG_TIMEOUT_MS),
        ];
        assert_eq!(*log.0.borrow(), [window.clone(), window].concat());
    }

    #[test]
    fn a_write_runs_in_a_long_window_and_reads_need_none() {
        let (mut flash, log) = guarded();
        embassy_futures::block_on(flash.write(0, &[0u8; 8])).unwrap();
        let mut buf = [0u8; 8];
        embassy_futures::block_on(flash.read(0, &mut buf)).unwrap();
        assert_eq!(
            *log.0.borrow(),
            [
                Event::Fed(FLASH_WATCHDOG_TIMEOUT_MS),
                Event::FlashUs(3_000),
                Event::Fed(WATCHDOG_TIMEOUT_MS),
            ]
        );
    }

    #[test]
    fn a_failed_erase_still_restores_the_short_timeout() {
        let (mut flash, log) = guarded();
        // Past the end of the flash: the second sector fails.
        let end = 5 * RamFlash::PAGE;
        assert!(embassy_futures::block_on(flash.erase(3 * RamFlash::PAGE, end)).is_err());
        assert_eq!(
            log.0.borrow().last(),
            Some(&Event::Fed(WATCHDOG_TIMEOUT_MS))
        );
    }
}
