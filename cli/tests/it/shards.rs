//! A comparison split into shards (`compare --shard i/N --shard-out PART`, each a separate
//! process) and joined (`twincal reduce`) gives the single process's tables and JSON, N = 1, 3
//! and 7, but for the measured seconds; a killed shard re-run completes without duplicates;
//! missing items and mixed comparisons are refused. `study hold` and `bench diagnose` shard the
//! same way (`crate::shard`).

use std::path::{Path, PathBuf};
use std::process::Output;

fn twincal(args: &[&str]) -> Output {
    std::process::Command::new(env!("CARGO_BIN_EXE_twincal")).args(args).arg("--quiet").output().expect("runs")
}

fn ok(o: Output, what: &str) -> Output {
    assert!(o.status.success(), "{what}: {}", String::from_utf8_lossy(&o.stderr));
    o
}

/// The table without its wall-time column (the last), and the JSON without the runs' seconds.
fn table(o: &Output) -> String {
    String::from_utf8_lossy(&o.stdout)
        .lines()
        .map(|l| if l.starts_with("| ") && l.matches('|').count() == 10 { l.rsplitn(3, '|').nth(2).unwrap().to_string() } else { l.to_string() })
        .collect::<Vec<_>>()
        .join("\n")
}

fn json(path: &Path) -> serde_json::Value {
    let mut v: serde_json::Value = serde_json::from_slice(&std::fs::read(path).unwrap()).unwrap();
    v["runs"].as_array_mut().unwrap().iter_mut().for_each(|r| {
        r.as_object_mut().unwrap().remove("seconds");
    });
    v
}

#[test]
fn shards_reduce_to_the_single_run() {
    let dir = tempfile::tempdir().unwrap();
    let p = |x: &Path| x.to_str().unwrap().to_owned();
    let data = dir.path().join("d");
    let scenario = PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/..")).join("scenarios/irb120_geometric.toml");
    ok(twincal(&["generate", "--scenario", &p(&scenario), "--out", &p(&data)]), "generate");
    let base = ["compare", "--data", &p(&data), "--methods", "lm,rbf", "--seeds", "7"];
    let single = ok(twincal(&[&base[..], &["--out", &p(&dir.path().join("single.json"))]].concat()), "compare");
    let (single_table, single_json) = (table(&single), json(&dir.path().join("single.json")));
    assert!(single_table.contains("| rbf |"), "{single_table}");
    for n in [1, 3, 7] {
        let parts: Vec<PathBuf> = (0..n).map(|i| dir.path().join(format!("n{n}_{i}.jsonl"))).collect();
        for (i, part) in parts.iter().enumerate() {
            ok(twincal(&[&base[..], &["--shard", &format!("{i}/{n}"), "--shard-out", &p(part)]].concat()), "shard");
        }
        let out = dir.path().join(format!("reduced{n}.json"));
        let mut args = vec!["reduce".to_string()];
        args.extend(parts.iter().map(|x| p(x)));
        args.extend(["--out".to_string(), p(&out)]);
        let reduced = ok(twincal(&args.iter().map(String::as_str).collect::<Vec<_>>()), "reduce");
        assert_eq!(table(&reduced), single_table, "{n} shards");
        assert_eq!(json(&out), single_json, "{n} shards");
    }
    // A shard killed while writing: three items kept and a torn fourth line. Re-run, it runs
    // only the missing items and cuts the torn line; every item is there once.
    let part = dir.path().join("killed.jsonl");
    ok(twincal(&[&base[..], &["--shard", "0/1", "--shard-out", &p(&part)]].concat()), "shard");
    let text = std::fs::read_to_string(&part).unwrap();
    let lines: Vec<&str> = text.lines().collect();
    assert_eq!(lines.len(), 14);
    std::fs::write(&part, format!("{}\n{}", lines[..3].join("\n"), &lines[3][..lines[3].len() / 2])).unwrap();
    let o = ok(
        std::process::Command::new(env!("CARGO_BIN_EXE_twincal")).args([&base[..], &["--shard", "0/1", "--shard-out", &p(&part)]].concat()).output().unwrap(),
        "resume",
    );
    assert!(String::from_utf8_lossy(&o.stderr).contains("11 items run, 3 already in"), "{}", String::from_utf8_lossy(&o.stderr));
    let text = std::fs::read_to_string(&part).unwrap();
    let mut items: Vec<u64> = text.lines().map(|l| serde_json::from_str::<serde_json::Value>(l).unwrap()["item"].as_u64().unwrap()).collect();
    items.sort_unstable();
    assert_eq!(items, (0..14).collect::<Vec<_>>());
    // The same part twice (a retried shard): duplicates dropped, the same table.
    let again = ok(twincal(&["reduce", &p(&part), &p(&part)]), "reduce duplicates");
    assert_eq!(table(&again), single_table);
    // Missing items are named; another comparison's part is refused.
    let o = twincal(&["reduce", &p(&dir.path().join("n3_0.jsonl"))]);
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("of the 14 items are missing (first: 1, 2, 4"), "{}", String::from_utf8_lossy(&o.stderr));
    let other = dir.path().join("other.jsonl");
    ok(twincal(&["compare", "--data", &p(&data), "--methods", "lm", "--seeds", "2", "--shard", "0/1", "--shard-out", &p(&other)]), "other");
    let o = twincal(&["reduce", &p(&part), &p(&other)]);
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("belongs to another study"), "{}", String::from_utf8_lossy(&o.stderr));
    // A shard file of another comparison is not appended to.
    let o = twincal(&[&base[..], &["--shard", "0/2", "--shard-out", &p(&other)]].concat());
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("written for another study"), "{}", String::from_utf8_lossy(&o.stderr));
    // A negative shard index reaches the shard's own check; a part in a missing folder is named
    // as such (not "cannot read"); neither leaves a file behind.
    let refused = |args: &[&str], says: &str| {
        let o = twincal(&[&base[..], args].concat());
        assert_eq!(o.status.code(), Some(2), "{args:?}");
        assert!(String::from_utf8_lossy(&o.stderr).contains(says), "{args:?}: {}", String::from_utf8_lossy(&o.stderr));
    };
    let neg = dir.path().join("neg.jsonl");
    refused(&["--shard", "-1/2", "--shard-out", &p(&neg)], "--shard must be i/N with 0 <= i < N <= 10000 (e.g. 0/3), got '-1/2'");
    assert!(!neg.exists());
    let missing = dir.path().join("no/such/part.jsonl");
    refused(&["--shard", "0/2", "--shard-out", &p(&missing)], "its folder");
    assert!(!dir.path().join("no").exists());
    edited_parts_are_refused(dir.path(), &part);
}

/// A part edited by hand is refused with the item named: a configuration that is not the one
/// its hash names (checked on every line, not the first only), a duplicate item with other
/// numbers, a negative error, a shortened residual list; text from a part is printed with its
/// control characters shown, never acted on (no forged `error:` line, no terminal escape).
fn edited_parts_are_refused(dir: &Path, part: &Path) {
    let p = |x: &Path| x.to_str().unwrap().to_owned();
    let lines: Vec<serde_json::Value> = std::fs::read_to_string(part).unwrap().lines().map(|l| serde_json::from_str(l).unwrap()).collect();
    let write = |name: &str, lines: &[serde_json::Value]| {
        let f = dir.join(name);
        std::fs::write(&f, lines.iter().map(|l| l.to_string() + "\n").collect::<String>()).unwrap();
        f
    };
    let refused = |lines: &[serde_json::Value], says: &str| {
        let f = write("edited.jsonl", lines);
        let o = twincal(&["reduce", &p(&f)]);
        assert_eq!(o.status.code(), Some(2), "{says}: {}", String::from_utf8_lossy(&o.stdout));
        assert!(String::from_utf8_lossy(&o.stderr).contains(says), "{says}: {}", String::from_utf8_lossy(&o.stderr));
    };
    let mut e = lines.clone();
    e[5]["config"]["effort"] = 0.5.into();
    refused(&e, &format!("item {}: its configuration differs from the one its hash names", e[5]["item"]));
    let mut e = lines.clone();
    let mut dup = e[4].clone();
    dup["run"]["test"]["rmse"] = 1.0.into();
    e.push(dup);
    refused(&e, &format!("item {} is also in", e[4]["item"]));
    let mut e = lines.clone();
    e[3]["run"]["train"]["rmse"] = (-0.1).into();
    refused(&e, "an error statistic that is negative");
    let mut e = lines.clone();
    let seed0 = e.iter().position(|l| l["run"]["seed"] == 0 && l["run"]["method"] == "rbf").unwrap();
    e[seed0]["test_abs_residuals"].as_array_mut().unwrap().pop();
    refused(&e, "per-sample test residuals where the other methods have");
    // A forged line: shown, not acted on.
    let mut e = lines.clone();
    e[2]["run"]["warnings"] = serde_json::json!(["\u{1b}[2J\nerror: forged"]);
    let o = ok(twincal(&["reduce", &p(&write("forged.jsonl", &e))]), "reduce of a part with control characters");
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!err.contains('\u{1b}') && !err.lines().any(|l| l.starts_with("error:")) && err.contains("\\u{1b}[2J\\u{a}error: forged"), "{err}");
}

/// The lines of a run's stdout.
fn stdout(o: &Output) -> Vec<String> {
    String::from_utf8_lossy(&o.stdout).lines().map(str::to_string).collect()
}

#[test]
fn a_hold_study_and_the_diagnosis_benchmark_shard_and_reduce_to_the_single_run() {
    let dir = tempfile::tempdir().unwrap();
    let p = |x: &Path| x.to_str().unwrap().to_owned();
    // study hold: settings (speed × hold) are the items.
    let study = ["study", "hold", "--poses", "4", "--holds", "0.05,0.5", "--speeds", "0.2,0.5"];
    let single = stdout(&ok(twincal(&study), "study hold"));
    assert_eq!(single.len(), 3 + 4, "{single:?}");
    for n in [1usize, 4] {
        let parts: Vec<String> = (0..n).map(|i| p(&dir.path().join(format!("hold-{i}-of-{n}.jsonl")))).collect();
        for (i, part) in parts.iter().enumerate() {
            ok(twincal(&[&study[..], &["--shard", &format!("{i}/{n}"), "--shard-out", part]].concat()), "a hold shard");
        }
        let reduced = ok(twincal(&[&["reduce"][..], &parts.iter().map(String::as_str).collect::<Vec<_>>()].concat()), "reduce");
        assert_eq!(stdout(&reduced), single, "{n} shards");
    }
    // A killed hold shard (its file cut inside its second line) resumes with the rest only.
    let part = dir.path().join("hold-0-of-1.jsonl");
    let text = std::fs::read_to_string(&part).unwrap();
    let second = text.find('\n').unwrap() + 1;
    std::fs::write(&part, &text[..second + 40]).unwrap();
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_twincal")).args(study).args(["--shard", "0/1", "--shard-out", &p(&part)]).output().unwrap();
    assert!(String::from_utf8_lossy(&o.stderr).contains("3 items run, 1 already in"), "{}", String::from_utf8_lossy(&o.stderr));
    assert_eq!(stdout(&ok(twincal(&["reduce", &p(&part)]), "reduce")), single);
    // A hold part edited to numbers no study writes is refused with the item named, as compare
    // parts are.
    let lines: Vec<serde_json::Value> = std::fs::read_to_string(&part).unwrap().lines().map(|l| serde_json::from_str(l).unwrap()).collect();
    for (key, value, says) in [("bias_mm", 1e308, "beyond the largest error"), ("spread_mm", -5.0, "below zero")] {
        let mut e = lines.clone();
        e[1]["row"][key] = value.into();
        let f = dir.path().join("edited-hold.jsonl");
        std::fs::write(&f, e.iter().map(|l| l.to_string() + "\n").collect::<String>()).unwrap();
        let o = twincal(&["reduce", &p(&f)]);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{key}: {err}");
        assert!(err.contains(&format!("item {}", e[1]["item"])) && err.contains(says) && err.contains("hand-edited"), "{key}: {err}");
    }
    // bench diagnose: seed × (hidden, clean, six realistic acquisitions) are the items, here
    // the hidden and clean ones (the realistic ones are diagnosed in tests/diagnose.rs); the
    // sharded run leaves out the timing (one machine's) and prints the same detection lines and
    // rates (the unsharded run times its speed once: --repeat 1).
    let bench = ["bench", "diagnose", "--seeds", "1", "--categories", "hidden,clean"];
    let single = stdout(&ok(twincal(&[&bench[..], &["--repeat", "1"]].concat()), "bench diagnose"));
    let detection: Vec<String> = single.iter().skip_while(|l| !l.starts_with("    seed")).cloned().collect();
    assert!(detection.len() >= 3, "{single:?}");
    let parts: Vec<String> = (0..2).map(|i| p(&dir.path().join(format!("diag-{i}.jsonl")))).collect();
    for (i, part) in parts.iter().enumerate() {
        ok(twincal(&[&bench[..], &["--shard", &format!("{i}/2"), "--shard-out", part]].concat()), "a diagnose shard");
    }
    let reduced = stdout(&ok(twincal(&["reduce", &parts[0], &parts[1]]), "reduce"));
    assert_eq!(reduced[1..].to_vec(), detection, "{reduced:?}");
    // Parts of different studies are not joined.
    let o = twincal(&["reduce", &parts[0], &p(&part)]);
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("belongs to another study"), "{}", String::from_utf8_lossy(&o.stderr));
}
