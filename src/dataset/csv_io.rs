//! CSV reading into a [`RawTable`](super::RawTable): structure only (header, field counts, line
//! numbers); interpretation of the cells happens in the parent module.

use super::table::{Cell, RawRow, RawTable};
use crate::error::{Error, Result};
use std::io::Read;

/// Reads CSV text. Lines starting with `#` are comments. The first other non-blank record is the
/// header, and its line decides the delimiter: `;` or tab when it holds more of them than commas
/// (a European spreadsheet export, whose numbers may then use a decimal comma), else `,`. Blank
/// lines and records whose fields are all empty (e.g. `,,,,,,` left by spreadsheet exports) are
/// skipped. Every other record must have exactly as many fields as the header.
pub(super) fn read_table<R: Read>(mut r: R, source: &str) -> Result<RawTable> {
    let mut bytes = Vec::new();
    r.read_to_end(&mut bytes).map_err(|e| Error::data(source, format!("cannot read: {e}")))?;
    blank_comments(&mut bytes);
    let delimiter = detect_delimiter(&bytes);
    let mut reader = csv::ReaderBuilder::new().has_headers(false).flexible(true).trim(csv::Trim::All).delimiter(delimiter).from_reader(bytes.as_slice());

    let mut lines = LineCounter::default();
    let mut header: Option<Vec<String>> = None;
    let mut rows = Vec::new();
    for record in reader.records() {
        let record = record.map_err(|e| {
            let line = e.position().map(|p| lines.at(&bytes, p.byte()));
            malformed(source, line, &e)
        })?;
        let line = record.position().map_or(0, |p| lines.at(&bytes, p.byte()));
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
                        .map(|(i, f)| if i == 0 { f.trim_start_matches('\u{feff}').trim() } else { f })
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
                let cells = record.iter().map(|f| if f.is_empty() { Cell::Empty } else { Cell::Text(f.to_owned()) }).collect();
                rows.push(RawRow { line, cells });
            }
        }
    }
    let header = header.ok_or_else(|| Error::data(source, "file is empty: expected a header line with q1..q6 and L, then data rows"))?;
    Ok(RawTable { header, rows, decimal_comma: delimiter != b',' })
}

/// Line numbers from byte offsets, counted from the file's line breaks (the csv crate's own line
/// count skips blank lines, and a record's offset is where the blank lines before it start, so
/// line breaks right at the offset are skipped first). Offsets must be asked for in increasing
/// order.
#[derive(Default)]
struct LineCounter {
    byte: usize,
    newlines: usize,
}

impl LineCounter {
    fn at(&mut self, bytes: &[u8], byte: u64) -> usize {
        let mut byte = (byte as usize).min(bytes.len()).max(self.byte);
        while byte < bytes.len() && matches!(bytes[byte], b'\r' | b'\n') {
            byte += 1;
        }
        self.newlines += bytes[self.byte..byte].iter().filter(|b| **b == b'\n').count();
        self.byte = byte;
        self.newlines + 1
    }
}

/// Turns every line starting with `#` into a blank line, keeping its line break so that line
/// numbers in messages still count it (the csv crate's own comment support does not).
fn blank_comments(bytes: &mut Vec<u8>) {
    let mut out = Vec::with_capacity(bytes.len());
    for line in bytes.split_inclusive(|b| *b == b'\n') {
        let body = line.strip_prefix(b"\xef\xbb\xbf").unwrap_or(line);
        if body.starts_with(b"#") {
            out.extend(line.iter().filter(|b| matches!(b, b'\r' | b'\n')));
        } else {
            out.extend_from_slice(line);
        }
    }
    *bytes = out;
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

fn malformed(source: &str, line: Option<usize>, e: &csv::Error) -> Error {
    match line {
        Some(line) => Error::data(source, format!("line {line}: malformed CSV: {e}")),
        None => Error::data(source, format!("malformed CSV: {e}")),
    }
}
