//! Program filtering: a robot program's own targets compensated in place.
//!
//! A program is read as its controller reads it (ABB RAPID, KUKA KRL, URScript): each target
//! with the tool and the work object (base) it is moved with, and its configuration data. The
//! nominal controller's interpretation is the nominal model's inverse kinematics of the target
//! on the branch the configuration data name (for a language without them, the solution nearest
//! the arm's previous target); the compensated command is the calibrated model's, on that
//! branch ([`crate::compensate::Compensator`]); the filtered target is the nominal forward
//! kinematics of the compensated command, written back in the target's own frame with the
//! configuration data of the compensated command. The filtered copy differs from the program
//! only in the numbers of the targets it moved: comments, layout, line endings and every other
//! statement are the program's bytes.
//!
//! Left as written, each listed with why: targets the controller computes at run time
//! (`Offs`, `RelTool`, KRL's geometric operator and `_REL` moves, URScript's `pose_trans`,
//! targets assigned in code), targets moved with frames the program does not state, declared
//! targets no motion uses, targets named by `--leave` (none of the three languages marks a
//! target as taught on the robot: the list says which), joint targets unless asked, targets
//! the calibrated model does not reach, and targets whose compensated command would change the
//! arm's configuration (shoulder, elbow or wrist branch). A target whose filtered pose lies
//! within the compensation's tolerance of the written one is left as written (nothing to move).

mod branch;
mod krl;
mod rapid;
mod report;
pub mod sample;
mod text;
mod urscript;
pub mod verify;

pub use report::{left_lines, report_csv};

#[cfg(test)]
mod tests;

pub use branch::{ArmBranch, Setup};

use super::{Language, ProgramFile};
use crate::compensate::{Compensated, Compensator, Status};
use crate::error::{Error, Result};
use nalgebra::{Isometry3, Matrix3, Rotation3, Translation3, UnitQuaternion, Vector3};
use rayon::prelude::*;
use serde::Serialize;
use std::collections::BTreeMap;
use text::Num;

/// How a target's numbers are laid out.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Layout {
    /// RAPID `robtarget`: x, y, z (mm), q1..q4 (w first), cf1, cf4, cf6, cfx.
    RapidPose,
    /// RAPID `jointtarget`'s robax: six angles, degrees.
    RapidJoints,
    /// KRL `POS` / `E6POS`: X, Y, Z (mm), A, B, C (Z-Y-X, degrees), and S, T where written.
    KrlPose {
        /// S and T are written.
        config: bool,
    },
    /// KRL `AXIS` / `E6AXIS`: A1..A6, degrees.
    KrlJoints,
    /// URScript pose `p[x, y, z, rx, ry, rz]`: metres, rotation vector (rad).
    UrPose,
    /// URScript joint list: six angles, rad.
    UrJoints,
}

impl Layout {
    /// Whether its numbers are joint angles.
    fn joints(self) -> bool {
        matches!(self, Layout::RapidJoints | Layout::KrlJoints | Layout::UrJoints)
    }
    /// Whether the target states the arm's configuration.
    fn has_config(self) -> bool {
        matches!(self, Layout::RapidPose | Layout::KrlPose { config: true })
    }
}

/// One target of a program as the parser found it.
#[derive(Clone, Debug)]
pub(crate) struct Site {
    /// The file it is written in (index into the program's files).
    pub file: usize,
    /// Byte offset of its data in that file.
    pub at: usize,
    /// Its declared name, or `inline`.
    pub name: String,
    /// Its layout.
    pub layout: Layout,
    /// Its numbers, in the layout's order.
    pub nums: Vec<Num>,
    /// The (tool, frame) names of each motion that moves to it.
    pub uses: Vec<(String, String)>,
    /// Why it is left as written whatever it is moved with (assigned at run time), if so.
    pub left: Option<Left>,
    /// How many of its uses ignore its configuration data (RAPID: a motion run with `ConfJ\Off`
    /// or `ConfL\Off`; KRL: `S` and `T` in a `LIN` or `CIRC`, which keep the arm's branch).
    pub config_ignored: usize,
}

impl Site {
    /// A site with nothing used yet and nothing ignored.
    pub(crate) fn new(file: usize, at: usize, name: &str, layout: Layout, nums: Vec<Num>, left: Option<Left>) -> Site {
        Site { file, at, name: name.to_string(), layout, nums, uses: Vec::new(), left, config_ignored: 0 }
    }
    /// Its numbers' values, in the layout's order.
    fn values(&self) -> Vec<f64> {
        self.nums.iter().map(|n| n.value).collect()
    }
    /// Whether the controller reads its configuration data: it states them and a motion that
    /// moves to it reads them (or none moves to it).
    fn reads_config(&self) -> bool {
        self.layout.has_config() && (self.uses.is_empty() || self.config_ignored < self.uses.len())
    }
    /// The configuration data the controller reads, if any.
    fn config(&self) -> Option<Vec<i64>> {
        if self.reads_config() {
            pose_config(self.layout, &self.values())
        } else {
            None
        }
    }
}

/// What the parser found in a program: its targets, the frames it declares, what it computes
/// at run time.
#[derive(Clone, Debug, Default)]
pub(crate) struct Parsed {
    /// The targets with data written in the program.
    pub sites: Vec<Site>,
    /// Tools by name: the TCP's pose in the controller's flange frame (tool0), mm; `None` for a
    /// tool the controller holds still (RAPID `robhold`), which the filter does not move.
    pub tools: BTreeMap<String, Option<Isometry3<f64>>>,
    /// Work objects / bases by name: their pose in the controller's base frame, mm; `None` for
    /// one the robot holds or an external axis moves.
    pub frames: BTreeMap<String, Option<Isometry3<f64>>>,
    /// Motions to targets computed at run time, and targets the program does not declare.
    pub notes: Vec<RunTime>,
}

/// A motion the filter leaves alone because its target is not data of the program.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct RunTime {
    /// File, line, column.
    pub file: String,
    /// Line, 1-based.
    pub line: usize,
    /// Column, 1-based.
    pub column: usize,
    /// The motion's target as written.
    pub target: String,
    /// Why it is left.
    pub reason: String,
}

/// Why a target is left as written.
#[derive(Clone, Debug, PartialEq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Left {
    /// The program assigns it in code: its value is the controller's, at run time.
    RunTime(String),
    /// No motion of the program moves to it (its frames are not known).
    Unused,
    /// Its motions use different tools or frames, or ones the program does not state.
    Frames(String),
    /// Named by `--leave` (taught on the robot).
    Taught,
    /// A joint target, left unless `--joint-targets`.
    JointTarget,
}

/// What became of one target.
#[derive(Clone, Debug, PartialEq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Outcome {
    /// Its numbers were rewritten.
    Filtered,
    /// Its filtered pose lies within the tolerance of the written one: left as written.
    NothingToMove,
    /// Left as written, for this reason.
    Left(Left),
    /// The nominal model has no solution with the target's configuration data (the controller
    /// would stop there): left as written; with the configuration data the nominal arm reaches
    /// the target with, where it does.
    NoNominalSolution(Option<String>),
    /// The calibrated model does not reach it (the status): left as written.
    NotReached(Status),
    /// The compensated command lies on another branch of the arm (its configuration data would
    /// change: shoulder, elbow or wrist): left as written.
    BranchChange,
}

/// One target's line of the report.
#[derive(Clone, Debug, Serialize)]
pub struct TargetReport {
    /// The file it is written in.
    pub file: String,
    /// Line, 1-based.
    pub line: usize,
    /// Column, 1-based.
    pub column: usize,
    /// Its name (or `inline`).
    pub name: String,
    /// `pose` or `joints`.
    pub kind: &'static str,
    /// Tool and frame (work object, base) it is moved with.
    pub tool: String,
    /// The frame.
    pub frame: String,
    /// What became of it.
    pub outcome: Outcome,
    /// The configuration data as written, and after (empty where the language has none).
    pub config_before: String,
    /// After.
    pub config_after: String,
    /// The compensation (absent for a target left before it).
    pub compensated: Option<Compensated>,
    /// How far the filtered target's TCP lies from the written one, mm.
    pub moved_mm: Option<f64>,
    /// For a joint target, the largest change of an angle, degrees.
    pub moved_deg: Option<f64>,
}

/// What a filtering did.
#[derive(Clone, Debug, Serialize)]
pub struct Filtered {
    /// The filtered files, the program's names, in its order.
    #[serde(skip)]
    pub files: Vec<ProgramFile>,
    /// Per target, in the order the files declare them.
    pub targets: Vec<TargetReport>,
    /// The motions whose targets the controller computes at run time, left as written.
    pub run_time: Vec<RunTime>,
}

/// How to filter.
#[derive(Clone, Debug, Default)]
pub struct FilterOptions {
    /// Compensate joint targets too (`MoveAbsJ`, `E6AXIS`, `movej([...])`).
    pub joint_targets: bool,
    /// Targets to leave as written, by name (taught on the robot).
    pub leave: Vec<String>,
    /// The arm's joints (rad) when the program starts, for languages that choose among the
    /// arm's solutions by the previous position (URScript, KRL without S and T); `None`: the
    /// middle of the joints' ranges.
    pub start_q: Option<Vec<f64>>,
}

/// A language's program reader.
pub(crate) trait Reader {
    /// The targets, frames and run-time motions of `files` (the program), with the frames that
    /// `frames` declare (tool and base data kept elsewhere: `$config.dat`, a user module).
    fn parse(&self, files: &[ProgramFile], frames: &[ProgramFile]) -> Result<Parsed>;
    /// The default tool and frame.
    fn defaults(&self) -> (&'static str, &'static str);
}

fn reader(lang: Language) -> &'static dyn Reader {
    match lang {
        Language::Rapid => &rapid::RapidReader,
        Language::Krl => &krl::KrlReader,
        Language::Urscript => &urscript::UrReader,
    }
}

/// The program `files` read in `lang` with the frames `frames` declare, its default tool and
/// frame (the flange, the base) declared where the program does not.
fn parse(lang: Language, files: &[ProgramFile], frames: &[ProgramFile]) -> Result<Parsed> {
    let r = reader(lang);
    let mut parsed = r.parse(files, frames)?;
    let (tool0, frame0) = r.defaults();
    parsed.tools.entry(tool0.to_string()).or_insert(Some(Isometry3::identity()));
    parsed.frames.entry(frame0.to_string()).or_insert(Some(Isometry3::identity()));
    Ok(parsed)
}

/// The arm's joints (rad) when the program starts: `--start-joints-deg`, else the middle of each
/// joint's range.
fn start_joints(c: &Compensator, o: &FilterOptions) -> Vec<f64> {
    o.start_q.clone().unwrap_or_else(|| c.limits().iter().map(|(lo, hi)| 0.5 * (lo + hi)).collect())
}

/// The program `files` in `lang` filtered for the compensation `c` of an arm set up as `setup`,
/// with the frames declared in `frames`; or what is wrong with the program (by file, line and
/// column).
pub fn filter_program(c: &Compensator, setup: &Setup, lang: Language, files: &[ProgramFile], frames: &[ProgramFile], o: &FilterOptions) -> Result<Filtered> {
    let parsed = parse(lang, files, frames)?;
    if setup.n_joints != 6 && parsed.sites.iter().any(|s| s.layout.has_config() || s.layout.joints()) {
        return Err(Error::Invalid(format!("a {} program moves a six-axis arm; the model's has {} joints", lang.name(), setup.n_joints)));
    }
    let plans: Vec<Plan> = parsed.sites.iter().map(|s| plan(s, &parsed, o)).collect();
    let results = solve_all(c, setup, &parsed.sites, &plans, o);
    let mut edits: Vec<Vec<(std::ops::Range<usize>, String)>> = vec![Vec::new(); parsed.sites.len()];
    let mut targets = Vec::with_capacity(parsed.sites.len());
    let lines: Vec<text::Lines> = files.iter().map(|f| text::Lines::new(&f.text)).collect();
    for ((site, plan), result) in parsed.sites.iter().zip(&plans).zip(results) {
        let (l, col) = lines[site.file].at(site.at);
        let (outcome, new, compensated) = match (&plan.frames, result) {
            (Err(left), _) => (Outcome::Left(left.clone()), None, None),
            (Ok(_), Solved::NoNominal(other)) => (Outcome::NoNominalSolution(other.clone()), None, None),
            (Ok(_), Solved::Done(k, values)) => judge(site, &k, values, c.tolerances(), setup),
            (Ok(_), Solved::Elsewhere(k)) => (Outcome::BranchChange, None, Some(*k)),
            (Ok(_), Solved::Skipped) => unreachable!("every planned site is solved"),
        };
        let moved = new.as_ref().map(|v: &Vec<f64>| moved(site, v));
        if outcome == Outcome::Filtered {
            if let Some(v) = &new {
                edits[targets.len()] = rewrite(site, v);
            }
        }
        targets.push(TargetReport {
            file: files[site.file].name.clone(),
            line: l,
            column: col,
            name: site.name.clone(),
            kind: if site.layout.joints() { "joints" } else { "pose" },
            tool: site.uses.first().map_or(String::new(), |u| u.0.clone()),
            frame: site.uses.first().map_or(String::new(), |u| u.1.clone()),
            config_before: config_text(site, site.values().as_slice()),
            config_after: new.as_ref().map_or(String::new(), |v| config_text(site, v)),
            outcome,
            compensated,
            moved_mm: moved.and_then(|m| m.0),
            moved_deg: moved.and_then(|m| m.1),
        });
    }
    // Without configuration data the controller reads each target from where the last one
    // left the arm: the filtered program is read back as it would run, and a target it reads
    // as another of the arm's solutions is left as written (until none is).
    let mut out = written(files, &parsed.sites, &edits);
    for _ in 0..READ_BACK_PASSES {
        let wrong = read_back(&Arm { c, setup, o }, lang, &out, frames, &parsed.sites, &plans, &targets)?;
        if wrong.is_empty() {
            break;
        }
        for k in wrong {
            targets[k].outcome = Outcome::BranchChange;
            edits[k].clear();
        }
        out = written(files, &parsed.sites, &edits);
    }
    Ok(Filtered { files: out, targets, run_time: parsed.notes })
}

/// The nominal controller's joint command for each target of the program `files` (in the
/// order the reader lists them): a joint target's angles, a pose's nominal inverse kinematics on
/// the branch its configuration data state or, without them, nearest where the previous target
/// left the arm; `None` where it finds none (or the target's frames are not known).
pub fn read_program(
    c: &Compensator,
    setup: &Setup,
    lang: Language,
    files: &[ProgramFile],
    frames: &[ProgramFile],
    o: &FilterOptions,
) -> Result<Vec<Option<Vec<f64>>>> {
    let parsed = parse(lang, files, frames)?;
    let everything = FilterOptions { joint_targets: true, leave: Vec::new(), start_q: o.start_q.clone() };
    let (_, mut wn) = c.works();
    let mut last = start_joints(c, o);
    let mut out = Vec::with_capacity(parsed.sites.len());
    for s in &parsed.sites {
        let v = s.values();
        let q = match plan(s, &parsed, &everything).frames {
            _ if s.layout.joints() && !v.is_empty() => Some(joints_of(s.layout, &v)),
            Ok(f) if !v.is_empty() => {
                let (p, rot) = model_pose(setup, s.layout, &v, &f);
                match s.config() {
                    Some(cfg) => {
                        let accept = |q: &mut Vec<f64>| branch::matches(s.layout, &cfg, q, c.limits(), setup);
                        c.nominal_pose_command(&p, &rot, &branch::seeds(s.layout, &cfg, c.limits()), &accept, &mut wn)
                    }
                    None => c.nominal_pose_nearest(&p, &rot, &last, &mut wn),
                }
            }
            _ => None,
        };
        if let Some(q) = &q {
            last = q.clone();
        }
        out.push(q);
    }
    Ok(out)
}

/// The compensation, the arm's set-up and the filter's options, as the read-back takes them.
#[derive(Clone, Copy)]
struct Arm<'a> {
    c: &'a Compensator<'a>,
    setup: &'a Setup,
    o: &'a FilterOptions,
}

/// Most read-back passes of a program without configuration data.
const READ_BACK_PASSES: usize = 4;

/// The program's files with each site's edits applied.
fn written(files: &[ProgramFile], sites: &[Site], edits: &[Vec<(std::ops::Range<usize>, String)>]) -> Vec<ProgramFile> {
    files
        .iter()
        .enumerate()
        .map(|(i, f)| {
            let mine: Vec<(std::ops::Range<usize>, String)> =
                sites.iter().zip(edits).filter(|(s, _)| s.file == i).flat_map(|(_, e)| e.iter().cloned()).collect();
            ProgramFile { name: f.name.clone(), text: text::apply(&f.text, mine) }
        })
        .collect()
}

/// The filtered targets of a program without configuration data that its controller, reading
/// the filtered files target by target from where the arm stands ([`read_program`]), commands
/// to a place the calibrated model does not put the tool on the written target: their indices.
fn read_back(
    arm: &Arm,
    lang: Language,
    out: &[ProgramFile],
    frames: &[ProgramFile],
    sites: &[Site],
    plans: &[Plan],
    targets: &[TargetReport],
) -> Result<Vec<usize>> {
    let Arm { c, setup, o } = *arm;
    let checked = |s: &Site, t: &TargetReport| t.outcome == Outcome::Filtered && !s.reads_config() && !s.layout.joints();
    if !sites.iter().zip(targets).any(|(s, t)| checked(s, t)) {
        return Ok(Vec::new());
    }
    let read = read_program(c, setup, lang, out, frames, o)?;
    let mut wrong = Vec::new();
    for (k, ((s, p), t)) in sites.iter().zip(plans).zip(targets).enumerate() {
        if let (true, Ok(f)) = (checked(s, t), &p.frames) {
            let (ap, ar) = model_pose(setup, s.layout, &s.values(), f);
            if !read[k].as_ref().is_some_and(|q| c.reaches(q, &ap, &ar, 3.0)) {
                wrong.push(k);
            }
        }
    }
    Ok(wrong)
}

/// A site's frames resolved, or why it is left before any solve.
struct Plan {
    frames: std::result::Result<(Isometry3<f64>, Isometry3<f64>), Left>,
}

/// The tool and frame a site is moved with (both mm), or why it is left.
fn plan(s: &Site, p: &Parsed, o: &FilterOptions) -> Plan {
    let frames = (|| {
        if let Some(l) = &s.left {
            return Err(l.clone());
        }
        if o.leave.iter().any(|n| n.eq_ignore_ascii_case(&s.name)) {
            return Err(Left::Taught);
        }
        if s.layout.joints() && !o.joint_targets {
            return Err(Left::JointTarget);
        }
        let Some((tool, frame)) = s.uses.first() else { return Err(Left::Unused) };
        if let Some(other) = s.uses.iter().find(|u| *u != &s.uses[0]) {
            return Err(Left::Frames(format!("moved with {tool} in {frame} and with {} in {}", other.0, other.1)));
        }
        let t = p.tools.get(tool).ok_or_else(|| Left::Frames(format!("the tool {tool} is not declared (give the file that declares it with --frames)")))?;
        let f = p.frames.get(frame).ok_or_else(|| Left::Frames(format!("the frame {frame} is not declared (give the file that declares it with --frames)")))?;
        match (t, f) {
            (Some(t), Some(f)) => Ok((*t, *f)),
            (None, _) => Err(Left::Frames(format!("the tool {tool} is held by the robot's surroundings, not on the flange"))),
            (_, None) => Err(Left::Frames(format!("the frame {frame} is held by the robot or moved by an external axis"))),
        }
    })();
    Plan { frames }
}

/// A site's solve.
enum Solved {
    /// The nominal controller finds no solution with the target's configuration (the
    /// configuration data it reaches the target with instead, where it does).
    NoNominal(Option<String>),
    /// The compensation, and the filtered numbers of the site (in its layout's order).
    Done(Box<Compensated>, Vec<f64>),
    /// Left before solving.
    Skipped,
    /// The controller would read the filtered target, from where the filtered program leaves
    /// the arm, as another of the arm's solutions (a language without configuration data).
    Elsewhere(Box<Compensated>),
}

/// Every planned site solved: those that state their configuration in parallel, the others
/// in program order, each from the previous target's nominal command.
fn solve_all(c: &Compensator, setup: &Setup, sites: &[Site], plans: &[Plan], o: &FilterOptions) -> Vec<Solved> {
    let mut out: Vec<Solved> = sites
        .par_iter()
        .zip(plans)
        .map_init(
            || c.works(),
            |(wc, wn), (s, p)| match &p.frames {
                Ok(f) if s.reads_config() || s.layout.joints() => solve_site(c, setup, s, f, None, wc, wn),
                _ => Solved::Skipped,
            },
        )
        .collect();
    let (mut wc, mut wn) = c.works();
    // Where the program as written leaves the arm, and where the filtered program does.
    let start = start_joints(c, o);
    let (mut nominal_last, mut command_last) = (start.clone(), start);
    for (k, (s, p)) in sites.iter().zip(plans).enumerate() {
        if let (Ok(f), Solved::Skipped) = (&p.frames, &out[k]) {
            // The filtered target as the controller reads it, from where the filtered program
            // leaves the arm, must command the compensated joints, not another solution: the
            // compensation from the written program's reading, else from the reading the
            // filtered program's position gives.
            let (solved, read) = {
                let mut tries = [&nominal_last, &command_last].into_iter().map(|from| {
                    let solved = solve_site(c, setup, s, f, Some(from), &mut wc, &mut wn);
                    match solved {
                        Solved::Done(done, values) if done.status == Status::Reachable => {
                            let (tp, tr) = model_pose(setup, s.layout, &values, f);
                            let (ap, ar) = model_pose(setup, s.layout, &s.values(), f);
                            match c.nominal_pose_nearest(&tp, &tr, &command_last, &mut wn) {
                                // Two solves, each within the tolerance: within three times it.
                                Some(q) if c.reaches(&q, &ap, &ar, 3.0) => (Solved::Done(done, values), Some(q)),
                                _ => (Solved::Elsewhere(done), None),
                            }
                        }
                        other => (other, None),
                    }
                });
                let first = tries.next().unwrap_or((Solved::NoNominal(None), None));
                match first {
                    (Solved::Elsewhere(done), _) => match tries.next() {
                        Some((Solved::Done(d, v), read)) => (Solved::Done(d, v), read),
                        _ => (Solved::Elsewhere(done), None),
                    },
                    other => other,
                }
            };
            out[k] = solved;
            // The program as written leaves the arm at its reading of the target; the filtered
            // one where its controller reads the filtered target, or the target as written
            // where it is left.
            if let Solved::Done(done, _) | Solved::Elsewhere(done) = &out[k] {
                nominal_last = done.nominal_q.clone();
            }
            command_last = match read {
                Some(q) => q,
                None => {
                    let (ap, ar) = model_pose(setup, s.layout, &s.values(), f);
                    c.nominal_pose_nearest(&ap, &ar, &command_last, &mut wn).unwrap_or(command_last)
                }
            };
            continue;
        }
        // The arm stands at each joint target it moves to: a compensated one at its command
        // in the filtered program, one left as written at its angles.
        match &out[k] {
            Solved::Done(done, _) if s.layout.joints() => {
                nominal_last = done.nominal_q.clone();
                command_last = if done.status == Status::Reachable { done.command_q.clone() } else { done.nominal_q.clone() };
            }
            _ if s.layout.joints() && !s.nums.is_empty() && !s.uses.is_empty() => {
                nominal_last = joints_of(s.layout, &s.values());
                command_last = nominal_last.clone();
            }
            _ => {}
        }
    }
    out
}

/// A pose site's `values` as the model's tool target (its tool point, mm, and orientation),
/// moved with `tool` in `frame`.
fn model_pose(setup: &Setup, layout: Layout, values: &[f64], (tool, frame): &(Isometry3<f64>, Isometry3<f64>)) -> (Vector3<f64>, Matrix3<f64>) {
    let (pose, _) = pose_of(layout, values);
    setup.model_target(&(frame * pose * tool.inverse()))
}

/// One site: its pose in the model's terms, the nominal controller's command, the compensated
/// one, and the site's new numbers.
fn solve_site(
    c: &Compensator,
    setup: &Setup,
    s: &Site,
    (tool, frame): &(Isometry3<f64>, Isometry3<f64>),
    previous: Option<&[f64]>,
    wc: &mut crate::ik::IkWork,
    wn: &mut crate::ik::IkWork,
) -> Solved {
    let v = s.values();
    if s.layout.joints() {
        let q = joints_of(s.layout, &v);
        let (p, r) = c.nominal_pose(&q, wn);
        let k = c.compensate_commanded(&p, &r, q, wc, wn);
        let new = joint_values(s.layout, &k.command_q);
        return Solved::Done(Box::new(k), new);
    }
    let config = s.config();
    let (p, r) = model_pose(setup, s.layout, &v, &(*tool, *frame));
    let nominal = match (&config, previous) {
        (Some(cfg), _) => {
            let accept = |q: &mut Vec<f64>| branch::matches(s.layout, cfg, q, c.limits(), setup);
            c.nominal_pose_command(&p, &r, &branch::seeds(s.layout, cfg, c.limits()), &accept, wn)
        }
        (None, Some(q)) => c.nominal_pose_nearest(&p, &r, q, wn),
        (None, None) => c.nominal_pose_command(&p, &r, &[], &|_| true, wn),
    };
    let Some(nominal_q) = nominal else {
        // Which configuration data the target takes instead, said as the language writes them.
        let mut other: Vec<String> = match config {
            Some(_) => c.nominal_pose_solutions(&p, &r, wn).iter().map(|q| config_words(s.layout, &setup.config(s.layout, q))).collect(),
            None => Vec::new(),
        };
        other.sort();
        other.dedup();
        return Solved::NoNominal((!other.is_empty()).then(|| other.join("; or ")));
    };
    let k = c.compensate_commanded(&p, &r, nominal_q, wc, wn);
    let filtered = match &k.pose {
        Some(parts) => setup.program_pose(&Vector3::from(k.filtered_mm), &parts.filtered),
        None => return Solved::NoNominal(None),
    };
    let in_frame = frame.inverse() * filtered * tool;
    // Configuration data the controller ignores are kept as written.
    let cfg = match config {
        Some(_) => Some(branch::config_of(s.layout, &setup.branch(&k.command_q), &k.command_q)),
        None => pose_config(s.layout, &v),
    };
    let new = pose_values(s.layout, &in_frame, cfg.as_deref(), &v);
    Solved::Done(Box::new(k), new)
}

/// Configuration data as the language names them (`cf1 -1, cf4 0, cf6 1, cfx 2`; `S 2, T 35`).
fn config_words(layout: Layout, cfg: &[i64]) -> String {
    let names: &[&str] = match layout {
        Layout::RapidPose => &["cf1", "cf4", "cf6", "cfx"],
        _ => &["S", "T"],
    };
    names.iter().zip(cfg).map(|(n, v)| format!("{n} {v}")).collect::<Vec<_>>().join(", ")
}

/// Judges a solved site: not reached, a branch change, nothing to move (the calibrated model
/// already puts the tool within the compensation's tolerance at the nominal command), or
/// filtered.
fn judge(site: &Site, k: &Compensated, new: Vec<f64>, (tol_mm, tol_deg): (f64, f64), setup: &Setup) -> (Outcome, Option<Vec<f64>>, Option<Compensated>) {
    if k.status != Status::Reachable {
        return (Outcome::NotReached(k.status), None, Some(k.clone()));
    }
    if let Some(cfg) = site.config() {
        if !branch::agrees(site.layout, &cfg, &k.command_q, setup) {
            return (Outcome::BranchChange, Some(new), Some(k.clone()));
        }
    }
    if k.nominal_error_mm <= tol_mm && k.pose.as_ref().is_none_or(|p| p.nominal_error_deg <= tol_deg) {
        return (Outcome::NothingToMove, Some(new), Some(k.clone()));
    }
    (Outcome::Filtered, Some(new), Some(k.clone()))
}

/// How far the new numbers move the target: its TCP (mm) and its orientation or its largest
/// joint change (degrees).
fn moved(site: &Site, new: &[f64]) -> (Option<f64>, Option<f64>) {
    let old = site.values();
    if site.layout.joints() {
        let a = joints_of(site.layout, &old);
        let b = joints_of(site.layout, new);
        return (None, Some(a.iter().zip(&b).map(|(x, y)| (x - y).abs().to_degrees()).fold(0.0, f64::max)));
    }
    let (a, _) = pose_of(site.layout, &old);
    let (b, _) = pose_of(site.layout, new);
    let d = a.inverse() * b;
    (Some(d.translation.vector.norm()), Some(d.rotation.angle().to_degrees()))
}

/// The edits that write `new` over a site's numbers: each number whose value changes by more
/// than its slot's precision.
fn rewrite(site: &Site, new: &[f64]) -> Vec<(std::ops::Range<usize>, String)> {
    site.nums
        .iter()
        .zip(new)
        .enumerate()
        .filter_map(|(i, (n, v))| {
            let min = decimals(site.layout, i);
            let text = text::write(*v, n, min);
            let same =
                (text.trim_matches('\'').trim_start_matches('B').parse::<f64>().ok().unwrap_or(f64::NAN) - n.value).abs() < 0.5 * 10f64.powi(-(min as i32));
            let binary_same = matches!(n.style, text::Style::Binary(_)) && (v.round() - n.value).abs() < 0.5;
            (!(same || binary_same)).then(|| (n.span.clone(), text))
        })
        .collect()
}

/// Least decimals written in slot `i` of a layout: a micrometre (mm slots), a nanometre's
/// worth of turn at a metre's lever (quaternions, rotation vectors, radians), a micro-degree.
fn decimals(layout: Layout, i: usize) -> usize {
    match layout {
        Layout::RapidPose if i < 3 => 6,
        Layout::RapidPose if i < 7 => 9,
        Layout::RapidPose => 0,
        Layout::RapidJoints | Layout::KrlJoints => 6,
        Layout::KrlPose { .. } if i < 3 => 6,
        Layout::KrlPose { .. } if i < 6 => 7,
        Layout::KrlPose { .. } => 0,
        Layout::UrPose | Layout::UrJoints => 9,
    }
}

/// The configuration data of a site's values, as written (`cf1,cf4,cf6,cfx`, `S,T`).
fn config_text(site: &Site, v: &[f64]) -> String {
    match site.layout {
        Layout::RapidPose => v[7..11].iter().map(|c| format!("{}", c.round() as i64)).collect::<Vec<_>>().join(","),
        Layout::KrlPose { config: true } => format!("S {},T {}", v[6].round() as i64, v[7].round() as i64),
        _ => String::new(),
    }
}

/// A joint layout's values as joint angles, rad.
fn joints_of(layout: Layout, v: &[f64]) -> Vec<f64> {
    match layout {
        Layout::UrJoints => v.to_vec(),
        _ => v.iter().map(|d| d.to_radians()).collect(),
    }
}

/// Joint angles (rad) as a joint layout's values.
fn joint_values(layout: Layout, q: &[f64]) -> Vec<f64> {
    match layout {
        Layout::UrJoints => q.to_vec(),
        _ => q.iter().map(|r| r.to_degrees()).collect(),
    }
}

/// The configuration data a pose layout's values state, if any.
fn pose_config(layout: Layout, v: &[f64]) -> Option<Vec<i64>> {
    match layout {
        Layout::RapidPose | Layout::KrlPose { config: true } => pose_of(layout, v).1,
        _ => None,
    }
}

/// A pose layout's values as a pose (mm) and its configuration data (if it states them).
fn pose_of(layout: Layout, v: &[f64]) -> (Isometry3<f64>, Option<Vec<i64>>) {
    let t = Translation3::new(v[0], v[1], v[2]);
    match layout {
        Layout::RapidPose => {
            let q = UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(v[3], v[4], v[5], v[6]));
            (Isometry3::from_parts(t, q), Some(v[7..11].iter().map(|c| c.round() as i64).collect()))
        }
        Layout::KrlPose { config } => {
            let r = crate::measurement::Euler::ZYX.matrix([v[3], v[4], v[5]].map(f64::to_radians));
            let cfg = config.then(|| vec![v[6].round() as i64, v[7].round() as i64]);
            (Isometry3::from_parts(t, UnitQuaternion::from_matrix(&r)), cfg)
        }
        Layout::UrPose => {
            let t = Translation3::new(v[0] * 1000.0, v[1] * 1000.0, v[2] * 1000.0);
            (Isometry3::from_parts(t, UnitQuaternion::from_scaled_axis(Vector3::new(v[3], v[4], v[5]))), None)
        }
        _ => unreachable!("a joint layout has no pose"),
    }
}

/// A pose (mm) and configuration data as a pose layout's values, each angle written nearest
/// the `old` one (a quaternion's sign, an Euler angle's turn, a rotation vector's).
fn pose_values(layout: Layout, pose: &Isometry3<f64>, config: Option<&[i64]>, old: &[f64]) -> Vec<f64> {
    let p = pose.translation.vector;
    let mut out = vec![p.x, p.y, p.z];
    match layout {
        Layout::RapidPose => {
            let q = pose.rotation.quaternion();
            let s = if q.w * old[3] + q.i * old[4] + q.j * old[5] + q.k * old[6] < 0.0 { -1.0 } else { 1.0 };
            out.extend([s * q.w, s * q.i, s * q.j, s * q.k]);
            out.extend(config.unwrap_or(&[0, 0, 0, 0]).iter().map(|c| *c as f64));
        }
        Layout::KrlPose { config: stated } => {
            let m: Matrix3<f64> = pose.rotation.to_rotation_matrix().into_inner();
            let abc = crate::measurement::Euler::ZYX.angles(&m).map(f64::to_degrees);
            out.extend(abc.iter().zip(&old[3..6]).map(|(a, o)| a + 360.0 * ((o - a) / 360.0).round()));
            if stated {
                out.extend(config.unwrap_or(&[0, 0]).iter().map(|c| *c as f64));
            }
        }
        Layout::UrPose => {
            out.iter_mut().for_each(|c| *c /= 1000.0);
            let v = Rotation3::from(pose.rotation).scaled_axis();
            let o = Vector3::new(old[3], old[4], old[5]);
            // The same rotation as the vector turned the other way round by 2π - |v|.
            let alt = if v.norm() > 1e-9 { v - v.normalize() * std::f64::consts::TAU } else { v };
            let v = if (alt - o).norm() < (v - o).norm() { alt } else { v };
            out.extend([v.x, v.y, v.z]);
        }
        _ => unreachable!("a joint layout has no pose"),
    }
    out
}
