//! Implementations of the CLI commands (kept in the library so tests can call them).

use crate::calib::stats::median;
use crate::dataset::Dataset;
use crate::error::{Error, Result};
use crate::generate::{generate as run_generate, stage_outputs, write_outputs, Generated, Progress, Silent};
use crate::io::{check_outputs, OutputSet};
use crate::report::verdict::{judge, with_verdict, Limit};
use crate::scenario::Scenario;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Most seeds `compare` and `bench calib` accept.
pub const MAX_SEEDS: u64 = 1000;
/// Most calibrations (methods × seeds) one `compare` runs.
pub const MAX_COMPARE_JOBS: u64 = 5000;
/// Most repetitions `bench` accepts.
pub const MAX_REPEAT: usize = 1000;

/// `--angles`: unit of the joint angles in a dataset.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum AngleArg {
    /// Degrees, unless the values look like radians (then an error says so).
    Auto,
    /// Degrees.
    Deg,
    /// Radians.
    Rad,
}

/// `twincal bench` targets.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum BenchTarget {
    /// The twin: settled poses per second, rapier against the quasi-static model.
    Twin,
    /// The calibration core's targets.
    Calib,
    /// The diagnosis: detection and false-alarm rates over hidden-effect scenarios, time.
    Diagnose,
    /// Evo-NPH: DS-ADE speed, ablations with the truth, DE engines on one objective (Table 10).
    Dsade,
    /// Inverse kinematics: Jacobian variants, time per query, true error on the twin.
    Ik,
    /// PSO-EKF-AWNN: stage times against LM, accuracy and truth over seeds, data efficiency,
    /// sensitivity to Q, R and the learning rate, HSR-RobotCali.
    Awnn,
    /// Real measured data: HSR generic model per search seed and its diagnosis, RobotCali
    /// methods over random splits with and without the outlier screen.
    Real,
}

/// Loads a dataset for a command. `require_length`: the `L` column must be present (calibrate,
/// compare) or may be absent (predict).
fn load_dataset(path: &Path, angles: AngleArg, require_length: bool) -> Result<Dataset> {
    use crate::dataset::{AngleUnit, LoadOptions};
    let angles = match angles {
        AngleArg::Auto => AngleUnit::Auto,
        AngleArg::Deg => AngleUnit::Deg,
        AngleArg::Rad => AngleUnit::Rad,
    };
    Dataset::load_with(path, &LoadOptions { angles, require_length })
}

/// The files a `--data` path reads: `DIR/dataset.csv` for a folder, the file otherwise (without
/// an xlsx `#Sheet`), plus the truth file `calibrate` reads beside either.
fn data_inputs(data: &Path) -> Vec<PathBuf> {
    let file = if data.is_dir() {
        data.join(crate::dataset::DATASET_FILE)
    } else {
        match data.to_string_lossy().rsplit_once('#') {
            Some((f, _)) if !data.exists() => PathBuf::from(f),
            _ => data.to_path_buf(),
        }
    };
    let dir = if data.is_dir() { data.to_path_buf() } else { file.parent().map(Path::to_path_buf).unwrap_or_default() };
    vec![file, dir.join(crate::calib::truth::TRUTH_FILE)]
}

/// The calibration model a `--model` / `--params` pair names; `--params` is refused for
/// `generic6r`, which has no nominal model to parametrise.
fn model_spec(model: &str, params: Option<&str>) -> Result<crate::calib::run::ModelSpec> {
    if model == "generic6r" {
        if let Some(p) = params {
            return Err(Error::Invalid(format!("--params {p} applies to nominal models (irb120 or a .urdf); generic6r has no nominal model to parametrise")));
        }
    }
    crate::calib::run::ModelSpec::parse(model, params.unwrap_or("hayati"))
}

/// Which model a calibration fits (`--model`, `--params`).
#[derive(Clone, Debug, clap::Args)]
pub struct ModelArgs {
    /// irb120 (embedded URDF), a .urdf path, or generic6r (no nominal).
    #[arg(long, default_value = "irb120")]
    pub model: String,
    /// Parametrisation of a nominal model: hayati (D-H, β on parallel axes; the default), dh (papers' 24)
    /// or frame. Not for generic6r.
    #[arg(long)]
    pub params: Option<String>,
}

impl ModelArgs {
    /// The model these options name; `--params` is refused for `generic6r`.
    pub fn spec(&self) -> Result<crate::calib::run::ModelSpec> {
        model_spec(&self.model, self.params.as_deref())
    }

    /// `--model` as an input file, when it names one (a .urdf).
    fn input(&self) -> Option<PathBuf> {
        self.model.ends_with(".urdf").then(|| PathBuf::from(&self.model))
    }
}

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
    if out.exists() && !out.is_dir() {
        return Err(Error::Invalid(format!("--out {} is a file; generate writes a folder (dataset.csv, truth.json)", out.display())));
    }
    let dataset = out.join(crate::dataset::DATASET_FILE);
    let truth = out.join(crate::calib::truth::TRUTH_FILE);
    let mut outputs_named = vec![("--out", dataset.as_path()), ("--out", truth.as_path())];
    if let Some(p) = rrd {
        outputs_named.push(("--rrd", p));
    }
    let inputs: Vec<(&str, &Path)> = scenario.map(|p| ("--scenario", p)).into_iter().collect();
    check_outputs(&inputs, &outputs_named)?;
    let (mut s, robot) = load_scenario(scenario)?;
    if let Some(seed) = seed {
        s.seed = seed;
    }
    let t0 = Instant::now();
    let g = run_generate(&s, &robot, progress(quiet).as_ref())?;
    let elapsed = t0.elapsed().as_secs_f64();
    let mut outputs = OutputSet::new();
    if let Some(path) = rrd {
        crate::viz::scenes::record_dataset(&g, &mut outputs, path)?;
    }
    stage_outputs(&g, out, &mut outputs)?;
    outputs.commit()?;
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
    let acq: Vec<&crate::generate::PoseAcquisition> = t.poses.iter().filter_map(|p| p.acquisition.as_ref()).collect();
    if acq.is_empty() {
        let slow = t.poses.iter().filter(|p| p.settle_time_s > g.twin.sensor.hold_s).count();
        eprintln!("  mean settle steps per pose: {mean_steps:.0}; poses still moving after the {} s hold: {slow}", g.twin.sensor.hold_s);
    } else {
        // The simulated tour: rapier steps per pose, and how the stability gate and the transient fared.
        let closed = acq.iter().filter(|a| a.gate_s.is_none()).count();
        let worst = acq.iter().map(|a| a.transient_mm.abs()).fold(0.0f64, f64::max);
        eprintln!(
            "  simulated tour: {mean_steps:.0} rapier steps per pose; gate still closed after the {} s hold: {closed} read anyway; largest transient in L {worst:.1e} mm",
            g.twin.sensor.hold_s
        );
    }
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

/// `twincal bench [twin|calib]`: checks that every option given applies to the target, then runs it.
pub fn bench_command(what: BenchTarget, scenario: Option<&Path>, repeat: usize, seeds: Option<u64>, compare: bool, quiet: bool) -> Result<()> {
    check_repeat(repeat)?;
    match what {
        BenchTarget::Twin => {
            if seeds.is_some() {
                return Err(Error::Invalid("--seeds applies to bench calib, not bench twin".into()));
            }
            if compare {
                return Err(Error::Invalid("--compare applies to bench calib, not bench twin".into()));
            }
            bench(scenario, repeat, quiet)
        }
        BenchTarget::Calib => {
            if scenario.is_some() {
                return Err(Error::Invalid("--scenario applies to bench twin; bench calib uses the embedded irb120_geometric scenario".into()));
            }
            bench_calib(repeat, seeds.unwrap_or(20), compare)
        }
        BenchTarget::Diagnose => {
            if scenario.is_some() || compare {
                return Err(Error::Invalid("--scenario and --compare do not apply to bench diagnose".into()));
            }
            let seeds = seeds.unwrap_or(20);
            check_seeds(seeds)?;
            bench_diagnose(seeds, quiet)
        }
        BenchTarget::Dsade | BenchTarget::Ik => {
            if scenario.is_some() || compare {
                return Err(Error::Invalid(
                    "--scenario and --compare do not apply to bench dsade / bench ik (they use the embedded irb120_evo_nph scenario)".into(),
                ));
            }
            if what == BenchTarget::Ik {
                if seeds.is_some() {
                    return Err(Error::Invalid("--seeds applies to bench dsade, not bench ik".into()));
                }
                return crate::bench::evo::bench_ik(repeat);
            }
            let seeds = seeds.unwrap_or(30);
            check_seeds(seeds)?;
            crate::bench::evo::bench_dsade(repeat, seeds)
        }
        BenchTarget::Awnn => {
            if scenario.is_some() || compare {
                return Err(Error::Invalid("--scenario and --compare do not apply to bench awnn (it uses the embedded irb120_pso_ekf scenario)".into()));
            }
            let seeds = seeds.unwrap_or(5);
            check_seeds(seeds)?;
            crate::bench::awnn::bench_awnn(repeat, seeds, quiet)
        }
        BenchTarget::Real => {
            if scenario.is_some() || compare {
                return Err(Error::Invalid("--scenario and --compare do not apply to bench real (it reads ../shared/data)".into()));
            }
            let seeds = seeds.unwrap_or(5);
            check_seeds(seeds)?;
            crate::bench::real::bench_real(seeds)
        }
    }
}

/// `twincal bench diagnose`: the 600-pose all-effects diagnosis timed (median of three, time per
/// candidate), then `seeds` scenarios with one hidden effect (cause, joint and size from the
/// seed) and `seeds` clean ones: detection rate (cause and joint named first, size within its
/// uncertainty band or 30 %) and false-alarm rate.
pub fn bench_diagnose(seeds: u64, quiet: bool) -> Result<()> {
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
        per_candidate.push(crate::calib::stats::median(&c));
        verdict = d.verdict.clone();
    }
    println!(
        "  {} poses, every effect, {} threads: {:.2} s median (target < 10 s); {evaluated} candidate fits, {:.0} ms each (median, one thread each); found {verdict}",
        data.rows.len(),
        rayon::current_num_threads(),
        crate::calib::stats::median(&times),
        crate::calib::stats::median(&per_candidate) * 1e3
    );
    // 2. Detection and false alarms.
    let bar = progress(quiet);
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

fn check_repeat(repeat: usize) -> Result<()> {
    if !(1..=MAX_REPEAT).contains(&repeat) {
        return Err(Error::Invalid(format!("--repeat must be between 1 and {MAX_REPEAT}, got {repeat}")));
    }
    Ok(())
}

fn check_seeds(seeds: u64) -> Result<()> {
    if !(1..=MAX_SEEDS).contains(&seeds) {
        return Err(Error::Invalid(format!("--seeds must be between 1 and {MAX_SEEDS}, got {seeds}")));
    }
    Ok(())
}

/// Rapier's settled poses against the quasi-static model's over the same commands.
#[derive(Clone, Debug, PartialEq)]
pub struct TwinAgreement {
    pub poses: usize,
    /// Largest tool-point distance, mm.
    pub worst_tool_mm: f64,
    /// Poses whose backlash contact states differ.
    pub contact_differs: usize,
}

/// Settles every command with rapier and with the quasi-static model and compares the results.
pub fn twin_agreement(twin: &crate::twin::Twin, cmds: &[crate::twin::PoseCommand]) -> Result<TwinAgreement> {
    use rayon::prelude::*;
    let per: Vec<Result<(f64, bool)>> = cmds
        .par_iter()
        .map(|c| {
            let sim = twin.simulate(c)?;
            let qs = twin.quasi_static(c);
            Ok(((sim.tool - qs.tool).norm() * 1e3, sim.contact != qs.contact))
        })
        .collect();
    let per: Vec<(f64, bool)> = per.into_iter().collect::<Result<_>>()?;
    Ok(TwinAgreement {
        poses: per.len(),
        // `simulate` refuses a diverged (non-finite) pose, so every distance here is finite.
        worst_tool_mm: per.iter().map(|(d, _)| *d).fold(0.0, f64::max),
        contact_differs: per.iter().filter(|(_, c)| *c).count(),
    })
}

/// Flanks of a simulated tour against the load/approach rule, per joint and pose.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct FlankCheck {
    /// Static load above twice the breakaway: the load decides the flank.
    pub loaded_agree: usize,
    pub loaded_differ: usize,
    /// Load below the breakaway: the rule says the approach flank; the motion (deceleration,
    /// loads along the way) may leave the link elsewhere, so differences are not errors.
    pub unloaded_agree: usize,
    pub unloaded_differ: usize,
    /// Joints left inside their band by friction.
    pub free: usize,
}

/// Compares the flank each joint of `acquired` rests on with the rule (`breakaway` in N·m).
pub fn flank_check(acquired: &[crate::twin::tour::Acquired], breakaway: f64) -> FlankCheck {
    use crate::effects::statics::Contact;
    let mut c = FlankCheck::default();
    for a in acquired {
        for (j, contact) in a.rest.contact.iter().enumerate() {
            let tau = a.rest.torque[j];
            let side = match contact {
                Contact::Positive => 1.0,
                Contact::Negative => -1.0,
                Contact::Held => {
                    // Held against the load on the flank opposite to it.
                    -tau.signum()
                }
                Contact::Free => {
                    c.free += 1;
                    continue;
                }
                Contact::Spring => continue,
            };
            if tau.abs() > 2.0 * breakaway {
                if side == tau.signum() {
                    c.loaded_agree += 1;
                } else {
                    c.loaded_differ += 1;
                }
            } else if tau.abs() < breakaway {
                if side == a.rule_sides[j] {
                    c.unloaded_agree += 1;
                } else {
                    c.unloaded_differ += 1;
                }
            }
        }
    }
    c
}

/// `twincal bench twin`: the simulated tour (the scenario's `[acquisition]` settings, simulated
/// whatever its model) timed in parallel and on one thread (the two must agree bit for bit), its
/// steps per pose and where the time goes, its readings against the quasi-static model and its
/// flanks against the rule; then the per-pose settled model and the quasi-static model as
/// baselines, with the settled poses' agreement with the quasi-static model.
pub fn bench(scenario: Option<&Path>, repeat: usize, quiet: bool) -> Result<()> {
    use crate::generate::{acquisition_times, build_twin, sample_poses};
    use crate::twin::tour::{acquire, Acquired, PHASES};
    use crate::twin::{approach_sides, PoseCommand};
    use rayon::prelude::*;
    check_repeat(repeat)?;
    let (s, robot) = load_scenario(scenario)?;
    let twin = build_twin(&s, &robot);
    let poses = sample_poses(&s, &robot)?;
    let n = poses.len();
    let threads = rayon::current_num_threads();
    if !quiet {
        eprintln!("bench: scenario {}, {n} poses, {threads} threads, {repeat} repetitions (medians reported)", s.name);
    }
    let home = vec![0.0; robot.dof()];
    let settings = crate::twin::tour::TourSettings { seed: s.seed, speed_fraction: s.sampling.speed_fraction };
    let tour = || -> Result<Vec<Acquired>> { acquire(&twin, &s.acquisition, settings, &home, &poses, &Silent).into_iter().collect() };
    let time = |f: &dyn Fn() -> Result<()>| -> Result<f64> {
        let mut ts = Vec::new();
        for _ in 0..repeat {
            let t0 = Instant::now();
            f()?;
            ts.push(t0.elapsed().as_secs_f64());
        }
        Ok(median(&ts))
    };
    let t_par = time(&|| tour().map(|_| ()))?;
    let one = rayon::ThreadPoolBuilder::new().num_threads(1).build().map_err(|e| Error::Invalid(format!("cannot start a thread pool: {e}")))?;
    let t0 = Instant::now();
    let seq = one.install(tour)?;
    let t_seq = t0.elapsed().as_secs_f64();
    let par = tour()?;
    let identical = seq.len() == par.len()
        && seq
            .iter()
            .zip(&par)
            .all(|(a, b)| a.lengths == b.lengths && a.gate_s == b.gate_s && a.rest.q_link == b.rest.q_link && a.rest.contact == b.rest.contact);
    let mut steps = [0usize; 5];
    let mut secs = [0.0f64; 5];
    for a in &seq {
        for k in 0..5 {
            steps[k] += a.stats.steps[k];
            secs[k] += a.stats.seconds[k];
        }
    }
    let total_steps: usize = steps.iter().sum();
    let in_phases: f64 = secs.iter().sum();
    let worst_transient = seq.iter().map(|a| a.transient_mm.abs()).fold(0.0, f64::max);
    let closed = seq.iter().filter(|a| a.gate_s.is_none()).count();
    let flanks = flank_check(&seq, twin.transmission.as_ref().map(|t| t.breakaway).unwrap_or(0.0));
    let sim_time: f64 = {
        let sc = crate::twin::tour::Schedule::new(&robot, s.sampling.speed_fraction, s.acquisition.ramp_s, s.sensor.hold_s, s.sensor.window_s(), &home, &poses);
        sc.read_t.last().copied().unwrap_or(0.0) + 0.5 * s.sensor.window_s()
    };

    // Baselines: the per-pose settled model and the quasi-static model, flanks from the rule.
    let times = acquisition_times(&s, &robot, &poses);
    let sides = approach_sides(&home, &poses);
    let cmds: Vec<PoseCommand> = (0..n).map(|i| PoseCommand { q_cmd: poses[i].clone(), sides: sides[i].clone(), t: times[i] }).collect();
    let t_qs = time(&|| {
        for c in &cmds {
            std::hint::black_box(twin.quasi_static(c));
        }
        Ok(())
    })?;
    let t0 = Instant::now();
    let settled: Vec<usize> = cmds.par_iter().map(|c| twin.simulate(c).map(|r| r.steps)).collect::<Result<_>>()?;
    let t_settled = t0.elapsed().as_secs_f64();
    let agree = twin_agreement(&twin, &cmds)?;

    println!("twin benchmark ({}, {n} poses, {threads} threads)", s.name);
    println!("  simulated tour, parallel : {t_par:8.3} s  = {:8.1} poses/s   (target: {n} poses < 5 s)", n as f64 / t_par);
    println!(
        "  simulated tour, 1 thread : {t_seq:8.3} s  (parallel speed-up {:.2}x); same bytes as the parallel run: {}",
        t_seq / t_par,
        if identical { "yes" } else { "NO" }
    );
    println!(
        "  simulated acquisition    : {sim_time:.0} s of robot time ({:.2} s per pose), {:.0} rapier steps per pose",
        sim_time / n as f64,
        total_steps as f64 / n as f64
    );
    println!("  where the time goes (1 thread, {:.2} µs per step):", in_phases / total_steps.max(1) as f64 * 1e6);
    for k in 0..5 {
        println!("    {:22} {:6.0} steps/pose  {:5.1} % of the time", PHASES[k], steps[k] as f64 / n as f64, 100.0 * secs[k] / t_seq);
    }
    println!("    {:22} {:>17}  {:5.1} % (chunk set-up, readings, gate, truth)", "outside steps", "", 100.0 * (t_seq - in_phases).max(0.0) / t_seq);
    println!(
        "  tour vs quasi-static on the flanks the motion left: worst |transient in L| {worst_transient:.1e} mm over {n} poses (target < 1e-3 mm); gate still closed at the end of the hold: {closed} poses"
    );
    println!(
        "  flanks vs the load/approach rule: loaded joints (|τ| > 2 × breakaway) {} agree, {} differ; unloaded joints (|τ| < breakaway) {} on the approach flank, {} elsewhere (deceleration, loads along the move); {} inside the band",
        flanks.loaded_agree, flanks.loaded_differ, flanks.unloaded_agree, flanks.unloaded_differ, flanks.free
    );
    println!(
        "  settled poses (one world per pose), parallel: {t_settled:8.3} s, {:.0} settle steps per pose (4 substeps each)",
        settled.iter().sum::<usize>() as f64 / n as f64
    );
    println!("  quasi-static baseline    : {t_qs:8.3} s  = {:8.1} poses/s   (the tour costs {:.0}x the quasi-static model)", n as f64 / t_qs, t_par / t_qs);
    println!(
        "  rapier vs quasi-static: worst tool-point difference {:.1e} mm over {} poses (target < 1e-3 mm); backlash contacts differ in {} poses",
        agree.worst_tool_mm, agree.poses, agree.contact_differs
    );
    if t_par.is_nan() {
        return Err(Error::Invalid("benchmark produced no timing".into()));
    }
    if !identical {
        return Err(Error::Simulation("the tour on one thread differs from the parallel run".into()));
    }
    Ok(())
}

/// `twincal study` subjects.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum StudyTarget {
    /// Bias and spread of the readings against the hold time and the approach speed.
    Hold,
}

/// `twincal study hold`: the table on stdout, optionally a Rerun recording.
pub fn study(what: StudyTarget, scenario: Option<&Path>, study: &crate::twin::study::HoldStudy, rrd: Option<&Path>, quiet: bool) -> Result<()> {
    let StudyTarget::Hold = what;
    if let Some(p) = rrd {
        let inputs: Vec<(&str, &Path)> = scenario.map(|p| ("--scenario", p)).into_iter().collect();
        check_outputs(&inputs, &[("--rrd", p)])?;
    }
    study.validate().map_err(Error::Invalid)?;
    let (s, robot) = load_scenario(scenario)?;
    let rows = crate::twin::study::hold_study(&s, &robot, study, progress(quiet).as_ref())?;
    let floor = s.sensor.noise_std_mm / (s.sensor.samples as f64).sqrt();
    println!("hold study ({}, first {} poses, readings taken even with the gate closed)", s.name, rows.first().map(|r| r.poses).unwrap_or(0));
    println!(
        "  damping ratio {}, gate: {} s windows within {} mm; averaged reading noise {:.2} µm (not included below)",
        s.acquisition.damping_ratio,
        s.acquisition.gate_window_s,
        s.acquisition.gate_mm,
        floor * 1e3
    );
    println!(
        "  {:>6} {:>8} {:>10} {:>11} {:>10} {:>12} {:>11} {:>9}",
        "speed", "hold s", "bias µm", "spread µm", "max µm", "gate closed", "gate s (med)", "s/pose"
    );
    for r in &rows {
        println!(
            "  {:6.2} {:8.3} {:10.3} {:11.3} {:10.3} {:>12} {:>11} {:9.2}",
            r.speed_fraction,
            r.hold_s,
            r.bias_mm * 1e3,
            r.spread_mm * 1e3,
            r.max_mm * 1e3,
            format!("{}/{}", r.gate_closed, r.poses),
            r.median_gate_s.map(|g| format!("{g:.3}")).unwrap_or_else(|| "-".into()),
            r.time_per_pose_s
        );
    }
    if let Some(p) = rrd {
        let mut outputs = OutputSet::new();
        crate::viz::study::record_hold_study(&rows, &s.name, floor, &mut outputs, p)?;
        outputs.commit()?;
        if !quiet {
            eprintln!("  wrote {}", p.display());
        }
    }
    Ok(())
}

/// Arguments of `twincal calibrate` (the field docs are its `--help`).
#[derive(Clone, Debug, clap::Args)]
pub struct CalibrateArgs {
    /// Dataset folder (DIR/dataset.csv, with truth.json when the twin made it), CSV, or xlsx (file.xlsx#Sheet).
    #[arg(long)]
    pub data: PathBuf,
    /// Unit of the joint angles in the data (auto: degrees unless they look like radians).
    #[arg(long, value_enum, default_value_t = AngleArg::Auto)]
    pub angles: AngleArg,
    /// lm, ekf, pf, pso, rbf, dsade-gkan (Evo-NPH; ablations dsade-gkan-v1, -v2, -v3), pso-ekf-awnn (ablations: pso-ekf-awnn-v1 .. -v5; pso-ekf-awnn-x: network also on temperature and backlash flanks, network/LM alternations).
    #[arg(long, default_value = "lm")]
    pub method: String,
    #[command(flatten)]
    pub model: ModelArgs,
    /// Hold out this fraction instead of the dataset's split column (0 trains on every row).
    #[arg(long, allow_negative_numbers = true)]
    pub test_fraction: Option<f64>,
    /// Seed of the hold-out split and of the stochastic methods.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Sensor geometry guess, mm: exit x,y,z, length offset, tool x,y,z (default: estimated).
    #[arg(long, value_delimiter = ',', allow_hyphen_values = true, value_name = "EX,EY,EZ,OFFSET,TX,TY,TZ")]
    pub sensor_guess: Option<Vec<f64>>,
    /// Relative singular-value threshold for identifiability (combinations the data see below
    /// this fraction of the strongest are fixed).
    #[arg(long, default_value_t = crate::calib::run::DEFAULT_RANK_TOL, allow_negative_numbers = true)]
    pub rank_tol: f64,
    /// Budget of the stochastic methods and of the generic model's global search (1 = default).
    #[arg(long, default_value_t = 1.0, allow_negative_numbers = true)]
    pub effort: f64,
    /// The calibrated model and its report.
    #[arg(long, default_value = "result.json")]
    pub out: PathBuf,
    /// Also write the calibrated model as a URDF.
    #[arg(long)]
    pub urdf: Option<PathBuf>,
    /// Rerun recording of the residual field before and after, convergence and parameters.
    #[arg(long)]
    pub rrd: Option<PathBuf>,
    /// Self-contained HTML report (tables and plots, opens offline in any browser).
    #[arg(long)]
    pub report: Option<PathBuf>,
    /// Accuracy limit for the verdict in --out: RMSE of the test rows after calibration, mm.
    #[arg(long, allow_negative_numbers = true)]
    pub max_test_rmse_mm: Option<f64>,
    /// Accuracy limit for the verdict in --out: largest |residual| of the test rows, mm.
    #[arg(long, allow_negative_numbers = true)]
    pub max_test_max_mm: Option<f64>,
    /// Non-geometric effects to fit with the geometry: compliance, backlash, thermal,
    /// eccentricity, nonlinearity, each optionally on one joint (backlash:2).
    #[arg(long, value_delimiter = ',')]
    pub effects: Vec<String>,
    #[command(flatten)]
    pub loads: LoadArgs,
    #[command(flatten)]
    pub robust: RobustArgs,
}

/// Robust estimation and the data's floor (`--outliers`, `--loss`, `--angle-resolution-deg`).
#[derive(Clone, Debug, clap::Args)]
pub struct RobustArgs {
    /// Training rows more than this many robust standard deviations (1.4826 MAD) off the fit
    /// are outliers: kept out and listed in the result (0: keep every row).
    #[arg(long, default_value_t = crate::calib::run::DEFAULT_OUTLIER_K, allow_negative_numbers = true)]
    pub outliers: f64,
    /// Keep out the rows of a run of outliers even when they all sit one constant offset off
    /// (by default such a reading step is corrected and its rows kept).
    #[arg(long)]
    pub no_reading_steps: bool,
    /// Least-squares loss of `--method lm`: l2, huber or cauchy (by IRLS, robust scale from the data).
    #[arg(long, default_value = "l2")]
    pub loss: String,
    /// Logging step of the joint angles in degrees, for the noise floor (default: read from the
    /// data's decimals).
    #[arg(long, allow_negative_numbers = true)]
    pub angle_resolution_deg: Option<f64>,
}

impl RobustArgs {
    /// (outlier threshold, loss, angle step), validated.
    pub fn resolve(&self) -> Result<(f64, crate::calib::robust::Loss, Option<f64>)> {
        if !(self.outliers.is_finite() && (self.outliers == 0.0 || (2.0..=100.0).contains(&self.outliers))) {
            return Err(Error::Invalid(format!("--outliers must be 0 (off) or in [2, 100] robust standard deviations, got {}", self.outliers)));
        }
        if let Some(r) = self.angle_resolution_deg {
            if !(r.is_finite() && r > 0.0 && r <= 10.0) {
                return Err(Error::Invalid(format!("--angle-resolution-deg must be in (0, 10] degrees, got {r}")));
            }
        }
        Ok((self.outliers, crate::calib::robust::Loss::parse(&self.loss)?, self.angle_resolution_deg))
    }
}

/// What loads the joints, for the torque-driven effects (`--robot`, `--payload-kg`,
/// `--payload-com-mm`, `--cable-tension-n`).
#[derive(Clone, Debug, Default, clap::Args)]
pub struct LoadArgs {
    /// URDF whose inertial data give the static joint torques (default: the model's own robot;
    /// needed for joint_compliance with generic6r).
    #[arg(long)]
    pub robot: Option<PathBuf>,
    /// Payload on the flange, kg.
    #[arg(long, allow_negative_numbers = true)]
    pub payload_kg: Option<f64>,
    /// Payload centre of mass in the flange frame, mm (x,y,z).
    #[arg(long, value_delimiter = ',', allow_hyphen_values = true, value_name = "X,Y,Z")]
    pub payload_com_mm: Option<Vec<f64>>,
    /// Draw-wire cable tension from the sensor's data sheet, N (0: ignored).
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    pub cable_tension_n: f64,
}

impl LoadArgs {
    /// The load options and the inertial robot (`--robot`), validated.
    pub fn resolve(&self) -> Result<(crate::calib::inputs::LoadOptions, Option<crate::robot::Robot>)> {
        let mut o = crate::calib::inputs::LoadOptions::default();
        if !(self.cable_tension_n.is_finite() && (0.0..=1000.0).contains(&self.cable_tension_n)) {
            return Err(Error::Invalid(format!("--cable-tension-n must be in [0, 1000] N, got {}", self.cable_tension_n)));
        }
        o.cable_tension_n = self.cable_tension_n;
        match (self.payload_kg, &self.payload_com_mm) {
            (None, None) => {}
            (Some(m), com) => {
                if !(m.is_finite() && (0.0..=1000.0).contains(&m)) {
                    return Err(Error::Invalid(format!("--payload-kg must be in [0, 1000] kg, got {m}")));
                }
                let com = com.clone().unwrap_or_else(|| vec![0.0; 3]);
                if com.len() != 3 || com.iter().any(|v| !v.is_finite() || v.abs() > 5000.0) {
                    return Err(Error::Invalid("--payload-com-mm needs 3 finite values in mm (x,y,z in the flange frame, each within ±5000)".into()));
                }
                o.payload = Some(crate::effects::Payload { mass_kg: m, com_mm: [com[0], com[1], com[2]] });
            }
            (None, Some(_)) => return Err(Error::Invalid("--payload-com-mm needs --payload-kg".into())),
        }
        let robot = match &self.robot {
            Some(p) => Some(crate::robot::Robot::from_urdf_file(p)?),
            None => None,
        };
        Ok((o, robot))
    }
}

/// Parses `--effects compliance,backlash:2,thermal`: a kind, optionally `:JOINT` (1..N, checked against the data).
pub fn parse_effects(list: &[String]) -> Result<Vec<(crate::calib::effects::EffectKind, Option<usize>)>> {
    use crate::calib::effects::EffectKind;
    list.iter()
        .filter(|s| !s.trim().is_empty())
        .map(|item| {
            let (kind, joint) = match item.split_once(':') {
                Some((k, j)) => {
                    let max = crate::dataset::MAX_JOINTS;
                    let bad = || Error::Invalid(format!("--effects {item}: the joint after ':' must be a joint number, 1..N"));
                    let j: usize = j.trim().parse().map_err(|_| bad())?;
                    if !(1..=max).contains(&j) {
                        return Err(bad());
                    }
                    (EffectKind::parse(k)?, Some(j - 1))
                }
                None => (EffectKind::parse(item)?, None),
            };
            let allowed = kind.joint_options(crate::dataset::MAX_JOINTS).contains(&joint) || (joint.is_none() && kind.per_joint());
            if !allowed {
                return Err(Error::Invalid(format!("--effects {item}: {} is not a per-joint effect", kind.name())));
            }
            Ok((kind, joint))
        })
        .collect()
}

/// `twincal calibrate`. Its outputs (`--out`, `--urdf`, `--rrd`) appear together or not at all.
/// Warnings (an optimiser that stopped without converging) go to stderr also with `--quiet`.
pub fn calibrate(a: &CalibrateArgs, quiet: bool) -> Result<()> {
    use crate::calib::model::SensorGuess;
    use crate::calib::run::{calibrate as run, CalibOptions, Method, ModelSpec, TruthFile};
    let method = Method::parse(&a.method)?;
    if !(a.rank_tol > 0.0 && a.rank_tol < 1.0) {
        return Err(Error::Invalid(format!("--rank-tol must be in (0, 1), got {}", a.rank_tol)));
    }
    if !(a.effort > 0.0 && a.effort <= 10.0) {
        return Err(Error::Invalid(format!("--effort must be in (0, 10], got {}", a.effort)));
    }
    if let Some(f) = a.test_fraction {
        if !(0.0..1.0).contains(&f) {
            return Err(Error::Invalid(format!("--test-fraction must be in [0, 1), got {f}")));
        }
    }
    let sensor_guess = match &a.sensor_guess {
        None => None,
        Some(g) => {
            if g.len() != 7 {
                return Err(Error::Invalid(format!("--sensor-guess needs 7 values in mm (exit x,y,z, length offset, tool x,y,z), got {}", g.len())));
            }
            if g.iter().any(|v| !v.is_finite()) {
                return Err(Error::Invalid("--sensor-guess values must be finite numbers (mm)".into()));
            }
            Some(SensorGuess { exit_m: [g[0] * 1e-3, g[1] * 1e-3, g[2] * 1e-3], offset_m: g[3] * 1e-3, tool_m: [g[4] * 1e-3, g[5] * 1e-3, g[6] * 1e-3] })
        }
    };
    let data_files = data_inputs(&a.data);
    let model_file = a.model.input();
    let mut inputs: Vec<(&str, &Path)> = data_files.iter().map(|p| ("--data", p.as_path())).collect();
    if let Some(m) = &model_file {
        inputs.push(("--model", m));
    }
    let mut outs: Vec<(&str, &Path)> = vec![("--out", &a.out)];
    outs.extend(a.urdf.as_deref().map(|p| ("--urdf", p)));
    outs.extend(a.rrd.as_deref().map(|p| ("--rrd", p)));
    outs.extend(a.report.as_deref().map(|p| ("--report", p)));
    check_outputs(&inputs, &outs)?;
    let limits = [Limit { flag: "--max-test-rmse-mm", value: a.max_test_rmse_mm }, Limit { flag: "--max-test-max-mm", value: a.max_test_max_mm }];
    for l in &limits {
        l.validate()?;
    }
    let spec = a.model.spec()?;
    let data = load_dataset(&a.data, a.angles, true)?;
    let truth = TruthFile::find(&a.data)?;
    let mut opts = CalibOptions::new(spec.clone(), method);
    opts.test_fraction = a.test_fraction;
    opts.seed = a.seed;
    opts.rank_tol = a.rank_tol;
    opts.effort = a.effort;
    opts.sensor_guess = sensor_guess;
    opts.effects = parse_effects(&a.effects)?;
    let (loads, inertial) = a.loads.resolve()?;
    opts.loads = loads;
    opts.inertial = inertial;
    (opts.outlier_k, opts.loss, opts.angle_step_deg) = a.robust.resolve()?;
    opts.reading_steps = !a.robust.no_reading_steps;
    let result = run(&data, truth.as_ref(), &opts)?;
    let test = result.metrics.test_after.as_ref();
    let source = if test.is_some() { "test rows after calibration" } else { "no test rows: hold some out with --test-fraction or a split column" };
    let verdict = judge(&[(limits[0], "test_rmse_mm", test.map(|t| t.rmse), source), (limits[1], "test_max_mm", test.map(|t| t.max), source)]);
    let mut outputs = OutputSet::new();
    let figures = if a.rrd.is_some() || a.report.is_some() { Some(crate::report::CalibFigures::new(&result, &data, &opts)?) } else { None };
    if let (Some(p), Some(f)) = (&a.rrd, &figures) {
        crate::viz::scenes::record_calibration(&result, f, &mut outputs, p)?;
    }
    if let (Some(p), Some(f)) = (&a.report, &figures) {
        outputs.write(p, crate::report::html::calibration_page(&result, f, verdict.as_ref()).as_bytes())?;
    }
    if let Some(p) = &a.urdf {
        let nominal = match &spec {
            ModelSpec::Nominal { robot, .. } => Some(robot.as_ref()),
            ModelSpec::Generic6r => None,
        };
        outputs.write(p, crate::calib::export::urdf(&result.model, &result.x, nominal, "calibrated").as_bytes())?;
    }
    outputs.write_json(&a.out, &with_verdict(&result, verdict.as_ref())?)?;
    outputs.commit()?;
    if !quiet {
        print_summary(&result);
    }
    print_verdict(verdict.as_ref(), &a.out);
    for w in calibration_warnings(&result) {
        eprintln!("warning: {w}");
    }
    Ok(())
}

/// The verdict on stderr (also with `--quiet`: it is the answer a user asked for).
fn print_verdict(v: Option<&crate::report::verdict::Verdict>, file: &Path) {
    let Some(v) = v else { return };
    let checks: Vec<String> = v
        .checks
        .iter()
        .map(|c| match c.value {
            Some(x) => format!("{} {x:.4} {} {:.4} mm", c.name, if c.pass { "<=" } else { ">" }, c.limit),
            None => format!("{} not measured ({})", c.name, c.source),
        })
        .collect();
    eprintln!("verdict: {} ({}); in {}", if v.pass { "PASS" } else { "FAIL" }, checks.join(", "), file.display());
}

/// What a user must know about a calibration that succeeded: an optimiser that stopped on its
/// iteration / evaluation budget instead of a convergence test.
pub fn calibration_warnings(r: &crate::calib::run::CalibResult) -> Vec<String> {
    r.warnings.clone()
}

fn print_summary(r: &crate::calib::run::CalibResult) {
    let m = &r.metrics;
    let row = |label: &str, s: &crate::calib::metrics::ErrorStats| format!("  {label:<14} {:>10.4} {:>10.4} {:>10.4}", s.rmse, s.std, s.max);
    eprintln!(
        "{} / {} on {} ({} train, {} test rows), {} iterations, {:.3} s",
        r.method.name(),
        r.model_name,
        r.data,
        r.n_train,
        r.n_test,
        r.iterations,
        r.wall_time_s
    );
    eprintln!("  {:<14} {:>10} {:>10} {:>10}   (mm)", "residuals", "RMSE", "STD", "MAX");
    eprintln!("{}", row("train before", &m.train_before));
    eprintln!("{}", row("train after", &m.train_after));
    if let (Some(b), Some(a)) = (&m.test_before, &m.test_after) {
        eprintln!("{}", row("test before", b));
        eprintln!("{}", row("test after", a));
    }
    let fixed: Vec<&str> = r.parameters.iter().filter(|p| p.fixed).map(|p| p.name.as_str()).collect();
    eprintln!(
        "  identifiable: {} of {} parameters; fixed (not identifiable from these poses): {}",
        r.parameters.len() - fixed.len(),
        r.parameters.len(),
        fixed.join(", ")
    );
    let id = |k: &str| r.identifiability.get(k).and_then(|v| v.as_f64());
    if let (Some(all), Some(c)) = (id("condition_all"), id("condition_identifiable")) {
        eprintln!("  condition number: {all:.3e} with every parameter free, {c:.3e} for the identifiable set");
    }
    if let Some(still) = r.identifiability.get("still_joints").and_then(|v| v.as_array()).filter(|v| !v.is_empty()) {
        let joints: Vec<String> = still.iter().map(|j| j.to_string()).collect();
        eprintln!("  joints that do not move in the data (held for the identifiability analysis): {}", joints.join(", "));
    }
    if r.outlier_k > 0.0 {
        let runs: Vec<String> = r.outlier_runs.iter().map(|u| format!("rows {}-{} ({:+.2} mm)", u.first_row, u.last_row, u.median_residual_mm)).collect();
        eprintln!(
            "  outliers (> {} robust sd of {:.4} mm): {} training rows kept out{}; {} test rows beyond the same rule",
            r.outlier_k,
            r.robust_scale_mm,
            r.outliers.len(),
            if runs.is_empty() { String::new() } else { format!(", runs: {}", runs.join(", ")) },
            r.test_outliers.len()
        );
        for s in &r.reading_steps {
            eprintln!(
                "  reading step: rows {}-{} read {:+.2} ± {:.2} mm off ({} training rows), corrected and kept",
                s.first_row, s.last_row, s.offset_mm, s.std_mm, s.rows
            );
        }
        if r.test_rows_in_steps > 0 {
            eprintln!("  {} test rows inside reading steps corrected by their step's offset (from training rows)", r.test_rows_in_steps);
        }
        if let (Some(t), false) = (&m.test_after_inliers, r.test_outliers.is_empty()) {
            eprintln!("{}", row("test inliers", t));
        }
    }
    if let Some(t) = &m.test_after_trimmed {
        eprintln!("{}", row("test, best 99%", t));
    }
    if let Some(f) = &r.noise_floor {
        let parts: Vec<String> = f.sources.iter().map(|s| format!("{} {:.4}", s.source, s.rms_mm)).collect();
        // Without repeated configurations the reading's own noise is not in the data: the
        // floor is only what the logging resolutions show, a lower bound.
        let measured = f.sources.iter().any(|s| s.source == "repeatability");
        let (bound, why) = if measured { ("", "") } else { ("at least ", "; no repeated configurations, so the reading's own noise is not measured") };
        eprintln!("  noise floor of the data: {bound}{:.4} mm ({}{why})", f.total_mm, parts.join(", "));
        if let (Some(t), Some(tt), true) = (&m.test_after, &m.test_after_trimmed, f.total_mm > 0.0) {
            let ratio = t.rmse / f.total_mm;
            if measured || ratio <= MAX_BOUND_RATIO {
                eprintln!("  held-out RMSE / floor = {ratio:.3} (without the worst 1 % of test rows: {:.3})", tt.rmse / f.total_mm);
            } else {
                eprintln!("  held-out RMSE is more than {MAX_BOUND_RATIO}× that lower bound: the data do not show their floor");
            }
        }
    }
    if let Some(t) = &r.truth_comparison {
        eprintln!(
            "  truth: {}/{} identifiable parameters within 3σ (max |z| = {:.2}); sensor noise floor {:.4} mm",
            t.within_3_sigma, t.identifiable, t.max_abs_z, t.noise_floor_mm
        );
    }
}

/// Above this many times a floor that is only a lower bound (no repeated configurations), the
/// ratio says nothing about the fit and is not printed.
const MAX_BOUND_RATIO: f64 = 10.0;

/// Loads a calibrated model (result.json); its errors are labelled `model PATH`.
fn load_model(path: &Path) -> Result<crate::calib::run::CalibResult> {
    crate::calib::run::CalibResult::load(path)
}

/// The CSV `predict` writes: `q1..qN,L,L_pred,residual` when every row has a measured length,
/// `q1..qN,L_pred` otherwise.
pub fn prediction_csv(rows: &[(&[f64], Option<f64>)], predicted: &[f64]) -> String {
    let with_l = rows.iter().all(|(_, l)| l.is_some());
    let joints: Vec<String> = (1..=rows.first().map_or(0, |(q, _)| q.len())).map(|j| format!("q{j},")).collect();
    let mut text = joints.concat() + if with_l { "L,L_pred,residual\n" } else { "L_pred\n" };
    for ((q, l), p) in rows.iter().zip(predicted) {
        let q: Vec<String> = q.iter().map(|v| v.to_string()).collect();
        match (with_l, l) {
            (true, Some(l)) => text.push_str(&format!("{},{l},{p},{}\n", q.join(","), l - p)),
            _ => text.push_str(&format!("{},{p}\n", q.join(","))),
        }
    }
    text
}

/// `twincal predict`: the calibrated model's length for every row of a dataset (which needs no
/// measured lengths), with the residual where a length was measured.
pub fn predict(model: &Path, data: &Path, angles: AngleArg, out: &Path, quiet: bool) -> Result<()> {
    let data_files = data_inputs(data);
    check_outputs(&[("--model", model), ("--data", &data_files[0])], &[("--out", out)])?;
    let result = load_model(model)?;
    let ds = load_dataset(data, angles, false)?;
    ds.require_joints(result.model.chain.n_joints, &format!("the model {}", model.display()))?;
    let rows: Vec<(&[f64], Option<f64>)> = ds.rows.iter().map(|r| (r.q_deg.as_slice(), r.l_mm)).collect();
    let predicted = result.predict_rows(&ds);
    for (i, p) in predicted.iter().enumerate() {
        if !p.is_finite() {
            return Err(Error::Calibration(format!("the model predicted a non-finite length for row {}", i + 1)));
        }
    }
    crate::io::write_atomic(out, prediction_csv(&rows, &predicted).as_bytes())?;
    if !quiet {
        let res: Vec<f64> = rows.iter().zip(&predicted).filter_map(|((_, l), p)| l.map(|l| l - p)).collect();
        if res.is_empty() {
            eprintln!("{} rows predicted; wrote {}", rows.len(), out.display());
        } else {
            let s = crate::calib::metrics::ErrorStats::of(&res);
            eprintln!("{} rows: RMSE {:.4} mm, STD {:.4} mm, MAX {:.4} mm; wrote {}", rows.len(), s.rmse, s.std, s.max, out.display());
        }
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

/// Arguments of `twincal compare` (the field docs are its `--help`).
#[derive(Clone, Debug, clap::Args)]
pub struct CompareArgs {
    #[arg(long)]
    pub data: PathBuf,
    /// Unit of the joint angles in the data.
    #[arg(long, value_enum, default_value_t = AngleArg::Auto)]
    pub angles: AngleArg,
    #[arg(long, value_delimiter = ',', default_value = "lm,ekf,pf,pso,rbf")]
    pub methods: Vec<String>,
    /// Number of seeds (1 to 1000).
    #[arg(long, default_value_t = 30, allow_negative_numbers = true)]
    pub seeds: u64,
    #[command(flatten)]
    pub model: ModelArgs,
    /// Test fraction of each seed's re-split, in (0, 1) (default: the dataset's split size, else 0.2).
    #[arg(long, allow_negative_numbers = true)]
    pub test_fraction: Option<f64>,
    /// Effort of the stochastic methods (1 = full budget).
    #[arg(long, default_value_t = 1.0, allow_negative_numbers = true)]
    pub effort: f64,
    /// Also write the tables as JSON.
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Rerun recording of the accuracy table and the per-seed spread of each method.
    #[arg(long)]
    pub rrd: Option<PathBuf>,
}

/// `twincal compare`: every method on every seed (a fresh stratified split per seed), then the
/// accuracy / time table and Wilcoxon signed-rank tests of each method against the first one,
/// across seeds (test RMSE) and per sample (|test residual| of seed 0).
pub fn compare(a: &CompareArgs, quiet: bool) -> Result<()> {
    use crate::calib::run::{calibrate as run, CalibOptions, Method};
    use crate::calib::stats::{mean_std, wilcoxon_signed_rank};
    use rayon::prelude::*;
    let (seeds, test_fraction, effort) = (a.seeds, a.test_fraction, a.effort);
    let methods: Vec<Method> = a.methods.iter().map(|m| Method::parse(m)).collect::<Result<_>>()?;
    if methods.is_empty() {
        return Err(Error::Invalid("--methods is empty: compare needs at least one method".into()));
    }
    if let Some(m) = methods.iter().enumerate().find_map(|(i, m)| methods[..i].contains(m).then_some(m)) {
        return Err(Error::Invalid(format!("--methods lists {} twice", m.name())));
    }
    check_seeds(seeds)?;
    let jobs_count = seeds * methods.len() as u64;
    if jobs_count > MAX_COMPARE_JOBS {
        return Err(Error::Invalid(format!(
            "{} methods x {seeds} seeds = {jobs_count} calibrations, more than compare runs at once ({MAX_COMPARE_JOBS})",
            methods.len()
        )));
    }
    if let Some(f) = test_fraction {
        if !(f > 0.0 && f < 1.0) {
            return Err(Error::Invalid(format!("--test-fraction must be in (0, 1) for compare (every seed is scored on held-out rows), got {f}")));
        }
    }
    if !(effort > 0.0 && effort <= 10.0) {
        return Err(Error::Invalid(format!("--effort must be in (0, 10], got {effort}")));
    }
    let data_files = data_inputs(&a.data);
    let outs: Vec<(&str, &Path)> = a.out.as_deref().map(|p| ("--out", p)).into_iter().chain(a.rrd.as_deref().map(|p| ("--rrd", p))).collect();
    if !outs.is_empty() {
        let mut inputs: Vec<(&str, &Path)> = vec![("--data", &data_files[0])];
        let model_file = a.model.input();
        inputs.extend(model_file.as_deref().map(|m| ("--model", m)));
        check_outputs(&inputs, &outs)?;
    }
    let spec = a.model.spec()?;
    let ds = load_dataset(&a.data, a.angles, true)?;
    let n = ds.rows.len();
    let frac = test_fraction.unwrap_or_else(|| {
        let t = ds.test_indices().len();
        if t > 0 && t < n {
            t as f64 / n as f64
        } else {
            0.2
        }
    });
    if (frac * n as f64).round() < 1.0 || (frac * n as f64).round() as usize >= n {
        return Err(Error::Invalid(format!("test fraction {frac} of {n} rows leaves no test rows or no training rows")));
    }
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
            // The residuals the calibration scored (with each row's inputs: temperature, flanks,
            // torques; and reading steps), not a re-prediction from the angles alone.
            let test_abs_residuals = r.test_residuals_mm.iter().map(|v| v.abs()).collect();
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
    table.push_str(
        "| method | train RMSE | train STD | train MAX | test RMSE | test STD | test MAX | iterations | seconds |\n|---|---|---|---|---|---|---|---|---|\n",
    );
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
    let mut outputs = OutputSet::new();
    if let Some(p) = a.rrd.as_deref() {
        let names: Vec<String> = methods.iter().map(|m| m.name().to_string()).collect();
        let rows: Vec<crate::viz::scenes::CompareRow> = runs
            .iter()
            .map(|r| crate::viz::scenes::CompareRow { method: &r.method, seed: r.seed, test_rmse_mm: r.test.rmse, test_max_mm: r.test.max })
            .collect();
        crate::viz::scenes::record_comparison(&table, &names, &rows, &mut outputs, p)?;
    }
    if let Some(p) = a.out.as_deref() {
        outputs.write_json(p, &serde_json::json!({"data": ds.source, "seeds": seeds, "test_fraction": frac, "runs": runs, "wilcoxon": tests}))?;
    }
    outputs.commit()?;
    Ok(())
}

/// `twincal bench calib`: the calibration core's targets, measured.
pub fn bench_calib(repeat: usize, seeds: u64, with_compare: bool) -> Result<()> {
    check_repeat(repeat)?;
    check_seeds(seeds)?;
    use crate::calib::problem::LengthFit;
    use crate::calib::run::{calibrate as run, CalibOptions, Method, ModelSpec, TruthFile};
    use crate::optim::LeastSquares;
    use rayon::prelude::*;
    let (base, robot) =
        Scenario::from_toml(include_str!("../scenarios/irb120_geometric.toml"), "irb120_geometric").and_then(|s| s.load_robot(None).map(|r| (s, r)))?;
    let spec = ModelSpec::Nominal { robot: Box::new(robot.clone()), parametrisation: "hayati".into() };
    // Removed on every exit path (by its Drop).
    let tmp_dir = tempfile::Builder::new().prefix("twincal-bench-").tempdir().map_err(|e| Error::create_dir(std::env::temp_dir(), e))?;
    let tmp = tmp_dir.path();
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
    let t_lm = median(&times);
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
    let t_j = median(&jt);
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
    let ratios: Vec<f64> = rows.iter().map(|r| r.0).collect();
    let within5 = ratios.iter().filter(|r| (*r - 1.0).abs() <= 0.05).count();
    let all_in = rows.iter().filter(|r| r.1 == r.2).count();
    let total_in: usize = rows.iter().map(|r| r.1).sum();
    let total: usize = rows.iter().map(|r| r.2).sum();
    let zs: Vec<f64> = rows.iter().map(|r| r.3).collect();
    let (r_min, r_max) = ratios.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), r| (lo.min(*r), hi.max(*r)));
    println!("  irb120_geometric, {seeds} seeds (400 poses, 300/100):");
    println!("    test RMSE / noise floor   : median {:.3}, min {:.3}, max {:.3}; within 5 %: {within5}/{seeds} (sampling spread of an RMSE over 100 test poses is about ±7 %)", median(&ratios), r_min, r_max);
    println!("    identifiable within 3σ    : {total_in}/{total} parameters; every one in {all_in}/{seeds} seeds; median max |z| {:.2}", median(&zs));

    // 2b. Untuned methods: a scenario whose spreads and noise differ from the defaults (0.8 mm,
    // 0.12°, 0.15° and 0.2 mm raw noise, 20 samples); priors come from the documented tolerances
    // and the noise from the data, never from the scenario.
    let mut other = base.clone();
    other.geometry.origin_offset_std_mm = 0.8;
    other.geometry.origin_rotation_std_deg = 0.12;
    other.geometry.joint_zero_std_deg = 0.15;
    other.sensor.noise_std_mm = 0.2;
    other.sensor.samples = 20;
    let sets: Vec<(crate::dataset::Dataset, f64)> = (0..5u64)
        .map(|i| {
            let mut s = other.clone();
            s.seed = 21 + i;
            let g = run_generate(&s, &robot, &Silent)?;
            Ok((g.dataset, g.truth.noise_std_mm))
        })
        .collect::<Result<_>>()?;
    println!("  untuned methods on other spreads and noise (5 seeds, 400 poses, floor {:.4} mm): median test RMSE / floor, time per run", sets[0].1);
    for m in Method::ALL {
        let t0 = Instant::now();
        let ratios: Vec<f64> = sets
            .par_iter()
            .map(|(ds, floor)| {
                let r = run(ds, None, &CalibOptions::new(spec.clone(), m))?;
                Ok(r.metrics.test_after.map(|t| t.rmse).unwrap_or(f64::NAN) / floor)
            })
            .collect::<Result<_>>()?;
        println!(
            "    {:<4} {:.3} (range {:.3}–{:.3}), {:.1} s per run",
            m.name(),
            median(&ratios),
            ratios.iter().cloned().fold(f64::INFINITY, f64::min),
            ratios.iter().cloned().fold(0.0, f64::max),
            t0.elapsed().as_secs_f64() / 2.5
        );
    }

    // 3. The full comparison over 30 seeds.
    if with_compare {
        let dir = tmp.join(format!("s{}-400", 1000));
        let t0 = Instant::now();
        let args = CompareArgs {
            data: dir,
            angles: AngleArg::Deg,
            methods: ["lm", "ekf", "pf", "pso", "rbf"].map(String::from).to_vec(),
            seeds: 30,
            model: ModelArgs { model: "irb120".into(), params: None },
            test_fraction: None,
            effort: 1.0,
            out: None,
            rrd: None,
        };
        compare(&args, true)?;
        println!("  compare, 5 methods x 30 seeds: {:.1} s wall time", t0.elapsed().as_secs_f64());
    }

    // 4. Real data.
    let hsr = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/data/hsr-robotcali/hsr_robotcali_pool.csv");
    if hsr.exists() {
        let ds = crate::dataset::Dataset::load(&hsr)?;
        let mut o = CalibOptions::new(ModelSpec::Generic6r, Method::Lm);
        o.test_fraction = Some(0.2);
        let r = run(&ds, None, &o)?;
        if let (Some(rep), Some(t), Some(tt)) = (&r.repeatability, &r.metrics.test_after, &r.metrics.test_after_trimmed) {
            println!(
                "  HSR-RobotCali (generic6r, 80/20): held-out RMSE {:.4} mm, repeatability floor {:.4} mm, ratio {:.3} (target < 1.3); without the worst 1 % {:.3}; {:.1} s (bench real: the interleaved split over seeds)",
                t.rmse,
                rep.pooled_std,
                t.rmse / rep.pooled_std,
                tt.rmse / rep.pooled_std,
                r.wall_time_s
            );
        }
    } else {
        println!("  HSR-RobotCali: skipped, {} is absent", hsr.display());
    }
    drop(tmp_dir);
    Ok(())
}

/// Arguments of `twincal diagnose` (the field docs are its `--help`).
#[derive(Clone, Debug, clap::Args)]
pub struct DiagnoseArgs {
    /// Dataset folder, CSV or xlsx (q1..q6, L; optional t, temp). No truth file is read.
    #[arg(long)]
    pub data: PathBuf,
    /// Unit of the joint angles in the data.
    #[arg(long, value_enum, default_value_t = AngleArg::Auto)]
    pub angles: AngleArg,
    #[command(flatten)]
    pub model: ModelArgs,
    #[command(flatten)]
    pub loads: LoadArgs,
    /// Candidate effects (default: every kind the data support).
    #[arg(long, value_delimiter = ',')]
    pub candidates: Vec<String>,
    /// Cross-validation folds (contiguous blocks of acquisition order).
    #[arg(long, default_value_t = crate::diagnose::DEFAULT_FOLDS)]
    pub folds: usize,
    /// Family-wise significance level of each selection step.
    #[arg(long, default_value_t = crate::diagnose::DEFAULT_ALPHA, allow_negative_numbers = true)]
    pub alpha: f64,
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// The diagnosis report.
    #[arg(long, default_value = "report.json")]
    pub out: PathBuf,
    /// The extended model, saved like any calibration result.
    #[arg(long, default_value = "diagnosed.json")]
    pub result: PathBuf,
    /// Rerun recording of the evidence.
    #[arg(long)]
    pub rrd: Option<PathBuf>,
    /// Self-contained HTML report (tables and plots, opens offline in any browser).
    #[arg(long)]
    pub report: Option<PathBuf>,
    /// Accuracy limit for the verdict in --out: the final cross-validated held-out RMSE, mm.
    #[arg(long, allow_negative_numbers = true)]
    pub max_test_rmse_mm: Option<f64>,
    /// Logging step of the joint angles in degrees, for the noise floor (default: read from the
    /// data's decimals).
    #[arg(long, allow_negative_numbers = true)]
    pub angle_resolution_deg: Option<f64>,
}

/// `twincal diagnose`: report.json, the extended model (a calibration result) and optionally a
/// recording, all together or none.
pub fn diagnose(a: &DiagnoseArgs, quiet: bool) -> Result<()> {
    use crate::diagnose::{diagnose as run, DiagnoseOptions};
    let data_files = data_inputs(&a.data);
    let mut inputs: Vec<(&str, &Path)> = data_files.iter().map(|p| ("--data", p.as_path())).collect();
    let model_file = a.model.input();
    if let Some(m) = &model_file {
        inputs.push(("--model", m));
    }
    if let Some(r) = &a.loads.robot {
        inputs.push(("--robot", r));
    }
    let mut outs: Vec<(&str, &Path)> = vec![("--out", &a.out), ("--result", &a.result)];
    outs.extend(a.rrd.as_deref().map(|p| ("--rrd", p)));
    outs.extend(a.report.as_deref().map(|p| ("--report", p)));
    check_outputs(&inputs, &outs)?;
    let limit = Limit { flag: "--max-test-rmse-mm", value: a.max_test_rmse_mm };
    limit.validate()?;
    if !(a.alpha > 0.0 && a.alpha < 0.5) {
        return Err(Error::Invalid(format!("--alpha must be in (0, 0.5), got {}", a.alpha)));
    }
    let spec = a.model.spec()?;
    let data = load_dataset(&a.data, a.angles, true)?;
    let mut opts = DiagnoseOptions::new(spec);
    let (loads, inertial) = a.loads.resolve()?;
    opts.loads = loads;
    opts.inertial = inertial;
    opts.folds = a.folds;
    opts.alpha = a.alpha;
    opts.seed = a.seed;
    opts.candidates = parse_effects(&a.candidates)?.into_iter().map(|(k, _)| k).collect();
    if let Some(r) = a.angle_resolution_deg {
        if !(r.is_finite() && r > 0.0 && r <= 10.0) {
            return Err(Error::Invalid(format!("--angle-resolution-deg must be in (0, 10] degrees, got {r}")));
        }
        opts.angle_step_deg = Some(r);
    }
    let say = |line: &str| {
        if !quiet {
            eprintln!("  {line}");
        }
    };
    let (report, result) = run(&data, &opts, &say)?;
    let verdict = judge(&[(limit, "heldout_rmse_mm", Some(report.final_heldout_rmse_mm), "cross-validated held-out RMSE of the final model")]);
    let mut outputs = OutputSet::new();
    let figures = (a.rrd.is_some() || a.report.is_some()).then(|| crate::report::DiagnosisFigures::new(&report, &result, &data));
    if let (Some(p), Some(f)) = (&a.rrd, &figures) {
        crate::viz::scenes::record_diagnosis(&report, f, &mut outputs, p)?;
    }
    if let (Some(p), Some(f)) = (&a.report, &figures) {
        outputs.write(p, crate::report::html::diagnosis_page(&report, f, verdict.as_ref()).as_bytes())?;
    }
    outputs.write_json(&a.out, &with_verdict(&report, verdict.as_ref())?)?;
    outputs.write_json(&a.result, &result)?;
    outputs.commit()?;
    if !quiet {
        print_diagnosis(&report, &a.out, &a.result);
    }
    print_verdict(verdict.as_ref(), &a.out);
    Ok(())
}

fn print_diagnosis(d: &crate::diagnose::Diagnosis, out: &Path, result: &Path) {
    eprintln!("diagnosis of {} ({} rows, {} outliers kept out) in {:.1} s", d.data, d.rows, d.outliers.len(), d.seconds);
    for o in &d.outliers {
        eprintln!("  outlier: row {} residual {:+.3} mm ({:+.1} robust sd)", o.row, o.residual_mm, o.robust_z);
    }
    for u in &d.outlier_runs {
        eprintln!("  outlier run: rows {}-{}, median residual {:+.3} mm", u.first_row, u.last_row, u.median_residual_mm);
    }
    for s in &d.reading_steps {
        eprintln!(
            "  reading step: rows {}-{} read {:+.3} ± {:.3} mm off ({} rows; the reading jumped and stayed), corrected and kept",
            s.first_row, s.last_row, s.offset_mm, s.std_mm, s.rows
        );
    }
    eprintln!("  noise floor {:.4} mm ({})", d.noise_floor_mm, d.noise_floor_source);
    eprintln!(
        "  geometric model ({}): held-out RMSE {:.4} mm on blocked folds, {:.4} mm on interleaved folds; judged on {} folds ({} selection rows, {} confirmation rows kept back)",
        d.baseline.model, d.baseline.heldout_rmse_blocked_mm, d.baseline.heldout_rmse_interleaved_mm, d.judged_on, d.selection_rows, d.confirmation_rows
    );
    let top: Vec<String> = d.evidence.iter().take(4).map(|e| format!("{} r={:+.2}", e.feature, e.correlation)).collect();
    eprintln!("  residual follows most: {}", top.join(", "));
    if d.causes.is_empty() {
        eprintln!("  verdict: geometric_only (no effect improves the held-out fit significantly)");
    }
    for (i, c) in d.causes.iter().enumerate() {
        eprintln!("  cause {}: {}", i + 1, c.summary());
        eprintln!(
            "           confirmation rows: {:.4} -> {:.4} mm; other folds: {:.4} -> {:.4} mm",
            c.confirmation_rmse_before_mm, c.confirmation_rmse_after_mm, c.heldout_rmse_other_folds_before_mm, c.heldout_rmse_other_folds_after_mm
        );
    }
    if !d.unconfirmed.is_empty() {
        eprintln!("  not confirmed on the confirmation rows (left out of the model): {}", d.unconfirmed.join(", "));
    }
    eprintln!(
        "  final held-out RMSE {:.4} mm ({}); the final model's RMSE on the {} kept rows: {:.4} mm",
        d.final_heldout_rmse_mm,
        d.against_floor(),
        d.rows - d.outliers.len(),
        d.final_train_rmse_mm
    );
    let sources: Vec<String> = d.noise_floor.sources.iter().map(|s| format!("{} {:.4} mm", s.source, s.rms_mm)).collect();
    eprintln!(
        "  what remains: the data's floor ({}) accounts for {:.0} % of the final held-out mean square",
        sources.join(", "),
        100.0 * d.floor_share_of_remaining
    );
    if let Some(c) = &d.comparison {
        eprintln!(
            "  held-out RMSE geometric / physical extension / RBF compensator: {:.4} / {:.4} / {:.4} mm",
            c.heldout_rmse_mm[0], c.heldout_rmse_mm[1], c.heldout_rmse_mm[2]
        );
        eprintln!(
            "  extrapolation to q2 > {:.1} deg ({} rows, trained on {}): {:.4} / {:.4} / {:.4} mm",
            c.q2_split_deg,
            c.extrapolation_rows[1],
            c.extrapolation_rows[0],
            c.extrapolation_rmse_mm[0],
            c.extrapolation_rmse_mm[1],
            c.extrapolation_rmse_mm[2]
        );
    }
    eprintln!("  wrote {} and {} (calibrate --effects {})", out.display(), result.display(), if d.effects_option.is_empty() { "-" } else { &d.effects_option });
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn prediction_csv_has_residuals_only_when_every_row_has_a_length() {
        let q: &[f64] = &[1.0, 2.0, 3.0, 4.0, 5.0, 6.5];
        let with = prediction_csv(&[(q, Some(300.5)), (q, Some(301.0))], &[300.25, 301.0]);
        assert_eq!(with, "q1,q2,q3,q4,q5,q6,L,L_pred,residual\n1,2,3,4,5,6.5,300.5,300.25,0.25\n1,2,3,4,5,6.5,301,301,0\n");
        let without = prediction_csv(&[(q, None), (q, Some(301.0))], &[300.25, 301.0]);
        assert_eq!(without, "q1,q2,q3,q4,q5,q6,L_pred\n1,2,3,4,5,6.5,300.25\n1,2,3,4,5,6.5,301\n");
    }

    #[test]
    fn generic6r_takes_no_parametrisation() {
        let e = model_spec("generic6r", Some("dh")).unwrap_err().to_string();
        assert!(e.contains("--params dh"), "{e}");
        assert!(model_spec("generic6r", None).is_ok());
        assert!(model_spec("irb120", Some("frame")).is_ok());
    }

    #[test]
    fn data_inputs_name_the_files_read() {
        let dir = tempfile::tempdir().unwrap();
        assert_eq!(data_inputs(dir.path()), vec![dir.path().join("dataset.csv"), dir.path().join("truth.json")]);
        let x = dir.path().join("m.xlsx#Sheet1");
        assert_eq!(data_inputs(&x), vec![dir.path().join("m.xlsx"), dir.path().join("truth.json")]);
    }
}
