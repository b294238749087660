//! `twincal bench dsade` and `twincal bench ik`: the Evo-NPH targets, measured on the embedded
//! `irb120_evo_nph` scenario (600 poses, 500 train / 100 test, every effect on).

use std::path::Path;
use std::time::Instant;
use twincal::calib::fit::ReadingFit;
use twincal::calib::methods::evonph::{EvoNphSolver, EvoRun, EvoVariant};
use twincal::calib::methods::Problem;
use twincal::calib::pipeline::{calibrate_with, CalibOptions, CalibResult, Method, ModelSpec, TruthFile};
use twincal::dataset::Dataset;
use twincal::error::{Error, Result};
use twincal::ik::{ik_runs, table, TwinCheck};
use twincal::ik::{IkModel, JacobianKind};
use twincal::optim::{DeVariant, NoObserver};
use twincal::sim::scenario::Scenario;
use twincal::stats::{mean_std, median};

/// The embedded evo_nph scenario generated into `dir` (seed override optional).
fn dataset(dir: &Path, seed: Option<u64>) -> Result<(Dataset, TruthFile)> {
    let (mut s, robot) = Scenario::default_embedded()?;
    if let Some(seed) = seed {
        s.seed = seed;
    }
    let g = twincal::sim::generate::generate(&s, &robot, &twincal::sim::generate::Silent)?;
    twincal::sim::generate::write_outputs(&g, dir)?;
    let truth = TruthFile::find(dir)?.ok_or_else(|| Error::Invalid("truth.json missing after generation".into()))?;
    Ok((g.dataset, truth))
}

fn options(method: Method) -> CalibOptions {
    CalibOptions::new(ModelSpec::nominal(twincal::robot::Robot::irb120(), twincal::calib::pipeline::Parametrisation::Hayati), method)
}

/// The calibration problem as the pipeline builds it (split, sensor placement, identifiability,
/// noise, tolerances), for running a solver directly.
struct Prepared {
    model: twincal::calib::model::CalibModel,
    train: twincal::calib::fit::Samples,
    test: twincal::calib::fit::Samples,
    x0: Vec<f64>,
    fixed: Vec<bool>,
    prior: Vec<f64>,
    noise: f64,
}

/// The calibration's own stages ([`twincal::calib::pipeline::prepare`]) without the outlier screen (the
/// benchmark compares the solvers on every training row), then the noise and priors the solvers
/// are given.
fn prepare(ds: &Dataset, opts: &CalibOptions) -> Result<Prepared> {
    let unscreened = {
        let mut o = opts.clone();
        o.screen.outlier_k = 0.0;
        o
    };
    let p = twincal::calib::pipeline::prepare(ds, &unscreened, opts.method.needs())?;
    let (split, model, fixed) = (p.split, p.model, p.id.fixed_mask);
    let x0 = model.nominal.clone();
    let fit = ReadingFit { model: &model, data: &split.train };
    let noise = twincal::calib::pipeline::estimate_noise(&fit, &x0, &fixed, None);
    let prior = opts.tolerances.prior_std(&model);
    Ok(Prepared { train: split.train, test: split.test, x0, fixed, prior, noise, model })
}

impl Prepared {
    fn run(&self, s: &EvoNphSolver, seed: u64) -> Result<EvoRun> {
        let fit = ReadingFit { model: &self.model, data: &self.train };
        let p = Problem { fit: &fit, x0: &self.x0, fixed: &self.fixed, prior_std: &self.prior, noise_mm: self.noise, seed };
        s.run(&p, &mut NoObserver)
    }
    /// Test RMSE (mm) of a run's geometry and corrector.
    fn test_rmse(&self, r: &EvoRun) -> f64 {
        let fit = ReadingFit { model: &self.model, data: &self.test };
        let res = fit.residuals_mm(&r.solution_x);
        let c = r.corrector.as_correct();
        let ss: f64 = res.iter().enumerate().map(|(i, v)| (v - c.correction_mm(&self.test.q[i], &self.test.inputs[i])).powi(2)).sum();
        (ss / res.len().max(1) as f64).sqrt()
    }
}

/// First generation whose best objective is within 1 % of the run's final DE objective.
fn convergence_generation(curve: &[f64]) -> usize {
    let last = curve.last().copied().unwrap_or(0.0);
    curve.iter().position(|c| *c <= last * 1.01).map(|g| g + 1).unwrap_or(0)
}

/// The whole pipeline against LM, and the ablations (the paper's Table 9) with the truth.
fn ablations(ds: &Dataset, truth: &TruthFile) -> Result<()> {
    println!("\n  calibrate on the generated dataset (its 500/100 split), truth beside:");
    println!(
        "| method | test RMSE (mm) | vs LM | non-geometric error recovered | geometry, RMS (x − truth-eq.)/tolerance | seconds |\n|---|---|---|---|---|---|"
    );
    let test_idx = ds.test_indices();
    let lm = calibrate_with(ds, Some(truth), &options(Method::LM), Method::LM.solver(1.0).as_ref())?;
    let lm_rmse = lm.evaluation.metrics.test_after.as_ref().map(|m| m.rmse).unwrap_or(f64::NAN);
    // The non-geometric error: measured lengths minus the truth-equivalent rigid model (the
    // sensor's linearity error is part of what a corrector can learn; the reading noise stays).
    let x_eq: Vec<f64> = lm.parameters.iter().enumerate().map(|(k, p)| p.truth.unwrap_or(p.value) / lm.model.kinds[k].display()).collect();
    let mut rigid = lm.clone();
    rigid.x = x_eq.clone();
    rigid.corrector = None;
    let truth_rms = |r: &CalibResult| {
        let pred = r.predict_rows(ds);
        (test_idx.iter().map(|&i| (ds.rows[i].l_mm().unwrap_or(f64::NAN) - pred[i]).powi(2)).sum::<f64>() / test_idx.len() as f64).sqrt()
    };
    let ng = truth_rms(&rigid);
    let geo_dev = |r: &CalibResult| {
        let tol = twincal::calib::model::tolerance::Tolerances::default().prior_std(&r.model);
        let v: Vec<f64> =
            (0..r.x.len()).filter(|k| !r.parameters[*k].fixed && *k < r.model.first_effect()).map(|k| ((r.x[k] - x_eq[k]) / tol[k]).powi(2)).collect();
        (v.iter().sum::<f64>() / v.len().max(1) as f64).sqrt()
    };
    let row = |name: &str, r: &CalibResult| {
        let t = r.evaluation.metrics.test_after.as_ref().map(|m| m.rmse).unwrap_or(f64::NAN);
        println!(
            "| {name} | {t:.4} | {:+.1} % | {:.0} % | {:.2} | {:.2} |",
            100.0 * (t / lm_rmse - 1.0),
            100.0 * (1.0 - truth_rms(r) / ng),
            geo_dev(r),
            r.provenance.wall_time_s
        );
    };
    row("lm", &lm);
    for m in [Method::DSADE_GKAN_V1, Method::DSADE_GKAN_V2, Method::DSADE_GKAN_V3, Method::DSADE_GKAN] {
        let r = calibrate_with(ds, Some(truth), &options(m), m.solver(1.0).as_ref())?;
        row(m.name(), &r);
    }
    println!(
        "    (non-geometric error: measured lengths minus the truth-equivalent rigid model, RMS {ng:.4} mm on the test poses with the {:.4} mm reading noise; recovered = 1 − test RMSE/that)",
        truth.noise_std_mm
    );

    Ok(())
}

/// The DE engines on the same objective and budget (the paper's Table 10), no polish.
fn de_engines(prep: &Prepared, full: &EvoNphSolver, de_only: &EvoNphSolver, seeds: u64) -> Result<()> {
    let budget = full.pop * (full.generations + 1);
    let variants: Vec<(&str, DeVariant, bool)> = vec![
        ("DS-ADE", DeVariant::DsAde { memory: 6, p: 0.11, p_min: 0.1 }, true),
        ("DS-ADE, literal (no coefficient step)", DeVariant::DsAde { memory: 6, p: 0.11, p_min: 0.1 }, false),
        ("rand-to-pbest/1 only (V3)", DeVariant::RandToPBest { memory: 6, p: 0.11 }, true),
        ("JADE", DeVariant::Jade { c: 0.1, p: 0.05 }, true),
        ("SHADE", DeVariant::Shade { memory: 6, p: 0.11 }, true),
        ("L-SHADE", DeVariant::LShade { memory: 6, p: 0.11, min_pop: 4 }, true),
        ("DE/rand/1/bin", DeVariant::Classic { f: 0.5, cr: 0.9 }, true),
    ];
    println!("\n  DE engines, same objective, {budget} evaluations each, {seeds} seeds, DE result without the polish (mean ± std over seeds):");
    println!("| engine | final objective (mm²) | test RMSE (mm) | convergence generation | seconds |\n|---|---|---|---|---|");
    for (name, v, refine) in variants {
        let s = EvoNphSolver {
            de: v.clone(),
            refine_coefficients: refine,
            max_evals: Some(budget),
            generations: if matches!(v, DeVariant::LShade { .. }) { 100 * full.generations } else { full.generations },
            ..de_only.clone()
        };
        let runs: Vec<EvoRun> = (0..seeds).map(|k| prep.run(&s, 1000 + k)).collect::<Result<_>>()?;
        let f = |x: Vec<f64>, d: usize| {
            let (m, sd) = mean_std(&x);
            format!("{m:.*} ± {sd:.*}", d, d)
        };
        println!(
            "| {name} | {} | {} | {} | {} |",
            f(runs.iter().map(|r| r.de_objective).collect(), 6),
            f(runs.iter().map(|r| prep.test_rmse(r)).collect(), 4),
            f(runs.iter().map(|r| convergence_generation(&r.curve) as f64).collect(), 1),
            f(runs.iter().map(|r| r.de_seconds).collect(), 2),
        );
    }
    Ok(())
}

/// `twincal bench dsade`.
pub fn bench_dsade(repeat: usize, seeds: u64) -> Result<()> {
    let tmp = tempfile::Builder::new().prefix("twincal-dsade-").tempdir().map_err(|e| Error::create_dir(std::env::temp_dir(), e))?;
    let dir = tmp.path().join("evo");
    let (ds, truth) = dataset(&dir, None)?;
    let prep = prepare(&ds, &options(Method::DSADE_GKAN))?;
    let fit = ReadingFit { model: &prep.model, data: &prep.train };
    println!("Evo-NPH benchmark on irb120_evo_nph ({} train, {} test poses)", prep.train.len(), prep.test.len());

    // 1. Speed: the DS-ADE stage alone, against one residual evaluation over the training poses.
    let mut res_t = Vec::new();
    for _ in 0..50 {
        let t0 = Instant::now();
        std::hint::black_box(fit.residuals_mm(&prep.x0));
        res_t.push(t0.elapsed().as_secs_f64());
    }
    let t_res = median(&res_t);
    // The network is chosen once on the training rows; the timed runs and the engines then
    // share that one objective.
    let sel = {
        let p = Problem { fit: &fit, x0: &prep.x0, fixed: &prep.fixed, prior_std: &prep.prior, noise_mm: prep.noise, seed: 0 };
        let t0 = Instant::now();
        let sel = twincal::calib::methods::gkan_select::select(&p)?;
        println!("  network choice ({:.2} s): {}", t0.elapsed().as_secs_f64(), sel.summary());
        sel
    };
    let chosen = EvoNphSolver::new(EvoVariant::Full, 1.0);
    let full = EvoNphSolver { shape: sel.chosen.shape, weights: sel.weights(chosen.weights.geometry), select: false, ..chosen };
    let de_only = EvoNphSolver { polish: false, ..full.clone() };
    let mut de_t = Vec::new();
    let mut last = None;
    for _ in 0..repeat.max(3) {
        let r = prep.run(&de_only, 0)?;
        de_t.push(r.de_seconds);
        last = Some(r);
    }
    let r = last.expect("ran");
    let t_de = median(&de_t);
    println!(
        "  DS-ADE, population {}, {} generations, {} dimensions ({} geometric + {} spline coefficients): {:.3} s median (target < 3 s), {:.2} ms per generation",
        full.pop,
        r.generations,
        r.dim,
        r.n_geometry,
        r.dim - r.n_geometry,
        t_de,
        t_de / r.generations.max(1) as f64 * 1e3
    );
    println!(
        "    one residual evaluation over the training poses: {:.3} ms -> DS-ADE = {:.0} of them ({} objective evaluations)",
        t_res * 1e3,
        t_de / t_res,
        r.evaluations
    );

    ablations(&ds, &truth)?;
    de_engines(&prep, &full, &de_only, seeds)?;
    let polished = prep.run(&full, 0)?;
    println!("    after the joint polish (the method): objective {:.6} mm², test RMSE {:.4} mm", polished.objective, prep.test_rmse(&polished));
    println!("\n  Wilcoxon tests against every baseline of the core: twincal compare --data DIR --methods dsade-gkan,lm,ekf,pf,pso,rbf,dsade-gkan-v1,dsade-gkan-v2,dsade-gkan-v3");
    drop(tmp);
    Ok(())
}

/// `twincal bench ik`.
pub fn bench_ik(repeat: usize) -> Result<()> {
    let tmp = tempfile::Builder::new().prefix("twincal-ik-").tempdir().map_err(|e| Error::create_dir(std::env::temp_dir(), e))?;
    let dir = tmp.path().join("evo");
    let (ds, truth) = dataset(&dir, None)?;
    let mut r = calibrate_with(&ds, Some(&truth), &options(Method::DSADE_GKAN), Method::DSADE_GKAN.solver(1.0).as_ref())?;
    r.provenance.data = dir.display().to_string();
    let check = TwinCheck::load(&dir, &r)?;
    let n = 1000;
    let targets = twincal::ik::random_targets(&r, Some(&check), n, 0);
    let o = twincal::ik::IkOptions::default();
    // Baseline in the same process: one forward evaluation with the hybrid Jacobian.
    let corr = r.corrector.as_ref().map(|c| c.as_correct());
    let m = IkModel::new(&r.model, &r.x, corr, r.model.joint_limits());
    let mut w = m.work();
    let q = vec![0.1, 0.2, -0.3, 0.4, 0.5, 0.6];
    let mut ft = Vec::new();
    for _ in 0..2000 {
        let t0 = Instant::now();
        std::hint::black_box(m.position(&q, &mut w, Some(JacobianKind::Hybrid)));
        ft.push(t0.elapsed().as_secs_f64());
    }
    let t_f = median(&ft);
    let mut best: Option<Vec<twincal::ik::IkRun>> = None;
    for _ in 0..repeat.max(1) {
        let runs = ik_runs(&r, &targets, &JacobianKind::ALL, &o, Some(&check));
        if best.as_ref().is_none_or(|b| runs[2].median_seconds < b[2].median_seconds) {
            best = Some(runs);
        }
    }
    let runs = best.expect("ran");
    println!(
        "IK benchmark: {n} reachable targets (true tool points of random configurations inside the calibrated ranges), dsade-gkan model, tolerance {} mm",
        o.tol_mm
    );
    println!("  twin frame fit RMS {:.4} mm; one hybrid forward + Jacobian evaluation {:.2} µs", check.fit_rms_mm, t_f * 1e6);
    println!("{}", table(&runs));
    let h = &runs[2];
    println!(
        "  hybrid: median {:.1} µs per query (target < 20 µs) = {:.1} forward evaluations; success {:.1} % (target 100 %)",
        h.median_seconds * 1e6,
        h.median_seconds / t_f,
        100.0 * h.success()
    );
    if let (Some(a), Some(fl), Some(nom)) = (&h.true_error_mm, &runs[4].true_error_mm, &runs[3].true_error_mm) {
        println!("  true error on the twin, median: hybrid {:.4} mm, floor {:.4} mm, nominal {:.4} mm", median(a), median(fl), median(nom));
    }
    drop(tmp);
    Ok(())
}
