//! An effect as a user names it (`--effects`, `--candidates`, `plan --effects`, Python's
//! `effects=`): a kind, optionally on one joint, written `KIND[:JOINT]` with the joint 1-based
//! (`backlash:2`, `compliance`).

use super::EffectKind;
use crate::error::{Error, Result};
use serde::{Deserialize, Serialize};

/// A kind of effect and, where it sits on one joint, the joint (0-based); a per-joint kind
/// without a joint means every joint.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(try_from = "String", into = "String")]
pub struct EffectChoice {
    /// The kind.
    pub kind: EffectKind,
    /// The joint (0-based), or `None` for a whole-arm kind or every joint of a per-joint one.
    pub joint: Option<usize>,
}

impl EffectChoice {
    /// The pair the calibration's options hold.
    pub fn pair(self) -> (EffectKind, Option<usize>) {
        (self.kind, self.joint)
    }
}

impl std::str::FromStr for EffectChoice {
    type Err = Error;
    /// `KIND[:JOINT]`: a kind (any of [`EffectKind::parse`]'s names) and a joint 1..N (checked
    /// against the data later); a joint only on a kind that sits on joints.
    fn from_str(item: &str) -> Result<EffectChoice> {
        if item.trim().is_empty() {
            return Err(Error::Invalid("an empty item names no effect: give KIND[:JOINT] items separated by commas".into()));
        }
        let kind = EffectKind::parse;
        let (kind, joint) = match item.split_once(':') {
            Some((k, j)) => {
                let max = crate::dataset::MAX_JOINTS;
                let bad = || Error::Invalid("the joint after ':' must be a joint number, 1..N".into());
                let j: usize = j.trim().parse().map_err(|_| bad())?;
                if !(1..=max).contains(&j) {
                    return Err(bad());
                }
                (kind(k)?, Some(j - 1))
            }
            None => (kind(item)?, None),
        };
        let allowed = kind.joint_options(crate::dataset::MAX_JOINTS).contains(&joint) || (joint.is_none() && kind.per_joint());
        if !allowed {
            return Err(Error::Invalid(format!("{} is not a per-joint effect", kind.name())));
        }
        Ok(EffectChoice { kind, joint })
    }
}

impl std::fmt::Display for EffectChoice {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let name = self.kind.name();
        match self.joint {
            Some(j) => write!(f, "{name}:{}", j + 1),
            None => f.write_str(name),
        }
    }
}

impl TryFrom<String> for EffectChoice {
    type Error = Error;
    fn try_from(s: String) -> Result<EffectChoice> {
        s.parse()
    }
}

impl From<EffectChoice> for String {
    fn from(c: EffectChoice) -> String {
        c.to_string()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_choice_reads_and_writes_kind_and_joint() {
        for (text, kind, joint, back) in [
            ("backlash:2", EffectKind::Backlash, Some(1), "backlash:2"),
            ("Compliance", EffectKind::Compliance, None, "compliance"),
            ("thermal", EffectKind::Thermal, None, "thermal"),
            // The names earlier versions wrote are read as the kinds they named.
            ("thermal_drift", EffectKind::Thermal, None, "thermal"),
            ("Joint_Compliance:1", EffectKind::Compliance, Some(0), "compliance:1"),
        ] {
            let c: EffectChoice = text.parse().unwrap();
            assert_eq!((c.kind, c.joint), (kind, joint), "{text}");
            assert_eq!(c.to_string(), back);
            assert_eq!(back.parse::<EffectChoice>().unwrap(), c);
        }
        for bad in ["", "backlash:0", "backlash:x", "warp", "nonlinearity:2"] {
            assert!(bad.parse::<EffectChoice>().is_err(), "{bad}");
        }
        // A result file of an earlier version names its blocks' kinds by their former names.
        for (former, kind) in EffectKind::FORMER_NAMES {
            assert_eq!(serde_json::from_str::<EffectKind>(&format!("\"{former}\"")).unwrap(), kind);
            assert_eq!(serde_json::to_string(&kind).unwrap(), format!("\"{}\"", kind.name()));
        }
        let json = serde_json::to_string(&vec!["backlash:2".parse::<EffectChoice>().unwrap()]).unwrap();
        assert_eq!(json, r#"["backlash:2"]"#);
    }
}
