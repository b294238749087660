//! URScript read for filtering: poses `p[x, y, z, rx, ry, rz]` (metres, rotation vector) and
//! joint lists moved to by `movel`, `movej`, `movep` and `movec`, written inline or assigned
//! once to a variable; the TCP the script last set (`set_tcp`; the flange until then, the
//! installation's TCP being outside the script: give it as a `--frames` script with its
//! `set_tcp`). Poses are in the base frame: a feature frame applied with `pose_trans` is a
//! run-time target.

use super::text::{self, error_at, group_end, lines, numbers_in, split_top, trim, Num, Source};
use super::{Layout, Left, Parsed, Reader, RunTime, Site};
use crate::controller::ProgramFile;
use crate::error::Result;
use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use std::collections::BTreeMap;
use std::ops::Range;

pub(super) struct UrReader;

/// Motions and how many targets each takes.
const MOTIONS: [(&str, usize); 4] = [("movel", 1), ("movej", 1), ("movep", 1), ("movec", 2)];

/// The flange: the TCP before the script sets one.
const FLANGE: &str = "flange";
/// The frame every pose is in.
const BASE: &str = "base";

impl Reader for UrReader {
    fn defaults(&self) -> (&'static str, &'static str) {
        (FLANGE, BASE)
    }

    fn parse(&self, files: &[ProgramFile], frames: &[ProgramFile]) -> Result<Parsed> {
        let mut p = Parsed::default();
        let mut tool = FLANGE.to_string();
        let mut vars: BTreeMap<String, usize> = BTreeMap::new();
        for f in frames {
            let m = text::mask(&f.text, b'#', b"\"'");
            for line in lines(&m) {
                if let Some(t) = set_tcp(&f.name, &f.text, &m, line, &mut p, &vars)? {
                    tool = t;
                }
            }
        }
        for (i, f) in files.iter().enumerate() {
            let m = text::mask(&f.text, b'#', b"\"'");
            for line in lines(&m) {
                if let Some(t) = set_tcp(&f.name, &f.text, &m, line.clone(), &mut p, &vars)? {
                    tool = t;
                    continue;
                }
                assignment(&f.name, &f.text, &m, line.clone(), i, &mut p, &mut vars)?;
                motions(&Source { name: &f.name, text: &f.text, mask: &m, file: i }, line, &mut p, &vars, &tool)?;
            }
        }
        Ok(p)
    }
}

/// The numbers of the list that opens at `open` (`[` or the `p` of `p[`): a pose's six or a
/// joint list's six.
fn literal(name: &str, src: &str, m: &str, open: usize) -> Result<(Layout, Vec<Num>)> {
    let (layout, bracket) = if m.as_bytes()[open] == b'p' { (Layout::UrPose, open + 1) } else { (Layout::UrJoints, open) };
    let end = group_end(name, m, bracket)?;
    let nums = numbers_in(name, src, bracket..end, b"[],")?;
    if nums.len() != 6 {
        let what = if layout == Layout::UrPose { "a pose p[x, y, z, rx, ry, rz]" } else { "a joint list [q1, ..., q6]" };
        return Err(error_at(name, src, open, format!("{what} holds six numbers, found {}", nums.len())));
    }
    Ok((layout, nums))
}

/// Whether the text at `at` opens a literal target (`p[` or `[`).
fn opens_literal(m: &str, at: usize) -> bool {
    let s = &m[at..];
    s.starts_with('[') || (s.starts_with('p') && s[1..].trim_start().starts_with('[') && s[1..].starts_with('['))
}

/// `set_tcp(p[...])` or `set_tcp(var)`: the name of the tool it selects, declared in `p`.
fn set_tcp(name: &str, src: &str, m: &str, line: Range<usize>, p: &mut Parsed, vars: &BTreeMap<String, usize>) -> Result<Option<String>> {
    let s = &m[line.clone()];
    let Some(k) = s.find("set_tcp(") else { return Ok(None) };
    let open = line.start + k + "set_tcp".len();
    let end = group_end(name, m, open)?;
    let arg = trim(m, open + 1..end - 1);
    let (l, _) = text::line_col(src, line.start);
    let key = format!("set_tcp of line {l}");
    let pose = if opens_literal(m, arg.start) {
        let (_, nums) = literal(name, src, m, arg.start)?;
        Some(pose_mm(&nums.iter().map(|n| n.value).collect::<Vec<_>>()))
    } else {
        vars.get(m[arg.clone()].trim()).map(|&k| pose_mm(&p.sites[k].values()))
    };
    if let Some(t) = pose {
        p.tools.insert(key.clone(), Some(t));
    }
    Ok(Some(key))
}

/// A URScript pose's values (m, rotation vector) as a pose in mm.
fn pose_mm(v: &[f64]) -> Isometry3<f64> {
    Isometry3::from_parts(Translation3::new(v[0] * 1000.0, v[1] * 1000.0, v[2] * 1000.0), UnitQuaternion::from_scaled_axis(Vector3::new(v[3], v[4], v[5])))
}

/// `[global|local] name = p[...]` (or a joint list): a declared target; a second assignment
/// marks it computed at run time.
fn assignment(name: &str, src: &str, m: &str, line: Range<usize>, file: usize, p: &mut Parsed, vars: &mut BTreeMap<String, usize>) -> Result<()> {
    let s = &m[line.clone()];
    let Some(eq) = s.find('=') else { return Ok(()) };
    if s[eq + 1..].starts_with('=') || s[..eq].ends_with(['!', '<', '>', '=']) {
        return Ok(());
    }
    let lhs: Vec<&str> = s[..eq].split_whitespace().filter(|w| !matches!(*w, "global" | "local")).collect();
    let [var] = lhs.as_slice() else { return Ok(()) };
    if !text::is_name(var) {
        return Ok(());
    }
    let value = trim(m, line.start + eq + 1..line.end);
    if let Some(&k) = vars.get(*var) {
        let (l, c) = text::line_col(src, line.start);
        p.sites[k].left = Some(Left::RunTime(format!("assigned again at line {l}, column {c}")));
        return Ok(());
    }
    if opens_literal(m, value.start) {
        let (layout, nums) = literal(name, src, m, value.start)?;
        vars.insert(var.to_string(), p.sites.len());
        p.sites.push(Site::new(file, value.start, var, layout, nums, None));
    }
    Ok(())
}

/// The motions of a line: each target a declared variable's use, an inline site, or a note.
fn motions(f: &Source, line: Range<usize>, p: &mut Parsed, vars: &BTreeMap<String, usize>, tool: &str) -> Result<()> {
    let (name, src, m, file) = (f.name, f.text, f.mask, f.file);
    let s = &m[line.clone()];
    for (word, n) in MOTIONS {
        let mut from = 0;
        while let Some(k) = s[from..].find(word).map(|k| from + k) {
            from = k + word.len();
            let before_ok = k == 0 || !s.as_bytes()[k - 1].is_ascii_alphanumeric() && s.as_bytes()[k - 1] != b'_';
            if !before_ok || !s[from..].trim_start().starts_with('(') {
                continue;
            }
            let open = line.start + from + (s[from..].len() - s[from..].trim_start().len());
            let end = group_end(name, m, open)?;
            for part in split_top(m, open + 1..end - 1).into_iter().take(n) {
                let r = trim(m, part);
                let t = m[r.clone()].to_string();
                let use_ = (tool.to_string(), BASE.to_string());
                if opens_literal(m, r.start) {
                    let (layout, nums) = literal(name, src, m, r.start)?;
                    let mut site = Site::new(file, r.start, "inline", layout, nums, None);
                    site.uses.push(use_);
                    p.sites.push(site);
                } else if let Some(&k) = vars.get(t.trim()) {
                    p.sites[k].uses.push(use_);
                } else {
                    let (l, c) = text::line_col(src, r.start);
                    let reason =
                        if t.contains('(') { "a function computes the target at run time" } else { "not assigned a literal pose or joint list in the script" };
                    p.notes.push(RunTime { file: name.into(), line: l, column: c, target: t.trim().into(), reason: reason.into() });
                }
            }
            from = end - line.start;
        }
    }
    Ok(())
}
