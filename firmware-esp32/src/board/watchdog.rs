//! The board's hardware watchdog: TIMG1's MWDT, resetting the whole system at its first stage.
//!
//! Two users share it: the control task, which feeds it every tick at
//! [`WATCHDOG_TIMEOUT_MS`], and the configuration flash ([`WatchdogFlash`]), which gives each
//! erase and write its own longer window. Both run in the control task, one after the other; the
//! watchdog lives in a static behind a critical-section mutex so that each can hold a
//! [`BoardWatchdog`] handle. Until [`BoardWatchdog::start`] takes the MWDT, feeding does nothing
//! (the configuration is opened at boot, before the watchdog runs).
//!
//! [`WatchdogFlash`]: crate::watchdog::WatchdogFlash

use core::cell::RefCell;

use embassy_sync::blocking_mutex::{Mutex, raw::CriticalSectionRawMutex};
use esp_hal::peripherals::TIMG1;
use esp_hal::time::Duration;
use esp_hal::timer::timg::{MwdtStage, TimerGroup, Wdt};

use crate::watchdog::{WATCHDOG_TIMEOUT_MS, Watchdog};

/// The running MWDT and the timeout it was last given, ms.
struct Running {
    wdt: Wdt<TIMG1<'static>>,
    timeout_ms: u64,
}

static MWDT: Mutex<CriticalSectionRawMutex, RefCell<Option<Running>>> =
    Mutex::new(RefCell::new(None));

/// A handle on the board's watchdog (see the module docs).
#[derive(Debug, Clone, Copy, Default)]
pub struct BoardWatchdog;

impl BoardWatchdog {
    /// Take TIMG1's MWDT and start it at [`WATCHDOG_TIMEOUT_MS`]: from now on the chip resets
    /// unless it is fed in time.
    pub fn start(timg1: TIMG1<'static>) -> Self {
        let mut wdt = TimerGroup::new(timg1).wdt;
        wdt.set_timeout(
            MwdtStage::Stage0,
            Duration::from_millis(WATCHDOG_TIMEOUT_MS),
        );
        wdt.enable();
        wdt.feed();
        MWDT.lock(|cell| {
            *cell.borrow_mut() = Some(Running {
                wdt,
                timeout_ms: WATCHDOG_TIMEOUT_MS,
            })
        });
        Self
    }
}

impl Watchdog for BoardWatchdog {
    fn feed_ms(&mut self, timeout_ms: u64) {
        MWDT.lock(|cell| {
            if let Some(running) = cell.borrow_mut().as_mut() {
                if running.timeout_ms != timeout_ms {
                    // Restart the count first, so that a shorter timeout cannot find it past.
                    running.wdt.feed();
                    running
                        .wdt
                        .set_timeout(MwdtStage::Stage0, Duration::from_millis(timeout_ms));
                    running.timeout_ms = timeout_ms;
                }
                running.wdt.feed();
            }
        });
    }
}
