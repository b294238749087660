//! Unit tests of the diagnosis's steps.

use super::fit::*;
use super::screen::*;
use crate::calib::effects::{EffectBlock, EffectKind};
use crate::calib::model::CalibModel;
use crate::dataset::{Dataset, Row};
use crate::robot::Robot;
use crate::stats::rms;

fn data() -> Dataset {
    let rows = (0..20)
        .map(|i| {
            let a = i as f64;
            Row {
                q_deg: vec![a, -a, 2.0 * a, 0.5 * a, 10.0 - a, a],
                reading_mm: vec![500.0 + a],
                t_s: Some(10.0 * a),
                temp_c: None,
                split: None,
                std_mm: None,
                ..Default::default()
            }
        })
        .collect();
    Dataset { rows, source: "test".into() }
}

#[test]
fn listed_candidates_keep_their_joint_count_once_and_name_what_the_data_lack() {
    let d = data();
    // Every kind on every joint the data support (no torques: no compliance).
    let all = candidates(&d, &[], false).unwrap();
    assert!(all.iter().all(|b| b.kind != EffectKind::Compliance));
    assert_eq!(all.iter().filter(|b| b.kind == EffectKind::Backlash).count(), 6);
    // A joint given is that block only; listed twice, it is still one candidate.
    let two = candidates(&d, &[(EffectKind::Backlash, Some(1)), (EffectKind::Backlash, Some(1))], false).unwrap();
    assert_eq!(two.len(), 1);
    assert_eq!((two[0].kind, two[0].joint), (EffectKind::Backlash, Some(1)));
    // A listed candidate the data cannot support is an error, not a silent "geometric only".
    let e = candidates(&d, &[(EffectKind::Compliance, None)], false).unwrap_err().to_string();
    assert!(e.contains("joint torques"), "{e}");
    let e = candidates(&d, &[(EffectKind::Backlash, Some(8))], false).unwrap_err().to_string();
    assert!(e.contains("joint 9 is beyond the data's 6 joints"), "{e}");
}

#[test]
fn a_warm_up_outside_its_physical_range_or_an_oversized_effect_is_not_physical() {
    use crate::calib::effects::ThermalDrive;
    use crate::calib::model::DrawWireGuess;
    let robot = Robot::irb120();
    let guess = DrawWireGuess { exit_m: [0.8, 0.3, 0.05], offset_m: 0.12, tool_m: [0.06, 0.0, 0.0] };
    let mut m = CalibModel::dh(&robot, &guess, true);
    m.add_effect(EffectBlock { kind: EffectKind::Thermal, joint: Some(0), thermal: Some(ThermalDrive::WarmUp), range_m: None }, 3600.0);
    let k = m.effect_params(0).start;
    let mut x = m.nominal.clone();
    (x[k], x[k + 1]) = (0.01f64.to_radians(), 1200.0);
    assert_eq!(implausible_param(&m, &x, 0), None);
    // The case: 2.1e8 s and thousands of degrees; a time constant of seconds.
    for tau in [2.1e8, 20.0, -70.0] {
        x[k + 1] = tau;
        let why = implausible_param(&m, &x, 0).expect("not physical");
        assert!(why.contains("warm-up time constant"), "{why}");
    }
    (x[k], x[k + 1]) = (87.5, 1200.0);
    assert!(implausible_param(&m, &x, 0).expect("not physical").contains("beyond 30x its plausible size"));
}

#[test]
fn a_kept_cause_that_ends_unphysical_is_named_in_a_warning() {
    use crate::calib::model::DrawWireGuess;
    let robot = Robot::irb120();
    let guess = DrawWireGuess { exit_m: [0.8, 0.3, 0.05], offset_m: 0.12, tool_m: [0.06, 0.0, 0.0] };
    let mut m = CalibModel::dh(&robot, &guess, true);
    let (band, spring) = (EffectBlock::joint(EffectKind::Backlash, 2), EffectBlock::joint(EffectKind::Compliance, 1));
    m.add_effect(spring.clone(), 3600.0);
    m.add_effect(band.clone(), 3600.0);
    let mut x = m.nominal.clone();
    let (kc, kb) = (m.effect_params(0).start, m.effect_params(1).start);
    x[kc] = 40e-6;
    x[kb] = 0.005f64.to_radians();
    assert!(unphysical_causes(&m, &x, &[spring.clone(), band.clone()]).is_empty());
    x[kb] = -0.005f64.to_radians();
    let w = unphysical_causes(&m, &x, &[spring.clone(), band.clone()]);
    assert_eq!(w.len(), 1, "{w:?}");
    assert!(w[0].starts_with("backlash[j3] ends with an unphysical size") && w[0].contains("backlash.j3 = -5.0000 mdeg"), "{w:?}");
    x[kc] = -1e-6;
    assert_eq!(unphysical_causes(&m, &x, &[spring, band]).len(), 2);
}

#[test]
fn a_leak_is_warned_only_beyond_the_held_out_mean_squares_sampling_error() {
    // 20 blocks of 20 rows sharing one error each, of RMS 0.22 mm against a 0.25 mm floor:
    // a realised shortfall that a few dozen shared errors give by chance.
    let (blocks, rows) = (20usize, 20usize);
    let groups: Vec<usize> = (0..blocks * rows).map(|i| i / rows).collect();
    let shared: Vec<f64> =
        groups.iter().map(|&b| 0.22 * std::f64::consts::SQRT_2 * ((b as f64) * 0.7).sin().signum() * ((b % 3) as f64 / 2.0 + 0.25)).collect();
    let floor = 1.1 * rms(&shared);
    assert!(leak_warning(&shared, 1, Some(&groups), floor, true).is_none());
    // The same rows as independent: 400 values well below the floor are a leak.
    assert!(leak_warning(&shared, 1, None, floor, true).is_some());
    // Every block predicted at half the floor, evenly: a leak whatever the blocks.
    let even: Vec<f64> = (0..blocks * rows).map(|i| if i % 2 == 0 { 0.5 * floor } else { -0.5 * floor }).collect();
    let w = leak_warning(&even, 1, Some(&groups), floor, true).expect("a leak");
    assert!(w.contains("split leaks") && w.contains("declare them in a block column"), "{w}");
}

#[test]
fn the_gain_a_cause_needs_follows_the_floors_sampling_error() {
    use super::select::{gain_threshold, BELOW_FLOOR_SHARE};
    // 300 independent tracker rows, three values each: the floor's mean square varies by
    // √(2/900) of itself, so a gain of 0.38 of the floor is beyond three such errors.
    let independent = gain_threshold(1.0, 900, 1.0);
    assert!((independent - (3.0 * (2.0f64 / 900.0).sqrt()).sqrt()).abs() < 1e-12 && independent < 0.4, "{independent}");
    // Half of one row's noise is then named; a tenth is not.
    assert!(0.5 > independent && 0.1 < independent);
    // Twenty sweeps of twenty rows sharing their rounding (design effect up to 20): nearly the
    // whole floor, and never more.
    assert!(gain_threshold(0.24, 400, 20.0) > 0.95 * 0.24);
    assert_eq!(gain_threshold(0.24, 400, 25.0), BELOW_FLOOR_SHARE * 0.24);
    // Fewer values, a larger share; never above the floor.
    assert!(gain_threshold(1.0, 100, 1.0) > independent && gain_threshold(1.0, 2, 1.0) <= 1.0);
}

/// A hidden tracker effect at half one row's noise on 400 independent rows (the rows' own
/// `sx, sy, sz` giving the floor) is named and sized; the same rows without it name nothing.
#[test]
fn an_effect_of_half_one_rows_noise_on_independent_tracker_rows_is_named() {
    use crate::diagnose::hidden::{clean_tracker, hidden_tracker};
    use crate::diagnose::{diagnose, DiagnoseOptions};
    let opts = DiagnoseOptions::new(crate::calib::pipeline::ModelSpec::nominal(Robot::irb120(), crate::calib::pipeline::Parametrisation::Hayati));
    let strip =
        |g: crate::sim::generate::Generated| Dataset { rows: g.dataset.rows.into_iter().map(|r| Row { split: None, ..r }).collect(), source: g.dataset.source };
    let (s, robot, truth, sigma) = hidden_tracker(50_001, 0.5..0.6).unwrap();
    let data = strip(crate::sim::generate::generate(&s, &robot, &crate::sim::generate::Silent).unwrap());
    assert!(data.rows.iter().all(|r| r.std_mm.is_some()), "the rows carry sx, sy, sz");
    let (d, _) = diagnose(&data, &opts, &|_| {}).unwrap();
    assert!((d.noise_floor_mm / sigma - 1.0).abs() < 0.05, "floor {} against the rows' noise {sigma}", d.noise_floor_mm);
    let first = d.causes.first().unwrap_or_else(|| panic!("nothing named: {} {:?}", d.verdict, d.steps.last().map(|s| &s.kept)));
    assert!(truth[0].named_by(first) && truth[0].sized_by(first), "{truth:?} -> {}", first.summary());
    let (s, robot) = clean_tracker(40_001).unwrap();
    let (d, _) = diagnose(&strip(crate::sim::generate::generate(&s, &robot, &crate::sim::generate::Silent).unwrap()), &opts, &|_| {}).unwrap();
    assert!(d.causes.is_empty(), "false alarm: {}", d.verdict);
}
