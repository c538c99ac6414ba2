//! The cutter twin's `$` commands and its settings (`$$`, `$N=V`): the values a stock GRBL 1.1
//! reports, with laser mode (`$32`), `$30`, the travel (`$130`–`$132`), homing (`$22`) and soft
//! limits (`$20`) as the twin was set up. As in GRBL, `$20=1` is refused without homing
//! (`error:10`) and `$22=0` turns soft limits off.

use std::collections::BTreeMap;
use std::fmt::Write as _;

use super::gcode::{Motion, Spindle, codes};
use super::machine::{Grbl, error, ok};
use super::options::CutterOptions;
use super::{PLANNER_BLOCKS, RX_BUFFER_LEN, VERSION};

use kerfmeter_grbl::commands;
use kerfmeter_grbl::settings::{
    ACCELERATION_MM_PER_S2, HOMING, HOMING_DIR_MASK, HOMING_PULLOFF_MM as HOMING_PULLOFF,
    LASER_MODE, MAX_POWER_S as MAX_POWER, MAX_RATE_MM_PER_MIN, MAX_TRAVEL_MM as MAX_TRAVEL,
    SOFT_LIMITS, STOCK,
};

/// `$110`: X's maximum rate, mm/min (the twin's rate for every axis).
const MAX_RATE: u16 = MAX_RATE_MM_PER_MIN[0];
/// `$120`: X's acceleration, mm/s² (used only to stop a feed hold).
const ACCELERATION: u16 = ACCELERATION_MM_PER_S2[0];

/// The settings by number.
#[derive(Debug, Clone)]
pub(super) struct Settings(BTreeMap<u16, f64>);

impl Settings {
    /// Stock settings, with laser mode, the `S` of full power, the travel, homing and soft
    /// limits as `options` give them (soft limits only with homing, as GRBL allows).
    pub fn new(options: &CutterOptions) -> Self {
        let flag = |on: bool| if on { 1.0 } else { 0.0 };
        let mut map: BTreeMap<u16, f64> = STOCK.into_iter().collect();
        map.insert(LASER_MODE, flag(options.laser_mode));
        map.insert(MAX_POWER, options.max_power_s);
        map.insert(HOMING, flag(options.homing));
        map.insert(SOFT_LIMITS, flag(options.homing && options.soft_limits));
        for (number, travel_mm) in MAX_TRAVEL.into_iter().zip(options.travel_mm) {
            map.insert(number, travel_mm);
        }
        Self(map)
    }

    fn get(&self, number: u16) -> f64 {
        self.0.get(&number).copied().unwrap_or(0.0)
    }

    pub fn laser_mode(&self) -> bool {
        self.get(LASER_MODE) != 0.0
    }

    pub fn max_power_s(&self) -> f64 {
        self.get(MAX_POWER)
    }

    pub fn max_rate_mm_per_min(&self) -> f64 {
        self.get(MAX_RATE).max(1.0)
    }

    pub fn acceleration_mm_per_s2(&self) -> f64 {
        self.get(ACCELERATION).max(1.0)
    }

    pub fn soft_limits(&self) -> bool {
        self.get(SOFT_LIMITS) != 0.0
    }

    pub fn homing(&self) -> bool {
        self.get(HOMING) != 0.0
    }

    /// Whether `axis` (0 X, 1 Y, 2 Z) homes toward negative (`$23`).
    pub fn homes_negative(&self, axis: usize) -> bool {
        (self.get(HOMING_DIR_MASK) as u32) & (1 << axis) != 0
    }

    pub fn homing_pulloff_mm(&self) -> f64 {
        self.get(HOMING_PULLOFF)
    }

    /// `$130`–`$132`: the travel GRBL believes each axis has, mm.
    pub fn max_travel_mm(&self) -> [f64; 3] {
        MAX_TRAVEL.map(|number| self.get(number))
    }

    /// `$N=V`: set a known setting. As GRBL: soft limits need homing (`error:10`), and homing
    /// off turns them off.
    fn set(&mut self, number: u16, value: f64) -> Result<(), u8> {
        if value < 0.0 {
            return Err(codes::NEGATIVE_VALUE);
        }
        if number == SOFT_LIMITS && value != 0.0 && !self.homing() {
            return Err(codes::SOFT_LIMIT_ERROR);
        }
        if number == HOMING && value == 0.0 {
            self.0.insert(SOFT_LIMITS, 0.0);
        }
        match self.0.get_mut(&number) {
            Some(slot) => {
                *slot = value;
                Ok(())
            }
            None => Err(codes::INVALID_STATEMENT),
        }
    }

    /// The `$$` report (without its `ok`).
    fn report(&self) -> String {
        let mut out = String::new();
        for (number, value) in &self.0 {
            let _ = if value.fract() == 0.0 {
                write!(out, "${number}={value:.0}\r\n")
            } else {
                write!(out, "${number}={value:.3}\r\n")
            };
        }
        out
    }
}

impl Grbl {
    /// Run a `$` line; its whole reply.
    pub(super) fn system_command(&mut self, line: &str) -> String {
        let command: String = line
            .chars()
            .filter(|c| !c.is_whitespace())
            .map(|c| c.to_ascii_uppercase())
            .collect();
        let needs_rest = matches!(command.as_str(), commands::SETTINGS | commands::HOME)
            || command.contains('=');
        if needs_rest && self.is_busy() {
            return error(codes::NOT_IDLE);
        }
        match command.as_str() {
            "$" => {
                "[HLP:$$ $# $G $I $N $x=val $Nx=line $J=line $SLP $C $X $H ~ ! ? ctrl-x]\r\nok\r\n"
                    .into()
            }
            commands::SETTINGS => self.settings.report() + &ok(),
            commands::UNLOCK if self.alarm.is_some() => {
                self.unlock();
                "[MSG:Caution: Unlocked]\r\nok\r\n".into()
            }
            commands::UNLOCK => ok(),
            commands::PARSER_STATE => format!("{}\r\nok\r\n", self.parser_state()),
            commands::BUILD_INFO => format!(
                "[VER:{VERSION}.kerfmeter-twin:]\r\n{}V,{PLANNER_BLOCKS},{RX_BUFFER_LEN}]\r\nok\r\n",
                kerfmeter_grbl::BUILD_OPTIONS_PREFIX
            ),
            commands::HOME if !self.settings.homing() => error(codes::SETTING_DISABLED),
            commands::HOME => self.home(),
            commands::PARAMETERS => self.parameters_report() + &ok(),
            commands::CHECK_MODE => self.toggle_check_mode(),
            _ => self.set_setting(&command),
        }
    }

    /// `$C`: into check mode from rest (`error:8` otherwise); out of it with a soft reset,
    /// as GRBL does (its `ok`, then the banner).
    fn toggle_check_mode(&mut self) -> String {
        if self.check_mode {
            self.out.extend_from_slice(b"[MSG:Disabled]\r\nok\r\n");
            self.soft_reset();
            return String::new();
        }
        if self.alarm.is_some() || self.is_busy() {
            return error(codes::NOT_IDLE);
        }
        self.check_mode = true;
        "[MSG:Enabled]\r\nok\r\n".into()
    }

    /// `$N=V`.
    fn set_setting(&mut self, command: &str) -> String {
        let Some((number, value)) = command[1..].split_once('=') else {
            return error(codes::INVALID_STATEMENT);
        };
        let (Ok(number), Ok(value)) = (number.parse::<u16>(), value.parse::<f64>()) else {
            return error(codes::BAD_NUMBER_FORMAT);
        };
        match self.settings.set(number, value) {
            Ok(()) => ok(),
            Err(code) => error(code),
        }
    }

    /// The `$G` report.
    fn parser_state(&self) -> String {
        let m = &self.modal;
        let motion = match m.motion {
            Motion::Rapid => "G0",
            Motion::Linear => "G1",
            Motion::Arc { clockwise: true } => "G2",
            Motion::Arc { clockwise: false } => "G3",
        };
        let units = if m.metric { "G21" } else { "G20" };
        let distance = if m.absolute { "G90" } else { "G91" };
        let spindle = match m.spindle {
            Spindle::Constant => "M3",
            Spindle::Dynamic => "M4",
            Spindle::Off => "M5",
        };
        format!(
            "[GC:{motion} G54 G17 {units} {distance} G94 {spindle} M9 T0 F{:.0} S{:.0}]",
            m.feed_mm_per_min, m.power_s
        )
    }
}
