//! The advice in messages, in the words of the interface that shows them. The library's messages
//! (and the plan crate's) name what to do as the command line does it (`kerfmeter clear-fault`,
//! `--recompensate`); a Python program or a server's client does the same thing by another name
//! (`clear_fault()`, the `clear_fault` method). [`in_words_of`] rewrites a message for them,
//! from the one table here.

/// Who reads a message.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Interface {
    /// The `kerfmeter` Python package.
    Python,
    /// `kerfmeter serve`'s JSON-RPC and HTTP clients.
    Server,
}

/// Each piece of advice as the command line says it, then as Python and the server do.
const ADVICE: [(&str, &str, &str); 8] = [
    (
        "`kerfmeter clear-fault`",
        "`clear_fault()`",
        "the `clear_fault` method",
    ),
    (
        "`kerfmeter reset`",
        "`reset_kerfmeter()`",
        "the `reset_kerfmeter` method",
    ),
    (
        "`kerfmeter confirm-zero`",
        "`confirm_hub_at_zero()`",
        "the `confirm_hub_at_zero` method",
    ),
    ("`kerfmeter status`", "`status()`", "the `status` method"),
    ("`kerfmeter run --force-n`", "`force_n`", "`force_n`"),
    ("(--force-n, force_n)", "(force_n)", "(force_n)"),
    (
        "--recompensate",
        "if_compensated=\"recompensate\"",
        "`recompensate: true`",
    ),
    (
        "--already-compensated-ok",
        "if_compensated=\"dilate_anyway\"",
        "`already_compensated_ok: true`",
    ),
];

/// `message` with its command-line advice in `interface`'s words.
pub fn in_words_of(interface: Interface, message: &str) -> String {
    ADVICE
        .iter()
        .fold(message.to_owned(), |m, (cli, python, server)| {
            let theirs = match interface {
                Interface::Python => python,
                Interface::Server => server,
            };
            m.replace(cli, theirs)
        })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_interface_is_told_its_own_way() {
        let m = "Fix the cause, then `kerfmeter clear-fault` and `kerfmeter reset`";
        assert_eq!(
            in_words_of(Interface::Python, m),
            "Fix the cause, then `clear_fault()` and `reset_kerfmeter()`"
        );
        assert_eq!(
            in_words_of(Interface::Server, m),
            "Fix the cause, then the `clear_fault` method and the `reset_kerfmeter` method"
        );
        let plan = "with --recompensate (...), or ... with --already-compensated-ok.";
        assert_eq!(
            in_words_of(Interface::Python, plan),
            "with if_compensated=\"recompensate\" (...), or ... with if_compensated=\"dilate_anyway\"."
        );
    }
}
