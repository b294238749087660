//! Causes that vary with time judged on what comes later: rolling-origin folds over each run of
//! the acquisition (train on every row before an origin, judge the stretch after it), beside the
//! blocked folds that interleave training and held-out stretches in time.
//!
//! A drift chosen on blocked folds may interpolate between training blocks on both sides of a
//! held-out one; a drift that has to hold tomorrow must predict rows after every row it was
//! fitted to. The rolling origins here sit at the same shares of every run (a run: rows between
//! pauses), so that each judged stretch is later than everything its fit saw in its run.

/// The origins, as shares of each run's rows: the fit of fold k sees every row before
/// `ORIGINS[k]` of its run and is judged on the rows up to the next origin (the last fold to the
/// run's end), so the later half of every run is judged, each stretch by a fit on all before it.
pub const ORIGINS: [f64; 4] = [0.5, 0.625, 0.75, 0.875];

/// A pause that starts a new run: a gap in `t` longer than this many times the median step
/// between rows, and at least [`MIN_PAUSE_S`].
pub const PAUSE_STEPS: f64 = 20.0;
/// See [`PAUSE_STEPS`], s.
pub const MIN_PAUSE_S: f64 = 600.0;

/// Fewest rows a judged stretch or its training rows may hold for the folds to be built.
const MIN_ROWS: usize = 20;

/// Rolling-origin folds over the selection rows and the runs they come from.
#[derive(Clone, Debug, Default)]
pub struct Forward {
    /// (training rows, judged rows) of each origin.
    pub folds: Vec<(Vec<usize>, Vec<usize>)>,
    /// How many runs the rows split into.
    pub runs: usize,
    /// Duration of the longest run, s (0 without a time column: order is time).
    pub longest_run_s: f64,
    /// Whether time comes from the rows' `t` (else from their order).
    pub timed: bool,
}

impl Forward {
    /// The rolling-origin folds over rows with times `t` (`None` for every row: the rows' order
    /// is their time) and blocks `groups` (a block that straddles an origin goes to the side its
    /// first row is on); `None` where the later stretches would hold fewer than [`MIN_ROWS`].
    pub fn over(t: &[Option<f64>], groups: Option<&[usize]>) -> Option<Forward> {
        let n = t.len();
        let timed = n > 0 && t.iter().all(Option::is_some);
        let time: Vec<f64> = if timed { t.iter().map(|v| v.unwrap_or(0.0)).collect() } else { (0..n).map(|i| i as f64).collect() };
        let mut order: Vec<usize> = (0..n).collect();
        order.sort_by(|&a, &b| time[a].total_cmp(&time[b]).then(a.cmp(&b)));
        let runs = split_runs(&order, &time, timed);
        // Each row's share of its run, taken at its block's first row.
        let mut share = vec![0.0; n];
        for run in &runs {
            for (r, &i) in run.iter().enumerate() {
                share[i] = r as f64 / run.len() as f64;
            }
        }
        if let Some(g) = groups {
            let mut first: std::collections::HashMap<usize, f64> = std::collections::HashMap::new();
            for &i in &order {
                first.entry(g[i]).or_insert(share[i]);
            }
            share = (0..n).map(|i| first[&g[i]]).collect();
        }
        let folds: Vec<(Vec<usize>, Vec<usize>)> = ORIGINS
            .iter()
            .enumerate()
            .map(|(k, &o)| {
                let end = ORIGINS.get(k + 1).copied().unwrap_or(f64::INFINITY);
                let train = (0..n).filter(|&i| share[i] < o).collect();
                let judged = (0..n).filter(|&i| share[i] >= o && share[i] < end).collect();
                (train, judged)
            })
            .collect();
        if folds.iter().any(|(tr, te)| tr.len() < MIN_ROWS || te.len() < MIN_ROWS) {
            return None;
        }
        let longest_run_s = if timed { runs.iter().map(|r| time[r[r.len() - 1]] - time[r[0]]).fold(0.0, f64::max) } else { 0.0 };
        Some(Forward { folds, runs: runs.len(), longest_run_s, timed })
    }

    /// The judged rows of every fold, in fold order (the rows a forward residual vector holds).
    pub fn judged_rows(&self) -> Vec<usize> {
        self.folds.iter().flat_map(|(_, te)| te.iter().copied()).collect()
    }
}

/// The rows (`order`: sorted by `time`) split at pauses ([`PAUSE_STEPS`]); one run without a
/// time column.
fn split_runs(order: &[usize], time: &[f64], timed: bool) -> Vec<Vec<usize>> {
    if !timed || order.len() < 2 {
        return vec![order.to_vec()];
    }
    let mut steps: Vec<f64> = order.windows(2).map(|w| time[w[1]] - time[w[0]]).collect();
    steps.sort_by(f64::total_cmp);
    let pause = (PAUSE_STEPS * steps[steps.len() / 2]).max(MIN_PAUSE_S);
    let mut runs = vec![vec![order[0]]];
    for w in order.windows(2) {
        if time[w[1]] - time[w[0]] > pause {
            runs.push(Vec::new());
        }
        runs.last_mut().expect("a run is open").push(w[1]);
    }
    runs
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_judged_row_comes_after_every_row_its_fit_saw_in_its_run() {
        // Two runs of 100 rows 10 s apart, a day between them, given out of order.
        let mut t: Vec<Option<f64>> = (0..100).map(|i| Some(i as f64 * 10.0)).chain((0..100).map(|i| Some(86_400.0 + i as f64 * 10.0))).collect();
        t.reverse();
        let f = Forward::over(&t, None).expect("folds");
        assert_eq!(f.runs, 2);
        assert!((f.longest_run_s - 990.0).abs() < 1e-9);
        let run_of = |i: usize| (t[i].unwrap() >= 86_400.0) as usize;
        for (train, judged) in &f.folds {
            for &j in judged {
                let latest = train.iter().filter(|&&i| run_of(i) == run_of(j)).map(|&i| t[i].unwrap()).fold(f64::MIN, f64::max);
                assert!(t[j].unwrap() > latest);
            }
        }
        // The later half of each run is judged, each row once.
        let mut judged = f.judged_rows();
        judged.sort_unstable();
        judged.dedup();
        assert_eq!(judged.len(), 100);
    }

    #[test]
    fn a_block_stays_on_one_side_of_an_origin() {
        let t: Vec<Option<f64>> = (0..400).map(|i| Some(i as f64)).collect();
        let groups: Vec<usize> = (0..400).map(|i| i / 15).collect();
        let f = Forward::over(&t, Some(&groups)).expect("folds");
        for (train, judged) in &f.folds {
            assert!(!judged.iter().any(|j| train.iter().any(|i| groups[*i] == groups[*j])));
        }
        assert!(Forward::over(&t[..30], None).is_none());
    }
}
