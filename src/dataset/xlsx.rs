//! Spreadsheet reading (xlsx, and whatever else calamine opens) into a
//! [`RawTable`](super::RawTable). Line numbers are the spreadsheet's own row numbers.
//!
//! xlsx/xlsm and xlsb sheets are streamed cell by cell and kept sparse, so memory follows the
//! number of filled cells, never the used range: one stray cell at `XFD1048576` would otherwise
//! make a dense range of 17 billion cells. At most [`MAX_SHEET_CELLS`] filled cells are read.
//! `.xls` and `.ods` have no streaming reader in calamine and are read as a dense range (their
//! formats bound it: 65 536 × 256 cells for `.xls`). The file's first bytes are checked against
//! its extension first (a CSV saved as `.xlsx` is reported as such), and a panic inside calamine
//! (e.g. a cell pointing at a shared string that does not exist) becomes an error.

use super::table::{Cell, RawRow, RawTable};
use crate::error::{Error, Result};
use calamine::{Data, Reader};
use std::collections::BTreeMap;
use std::io::Read;
use std::path::Path;

/// Largest number of filled cells read from one sheet (100 000 rows of 20 columns).
pub const MAX_SHEET_CELLS: usize = 2_000_000;

/// Filled cells by row, then column (0-based), as read.
type Sparse = BTreeMap<u32, Vec<(u32, Data)>>;

/// Reads sheet `sheet` (or the first sheet) of the workbook at `path`. Returns the table and a
/// source label `path#Sheet` for messages, which [`Dataset::load`](super::Dataset::load) accepts.
///
/// The first row with a filled cell is the header; rows with no filled cell under a header column
/// are skipped, and cells right of the header are ignored.
pub(super) fn read_table(path: &Path, sheet: Option<&str>) -> Result<(RawTable, String)> {
    let file = path.display().to_string();
    check_magic(path, &file)?;
    let (cells, source) = match crate::output::catch_quietly(|| read_sparse(path, sheet, &file)) {
        Ok(r) => r?,
        Err(what) => return Err(Error::data(&file, format!("cannot read spreadsheet: the file is malformed (the reader failed: {what})"))),
    };
    Ok((to_table(cells, &source)?, source))
}

/// Refuses a file whose first bytes do not match its spreadsheet extension, saying what it looks
/// like instead (CSV text, the other spreadsheet family, nothing at all).
fn check_magic(path: &Path, file: &str) -> Result<()> {
    let mut head = Vec::with_capacity(4096);
    std::fs::File::open(path).and_then(|f| f.take(4096).read_to_end(&mut head)).map_err(|e| Error::io(path, e))?;
    const ZIP: &[u8] = b"PK\x03\x04";
    const OLE: &[u8] = b"\xd0\xcf\x11\xe0\xa1\xb1\x1a\xe1";
    let ext = path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase).unwrap_or_default();
    let expect_ole = ext == "xls";
    if (expect_ole && head.starts_with(OLE)) || (!expect_ole && head.starts_with(ZIP)) {
        return Ok(());
    }
    let what = if head.is_empty() {
        "it is empty".to_string()
    } else if !expect_ole && head.starts_with(OLE) {
        "it is an OLE compound file (an old .xls workbook, or a password-protected one); save it \
         as .xlsx or .csv"
            .to_string()
    } else if expect_ole && head.starts_with(ZIP) {
        "it is a zip file, like .xlsx; rename it to .xlsx".to_string()
    } else if looks_like_text(&head) {
        let csv = head.iter().any(|b| matches!(b, b',' | b';' | b'\t'));
        if csv {
            "it looks like CSV text; rename it to .csv".to_string()
        } else {
            "it looks like plain text".to_string()
        }
    } else {
        let hex: Vec<String> = head.iter().take(4).map(|b| format!("{b:02x}")).collect();
        format!("it starts with bytes {} (an .{ext} file is a zip archive)", hex.join(" "))
    };
    Err(Error::data(file, format!("the file is not a spreadsheet: {what}")))
}

/// No NUL byte and valid UTF-8 (an incomplete character at the cut is allowed).
fn looks_like_text(head: &[u8]) -> bool {
    !head.contains(&0)
        && match std::str::from_utf8(head) {
            Ok(_) => true,
            Err(e) => e.error_len().is_none(),
        }
}

/// Opens the workbook and collects the filled cells of the sheet.
fn read_sparse(path: &Path, sheet: Option<&str>, file: &str) -> Result<(Sparse, String)> {
    let mut workbook = calamine::open_workbook_auto(path).map_err(|e| Error::data(file, format!("cannot open spreadsheet: {e}")))?;
    let names = workbook.sheet_names();
    let name = match sheet {
        Some(wanted) => names
            .iter()
            .find(|n| n.as_str() == wanted)
            .cloned()
            .ok_or_else(|| Error::data(file, format!("no sheet named '{wanted}'; sheets found: {}", names.join(", "))))?,
        None => names.first().cloned().ok_or_else(|| Error::data(file, "workbook has no sheets"))?,
    };
    let source = format!("{file}#{name}");
    let cannot = |e: &dyn std::fmt::Display| Error::data(&source, format!("cannot read sheet: {e}"));
    let mut cells = Collector { cells: Sparse::new(), count: 0, source: &source };
    match &mut workbook {
        calamine::Sheets::Xlsx(x) => {
            let mut r = x.worksheet_cells_reader(&name).map_err(|e| cannot(&e))?;
            while let Some(c) = r.next_cell().map_err(|e| cannot(&e))? {
                cells.push(c.get_position(), Data::from(c.get_value().clone()))?;
            }
        }
        calamine::Sheets::Xlsb(x) => {
            let mut r = x.worksheet_cells_reader(&name).map_err(|e| cannot(&e))?;
            while let Some(c) = r.next_cell().map_err(|e| cannot(&e))? {
                cells.push(c.get_position(), Data::from(c.get_value().clone()))?;
            }
        }
        other => {
            let range = other.worksheet_range(&name).map_err(|e| cannot(&e))?;
            let (r0, c0) = range.start().unwrap_or((0, 0));
            for (r, c, v) in range.used_cells() {
                cells.push((r0 + r as u32, c0 + c as u32), v.clone())?;
            }
        }
    }
    Ok((cells.cells, source))
}

struct Collector<'a> {
    cells: Sparse,
    count: usize,
    source: &'a str,
}

impl Collector<'_> {
    fn push(&mut self, (row, col): (u32, u32), v: Data) -> Result<()> {
        if is_blank(&v) {
            return Ok(());
        }
        self.count += 1;
        if self.count > MAX_SHEET_CELLS {
            return Err(Error::data(self.source, format!("sheet has more than {MAX_SHEET_CELLS} filled cells; a dataset is far smaller")));
        }
        self.cells.entry(row).or_default().push((col, v));
        Ok(())
    }
}

/// The header (first filled row) and data rows, each only as wide as needed.
fn to_table(cells: Sparse, source: &str) -> Result<RawTable> {
    let mut rows = cells.into_iter();
    let (_, header_cells) = rows.next().ok_or_else(|| Error::data(source, "sheet is empty: expected a header row with q1..q6 and L, then data rows"))?;
    let width = header_cells.iter().map(|(c, _)| *c as usize + 1).max().unwrap_or(0);
    let mut header = vec![String::new(); width];
    for (c, v) in &header_cells {
        header[*c as usize] = v.to_string().trim().to_owned();
    }
    let rows = rows
        .filter_map(|(r, filled)| {
            let inside: Vec<&(u32, Data)> = filled.iter().filter(|(c, _)| (*c as usize) < width).collect();
            let len = inside.iter().map(|(c, _)| *c as usize + 1).max()?;
            let mut out = vec![Cell::Empty; len];
            for (c, v) in inside {
                out[*c as usize] = cell(v);
            }
            Some(RawRow { line: r as usize + 1, cells: out })
        })
        .collect();
    Ok(RawTable { header, rows, decimal_comma: false })
}

fn is_blank(d: &Data) -> bool {
    match d {
        Data::Empty => true,
        Data::String(s) => s.trim().is_empty(),
        _ => false,
    }
}

fn cell(d: &Data) -> Cell {
    match d {
        Data::Empty => Cell::Empty,
        Data::Float(f) => Cell::Number(*f),
        Data::Int(i) => Cell::Number(*i as f64),
        Data::String(s) if s.trim().is_empty() => Cell::Empty,
        Data::String(s) => Cell::Text(s.trim().to_owned()),
        Data::Bool(b) => Cell::Other(format!("boolean {b}")),
        Data::DateTime(dt) => Cell::Other(format!("date/time {dt}")),
        Data::DateTimeIso(s) | Data::DurationIso(s) => Cell::Other(format!("date/time {s}")),
        Data::Error(e) => Cell::Other(format!("spreadsheet error {e}")),
    }
}
