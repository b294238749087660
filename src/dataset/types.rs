//! The dataset's data model: rows (joint angles, the reading, time, temperature, standard
//! deviations, split, block), the load options and the readers' limits.

pub use crate::measurement::length::MAX_L_MM;
use crate::measurement::{Euler, FeatureKind, Measurement};

/// File name of the CSV inside a dataset folder.
pub const DATASET_FILE: &str = "dataset.csv";

/// Most joint columns a dataset may have (`q1..q32`); beyond is taken for a mislabelled file.
pub const MAX_JOINTS: usize = 32;

/// Largest plausible |joint angle| in degrees; anything beyond is rejected.
pub const MAX_ABS_JOINT_DEG: f64 = 720.0;

/// Radians heuristic: minimum number of rows before it is applied.
pub const RADIANS_MIN_ROWS: usize = 10;

/// Radians heuristic: every |q| at most this (2π plus 5 %).
pub const RADIANS_MAX_ABS: f64 = 2.0 * std::f64::consts::PI * 1.05;

/// Radians heuristic for a pose's angles (rx, ry, rz): every |angle| at most this (π plus 5 %).
pub const POSE_RADIANS_MAX_ABS: f64 = std::f64::consts::PI * 1.05;

/// Radians heuristic: at least one joint must span more than this (same unit as the file).
pub const RADIANS_MIN_SPAN: f64 = 0.1;

/// Angles in degrees that look like radians: at least [`RADIANS_MIN_ROWS`] rows (`rows`, each
/// its angles in degrees), every |angle| at most `max_abs` (radians' range: [`RADIANS_MAX_ABS`]
/// for joints, [`POSE_RADIANS_MAX_ABS`] for a pose's angles) and one column spanning more than
/// [`RADIANS_MIN_SPAN`]. What the data's, a pose list's and a target file's readers all refuse:
/// `Some((largest |angle|, widest column (0-based), its span))`.
pub fn looks_like_radians(rows: &[Vec<f64>], max_abs: f64) -> Option<(f64, usize, f64)> {
    let n = rows.first().map_or(0, Vec::len);
    if rows.len() < RADIANS_MIN_ROWS || n == 0 {
        return None;
    }
    let largest = rows.iter().flatten().fold(0.0_f64, |m, q| m.max(q.abs()));
    let span = |j: usize| {
        let (lo, hi) = rows.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), r| (lo.min(r[j]), hi.max(r[j])));
        hi - lo
    };
    let (widest, spans) = (0..n).map(|j| (j, span(j))).fold((0, 0.0), |best, (j, s)| if s > best.1 { (j, s) } else { best });
    (largest <= max_abs && spans > RADIANS_MIN_SPAN).then_some((largest, widest, spans))
}

/// Metres heuristic: every `L` below this is taken as metres.
pub const METRES_MAX_L: f64 = 5.0;

/// Lowest possible temperature, °C (absolute zero).
pub const MIN_TEMP_C: f64 = -273.15;

/// Highest plausible temperature, °C (no robot cell runs hotter).
pub const MAX_TEMP_C: f64 = 1000.0;

/// Largest plausible time, s from the start of acquisition (about 3.2 years). Absolute clock
/// times (e.g. Unix seconds) are beyond it: subtract the first time.
pub const MAX_T_S: f64 = 1e8;

/// Unit of the joint angle columns in a file (`--angles`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
pub enum AngleUnit {
    /// Degrees, unless the values look like radians (then an error says so).
    #[default]
    Auto,
    /// Degrees.
    Deg,
    /// Radians (converted to degrees on load).
    Rad,
}

impl AngleUnit {
    /// The unit's name as `--angles` takes it: `auto`, `deg` or `rad`.
    pub fn name(self) -> &'static str {
        match self {
            AngleUnit::Auto => "auto",
            AngleUnit::Deg => "deg",
            AngleUnit::Rad => "rad",
        }
    }
}

impl std::str::FromStr for AngleUnit {
    type Err = String;
    /// `auto`, `deg` (also `degrees`) or `rad` (also `radians`), case-insensitive.
    fn from_str(s: &str) -> std::result::Result<Self, String> {
        match s.trim().to_ascii_lowercase().as_str() {
            "auto" => Ok(AngleUnit::Auto),
            "deg" | "degree" | "degrees" => Ok(AngleUnit::Deg),
            "rad" | "radian" | "radians" => Ok(AngleUnit::Rad),
            _ => Err(format!("unknown angle unit '{s}' (expected auto, deg or rad)")),
        }
    }
}

/// How [`Dataset::load_with`] reads a file.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ReadOptions {
    /// Unit of `q1..qN`.
    pub angles: AngleUnit,
    /// Whether the `L` column must be present (it always must be for calibration).
    pub require_length: bool,
    /// The instrument to read, when the header holds more than its columns (`point` reads only
    /// `x, y, z` of a file that also has a pose's angles); `None` takes what the header holds.
    pub measurement: Option<Measurement>,
    /// The convention of a pose's Euler angles in the file; a loaded row holds them as
    /// intrinsic X-Y-Z.
    pub euler: Euler,
}

impl Default for ReadOptions {
    /// Today's behaviour of [`Dataset::load`]: [`AngleUnit::Auto`], `L` required.
    fn default() -> Self {
        ReadOptions { angles: AngleUnit::Auto, require_length: true, measurement: None, euler: Euler::XYZ }
    }
}

impl ReadOptions {
    /// Poses (`q1..qN`) with an optional `L` column, e.g. for prediction.
    pub fn poses() -> Self {
        ReadOptions { require_length: false, ..Default::default() }
    }
}

/// Which subset a row belongs to.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Split {
    /// A training row (a truth pose without a split is one).
    #[default]
    Train,
    /// A held-out test row.
    Test,
}

impl Split {
    /// The lowercase word used in files (`train` / `test`).
    pub fn as_str(self) -> &'static str {
        match self {
            Split::Train => "train",
            Split::Test => "test",
        }
    }
}

/// One static configuration and its measurement.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Row {
    /// Joint angles `q1..qN`, degrees, controller convention; every row of a dataset has the
    /// same N.
    pub q_deg: Vec<f64>,
    /// The instrument's reading, mm, in its dataset columns' order (`L` for a draw-wire;
    /// `x, y, z` for a tracker; `x, y, z, rx, ry, rz` for a pose, its angles in degrees,
    /// intrinsic X-Y-Z: see [`Measurement`]); empty when the file has none (poses only, loaded
    /// with `require_length: false`). Every row of a dataset has the same kind.
    pub reading_mm: Vec<f64>,
    /// Seconds from acquisition start.
    pub t_s: Option<f64>,
    /// Temperature, °C.
    pub temp_c: Option<f64>,
    /// The subset the file assigns the row to (`split` column); `None` without the column.
    pub split: Option<Split>,
    /// The instrument's own standard deviation of each position coordinate (`sx, sy, sz`, mm)
    /// where the file gives it: a tracker's per-row uncertainty, which the fit weights by
    /// (see `calib::weighting`). `None` on rows without it and for a draw-wire.
    pub std_mm: Option<[f64; 3]>,
    /// The block the user declared the row in (`block` column: any label; rows of one block share
    /// an error, see [`blocks`](super::blocks)). `None` without the column.
    pub block: Option<String>,
    /// The payload mounted when the row was measured, kg (`payload_kg` column): a load-driven
    /// effect reads the row's torques under it (at the centre of mass the calibration states).
    /// `None` without the column: the calibration's payload for every row.
    pub payload_kg: Option<f64>,
    /// Where the instrument stood when the row was measured (`station` column: any label; a
    /// tracker re-stationed between sessions stands at another). Every station has its own
    /// placement in a calibration, the arm is shared. `None` without the column.
    pub station: Option<String>,
    /// How the target sat on the flange when the row was measured (`mount` column: any label;
    /// a probe re-mounted between sessions sits otherwise). Every mount has its own target (and
    /// probe orientation) in a calibration. `None` without the column.
    pub mount: Option<String>,
    /// The feature of an artifact the row stands at: the socket the ball on the flange was
    /// seated in (`socket` column; the row reads nothing, see [`Measurement::Socket`]) or the
    /// face a probe touched or an indicator read (`plane` column). The artifact's placement is
    /// the row's [`Self::station`] (a `placement` column). `None` without such a column.
    pub feature: Option<Feature>,
}

/// A feature of an artifact a row names ([`Row::feature`]): its kind and its label (any text).
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
pub struct Feature {
    /// A socket or a face.
    pub kind: FeatureKind,
    /// Its label on the artifact ("A", "top").
    pub label: String,
}

impl Feature {
    /// A socket labelled `label`.
    pub fn socket(label: impl Into<String>) -> Feature {
        Feature { kind: FeatureKind::Socket, label: label.into() }
    }
    /// A face labelled `label`.
    pub fn plane(label: impl Into<String>) -> Feature {
        Feature { kind: FeatureKind::Plane, label: label.into() }
    }
}

impl Row {
    /// The cable length (mm) of a draw-wire reading; `None` for no reading or another instrument's.
    pub fn l_mm(&self) -> Option<f64> {
        match self.reading_mm[..] {
            [l] => Some(l),
            _ => None,
        }
    }

    /// The reading as the model reads its values (mm; see [`Measurement::dim`]): the columns
    /// themselves, or a pose's origin and axes. `None` without a reading.
    pub fn values_mm(&self) -> Option<Vec<f64>> {
        Some(self.measurement()?.values_of_file(&self.reading_mm))
    }

    /// What read the row: the instrument of its reading columns, or the one at the artifact's
    /// feature it names (a ball in a socket, a probe or an indicator on a face). `None` for a
    /// row of joint angles only.
    pub fn measurement(&self) -> Option<Measurement> {
        match &self.feature {
            Some(f) => Measurement::of_feature(f.kind, self.reading_mm.len()),
            None => Measurement::of_file_dim(self.reading_mm.len()),
        }
    }

    /// The label of the socket the row names, if it names one.
    pub fn socket(&self) -> Option<&str> {
        self.feature.as_ref().filter(|f| f.kind == FeatureKind::Socket).map(|f| f.label.as_str())
    }
}

/// One column of a dataset held in memory (see [`Dataset::from_columns`]).
#[derive(Clone, Debug)]
pub enum ColumnValues {
    /// A numeric column.
    Numbers(Vec<f64>),
    /// A text column (a `split` or `block` label).
    Texts(Vec<String>),
}

impl ColumnValues {
    /// Number of values.
    pub fn len(&self) -> usize {
        match self {
            ColumnValues::Numbers(v) => v.len(),
            ColumnValues::Texts(v) => v.len(),
        }
    }
    /// Whether the column holds no value.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

/// A dataset and where it came from (a path, or a label for in-memory sources).
#[derive(Clone, Debug, Default)]
pub struct Dataset {
    /// The rows, in file (acquisition) order.
    pub rows: Vec<Row>,
    /// Where the rows came from: the path read, or a label for an in-memory source (messages name
    /// the data by it).
    pub source: String,
}
