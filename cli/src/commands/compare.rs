//! `twincal compare` and `twincal reduce`: the library's comparison job, its table on stdout and
//! its warnings on stderr; `reduce` joins the parts of any sharded study.

use super::*;
use twincal::jobs::shard::Parts;
use twincal::jobs::{Compared, Comparison};

/// `twincal compare`: every method on every seed (a fresh stratified split per seed), then the
/// accuracy / time table and Wilcoxon signed-rank tests of each method against the first one,
/// across seeds (test RMSE) and per sample (|test residual| of seed 0).
pub fn compare(a: &CompareJob, quiet: bool) -> Result<()> {
    match twincal::jobs::compare(a, progress(quiet).as_ref(), &twincal_viz::Rerun)? {
        Compared::Done(c) => print_comparison(c)?,
        Compared::Shard(line) if !quiet => eprintln!("{line}"),
        Compared::Shard(_) => {}
    }
    Ok(())
}

/// The table on stdout, each calibration's warnings on stderr, then the outputs written (none
/// when the table could not be shown).
fn print_comparison(c: Comparison) -> Result<()> {
    println!("{}", c.table);
    for w in &c.warnings {
        eprintln!("warning: {w}");
    }
    c.outputs.commit()
}

/// `twincal reduce PARTS...`: the shards' partial files of one study joined, checked (one
/// configuration; every item exactly once once retries' duplicates are dropped) and rendered as
/// the single-process run renders them: a comparison's table, `--out` and `--rrd`; a hold
/// study's table; a detection benchmark's lines and rates.
pub fn reduce(parts: &[PathBuf], out: Option<&Path>, rrd: Option<&Path>, quiet: bool) -> Result<()> {
    if parts.is_empty() {
        return Err(Error::Invalid("reduce needs the shards' partial files (twincal reduce PART...)".into()));
    }
    let outs: Vec<(&str, &Path)> = out.map(|p| ("--out", p)).into_iter().chain(rrd.map(|p| ("--rrd", p))).collect();
    check_outputs(&parts.iter().map(|p| ("PART", p.as_path())).collect::<Vec<_>>(), &outs)?;
    let read = Parts::read(parts)?;
    match read.kind() {
        "compare" => {}
        "study-hold" if out.is_some() => {
            return Err(Error::Invalid("--out applies to compare's parts; a hold study's reduce prints its table (and writes --rrd)".into()))
        }
        "study-hold" => return super::study::reduce_hold(read, rrd, quiet),
        "bench-diagnose" if out.is_some() || rrd.is_some() => {
            return Err(Error::Invalid("bench diagnose's reduce prints its lines and rates; --out and --rrd apply to compare's parts".into()))
        }
        "bench-diagnose" => return crate::bench::diagnose::reduce_detection(read, quiet),
        k => return Err(Error::Invalid(format!("the parts are of a study twincal does not know ('{k}'): written by another twincal version?"))),
    }
    let (c, items, duplicates, hash) = twincal::jobs::reduce_compare(read, out, rrd, &twincal_viz::Rerun)?;
    if !quiet {
        eprintln!("reduced {} parts: {items} items of config {}, {duplicates} duplicates dropped", parts.len(), &hash[..12]);
    }
    print_comparison(c)
}
