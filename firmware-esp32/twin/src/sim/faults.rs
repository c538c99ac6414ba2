//! The injected faults: when each one strikes in a run, and its repair, as a person would
//! before `ClearFault`.

use kerfmeter_firmware::fakes::as5048a::MisoFault;

use super::{FAULT_AT_MS, PARITY_ERROR_EVERY_FRAMES, Twin};
use crate::options::InjectedFault;

impl Twin {
    pub(super) fn strike_faults(&mut self) {
        let Some(fault) = self.options.fault else {
            return;
        };
        let chip = self.hardware.encoder.bus_mut();
        if fault == InjectedFault::Parity && chip.frames().is_multiple_of(PARITY_ERROR_EVERY_FRAMES)
        {
            chip.corrupt_next_responses(1);
        }
        let Some(start) = self.run_started_us else {
            return;
        };
        if self.fault_struck || self.now_us < start + FAULT_AT_MS * 1000 {
            return;
        }
        self.fault_struck = true;
        match fault {
            InjectedFault::MagnetLost => chip.set_magnet_lost(true),
            InjectedFault::MisoStuck => chip.set_miso_fault(Some(MisoFault::StuckLow)),
            InjectedFault::DriverFault => self.flt_injected = true,
            InjectedFault::OverCurrent => self.over_current = true,
            InjectedFault::ProngSlip => self.plant.slip_prong(),
            InjectedFault::HostSilent
            | InjectedFault::Parity
            | InjectedFault::NoInset
            | InjectedFault::MotorDisconnected => {}
        }
    }

    /// Clear the injected fault's cause (the magnet is put back, the short removed, ...), as a
    /// person would before `ClearFault`. A `ClearFault` request does this by itself.
    pub fn repair(&mut self) {
        let chip = self.hardware.encoder.bus_mut();
        chip.set_magnet_lost(false);
        chip.set_miso_fault(None);
        self.flt_injected = false;
        self.over_current = false;
        self.plant.set_inset_present(true);
        self.plant.set_motor_connected(true);
        self.options.fault = None;
        self.fault_struck = false;
    }
}
