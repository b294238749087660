//! `twincal bench twin`: the simulated tour's speed and determinism, where its time goes, and
//! how its settled poses and flanks agree with the quasi-static model and the flank rule.

use std::time::Instant;
use twincal::error::{Error, Result};
use twincal::robot::Robot;
use twincal::sim::generate::Silent;
use twincal::sim::scenario::Scenario;
use twincal::stats::median;

/// Rapier's settled poses against the quasi-static model's over the same commands.
#[derive(Clone, Debug, PartialEq)]
pub struct TwinAgreement {
    pub poses: usize,
    /// Largest tool-point distance, mm.
    pub worst_tool_mm: f64,
    /// Poses whose backlash contact states differ.
    pub contact_differs: usize,
}

/// Settles every command with rapier and with the quasi-static model and compares the results.
pub fn twin_agreement(twin: &twincal::sim::twin::Twin, cmds: &[twincal::sim::twin::PoseCommand]) -> Result<TwinAgreement> {
    use rayon::prelude::*;
    let per: Vec<Result<(f64, bool)>> = cmds
        .par_iter()
        .map(|c| {
            let sim = twin.simulate(c)?;
            let qs = twin.quasi_static(c);
            Ok(((sim.tool - qs.tool).norm() * 1e3, sim.contact != qs.contact))
        })
        .collect();
    let per: Vec<(f64, bool)> = per.into_iter().collect::<Result<_>>()?;
    Ok(TwinAgreement {
        poses: per.len(),
        // `simulate` refuses a diverged (non-finite) pose, so every distance here is finite.
        worst_tool_mm: per.iter().map(|(d, _)| *d).fold(0.0, f64::max),
        contact_differs: per.iter().filter(|(_, c)| *c).count(),
    })
}

/// Flanks of a simulated tour against the load/approach rule, per joint and pose.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct FlankCheck {
    /// Static load above twice the breakaway: the load decides the flank.
    pub loaded_agree: usize,
    pub loaded_differ: usize,
    /// Load below the breakaway: the rule says the approach flank; the motion (deceleration,
    /// loads along the way) may leave the link elsewhere, so differences are not errors.
    pub unloaded_agree: usize,
    pub unloaded_differ: usize,
    /// Joints left inside their band by friction.
    pub free: usize,
}

/// Compares the flank each joint of `acquired` rests on with the rule (`breakaway` in N·m).
pub fn flank_check(acquired: &[twincal::sim::twin::tour::Acquired], breakaway: f64) -> FlankCheck {
    use twincal::sim::effects::statics::Contact;
    let mut c = FlankCheck::default();
    for a in acquired {
        for (j, contact) in a.rest.contact.iter().enumerate() {
            let tau = a.rest.torque[j];
            let side = match contact {
                Contact::Positive => 1.0,
                Contact::Negative => -1.0,
                Contact::Held => {
                    // Held against the load on the flank opposite to it.
                    -tau.signum()
                }
                Contact::Free => {
                    c.free += 1;
                    continue;
                }
                Contact::Spring => continue,
            };
            if tau.abs() > 2.0 * breakaway {
                if side == tau.signum() {
                    c.loaded_agree += 1;
                } else {
                    c.loaded_differ += 1;
                }
            } else if tau.abs() < breakaway {
                if side == a.rule_sides[j] {
                    c.unloaded_agree += 1;
                } else {
                    c.unloaded_differ += 1;
                }
            }
        }
    }
    c
}

/// Rapier steps and seconds per phase of the tour, summed over its poses.
fn phase_totals(tour: &[twincal::sim::twin::tour::Acquired]) -> ([usize; 5], [f64; 5]) {
    let mut steps = [0usize; 5];
    let mut secs = [0.0f64; 5];
    for a in tour {
        for k in 0..5 {
            steps[k] += a.stats.steps[k];
            secs[k] += a.stats.seconds[k];
        }
    }
    (steps, secs)
}

/// Where the time of the one-thread tour (`t_seq` s, `n` poses) goes, phase by phase.
fn print_phases(steps: &[usize; 5], secs: &[f64; 5], n: usize, t_seq: f64) {
    let (total_steps, in_phases): (usize, f64) = (steps.iter().sum(), secs.iter().sum());
    println!("  where the time goes (1 thread, {:.2} µs per step):", in_phases / total_steps.max(1) as f64 * 1e6);
    for k in 0..5 {
        println!("    {:22} {:6.0} steps/pose  {:5.1} % of the time", twincal::sim::twin::tour::PHASES[k], steps[k] as f64 / n as f64, 100.0 * secs[k] / t_seq);
    }
    println!("    {:22} {:>17}  {:5.1} % (chunk set-up, readings, gate, truth)", "outside steps", "", 100.0 * (t_seq - in_phases).max(0.0) / t_seq);
}

/// The robot time the scenario's acquisition takes over `poses` (s): the last reading's time
/// and half a window.
fn robot_time(s: &Scenario, robot: &Robot, home: &[f64], poses: &[Vec<f64>]) -> f64 {
    let sc = twincal::sim::twin::tour::Schedule::new(robot, &s.timing(), home, poses, None);
    sc.read_t.last().copied().unwrap_or(0.0) + 0.5 * s.draw_wire.window_s()
}

/// `twincal bench twin`: the simulated tour (the scenario's `[acquisition]` settings, simulated
/// whatever its model) timed in parallel and on one thread (the two must agree bit for bit), its
/// steps per pose and where the time goes, its readings against the quasi-static model and its
/// flanks against the rule; then the per-pose settled model and the quasi-static model as
/// baselines, with the settled poses' agreement with the quasi-static model.
pub fn bench_twin(s: &Scenario, robot: &Robot, repeat: usize, quiet: bool) -> Result<()> {
    use rayon::prelude::*;
    use twincal::sim::generate::{acquisition_times, build_twin, sample_poses};
    use twincal::sim::twin::tour::{acquire, Acquired};
    use twincal::sim::twin::{approach_sides, PoseCommand};
    let twin = build_twin(s, robot);
    let poses = sample_poses(s, robot)?;
    let n = poses.len();
    let threads = rayon::current_num_threads();
    if !quiet {
        eprintln!("bench: scenario {}, {n} poses, {threads} threads, {repeat} repetitions (medians reported)", s.name);
    }
    let home = vec![0.0; robot.dof()];
    let settings = twincal::sim::twin::tour::TourSettings { seed: s.seed, speed_fraction: s.sampling.speed_fraction };
    let tour = || -> Result<Vec<Acquired>> { acquire(&twin, &s.acquisition, settings, &home, &poses, None, &Silent).into_iter().collect() };
    let time = |f: &dyn Fn() -> Result<()>| -> Result<f64> {
        let mut ts = Vec::new();
        for _ in 0..repeat {
            let t0 = Instant::now();
            f()?;
            ts.push(t0.elapsed().as_secs_f64());
        }
        Ok(median(&ts))
    };
    let t_par = time(&|| tour().map(|_| ()))?;
    let one = rayon::ThreadPoolBuilder::new().num_threads(1).build().map_err(|e| Error::Invalid(format!("cannot start a thread pool: {e}")))?;
    let t0 = Instant::now();
    let seq = one.install(tour)?;
    let t_seq = t0.elapsed().as_secs_f64();
    let par = tour()?;
    let identical = seq.len() == par.len()
        && seq
            .iter()
            .zip(&par)
            .all(|(a, b)| a.lengths == b.lengths && a.gate_s == b.gate_s && a.rest.q_link == b.rest.q_link && a.rest.contact == b.rest.contact);
    let (steps, secs) = phase_totals(&seq);
    let total_steps: usize = steps.iter().sum();
    let worst_transient = seq.iter().map(|a| a.transient_mm.abs()).fold(0.0, f64::max);
    let closed = seq.iter().filter(|a| a.gate_s.is_none()).count();
    let flanks = flank_check(&seq, twin.transmission.as_ref().map(|t| t.breakaway).unwrap_or(0.0));
    let sim_time = robot_time(s, robot, &home, &poses);

    // Baselines: the per-pose settled model and the quasi-static model, flanks from the rule.
    let times = acquisition_times(s, robot, &poses);
    let sides = approach_sides(&home, &poses);
    let cmds: Vec<PoseCommand> = (0..n).map(|i| PoseCommand { q_cmd: poses[i].clone(), sides: sides[i].clone(), t: times[i] }).collect();
    let t_qs = time(&|| {
        for c in &cmds {
            std::hint::black_box(twin.quasi_static(c));
        }
        Ok(())
    })?;
    let t0 = Instant::now();
    let settled: Vec<usize> = cmds.par_iter().map(|c| twin.simulate(c).map(|r| r.steps)).collect::<Result<_>>()?;
    let t_settled = t0.elapsed().as_secs_f64();
    let agree = twin_agreement(&twin, &cmds)?;

    println!("twin benchmark ({}, {n} poses, {threads} threads)", s.name);
    println!("  simulated tour, parallel : {t_par:8.3} s  = {:8.1} poses/s   (target: {n} poses < 5 s)", n as f64 / t_par);
    println!(
        "  simulated tour, 1 thread : {t_seq:8.3} s  (parallel speed-up {:.2}x); same bytes as the parallel run: {}",
        t_seq / t_par,
        if identical { "yes" } else { "NO" }
    );
    println!(
        "  simulated acquisition    : {sim_time:.0} s of robot time ({:.2} s per pose), {:.0} rapier steps per pose",
        sim_time / n as f64,
        total_steps as f64 / n as f64
    );
    print_phases(&steps, &secs, n, t_seq);
    println!(
        "  tour vs quasi-static on the flanks the motion left: worst |transient in L| {worst_transient:.1e} mm over {n} poses (target < 1e-3 mm); gate still closed at the end of the hold: {closed} poses"
    );
    println!(
        "  flanks vs the load/approach rule: loaded joints (|τ| > 2 × breakaway) {} agree, {} differ; unloaded joints (|τ| < breakaway) {} on the approach flank, {} elsewhere (deceleration, loads along the move); {} inside the band",
        flanks.loaded_agree, flanks.loaded_differ, flanks.unloaded_agree, flanks.unloaded_differ, flanks.free
    );
    println!(
        "  settled poses (one world per pose), parallel: {t_settled:8.3} s, {:.0} settle steps per pose (4 substeps each)",
        settled.iter().sum::<usize>() as f64 / n as f64
    );
    println!("  quasi-static baseline    : {t_qs:8.3} s  = {:8.1} poses/s   (the tour costs {:.0}x the quasi-static model)", n as f64 / t_qs, t_par / t_qs);
    println!(
        "  rapier vs quasi-static: worst tool-point difference {:.1e} mm over {} poses (target < 1e-3 mm); backlash contacts differ in {} poses",
        agree.worst_tool_mm, agree.poses, agree.contact_differs
    );
    if t_par.is_nan() {
        return Err(Error::Invalid("benchmark produced no timing".into()));
    }
    if !identical {
        return Err(Error::Simulation("the tour on one thread differs from the parallel run".into()));
    }
    Ok(())
}
