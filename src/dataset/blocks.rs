//! The acquisition's structure: blocks of consecutive rows that share an error.
//!
//! Real acquisitions are not made of independent rows. An arm is jogged in **sweeps** (one or
//! two joints step while the others hold for 10–30 rows), so every row of a sweep shares the
//! logging error of each joint that holds (an angle logged at 0.1° is off by the same amount on
//! all of them); a **pause** in `t` (a break, a re-mount, another session) separates stretches
//! that may each share an offset; a **reading step** (the cable slipped) offsets every row up to
//! the next one; a user may **declare** blocks in a `block` column. Rows that share such an
//! error are not independent evidence: cross-validation must hold them out together, and tests
//! must count them as less than their number of rows.
//!
//! [`detect`] finds the blocks from the data alone. A block boundary is put before a row when
//!
//! * **sweep**: more than [`MAX_SWEEP_MOVING`] joints differ from the block's first row (or all
//!   of them, on an arm of up to two joints); a joint "holds" while it stays within half its
//!   logging step of that row's value (or within [`UNROUNDED_TOL_DEG`] when the angles carry
//!   more than six decimals);
//! * **time gap**: `t` jumps by more than [`GAP_FACTOR`] times its median step and at least
//!   [`GAP_MIN_S`] seconds;
//! * **declared**: the `block` column changes value;
//!
//! and [`Blocks::split_before`] adds others (a reading step's first and last rows). Shuffled
//! data come out as blocks of one row each, and then everything that uses blocks behaves
//! exactly as it does with independent rows.

use super::Dataset;
use serde::{Deserialize, Serialize};

/// A sweep moves at most this many joints (from its first row) while the others hold.
pub const MAX_SWEEP_MOVING: usize = 2;
/// A joint logged with more than six decimals holds while it stays within this many degrees.
pub const UNROUNDED_TOL_DEG: f64 = 1e-6;
/// A pause in `t` longer than this many median steps ...
pub const GAP_FACTOR: f64 = 10.0;
/// ... and at least this many seconds starts a new block.
pub const GAP_MIN_S: f64 = 60.0;

/// Why a block starts where it starts.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Boundary {
    /// The first row.
    Start,
    /// The joints that held in the block before move (a new sweep, or a row on its own).
    Sweep,
    /// A pause in `t`.
    TimeGap,
    /// The `block` column changes.
    Declared,
    /// A reading step begins or ends.
    ReadingStep,
}

/// The blocks of a dataset's rows, in acquisition order.
#[derive(Clone, Debug, PartialEq)]
pub struct Blocks {
    /// Block index of every row (0-based, non-decreasing).
    pub of_row: Vec<usize>,
    /// First row of each block and why it starts there.
    pub starts: Vec<(usize, Boundary)>,
}

/// What the blocks look like, for a report.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct Structure {
    /// Rows the blocks cover.
    pub rows: usize,
    /// Number of blocks.
    pub blocks: usize,
    /// Blocks of more than one row, and the rows in them.
    pub multi_row_blocks: usize,
    /// Rows in those blocks.
    pub rows_in_multi_row_blocks: usize,
    /// Median rows per block.
    pub median_block_rows: f64,
    /// Rows in the largest block.
    pub largest_block_rows: usize,
    /// Boundaries by their reason.
    pub sweep_boundaries: usize,
    /// Boundaries at a pause in `t`.
    pub time_gaps: usize,
    /// Boundaries where the `block` column changes.
    pub declared_boundaries: usize,
    /// Boundaries where a reading step begins or ends.
    pub reading_step_boundaries: usize,
    /// The logging step of the joint angles the sweeps were found with (degrees), if any.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub angle_step_deg: Option<f64>,
    /// One line saying what was found.
    pub summary: String,
}

impl Blocks {
    /// Every row its own block.
    pub fn singletons(n: usize) -> Blocks {
        Blocks { of_row: (0..n).collect(), starts: (0..n).map(|i| (i, if i == 0 { Boundary::Start } else { Boundary::Sweep })).collect() }
    }

    /// Number of blocks.
    pub fn len(&self) -> usize {
        self.starts.len()
    }

    /// Whether there are no blocks (no rows).
    pub fn is_empty(&self) -> bool {
        self.starts.is_empty()
    }

    /// Whether some block holds more than one row.
    pub fn any_shared(&self) -> bool {
        self.starts.len() < self.of_row.len()
    }

    /// A new block starts at `row` (a no-op where one already does, or past the end).
    pub fn split_before(&mut self, row: usize, why: Boundary) {
        if row == 0 || row >= self.of_row.len() || self.starts.iter().any(|s| s.0 == row) {
            return;
        }
        let pos = self.starts.partition_point(|s| s.0 < row);
        self.starts.insert(pos, (row, why));
        self.renumber();
    }

    fn renumber(&mut self) {
        let mut b = 0;
        for (i, slot) in self.of_row.iter_mut().enumerate() {
            while b + 1 < self.starts.len() && self.starts[b + 1].0 <= i {
                b += 1;
            }
            *slot = b;
        }
    }

    /// The block ids of `rows` (indices into this dataset's rows, ascending), renumbered
    /// 0, 1, 2, ... in order of first appearance: the blocks of a subset.
    pub fn ids_of(&self, rows: &[usize]) -> Vec<usize> {
        let mut out = Vec::with_capacity(rows.len());
        let (mut last, mut next) = (usize::MAX, 0);
        for &i in rows {
            let b = self.of_row[i];
            if b != last {
                last = b;
                next += 1;
            }
            out.push(next - 1);
        }
        out
    }

    /// What the blocks look like, with the angle step the sweeps were found with.
    pub fn structure(&self, angle_step_deg: Option<f64>) -> Structure {
        let mut sizes = vec![0usize; self.starts.len()];
        for &b in &self.of_row {
            sizes[b] += 1;
        }
        let multi: Vec<usize> = sizes.iter().copied().filter(|&s| s > 1).collect();
        let median = median(sizes.iter().map(|&s| s as f64).collect());
        let count = |k: Boundary| self.starts.iter().filter(|s| s.1 == k).count();
        let (sweeps, gaps, declared, steps) = (count(Boundary::Sweep), count(Boundary::TimeGap), count(Boundary::Declared), count(Boundary::ReadingStep));
        let rows_multi: usize = multi.iter().sum();
        let summary = if multi.is_empty() {
            format!("{} rows, each its own block: no rows share a sweep, a pause or a reading step", self.of_row.len())
        } else {
            format!(
                "{} rows in {} blocks: {} blocks of 2 or more rows hold {} rows (median block {} rows, largest {}); boundaries: {sweeps} sweep, {gaps} time gap, {declared} declared, {steps} reading step",
                self.of_row.len(),
                self.starts.len(),
                multi.len(),
                rows_multi,
                median,
                sizes.iter().max().copied().unwrap_or(0)
            )
        };
        Structure {
            rows: self.of_row.len(),
            blocks: self.starts.len(),
            multi_row_blocks: multi.len(),
            rows_in_multi_row_blocks: rows_multi,
            median_block_rows: median,
            largest_block_rows: sizes.iter().max().copied().unwrap_or(0),
            sweep_boundaries: sweeps,
            time_gaps: gaps,
            declared_boundaries: declared,
            reading_step_boundaries: steps,
            angle_step_deg,
            summary,
        }
    }
}

/// The blocks of `data` (see the module docs); `angle_step_deg` is the joint angles' logging
/// step (`None`: read from their decimals).
pub fn detect(data: &Dataset, angle_step_deg: Option<f64>) -> (Blocks, Option<f64>) {
    let n = data.rows.len();
    let step = angle_step_deg.or_else(|| super::logging::logging_step(data.rows.iter().flat_map(|r| r.q_deg.iter().copied())));
    let tol = step.map_or(UNROUNDED_TOL_DEG, |s| 0.5 * s).max(UNROUNDED_TOL_DEG);
    let joints = data.n_joints();
    let min_still = joints.saturating_sub(MAX_SWEEP_MOVING).max(1);
    let gap = time_gap(data);
    let mut starts: Vec<(usize, Boundary)> = Vec::new();
    let mut first = 0usize;
    // Joints that have held since the block's first row.
    let mut held = vec![true; joints];
    for i in 0..n {
        if i == 0 {
            starts.push((0, Boundary::Start));
            continue;
        }
        let why = if data.rows[i].block.is_some() && data.rows[i].block != data.rows[i - 1].block {
            Some(Boundary::Declared)
        } else if let (Some(g), Some(a), Some(b)) = (gap, data.rows[i - 1].t_s, data.rows[i].t_s) {
            (b - a > g).then_some(Boundary::TimeGap)
        } else {
            None
        };
        let still: Vec<bool> = (0..joints).map(|j| held[j] && (data.rows[i].q_deg[j] - data.rows[first].q_deg[j]).abs() <= tol).collect();
        let why = why.or_else(|| (still.iter().filter(|s| **s).count() < min_still).then_some(Boundary::Sweep));
        match why {
            Some(w) => {
                starts.push((i, w));
                first = i;
                held = vec![true; joints];
            }
            None => held = still,
        }
    }
    let mut b = Blocks { of_row: vec![0; n], starts };
    b.renumber();
    (b, step)
}

/// The pause in `t` before row `row` (0-based), s, where there is one: a step in `t` beyond
/// [`GAP_FACTOR`] median steps and [`GAP_MIN_S`] (what starts a new block).
pub fn pause_before(data: &Dataset, row: usize) -> Option<f64> {
    let gap = time_gap(data)?;
    let (a, b) = (data.rows.get(row.checked_sub(1)?)?.t_s?, data.rows.get(row)?.t_s?);
    (b - a > gap).then_some(b - a)
}

/// The pause in `t` (s) beyond which a new block starts, when every row has `t`.
fn time_gap(data: &Dataset) -> Option<f64> {
    let t: Vec<f64> = data.rows.iter().map(|r| r.t_s).collect::<Option<Vec<f64>>>()?;
    let d: Vec<f64> = t.windows(2).map(|w| w[1] - w[0]).filter(|v| *v > 0.0).collect();
    if d.is_empty() {
        return None;
    }
    Some((GAP_FACTOR * median(d)).max(GAP_MIN_S))
}

/// The median of `v` (NaN for none).
fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    match v.len() {
        0 => f64::NAN,
        n if n % 2 == 1 => v[n / 2],
        n => 0.5 * (v[n / 2 - 1] + v[n / 2]),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dataset::Row;

    fn row(q: &[f64], t: f64) -> Row {
        Row { q_deg: q.to_vec(), reading_mm: vec![500.0], t_s: Some(t), temp_c: None, split: None, std_mm: None, ..Default::default() }
    }

    #[test]
    fn sweeps_pauses_and_declared_blocks_are_found() {
        // Sweep of joint 1 (3 rows), a sweep of joints 1 and 2 from a new base (3 rows), a row
        // on its own (all joints move), then a pause.
        let q = [
            [10.0, 20.0, 30.0, 40.0, 50.0, 60.0],
            [11.0, 20.0, 30.0, 40.0, 50.0, 60.0],
            [12.0, 20.0, 30.0, 40.0, 50.0, 60.0],
            [0.0, 5.0, 30.1, 40.0, 50.0, 60.0],
            [1.0, 6.0, 30.1, 40.0, 50.0, 60.0],
            [2.0, 7.0, 30.1, 40.0, 50.0, 60.0],
            [9.0, 9.0, 9.0, 9.0, 9.0, 9.0],
            [9.0, 9.1, 9.0, 9.0, 9.0, 9.0],
        ];
        let ts = [0.0, 10.0, 20.0, 30.0, 40.0, 50.0, 60.0, 1000.0];
        let rows: Vec<Row> = q.iter().zip(ts).map(|(q, t)| row(q, t)).collect();
        let data = Dataset { rows, source: "t".into() };
        let (b, step) = detect(&data, None);
        assert_eq!(step, Some(0.1));
        assert_eq!(b.of_row, vec![0, 0, 0, 1, 1, 1, 2, 3]);
        assert_eq!(b.starts.iter().map(|s| s.1).collect::<Vec<_>>(), vec![Boundary::Start, Boundary::Sweep, Boundary::Sweep, Boundary::TimeGap]);
        let s = b.structure(step);
        assert_eq!((s.blocks, s.multi_row_blocks, s.rows_in_multi_row_blocks, s.largest_block_rows), (4, 2, 6, 3));
        // A third joint moving breaks the sweep.
        let mut d2 = data.clone();
        d2.rows[2].q_deg[3] = 41.0;
        d2.rows[2].q_deg[4] = 51.0;
        assert_eq!(detect(&d2, None).0.of_row[..4], [0, 0, 1, 2]);
        // A declared column splits where it changes; a reading step where it starts.
        let mut d3 = data.clone();
        for (i, r) in d3.rows.iter_mut().enumerate() {
            r.block = Some(if i < 2 { "a".into() } else { "b".into() });
        }
        let (mut b3, _) = detect(&d3, None);
        assert_eq!(b3.of_row[..4], [0, 0, 1, 2]);
        assert_eq!(b3.starts[1].1, Boundary::Declared);
        b3.split_before(4, Boundary::ReadingStep);
        assert_eq!(b3.of_row, vec![0, 0, 1, 2, 3, 3, 4, 5]);
        assert_eq!(b3.ids_of(&[0, 4, 5, 7]), vec![0, 1, 1, 2]);
        // Shuffled rows: every row its own block.
        assert_eq!(Blocks::singletons(3).of_row, vec![0, 1, 2]);
        assert!(!Blocks::singletons(3).any_shared());
    }
}
