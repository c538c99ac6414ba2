//! The brake that starts a run or a reset: the driver woken from its sleep and held braking
//! (awake, duty 0: no torque, the motor shorted through the low-side switches) for
//! [`OFFSET_WINDOW_TICKS`], then the run engages or the reset drives.
//!
//! # Why
//!
//! The G2's current sense (`CS`) shows its offset only awake; what it reads while the driver
//! sleeps is not documented, and the controller idles asleep. So the current sense learns its
//! offset from readings taken braking, after the RC filter has forgotten the sleep level
//! (`board::current`), and this brake is where every run and every reset gets them, before the
//! first drive; the self-test's encoder phase, which brakes longer, is its own. The window
//! costs each run and reset 20 ms.
//!
//! # Safety
//!
//! The window is part of the run or reset: every fault check on the inputs (driver FLT,
//! over-current or an unknown current, encoder errors and diagnostics, a late step, host
//! silence) applies and latches the fault with the motor safe (asleep, duty 0) from that very
//! tick, and an abort ends it, as anywhere else. The run's motion limits are not checked: the
//! brake holds the hub where it stands, and the run's time counts from the engage.

use super::{Controller, State};
use crate::board::current::OFFSET_WINDOW_TICKS;

/// What the brake leads to.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Woken {
    /// The run engages.
    Run,
    /// The reset drives the hub back to zero.
    Reset,
}

impl Controller {
    /// One tick of the brake, `ticks` into it: braking for [`OFFSET_WINDOW_TICKS`] ticks; the
    /// tick after them is the first of what follows (`then`).
    pub(super) fn wake(&mut self, ticks: u32, then: Woken) {
        if u64::from(ticks) < OFFSET_WINDOW_TICKS {
            self.torque_nm = 0.0;
            self.state = State::Waking {
                ticks: ticks + 1,
                then,
            };
            return;
        }
        match then {
            Woken::Run => {
                self.state = State::Engaging;
                self.engage();
            }
            Woken::Reset => self.reset_step(0, 0),
        }
    }
}
