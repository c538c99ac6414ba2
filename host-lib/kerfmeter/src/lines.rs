//! The serial port's two modem-control outputs, DTR and RTS, as the device's ESP32-C3 reads them,
//! and the one sequence by which the host leaves them where the chip neither resets nor arms its
//! ROM download mode: [`release`].
//!
//! # What the chip does with them
//!
//! The C3's USB-Serial-JTAG controller receives both lines at once, in each CDC-ACM
//! `SET_CONTROL_LINE_STATE` request, and acts on the pair it receives (*ESP32-C3 Technical
//! Reference Manual*, chapter "USB Serial/JTAG Controller", §30.3.1, Table 30.3-2 "CDC-ACM
//! Settings with RTS and DTR"):
//!
//! | RTS | DTR | the chip |
//! |-----|-----|----------|
//! | 0 | 0 | clears its download-mode flag |
//! | 0 | 1 | sets its download-mode flag |
//! | 1 | 0 | is reset |
//! | 1 | 1 | does nothing |
//!
//! "If the download mode flag is set when the ESP32-C3 is reset, the ESP32-C3 will reboot into
//! download mode" (the same section): the ROM's serial loader, which answers nothing of this
//! protocol. §30.4 (Tables 30.4-1 and 30.4-2) gives the sequences that reset the chip into
//! download mode and into its firmware; the latter is "set RTS: reset SoC; clear RTS: exit
//! reset", with DTR cleared. esptool (`esptool/reset.py`: `HardReset`, `USBJTAGSerialReset`)
//! and espflash (`espflash/src/connection/reset.rs`: `reset_after_flash`) reset the chip exactly
//! so: RTS asserted while DTR is released.
//!
//! # What the operating system does with them
//!
//! - Linux (`drivers/tty/tty_port.c`, `drivers/usb/class/cdc-acm.c`): `open(2)` raises both lines
//!   in one request (`tty_port_block_til_ready` → `acm_port_dtr_rts`), (1, 1), which the chip
//!   ignores; the last `close(2)` lowers both in one request when the termios flag `HUPCL` is set
//!   (`tty_port_shutdown`), (0, 0), which only clears the flag. serialport's
//!   `write_request_to_send` and `write_data_terminal_ready` are `TIOCMBIC`/`TIOCMBIS` on one line:
//!   the driver sends the new pair, and nothing when it did not change (`acm_tty_tiocmset`).
//! - Windows: "some drivers (e.g. the standard CDC-ACM driver on Windows) do not set DTR until RTS
//!   is set and the user needs to explicitly set RTS in order to 'propagate' the DTR value"
//!   (the manual, §30.4).
//!
//! # The rule
//!
//! RTS is never asserted while DTR is released, and the flag is never left set. serialport
//! changes one line per call, so from (1, 1) to (0, 0) the pair passes through one of the two
//! mixed ones: releasing DTR first passes through the reset, at every open (what this crate did
//! before); releasing RTS first passes through "set the flag", which the next request clears, with
//! no reset in between. So the host only ever releases lines, RTS first; it never asserts one
//! (from (0, 0) either order of raising both would reset the chip or leave the flag set at (1, 1)).
//! Closing needs no step: from (0, 0), whatever the OS lowers, in one request or one line at a
//! time, still sends (0, 0). So `HUPCL` is left as it is; clearing it would leave the same (0, 0)
//! behind, and change the port's settings for the next program that opens it.
//!
//! Two ways the OS itself could break the rule, which this crate avoids: serialport's
//! `SerialPortBuilder::dtr_on_open(false)` releases DTR alone right after Linux raised both (a
//! reset), and a baud rate of 0 (`B0`) makes cdc-acm drop DTR alone (`acm_tty_set_termios`).

use serialport::SerialPort;

/// Leave both lines released, (0, 0), from whatever pair the port was opened with, without ever
/// asserting RTS while DTR is released: RTS is released, then DTR, then RTS is written once more
/// so that a driver which sends a DTR change only with an RTS write sends it (§30.4).
///
/// Stops at the first write the port refuses, so that a port on which RTS cannot be released
/// never has DTR released alone; such a port (a pseudo-terminal has no modem lines) is left as the
/// OS opened it. Returns the refusal.
pub fn release(port: &mut dyn SerialPort) -> serialport::Result<()> {
    port.write_request_to_send(false)?;
    port.write_data_terminal_ready(false)?;
    port.write_request_to_send(false)
}
