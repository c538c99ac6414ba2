//! The blocking client: one request, one response, with retries that never execute twice.

use std::io::{ErrorKind, Read, Write};
use std::time::{Duration, Instant};

use kerfmeter_protocol::{
    Deframer, DeviceInfo, Envelope, Feed, MAX_REQUEST_FRAME_LEN, MAX_RESPONSE_FRAME_LEN,
    PROTOCOL_VERSION, Request, Response, encode_frame,
};
use serialport::SerialPort;

use crate::error::{Error, Result};

/// How the client talks to the device.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Options {
    /// How long to wait for each response before re-sending the request.
    pub timeout: Duration,
    /// How many times a request is re-sent (with the same sequence number) after a timeout.
    pub retries: u32,
    /// How often long calls (run, reset, self-test) poll the device's status. Each poll feeds the
    /// device's communication watchdog, so keep it well under the run's `host_timeout_ms`.
    pub poll_interval: Duration,
}

impl Default for Options {
    fn default() -> Self {
        Self {
            timeout: Duration::from_millis(300),
            retries: 3,
            poll_interval: Duration::from_millis(20),
        }
    }
}

/// Baud rate for real UARTs; the USB-Serial-JTAG port and pseudo-terminals ignore it. Never 0:
/// Linux's cdc-acm drops DTR alone at `B0`, which resets an ESP32-C3 ([`crate::lines`]).
const BAUD: u32 = 115_200;
/// How long one `read` may block, so that deadlines are honoured.
const READ_SLICE: Duration = Duration::from_millis(10);

/// A connected Kerfmeter.
pub struct Kerfmeter {
    port: Box<dyn SerialPort>,
    path: String,
    deframer: Box<Deframer<MAX_RESPONSE_FRAME_LEN>>,
    seq: u16,
    options: Options,
    info: DeviceInfo,
}

impl std::fmt::Debug for Kerfmeter {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Kerfmeter")
            .field("path", &self.path)
            .field("boot_id", &self.info.boot_id)
            .finish_non_exhaustive()
    }
}

impl Kerfmeter {
    /// Open the device on the serial port at `path` and check that it speaks our protocol.
    pub fn open(path: &str) -> Result<Self> {
        Self::open_with(path, Options::default())
    }

    /// Find the device among the serial ports: the one USB port with Espressif's USB-Serial-JTAG
    /// ids (VID 0x303A, PID 0x1001), or else the only USB serial port there is. Anything else is
    /// an error that lists what was found.
    ///
    /// The choice is made from the OS's list of ports (their USB ids), without opening any: only
    /// the port chosen is opened, as [`open_with`](Self::open_with) opens it.
    pub fn discover(options: Options) -> Result<Self> {
        let ports = serialport::available_ports()
            .map_err(|e| Error::Discover(format!("cannot list serial ports: {e}")))?;
        let path = choose_port(&ports)?;
        Self::open_with(&path, options)
    }

    /// [`Kerfmeter::open`] with explicit [`Options`]: the OS opens the port (nothing else: no
    /// modem line is written on the way, see [`crate::lines`]), then [`Kerfmeter::from_port`].
    pub fn open_with(path: &str, options: Options) -> Result<Self> {
        let port = serialport::new(path, BAUD)
            .timeout(READ_SLICE)
            .open()
            .map_err(|source| Error::Open {
                path: path.to_owned(),
                source,
            })?;
        Self::from_port(port, options)
    }

    /// Use an already open port (a pseudo-terminal, a port opened with custom settings). Every
    /// way of opening the device ([`open`](Self::open), [`discover`](Self::discover), the `--sim`
    /// twin, the server's re-open, Python's) comes through here.
    ///
    /// First releases the port's modem lines without resetting an ESP32-C3 or arming its download
    /// mode ([`crate::lines::release`]; a port without modem lines, such as a pseudo-terminal,
    /// refuses, and is used as it is). Then performs the `GetInfo` handshake: fails with
    /// [`Error::ProtocolMismatch`] when the device speaks another major protocol version.
    pub fn from_port(mut port: Box<dyn SerialPort>, options: Options) -> Result<Self> {
        let _ = crate::lines::release(&mut *port);
        let path = port.name().unwrap_or_else(|| "<serial port>".into());
        port.set_timeout(READ_SLICE).map_err(|e| Error::Io {
            path: path.clone(),
            source: e.into(),
        })?;
        // Drop whatever the device printed before we came (the ROM boot banner).
        let _ = port.clear(serialport::ClearBuffer::Input);
        let mut meter = Self {
            port,
            path,
            deframer: Box::new(Deframer::new()),
            seq: initial_seq(),
            options,
            info: placeholder_info(),
        };
        meter.info = meter.fetch_info()?;
        Ok(meter)
    }

    /// The options in use.
    pub fn options(&self) -> &Options {
        &self.options
    }

    /// The path of the port in use.
    pub fn path(&self) -> &str {
        &self.path
    }

    /// What the device said about itself when it was opened.
    pub fn cached_info(&self) -> &DeviceInfo {
        &self.info
    }

    /// Ask the device what it is (`GetInfo`). Fails with [`Error::DeviceReset`] when the device
    /// restarted since it was opened.
    pub fn info(&mut self) -> Result<DeviceInfo> {
        let info = self.fetch_info()?;
        if info.boot_id != self.info.boot_id {
            let old = self.info.boot_id;
            self.info = info.clone();
            return Err(Error::DeviceReset {
                old,
                new: info.boot_id,
            });
        }
        Ok(info)
    }

    fn fetch_info(&mut self) -> Result<DeviceInfo> {
        match self.call(Request::GetInfo)? {
            Response::Info(info) => {
                if !PROTOCOL_VERSION.compatible_with(&info.protocol) {
                    return Err(Error::ProtocolMismatch {
                        device: info.protocol,
                        host: PROTOCOL_VERSION,
                    });
                }
                Ok(info)
            }
            other => Err(unexpected("GetInfo", &other)),
        }
    }

    /// Send one request and wait for its response. A device refusal is returned as
    /// [`Error::Device`]; every other response is returned as it came.
    ///
    /// After a timeout the request is re-sent with the *same* sequence number, so that a device
    /// whose response was lost answers again without acting twice.
    pub fn call(&mut self, request: Request) -> Result<Response> {
        let name = request_name(&request);
        self.seq = self.seq.wrapping_add(1);
        let seq = self.seq;
        let mut buf = [0u8; MAX_REQUEST_FRAME_LEN];
        let frame = encode_frame(&Envelope { seq, body: request }, &mut buf)
            .expect("request frames fit their compile-time bound");
        let attempts = self.options.retries + 1;
        for _ in 0..attempts {
            self.write(frame)?;
            if let Some(response) = self.read_response(seq)? {
                return match response {
                    Response::Error(code) => Err(Error::Device {
                        request: name,
                        code,
                    }),
                    other => Ok(other),
                };
            }
        }
        Err(Error::Timeout {
            path: self.path.clone(),
            request: name,
            attempts,
            timeout_ms: self.options.timeout.as_millis() as u64,
        })
    }

    fn write(&mut self, frame: &[u8]) -> Result<()> {
        self.port
            .write_all(frame)
            .and_then(|()| self.port.flush())
            .map_err(|e| self.io_error(e))
    }

    /// Read until the response with `seq` arrives (`Some`) or the timeout passes (`None`).
    /// Responses to other sequence numbers (late answers to earlier attempts) and bad frames are
    /// skipped.
    fn read_response(&mut self, seq: u16) -> Result<Option<Response>> {
        let deadline = Instant::now() + self.options.timeout;
        let mut buf = [0u8; 256];
        while Instant::now() < deadline {
            let n = match self.port.read(&mut buf) {
                Ok(0) => {
                    return Err(Error::PortVanished {
                        path: self.path.clone(),
                        source: ErrorKind::UnexpectedEof.into(),
                    });
                }
                Ok(n) => n,
                Err(e)
                    if matches!(
                        e.kind(),
                        ErrorKind::TimedOut | ErrorKind::WouldBlock | ErrorKind::Interrupted
                    ) =>
                {
                    continue;
                }
                Err(e) => return Err(self.io_error(e)),
            };
            let mut input = &buf[..n];
            let mut found = None;
            while let Feed::Frame { result, rest } = self.deframer.feed::<Envelope<Response>>(input)
            {
                input = rest;
                if let Ok(envelope) = result
                    && envelope.seq == seq
                {
                    found = Some(envelope.body);
                }
            }
            if found.is_some() {
                return Ok(found);
            }
        }
        Ok(None)
    }

    fn io_error(&self, source: std::io::Error) -> Error {
        // EIO (5), ENXIO (6), ENODEV (19): the device node is gone (unplugged, or the
        // pseudo-terminal's other end closed).
        let vanished = matches!(source.raw_os_error(), Some(5 | 6 | 19))
            || matches!(
                source.kind(),
                ErrorKind::BrokenPipe | ErrorKind::NotConnected | ErrorKind::UnexpectedEof
            );
        if vanished {
            Error::PortVanished {
                path: self.path.clone(),
                source,
            }
        } else {
            Error::Io {
                path: self.path.clone(),
                source,
            }
        }
    }
}

/// Pick the device's port from a list (see [`Kerfmeter::discover`]).
pub fn choose_port(ports: &[serialport::SerialPortInfo]) -> Result<String> {
    use serialport::SerialPortType;
    let usb: Vec<(&str, &serialport::UsbPortInfo)> = ports
        .iter()
        .filter_map(|p| match &p.port_type {
            SerialPortType::UsbPort(info) => Some((p.port_name.as_str(), info)),
            _ => None,
        })
        .collect();
    let espressif: Vec<&str> = usb
        .iter()
        .filter(|(_, i)| {
            i.vid == kerfmeter_protocol::USB_VID_ESPRESSIF
                && i.pid == kerfmeter_protocol::USB_PID_SERIAL_JTAG
        })
        .map(|(name, _)| *name)
        .collect();
    match (espressif.as_slice(), usb.as_slice()) {
        ([one], _) => Ok((*one).to_owned()),
        ([], [(one, _)]) => Ok((*one).to_owned()),
        _ => {
            let listing: Vec<String> = ports
                .iter()
                .map(|p| match &p.port_type {
                    SerialPortType::UsbPort(i) => format!(
                        "{} (USB {:04x}:{:04x}{})",
                        p.port_name,
                        i.vid,
                        i.pid,
                        i.product
                            .as_deref()
                            .map(|s| format!(" {s}"))
                            .unwrap_or_default()
                    ),
                    other => format!("{} ({other:?})", p.port_name),
                })
                .collect();
            let what = if espressif.len() > 1 {
                "more than one Kerfmeter (ESP32 USB-Serial-JTAG, 303a:1001) is connected"
            } else if usb.is_empty() {
                "no Kerfmeter found: no USB serial port is connected"
            } else {
                "no Kerfmeter (ESP32 USB-Serial-JTAG, 303a:1001) found among several USB serial ports"
            };
            let found = if listing.is_empty() {
                "none".to_owned()
            } else {
                listing.join(", ")
            };
            Err(Error::Discover(format!(
                "{what}. Ports found: {found}. Pass --port PATH, or --sim for the simulated device"
            )))
        }
    }
}

/// Start the sequence numbers somewhere unpredictable, so that a restarted host does not repeat
/// the device's remembered last (seq, request) pair by accident.
fn initial_seq() -> u16 {
    let nanos = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.subsec_nanos())
        .unwrap_or(0);
    (nanos ^ std::process::id()) as u16
}

fn placeholder_info() -> DeviceInfo {
    DeviceInfo {
        protocol: PROTOCOL_VERSION,
        firmware: kerfmeter_protocol::FirmwareVersion {
            major: 0,
            minor: 0,
            patch: 0,
        },
        boot_id: 0,
        hardware: kerfmeter_protocol::HardwareInfo {
            board: Default::default(),
            control_rate_hz: 0,
            encoder_bits: 0,
            pwm_bits: 0,
            max_samples: 0,
            max_request_frame_len: 0,
        },
    }
}

pub(crate) fn unexpected(request: &'static str, response: &Response) -> Error {
    Error::UnexpectedResponse {
        request,
        response: response_name(response),
    }
}

/// The request's name, for messages.
pub(crate) fn request_name(request: &Request) -> &'static str {
    match request {
        Request::GetInfo => "GetInfo",
        Request::Run(_) => "Run",
        Request::GetStatus => "GetStatus",
        Request::GetSamples { .. } => "GetSamples",
        Request::GetKerf => "GetKerf",
        Request::Reset => "Reset",
        Request::Abort => "Abort",
        Request::ClearFault => "ClearFault",
        Request::SelfTest => "SelfTest",
        Request::GetConfig => "GetConfig",
        Request::SetConfig(_) => "SetConfig",
        Request::GetSelfTest => "GetSelfTest",
        Request::ConfirmHubAtZero => "ConfirmHubAtZero",
        Request::GetDiagnostics => "GetDiagnostics",
    }
}

fn response_name(response: &Response) -> &'static str {
    match response {
        Response::Info(_) => "Info",
        Response::Ok => "Ok",
        Response::Error(_) => "Error",
        Response::Status(_) => "Status",
        Response::Samples(_) => "Samples",
        Response::Kerf(_) => "Kerf",
        Response::SelfTest(_) => "SelfTest",
        Response::Config(_) => "Config",
        Response::Diagnostics(_) => "Diagnostics",
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use serialport::{SerialPortInfo, SerialPortType, UsbPortInfo};

    fn usb(name: &str, vid: u16, pid: u16) -> SerialPortInfo {
        SerialPortInfo {
            port_name: name.into(),
            port_type: SerialPortType::UsbPort(UsbPortInfo {
                vid,
                pid,
                serial_number: None,
                manufacturer: None,
                product: None,
            }),
        }
    }

    #[test]
    fn discovery_prefers_the_espressif_port_then_the_only_usb_port() {
        let ports = [
            usb("/dev/ttyUSB0", 0x10c4, 0xea60),
            usb("/dev/ttyACM0", 0x303a, 0x1001),
        ];
        assert_eq!(choose_port(&ports).unwrap(), "/dev/ttyACM0");
        assert_eq!(choose_port(&ports[..1]).unwrap(), "/dev/ttyUSB0");
    }

    #[test]
    fn discovery_errors_list_what_was_found() {
        let e = choose_port(&[]).unwrap_err().to_string();
        assert!(
            e.contains("no USB serial port") && e.contains("--sim"),
            "{e}"
        );
        let two = [usb("/dev/ttyUSB0", 1, 2), usb("/dev/ttyUSB1", 3, 4)];
        let e = choose_port(&two).unwrap_err().to_string();
        assert!(
            e.contains("/dev/ttyUSB0 (USB 0001:0002)") && e.contains("/dev/ttyUSB1"),
            "{e}"
        );
        let twins = [
            usb("/dev/ttyACM0", 0x303a, 0x1001),
            usb("/dev/ttyACM1", 0x303a, 0x1001),
        ];
        assert!(
            choose_port(&twins)
                .unwrap_err()
                .to_string()
                .contains("more than one")
        );
    }
}
