//! Calibration datasets: one row per static robot configuration, its joint angles `q1..qN`
//! (degrees, controller convention; N is whatever the arm has) and the instrument's reading in
//! millimetres (the draw-wire cable length `L`, or a laser tracker's target position `x, y, z`:
//! the columns of a [`Measurement`]), with optional time, temperature and train/test split.
//!
//! # File formats
//!
//! [`Dataset::load`] reads
//! * a dataset folder (`DIR/dataset.csv`, see [`DATASET_FILE`]),
//! * a `.csv` file,
//! * a spreadsheet (`.xlsx`, also `.xlsm`/`.xlsb`/`.xls`/`.ods`): the first sheet, or the sheet
//!   named after a `#`, as in `pool.xlsx#Sheet1`.
//!
//! The header row must hold `q1`..`qN` (N ≥ 1 joints, numbered without gaps, at most
//! [`MAX_JOINTS`]) and the reading columns of one instrument (`L`, or `x`, `y`, `z`; a header
//! with both is refused); `t` (s), `temp` (°C) and `split` (`train`/`test`) are optional, and so
//! are a tracker's per-row standard deviations `sx, sy, sz` (mm, all three or none; empty on
//! rows that lack them). Names are matched case-insensitively with surrounding whitespace ignored; column
//! order is free and other columns are ignored. Blank rows are skipped.
//!
//! CSV files may come from spreadsheet exports: the delimiter (`,`, `;` or tab) is detected from
//! the header line, and with `;` or tab a decimal comma (`1,5`) is accepted. Lines starting with
//! `#` are comments. A spreadsheet extension on a file that is not a spreadsheet (e.g. CSV text
//! saved as `.xlsx`) is reported as such. Spreadsheets are read cell by cell (xlsx, xlsb), never
//! as a dense range, so a stray cell far away (e.g. at `XFD1048576`) costs nothing; cells outside
//! the header's columns are ignored.
//!
//! # Load options
//!
//! [`Dataset::load_with`] takes [`LoadOptions`]: the joint angle unit ([`AngleUnit::Auto`] applies
//! the radians heuristic below, [`AngleUnit::Deg`] skips it, [`AngleUnit::Rad`] converts the
//! angles to degrees on load) and whether `L` is required (`require_length: false` accepts a
//! file of poses `q1..qN` only, e.g. for prediction; rows then have `l_mm == None`). A dataset
//! used for calibration must have `L` ([`Dataset::require_length`]). [`Dataset::load`] is
//! `load_with` with the defaults (`Auto`, `L` required).
//!
//! # Validation
//!
//! Every problem is reported as [`Error::Data`] naming the file, the line (spreadsheet line number:
//! the header is line 1, so the first data row is usually line 2) and the column:
//! missing or duplicated columns, empty/non-numeric/NaN/infinite cells, malformed CSV rows, unknown
//! split values, a split column filled on some rows only, and values outside these plausibility
//! bounds: `0 < L <= `[`MAX_L_MM`] (a tracker's coordinates: `|x|, |y|, |z| <= 100 m`), `|q| <= `[`MAX_ABS_JOINT_DEG`],
//! `0 <= t <= `[`MAX_T_S`] and non-decreasing, [`MIN_TEMP_C`]` <= temp <= `[`MAX_TEMP_C`]; and two
//! unit mistakes detected by heuristics:
//!
//! * **radians**: with at least [`RADIANS_MIN_ROWS`] rows, if every joint angle satisfies
//!   `|q| <= 2π·1.05` *and* at least one joint spans more than [`RADIANS_MIN_SPAN`] (max − min),
//!   the joints are taken to be in radians. Degree data essentially never stays inside ±6.6° on all
//!   joints while moving; the span condition keeps a repeated home pose (all zeros, or a fixed
//!   pose near zero) from being flagged. The span threshold is deliberately low (0.1): the real
//!   HSR-RobotCali pool, converted to radians, has joint spans of 0.0001–0.62 rad. A genuine
//!   degree dataset over a narrow range (all joints within ±6.6°) trips it: load it with
//!   [`AngleUnit::Deg`] (`--angles deg`).
//! * **metres**: if every `L < 5` the lengths are taken to be metres (no draw-wire setup measures
//!   under 5 mm everywhere); likewise a tracker's points when every coordinate is within ±5.

pub mod blocks;
mod csv_io;
pub mod logging;
pub mod split;
pub mod truth;
mod xlsx;

use crate::error::{Error, Result};
use crate::measurement::{Euler, Measurement};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

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
/// Radians heuristic: at least one joint must span more than this (same unit as the file).
pub const RADIANS_MIN_SPAN: f64 = 0.1;
/// Metres heuristic: every `L` below this is taken as metres.
pub const METRES_MAX_L: f64 = 5.0;
pub use crate::measurement::length::MAX_L_MM;
/// Lowest possible temperature, °C (absolute zero).
pub const MIN_TEMP_C: f64 = -273.15;
/// Highest plausible temperature, °C (no robot cell runs hotter).
pub const MAX_TEMP_C: f64 = 1000.0;
/// Largest plausible time, s from the start of acquisition (about 3.2 years). Absolute clock
/// times (e.g. Unix seconds) are beyond it: subtract the first time.
pub const MAX_T_S: f64 = 1e8;

/// Unit of the joint angle columns in a file.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum AngleUnit {
    /// Degrees, with the radians heuristic of the module docs as a guard.
    #[default]
    Auto,
    /// Degrees, no heuristic.
    Deg,
    /// Radians, converted to degrees on load.
    Rad,
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
pub struct LoadOptions {
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

impl Default for LoadOptions {
    /// Today's behaviour of [`Dataset::load`]: [`AngleUnit::Auto`], `L` required.
    fn default() -> Self {
        LoadOptions { angles: AngleUnit::Auto, require_length: true, measurement: None, euler: Euler::XYZ }
    }
}

impl LoadOptions {
    /// Poses (`q1..qN`) with an optional `L` column, e.g. for prediction.
    pub fn poses() -> Self {
        LoadOptions { require_length: false, ..Default::default() }
    }
}

/// Which subset a row belongs to.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Split {
    Train,
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
#[derive(Clone, Debug, PartialEq)]
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
    pub split: Option<Split>,
    /// The instrument's own standard deviation of each position coordinate (`sx, sy, sz`, mm)
    /// where the file gives it: a tracker's per-row uncertainty, which the fit weights by
    /// (see `calib::weighting`). `None` on rows without it and for a draw-wire.
    pub std_mm: Option<[f64; 3]>,
    /// The block the user declared the row in (`block` column: any label; rows of one block share
    /// an error, see [`blocks`]). `None` without the column.
    pub block: Option<String>,
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
        Some(Measurement::of_file_dim(self.reading_mm.len())?.values_of_file(&self.reading_mm))
    }
}

/// One column of a dataset held in memory (see [`Dataset::from_columns`]).
#[derive(Clone, Debug)]
pub enum ColumnValues {
    Numbers(Vec<f64>),
    Texts(Vec<String>),
}

impl ColumnValues {
    pub fn len(&self) -> usize {
        match self {
            ColumnValues::Numbers(v) => v.len(),
            ColumnValues::Texts(v) => v.len(),
        }
    }
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

/// A dataset and where it came from (a path, or a label for in-memory sources).
#[derive(Clone, Debug, Default)]
pub struct Dataset {
    pub rows: Vec<Row>,
    pub source: String,
}

impl Dataset {
    /// Load from a dataset folder (reads `DIR/dataset.csv`), a `.csv` file, or an `.xlsx` file (first
    /// sheet, or sheet named by `path.xlsx#SheetName`). See the [module docs](self) for the accepted
    /// columns and the validation performed.
    pub fn load(path: &Path) -> Result<Dataset> {
        Self::load_with(path, &LoadOptions::default())
    }

    /// [`Self::load`] with explicit [`LoadOptions`] (angle unit, whether `L` is required).
    pub fn load_with(path: &Path, opts: &LoadOptions) -> Result<Dataset> {
        if path.is_dir() {
            return Self::load_csv_file(&path.join(DATASET_FILE), opts);
        }
        let (file, sheet) = split_sheet(path);
        let ext = file.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase).unwrap_or_default();
        match ext.as_str() {
            "csv" if sheet.is_none() => Self::load_csv_file(&file, opts),
            "xlsx" | "xlsm" | "xlsb" | "xls" | "ods" => {
                let (table, source) = xlsx::read_table(&file, sheet.as_deref())?;
                from_table(table, source, opts)
            }
            _ => Err(Error::data(
                path.display(),
                "unsupported dataset path: expected a folder containing dataset.csv, a .csv file, \
                 or an .xlsx file (optionally file.xlsx#Sheet)",
            )),
        }
    }

    fn load_csv_file(path: &Path, opts: &LoadOptions) -> Result<Dataset> {
        let file = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
        Self::from_csv_reader_with(std::io::BufReader::new(file), &path.display().to_string(), opts)
    }

    /// Parse and validate CSV text; `source` names the input in error messages and becomes
    /// [`Dataset::source`].
    pub fn from_csv_reader<R: std::io::Read>(r: R, source: &str) -> Result<Dataset> {
        Self::from_csv_reader_with(r, source, &LoadOptions::default())
    }

    /// [`Self::from_csv_reader`] with explicit [`LoadOptions`].
    pub fn from_csv_reader_with<R: std::io::Read>(r: R, source: &str, opts: &LoadOptions) -> Result<Dataset> {
        from_table(csv_io::read_table(r, source)?, source.to_owned(), opts)
    }

    /// A dataset from columns held in memory (numpy arrays from Python, say), read and validated
    /// exactly as a file with these columns would be: the same header rules, bounds, unit checks
    /// and messages. A missing number (NaN) in `sx, sy, sz` leaves the cell empty; elsewhere it
    /// is refused like a NaN cell. Messages name line k + 2 for row k (the header is line 1).
    pub fn from_columns(columns: Vec<(String, ColumnValues)>, source: &str, opts: &LoadOptions) -> Result<Dataset> {
        let n = columns.first().map_or(0, |(_, c)| c.len());
        if let Some((name, c)) = columns.iter().find(|(_, c)| c.len() != n) {
            return Err(Error::data(
                source,
                format!("column {name} has {} values, column {} has {n}: every column needs one value per row", c.len(), columns[0].0),
            ));
        }
        let header: Vec<String> = columns.iter().map(|(name, _)| name.clone()).collect();
        let optional_std: Vec<bool> = header.iter().map(|h| STD_COLUMNS.iter().any(|c| c.eq_ignore_ascii_case(h.trim()))).collect();
        let rows = (0..n)
            .map(|i| RawRow {
                line: i + 2,
                cells: columns
                    .iter()
                    .zip(&optional_std)
                    .map(|((_, c), &opt)| match c {
                        ColumnValues::Numbers(v) if opt && v[i].is_nan() => Cell::Empty,
                        ColumnValues::Numbers(v) => Cell::Number(v[i]),
                        ColumnValues::Texts(v) if v[i].trim().is_empty() => Cell::Empty,
                        ColumnValues::Texts(v) => Cell::Text(v[i].trim().to_owned()),
                    })
                    .collect(),
            })
            .collect();
        from_table(RawTable { header, rows, decimal_comma: false }, source.to_owned(), opts)
    }

    /// Number of joint angles per row (`q1..qN`); 0 for an empty dataset.
    pub fn n_joints(&self) -> usize {
        self.rows.first().map_or(0, |r| r.q_deg.len())
    }

    /// An error naming the source unless the rows hold `n` joint angles each, the joint count of
    /// the arm they are used with.
    pub fn require_joints(&self, n: usize, arm: &str) -> Result<()> {
        match self.rows.iter().position(|r| r.q_deg.len() != n) {
            None => Ok(()),
            Some(i) => {
                let k = self.rows[i].q_deg.len();
                let which = if i == 0 { "the rows hold".to_owned() } else { format!("row {} holds", i + 1) };
                Err(Error::data(&self.source, format!("{which} {k} joint angles (q1..q{k}) but {arm} has {n} joints")))
            }
        }
    }

    /// What the rows' readings are (from their number of values, which the loader took from the
    /// header's columns); `None` for a dataset of poses without readings.
    pub fn measurement(&self) -> Option<Measurement> {
        Measurement::of_file_dim(self.rows.first()?.reading_mm.len())
    }

    /// True when every row has a cable length (and there is at least one row).
    pub fn has_length(&self) -> bool {
        !self.rows.is_empty() && self.rows.iter().all(|r| r.l_mm().is_some())
    }

    /// True when every row has a reading (and there is at least one row).
    pub fn has_readings(&self) -> bool {
        !self.rows.is_empty() && self.rows.iter().all(|r| !r.reading_mm.is_empty())
    }

    /// An error naming the source unless every row has a cable length: calibration and anything
    /// that compares against measurements needs `L`.
    pub fn require_length(&self) -> Result<()> {
        if let Some(m) = self.measurement().filter(|m| *m != Measurement::Length) {
            return Err(Error::data(
                &self.source,
                format!("the rows hold a {} ({}), this needs a draw-wire cable length L", m.def().describe(), m.def().file_columns().join(", ")),
            ));
        }
        match self.rows.iter().position(|r| r.l_mm().is_none()) {
            None => Ok(()),
            Some(i) => Err(Error::data(
                &self.source,
                format!(
                    "row {} has no cable length L; this needs measured lengths (a file with \
                     q1..qN and L)",
                    i + 1
                ),
            )),
        }
    }

    /// An error naming the source unless every row has a reading of one kind (any instrument).
    pub fn require_readings(&self) -> Result<()> {
        let d = self.rows.first().map_or(0, |r| r.reading_mm.len());
        match self.rows.iter().position(|r| r.reading_mm.is_empty() || r.reading_mm.len() != d) {
            None if !self.rows.is_empty() => Ok(()),
            None => Err(Error::data(&self.source, "no rows")),
            Some(i) => Err(Error::data(
                &self.source,
                format!("row {} has no measurement; this needs measured readings (a file with q1..qN and {})", i + 1, reading_columns_hint()),
            )),
        }
    }

    /// The cable lengths of every row, mm; an error as [`Self::require_length`] when any is absent.
    pub fn lengths_mm(&self) -> Result<Vec<f64>> {
        self.require_length()?;
        Ok(self.rows.iter().map(|r| r.l_mm().unwrap_or(f64::NAN)).collect())
    }

    /// CSV text with header `q1,..,qN,L,t,temp,split` (a tracker's `x,y,z[,rx,ry,rz]`, and
    /// `sx,sy,sz` when some row has them, in place of `L`), one line per row in row order.
    /// Numbers use `f64`'s `Display` (shortest representation that round-trips exactly), so the
    /// output is deterministic and reloads to identical values; values rounded to `d` decimals
    /// beforehand (as the generator does) are written with at most `d` decimals. Columns `t`,
    /// `temp` and `split` are written only if every row has them (and there is at least one row);
    /// `L` is written unless no row has it (a row without it gets an empty cell).
    pub fn to_csv_string(&self) -> String {
        let mut columns = self.columns();
        if self.rows.is_empty() {
            // A dataset with no rows is written with the draw-wire's header.
            columns.extend(Measurement::Length.def().file_columns().iter().map(|c| (c.to_string(), ColumnValues::Numbers(Vec::new()))));
        }
        let mut out = columns.iter().map(|(name, _)| name.as_str()).collect::<Vec<_>>().join(",");
        out.push('\n');
        // `write!` into a String cannot fail. A missing number (NaN: a row without a reading or
        // without sx, sy, sz) is an empty cell.
        for i in 0..self.rows.len() {
            for (k, (_, c)) in columns.iter().enumerate() {
                if k > 0 {
                    out.push(',');
                }
                match c {
                    ColumnValues::Numbers(v) if v[i].is_nan() => {}
                    ColumnValues::Numbers(v) => {
                        let _ = write!(out, "{}", v[i]);
                    }
                    ColumnValues::Texts(v) => out.push_str(&v[i]),
                }
            }
            out.push('\n');
        }
        out
    }

    /// The dataset as columns, the ones [`Self::to_csv_string`] writes in its order: `q1..qN`,
    /// the reading's columns (those of the first row with a reading), `sx, sy, sz` when some row
    /// has them, and `t`, `temp`, `split` when every row has them; numbers (NaN where a row has no
    /// value) and `split` as text. [`Self::from_columns`] reads them back to the same rows.
    pub fn columns(&self) -> Vec<(String, ColumnValues)> {
        let all = |f: fn(&Row) -> bool| !self.rows.is_empty() && self.rows.iter().all(f);
        let number = |f: &dyn Fn(&Row) -> Option<f64>| ColumnValues::Numbers(self.rows.iter().map(|r| f(r).unwrap_or(f64::NAN)).collect());
        let reading_names: &[&str] = match self.rows.iter().find(|r| !r.reading_mm.is_empty()) {
            Some(r) => Measurement::of_file_dim(r.reading_mm.len()).map_or(&[], |m| m.def().file_columns()),
            None => &[],
        };
        let mut out: Vec<(String, ColumnValues)> = (0..self.n_joints()).map(|j| (format!("q{}", j + 1), number(&|r: &Row| r.q_deg.get(j).copied()))).collect();
        out.extend(reading_names.iter().enumerate().map(|(k, c)| (c.to_string(), number(&|r: &Row| r.reading_mm.get(k).copied()))));
        if self.rows.iter().any(|r| r.std_mm.is_some()) {
            out.extend(STD_COLUMNS.iter().enumerate().map(|(k, c)| (c.to_string(), number(&|r: &Row| r.std_mm.map(|s| s[k])))));
        }
        if all(|r| r.t_s.is_some()) {
            out.push(("t".into(), number(&|r: &Row| r.t_s)));
        }
        if all(|r| r.temp_c.is_some()) {
            out.push(("temp".into(), number(&|r: &Row| r.temp_c)));
        }
        if all(|r| r.block.is_some()) {
            out.push(("block".into(), ColumnValues::Texts(self.rows.iter().map(|r| r.block.clone().unwrap_or_default()).collect())));
        }
        if all(|r| r.split.is_some()) {
            out.push(("split".into(), ColumnValues::Texts(self.rows.iter().map(|r| r.split.map_or("", |s| s.as_str()).to_string()).collect())));
        }
        out
    }

    /// Writes [`Self::to_csv_string`] to `path` atomically (all or nothing). For the folder layout
    /// read by [`Self::load`], pass `dir.join(DATASET_FILE)`.
    pub fn write_csv(&self, path: &Path) -> Result<()> {
        crate::io::write_atomic(path, self.to_csv_string().as_bytes())
    }

    /// Indices of training rows: rows marked `train`, or every row when no row has a split.
    pub fn train_indices(&self) -> Vec<usize> {
        if self.rows.iter().all(|r| r.split.is_none()) {
            return (0..self.rows.len()).collect();
        }
        self.indices_of(Split::Train)
    }

    /// Indices of rows marked `test` (empty when no row has a split).
    pub fn test_indices(&self) -> Vec<usize> {
        self.indices_of(Split::Test)
    }

    fn indices_of(&self, split: Split) -> Vec<usize> {
        self.rows.iter().enumerate().filter(|(_, r)| r.split == Some(split)).map(|(i, _)| i).collect()
    }

    /// Number of rows.
    pub fn len(&self) -> usize {
        self.rows.len()
    }

    /// True when there are no rows.
    pub fn is_empty(&self) -> bool {
        self.rows.is_empty()
    }
}

/// The numeric columns `names` of a CSV file (other columns ignored), read by the dataset reader's
/// rules: delimiter detected (`,`, `;`, tab), decimal commas with `;` / tab, `#` comments, quoted
/// fields, a byte-order mark. A header matches a name case-insensitively, also as `NAME_mm`. A
/// non-finite cell (`NaN`, `inf`) reads as it is (the caller decides what that means); an empty
/// cell, a short row or other text is an error naming the line and column, as for a dataset's
/// cells. One `Vec` per row, in `names` order.
pub fn read_csv_columns(path: &Path, names: &[&str]) -> Result<Vec<Vec<f64>>> {
    let source = path.display().to_string();
    let file = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
    let table = csv_io::read_table(std::io::BufReader::new(file), &source)?;
    let found = table.header.join(",");
    let pos = names
        .iter()
        .map(|n| table.header.iter().position(|h| h.trim().eq_ignore_ascii_case(n) || h.trim().eq_ignore_ascii_case(&format!("{n}_mm"))))
        .collect::<Option<Vec<usize>>>()
        .ok_or_else(|| Error::data(&source, format!("the header '{found}' lacks the columns {}", names.join(", "))))?;
    // A column named twice is ambiguous (which x?): refused, as the dataset reader refuses it.
    for (n, &i) in names.iter().zip(&pos) {
        let same = |h: &String| h.trim().eq_ignore_ascii_case(n) || h.trim().eq_ignore_ascii_case(&format!("{n}_mm"));
        if table.header.iter().enumerate().any(|(k, h)| k != i && same(h)) {
            return Err(Error::data(&source, format!("the header '{found}' names the column {n} twice")));
        }
    }
    let cells = Cells { source: &source, decimal_comma: table.decimal_comma };
    let value = |row: &RawRow, i: usize, name: &str| -> Result<f64> {
        let cell =
            row.cells.get(i).ok_or_else(|| Error::data(&source, format!("line {}: {} fields, expected at least {}", row.line, row.cells.len(), i + 1)))?;
        // A non-finite value (NaN, inf) is the caller's to answer; anything else reads as a dataset cell.
        if let Cell::Text(t) = cell {
            if let Some(v) = parse_number(t, table.decimal_comma).filter(|v| !v.is_finite()) {
                return Ok(v);
            }
        }
        cells.required(Some(cell), name, row.line)
    };
    table.rows.iter().map(|row| pos.iter().zip(names).map(|(&i, name)| value(row, i, name)).collect()).collect()
}

/// Splits `book.xlsx#Sheet` into the file and the sheet name. A path that exists as given is never
/// split; otherwise the first `#` whose prefix ends in a spreadsheet extension is the separator.
fn split_sheet(path: &Path) -> (PathBuf, Option<String>) {
    if path.exists() {
        return (path.to_path_buf(), None);
    }
    if let Some(s) = path.to_str() {
        for (i, _) in s.match_indices('#') {
            let (file, sheet) = (&s[..i], &s[i + 1..]);
            let lower = file.to_ascii_lowercase();
            let is_book = [".xlsx", ".xlsm", ".xlsb", ".xls", ".ods"].iter().any(|e| lower.ends_with(e));
            if is_book && !sheet.is_empty() {
                return (PathBuf::from(file), Some(sheet.to_owned()));
            }
        }
    }
    (path.to_path_buf(), None)
}

// ---------------------------------------------------------------------------------------------
// Format-independent table and its interpretation.

/// A cell as read from the file, before interpretation.
#[derive(Clone, Debug, PartialEq)]
pub(crate) enum Cell {
    Empty,
    /// A native numeric cell (spreadsheets).
    Number(f64),
    /// Text, trimmed, non-empty.
    Text(String),
    /// Anything else (booleans, dates, spreadsheet errors), described for messages.
    Other(String),
}

/// A non-blank data row with its line number in the file.
#[derive(Clone, Debug)]
pub(crate) struct RawRow {
    pub line: usize,
    pub cells: Vec<Cell>,
}

/// Header plus data rows, as read.
#[derive(Clone, Debug)]
pub(crate) struct RawTable {
    pub header: Vec<String>,
    pub rows: Vec<RawRow>,
    /// Text cells may use a decimal comma (`1,5`): set for `;`- or tab-separated CSV.
    pub decimal_comma: bool,
}

/// The reading columns of every measurement type, each once, in registry order (`L`, `x`,
/// `y`, `z`, ...).
fn reading_names() -> &'static [&'static str] {
    static NAMES: std::sync::OnceLock<Vec<&'static str>> = std::sync::OnceLock::new();
    NAMES.get_or_init(|| {
        let mut v: Vec<&'static str> = Vec::new();
        for m in Measurement::ALL {
            for c in m.def().file_columns() {
                if !v.contains(c) {
                    v.push(c);
                }
            }
        }
        v
    })
}

/// "L (draw-wire cable length) or x, y, z (laser-tracker target position)": what a file may
/// hold as its readings.
fn reading_columns_hint() -> String {
    Measurement::ALL.iter().map(|m| format!("{} ({})", m.def().file_columns().join(", "), m.def().describe())).collect::<Vec<_>>().join(" or ")
}

/// The columns this module understands.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Column {
    /// Joint `j` (0-based): header `q{j+1}`.
    Q(usize),
    /// A reading column: [`reading_names`]`()[i]`.
    Reading(usize),
    T,
    Temp,
    Split,
    /// A declared block label.
    Block,
    /// A tracker's per-row standard deviation of position coordinate `k`: [`STD_COLUMNS`]`[k]`.
    Std(usize),
}

/// The per-row standard deviation columns of a tracker's position (mm), in x, y, z order.
pub const STD_COLUMNS: [&str; 3] = ["sx", "sy", "sz"];
/// Largest per-row standard deviation (mm) taken for a measurement's: beyond it the column
/// holds something else.
pub const MAX_STD_MM: f64 = 100.0;

impl Column {
    const OTHERS: [Column; 7] = [Column::T, Column::Temp, Column::Split, Column::Std(0), Column::Std(1), Column::Std(2), Column::Block];
    /// Slots of the named columns ([`Self::OTHERS`]) before the reading columns.
    const NAMED: usize = 7;

    /// Slot in [`Layout::pos`]: the named columns, the reading columns, then the joints.
    fn index(self) -> usize {
        match self {
            Column::T => 0,
            Column::Temp => 1,
            Column::Split => 2,
            Column::Std(k) => 3 + k,
            Column::Block => 6,
            Column::Reading(i) => Self::NAMED + i,
            Column::Q(j) => Self::NAMED + reading_names().len() + j,
        }
    }

    fn name(self) -> String {
        match self {
            Column::Q(j) => format!("q{}", j + 1),
            Column::Reading(i) => reading_names()[i].into(),
            Column::T => "t".into(),
            Column::Temp => "temp".into(),
            Column::Split => "split".into(),
            Column::Block => "block".into(),
            Column::Std(k) => STD_COLUMNS[k].into(),
        }
    }

    /// The column of reading name `name`.
    fn reading(name: &str) -> Column {
        Column::Reading(reading_names().iter().position(|n| *n == name).expect("a registered reading column"))
    }

    /// The column a header names: `q<k>` with 1 <= k <= [`MAX_JOINTS`] (case-insensitive,
    /// digits only, no leading zero), a reading column (`L`, `x`, ..., or with its unit `L_mm`,
    /// `x_mm`) or one of the named columns.
    fn from_header(h: &str) -> Option<Column> {
        let h = h.trim();
        if let Some(k) = h.strip_prefix(['q', 'Q']) {
            let digits = !k.is_empty() && k.bytes().all(|b| b.is_ascii_digit()) && !k.starts_with('0');
            return match k.parse::<usize>() {
                Ok(k) if digits && (1..=MAX_JOINTS).contains(&k) => Some(Column::Q(k - 1)),
                _ => None,
            };
        }
        // A reading column may carry its unit: `L_mm`, `x_mm` (as `ik --targets` reads them).
        let bare = match h.len().checked_sub(3).and_then(|k| Some((h.get(..k)?, h.get(k..)?))) {
            Some((stem, unit)) if !stem.is_empty() && unit.eq_ignore_ascii_case("_mm") => stem,
            _ => h,
        };
        if let Some(i) = reading_names().iter().position(|n| n.eq_ignore_ascii_case(bare)) {
            return Some(Column::Reading(i));
        }
        Self::OTHERS.into_iter().find(|c| c.name().eq_ignore_ascii_case(h))
    }
}

/// Positions of the known columns in the file's header.
struct Layout {
    pos: Vec<Option<usize>>,
    /// Number of joint columns, `q1..qN`.
    joints: usize,
    /// The instrument whose reading columns the header holds, if any.
    measurement: Option<Measurement>,
}

impl Layout {
    fn new(header: &[String], source: &str, require_length: bool, want: Option<Measurement>) -> Result<Layout> {
        let found = || header.join(",");
        let mut pos = vec![None; Column::NAMED + reading_names().len() + MAX_JOINTS];
        for (i, h) in header.iter().enumerate() {
            if let Some(c) = Column::from_header(h) {
                if let Some(first) = pos[c.index()] {
                    return Err(Error::data(
                        source,
                        format!("line 1: duplicate column {} (fields {} and {}); header found: {}", c.name(), first + 1, i + 1, found()),
                    ));
                }
                pos[c.index()] = Some(i);
            }
        }
        // The joints are q1..qN with N the highest joint named; at least one is needed.
        let joints = (0..MAX_JOINTS).rev().find(|&j| pos[Column::Q(j).index()].is_some()).map_or(1, |j| j + 1);
        let has = |m: &Measurement| m.def().file_columns().iter().all(|c| pos[Column::reading(c).index()].is_some());
        let mut complete: Vec<Measurement> = Measurement::ALL.into_iter().filter(has).collect();
        // An instrument whose columns another one's include (a point's x, y, z in a pose's) is
        // that one; the one asked for is read alone.
        let within = |a: &Measurement, b: &Measurement| a != b && a.def().file_columns().iter().all(|c| b.def().file_columns().contains(c));
        let all = complete.clone();
        complete.retain(|a| !all.iter().any(|b| within(a, b)));
        if let Some(w) = want {
            if !has(&w) {
                let missing: Vec<&str> = w.def().file_columns().iter().copied().filter(|c| pos[Column::reading(c).index()].is_none()).collect();
                return Err(Error::data(
                    source,
                    format!(
                        "line 1: a {} needs the columns {}; missing {}; header found: {}",
                        w.def().describe(),
                        w.def().file_columns().join(", "),
                        missing.join(", "),
                        found()
                    ),
                ));
            }
            complete = vec![w];
        }
        if complete.len() > 1 {
            let both = complete.iter().map(|m| format!("{} ({})", m.def().columns().join(", "), m.def().describe())).collect::<Vec<_>>().join(" and ");
            return Err(Error::data(source, format!("line 1: the header holds the readings of two instruments, {both}; keep one; header found: {}", found())));
        }
        let measurement = complete.first().copied();
        let mut missing: Vec<String> = (0..joints).map(Column::Q).filter(|c| pos[c.index()].is_none()).map(|c| c.name()).collect();
        if measurement.is_none() {
            // Name the columns of a partly given instrument (x and y without z), else L.
            let partial = Measurement::ALL.into_iter().find(|m| m.def().file_columns().iter().any(|c| pos[Column::reading(c).index()].is_some()));
            match partial {
                Some(m) => missing.extend(m.def().file_columns().iter().filter(|c| pos[Column::reading(c).index()].is_none()).map(|c| c.to_string())),
                None if require_length => missing.push("L".into()),
                None => {}
            }
        }
        if !missing.is_empty() {
            let hint = reading_columns_hint();
            let need = if require_length {
                format!("need q1..qN and {hint}; optional t, temp, split")
            } else {
                format!("need q1..qN; optional {hint}, t, temp, split")
            };
            return Err(Error::data(source, format!("missing required column(s) {}; header found: {} ({need})", missing.join(", "), found())));
        }
        // Per-row standard deviations: all three of a tracker's position, or none.
        let std_given: Vec<usize> = (0..3).filter(|&k| pos[Column::Std(k).index()].is_some()).collect();
        if !std_given.is_empty() {
            if std_given.len() < 3 {
                let lacking: Vec<&str> = (0..3).filter(|k| !std_given.contains(k)).map(|k| STD_COLUMNS[k]).collect();
                return Err(Error::data(
                    source,
                    format!("line 1: per-row standard deviations need all of sx, sy, sz; missing {}; header found: {}", lacking.join(", "), found()),
                ));
            }
            if let Some(m) = measurement.filter(|m| m.file_lengths() != 3) {
                return Err(Error::data(
                    source,
                    format!(
                        "line 1: sx, sy, sz are a tracker's per-axis standard deviations; this file holds a {} ({}); header found: {}",
                        m.def().describe(),
                        m.def().file_columns().join(", "),
                        found()
                    ),
                ));
            }
        }
        Ok(Layout { pos, joints, measurement })
    }

    fn cell<'a>(&self, row: &'a RawRow, c: Column) -> Option<&'a Cell> {
        self.pos[c.index()].map(|i| row.cells.get(i).unwrap_or(&Cell::Empty))
    }
}

impl std::fmt::Display for Column {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.name())
    }
}

/// An error naming the file, the line and the column (a [`Column`] or any column name).
fn cell_error(source: &str, line: usize, c: impl std::fmt::Display, msg: impl std::fmt::Display) -> Error {
    Error::data(source, format!("line {line}, column {c}: {msg}"))
}

/// Reads one table cell: numbers, text and the decimal-comma setting.
struct Cells<'a> {
    source: &'a str,
    decimal_comma: bool,
}

impl Cells<'_> {
    /// Interprets a cell as a finite number; `Ok(None)` for an empty cell or an absent column.
    fn number<C: std::fmt::Display + Copy>(&self, cell: Option<&Cell>, c: C, line: usize) -> Result<Option<f64>> {
        let source = self.source;
        let v = match cell {
            None | Some(Cell::Empty) => return Ok(None),
            Some(Cell::Number(v)) => *v,
            Some(Cell::Text(s)) => parse_number(s, self.decimal_comma).ok_or_else(|| {
                let hint = if !self.decimal_comma && s.contains(',') && !s.contains('.') {
                    " (a decimal comma is accepted only in ';'- or tab-separated files)"
                } else {
                    ""
                };
                cell_error(source, line, c, format!("'{s}' is not a number{hint}"))
            })?,
            Some(Cell::Other(what)) => return Err(cell_error(source, line, c, format!("{what} is not a number"))),
        };
        if v.is_nan() {
            return Err(cell_error(source, line, c, "NaN is not allowed"));
        }
        if v.is_infinite() {
            return Err(cell_error(source, line, c, "infinite value is not allowed"));
        }
        Ok(Some(v))
    }

    fn required<C: std::fmt::Display + Copy>(&self, cell: Option<&Cell>, c: C, line: usize) -> Result<f64> {
        self.number(cell, c, line)?.ok_or_else(|| cell_error(self.source, line, c, "empty cell (value required)"))
    }
}

/// Parses a decimal number; with `decimal_comma`, one `,` and no `.` reads as a decimal point.
fn parse_number(s: &str, decimal_comma: bool) -> Option<f64> {
    if let Ok(v) = s.parse::<f64>() {
        return Some(v);
    }
    if decimal_comma && s.matches(',').count() == 1 && !s.contains('.') {
        return s.replace(',', ".").parse::<f64>().ok();
    }
    None
}

fn split_value(cell: Option<&Cell>, line: usize, source: &str) -> Result<Option<Split>> {
    let text = match cell {
        None | Some(Cell::Empty) => return Ok(None),
        Some(Cell::Text(s)) => s.clone(),
        Some(Cell::Number(v)) => v.to_string(),
        Some(Cell::Other(what)) => what.clone(),
    };
    match text.to_ascii_lowercase().as_str() {
        "train" => Ok(Some(Split::Train)),
        "test" => Ok(Some(Split::Test)),
        _ => Err(cell_error(source, line, Column::Split, format!("unknown split value '{text}' (must be train or test)"))),
    }
}

/// A declared block's label (text or a number, trimmed); `None` for an empty cell or no column.
fn block_label(cell: Option<&Cell>, line: usize, source: &str) -> Result<Option<String>> {
    let text = match cell {
        None | Some(Cell::Empty) => return Ok(None),
        Some(Cell::Text(s)) => s.trim().to_string(),
        Some(Cell::Number(v)) => crate::error::shown(*v),
        Some(Cell::Other(what)) => return Err(cell_error(source, line, Column::Block, format!("{what} is not a block label"))),
    };
    if text.is_empty() {
        return Ok(None);
    }
    if text.len() > 100 || text.chars().any(|c| c.is_control() || c == ',' || c == '"') {
        return Err(cell_error(source, line, Column::Block, "a block label is at most 100 characters, without commas, quotes or control characters"));
    }
    Ok(Some(text))
}

/// A row's `sx, sy, sz` (mm): all three or none (empty cells), each in (0, [`MAX_STD_MM`]].
fn row_std(layout: &Layout, cells: &Cells, raw: &RawRow, line: usize) -> Result<Option<[f64; 3]>> {
    if layout.pos[Column::Std(0).index()].is_none() {
        return Ok(None);
    }
    let mut v = [None; 3];
    for (k, vk) in v.iter_mut().enumerate() {
        let c = Column::Std(k);
        *vk = cells.number(layout.cell(raw, c), c, line)?;
        if let Some(s) = *vk {
            if !(s > 0.0 && s <= MAX_STD_MM) {
                let why = format!("standard deviation {} mm is implausible (allowed (0, {MAX_STD_MM}] mm)", crate::error::shown(s));
                return Err(cell_error(cells.source, line, c, why));
            }
        }
    }
    match v {
        [Some(a), Some(b), Some(c)] => Ok(Some([a, b, c])),
        [None, None, None] => Ok(None),
        _ => {
            let k = v.iter().position(Option::is_none).expect("one is empty");
            Err(cell_error(cells.source, line, Column::Std(k), "empty cell while the row gives other standard deviations (give sx, sy, sz together or none)"))
        }
    }
}

/// Checks `lo <= v <= hi`, naming the cell and what the value is.
fn check_bounds(v: f64, (lo, hi): (f64, f64), what: &str, line: usize, c: Column, src: &str) -> Result<()> {
    if v < lo || v > hi {
        return Err(cell_error(src, line, c, format!("{what} {} is implausible (allowed range [{lo}, {hi}])", crate::error::shown(v))));
    }
    Ok(())
}

fn from_table(table: RawTable, source: String, opts: &LoadOptions) -> Result<Dataset> {
    let src = source.as_str();
    let layout = Layout::new(&table.header, src, opts.require_length, opts.measurement)?;
    if table.rows.is_empty() {
        return Err(Error::data(src, "no data rows (only a header)"));
    }
    let cells = Cells { source: src, decimal_comma: table.decimal_comma };

    let mut rows = Vec::with_capacity(table.rows.len());
    let mut last_t: Option<(f64, usize)> = None;
    let mut first_split_missing: Option<usize> = None;
    // First line with an empty `t` / `temp` cell.
    let (mut first_t_missing, mut first_temp_missing): (Option<usize>, Option<usize>) = (None, None);
    for raw in &table.rows {
        let line = raw.line;
        let q_deg = row_angles(&layout, &cells, raw, opts.angles)?;
        let reading_mm = row_reading(&layout, &cells, raw, opts.euler)?;
        let t_s = cells.number(layout.cell(raw, Column::T), Column::T, line)?;
        if let Some(t) = t_s {
            check_time(t, last_t, line, src)?;
            last_t = Some((t, line));
        }
        let temp_c = cells.number(layout.cell(raw, Column::Temp), Column::Temp, line)?;
        if let Some(temp) = temp_c {
            check_bounds(temp, (MIN_TEMP_C, MAX_TEMP_C), "temperature (°C)", line, Column::Temp, src)?;
        }
        if t_s.is_none() {
            first_t_missing = first_t_missing.or(Some(line));
        }
        if temp_c.is_none() {
            first_temp_missing = first_temp_missing.or(Some(line));
        }
        let split = split_value(layout.cell(raw, Column::Split), line, src)?;
        if split.is_none() && first_split_missing.is_none() {
            first_split_missing = Some(line);
        }
        let std_mm = row_std(&layout, &cells, raw, line)?;
        let block = block_label(layout.cell(raw, Column::Block), line, src)?;
        if layout.pos[Column::Block.index()].is_some() && block.is_none() {
            return Err(cell_error(src, line, Column::Block, "empty block label; when the file has a block column, every row must name its block"));
        }
        rows.push(Row { q_deg, reading_mm, t_s, temp_c, split, std_mm, block });
    }

    // A split column is all-or-nothing: a partially filled one would silently drop rows.
    if let Some(line) = first_split_missing {
        if rows.iter().any(|r| r.split.is_some()) {
            return Err(cell_error(src, line, Column::Split, "empty split value; when some rows have a split, every row must be train or test"));
        }
    }
    // So are `t` and `temp`: a model driven by them needs them on every row, and a gap would
    // silently drop the column from it (an empty column is no column).
    let gaps =
        [(Column::T, first_t_missing, rows.iter().any(|r| r.t_s.is_some())), (Column::Temp, first_temp_missing, rows.iter().any(|r| r.temp_c.is_some()))];
    for (c, missing, some) in gaps {
        if let (Some(line), true) = (missing, some) {
            let name = c.name();
            return Err(cell_error(
                src,
                line,
                c,
                format!("empty {name} value; when some rows have a {name}, every row must (leave the column empty on every row if it was not logged)"),
            ));
        }
    }
    check_units(&rows, src, opts.angles)?;
    Ok(Dataset { rows, source })
}

/// A row's joint angles in degrees (converted from radians when the file's are), each plausible.
fn row_angles(layout: &Layout, cells: &Cells, raw: &RawRow, angles: AngleUnit) -> Result<Vec<f64>> {
    let line = raw.line;
    let mut q_deg = vec![0.0; layout.joints];
    for (j, q) in q_deg.iter_mut().enumerate() {
        let c = Column::Q(j);
        let v = cells.required(layout.cell(raw, c), c, line)?;
        *q = if angles == AngleUnit::Rad { v.to_degrees() } else { v };
        if q.abs() > MAX_ABS_JOINT_DEG {
            let (v, q) = (crate::error::shown(v), crate::error::shown(*q));
            let shown = if angles == AngleUnit::Rad { format!("{v} rad ({q} deg)") } else { format!("{q} deg") };
            return Err(cell_error(cells.source, line, c, format!("joint angle {shown} is implausible (|q| > {MAX_ABS_JOINT_DEG} deg)")));
        }
    }
    Ok(q_deg)
}

/// A row's reading (empty without an instrument's columns), each value plausible; a pose's
/// angles turned from the file's Euler convention into XYZ.
fn row_reading(layout: &Layout, cells: &Cells, raw: &RawRow, euler: Euler) -> Result<Vec<f64>> {
    let mut reading_mm = Vec::new();
    let Some(m) = layout.measurement else { return Ok(reading_mm) };
    for (k, name) in m.def().file_columns().iter().enumerate() {
        let c = Column::reading(name);
        let v = cells.required(layout.cell(raw, c), c, raw.line)?;
        if let Some(why) = m.def().implausible(k, v) {
            return Err(cell_error(cells.source, raw.line, c, why));
        }
        reading_mm.push(v);
    }
    if m == Measurement::Pose && euler != Euler::XYZ {
        let r = euler.matrix([reading_mm[3].to_radians(), reading_mm[4].to_radians(), reading_mm[5].to_radians()]);
        let a = crate::measurement::pose::xyz_angles(&r);
        reading_mm[3..6].iter_mut().zip(a).for_each(|(v, a)| *v = a.to_degrees());
    }
    Ok(reading_mm)
}

/// A row's time `t` (s): plausible, and not before the previous row's (`last`: its time, line).
fn check_time(t: f64, last: Option<(f64, usize)>, line: usize, src: &str) -> Result<()> {
    check_bounds(t, (0.0, MAX_T_S), "time (s from the start of acquisition)", line, Column::T, src)?;
    match last {
        Some((prev, prev_line)) if t < prev => Err(cell_error(
            src,
            line,
            Column::T,
            format!(
                "t = {t} s is earlier than t = {prev} s on line {prev_line}; t must \
                 be non-decreasing (rows are read in acquisition order: sort the file by t if its times are right, \
                 or leave the t column out)"
            ),
        )),
        _ => Ok(()),
    }
}

/// The radians and metres heuristics described in the module docs (radians only with
/// [`AngleUnit::Auto`]).
fn check_units(rows: &[Row], source: &str, angles: AngleUnit) -> Result<()> {
    if angles == AngleUnit::Auto && rows.len() >= RADIANS_MIN_ROWS {
        let max_abs = rows.iter().flat_map(|r| r.q_deg.iter()).fold(0.0_f64, |m, q| m.max(q.abs()));
        let spans: Vec<f64> = (0..rows[0].q_deg.len())
            .map(|j| {
                let (lo, hi) = rows.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), r| (lo.min(r.q_deg[j]), hi.max(r.q_deg[j])));
                hi - lo
            })
            .collect();
        let (widest, span) = spans.iter().copied().enumerate().fold((0, 0.0), |best, (j, s)| if s > best.1 { (j, s) } else { best });
        if max_abs <= RADIANS_MAX_ABS && span > RADIANS_MIN_SPAN {
            return Err(Error::data(
                source,
                format!(
                    "columns q1..q{} look like radians (all {} rows have |q| <= {max_abs:.3}, q{} \
                     spans {span:.3}); the file must hold joint angles in degrees; if they really \
                     are degrees pass --angles deg (or --angles rad to convert)",
                    spans.len(),
                    rows.len(),
                    widest + 1
                ),
            ));
        }
    }
    // The lengths: every reading column but a pose's angles.
    let measurement = rows.first().and_then(|r| Measurement::of_file_dim(r.reading_mm.len()));
    let lengths = measurement.map_or(0, |m| m.file_lengths());
    let max_abs = rows.iter().flat_map(|r| r.reading_mm.iter().take(lengths)).fold(None, |m: Option<f64>, v| Some(m.map_or(v.abs(), |m| m.max(v.abs()))));
    if let (Some(max), Some(m)) = (max_abs, measurement) {
        if max < METRES_MAX_L {
            let cols = m.def().file_columns()[..lengths].join(", ");
            let msg = if m.dim() == 1 {
                format!("column {cols} looks like metres (every {cols} < {METRES_MAX_L}, max {max}); {cols} must be in millimetres")
            } else {
                format!("columns {cols} look like metres (every |value| < {METRES_MAX_L}, max {max}); they must be in millimetres")
            };
            return Err(Error::data(source, msg));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests;
