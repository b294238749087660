//! Implementations of the CLI commands (kept in the library so tests can call them).

use crate::error::{Error, Result};
use crate::generate::{generate as run_generate, write_outputs, Generated, Progress, Silent};
use crate::scenario::Scenario;
use std::path::Path;
use std::time::Instant;

/// A terminal progress bar (hidden when stderr is not a terminal).
pub struct Bar(indicatif::ProgressBar);

impl Bar {
    pub fn new() -> Self {
        let pb = indicatif::ProgressBar::new(0);
        pb.set_style(
            indicatif::ProgressStyle::with_template("{msg:>16} [{bar:40}] {pos}/{len} ({per_sec}, eta {eta})")
                .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar())
                .progress_chars("=> "),
        );
        Bar(pb)
    }
}

impl Default for Bar {
    fn default() -> Self {
        Self::new()
    }
}

impl Progress for Bar {
    fn start(&self, total: u64, what: &str) {
        self.0.set_length(total);
        self.0.set_position(0);
        self.0.set_message(what.to_string());
    }
    fn inc(&self, n: u64) {
        self.0.inc(n);
    }
    fn finish(&self) {
        self.0.finish_and_clear();
    }
}

pub fn progress(quiet: bool) -> Box<dyn Progress> {
    if quiet {
        Box::new(Silent)
    } else {
        Box::new(Bar::new())
    }
}

pub fn load_scenario(path: Option<&Path>) -> Result<(Scenario, crate::robot::Robot)> {
    match path {
        Some(p) => Scenario::load(p),
        None => Scenario::default_embedded(),
    }
}

/// `twincal generate`.
pub fn generate(scenario: Option<&Path>, out: &Path, rrd: Option<&Path>, seed: Option<u64>, quiet: bool) -> Result<()> {
    let (mut s, robot) = load_scenario(scenario)?;
    if let Some(seed) = seed {
        s.seed = seed;
    }
    let t0 = Instant::now();
    let g = run_generate(&s, &robot, progress(quiet).as_ref())?;
    let elapsed = t0.elapsed().as_secs_f64();
    // The recording first: if it fails, no dataset is left half-announced.
    if let Some(path) = rrd {
        crate::viz::scenes::record_dataset(&g, path)?;
    }
    write_outputs(&g, out)?;
    if !quiet {
        summary(&g, out, elapsed, rrd);
    }
    Ok(())
}

fn summary(g: &Generated, out: &Path, elapsed: f64, rrd: Option<&Path>) {
    let t = &g.truth;
    let n = g.dataset.rows.len();
    let test = t.poses.iter().filter(|p| p.split == crate::dataset::Split::Test).count();
    let steps: Vec<usize> = t.poses.iter().map(|p| p.settle_steps).collect();
    let mean_steps = steps.iter().sum::<usize>() as f64 / steps.len().max(1) as f64;
    eprintln!("scenario {} (seed {}): {n} poses ({} train / {test} test) in {elapsed:.2} s", t.scenario, t.seed, n - test);
    eprintln!("  mean settle steps per pose: {mean_steps:.0}");
    if !t.rejected.is_empty() {
        eprintln!("  {} poses rejected (listed in truth.json):", t.rejected.len());
        for r in t.rejected.iter().take(5) {
            eprintln!("    pose {}: {}", r.index, r.reason);
        }
    }
    eprintln!("  wrote {}/dataset.csv and {}/truth.json", out.display(), out.display());
    if let Some(p) = rrd {
        eprintln!("  wrote {}", p.display());
    }
}

fn median(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n == 0 {
        return f64::NAN;
    }
    if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

/// `twincal bench`: settled poses per second, with the quasi-static model and a single thread as
/// in-process baselines, and cost versus pose count.
pub fn bench(scenario: Option<&Path>, repeat: usize, quiet: bool) -> Result<()> {
    use crate::generate::{acquisition_times, build_twin, sample_poses};
    use crate::twin::{approach_sides, PoseCommand};
    use rayon::prelude::*;
    let (s, robot) = load_scenario(scenario)?;
    let repeat = repeat.max(1);
    let twin = build_twin(&s, &robot);
    let poses = sample_poses(&s, &robot)?;
    let times = acquisition_times(&s, &robot, &poses);
    let sides = approach_sides(&vec![0.0; robot.dof()], &poses);
    let cmds: Vec<PoseCommand> =
        (0..poses.len()).map(|i| PoseCommand { q_cmd: poses[i].clone(), sides: sides[i].clone(), t: times[i] }).collect();
    let n = cmds.len();
    let threads = rayon::current_num_threads();
    if !quiet {
        eprintln!("bench: scenario {}, {n} poses, {threads} threads, {repeat} repetitions (medians reported)", s.name);
    }

    let time = |f: &dyn Fn() -> Result<usize>| -> Result<(f64, usize)> {
        let mut ts = Vec::new();
        let mut steps = 0;
        for _ in 0..repeat {
            let t0 = Instant::now();
            steps = f()?;
            ts.push(t0.elapsed().as_secs_f64());
        }
        Ok((median(&mut ts), steps))
    };
    let sim_all = |subset: &[PoseCommand], parallel: bool| -> Result<usize> {
        let r: Result<Vec<usize>> = if parallel {
            subset.par_iter().map(|c| twin.simulate(c).map(|r| r.steps)).collect()
        } else {
            subset.iter().map(|c| twin.simulate(c).map(|r| r.steps)).collect()
        };
        Ok(r?.iter().sum())
    };
    let (t_qs, _) = time(&|| {
        for c in &cmds {
            std::hint::black_box(twin.quasi_static(c));
        }
        Ok(0)
    })?;
    let (t_par, steps) = time(&|| sim_all(&cmds, true))?;
    let (t_seq, _) = time(&|| sim_all(&cmds, false))?;
    let mut scaling = Vec::new();
    for frac in [4usize, 2, 1] {
        let m = n / frac;
        let (t, _) = time(&|| sim_all(&cmds[..m], true))?;
        scaling.push((m, t));
    }
    let per_step_us = t_seq / steps.max(1) as f64 * 1e6;
    println!("twin benchmark ({}, {n} poses, {threads} threads)", s.name);
    println!("  rapier, parallel      : {t_par:8.3} s  = {:8.1} poses/s   (target: {n} poses < 5 s)", n as f64 / t_par);
    println!("  rapier, one thread    : {t_seq:8.3} s  = {:8.1} poses/s   (parallel speed-up {:.2}x)", n as f64 / t_seq, t_seq / t_par);
    println!("  quasi-static baseline : {t_qs:8.3} s  = {:8.1} poses/s   (rapier costs {:.0}x the quasi-static model)", n as f64 / t_qs, t_par / t_qs);
    println!("  where the time goes   : {:.0} settle steps per pose, {per_step_us:.2} µs per step incl. world set-up (one thread)", steps as f64 / n as f64);
    println!("  cost versus pose count (parallel):");
    let base = scaling.last().map(|(m, t)| t / *m as f64).unwrap_or(f64::NAN);
    for (m, t) in &scaling {
        println!("    {m:6} poses: {t:8.3} s, {:7.3} ms/pose, ratio to full run per pose {:.2}", t / *m as f64 * 1e3, t / *m as f64 / base);
    }
    if t_par.is_nan() {
        return Err(Error::Invalid("benchmark produced no timing".into()));
    }
    Ok(())
}
