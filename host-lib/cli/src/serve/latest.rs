//! What the device said last, so that a page or a design tool watching the device is never
//! blind: while a long call (a run, reset, self-test or job) holds the device, the read-only
//! calls (`info`, `status`, `get_kerf_value` and their HTTP GETs) are answered from here instead
//! of "busy", each answer with `poll_age_ms`, the age of the poll it comes from. The long call
//! keeps `status` fresh (it polls the device about every 20 ms, and every poll lands here); the
//! others are read when the long call starts, and a run or reset clears the result as the device
//! does.

use std::sync::{Mutex, PoisonError};
use std::time::Instant;

use kerfmeter::protocol::Status;
use serde_json::{Value, json};

use crate::commands::status::StatusReport;

/// The read-only calls, answered at any time.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Query {
    /// `info`.
    Info,
    /// `status`.
    Status,
    /// `get_kerf_value`.
    Kerf,
}

/// An answer as the device gave it: the JSON of a reply, or a status a poll read (kept as it
/// is: polls come every 20 ms, and its report is built only when a read asks for it).
#[derive(Debug, Clone)]
enum Answer {
    Json(Value),
    Polled(Status),
}

impl Answer {
    fn to_json(&self) -> Value {
        match self {
            Answer::Json(value) => value.clone(),
            Answer::Polled(status) => {
                serde_json::to_value(StatusReport::from(*status)).expect("reports serialize")
            }
        }
    }
}

/// An answer and when the device gave it.
#[derive(Debug, Clone)]
struct Stamped {
    answer: Answer,
    at: Instant,
}

/// The device's last answers.
#[derive(Debug, Default)]
pub struct Latest {
    answers: Mutex<[Option<Stamped>; 3]>,
}

impl Latest {
    /// Keep `value`, the device's answer to `query` now.
    pub fn remember(&self, query: Query, value: &Value) {
        self.keep(query, Answer::Json(value.clone()));
    }

    /// A status a long call's poll read.
    pub fn polled(&self, status: &Status) {
        self.keep(Query::Status, Answer::Polled(*status));
    }

    fn keep(&self, query: Query, answer: Answer) {
        let mut answers = self.answers.lock().unwrap_or_else(PoisonError::into_inner);
        answers[query as usize] = Some(Stamped {
            answer,
            at: Instant::now(),
        });
    }

    /// A run or a reset started: the device holds no result until it ends.
    pub fn result_cleared(&self) {
        self.remember(Query::Kerf, &Value::Null);
    }

    /// The last answer to `query`, with `poll_age_ms` (a `get_kerf_value` with no result stays
    /// `null`); `None` if the device was never asked.
    pub fn answer(&self, query: Query) -> Option<Value> {
        let answers = self.answers.lock().unwrap_or_else(PoisonError::into_inner);
        let stamped = answers[query as usize].as_ref()?;
        let mut value = stamped.answer.to_json();
        if let Some(fields) = value.as_object_mut() {
            let age_ms = stamped.at.elapsed().as_millis() as u64;
            fields.insert("poll_age_ms".into(), json!(age_ms));
        }
        Some(value)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_answer_carries_its_age_and_a_cleared_result_is_null() {
        let latest = Latest::default();
        assert_eq!(latest.answer(Query::Info), None);
        latest.remember(Query::Info, &json!({ "boot_id": 7 }));
        let info = latest.answer(Query::Info).unwrap();
        assert_eq!(info["boot_id"], 7);
        assert!(info["poll_age_ms"].as_u64().unwrap() < 60_000);
        latest.remember(Query::Kerf, &json!({ "kerf_um": 150.0 }));
        latest.result_cleared();
        assert_eq!(latest.answer(Query::Kerf), Some(Value::Null));
    }
}
