//! The robot controller's own files: a measurement tour written as a program the controller
//! runs as it is (ABB RAPID, KUKA KRL, Universal Robots URScript), one file per language.
//!
//! A measurement program drives the arm through the poses in their order by joint moves (the
//! approach direction of each pose is the tour's, which the backlash flanks depend on), holds
//! still for the hold time, then raises a *ready* flag and waits until the instrument's software
//! sets a *measured* flag, which it clears before the next move. The flags are variables the
//! controller's own interfaces can read and write without any I/O configuration: RAPID `PERS
//! bool` variables (Robot Web Services, PC SDK), KRL global variables of the program's data list
//! (KUKA's variable access), URScript RTDE boolean registers 64 (ready, output) and 64
//! (measured, input). Where the payload changes between two poses, the program stops and asks
//! for the next payload; the payload's own load data are the controller's to set.
//!
//! The joint angles are the model's (the URDF's joint angles, degrees for RAPID and KRL, radians
//! for URScript): a controller whose joint zeros or directions differ from its URDF's needs them
//! mapped first. Each language reads its own programs' joint targets back
//! ([`Language::joint_targets`]), which the tests use to check a written program.

pub mod filter;
mod krl;
mod rapid;
mod subset;
mod urscript;

pub use subset::ControllerData;

use crate::error::{Error, Result};
use serde::{Deserialize, Serialize};

/// A robot programming language.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
pub enum Language {
    /// ABB RAPID: a module (`.mod`).
    Rapid,
    /// KUKA KRL: a program (`.src`) and its data list (`.dat`).
    Krl,
    /// Universal Robots URScript (`.script`).
    Urscript,
}

impl Language {
    /// Every language.
    pub const ALL: [Language; 3] = [Language::Rapid, Language::Krl, Language::Urscript];

    /// The implementation.
    fn dialect(self) -> &'static dyn Dialect {
        match self {
            Language::Rapid => &rapid::Rapid,
            Language::Krl => &krl::Krl,
            Language::Urscript => &urscript::UrScript,
        }
    }
    /// Its name in options and files.
    pub fn name(self) -> &'static str {
        match self {
            Language::Rapid => "rapid",
            Language::Krl => "krl",
            Language::Urscript => "urscript",
        }
    }
    /// The measurement program of `tour` as its files (name, text), every pose a joint target.
    pub fn measurement_program(self, tour: &Tour) -> Result<Vec<ProgramFile>> {
        tour.check()?;
        let (n, range) = (tour.q[0].len(), self.dialect().joints());
        if !range.contains(&n) {
            return Err(Error::Invalid(format!("a {} program moves arms of {} to {} joints; this one has {n}", self.name(), range.start(), range.end())));
        }
        Ok(self.dialect().measurement_program(tour))
    }
    /// The extensions of its files: a program's, the data file last.
    fn extensions(self) -> &'static [&'static str] {
        match self {
            Language::Rapid => &["mod"],
            Language::Krl => &["src", "dat"],
            Language::Urscript => &["script"],
        }
    }
    /// The extension of its data file ([`ControllerData::write`]): a module, a data list, a
    /// script.
    pub fn data_extension(self) -> &'static str {
        self.extensions()[self.extensions().len() - 1]
    }
    /// The names of the files a program called `name` is written in.
    pub fn file_names(self, name: &str) -> Vec<String> {
        self.extensions().iter().map(|e| format!("{name}.{e}")).collect()
    }
    /// The language of a program file, by its extension (`.mod`, `.prg`, `.sys`: RAPID; `.src`,
    /// `.dat`: KRL; `.script`, `.urscript`: URScript).
    pub fn of_file(path: &std::path::Path) -> Result<Language> {
        let ext = path.extension().and_then(|e| e.to_str()).unwrap_or("").to_ascii_lowercase();
        match ext.as_str() {
            "mod" | "modx" | "prg" | "sys" => Ok(Language::Rapid),
            "src" | "dat" => Ok(Language::Krl),
            "script" | "urscript" => Ok(Language::Urscript),
            _ => {
                Err(Error::data(path.display(), format!("'.{ext}' is not a program file twincal reads: RAPID .mod/.prg/.sys, KRL .src/.dat, URScript .script")))
            }
        }
    }
    /// The joint targets (rad) of a program this language's [`Self::measurement_program`]
    /// wrote, in the order the program moves to them; `files` as written.
    pub fn joint_targets(self, files: &[ProgramFile]) -> Result<Vec<Vec<f64>>> {
        self.dialect().joint_targets(files)
    }
}

/// One file of a program.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ProgramFile {
    /// The file's name (no folder).
    pub name: String,
    /// Its text.
    pub text: String,
}

/// A measurement tour: the poses in order and how each is measured.
#[derive(Clone, Debug, PartialEq)]
pub struct Tour {
    /// The program's name (a letter, then letters, digits and `_`; at most 24 characters).
    pub name: String,
    /// The poses, rad, in the order they are measured.
    pub q: Vec<Vec<f64>>,
    /// The payload mounted for each pose, kg (`None`: one payload throughout).
    pub payload_kg: Option<Vec<f64>>,
    /// Seconds the arm stands still at a pose before it signals that it is ready.
    pub hold_s: f64,
    /// Joint speed of the moves, a fraction of each joint's maximum, in (0, 1].
    pub speed_fraction: f64,
    /// Lines said in the program's header comment (where the tour comes from).
    pub about: Vec<String>,
}

/// Default seconds a measurement program holds the arm still before it waits for the reading.
pub const DEFAULT_HOLD_S: f64 = 2.0;

/// Default joint speed of a measurement program's moves, a fraction of each joint's maximum.
pub const DEFAULT_SPEED_FRACTION: f64 = 0.2;

/// The words a program may not be named, of the three languages (RAPID and KRL read them in any
/// case): the name is the module's, the `DEF`'s or the `def`'s.
const KEYWORDS: &[&str] = &[
    // RAPID
    "module",
    "endmodule",
    "proc",
    "endproc",
    "func",
    "endfunc",
    "trap",
    "endtrap",
    "const",
    "pers",
    "var",
    "if",
    "then",
    "else",
    "elseif",
    "endif",
    "for",
    "from",
    "to",
    "step",
    "do",
    "endfor",
    "while",
    "endwhile",
    "test",
    "case",
    "default",
    "endtest",
    "return",
    "goto",
    "and",
    "or",
    "not",
    "xor",
    "div",
    "mod",
    "true",
    "false",
    "local",
    "task",
    "sysmodule",
    "nostepin",
    "viewonly",
    "readonly",
    "inout",
    "raise",
    "retry",
    "trynext",
    "error",
    "undo",
    "backward",
    "connect",
    "with",
    "exit",
    // KRL (beside the shared ones)
    "def",
    "end",
    "defdat",
    "enddat",
    "deffct",
    "endfct",
    "decl",
    "global",
    "public",
    "repeat",
    "until",
    "loop",
    "endloop",
    "switch",
    "endswitch",
    "halt",
    "wait",
    "sec",
    "ptp",
    "lin",
    "circ",
    "int",
    "real",
    "bool",
    "char",
    "struc",
    "enum",
    "signal",
    "continue",
    "exor",
    // URScript (beside the shared ones)
    "elif",
    "in",
    "break",
    "pass",
    "thread",
    "run",
    "kill",
    "none",
];

/// Longest program name the three languages all take.
pub const MAX_NAME: usize = 24;

/// `--hold-s`, checked: in [0, 3600] s (a plan checks it before it plans).
pub fn check_hold_s(hold_s: f64) -> Result<()> {
    if !(hold_s.is_finite() && (0.0..=3600.0).contains(&hold_s)) {
        return Err(Error::Invalid(format!("--hold-s must be in [0, 3600] s, got {hold_s}")));
    }
    Ok(())
}

impl Tour {
    /// Refuses a tour no controller could run: no pose, a name the languages do not take, a
    /// non-finite angle, a hold or a speed out of range.
    fn check(&self) -> Result<()> {
        let ok = self.name.len() <= MAX_NAME
            && self.name.chars().next().is_some_and(|c| c.is_ascii_alphabetic())
            && self.name.chars().all(|c| c.is_ascii_alphanumeric() || c == '_');
        if !ok {
            return Err(Error::Invalid(format!("program name '{}': a letter, then letters, digits and '_', at most {MAX_NAME} characters", self.name)));
        }
        if KEYWORDS.iter().any(|k| k.eq_ignore_ascii_case(&self.name)) {
            return Err(Error::Invalid(format!("program name '{}' is a keyword of RAPID, KRL or URScript: a controller would not load it", self.name)));
        }
        if self.q.is_empty() {
            return Err(Error::Invalid("a measurement program needs at least one pose".into()));
        }
        if let Some((i, _)) = self.q.iter().enumerate().find(|(_, q)| q.len() != self.q[0].len() || q.iter().any(|v| !v.is_finite())) {
            return Err(Error::Invalid(format!("pose {}: its joint angles are not {} finite numbers", i + 1, self.q[0].len())));
        }
        if self.payload_kg.as_ref().is_some_and(|p| p.len() != self.q.len() || p.iter().any(|m| !m.is_finite() || *m < 0.0)) {
            return Err(Error::Invalid("payload_kg: one finite, non-negative payload per pose".into()));
        }
        check_hold_s(self.hold_s)?;
        if !(self.speed_fraction > 0.0 && self.speed_fraction <= 1.0) {
            return Err(Error::Invalid(format!("--speed-fraction must be in (0, 1], got {}", self.speed_fraction)));
        }
        Ok(())
    }
    /// The payload to mount before pose `i`, where it differs from the previous pose's (or at
    /// the first pose of a tour with payloads).
    fn payload_change(&self, i: usize) -> Option<f64> {
        let p = self.payload_kg.as_ref()?;
        (i == 0 || p[i] != p[i - 1]).then_some(p[i])
    }
}

/// A language's writer and reader.
trait Dialect: Sync {
    /// The joint counts the language's joint targets hold (the arm's six, and a seventh as the
    /// first external axis where the language has one).
    fn joints(&self) -> std::ops::RangeInclusive<usize>;
    /// The program's files.
    fn measurement_program(&self, tour: &Tour) -> Vec<ProgramFile>;
    /// The joint targets (rad) a program of this writer moves to, in order.
    fn joint_targets(&self, files: &[ProgramFile]) -> Result<Vec<Vec<f64>>>;
}

/// The number `text` (`-2`, `9E+09`), or an error naming `what`.
fn number(text: &str, what: &str) -> Result<f64> {
    text.trim().parse::<f64>().map_err(|_| Error::Invalid(format!("{what}: '{}' is not a number", text.trim())))
}

/// The numbers of a comma-separated list (`1.5, -2, 9E+09`), or an error naming `what`.
fn numbers(list: &str, what: &str) -> Result<Vec<f64>> {
    list.split(',').map(|t| number(t, what)).collect()
}

/// The header comment's lines: what the program does, the angles' `unit`, the `handshake`,
/// and where the tour comes from.
fn header(tour: &Tour, unit: &str, handshake: &str) -> Vec<String> {
    let mut lines = vec![
        format!("twincal measurement program: {} poses in the tour's order, joint moves.", tour.q.len()),
        format!("At each pose the arm holds still {} s, then waits until the pose is measured.", tour.hold_s),
        handshake.to_string(),
        format!("Joint angles are the robot model's (its URDF's), {unit}: map them first where the controller's zeros or directions differ."),
    ];
    lines.extend(tour.about.iter().cloned());
    lines
}

/// Degrees at six decimals (a micro-degree: below any controller's resolution).
fn deg(v: f64) -> String {
    format!("{:.6}", v.to_degrees())
}

#[cfg(test)]
mod tests;
