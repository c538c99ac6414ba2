//! Why a Ruida controller failed the driver, each with what to do ([`RuidaFailure`]); carried
//! by the cutters' one error type as [`CutterError::Ruida`](crate::grbl::CutterError::Ruida),
//! so that the loop, its stop and the exit codes stay one.

use kerfmeter_ruida::link::LinkError;

use crate::error::Category;
use crate::grbl::CutterError;

/// A Ruida controller's failure.
#[derive(Debug, thiserror::Error)]
pub enum RuidaFailure {
    /// The address cannot be read.
    #[error(
        "cannot understand the Ruida address {text:?}: {reason}. Use ruida:HOST[:PORT]?z-mm=MIN,MAX[&bed-mm=W,H][&axis=z|u][&local-port=N], or ruida-sim"
    )]
    Address {
        /// As given.
        text: String,
        /// Why.
        reason: String,
    },
    /// No answer: the controller is off, elsewhere, or its state is unknown.
    #[error("the Ruida controller at {address} did not answer while {doing} ({reason})")]
    NoAnswer {
        /// The address.
        address: String,
        /// What the driver was doing.
        doing: &'static str,
        /// The link's words.
        reason: String,
    },
    /// An answer the protocol does not allow.
    #[error(
        "the Ruida controller at {address} answered in a way the protocol does not allow while {doing}: {reason}"
    )]
    Protocol {
        /// The address.
        address: String,
        /// What the driver was doing.
        doing: &'static str,
        /// What was wrong.
        reason: String,
    },
    /// Busy (a job running, the head moving) when a program was to be sent: another job.
    #[error(
        "the Ruida controller at {address} is busy (a job runs or the head moves, status {status:#x}); let it finish or stop it at its panel, and try again. Nothing was sent"
    )]
    Busy {
        /// The address.
        address: String,
        /// Its status register.
        status: u64,
    },
    /// The controller refused a packet (ERR).
    #[error("the Ruida controller at {address} answered ERR while {doing}: it refused the job")]
    Refused {
        /// The address.
        address: String,
        /// What the driver was doing.
        doing: &'static str,
    },
    /// The bed size cannot be read, and the address gives none.
    #[error(
        "the Ruida controller at {address} reports no bed size (registers 00 26/00 36 read {read_mm:?} mm): give it in the address, ruida:HOST?bed-mm=W,H&z-mm=MIN,MAX (or, for a job, --bed-mm W,H). Nothing was sent"
    )]
    NoBed {
        /// The address.
        address: String,
        /// What the registers said, mm.
        read_mm: [f64; 2],
    },
    /// The address's bed and the controller's disagree.
    #[error(
        "the address says the bed is {given_mm:?} mm, the Ruida controller at {address} says {read_mm:?} mm: leave bed-mm out, or correct it (or the controller's settings). Nothing was sent"
    )]
    BedMismatch {
        /// The address.
        address: String,
        /// From the address, mm.
        given_mm: [f64; 2],
        /// From the controller, mm.
        read_mm: [f64; 2],
    },
    /// Still busy after a stop.
    #[error(
        "the Ruida controller at {address} still reports a job or motion {waited_ms} ms after the stop (D8 01)"
    )]
    StillBusy {
        /// The address.
        address: String,
        /// How long the driver waited, ms.
        waited_ms: u64,
    },
    /// Idle, and the head not where a step ends: the step was not run.
    #[error(
        "the Ruida controller at {address} stayed idle for {waited_ms} ms with {register} at {read_mm:.3} mm, not at the {expected_mm:.3} mm the {what} ends at: it did not run it (a controller that refuses a job without a word, or waits for it to be started at its panel)"
    )]
    NotRun {
        /// The address.
        address: String,
        /// What was sent.
        what: &'static str,
        /// The register read.
        register: String,
        /// Where the step ends, mm.
        expected_mm: f64,
        /// Where the register says, mm.
        read_mm: f64,
        /// How long the driver waited, ms.
        waited_ms: u64,
    },
    /// The simulated controller could not be started.
    #[error("cannot start the simulated Ruida controller: {0}")]
    Sim(String),
}

impl RuidaFailure {
    /// What kind of failure this is (the exit code follows).
    pub fn category(&self) -> Category {
        match self {
            Self::Address { .. } | Self::NoBed { .. } | Self::BedMismatch { .. } => Category::Usage,
            Self::NoAnswer { .. } | Self::Protocol { .. } | Self::Sim(_) => Category::Communication,
            Self::Busy { .. }
            | Self::Refused { .. }
            | Self::StillBusy { .. }
            | Self::NotRun { .. } => Category::Device,
        }
    }

    /// A link's failure at `address` while `doing`, as the cutters' error.
    pub fn from_link(address: &str, doing: &'static str, e: LinkError) -> CutterError {
        let address = address.to_owned();
        let failure = match e {
            LinkError::Io(source) => return CutterError::Io { address, source },
            LinkError::NoAnswer { .. } => Self::NoAnswer {
                address,
                doing,
                reason: e.to_string(),
            },
            LinkError::Refused => Self::Refused { address, doing },
            LinkError::Naked { .. } | LinkError::Protocol(_) => Self::Protocol {
                address,
                doing,
                reason: e.to_string(),
            },
        };
        failure.into()
    }
}

impl From<RuidaFailure> for CutterError {
    fn from(f: RuidaFailure) -> Self {
        CutterError::Ruida(Box::new(f))
    }
}
