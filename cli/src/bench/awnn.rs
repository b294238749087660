//! `twincal bench awnn`: the PSO-EKF-AWNN method measured on the twin's `irb120_pso_ekf`
//! scenario: speed of its stages against LM in the same process, accuracy over seeds against LM
//! and against the truth, the data-efficiency curve, the sensitivity to Q, R and the learning
//! rate, and HSR-RobotCali against its repeatability floor when the data are present.

use std::path::Path;
use std::sync::Mutex;
use std::time::Instant;
use twincal::calib::fit::{ReadingFit, Samples};
use twincal::calib::methods::psoekf::{Ablation, Hyper, NetStart, PsoEkfAwnn};
use twincal::calib::methods::{Method, Problem, Solution, Solver};
use twincal::calib::pipeline::{calibrate_with, split_stage, CalibOptions, CalibResult, ModelSpec, TruthFile};
use twincal::dataset::{Dataset, Split};
use twincal::error::{Error, Result};
use twincal::optim::Observer;
use twincal::sim::generate::{generate, write_outputs, Silent};
use twincal::sim::scenario::Scenario;
use twincal::stats::{mean_std, median};

/// Runs the method and records how long the network start, Stage 0 and the core (Stage I + II)
/// took.
struct Timed {
    inner: PsoEkfAwnn,
    times: Mutex<Vec<Times>>,
}

/// Seconds spent on the network's start, Stage 0 and the core (Stage I + II) in one run.
#[derive(Clone, Copy)]
struct Times {
    start: f64,
    zero: f64,
    core: f64,
    hyper: Hyper,
}

impl Solver for Timed {
    fn name(&self) -> &'static str {
        self.inner.name()
    }
    fn needs_noise(&self) -> bool {
        true
    }
    fn needs_row_inputs(&self) -> bool {
        self.inner.needs_row_inputs()
    }
    fn solve(&self, p: &Problem, obs: &mut dyn Observer) -> Result<Solution> {
        let t0 = Instant::now();
        let start = self.inner.new_net(p)?;
        let t_start = t0.elapsed().as_secs_f64();
        let t1 = Instant::now();
        let zero = self.inner.stage_zero(p, &start.0)?;
        let t_zero = t1.elapsed().as_secs_f64();
        let h = zero.0;
        let t2 = Instant::now();
        let sol = self.inner.finish(p, start, zero, obs)?;
        let t_core = t2.elapsed().as_secs_f64();
        self.times.lock().map_err(|_| Error::Invalid("timer poisoned".into()))?.push(Times { start: t_start, zero: t_zero, core: t_core, hyper: h });
        Ok(sol)
    }
}

fn test_rmse(r: &CalibResult) -> f64 {
    r.evaluation.metrics.test_after.as_ref().map(|m| m.rmse).unwrap_or(f64::NAN)
}

/// A dataset whose training rows are the subset `keep` of `ds`'s (test rows unchanged).
fn with_train_rows(ds: &Dataset, keep: &[usize]) -> Dataset {
    let rows = ds.rows.iter().enumerate().filter(|(i, r)| r.split != Some(Split::Train) || keep.contains(i)).map(|(_, r)| r.clone()).collect();
    Dataset { rows, source: ds.source.clone() }
}

/// Truth analysis of one calibration: RMS distance (mm-equivalent: lengths in mm, angles in
/// millidegrees) of the free chain parameters from the mapped true rigid geometry and from the
/// truth-equivalent values; the fraction of the non-geometric length error left by the model's
/// geometry on the noise-free test lengths that the corrector removes.
pub struct TruthView {
    pub to_rigid: f64,
    pub to_equivalent: f64,
    pub recovered: f64,
}

pub fn truth_view(r: &CalibResult, ds: &Dataset, truth: &TruthFile, opts: &CalibOptions) -> Option<TruthView> {
    let robot = opts.model.robot()?;
    let split = split_stage(ds, opts).ok()?;
    let rigid = twincal::calib::pipeline::equivalent::map_truth(&r.model, robot, truth, &split.train.q)?;
    let nc = r.model.n_chain();
    let dist = |t: &[f64]| {
        let v: Vec<f64> = r
            .parameters
            .iter()
            .enumerate()
            .take(nc)
            .filter(|(_, p)| !p.fixed)
            .map(|(k, p)| {
                let scale = if p.unit == "mm" { 1.0 } else { 1e3 };
                (p.value - t[k] * r.model.kinds[k].display()) * scale
            })
            .collect();
        (v.iter().map(|d| d * d).sum::<f64>() / v.len().max(1) as f64).sqrt()
    };
    let eq: Vec<f64> = r.parameters.iter().enumerate().map(|(k, p)| p.truth.unwrap_or(f64::NAN) / r.model.kinds[k].display()).collect();
    let all = twincal::calib::effects::inputs::row_inputs(ds, r.torque_model.as_ref());
    let clean = Samples {
        y: split.test_idx.iter().map(|&i| truth.poses[i].length_true_mm * 1e-3).collect(),
        dim: 1,
        measurement: twincal::measurement::Measurement::Length,
        also: None,
        inputs: split.test_idx.iter().map(|&i| all[i].clone()).collect(),
        q: split.test.q.clone(),
        w: None,
        gls: None,
    };
    let left = ReadingFit { model: &r.model, data: &clean }.residuals_mm(&r.x);
    let after: Vec<f64> = left.iter().zip(&clean.q).zip(&clean.inputs).map(|((d, q), inp)| d - r.correction_mm(q, inp)).collect();
    use twincal::stats::rms;
    Some(TruthView { to_rigid: dist(&rigid), to_equivalent: dist(&eq), recovered: 1.0 - rms(&after) / rms(&left) })
}

/// What the sections of `twincal bench awnn` share: the scenario, the model, the options and a
/// scratch folder for the datasets (removed when dropped).
struct AwnnBench {
    base: Scenario,
    robot: twincal::robot::Robot,
    spec: ModelSpec,
    lm_opts: CalibOptions,
    awnn_opts: CalibOptions,
    lm: Box<dyn twincal::calib::methods::Solver>,
    tmp_dir: tempfile::TempDir,
}

impl AwnnBench {
    /// The scenario's dataset at `seed`, with its truth (written and read back as a user's).
    fn gen(&self, seed: u64) -> Result<(Dataset, TruthFile)> {
        let mut s = self.base.clone();
        s.seed = seed;
        let g = generate(&s, &self.robot, &Silent)?;
        let dir = self.tmp_dir.path().join(format!("s{seed}"));
        write_outputs(&g, &dir)?;
        let truth = TruthFile::find(&dir)?.ok_or_else(|| Error::Invalid("truth missing".into()))?;
        Ok((g.dataset, truth))
    }

    /// Speed on the scenario's own dataset, LM in the same process as the baseline; returns the
    /// dataset and Stage 0's hyperparameters.
    fn speed(&self, repeat: usize, quiet: bool) -> Result<(Dataset, Hyper)> {
        if !quiet {
            eprintln!("bench awnn: speed ({} repetitions)", repeat.max(3));
        }
        let (ds, truth) = self.gen(self.base.seed)?;
        let timed = Timed { inner: PsoEkfAwnn::default(), times: Mutex::new(Vec::new()) };
        let (mut t_lm, mut t_full) = (Vec::new(), Vec::new());
        let mut last = None;
        for _ in 0..repeat.max(3) {
            t_lm.push(calibrate_with(&ds, None, &self.lm_opts, self.lm.as_ref())?.provenance.wall_time_s);
            let t0 = Instant::now();
            let r = calibrate_with(&ds, Some(&truth), &self.awnn_opts, &timed)?;
            t_full.push(t0.elapsed().as_secs_f64());
            last = Some(r);
        }
        let times = timed.times.lock().map_err(|_| Error::Invalid("timer poisoned".into()))?.clone();
        let t_start = median(&times.iter().map(|t| t.start).collect::<Vec<_>>());
        let t_zero = median(&times.iter().map(|t| t.zero).collect::<Vec<_>>());
        let t_core = median(&times.iter().map(|t| t.core).collect::<Vec<_>>());
        let (lm_med, full_med) = (median(&t_lm), median(&t_full));
        let h = times[0].hyper;
        println!("  speed (medians of {}, {} training poses):", t_full.len(), ds.train_indices().len());
        println!("    core, Stage I + II         : {:8.1} ms (target < 500 ms; the paper: 20.15 s)", t_core * 1e3);
        println!("    Stage 0, PSO               : {:8.1} ms (target < 5 s; the paper: about 125 s)", t_zero * 1e3);
        println!("    network start (LM + CV)    : {:8.1} ms", t_start * 1e3);
        println!("    whole calibration          : {:8.1} ms = {:.1} x LM's {:.1} ms", full_med * 1e3, full_med / lm_med, lm_med * 1e3);
        if let Some(r) = &last {
            println!(
                "    Stage 0 chose Q = {:.2e}·σ̄², R = {:.2e}·σ², η = {:.2e}; {}",
                h.q_rel,
                h.r_rel,
                h.lr,
                r.solve.stop_reason.split("; ").last().unwrap_or("")
            );
        }
        Ok((ds, h))
    }

    /// Accuracy over seeds: against LM, against the truth.
    fn accuracy(&self, seeds: u64, quiet: bool) -> Result<()> {
        if !quiet {
            eprintln!("bench awnn: accuracy over {seeds} seeds");
        }
        let mut rows = Vec::new();
        let q_opts = CalibOptions::new(self.spec.clone(), Ablation::Extended.method());
        let mut q_rows = Vec::new();
        let mut z_rows = Vec::new();
        let zero = PsoEkfAwnn { start: NetStart::Zero, ..Default::default() };
        for seed in 0..seeds {
            let (ds, truth) = self.gen(self.base.seed + 1000 + seed)?;
            let l = calibrate_with(&ds, Some(&truth), &self.lm_opts, self.lm.as_ref())?;
            let a = calibrate_with(&ds, Some(&truth), &self.awnn_opts, &PsoEkfAwnn::default())?;
            let q = calibrate_with(&ds, Some(&truth), &q_opts, &PsoEkfAwnn::variant(Ablation::Extended))?;
            let (tl, ta) = (truth_view(&l, &ds, &truth, &self.lm_opts), truth_view(&a, &ds, &truth, &self.awnn_opts));
            q_rows.push((test_rmse(&q), truth_view(&q, &ds, &truth, &q_opts).map_or(f64::NAN, |t| t.recovered)));
            let z = calibrate_with(&ds, Some(&truth), &self.awnn_opts, &zero)?;
            z_rows.push((test_rmse(&z), truth_view(&z, &ds, &truth, &self.awnn_opts).map_or(f64::NAN, |t| t.recovered)));
            rows.push((test_rmse(&l), test_rmse(&a), tl, ta, truth.noise_std_mm));
        }
        let lm_r: Vec<f64> = rows.iter().map(|r| r.0).collect();
        let aw_r: Vec<f64> = rows.iter().map(|r| r.1).collect();
        let summary = |v: &[f64]| {
            let ratio: Vec<f64> = v.iter().zip(&lm_r).map(|(a, l)| a / l).collect();
            let wins = ratio.iter().filter(|r| **r < 1.0).count();
            format!(
                "ratio to LM median {:.3} (range {:.3}–{:.3}), lower than LM in {wins}/{seeds}",
                median(&ratio),
                ratio.iter().cloned().fold(f64::INFINITY, f64::min),
                ratio.iter().cloned().fold(0.0, f64::max)
            )
        };
        let net = match PsoEkfAwnn::default().new_net_label() {
            s if s.is_empty() => "no network".to_string(),
            s => s,
        };
        println!("  accuracy over {seeds} seeds (scenario seeds {}..{}):", self.base.seed + 1000, self.base.seed + 1000 + seeds - 1);
        println!(
            "    test RMSE, median          : LM {:.4} mm, pso-ekf-awnn {:.4} mm; noise floor {:.4} mm per raw sample",
            median(&lm_r),
            median(&aw_r),
            rows[0].4
        );
        println!("    pso-ekf-awnn ({net}, network chosen by CV on the training rows): {}", summary(&aw_r));
        let z_r: Vec<f64> = z_rows.iter().map(|r| r.0).collect();
        println!(
            "    same, Stage I from {} zero-output neurons instead: median {:.4} mm, {}; removes {:.1} % (median)",
            zero.neurons,
            median(&z_r),
            summary(&z_r),
            100.0 * median(&z_rows.iter().map(|r| r.1).collect::<Vec<_>>())
        );
        let q_r: Vec<f64> = q_rows.iter().map(|r| r.0).collect();
        println!(
            "    pso-ekf-awnn-x (q + temperature (or time) + flanks, 2 network/LM alternations): median {:.4} mm, {}; removes {:.1} % (median)",
            median(&q_r),
            summary(&q_r),
            100.0 * median(&q_rows.iter().map(|r| r.1).collect::<Vec<_>>())
        );
        let col = |f: &dyn Fn(&TruthView) -> f64, pick: usize| -> f64 {
            let v: Vec<f64> = rows.iter().filter_map(|r| if pick == 0 { r.2.as_ref() } else { r.3.as_ref() }).map(f).collect();
            median(&v)
        };
        println!(
            "    geometry vs true rigid arm : RMS over free chain parameters (mm, mdeg) LM {:.4}, pso-ekf-awnn {:.4}",
            col(&|t| t.to_rigid, 0),
            col(&|t| t.to_rigid, 1)
        );
        println!(
            "    geometry vs truth-equiv.   : LM {:.4}, pso-ekf-awnn {:.4} (the rigid fit to the noise-free lengths, from the truth)",
            col(&|t| t.to_equivalent, 0),
            col(&|t| t.to_equivalent, 1)
        );
        println!(
            "    non-geometric error removed by the AWNN: median {:.1} % of what its own geometry leaves on the noise-free test lengths",
            100.0 * col(&|t| t.recovered, 1)
        );
        Ok(())
    }

    /// Data efficiency: fixed test set, training subsamples.
    fn data_efficiency(&self, ds: &Dataset, quiet: bool) -> Result<()> {
        if !quiet {
            eprintln!("bench awnn: data efficiency");
        }
        println!("  data efficiency (dataset seed {}, fixed 100 test poses, 10 subsamples each; mean ± std test RMSE, mm):", self.base.seed);
        let train = ds.train_indices();
        for n in [50usize, 100, 150, 200, 250, 300] {
            let mut la = Vec::new();
            let mut aa = Vec::new();
            let mut kept = 0;
            for k in 0..10u64 {
                let mut idx = train.clone();
                use rand::seq::SliceRandom;
                use rand::SeedableRng;
                idx.shuffle(&mut rand_chacha::ChaCha8Rng::seed_from_u64(k * 7919 + n as u64));
                idx.truncate(n);
                let sub = with_train_rows(ds, &idx);
                let mut o = self.lm_opts.clone();
                o.seed = k;
                la.push(test_rmse(&calibrate_with(&sub, None, &o, self.lm.as_ref())?));
                let mut o = self.awnn_opts.clone();
                o.seed = k;
                let r = calibrate_with(&sub, None, &o, &PsoEkfAwnn::default())?;
                kept += usize::from(!r.solve.stop_reason.contains("zero output weights"));
                aa.push(test_rmse(&r));
                if n == 300 {
                    break;
                }
            }
            let ((lm_m, lm_s), (aw_m, aw_s)) = (mean_std(&la), mean_std(&aa));
            println!(
                "    n = {n:3}: LM {lm_m:.4} ± {lm_s:.4}, pso-ekf-awnn {aw_m:.4} ± {aw_s:.4} (network kept in {kept} of {}){}",
                aa.len(),
                if n == 300 { "; all rows: one run" } else { "" }
            );
        }
        Ok(())
    }

    /// Sensitivity: one hyperparameter at a time around Stage 0's choice `h`.
    fn sensitivity(&self, ds: &Dataset, h: Hyper) -> Result<()> {
        println!("  sensitivity of the test RMSE (mm) around Stage 0's choice (one factor at a time):");
        let factors = [1e-2, 1e-1, 1.0, 1e1, 1e2];
        for (name, set) in [
            ("Q", (|h: Hyper, f: f64| Hyper { q_rel: h.q_rel * f, ..h }) as fn(Hyper, f64) -> Hyper),
            ("R", |h: Hyper, f: f64| Hyper { r_rel: h.r_rel * f, ..h }),
            ("η", |h: Hyper, f: f64| Hyper { lr: (h.lr * f).min(1.0), ..h }),
        ] {
            let mut cells = Vec::new();
            for f in factors {
                let s = PsoEkfAwnn { hyper: Some(set(h, f)), ..Default::default() };
                cells.push(format!("x{f}: {:.4}", test_rmse(&calibrate_with(ds, None, &self.awnn_opts, &s)?)));
            }
            println!("    {name}: {}", cells.join(", "));
        }
        Ok(())
    }
}

/// Real data: LM and PSO-EKF-AWNN on HSR-RobotCali, when ../shared has it.
fn real_data() -> Result<()> {
    let hsr = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/data/hsr-robotcali/hsr_robotcali_pool.csv");
    if hsr.exists() {
        let ds = Dataset::load(&hsr)?;
        let mut cells = Vec::new();
        for m in [Method::LM, Method::PSO_EKF_AWNN] {
            let mut o = CalibOptions::new(ModelSpec::Generic, m);
            o.split.test_fraction = Some(0.2);
            let r = calibrate_with(&ds, None, &o, m.solver(1.0).as_ref())?;
            if let (Some(rep), Some(t)) = (&r.evaluation.repeatability, &r.evaluation.metrics.test_after) {
                cells.push(format!("{} {:.4} mm ({:.3} x floor, {:.1} s)", m.name(), t.rmse, t.rmse / rep.pooled_std, r.provenance.wall_time_s));
                if m == Method::LM {
                    cells.insert(0, format!("repeatability floor {:.4} mm", rep.pooled_std));
                }
            }
        }
        println!("  HSR-RobotCali (generic6r, 80/20, held-out RMSE): {}", cells.join("; "));
    } else {
        println!("  HSR-RobotCali: skipped, {} is absent", hsr.display());
    }
    Ok(())
}

/// `twincal bench awnn`.
pub fn bench_awnn(repeat: usize, seeds: u64, quiet: bool) -> Result<()> {
    let (base, robot) =
        Scenario::from_toml(include_str!("../../../scenarios/irb120_pso_ekf.toml"), "irb120_pso_ekf").and_then(|s| s.load_robot(None).map(|r| (s, r)))?;
    let spec = ModelSpec::nominal(robot.clone(), twincal::calib::pipeline::Parametrisation::Hayati);
    let tmp_dir = tempfile::Builder::new().prefix("twincal-bench-awnn-").tempdir().map_err(|e| Error::create_dir(std::env::temp_dir(), e))?;
    let lm_opts = CalibOptions::new(spec.clone(), Method::LM);
    let awnn_opts = CalibOptions::new(spec.clone(), Method::PSO_EKF_AWNN);
    let bench = AwnnBench { base, robot, spec, lm_opts, awnn_opts, lm: Method::LM.solver(1.0), tmp_dir };
    println!("PSO-EKF-AWNN benchmark (irb120_pso_ekf: 400 poses, 300 train / 100 test, every effect on)");
    let (ds, h) = bench.speed(repeat, quiet)?;
    bench.accuracy(seeds, quiet)?;
    bench.data_efficiency(&ds, quiet)?;
    bench.sensitivity(&ds, h)?;
    real_data()
}
