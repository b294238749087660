//! What remains after the named causes, characterised: is the final model's residual on the
//! rows it was fitted to white, or does it still follow something — the acquisition order (a drift, a set-up change),
//! a station, a joint angle, the temperature, where in the instrument's volume the target was?
//! Where it is white, its spread per coordinate is the instrument's apparent noise, set beside
//! what the instrument states (the rows' `sx, sy, sz`, `--instrument-accuracy-mm`, repeats).
//!
//! Each test is a one-way analysis of variance of one value's residual over bins of one
//! regressor (quantile bins; one group per station or backlash flank), Bonferroni-corrected over
//! every test. Where rows share errors in blocks (a sweep's logging rounding), the units are the
//! blocks (each its rows' mean residual and mean regressor), so that a shared error is one
//! unit's noise and not a structure of the rows it spans. A test counts as structure
//! where it is significant and its bins' means hold at least [`STRUCTURE_SHARE`] of that
//! value's mean square (the adjusted share: what chance leaves to bins is taken off).

use crate::calib::fit::floor::NoiseFloor;
use crate::calib::fit::Samples;
use crate::measurement::Measurement;
use crate::stats::{f_survival, rms};
use serde::{Deserialize, Serialize};

/// The least share of a value's mean square a regressor's bins must hold to count as structure:
/// below it a model of that dependence gains too little to name.
pub const STRUCTURE_SHARE: f64 = 0.05;
/// Family-wise significance level of the whiteness tests.
pub const WHITENESS_ALPHA: f64 = 0.01;
/// Fewest rows the remainder is characterised on.
pub const MIN_ROWS: usize = 30;
/// Rows per bin the tests aim at (bins: 2 to 10 for a regressor, to 20 for the order).
const ROWS_PER_BIN: usize = 30;

/// One regressor's strongest dependence of the remainder (over the reading's values).
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct StructureTest {
    /// What the residual was binned by: `acquisition order`, `station`, `q2`, `temp`, `x`, ...
    pub against: String,
    /// The reading value it shows most in (`z`; `L` for a cable).
    pub value: String,
    /// Share of that value's held-out mean square the bins' means hold (adjusted for chance).
    pub share: f64,
    /// Bonferroni-corrected p-value of the F test.
    pub p_value: f64,
    /// Significant and at least [`STRUCTURE_SHARE`].
    pub structured: bool,
}

/// What remains after the named causes.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct Remainder {
    /// Each regressor's strongest test, in the order: acquisition order, station, joints,
    /// temperature, the measured position.
    pub tests: Vec<StructureTest>,
    /// No test found structure.
    pub white: bool,
    /// The held-out residual's RMS per reading value, mm (where it is white: the instrument's
    /// apparent noise).
    pub apparent_noise_mm: Vec<(String, f64)>,
    /// The positions' apparent noise: RMS over the position values, mm.
    pub apparent_position_mm: f64,
    /// What the data or the instrument state of one position value's noise (repeats, rows'
    /// own standard deviations, a stated accuracy, with the angles' logging), mm; `None` where
    /// nothing is stated.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub stated_mm: Option<f64>,
    /// Where `stated_mm` comes from.
    #[serde(default, skip_serializing_if = "String::is_empty")]
    pub stated_by: String,
    /// What the tests counted: rows, or blocks of rows that share an error (each block's mean
    /// residual one unit: its shared error is then one unit's noise).
    #[serde(default)]
    pub units: String,
}

impl Remainder {
    /// The tests that found structure, the largest share first.
    pub fn structure(&self) -> impl Iterator<Item = &StructureTest> {
        let mut s: Vec<&StructureTest> = self.tests.iter().filter(|t| t.structured).collect();
        s.sort_by(|a, b| b.share.total_cmp(&a.share));
        s.into_iter()
    }

    /// The apparent noise over what is stated, where something is.
    pub fn noise_ratio(&self) -> Option<f64> {
        self.stated_mm.filter(|s| *s > 0.0).map(|s| self.apparent_position_mm / s)
    }

    /// One line for the report.
    pub fn summary(&self) -> String {
        let noise: Vec<String> = self.apparent_noise_mm.iter().map(|(c, v)| format!("{c} {v:.4}")).collect();
        let stated = match (self.stated_mm, self.noise_ratio()) {
            (Some(s), Some(r)) => format!(", {r:.2}x the {s:.4} mm {} states", self.stated_by),
            _ => ", no accuracy stated to compare with (--instrument-accuracy-mm, or sx, sy, sz columns)".into(),
        };
        let against: Vec<&str> = self.tests.iter().map(|t| t.against.as_str()).collect();
        if self.white {
            format!(
                "white ({} binned by {}: no dependence holds {:.0} % of a value's mean square): the instrument's apparent noise {} mm per value{stated}",
                self.units,
                against.join(", "),
                100.0 * STRUCTURE_SHARE,
                noise.join(", ")
            )
        } else {
            let s: Vec<String> =
                self.structure().take(4).map(|t| format!("{} [{}] {:.0} % (p = {:.1e})", t.against, t.value, 100.0 * t.share, t.p_value)).collect();
            format!("structured: it follows {}; its spread {} mm per value{stated}", s.join(", "), noise.join(", "))
        }
    }
}

/// One regressor: its name, its value on every row, and whether the values are categories (a
/// station, a backlash flank) rather than quantities to bin by quantiles.
struct Regressor {
    name: String,
    values: Vec<f64>,
    categorical: bool,
}

/// Bin index of every unit by quantiles of `v` (`k` bins; ties share a bin).
fn quantile_bins(v: &[f64], k: usize) -> Vec<usize> {
    let mut order: Vec<usize> = (0..v.len()).collect();
    order.sort_by(|&a, &b| v[a].total_cmp(&v[b]));
    let mut bins = vec![0; v.len()];
    for (r, &i) in order.iter().enumerate() {
        bins[i] = r * k / v.len().max(1);
    }
    // Units of equal value in one bin.
    for w in order.windows(2) {
        if v[w[1]] == v[w[0]] {
            bins[w[1]] = bins[w[0]];
        }
    }
    bins
}

/// Bin index of every unit by category (values compared exactly).
fn category_bins(v: &[f64]) -> Vec<usize> {
    let mut seen: Vec<f64> = Vec::new();
    v.iter()
        .map(|x| {
            seen.iter().position(|s| s == x).unwrap_or_else(|| {
                seen.push(*x);
                seen.len() - 1
            })
        })
        .collect()
}

/// The regressors the remainder is tested against: the acquisition order (by `t` where every row
/// has one), the station, each joint angle, each joint's torque and backlash flank (where the
/// rows carry them), the temperature and the reading's position values. Those that do not vary
/// are left out.
fn regressors(data: &Samples, m: Measurement) -> Vec<Regressor> {
    let n = data.len();
    let mut out = Vec::new();
    let mut add = |name: String, values: Vec<f64>, categorical: bool| {
        if values.iter().any(|v| *v != values[0]) {
            out.push(Regressor { name, values, categorical });
        }
    };
    let times: Option<Vec<f64>> = data.inputs.iter().map(|i| i.t_s).collect();
    add("acquisition order".into(), times.unwrap_or_else(|| (0..n).map(|i| i as f64).collect()), false);
    add("station".into(), data.inputs.iter().map(|i| i.station as f64).collect(), true);
    let nj = data.q.first().map_or(0, Vec::len);
    for j in 0..nj {
        add(format!("q{}", j + 1), data.q.iter().map(|q| q[j]).collect(), false);
    }
    // What loads each joint and the flank its gear sits on (where the rows carry them): a
    // compliance or a backlash the model lacks follows these more than any one angle.
    for j in 0..nj {
        add(format!("torque_j{}", j + 1), data.inputs.iter().map(|i| i.torque(j)).collect(), false);
        add(format!("backlash_side_j{}", j + 1), data.inputs.iter().map(|i| i.side(j).signum()).collect(), true);
    }
    if let Some(t) = data.inputs.iter().map(|i| i.temp_c).collect::<Option<Vec<f64>>>() {
        add("temp".into(), t, false);
    }
    let d = data.dim;
    let groups = m.def().value_groups();
    for (c, name) in m.def().columns().iter().enumerate().take(d) {
        if groups.get(c).copied().unwrap_or(0) == 0 && d > 1 {
            add(format!("measured {name}"), (0..n).map(|i| data.y[i * d + c]).collect(), false);
        }
    }
    out
}

/// The units the tests count: every row, or where rows share errors in blocks (`groups`) every
/// block, its residual and its regressors the means of its rows (a category: its first row's).
/// A block's shared error is then one unit's noise, not a structure of the rows it spans.
struct Units {
    /// Each unit's rows.
    members: Vec<Vec<usize>>,
}

impl Units {
    fn of(n: usize, groups: Option<&[usize]>) -> Units {
        match groups.filter(|g| g.len() == n) {
            Some(g) => {
                let mut members: Vec<Vec<usize>> = vec![Vec::new(); g.iter().max().map_or(0, |m| m + 1)];
                for (i, &b) in g.iter().enumerate() {
                    members[b].push(i);
                }
                members.retain(|m| !m.is_empty());
                Units { members }
            }
            None => Units { members: (0..n).map(|i| vec![i]).collect() },
        }
    }
    fn len(&self) -> usize {
        self.members.len()
    }
    /// The mean of `v` (one value per row) over each unit's rows.
    fn mean(&self, v: &[f64]) -> Vec<f64> {
        self.members.iter().map(|m| m.iter().map(|&i| v[i]).sum::<f64>() / m.len() as f64).collect()
    }
    /// Each unit's first row's value.
    fn first(&self, v: &[f64]) -> Vec<f64> {
        self.members.iter().map(|m| v[m[0]]).collect()
    }
    /// How many bins a quantity's quantiles make over the units: about [`ROWS_PER_BIN`] rows a
    /// bin (5 blocks a bin where units are blocks), 2 to 10 (to 20 for the acquisition order).
    fn bins(&self, blocks: bool, order: bool) -> usize {
        let per = if blocks { 5 } else { ROWS_PER_BIN };
        (self.len() / per).clamp(2, if order { 20 } else { 10 })
    }
}

/// (F, numerator and denominator degrees of freedom, adjusted share) of a one-way analysis of
/// variance of `r` over `bins`.
fn anova(r: &[f64], bins: &[usize]) -> Option<(f64, f64, f64, f64)> {
    let g = bins.iter().max()? + 1;
    let (mut sum, mut cnt) = (vec![0.0; g], vec![0usize; g]);
    for (v, &b) in r.iter().zip(bins) {
        sum[b] += v;
        cnt[b] += 1;
    }
    let used = cnt.iter().filter(|c| **c > 0).count();
    let n = r.len();
    if used < 2 || n <= used {
        return None;
    }
    let mean = r.iter().sum::<f64>() / n as f64;
    let means: Vec<f64> = sum.iter().zip(&cnt).map(|(s, c)| if *c > 0 { s / *c as f64 } else { 0.0 }).collect();
    let ssb: f64 = means.iter().zip(&cnt).map(|(m, c)| *c as f64 * (m - mean) * (m - mean)).sum();
    let ssw: f64 = r.iter().zip(bins).map(|(v, &b)| (v - means[b]) * (v - means[b])).sum();
    let sst = ssb + ssw;
    let (d1, d2) = ((used - 1) as f64, (n - used) as f64);
    if !(ssw > 0.0) || !(sst > 0.0) {
        return None;
    }
    let f = (ssb / d1) / (ssw / d2);
    let share = ((ssb - d1 * ssw / d2) / sst).max(0.0);
    Some((f, d1, d2, share))
}

/// The remainder of the held-out residuals `oof` (`data`'s rows, read by `m`; `groups`: each
/// row's block where rows share errors) characterised against the regressors, and its apparent
/// noise beside what `floor` states. `None` under [`MIN_ROWS`] rows.
pub fn characterise(oof: &[f64], data: &Samples, m: Measurement, groups: Option<&[usize]>, floor: &NoiseFloor) -> Option<Remainder> {
    let (n, d) = (data.len(), data.dim);
    if n < MIN_ROWS || oof.len() != n * d {
        return None;
    }
    let columns = m.def().columns();
    let value_groups = m.def().value_groups();
    let shared = groups.is_some_and(|g| g.len() == n && (1..n).any(|i| g[i] == g[i - 1]));
    let units = Units::of(n, if shared { groups } else { None });
    if units.len() < 8 {
        return None;
    }
    let regs = regressors(data, m);
    let n_tests = (regs.len() * d).max(1) as f64;
    let cols: Vec<Vec<f64>> = (0..d).map(|c| (0..n).map(|i| oof[i * d + c]).collect()).collect();
    let unit_cols: Vec<Vec<f64>> = cols.iter().map(|c| units.mean(c)).collect();
    let tests: Vec<StructureTest> = regs
        .iter()
        .filter_map(|reg| {
            let bins = if reg.categorical {
                category_bins(&units.first(&reg.values))
            } else {
                quantile_bins(&units.mean(&reg.values), units.bins(shared, reg.name == "acquisition order"))
            };
            (0..d)
                .filter_map(|c| {
                    let (f, d1, d2, share) = anova(&unit_cols[c], &bins)?;
                    let p = (f_survival(f, d1, d2) * n_tests).min(1.0);
                    let value = columns.get(c).copied().unwrap_or("value").to_string();
                    Some(StructureTest { against: reg.name.clone(), value, share, p_value: p, structured: p < WHITENESS_ALPHA && share >= STRUCTURE_SHARE })
                })
                .max_by(|a, b| (a.structured, a.share).partial_cmp(&(b.structured, b.share)).unwrap_or(std::cmp::Ordering::Equal))
        })
        .collect();
    let position = |c: usize| value_groups.get(c).copied().unwrap_or(0) == 0;
    let apparent_noise_mm: Vec<(String, f64)> = (0..d).map(|c| (columns.get(c).copied().unwrap_or("value").to_string(), rms(&cols[c]))).collect();
    let positions: Vec<f64> = (0..d).filter(|c| position(*c)).flat_map(|c| cols[c].iter().copied()).collect();
    let stated = match floor.by_group.first() {
        Some(g) if g.measured => Some(g.total_mm),
        Some(_) => None,
        None => floor.is_measured().then_some(floor.total_mm),
    };
    let stated_by: Vec<&str> = floor.sources.iter().filter(|s| s.source.measured()).map(|s| s.source.name()).collect();
    Some(Remainder {
        white: !tests.iter().any(|t| t.structured),
        tests,
        apparent_noise_mm,
        apparent_position_mm: rms(&positions),
        stated_mm: stated,
        stated_by: if stated.is_some() { stated_by.join(" and ") } else { String::new() },
        units: if shared { format!("{} blocks of rows that share an error", units.len()) } else { format!("{} rows", units.len()) },
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    fn samples(n: usize) -> Samples {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        let q: Vec<Vec<f64>> = (0..n).map(|_| (0..6).map(|_| rng.random_range(-2.0..2.0)).collect()).collect();
        let mut s = Samples::new(q, vec![0.0; n]);
        s.inputs = (0..n).map(|i| crate::calib::effects::RowInputs { t_s: Some(i as f64 * 10.0), ..Default::default() }).collect();
        s
    }

    fn noise(n: usize, seed: u64) -> Vec<f64> {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        (0..n).map(|_| rng.sample::<f64, _>(rand_distr::StandardNormal) * 0.01).collect()
    }

    #[test]
    fn white_noise_is_white_and_its_spread_is_the_apparent_noise() {
        let data = samples(600);
        let floor = NoiseFloor { total_mm: 0.01, sources: vec![], by_group: vec![] };
        for seed in 0..5 {
            let r = characterise(&noise(600, seed), &data, Measurement::Length, None, &floor).expect("enough rows");
            assert!(r.white, "seed {seed}: {:?}", r.tests);
            assert!((r.apparent_position_mm - 0.01).abs() < 0.0015);
            assert!(r.stated_mm.is_none());
        }
    }

    #[test]
    fn a_remainder_that_follows_a_joint_or_drifts_is_structured() {
        let data = samples(600);
        let floor = NoiseFloor { total_mm: 0.01, sources: vec![], by_group: vec![] };
        let e = noise(600, 9);
        let follows: Vec<f64> = e.iter().zip(&data.q).map(|(v, q)| v + 0.006 * (2.0 * q[1]).sin()).collect();
        let r = characterise(&follows, &data, Measurement::Length, None, &floor).unwrap();
        assert!(!r.white);
        assert_eq!(r.structure().next().map(|t| t.against.as_str()), Some("q2"));
        let drifts: Vec<f64> = e.iter().enumerate().map(|(i, v)| v + 0.01 * i as f64 / 600.0).collect();
        let r = characterise(&drifts, &data, Measurement::Length, None, &floor).unwrap();
        assert_eq!(r.structure().next().map(|t| t.against.as_str()), Some("acquisition order"));
    }
}
