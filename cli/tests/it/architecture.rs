//! The code's shape, checked on every run: no import cycle among the library's files, folders
//! or top-level modules, and every source path ARCHITECTURE.md names exists.
//!
//! A file uses another when its code names an item through a `crate::`, `super::` or `self::`
//! path that resolves into the other file's module (comments, strings and a folder's `mod x;`
//! declarations do not count; a test module inside a file counts as that file).

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

fn root() -> PathBuf {
    PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/.."))
}

fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    let mut entries: Vec<PathBuf> = std::fs::read_dir(dir).unwrap().map(|e| e.unwrap().path()).collect();
    entries.sort();
    for p in entries {
        if p.is_dir() {
            rust_files(&p, out);
        } else if p.extension().is_some_and(|e| e == "rs") {
            out.push(p);
        }
    }
}

/// The module a file defines, as path segments from the crate root (`src/a/mod.rs` and
/// `src/a.rs` are `a`; `src/lib.rs` and `src/main.rs` the root).
fn module_of(src: &Path, file: &Path) -> Vec<String> {
    let rel = file.strip_prefix(src).unwrap().with_extension("");
    let mut seg: Vec<String> = rel.iter().map(|s| s.to_string_lossy().into_owned()).collect();
    if matches!(seg.last().map(String::as_str), Some("mod" | "lib" | "main")) {
        seg.pop();
    }
    seg
}

/// The code of a Rust file without its comments and the contents of its string and character
/// literals (so that neither can be read as a path or a brace).
fn strip(text: &str) -> String {
    let c: Vec<char> = text.chars().collect();
    let mut out = String::with_capacity(c.len());
    let mut i = 0;
    while i < c.len() {
        match c[i] {
            '/' if c.get(i + 1) == Some(&'/') => {
                while i < c.len() && c[i] != '\n' {
                    i += 1;
                }
            }
            '/' if c.get(i + 1) == Some(&'*') => {
                let mut depth = 0;
                while i < c.len() {
                    if c[i] == '/' && c.get(i + 1) == Some(&'*') {
                        depth += 1;
                        i += 2;
                    } else if c[i] == '*' && c.get(i + 1) == Some(&'/') {
                        depth -= 1;
                        i += 2;
                        if depth == 0 {
                            break;
                        }
                    } else {
                        i += 1;
                    }
                }
                out.push(' ');
            }
            'r' if (c.get(i + 1) == Some(&'"') || c.get(i + 1) == Some(&'#')) && (i == 0 || !(c[i - 1].is_alphanumeric() || c[i - 1] == '_')) => {
                let mut j = i + 1;
                let mut hashes = 0;
                while c.get(j) == Some(&'#') {
                    hashes += 1;
                    j += 1;
                }
                if c.get(j) != Some(&'"') {
                    out.push(c[i]);
                    i += 1;
                    continue;
                }
                j += 1;
                loop {
                    if j >= c.len() {
                        break;
                    }
                    if c[j] == '"' && (1..=hashes).all(|h| c.get(j + h) == Some(&'#')) {
                        j += 1 + hashes;
                        break;
                    }
                    j += 1;
                }
                out.push_str("\"\"");
                i = j;
            }
            '"' => {
                i += 1;
                while i < c.len() && c[i] != '"' {
                    i += if c[i] == '\\' { 2 } else { 1 };
                }
                i += 1;
                out.push_str("\"\"");
            }
            '\'' => {
                // A character literal ('x', '\n', '\u{..}'), else a lifetime.
                if c.get(i + 1) == Some(&'\\') {
                    let mut j = i + 2;
                    while j < c.len() && c[j] != '\'' {
                        j += 1;
                    }
                    i = j + 1;
                    out.push_str("' '");
                } else if c.get(i + 2) == Some(&'\'') {
                    i += 3;
                    out.push_str("' '");
                } else {
                    out.push('\'');
                    i += 1;
                }
            }
            ch => {
                out.push(ch);
                i += 1;
            }
        }
    }
    out
}

fn is_ident(ch: char) -> bool {
    ch.is_alphanumeric() || ch == '_'
}

/// Reads an identifier at `i`, returning it and the index after it.
fn ident_at(c: &[char], i: usize) -> Option<(String, usize)> {
    let mut j = i;
    while j < c.len() && is_ident(c[j]) {
        j += 1;
    }
    (j > i).then(|| (c[i..j].iter().collect(), j))
}

fn skip_ws(c: &[char], mut i: usize) -> usize {
    while i < c.len() && c[i].is_whitespace() {
        i += 1;
    }
    i
}

/// The continuation of a path after `prefix` at `i` (just after an identifier): `::seg` as long
/// as they come, a `::{a, b::c}` group expanded into one path per item.
fn path_from(c: &[char], mut i: usize, prefix: Vec<String>, out: &mut Vec<Vec<String>>) -> usize {
    let mut path = prefix;
    loop {
        if c.get(i) == Some(&':') && c.get(i + 1) == Some(&':') {
            let j = skip_ws(c, i + 2);
            if c.get(j) == Some(&'{') {
                let mut k = j + 1;
                loop {
                    k = skip_ws(c, k);
                    match c.get(k) {
                        Some('}') => return k + 1,
                        Some(',') => k += 1,
                        Some(ch) if is_ident(*ch) => {
                            let (id, after) = ident_at(c, k).unwrap();
                            let mut p = path.clone();
                            p.push(id);
                            k = path_from(c, after, p, out);
                        }
                        Some(_) => k += 1,
                        None => return k,
                    }
                }
            }
            match ident_at(c, j) {
                Some((id, after)) => {
                    path.push(id);
                    i = after;
                }
                None => break,
            }
        } else {
            break;
        }
    }
    out.push(path);
    i
}

/// Every `crate::` / `super::` / `self::` path of a stripped file, with the inline modules
/// (`mod tests { .. }`) it sits in.
fn references(code: &str) -> Vec<(Vec<String>, Vec<String>)> {
    let c: Vec<char> = code.chars().collect();
    let mut refs = Vec::new();
    // Inline modules open at these brace depths.
    let mut inline: Vec<(String, usize)> = Vec::new();
    let mut depth = 0usize;
    let mut pending_mod: Option<String> = None;
    let mut i = 0;
    while i < c.len() {
        let ch = c[i];
        if ch == '{' {
            depth += 1;
            if let Some(name) = pending_mod.take() {
                inline.push((name, depth));
            }
            i += 1;
            continue;
        }
        if ch == '}' {
            if inline.last().is_some_and(|(_, d)| *d == depth) {
                inline.pop();
            }
            depth = depth.saturating_sub(1);
            i += 1;
            continue;
        }
        if ch == ';' {
            pending_mod = None;
        }
        if is_ident(ch) && (i == 0 || !is_ident(c[i - 1])) {
            let (id, after) = ident_at(&c, i).unwrap();
            if id == "mod" {
                let j = skip_ws(&c, after);
                if let Some((name, k)) = ident_at(&c, j) {
                    pending_mod = Some(name);
                    i = k;
                    continue;
                }
            }
            if matches!(id.as_str(), "crate" | "super" | "self") && c.get(after) == Some(&':') {
                let mut paths = Vec::new();
                let end = path_from(&c, after, vec![id], &mut paths);
                let mods: Vec<String> = inline.iter().map(|(n, _)| n.clone()).collect();
                refs.extend(paths.into_iter().map(|p| (mods.clone(), p)));
                i = end;
                continue;
            }
            i = after;
            continue;
        }
        i += 1;
    }
    refs
}

/// The file each path of `refs` lands in (the longest prefix of its resolved module path that
/// is a module with a file), from the file of module `here`.
fn targets(modules: &BTreeMap<Vec<String>, PathBuf>, here: &[String], refs: &[(Vec<String>, Vec<String>)]) -> BTreeSet<PathBuf> {
    let mut out = BTreeSet::new();
    for (inline, path) in refs {
        let mut base: Vec<String> = here.iter().chain(inline).cloned().collect();
        let mut rest = path.as_slice();
        match rest[0].as_str() {
            "crate" => {
                base.clear();
                rest = &rest[1..];
            }
            _ => {
                while let Some(first) = rest.first() {
                    match first.as_str() {
                        "super" => {
                            base.pop();
                        }
                        "self" => {}
                        _ => break,
                    }
                    rest = &rest[1..];
                }
            }
        }
        let full: Vec<String> = base.into_iter().chain(rest.iter().cloned()).collect();
        if let Some(file) = (1..=full.len()).rev().find_map(|n| modules.get(&full[..n])) {
            out.insert(file.clone());
        }
    }
    out
}

/// The strongly connected components of more than one node (Tarjan).
fn cycles<N: Ord + Clone>(edges: &BTreeMap<N, BTreeSet<N>>) -> Vec<Vec<N>> {
    struct State<N> {
        index: BTreeMap<N, usize>,
        low: BTreeMap<N, usize>,
        stack: Vec<N>,
        on: BTreeSet<N>,
        out: Vec<Vec<N>>,
    }
    fn visit<N: Ord + Clone>(v: &N, edges: &BTreeMap<N, BTreeSet<N>>, s: &mut State<N>) {
        let i = s.index.len();
        s.index.insert(v.clone(), i);
        s.low.insert(v.clone(), i);
        s.stack.push(v.clone());
        s.on.insert(v.clone());
        for w in edges.get(v).into_iter().flatten() {
            if !s.index.contains_key(w) {
                visit(w, edges, s);
                let lw = s.low[w];
                let lv = s.low.get_mut(v).unwrap();
                *lv = (*lv).min(lw);
            } else if s.on.contains(w) {
                let iw = s.index[w];
                let lv = s.low.get_mut(v).unwrap();
                *lv = (*lv).min(iw);
            }
        }
        if s.low[v] == s.index[v] {
            let mut comp = Vec::new();
            loop {
                let w = s.stack.pop().unwrap();
                s.on.remove(&w);
                let done = &w == v;
                comp.push(w);
                if done {
                    break;
                }
            }
            if comp.len() > 1 {
                comp.sort();
                s.out.push(comp);
            }
        }
    }
    let mut s = State { index: BTreeMap::new(), low: BTreeMap::new(), stack: Vec::new(), on: BTreeSet::new(), out: Vec::new() };
    for v in edges.keys() {
        if !s.index.contains_key(v) {
            visit(v, edges, &mut s);
        }
    }
    s.out
}

/// A crate's file graph (`src` its source folder from the project root): file → the files it
/// uses. Uses of the other crate (`twincal::` in the command line's) are not edges: Cargo
/// already forbids a cycle between the packages.
fn file_graph(src: &str) -> BTreeMap<PathBuf, BTreeSet<PathBuf>> {
    let src = root().join(src);
    let mut files = Vec::new();
    rust_files(&src, &mut files);
    files.retain(|f| !f.ends_with("main.rs"));
    let modules: BTreeMap<Vec<String>, PathBuf> = files.iter().map(|f| (module_of(&src, f), f.strip_prefix(&src).unwrap().to_path_buf())).collect();
    let mut graph = BTreeMap::new();
    for f in &files {
        let here = module_of(&src, f);
        let code = strip(&std::fs::read_to_string(f).unwrap());
        let me = f.strip_prefix(&src).unwrap().to_path_buf();
        let mut to = targets(&modules, &here, &references(&code));
        to.remove(&me);
        to.remove(Path::new("lib.rs"));
        graph.insert(me, to);
    }
    graph
}

fn coarsen(graph: &BTreeMap<PathBuf, BTreeSet<PathBuf>>, node: impl Fn(&Path) -> String) -> BTreeMap<String, BTreeSet<String>> {
    let mut out: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
    for (from, tos) in graph {
        let a = node(from);
        let set = out.entry(a.clone()).or_default();
        set.extend(tos.iter().map(|t| node(t)).filter(|b| *b != a));
    }
    out
}

#[test]
fn the_library_has_no_import_cycle_among_files_folders_or_top_level_modules() {
    let files = file_graph("src");
    assert!(files.len() > 50, "read only {} files", files.len());
    // The reader sees the uses it must: the pipeline uses the model and the problem, and a
    // method its solver interface through a `super::` path.
    let uses = |a: &str, b: &str| files[Path::new(a)].contains(Path::new(b));
    assert!(uses("calib/pipeline/calibrate.rs", "calib/model/mod.rs") && uses("calib/pipeline/calibrate.rs", "calib/fit/mod.rs"));
    assert!(uses("calib/methods/lm.rs", "calib/methods/solver.rs"));
    let top = coarsen(&files, |f| f.iter().next().unwrap().to_string_lossy().trim_end_matches(".rs").to_string());
    // The twin and the calibration sit side by side: neither uses the other.
    for (a, b) in [("sim", "calib"), ("calib", "sim")] {
        assert!(
            !top[a].contains(b),
            "{a}/ uses {b}/: {:?}",
            files.iter().filter(|(f, to)| f.starts_with(a) && to.iter().any(|t| t.starts_with(b))).map(|(f, _)| f).collect::<Vec<_>>()
        );
    }
    let found = cycles_of(&files);
    assert!(found.is_empty(), "import cycles in src/:\n{}", found.join("\n"));
}

/// The cycles of a file graph at its three levels: files, folders (a folder's files are one node;
/// a file at the top of src/ is a module of its own) and top-level modules.
fn cycles_of(files: &BTreeMap<PathBuf, BTreeSet<PathBuf>>) -> Vec<String> {
    let folders = coarsen(files, |f| match f.parent().filter(|p| !p.as_os_str().is_empty()) {
        Some(p) => p.to_string_lossy().into_owned(),
        None => f.to_string_lossy().into_owned(),
    });
    let top = coarsen(files, |f| f.iter().next().unwrap().to_string_lossy().trim_end_matches(".rs").to_string());
    let mut found = Vec::new();
    found.extend(cycles(files).into_iter().map(|c| format!("files: {}", c.iter().map(|p| p.display().to_string()).collect::<Vec<_>>().join(", "))));
    found.extend(cycles(&folders).into_iter().map(|c| format!("folders: {}", c.join(", "))));
    found.extend(cycles(&top).into_iter().map(|c| format!("top-level modules: {}", c.join(", "))));
    found
}

#[test]
fn the_recordings_the_command_line_and_the_python_package_have_no_import_cycle() {
    for src in ["viz/src", "cli/src", "python/src"] {
        let files = file_graph(src);
        assert!(!files.is_empty(), "no source files in {src}");
        let found = cycles_of(&files);
        assert!(found.is_empty(), "import cycles in {src}/:\n{}", found.join("\n"));
    }
    // The reader sees the command line's own uses (its commands use their shared module).
    let files = file_graph("cli/src");
    assert!(files[Path::new("commands/calibrate.rs")].contains(Path::new("commands/mod.rs")));
}

#[test]
fn the_cycle_finder_finds_a_cycle_and_reads_groups_and_inline_modules() {
    let code = strip("use crate::a::{b::C, d};\n// crate::x::y\nlet s = \"crate::q::r\";\nmod tests { use super::*; use super::super::super::e::F; }\n");
    let refs = references(&code);
    let paths: Vec<String> = refs.iter().map(|(m, p)| format!("{}|{}", m.join("/"), p.join("::"))).collect();
    assert_eq!(paths, ["|crate::a::b::C", "|crate::a::d", "tests|super", "tests|super::super::super::e::F"]);
    let modules: BTreeMap<Vec<String>, PathBuf> = [
        (vec!["a".to_string()], PathBuf::from("a/mod.rs")),
        (vec!["a".into(), "b".into()], PathBuf::from("a/b.rs")),
        (vec!["e".into()], PathBuf::from("e.rs")),
    ]
    .into_iter()
    .collect();
    // From `a::b`: `super::super::super::e` inside its test module is the root's `e`; `super::*` is `a::b` itself.
    let t = targets(&modules, &["a".to_string(), "b".to_string()], &refs);
    assert_eq!(t, [PathBuf::from("a/b.rs"), PathBuf::from("a/mod.rs"), PathBuf::from("e.rs")].into_iter().collect());
    let g: BTreeMap<u8, BTreeSet<u8>> = [(1, [2].into()), (2, [3].into()), (3, [1].into()), (4, [1].into())].into_iter().collect();
    assert_eq!(cycles(&g), vec![vec![1, 2, 3]]);
}

#[test]
fn every_source_path_architecture_md_names_exists() {
    let text = std::fs::read_to_string(root().join("ARCHITECTURE.md")).unwrap();
    let exists = |p: &Path| ["", "src", "cli/src"].iter().any(|d| root().join(d).join(p).exists());
    let mut missing = Vec::new();
    let mut checked = 0;
    // A bare file name (`lm.rs`) is read in the last folder named before it (`calib/methods/`),
    // or at the top of src/ (`io.rs`).
    let mut folder = PathBuf::new();
    for (k, span) in text.split('`').enumerate() {
        let looks_like_path = k % 2 == 1
            && !span.is_empty()
            && span.chars().all(|c| c.is_alphanumeric() || "_./-".contains(c))
            && (span.contains('/') || span.ends_with(".rs"))
            && !span.starts_with("../")
            && !span.starts_with('-');
        if !looks_like_path {
            continue;
        }
        checked += 1;
        let path = if span.contains('/') { PathBuf::from(span) } else { folder.join(span) };
        let bare_at_top = !span.contains('/') && exists(Path::new(span));
        if !exists(&path) && !bare_at_top {
            missing.push(path.display().to_string());
        }
        if span.ends_with('/') {
            folder = PathBuf::from(span);
        }
    }
    assert!(checked > 20, "only {checked} paths found in ARCHITECTURE.md");
    assert!(missing.is_empty(), "ARCHITECTURE.md names paths that do not exist (from the project root, src/ or cli/src/): {missing:?}");
}

/// The functions of a stripped file that take the calibrate options (`&CalibOptions`).
fn option_takers(code: &str) -> Vec<String> {
    let mut out = Vec::new();
    for (k, _) in code.match_indices("fn ") {
        let rest = &code[k + 3..];
        let name: String = rest.chars().take_while(|c| is_ident(*c)).collect();
        let Some(open) = rest.find('(') else { continue };
        let mut depth = 0;
        let close = rest[open..]
            .char_indices()
            .find(|&(_, c)| {
                depth += i32::from(c == '(') - i32::from(c == ')');
                depth == 0
            })
            .map_or(rest.len(), |(i, _)| open + i);
        if rest[open..close].contains("&CalibOptions") {
            out.push(name);
        }
    }
    out
}

/// The walk of the options through `calibrate`: only `calib/pipeline/calibrate.rs` hands them
/// to another stage's file. A stage (split, placement, set-up, the other stages) reads them and
/// returns what it found; it never calls a function of another file that takes them, so each
/// stage is entered from the one corridor, not from a room the options passed before.
#[test]
fn only_the_calibrate_pipeline_hands_its_options_to_another_stage() {
    let dir = root().join("src/calib/pipeline");
    let mut files = Vec::new();
    rust_files(&dir, &mut files);
    let code: Vec<(PathBuf, String)> = files.iter().map(|f| (f.clone(), strip(&std::fs::read_to_string(f).unwrap()))).collect();
    let takers: Vec<(String, &PathBuf)> = code.iter().flat_map(|(f, c)| option_takers(c).into_iter().map(move |n| (n, f))).collect();
    assert!(takers.len() >= 8, "only {} functions take the options: {takers:?}", takers.len());
    let corridor = dir.join("calibrate.rs");
    let mut handed = Vec::new();
    for (file, c) in code.iter().filter(|(f, _)| *f != corridor) {
        for (name, home) in takers.iter().filter(|(_, home)| *home != file) {
            let called = c.match_indices(name.as_str()).any(|(i, _)| {
                let before = c[..i].chars().next_back().is_some_and(is_ident);
                let after = c[i + name.len()..].trim_start().starts_with('(');
                !before && after && !c[..i].ends_with("fn ")
            });
            // A name the file defines itself is its own function.
            if called && !option_takers(c).contains(name) {
                handed.push(format!("{} calls {name} of {}", file.display(), home.display()));
            }
        }
    }
    assert!(handed.is_empty(), "a stage hands the calibrate options to another stage's file: {handed:#?}");
}
