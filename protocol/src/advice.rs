//! Advice as data: what a message tells its reader to do next, as a typed value that each front
//! end words in its own terms (`kerfmeter clear-fault` on the command line, `clear_fault()` in
//! Python, the `clear_fault` method for a server's client).
//!
//! The host crates (the device library and the plan crate) build the messages that carry advice
//! as an [`Advised`] text: plain words with [`Advice`] values among them. [`Advised::advice`]
//! gives the values to a program that acts on them. Shown as text, each value is worded by the
//! [`Wording`] the front end has set for the duration of a call with [`in_words_of`], or by
//! [`RUST`], the library's own API, where none is set. The table of words therefore lives in
//! each front end, beside the flags or methods it names; the libraries never name a command.
//! It lives here, in the one crate below both host libraries.

use core::cell::Cell;
use core::fmt;
use std::borrow::ToOwned;
use std::string::String;
use std::vec::Vec;

/// Something the reader can do next, named by what it does, not by how a front end spells it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub enum Advice {
    /// Leave a latched fault (once its cause is fixed).
    ClearFault,
    /// Turn the hub back to zero and clear the last result (and a latched fault).
    Reset,
    /// Say the hub stands at its zero mark (encoder on the motor shaft, after power-up).
    ConfirmZero,
    /// Read the device's state, idle conditions and supply.
    Status,
    /// Read the device's configuration.
    ConfigGet,
    /// Measure at a lower joint force.
    LowerForce,
    /// The name of the run's joint-force parameter.
    ForceParam,
    /// A plan already compensated: undo its compensation and apply the measured kerf instead.
    Recompensate,
    /// A plan already compensated: dilate it by the full kerf anyway.
    AlreadyCompensatedOk,
    /// Set LightBurn's Kerf Offsets again.
    LightBurnApply,
    /// A parameter of a request, by its name there (`test_piece_kerf_um`): the CLI's flag, a
    /// keyword argument, a JSON-RPC parameter.
    Param(&'static str),
}

/// How a front end words each [`Advice`].
pub trait Wording: Sync {
    /// `advice` as this front end's reader would do it ([`Advice::Param`] goes to
    /// [`Wording::param`]).
    fn advice(&self, advice: Advice) -> &'static str;

    /// The request's parameter `name` as this front end's reader gives it (by default, as it
    /// is: a keyword argument, a JSON-RPC parameter).
    fn param(&self, name: &'static str) -> String {
        name.to_owned()
    }
}

/// The words of the library's own Rust API: where no front end has set its wording.
pub struct RustApi;

/// The Rust API's wording (the default).
pub static RUST: RustApi = RustApi;

impl Wording for RustApi {
    fn advice(&self, advice: Advice) -> &'static str {
        match advice {
            Advice::ClearFault => "`Kerfmeter::clear_fault`",
            Advice::Reset => "`Kerfmeter::reset_kerfmeter`",
            Advice::ConfirmZero => "`Kerfmeter::confirm_hub_at_zero`",
            Advice::Status => "`Kerfmeter::status`",
            Advice::ConfigGet => "`Kerfmeter::config`",
            Advice::LowerForce => "a lower `RunParams::target_force_n`",
            Advice::ForceParam => "target_force_n",
            Advice::Recompensate => "`IfCompensated::Recompensate`",
            Advice::AlreadyCompensatedOk => "`IfCompensated::DilateAnyway`",
            Advice::LightBurnApply => "`lightburn::apply_kerf`",
            Advice::Param(name) => name,
        }
    }
}

std::thread_local! {
    static WORDING: Cell<&'static dyn Wording> = const { Cell::new(&RUST) };
}

/// Run `f` with advice shown in `wording` on this thread (the previous wording comes back after,
/// even if `f` panics): a front end wraps the work whose messages it shows.
pub fn in_words_of<R>(wording: &'static dyn Wording, f: impl FnOnce() -> R) -> R {
    struct Restore(&'static dyn Wording);
    impl Drop for Restore {
        fn drop(&mut self) {
            WORDING.with(|w| w.set(self.0));
        }
    }
    let _restore = Restore(WORDING.with(|w| w.replace(wording)));
    f()
}

/// Show advice in `wording` on this thread from now on: for a thread that a front end starts
/// (a server's runtime threads), where no call wraps the work.
pub fn word_this_thread(wording: &'static dyn Wording) {
    WORDING.with(|w| w.set(wording));
}

impl fmt::Display for Advice {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let wording = WORDING.with(Cell::get);
        match self {
            Advice::Param(name) => f.write_str(&wording.param(name)),
            advice => f.write_str(wording.advice(*advice)),
        }
    }
}

/// A piece of an [`Advised`] text.
#[derive(Debug, Clone, PartialEq)]
enum Piece {
    Text(String),
    Advice(Advice),
}

/// A message with advice among its words, worded when shown (see the module's docs).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Advised {
    pieces: Vec<Piece>,
}

impl Advised {
    /// A message that starts with `text`.
    pub fn text(text: impl Into<String>) -> Self {
        Self::default().then(text)
    }

    /// This message, then `text`.
    pub fn then(mut self, text: impl Into<String>) -> Self {
        self.pieces.push(Piece::Text(text.into()));
        self
    }

    /// This message, then `advice`.
    pub fn advise(mut self, advice: Advice) -> Self {
        self.pieces.push(Piece::Advice(advice));
        self
    }

    /// This message, then all of `other`.
    pub fn append(mut self, other: Advised) -> Self {
        self.pieces.extend(other.pieces);
        self
    }

    /// The advice given, in order.
    pub fn advice(&self) -> impl Iterator<Item = Advice> + '_ {
        self.pieces.iter().filter_map(|p| match p {
            Piece::Advice(a) => Some(*a),
            Piece::Text(_) => None,
        })
    }

    /// Whether the words (the advice left out) contain `needle`.
    pub fn says(&self, needle: &str) -> bool {
        self.pieces
            .iter()
            .any(|p| matches!(p, Piece::Text(t) if t.contains(needle)))
    }
}

impl From<String> for Advised {
    fn from(text: String) -> Self {
        Self::text(text)
    }
}

impl From<&str> for Advised {
    fn from(text: &str) -> Self {
        Self::text(text)
    }
}

impl fmt::Display for Advised {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        self.pieces.iter().try_for_each(|p| match p {
            Piece::Text(t) => f.write_str(t),
            Piece::Advice(a) => write!(f, "{a}"),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::string::ToString;

    struct Shouting;
    impl Wording for Shouting {
        fn advice(&self, advice: Advice) -> &'static str {
            match advice {
                Advice::ClearFault => "CLEAR",
                _ => "OTHER",
            }
        }
    }
    static SHOUTING: Shouting = Shouting;

    #[test]
    fn each_front_end_words_the_same_advice_its_own_way() {
        let m = Advised::text("fix it, then ")
            .advise(Advice::ClearFault)
            .then(" and ")
            .advise(Advice::Reset);
        assert_eq!(
            m.to_string(),
            "fix it, then `Kerfmeter::clear_fault` and `Kerfmeter::reset_kerfmeter`"
        );
        assert_eq!(
            in_words_of(&SHOUTING, || m.to_string()),
            "fix it, then CLEAR and OTHER"
        );
        // The wording is back to the default after the call, and the advice is data.
        assert!(m.to_string().contains("clear_fault"));
        let given: Vec<Advice> = m.advice().collect();
        assert_eq!(given, [Advice::ClearFault, Advice::Reset]);
    }

    #[test]
    fn the_wording_comes_back_after_a_panic() {
        let caught = std::panic::catch_unwind(|| in_words_of(&SHOUTING, || panic!("boom")));
        assert!(caught.is_err());
        assert_eq!(Advice::ClearFault.to_string(), "`Kerfmeter::clear_fault`");
    }
}
