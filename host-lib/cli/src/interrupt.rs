//! Ctrl-C, SIGTERM and SIGHUP: one handler for the whole process, installed before a command
//! runs, chosen by what the command can leave behind if it dies mid-way.
//!
//! - A command that moves the motor or a cutter ([`OnSignal::Stop`]) is not killed: the signal
//!   raises a flag that it checks between status polls, so that it stops the device (abort, then
//!   wait for the device to report its motor at rest) or the cutter first. The device's own
//!   host-silence check would stop the motor too, but a second later and with a latched
//!   `HostSilent` fault that the next run trips over.
//! - A command that writes a file ([`OnSignal::CleanUp`]) removes its unfinished temporary file
//!   and exits, so that an output is only ever replaced by a finished one.
//! - The rest keep the default: the signal ends them at once.
//!
//! Interrupted, the process exits 128 + the signal's number (130 for SIGINT, 143 for SIGTERM,
//! 129 for SIGHUP), as a shell reports an interrupted program; `cut` and `job` report their own
//! cancellation instead (exit 4: what was sent, and that the laser is off).

use std::ops::ControlFlow;
use std::sync::atomic::{AtomicBool, AtomicI32, Ordering};
use std::sync::{Arc, OnceLock};

/// What a signal does to this process.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum OnSignal {
    /// The default: the process ends at once.
    Die,
    /// Raise the stop flag; the command stops its machines and returns.
    Stop,
    /// Remove unfinished outputs and exit.
    CleanUp,
}

/// The signal that interrupted the process (0: none yet).
static SIGNAL: AtomicI32 = AtomicI32::new(0);
/// True while the command waits at a prompt, where nothing moves: a signal then exits at once.
static PROMPTING: AtomicBool = AtomicBool::new(false);

/// The stop flag that `cut` and `job` poll, raised with [`SIGNAL`].
fn stop_flag() -> &'static Arc<AtomicBool> {
    static FLAG: OnceLock<Arc<AtomicBool>> = OnceLock::new();
    FLAG.get_or_init(|| Arc::new(AtomicBool::new(false)))
}

/// A signal that interrupted the process.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Signal(i32);

impl Signal {
    /// The signal's name (`SIGINT`, …).
    pub fn name(self) -> &'static str {
        match self.0 {
            1 => "SIGHUP",
            2 => "SIGINT",
            15 => "SIGTERM",
            _ => "a signal",
        }
    }

    /// The exit code of a process it interrupted: 128 + its number.
    pub fn exit_code(self) -> u8 {
        u8::try_from(128 + self.0).unwrap_or(u8::MAX)
    }
}

/// Install the handler for `on` (nothing for [`OnSignal::Die`]).
pub fn install(on: OnSignal) -> std::io::Result<()> {
    if on == OnSignal::Die {
        return Ok(());
    }
    platform::install(move |signal| on_signal(on, signal))
}

/// What the handler's thread does with `signal`.
fn on_signal(on: OnSignal, signal: i32) {
    // The first signal is the one the exit code tells; a second one changes nothing.
    let _ = SIGNAL.compare_exchange(0, signal, Ordering::SeqCst, Ordering::SeqCst);
    stop_flag().store(true, Ordering::SeqCst);
    let code = Signal(signal).exit_code();
    match on {
        OnSignal::CleanUp => {
            kerfmeter::files::remove_unfinished_outputs();
            std::process::exit(code.into());
        }
        OnSignal::Stop if PROMPTING.load(Ordering::SeqCst) => {
            eprintln!(
                "\ninterrupted ({}) at the prompt; nothing was moving",
                Signal(signal).name()
            );
            std::process::exit(code.into());
        }
        OnSignal::Stop | OnSignal::Die => {}
    }
}

/// The signal that interrupted the process, if one did.
pub fn raised() -> Option<Signal> {
    match SIGNAL.load(Ordering::SeqCst) {
        0 => None,
        n => Some(Signal(n)),
    }
}

/// [`ControlFlow::Break`] once a signal came: what a long device call's progress returns so
/// that the library aborts the device and waits for its motor to be at rest.
pub fn check() -> ControlFlow<()> {
    if raised().is_some() {
        ControlFlow::Break(())
    } else {
        ControlFlow::Continue(())
    }
}

/// The flag a signal raises, for code that polls an `AtomicBool` (the cutter's stream, the job).
pub fn flag() -> Arc<AtomicBool> {
    stop_flag().clone()
}

/// Run `wait` (a prompt's read), during which a signal exits the process at once: nothing moves
/// while a person is asked to place a gauge.
pub fn at_prompt<T>(wait: impl FnOnce() -> T) -> T {
    PROMPTING.store(true, Ordering::SeqCst);
    let result = wait();
    PROMPTING.store(false, Ordering::SeqCst);
    result
}

#[cfg(unix)]
mod platform {
    use signal_hook::consts::{SIGHUP, SIGINT, SIGTERM};
    use signal_hook::iterator::Signals;

    /// Hand SIGINT, SIGTERM and SIGHUP to `handle`, on a thread of its own.
    pub fn install(handle: impl Fn(i32) + Send + 'static) -> std::io::Result<()> {
        let mut signals = Signals::new([SIGINT, SIGTERM, SIGHUP])?;
        std::thread::Builder::new()
            .name("signals".into())
            .spawn(move || {
                for signal in signals.forever() {
                    handle(signal);
                }
            })?;
        Ok(())
    }
}

#[cfg(not(unix))]
mod platform {
    /// Hand Ctrl-C (and the console's close) to `handle`, as SIGINT.
    pub fn install(handle: impl Fn(i32) + Send + 'static) -> std::io::Result<()> {
        ctrlc::set_handler(move || handle(2)).map_err(std::io::Error::other)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn exit_codes_are_128_plus_the_signal() {
        assert_eq!(Signal(2).exit_code(), 130);
        assert_eq!(Signal(15).exit_code(), 143);
        assert_eq!(Signal(1).exit_code(), 129);
        assert_eq!(Signal(15).name(), "SIGTERM");
    }
}
