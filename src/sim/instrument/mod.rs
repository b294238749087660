//! The twin's instruments. The draw-wire (cable) length sensor the papers use is always there:
//! it carries the tool point (the target on the flange), the hold and the samples averaged, and
//! reads the cable when no other instrument does. Another instrument (a laser tracker reading the
//! tool point in 3-D, or a 6-D probe's pose) reads instead of the cable, through the
//! calibration's own [`Instrument`](crate::measurement::Instrument) reading (one reading function
//! for the twin and the fit).
//!
//! Adding an instrument to the twin means one module implementing [`TwinInstrument`] and its
//! key in [`Instruments`] (the scenario's table of that name, with its line in
//! [`Instruments::active`]); what the twin writes of it (the dataset's columns, the truth's
//! readings and placement) follows from the trait.

pub mod drawwire;
pub mod tracker;
pub use drawwire::DrawWire;
pub use tracker::Tracker;

use crate::dataset::truth::PoseTruth;
use crate::measurement::{Measurement, Placement};
use nalgebra::{Matrix3, Vector3};
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

/// What an instrument other than the cable read at one pose.
#[derive(Clone, Debug, PartialEq)]
pub struct TwinReading {
    /// What a perfect instrument reads: the dataset's reading columns (mm, and degrees for
    /// angles).
    pub ideal: Vec<f64>,
    /// What it wrote: the same columns with its noise, at its written decimals.
    pub read: Vec<f64>,
    /// Standard deviation of one written length value, mm (its noise averaged over the
    /// samples).
    pub std_mm: f64,
    /// Whether the dataset gets that standard deviation as `sx, sy, sz`.
    pub write_std: bool,
}

/// An instrument that reads the tool point (and the flange's orientation) instead of the cable.
pub trait TwinInstrument: Sync {
    /// The scenario's key of its table ("tracker").
    fn key(&self) -> &'static str;
    /// What it reads (the calibration's measurement type).
    fn measurement(&self) -> Measurement;
    /// Its true placement, reading the target `tool` (flange frame, m).
    fn placement(&self, tool: Vector3<f64>) -> Placement;
    /// Its reading of the target at `p` (base frame, m) on the flange rotated by `flange_rot`:
    /// the mean of `samples` samples, its noise drawn from `rng`.
    fn reading(&self, p: &Vector3<f64>, flange_rot: &Matrix3<f64>, samples: usize, rng: &mut ChaCha8Rng) -> TwinReading;
    /// The station pose `pose` (0-based, acquisition order) is read from (0: where the scenario
    /// places it; an instrument moved during the acquisition counts its moves), and whether the
    /// dataset states it (a `station` column).
    fn station(&self, _pose: usize) -> (usize, bool) {
        (0, false)
    }
    /// [`Self::reading`] of pose `pose`, from the station the instrument stood at then.
    fn reading_at(&self, _pose: usize, p: &Vector3<f64>, flange_rot: &Matrix3<f64>, samples: usize, rng: &mut ChaCha8Rng) -> TwinReading {
        self.reading(p, flange_rot, samples, rng)
    }
    /// One raw sample's length values (mm) of the target at `p` (base frame, m), for a
    /// simulated acquisition's stability gate.
    fn raw_sample(&self, p: &Vector3<f64>, rng: &mut ChaCha8Rng) -> Vec<f64>;
    /// An error naming the key whose value is out of range.
    fn validate(&self) -> Result<(), String>;
    /// Its noise as the scenario states it, for messages ("tracker noise 5 µm + 2 µm/m").
    fn noise(&self) -> String;
    /// Writes pose truth `t`'s record of reading `r`: by default the generic
    /// `reading_true` / `reading_measured`.
    fn record(&self, r: &TwinReading, t: &mut PoseTruth) {
        t.reading_true = Some(r.ideal.clone());
        t.reading_measured = Some(r.read.clone());
    }
    /// Whether truth.json states its placement in a table of its own (the tracker's); else the
    /// truth's generic `instrument` entry holds it.
    fn own_truth_table(&self) -> bool {
        false
    }
}

/// The scenario's instruments other than the cable (at most one): each a table of its own.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Instruments {
    /// A laser tracker instead of the cable's reading: the dataset then holds the tool point's
    /// `x, y, z` in the tracker's frame (with a 6-D probe also its orientation). The `[sensor]`
    /// still gives the tool point (the reflector), the hold and the samples averaged; it pulls
    /// no cable.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tracker: Option<Tracker>,
}

impl Instruments {
    /// Every instrument the scenario names, in key order.
    fn all(&self) -> Vec<&dyn TwinInstrument> {
        let mut v: Vec<&dyn TwinInstrument> = Vec::new();
        if let Some(t) = &self.tracker {
            v.push(t);
        }
        v
    }

    /// The instrument that reads instead of the cable, if any.
    pub fn active(&self) -> Option<&dyn TwinInstrument> {
        self.all().into_iter().next()
    }

    /// An error naming the key whose value is out of range, or the two instruments that would
    /// both read.
    pub fn validate(&self) -> Result<(), String> {
        let all = self.all();
        if let [a, b, ..] = all.as_slice() {
            return Err(format!("[{}] and [{}] both read the tool point: a scenario has one instrument besides the cable", a.key(), b.key()));
        }
        all.iter().try_for_each(|i| i.validate())
    }

    /// What the twin reads: the active instrument's measurement, else the cable's length.
    pub fn measurement(&self) -> Measurement {
        self.active().map_or(Measurement::Length, |i| i.measurement())
    }
}

/// The true placement (m, rad) of the instrument a twin reads with: the other instrument's when
/// there is one, else the draw-wire's; the target is the sensor's tool point.
pub fn placement(sensor: &DrawWire, instruments: &Instruments) -> Placement {
    let tool = sensor.tool_point_m();
    match instruments.active() {
        Some(i) => i.placement(tool),
        None => Placement::cable(sensor.exit_point_m(), crate::units::to_m(sensor.length_offset_mm), tool),
    }
}
