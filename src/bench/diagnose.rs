//! `twincal bench diagnose`: the diagnosis' speed, detection and false-alarm rates.

use crate::calib::stats::median;
use crate::dataset::Dataset;
use crate::error::Result;
use crate::sim::generate::{generate as run_generate, Generated, Progress, Silent};
use crate::sim::scenario::Scenario;
use std::time::Instant;

/// `twincal bench diagnose`: the 600-pose all-effects diagnosis timed (median of three, time per
/// candidate), then `seeds` scenarios with one hidden effect (cause, joint and size from the
/// seed) and `seeds` clean ones: detection rate (cause and joint named first, size within its
/// uncertainty band or 30 %) and false-alarm rate.
pub fn bench_diagnose(seeds: u64, bar: &dyn Progress) -> Result<()> {
    use crate::dataset::Row;
    use crate::diagnose::hidden::{clean, hidden};
    use crate::diagnose::{diagnose, DiagnoseOptions};
    let opts = DiagnoseOptions::new(crate::calib::run::ModelSpec::parse("irb120", "hayati")?);
    let strip = |g: &Generated| Dataset { rows: g.dataset.rows.iter().map(|r| Row { split: None, ..r.clone() }).collect(), source: g.dataset.source.clone() };
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
    let mut detected = 0;
    let mut sized = 0;
    let mut alarms = 0;
    let mut rows = Vec::new();
    for seed in 1..=seeds {
        let (s, robot, truth) = hidden(seed, 1)?;
        let h = &truth[0];
        let (d, _) = diagnose(&strip(&run_generate(&s, &robot, &Silent)?), &opts, &|_| {})?;
        let first = d.causes.first();
        let named = first.is_some_and(|c| h.named_by(c));
        let size = first.is_some_and(|c| named && h.sized_by(c));
        detected += named as usize;
        sized += size as usize;
        rows.push(format!(
            "    seed {seed:3}: hidden {}{} {:.4} ({:.1}x) -> {}{}",
            h.cause.name(),
            h.joint.map(|j| format!("[j{}]", j + 1)).unwrap_or_default(),
            h.magnitude,
            h.factor,
            d.verdict,
            first.map(|c| format!(" {:.4} ± {:.4} {}", c.magnitude, c.uncertainty, c.unit)).unwrap_or_default()
        ));
        bar.inc(1);
        let (s, robot) = clean(10_000 + seed)?;
        let (d, _) = diagnose(&strip(&run_generate(&s, &robot, &Silent)?), &opts, &|_| {})?;
        if !d.causes.is_empty() {
            alarms += 1;
            rows.push(format!("    clean seed {}: false alarm {}", 10_000 + seed, d.verdict));
        }
        bar.inc(1);
    }
    bar.finish();
    for r in &rows {
        println!("{r}");
    }
    let n = seeds as f64;
    println!(
        "  hidden effects: {detected}/{seeds} named first with the right joint ({:.0} %, target >= 95 %), {sized}/{seeds} also sized right",
        100.0 * detected as f64 / n
    );
    println!("  clean datasets: {alarms}/{seeds} false alarms ({:.0} %, target <= 5 %)", 100.0 * alarms as f64 / n);
    Ok(())
}
