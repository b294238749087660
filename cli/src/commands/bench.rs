//! `twincal bench`: checks the options against the target and runs the benchmark in
//! `crate::bench`.

use super::*;

/// The options of `twincal bench`.
#[derive(Clone, Debug, clap::Args)]
pub struct BenchArgs {
    #[arg(value_enum, default_value_t = BenchTarget::Twin)]
    pub what: BenchTarget,
    /// twin, replay: scenario TOML (default: the embedded one).
    #[arg(long)]
    pub scenario: Option<PathBuf>,
    /// Repetitions, 1 to 1000 (the median is reported).
    #[arg(long, default_value_t = 3, allow_negative_numbers = true)]
    pub repeat: usize,
    /// calib: number of seeds for the accuracy targets, 1 to 1000 (default 20).
    #[arg(long, allow_negative_numbers = true)]
    pub seeds: Option<u64>,
    /// calib: also time `compare` over 30 seeds with every method.
    #[arg(long)]
    pub compare: bool,
    /// diagnose: only these kinds of scenario (hidden, clean, realistic-1-clean,
    /// realistic-1-above, realistic-1-below, and the same with 2 for 0.01 deg logging).
    #[arg(long, value_delimiter = ',')]
    pub categories: Vec<String>,
    #[command(flatten)]
    pub shard: ShardArgs,
}

/// `twincal bench TARGET`: checks that every option given applies to the target, then runs it.
pub fn bench_command(a: &BenchArgs, quiet: bool) -> Result<()> {
    let (what, scenario, repeat, seeds, compare, categories, shard) =
        (a.what, a.scenario.as_deref(), a.repeat, a.seeds, a.compare, &a.categories[..], &a.shard);
    check_repeat(repeat)?;
    if !categories.is_empty() && what != BenchTarget::Diagnose {
        return Err(Error::Invalid("--categories applies to bench diagnose".into()));
    }
    if (shard.shard.is_some() || shard.shard_out.is_some()) && what != BenchTarget::Diagnose {
        return Err(Error::Invalid("--shard and --shard-out apply to bench diagnose (and to compare and study hold)".into()));
    }
    check_applies(what, scenario.is_some(), compare, seeds.is_some())?;
    let seeds = takes(what).seeds.map(|default| seeds.unwrap_or(default));
    if let Some(n) = seeds {
        check_seeds(n)?;
    }
    let seeds = seeds.unwrap_or(0);
    match what {
        BenchTarget::Twin => {
            let (s, robot) = load_scenario(scenario)?;
            crate::bench::twin::bench_twin(&s, &robot, repeat, quiet)
        }
        BenchTarget::Calib => {
            // The full method comparison is the `compare` command on one of the benchmark's datasets.
            let run_compare = |dir: &Path| -> Result<()> {
                let args = CompareJob {
                    data: dir.to_path_buf(),
                    request: CompareRequest { reading: Reading { angles: AngleUnit::Deg, ..Reading::default() }, ..CompareRequest::default() },
                    out: None,
                    rrd: None,
                    shard: None,
                    shard_out: None,
                };
                super::compare(&args, true)
            };
            crate::bench::calib::bench_calib(repeat, seeds, compare.then_some(&run_compare as crate::bench::calib::OnDataset))
        }
        BenchTarget::Diagnose => {
            let config = crate::bench::diagnose::DetectionConfig::new(seeds, categories)?;
            let sh = crate::shard::from_options(shard.shard.as_deref(), shard.shard_out.as_deref(), false, "", &config, &[])?;
            crate::bench::diagnose::bench_diagnose(seeds, repeat, progress(quiet).as_ref(), sh.as_ref(), &config)
        }
        BenchTarget::Dsade => crate::bench::evo::bench_dsade(repeat, seeds),
        BenchTarget::Ik => crate::bench::evo::bench_ik(repeat),
        BenchTarget::Awnn => crate::bench::awnn::bench_awnn(repeat, seeds, quiet),
        BenchTarget::Real => crate::bench::real::bench_real(seeds),
        BenchTarget::DiagnoseUr10 => crate::bench::real::bench_diagnose_ur10(repeat),
        BenchTarget::NoiseModel => crate::bench::noise::bench_noise_model(seeds),
        BenchTarget::Replay => {
            let (s, robot) = load_scenario(scenario)?;
            crate::bench::replay::bench_replay(&s, &robot, repeat)
        }
        BenchTarget::Compensate => crate::bench::compensate::bench_compensate(seeds),
        BenchTarget::Programs => crate::bench::programs::bench_programs(seeds, repeat),
        BenchTarget::Plan => crate::bench::plan::bench_plan(seeds, repeat),
        BenchTarget::PlanHidden => crate::bench::plan::hidden(seeds),
        BenchTarget::Stations => crate::bench::stations::bench_stations(seeds),
        BenchTarget::Sockets => crate::bench::sockets::bench_sockets(seeds),
        BenchTarget::Planes => crate::bench::planes::bench_planes(seeds),
    }
}

/// What a benchmark target takes beyond `--repeat`.
struct Takes {
    scenario: bool,
    compare: bool,
    /// `--seeds` and its default; None: the target takes no `--seeds`.
    seeds: Option<u64>,
    /// What the target runs on, for the error naming an option it does not take.
    runs_on: &'static str,
}

fn takes(what: BenchTarget) -> Takes {
    let t = |scenario, compare, seeds, runs_on| Takes { scenario, compare, seeds, runs_on };
    match what {
        BenchTarget::Twin => t(true, false, None, "a scenario, the embedded one by default"),
        BenchTarget::Calib => t(false, true, Some(20), "the embedded irb120_geometric scenario"),
        BenchTarget::Diagnose => t(false, false, Some(20), "hidden-effect scenarios over seeds; --repeat runs of the speed"),
        BenchTarget::Dsade => t(false, false, Some(30), "the embedded irb120_evo_nph scenario"),
        BenchTarget::Ik => t(false, false, None, "the embedded irb120_evo_nph scenario"),
        BenchTarget::Awnn => t(false, false, Some(5), "the embedded irb120_pso_ekf scenario"),
        BenchTarget::Real => t(false, false, Some(5), "../shared/data"),
        BenchTarget::DiagnoseUr10 => t(false, false, None, "../shared/data; --repeat runs"),
        BenchTarget::NoiseModel => t(false, false, Some(5), "realistic IRB 120 acquisitions it generates"),
        BenchTarget::Replay => t(true, false, None, "a scenario; --repeat runs"),
        BenchTarget::Compensate => t(false, false, Some(10), "IRB 120 cable and tracker scenarios, with and without compliance"),
        BenchTarget::Programs => {
            t(false, false, Some(10), "IRB 120, UR10 and KUKA-like tracker scenarios, with and without compliance; --repeat runs of the speed")
        }
        BenchTarget::Plan => t(false, false, Some(10), "IRB 120 tracker and cable scenarios; --repeat runs of the speed"),
        BenchTarget::PlanHidden => t(false, false, Some(10), "the IRB 120 tracker scenario with compliance hidden"),
        BenchTarget::Stations => t(false, false, Some(20), "IRB 120 point and UR10 pose tracker scenarios with the tracker moved"),
        BenchTarget::Sockets => t(false, false, Some(10), "the IRB 120 ball-in-socket scenario, judged on its tracker's points"),
        BenchTarget::Planes => t(false, false, Some(10), "IRB 120, UR10 and WAM touch-probe scenarios, judged on their trackers' points"),
    }
}

/// Refuses `--scenario`, `--compare` or `--seeds` given to a target that does not take it,
/// naming the targets that do.
fn check_applies(what: BenchTarget, scenario: bool, compare: bool, seeds: bool) -> Result<()> {
    use clap::ValueEnum;
    let name = |t: &BenchTarget| t.to_possible_value().map(|v| v.get_name().to_string()).unwrap_or_default();
    type Taken = fn(&Takes) -> bool;
    let options: [(&str, bool, Taken); 3] =
        [("--scenario", scenario, |t| t.scenario), ("--compare", compare, |t| t.compare), ("--seeds", seeds, |t| t.seeds.is_some())];
    for (option, given, taken) in options {
        if given && !taken(&takes(what)) {
            let targets: Vec<String> = BenchTarget::value_variants().iter().filter(|t| taken(&takes(**t))).map(name).collect();
            return Err(Error::Invalid(format!(
                "{option} applies to bench {}, not bench {} (it runs on {})",
                targets.join(", "),
                name(&what),
                takes(what).runs_on
            )));
        }
    }
    Ok(())
}
