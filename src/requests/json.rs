//! A request from a JSON object of options (Python's keyword arguments): unknown options and
//! values of the wrong type are refused with the option's name.

use crate::error::{Error, Result};
use serde::de::DeserializeOwned;
use serde::Serialize;

/// The request `command` takes, from `text`, a JSON object of its options by name (snake case:
/// `test_fraction`); options left out keep their defaults. An option the request does not have,
/// or a value of the wrong type, is an error that names it and what was expected.
pub fn from_json<T: DeserializeOwned + Serialize + Default>(command: &str, text: &str) -> Result<T> {
    let given: serde_json::Value = serde_json::from_str(text).map_err(|e| Error::Invalid(format!("{command}: options are not JSON: {e}")))?;
    let Some(given) = given.as_object() else {
        return Err(Error::Invalid(format!("{command}: options must be an object of names to values, got {given}")));
    };
    // Every option the request has, at its default (a group's options at the top level).
    let defaults = serde_json::to_value(T::default()).map_err(|e| Error::Invalid(format!("{command}: {e}")))?;
    let Some(defaults) = defaults.as_object() else {
        return Err(Error::Invalid(format!("{command}: a request must be an object")));
    };
    let mut all = defaults.clone();
    for (name, value) in given {
        if !defaults.contains_key(name) {
            let known: Vec<&str> = defaults.keys().map(String::as_str).collect();
            return Err(Error::Invalid(format!("{command}: unknown option '{name}' (its options: {})", known.join(", "))));
        }
        // Each value on its own among the defaults, so that a type error names its option.
        let mut one = defaults.clone();
        one.insert(name.clone(), value.clone());
        serde_json::from_value::<T>(serde_json::Value::Object(one)).map_err(|e| Error::Invalid(format!("{command}: option '{name}' = {value}: {e}")))?;
        all.insert(name.clone(), value.clone());
    }
    serde_json::from_value(serde_json::Value::Object(all)).map_err(|e| Error::Invalid(format!("{command}: {e}")))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::requests::{CalibrateRequest, DiagnoseRequest};

    #[test]
    fn options_are_read_by_name_with_their_defaults() {
        let r: CalibrateRequest =
            from_json("calibrate", r#"{"method": "ekf", "test_fraction": 0.2, "cable_tension_n": 5.0, "effects": ["backlash:2"]}"#).unwrap();
        assert_eq!((r.method.name(), r.test_fraction, r.loads.cable_tension_n), ("ekf", Some(0.2), 5.0));
        assert_eq!(r.effects, vec!["backlash:2".parse().unwrap()]);
        let d = CalibrateRequest::default();
        assert_eq!((r.seed, r.effort, r.robust.outliers), (d.seed, d.effort, d.robust.outliers));
        let r: DiagnoseRequest = from_json("diagnose", "{}").unwrap();
        assert_eq!(r.folds, crate::diagnose::DEFAULT_FOLDS);
    }

    #[test]
    fn unknown_options_and_wrong_types_are_named() {
        let e = from_json::<CalibrateRequest>("calibrate", r#"{"metod": "lm"}"#).unwrap_err().to_string();
        assert!(e.contains("unknown option 'metod'") && e.contains("method"), "{e}");
        let e = from_json::<CalibrateRequest>("calibrate", r#"{"seed": "seven"}"#).unwrap_err().to_string();
        assert!(e.contains("option 'seed'") && e.contains("invalid type"), "{e}");
        let e = from_json::<DiagnoseRequest>("diagnose", r#"{"payload_kg": [1]}"#).unwrap_err().to_string();
        assert!(e.contains("option 'payload_kg'"), "{e}");
        let e = from_json::<DiagnoseRequest>("diagnose", "[1]").unwrap_err().to_string();
        assert!(e.contains("must be an object"), "{e}");
    }
}
