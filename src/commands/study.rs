//! `twincal study`: hold-time and posture studies on the twin.

use super::*;

/// `twincal study` subjects.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum StudyTarget {
    /// Bias and spread of the readings against the hold time and the approach speed.
    Hold,
}

/// `twincal study hold`: the table on stdout, optionally a Rerun recording.
/// `poses_given`: whether the user chose `study.poses` (a scenario with fewer is then said).
pub fn study(
    what: StudyTarget,
    scenario: Option<&Path>,
    study: &crate::sim::twin::study::HoldStudy,
    poses_given: bool,
    rrd: Option<&Path>,
    quiet: bool,
) -> Result<()> {
    let StudyTarget::Hold = what;
    study.validate().map_err(Error::Invalid)?;
    let (s, robot) = load_scenario(scenario)?;
    if let Some(p) = rrd {
        let read = scenario_inputs(scenario, &s);
        check_outputs(&read, &[("--rrd", p)])?;
    }
    if poses_given && study.poses > s.sampling.poses {
        eprintln!("warning: --poses {}: scenario {} has {} poses; the study takes all {}", study.poses, s.name, s.sampling.poses, s.sampling.poses);
    }
    let rows = crate::sim::twin::study::hold_study(&s, &robot, study, progress(quiet).as_ref())?;
    let floor = s.sensor.noise_std_mm / (s.sensor.samples as f64).sqrt();
    let noise = match &s.tracker {
        // A tracker's noise grows with the distance: stated per sample, then averaged.
        Some(t) => format!("tracker noise {} µm + {} µm/m per sample, {} samples averaged", t.noise_um, t.noise_um_per_m, s.sensor.samples),
        None => format!("averaged reading noise {:.2} µm", floor * 1e3),
    };
    println!("hold study ({}, first {} poses, readings taken even with the gate closed)", s.name, rows.first().map(|r| r.poses).unwrap_or(0));
    println!(
        "  damping ratio {}, gate: {} s windows within {} mm; {noise} (not included below)",
        s.acquisition.damping_ratio, s.acquisition.gate_window_s, s.acquisition.gate_mm,
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
