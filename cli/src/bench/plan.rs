//! `twincal bench plan`: measurement plans verified on the twin ([`twincal::plan::verify`]) —
//! for N in {15, 30, 60} planned poses against random feasible sets of N, 1.5N, 2N, 3N and 4N poses,
//! each calibrated alone and judged by its true error on independent test poses, over seeds —
//! and the time a plan of 30 poses out of 10 000 candidates takes against its 5 s target.

use std::path::Path;
use std::time::Instant;
use twincal::error::Result;
use twincal::plan::verify::{study, Comparison, StudyOptions};
use twincal::plan::{plan, PlanOptions};
use twincal::sim::scenario::Scenario;

/// The scenarios compared: (label, scenario file, plan sizes).
const CASES: [(&str, &str, &[usize]); 2] =
    [("IRB 120, laser tracker, geometric", "irb120_tracker", &[15, 30, 60]), ("IRB 120, draw-wire cable, geometric", "irb120_geometric", &[40, 60, 120])];

fn load(file: &str) -> Result<(Scenario, twincal::robot::Robot)> {
    let dir = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../scenarios"));
    let path = dir.join(format!("{file}.toml"));
    let text = std::fs::read_to_string(&path).map_err(|e| twincal::error::Error::io(&path, e))?;
    let s = Scenario::from_toml(&text, file)?;
    let robot = s.load_robot(Some(dir))?;
    Ok((s, robot))
}

fn print(label: &str, rows: &[Comparison], seeds: u64) {
    println!("\n## {label} ({seeds} seeds; true position error on 200 independent test poses after calibration, RMS mm, median over seeds)\n");
    let sizes = &rows[0].random_sizes;
    let head: Vec<String> = (0..sizes.len()).map(|k| format!("random {}N", o_round(sizes[k] as f64 / rows[0].n as f64))).collect();
    println!(
        "| N | planned | {} | random poses reaching the plan's error | planned better than random N (seeds) | predicted worth of the plan, random poses | predicted worth of the best possible N |",
        head.join(" | ")
    );
    println!("|---|---|{}---|---|---|---|", "---|".repeat(sizes.len()));
    for c in rows {
        let wins = c.seeds.iter().filter(|r| r.planned_mm < r.random_mm[0]).count();
        let worth = |w: Option<f64>| w.map_or("beyond 8N".to_string(), |k| format!("{k:.0} ({:.1}N)", k / c.n as f64));
        println!(
            "| {} | {:.4} | {} | {} | {wins}/{} | {} | {} |",
            c.n,
            c.planned_median_mm,
            c.random_median_mm.iter().map(|e| format!("{e:.4}")).collect::<Vec<_>>().join(" | "),
            c.random_poses_to_match.map_or(format!("more than {}", sizes.last().unwrap_or(&0)), |k| k.to_string()),
            c.seeds.len(),
            worth(c.predicted_plan_worth),
            worth(c.predicted_best_worth)
        );
    }
}

/// Runs the study over `seeds` seeds and prints its tables, then the speed.
pub fn bench_plan(seeds: u64, repeat: usize) -> Result<()> {
    println!("# Measurement plans verified on the twin (I-optimal and D-optimal, 10 000 feasible candidates, Hayati model)");
    for (label, file, ns) in CASES {
        let (s, robot) = load(file)?;
        for criterion in ["i", "d"] {
            let plan = PlanOptions { criterion: criterion.into(), ..PlanOptions::default() };
            let o = StudyOptions { ns: ns.to_vec(), multiples: vec![1.0, 1.5, 2.0, 3.0, 4.0], seeds: (1..=seeds).collect(), test_poses: 200, plan };
            let rows = study(&s, &robot, &o)?;
            print(&format!("{label}, criterion {criterion}"), &rows, seeds);
        }
    }
    hidden(seeds)?;
    speed(repeat)
}

/// Compliance under a 3 kg payload, hidden in the tracker scenario (as `bench compensate` adds it).
const COMPLIANCE: &str =
    "[effects.compliance]\nstiffness_nm_per_rad = [1.5e5, 2.0e4, 3.0e4, 3.0e4, 3.0e4, 2.0e4]\n\n[effects.payload]\nmass_kg = 3.0\ncom_mm = [40.0, 0.0, 60.0]\n\n";

/// Compliance twenty times stiffer, no payload in the scenario: the engineer measures without one
/// unless a plan says to mount one (0 or 5 kg at the same centre of mass).
const STIFF: &str =
    "[effects.compliance]\nstiffness_nm_per_rad = [3.0e6, 4.0e5, 6.0e5, 6.0e5, 6.0e5, 4.0e5]\n\n[effects.payload]\nmass_kg = 0.0\ncom_mm = [40.0, 0.0, 60.0]\n\n";

/// The hidden-effect comparisons: a plan that includes the compliance's parameters against random
/// feasible sets of the same size, each diagnosed and calibrated with compliance; then a stiff
/// compliance with no payload mounted, planned over payloads of 0 and 5 kg.
pub fn hidden(seeds: u64) -> Result<()> {
    hidden_case("joint compliance under a 3 kg payload", COMPLIANCE, &[60, 120], &[], seeds)?;
    hidden_case("joint compliance 20 times stiffer, no payload mounted; the plan chooses 0 or 5 kg per pose", STIFF, &[60], &[0.0, 5.0], seeds)
}

/// One hidden-effect comparison (`extra` added to the tracker scenario before `[sensor]`).
fn hidden_case(what: &str, extra: &str, sizes: &[usize], payloads: &[f64], seeds: u64) -> Result<()> {
    let (_, robot) = load("irb120_tracker")?;
    let path = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../scenarios/irb120_tracker.toml"));
    let text = std::fs::read_to_string(path).map_err(|e| twincal::error::Error::io(path, e))?;
    let s = Scenario::from_toml(&text.replacen("[sensor]", &format!("{extra}[sensor]"), 1), "irb120_tracker + compliance")?;
    let truth: Vec<f64> = s.effects.compliance.as_ref().map_or(vec![], |c| c.stiffness_nm_per_rad.iter().map(|k| 1e6 / k).collect());
    let loads = twincal::calib::effects::inputs::JointLoads { payload: s.effects.payload.clone(), ..Default::default() };
    let o =
        PlanOptions { effects: vec![(twincal::calib::effects::EffectKind::Compliance, None)], loads, payloads: payloads.to_vec(), ..PlanOptions::default() };
    println!(
        "\n## Hidden effect: {what} (IRB 120, laser tracker; {seeds} seeds; true compliance per joint {} µrad/Nm)\n",
        truth.iter().map(|c| format!("{c:.2}")).collect::<Vec<_>>().join(", ")
    );
    println!("| poses | N | diagnose named compliance (seeds) | joints named (all seeds) | other causes named (all seeds) | joint 2 named as, µrad/Nm (median) | true error calibrated with compliance, mm (median) |");
    println!("|---|---|---|---|---|---|---|");
    for &n in sizes {
        let rows = twincal::plan::verify::hidden_effect(&s, &robot, n, &(1..=seeds).collect::<Vec<_>>(), 200, &o)?;
        let planned = if payloads.is_empty() { "planned (with compliance)" } else { "planned (with compliance and payloads)" };
        let mut cases: Vec<(&str, Vec<&twincal::plan::verify::EffectCheck>)> =
            vec![(planned, rows.iter().map(|r| &r.planned).collect()), ("random feasible", rows.iter().map(|r| &r.random).collect())];
        if !payloads.is_empty() {
            cases.push(("random feasible, random payload", rows.iter().filter_map(|r| r.random_payloads.as_ref()).collect()));
        }
        for (label, checks) in cases {
            let named = checks.iter().filter(|c| !c.named.is_empty()).count();
            let mut joints = std::collections::BTreeMap::<usize, usize>::new();
            checks.iter().flat_map(|c| c.named.iter()).for_each(|(j, ..)| *joints.entry(*j).or_default() += 1);
            let mut others = std::collections::BTreeMap::<String, usize>::new();
            checks.iter().flat_map(|c| c.others.iter()).for_each(|o| *others.entry(o.clone()).or_default() += 1);
            let j2: Vec<f64> = checks.iter().flat_map(|c| c.named.iter().filter(|(j, ..)| *j == 2).map(|(_, m, _)| *m)).collect();
            println!(
                "| {label} | {n} | {named}/{} | {} | {} | {} | {:.4} |",
                checks.len(),
                joints.iter().map(|(j, k)| format!("{j}: {k}")).collect::<Vec<_>>().join(", "),
                if others.is_empty() { "none".into() } else { others.iter().map(|(c, k)| format!("{c}: {k}")).collect::<Vec<_>>().join(", ") },
                if j2.is_empty() { "never named".into() } else { format!("{:.2} ({} seeds)", twincal::stats::median(&j2), j2.len()) },
                twincal::stats::median(&checks.iter().map(|c| c.true_error_mm).collect::<Vec<_>>())
            );
        }
    }
    Ok(())
}

/// `plan` for 30 poses out of 10 000 candidates on the tracker scenario: median of `repeat` runs
/// against the 5 s target, and the stages' share.
fn speed(repeat: usize) -> Result<()> {
    let (s, robot) = load("irb120_tracker")?;
    let mut times = Vec::new();
    let mut last = None;
    for _ in 0..repeat.max(1) {
        let t0 = Instant::now();
        last = Some(plan(&s, &robot, &PlanOptions::default())?);
        times.push(t0.elapsed().as_secs_f64());
    }
    let med = twincal::stats::median(&times);
    let p = last.expect("ran at least once");
    println!(
        "\n## Speed\n\nplan 30 of 10 000 candidates (irb120_tracker, {} parameters): {med:.2} s median of {} runs (target < 5 s; {} exchange sweeps, {} swaps)",
        p.identifiable.len(),
        times.len(),
        p.design.sweeps,
        p.design.exchanges
    );
    Ok(())
}

/// A multiple as the table heads it: 1.5, 2 (one decimal at most).
fn o_round(m: f64) -> String {
    let r = (m * 10.0).round() / 10.0;
    if r.fract() == 0.0 {
        format!("{r:.0}")
    } else {
        format!("{r:.1}")
    }
}
