//! `twincal bench stations`: a tracker campaign's set-up changes on the twin over seeds. The
//! twin's tracker is moved during the acquisition (`[tracker] moves`): re-stationed (metres,
//! tens of degrees), re-registered (half a millimetre, a twentieth of a degree) or bumped (a
//! tenth of a millimetre, five thousandths of a degree), for the IRB 120's points and the UR10's
//! 6-D poses; `calibrate --stations auto` must find each move at its row (counted when every move
//! is found there and nothing else), size it, and predict the unseen rows as well as on the
//! data of a tracker that never moved, which, like a hidden compliance calibrated geometric
//! only, must raise no alarm. Also the time of a 3-station campaign of 3 000 poses, calibrated and
//! diagnosed, against its 30 s target.

use std::path::Path;
use std::time::Instant;
use twincal::calib::pipeline::{calibrate, CalibOptions, CalibResult, Method, ModelSpec, Parametrisation};
use twincal::error::{Error, Result};
use twincal::sim::scenario::Scenario;

/// The moves: (label, shift of the tracker's origin, mm, turn about z, degrees); each case
/// moves the tracker twice, at 40 % and at 75 % of the poses, by the shift and turn and then by
/// twice them.
const MOVES: [(&str, [f64; 3], f64); 4] = [
    ("never moved", [0.0; 3], 0.0),
    ("re-stationed", [900.0, -600.0, 150.0], 30.0),
    ("re-registered", [0.4, -0.3, 0.1], 0.05),
    ("bumped", [0.08, 0.05, -0.03], 0.005),
];

/// Compliance under a 3 kg payload, hidden before `[sensor]`.
const MISFIT: &str =
    "[effects.compliance]\nstiffness_nm_per_rad = [1.5e5, 2.0e4, 3.0e4, 3.0e4, 3.0e4, 2.0e4]\n\n[effects.payload]\nmass_kg = 3.0\ncom_mm = [40.0, 0.0, 60.0]\n\n";

fn scenario(file: &str, seed: u64, poses: Option<usize>, extra: &str, moves: &str) -> Result<(Scenario, twincal::robot::Robot)> {
    let dir = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../scenarios"));
    let path = dir.join(format!("{file}.toml"));
    let mut text = std::fs::read_to_string(&path).map_err(|e| Error::io(&path, e))?.replacen("[sensor]", &format!("{extra}[sensor]"), 1);
    text = text.replacen("[tracker]\n", &format!("[tracker]\n{moves}"), 1);
    let mut s = Scenario::from_toml(&text, file)?;
    s.seed = seed;
    if let Some(n) = poses {
        s.sampling.poses = n;
        s.sampling.test = n / 5;
    }
    let robot = s.load_robot(Some(dir))?;
    Ok((s, robot))
}

/// The `moves = [...]` line of a tracker at `placement` (translation mm, rotation deg) moved
/// at 40 % and 75 % of `n` poses by `shift` and `turn`, then by twice them.
fn moves_line(placement: ([f64; 3], [f64; 3]), n: usize, shift: [f64; 3], turn: f64) -> String {
    if turn == 0.0 && shift == [0.0; 3] {
        return String::new();
    }
    let (t, r) = placement;
    let at = |k: f64| {
        format!(
            "{{ from_pose = {}, translation_mm = [{}, {}, {}], rotation_deg = [{}, {}, {}] }}",
            (n as f64 * if k == 1.0 { 0.4 } else { 0.75 }) as usize,
            t[0] + k * shift[0],
            t[1] + k * shift[1],
            t[2] + k * shift[2],
            r[0],
            r[1],
            r[2] + k * turn
        )
    };
    format!("moves = [{}, {}]\n", at(1.0), at(2.0))
}

fn calibrated(s: &Scenario, robot: &twincal::robot::Robot) -> Result<CalibResult> {
    let g = twincal::sim::generate::generate(s, robot, &twincal::sim::generate::Silent)?;
    calibrate(&g.dataset, None, &CalibOptions::new(ModelSpec::nominal(robot.clone(), Parametrisation::Hayati), Method::LM))
}

fn test_rmse(r: &CalibResult) -> f64 {
    r.evaluation.metrics.test_after.as_ref().map_or(f64::NAN, |m| m.rmse)
}

/// Runs every case over `seeds` seeds and prints the table, then the campaign's time.
pub fn bench_stations(seeds: u64) -> Result<()> {
    println!("# Set-up changes of a tracker campaign on the twin ({seeds} seeds; the tracker moved at 40 % and 75 % of the poses)\n");
    println!("| arm, instrument | case | found at the right rows | false alarms | shift error (median, mm) | turn error (median, °) | test RMSE / unmoved (median) | with the stations declared |");
    println!("|---|---|---|---|---|---|---|---|");
    for (arm, file) in [("IRB 120, points", "irb120_tracker"), ("UR10, 6-D poses", "ur10_pose")] {
        for (case, shift, turn) in MOVES {
            let (mut right, mut alarms, mut shift_err, mut turn_err, mut ratio, mut declared) = (0, 0, Vec::new(), Vec::new(), Vec::new(), Vec::new());
            for seed in 1..=seeds {
                let (base, robot) = scenario(file, seed, None, "", "")?;
                let tr = base.instruments.tracker.clone().ok_or_else(|| Error::Invalid(format!("{file} has no tracker")))?;
                let n = base.sampling.poses;
                let (s, _) = scenario(file, seed, None, "", &moves_line((tr.translation_mm, tr.rotation_deg), n, shift, turn))?;
                let (still, r) = (calibrated(&base, &robot)?, calibrated(&s, &robot)?);
                let found: Vec<(usize, f64, f64)> =
                    r.setup.iter().flat_map(|u| u.stations.iter().skip(1).map(|p| (p.first_row, p.shift_mm, p.turn_deg))).collect();
                let expected: Vec<usize> = tr_rows(&s);
                if expected.is_empty() {
                    alarms += usize::from(!found.is_empty());
                } else if found.iter().map(|f| f.0).collect::<Vec<_>>() == expected {
                    right += 1;
                    let (true_shift, true_turn) = truth_change(&tr, s.instruments.tracker.as_ref().map(|t| &t.moves[0]));
                    shift_err.push((found[0].1 - true_shift).abs());
                    turn_err.push((found[0].2 - true_turn).abs());
                } else {
                    alarms += usize::from(found.iter().any(|f| !expected.contains(&f.0)));
                }
                ratio.push(test_rmse(&r) / test_rmse(&still));
                if !expected.is_empty() {
                    let line = moves_line((tr.translation_mm, tr.rotation_deg), n, shift, turn) + "write_station = true\n";
                    let (sd, _) = scenario(file, seed, None, "", &line)?;
                    declared.push(test_rmse(&calibrated(&sd, &robot)?) / test_rmse(&still));
                }
            }
            let med = |v: &[f64]| if v.is_empty() { "–".to_string() } else { format!("{:.4}", twincal::stats::median(v)) };
            let right = if shift == [0.0; 3] { "–".to_string() } else { format!("{right}/{seeds}") };
            println!("| {arm} | {case} | {right} | {alarms}/{seeds} | {} | {} | {} | {} |", med(&shift_err), med(&turn_err), med(&ratio), med(&declared));
        }
        // A misfit the geometry cannot fit is no set-up change.
        let mut alarms = 0;
        for seed in 1..=seeds {
            let (s, robot) = scenario(file, seed, None, MISFIT, "")?;
            alarms += usize::from(calibrated(&s, &robot)?.setup.is_some());
        }
        println!("| {arm} | compliance under 3 kg hidden, calibrated geometric only | – | {alarms}/{seeds} | – | – | – | – |");
    }
    campaign_time()
}

/// How far the tracker's origin moved (mm) and how far its axes turned (degrees) from its
/// scenario placement to its first move: the truth the result's set-up report is compared with.
fn truth_change(tr: &twincal::sim::instrument::tracker::Tracker, first: Option<&twincal::sim::instrument::tracker::TrackerMove>) -> (f64, f64) {
    use twincal::measurement::{Measurement, Placement};
    let Some(m) = first else { return (0.0, 0.0) };
    let frame = |t: [f64; 3], r: [f64; 3]| Measurement::Point.def().frame(&Placement::tracker(t, r, None, nalgebra::Vector3::zeros()).own);
    let (a, b) = (frame(tr.translation_mm, tr.rotation_deg), frame(m.translation_mm, m.rotation_deg));
    let turn = a.axes.zip(b.axes).map_or(0.0, |(a, b)| nalgebra::Rotation3::from_matrix_unchecked(a.transpose() * b).angle().to_degrees());
    ((b.origin - a.origin).norm() * 1e3, turn)
}

/// The first data rows (1-based) of the moved stations of a scenario's tracker.
fn tr_rows(s: &Scenario) -> Vec<usize> {
    s.instruments.tracker.as_ref().map(|t| t.moves.iter().map(|m| m.from_pose + 1).collect()).unwrap_or_default()
}

/// A 3-station campaign of 3 000 poses (IRB 120, points, moved without a station column):
/// calibrate and diagnose timed against 30 s.
fn campaign_time() -> Result<()> {
    let (base, robot) = scenario("irb120_tracker", 1, Some(3000), "", "")?;
    let tr = base.instruments.tracker.clone().ok_or_else(|| Error::Invalid("irb120_tracker has no tracker".into()))?;
    let (s, _) = scenario("irb120_tracker", 1, Some(3000), "", &moves_line((tr.translation_mm, tr.rotation_deg), 3000, [900.0, -600.0, 150.0], 30.0))?;
    let g = twincal::sim::generate::generate(&s, &robot, &twincal::sim::generate::Silent)?;
    let opts = CalibOptions::new(ModelSpec::nominal(robot.clone(), Parametrisation::Hayati), Method::LM);
    let t0 = Instant::now();
    let r = calibrate(&g.dataset, None, &opts)?;
    let t_cal = t0.elapsed().as_secs_f64();
    let t1 = Instant::now();
    let mut d = twincal::diagnose::DiagnoseOptions::new(ModelSpec::nominal(robot.clone(), Parametrisation::Hayati));
    d.seed = 1;
    let (labelled, _) = twincal::calib::pipeline::resolve_stations(&g.dataset, &d.baseline_options())?;
    let (report, _) = twincal::diagnose::diagnose(labelled.as_ref().unwrap_or(&g.dataset), &d, &|_| {})?;
    let t_diag = t1.elapsed().as_secs_f64();
    let stations = r.setup.as_ref().map_or(1, |u| u.stations.len());
    println!(
        "\n3 000 poses at 3 stations (found, not declared: {stations}): calibrate {t_cal:.1} s, diagnose (stations, then causes: {}) {t_diag:.1} s, together {:.1} s (target < 30 s)",
        report.verdict,
        t_cal + t_diag
    );
    Ok(())
}
