//! `twincal study`: hold-time and posture studies on the twin.

use super::*;

/// `twincal study` subjects.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum StudyTarget {
    /// Bias and spread of the readings against the hold time and the approach speed.
    Hold,
}

/// What a hold study is over: every shard of one study holds the same (its hash ties them).
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct HoldConfig {
    pub scenario: String,
    /// SHA-256 of the scenario and robot as loaded (what the results depend on).
    pub scenario_sha256: String,
    pub holds_s: Vec<f64>,
    pub speed_fractions: Vec<f64>,
    pub poses: usize,
    /// The lines above the table (the scenario's gate and noise).
    pub header: Vec<String>,
    /// Averaged reading noise, mm (the recording's reference line).
    pub floor_mm: f64,
    pub twincal_version: String,
}

impl crate::shard::Config for HoldConfig {
    const KIND: &'static str = "study-hold";
    fn hash(&self) -> String {
        twincal::dataset::truth::sha256_hex(serde_json::to_string(self).unwrap_or_default().as_bytes())
    }
    fn items(&self) -> u64 {
        (self.holds_s.len() * self.speed_fractions.len()) as u64
    }
}

/// One finished setting of a sharded hold study.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct HoldItem {
    pub row: twincal::sim::study::HoldStudyRow,
}

impl crate::shard::Item for HoldItem {
    fn check(&self) -> std::result::Result<(), String> {
        self.row.check()
    }
}

/// The options of `twincal study`.
#[derive(Clone, Debug, clap::Args)]
pub struct StudyArgs {
    #[arg(value_enum)]
    pub what: StudyTarget,
    /// Scenario TOML; default: the embedded irb120_evo_nph scenario.
    #[arg(long)]
    pub scenario: Option<PathBuf>,
    /// Hold times, s.
    #[arg(long, value_delimiter = ',', default_value = "0.02,0.05,0.1,0.2,0.5,1,2", allow_negative_numbers = true)]
    pub holds: Vec<f64>,
    /// Approach speeds, fractions of the URDF speed limits.
    #[arg(long, value_delimiter = ',', default_value = "0.05,0.2,0.5", allow_negative_numbers = true)]
    pub speeds: Vec<f64>,
    /// The first this many poses of the scenario's tour [default: 60].
    #[arg(long, allow_negative_numbers = true)]
    pub poses: Option<usize>,
    /// Rerun recording of bias and spread against the hold time.
    #[arg(long)]
    pub rrd: Option<PathBuf>,
    #[command(flatten)]
    pub shard: ShardArgs,
}

/// `twincal study hold`: the table on stdout, optionally a Rerun recording; with `shard`
/// (`i/N`) only that shard's settings (work item `id`: speed `id / holds`, hold `id % holds`),
/// appended to `shard_out` for `twincal reduce`. A scenario with fewer poses than `--poses`
/// asks for is said.
pub fn study(a: &StudyArgs, quiet: bool) -> Result<()> {
    let study = &twincal::sim::study::HoldStudy {
        holds_s: a.holds.clone(),
        speed_fractions: a.speeds.clone(),
        poses: a.poses.unwrap_or(twincal::sim::study::DEFAULT_POSES),
    };
    let (what, scenario, poses_given, rrd) = (a.what, a.scenario.as_deref(), a.poses.is_some(), a.rrd.as_deref());
    let (shard, shard_out) = (a.shard.shard.as_deref(), a.shard.shard_out.as_deref());
    use twincal::sim::study::{hold_setting, hold_study_at, study_poses};
    let StudyTarget::Hold = what;
    study.validate().map_err(Error::Invalid)?;
    let (s, robot) = load_scenario(scenario)?;
    let read = scenario_inputs(scenario, &s);
    if let Some(p) = rrd {
        check_outputs(&read, &[("--rrd", p)])?;
    }
    if poses_given && study.poses > s.sampling.poses {
        eprintln!("warning: --poses {}: scenario {} has {} poses; the study takes all {}", study.poses, s.name, s.sampling.poses, s.sampling.poses);
    }
    let poses = study_poses(&s, &robot, study)?;
    let floor = s.draw_wire.noise_std_mm / (s.draw_wire.samples as f64).sqrt();
    let noise = match s.instruments.active() {
        Some(i) => format!("{} per sample, {} samples averaged", i.noise(), s.draw_wire.samples),
        None => format!("averaged reading noise {:.2} µm", floor * 1e3),
    };
    let config = HoldConfig {
        scenario: s.name.clone(),
        scenario_sha256: twincal::dataset::truth::sha256_hex(format!("{s:?}{robot:?}").as_bytes()),
        holds_s: study.holds_s.clone(),
        speed_fractions: study.speed_fractions.clone(),
        poses: poses.len(),
        header: vec![
            format!("hold study ({}, first {} poses, readings taken even with the gate closed)", s.name, poses.len()),
            format!(
                "  damping ratio {}, gate: {} s windows within {} mm; {noise} (not included below)",
                s.acquisition.damping_ratio, s.acquisition.gate_window_s, s.acquisition.gate_mm,
            ),
        ],
        floor_mm: floor,
        twincal_version: env!("CARGO_PKG_VERSION").into(),
    };
    let inputs: Vec<(&str, &Path)> = read.iter().map(|(o, p)| (*o, p.as_path())).collect();
    if let Some(sh) = crate::shard::from_options(shard, shard_out, rrd.is_some(), "--rrd", &config, &inputs)? {
        let bar = progress(quiet);
        let mine: Vec<(u64, (f64, f64))> = study.settings().into_iter().enumerate().map(|(id, vh)| (id as u64, vh)).filter(|(id, _)| sh.wants(*id)).collect();
        bar.start((mine.len() * poses.len()) as u64, "hold study");
        for (id, (v, h)) in &mine {
            sh.append(*id, &config, &HoldItem { row: hold_setting(&s, &robot, &poses, *v, *h, bar.as_ref())? })?;
        }
        bar.finish();
        if !quiet {
            eprintln!("{}", sh.summary(mine.len()));
        }
        return Ok(());
    }
    let rows = hold_study_at(&s, &robot, study, &poses, progress(quiet).as_ref())?;
    finish_hold(&config, &rows, rrd, quiet)
}

/// The table and recording of a finished hold study: what `study hold` prints and writes, and
/// `reduce` the same from the shards' parts.
fn finish_hold(config: &HoldConfig, rows: &[twincal::sim::study::HoldStudyRow], rrd: Option<&Path>, quiet: bool) -> Result<()> {
    for line in &config.header {
        println!("{line}");
    }
    println!(
        "  {:>6} {:>8} {:>10} {:>11} {:>10} {:>12} {:>11} {:>9}",
        "speed", "hold s", "bias µm", "spread µm", "max µm", "gate closed", "gate s (med)", "s/pose"
    );
    for r in rows {
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
        twincal_viz::study::record_hold_study(rows, &config.scenario, config.floor_mm, &mut outputs, p)?;
        outputs.commit()?;
        if !quiet {
            eprintln!("  wrote {}", p.display());
        }
    }
    Ok(())
}

/// `twincal reduce` of a hold study's parts: the same table and recording as one run.
pub fn reduce_hold(parts: crate::shard::Parts, rrd: Option<&Path>, quiet: bool) -> Result<()> {
    let files = parts.files;
    let (config, items, duplicates) = parts.gather::<HoldConfig, HoldItem>()?;
    if !quiet {
        eprintln!(
            "reduced {files} parts: {} settings of hold study config {}, {duplicates} duplicates dropped",
            items.len(),
            &crate::shard::Config::hash(&config)[..12]
        );
    }
    let rows: Vec<_> = items.into_iter().map(|i| i.row).collect();
    finish_hold(&config, &rows, rrd, quiet)
}
