//! How a parameter is drawn from its range: uniformly, or log-uniformly where the range spans
//! decades (see the module docs, "How a draw is made").

use super::LOG_UNIFORM_SPAN;
use crate::plant::ParamSpec;

/// How a parameter is drawn from its range.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Scale {
    /// Every value equally likely.
    Uniform,
    /// Every decade equally likely.
    LogUniform,
}

/// How `spec` is drawn: log-uniformly when its range spans more than [`LOG_UNIFORM_SPAN`]× from
/// a positive minimum, uniformly otherwise.
pub fn scale(spec: &ParamSpec) -> Scale {
    if spec.min > 0.0 && spec.max / spec.min > LOG_UNIFORM_SPAN {
        Scale::LogUniform
    } else {
        Scale::Uniform
    }
}

/// The value of `spec` at the fraction `u` (0..1) of its range, on its [`scale`].
pub fn value_at(spec: &ParamSpec, u: f64) -> f64 {
    let value = match scale(spec) {
        Scale::Uniform => spec.min + u * (spec.max - spec.min),
        Scale::LogUniform => (spec.min.ln() + u * (spec.max / spec.min).ln()).exp(),
    };
    value.clamp(spec.min, spec.max)
}

/// Where `value` lies in `spec`'s range on its [`scale`], 0..=1 (for "how unusual is this").
pub fn fraction_of(spec: &ParamSpec, value: f64) -> f64 {
    match scale(spec) {
        Scale::Uniform => (value - spec.min) / (spec.max - spec.min),
        Scale::LogUniform => (value / spec.min).ln() / (spec.max / spec.min).ln(),
    }
}
