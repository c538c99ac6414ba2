//! One draw run: its twin booted and configured, one measurement from a reset, and how it ended
//! (a panic caught and named).

use super::SETTLE_TICKS;
use super::device::device_config;
use super::draw::Draw;
use crate::Twin;
use crate::study::{Outcome, configure, measure};

/// What a draw ended in.
#[derive(Debug, Clone, PartialEq)]
pub struct DrawReport {
    /// The draw.
    pub draw: Draw,
    /// How its measurement ended.
    pub outcome: Outcome,
    /// Whether the motor was in its safe state when it ended (`None` after a panic).
    pub motor_safe: Option<bool>,
    /// Simulated time the twin ran, ms.
    pub sim_ms: u64,
}

/// Build the draw's twin and run its one measurement, catching a panic.
pub fn run_draw(draw: &Draw) -> DrawReport {
    let options = draw.options();
    let run = draw.run;
    let ran = std::panic::catch_unwind(move || {
        let mut twin = Twin::new(options);
        twin.advance_ticks(SETTLE_TICKS);
        let outcome = match configure(&mut twin, &device_config(&options.plant)) {
            Ok(()) => measure(&mut twin, &run),
            Err(ending) => ending,
        };
        (outcome, twin.motor_safe(), twin.now_us() / 1000)
    });
    let (outcome, motor_safe, sim_ms) = match ran {
        Ok((outcome, safe, sim_ms)) => (outcome, Some(safe), sim_ms),
        Err(payload) => (Outcome::Panic(panic_text(payload.as_ref())), None, 0),
    };
    DrawReport {
        draw: draw.clone(),
        outcome,
        motor_safe,
        sim_ms,
    }
}

fn panic_text(payload: &(dyn std::any::Any + Send)) -> String {
    payload
        .downcast_ref::<&str>()
        .map(|s| (*s).to_owned())
        .or_else(|| payload.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "panic".to_owned())
}
