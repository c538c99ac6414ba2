//! A NOR flash in RAM with the ESP32's geometry (4 KiB erase sectors, 256-byte program pages,
//! 4-byte words), for the twin's configuration store. NOR rules apply: erase sets bytes to 0xFF,
//! writes can only clear bits, misaligned or out-of-range access is an error.
//!
//! Its [`FlashClock`] (a handle shared with whoever watches the flash) says how long each erase
//! and write takes, counts them, and can cut the power part-way: the operation under way when
//! the time budget runs out is left torn, as on a chip reset mid-operation, and every later one
//! fails without effect until [`FlashClock::power_on`].
//!
//! - A torn erase has erased the first part of its sector (in proportion to the time it got),
//!   left a 256-byte band of random bytes where it stopped, and the old bytes after it.
//! - A torn write has programmed the first words (in proportion to the time it got), and one word
//!   partly; the rest of the write never happened.

use std::sync::{Arc, Mutex, MutexGuard};

use embedded_storage_async::nor_flash::{
    ErrorType, NorFlash, NorFlashError, NorFlashErrorKind, ReadNorFlash,
};

use super::rng::Rng;

/// A flash error.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RamFlashError(NorFlashErrorKind);

impl NorFlashError for RamFlashError {
    fn kind(&self) -> NorFlashErrorKind {
        self.0
    }
}

/// How an operation went against the clock's budget.
enum Charge {
    /// Completed.
    Done,
    /// Cut after this fraction of its time (0..1).
    Torn(f64),
    /// The power was already off: nothing happened.
    Dead,
}

#[derive(Debug)]
struct ClockState {
    erase_us: u64,
    write_page_us: u64,
    spent_us: u64,
    budget_us: Option<u64>,
    cut: bool,
    erases: u64,
    pages_written: u64,
    rng: Rng,
}

/// The time flash operations take, and a budget after which the power is cut. A cheap shared
/// handle: clone it, give one clone to the flash ([`RamFlash::with_clock`]), keep one to watch.
#[derive(Debug, Clone)]
pub struct FlashClock(Arc<Mutex<ClockState>>);

impl Default for FlashClock {
    /// Operations take no time and the power is never cut.
    fn default() -> Self {
        Self::new(0, 0, 0)
    }
}

impl FlashClock {
    /// A sector erase takes `erase_us`, programming each 256-byte page `write_page_us`; torn
    /// contents are drawn from `seed`.
    pub fn new(erase_us: u64, write_page_us: u64, seed: u64) -> Self {
        Self(Arc::new(Mutex::new(ClockState {
            erase_us,
            write_page_us,
            spent_us: 0,
            budget_us: None,
            cut: false,
            erases: 0,
            pages_written: 0,
            rng: Rng::new(seed),
        })))
    }

    fn state(&self) -> MutexGuard<'_, ClockState> {
        // A panic elsewhere cannot leave the counters half-updated: use them as they are.
        self.0.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// Cut the power once operations have taken `budget_us` more (`None`: never).
    pub fn set_budget_us(&self, budget_us: Option<u64>) {
        self.state().budget_us = budget_us;
    }

    /// Time spent in operations since the last call, µs.
    pub fn take_spent_us(&self) -> u64 {
        core::mem::take(&mut self.state().spent_us)
    }

    /// True once the power was cut (until [`power_on`](Self::power_on)).
    pub fn is_cut(&self) -> bool {
        self.state().cut
    }

    /// Power back on (a reboot): operations work again, with no budget.
    pub fn power_on(&self) {
        let mut s = self.state();
        s.cut = false;
        s.budget_us = None;
    }

    /// Sector erases started so far (torn ones included).
    pub fn erases(&self) -> u64 {
        self.state().erases
    }

    /// 256-byte pages programmed so far (torn writes included).
    pub fn pages_written(&self) -> u64 {
        self.state().pages_written
    }

    /// Spend the time of one operation (`pages` program pages, or a sector erase when `None`),
    /// within the budget if there is one.
    fn charge(&self, pages: Option<u64>) -> Charge {
        let mut s = self.state();
        if s.cut {
            return Charge::Dead;
        }
        let cost_us = match pages {
            Some(pages) => {
                s.pages_written += pages;
                pages * s.write_page_us
            }
            None => {
                s.erases += 1;
                s.erase_us
            }
        };
        match s.budget_us {
            Some(left) if cost_us > left => {
                s.spent_us += left;
                s.budget_us = Some(0);
                s.cut = true;
                Charge::Torn(left as f64 / cost_us as f64)
            }
            budget => {
                s.spent_us += cost_us;
                s.budget_us = budget.map(|left| left - cost_us);
                Charge::Done
            }
        }
    }

    fn random_byte(&self) -> u8 {
        self.state().rng.next_u64() as u8
    }
}

/// The RAM flash.
#[derive(Debug, Clone)]
pub struct RamFlash {
    bytes: Vec<u8>,
    clock: FlashClock,
}

impl RamFlash {
    /// Erase sector size.
    pub const PAGE: u32 = 4096;
    /// Program page size: a write's time is per page it touches.
    pub const PROGRAM_PAGE: u32 = 256;

    /// An erased flash of `pages` sectors whose operations take no time.
    pub fn new(pages: usize) -> Self {
        Self {
            bytes: vec![0xFF; pages * Self::PAGE as usize],
            clock: FlashClock::default(),
        }
    }

    /// The same flash, timed (and powered) by `clock`.
    pub fn with_clock(self, clock: FlashClock) -> Self {
        Self { clock, ..self }
    }

    /// Its clock (a shared handle).
    pub fn clock(&self) -> &FlashClock {
        &self.clock
    }

    /// Flip every byte of each occurrence of `pattern` (a test's way of corrupting a record);
    /// returns how many occurrences were found.
    pub fn corrupt_pattern(&mut self, pattern: &[u8]) -> usize {
        let mut found = 0;
        let mut i = 0;
        while i + pattern.len() <= self.bytes.len() {
            if &self.bytes[i..i + pattern.len()] == pattern {
                for b in &mut self.bytes[i..i + pattern.len()] {
                    *b ^= 0x5A;
                }
                found += 1;
                i += pattern.len();
            } else {
                i += 1;
            }
        }
        found
    }

    fn check(&self, offset: u32, len: usize, align: u32) -> Result<(), RamFlashError> {
        if !offset.is_multiple_of(align) || !(len as u32).is_multiple_of(align) {
            return Err(RamFlashError(NorFlashErrorKind::NotAligned));
        }
        if offset as usize + len > self.bytes.len() {
            return Err(RamFlashError(NorFlashErrorKind::OutOfBounds));
        }
        Ok(())
    }
}

impl ErrorType for RamFlash {
    type Error = RamFlashError;
}

impl ReadNorFlash for RamFlash {
    const READ_SIZE: usize = 1;

    async fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), RamFlashError> {
        self.check(offset, bytes.len(), 1)?;
        let start = offset as usize;
        bytes.copy_from_slice(&self.bytes[start..start + bytes.len()]);
        Ok(())
    }

    fn capacity(&self) -> usize {
        self.bytes.len()
    }
}

impl NorFlash for RamFlash {
    const WRITE_SIZE: usize = 4;
    const ERASE_SIZE: usize = Self::PAGE as usize;

    async fn erase(&mut self, from: u32, to: u32) -> Result<(), RamFlashError> {
        if to < from {
            return Err(RamFlashError(NorFlashErrorKind::OutOfBounds));
        }
        self.check(from, (to - from) as usize, Self::PAGE)?;
        for sector in (from..to).step_by(Self::PAGE as usize) {
            self.erase_sector(sector as usize)?;
        }
        Ok(())
    }

    async fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), RamFlashError> {
        self.check(offset, bytes.len(), Self::WRITE_SIZE as u32)?;
        if bytes.is_empty() {
            return Ok(());
        }
        let first = offset / Self::PROGRAM_PAGE;
        let last = (offset + bytes.len() as u32 - 1) / Self::PROGRAM_PAGE;
        let done = match self.clock.charge(Some(u64::from(last - first + 1))) {
            Charge::Dead => return Err(RamFlashError(NorFlashErrorKind::Other)),
            Charge::Done => bytes.len(),
            Charge::Torn(fraction) => {
                let words = (fraction * (bytes.len() / Self::WRITE_SIZE) as f64) as usize;
                words * Self::WRITE_SIZE
            }
        };
        let start = offset as usize;
        for (cell, b) in self.bytes[start..start + done].iter_mut().zip(bytes) {
            *cell &= b;
        }
        if done == bytes.len() {
            return Ok(());
        }
        // The word being programmed when the power went: some of its bits cleared.
        for (cell, b) in self.bytes[start + done..]
            .iter_mut()
            .zip(&bytes[done..])
            .take(4)
        {
            *cell &= b | self.clock.random_byte();
        }
        Err(RamFlashError(NorFlashErrorKind::Other))
    }
}

impl RamFlash {
    /// Erase one sector, or tear it if the power goes.
    fn erase_sector(&mut self, start: usize) -> Result<(), RamFlashError> {
        let sector = &mut self.bytes[start..start + Self::PAGE as usize];
        match self.clock.charge(None) {
            Charge::Dead => Err(RamFlashError(NorFlashErrorKind::Other)),
            Charge::Done => {
                sector.fill(0xFF);
                Ok(())
            }
            Charge::Torn(fraction) => {
                let erased = (fraction * sector.len() as f64) as usize;
                sector[..erased].fill(0xFF);
                let band_end = (erased + Self::PROGRAM_PAGE as usize).min(sector.len());
                for cell in &mut sector[erased..band_end] {
                    *cell = self.clock.random_byte();
                }
                Err(RamFlashError(NorFlashErrorKind::Other))
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use embassy_futures::block_on;

    fn timed() -> (RamFlash, FlashClock) {
        let clock = FlashClock::new(400_000, 3_000, 7);
        (RamFlash::new(2).with_clock(clock.clone()), clock)
    }

    #[test]
    fn operations_take_their_time_and_are_counted() {
        let (mut flash, clock) = timed();
        block_on(flash.erase(0, 2 * RamFlash::PAGE)).unwrap();
        // 8 bytes across a program-page boundary: two pages.
        block_on(flash.write(252, &[0; 8])).unwrap();
        assert_eq!((clock.erases(), clock.pages_written()), (2, 2));
        assert_eq!(clock.take_spent_us(), 2 * 400_000 + 2 * 3_000);
        assert_eq!(clock.take_spent_us(), 0, "taken once");
    }

    #[test]
    fn an_erase_cut_mid_way_is_torn_and_nothing_after_it_happens() {
        let (mut flash, clock) = timed();
        block_on(flash.write(0, &[0; RamFlash::PAGE as usize])).unwrap();
        clock.set_budget_us(Some(100_000));
        assert!(block_on(flash.erase(0, RamFlash::PAGE)).is_err());
        assert!(clock.is_cut());
        assert_eq!(clock.take_spent_us(), 100_000 + 16 * 3_000);
        let mut sector = vec![0u8; RamFlash::PAGE as usize];
        block_on(flash.read(0, &mut sector)).unwrap();
        // A quarter of the time: the first quarter erased, random bytes, then the old zeros.
        assert!(sector[..1024].iter().all(|&b| b == 0xFF));
        assert!(sector[1024..1280].iter().any(|&b| b != 0xFF && b != 0));
        assert!(sector[1280..].iter().all(|&b| b == 0));
        assert!(block_on(flash.write(RamFlash::PAGE, &[0; 4])).is_err());
        assert_eq!(clock.take_spent_us(), 0, "dead: nothing more took time");
        clock.power_on();
        block_on(flash.write(RamFlash::PAGE, &[0; 4])).unwrap();
    }

    #[test]
    fn a_write_cut_mid_way_programs_only_its_first_words() {
        let (mut flash, clock) = timed();
        clock.set_budget_us(Some(1_500));
        assert!(block_on(flash.write(0, &[0; 16])).is_err());
        let mut bytes = [0u8; 16];
        block_on(flash.read(0, &mut bytes)).unwrap();
        // Half the time: two words programmed, then a partly programmed one, then nothing.
        assert_eq!(bytes[..8], [0; 8]);
        assert_eq!(bytes[12..], [0xFF; 4]);
    }
}
