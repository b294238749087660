//! Loading a dataset from a folder, a CSV or an xlsx sheet, or from columns in memory.

use super::table::*;
use super::types::*;
use super::{csv_io, xlsx};
use crate::error::{Error, Result};
use crate::measurement::Measurement;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

impl Dataset {
    /// The rows at `idx` (in that order), from the same source.
    pub fn subset(&self, idx: &[usize]) -> Dataset {
        Dataset { rows: idx.iter().map(|&i| self.rows[i].clone()).collect(), source: self.source.clone() }
    }

    /// Load from a dataset folder (reads `DIR/dataset.csv`), a `.csv` file, or an `.xlsx` file (first
    /// sheet, or sheet named by `path.xlsx#SheetName`). See the [dataset module](crate::dataset) for the accepted
    /// columns and the validation performed.
    pub fn load(path: &Path) -> Result<Dataset> {
        Self::load_with(path, &ReadOptions::default())
    }

    /// [`Self::load`] with explicit [`ReadOptions`] (angle unit, whether `L` is required).
    pub fn load_with(path: &Path, opts: &ReadOptions) -> Result<Dataset> {
        if let Some(files) = artifact_files(path) {
            return Self::load_artifact(path, &files, opts);
        }
        if let Some(files) = campaign_files(path) {
            return Self::load_campaign(path, &files, opts);
        }
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

    /// A campaign: the CSV files of a folder (by name), each read on its own, their rows one
    /// after the other; a file's rows that name no station stand at a station named by the
    /// file (its name without `.csv`). The files must read the same instrument on the same arm.
    fn load_campaign(dir: &Path, files: &[PathBuf], opts: &ReadOptions) -> Result<Dataset> {
        let mut rows: Vec<Row> = Vec::new();
        let mut first: Option<(String, Option<Measurement>, usize)> = None;
        for f in files {
            let d = Self::load_csv_file(f, opts)?;
            let what = (d.source.clone(), d.measurement(), d.n_joints());
            match &first {
                Some((src, m, n)) if (*m, *n) != (what.1, what.2) => {
                    return Err(Error::data(
                        dir.display(),
                        format!(
                            "a campaign's files must read one instrument on one arm: {src} holds {n} joints and {}, {} holds {} and {}",
                            m.map_or("no readings", |m| m.def().describe()),
                            what.0,
                            what.2,
                            what.1.map_or("no readings", |m| m.def().describe())
                        ),
                    ))
                }
                Some(_) => {}
                None => first = Some(what),
            }
            let stem = f.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
            rows.extend(d.rows.into_iter().map(|r| Row { station: r.station.or_else(|| Some(stem.clone())), ..r }));
        }
        Ok(Dataset { rows, source: dir.display().to_string() })
    }

    /// A ball seated in an artifact's sockets, recorded as such tools record it: a folder of
    /// one folder per placement of the artifact, each with one CSV file per socket of the
    /// configurations seated in it (joint angles `q1..qN`, one row a configuration; `--angles
    /// rad` for radians). The rows stand at their placement (the folder's name) and in their
    /// socket (the file's name without `.csv`), in that order.
    fn load_artifact(dir: &Path, files: &[(String, PathBuf)], opts: &ReadOptions) -> Result<Dataset> {
        let mut rows: Vec<Row> = Vec::new();
        let poses = ReadOptions { require_length: false, measurement: None, ..*opts };
        for (placement, f) in files {
            let d = Self::load_csv_file(f, &poses)?;
            if let Some(m) = d.measurement() {
                return Err(Error::data(&d.source, format!("a socket's file holds joint angles only; this one reads a {} too", m.def().describe())));
            }
            if let Some(r) = rows.first().filter(|r| r.q_deg.len() != d.n_joints()) {
                return Err(Error::data(&d.source, format!("holds {} joint angles per row, the artifact's other files {}", d.n_joints(), r.q_deg.len())));
            }
            let socket = f.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
            rows.extend(d.rows.into_iter().map(|r| Row { station: Some(placement.clone()), feature: Some(Feature::socket(socket.clone())), ..r }));
        }
        Ok(Dataset { rows, source: dir.display().to_string() })
    }

    pub(super) fn load_csv_file(path: &Path, opts: &ReadOptions) -> Result<Dataset> {
        let file = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
        Self::from_csv_reader_with(std::io::BufReader::new(file), &path.display().to_string(), opts)
    }

    /// Parse and validate CSV text; `source` names the input in error messages and becomes
    /// [`Dataset::source`].
    pub fn from_csv_reader<R: std::io::Read>(r: R, source: &str) -> Result<Dataset> {
        Self::from_csv_reader_with(r, source, &ReadOptions::default())
    }

    /// [`Self::from_csv_reader`] with explicit [`ReadOptions`].
    pub fn from_csv_reader_with<R: std::io::Read>(r: R, source: &str, opts: &ReadOptions) -> Result<Dataset> {
        from_table(csv_io::read_table(r, source)?, source.to_owned(), opts)
    }

    /// A dataset from columns held in memory (numpy arrays from Python, say), read and validated
    /// exactly as a file with these columns would be: the same header rules, bounds, unit checks
    /// and messages. A missing number (NaN) in `sx, sy, sz` leaves the cell empty; elsewhere it
    /// is refused like a NaN cell. Messages name line k + 2 for row k (the header is line 1).
    pub fn from_columns(columns: Vec<(String, ColumnValues)>, source: &str, opts: &ReadOptions) -> Result<Dataset> {
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
    /// header's columns; the instrument at the artifact's feature when rows name one); `None`
    /// for a dataset of poses without readings.
    pub fn measurement(&self) -> Option<Measurement> {
        // Sockets seated beside faces touched: the sockets' rows are the first instrument's.
        let seated = self.rows.iter().find(|r| r.socket().is_some());
        if let Some(r) = seated.or_else(|| self.rows.iter().find(|r| r.feature.is_some())) {
            return r.measurement();
        }
        self.rows.first()?.measurement()
    }

    /// The other instrument whose rows stand beside the first's (a tracker's points beside
    /// seated rows), if any.
    pub fn also_measurement(&self) -> Option<Measurement> {
        let first = self.measurement()?;
        self.rows.iter().filter_map(|r| r.measurement()).find(|m| *m != first)
    }

    /// True when every row has a cable length (and there is at least one row).
    pub fn has_length(&self) -> bool {
        !self.rows.is_empty() && self.rows.iter().all(|r| r.l_mm().is_some())
    }

    /// True when every row has a reading (and there is at least one row).
    pub fn has_readings(&self) -> bool {
        !self.rows.is_empty() && self.rows.iter().all(|r| r.measurement().is_some())
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
        let kinds = [self.measurement(), self.also_measurement()];
        match self.rows.iter().position(|r| r.measurement().is_none() || !kinds.contains(&r.measurement())) {
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
    /// has them, and `t`, `temp`, `payload_kg`, `block`, `split` when every row has them; numbers (NaN where a row has no
    /// value) and `split` as text. [`Self::from_columns`] reads them back to the same rows.
    pub fn columns(&self) -> Vec<(String, ColumnValues)> {
        let all = |f: fn(&Row) -> bool| !self.rows.is_empty() && self.rows.iter().all(f);
        let number = |f: &dyn Fn(&Row) -> Option<f64>| ColumnValues::Numbers(self.rows.iter().map(|r| f(r).unwrap_or(f64::NAN)).collect());
        let reading_names: &[&str] = match self.rows.iter().find(|r| !r.reading_mm.is_empty()) {
            Some(r) => r.measurement().map_or(&[], |m| m.def().file_columns()),
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
        if all(|r| r.payload_kg.is_some()) {
            out.push(("payload_kg".into(), number(&|r: &Row| r.payload_kg)));
        }
        if all(|r| r.block.is_some()) {
            out.push(("block".into(), ColumnValues::Texts(self.rows.iter().map(|r| r.block.clone().unwrap_or_default()).collect())));
        }
        // (A tracker's points beside seated rows stand at no placement.)
        let beside = self.also_measurement().is_some();
        if self.rows.iter().all(|r| r.station.is_some() || (r.feature.is_none() && beside)) && self.rows.iter().any(|r| r.station.is_some()) {
            let name = if self.measurement().is_some_and(|m| m.feature().is_some()) { "placement" } else { "station" };
            out.push((name.into(), ColumnValues::Texts(self.rows.iter().map(|r| r.station.clone().unwrap_or_default()).collect())));
        }
        for kind in crate::measurement::FeatureKind::ALL {
            if self.rows.iter().any(|r| r.feature.as_ref().is_some_and(|f| f.kind == kind)) {
                let labels = self.rows.iter().map(|r| r.feature.as_ref().filter(|f| f.kind == kind).map(|f| f.label.clone()).unwrap_or_default()).collect();
                out.push((kind.column().into(), ColumnValues::Texts(labels)));
            }
        }
        if all(|r| r.mount.is_some()) {
            out.push(("mount".into(), ColumnValues::Texts(self.rows.iter().map(|r| r.mount.clone().unwrap_or_default()).collect())));
        }
        if all(|r| r.split.is_some()) {
            out.push(("split".into(), ColumnValues::Texts(self.rows.iter().map(|r| r.split.map_or("", |s| s.as_str()).to_string()).collect())));
        }
        out
    }

    /// Writes [`Self::to_csv_string`] to `path` atomically (all or nothing). For the folder layout
    /// read by [`Self::load`], pass `dir.join(DATASET_FILE)`.
    pub fn write_csv(&self, path: &Path) -> Result<()> {
        crate::output::write_atomic(path, self.to_csv_string().as_bytes())
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

    pub(super) fn indices_of(&self, split: Split) -> Vec<usize> {
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
/// fields, a byte-order mark. A header matches a name case-insensitively, also as `NAME_mm` or `NAME_deg`. A
/// non-finite cell (`NaN`, `inf`) reads as it is (the caller decides what that means); an empty
/// cell, a short row or other text is an error naming the line and column, as for a dataset's
/// cells. One `Vec` per row, in `names` order.
pub fn read_csv_columns(path: &Path, names: &[&str]) -> Result<Vec<Vec<f64>>> {
    CsvColumns::read(path)?.columns(names)
}

/// A CSV file read once, to ask for its columns by name ([`read_csv_columns`]'s rules).
pub struct CsvColumns {
    source: String,
    table: RawTable,
}

impl CsvColumns {
    /// Reads `path` (delimiter, decimal commas, comments, quotes and a byte-order mark as
    /// [`read_csv_columns`] reads them).
    pub fn read(path: &Path) -> Result<CsvColumns> {
        let source = path.display().to_string();
        let file = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
        let table = csv_io::read_table(std::io::BufReader::new(file), &source)?;
        Ok(CsvColumns { source, table })
    }

    fn matches(h: &str, n: &str) -> bool {
        let h = h.trim();
        h.eq_ignore_ascii_case(n) || ["_mm", "_deg"].iter().any(|u| h.eq_ignore_ascii_case(&format!("{n}{u}")))
    }

    /// Whether the header has a column `name` (also as `name_mm` or `name_deg`, any case).
    pub fn has(&self, name: &str) -> bool {
        self.table.header.iter().any(|h| Self::matches(h, name))
    }

    /// The header as the file gives it, comma-joined.
    pub fn header(&self) -> String {
        self.table.header.join(",")
    }

    /// Rows of data.
    pub fn len(&self) -> usize {
        self.table.rows.len()
    }

    /// No row of data.
    pub fn is_empty(&self) -> bool {
        self.table.rows.is_empty()
    }

    /// The columns `names`, one `Vec` per row in `names` order, or an error naming what is missing
    /// or malformed.
    pub fn columns(&self, names: &[&str]) -> Result<Vec<Vec<f64>>> {
        let (source, table) = (&self.source, &self.table);
        let found = self.header();
        let missing: Vec<&str> = names.iter().copied().filter(|n| !table.header.iter().any(|h| Self::matches(h, n))).collect();
        if !missing.is_empty() {
            let what = if missing.len() == 1 { "the column" } else { "the columns" };
            return Err(Error::data(source, format!("the header '{found}' lacks {what} {}", missing.join(", "))));
        }
        let pos: Vec<usize> = names.iter().map(|n| table.header.iter().position(|h| Self::matches(h, n)).unwrap_or(0)).collect();
        // A column named twice is ambiguous (which x?): refused, as the dataset reader refuses it.
        for (n, &i) in names.iter().zip(&pos) {
            if table.header.iter().enumerate().any(|(k, h)| k != i && Self::matches(h, n)) {
                return Err(Error::data(source, format!("the header '{found}' names the column {n} twice")));
            }
        }
        let cells = Cells { source, decimal_comma: table.decimal_comma };
        let value = |row: &RawRow, i: usize, name: &str| -> Result<f64> {
            let cell =
                row.cells.get(i).ok_or_else(|| Error::data(source, format!("line {}: {} fields, expected at least {}", row.line, row.cells.len(), i + 1)))?;
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
}

/// Splits `book.xlsx#Sheet` into the file and the sheet name. A path that exists as given is never
/// split; otherwise the first `#` whose prefix ends in a spreadsheet extension is the separator.
pub(super) fn split_sheet(path: &Path) -> (PathBuf, Option<String>) {
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

/// The files of a campaign folder: a folder without `dataset.csv` whose `.csv` files (by name)
/// are its sessions ([`Dataset::load`]); `None` for anything else.
pub fn campaign_files(path: &Path) -> Option<Vec<PathBuf>> {
    if !path.is_dir() || path.join(DATASET_FILE).exists() {
        return None;
    }
    let mut files: Vec<PathBuf> = std::fs::read_dir(path)
        .ok()?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.is_file() && p.extension().is_some_and(|e| e.eq_ignore_ascii_case("csv")))
        .collect();
    files.sort();
    (!files.is_empty()).then_some(files)
}

/// The files of an artifact's folder ([`Dataset::load`]): a folder without `dataset.csv` and
/// without CSV files of its own whose sub-folders (the placements) hold CSV files (the sockets),
/// each with its placement's name, sorted; `None` for any other path.
pub fn artifact_files(path: &Path) -> Option<Vec<(String, PathBuf)>> {
    if !path.is_dir() || path.join(DATASET_FILE).exists() || campaign_files(path).is_some() {
        return None;
    }
    let mut dirs: Vec<PathBuf> = std::fs::read_dir(path).ok()?.filter_map(|e| e.ok().map(|e| e.path())).filter(|p| p.is_dir()).collect();
    dirs.sort();
    let mut out = Vec::new();
    for d in dirs {
        let name = d.file_name().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
        out.extend(campaign_files(&d).unwrap_or_default().into_iter().map(|f| (name.clone(), f)));
    }
    (!out.is_empty()).then_some(out)
}
