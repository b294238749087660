//! KUKA KRL read for filtering: `POS` / `E6POS` / `AXIS` / `E6AXIS` data of the data list
//! (`.dat`) and inline aggregates of the program (`.src`), moved by `PTP`, `LIN`, `CIRC` (and
//! their spline forms `SPTP`, `SLIN`, `SCIRC`) with the tool and base the program last selected
//! (`$TOOL = TOOL_DATA[n]`, `BAS(#TOOL, n)`, an inline form's `FDAT` with its `TOOL_NO` and
//! `BASE_NO`); `TOOL_DATA` and `BASE_DATA` from `$config.dat` (given with the program's
//! frames) or any `FRAME` the files declare. `$ROBROOT` is taken as the world frame.

use super::text::{self, error_at, group_end, lines, numbers_in, split_top, trim, Num, Source};
use super::{Layout, Left, Parsed, Reader, RunTime, Site};
use crate::controller::ProgramFile;
use crate::error::Result;
use crate::measurement::Euler;
use nalgebra::{Isometry3, Translation3, UnitQuaternion};
use std::collections::BTreeMap;
use std::ops::Range;

pub(super) struct KrlReader;

/// Motions and how many targets each takes.
const MOTIONS: [(&str, usize); 6] = [("PTP", 1), ("LIN", 1), ("CIRC", 2), ("SPTP", 1), ("SLIN", 1), ("SCIRC", 2)];

/// The tool and base before the program selects any.
const UNSET: &str = "(not selected)";

/// The program's state as it is read: the declared points, the frames' names, the FDATs.
#[derive(Default)]
struct State {
    declared: BTreeMap<String, usize>,
    fdat: BTreeMap<String, (i64, i64)>,
    tool: String,
    base: String,
}

impl Reader for KrlReader {
    fn defaults(&self) -> (&'static str, &'static str) {
        ("$NULLFRAME", "$NULLFRAME")
    }

    fn parse(&self, files: &[ProgramFile], frames: &[ProgramFile]) -> Result<Parsed> {
        let mut p = Parsed::default();
        let mut st = State { tool: UNSET.into(), base: UNSET.into(), ..State::default() };
        p.frames.insert("BASE_DATA[0]".into(), Some(Isometry3::identity()));
        p.tools.insert("TOOL_DATA[0]".into(), Some(Isometry3::identity()));
        for f in frames {
            let m = text::mask(&f.text, b';', b"\"");
            for line in lines(&m) {
                data_line(&f.name, &f.text, &m, line, usize::MAX, &mut p, &mut st)?;
            }
        }
        let masks: Vec<String> = files.iter().map(|f| text::mask(&f.text, b';', b"\"")).collect();
        // The data lists first (a program's points are declared there), then the programs.
        let mut order: Vec<usize> = (0..files.len()).collect();
        order.sort_by_key(|&i| !files[i].name.to_ascii_lowercase().ends_with(".dat"));
        for &i in &order {
            for line in lines(&masks[i]) {
                data_line(&files[i].name, &files[i].text, &masks[i], line, i, &mut p, &mut st)?;
            }
        }
        for &i in &order {
            for line in lines(&masks[i]) {
                code_line(&files[i].name, &files[i].text, &masks[i], line, i, &mut p, &mut st)?;
            }
        }
        Ok(p)
    }
}

/// An aggregate `{X 1.0,Y 2,...}` at `open`: its fields (upper case) and their numbers.
fn aggregate(name: &str, src: &str, m: &str, open: usize) -> Result<(BTreeMap<String, Num>, Range<usize>)> {
    let end = group_end(name, m, open)?;
    let mut fields = BTreeMap::new();
    for part in split_top(m, open + 1..end - 1) {
        let part = trim(m, part);
        if part.is_empty() {
            continue;
        }
        let label: String = m[part.clone()].chars().take_while(|c| c.is_ascii_alphanumeric() || *c == '_').collect();
        let nums = numbers_in(name, src, part.start + label.len()..part.end, b"")?;
        match nums.as_slice() {
            [n] if !label.is_empty() => {
                fields.insert(label.to_ascii_uppercase(), n.clone());
            }
            _ => return Err(error_at(name, src, part.start, format!("'{}' is not a field and its number", &src[part.clone()]))),
        }
    }
    Ok((fields, open..end))
}

/// A site's layout and numbers from an aggregate's fields, or why it is left.
fn point(kind: &str, fields: &BTreeMap<String, Num>) -> Option<(Layout, Vec<Num>, Option<Left>)> {
    let get = |names: &[&str]| names.iter().map(|n| fields.get(*n).cloned()).collect::<Option<Vec<Num>>>();
    match kind {
        "POS" | "E6POS" | "FRAME_POINT" => match (get(&["X", "Y", "Z", "A", "B", "C"]), get(&["S", "T"])) {
            (Some(mut v), Some(st)) => {
                v.extend(st);
                Some((Layout::KrlPose { config: true }, v, None))
            }
            (Some(v), None) => Some((Layout::KrlPose { config: false }, v, None)),
            (None, _) => Some((
                Layout::KrlPose { config: false },
                Vec::new(),
                Some(Left::RunTime("a partial aggregate: the controller completes it from the arm's position".into())),
            )),
        },
        "AXIS" | "E6AXIS" => match get(&["A1", "A2", "A3", "A4", "A5", "A6"]) {
            Some(v) => Some((Layout::KrlJoints, v, None)),
            None => {
                Some((Layout::KrlJoints, Vec::new(), Some(Left::RunTime("a partial aggregate: the controller completes it from the arm's position".into()))))
            }
        },
        _ => None,
    }
}

/// A frame (mm; A, B, C Z-Y-X degrees) from an aggregate's fields.
fn frame(fields: &BTreeMap<String, Num>) -> Option<Isometry3<f64>> {
    let v: Vec<f64> = ["X", "Y", "Z", "A", "B", "C"].iter().map(|k| fields.get(*k).map_or(0.0, |n| n.value)).collect();
    let r = Euler::ZYX.matrix([v[3], v[4], v[5]].map(f64::to_radians));
    Some(Isometry3::from_parts(Translation3::new(v[0], v[1], v[2]), UnitQuaternion::from_matrix(&r)))
}

/// A line of a data list (or of `$config.dat`): `DECL [GLOBAL] TYPE NAME={...}` or
/// `TOOL_DATA[n]={...}` / `BASE_DATA[n]={...}`.
fn data_line(name: &str, src: &str, m: &str, line: Range<usize>, file: usize, p: &mut Parsed, st: &mut State) -> Result<()> {
    let s = &m[line.clone()];
    let Some(eq) = s.find('=') else { return Ok(()) };
    let Some(open) = s[eq..].find('{').map(|k| line.start + eq + k) else { return Ok(()) };
    if !m[line.start + eq + 1..open].trim().is_empty() {
        return Ok(());
    }
    let head: Vec<String> = s[..eq].split_whitespace().map(str::to_ascii_uppercase).collect();
    let head: Vec<&str> = head.iter().map(String::as_str).filter(|w| *w != "GLOBAL").collect();
    let (fields, _) = aggregate(name, src, m, open)?;
    match head.as_slice() {
        ["DECL", "FRAME", var] => {
            p.frames.insert(var.to_string(), frame(&fields));
            p.tools.insert(var.to_string(), frame(&fields));
        }
        ["DECL", "FDAT", var] => {
            let no = |k: &str| fields.get(k).map_or(0, |n| n.value.round() as i64);
            st.fdat.insert(var.to_string(), (no("TOOL_NO"), no("BASE_NO")));
        }
        ["DECL", kind, var] if file != usize::MAX => {
            if let Some((layout, nums, left)) = point(kind, &fields) {
                st.declared.insert(var.to_string(), p.sites.len());
                p.sites.push(Site { file, at: open, name: var.to_string(), layout, nums, uses: Vec::new(), left });
            }
        }
        [data] if data.starts_with("TOOL_DATA[") => {
            p.tools.insert(data.replace(' ', ""), frame(&fields));
        }
        [data] if data.starts_with("BASE_DATA[") => {
            p.frames.insert(data.replace(' ', ""), frame(&fields));
        }
        _ => {}
    }
    Ok(())
}

/// A line of a program: a tool or base selection, a motion, an assignment to a point.
fn code_line(name: &str, src: &str, m: &str, line: Range<usize>, file: usize, p: &mut Parsed, st: &mut State) -> Result<()> {
    let s = m[line.clone()].to_string();
    let up = s.to_ascii_uppercase();
    let compact: String = up.chars().filter(|c| !c.is_whitespace()).collect();
    if up.starts_with("DECL ") || up.starts_with("DEF") || up.starts_with("END") || up.starts_with('&') {
        return Ok(());
    }
    if let Some(v) = compact.strip_prefix("$TOOL=") {
        st.tool = selected(&Source { name, text: src, mask: m, file }, v, line.start, p, true)?;
        return Ok(());
    }
    if let Some(v) = compact.strip_prefix("$BASE=") {
        st.base = selected(&Source { name, text: src, mask: m, file }, v, line.start, p, false)?;
        return Ok(());
    }
    if let Some(v) = compact.strip_prefix("BAS(#TOOL,").and_then(|v| v.strip_suffix(')')) {
        st.tool = format!("TOOL_DATA[{v}]");
        return Ok(());
    }
    if let Some(v) = compact.strip_prefix("BAS(#BASE,").and_then(|v| v.strip_suffix(')')) {
        st.base = format!("BASE_DATA[{v}]");
        return Ok(());
    }
    if let Some(v) = compact.strip_prefix("FDAT_ACT=") {
        if let Some((t, b)) = st.fdat.get(v) {
            st.tool = format!("TOOL_DATA[{t}]");
            st.base = format!("BASE_DATA[{b}]");
        }
        return Ok(());
    }
    let word: String = up.chars().take_while(|c| c.is_ascii_alphanumeric() || *c == '_').collect();
    if let Some(&(_, n)) = MOTIONS.iter().find(|(w, _)| *w == word) {
        return motion(&Source { name, text: src, mask: m, file }, line.start + word.len()..line.end, n, p, st);
    }
    if word.ends_with("_REL") && MOTIONS.iter().any(|(w, _)| word.starts_with(w)) {
        let (l, c) = text::line_col(src, line.start);
        p.notes.push(RunTime {
            file: name.into(),
            line: l,
            column: c,
            target: s.trim().into(),
            reason: "a relative motion: its target follows the arm's position at run time".into(),
        });
        return Ok(());
    }
    // An assignment to a declared point (`XP1=...`, `XP1.Z=XP1.Z+10`).
    if let Some((lhs, _)) = compact.split_once('=').filter(|(l, r)| !l.is_empty() && !r.starts_with('=')) {
        let base = lhs.split('.').next().unwrap_or("");
        if let Some(&k) = st.declared.get(base) {
            let (l, c) = text::line_col(src, line.start);
            p.sites[k].left = Some(Left::RunTime(format!("assigned in code at line {l}, column {c}")));
        }
    }
    Ok(())
}

/// The name a `$TOOL =` / `$BASE =` value selects (`TOOL_DATA[1]`, a declared `FRAME`,
/// `$NULLFRAME`); an inline frame is declared under the line's name.
fn selected(f: &Source, v: &str, at: usize, p: &mut Parsed, tool: bool) -> Result<String> {
    let (name, src, m) = (f.name, f.text, f.mask);
    if v.starts_with('{') {
        let open = at + m[at..].find('{').unwrap_or(0);
        let (fields, _) = aggregate(name, src, m, open)?;
        let (l, _) = text::line_col(src, at);
        let key = format!("{} of line {l}", if tool { "$TOOL" } else { "$BASE" });
        if tool {
            p.tools.insert(key.clone(), frame(&fields));
        } else {
            p.frames.insert(key.clone(), frame(&fields));
        }
        return Ok(key);
    }
    Ok(match v {
        "$NULLFRAME" | "$WORLD" | "$ROBROOT" => "$NULLFRAME".into(),
        other => other.to_string(),
    })
}

/// A motion's targets: a declared point's use, an inline aggregate's site, or a note.
fn motion(f: &Source, args: Range<usize>, n: usize, p: &mut Parsed, st: &State) -> Result<()> {
    let (name, src, m, file) = (f.name, f.text, f.mask, f.file);
    // The targets end where the approximation (C_PTP, C_DIS, ...) or the spline's options begin.
    let text = &m[args.clone()];
    let stop = text.to_ascii_uppercase().find(" C_").map_or(args.end, |k| args.start + k);
    let parts = split_top(m, args.start..stop);
    for part in parts.into_iter().take(n) {
        let r = trim(m, part);
        let t = m[r.clone()].trim().to_string();
        let up = t.to_ascii_uppercase();
        let use_ = (st.tool.clone(), st.base.clone());
        if t.starts_with('{') {
            let (fields, _) = aggregate(name, src, m, r.start)?;
            let kind = if fields.contains_key("A1") { "E6AXIS" } else { "E6POS" };
            if let Some((layout, nums, left)) = point(kind, &fields) {
                p.sites.push(Site { file, at: r.start, name: "inline".into(), layout, nums, uses: vec![use_], left });
            }
        } else if let Some(&k) = st.declared.get(&up) {
            p.sites[k].uses.push(use_);
        } else {
            let (line, column) = text::line_col(src, r.start);
            let reason = if t.contains(':') {
                "the geometric operator ':' composes the target at run time".to_string()
            } else if up == "HOME" || up == "XHOME" || up.starts_with("$") {
                "a system or $config.dat position, not data of the program".to_string()
            } else {
                "not declared with data in the program".to_string()
            };
            p.notes.push(RunTime { file: name.into(), line, column, target: t, reason });
        }
    }
    Ok(())
}
