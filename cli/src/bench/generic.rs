//! `twincal bench real`, the tracker files without their URDF: the generic arm (`--model
//! generic`) on the real UR5 and WAM grids and the UR10's series b (../shared, each skipped,
//! saying so, when absent), a fifth of the rows held out, per seed against the calibration
//! seeded with the arm's URDF. Targets: held-out mean |Δp| within 5 % of the URDF-seeded one, the
//! search under 30 s (median wall time; the URDF-seeded run in the same process is the
//! baseline).

use std::time::Instant;
use twincal::calib::pipeline::{calibrate, CalibOptions, Method, ModelSpec, Parametrisation};
use twincal::dataset::Dataset;
use twincal::error::Result;
use twincal::robot::Robot;

/// The generic arm's held-out mean |Δp| may exceed the URDF-seeded one by this factor.
pub const GENERIC_RATIO_TARGET: f64 = 1.05;
/// The generic arm's calibration must take less than this (s, median wall time).
pub const GENERIC_TIME_TARGET_S: f64 = 30.0;

/// One calibration: (held-out mean |Δp| mm, wall time s, the search's report if any).
fn run(data: &Dataset, spec: ModelSpec, seed: u64) -> Result<(f64, f64, Option<twincal::calib::pipeline::generic::SearchReport>)> {
    let mut o = CalibOptions::new(spec, Method::LM);
    o.seed = seed;
    o.split.test_fraction = Some(0.2);
    let t0 = Instant::now();
    let r = calibrate(data, None, &o)?;
    let mae = r.evaluation.metrics.test_position_after.map_or(f64::NAN, |m| m.mae);
    Ok((mae, t0.elapsed().as_secs_f64(), r.solve.search))
}

/// The generic arm against the URDF-seeded calibration on the real tracker files.
pub fn bench_generic_trackers(seeds: u64, shared: &dyn Fn(&str, &str) -> Option<std::path::PathBuf>) -> Result<()> {
    println!(
        "  Tracker files without their URDF (--model generic), a fifth held out: held-out mean |dp| generic / URDF-seeded (target <= {GENERIC_RATIO_TARGET}), wall time (target < {GENERIC_TIME_TARGET_S} s)"
    );
    for (rel, urdf) in [
        ("ur5-lasertracker/ur5_grid_pool.csv", ("reference", "ur_description/ur5_robot.urdf")),
        ("wam-lasertracker/wam_grid.csv", ("", "urdf/wam.urdf")),
        ("ipa-ur10/ur10_series_b.csv", ("", "urdf/ur10.urdf")),
    ] {
        let Some(path) = shared("data", rel) else { continue };
        let urdf_path = if urdf.0.is_empty() {
            std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("..").join(urdf.1)
        } else {
            shared(urdf.0, urdf.1).unwrap_or_default()
        };
        if !urdf_path.exists() {
            continue;
        }
        let data = Dataset::load(&path)?;
        let robot = Robot::from_urdf_file(&urdf_path)?;
        let (mut times, mut base_times, mut ratios) = (Vec::new(), Vec::new(), Vec::new());
        for seed in 0..seeds {
            let (u, tu, _) = run(&data, ModelSpec::nominal(robot.clone(), Parametrisation::Hayati), seed)?;
            let (g, tg, search) = run(&data, ModelSpec::Generic, seed)?;
            let s = search.map_or(String::from("-"), |s| format!("{} of {} finalists at the best cost", s.in_best_basin, s.finalists));
            println!("    {rel} seed {seed}: generic {g:.4} mm, URDF-seeded {u:.4} mm (ratio {:.4}); {tg:.1} s against {tu:.2} s; {s}", g / u);
            times.push(tg);
            base_times.push(tu);
            ratios.push(g / u);
        }
        let worst = ratios.iter().copied().fold(0.0, f64::max);
        let (t, tb) = (twincal::stats::median(&times), twincal::stats::median(&base_times));
        println!(
            "    {rel}: worst ratio {worst:.4} ({}), median wall time {t:.1} s ({}; {:.1} x the URDF-seeded run)",
            if worst <= GENERIC_RATIO_TARGET { "meets the target" } else { "MISSES the target" },
            if t < GENERIC_TIME_TARGET_S { "meets the target" } else { "MISSES the target" },
            t / tb
        );
    }
    Ok(())
}
