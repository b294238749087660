//! `twincal generate`: simulate a scenario and write its dataset and truth.

use super::*;

/// `twincal generate`.
pub fn generate(scenario: Option<&Path>, out: &Path, rrd: Option<&Path>, seed: Option<u64>, poses: Option<&Path>, quiet: bool) -> Result<()> {
    if out.exists() && !out.is_dir() {
        return Err(Error::Invalid(format!("--out {} is a file; generate writes a folder (dataset.csv, truth.json)", out.display())));
    }
    let dataset = out.join(twincal::dataset::DATASET_FILE);
    let truth = out.join(twincal::dataset::truth::TRUTH_FILE);
    let mut outputs_named = vec![("--out", dataset.as_path()), ("--out", truth.as_path())];
    if let Some(p) = rrd {
        outputs_named.push(("--rrd", p));
    }
    let (mut s, robot) = load_scenario(scenario)?;
    if (s.sockets.is_some() || s.planes.is_some()) && poses.is_none() {
        if let Some(seed) = seed {
            s.seed = seed;
        }
        return seat(&s, &robot, scenario, out, rrd, quiet);
    }
    let mut read = scenario_inputs(scenario, &s);
    read.extend(poses.map(|p| ("--poses", p.to_path_buf())));
    check_outputs(&read, &outputs_named)?;
    if let Some(seed) = seed {
        s.seed = seed;
    }
    let t0 = Instant::now();
    let g = match poses {
        None => run_generate(&s, &robot, progress(quiet).as_ref())?,
        Some(p) => {
            // The listed poses, in their order, every one a training row.
            let list = twincal::sim::pose_list::read_pose_list(p, &robot)?;
            twincal::sim::pose_list::generate_pose_list(&s, &robot, list, progress(quiet).as_ref())?
        }
    };
    let elapsed = t0.elapsed().as_secs_f64();
    let mut outputs = OutputSet::new();
    if let Some(path) = rrd {
        twincal_viz::scenes::record_dataset(&g, &mut outputs, path)?;
    }
    stage_outputs(&g, out, &mut outputs)?;
    outputs.commit()?;
    for w in g.warnings() {
        eprintln!("warning: {w}");
    }
    if !quiet {
        summary(&g, out, elapsed, rrd);
    }
    Ok(())
}

fn summary(g: &Generated, out: &Path, elapsed: f64, rrd: Option<&Path>) {
    let t = &g.truth;
    let n = g.dataset.rows.len();
    let test = t.poses.iter().filter(|p| p.split == twincal::dataset::Split::Test).count();
    let steps: Vec<usize> = t.poses.iter().map(|p| p.settle_steps).collect();
    let mean_steps = steps.iter().sum::<usize>() as f64 / steps.len().max(1) as f64;
    eprintln!("scenario {} (seed {}): {n} poses ({} train / {test} test) in {elapsed:.2} s", t.scenario, t.seed, n - test);
    if let Some(tr) = &t.tracker {
        eprintln!("  read by a laser tracker (x, y, z in its frame): {:.4} mm per coordinate, averaged noise (RMS over the poses)", t.noise_std_mm);
        if tr.probe_rotation_deg.is_some() {
            let sd = tr.orientation_noise_urad / (g.twin.draw_wire.samples.max(1) as f64).sqrt();
            eprintln!(
                "  with a 6-D probe (rx, ry, rz: degrees, intrinsic X-Y-Z in the tracker's frame): {sd:.1} µrad per axis, averaged noise ({:.4} mm at the {} mm lever the model reads the axes at)",
                sd * 1e-6 * twincal::measurement::pose::LEVER_MM,
                twincal::measurement::pose::LEVER_MM
            );
        }
    }
    let acq: Vec<&twincal::sim::generate::PoseAcquisition> = t.poses.iter().filter_map(|p| p.acquisition.as_ref()).collect();
    if acq.is_empty() {
        let slow = t.poses.iter().filter(|p| p.settle_time_s > g.twin.draw_wire.hold_s).count();
        eprintln!("  mean settle steps per pose: {mean_steps:.0}; poses still moving after the {} s hold: {slow}", g.twin.draw_wire.hold_s);
    } else {
        // The simulated tour: rapier steps per pose, and how the stability gate and the transient fared.
        let closed = acq.iter().filter(|a| a.gate_s.is_none()).count();
        let worst = acq.iter().map(|a| a.transient_mm.abs()).fold(0.0f64, f64::max);
        let of = if g.twin.instruments.active().is_some() { "at the tool" } else { "in L" };
        eprintln!(
            "  simulated tour: {mean_steps:.0} rapier steps per pose; gate still closed after the {} s hold: {closed} read anyway; largest transient {of} {worst:.1e} mm",
            g.twin.draw_wire.hold_s
        );
    }
    if !t.rejected.is_empty() {
        eprintln!("  {} poses rejected (listed in truth.json):", t.rejected.len());
        for r in t.rejected.iter().take(5) {
            eprintln!("    pose {}: {}", r.index, r.reason);
        }
    }
    eprintln!("  wrote {}/dataset.csv and {}/truth.json", out.display(), out.display());
    if let Some(p) = rrd {
        eprintln!("  wrote {}", p.display());
    }
}

/// `twincal generate` of a scenario with an artifact (`[sockets]`, `[planes]`): the ball seated
/// in the sockets or the probe touching the faces, dataset.csv (joint angles, socket or plane,
/// placement, t, split; an indicator's reading) and the truth (sockets.json, planes.json).
fn seat(
    s: &twincal::sim::scenario::Scenario,
    robot: &twincal::robot::Robot,
    scenario: Option<&Path>,
    out: &Path,
    rrd: Option<&Path>,
    quiet: bool,
) -> Result<()> {
    if rrd.is_some() {
        return Err(Error::Invalid(
            "--rrd records a tour of the instrument's readings; an artifact scenario's recording is not written yet (drop --rrd)".into(),
        ));
    }
    let dataset = out.join(twincal::dataset::DATASET_FILE);
    let mut files = Vec::new();
    if s.sockets.is_some() {
        files.push(out.join(twincal::sim::artifact::SOCKETS_TRUTH_FILE));
    }
    if s.planes.is_some() {
        files.push(out.join(twincal::sim::planes::PLANES_TRUTH_FILE));
    }
    let mut checked = vec![("--out", dataset.as_path())];
    checked.extend(files.iter().map(|f| ("--out", f.as_path())));
    check_outputs(&scenario_inputs(scenario, s), &checked)?;
    let t0 = Instant::now();
    let a = twincal::sim::generate::artifact_rows(s, robot).expect("an artifact scenario")?;
    let data = &a.dataset;
    let mut outputs = OutputSet::new();
    outputs.write(&dataset, data.to_csv_string().as_bytes())?;
    for (name, value) in &a.truths {
        outputs.write_json(&out.join(name), value)?;
    }
    outputs.commit()?;
    if !quiet {
        let test = data.rows.iter().filter(|r| r.split == Some(twincal::dataset::Split::Test)).count();
        eprintln!(
            "scenario {} (seed {}): {}, {} rows ({} train / {test} test) in {:.2} s; {} configurations out of reach redrawn",
            s.name,
            s.seed,
            a.what,
            data.rows.len(),
            data.rows.len() - test,
            t0.elapsed().as_secs_f64(),
            a.unreachable
        );
        let n_spacings = s.sockets.as_ref().map_or(0, |k| k.designed_spacings_mm().len());
        for (k, (x, y, d)) in a.designed.iter().enumerate() {
            let word = if k < n_spacings { "spacing" } else { "step" };
            eprintln!("  {word} {x}:{y} designed {d:.3} mm (state it with calibrate --spacing-mm {x}:{y}={d})");
        }
        let wrote: Vec<String> = std::iter::once(&dataset).chain(&files).map(|p| p.display().to_string()).collect();
        eprintln!("  wrote {}", wrote.join(" and "));
    }
    Ok(())
}
