//! A test double of an ESP32-C3's USB-Serial-JTAG port as the host sees it: the
//! `serialport::SerialPort` a program gets when the OS opens the device's tty, with the device's
//! digital twin behind it. What a pseudo-terminal cannot do, it does:
//!
//! - It carries DTR and RTS to the chip as the OS driver does ([`Driver`]): what `open(2)` and the
//!   last `close(2)` send, and whether a one-line write sends the pair at once.
//! - It applies the chip's rules to every pair the chip receives, as Espressif documents them
//!   (*ESP32-C3 Technical Reference Manual*, "USB Serial/JTAG Controller", §30.3.1, Table 30.3-2
//!   "CDC-ACM Settings with RTS and DTR"):
//!
//!   | RTS | DTR | the chip |
//!   |-----|-----|----------|
//!   | 0 | 0 | clears its download-mode flag |
//!   | 0 | 1 | sets its download-mode flag |
//!   | 1 | 0 | is reset |
//!   | 1 | 1 | does nothing |
//!
//!   "If the download mode flag is set when the ESP32-C3 is reset, the ESP32-C3 will reboot into
//!   download mode. When this flag is cleared and the chip is reset, the ESP32-C3 will boot from
//!   flash." The chip stays in reset until the pair changes ("set RTS: reset SoC; clear RTS: exit
//!   reset", Table 30.4-2), and boots as the flag stood when it was reset (Table 30.4-1 clears the
//!   flag as its last step, leaving the chip in download mode). A reset reboots the twin
//!   (`Twin::reboot`: a new boot id, everything in RAM lost, the flash kept); in download mode
//!   the ROM's loader answers none of the device's frames.
//! - It records every request the chip receives ([`LineRequest`]).
//!
//! It is written from the manual, not from the `kerfmeter::lines` module it tests. Simulated time
//! runs in lock-step with the host, as the twin's serve loop runs it: at most
//! [`kerfmeter_twin::sim::MAX_LEAD_MS`] past the host's last request.

use std::collections::VecDeque;
use std::io::{self, Read, Write};
use std::sync::{Arc, Mutex, MutexGuard};
use std::time::Duration;

use kerfmeter_twin::{Twin, TwinOptions};
use serialport::{ClearBuffer, DataBits, FlowControl, Parity, SerialPort, StopBits};

/// Ticks the twin runs at once while the host waits, as the twin's serve loop does.
const TICKS_PER_WAIT: u64 = 50;
/// How long a read that finds nothing sleeps before it says so (a tty's read blocks).
const EMPTY_READ_SLEEP: Duration = Duration::from_millis(1);
/// `ENODEV`: what a vanished USB tty answers to I/O.
const ENODEV: i32 = 19;

/// The two lines as one request carries them.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Pair {
    /// Data terminal ready.
    pub dtr: bool,
    /// Request to send.
    pub rts: bool,
}

impl Pair {
    /// Both released.
    pub const RELEASED: Pair = Pair {
        dtr: false,
        rts: false,
    };
    /// Both asserted.
    pub const RAISED: Pair = Pair {
        dtr: true,
        rts: true,
    };
    /// Every pair.
    pub const ALL: [Pair; 4] = [
        Pair::RELEASED,
        Pair {
            dtr: true,
            rts: false,
        },
        Pair {
            dtr: false,
            rts: true,
        },
        Pair::RAISED,
    ];
}

/// What the chip did with a request (Table 30.3-2).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Action {
    /// (RTS 0, DTR 0).
    ClearDownloadFlag,
    /// (RTS 0, DTR 1).
    SetDownloadFlag,
    /// (RTS 1, DTR 0), the chip running: it is reset, to boot into download mode or not.
    Reset { into_download: bool },
    /// (RTS 1, DTR 0) again, the chip already in reset: it stays there.
    StillInReset,
    /// (RTS 1, DTR 1).
    Nothing,
}

/// Who sent a request.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Source {
    /// The OS, opening the port.
    Open,
    /// The OS, on the last close.
    Close,
    /// The program, writing a line.
    Write,
}

/// One `SET_CONTROL_LINE_STATE` request as the chip received it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct LineRequest {
    /// Who sent it.
    pub source: Source,
    /// The pair the chip had before.
    pub before: Pair,
    /// The pair it carries.
    pub pair: Pair,
    /// What the chip did.
    pub action: Action,
}

/// How the host's OS carries the lines to the chip.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Driver {
    /// The pair `open(2)` sends, if any.
    pub on_open: Option<Pair>,
    /// The pair the last `close(2)` sends, if any.
    pub on_close: Option<Pair>,
    /// A DTR write is sent only with the next RTS write, which always sends the pair.
    pub dtr_waits_for_rts: bool,
    /// The port refuses RTS writes (it has no such line).
    pub rts_refused: bool,
}

impl Driver {
    /// Linux's cdc-acm: `open(2)` raises both lines in one request (`tty_port_block_til_ready` →
    /// `acm_port_dtr_rts`), the last `close(2)` lowers both in one request under the default
    /// `HUPCL` (`tty_port_shutdown`), and a one-line write sends the new pair only when it
    /// changed (`acm_tty_tiocmset`).
    pub const LINUX_CDC_ACM: Driver = Driver {
        on_open: Some(Pair::RAISED),
        on_close: Some(Pair::RELEASED),
        dtr_waits_for_rts: false,
        rts_refused: false,
    };
    /// Windows' CDC-ACM driver as the manual describes it (§30.4): a DTR change reaches the chip
    /// only with the next RTS write. What it sends on open and close is not documented there:
    /// nothing, here.
    pub const WINDOWS_USBSER: Driver = Driver {
        on_open: None,
        on_close: None,
        dtr_waits_for_rts: true,
        rts_refused: false,
    };
}

/// What the chip is running.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Mode {
    /// The firmware (the twin).
    Firmware,
    /// Held in reset, to boot as the flag stood.
    InReset { into_download: bool },
    /// The ROM's download mode: no frame is answered.
    RomDownload,
}

/// The chip: its line state, its flag, its twin, and what the host's tty has queued from it.
struct Chip {
    twin: Twin,
    seen: Pair,
    download_flag: bool,
    mode: Mode,
    requests: Vec<LineRequest>,
    resets: u32,
    /// Bumped when the port vanishes: handles opened before it are dead.
    bus_session: u32,
    present: bool,
    /// Bytes the chip sent that the host has not read.
    to_host: VecDeque<u8>,
}

impl Chip {
    fn receive_pair(&mut self, source: Source, pair: Pair) {
        let before = self.seen;
        self.seen = pair;
        if let Mode::InReset { into_download } = self.mode
            && pair != RESET_PAIR
        {
            self.mode = if into_download {
                Mode::RomDownload
            } else {
                Mode::Firmware
            };
        }
        let action = self.act_on(pair);
        self.requests.push(LineRequest {
            source,
            before,
            pair,
            action,
        });
    }

    /// Table 30.3-2.
    fn act_on(&mut self, pair: Pair) -> Action {
        match (pair.rts, pair.dtr) {
            (false, false) => {
                self.download_flag = false;
                Action::ClearDownloadFlag
            }
            (false, true) => {
                self.download_flag = true;
                Action::SetDownloadFlag
            }
            (true, false) if matches!(self.mode, Mode::InReset { .. }) => Action::StillInReset,
            (true, false) => self.reset(),
            (true, true) => Action::Nothing,
        }
    }

    fn reset(&mut self) -> Action {
        let into_download = self.download_flag;
        self.resets += 1;
        self.twin.reboot();
        self.mode = Mode::InReset { into_download };
        Action::Reset { into_download }
    }

    /// Bytes from the host: the firmware answers them; held in reset or in the ROM's loader, the
    /// chip answers nothing.
    fn receive_bytes(&mut self, bytes: &[u8]) {
        if self.mode != Mode::Firmware {
            return;
        }
        self.run_while_host_waits(u64::MAX);
        let Self { twin, to_host, .. } = self;
        twin.receive(bytes, |frame| to_host.extend(frame));
    }

    /// The twin runs on while the host waits, at most `max_ticks` and never past its lead.
    fn run_while_host_waits(&mut self, max_ticks: u64) {
        if self.mode == Mode::Firmware {
            let ticks = self.twin.lead_ticks().min(max_ticks);
            self.twin.advance_ticks(ticks);
        }
    }
}

/// (RTS 1, DTR 0): the chip's reset.
const RESET_PAIR: Pair = Pair {
    dtr: false,
    rts: true,
};

/// The device on the host's USB bus: open its port with [`C3::open`].
#[derive(Clone)]
pub struct C3 {
    chip: Arc<Mutex<Chip>>,
    driver: Driver,
}

impl C3 {
    /// A powered chip running a twin booted with `options`, its lines released, its flag clear,
    /// reached through `driver`.
    pub fn new(options: TwinOptions, driver: Driver) -> Self {
        let chip = Chip {
            twin: Twin::new(options),
            seen: Pair::RELEASED,
            download_flag: false,
            mode: Mode::Firmware,
            requests: Vec::new(),
            resets: 0,
            bus_session: 0,
            present: true,
            to_host: VecDeque::new(),
        };
        Self {
            chip: Arc::new(Mutex::new(chip)),
            driver,
        }
    }

    /// The OS opens the port (and sends what its driver sends on open).
    ///
    /// # Panics
    ///
    /// While the port has vanished: there is no tty to open.
    pub fn open(&self) -> Box<dyn SerialPort> {
        let mut chip = self.chip();
        assert!(chip.present, "the port has vanished: nothing to open");
        chip.to_host.clear();
        if let Some(pair) = self.driver.on_open {
            chip.receive_pair(Source::Open, pair);
        }
        Box::new(C3Port {
            chip: Arc::clone(&self.chip),
            driver: self.driver,
            session: chip.bus_session,
            // A driver that sends nothing on open starts from the pair the chip holds.
            lines: self.driver.on_open.unwrap_or(chip.seen),
            timeout: Duration::from_millis(10),
        })
    }

    /// The port vanishes from the host (a USB glitch, the hub re-enumerating) while the chip keeps
    /// running: the open handles answer `ENODEV`, and their close reaches nothing.
    pub fn vanish(&self) {
        let mut chip = self.chip();
        chip.present = false;
        chip.bus_session += 1;
        chip.to_host.clear();
    }

    /// The port is back (nothing is sent to the chip until it is opened).
    pub fn reappear(&self) {
        self.chip().present = true;
    }

    /// Set the flag as another program (a flashing tool) could have left it.
    pub fn set_download_flag(&self, set: bool) {
        self.chip().download_flag = set;
    }

    /// Every request the chip received, in order.
    pub fn requests(&self) -> Vec<LineRequest> {
        self.chip().requests.clone()
    }

    /// How many times the lines reset the chip.
    pub fn resets(&self) -> u32 {
        self.chip().resets
    }

    /// The pair the chip holds now.
    pub fn pair(&self) -> Pair {
        self.chip().seen
    }

    /// Whether the chip's download-mode flag is set now.
    pub fn download_flag(&self) -> bool {
        self.chip().download_flag
    }

    /// Whether the chip runs in the ROM's download mode.
    pub fn in_download_mode(&self) -> bool {
        self.chip().mode == Mode::RomDownload
    }

    fn chip(&self) -> MutexGuard<'_, Chip> {
        self.chip
            .lock()
            .expect("a test thread panicked holding the chip")
    }
}

/// Which line a write sets.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Line {
    Dtr,
    Rts,
}

/// One open handle of the port.
struct C3Port {
    chip: Arc<Mutex<Chip>>,
    driver: Driver,
    session: u32,
    /// The pair as the host's driver holds it (what a DTR write waiting for RTS waits in).
    lines: Pair,
    timeout: Duration,
}

impl C3Port {
    /// The chip, or `ENODEV` when this handle's port has vanished.
    fn live_chip(&self) -> io::Result<MutexGuard<'_, Chip>> {
        let chip = self
            .chip
            .lock()
            .expect("a test thread panicked holding the chip");
        if chip.present && chip.bus_session == self.session {
            Ok(chip)
        } else {
            Err(io::Error::from_raw_os_error(ENODEV))
        }
    }

    fn write_line(&mut self, line: Line, level: bool) -> serialport::Result<()> {
        if line == Line::Rts && self.driver.rts_refused {
            return Err(io::Error::from(io::ErrorKind::Unsupported).into());
        }
        let mut lines = self.lines;
        match line {
            Line::Dtr => lines.dtr = level,
            Line::Rts => lines.rts = level,
        }
        let sent = match (line, self.driver.dtr_waits_for_rts) {
            (Line::Rts, true) => true,
            (Line::Dtr, true) => false,
            (_, false) => lines != self.lines,
        };
        {
            let mut chip = self.live_chip()?;
            if sent {
                chip.receive_pair(Source::Write, lines);
            }
        }
        self.lines = lines;
        Ok(())
    }
}

impl Drop for C3Port {
    /// The last close: the OS sends what its driver sends, if the port is still there.
    fn drop(&mut self) {
        let Some(pair) = self.driver.on_close else {
            return;
        };
        if let Ok(mut chip) = self.live_chip() {
            chip.receive_pair(Source::Close, pair);
        }
    }
}

impl Read for C3Port {
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        let mut chip = self.live_chip()?;
        if chip.to_host.is_empty() {
            chip.run_while_host_waits(TICKS_PER_WAIT);
            drop(chip);
            std::thread::sleep(EMPTY_READ_SLEEP);
            return Err(io::ErrorKind::TimedOut.into());
        }
        let n = buf.len().min(chip.to_host.len());
        for (slot, byte) in buf.iter_mut().zip(chip.to_host.drain(..n)) {
            *slot = byte;
        }
        Ok(n)
    }
}

impl Write for C3Port {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        self.live_chip()?.receive_bytes(buf);
        Ok(buf.len())
    }

    fn flush(&mut self) -> io::Result<()> {
        self.live_chip().map(|_| ())
    }
}

impl SerialPort for C3Port {
    fn name(&self) -> Option<String> {
        Some("/dev/ttyACM-double".into())
    }

    fn baud_rate(&self) -> serialport::Result<u32> {
        // The controller's answer to GET_LINE_CODING (Table 30.3-1).
        Ok(9600)
    }

    fn data_bits(&self) -> serialport::Result<DataBits> {
        Ok(DataBits::Eight)
    }

    fn flow_control(&self) -> serialport::Result<FlowControl> {
        Ok(FlowControl::None)
    }

    fn parity(&self) -> serialport::Result<Parity> {
        Ok(Parity::None)
    }

    fn stop_bits(&self) -> serialport::Result<StopBits> {
        Ok(StopBits::One)
    }

    fn timeout(&self) -> Duration {
        self.timeout
    }

    // SET_LINE_CODING is "accepted but ignored" (Table 30.3-1).
    fn set_baud_rate(&mut self, _: u32) -> serialport::Result<()> {
        Ok(())
    }

    fn set_data_bits(&mut self, _: DataBits) -> serialport::Result<()> {
        Ok(())
    }

    fn set_flow_control(&mut self, _: FlowControl) -> serialport::Result<()> {
        Ok(())
    }

    fn set_parity(&mut self, _: Parity) -> serialport::Result<()> {
        Ok(())
    }

    fn set_stop_bits(&mut self, _: StopBits) -> serialport::Result<()> {
        Ok(())
    }

    fn set_timeout(&mut self, timeout: Duration) -> serialport::Result<()> {
        self.timeout = timeout;
        Ok(())
    }

    fn write_request_to_send(&mut self, level: bool) -> serialport::Result<()> {
        self.write_line(Line::Rts, level)
    }

    fn write_data_terminal_ready(&mut self, level: bool) -> serialport::Result<()> {
        self.write_line(Line::Dtr, level)
    }

    // The controller's notification endpoint "will never send any events" (§30.3.1): no input
    // line ever changes.
    fn read_clear_to_send(&mut self) -> serialport::Result<bool> {
        Ok(false)
    }

    fn read_data_set_ready(&mut self) -> serialport::Result<bool> {
        Ok(false)
    }

    fn read_ring_indicator(&mut self) -> serialport::Result<bool> {
        Ok(false)
    }

    fn read_carrier_detect(&mut self) -> serialport::Result<bool> {
        Ok(false)
    }

    fn bytes_to_read(&self) -> serialport::Result<u32> {
        Ok(self.live_chip()?.to_host.len() as u32)
    }

    fn bytes_to_write(&self) -> serialport::Result<u32> {
        Ok(0)
    }

    fn clear(&self, buffer: ClearBuffer) -> serialport::Result<()> {
        if matches!(buffer, ClearBuffer::Input | ClearBuffer::All) {
            self.live_chip()?.to_host.clear();
        }
        Ok(())
    }

    fn try_clone(&self) -> serialport::Result<Box<dyn SerialPort>> {
        Err(serialport::Error::new(
            serialport::ErrorKind::Unknown,
            "the C3 double has one handle per open",
        ))
    }

    // SEND_BREAK is "accepted but ignored" (Table 30.3-1).
    fn set_break(&self) -> serialport::Result<()> {
        Ok(())
    }

    fn clear_break(&self) -> serialport::Result<()> {
        Ok(())
    }
}
