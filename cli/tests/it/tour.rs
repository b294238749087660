//! The acquisition simulated as a tour: moves, holds, gate and readings in one rapier multibody.

use twincal::robot::Robot;
use twincal::sim::effects::statics::Contact;
use twincal::sim::effects::Eccentricity;
use twincal::sim::generate::{build_twin, generate, sample_poses, Silent};
use twincal::sim::scenario::Scenario;
use twincal::sim::study::{hold_study, HoldStudy};
use twincal::sim::twin::motion::Move;
use twincal::sim::twin::tour::{acquire, Acquired, Acquisition, AcquisitionModel, OnTimeout, TourSettings};
use twincal::sim::twin::PoseCommand;

/// The embedded scenario: its acquisition is the simulated tour.
fn embedded() -> (Scenario, Robot) {
    let (s, robot) = Scenario::default_embedded().unwrap();
    assert_eq!(s.acquisition.model, AcquisitionModel::Simulated);
    (s, robot)
}

fn tour(s: &Scenario, robot: &Robot, n: usize) -> (Vec<Vec<f64>>, Vec<Acquired>) {
    let twin = build_twin(s, robot);
    let mut poses = sample_poses(s, robot).unwrap();
    poses.truncate(n);
    let settings = TourSettings { seed: s.seed, speed_fraction: s.sampling.speed_fraction };
    let a = acquire(&twin, &s.acquisition, settings, &[0.0; 6], &poses, None, &Silent).into_iter().collect::<Result<Vec<_>, _>>().unwrap();
    (poses, a)
}

/// Slow moves (decelerations far below what breaks the friction) and a long hold, every effect on
/// (eccentricity added): each reading is the quasi-static model's on the flanks the motion left,
/// and those flanks are the rule's wherever the rule is unambiguous.
#[test]
fn slow_tour_with_ample_hold_equals_the_quasi_static_model() {
    let (mut s, robot) = embedded();
    s.effects.eccentricity = Some(Eccentricity { amplitude_deg: vec![0.005, 0.005, 0.005, 0.0, 0.0, 0.0], phase_deg: vec![30.0, -60.0, 120.0, 0.0, 0.0, 0.0] });
    s.sampling.speed_fraction = 0.01;
    s.acquisition.ramp_s = 1.0;
    s.validate(&robot, "slow").unwrap();
    let twin = build_twin(&s, &robot);
    let (poses, acquired) = tour(&s, &robot, 8);
    let breakaway = twin.transmission.as_ref().unwrap().breakaway;
    let speed: Vec<f64> = robot.joints.iter().map(|j| 0.01 * j.max_velocity).collect();
    let (mut worst, mut loaded, mut approach) = (0.0f64, 0, 0);
    let mut prev = vec![0.0; 6];
    for (i, a) in acquired.iter().enumerate() {
        assert!(a.gate_s.is_some(), "pose {i}: gate closed");
        let sides: Vec<f64> = a
            .rest
            .contact
            .iter()
            .zip(&a.rest.torque)
            .map(|(c, tau)| match c {
                Contact::Positive => 1.0,
                Contact::Negative => -1.0,
                Contact::Held => -tau.signum(),
                other => panic!("pose {i}: contact {other:?} after a slow move"),
            })
            .collect();
        // The quasi-static model at the reading's time on the simulated flanks.
        let mid = a.lengths.len() / 2;
        let l = a.lengths.iter().sum::<f64>() / a.lengths.len() as f64;
        let timing = twincal::sim::twin::tour::Timing { speed_fraction: 0.01, ramp_s: 1.0, hold_s: s.draw_wire.hold_s, window_s: s.draw_wire.window_s() };
        let schedule = twincal::sim::twin::tour::Schedule::new(&robot, &timing, &[0.0; 6], &poses, None);
        let qs = twin.quasi_static(&PoseCommand { q_cmd: poses[i].clone(), sides: sides.clone(), t: schedule.read_t[i] });
        let d = (l - twin.draw_wire.ideal_length(&qs.tool)).abs();
        worst = worst.max(d);
        assert!((a.rest.tool - qs.tool).norm() * 1e3 < 1e-3, "pose {i}: tool {:e} mm off", (a.rest.tool - qs.tool).norm() * 1e3);
        assert!(a.transient_mm.abs() < 1e-3 && (a.lengths[mid] - l).abs() < 1e-6, "pose {i}: transient {}", a.transient_mm);
        assert_eq!(qs.contact.iter().filter(|c| **c == Contact::Held).count(), a.rest.contact.iter().filter(|c| **c == Contact::Held).count(), "pose {i}");
        // Flanks against the rule: the load decides above twice the breakaway ...
        let mv = Move::plan(&prev, &poses[i], &speed, 1.0);
        for j in 0..6 {
            let tau = a.rest.torque[j];
            if tau.abs() > 2.0 * breakaway {
                assert_eq!(sides[j], tau.signum(), "pose {i} joint {j}: loaded by {tau} N·m");
                loaded += 1;
                continue;
            }
            // ... the approach where the load stayed below the breakaway all along the move.
            let along = (0..=40).map(|k| {
                let q: Vec<f64> = (0..6).map(|jj| mv.joint(jj, mv.duration * k as f64 / 40.0).0).collect();
                twin.quasi_static(&PoseCommand { q_cmd: q, sides: vec![-1.0; 6], t: 0.0 }).torque[j].abs()
            });
            if poses[i][j] != prev[j] && along.fold(0.0f64, f64::max) < 0.8 * breakaway {
                assert_eq!(
                    sides[j], a.rule_sides[j],
                    "pose {i} joint {j}: approach flank; contact {:?}, δ {:e}, τ {}",
                    a.rest.contact[j], a.rest.deflection[j], a.rest.torque[j]
                );
                approach += 1;
            }
        }
        prev = poses[i].clone();
    }
    assert!(worst < 1e-3, "worst |L − quasi-static| {worst:e} mm");
    assert!(loaded >= 10 && approach >= 3, "checked {loaded} loaded and {approach} approach flanks");
}

/// At the scenario's own speed the decelerations carry links off their flanks; once the arm is
/// still, a joint loaded beyond the breakaway rests on the flank its load pushes it to, and only
/// a joint whose load friction can hold stays inside its band.
#[test]
fn loaded_joints_end_on_the_loads_flank_at_full_speed() {
    let (s, robot) = embedded();
    let twin = build_twin(&s, &robot);
    let breakaway = twin.transmission.as_ref().unwrap().breakaway;
    let (_, acquired) = tour(&s, &robot, 150);
    let (mut loaded, mut free) = (0, 0);
    for (i, a) in acquired.iter().enumerate() {
        for j in 0..6 {
            let tau = a.rest.torque[j];
            match a.rest.contact[j] {
                Contact::Free => {
                    assert!(tau.abs() <= breakaway, "pose {i} joint {j}: inside the band although loaded by {tau} N·m");
                    free += 1;
                }
                Contact::Positive | Contact::Negative if tau.abs() > breakaway => {
                    assert_eq!(a.rest.contact[j] == Contact::Positive, tau > 0.0, "pose {i} joint {j}: loaded by {tau} N·m");
                    loaded += 1;
                }
                _ => {}
            }
        }
    }
    // Both situations occur (the check is not vacuous).
    assert!(loaded > 300 && free > 5, "{loaded} loaded joints on a flank, {free} inside the band");
}

/// A 20 ms hold on the lightly damped arm reads during the transient; 2 s do not; more damping
/// shortens it. The gate cannot open within 20 ms (it needs two 20 ms windows).
#[test]
fn short_hold_on_a_lightly_damped_arm_shows_the_transient() {
    let (s, robot) = embedded();
    let study = HoldStudy { holds_s: vec![0.02, 2.0], speed_fractions: vec![0.2], poses: 12 };
    let rows = hold_study(&s, &robot, &study, &Silent).unwrap();
    let (short, long) = (&rows[0], &rows[1]);
    assert_eq!((short.hold_s, long.hold_s), (0.02, 2.0));
    assert!(short.max_mm > 2e-3 && short.spread_mm > 5e-4, "20 ms hold: {short:?}");
    assert!(long.max_mm < 1e-5 && short.max_mm > 100.0 * long.max_mm, "2 s hold: {long:?}");
    assert_eq!(short.gate_closed, 12);
    assert_eq!(long.gate_closed, 0);
    assert!(long.time_per_pose_s > short.time_per_pose_s + 1.9);
    let mut damped = s.clone();
    damped.acquisition.damping_ratio = 0.5;
    let rows = hold_study(&damped, &robot, &HoldStudy { holds_s: vec![0.02], ..study.clone() }, &Silent).unwrap();
    assert!(rows[0].max_mm < 0.5 * short.max_mm, "ζ = 0.5: {:?} vs ζ = 0.05: {short:?}", rows[0]);

    // The dataset: rejected when the gate is still closed, read anyway when asked to.
    let mut quick = s.clone();
    quick.sampling.poses = 10;
    quick.sampling.test = 2;
    quick.draw_wire.hold_s = 0.02;
    let g = generate(&quick, &robot, &Silent).err().expect("every pose rejected");
    assert!(g.to_string().contains("stability gate still closed"), "{g}");
    quick.acquisition.on_timeout = OnTimeout::Read;
    let g = generate(&quick, &robot, &Silent).unwrap();
    assert_eq!(g.dataset.rows.len(), 10);
    let p = g.truth.poses[3].acquisition.as_ref().unwrap();
    assert!(p.read_with_gate_closed && p.gate_s.is_none() && p.move_s > 0.0);
    assert!(g.truth.poses.iter().any(|p| p.acquisition.as_ref().unwrap().transient_mm.abs() > 1e-3));
}

/// Same scenario and seed, same bytes: also with the tour split into small chunks on one thread
/// or on three.
#[test]
fn tour_is_deterministic_whatever_the_thread_count() {
    let (mut s, robot) = embedded();
    s.sampling.poses = 24;
    s.sampling.test = 4;
    s.draw_wire.hold_s = 0.1;
    s.acquisition.chunk_poses = 5;
    s.validate(&robot, "small").unwrap();
    let run = |s: &Scenario, threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        let g = pool.install(|| generate(s, &robot, &Silent)).unwrap();
        (g.dataset.to_csv_string(), serde_json::to_string(&g.truth).unwrap())
    };
    let one = run(&s, 1);
    assert_eq!(one, run(&s, 3));
    assert_eq!(one, run(&s, 1));
}

#[test]
fn acquisition_keys_are_checked_naming_the_key() {
    let (s, robot) = embedded();
    let text = twincal::sim::scenario::DEFAULT_SCENARIO;
    let cases = [
        ("damping_ratio = 0.05", "damping_ratio = 0.0", "acquisition.damping_ratio"),
        ("ramp_s = 0.1", "ramp_s = -1.0", "acquisition.ramp_s"),
        ("gate_window_s = 0.02", "gate_window_s = 0.0001", "acquisition.gate_window_s"),
        ("gate_mm = 0.02", "gate_mm = nan", "acquisition.gate_mm"),
        ("on_timeout = \"reject\"", "on_timeout = \"retry\"", "on_timeout"),
        ("model = \"simulated\"", "model = \"fast\"", "model"),
        ("model = \"simulated\"", "model = \"simulated\"\ncoarse_dt_s = 0.5", "acquisition.coarse_dt_s"),
        ("model = \"simulated\"", "model = \"simulated\"\nchunk_poses = 0", "acquisition.chunk_poses"),
        ("model = \"simulated\"", "model = \"simulated\"\nhold_time = 1.0", "hold_time"),
    ];
    for (from, to, key) in cases {
        let patched = text.replace(from, to);
        assert_ne!(patched, text);
        let msg = match Scenario::from_toml(&patched, "p.toml") {
            Err(e) => e.to_string(),
            Ok(s) => s.validate(&robot, "p.toml").expect_err(to).to_string(),
        };
        assert!(msg.contains("p.toml") && msg.contains(key), "{to}: {msg}");
    }
    // The defaults of a scenario without the table: settled poses as before.
    let ideal = Scenario::load(&std::path::Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/..")).join("scenarios/irb120_ideal.toml")).unwrap().0;
    assert_eq!(ideal.acquisition, Acquisition::default());
    assert_eq!(ideal.acquisition.model, AcquisitionModel::Settled);
    assert_eq!(s.acquisition.on_timeout, OnTimeout::Reject);
}
