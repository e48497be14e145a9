//! The JSON files prrrp writes and reads back (models, payloads, chains): one error for a
//! value JSON cannot hold and one, with the line and column, for a file that is not one.

use serde::de::DeserializeOwned;
use serde::Serialize;

use crate::error::{PrrrpError, Result};

/// `value` as indented JSON; [`PrrrpError::NonFinite`] naming `what` if a value is NaN or
/// infinite (JSON has neither).
pub(crate) fn to_pretty<T: Serialize>(value: &T, what: &str) -> Result<String> {
    serde_json::to_string_pretty(value).map_err(|_| PrrrpError::NonFinite {
        what: format!("{what} (JSON has no NaN or infinity)"),
        row: None,
    })
}

/// A `T` parsed from `text`, unchecked; [`PrrrpError::InvalidParameter`] with the field
/// `"{kind} JSON (line L, column C)"` of the first problem and `reason` (which says how to
/// write such a file) if it is not one.
pub(crate) fn parse<T: DeserializeOwned>(
    text: &str,
    kind: &str,
    reason: &'static str,
) -> Result<T> {
    serde_json::from_str(text).map_err(|e| PrrrpError::InvalidParameter {
        field: format!("{kind} JSON (line {}, column {})", e.line(), e.column()),
        value: f64::NAN,
        reason,
    })
}
