//! `twincal bench`: checks the options against the target and runs the benchmark in
//! `crate::bench`.

use super::*;

/// `twincal bench TARGET`: checks that every option given applies to the target, then runs it.
#[allow(clippy::too_many_arguments)]
pub fn bench_command(
    what: BenchTarget,
    scenario: Option<&Path>,
    repeat: usize,
    seeds: Option<u64>,
    compare: bool,
    categories: &[String],
    shard: &ShardArgs,
    quiet: bool,
) -> Result<()> {
    check_repeat(repeat)?;
    if !categories.is_empty() && what != BenchTarget::Diagnose {
        return Err(Error::Invalid("--categories applies to bench diagnose".into()));
    }
    if (shard.shard.is_some() || shard.shard_out.is_some()) && what != BenchTarget::Diagnose {
        return Err(Error::Invalid("--shard and --shard-out apply to bench diagnose (and to compare and study hold)".into()));
    }
    match what {
        BenchTarget::Twin => {
            if seeds.is_some() {
                return Err(Error::Invalid("--seeds applies to bench calib, not bench twin".into()));
            }
            if compare {
                return Err(Error::Invalid("--compare applies to bench calib, not bench twin".into()));
            }
            let (s, robot) = load_scenario(scenario)?;
            crate::bench::twin::bench_twin(&s, &robot, repeat, quiet)
        }
        BenchTarget::Calib => {
            if scenario.is_some() {
                return Err(Error::Invalid("--scenario applies to bench twin; bench calib uses the embedded irb120_geometric scenario".into()));
            }
            let seeds = seeds.unwrap_or(20);
            check_seeds(seeds)?;
            // The full method comparison is the `compare` command on one of the benchmark's datasets.
            let run_compare = |dir: &Path| -> Result<()> {
                let args = CompareArgs {
                    data: dir.to_path_buf(),
                    angles: AngleArg::Deg,
                    reading: ReadingArgs::default(),
                    methods: ["lm", "ekf", "pf", "pso", "rbf"].map(String::from).to_vec(),
                    seeds: 30,
                    model: ModelArgs { model: "irb120".into(), params: None },
                    test_fraction: None,
                    effort: 1.0,
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
            if scenario.is_some() || compare {
                return Err(Error::Invalid("--scenario and --compare do not apply to bench diagnose".into()));
            }
            let seeds = seeds.unwrap_or(20);
            check_seeds(seeds)?;
            let config = crate::bench::diagnose::DetectionConfig::new(seeds, categories)?;
            let sh = crate::shard::from_options(shard.shard.as_deref(), shard.shard_out.as_deref(), false, "", &config, &[])?;
            crate::bench::diagnose::bench_diagnose(seeds, progress(quiet).as_ref(), sh.as_ref(), &config)
        }
        BenchTarget::Dsade | BenchTarget::Ik => {
            if scenario.is_some() || compare {
                return Err(Error::Invalid(
                    "--scenario and --compare do not apply to bench dsade / bench ik (they use the embedded irb120_evo_nph scenario)".into(),
                ));
            }
            if what == BenchTarget::Ik {
                if seeds.is_some() {
                    return Err(Error::Invalid("--seeds applies to bench dsade, not bench ik".into()));
                }
                return crate::bench::evo::bench_ik(repeat);
            }
            let seeds = seeds.unwrap_or(30);
            check_seeds(seeds)?;
            crate::bench::evo::bench_dsade(repeat, seeds)
        }
        BenchTarget::Awnn => {
            if scenario.is_some() || compare {
                return Err(Error::Invalid("--scenario and --compare do not apply to bench awnn (it uses the embedded irb120_pso_ekf scenario)".into()));
            }
            let seeds = seeds.unwrap_or(5);
            check_seeds(seeds)?;
            crate::bench::awnn::bench_awnn(repeat, seeds, quiet)
        }
        BenchTarget::Real => {
            if scenario.is_some() || compare {
                return Err(Error::Invalid("--scenario and --compare do not apply to bench real (it reads ../shared/data)".into()));
            }
            let seeds = seeds.unwrap_or(5);
            check_seeds(seeds)?;
            crate::bench::real::bench_real(seeds)
        }
        BenchTarget::DiagnoseUr10 => {
            if scenario.is_some() || compare || seeds.is_some() {
                return Err(Error::Invalid(
                    "--scenario, --compare and --seeds do not apply to bench diagnose-ur10 (it reads ../shared/data; --repeat runs)".into(),
                ));
            }
            crate::bench::real::bench_diagnose_ur10(repeat)
        }
        BenchTarget::NoiseModel => {
            if scenario.is_some() || compare {
                return Err(Error::Invalid("--scenario and --compare do not apply to bench noise-model (it generates realistic IRB 120 acquisitions)".into()));
            }
            let seeds = seeds.unwrap_or(5);
            check_seeds(seeds)?;
            crate::bench::noise::bench_noise_model(seeds)
        }
        BenchTarget::Replay => {
            if compare || seeds.is_some() {
                return Err(Error::Invalid("--compare and --seeds do not apply to bench replay (--scenario and --repeat do)".into()));
            }
            let (s, robot) = load_scenario(scenario)?;
            crate::bench::replay::bench_replay(&s, &robot, repeat)
        }
    }
}
