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
    let slow = t.poses.iter().filter(|p| p.settle_time_s > g.twin.sensor.hold_s).count();
    eprintln!("  mean settle steps per pose: {mean_steps:.0}; poses still moving after the {} s hold: {slow}", g.twin.sensor.hold_s);
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

/// Arguments of `twincal calibrate`.
pub struct CalibrateArgs {
    pub data: std::path::PathBuf,
    pub method: String,
    pub model: String,
    pub params: String,
    pub test_fraction: Option<f64>,
    pub seed: u64,
    pub sensor_guess: Option<Vec<f64>>,
    pub rank_tol: f64,
    pub effort: f64,
    pub out: std::path::PathBuf,
    pub urdf: Option<std::path::PathBuf>,
    pub rrd: Option<std::path::PathBuf>,
}

/// `twincal calibrate`.
pub fn calibrate(a: &CalibrateArgs, quiet: bool) -> Result<()> {
    use crate::calib::model::SensorGuess;
    use crate::calib::run::{calibrate as run, CalibOptions, Method, ModelSpec, TruthFile};
    let method = Method::parse(&a.method)?;
    let spec = ModelSpec::parse(&a.model, &a.params)?;
    if !(a.rank_tol > 0.0 && a.rank_tol < 1.0) {
        return Err(Error::Invalid(format!("--rank-tol must be in (0, 1), got {}", a.rank_tol)));
    }
    let data = crate::dataset::Dataset::load(&a.data)?;
    let truth = TruthFile::find(&a.data)?;
    let mut opts = CalibOptions::new(spec.clone(), method);
    opts.test_fraction = a.test_fraction;
    opts.seed = a.seed;
    opts.rank_tol = a.rank_tol;
    if !(a.effort > 0.0 && a.effort <= 10.0) {
        return Err(Error::Invalid(format!("--effort must be in (0, 10], got {}", a.effort)));
    }
    opts.effort = a.effort;
    if let Some(g) = &a.sensor_guess {
        if g.len() != 7 {
            return Err(Error::Invalid(format!("--sensor-guess needs 7 values in mm (exit x,y,z, length offset, tool x,y,z), got {}", g.len())));
        }
        if g.iter().any(|v| !v.is_finite()) {
            return Err(Error::Invalid("--sensor-guess values must be finite numbers (mm)".into()));
        }
        opts.sensor_guess = Some(SensorGuess { exit_m: [g[0] * 1e-3, g[1] * 1e-3, g[2] * 1e-3], offset_m: g[3] * 1e-3, tool_m: [g[4] * 1e-3, g[5] * 1e-3, g[6] * 1e-3] });
    }
    let result = run(&data, truth.as_ref(), &opts)?;
    if let Some(p) = &a.rrd {
        crate::viz::scenes::record_calibration(&result, &data, &opts, p)?;
    }
    if let Some(p) = &a.urdf {
        let nominal = match &spec {
            ModelSpec::Nominal { robot, .. } => Some(robot),
            ModelSpec::Generic6r => None,
        };
        crate::io::write_atomic(p, crate::calib::export::urdf(&result.model, &result.x, nominal, "calibrated").as_bytes())?;
    }
    crate::io::write_json(&a.out, &result)?;
    if !quiet {
        print_summary(&result);
    }
    Ok(())
}

fn print_summary(r: &crate::calib::run::CalibResult) {
    let m = &r.metrics;
    let row = |label: &str, s: &crate::calib::metrics::ErrorStats| format!("  {label:<14} {:>10.4} {:>10.4} {:>10.4}", s.rmse, s.std, s.max);
    eprintln!("{} / {} on {} ({} train, {} test rows), {} iterations, {:.3} s", r.method.name(), r.model_name, r.data, r.n_train, r.n_test, r.iterations, r.wall_time_s);
    eprintln!("  {:<14} {:>10} {:>10} {:>10}   (mm)", "residuals", "RMSE", "STD", "MAX");
    eprintln!("{}", row("train before", &m.train_before));
    eprintln!("{}", row("train after", &m.train_after));
    if let (Some(b), Some(a)) = (&m.test_before, &m.test_after) {
        eprintln!("{}", row("test before", b));
        eprintln!("{}", row("test after", a));
    }
    let fixed: Vec<&str> = r.parameters.iter().filter(|p| p.fixed).map(|p| p.name.as_str()).collect();
    eprintln!("  identifiable: {} of {} parameters; fixed (not identifiable from these poses): {}", r.parameters.len() - fixed.len(), r.parameters.len(), fixed.join(", "));
    if let Some(c) = r.identifiability.get("condition_identifiable").and_then(|v| v.as_f64()) {
        eprintln!("  condition number of the identifiable set: {c:.3e}");
    }
    if let Some(rep) = &r.repeatability {
        eprintln!("  repeatability floor: {:.4} mm from {} repeated configurations ({} rows)", rep.pooled_std, rep.groups, rep.rows);
        if let Some(t) = &m.test_after {
            eprintln!("  held-out RMSE / floor = {:.3}", t.rmse / rep.pooled_std);
        }
    }
    if let Some(t) = &r.truth_comparison {
        eprintln!("  truth: {}/{} identifiable parameters within 3σ (max |z| = {:.2}); sensor noise floor {:.4} mm", t.within_3_sigma, t.identifiable, t.max_abs_z, t.noise_floor_mm);
    }
}

/// `twincal predict`.
pub fn predict(model: &Path, data: &Path, out: &Path, quiet: bool) -> Result<()> {
    let result = crate::calib::run::CalibResult::load(model)?;
    let ds = crate::dataset::Dataset::load(data)?;
    let lengths = ds.lengths_mm()?;
    let mut text = String::from("q1,q2,q3,q4,q5,q6,L,L_pred,residual\n");
    let mut res = Vec::new();
    for (r, l) in ds.rows.iter().zip(lengths) {
        let p = result.predict_mm(&r.q_deg);
        if !p.is_finite() {
            return Err(Error::Calibration("the model predicted a non-finite length".into()));
        }
        res.push(l - p);
        let q: Vec<String> = r.q_deg.iter().map(|v| v.to_string()).collect();
        text.push_str(&format!("{},{},{},{}\n", q.join(","), l, p, l - p));
    }
    crate::io::write_atomic(out, text.as_bytes())?;
    if !quiet {
        let s = crate::calib::metrics::ErrorStats::of(&res);
        eprintln!("{} rows: RMSE {:.4} mm, STD {:.4} mm, MAX {:.4} mm; wrote {}", ds.rows.len(), s.rmse, s.std, s.max, out.display());
    }
    Ok(())
}

/// One calibration run inside `compare`.
#[derive(Clone, Debug, serde::Serialize)]
pub struct CompareRun {
    pub method: String,
    pub seed: u64,
    pub train: crate::calib::metrics::ErrorStats,
    pub test: crate::calib::metrics::ErrorStats,
    pub iterations: usize,
    pub seconds: f64,
    #[serde(skip)]
    pub test_abs_residuals: Vec<f64>,
}

/// `twincal compare`: every method on every seed (a fresh stratified split per seed), then the
/// accuracy / time table and Wilcoxon signed-rank tests of each method against the first one,
/// across seeds (test RMSE) and per sample (|test residual| of seed 0).
#[allow(clippy::too_many_arguments)]
pub fn compare(data: &Path, methods: &[String], seeds: u64, model: &str, params: &str, test_fraction: Option<f64>, effort: f64, out: Option<&Path>, quiet: bool) -> Result<()> {
    use crate::calib::run::{calibrate as run, split_rows, CalibOptions, Method, ModelSpec};
    use crate::calib::stats::{mean_std, wilcoxon_signed_rank};
    use rayon::prelude::*;
    let ds = crate::dataset::Dataset::load(data)?;
    let methods: Vec<Method> = methods.iter().map(|m| Method::parse(m)).collect::<Result<_>>()?;
    if methods.is_empty() || seeds == 0 {
        return Err(Error::Invalid("compare needs at least one method and one seed".into()));
    }
    if !(effort > 0.0 && effort <= 10.0) {
        return Err(Error::Invalid(format!("--effort must be in (0, 10], got {effort}")));
    }
    let spec = ModelSpec::parse(model, params)?;
    let n = ds.rows.len();
    let frac = test_fraction.unwrap_or_else(|| {
        let t = ds.test_indices().len();
        if t > 0 && t < n { t as f64 / n as f64 } else { 0.2 }
    });
    let jobs: Vec<(u64, Method)> = (0..seeds).flat_map(|s| methods.iter().map(move |m| (s, *m))).collect();
    let bar = progress(quiet);
    bar.start(jobs.len() as u64, "calibrations");
    let runs: Vec<Result<CompareRun>> = jobs
        .par_iter()
        .map(|(seed, m)| {
            let mut o = CalibOptions::new(spec.clone(), *m);
            o.test_fraction = Some(frac);
            o.seed = *seed;
            o.effort = effort;
            let r = run(&ds, None, &o)?;
            let (_, test_idx) = split_rows(&ds, Some(frac), *seed)?;
            let test_abs_residuals = test_idx.iter().map(|&i| (ds.rows[i].l_mm.unwrap_or(f64::NAN) - r.predict_mm(&ds.rows[i].q_deg)).abs()).collect();
            bar.inc(1);
            Ok(CompareRun {
                method: m.name().into(),
                seed: *seed,
                train: r.metrics.train_after,
                test: r.metrics.test_after.unwrap_or_default(),
                iterations: r.iterations,
                seconds: r.wall_time_s,
                test_abs_residuals,
            })
        })
        .collect();
    bar.finish();
    let runs: Vec<CompareRun> = runs.into_iter().collect::<Result<_>>()?;
    let by = |m: &str| runs.iter().filter(|r| r.method == m).cloned().collect::<Vec<_>>();
    let mut table = String::new();
    table.push_str(&format!("# Method comparison on {} ({} rows, {seeds} seeds, test fraction {frac:.2})\n\n", ds.source, n));
    table.push_str("| method | train RMSE | train STD | train MAX | test RMSE | test STD | test MAX | iterations | seconds |\n|---|---|---|---|---|---|---|---|---|\n");
    let ms = |v: Vec<f64>| {
        let (m, s) = mean_std(&v);
        format!("{m:.4} ± {s:.4}")
    };
    for m in &methods {
        let r = by(m.name());
        table.push_str(&format!(
            "| {} | {} | {} | {} | {} | {} | {} | {} | {} |\n",
            m.name(),
            ms(r.iter().map(|x| x.train.rmse).collect()),
            ms(r.iter().map(|x| x.train.std).collect()),
            ms(r.iter().map(|x| x.train.max).collect()),
            ms(r.iter().map(|x| x.test.rmse).collect()),
            ms(r.iter().map(|x| x.test.std).collect()),
            ms(r.iter().map(|x| x.test.max).collect()),
            ms(r.iter().map(|x| x.iterations as f64).collect()),
            ms(r.iter().map(|x| x.seconds).collect()),
        ));
    }
    let mut tests = Vec::new();
    let reference = methods[0].name();
    let ref_runs = by(reference);
    table.push_str(&format!("\n## Wilcoxon signed-rank tests against `{reference}` (two-sided)\n\n| method | across seeds: W | p | per sample (seed 0): W | p |\n|---|---|---|---|---|\n"));
    for m in methods.iter().skip(1) {
        let r = by(m.name());
        let a: Vec<f64> = ref_runs.iter().map(|x| x.test.rmse).collect();
        let b: Vec<f64> = r.iter().map(|x| x.test.rmse).collect();
        let across = wilcoxon_signed_rank(&a, &b).ok();
        let per = wilcoxon_signed_rank(&ref_runs[0].test_abs_residuals, &r[0].test_abs_residuals).ok();
        let cell = |w: &Option<crate::calib::stats::Wilcoxon>| match w {
            Some(w) => (format!("{:.1}", w.statistic.abs()), format!("{:.3e}", w.p_value)),
            None => ("–".into(), "–".into()),
        };
        let (wa, pa) = cell(&across);
        let (wp, pp) = cell(&per);
        table.push_str(&format!("| {} | {wa} | {pa} | {wp} | {pp} |\n", m.name()));
        tests.push(serde_json::json!({"method": m.name(), "against": reference, "across_seeds": across.map(|w| serde_json::json!({"statistic": w.statistic, "p_value": w.p_value, "n": w.n})), "per_sample": per.map(|w| serde_json::json!({"statistic": w.statistic, "p_value": w.p_value, "n": w.n}))}));
    }
    println!("{table}");
    if let Some(p) = out {
        crate::io::write_json(p, &serde_json::json!({"data": ds.source, "seeds": seeds, "test_fraction": frac, "runs": runs, "wilcoxon": tests}))?;
    }
    Ok(())
}

/// `twincal bench calib`: the calibration core's targets, measured.
pub fn bench_calib(repeat: usize, seeds: u64, with_compare: bool) -> Result<()> {
    use crate::calib::optim::LeastSquares;
    use crate::calib::problem::LengthFit;
    use crate::calib::run::{calibrate as run, CalibOptions, Method, ModelSpec, TruthFile};
    use rayon::prelude::*;
    let (base, robot) = Scenario::from_toml(include_str!("../scenarios/irb120_geometric.toml"), "irb120_geometric")
        .and_then(|s| s.load_robot(None).map(|r| (s, r)))?;
    let spec = ModelSpec::Nominal { robot: robot.clone(), parametrisation: "hayati".into() };
    let tmp = std::env::temp_dir().join(format!("twincal-bench-{}", std::process::id()));
    let gen = |seed: u64, poses: usize, test: usize| -> Result<(crate::dataset::Dataset, TruthFile)> {
        let mut s = base.clone();
        s.seed = seed;
        s.sampling.poses = poses;
        s.sampling.test = test;
        let g = run_generate(&s, &robot, &Silent)?;
        let dir = tmp.join(format!("s{seed}-{poses}"));
        write_outputs(&g, &dir)?;
        let truth = TruthFile::find(&dir)?.ok_or_else(|| Error::Invalid("truth missing".into()))?;
        Ok((g.dataset, truth))
    };

    // 1. LM speed on 500 training poses, against one residual + Jacobian evaluation.
    let (ds, truth) = gen(base.seed, 600, 100)?;
    let opts = CalibOptions::new(spec.clone(), Method::Lm);
    let mut times = Vec::new();
    let mut iters = 0;
    for _ in 0..repeat.max(5) {
        let r = run(&ds, Some(&truth), &opts)?;
        times.push(r.wall_time_s);
        iters = r.iterations;
    }
    let t_lm = median(&mut times);
    let train: Vec<usize> = ds.train_indices();
    let samples = crate::calib::run::samples(&ds, &train);
    let model = run(&ds, None, &opts)?.model;
    let fit = LengthFit { model: &model, data: &samples };
    let mut jt = Vec::new();
    for _ in 0..20 {
        let t0 = Instant::now();
        let mut j = nalgebra::DMatrix::zeros(samples.len(), model.n_params());
        fit.jacobian(&model.nominal, &mut j);
        let mut r = vec![0.0; samples.len()];
        fit.residuals(&model.nominal, &mut r);
        std::hint::black_box((&j, &r));
        jt.push(t0.elapsed().as_secs_f64());
    }
    let t_j = median(&mut jt);
    println!("calibration benchmark");
    println!("  LM, {} training poses      : {:8.2} ms median (target < 20 ms), {iters} iterations; one residual+Jacobian evaluation {:.3} ms -> LM = {:.1} evaluations", train.len(), t_lm * 1e3, t_j * 1e3, t_lm / t_j);
    println!("    (calibrate wall time includes the sensor pre-alignment, identifiability analysis and covariance)");

    // 2. Accuracy over seeds: test RMSE against the noise floor, parameters against the truth.
    let rows: Vec<Result<(f64, usize, usize, f64)>> = (0..seeds)
        .into_par_iter()
        .map(|seed| {
            let (ds, truth) = gen(1000 + seed, 400, 100)?;
            let r = run(&ds, Some(&truth), &opts)?;
            let c = r.truth_comparison.clone().ok_or_else(|| Error::Invalid("no truth comparison".into()))?;
            Ok((r.metrics.test_after.map(|m| m.rmse).unwrap_or(f64::NAN) / truth.noise_std_mm, c.within_3_sigma, c.identifiable, c.max_abs_z))
        })
        .collect();
    let rows: Vec<(f64, usize, usize, f64)> = rows.into_iter().collect::<Result<_>>()?;
    let mut ratios: Vec<f64> = rows.iter().map(|r| r.0).collect();
    let within5 = ratios.iter().filter(|r| (*r - 1.0).abs() <= 0.05).count();
    let all_in = rows.iter().filter(|r| r.1 == r.2).count();
    let total_in: usize = rows.iter().map(|r| r.1).sum();
    let total: usize = rows.iter().map(|r| r.2).sum();
    let mut zs: Vec<f64> = rows.iter().map(|r| r.3).collect();
    println!("  irb120_geometric, {seeds} seeds (400 poses, 300/100):");
    println!("    test RMSE / noise floor   : median {:.3}, min {:.3}, max {:.3}; within 5 %: {within5}/{seeds} (sampling spread of an RMSE over 100 test poses is about ±7 %)", median(&mut ratios), ratios.first().copied().unwrap_or(f64::NAN), ratios.last().copied().unwrap_or(f64::NAN));
    println!("    identifiable within 3σ    : {total_in}/{total} parameters; every one in {all_in}/{seeds} seeds; median max |z| {:.2}", median(&mut zs));

    // 3. The full comparison over 30 seeds.
    if with_compare {
        let dir = tmp.join(format!("s{}-400", 1000));
        let t0 = Instant::now();
        compare(&dir, &["lm", "ekf", "pf", "pso", "rbf"].map(String::from), 30, "irb120", "hayati", None, 1.0, None, true)?;
        println!("  compare, 5 methods x 30 seeds: {:.1} s wall time", t0.elapsed().as_secs_f64());
    }

    // 4. Real data.
    let hsr = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/data/hsr-robotcali/hsr_robotcali_pool.csv");
    if hsr.exists() {
        let ds = crate::dataset::Dataset::load(&hsr)?;
        let mut o = CalibOptions::new(ModelSpec::Generic6r, Method::Lm);
        o.test_fraction = Some(0.2);
        let r = run(&ds, None, &o)?;
        if let (Some(rep), Some(t)) = (&r.repeatability, &r.metrics.test_after) {
            println!("  HSR-RobotCali (generic6r, 80/20): held-out RMSE {:.4} mm, repeatability floor {:.4} mm, ratio {:.3} (target < 1.3), {:.1} s", t.rmse, rep.pooled_std, t.rmse / rep.pooled_std, r.wall_time_s);
        }
    } else {
        println!("  HSR-RobotCali: skipped, {} is absent", hsr.display());
    }
    let _ = std::fs::remove_dir_all(&tmp);
    Ok(())
}
