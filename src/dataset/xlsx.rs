//! Spreadsheet reading (xlsx, and whatever else calamine opens) into a
//! [`RawTable`](super::RawTable). Line numbers are the spreadsheet's own row numbers.

use super::{Cell, RawRow, RawTable};
use crate::error::{Error, Result};
use calamine::{Data, Reader};
use std::path::Path;

/// Reads sheet `sheet` (or the first sheet) of the workbook at `path`. Returns the table and a
/// source label `path#Sheet` for messages, which [`Dataset::load`](super::Dataset::load) accepts.
///
/// The first row of the sheet's used range is the header; fully empty rows are skipped.
pub(super) fn read_table(path: &Path, sheet: Option<&str>) -> Result<(RawTable, String)> {
    // Report a missing/unreadable file as an I/O error, like the CSV path does.
    std::fs::metadata(path).map_err(|e| Error::io(path, e))?;
    let file = path.display().to_string();
    let mut workbook =
        calamine::open_workbook_auto(path).map_err(|e| Error::data(&file, format!("cannot open spreadsheet: {e}")))?;
    let names = workbook.sheet_names();
    let name = match sheet {
        Some(wanted) => names.iter().find(|n| n.as_str() == wanted).cloned().ok_or_else(|| {
            Error::data(&file, format!("no sheet named '{wanted}'; sheets found: {}", names.join(", ")))
        })?,
        None => names.first().cloned().ok_or_else(|| Error::data(&file, "workbook has no sheets"))?,
    };
    let source = format!("{file}#{name}");
    let range = workbook.worksheet_range(&name).map_err(|e| Error::data(&source, format!("cannot read sheet: {e}")))?;

    let first_row = range.start().map_or(0, |(r, _)| r as usize);
    let mut rows_iter = range.rows().enumerate().map(|(i, cells)| (first_row + i + 1, cells));
    let header = rows_iter
        .by_ref()
        .find(|(_, cells)| !cells.iter().all(is_blank))
        .map(|(_, cells)| cells.iter().map(header_text).collect::<Vec<_>>())
        .ok_or_else(|| {
            Error::data(&source, "sheet is empty: expected a header row with q1..q6 and L, then data rows")
        })?;
    let rows = rows_iter
        .filter(|(_, cells)| !cells.iter().all(is_blank))
        .map(|(line, cells)| RawRow { line, cells: cells.iter().map(cell).collect() })
        .collect();
    Ok((RawTable { header, rows }, source))
}

fn is_blank(d: &Data) -> bool {
    match d {
        Data::Empty => true,
        Data::String(s) => s.trim().is_empty(),
        _ => false,
    }
}

fn header_text(d: &Data) -> String {
    match d {
        Data::Empty => String::new(),
        other => other.to_string().trim().to_owned(),
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
