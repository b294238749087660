//! `twincal bench sockets`: a ball seated in an artifact's sockets on the twin over seeds
//! ([`twincal::sockets_check`]): calibrated from the seated rows alone, judged on tracker points
//! of the same arm no fit saw (the tracker registered on other points), beside the nominal arm
//! and a tracker calibration from as many rows; and the time of the sockets' calibration.

use super::compensate::mean_sd;
use std::path::Path;
use std::time::Instant;
use twincal::calib::pipeline::{CalibOptions, Method, ModelSpec, Parametrisation};
use twincal::error::{Error, Result};
use twincal::sim::scenario::Scenario;
use twincal::sockets_check::{check, SocketCheck};

/// The cases: (label, scenario file).
const CASES: [(&str, &str); 1] = [("IRB 120, two sockets 50 mm apart, three placements, 30 seatings per socket", "irb120_sockets")];

/// Runs every case over `seeds` seeds and prints the table.
pub fn bench_sockets(seeds: u64) -> Result<()> {
    let dir = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../scenarios"));
    println!("# A ball in sockets on the twin ({seeds} seeds): calibrated from the seated rows alone, judged on 100 tracker points no fit saw after registering the tracker on 200 others; |Δp| RMS over the points, mm, mean ± sd over seeds\n");
    println!("| case | seated rows (train) | socket rows' test RMSE | nominal | sockets | tracker, as many rows | sockets / tracker (worst seed) | calibration time (median) |");
    println!("|---|---|---|---|---|---|---|---|");
    for (label, file) in CASES {
        let path = dir.join(format!("{file}.toml"));
        let text = std::fs::read_to_string(&path).map_err(|e| Error::io(&path, e))?;
        let s0 = Scenario::from_toml(&text, file)?;
        let robot = s0.load_robot(Some(dir))?;
        let opts = CalibOptions::new(ModelSpec::Nominal { robot: Box::new(robot.clone()), parametrisation: Parametrisation::Hayati }, Method::LM);
        let mut times = Vec::new();
        let checks: Vec<SocketCheck> = (1..=seeds)
            .map(|seed| {
                let t0 = Instant::now();
                let c = check(&Scenario { seed, ..s0.clone() }, &robot, &opts);
                times.push(t0.elapsed().as_secs_f64());
                c
            })
            .collect::<Result<_>>()?;
        let col = |f: &dyn Fn(&SocketCheck) -> f64| {
            let (m, sd) = mean_sd(&checks.iter().map(f).collect::<Vec<_>>());
            format!("{m:.4} ± {sd:.4}")
        };
        let worst = checks.iter().map(|c| c.sockets_mm / c.tracker_mm).fold(0.0, f64::max);
        times.sort_by(f64::total_cmp);
        println!(
            "| {label} | {} | {} | {} | {} | {} | {worst:.2} | {:.2} s |",
            checks[0].socket_rows,
            col(&|c| c.socket_test_rmse_mm),
            col(&|c| c.nominal_mm),
            col(&|c| c.sockets_mm),
            col(&|c| c.tracker_mm),
            times[times.len() / 2]
        );
    }
    Ok(())
}
