//! Calibration datasets: one row per static robot configuration, its joint angles `q1..qN`
//! (degrees, controller convention; N is whatever the arm has) and the instrument's reading in
//! millimetres (the draw-wire cable length `L`, or a laser tracker's target position `x, y, z`:
//! the columns of a [`Measurement`](crate::measurement::Measurement)), with optional time, temperature and train/test split.
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
//! [`Dataset::load_with`] takes [`ReadOptions`]: the joint angle unit ([`AngleUnit::Auto`] applies
//! the radians heuristic below, [`AngleUnit::Deg`] skips it, [`AngleUnit::Rad`] converts the
//! angles to degrees on load) and whether `L` is required (`require_length: false` accepts a
//! file of poses `q1..qN` only, e.g. for prediction; rows then have `l_mm == None`). A dataset
//! used for calibration must have `L` ([`Dataset::require_length`]). [`Dataset::load`] is
//! `load_with` with the defaults (`Auto`, `L` required).
//!
//! # Validation
//!
//! Every problem is reported as [`Error::Data`](crate::Error::Data) naming the file, the line (spreadsheet line number:
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

mod beside;
pub mod blocks;
mod csv_io;
mod load;
pub mod logging;
pub mod split;
mod stations;
mod table;
pub mod truth;
mod types;
mod xlsx;

pub use load::{artifact_files, campaign_files, read_csv_columns, CsvColumns};
pub use stations::{feature_station, Stations};
pub use table::{MAX_PAYLOAD_KG, MAX_STD_MM, STD_COLUMNS};
pub use types::*;

#[cfg(test)]
mod tests;
