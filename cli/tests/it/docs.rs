//! The user guide's links hold: every local link of README.md, ARCHITECTURE.md, CHANGELOG.md
//! and docs/*.md names a file that exists, and an anchor names a heading of its page (GitHub's
//! slugs). Links inside code are not links.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).parent().unwrap().to_path_buf()
}

/// The lines of a Markdown text outside fenced code, inline code spans removed.
fn prose(text: &str) -> Vec<String> {
    let mut fence: Option<String> = None;
    let mut out = Vec::new();
    for line in text.lines() {
        let t = line.trim_start();
        let mark: String = t.chars().take_while(|c| *c == '`' || *c == '~').collect();
        if mark.len() >= 3 {
            match &fence {
                None => fence = Some(mark),
                Some(f) if mark.starts_with(f.as_str()) => fence = None,
                Some(_) => {}
            }
            continue;
        }
        if fence.is_none() {
            let parts: Vec<&str> = line.split('`').collect();
            out.push(parts.iter().step_by(2).copied().collect::<Vec<_>>().join(""));
        }
    }
    out
}

/// GitHub's anchor of a heading's text.
fn slug(text: &str) -> String {
    let mut s = String::new();
    let mut chars = text.trim().chars().peekable();
    while let Some(c) = chars.next() {
        // A link in a heading keeps its text.
        if c == ']' && chars.peek() == Some(&'(') {
            chars.by_ref().take_while(|c| *c != ')').for_each(drop);
            continue;
        }
        if c.is_alphanumeric() || c == '-' || c == '_' {
            s.extend(c.to_lowercase());
        } else if c == ' ' {
            s.push('-');
        }
    }
    s
}

fn anchors(text: &str) -> BTreeSet<String> {
    let mut seen: BTreeMap<String, usize> = BTreeMap::new();
    let mut out = BTreeSet::new();
    for line in prose(text) {
        let t = line.trim_start();
        let hashes = t.chars().take_while(|c| *c == '#').count();
        if (1..=6).contains(&hashes) && t[hashes..].starts_with(' ') {
            let base = slug(t[hashes..].trim().trim_end_matches('#'));
            let n = seen.entry(base.clone()).or_insert(0);
            out.insert(if *n == 0 { base.clone() } else { format!("{base}-{n}") });
            *n += 1;
        }
    }
    out
}

/// The targets of a line's inline links `[text](target)`.
fn targets(line: &str) -> Vec<String> {
    let mut out = Vec::new();
    let mut rest = line;
    while let Some(i) = rest.find("](") {
        let after = &rest[i + 2..];
        let end = after.find(')').unwrap_or(after.len());
        out.push(after[..end].split_whitespace().next().unwrap_or("").trim_matches(|c| c == '<' || c == '>').to_string());
        rest = &after[end..];
    }
    out
}

#[test]
fn every_local_link_of_the_guide_resolves() {
    let root = root();
    let mut pages: Vec<PathBuf> = ["README.md", "ARCHITECTURE.md", "CHANGELOG.md"].iter().map(|f| root.join(f)).collect();
    let mut docs: Vec<PathBuf> =
        std::fs::read_dir(root.join("docs")).unwrap().map(|e| e.unwrap().path()).filter(|p| p.extension().is_some_and(|e| e == "md")).collect();
    docs.sort();
    pages.extend(docs);
    assert!(pages.iter().any(|p| p.ends_with("docs/README.md")), "the guide's index, docs/README.md");
    let mut broken = Vec::new();
    let mut checked = 0;
    for page in &pages {
        let text = std::fs::read_to_string(page).unwrap();
        for line in prose(&text) {
            for t in targets(&line) {
                if t.is_empty() || t.contains("://") || t.starts_with("mailto:") {
                    continue;
                }
                checked += 1;
                let (file, anchor) = t.split_once('#').map_or((t.as_str(), None), |(f, a)| (f, Some(a)));
                let target = if file.is_empty() { page.clone() } else { page.parent().unwrap().join(file) };
                if !target.exists() {
                    broken.push(format!("{}: {t} (no such file)", page.display()));
                } else if let Some(a) = anchor.filter(|_| target.extension().is_some_and(|e| e == "md")) {
                    if !anchors(&std::fs::read_to_string(&target).unwrap()).contains(a) {
                        broken.push(format!("{}: {t} (no such heading)", page.display()));
                    }
                }
            }
        }
    }
    assert!(checked > 50, "only {checked} local links found: the reader misses them");
    assert!(broken.is_empty(), "{} broken links:\n{}", broken.len(), broken.join("\n"));
}
