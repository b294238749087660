//! Stage "split": the training and test rows (stratified, interleaved or by whole blocks), their
//! samples with each row's inputs, and the joint-limit check.

use super::options::*;
use super::result::*;
use crate::calib::fit::Samples;
use crate::dataset::blocks::Blocks;
use crate::dataset::{Dataset, Split};
use crate::error::{Error, Result};
use crate::robot::Robot;

/// The rows a calibration trains and tests on: the dataset's split column, or with a test
/// fraction `f` a held-out share drawn by `by` from `seed`.
pub fn split_rows(data: &Dataset, blocks: &Blocks, test_fraction: Option<f64>, seed: u64, by: SplitBy) -> Result<(Vec<usize>, Vec<usize>)> {
    let n = data.rows.len();
    match test_fraction {
        Some(f) => {
            if !(0.0..1.0).contains(&f) {
                return Err(Error::Invalid(format!("--test-fraction must be in [0, 1), got {f}")));
            }
            let n_test = (f * n as f64).round() as usize;
            // The later rows (a dataset's rows are in acquisition order, `t` non-decreasing).
            if by == SplitBy::Time {
                return Ok(((0..n - n_test).collect(), (n - n_test..n).collect()));
            }
            // Rows that share a sweep (or a pause, a declared block) share its errors: the test
            // rows are then whole blocks, never rows of a block whose other rows train.
            if by == SplitBy::Blocks && blocks.any_shared() && n_test > 0 {
                let test = block_split(blocks, n_test, seed);
                return Ok(((0..n).filter(|i| !test[*i]).collect(), (0..n).filter(|i| test[*i]).collect()));
            }
            // Strata by the reading: the cable length, or a point's distance from the
            // instrument's origin.
            let lengths = reading_measurement(data)?.file_lengths();
            let key: Vec<f64> = data
                .rows
                .iter()
                .map(|r| if r.reading_mm.len() == 1 { r.reading_mm[0] } else { r.reading_mm.iter().take(lengths).map(|v| v * v).sum::<f64>().sqrt() })
                .collect();
            let split = crate::dataset::split::stratified_split(&key, n_test, seed);
            Ok(((0..n).filter(|i| split[*i] == Split::Train).collect(), (0..n).filter(|i| split[*i] == Split::Test).collect()))
        }
        None => Ok((data.train_indices(), data.test_indices())),
    }
}

/// Test rows of whole blocks: the blocks in a seeded random order, taken while the test rows
/// stay nearer to `n_test` than without the block (at least one block, never all of them).
pub fn block_split(blocks: &crate::dataset::blocks::Blocks, n_test: usize, seed: u64) -> Vec<bool> {
    use rand::seq::SliceRandom;
    use rand::SeedableRng;
    let mut sizes = vec![0usize; blocks.len()];
    for &b in &blocks.of_row {
        sizes[b] += 1;
    }
    let mut order: Vec<usize> = (0..blocks.len()).collect();
    let seed = crate::seed::stream_seed(seed, crate::seed::Stream::Split, 1);
    order.shuffle(&mut rand_chacha::ChaCha8Rng::seed_from_u64(seed));
    let mut chosen = vec![false; blocks.len()];
    let mut rows = 0;
    for (taken, &b) in order.iter().enumerate() {
        if taken + 1 == order.len() || (rows > 0 && (rows + sizes[b]).abs_diff(n_test) > rows.abs_diff(n_test)) {
            break;
        }
        chosen[b] = true;
        rows += sizes[b];
        if rows >= n_test {
            break;
        }
    }
    blocks.of_row.iter().map(|&b| chosen[b]).collect()
}

/// The rows `idx` of a dataset as calibration samples (radians, metres), with their time,
/// temperature, station and mount ([`Dataset::stations`], [`Dataset::mounts`]); torques and backlash sides are added by [`crate::calib::effects::inputs`] where needed. A row
/// without a reading reads NaN.
pub fn samples(data: &Dataset, idx: &[usize]) -> Samples {
    let rows = idx.iter().map(|&i| &data.rows[i]);
    let m = data.measurement();
    let dim = m.map_or(1, |m| m.dim());
    // A narrower instrument's rows beside the first's (a face's contact beside seated rows)
    // hold their values first and zeros after: the model reads zeros there too.
    let reading = |r: &crate::dataset::Row| -> Vec<f64> {
        match r.values_mm() {
            Some(v) if v.len() <= dim && (v.len() == dim || r.measurement() != m) => {
                v.iter().map(crate::units::to_m).chain(std::iter::repeat(0.0)).take(dim).collect()
            }
            _ => vec![f64::NAN; dim],
        }
    };
    let (stations, mounts) = (data.stations(), data.mounts());
    Samples {
        q: rows.clone().map(|r| r.q_deg.iter().map(|d| d.to_radians()).collect()).collect(),
        y: rows.clone().flat_map(reading).collect(),
        dim,
        measurement: m.unwrap_or_default(),
        also: data.also_measurement(),
        inputs: idx
            .iter()
            .zip(rows)
            .map(|(&i, r)| crate::calib::effects::RowInputs {
                t_s: r.t_s,
                temp_c: r.temp_c,
                station: stations.of_row[i],
                mount: mounts.of_row[i],
                instrument: usize::from(r.measurement().is_some() && r.measurement() != m),
                ..Default::default()
            })
            .collect(),
        w: None,
        gls: None,
    }
}

/// Stage "split": training and test samples, with the checks that make a calibration meaningful.
pub struct SplitData {
    /// The static-torque model of the effects (set by the effects stage where there is one).
    pub torque_model: Option<crate::calib::effects::inputs::TorqueModel>,
    /// Data rows (0-based) of the training samples.
    pub train_idx: Vec<usize>,
    /// Data rows (0-based) of the test samples.
    pub test_idx: Vec<usize>,
    /// The training rows as samples.
    pub train: Samples,
    /// The test rows as samples.
    pub test: Samples,
    /// The blocks of rows that share an error (a sweep, a pause, a declared block), of every
    /// row, detected once with the joint angles' logging step: the split, the noise model and
    /// the leak warning read the same blocks.
    pub blocks: Blocks,
    /// The joint angles' logging step, degrees: given (`--angle-resolution-deg`) or read from
    /// their decimals; `None` where they are not rounded.
    pub angle_step_deg: Option<f64>,
}

impl SplitData {
    /// How `data`'s angles were logged (its blocks and step), `None` where they are not rounded.
    pub fn logging<'a>(&'a self, data: &'a Dataset) -> Option<crate::calib::fit::noise_model::Logging<'a>> {
        self.angle_step_deg.map(|step_deg| crate::calib::fit::noise_model::Logging { data, blocks: &self.blocks, step_deg })
    }
}

/// Number of distinct joint configurations among `rows` (angles compared to 1e-6 degrees).
pub(super) fn distinct_configurations(data: &Dataset, rows: &[usize]) -> usize {
    let mut keys: Vec<Vec<i64>> = rows.iter().map(|&i| data.rows[i].q_deg.iter().map(|v| (v * 1e6).round() as i64).collect()).collect();
    keys.sort_unstable();
    keys.dedup();
    keys.len()
}

/// An error unless the rows fit the model's arm and the inertial one: as many joint angles as
/// each has joints, every angle within the model's joint limits. Checked before anything
/// evaluates the arm at the rows.
pub fn check_arm(data: &Dataset, opts: &CalibOptions) -> Result<()> {
    if let Some(robot) = opts.model.robot() {
        data.require_joints(robot.dof(), &format!("the robot '{}'", robot.name))?;
        check_joint_limits(data, robot)?;
    }
    if let Some(robot) = opts.loads.inertial.as_ref() {
        data.require_joints(robot.dof(), &format!("the inertial robot '{}' (--robot)", robot.name))?;
    }
    Ok(())
}

/// Splits `data` into training and test samples (the dataset's split column, or
/// `opts.test_fraction`); errors on rows beyond the robot's joint limits, or on fewer than 8
/// training rows or 8 distinct training configurations.
pub fn split_stage(data: &Dataset, opts: &CalibOptions) -> Result<SplitData> {
    check_arm(data, opts)?;
    let (blocks, angle_step_deg) = crate::dataset::blocks::detect(data, opts.floor.angle_step_deg);
    let (train_idx, test_idx) = split_rows(data, &blocks, opts.split.test_fraction, opts.seed, opts.split.by)?;
    if train_idx.len() < 8 {
        return Err(Error::Calibration(format!("only {} training rows; at least 8 are needed", train_idx.len())));
    }
    let distinct = distinct_configurations(data, &train_idx);
    if distinct < 8 {
        return Err(Error::Calibration(format!(
            "the {} training rows hold only {distinct} distinct joint configurations; a calibration needs many different poses",
            train_idx.len()
        )));
    }
    let train = samples(data, &train_idx);
    let test = samples(data, &test_idx);
    Ok(SplitData { torque_model: None, train_idx, test_idx, train, test, blocks, angle_step_deg })
}

/// Refuses rows whose joint angles lie beyond the robot's limits (more than the slack).
pub(super) fn check_joint_limits(data: &Dataset, robot: &Robot) -> Result<()> {
    match outside_limits(data, &robot.limits()).next() {
        Some((i, j, q)) => {
            let spec = &robot.joints[j];
            let (lo, hi) = (spec.lower.to_degrees(), spec.upper.to_degrees());
            Err(Error::data(&data.source, format!("row {}: q{} = {q} deg is outside {}'s limits [{lo:.2}, {hi:.2}] deg", i + 1, j + 1, spec.name)))
        }
        None => Ok(()),
    }
}

/// Every joint angle of `data` beyond `limits` (rad, per joint) by more than
/// [`JOINT_LIMIT_SLACK_DEG`], as (row, joint, angle in degrees), rows in order.
pub fn outside_limits<'a>(data: &'a Dataset, limits: &'a [(f64, f64)]) -> impl Iterator<Item = (usize, usize, f64)> + 'a {
    data.rows.iter().enumerate().flat_map(move |(i, r)| {
        r.q_deg.iter().zip(limits).enumerate().filter_map(move |(j, (q, (lo, hi)))| {
            (*q < lo.to_degrees() - JOINT_LIMIT_SLACK_DEG || *q > hi.to_degrees() + JOINT_LIMIT_SLACK_DEG).then_some((i, j, *q))
        })
    })
}

/// What the rows of `data` read: every row must have a reading (a cable length `L`, or a
/// tracker's `x, y, z`), as [`Dataset::require_length`] words it for the draw-wire.
pub fn reading_measurement(data: &Dataset) -> Result<crate::measurement::Measurement> {
    match data.measurement() {
        Some(m) if m != crate::measurement::Measurement::Length => {
            data.require_readings()?;
            Ok(m)
        }
        _ => {
            data.require_length()?;
            Ok(crate::measurement::Measurement::Length)
        }
    }
}
