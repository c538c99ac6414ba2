//! The front ends' words for the libraries' advice ([`Advice`]): the command line names each
//! thing to do next as the command or flag that does it (`main` shows every message in these
//! words); the server as the method or parameter (its threads show every message in those).

use kerfmeter_protocol::advice::{Advice, Wording};

/// The command line's wording.
pub struct CommandLine;

/// The command line's wording, for [`kerfmeter_protocol::advice::in_words_of`].
pub static CLI: CommandLine = CommandLine;

impl Wording for CommandLine {
    fn advice(&self, advice: Advice) -> &'static str {
        match advice {
            Advice::ClearFault => "`kerfmeter clear-fault`",
            Advice::Reset => "`kerfmeter reset`",
            Advice::ConfirmZero => "`kerfmeter confirm-zero`",
            Advice::Status => "`kerfmeter status`",
            Advice::ConfigGet => "`kerfmeter config get`",
            Advice::LowerForce => "`kerfmeter run --force-n`",
            Advice::ForceParam => "--force-n",
            Advice::Recompensate => "--recompensate",
            Advice::AlreadyCompensatedOk => "--already-compensated-ok",
            Advice::LightBurnApply => "`kerfmeter lightburn apply`",
            _ => "(see `kerfmeter --help`)",
        }
    }

    /// A parameter as its flag: `test_piece_kerf_um` is `--test-piece-kerf-um`.
    fn param(&self, name: &'static str) -> String {
        format!("--{}", name.replace('_', "-"))
    }
}

/// The server's wording (JSON-RPC methods and parameters).
pub struct ServerApi;

/// The server's wording, for its threads.
pub static SERVER: ServerApi = ServerApi;

impl Wording for ServerApi {
    fn advice(&self, advice: Advice) -> &'static str {
        match advice {
            Advice::ClearFault => "the `clear_fault` method",
            Advice::Reset => "the `reset_kerfmeter` method",
            Advice::ConfirmZero => "the `confirm_hub_at_zero` method",
            Advice::Status => "the `status` method",
            Advice::ConfigGet => "the `config` method",
            Advice::LowerForce => "`force_n`",
            Advice::ForceParam => "force_n",
            Advice::Recompensate => "`recompensate: true`",
            Advice::AlreadyCompensatedOk => "`already_compensated_ok: true`",
            Advice::LightBurnApply => "`kerfmeter lightburn apply`",
            _ => "(see docs/server.md)",
        }
    }
}
