//! The text of a program as the filter reads and edits it: comments and strings masked (byte
//! for byte, so that every offset found in the mask is the original's), numbers with their
//! spans and written precision, positions as line and column, and edits applied in place.

use crate::error::{Error, Result};
use std::ops::Range;

/// How a number is written.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Style {
    /// Decimal, with this many digits after the point (0: an integer).
    Decimal(usize),
    /// A KRL binary literal `'B0110'`, this many digits.
    Binary(usize),
}

/// One number of a program: where it is written, its value, how it is written.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct Num {
    /// Its bytes in the file.
    pub span: Range<usize>,
    /// Its value.
    pub value: f64,
    /// How it is written.
    pub style: Style,
}

/// `text` with every comment (from `comment` to the end of the line) and every string's
/// contents (between `quotes`) replaced by spaces, newlines kept: offsets in the mask are the
/// text's. A string left open at the end of its line is closed there.
pub(crate) fn mask(text: &str, comment: u8, quotes: &[u8]) -> String {
    let mut out = text.as_bytes().to_vec();
    let mut i = 0;
    let b = text.as_bytes();
    while i < b.len() {
        let c = b[i];
        if c == comment {
            while i < b.len() && b[i] != b'\n' {
                out[i] = b' ';
                i += 1;
            }
        } else if quotes.contains(&c) {
            i += 1;
            while i < b.len() && b[i] != c && b[i] != b'\n' {
                out[i] = b' ';
                i += 1;
            }
            i += 1;
        } else {
            i += 1;
        }
    }
    // Only ASCII bytes were replaced, by ASCII, and a multi-byte character lies wholly inside
    // a comment or a string (replaced byte by byte) or wholly outside: still UTF-8 unless a
    // character was cut, which spaces never do; fall back to a lossy copy regardless.
    String::from_utf8(out).unwrap_or_else(|e| String::from_utf8_lossy(e.as_bytes()).into_owned())
}

/// A program file as a reader reads it: its name (for messages), its text and its mask, and its
/// index among the program's files (`usize::MAX` for a file read for its frames only).
#[derive(Clone, Copy)]
pub(crate) struct Source<'a> {
    /// The file's name.
    pub name: &'a str,
    /// Its text.
    pub text: &'a str,
    /// Its text with comments and strings masked ([`mask`]).
    pub mask: &'a str,
    /// Its index among the program's files.
    pub file: usize,
}

/// 1-based line and column (in characters) of byte `at` of `text`.
pub(crate) fn line_col(text: &str, at: usize) -> (usize, usize) {
    let at = at.min(text.len());
    let before = &text[..text.floor_char_boundary_compat(at)];
    let line = before.matches('\n').count() + 1;
    let col = before.rsplit('\n').next().map_or(0, |l| l.chars().count()) + 1;
    (line, col)
}

/// The starts of a text's lines, for line and column of many offsets (each a binary search, not
/// a scan from the start).
pub(crate) struct Lines<'a> {
    text: &'a str,
    starts: Vec<usize>,
}

impl<'a> Lines<'a> {
    /// The line starts of `text`.
    pub(crate) fn new(text: &'a str) -> Lines<'a> {
        let starts = std::iter::once(0).chain(text.bytes().enumerate().filter(|(_, b)| *b == b'\n').map(|(i, _)| i + 1)).collect();
        Lines { text, starts }
    }
    /// 1-based line and column (in characters) of byte `at`, as [`line_col`].
    pub(crate) fn at(&self, at: usize) -> (usize, usize) {
        let at = self.text.floor_char_boundary_compat(at.min(self.text.len()));
        let line = self.starts.partition_point(|s| *s <= at);
        let start = self.starts[line - 1];
        (line, self.text[start..at].chars().count() + 1)
    }
}

/// `str::floor_char_boundary` on stable Rust.
trait FloorBoundary {
    fn floor_char_boundary_compat(&self, i: usize) -> usize;
}
impl FloorBoundary for str {
    fn floor_char_boundary_compat(&self, mut i: usize) -> usize {
        while i > 0 && !self.is_char_boundary(i) {
            i -= 1;
        }
        i
    }
}

/// An error at byte `at` of file `file`: `file:line:col: message`.
pub(crate) fn error_at(file: &str, text: &str, at: usize, message: impl std::fmt::Display) -> Error {
    let (l, c) = line_col(text, at);
    Error::Invalid(format!("{file}:{l}:{c}: {message}"))
}

/// The number written at the start of `s` (`-1.5`, `+2`, `.5`, `9E+09`), and its length and
/// style; `None` if `s` does not start with one.
fn number_at(s: &[u8]) -> Option<(f64, usize, Style)> {
    let mut i = 0;
    if i < s.len() && (s[i] == b'-' || s[i] == b'+') {
        i += 1;
    }
    let int_start = i;
    while i < s.len() && s[i].is_ascii_digit() {
        i += 1;
    }
    let mut decimals = 0;
    let has_int = i > int_start;
    if i < s.len() && s[i] == b'.' {
        let frac = i + 1;
        i += 1;
        while i < s.len() && s[i].is_ascii_digit() {
            i += 1;
        }
        decimals = i - frac;
    }
    if !has_int && decimals == 0 {
        return None;
    }
    if i < s.len() && (s[i] == b'e' || s[i] == b'E') {
        let mut j = i + 1;
        if j < s.len() && (s[j] == b'-' || s[j] == b'+') {
            j += 1;
        }
        let digits = j;
        while j < s.len() && s[j].is_ascii_digit() {
            j += 1;
        }
        if j > digits {
            i = j;
        }
    }
    let text = std::str::from_utf8(&s[..i]).ok()?;
    text.parse::<f64>().ok().map(|v| (v, i, Style::Decimal(decimals)))
}

/// Largest magnitude of a number in a target's data (RAPID writes an unused external axis as
/// 9E+09).
const MAX_NUMBER: f64 = 1e10;

/// The numbers in `range` of the (masked) `text`, in order; an error (by line and column of
/// `file`) at anything in it that is neither a number, nor punctuation of `allowed`, nor a
/// name of letters (`TRUE`, `FALSE`, a KRL field name): such a literal is not the data the
/// language's type holds. KRL binary literals `'B0110'` read as numbers.
pub(crate) fn numbers_in(file: &str, text: &str, range: Range<usize>, allowed: &[u8]) -> Result<Vec<Num>> {
    let b = text.as_bytes();
    let mut out = Vec::new();
    let mut i = range.start;
    while i < range.end {
        let c = b[i];
        if c.is_ascii_whitespace() || allowed.contains(&c) {
            i += 1;
        } else if c == b'\'' && b.get(i + 1).is_some_and(|x| *x == b'B' || *x == b'b') {
            let start = i;
            let mut j = i + 2;
            while j < range.end && (b[j] == b'0' || b[j] == b'1') {
                j += 1;
            }
            if j >= range.end || b[j] != b'\'' {
                return Err(error_at(file, text, start, "a binary literal 'B...' is not closed"));
            }
            let digits = &text[start + 2..j];
            let value = i64::from_str_radix(digits, 2).map_err(|_| error_at(file, text, start, "an empty binary literal"))? as f64;
            out.push(Num { span: start..j + 1, value, style: Style::Binary(digits.len()) });
            i = j + 1;
        } else if c.is_ascii_alphabetic() || c == b'_' || c == b'$' || c == b'#' {
            // A name: a field label, a boolean, a constant like 9E+09 never starts with a letter.
            while i < range.end && (b[i].is_ascii_alphanumeric() || b[i] == b'_' || b[i] == b'$' || b[i] == b'#') {
                i += 1;
            }
        } else if let Some((value, len, style)) = number_at(&b[i..range.end]) {
            // A number glued to a letter or a second point (1.2.3, 5x) is not a number.
            if b.get(i + len).is_some_and(|n| n.is_ascii_alphanumeric() || *n == b'.' || *n == b'_') && i + len < range.end {
                return Err(error_at(file, text, i, format!("'{}' is not a number", token(text, i, range.end))));
            }
            // An overflowing literal (1e999) is no target's number; RAPID's unused axis is 9E+09.
            if !value.is_finite() || value.abs() > MAX_NUMBER {
                return Err(error_at(file, text, i, format!("'{}' is beyond any target's number (|v| <= {MAX_NUMBER:e})", token(text, i, range.end))));
            }
            out.push(Num { span: i..i + len, value, style });
            i += len;
        } else {
            return Err(error_at(file, text, i, format!("unexpected '{}'", token(text, i, range.end))));
        }
    }
    Ok(out)
}

/// The token at `at` (up to a separator), for messages.
fn token(text: &str, at: usize, end: usize) -> String {
    text[at..end].chars().take_while(|c| !c.is_whitespace() && !",;[]{}()".contains(*c)).take(24).collect::<String>().chars().take(24).collect()
}

/// The end (exclusive) of the bracketed group that opens at `open` (`[`, `{` or `(`) in the
/// masked `text`, nested groups of all three kinds inside; an error where it does not close
/// or closes with the wrong bracket.
pub(crate) fn group_end(file: &str, text: &str, open: usize) -> Result<usize> {
    let b = text.as_bytes();
    let mut stack = Vec::new();
    for (i, &c) in b.iter().enumerate().skip(open) {
        match c {
            b'[' | b'{' | b'(' => stack.push((c, i)),
            b']' | b'}' | b')' => {
                let want = match c {
                    b']' => b'[',
                    b'}' => b'{',
                    _ => b'(',
                };
                match stack.pop() {
                    Some((o, _)) if o == want => {}
                    Some((o, at)) => {
                        return Err(error_at(file, text, i, format!("'{}' closes the '{}' opened at {}", c as char, o as char, at_text(text, at))))
                    }
                    None => return Err(error_at(file, text, i, format!("'{}' closes nothing", c as char))),
                }
                if stack.is_empty() {
                    return Ok(i + 1);
                }
            }
            b';' if stack.iter().all(|(o, _)| *o != b'(') && b[open] == b'[' => {
                return Err(error_at(file, text, open, "the data's '[' is not closed before the end of the statement"));
            }
            _ => {}
        }
    }
    Err(error_at(file, text, open, format!("'{}' is never closed", b[open] as char)))
}

fn at_text(text: &str, at: usize) -> String {
    let (l, c) = line_col(text, at);
    format!("{l}:{c}")
}

/// Splits `range` of the masked `text` at the commas outside brackets: the ranges of the parts.
pub(crate) fn split_top(text: &str, range: Range<usize>) -> Vec<Range<usize>> {
    split_top_at(text, range, b',')
}

/// Splits `range` of the masked `text` at each `separator` outside brackets: the ranges of the
/// parts, the separators left out.
pub(crate) fn split_top_at(text: &str, range: Range<usize>, separator: u8) -> Vec<Range<usize>> {
    let b = text.as_bytes();
    let (mut depth, mut start, mut out) = (0i32, range.start, Vec::new());
    for i in range.clone() {
        match b[i] {
            b'[' | b'{' | b'(' => depth += 1,
            b']' | b'}' | b')' => depth -= 1,
            c if c == separator && depth == 0 => {
                out.push(start..i);
                start = i + 1;
            }
            _ => {}
        }
    }
    out.push(start..range.end);
    out
}

/// The lines of (masked) text, each trimmed.
pub(crate) fn lines(m: &str) -> Vec<Range<usize>> {
    let mut out = Vec::new();
    let mut start = 0;
    for (i, c) in m.bytes().enumerate() {
        if c == b'\n' {
            out.push(trim(m, start..i));
            start = i + 1;
        }
    }
    out.push(trim(m, start..m.len()));
    out
}

/// `range` without its leading and trailing whitespace.
pub(crate) fn trim(text: &str, range: Range<usize>) -> Range<usize> {
    let s = &text[range.clone()];
    let start = range.start + (s.len() - s.trim_start().len());
    let end = range.end - (s.len() - s.trim_end().len());
    start..end.max(start)
}

/// Whether `s` is a plain name (a letter or `_`, then letters, digits, `_`).
pub(crate) fn is_name(s: &str) -> bool {
    let mut c = s.chars();
    c.next().is_some_and(|f| f.is_ascii_alphabetic() || f == '_' || f == '$') && c.all(|x| x.is_ascii_alphanumeric() || x == '_')
}

/// A number written for the slot of `old`: as many decimals as it had, at least `min`; a
/// binary literal as binary of its width. Zero is written without a sign.
pub(crate) fn write(value: f64, old: &Num, min: usize) -> String {
    match old.style {
        Style::Binary(width) => format!("'B{:0width$b}'", value.round().max(0.0) as i64),
        Style::Decimal(d) if d == 0 && min == 0 => format!("{}", value.round() as i64),
        Style::Decimal(d) => {
            let d = d.max(min);
            let s = format!("{value:.d$}");
            if s.trim_start_matches('-').chars().all(|c| c == '0' || c == '.') {
                s.trim_start_matches('-').to_string()
            } else {
                s
            }
        }
    }
}

/// `text` with each `(span, replacement)` applied (spans sorted by their start, none
/// overlapping).
pub(crate) fn apply(text: &str, mut edits: Vec<(Range<usize>, String)>) -> String {
    edits.sort_by_key(|e| e.0.start);
    let mut out = String::with_capacity(text.len() + 16 * edits.len());
    let mut at = 0;
    for (span, new) in edits {
        debug_assert!(span.start >= at, "overlapping edits");
        out.push_str(&text[at..span.start]);
        out.push_str(&new);
        at = span.end;
    }
    out.push_str(&text[at..]);
    out
}
