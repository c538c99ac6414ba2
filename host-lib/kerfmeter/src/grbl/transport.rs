//! Where the cutter is: its address (`grbl:/dev/ttyUSB0[?baud=N]`, `grbl+tcp://HOST:PORT`,
//! `sim`) and the byte stream to it, a serial port or a TCP connection, each read in short
//! slices so that the driver's deadlines hold.

use std::io::{Read, Write};
use std::net::{SocketAddr, TcpStream, ToSocketAddrs};
use std::str::FromStr;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc;
use std::time::{Duration, Instant};

use super::error::CutterError;

/// GRBL's usual baud rate.
pub const DEFAULT_BAUD: u32 = 115_200;
/// How long one read may block.
pub(super) const READ_SLICE: Duration = Duration::from_millis(10);
/// How long a TCP write may block (a controller that stopped reading).
const TCP_WRITE_TIMEOUT: Duration = Duration::from_secs(1);
/// How long a TCP connection may take to open.
const TCP_CONNECT_TIMEOUT: Duration = Duration::from_secs(5);

/// Where a cutter is.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum CutterAddress {
    /// A serial port (`grbl:/dev/ttyUSB0`, `grbl:COM3?baud=250000`).
    Serial {
        /// The port's path.
        path: String,
        /// Its baud rate.
        baud: u32,
    },
    /// A networked controller (`grbl+tcp://192.168.1.20:23`).
    Tcp {
        /// `HOST:PORT`.
        host_port: String,
    },
    /// The simulated cutter, in this process (`sim`).
    Sim,
    /// A Ruida controller over the network (`ruida:HOST?z-mm=MIN,MAX`, read by
    /// [`crate::ruida::RuidaAddress`]), driven by [`crate::ruida::RuidaCutter`].
    Ruida {
        /// The address as given (checked).
        address: String,
    },
    /// The simulated Ruida controller, on loopback UDP (`ruida-sim`).
    RuidaSim,
}

impl CutterAddress {
    /// Whether it names a simulated cutter.
    pub fn is_sim(&self) -> bool {
        matches!(self, Self::Sim | Self::RuidaSim)
    }

    /// Whether it names a Ruida controller (real or simulated).
    pub fn is_ruida(&self) -> bool {
        matches!(self, Self::Ruida { .. } | Self::RuidaSim)
    }
}

impl FromStr for CutterAddress {
    type Err = CutterError;

    fn from_str(text: &str) -> Result<Self, Self::Err> {
        let bad = || CutterError::BadAddress(text.to_owned());
        if text == "sim" {
            return Ok(Self::Sim);
        }
        if text == "ruida-sim" {
            return Ok(Self::RuidaSim);
        }
        if text.starts_with("ruida:") {
            text.parse::<crate::ruida::RuidaAddress>()?;
            return Ok(Self::Ruida {
                address: text.to_owned(),
            });
        }
        if let Some(rest) = text.strip_prefix("grbl+tcp://") {
            let host_port = rest.trim_end_matches('/');
            let (host, port) = host_port.rsplit_once(':').ok_or_else(bad)?;
            if host.is_empty() || port.parse::<u16>().is_err() {
                return Err(bad());
            }
            return Ok(Self::Tcp {
                host_port: host_port.to_owned(),
            });
        }
        let rest = text.strip_prefix("grbl:").ok_or_else(bad)?;
        let (path, query) = match rest.split_once('?') {
            Some((path, query)) => (path, Some(query)),
            None => (rest, None),
        };
        let baud = match query {
            None => DEFAULT_BAUD,
            Some(q) => q
                .strip_prefix("baud=")
                .and_then(|b| b.parse().ok())
                .filter(|b| *b > 0)
                .ok_or_else(bad)?,
        };
        if path.is_empty() {
            return Err(bad());
        }
        Ok(Self::Serial {
            path: path.to_owned(),
            baud,
        })
    }
}

impl std::fmt::Display for CutterAddress {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Serial { path, baud } if *baud == DEFAULT_BAUD => write!(f, "grbl:{path}"),
            Self::Serial { path, baud } => write!(f, "grbl:{path}?baud={baud}"),
            Self::Tcp { host_port } => write!(f, "grbl+tcp://{host_port}"),
            Self::Sim => f.write_str("sim"),
            Self::Ruida { address } => f.write_str(address),
            Self::RuidaSim => f.write_str("ruida-sim"),
        }
    }
}

/// A byte stream to a controller whose reads time out after a few milliseconds.
pub trait Link: Read + Write + Send {}

impl<T: Read + Write + Send> Link for T {}

/// Open a serial port at `baud`.
pub(super) fn open_serial(path: &str, baud: u32) -> Result<Box<dyn Link>, CutterError> {
    let port = serialport::new(path, baud)
        .timeout(READ_SLICE)
        .open()
        .map_err(|e| CutterError::Open {
            address: format!("grbl:{path}"),
            reason: format!(
                "{e}. Check the path and that no other program (a sender, a serial monitor) holds the port"
            ),
        })?;
    Ok(Box::new(port))
}

/// Connect to `host:port`; the name is resolved within [`TCP_CONNECT_TIMEOUT`] and given up
/// as soon as `cancel` is set.
pub(super) fn open_tcp(host_port: &str, cancel: &AtomicBool) -> Result<Box<dyn Link>, CutterError> {
    let open_error = |reason: String| CutterError::Open {
        address: format!("grbl+tcp://{host_port}"),
        reason,
    };
    let addr = resolve(host_port, cancel)?
        .map_err(|e| open_error(format!("cannot resolve it: {e}")))?
        .ok_or_else(|| open_error("it resolves to no address".into()))?;
    let stream = TcpStream::connect_timeout(&addr, TCP_CONNECT_TIMEOUT)
        .map_err(|e| open_error(format!("{e}. Is the controller on the network?")))?;
    stream
        .set_read_timeout(Some(READ_SLICE))
        .and_then(|()| stream.set_write_timeout(Some(TCP_WRITE_TIMEOUT)))
        .and_then(|()| stream.set_nodelay(true))
        .map_err(|e| open_error(e.to_string()))?;
    Ok(Box::new(stream))
}

/// Resolve `host_port` on a thread of its own (the system's resolver has no timeout): its first
/// address, or the resolver's error; [`CutterError::ConnectCancelled`] when `cancel` is set
/// first, [`CutterError::Open`] when it takes longer than [`TCP_CONNECT_TIMEOUT`].
fn resolve(
    host_port: &str,
    cancel: &AtomicBool,
) -> Result<std::io::Result<Option<SocketAddr>>, CutterError> {
    let (tx, rx) = mpsc::channel();
    let name = host_port.to_owned();
    std::thread::spawn(move || {
        let _ = tx.send(name.to_socket_addrs().map(|mut a| a.next()));
    });
    let deadline = Instant::now() + TCP_CONNECT_TIMEOUT;
    let address = format!("grbl+tcp://{host_port}");
    loop {
        if cancel.load(Ordering::Relaxed) {
            return Err(CutterError::ConnectCancelled { address });
        }
        match rx.recv_timeout(READ_SLICE) {
            Ok(resolved) => return Ok(resolved),
            Err(mpsc::RecvTimeoutError::Timeout) if Instant::now() < deadline => {}
            Err(_) => {
                return Err(CutterError::Open {
                    address,
                    reason: format!(
                        "its name did not resolve within {} s; check the name or use an IP address",
                        TCP_CONNECT_TIMEOUT.as_secs()
                    ),
                });
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn addresses_are_read_and_bad_ones_refused() {
        let serial: CutterAddress = "grbl:/dev/ttyUSB0".parse().unwrap();
        assert_eq!(
            serial,
            CutterAddress::Serial {
                path: "/dev/ttyUSB0".into(),
                baud: DEFAULT_BAUD
            }
        );
        let fast: CutterAddress = "grbl:COM3?baud=250000".parse().unwrap();
        assert_eq!(fast.to_string(), "grbl:COM3?baud=250000");
        let tcp: CutterAddress = "grbl+tcp://10.0.0.5:23".parse().unwrap();
        assert_eq!(tcp.to_string(), "grbl+tcp://10.0.0.5:23");
        for bad in [
            "grbl:",
            "grbl:/dev/x?baud=0",
            "grbl+tcp://host",
            "tcp://h:1",
            "/dev/ttyUSB0",
        ] {
            assert!(bad.parse::<CutterAddress>().is_err(), "{bad}");
        }
    }
}
