//! Requests read from JSON: a front end that receives named parameters (the server's JSON-RPC
//! params, an HTTP query) deserializes them straight into a request type of this crate. A
//! parameter of the wrong type is named by its path; an unknown one is refused, named too
//! (every request type denies unknown fields).

use serde::de::DeserializeOwned;
use serde_json::Value;

/// A parameter that does not fit the request.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct BadParam {
    /// The parameter's name (its path, `cut_colors[1]`), when the fault is its value; `None`
    /// when the fault is the parameters as a whole (an unknown or a missing name, which the
    /// message names).
    pub name: Option<String>,
    /// What is wrong.
    pub why: String,
}

impl BadParam {
    /// The parameter `name` is wrong: `why`.
    pub fn named(name: &str, why: impl Into<String>) -> Self {
        Self {
            name: Some(name.to_owned()),
            why: why.into(),
        }
    }
}

/// Strings given as one string or a list of them (`"red"`, `["red", "blue"]`).
#[derive(Debug, Clone, Default, PartialEq, Eq, serde::Serialize)]
#[serde(transparent)]
pub struct OneOrMany(pub Vec<String>);

impl<'de> serde::Deserialize<'de> for OneOrMany {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        #[derive(serde::Deserialize)]
        #[serde(untagged, expecting = "a string or a list of strings")]
        enum Given {
            One(String),
            Many(Vec<String>),
        }
        Ok(match Option::<Given>::deserialize(d)? {
            None => Self::default(),
            Some(Given::One(s)) => Self(vec![s]),
            Some(Given::Many(v)) => Self(v),
        })
    }
}

impl std::fmt::Display for BadParam {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match &self.name {
            Some(name) => write!(f, "parameter `{name}`: {}", self.why),
            None => write!(f, "{}", self.why),
        }
    }
}

/// `params` (a JSON object; `null` is none) as the request `T`.
pub fn from_params<T: DeserializeOwned>(params: Value) -> Result<T, BadParam> {
    let params = if params.is_null() {
        Value::Object(Default::default())
    } else {
        params
    };
    serde_path_to_error::deserialize(params).map_err(|e| {
        let path = e.path().to_string();
        let why = e.into_inner().to_string();
        BadParam {
            name: (path != ".").then_some(path),
            why,
        }
    })
}

/// Serde helpers for parameters that an HTTP query gives as text.
pub mod text_or_number {
    use serde::{Deserialize, Deserializer, de::Error};

    /// A whole number, given as a JSON number or as its decimal text (`?limit=10`).
    pub fn u32<'de, D: Deserializer<'de>>(d: D) -> Result<u32, D::Error> {
        u32_opt(d)?.ok_or_else(|| D::Error::custom("expected a whole number, got null"))
    }

    /// [`u32()`], or nothing (`null`).
    pub fn u32_opt<'de, D: Deserializer<'de>>(d: D) -> Result<Option<u32>, D::Error> {
        #[derive(Deserialize)]
        #[serde(untagged)]
        enum Given {
            Number(u32),
            Text(String),
        }
        match Option::<Given>::deserialize(d)? {
            None => Ok(None),
            Some(Given::Number(n)) => Ok(Some(n)),
            Some(Given::Text(t)) => t
                .trim()
                .parse()
                .map(Some)
                .map_err(|_| D::Error::custom(format!("expected a whole number, got {t:?}"))),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde::Deserialize;
    use serde_json::json;

    #[derive(Debug, Deserialize)]
    #[serde(deny_unknown_fields)]
    #[allow(dead_code)]
    struct Asked {
        #[serde(default)]
        count: u32,
        #[serde(default, deserialize_with = "text_or_number::u32_opt")]
        limit: Option<u32>,
    }

    #[test]
    fn a_bad_or_unknown_parameter_is_named() {
        let e = from_params::<Asked>(json!({"count": "three"})).unwrap_err();
        assert_eq!(e.name.as_deref(), Some("count"), "{e}");
        let e = from_params::<Asked>(json!({"cuont": 3})).unwrap_err();
        assert!(e.to_string().contains("unknown field `cuont`"), "{e}");
        let asked: Asked = from_params(json!({"limit": "10"})).unwrap();
        assert_eq!(asked.limit, Some(10));
        assert!(from_params::<Asked>(Value::Null).is_ok());
    }
}
