//! CSV reading into a [`RawTable`](super::RawTable): structure only (header, field counts, line
//! numbers); interpretation of the cells happens in the parent module.

use super::{Cell, RawRow, RawTable};
use crate::error::{Error, Result};
use std::io::Read;

/// Reads CSV text. Lines starting with `#` are comments. The first other non-blank record is the
/// header, and its line decides the delimiter: `;` or tab when it holds more of them than commas
/// (a European spreadsheet export, whose numbers may then use a decimal comma), else `,`. Blank
/// lines and records whose fields are all empty (e.g. `,,,,,,` left by spreadsheet exports) are
/// skipped. Every other record must have exactly as many fields as the header.
pub(super) fn read_table<R: Read>(mut r: R, source: &str) -> Result<RawTable> {
    let mut bytes = Vec::new();
    r.read_to_end(&mut bytes)
        .map_err(|e| Error::data(source, format!("cannot read: {e}")))?;
    let delimiter = detect_delimiter(&bytes);
    let mut reader = csv::ReaderBuilder::new()
        .has_headers(false)
        .flexible(true)
        .trim(csv::Trim::All)
        .comment(Some(b'#'))
        .delimiter(delimiter)
        .from_reader(bytes.as_slice());

    let mut header: Option<Vec<String>> = None;
    let mut rows = Vec::new();
    for record in reader.records() {
        let record = record.map_err(|e| malformed(source, &e))?;
        let line = record.position().map_or(0, |p| p.line() as usize);
        if record.iter().all(str::is_empty) {
            continue;
        }
        match &header {
            None => {
                header = Some(
                    record
                        .iter()
                        .enumerate()
                        // A UTF-8 byte order mark survives trimming: drop it from the first name.
                        .map(|(i, f)| {
                            if i == 0 {
                                f.trim_start_matches('\u{feff}').trim()
                            } else {
                                f
                            }
                        })
                        .map(str::to_owned)
                        .collect(),
                );
            }
            Some(h) => {
                if record.len() != h.len() {
                    return Err(Error::data(
                        source,
                        format!(
                            "line {line}: malformed CSV: expected {} fields (as in the header), \
                             found {}",
                            h.len(),
                            record.len()
                        ),
                    ));
                }
                let cells = record
                    .iter()
                    .map(|f| {
                        if f.is_empty() {
                            Cell::Empty
                        } else {
                            Cell::Text(f.to_owned())
                        }
                    })
                    .collect();
                rows.push(RawRow { line, cells });
            }
        }
    }
    let header = header.ok_or_else(|| {
        Error::data(
            source,
            "file is empty: expected a header line with q1..q6 and L, then data rows",
        )
    })?;
    Ok(RawTable {
        header,
        rows,
        decimal_comma: delimiter != b',',
    })
}

/// The delimiter of the header line: the first line that is neither blank nor a `#` comment.
fn detect_delimiter(bytes: &[u8]) -> u8 {
    let header = bytes
        .split(|b| *b == b'\n')
        .map(|l| l.strip_prefix(b"\xef\xbb\xbf").unwrap_or(l))
        .find(|l| {
            let t = l.trim_ascii();
            !t.is_empty() && !l.starts_with(b"#")
        })
        .unwrap_or(&[]);
    let count = |d: u8| header.iter().filter(|b| **b == d).count();
    let (commas, semis, tabs) = (count(b','), count(b';'), count(b'\t'));
    if semis > commas && semis >= tabs {
        b';'
    } else if tabs > commas && tabs > semis {
        b'\t'
    } else {
        b','
    }
}

fn malformed(source: &str, e: &csv::Error) -> Error {
    match e.position() {
        Some(p) => Error::data(source, format!("line {}: malformed CSV: {e}", p.line())),
        None => Error::data(source, format!("malformed CSV: {e}")),
    }
}
