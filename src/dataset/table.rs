//! A table of cells (from a CSV or a spreadsheet) read into rows: the header's layout, each
//! cell's number, the plausibility checks and the unit heuristics.

use super::types::*;
use crate::error::{Error, Result};
use crate::measurement::{Euler, FeatureKind, Measurement};

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
pub(super) fn reading_names() -> &'static [&'static str] {
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
pub(super) fn reading_columns_hint() -> String {
    Measurement::ALL.iter().map(|m| format!("{} ({})", m.def().file_columns().join(", "), m.def().describe())).collect::<Vec<_>>().join(" or ")
}

/// The columns this module understands.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Column {
    /// Joint `j` (0-based): header `q{j+1}`.
    Q(usize),
    /// A reading column: [`reading_names`]`()[i]`.
    Reading(usize),
    T,
    Temp,
    Split,
    /// A declared block label.
    Block,
    /// The payload mounted, kg.
    Payload,
    /// A declared instrument station (a tracker's place between re-stationings).
    Station,
    /// A declared mount of the target on the flange (a probe re-mounted between sessions).
    Mount,
    /// The feature of an artifact the row stands at: a socket the ball on the flange was
    /// seated in (the row reads nothing) or a face a probe touched or an indicator read.
    Feature(FeatureKind),
    /// A tracker's per-row standard deviation of position coordinate `k`: [`STD_COLUMNS`]`[k]`.
    Std(usize),
}

/// Largest payload (kg) a `payload_kg` cell may hold (as `--payload-kg`).
pub const MAX_PAYLOAD_KG: f64 = 1000.0;

/// The per-row standard deviation columns of a tracker's position (mm), in x, y, z order.
pub const STD_COLUMNS: [&str; 3] = ["sx", "sy", "sz"];

/// Largest per-row standard deviation (mm) taken for a measurement's: beyond it the column
/// holds something else.
pub const MAX_STD_MM: f64 = 100.0;

impl Column {
    const OTHERS: [Column; 12] = [
        Column::T,
        Column::Temp,
        Column::Split,
        Column::Std(0),
        Column::Std(1),
        Column::Std(2),
        Column::Block,
        Column::Payload,
        Column::Station,
        Column::Mount,
        Column::Feature(FeatureKind::Socket),
        Column::Feature(FeatureKind::Plane),
    ];
    /// Slots of the named columns ([`Self::OTHERS`]) before the reading columns.
    const NAMED: usize = 12;
    /// The header an artifact's placement goes by: the station of a socket's rows (where the
    /// artifact stood).
    pub(super) const PLACEMENT: &'static str = "placement";

    /// Slot in [`Layout::pos`]: the named columns, the reading columns, then the joints.
    pub(super) fn index(self) -> usize {
        match self {
            Column::T => 0,
            Column::Temp => 1,
            Column::Split => 2,
            Column::Std(k) => 3 + k,
            Column::Block => 6,
            Column::Payload => 7,
            Column::Station => 8,
            Column::Mount => 9,
            Column::Feature(FeatureKind::Socket) => 10,
            Column::Feature(FeatureKind::Plane) => 11,
            Column::Reading(i) => Self::NAMED + i,
            Column::Q(j) => Self::NAMED + reading_names().len() + j,
        }
    }

    pub(super) fn name(self) -> String {
        match self {
            Column::Q(j) => format!("q{}", j + 1),
            Column::Reading(i) => reading_names()[i].into(),
            Column::T => "t".into(),
            Column::Temp => "temp".into(),
            Column::Split => "split".into(),
            Column::Block => "block".into(),
            Column::Payload => "payload_kg".into(),
            Column::Station => "station".into(),
            Column::Mount => "mount".into(),
            Column::Feature(k) => k.column().into(),
            Column::Std(k) => STD_COLUMNS[k].into(),
        }
    }

    /// The column of reading name `name`.
    pub(super) fn reading(name: &str) -> Column {
        Column::Reading(reading_names().iter().position(|n| *n == name).expect("a registered reading column"))
    }

    /// The column a header names: `q<k>` with 1 <= k <= [`MAX_JOINTS`] (case-insensitive,
    /// digits only, no leading zero), a reading column (`L`, `x`, ..., or with its unit `L_mm`,
    /// `x_mm`) or one of the named columns.
    pub(super) fn from_header(h: &str) -> Option<Column> {
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
        if h.eq_ignore_ascii_case(Self::PLACEMENT) {
            return Some(Column::Station);
        }
        Self::OTHERS.into_iter().find(|c| c.name().eq_ignore_ascii_case(h))
    }
}

/// Positions of the known columns in the file's header.
pub(super) struct Layout {
    pub(super) pos: Vec<Option<usize>>,
    /// Number of joint columns, `q1..qN`.
    pub(super) joints: usize,
    /// The instrument whose reading columns the header holds, if any.
    pub(super) measurement: Option<Measurement>,
    /// The kind of artifact's feature the header's column names, if any (sockets, where the
    /// header names sockets and faces).
    pub(super) feature: Option<FeatureKind>,
    /// Faces touched beside sockets seated (one ball, one fit): the instrument of the rows that
    /// name a face (a probe's contact, or a dial indicator's reading where the header has its
    /// column); the rows that name a socket read nothing.
    pub(super) faces_beside: Option<Measurement>,
}

impl Layout {
    pub(super) fn new(header: &[String], source: &str, require_length: bool, want: Option<Measurement>) -> Result<Layout> {
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
        let feature = feature_named(&pos);
        // The joints are q1..qN with N the highest joint named; at least one is needed.
        let joints = (0..MAX_JOINTS).rev().find(|&j| pos[Column::Q(j).index()].is_some()).map_or(1, |j| j + 1);
        let has = |m: &Measurement| present(m, &pos);
        let mut complete: Vec<Measurement> = Measurement::ALL.into_iter().filter(has).collect();
        // An instrument whose columns another one's include (a point's x, y, z in a pose's) is
        // that one; the one asked for is read alone.
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
        seated_beside_points(&mut complete);
        let faces_beside = super::beside::faces_beside_sockets(&mut complete, source, &found())?;
        if complete.len() > 1 {
            let both = complete.iter().map(|m| format!("{} ({})", m.def().columns().join(", "), m.def().describe())).collect::<Vec<_>>().join(" and ");
            return Err(Error::data(source, format!("line 1: the header holds the readings of two instruments, {both}; keep one; header found: {}", found())));
        }
        let measurement = complete.first().copied();
        // A wider instrument's columns given in part (rx and ry without rz beside x, y, z) are a
        // mistake, not columns to ignore (unless the reading asked for is the narrower one).
        if let (Some(m), None) = (measurement, want) {
            partial_wider(m, &pos, source, &found())?;
        }
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
        Ok(Layout { pos, joints, measurement, feature, faces_beside })
    }

    pub(super) fn cell<'a>(&self, row: &'a RawRow, c: Column) -> Option<&'a Cell> {
        self.pos[c.index()].map(|i| row.cells.get(i).unwrap_or(&Cell::Empty))
    }
}

impl std::fmt::Display for Column {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.name())
    }
}

/// An error naming the file, the line and the column (a [`Column`] or any column name).
pub(super) fn cell_error(source: &str, line: usize, c: impl std::fmt::Display, msg: impl std::fmt::Display) -> Error {
    Error::data(source, format!("line {line}, column {c}: {msg}"))
}

/// Reads one table cell: numbers, text and the decimal-comma setting.
pub(super) struct Cells<'a> {
    pub(super) source: &'a str,
    pub(super) decimal_comma: bool,
}

impl Cells<'_> {
    /// Interprets a cell as a finite number; `Ok(None)` for an empty cell or an absent column.
    pub(super) fn number<C: std::fmt::Display + Copy>(&self, cell: Option<&Cell>, c: C, line: usize) -> Result<Option<f64>> {
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

    pub(super) fn required<C: std::fmt::Display + Copy>(&self, cell: Option<&Cell>, c: C, line: usize) -> Result<f64> {
        self.number(cell, c, line)?.ok_or_else(|| cell_error(self.source, line, c, "empty cell (value required)"))
    }
}

/// Parses a decimal number; with `decimal_comma`, one `,` and no `.` reads as a decimal point.
pub(super) fn parse_number(s: &str, decimal_comma: bool) -> Option<f64> {
    if let Ok(v) = s.parse::<f64>() {
        return Some(v);
    }
    if decimal_comma && s.matches(',').count() == 1 && !s.contains('.') {
        return s.replace(',', ".").parse::<f64>().ok();
    }
    None
}

pub(super) fn split_value(cell: Option<&Cell>, line: usize, source: &str) -> Result<Option<Split>> {
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

/// A declared label of column `c` (a block's or a station's: text or a number, trimmed); `None`
/// for an empty cell or no column.
pub(super) fn label(cell: Option<&Cell>, c: Column, line: usize, source: &str) -> Result<Option<String>> {
    let what = c.name();
    let text = match cell {
        None | Some(Cell::Empty) => return Ok(None),
        Some(Cell::Text(s)) => s.trim().to_string(),
        Some(Cell::Number(v)) => crate::error::shown(*v),
        Some(Cell::Other(other)) => return Err(cell_error(source, line, c, format!("{other} is not a {what} label"))),
    };
    if text.is_empty() {
        return Ok(None);
    }
    if text.len() > 100 || text.chars().any(|c| c.is_control() || c == ',' || c == '"') {
        return Err(cell_error(source, line, c, format!("a {what} label is at most 100 characters, without commas, quotes or control characters")));
    }
    Ok(Some(text))
}

/// A row's `sx, sy, sz` (mm): all three or none (empty cells), each in (0, [`MAX_STD_MM`]].
pub(super) fn row_std(layout: &Layout, cells: &Cells, raw: &RawRow, line: usize) -> Result<Option<[f64; 3]>> {
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
pub(super) fn check_bounds(v: f64, (lo, hi): (f64, f64), what: &str, line: usize, c: Column, src: &str) -> Result<()> {
    if v < lo || v > hi {
        return Err(cell_error(src, line, c, format!("{what} {} is implausible (allowed range [{lo}, {hi}])", crate::error::shown(v))));
    }
    Ok(())
}

pub(super) fn from_table(table: RawTable, source: String, opts: &ReadOptions) -> Result<Dataset> {
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
    let mut first_payload_missing: Option<usize> = None;
    for raw in &table.rows {
        let line = raw.line;
        let q_deg = row_angles(&layout, &cells, raw, opts.angles)?;
        let socket = Column::Feature(layout.feature.unwrap_or(FeatureKind::Socket));
        let mixed = layout.measurement.is_some_and(|m| m.feature().is_none()) && layout.pos[socket.index()].is_some();
        let seated = mixed && label(layout.cell(raw, socket), socket, line, src)?.is_some();
        let (face, reading_mm) = reading_at(&layout, &cells, raw, seated, opts.euler)?;
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
        let block = label(layout.cell(raw, Column::Block), Column::Block, line, src)?;
        if layout.pos[Column::Block.index()].is_some() && block.is_none() {
            return Err(cell_error(src, line, Column::Block, "empty block label; when the file has a block column, every row must name its block"));
        }
        let feature_column = Column::Feature(layout.feature.unwrap_or(FeatureKind::Socket));
        let [station, mount, feature] = [Column::Station, Column::Mount, feature_column].map(|c| match label(layout.cell(raw, c), c, line, src) {
            // Beside a tracker's points, a row without a socket is a point, at no placement.
            Ok(None) if mixed && (c == socket || (c == Column::Station && !seated)) => Ok(None),
            // Beside faces, a row at a face names no socket.
            Ok(None) if face.is_some() && c == feature_column => Ok(None),
            Ok(None) if layout.pos[c.index()].is_some() => {
                let what = c.name();
                Err(cell_error(src, line, c, format!("empty {what} label; when the file has a {what} column, every row must name its {what}")))
            }
            other => other,
        });
        let (station, mount) = (station?, mount?);
        let kind = if face.is_some() { FeatureKind::Plane } else { layout.feature.unwrap_or(FeatureKind::Socket) };
        let feature = if face.is_some() { face } else { feature? }.map(|label| Feature { kind, label });
        let payload_kg = cells.number(layout.cell(raw, Column::Payload), Column::Payload, line)?;
        if let Some(m) = payload_kg {
            check_bounds(m, (0.0, MAX_PAYLOAD_KG), "payload (kg)", line, Column::Payload, src)?;
        }
        if payload_kg.is_none() {
            first_payload_missing = first_payload_missing.or(Some(line));
        }
        rows.push(Row { q_deg, reading_mm, t_s, temp_c, split, std_mm, block, payload_kg, station, mount, feature });
    }

    // A split column is all-or-nothing: a partially filled one would silently drop rows.
    if let Some(line) = first_split_missing {
        if rows.iter().any(|r| r.split.is_some()) {
            return Err(cell_error(src, line, Column::Split, "empty split value; when some rows have a split, every row must be train or test"));
        }
    }
    // So are `t` and `temp`: a model driven by them needs them on every row, and a gap would
    // silently drop the column from it (an empty column is no column).
    let gaps = [
        (Column::T, first_t_missing, rows.iter().any(|r| r.t_s.is_some())),
        (Column::Temp, first_temp_missing, rows.iter().any(|r| r.temp_c.is_some())),
        (Column::Payload, first_payload_missing, rows.iter().any(|r| r.payload_kg.is_some())),
    ];
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
    if layout.faces_beside.is_some() {
        super::beside::same_label_for_socket_and_face(&rows, src)?;
    }
    Ok(Dataset { rows, source })
}

/// A row's joint angles in degrees (converted from radians when the file's are), each plausible.
pub(super) fn row_angles(layout: &Layout, cells: &Cells, raw: &RawRow, angles: AngleUnit) -> Result<Vec<f64>> {
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
pub(super) fn row_reading(layout: &Layout, cells: &Cells, raw: &RawRow, euler: Euler) -> Result<Vec<f64>> {
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
    // Trailing angles of a rotation (a pose's) are turned into intrinsic X-Y-Z.
    if m.def().file_angles() == 3 && euler != Euler::XYZ {
        let n = reading_mm.len();
        let r = euler.matrix([reading_mm[n - 3].to_radians(), reading_mm[n - 2].to_radians(), reading_mm[n - 1].to_radians()]);
        let a = crate::measurement::pose::xyz_angles(&r);
        reading_mm[n - 3..].iter_mut().zip(a).for_each(|(v, a)| *v = a.to_degrees());
    }
    Ok(reading_mm)
}

/// A seated row's (a contact's) reading cells beside a tracker's points: empty (it reads
/// nothing). `feature`: the column naming the socket or face.
fn no_reading(layout: &Layout, cells: &Cells, raw: &RawRow, feature: Column) -> Result<Vec<f64>> {
    let Some(m) = layout.measurement else { return Ok(Vec::new()) };
    let what = if feature == Column::Feature(FeatureKind::Plane) { "a probe's contact with a face" } else { "a row seated in a socket" };
    for name in m.def().file_columns() {
        let c = Column::reading(name);
        if cells.number(layout.cell(raw, c), c, raw.line)?.is_some() {
            return Err(cell_error(
                cells.source,
                raw.line,
                c,
                format!("{what} reads nothing: leave the tracker's columns empty on it (or its {feature}, if the tracker read it)"),
            ));
        }
    }
    Ok(Vec::new())
}

/// A row's face (where it names one beside sockets) and its reading: a face's contact or
/// indicator reading, a seated row's nothing (`seated`: a socket beside a tracker's points), or
/// the instrument's columns.
fn reading_at(layout: &Layout, cells: &Cells, raw: &RawRow, seated: bool, euler: Euler) -> Result<(Option<String>, Vec<f64>)> {
    let face = layout.faces_beside.map(|m| face_beside(layout, cells, raw, m)).transpose()?.flatten();
    let socket = Column::Feature(layout.feature.unwrap_or(FeatureKind::Socket));
    match face {
        Some((label, reading)) => Ok((Some(label), reading)),
        None if seated => Ok((None, no_reading(layout, cells, raw, socket)?)),
        None => Ok((None, row_reading(layout, cells, raw, euler)?)),
    }
}

/// A row's face and reading where faces stand beside sockets (`m`: the faces' instrument):
/// `None` for a row seated in a socket (which reads nothing: an indicator's cell left empty),
/// else the face's label and the reading (a probe's contact reads nothing). A row naming both
/// a socket and a face, or neither, is an error.
fn face_beside(layout: &Layout, cells: &Cells, raw: &RawRow, m: Measurement) -> Result<Option<(String, Vec<f64>)>> {
    let (socket, plane) = (Column::Feature(FeatureKind::Socket), Column::Feature(FeatureKind::Plane));
    let (line, src) = (raw.line, cells.source);
    let (s, f) = (label(layout.cell(raw, socket), socket, line, src)?, label(layout.cell(raw, plane), plane, line, src)?);
    let reading = |c: &str| -> Result<Option<f64>> {
        let c = Column::reading(c);
        cells.number(layout.cell(raw, c), c, line)
    };
    match (s, f) {
        (Some(_), Some(_)) => Err(cell_error(src, line, plane, "the row names a socket and a face; a row is seated in a socket or touches a face, not both")),
        (None, None) => {
            Err(cell_error(src, line, socket, "the row names neither a socket nor a face; when the file has both columns, every row names one of them"))
        }
        (Some(_), None) => {
            if let Some(c) = m.def().file_columns().iter().find(|c| reading(c).ok().flatten().is_some()) {
                return Err(cell_error(src, line, c, "a row seated in a socket reads nothing: leave the indicator's column empty on it"));
            }
            Ok(None)
        }
        (None, Some(face)) => {
            let mut values = Vec::new();
            for (k, name) in m.def().file_columns().iter().enumerate() {
                let c = Column::reading(name);
                let v = cells.required(layout.cell(raw, c), c, line)?;
                if let Some(why) = m.def().implausible(k, v) {
                    return Err(cell_error(src, line, c, why));
                }
                values.push(v);
            }
            Ok(Some((face, values)))
        }
    }
}

/// A row's time `t` (s): plausible, and not before the previous row's (`last`: its time, line).
pub(super) fn check_time(t: f64, last: Option<(f64, usize)>, line: usize, src: &str) -> Result<()> {
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

/// The kind of artifact's feature the header's columns (their positions `pos`) name, if any.
fn feature_named(pos: &[Option<usize>]) -> Option<FeatureKind> {
    // Sockets and faces both named: one ball seated in the sockets and touching the faces, each
    // row at one of them (the sockets' kind is the file's; the faces stand beside them).
    FeatureKind::ALL.into_iter().find(|k| pos[Column::Feature(*k).index()].is_some())
}

/// Whether the header (its columns' positions `pos`) holds instrument `m`'s columns (an
/// instrument at an artifact's feature needs its feature's column too: a ball in a socket reads
/// nothing, its rows name their socket).
fn present(m: &Measurement, pos: &[Option<usize>]) -> bool {
    let columns = m.def().file_columns().iter().all(|c| pos[Column::reading(c).index()].is_some());
    match m.feature() {
        Some(k) => columns && pos[Column::Feature(k).index()].is_some(),
        None => columns && !m.def().file_columns().is_empty(),
    }
}

/// Seated rows beside a tracker's points (sockets plus a few points, one fit): the header's
/// instruments `complete` read as the points', the rows that name a socket reading nothing.
/// (A face's contact reads one value, a point three: a model's rows are one width, so faces
/// beside points are refused as two instruments.)
fn seated_beside_points(complete: &mut Vec<Measurement>) {
    if complete.len() == 2 && complete.contains(&Measurement::Socket) && complete.contains(&Measurement::Point) {
        complete.retain(|m| *m == Measurement::Point);
    }
}

/// Whether instrument `a`'s reading columns are all among `b`'s, at the same kind of feature
/// (a point's x, y, z in a pose's; a probe's contacts, which read nothing, in an indicator's).
fn within(a: &Measurement, b: &Measurement) -> bool {
    a != b && a.feature() == b.feature() && a.def().file_columns().iter().all(|c| b.def().file_columns().contains(c))
}

/// The spread (max − min) of `value` over `rows`.
fn span(rows: &[Row], value: impl Fn(&Row) -> f64) -> f64 {
    let (lo, hi) = rows.iter().map(value).fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| (lo.min(v), hi.max(v)));
    hi - lo
}

/// The error for a wider instrument's reading columns given in part beside the complete ones of
/// `m` (a pose's `rx, ry` without `rz` beside `x, y, z`), if any.
fn partial_wider(m: Measurement, pos: &[Option<usize>], source: &str, found: &str) -> Result<()> {
    for w in Measurement::ALL.into_iter().filter(|w| within(&m, w)) {
        let extra: Vec<&str> = w.def().file_columns().iter().copied().filter(|c| !m.def().file_columns().contains(c)).collect();
        let (given, lacking): (Vec<&str>, Vec<&str>) = extra.iter().copied().partition(|c| pos[Column::reading(c).index()].is_some());
        if !given.is_empty() {
            return Err(Error::data(
                source,
                format!(
                    "line 1: {} given without {}: a {} needs all of {} (or --measurement {} to read {} alone); header found: {found}",
                    given.join(", "),
                    lacking.join(", "),
                    w.def().describe(),
                    w.def().file_columns().join(", "),
                    m.name(),
                    m.def().file_columns().join(", "),
                ),
            ));
        }
    }
    Ok(())
}

/// The radians and metres heuristics described in the module docs (radians only with
/// [`AngleUnit::Auto`]).
pub(super) fn check_units(rows: &[Row], source: &str, angles: AngleUnit) -> Result<()> {
    let q: Vec<Vec<f64>> = if angles == AngleUnit::Auto { rows.iter().map(|r| r.q_deg.clone()).collect() } else { Vec::new() };
    if let Some((max_abs, widest, span)) = super::looks_like_radians(&q, RADIANS_MAX_ABS) {
        return Err(Error::data(
            source,
            format!(
                "columns q1..q{} look like radians (all {} rows have |q| <= {max_abs:.3}, q{} \
                 spans {span:.3}); the file must hold joint angles in degrees; if they really \
                 are degrees pass --angles deg (or --angles rad to convert)",
                q[0].len(),
                rows.len(),
                widest + 1
            ),
        ));
    }
    // The lengths: every reading column but a pose's angles.
    let measurement = rows.first().and_then(|r| r.measurement());
    let lengths = measurement.map_or(0, |m| m.file_lengths());
    // A pose's angles (rx, ry, rz, degrees) in radians: every one within ±π, one spanning more
    // than the radians heuristic's span.
    if let Some(m) = measurement.filter(|m| angles == AngleUnit::Auto && rows.len() >= RADIANS_MIN_ROWS && m.def().file_columns().len() > lengths) {
        let names = &m.def().file_columns()[lengths..];
        let max_abs = rows.iter().flat_map(|r| r.reading_mm[lengths..].iter()).fold(0.0_f64, |a, v| a.max(v.abs()));
        let widest = (lengths..lengths + names.len()).map(|k| span(rows, |r| r.reading_mm[k])).fold(0.0_f64, f64::max);
        if max_abs <= POSE_RADIANS_MAX_ABS && widest > RADIANS_MIN_SPAN {
            return Err(Error::data(
                source,
                format!(
                    "columns {} look like radians (all {} rows have |angle| <= {max_abs:.3}, one spans {widest:.3}); a pose's \
                     angles must be in degrees: convert them (x 180/pi), or pass --angles deg if they really are degrees",
                    names.join(", "),
                    rows.len()
                ),
            ));
        }
    }
    let max_abs = rows.iter().flat_map(|r| r.reading_mm.iter().take(lengths)).fold(None, |m: Option<f64>, v| Some(m.map_or(v.abs(), |m| m.max(v.abs()))));
    // (A dial indicator reads millimetres of travel: small readings are its kind.)
    if let (Some(max), Some(m)) = (max_abs, measurement.filter(|m| m.feature().is_none())) {
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
