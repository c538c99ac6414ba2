//! The network link to a controller, for the driver: packets sent over UDP one at a time, each
//! waited for, with the one rule that keeps a cut from running twice.
//!
//! - A NAK means the controller dropped the packet (checksum mismatch): it is sent again, up to
//!   [`UdpLink::tries`] times.
//! - No answer within the timeout: a *repeatable* packet (a move to an absolute position, a
//!   register read, a stop, a keep-alive) is sent again; a program packet is not, since a late
//!   ACK followed by a resend would run its commands twice. [`LinkError::NoAnswer`] then leaves
//!   the controller in an unknown state, and the caller must stop it ([`Command::StopProcess`])
//!   and confirm the stop.
//! - `CD` (ERR) is [`LinkError::Refused`]; any other byte, [`LinkError::Protocol`].
//!
//! Datagrams left over from an earlier exchange (a late ACK, a late register answer) are
//! discarded before each packet is sent.

use std::net::{SocketAddr, UdpSocket};
use std::time::Duration;

use crate::register::{Register, RegisterValue};
use crate::{Command, Packet, Program, Reply, RuidaError};

/// Why an exchange with the controller failed.
#[derive(Debug, thiserror::Error)]
pub enum LinkError {
    /// The socket failed.
    #[error("Ruida link: {0}")]
    Io(#[from] std::io::Error),
    /// No answer after `tries` sends (a program packet is sent once).
    #[error(
        "the Ruida controller did not answer ({tries} tries of {timeout:?}): its state is unknown"
    )]
    NoAnswer {
        /// How many times the packet was sent.
        tries: usize,
        /// How long each wait was.
        timeout: Duration,
    },
    /// NAKed every time.
    #[error("the Ruida controller NAKed the packet {tries} times (checksum mismatch)")]
    Naked {
        /// How many times the packet was sent.
        tries: usize,
    },
    /// The controller answered ERR.
    #[error("the Ruida controller refused the packet (ERR)")]
    Refused,
    /// An answer the protocol does not allow.
    #[error(transparent)]
    Protocol(#[from] RuidaError),
}

/// A UDP link to one controller (its port 50200, [`crate::UDP_PORT`]).
#[derive(Debug)]
pub struct UdpLink {
    socket: UdpSocket,
    magic: u8,
    timeout: Duration,
    tries: usize,
}

impl UdpLink {
    /// A link to `controller` from an ephemeral local port, each answer waited for `timeout`, a
    /// packet sent at most `tries` times (for a controller that answers the sender's port, as
    /// the twin does).
    pub fn connect(
        controller: SocketAddr,
        magic: u8,
        timeout: Duration,
        tries: usize,
    ) -> Result<Self, LinkError> {
        Self::connect_from(0, controller, magic, timeout, tries)
    }

    /// A link to `controller` from local port `local_port` ([`crate::REPLY_UDP_PORT`] for a real
    /// controller, which answers there; 0 for an ephemeral one).
    pub fn connect_from(
        local_port: u16,
        controller: SocketAddr,
        magic: u8,
        timeout: Duration,
        tries: usize,
    ) -> Result<Self, LinkError> {
        let local: SocketAddr = if controller.is_ipv4() {
            ([0, 0, 0, 0], local_port).into()
        } else {
            ([0u16; 8], local_port).into()
        };
        let socket = UdpSocket::bind(local)?;
        socket.connect(controller)?;
        Ok(Self {
            socket,
            magic,
            timeout,
            tries: tries.max(1),
        })
    }

    /// Wait `timeout` for each answer from now on (a stop may deserve longer than a read).
    pub fn set_timeout(&mut self, timeout: Duration) {
        self.timeout = timeout;
    }

    /// How many times a packet may be sent.
    pub fn tries(&self) -> usize {
        self.tries
    }

    /// Send a repeatable command (a move to an absolute position, a stop, a keep-alive).
    pub fn command(&self, command: Command) -> Result<(), LinkError> {
        let packet = Packet::new(&command.to_bytes(), self.magic)?;
        self.send(&packet, true)
    }

    /// Read a register.
    pub fn read(&self, register: Register) -> Result<RegisterValue, LinkError> {
        let packet = Packet::new(&register.read().to_bytes(), self.magic)?;
        for _ in 0..self.tries {
            self.send(&packet, true)?;
            if let Some(answer) = self.receive()? {
                return Ok(register.parse_reply(&answer, self.magic)?);
            }
        }
        Err(self.no_answer(self.tries))
    }

    /// Send a whole program, packet by packet; a packet that goes unanswered is not sent again
    /// (see the [module docs](self)).
    pub fn send_program(&self, program: &Program) -> Result<(), LinkError> {
        for packet in program.packets(self.magic)? {
            self.send(&packet, false)?;
        }
        Ok(())
    }

    /// Send `packet` until it is ACKed: again on a NAK, and on a timeout when `repeatable`.
    pub fn send(&self, packet: &Packet, repeatable: bool) -> Result<(), LinkError> {
        self.discard_stale()?;
        for attempt in 1..=self.tries {
            self.socket.send(packet.as_bytes())?;
            let Some(answer) = self.receive()? else {
                if repeatable {
                    continue;
                }
                return Err(self.no_answer(attempt));
            };
            let [byte] = answer[..] else {
                return Err(RuidaError::NotAReply { len: answer.len() }.into());
            };
            match Reply::from_swizzled(byte, self.magic)? {
                Reply::Ack => return Ok(()),
                Reply::Nak if attempt == self.tries => {
                    return Err(LinkError::Naked { tries: attempt });
                }
                Reply::Nak => {}
                Reply::Err => return Err(LinkError::Refused),
                Reply::KeepAlive => return Err(RuidaError::UnknownReply { byte: 0xCE }.into()),
            }
        }
        Err(self.no_answer(self.tries))
    }

    fn no_answer(&self, tries: usize) -> LinkError {
        LinkError::NoAnswer {
            tries,
            timeout: self.timeout,
        }
    }

    /// The next datagram within the timeout, or `None`.
    fn receive(&self) -> Result<Option<Vec<u8>>, LinkError> {
        self.socket.set_read_timeout(Some(self.timeout))?;
        let mut buf = [0u8; 2048];
        match self.socket.recv(&mut buf) {
            Ok(len) => Ok(Some(buf[..len].to_vec())),
            Err(e) if is_timeout(&e) => Ok(None),
            Err(e) => Err(e.into()),
        }
    }

    /// Drop datagrams already waiting (late answers to an earlier exchange).
    fn discard_stale(&self) -> Result<(), LinkError> {
        self.socket.set_nonblocking(true)?;
        let mut buf = [0u8; 2048];
        let result = loop {
            match self.socket.recv(&mut buf) {
                Ok(_) => continue,
                Err(e) if is_timeout(&e) => break Ok(()),
                // A port unreachable from an earlier send, reported now.
                Err(e) if e.kind() == std::io::ErrorKind::ConnectionRefused => continue,
                Err(e) => break Err(e.into()),
            }
        };
        self.socket.set_nonblocking(false)?;
        result
    }
}

fn is_timeout(e: &std::io::Error) -> bool {
    matches!(
        e.kind(),
        std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut
    )
}
