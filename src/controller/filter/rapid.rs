//! ABB RAPID read for filtering: `robtarget` and `jointtarget` data (declared, or written
//! inline in a motion), the `tooldata` and `wobjdata` they are moved with, and the motions of
//! `MoveL`, `MoveJ`, `MoveC`, their `DO` forms and `MoveAbsJ`.

use super::text::{self, error_at, group_end, is_name, numbers_in, split_top, split_top_at, trim};
use super::{Layout, Left, Parsed, Reader, RunTime, Site};
use crate::controller::ProgramFile;
use crate::error::Result;
use nalgebra::{Isometry3, Quaternion, Translation3, UnitQuaternion};
use std::collections::BTreeMap;
use std::ops::Range;

pub(super) struct RapidReader;

/// A motion instruction: its name, how many target arguments lead, whether they are joints.
const MOTIONS: [(&str, usize, bool); 7] =
    [("MoveL", 1, false), ("MoveJ", 1, false), ("MoveC", 2, false), ("MoveLDO", 1, false), ("MoveJDO", 1, false), ("MoveCDO", 2, false), ("MoveAbsJ", 1, true)];

/// Functions whose value is a target the controller computes.
const RUN_TIME: [&str; 6] = ["Offs", "RelTool", "CRobT", "CJointT", "CalcRobT", "CalcJointT"];

impl Reader for RapidReader {
    fn defaults(&self) -> (&'static str, &'static str) {
        ("tool0", "wobj0")
    }

    fn parse(&self, files: &[ProgramFile], frames: &[ProgramFile]) -> Result<Parsed> {
        let mut p = Parsed::default();
        let mut declared: BTreeMap<String, usize> = BTreeMap::new();
        let masks: Vec<String> = files.iter().map(|f| mask(&f.text)).collect();
        for f in frames {
            let m = mask(&f.text);
            for st in statements(&m) {
                declaration(&f.name, &f.text, &m, st, usize::MAX, &mut p, &mut declared)?;
            }
        }
        for (i, f) in files.iter().enumerate() {
            for st in statements(&masks[i]) {
                declaration(&f.name, &f.text, &masks[i], st, i, &mut p, &mut declared)?;
            }
        }
        for (i, f) in files.iter().enumerate() {
            // Each module starts with the controller's default: configuration monitored.
            let mut conf = Conf { joint: true, linear: true };
            for st in statements(&masks[i]) {
                instruction(&f.name, &masks[i], st, i, &mut p, &declared, &mut conf)?;
            }
        }
        Ok(p)
    }
}

/// RAPID text masked ([`text::mask`]: comments after `!`, strings), and the header block that
/// ABB's tools write before the module (`%%%`, `VERSION:1`, `LANGUAGE:ENGLISH`, `%%%`) blanked.
fn mask(src: &str) -> String {
    let mut m = text::mask(src, b'!', b"\"");
    let start = m.len() - m.trim_start_matches(|c: char| c.is_whitespace() || c == '\u{feff}').len();
    if m[start..].starts_with(HEADER) {
        let end = m[start + HEADER.len()..].find(HEADER).map_or(start, |k| start + HEADER.len() + k + HEADER.len());
        // Byte for byte, so that offsets in the mask stay the text's.
        let blank: String = m[start..end].bytes().map(|b| if b == b'\n' || b == b'\r' { b as char } else { ' ' }).collect();
        m.replace_range(start..end, &blank);
    }
    m
}

/// The marker that opens and closes the header of a module saved by ABB's tools.
const HEADER: &str = "%%%";

/// Words that open or close a block on a line of their own (no semicolon ends them).
const BLOCK_WORDS: [&str; 18] = [
    "MODULE",
    "ENDMODULE",
    "PROC",
    "ENDPROC",
    "FUNC",
    "ENDFUNC",
    "TRAP",
    "ENDTRAP",
    "ELSE",
    "ENDIF",
    "ENDFOR",
    "ENDWHILE",
    "ENDTEST",
    "DEFAULT:",
    "CASE",
    "ERROR",
    "BACKWARD",
    "UNDO",
];

/// The statements of masked RAPID text: the ranges between semicolons, trimmed, each without
/// the block lines before it (`MODULE m`, `PROC main()`, `IF c THEN`, `ENDIF`, ...).
fn statements(m: &str) -> Vec<Range<usize>> {
    let mut out = Vec::new();
    let mut start = 0;
    for (i, c) in m.bytes().enumerate() {
        if c == b';' {
            out.push(without_block_lines(m, trim(m, start..i)));
            start = i + 1;
        }
    }
    out
}

/// `st` from its first line that is not a block line.
fn without_block_lines(m: &str, mut st: Range<usize>) -> Range<usize> {
    while let Some(nl) = m[st.clone()].find('\n') {
        let line = m[st.start..st.start + nl].trim();
        let first = line.split_whitespace().next().unwrap_or("").to_ascii_uppercase();
        let upper = line.to_ascii_uppercase();
        let block = line.is_empty()
            || BLOCK_WORDS.contains(&first.as_str())
            || upper.ends_with(" THEN")
            || upper.ends_with(" DO")
            || upper.starts_with("LOCAL PROC")
            || upper.starts_with("LOCAL FUNC");
        if !block {
            break;
        }
        st = trim(m, st.start + nl + 1..st.end);
    }
    st
}

/// The words of a statement's head before `:=` (`PERS robtarget p10`), and the value's range.
fn split_assign(m: &str, st: &Range<usize>) -> Option<(Vec<String>, Range<usize>)> {
    let s = &m[st.clone()];
    let at = s.find(":=")?;
    let head = s[..at].split_whitespace().map(str::to_string).collect();
    Some((head, trim(m, st.start + at + 2..st.end)))
}

/// A data declaration (`CONST robtarget p10 := [...]`): targets become sites of file `file`
/// (`usize::MAX`: a file read for frames only), tools and work objects frames; a target
/// assigned in a statement marks the declared one as computed at run time.
fn declaration(name: &str, src: &str, m: &str, st: Range<usize>, file: usize, p: &mut Parsed, declared: &mut BTreeMap<String, usize>) -> Result<()> {
    let Some((head, value)) = split_assign(m, &st) else { return Ok(()) };
    let head: Vec<&str> = head.iter().map(String::as_str).filter(|w| !matches!(w.to_ascii_uppercase().as_str(), "LOCAL" | "TASK")).collect();
    match head.as_slice() {
        [storage, ty, var] if matches!(storage.to_ascii_uppercase().as_str(), "CONST" | "PERS" | "VAR") => {
            let ty = ty.to_ascii_lowercase();
            let literal = m.as_bytes().get(value.start) == Some(&b'[');
            if !is_name(var) {
                return Ok(()); // An array (`p{10}`) or something else: not one target.
            }
            match ty.as_str() {
                "robtarget" | "jointtarget" if file != usize::MAX => {
                    let layout = if ty == "robtarget" { Layout::RapidPose } else { Layout::RapidJoints };
                    if literal {
                        let nums = target_numbers(name, src, m, value, layout)?;
                        declared.insert(var.to_ascii_lowercase(), p.sites.len());
                        p.sites.push(Site::new(file, st.start, var, layout, nums, None));
                    }
                }
                "tooldata" if literal => {
                    let (hold, n) =
                        flagged_numbers(name, src, m, value, 18, "tooldata [robhold,[[x,y,z],[q1,q2,q3,q4]],[mass,[cx,cy,cz],[q1,q2,q3,q4],ix,iy,iz]]")?;
                    // robhold TRUE: the robot holds the tool (on its flange); FALSE: a stationary tool.
                    p.tools.insert(var.to_ascii_lowercase(), hold[0].then(|| pose(&n[..7])));
                }
                "wobjdata" if literal => {
                    let (flags, n) =
                        flagged_numbers(name, src, m, value, 14, "wobjdata [robhold,ufprog,\"ufmec\",[[x,y,z],[q1,q2,q3,q4]],[[x,y,z],[q1,q2,q3,q4]]]")?;
                    let fixed = !flags[0] && flags.get(1).copied().unwrap_or(true);
                    p.frames.insert(var.to_ascii_lowercase(), fixed.then(|| pose(&n[..7]) * pose(&n[7..14])));
                }
                _ => {}
            }
        }
        [target, ..] => {
            // An assignment in code (`p10 := Offs(p10, 0, 0, 10)`, `p10.trans.z := 5`).
            let base = target.split(['.', '{']).next().unwrap_or("").to_ascii_lowercase();
            if let Some(&k) = declared.get(&base) {
                p.sites[k].left = Some(Left::RunTime(format!("assigned in code at {}", pos(src, st.start))));
            }
        }
        _ => {}
    }
    Ok(())
}

/// `line:col` of byte `at`.
fn pos(src: &str, at: usize) -> String {
    let (l, c) = text::line_col(src, at);
    format!("line {l}, column {c}")
}

/// A target's numbers: a robtarget's 17 (the 11 the filter reads), a jointtarget's 12 (six).
fn target_numbers(name: &str, src: &str, m: &str, value: Range<usize>, layout: Layout) -> Result<Vec<text::Num>> {
    let end = group_end(name, m, value.start)?;
    let nums = numbers_in(name, src, value.start..end, b"[],")?;
    let (want, keep, shape) = match layout {
        Layout::RapidPose => (17, 11, "[[x,y,z],[q1,q2,q3,q4],[cf1,cf4,cf6,cfx],[eax_a,...,eax_f]]"),
        _ => (12, 6, "[[rax_1,...,rax_6],[eax_a,...,eax_f]]"),
    };
    if nums.len() != want {
        return Err(error_at(
            name,
            src,
            value.start,
            format!("a {} is {shape}: {want} numbers, found {}", if layout == Layout::RapidPose { "robtarget" } else { "jointtarget" }, nums.len()),
        ));
    }
    if layout == Layout::RapidPose {
        let q = &nums[3..7];
        let norm = q.iter().map(|n| n.value * n.value).sum::<f64>().sqrt();
        if (norm - 1.0).abs() > 1e-3 {
            return Err(error_at(
                name,
                src,
                q[0].span.start,
                format!("the orientation [{}] is not a unit quaternion (norm {norm:.6})", q.iter().map(|n| n.value.to_string()).collect::<Vec<_>>().join(",")),
            ));
        }
    }
    Ok(nums.into_iter().take(keep).collect())
}

/// A frame datum's leading booleans and its numbers (`want` of them), or an error naming the
/// type's shape.
fn flagged_numbers(name: &str, src: &str, m: &str, value: Range<usize>, want: usize, shape: &str) -> Result<(Vec<bool>, Vec<f64>)> {
    let end = group_end(name, m, value.start)?;
    let inner = &m[value.start..end];
    let flags: Vec<bool> = inner
        .split(|c: char| !c.is_ascii_alphabetic())
        .filter_map(|w| match w.to_ascii_uppercase().as_str() {
            "TRUE" => Some(true),
            "FALSE" => Some(false),
            _ => None,
        })
        .collect();
    let nums = numbers_in(name, src, value.start..end, b"[],\"")?;
    if nums.len() != want || flags.is_empty() {
        return Err(error_at(name, src, value.start, format!("a {shape}: {want} numbers, found {}", nums.len())));
    }
    Ok((flags, nums.iter().map(|n| n.value).collect()))
}

/// A pose from `x, y, z, q1, q2, q3, q4` (mm, w first).
fn pose(v: &[f64]) -> Isometry3<f64> {
    Isometry3::from_parts(Translation3::new(v[0], v[1], v[2]), UnitQuaternion::from_quaternion(Quaternion::new(v[3], v[4], v[5], v[6])))
}

/// Whether the controller holds a motion to the configuration its target states (`ConfJ \On`,
/// `ConfL \On`, the default) or takes the solution nearest the arm's (`\Off`).
struct Conf {
    /// `ConfJ`: joint motions (`MoveJ`).
    joint: bool,
    /// `ConfL`: linear and circular motions (`MoveL`, `MoveC`).
    linear: bool,
}

/// A motion instruction: its targets' uses (a declared target: its tool and work object, and
/// whether the configuration monitoring `conf` reads its configuration data), its inline
/// targets as sites, its computed targets as notes; `ConfJ` and `ConfL` switch `conf`.
fn instruction(name: &str, m: &str, st: Range<usize>, file: usize, p: &mut Parsed, declared: &BTreeMap<String, usize>, conf: &mut Conf) -> Result<()> {
    let s = &m[st.clone()];
    let word: String = s.chars().take_while(|c| c.is_ascii_alphanumeric()).collect();
    if word.eq_ignore_ascii_case("ConfJ") || word.eq_ignore_ascii_case("ConfL") {
        let on = !s[word.len()..].to_ascii_lowercase().contains("\\off");
        *(if word.eq_ignore_ascii_case("ConfJ") { &mut conf.joint } else { &mut conf.linear }) = on;
        return Ok(());
    }
    let Some(&(_, n_targets, _)) = MOTIONS.iter().find(|(w, _, _)| w.eq_ignore_ascii_case(&word)) else { return Ok(()) };
    let reads_config = if word.to_ascii_lowercase().starts_with("movej") { conf.joint } else { conf.linear };
    let args = st.start + word.len()..st.end;
    let (positional, wobj) = arguments(m, args);
    if positional.len() < n_targets + 3 {
        return Err(error_at(
            name,
            m,
            st.start,
            format!("{word} takes {} target(s), a speed, a zone and a tool: found {} arguments", n_targets, positional.len()),
        ));
    }
    let tool = m[positional[n_targets + 2].clone()].trim().to_ascii_lowercase();
    let frame = wobj.unwrap_or_else(|| "wobj0".into());
    for r in &positional[..n_targets] {
        let t = m[r.clone()].trim();
        let layout = if MOTIONS.iter().any(|(w, _, j)| *j && w.eq_ignore_ascii_case(&word)) { Layout::RapidJoints } else { Layout::RapidPose };
        let site = if t.starts_with('[') {
            let nums = target_numbers(name, m, m, r.clone(), layout)?;
            p.sites.push(Site::new(file, r.start, "inline", layout, nums, None));
            Some(p.sites.len() - 1)
        } else {
            declared.get(&t.to_ascii_lowercase()).copied()
        };
        if let Some(k) = site {
            p.sites[k].uses.push((tool.clone(), frame.clone()));
            p.sites[k].config_ignored += usize::from(!reads_config);
        } else {
            let (line, column) = text::line_col(m, r.start);
            let fname = t.split('(').next().unwrap_or("").trim();
            let reason = if RUN_TIME.iter().any(|f| f.eq_ignore_ascii_case(fname)) {
                format!("{fname} computes the target at run time")
            } else if t == "*" {
                "an inline target stored by the pendant".into()
            } else if is_name(t) {
                "not declared with data in the program".into()
            } else {
                "an expression the controller evaluates at run time".into()
            };
            p.notes.push(RunTime { file: name.to_string(), line, column, target: t.to_string(), reason });
        }
    }
    Ok(())
}

/// A motion's positional arguments (the optional `\Name` and `\Name:=value` ones removed) and
/// the `\WObj` it names.
fn arguments(m: &str, args: Range<usize>) -> (Vec<Range<usize>>, Option<String>) {
    let mut positional = Vec::new();
    let mut wobj = None;
    for part in split_top(m, args) {
        // A part is `[\Opt ...] value [\Opt:=v ...]`: what follows each top-level backslash is
        // an optional argument, what precedes the first one the positional argument.
        for (j, piece) in split_top_at(m, part, b'\\').into_iter().enumerate() {
            let t = m[piece.clone()].trim();
            if j > 0 {
                if let Some(v) = t.split_once(":=").filter(|(k, _)| k.trim().eq_ignore_ascii_case("WObj")) {
                    wobj = Some(v.1.trim().to_ascii_lowercase());
                }
            } else if !t.is_empty() {
                positional.push(trim(m, piece));
            }
        }
    }
    (positional, wobj)
}
