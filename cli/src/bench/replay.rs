//! `bench replay`: the twin driven through 1 000 measured rows with the scenario's acquisition
//! (the embedded scenario's simulated tour by default) against 5 s, beside generating the same
//! number of poses in the same process; and what writing the identified twin adds to an
//! identification, against 1 s.

use std::time::Instant;
use twincal::calib::pipeline::{calibrate, CalibOptions, Method, ModelSpec};
use twincal::error::Result;
use twincal::robot::Robot;
use twincal::sim::generate::{generate, generate_at, Silent};
use twincal::sim::scenario::Scenario;
use twincal::stats::median;

/// Rows a replay benchmark replays.
pub const REPLAY_ROWS: usize = 1000;
/// Target for the replay of [`REPLAY_ROWS`] rows, s.
pub const REPLAY_TARGET_S: f64 = 5.0;
/// Target for what writing the identified twin adds to an identification, s.
pub const IDENTIFY_EXTRA_TARGET_S: f64 = 1.0;

pub fn bench_replay(s: &Scenario, robot: &Robot, repeat: usize) -> Result<()> {
    let mut s = s.clone();
    s.sampling.poses = REPLAY_ROWS;
    s.sampling.test = 0;
    println!("replay of {REPLAY_ROWS} rows of scenario {} ({:?} acquisition), median of {repeat}", s.name, s.acquisition.model);
    // The "measured" acquisition: the scenario's own, whose poses and times are replayed.
    let measured = generate(&s, robot, &Silent)?;
    let poses: Vec<Vec<f64>> = measured.dataset.rows.iter().map(|r| r.q_deg.iter().map(|v| v.to_radians()).collect()).collect();
    let times: Option<Vec<f64>> = measured.dataset.rows.iter().map(|r| r.t_s).collect();
    let (mut replay_s, mut generate_s) = (Vec::new(), Vec::new());
    let mut worst = 0.0_f64;
    for _ in 0..repeat {
        let t0 = Instant::now();
        let g = generate_at(&s, robot, poses.clone(), times.clone(), &Silent)?;
        replay_s.push(t0.elapsed().as_secs_f64());
        // The same scenario, seed, poses and (logged, ms) times: the same readings but for what
        // the rounding of the times moves.
        for (a, b) in g.dataset.rows.iter().zip(&measured.dataset.rows) {
            worst = a.reading_mm.iter().zip(&b.reading_mm).fold(worst, |w, (x, y)| w.max((x - y).abs()));
        }
        let t0 = Instant::now();
        generate(&s, robot, &Silent)?;
        generate_s.push(t0.elapsed().as_secs_f64());
    }
    let (r, b) = (median(&replay_s), median(&generate_s));
    println!(
        "  replay {r:.3} s (target < {REPLAY_TARGET_S:.0} s: {}), generate of as many poses {b:.3} s, ratio {:.2}; replayed readings within {worst:.2e} mm of the measured ones",
        if r < REPLAY_TARGET_S { "met" } else { "MISSED" },
        r / b
    );
    // Identification: a calibration, then the identified twin written from it.
    let opts = CalibOptions::new(ModelSpec::nominal(twincal::robot::Robot::irb120(), twincal::calib::pipeline::Parametrisation::Hayati), Method::LM);
    let t0 = Instant::now();
    let result = calibrate(&measured.dataset, None, &opts)?;
    let calib_s = t0.elapsed().as_secs_f64();
    let mut twin_s = Vec::new();
    for _ in 0..repeat {
        let t0 = Instant::now();
        twincal::identified::identified_scenario(&result, &measured.dataset, opts.model.robot(), std::path::Path::new("bench_twin.toml"), "bench")?;
        twin_s.push(t0.elapsed().as_secs_f64());
    }
    let t = median(&twin_s);
    println!(
        "  identification: calibrate {calib_s:.3} s, then the identified twin (URDF, scenario, its validation) {:.2} ms (target < {IDENTIFY_EXTRA_TARGET_S:.0} s: {})",
        t * 1e3,
        if t < IDENTIFY_EXTRA_TARGET_S { "met" } else { "MISSED" }
    );
    Ok(())
}
