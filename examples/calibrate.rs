//! Generate the embedded default scenario's dataset, calibrate it as `twincal calibrate` does
//! (its default request: LM on the Hayati model), and judge the result against the truth the
//! twin wrote beside the data: the held-out error before and after, and how many identifiable
//! parameters the fit recovered within three standard uncertainties.
//!
//! `cargo run --release --example calibrate [SEED]` (CI runs it with the default seed).

use twincal::calib::pipeline::calibrate;
use twincal::dataset::truth::TruthFile;
use twincal::requests::CalibrateRequest;
use twincal::sim::generate::{generate, output_texts, Silent};
use twincal::sim::scenario::Scenario;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let seed: u64 = match std::env::args().nth(1) {
        Some(s) => s.parse().map_err(|e| format!("SEED {s:?}: {e}"))?,
        None => 7,
    };
    // The twin: the IRB 120 with the scenario's effects, read by its draw-wire sensor.
    let (mut scenario, robot) = Scenario::default_embedded()?;
    scenario.seed = seed;
    let generated = generate(&scenario, &robot, &Silent)?;
    // The truth as truth.json holds it, tied to the dataset's bytes as a file would be.
    let (csv, truth_json) = output_texts(&generated)?;
    let truth = TruthFile::parse(&truth_json, "truth.json (in memory)")?;
    truth.check_belongs(csv.as_bytes(), "dataset.csv (in memory)", "truth.json (in memory)", "generate them together")?;

    // What `twincal calibrate --data DIR` asks for, with its checks.
    let (options, _limits) = CalibrateRequest::default().options()?;
    let result = calibrate(&generated.dataset, Some(&truth), &options)?;

    let m = &result.evaluation.metrics;
    let (before, after) = (m.test_before.as_ref().ok_or("no test rows")?, m.test_after.as_ref().ok_or("no test rows")?);
    println!(
        "scenario {} seed {seed}: {} train / {} test rows, model {}",
        scenario.name, result.provenance.n_train, result.provenance.n_test, result.provenance.model_name
    );
    println!("held-out RMSE {:.4} mm before, {:.4} mm after ({} iterations)", before.rmse, after.rmse, result.solve.iterations);
    let t = result.evaluation.truth_comparison.as_ref().ok_or("no truth comparison")?;
    println!("truth: {}/{} identifiable parameters within 3 sigma (max |z| {:.2})", t.within_3_sigma, t.identifiable, t.max_abs_z);
    // The example fails loudly when the calibration does not do its job.
    if after.rmse.is_nan() || after.rmse >= 0.5 * before.rmse {
        return Err(format!("calibration did not halve the held-out error: {:.4} -> {:.4} mm", before.rmse, after.rmse).into());
    }
    Ok(())
}
