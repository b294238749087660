//! Pass / fail against accuracy limits the user gives (`--max-test-rmse-mm`,
//! `--max-test-max-mm`), written into the command's JSON output as `verdict`.
//!
//! Without any limit no verdict is written (the key is absent): twincal has no opinion on what
//! accuracy an application needs. A check whose value cannot be measured (no test rows) fails.

use crate::error::{Error, Result};
use serde::{Deserialize, Serialize};

/// One limit and what was measured against it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Check {
    /// What was measured (`test_rmse_mm`, `test_max_mm`, `heldout_rmse_mm`).
    pub name: String,
    /// The user's limit, mm: the check passes when `value <= limit`.
    pub limit: f64,
    /// The measured value, mm; `null` when it could not be measured (the check fails).
    pub value: Option<f64>,
    /// Whether the value is measured and within the limit.
    pub pass: bool,
    /// How the value was obtained, or why it is missing.
    pub source: String,
}

/// All checks pass (`pass`), or not.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Verdict {
    /// Whether every check passes.
    pub pass: bool,
    /// Each limit given, with what was measured against it.
    pub checks: Vec<Check>,
}

/// A limit on a residual statistic, mm, from a command-line flag.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Limit {
    /// The command-line flag that sets the limit (`--max-test-rmse-mm`, ...), named in errors.
    pub flag: &'static str,
    /// The limit, mm; `None` when the flag is not given.
    pub value: Option<f64>,
}

impl Limit {
    /// Refuses a limit that is not a positive finite number of millimetres.
    pub fn validate(&self) -> Result<()> {
        match self.value {
            Some(v) if !(v.is_finite() && v > 0.0) => Err(Error::Invalid(format!("{} must be a positive number of millimetres, got {v}", self.flag))),
            _ => Ok(()),
        }
    }
}

/// Checks each given limit against its measured value: `(limit, check name, value, source)`.
/// `None` when no limit was given.
pub fn judge(items: &[(Limit, &str, Option<f64>, &str)]) -> Option<Verdict> {
    let checks: Vec<Check> = items
        .iter()
        .filter_map(|(limit, name, value, source)| {
            let l = limit.value?;
            let value = value.filter(|v| v.is_finite());
            Some(Check { name: name.to_string(), limit: l, value, pass: value.is_some_and(|v| v <= l), source: source.to_string() })
        })
        .collect();
    (!checks.is_empty()).then(|| Verdict { pass: checks.iter().all(|c| c.pass), checks })
}

/// `value` (a JSON object) with `verdict` added when there is one.
pub fn with_verdict<T: Serialize>(value: &T, verdict: Option<&Verdict>) -> Result<serde_json::Value> {
    let mut v = serde_json::to_value(value).map_err(|e| Error::Invalid(format!("cannot serialise the result: {e}")))?;
    if let (Some(obj), Some(verdict)) = (v.as_object_mut(), verdict) {
        obj.insert("verdict".into(), serde_json::to_value(verdict).map_err(|e| Error::Invalid(format!("cannot serialise the verdict: {e}")))?);
    }
    Ok(v)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn limits_pass_fail_and_missing_values() {
        let rmse = Limit { flag: "--max-test-rmse-mm", value: Some(0.05) };
        let max = Limit { flag: "--max-test-max-mm", value: Some(0.1) };
        let v = judge(&[(rmse, "test_rmse_mm", Some(0.04), "test rows"), (max, "test_max_mm", Some(0.2), "test rows")]).unwrap();
        assert!(!v.pass);
        assert_eq!(v.checks.iter().map(|c| c.pass).collect::<Vec<_>>(), [true, false]);
        // Equal to the limit passes; a value that could not be measured fails.
        assert!(judge(&[(rmse, "test_rmse_mm", Some(0.05), "")]).unwrap().pass);
        let missing = judge(&[(rmse, "test_rmse_mm", None, "no test rows")]).unwrap();
        assert!(!missing.pass && missing.checks[0].value.is_none());
        assert!(!judge(&[(rmse, "test_rmse_mm", Some(f64::NAN), "")]).unwrap().pass);
        // No limit, no verdict.
        assert!(judge(&[(Limit { flag: "x", value: None }, "test_rmse_mm", Some(1.0), "")]).is_none());
        for bad in [0.0, -1.0, f64::NAN, f64::INFINITY] {
            let e = Limit { flag: "--max-test-max-mm", value: Some(bad) }.validate().unwrap_err().to_string();
            assert!(e.contains("--max-test-max-mm"), "{e}");
        }
        let json = with_verdict(&serde_json::json!({"a": 1}), Some(&v)).unwrap();
        assert_eq!(json["verdict"]["pass"], false);
        assert_eq!(json["verdict"]["checks"][1]["name"], "test_max_mm");
        assert_eq!(with_verdict(&serde_json::json!({"a": 1}), None).unwrap(), serde_json::json!({"a": 1}));
    }
}
