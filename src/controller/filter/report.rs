//! What a filtering reports: each outcome's name and reason in words, the report CSV (a line per
//! target) and the warnings' lines of the targets left as written.

use super::{Filtered, Left, Outcome};
use std::collections::BTreeMap;

impl Outcome {
    /// Its name in the report.
    pub fn name(&self) -> String {
        match self {
            Outcome::Filtered => "filtered".into(),
            Outcome::NothingToMove => "nothing_to_move".into(),
            Outcome::Left(l) => format!(
                "left_{}",
                match l {
                    Left::RunTime(_) => "run_time",
                    Left::Unused => "unused",
                    Left::Frames(_) => "frames",
                    Left::Taught => "taught",
                    Left::JointTarget => "joint_target",
                }
            ),
            Outcome::NoNominalSolution(_) => "no_nominal_solution".into(),
            Outcome::NotReached(s) => format!("not_reached_{}", s.name()),
            Outcome::BranchChange => "branch_change".into(),
        }
    }

    /// Why the target was left as written, in words (empty for a filtered one).
    pub fn reason(&self) -> String {
        match self {
            Outcome::Filtered | Outcome::NothingToMove => String::new(),
            Outcome::Left(Left::RunTime(why) | Left::Frames(why)) => why.clone(),
            Outcome::Left(Left::Unused) => "no motion of the program moves to it, so its tool and frame are unknown".into(),
            Outcome::Left(Left::Taught) => "named by --leave (taught on the robot)".into(),
            Outcome::Left(Left::JointTarget) => "a joint target (--joint-targets filters them)".into(),
            Outcome::NoNominalSolution(None) => "the nominal controller reaches it with no configuration within the joint limits".into(),
            Outcome::NoNominalSolution(Some(other)) => {
                format!("the nominal controller has no solution with its configuration data within the joint limits; it reaches the target with {other}")
            }
            Outcome::NotReached(s) => format!("the calibrated arm does not reach it ({})", s.name()),
            Outcome::BranchChange => {
                "the compensated command lies on another branch of the arm (shoulder, elbow or wrist), so its configuration data would change".into()
            }
        }
    }
}

/// The targets left as written, grouped by outcome and reason: one line per group naming them.
pub fn left_lines(f: &Filtered) -> Vec<String> {
    let mut groups: BTreeMap<(String, String), Vec<String>> = BTreeMap::new();
    for t in f.targets.iter().filter(|t| !matches!(t.outcome, Outcome::Filtered | Outcome::NothingToMove)) {
        groups.entry((t.outcome.name(), t.outcome.reason())).or_default().push(format!("{} ({}:{})", t.name, t.file, t.line));
    }
    groups.into_iter().map(|((name, reason), targets)| format!("{} left as written ({name}): {reason}: {}", targets.len(), targets.join(", "))).collect()
}

/// The filter's report as CSV: a line per target.
pub fn report_csv(f: &Filtered) -> String {
    use std::fmt::Write;
    let mut out = String::from(
        "file,line,column,name,kind,tool,frame,outcome,reason,config_before,config_after,residual_mm,residual_deg,nominal_error_mm,nominal_error_deg,moved_mm,moved_deg\n",
    );
    let num = |v: Option<f64>| v.map_or(String::new(), |v| format!("{v:.6}"));
    for t in &f.targets {
        let k = t.compensated.as_ref();
        let _ = writeln!(
            out,
            "{},{},{},{},{},{},{},{},\"{}\",\"{}\",\"{}\",{},{},{},{},{},{}",
            t.file,
            t.line,
            t.column,
            t.name,
            t.kind,
            t.tool,
            t.frame,
            t.outcome.name(),
            t.outcome.reason().replace('"', "\"\""),
            t.config_before,
            t.config_after,
            num(k.map(|k| k.residual_mm)),
            num(k.and_then(|k| k.pose.as_ref().map(|p| p.residual_deg))),
            num(k.map(|k| k.nominal_error_mm)),
            num(k.and_then(|k| k.pose.as_ref().map(|p| p.nominal_error_deg))),
            num(t.moved_mm),
            num(t.moved_deg)
        );
    }
    out
}
