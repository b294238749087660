//! Studies split across processes or machines: work items in a fixed order, each with its own
//! seed, so that how the work is split changes no result. `--shard i/N` runs the items with
//! `id % N == i` and appends each finished one to a partial file (JSONL: one whole line per
//! item, with the study's configuration, its hash and the twincal version); a shard run again
//! skips the items its file holds, after cutting off a torn last line. `twincal reduce` gathers
//! the parts: one configuration, every item exactly once (duplicates from retries dropped,
//! missing items named). `compare`, `study hold` and `bench diagnose` shard this way.

use crate::error::{Error, Result};
use serde::de::DeserializeOwned;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::Mutex;

/// One work item's result in a part: what it must hold to be a result the study wrote (finite
/// statistics, spreads and sizes not negative), checked for every line `reduce` reads.
pub trait Item: DeserializeOwned {
    /// What is wrong with the item, or `Ok`.
    fn check(&self) -> std::result::Result<(), String>;
}

/// What a sharded study is over: every shard of one study holds the same configuration.
pub trait Config: Clone + Serialize + DeserializeOwned {
    /// The study's kind, written on every line (`reduce` tells the parts apart by it).
    const KIND: &'static str;
    /// SHA-256 of what the results depend on (not of where the inputs were read from).
    fn hash(&self) -> String;
    /// Number of work items.
    fn items(&self) -> u64;
}

/// One line of a partial file: a finished work item and what it found.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Line<C, R> {
    /// The study's kind (lines written before it was recorded are compare's).
    #[serde(default = "compare_kind")]
    pub kind: String,
    /// The work item's id.
    pub item: u64,
    /// The hash of the study's configuration ([`Config::hash`]).
    pub config_hash: String,
    /// The version of twincal that ran the item.
    pub twincal_version: String,
    /// The study's configuration.
    pub config: C,
    /// What the item found.
    #[serde(flatten)]
    pub result: R,
}

fn compare_kind() -> String {
    "compare".into()
}

/// Parses `--shard i/N` (0 ≤ i < N ≤ 10 000).
pub fn parse(s: &str) -> Result<(u64, u64)> {
    let bad = || Error::Invalid(format!("--shard must be i/N with 0 <= i < N <= 10000 (e.g. 0/3), got '{s}'"));
    let (i, n) = s.split_once('/').ok_or_else(bad)?;
    let (i, n): (u64, u64) = (i.trim().parse().map_err(|_| bad())?, n.trim().parse().map_err(|_| bad())?);
    if n == 0 || n > 10_000 || i >= n {
        return Err(bad());
    }
    Ok((i, n))
}

/// The shard `--shard` and `--shard-out` ask for; None without them. `single_outputs` names the
/// outputs of a single run (`--out and --rrd`) and `single_given` whether any was given: a shard
/// writes its part only.
pub fn from_options<C: Config>(
    spec: Option<&str>,
    out: Option<&Path>,
    single_given: bool,
    single_outputs: &str,
    config: &C,
    inputs: &[(&str, &Path)],
) -> Result<Option<Shard>> {
    match (spec, out) {
        (Some(_), _) if single_given => Err(Error::Invalid(format!("--shard writes --shard-out only; {single_outputs} belong to `twincal reduce`"))),
        (Some(s), Some(o)) => Shard::open(s, o, config, inputs).map(Some),
        (Some(_), None) => Err(Error::Invalid("--shard needs --shard-out FILE (the shard's partial file)".into())),
        (None, Some(_)) => Err(Error::Invalid("--shard-out needs --shard i/N".into())),
        (None, None) => Ok(None),
    }
}

/// A running shard: which items it runs, which its file already holds, and the file.
pub struct Shard {
    /// `i` of `--shard i/N`.
    pub index: u64,
    /// `N` of `--shard i/N`.
    pub count: u64,
    /// The partial file.
    pub out: PathBuf,
    done: std::collections::BTreeSet<u64>,
    sink: Mutex<std::fs::File>,
    hash: String,
}

impl Shard {
    /// Opens shard `spec` (`i/N`) of the study `config`, its partial file `out` (created, or
    /// resumed: its items are skipped, a torn last line cut off; a file of another study is
    /// refused). `inputs` are the files the study reads, which `out` must not be.
    pub fn open<C: Config>(spec: &str, out: &Path, config: &C, inputs: &[(&str, &Path)]) -> Result<Shard> {
        crate::output::check_outputs(inputs, &[("--shard-out", out)])?;
        let (index, count) = parse(spec)?;
        if let Some(dir) = out.parent().filter(|d| !d.as_os_str().is_empty() && !d.is_dir()) {
            return Err(Error::Invalid(format!("--shard-out {}: its folder {} does not exist", out.display(), dir.display())));
        }
        let hash = config.hash();
        let done = read::<C, serde_json::Value>(out, Some(&hash))?.iter().map(|l| l.item).collect();
        let sink = Mutex::new(open_append(out)?);
        Ok(Shard { index, count, out: out.to_path_buf(), done, sink, hash })
    }

    /// Whether this run does item `id`: it is this shard's, and not yet in the file.
    pub fn wants(&self, id: u64) -> bool {
        id % self.count == self.index && !self.done.contains(&id)
    }

    /// Items the file held when this run started.
    pub fn already(&self) -> usize {
        self.done.len()
    }

    /// Appends a finished item, one whole line, flushed at once.
    pub fn append<C: Config, R: Serialize>(&self, id: u64, config: &C, result: &R) -> Result<()> {
        let line =
            Line { kind: C::KIND.to_string(), item: id, config_hash: self.hash.clone(), twincal_version: env!("CARGO_PKG_VERSION").into(), config, result };
        let text = serde_json::to_string(&line).map_err(|e| Error::Invalid(format!("cannot write a shard line: {e}")))? + "\n";
        let mut f = self.sink.lock().unwrap_or_else(|e| e.into_inner());
        f.write_all(text.as_bytes()).and_then(|_| f.flush()).map_err(|e| Error::io(&self.out, e))
    }

    /// The line a shard prints when it is done.
    pub fn summary(&self, ran: usize) -> String {
        format!("shard {}/{}: {ran} items run, {} already in {} (config {})", self.index, self.count, self.already(), self.out.display(), &self.hash[..12])
    }
}

/// The finished items of a partial file (a torn last line, from a killed run, is dropped), each
/// checked against `hash` when given. A missing file is empty when `hash` is given (a shard's
/// first run), an error otherwise (`reduce`).
pub fn read<C: DeserializeOwned, R: DeserializeOwned>(path: &Path, hash: Option<&str>) -> Result<Vec<Line<C, R>>> {
    let text = match std::fs::read_to_string(path) {
        Ok(t) => t,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound && hash.is_some() => return Ok(Vec::new()),
        Err(e) => return Err(Error::io(path, e)),
    };
    let lines: Vec<&str> = text.lines().filter(|l| !l.trim().is_empty()).collect();
    let mut out = Vec::new();
    for (k, line) in lines.iter().enumerate() {
        // Only the last line can be torn (a run killed while writing it): without its newline it
        // is not finished, even when it parses (the resume cuts it off and runs its item again).
        if k + 1 == lines.len() && !text.ends_with('\n') {
            break;
        }
        let head: serde_json::Value = serde_json::from_str(line).map_err(|e| Error::data(path.display(), format!("line {}: not a shard line ({e})", k + 1)))?;
        if let Some(h) = hash.filter(|h| head.get("config_hash").and_then(|v| v.as_str()) != Some(h)) {
            let theirs = head.get("config_hash").and_then(|v| v.as_str()).unwrap_or("none");
            return Err(Error::data(
                path.display(),
                format!("line {}: written for another study (config {}, this one {h}): use another --shard-out", k + 1, &theirs[..theirs.len().min(12)]),
            ));
        }
        out.push(serde_json::from_value(head).map_err(|e| Error::data(path.display(), format!("line {}: not a shard line of this study ({e})", k + 1)))?);
    }
    Ok(out)
}

/// Opens a partial file for appending, cutting off a torn last line first.
fn open_append(path: &Path) -> Result<std::fs::File> {
    if let Ok(bytes) = std::fs::read(path) {
        if !bytes.is_empty() && !bytes.ends_with(b"\n") {
            let keep = bytes.iter().rposition(|b| *b == b'\n').map_or(0, |k| k + 1);
            let f = std::fs::OpenOptions::new().write(true).open(path).map_err(|e| Error::io(path, e))?;
            f.set_len(keep as u64).map_err(|e| Error::io(path, e))?;
        }
    }
    std::fs::OpenOptions::new().create(true).append(true).open(path).map_err(|e| Error::io(path, e))
}

/// The finished lines of a study's partial files, read once (untyped, so that a part of another
/// kind of study is named, not misparsed), for `reduce`.
pub struct Parts {
    lines: Vec<(Line<serde_json::Value, serde_json::Value>, PathBuf)>,
    /// Number of files read.
    pub files: usize,
}

impl Parts {
    /// Reads every part; at least one finished item is needed.
    pub fn read(parts: &[PathBuf]) -> Result<Parts> {
        let mut lines = Vec::new();
        for p in parts {
            lines.extend(read::<serde_json::Value, serde_json::Value>(p, None)?.into_iter().map(|l| (l, p.clone())));
        }
        if lines.is_empty() {
            return Err(Error::Invalid("the parts hold no finished item".into()));
        }
        Ok(Parts { lines, files: parts.len() })
    }

    /// The kind of study the parts hold (that of their first finished line).
    pub fn kind(&self) -> &str {
        &self.lines[0].0.kind
    }

    /// Every item of the study, in item order: the configuration, the items' results, and how
    /// many duplicate lines (from retried shards) were dropped. Parts of another study, a
    /// configuration that does not match its hash, items beyond the study's and missing items
    /// are errors naming them.
    pub fn gather<C: Config, R: Item>(self) -> Result<(C, Vec<R>, usize)> {
        let lines = self.lines;
        let (first_hash, first_file) = (lines[0].0.config_hash.clone(), lines[0].1.clone());
        if let Some((l, p)) = lines.iter().find(|(l, _)| l.config_hash != first_hash || l.kind != C::KIND) {
            return Err(Error::data(
                p.display(),
                format!(
                    "item {} belongs to another study ({} config {}; {} holds {} config {})",
                    l.item,
                    l.kind,
                    &l.config_hash[..l.config_hash.len().min(12)],
                    first_file.display(),
                    C::KIND,
                    &first_hash[..first_hash.len().min(12)]
                ),
            ));
        }
        fn typed<T: DeserializeOwned>(v: serde_json::Value, p: &Path, item: u64) -> Result<T> {
            serde_json::from_value(v).map_err(|e| Error::data(p.display(), format!("item {item}: not a line of this study ({e})")))
        }
        let first_file = first_file.as_path();
        let config: C = typed(lines[0].0.config.clone(), first_file, lines[0].0.item)?;
        if config.hash() != first_hash {
            return Err(Error::data(first_file.display(), "its configuration does not match its hash (a hand-edited part?)"));
        }
        let total = config.items();
        let first_config = lines[0].0.config.clone();
        // Each item's result as first read (untimed, to tell a retry from an edit) and typed.
        let mut by_item: BTreeMap<u64, (serde_json::Value, PathBuf, R)> = BTreeMap::new();
        let mut duplicates = 0;
        for (l, p) in lines {
            if l.item >= total {
                return Err(Error::data(p.display(), format!("item {} is beyond the study's {total} items", l.item)));
            }
            // The hash ties the parts only if every line's configuration is one it hashes (the
            // same study reached by another path to its data hashes the same).
            if l.config != first_config && typed::<C>(l.config.clone(), &p, l.item)?.hash() != first_hash {
                return Err(Error::data(p.display(), format!("item {}: its configuration differs from the one its hash names (a hand-edited part?)", l.item)));
            }
            let untimed = untimed(&l.result);
            match by_item.entry(l.item) {
                std::collections::btree_map::Entry::Occupied(o) if o.get().0 == untimed => duplicates += 1,
                std::collections::btree_map::Entry::Occupied(o) => {
                    return Err(Error::data(
                        p.display(),
                        format!(
                            "item {} is also in {} with other results: a retried item gives the same numbers, so one of the parts was edited or written by another build",
                            l.item,
                            o.get().1.display()
                        ),
                    ));
                }
                std::collections::btree_map::Entry::Vacant(v) => {
                    let r: R = typed(l.result, &p, l.item)?;
                    r.check().map_err(|why| Error::data(p.display(), format!("item {}: {why} (a hand-edited part?)", l.item)))?;
                    v.insert((untimed, p, r));
                }
            }
        }
        let missing: Vec<u64> = (0..total).filter(|i| !by_item.contains_key(i)).collect();
        if !missing.is_empty() {
            let shown: Vec<String> = missing.iter().take(20).map(u64::to_string).collect();
            return Err(Error::Invalid(format!(
                "{} of the {total} items are missing (first: {}{}): run the shards that hold them (re-running a shard resumes it)",
                missing.len(),
                shown.join(", "),
                if missing.len() > 20 { ", ..." } else { "" }
            )));
        }
        Ok((config, by_item.into_values().map(|(_, _, r)| r).collect(), duplicates))
    }
}

/// A result without its measured times (keys naming seconds), which a retried item does not
/// repeat.
fn untimed(v: &serde_json::Value) -> serde_json::Value {
    use serde_json::Value;
    match v {
        Value::Object(m) => Value::Object(m.iter().filter(|(k, _)| !k.contains("second")).map(|(k, x)| (k.clone(), untimed(x))).collect()),
        Value::Array(a) => Value::Array(a.iter().map(untimed).collect()),
        other => other.clone(),
    }
}
