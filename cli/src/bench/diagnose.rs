//! `twincal bench diagnose`: the diagnosis' speed, detection and false-alarm rates.

use std::time::Instant;
use twincal::dataset::Dataset;
use twincal::error::Result;
use twincal::sim::generate::{generate as run_generate, Generated, Progress, Silent};
use twincal::sim::scenario::Scenario;
use twincal::stats::median;

/// What the detection part of `bench diagnose` is over (its work items: seed × hidden/clean).
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct DetectionConfig {
    pub seeds: u64,
    pub twincal_version: String,
    /// Only the scenarios of these categories (all when empty; see [`Variant::category`]).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub categories: Vec<String>,
}

impl DetectionConfig {
    /// The detection part over `seeds` seeds, the scenarios of `categories` only (all when
    /// empty; an unknown category is an error naming the known ones).
    pub fn new(seeds: u64, categories: &[String]) -> Result<DetectionConfig> {
        // Item ids 0, 1 are seed 1's hidden and clean scenarios, 2·seeds.. its six realistic
        // ones, 8·seeds.. its tracker ones.
        let known: Vec<String> = [0, 1]
            .into_iter()
            .chain(2 * seeds..2 * seeds + 6)
            .chain(8 * seeds..8 * seeds + TRACKER_CASES.len() as u64)
            .map(|id| Variant::of(id, seeds).1.category())
            .collect();
        if let Some(c) = categories.iter().find(|c| !known.contains(c)) {
            return Err(twincal::error::Error::Invalid(format!("unknown --categories entry '{c}': known are {}", known.join(", "))));
        }
        Ok(DetectionConfig { seeds, twincal_version: env!("CARGO_PKG_VERSION").into(), categories: categories.to_vec() })
    }

    /// The variant ids (see [`Variant::of`]) of the work items, in order.
    fn ids(&self) -> Vec<u64> {
        (0..VARIANTS * self.seeds).filter(|&id| self.categories.is_empty() || self.categories.contains(&Variant::of(id, self.seeds).1.category())).collect()
    }
}

impl crate::shard::Config for DetectionConfig {
    const KIND: &'static str = "bench-diagnose";
    fn hash(&self) -> String {
        twincal::dataset::truth::sha256_hex(serde_json::to_string(self).unwrap_or_default().as_bytes())
    }
    /// Item `id` (see [`Variant::of`]): per seed, the hidden-effect and the clean scenario, then
    /// the realistic acquisitions (0.1° and 0.01° logging; clean, an effect above the floor, an
    /// effect far below it).
    fn items(&self) -> u64 {
        self.ids().len() as u64
    }
}

/// Work items per seed: hidden, clean, 2 loggings × (clean, above, below), and the tracker
/// cases.
const VARIANTS: u64 = 8 + TRACKER_CASES.len() as u64;

/// The tracker cases of each seed, in item order.
const TRACKER_CASES: [TrackerCase; 5] = [TrackerCase::Clean, TrackerCase::Half, TrackerCase::PayloadRuns, TrackerCase::WarmUp, TrackerCase::Moved];

/// What one work item diagnoses.
/// A tracker scenario of the detection part.
#[derive(Clone, Copy, Debug, PartialEq)]
enum TrackerCase {
    /// 400 independent rows, no effect.
    Clean,
    /// 400 independent rows, one effect at half one row's noise.
    Half,
    /// Payload runs (0, 1.5, 3 kg at the same 120 poses), a compliance the unloaded run hides.
    PayloadRuns,
    /// 400 rows over a warm-up whose temperature sensor lags the structure.
    WarmUp,
    /// 400 rows of a rigid arm, the tracker re-stationed, re-registered or bumped once.
    Moved,
}

#[derive(Clone, Copy, Debug, PartialEq)]
enum Variant {
    /// One effect at 1.5–4× the reading noise, angles unrounded, Halton order.
    Hidden,
    /// No effect.
    Clean,
    /// Sweeps, angles logged at `decimals`, glitch runs; `Some(true)`: one effect above the
    /// floor, `Some(false)`: one far below it, `None`: no effect.
    Realistic { decimals: usize, effect: Option<bool> },
    /// Tracker points with their `sx, sy, sz`.
    Tracker(TrackerCase),
}

impl Variant {
    /// The seed and variant of item `id`: the first `2·seeds` items are the hidden and clean
    /// scenarios of seeds 1, 2, ... (as before realistic acquisitions were added), the rest six
    /// realistic ones per seed, then the [`TRACKER_CASES`] of each seed.
    fn of(id: u64, seeds: u64) -> (u64, Variant) {
        if id < 2 * seeds {
            return (id / 2 + 1, if id % 2 == 0 { Variant::Hidden } else { Variant::Clean });
        }
        if id >= 8 * seeds {
            let (k, n) = (id - 8 * seeds, TRACKER_CASES.len() as u64);
            return (k / n + 1, Variant::Tracker(TRACKER_CASES[(k % n) as usize]));
        }
        let k = id - 2 * seeds;
        let decimals = if (k % 6) < 3 { 1 } else { 2 };
        let effect = [None, Some(true), Some(false)][(k % 3) as usize];
        (k / 6 + 1, Variant::Realistic { decimals, effect })
    }
    /// The category items are counted in.
    fn category(self) -> String {
        match self {
            Variant::Hidden => "hidden".into(),
            Variant::Tracker(TrackerCase::Clean) => "tracker-clean".into(),
            Variant::Tracker(TrackerCase::Half) => "tracker-half".into(),
            Variant::Tracker(TrackerCase::PayloadRuns) => "tracker-payload".into(),
            Variant::Tracker(TrackerCase::WarmUp) => "tracker-warmup".into(),
            Variant::Tracker(TrackerCase::Moved) => "tracker-moved".into(),
            Variant::Clean => "clean".into(),
            Variant::Realistic { decimals, effect } => {
                format!(
                    "realistic-{decimals}-{}",
                    match effect {
                        None => "clean",
                        Some(true) => "above",
                        Some(false) => "below",
                    }
                )
            }
        }
    }
}

/// One diagnosed scenario of the detection part.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct DetectionItem {
    /// The line printed for it (every hidden effect; a clean scenario's false alarm).
    pub line: Option<String>,
    pub detected: bool,
    pub sized: bool,
    pub alarm: bool,
    /// `hidden`, `clean`, `realistic-<decimals>-<clean|above|below>` or
    /// `tracker-<clean|half|payload|warmup|moved>`.
    #[serde(default)]
    pub category: String,
    /// The size within 3 standard uncertainties (not the 30 % band).
    #[serde(default)]
    pub within_3_sigma: bool,
    /// The data's floor of a realistic item (reading noise and angle logging), mm.
    #[serde(default)]
    pub floor_mm: f64,
    /// A scenario with one hidden effect whose diagnosis names more than one cause: a cause
    /// that is not there.
    #[serde(default)]
    pub extra: bool,
    /// A warm-up diagnosed on the first [`FORWARD_SHARE`] of its rows in time, judged on the
    /// rest: the RMSE per coordinate there of the diagnosed model and of the hidden cause's own
    /// form calibrated on the same rows, mm.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub forward_mm: Option<[f64; 2]>,
    /// A tracker item's remainder: [white at the instrument's noise after the named cause (not
    /// unexplained), reported unexplained where a larger effect's kind was no candidate].
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub remainder: Option<[bool; 2]>,
}

/// The share of a warm-up's rows (earliest first) its forward check diagnoses on.
pub const FORWARD_SHARE: f64 = 0.7;
/// The forward check's target: the diagnosed model's error on the later rows within this many
/// times that of the hidden cause's own form.
pub const FORWARD_TARGET: f64 = 1.2;

impl crate::shard::Item for DetectionItem {
    fn check(&self) -> std::result::Result<(), String> {
        match self.floor_mm.is_finite() && self.floor_mm >= 0.0 {
            true => Ok(()),
            false => Err(format!("a floor of {} mm", self.floor_mm)),
        }
    }
}

fn strip(g: &Generated) -> Dataset {
    use twincal::dataset::Row;
    Dataset { rows: g.dataset.rows.iter().map(|r| Row { split: None, ..r.clone() }).collect(), source: g.dataset.source.clone() }
}

fn options() -> Result<twincal::diagnose::DiagnoseOptions> {
    Ok(twincal::diagnose::DiagnoseOptions::new(twincal::calib::pipeline::ModelSpec::nominal(
        twincal::robot::Robot::irb120(),
        twincal::calib::pipeline::Parametrisation::Hayati,
    )))
}

/// A hidden effect diagnosed: its line, whether it was named first, sized (3σ or 30 %), and
/// within 3σ.
fn judge_hidden(seed: u64, h: &twincal::diagnose::hidden::Hidden, d: &twincal::diagnose::Diagnosis) -> (String, bool, bool, bool) {
    let first = d.causes.first();
    let named = first.is_some_and(|c| h.named_by(c));
    let sized = first.is_some_and(|c| named && h.sized_by(c));
    let within = first.is_some_and(|c| named && (c.magnitude - h.magnitude).abs() <= 3.0 * c.uncertainty);
    let line = format!(
        "    seed {seed:3}: hidden {}{} {:.4} ({:.2}x) -> {}{}",
        h.cause.name(),
        h.joint.map(|j| format!("[j{}]", j + 1)).unwrap_or_default(),
        h.magnitude,
        h.factor,
        d.verdict,
        first.map(|c| format!(" {:.4} ± {:.4} {}", c.magnitude, c.uncertainty, c.unit)).unwrap_or_default()
    );
    (line, named, sized, within)
}

/// Work item `id` of the detection part: a scenario generated from its seed and diagnosed.
pub fn detection_item(id: u64, seeds: u64) -> Result<DetectionItem> {
    use twincal::diagnose::diagnose;
    use twincal::diagnose::hidden::{clean, clean_tracker, hidden, hidden_realistic, hidden_tracker, realistic};
    let (seed, variant) = Variant::of(id, seeds);
    let opts = options()?;
    let category = variant.category();
    let item = |line, detected, sized, alarm, within_3_sigma, floor_mm| DetectionItem {
        line,
        detected,
        sized,
        alarm,
        category: category.clone(),
        within_3_sigma,
        extra: false,
        floor_mm,
        forward_mm: None,
        remainder: None,
    };
    match variant {
        Variant::Hidden => {
            let (s, robot, truth) = hidden(seed, 1)?;
            let (d, _) = diagnose(&strip(&run_generate(&s, &robot, &Silent)?), &opts, &|_| {})?;
            let (line, named, sized, within) = judge_hidden(seed, &truth[0], &d);
            Ok(DetectionItem { extra: d.causes.len() > 1, ..item(Some(line), named, sized, false, within, 0.0) })
        }
        Variant::Clean => {
            let (s, robot) = clean(10_000 + seed)?;
            let (d, _) = diagnose(&strip(&run_generate(&s, &robot, &Silent)?), &opts, &|_| {})?;
            // A cause named, or the remainder called unexplained, on data with no effect.
            let alarm = !d.causes.is_empty() || d.unexplained.is_some();
            let line = alarm.then(|| {
                format!("    clean seed {}: false alarm {}{}", 10_000 + seed, d.verdict, d.unexplained.as_ref().map_or(String::new(), |u| format!(" ({u})")))
            });
            Ok(item(line, false, false, alarm, false, 0.0))
        }
        Variant::Realistic { decimals, effect: None } => {
            let (s, robot) = realistic(20_000 + seed, decimals)?;
            let (d, _) = diagnose(&strip(&run_generate(&s, &robot, &Silent)?), &opts, &|_| {})?;
            let alarm = !d.causes.is_empty() || d.unexplained.is_some();
            let line = alarm.then(|| {
                format!(
                    "    realistic clean seed {} ({} deg): false alarm {}{}",
                    20_000 + seed,
                    10f64.powi(-(decimals as i32)),
                    d.verdict,
                    d.unexplained.as_ref().map_or(String::new(), |u| format!(" ({u})"))
                )
            });
            Ok(item(line, false, false, alarm, false, d.noise_floor_mm))
        }
        Variant::Realistic { decimals, effect: Some(above) } => {
            let factors = if above { 1.5..4.0 } else { 0.05..0.2 };
            let (s, robot, truth, floor) = hidden_realistic(30_000 + seed, decimals, factors)?;
            let (d, _) = diagnose(&strip(&run_generate(&s, &robot, &Silent)?), &opts, &|_| {})?;
            let (line, named, sized, within) = judge_hidden(30_000 + seed, &truth[0], &d);
            let line = format!("{line} [{} deg logging, {}]", 10f64.powi(-(decimals as i32)), if above { "above the floor" } else { "below the floor" });
            let named_any = !d.causes.is_empty();
            // Below the floor: a miss is right; naming anything is the alarm.
            let extra = above && d.causes.len() > 1;
            let line = if above { (!named || !within || extra).then_some(line) } else { named_any.then_some(line) };
            Ok(DetectionItem { extra, ..item(line, named, sized, !above && named_any, within, floor) })
        }
        Variant::Tracker(TrackerCase::Clean) => {
            let (s, robot) = clean_tracker(40_000 + seed)?;
            let (d, _) = diagnose(&strip(&run_generate(&s, &robot, &Silent)?), &opts, &|_| {})?;
            let alarm = !d.causes.is_empty() || d.unexplained.is_some();
            let line = alarm.then(|| {
                format!(
                    "    tracker clean seed {}: false alarm {}{}",
                    40_000 + seed,
                    d.verdict,
                    d.unexplained.as_ref().map_or(String::new(), |u| format!(" ({u})"))
                )
            });
            Ok(item(line, false, false, alarm, false, d.noise_floor_mm))
        }
        Variant::Tracker(TrackerCase::Half) => {
            let (s, robot, truth, sigma) = hidden_tracker(50_000 + seed, TRACKER_HALF)?;
            let (d, _) = diagnose(&strip(&run_generate(&s, &robot, &Silent)?), &opts, &|_| {})?;
            let (line, named, sized, within) = judge_hidden(50_000 + seed, &truth[0], &d);
            let extra = d.causes.len() > 1;
            let white = d.remainder.as_ref().is_some_and(|r| r.white) && d.unexplained.is_none();
            // The same kind of effect, larger, where the diagnosis may not name its kind: what
            // remains must be reported unexplained.
            let (s2, robot2, truth2, _) = hidden_tracker(55_000 + seed, TRACKER_UNNAMED)?;
            let without = twincal::diagnose::DiagnoseOptions {
                // (A sensor's nonlinearity is a draw-wire's: no candidate for a tracker either.)
                candidates: twincal::calib::effects::EffectKind::ALL
                    .into_iter()
                    .filter(|k| *k != truth2[0].cause && *k != twincal::calib::effects::EffectKind::Nonlinearity)
                    .map(|k| (k, None))
                    .collect(),
                ..opts.clone()
            };
            let (d2, _) = diagnose(&strip(&run_generate(&s2, &robot2, &Silent)?), &without, &|_| {})?;
            let structured = d2.unexplained.is_some();
            let line = (!named || !within || extra || !white || !structured).then(|| {
                format!(
                    "{line} [tracker, {sigma:.4} mm per coordinate; what remains: {}; seed {} with {}{} {:.4} ({:.2}x) not a candidate: {} ({} outliers); what remains: {}]",
                    d.remainder.as_ref().map_or("not characterised".into(), |r| r.summary()),
                    55_000 + seed,
                    truth2[0].cause.name(),
                    truth2[0].joint.map(|j| format!("[j{}]", j + 1)).unwrap_or_default(),
                    truth2[0].magnitude,
                    truth2[0].factor,
                    d2.verdict,
                    d2.outliers.len(),
                    d2.remainder.as_ref().map_or("not characterised".into(), |r| r.summary())
                )
            });
            Ok(DetectionItem { extra, remainder: Some([white, structured]), ..item(line, named, sized, false, within, sigma) })
        }
        Variant::Tracker(TrackerCase::PayloadRuns) => {
            let (s, robot, list, truth, sigma) = twincal::diagnose::hidden::hidden_payload_runs(60_000 + seed, 1.0..2.0)?;
            let g = twincal::sim::pose_list::generate_pose_list(&s, &robot, list, &Silent)?;
            let payload = twincal::robot::statics::Payload { mass_kg: 0.0, com_mm: twincal::diagnose::hidden::PAYLOAD_COM_MM };
            let opts = twincal::diagnose::DiagnoseOptions {
                loads: twincal::calib::pipeline::LoadOptions {
                    joints: twincal::calib::effects::inputs::JointLoads { payload: Some(payload), ..Default::default() },
                    inertial: None,
                },
                ..opts
            };
            let data = strip(&g);
            let (d, _) = diagnose(&data, &opts, &|_| {})?;
            let (line, named, sized, within) = judge_hidden(60_000 + seed, &truth, &d);
            let extra = d.causes.len() > 1;
            // The unloaded run alone, diagnosed as it would be without the other runs.
            let unloaded = Dataset { rows: data.rows.iter().filter(|r| r.payload_kg == Some(0.0)).cloned().collect(), source: data.source.clone() };
            let (du, _) = diagnose(&unloaded, &opts, &|_| {})?;
            let seen_unloaded = du.causes.iter().any(|c| truth.named_by(c));
            let line = Some(format!("{line} [payload runs, {sigma:.4} mm per coordinate; the unloaded run alone: {}]", du.verdict));
            Ok(DetectionItem { extra, ..item(line, named, sized, seen_unloaded, within, sigma) })
        }
        Variant::Tracker(TrackerCase::WarmUp) => {
            let (s, robot, truth, sigma) = twincal::diagnose::hidden::hidden_warm_up(70_000 + seed)?;
            let data = strip(&run_generate(&s, &robot, &Silent)?);
            // As `diagnose` runs it: the tracker's set-up changes searched first (a warm-up must
            // not read as moves of the tracker).
            let request = twincal::requests::DiagnoseRequest::default();
            let d = twincal::jobs::diagnose_loaded(&request, (opts.clone(), Default::default()), data.clone(), &|_| {})?;
            let (line, named, sized, within) = judge_hidden(70_000 + seed, &truth, &d.report);
            let moves = d.report.setup.as_ref().map_or(0, |s| s.stations.len().saturating_sub(1) + s.mounts.len().saturating_sub(1));
            let extra = d.report.causes.len() > 1;
            let (forward, first_verdict) = forward_check(&request, &opts, &data)?;
            let behind = forward[0] > FORWARD_TARGET * forward[1];
            let line = (!named || !within || extra || moves > 0 || behind).then(|| {
                format!(
                    "{line} [warm-up, sensor lag {:.2} of the time constant, {sigma:.4} mm per coordinate; {moves} set-up changes found; on the first {:.0} % {first_verdict}, the rest at {:.4} mm against {:.4} mm by the hidden form]",
                    truth.factor,
                    100.0 * FORWARD_SHARE,
                    forward[0],
                    forward[1]
                )
            });
            let forward_mm = Some(forward);
            // The alarm: a set-up change found on a tracker that never moved.
            Ok(DetectionItem { extra, forward_mm, ..item(line, named, sized, moves > 0, within, sigma) })
        }
        Variant::Tracker(TrackerCase::Moved) => moved_item(80_000 + seed, opts, item),
    }
}

/// A warm-up's forward check: `diagnose` (as the command runs it) on the first
/// [`FORWARD_SHARE`] of the rows in time, and the hidden cause's own form (the whole arm's
/// thermal expansion with the sensor's lag) calibrated on the same rows; each model's RMSE per
/// coordinate on the later rows, mm, and the diagnosis' verdict.
fn forward_check(request: &twincal::requests::DiagnoseRequest, opts: &twincal::diagnose::DiagnoseOptions, data: &Dataset) -> Result<([f64; 2], String)> {
    // As `diagnose --test-fraction 0.3 --split-by time` runs it: the later rows never seen.
    let forward =
        twincal::requests::DiagnoseRequest { test_fraction: Some(1.0 - FORWARD_SHARE), split_by: twincal::calib::pipeline::SplitBy::Time, ..request.clone() };
    let d = twincal::jobs::diagnose_loaded(&forward, (opts.clone(), Default::default()), data.clone(), &|_| {})?;
    let later = Dataset { rows: data.rows[d.data.rows.len()..].to_vec(), source: data.source.clone() };
    let mut truth_form = opts.baseline_options();
    truth_form.effects = vec![(twincal::calib::effects::EffectKind::Thermal, None)];
    let truth = twincal::calib::pipeline::calibrate(&d.data, None, &truth_form)?;
    Ok(([d.result.rmse_on(&later), truth.rmse_on(&later)], d.report.verdict))
}

/// A rigid arm's tracker data with the tracker moved once, diagnosed as the command runs it:
/// `detected` where exactly one station change is found at the row it happened and sized
/// (shift within 2 % + 0.01 mm, turn within 1 % + 0.001°), `alarm` where a cause is named.
fn moved_item(
    seed: u64,
    opts: twincal::diagnose::DiagnoseOptions,
    item: impl Fn(Option<String>, bool, bool, bool, bool, f64) -> DetectionItem,
) -> Result<DetectionItem> {
    let (s, robot, m) = twincal::diagnose::hidden::moved_tracker(seed)?;
    let data = m.apply(&strip(&run_generate(&s, &robot, &Silent)?));
    let sigma = twincal::diagnose::hidden::tracker_row_noise_mm(&s, &robot)?;
    let request = twincal::requests::DiagnoseRequest::default();
    let d = twincal::jobs::diagnose_loaded(&request, (opts, Default::default()), data, &|_| {})?;
    let stations = d.report.setup.as_ref().map_or(&[][..], |s| &s.stations[..]);
    let (shift, turn) = (m.origin_shift_mm(), m.turn_deg());
    let found = match stations {
        [_, st] => st.first_row == m.from + 1 && (st.shift_mm - shift).abs() < 0.02 * shift + 0.01 && (st.turn_deg - turn).abs() < 0.01 * turn + 0.001,
        _ => false,
    };
    let alarm = !d.report.causes.is_empty();
    let at = |st: &twincal::calib::pipeline::SetupPart| format!("row {} {:.3} mm {:.4} deg", st.first_row, st.shift_mm, st.turn_deg);
    let line = (!found || alarm).then(|| {
        format!(
            "    seed {seed}: tracker {:?} at row {} by {shift:.3} mm and {turn:.4} deg -> {} station(s) [{}], {}",
            m.kind,
            m.from + 1,
            stations.len().max(1),
            stations.iter().skip(1).map(at).collect::<Vec<_>>().join("; "),
            d.report.verdict
        )
    });
    Ok(item(line, found, found, alarm, found, sigma))
}

/// The hidden tracker effects' size: what a rigid fit leaves of it, as multiples of one row's
/// noise per coordinate.
const TRACKER_HALF: std::ops::Range<f64> = 0.5..0.6;
/// The size of the tracker effect whose kind is no candidate (its remainder must be reported
/// unexplained), as multiples of one row's noise per coordinate.
const TRACKER_UNNAMED: std::ops::Range<f64> = 2.0..3.0;

/// The detection part's lines and rates, from every item in order (what `bench diagnose`
/// prints, and `reduce` the same from the shards' parts).
pub fn print_detection(config: &DetectionConfig, items: &[DetectionItem]) {
    for line in items.iter().filter_map(|i| i.line.as_ref()) {
        println!("{line}");
    }
    let seeds = config.seeds;
    let of = |cat: &str| items.iter().filter(|i| i.category == cat).collect::<Vec<_>>();
    let n = seeds as f64;
    let hidden = of("hidden");
    let (detected, sized) = (count(&hidden, |i| i.detected), count(&hidden, |i| i.sized));
    if !hidden.is_empty() {
        println!(
            "  hidden effects: {detected}/{seeds} named first with the right joint ({:.0} %, target >= 95 %), {sized}/{seeds} also sized right, {}/{seeds} name a cause not hidden",
            100.0 * detected as f64 / n,
            count(&hidden, |i| i.extra)
        );
    }
    let clean = of("clean");
    let alarms = count(&clean, |i| i.alarm);
    if !clean.is_empty() {
        println!("  clean datasets: {alarms}/{seeds} false alarms, a cause or an unexplained remainder ({:.0} %, target <= 5 %)", 100.0 * alarms as f64 / n);
    }
    for decimals in [1usize, 2] {
        let clean = of(&format!("realistic-{decimals}-clean"));
        let above = of(&format!("realistic-{decimals}-above"));
        let below = of(&format!("realistic-{decimals}-below"));
        if clean.is_empty() && above.is_empty() && below.is_empty() {
            continue;
        }
        // The generator's floor of the items with an effect; with none run, the floor the clean
        // items' diagnoses stated.
        let floor_of = |items: &[&DetectionItem]| items.iter().map(|i| i.floor_mm).filter(|f| *f > 0.0).collect::<Vec<f64>>();
        let floors = if above.is_empty() && below.is_empty() { floor_of(&clean) } else { floor_of(&[&above[..], &below[..]].concat()) };
        println!(
            "  realistic acquisitions, angles logged at {} deg (sweeps of {}, {} glitch runs; floor {:.4} mm median):",
            10f64.powi(-(decimals as i32)),
            twincal::diagnose::hidden::REALISTIC_SWEEP,
            twincal::diagnose::hidden::REALISTIC_GLITCHES.0,
            median(&floors)
        );
        if !clean.is_empty() {
            println!("    no effect: {}/{} false alarms, a cause or an unexplained remainder (target 0)", count(&clean, |i| i.alarm), clean.len());
        }
        if !above.is_empty() {
            println!(
                "    one effect at 1.5-4x the floor: {}/{} named first with the right joint (target >= 95 %), {}/{} sized within 3 sigma, {}/{} name a cause not hidden",
                count(&above, |i| i.detected),
                above.len(),
                count(&above, |i| i.within_3_sigma),
                above.len(),
                count(&above, |i| i.extra),
                above.len()
            );
        }
        if !below.is_empty() {
            println!("    one effect at 0.05-0.2x the floor: {}/{} named anything (target 0)", count(&below, |i| i.alarm), below.len());
        }
    }
    print_tracker(&of("tracker-clean"), &of("tracker-half"));
    print_payload_runs(&of("tracker-payload"));
    print_warm_up(&of("tracker-warmup"));
    print_moved(&of("tracker-moved"));
}

/// The moved-tracker category's rates: the set-up change found and sized, no cause named.
fn print_moved(runs: &[&DetectionItem]) {
    if runs.is_empty() {
        return;
    }
    println!(
        "  a moved tracker ({} rows of a rigid arm, the tracker re-stationed, re-registered or bumped once between 30 and 70 % of the rows):",
        twincal::diagnose::hidden::TRACKER_POSES
    );
    let [found, _, _, alarm] = rates(runs);
    println!("    {found} set-up changes found at their row and sized (target 20/20), {alarm} false alarms: a cause named (target 0)");
}

/// How many of `items` `f` holds for.
fn count(items: &[&DetectionItem], f: fn(&DetectionItem) -> bool) -> usize {
    items.iter().filter(|i| f(i)).count()
}

/// The payload-run category's rates: the compliance named and sized.
fn print_payload_runs(runs: &[&DetectionItem]) {
    if runs.is_empty() {
        return;
    }
    use twincal::diagnose::hidden::{PAYLOAD_RUNS_KG, PAYLOAD_RUN_POSES, UNLOADED_FACTOR};
    println!(
        "  payload runs ({PAYLOAD_RUN_POSES} tracker poses at each of {PAYLOAD_RUNS_KG:?} kg; a joint compliance at 1-2x one row's noise over the runs where it stays under {UNLOADED_FACTOR}x in the unloaded run, else at {UNLOADED_FACTOR}x there):"
    );
    let [named, sized, extra, alarm] = rates(runs);
    println!(
        "    {named} named first with the right joint (target >= 95 %), {sized} sized within 3 sigma, {extra} name a cause not hidden; the unloaded run alone names it on {alarm}"
    );
}

/// `k/n` of the items named first, sized within 3σ, naming a cause not hidden, and alarmed.
fn rates(runs: &[&DetectionItem]) -> [String; 4] {
    let of = |f: fn(&DetectionItem) -> bool| format!("{}/{}", count(runs, f), runs.len());
    [of(|i| i.detected), of(|i| i.within_3_sigma), of(|i| i.extra), of(|i| i.alarm)]
}

/// The warm-up category's rates: the expansion named and sized, no set-up change found.
fn print_warm_up(runs: &[&DetectionItem]) {
    if runs.is_empty() {
        return;
    }
    use twincal::diagnose::hidden::{WARM_UP_ALPHA_PPM, WARM_UP_LAG_SHARE, WARM_UP_RISE_K, WARM_UP_TAU_S, WARM_UP_TEMP_NOISE_K};
    println!(
        "  warm-ups ({} tracker rows; {}-{} ppm/K over a {}-{} K rise, time constant {}-{} s, the temperature sensor lagging {}-{} of it, {WARM_UP_TEMP_NOISE_K} K reading noise):",
        twincal::diagnose::hidden::TRACKER_POSES,
        WARM_UP_ALPHA_PPM.start,
        WARM_UP_ALPHA_PPM.end,
        WARM_UP_RISE_K.start,
        WARM_UP_RISE_K.end,
        WARM_UP_TAU_S.start,
        WARM_UP_TAU_S.end,
        WARM_UP_LAG_SHARE.start,
        WARM_UP_LAG_SHARE.end
    );
    let [named, sized, extra, alarm] = rates(runs);
    println!(
        "    {named} named first (target >= 95 %), {sized} sized within 3 sigma (target >= 95 %), {extra} name a cause not hidden, {alarm} find a set-up change that did not happen (target 0)"
    );
    let ratios: Vec<f64> = runs.iter().filter_map(|i| i.forward_mm).map(|[d, t]| d / t).collect();
    if !ratios.is_empty() {
        let within = ratios.iter().filter(|r| **r <= FORWARD_TARGET).count();
        let later: Vec<f64> = runs.iter().filter_map(|i| i.forward_mm).map(|[d, _]| d).collect();
        let truth: Vec<f64> = runs.iter().filter_map(|i| i.forward_mm).map(|[_, t]| t).collect();
        println!(
            "    forward in time (diagnosed on the first {:.0} % of the rows, judged on the rest): {within}/{} within {FORWARD_TARGET}x the error of the hidden cause's own form calibrated on the same rows (median {:.4} against {:.4} mm per coordinate; ratio median {:.2}, worst {:.2})",
            100.0 * FORWARD_SHARE,
            ratios.len(),
            median(&later),
            median(&truth),
            median(&ratios),
            ratios.iter().copied().fold(0.0, f64::max)
        );
    }
}

/// The tracker categories' rates: false alarms on clean rows, the half-noise effect named.
fn print_tracker(clean: &[&DetectionItem], half: &[&DetectionItem]) {
    if clean.is_empty() && half.is_empty() {
        return;
    }
    let noise: Vec<f64> = half.iter().chain(clean).map(|i| i.floor_mm).filter(|f| *f > 0.0).collect();
    println!(
        "  tracker points ({} independent rows with sx, sy, sz; one row's noise {:.4} mm per coordinate, median):",
        twincal::diagnose::hidden::TRACKER_POSES,
        median(&noise)
    );
    if !clean.is_empty() {
        println!("    no effect: {}/{} false alarms, a cause or an unexplained remainder (target 0)", count(clean, |i| i.alarm), clean.len());
    }
    if !half.is_empty() {
        println!(
            "    one effect at {}-{}x one row's noise: {}/{} named first with the right joint (target >= 95 %), {}/{} sized within 3 sigma, {}/{} name a cause not hidden",
            TRACKER_HALF.start,
            TRACKER_HALF.end,
            count(half, |i| i.detected),
            half.len(),
            count(half, |i| i.within_3_sigma),
            half.len(),
            count(half, |i| i.extra),
            half.len()
        );
        let with = |k: usize| half.iter().filter(|i| i.remainder.is_some_and(|r| r[k])).count();
        println!(
            "    what remains after the named cause: {}/{} white at the instrument's noise, not unexplained (target all); an effect at {}-{}x the noise whose kind is no candidate: {}/{} reported unexplained (target all)",
            with(0),
            half.len(),
            TRACKER_UNNAMED.start,
            TRACKER_UNNAMED.end,
            with(1),
            half.len()
        );
    }
}

/// `twincal bench diagnose`: the 600-pose all-effects diagnosis timed (median of `repeat` runs,
/// time per candidate), then `seeds` scenarios with one hidden effect (cause, joint and size from the
/// seed) and `seeds` clean ones: detection rate (cause and joint named first, size within its
/// uncertainty band or 30 %) and false-alarm rate. With a shard, only its detection items
/// (the timing is a single machine's and is left out).
pub fn bench_diagnose(seeds: u64, repeat: usize, bar: &dyn Progress, shard: Option<&crate::shard::Shard>, config: &DetectionConfig) -> Result<()> {
    use twincal::diagnose::diagnose;
    let ids = config.ids();
    if let Some(sh) = shard {
        let mine: Vec<u64> = (0..ids.len() as u64).filter(|k| sh.wants(*k)).collect();
        bar.start(mine.len() as u64, "diagnoses");
        for k in &mine {
            sh.append(*k, config, &detection_item(ids[*k as usize], seeds)?)?;
            bar.inc(1);
        }
        bar.finish();
        eprintln!("{}", sh.summary(mine.len()));
        return Ok(());
    }
    let opts = options()?;
    println!("diagnosis benchmark");
    // 1. Speed on the embedded 600-pose scenario with every effect.
    let (s, robot) = Scenario::default_embedded()?;
    let g = run_generate(&s, &robot, &Silent)?;
    let data = strip(&g);
    let mut times = Vec::new();
    let mut per_candidate = Vec::new();
    let mut evaluated = 0;
    let mut verdict = String::new();
    for _ in 0..repeat {
        let t0 = Instant::now();
        let (d, _) = diagnose(&data, &opts, &|_| {})?;
        times.push(t0.elapsed().as_secs_f64());
        let c: Vec<f64> = d.steps.iter().flat_map(|st| st.candidates.iter().map(|c| c.seconds)).collect();
        evaluated = c.len();
        per_candidate.push(median(&c));
        verdict = d.verdict.clone();
    }
    println!(
        "  {} poses, every effect, {} threads: {:.2} s median (target < 10 s); {evaluated} candidate fits, {:.0} ms each (median, one thread each); found {verdict}",
        data.rows.len(),
        rayon::current_num_threads(),
        median(&times),
        median(&per_candidate) * 1e3
    );
    // 2. What the logging error's noise model costs: a realistic acquisition (sweeps, angles
    // logged at 0.1°) diagnosed with and without it, median of `repeat` runs each.
    let (s, robot) = twincal::diagnose::hidden::realistic(20_001, 1)?;
    let data = strip(&run_generate(&s, &robot, &Silent)?);
    let timed = |choice: twincal::calib::fit::noise_model::NoiseChoice| -> Result<(f64, String)> {
        let opts = {
            let mut o = options()?;
            o.floor.noise_model = choice;
            o
        };
        let mut t = Vec::new();
        let mut verdict = String::new();
        for _ in 0..repeat {
            let t0 = Instant::now();
            verdict = diagnose(&data, &opts, &|_| {})?.0.verdict;
            t.push(t0.elapsed().as_secs_f64());
        }
        Ok((median(&t), verdict))
    };
    let ((on, v_on), (off, v_off)) = (timed(twincal::calib::fit::noise_model::NoiseChoice::Auto)?, timed(twincal::calib::fit::noise_model::NoiseChoice::Off)?);
    println!(
        "  the logging noise model's cost: {} poses in sweeps, angles logged at 0.1 deg: {on:.2} s with it, {off:.2} s without (ratio {:.2}, medians of {repeat}); found {v_on} / {v_off}",
        data.rows.len(),
        on / off
    );
    // 3. Detection and false alarms.
    bar.start(ids.len() as u64, "diagnoses");
    let mut items = Vec::new();
    for &id in &ids {
        items.push(detection_item(id, seeds)?);
        bar.inc(1);
    }
    bar.finish();
    print_detection(config, &items);
    Ok(())
}

/// `twincal reduce` of `bench diagnose` shards: the detection part's lines and rates.
pub fn reduce_detection(parts: crate::shard::Parts, quiet: bool) -> Result<()> {
    let files = parts.files;
    let (config, items, duplicates) = parts.gather::<DetectionConfig, DetectionItem>()?;
    if !quiet {
        eprintln!("reduced {files} parts: {} diagnoses of bench diagnose (detection, {} seeds), {duplicates} duplicates dropped", items.len(), config.seeds);
    }
    println!("diagnosis benchmark: detection and false alarms (sharded; the timing is one machine's: run bench diagnose unsharded)");
    print_detection(&config, &items);
    Ok(())
}
