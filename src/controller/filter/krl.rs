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
/// What an external tool's name carries (an FDAT with `IPO_FRAME #TCP`).
const EXTERNAL: &str = " (IPO_FRAME #TCP)";

/// The program's state as it is read: the declared points, the frames' names, the FDATs.
#[derive(Default)]
struct State {
    declared: BTreeMap<String, usize>,
    fdat: BTreeMap<String, Fdat>,
    tool: String,
    base: String,
}

/// An FDAT's frame choice: the tool's and the base's numbers, and whether the tool is external
/// (`IPO_FRAME #TCP`: the robot carries the part past a tool standing in the cell).
#[derive(Clone, Copy, Debug)]
struct Fdat {
    tool: i64,
    base: i64,
    external: bool,
}

/// The data types of positions the filter reads.
const POINT_TYPES: [&str; 5] = ["POS", "E6POS", "FRAME_POINT", "AXIS", "E6AXIS"];

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

/// An aggregate `{X 1.0,Y 2,...}` at `open`: its numeric fields (upper case) and their numbers,
/// and its other fields (upper case) with their values' text (`IPO_FRAME #BASE`, `POINT2[] " "`,
/// a nested aggregate). A field of a position or a frame (`X`, `A1`, `S`, ...) that is not one
/// number, or a part that is no field at all, is an error naming it.
fn aggregate(name: &str, src: &str, m: &str, open: usize) -> Result<(BTreeMap<String, Num>, BTreeMap<String, String>)> {
    let end = group_end(name, m, open)?;
    let (mut fields, mut other) = (BTreeMap::new(), BTreeMap::new());
    for part in split_top(m, open + 1..end - 1) {
        let part = trim(m, part);
        if part.is_empty() {
            continue;
        }
        let label: String = m[part.clone()].chars().take_while(|c| c.is_ascii_alphanumeric() || *c == '_' || *c == '[' || *c == ']').collect();
        let key = label.to_ascii_uppercase();
        let not_a_field = || error_at(name, src, part.start, format!("'{}' is not a field and its value", &src[part.clone()]));
        if label.is_empty() || !m[part.start + label.len()..part.end].starts_with(char::is_whitespace) {
            return Err(not_a_field());
        }
        let value = part.start + label.len()..part.end;
        if NUMERIC_FIELDS.contains(&key.as_str()) {
            match numbers_in(name, src, value, b"")?.as_slice() {
                [n] => fields.insert(key, n.clone()),
                _ => return Err(error_at(name, src, part.start, format!("'{}': the field {key} takes one number", &src[part.clone()]))),
            };
            continue;
        }
        match numbers_in(name, src, value.clone(), b"") {
            Ok(nums) if nums.len() == 1 => {
                fields.insert(key, nums[0].clone());
            }
            _ => {
                other.insert(key, m[value].trim().to_string());
            }
        }
    }
    Ok((fields, other))
}

/// The fields of a position, a joint position or a frame: each one number.
const NUMERIC_FIELDS: [&str; 26] = [
    "X", "Y", "Z", "A", "B", "C", "S", "T", "A1", "A2", "A3", "A4", "A5", "A6", "E1", "E2", "E3", "E4", "E5", "E6", "TOOL_NO", "BASE_NO", "E7", "E8", "E9",
    "E10",
];

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
    // Only positions, frames and the frame choice (FDAT) are read; other data (PDAT, LDAT, LOAD,
    // the machine's $config.dat structures) pass through untouched.
    let read = || aggregate(name, src, m, open);
    match head.as_slice() {
        ["DECL", "FRAME", var] => {
            let (fields, _) = read()?;
            p.frames.insert(var.to_string(), frame(&fields));
            p.tools.insert(var.to_string(), frame(&fields));
        }
        ["DECL", "FDAT", var] => {
            let (fields, other) = read()?;
            let no = |k: &str| fields.get(k).map_or(0, |n| n.value.round() as i64);
            // IPO_FRAME #TCP: the tool stands in the cell and the robot carries the part.
            let external = other.get("IPO_FRAME").is_some_and(|v| v.eq_ignore_ascii_case("#TCP"));
            st.fdat.insert(var.to_string(), Fdat { tool: no("TOOL_NO"), base: no("BASE_NO"), external });
        }
        ["DECL", kind, var] if file != usize::MAX && POINT_TYPES.contains(kind) => {
            let (fields, _) = read()?;
            if let Some((layout, nums, left)) = point(kind, &fields) {
                st.declared.insert(var.to_string(), p.sites.len());
                p.sites.push(Site::new(file, open, var, layout, nums, left));
            }
        }
        [data] if data.starts_with("TOOL_DATA[") => {
            let (fields, _) = read()?;
            p.tools.insert(data.replace(' ', ""), frame(&fields));
        }
        [data] if data.starts_with("BASE_DATA[") => {
            let (fields, _) = read()?;
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
        // The inline forms then call BAS(#PTP_PARAMS, ...) or BAS(#CP_PARAMS, ...), which select
        // FDAT_ACT's tool and base.
        if let Some(f) = st.fdat.get(v).copied() {
            st.tool = format!("TOOL_DATA[{}]", f.tool);
            if f.external {
                st.tool += EXTERNAL;
                p.tools.insert(st.tool.clone(), None);
            }
            st.base = format!("BASE_DATA[{}]", f.base);
        }
        return Ok(());
    }
    let word: String = up.chars().take_while(|c| c.is_ascii_alphanumeric() || *c == '_').collect();
    if let Some(&(_, n)) = MOTIONS.iter().find(|(w, _)| *w == word) {
        // KRL reads S and T in a PTP motion only; a LIN or CIRC keeps the arm's branch.
        let ptp = word.ends_with("PTP");
        return motion(&Source { name, text: src, mask: m, file }, line.start + word.len()..line.end, (n, ptp), p, st);
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

/// A motion's `n` targets (a PTP motion's read with their S and T: `ptp`): a declared point's
/// use, an inline aggregate's site, or a note.
fn motion(f: &Source, args: Range<usize>, (n, ptp): (usize, bool), p: &mut Parsed, st: &State) -> Result<()> {
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
        let site = if t.starts_with('{') {
            let (fields, _) = aggregate(name, src, m, r.start)?;
            let kind = if fields.contains_key("A1") { "E6AXIS" } else { "E6POS" };
            point(kind, &fields).map(|(layout, nums, left)| {
                p.sites.push(Site::new(file, r.start, "inline", layout, nums, left));
                p.sites.len() - 1
            })
        } else {
            st.declared.get(&up).copied()
        };
        if let Some(k) = site {
            p.sites[k].uses.push(use_);
            p.sites[k].config_ignored += usize::from(!ptp);
        } else if t.starts_with('{') {
            continue;
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
