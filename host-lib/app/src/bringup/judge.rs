//! Each bench check judged from what the device reported (and what a person answered): pure
//! functions, one a step, with the bands they judge by and where each band comes from.

use kerfmeter::protocol::advice::{Advice, Advised};
use kerfmeter::protocol::{
    AdcCalibration, BrownOutDetector, Conditions, Diagnostics, G2Variant, SUPPLY_MIN_V,
    SelfTestItem, SelfTestReport, Status, TestOutcome,
};

use super::HubTurn;
use super::report::{AnsweredBy, Step, StepId};
use crate::self_test::{self, STILL_DEG};

/// The supply sense's honest tolerance, as a fraction of the reading: the divider's 1 %
/// resistors and the ADC's gain (docs/hardware.md, bench check 4).
pub const SUPPLY_TOLERANCE_FRACTION: f32 = 0.02;
/// ... plus this, V: the C3 ADC's ±35 mV at 11 dB through the 100k/8.2k divider.
pub const SUPPLY_TOLERANCE_V: f32 = 0.46;

/// The CS offset band the firmware takes a braking reading for (`board::current`'s
/// `OFFSET_RANGE_MV`, about Pololu's 50 mV), mV.
pub const CS_OFFSET_RANGE_MV: (f32, f32) = (30.0, 80.0);
/// The highest CS reading with the driver asleep that a G2's sense can give, mV: its offset
/// (at most 80 mV) and a sleep level up to 40 mV above it, rounded up. Pololu does not
/// document the sleep level; more than this is another signal on the pin.
pub const CS_ASLEEP_MAX_MV: u16 = 120;

/// The AS5048A's AGC band that the firmware trusts without flagging `weak-magnet` (its
/// `as5048a::AGC_WARN`): outside it the magnet is too close (low) or too far (high).
pub const AGC_GOOD: (u8, u8) = (20, 220);
/// The CORDIC magnitude band the firmware accepts (its `as5048a::MAGNITUDE_RANGE`).
pub const MAGNITUDE_GOOD: (u16, u16) = (500, 16_000);

/// The longest control step a board may take, µs: "a few hundred µs at most" of its 1000 µs
/// period (bench check 5).
pub const STEP_MAX_US: u32 = 500;
/// The longest gap between two control steps, µs: "a little over 1000 µs"; three periods
/// means something blocks the core (bench check 5).
pub const GAP_MAX_US: u32 = 3000;

/// `before`, the parameter `param` in the front end's words, then `after`: advice a library
/// gives without naming a front end's flag (`--motor-inverted` on the command line).
pub(super) fn with_param(before: &str, param: &'static str, after: &str) -> String {
    Advised::text(before)
        .advise(Advice::Param(param))
        .then(after)
        .to_string()
}

/// `before`, `advice` in the front end's words, then `after`.
fn with_advice(before: &str, advice: Advice, after: &str) -> String {
    Advised::text(before).advise(advice).then(after).to_string()
}

/// The supply sense's tolerance at `v` volts.
pub fn supply_tolerance_v(v: f32) -> f32 {
    SUPPLY_TOLERANCE_FRACTION * v + SUPPLY_TOLERANCE_V
}

/// The reset reason.
pub fn reset_reason(d: &Diagnostics) -> Step {
    let r = d.reset_reason;
    let seen = format!("last reset: {}", r.words());
    if !r.is_abnormal() {
        return Step::pass(StepId::ResetReason, seen);
    }
    Step::fail(
        StepId::ResetReason,
        seen,
        "the chip did not start cleanly: a watchdog reset means its control loop stopped (a \
         hang), a brown-out that its 3.3 V dipped (a weak USB port or cable, or the motor's \
         current pulling the logic supply down), a panic a firmware bug; the motor was made safe \
         by the reset. Power it up again: if it recurs, capture the log on UART0 (GPIO21, 115200 \
         baud) and report it with this report",
    )
}

/// The ADC's calibration (and, as a note, the brown-out detector).
pub fn adc_calibration(d: &Diagnostics) -> Step {
    let brown_out = match d.brown_out {
        BrownOutDetector::Resets => "on",
        BrownOutDetector::InterruptOnly => "interrupt only",
        BrownOutDetector::Off => "OFF (a sagging logic supply can corrupt the chip's state)",
        BrownOutDetector::Unknown => "not reported",
    };
    let restarts = match d.adc_restarts {
        0 => String::new(),
        n => format!(", {n} conversion(s) given up"),
    };
    match d.adc_calibration {
        AdcCalibration::Efuse { version } if d.adc_restarts == 0 => Step::pass(
            StepId::AdcCalibration,
            format!("calibrated (eFuse scheme {version}); brown-out detector {brown_out}"),
        ),
        AdcCalibration::Efuse { version } => Step::fail(
            StepId::AdcCalibration,
            format!("calibrated (eFuse scheme {version}){restarts}"),
            "an ADC conversion never finished and the ADC was restarted: the current and supply \
             readings had gaps; check the CS and supply-sense wiring (their RC filters, no \
             other signal on GPIO0 and GPIO4)",
        ),
        AdcCalibration::Uncalibrated => Step::fail(
            StepId::AdcCalibration,
            format!("UNCALIBRATED (no ADC calibration eFuses){restarts}"),
            "this chip carries no ADC calibration: its current sense reads some 30–40 % high, \
             and the over-current trip, the self-test's torque constant and the winding estimate \
             with it (a measurement's torque, set from the duty, is not affected). Use a board \
             with a calibrated ESP32-C3 (eFuse block 2 of version 1), or accept the error \
             knowingly",
        ),
        AdcCalibration::Unknown => Step::not_checked(
            StepId::AdcCalibration,
            "not reported by this board",
            "the board does not read its ADC calibration eFuses",
        ),
    }
}

/// The motor supply the device reads, within the G2's limits by more than the sense's
/// tolerance.
pub fn supply(status: &Status, driver: G2Variant) -> Step {
    let max_v = driver.supply_max_v();
    let Some(v) = status.supply_v else {
        return Step::not_checked(
            StepId::Supply,
            "not measured by this board",
            "the board has no supply sense: check the supply with a meter",
        );
    };
    let tol = supply_tolerance_v(v);
    let seen = format!(
        "{v:.2} V ± {tol:.2} V (G2 {} accepts {SUPPLY_MIN_V:.0}–{max_v:.0} V)",
        driver.name()
    );
    if v > max_v {
        return Step::fail(
            StepId::Supply,
            seen,
            format!(
                "too high for the G2 {} (`supply-out-of-range`: the device will not drive the \
                 motor): use a 12 V supply, or build with a 24 V variant for a 24 V rail",
                driver.name()
            ),
        );
    }
    if v < SUPPLY_MIN_V || status.conditions.contains(Conditions::SUPPLY_OUT_OF_RANGE) {
        return Step::fail(
            StepId::Supply,
            seen,
            "too low (`supply-out-of-range`: the device will not drive the motor): near 0 V the \
             motor supply is off or not wired to the G2's VIN, or the divider to GPIO4 is open; \
             otherwise the supply is below 9 V or sags under its own cable: give it 12 V",
        );
    }
    if v - tol < SUPPLY_MIN_V || v + tol > max_v {
        return Step::fail(
            StepId::Supply,
            seen,
            "the supply is within the sense's tolerance of a limit: the device may refuse it as \
             it sags or rises; use a supply well inside the range (12 V is the reference)",
        );
    }
    Step::pass(StepId::Supply, seen)
}

/// The device's supply reading against a meter's at the G2's `VIN`.
pub fn supply_meter(device_v: f32, meter: Option<(f32, AnsweredBy)>) -> Step {
    let Some((meter_v, by)) = meter else {
        return Step::not_checked(
            StepId::SupplyMeter,
            format!("device reads {device_v:.2} V; no meter reading given"),
            with_param(
                "measure VIN at the G2 with a meter and give it (",
                "meter_v",
                ", or when asked)",
            ),
        );
    };
    let tol = supply_tolerance_v(meter_v);
    let diff = device_v - meter_v;
    let seen = format!(
        "meter {meter_v:.2} V, device {device_v:.2} V: {diff:+.2} V (tolerance ±{tol:.2} V)"
    );
    let step = if diff.abs() <= tol {
        Step::pass(StepId::SupplyMeter, seen)
    } else {
        Step::fail(
            StepId::SupplyMeter,
            seen,
            "the device reads its supply further from the meter than its sense's tolerance: \
             check the divider's resistors (100 kΩ over 8.2 kΩ, 1 %) and that it goes to GPIO4, \
             and that the meter measured at the G2's VIN, not at the supply",
        )
    };
    step.answered_by(Some(by))
}

/// The current sense with the driver asleep.
pub fn cs_asleep(d: &Diagnostics) -> Step {
    let Some(mv) = d.cs_asleep_mv else {
        return Step::not_checked(
            StepId::CsAsleep,
            "no reading yet",
            "the device has not yet held the driver asleep long enough to read CS",
        );
    };
    let cost_a = (f32::from(mv) - d.cs_offset_mv) / (d.driver.cs_mv_per_a() * 0.2);
    let seen = format!(
        "{mv} mV ({:+.1} A at the 0.2 duty floor, were it taken for the offset)",
        cost_a
    );
    if mv <= CS_ASLEEP_MAX_MV {
        return Step::pass(StepId::CsAsleep, seen);
    }
    Step::fail(
        StepId::CsAsleep,
        seen,
        format!(
            "CS reads more than a sleeping G2's sense can give ({CS_ASLEEP_MAX_MV} mV): another \
             signal is on the pin; check that the G2's CS goes to GPIO0 through the 10 kΩ / \
             100 nF filter, and nothing else does"
        ),
    )
}

/// The current-sense offset learnt awake and braking (after the self-test).
pub fn cs_braking(d: &Diagnostics) -> Step {
    let (lo, hi) = CS_OFFSET_RANGE_MV;
    let seen = format!(
        "offset {:.1} mV{}",
        d.cs_offset_mv,
        if d.cs_offset_learnt {
            ", learnt braking"
        } else {
            ", NOT learnt (still the nominal one)"
        }
    );
    if d.cs_offset_learnt && (lo..=hi).contains(&d.cs_offset_mv) {
        return Step::pass(StepId::CsBraking, seen);
    }
    Step::fail(
        StepId::CsBraking,
        seen,
        format!(
            "no braking reading of CS fell in {lo:.0}–{hi:.0} mV (Pololu gives about 50 mV): \
             every current the device reads is off by the difference; check the CS wire and \
             its filter, and that the G2 variant the firmware is built for is the one fitted"
        ),
    )
}

/// The encoder's own diagnostics and the conditions they raise.
pub fn encoder(d: &Diagnostics, conditions: Conditions) -> Step {
    let Some(e) = d.encoder else {
        return Step::fail(
            StepId::Encoder,
            "no good read since boot",
            "the AS5048A does not answer: check its 3.3 V (VDD5V tied to VDD3V3), CSn on GPIO2 \
             with its pull-up, and the SPI lines (CLK GPIO6, MISO GPIO5, MOSI GPIO7)",
        );
    };
    let seen = format!(
        "magnitude {}, AGC {}, OCF {}, COF {}, COMP {}",
        e.magnitude,
        e.agc,
        if e.ocf { "set" } else { "CLEAR" },
        if e.cof { "SET" } else { "clear" },
        match (e.comp_low, e.comp_high) {
            (false, false) => "ok",
            (true, _) => "LOW (field too strong)",
            (_, true) => "HIGH (field too weak)",
        }
    );
    let (agc_lo, agc_hi) = AGC_GOOD;
    let (mag_lo, mag_hi) = MAGNITUDE_GOOD;
    let unreadable = conditions.contains(Conditions::ENCODER_UNREADABLE);
    let means = if unreadable || !e.ocf || e.cof {
        "the encoder's reads are bad or its diagnostics say so (OCF clear or COF set): check \
         its 3.3 V, CSn's pull-up and the SPI wiring, and keep the motor leads away from them"
    } else if e.comp_high || e.agc > agc_hi || e.magnitude < mag_lo {
        "the magnet's field is weak: the magnet is missing, too far from the chip (the \
         datasheet's air gap is 0.5–2.5 mm) or off-centre; fit it centred over the chip"
    } else if e.comp_low || e.agc < agc_lo || e.magnitude > mag_hi {
        "the magnet's field is too strong: it sits too close to the chip; add a little air gap"
    } else if conditions.contains(Conditions::NO_MAGNET) {
        "the device reports no magnet (`no-magnet`): check that the magnet is fitted and centred"
    } else {
        return Step::pass(StepId::Encoder, seen);
    };
    Step::fail(
        StepId::Encoder,
        format!("{seen}; AGC good {agc_lo}–{agc_hi}"),
        means,
    )
}

/// The self-test's items other than the direction, which [`direction`] judges.
pub fn self_test(r: &SelfTestReport, configured_nm: Option<f32>) -> Step {
    let seen = format!(
        "encoder reads {:.1} % ok, magnet {:.0}, torque constant {:.3} N·m per duty{}",
        r.encoder_ok_fraction.value * 100.0,
        r.magnet_magnitude.value,
        r.torque_per_duty_nm.value,
        configured_nm.map_or(String::new(), |c| format!(" (configured {c:.3})"))
    );
    // The first item that did not pass, the direction aside ([`direction`] judges it).
    let failed = self_test::items(r)
        .into_iter()
        .find(|&(name, item, _)| name != self_test::DIRECTION && item.outcome != TestOutcome::Pass);
    let Some((name, item, _)) = failed else {
        return Step::pass(StepId::SelfTest, seen);
    };
    let means = format!("{name}: {}", self_test::explain(name, item, configured_nm));
    Step::fail(StepId::SelfTest, seen, means)
}

/// The self-test's direction item, and what the person saw the hub do.
pub fn direction(item: SelfTestItem, seen_by: Option<(HubTurn, AnsweredBy)>) -> Step {
    let device = if item.outcome == TestOutcome::Pass {
        HubTurn::Cw
    } else if item.value <= -STILL_DEG {
        HubTurn::Ccw
    } else {
        HubTurn::Still
    };
    let person = seen_by.map(|(t, _)| t);
    let seen = format!(
        "encoder: {:+.1}° under a clockwise torque ({}); seen: {}",
        item.value,
        device.words(),
        person.map_or("no answer", HubTurn::words)
    );
    let by = seen_by.map(|(_, b)| b);
    match (device, person) {
        (HubTurn::Cw, Some(HubTurn::Cw)) => Step::pass(StepId::Direction, seen).answered_by(by),
        (HubTurn::Cw, None) => Step::not_checked(
            StepId::Direction,
            seen,
            with_param(
                "the encoder agrees with the drive, but nobody said which way the hub turned \
                 seen from above (",
                "hub_turned",
                ", or when asked): both could be reversed",
            ),
        ),
        _ => Step::fail(StepId::Direction, seen, direction_means(device, person)).answered_by(by),
    }
}

/// What a direction that is not clockwise on both counts means: which sense to invert.
fn direction_means(device: HubTurn, person: Option<HubTurn>) -> String {
    // `--motor-inverted true` on the command line, `motor_inverted true` elsewhere.
    let inverted = |params: &[&'static str]| {
        params.iter().fold(
            Advised::text("change the device's configuration:"),
            |advised, &param| advised.then(" ").advise(Advice::Param(param)).then(" true"),
        )
    };
    match (device, person) {
        (HubTurn::Cw, Some(HubTurn::Ccw)) => Advised::text(
            "motor and encoder are both reversed: the device agrees with itself, but turns the \
             gauge's inset the wrong way; ",
        )
        .append(inverted(&["motor_inverted", "encoder_inverted"]))
        .then(" (or swap the motor's leads and turn the encoder's magnet over)")
        .to_string(),
        (HubTurn::Ccw, Some(HubTurn::Cw)) => {
            Advised::text("the hub turned the right way but the encoder counted backwards: ")
                .append(inverted(&["encoder_inverted"]))
                .to_string()
        }
        (HubTurn::Ccw, _) => Advised::text(
            "the hub turned the wrong way under a clockwise torque: the motor's leads are \
             swapped; swap them at the G2's OUTA/OUTB, or ",
        )
        .append(inverted(&["motor_inverted"]))
        .to_string(),
        (HubTurn::Still, Some(HubTurn::Still) | None) => "the hub did not turn: the motor is \
            disconnected, its supply is off, or the hub is jammed"
            .to_owned(),
        _ => with_advice(
            "the encoder and the hub disagree: the magnet is not on the shaft that turned (check \
             the encoder's placement: ",
            Advice::ConfigGet,
            "), or it slips on its shaft",
        ),
    }
}

/// The worst timing since boot.
pub fn timing(status: &Status, simulated: bool) -> Step {
    let (step, gap) = (status.longest_step_us, status.longest_gap_us);
    let unmodelled = if simulated && step == 0 {
        " (the twin does not model a step's duration)"
    } else {
        ""
    };
    let seen = format!("longest step {step} µs{unmodelled}, longest gap {gap} µs");
    if step <= STEP_MAX_US && gap <= GAP_MAX_US {
        return Step::pass(StepId::Timing, seen);
    }
    Step::fail(
        StepId::Timing,
        format!("{seen} (at most {STEP_MAX_US} and {GAP_MAX_US} µs)"),
        "the control loop ran late: something blocks the core (a debug build, a log flood on \
         UART0, a flash stall); flash a release build (`cargo xtask flash`) and check again",
    )
}
