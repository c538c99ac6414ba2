//! How a cutter twin is set up ([`CutterOptions`]): its settings at boot, its travel and work
//! offset, the faults injected into it, and how what its laser traces is cut.

use kerfmeter_twin::plant::CutterKerf;

/// How a cutter twin is set up, and the faults injected into it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CutterOptions {
    /// `$32` at boot: laser mode (the default) or a spindle machine.
    pub laser_mode: bool,
    /// Boot in the alarm state, as a machine with homing enabled does (`$X` unlocks it).
    pub boot_in_alarm: bool,
    /// `$30` at boot: the `S` of full power (GRBL's default 1000; many diode lasers use 255).
    pub max_power_s: f64,
    /// The machine's travel, X, Y and Z, mm: where its end stops are, and `$130`–`$132` at boot
    /// (see [`super::travel`] for where the twin boots in it).
    pub travel_mm: [f64; 3],
    /// `$22` at boot: homing enabled. The twin then boots in alarm, as GRBL does, until `$H`
    /// (or `$X`); its machine space runs from −travel to 0 on each axis.
    pub homing: bool,
    /// `$20` at boot: soft limits (only with `homing`: GRBL refuses them without).
    pub soft_limits: bool,
    /// The G54 work offset, mm (kept in GRBL's EEPROM): every absolute target but G53's is
    /// this much from the program's number (work = machine − offset).
    pub work_offset_mm: [f64; 3],
    /// Trip a hard limit (`ALARM:1`) after this much motion time, ms.
    pub hard_limit_after_ms: Option<u64>,
    /// Answer the Nth G-code line since boot (1 = the first) with `error:` this code.
    pub error_on_line: Option<(u32, u8)>,
    /// At the Nth G-code line it runs (1 = the first; check mode's lines not counted), go into
    /// alarm (a soft limit, `ALARM:2`: motion stops, the laser off) with the `ALARM:2` line lost
    /// on the way, as on a noisy line: only its status reports say it is in alarm.
    pub unannounced_alarm_on_line: Option<u32>,
    /// How what the laser traces is cut: kerf, its spread and the machine's repeatability (the
    /// one kerf model, [`kerfmeter_twin::plant::Cutter`], made by [`CutterKerf::cutter`]). The
    /// device twin measures a traced gauge cut so
    /// ([`kerfmeter_twin::Twin::place_traced_gauge_cut_by`]).
    pub kerf: CutterKerf,
}

impl Default for CutterOptions {
    fn default() -> Self {
        Self {
            laser_mode: true,
            boot_in_alarm: false,
            max_power_s: 1000.0,
            travel_mm: [600.0, 400.0, 50.0],
            homing: false,
            soft_limits: false,
            work_offset_mm: [0.0; 3],
            hard_limit_after_ms: None,
            error_on_line: None,
            unannounced_alarm_on_line: None,
            kerf: CutterKerf::default(),
        }
    }
}
