//! `twincal bench diagnose`: the diagnosis' speed, detection and false-alarm rates.

use crate::calib::stats::median;
use crate::dataset::Dataset;
use crate::error::Result;
use crate::sim::generate::{generate as run_generate, Generated, Progress, Silent};
use crate::sim::scenario::Scenario;
use std::time::Instant;

/// What the detection part of `bench diagnose` is over (its work items: seed × hidden/clean).
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct DetectionConfig {
    pub seeds: u64,
    pub twincal_version: String,
}

impl crate::shard::Config for DetectionConfig {
    const KIND: &'static str = "bench-diagnose";
    fn hash(&self) -> String {
        crate::calib::truth::sha256_hex(serde_json::to_string(self).unwrap_or_default().as_bytes())
    }
    /// Item `id`: seed `id / 2 + 1`, its hidden-effect scenario (even) or its clean one (odd).
    fn items(&self) -> u64 {
        2 * self.seeds
    }
}

/// One diagnosed scenario of the detection part.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct DetectionItem {
    /// The line printed for it (every hidden effect; a clean scenario's false alarm).
    pub line: Option<String>,
    pub detected: bool,
    pub sized: bool,
    pub alarm: bool,
}

fn strip(g: &Generated) -> Dataset {
    use crate::dataset::Row;
    Dataset { rows: g.dataset.rows.iter().map(|r| Row { split: None, ..r.clone() }).collect(), source: g.dataset.source.clone() }
}

fn options() -> Result<crate::diagnose::DiagnoseOptions> {
    Ok(crate::diagnose::DiagnoseOptions::new(crate::calib::run::ModelSpec::parse("irb120", "hayati")?))
}

/// Work item `id` of the detection part: a scenario generated from its seed and diagnosed.
pub fn detection_item(id: u64) -> Result<DetectionItem> {
    use crate::diagnose::diagnose;
    use crate::diagnose::hidden::{clean, hidden};
    let (seed, opts) = (id / 2 + 1, options()?);
    if id % 2 == 0 {
        let (s, robot, truth) = hidden(seed, 1)?;
        let h = &truth[0];
        let (d, _) = diagnose(&strip(&run_generate(&s, &robot, &Silent)?), &opts, &|_| {})?;
        let first = d.causes.first();
        let named = first.is_some_and(|c| h.named_by(c));
        let sized = first.is_some_and(|c| named && h.sized_by(c));
        let line = format!(
            "    seed {seed:3}: hidden {}{} {:.4} ({:.1}x) -> {}{}",
            h.cause.name(),
            h.joint.map(|j| format!("[j{}]", j + 1)).unwrap_or_default(),
            h.magnitude,
            h.factor,
            d.verdict,
            first.map(|c| format!(" {:.4} ± {:.4} {}", c.magnitude, c.uncertainty, c.unit)).unwrap_or_default()
        );
        Ok(DetectionItem { line: Some(line), detected: named, sized, alarm: false })
    } else {
        let (s, robot) = clean(10_000 + seed)?;
        let (d, _) = diagnose(&strip(&run_generate(&s, &robot, &Silent)?), &opts, &|_| {})?;
        let alarm = !d.causes.is_empty();
        let line = alarm.then(|| format!("    clean seed {}: false alarm {}", 10_000 + seed, d.verdict));
        Ok(DetectionItem { line, detected: false, sized: false, alarm })
    }
}

/// The detection part's lines and rates, from every item in order (what `bench diagnose`
/// prints, and `reduce` the same from the shards' parts).
pub fn print_detection(config: &DetectionConfig, items: &[DetectionItem]) {
    for line in items.iter().filter_map(|i| i.line.as_ref()) {
        println!("{line}");
    }
    let seeds = config.seeds;
    let count = |f: fn(&DetectionItem) -> bool| items.iter().filter(|i| f(i)).count();
    let (detected, sized, alarms) = (count(|i| i.detected), count(|i| i.sized), count(|i| i.alarm));
    let n = seeds as f64;
    println!(
        "  hidden effects: {detected}/{seeds} named first with the right joint ({:.0} %, target >= 95 %), {sized}/{seeds} also sized right",
        100.0 * detected as f64 / n
    );
    println!("  clean datasets: {alarms}/{seeds} false alarms ({:.0} %, target <= 5 %)", 100.0 * alarms as f64 / n);
}

/// `twincal bench diagnose`: the 600-pose all-effects diagnosis timed (median of three, time per
/// candidate), then `seeds` scenarios with one hidden effect (cause, joint and size from the
/// seed) and `seeds` clean ones: detection rate (cause and joint named first, size within its
/// uncertainty band or 30 %) and false-alarm rate. With a shard, only its detection items
/// (the timing is a single machine's and is left out).
pub fn bench_diagnose(seeds: u64, bar: &dyn Progress, shard: Option<&crate::shard::Shard>, config: &DetectionConfig) -> Result<()> {
    use crate::diagnose::diagnose;
    if let Some(sh) = shard {
        let mine: Vec<u64> = (0..2 * seeds).filter(|id| sh.wants(*id)).collect();
        bar.start(mine.len() as u64, "diagnoses");
        for id in &mine {
            sh.append(*id, config, &detection_item(*id)?)?;
            bar.inc(1);
        }
        bar.finish();
        eprintln!("{}", sh.summary(mine.len()));
        return Ok(());
    }
    let opts = options()?;
    println!("diagnosis benchmark");
    // 1. Speed on the embedded 600-pose scenario with every effect.
    let (s, robot) = Scenario::default_embedded()?;
    let g = run_generate(&s, &robot, &Silent)?;
    let data = strip(&g);
    let mut times = Vec::new();
    let mut per_candidate = Vec::new();
    let mut evaluated = 0;
    let mut verdict = String::new();
    for _ in 0..3 {
        let t0 = Instant::now();
        let (d, _) = diagnose(&data, &opts, &|_| {})?;
        times.push(t0.elapsed().as_secs_f64());
        let c: Vec<f64> = d.steps.iter().flat_map(|st| st.candidates.iter().map(|c| c.seconds)).collect();
        evaluated = c.len();
        per_candidate.push(median(&c));
        verdict = d.verdict.clone();
    }
    println!(
        "  {} poses, every effect, {} threads: {:.2} s median (target < 10 s); {evaluated} candidate fits, {:.0} ms each (median, one thread each); found {verdict}",
        data.rows.len(),
        rayon::current_num_threads(),
        median(&times),
        median(&per_candidate) * 1e3
    );
    // 2. Detection and false alarms.
    bar.start(2 * seeds, "diagnoses");
    let mut items = Vec::new();
    for id in 0..2 * seeds {
        items.push(detection_item(id)?);
        bar.inc(1);
    }
    bar.finish();
    print_detection(config, &items);
    Ok(())
}

/// `twincal reduce` of `bench diagnose` shards: the detection part's lines and rates.
pub fn reduce_detection(parts: crate::shard::Parts, quiet: bool) -> Result<()> {
    let files = parts.files;
    let (config, items, duplicates) = parts.gather::<DetectionConfig, DetectionItem>()?;
    if !quiet {
        eprintln!("reduced {files} parts: {} diagnoses of bench diagnose (detection, {} seeds), {duplicates} duplicates dropped", items.len(), config.seeds);
    }
    println!("diagnosis benchmark: detection and false alarms (sharded; the timing is one machine's: run bench diagnose unsharded)");
    print_detection(&config, &items);
    Ok(())
}
