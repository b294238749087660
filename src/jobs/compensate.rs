//! `twincal compensate`: the joint commands that make the calibrated arm reach a program's
//! targets ([`crate::compensate`]), written as a CSV whole or not at all.

use crate::calib::pipeline::CalibResult;
use crate::compensate::{commands_csv, nominal_x, read_targets, Compensated, Compensator, Status};
use crate::error::{Error, Result};
use crate::output::{check_outputs, OutputSet};
use serde::{Deserialize, Serialize};
use std::path::PathBuf;

/// A compensation as `twincal compensate` runs it; Python's `twincal.compensate` arguments.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "clap", derive(clap::Args))]
#[serde(deny_unknown_fields)]
pub struct CompensateJob {
    /// A result.json written by `calibrate` (or diagnosed.json by `diagnose`).
    #[cfg_attr(feature = "clap", arg(long))]
    pub model: PathBuf,
    /// The program's targets, CSV: columns x, y, z (mm, the robot's base frame), with rx, ry, rz
    /// (degrees, the tool's orientation, `--euler`) for poses, or q1..qN (degrees, joint targets
    /// taught on the nominal model).
    #[cfg_attr(feature = "clap", arg(long, required_unless_present = "program", conflicts_with = "program"))]
    #[serde(default)]
    pub targets: Option<PathBuf>,
    /// A robot program to filter, its targets compensated in place: ABB RAPID (.mod, .prg,
    /// .sys), KUKA KRL (.src with its .dat: give both, the option repeated), URScript (.script).
    /// The filtered copies go to `--filtered-dir`, a line per target to `--report`.
    #[cfg_attr(feature = "clap", arg(long))]
    #[serde(default)]
    pub program: Vec<PathBuf>,
    /// Files that declare frames the program moves with but does not declare itself: a RAPID
    /// module with its tooldata / wobjdata, KUKA's $config.dat (TOOL_DATA, BASE_DATA), a
    /// URScript with the installation's set_tcp (repeat the option for several).
    #[cfg_attr(feature = "clap", arg(long, requires = "program"))]
    #[serde(default)]
    pub frames: Vec<PathBuf>,
    /// The arm's URDF (or irb120), whose links `base` and `tool0` are the controller's base and
    /// flange frames (default: the model's base and flange frames are the controller's).
    #[cfg_attr(feature = "clap", arg(long, requires = "program"))]
    #[serde(default)]
    pub robot: Option<crate::robot::RobotChoice>,
    /// Compensate the program's joint targets too (MoveAbsJ, E6AXIS, movej([...])): each is
    /// moved so that the calibrated arm puts the tool where the nominal one did.
    #[cfg_attr(feature = "clap", arg(long, requires = "program"))]
    #[serde(default)]
    pub joint_targets: bool,
    /// Targets to leave as written, by name (taught on the robot; comma-separated).
    #[cfg_attr(feature = "clap", arg(long, requires = "program", value_delimiter = ','))]
    #[serde(default)]
    pub leave: Vec<String>,
    /// The arm's joints when the program starts, degrees (comma-separated): a URScript pose (and
    /// a KRL one without S and T) is solved nearest the arm's previous position (default: the
    /// middle of each joint's range).
    #[cfg_attr(feature = "clap", arg(long, requires = "program", value_delimiter = ',', allow_negative_numbers = true, allow_hyphen_values = true))]
    #[serde(default)]
    pub start_joints_deg: Option<Vec<f64>>,
    /// Where the filtered copies of the program's files are written (their own names).
    #[cfg_attr(feature = "clap", arg(long, default_value = "filtered"))]
    #[serde(default = "default_filtered_dir")]
    pub filtered_dir: PathBuf,
    /// The filter's report: a line per target (its outcome, configuration data before and
    /// after, the predicted residual, the uncompensated error, how far it moved).
    #[cfg_attr(feature = "clap", arg(long, default_value = "filter_report.csv"))]
    #[serde(default = "default_report")]
    pub report: PathBuf,
    /// The payload the program runs with, kg (default: the one the calibration stated); it
    /// loads the joints of a model with compliance.
    #[cfg_attr(feature = "clap", arg(long, allow_negative_numbers = true))]
    #[serde(default)]
    pub payload_kg: Option<f64>,
    /// Its centre of mass in the flange frame, mm (x,y,z).
    #[cfg_attr(feature = "clap", arg(long, allow_negative_numbers = true, value_delimiter = ',', allow_hyphen_values = true, value_name = "X,Y,Z"))]
    #[serde(default)]
    pub payload_com_mm: Option<Vec<f64>>,
    /// Model residual at which a target counts as reached, mm.
    #[cfg_attr(feature = "clap", arg(long, default_value_t = 0.001))]
    #[serde(default = "default_tol")]
    pub tol_mm: f64,
    /// Orientation residual at which a pose target counts as reached, degrees.
    #[cfg_attr(feature = "clap", arg(long, default_value_t = 0.001))]
    #[serde(default = "default_tol")]
    pub tol_deg: f64,
    /// The Euler convention of the targets' (and the commands') rx, ry, rz: capitals for
    /// rotations about the moving axes (intrinsic; XYZ is R = Rx(rx)·Ry(ry)·Rz(rz)), lower case
    /// for the fixed axes (extrinsic; xyz is R = Rz(rz)·Ry(ry)·Rx(rx)).
    #[cfg_attr(feature = "clap", arg(long, default_value_t = crate::measurement::Euler::default()))]
    #[serde(default)]
    pub euler: crate::measurement::Euler,
    /// The commands: per target its point, the compensated joint angles, the status, the
    /// predicted residual and uncompensated error, the filtered Cartesian target and the nominal
    /// command.
    #[cfg_attr(feature = "clap", arg(long, default_value = "commands.csv"))]
    #[serde(default = "default_out")]
    pub out: PathBuf,
}

fn default_tol() -> f64 {
    0.001
}
impl Default for CompensateJob {
    /// Every option at its default (the model and the targets or program still to be given).
    fn default() -> Self {
        CompensateJob {
            model: PathBuf::new(),
            targets: None,
            program: Vec::new(),
            frames: Vec::new(),
            robot: None,
            joint_targets: false,
            leave: Vec::new(),
            start_joints_deg: None,
            filtered_dir: default_filtered_dir(),
            report: default_report(),
            payload_kg: None,
            payload_com_mm: None,
            tol_mm: default_tol(),
            tol_deg: default_tol(),
            euler: crate::measurement::Euler::default(),
            out: default_out(),
        }
    }
}

/// A payload: mass kg, centre of mass mm (flange frame).
type Payload = (f64, [f64; 3]);

fn default_filtered_dir() -> PathBuf {
    PathBuf::from("filtered")
}
fn default_report() -> PathBuf {
    PathBuf::from("filter_report.csv")
}
fn default_out() -> PathBuf {
    PathBuf::from("commands.csv")
}

/// What a compensation did.
#[derive(Clone, Debug, Serialize)]
pub struct CompensateSummary {
    /// Per target, in file order.
    pub targets: Vec<Compensated>,
    /// Targets per status.
    pub reachable: usize,
    /// Targets not reached (limit, singular, unreachable, invalid).
    pub not_reached: usize,
    /// The payload the commands were computed for (mass kg, centre of mass mm), when the model
    /// has load-driven effects.
    pub payload: Option<(f64, [f64; 3])>,
    /// What the user should know (a payload that changes nothing, targets not reached).
    pub warnings: Vec<String>,
    /// A filtered program: per target what became of it, and the run-time motions left.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub program: Option<crate::controller::filter::Filtered>,
}

impl CompensateJob {
    /// Reads the model and the targets (or the program), compensates, writes the commands (or
    /// the filtered program and its report).
    pub fn run(&self) -> Result<CompensateSummary> {
        let Some(targets_path) = &self.targets else { return self.run_program() };
        if !self.program.is_empty() {
            return Err(Error::Invalid("give --targets or --program, not both".into()));
        }
        check_outputs(&[("--model", self.model.clone()), ("--targets", targets_path.clone())], &[("--out", self.out.as_path())])?;
        let r = CalibResult::load(&self.model)?;
        let euler = self.euler;
        let targets = read_targets(targets_path, r.model.chain.n_joints, euler)?;
        // Taught joint targets lie inside the arm's limits (a radian file read as degrees does not).
        let limits = r.model.joint_limits();
        for (i, t) in targets.iter().enumerate() {
            if let crate::compensate::Target::Joints(q) = t {
                if let Some((j, v)) = q.iter().enumerate().find(|(j, v)| !(limits[*j].0 - 1e-9..=limits[*j].1 + 1e-9).contains(*v)) {
                    return Err(Error::data(
                        targets_path.display(),
                        format!(
                            "target {}: q{} = {} deg is outside the joint's limits [{:.1}, {:.1}] deg",
                            i + 1,
                            j + 1,
                            crate::error::shown(v.to_degrees()),
                            limits[j].0.to_degrees(),
                            limits[j].1.to_degrees()
                        ),
                    ));
                }
            }
        }
        let mut warnings = Vec::new();
        let (torque, payload) = self.loads(&r, &mut warnings)?;
        let x_nom = nominal_x(&r);
        let c = Compensator::new(&r, &x_nom, torque, self.tol_mm, self.tol_deg)?;
        let solved = c.compensate(&targets);
        let reachable = solved.iter().filter(|s| s.status == Status::Reachable).count();
        if reachable < solved.len() {
            warnings.push(format!("{} of {} targets not reached (see the status column)", solved.len() - reachable, solved.len()));
        }
        if solved.is_empty() {
            return Err(Error::Invalid("no targets".into()));
        }
        let mut outputs = OutputSet::new();
        outputs.write(&self.out, commands_csv(&solved, euler).as_bytes())?;
        outputs.commit()?;
        Ok(CompensateSummary { reachable, not_reached: solved.len() - reachable, targets: solved, payload, warnings, program: None })
    }

    /// The joints' loads the commands are computed under: the result's torque model with the
    /// stated payload; and that payload (kg, mm) where the model has load-driven effects.
    fn loads(&self, r: &CalibResult, warnings: &mut Vec<String>) -> Result<(Option<crate::calib::effects::inputs::TorqueModel>, Option<Payload>)> {
        let loads = crate::requests::Loads { payload_kg: self.payload_kg, payload_com_mm: self.payload_com_mm.clone(), ..Default::default() }.resolve()?.joints;
        if let Some(kind) = r.model.measurement.feature() {
            warnings.push(format!(
                "the model was calibrated from an artifact ({}s), which never sees the base frame: targets in the base frame are reached in the nominal one (the arm's mounting error is left); register the base frame, or give targets in a frame touched with the same tool (user-frame)",
                kind.column()
            ));
        }
        let mut torque = r.torque_model.clone();
        match (&mut torque, &loads.payload) {
            (Some(tm), Some(p)) => tm.payload = Some((p.mass_kg, p.com_mm.map(crate::units::to_m))),
            (None, Some(_)) => warnings.push("the model has no load-driven effect (no compliance block): --payload-kg changes nothing".into()),
            _ => {}
        }
        let payload = torque.as_ref().map(|t| t.payload.map_or((0.0, [0.0; 3]), |(m, c)| (m, c.map(crate::units::to_mm))));
        Ok((torque, payload))
    }

    /// Filters `--program`: reads its files (and `--frames`), writes the filtered copies and the
    /// report, all or none.
    fn run_program(&self) -> Result<CompensateSummary> {
        use crate::controller::{filter, Language, ProgramFile};
        let Some(first) = self.program.first() else { return Err(Error::Invalid("give --targets (a CSV) or --program (a robot program)".into())) };
        let lang = Language::of_file(first)?;
        if let Some(p) = self.program.iter().find(|p| Language::of_file(p).ok() != Some(lang)) {
            return Err(Error::data(p.display(), format!("a {} program's files are {}: this one is not", lang.name(), lang.file_names("*").join(", "))));
        }
        let outputs: Vec<PathBuf> = self.program.iter().map(|p| self.filtered_dir.join(p.file_name().unwrap_or_default())).collect();
        let mut inputs: Vec<(&str, PathBuf)> = vec![("--model", self.model.clone())];
        inputs.extend(self.program.iter().map(|p| ("--program", p.clone())));
        inputs.extend(self.frames.iter().map(|p| ("--frames", p.clone())));
        inputs.extend(self.robot.as_ref().and_then(crate::jobs::files::named_robot_input));
        let mut named: Vec<(&str, &std::path::Path)> = outputs.iter().map(|p| ("--filtered-dir", p.as_path())).collect();
        named.push(("--report", self.report.as_path()));
        check_outputs(&inputs, &named)?;
        let read = |p: &PathBuf| -> Result<(ProgramFile, Encoding)> {
            let (text, encoding) = Encoding::read(p)?;
            Ok((ProgramFile { name: p.file_name().unwrap_or_default().to_string_lossy().into_owned(), text }, encoding))
        };
        let (files, encodings): (Vec<ProgramFile>, Vec<Encoding>) = self.program.iter().map(read).collect::<Result<Vec<_>>>()?.into_iter().unzip();
        let frames: Vec<ProgramFile> = self.frames.iter().map(|p| read(p).map(|(f, _)| f)).collect::<Result<_>>()?;
        let r = CalibResult::load(&self.model)?;
        let robot = self.robot.as_ref().map(crate::robot::RobotChoice::load).transpose()?;
        let mut warnings = Vec::new();
        if robot.is_none() {
            warnings.push(
                "no --robot: the model's base and flange frames are taken as the controller's (give the arm's URDF, or irb120, to read its base and tool0)"
                    .into(),
            );
        }
        for (p, _) in self.program.iter().zip(&encodings).filter(|(_, e)| **e == Encoding::Latin1) {
            warnings.push(format!("{}: not UTF-8, read and written as ISO-8859-1 (Latin-1), as older controllers save their programs", p.display()));
        }
        let start_q = match &self.start_joints_deg {
            Some(q) if q.len() != r.model.chain.n_joints || q.iter().any(|v| !v.is_finite()) => {
                return Err(Error::Invalid(format!("--start-joints-deg: {} finite angles, one per joint, got {q:?}", r.model.chain.n_joints)))
            }
            q => q.as_ref().map(|q| q.iter().map(|d| d.to_radians()).collect()),
        };
        let (torque, payload) = self.loads(&r, &mut warnings)?;
        let x_nom = nominal_x(&r);
        let c = Compensator::new(&r, &x_nom, torque, self.tol_mm, self.tol_deg)?;
        let setup = filter::Setup::new(&r, &x_nom, robot.as_ref());
        let options = filter::FilterOptions { joint_targets: self.joint_targets, leave: self.leave.clone(), start_q };
        let f = filter::filter_program(&c, &setup, lang, &files, &frames, &options)?;
        let mut out = OutputSet::new();
        for ((file, path), encoding) in f.files.iter().zip(&outputs).zip(&encodings) {
            out.write(path, &encoding.bytes(&file.text, path)?)?;
        }
        out.write(&self.report, filter::report_csv(&f).as_bytes())?;
        out.commit()?;
        let solved: Vec<Compensated> = f.targets.iter().filter_map(|t| t.compensated.clone()).collect();
        let reachable = solved.iter().filter(|s| s.status == Status::Reachable).count();
        let left = f.targets.iter().filter(|t| !matches!(t.outcome, filter::Outcome::Filtered | filter::Outcome::NothingToMove)).count();
        if left > 0 {
            warnings.push(format!("{left} of {} targets left as written (the outcome and reason columns of {})", f.targets.len(), self.report.display()));
            warnings.extend(filter::left_lines(&f));
        }
        for n in &f.run_time {
            warnings.push(format!("{}:{}:{}: {} left as written: {}", n.file, n.line, n.column, n.target, n.reason));
        }
        if f.targets.is_empty() && f.run_time.is_empty() {
            warnings.push(
                "the program holds no motion target twincal reads (robtarget / jointtarget data or Move instructions, KRL POS / E6POS / AXIS, URScript movel / movej / movep / movec): written as it is".into(),
            );
        }
        Ok(CompensateSummary { reachable, not_reached: solved.len() - reachable, targets: solved, payload, warnings, program: Some(f) })
    }
}

/// How a program file's bytes hold its text: UTF-8, or ISO-8859-1 (each byte its character),
/// as RAPID and KRL files of older controllers are saved. A file is read and written back in its
/// own.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Encoding {
    Utf8,
    Latin1,
}

impl Encoding {
    /// The text of program file `p` and its encoding; a UTF-16 or binary file (a control byte
    /// other than tab, line feed, form feed and carriage return: an archive, a binary backup) is
    /// refused by name.
    fn read(p: &std::path::Path) -> Result<(String, Encoding)> {
        let bytes = std::fs::read(p).map_err(|e| Error::data(p.display(), format!("cannot read it: {e}")))?;
        if bytes.starts_with(&[0xff, 0xfe]) || bytes.starts_with(&[0xfe, 0xff]) {
            return Err(Error::data(p.display(), "a UTF-16 file: save the program as UTF-8 or ISO-8859-1"));
        }
        if let Some(k) = bytes.iter().position(|&b| (b < 0x20 && !matches!(b, b'\t' | b'\n' | 0x0c | b'\r')) || b == 0x7f) {
            return Err(Error::data(p.display(), format!("not a program's text: control byte 0x{:02x} at byte {k}", bytes[k])));
        }
        Ok(match String::from_utf8(bytes) {
            Ok(text) => (text, Encoding::Utf8),
            Err(e) => (e.into_bytes().iter().map(|&b| char::from(b)).collect(), Encoding::Latin1),
        })
    }

    /// `text` as bytes of this encoding, for the file `path`; a character ISO-8859-1 has no byte
    /// for is refused, not replaced.
    fn bytes(self, text: &str, path: &std::path::Path) -> Result<Vec<u8>> {
        match self {
            Encoding::Utf8 => Ok(text.as_bytes().to_vec()),
            Encoding::Latin1 => text
                .chars()
                .map(|c| u8::try_from(u32::from(c)).map_err(|_| Error::data(path.display(), format!("'{c}' has no ISO-8859-1 byte, the file's encoding"))))
                .collect(),
        }
    }
}
