//! A laser tracker following a reflector on the flange (the scenario's `[tracker]`): it reads
//! the reflector's position in its own frame. The reflector is the sensor's tool point (the
//! point the twin carries on the flange). The reading is the calibration's own
//! [`Measurement::Point`] of the true reflector position, plus the tracker's volumetric noise
//! (a + b·distance, one standard deviation per coordinate), averaged over the sensor's samples,
//! rounded to the written decimals. Line of sight is not modelled: every pose is seen.

use crate::measurement::Measurement;
use nalgebra::Vector3;
use rand::Rng;
use serde::{Deserialize, Serialize};

/// Largest tracker distance from the base origin, mm (a tracker reaches about 80 m).
pub const MAX_DISTANCE_MM: f64 = 80_000.0;
/// Most decimals of a written coordinate (mm): 1 nm.
pub const MAX_DECIMALS: usize = 6;

/// One reading of [`Tracker::read`], mm.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TrackerReading {
    /// What a perfect tracker reads (the reflector in the tracker's frame).
    pub ideal_mm: [f64; 3],
    /// The mean of the noisy samples, unrounded.
    pub read_mm: [f64; 3],
    /// Standard deviation of one coordinate of that mean.
    pub std_mm: f64,
}

/// A laser tracker (the scenario's `[tracker]`): its placement, noise and written decimals.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Tracker {
    /// The base-to-tracker translation `t` of `y = R·p + t` (a base-frame point `p` read in the
    /// tracker's frame), mm.
    pub translation_mm: [f64; 3],
    /// The base-to-tracker rotation `R = Rx(a)·Ry(b)·Rz(c)`, degrees.
    #[serde(default)]
    pub rotation_deg: [f64; 3],
    /// Noise of one coordinate of one sample: a constant part, µm.
    #[serde(default)]
    pub noise_um: f64,
    /// ... and a part growing with the distance from the tracker, µm per m.
    #[serde(default)]
    pub noise_um_per_m: f64,
    /// Decimals of a written coordinate, mm.
    #[serde(default = "Tracker::default_decimals")]
    pub decimals: usize,
    /// A 6-D probe instead of a reflector: its orientation on the flange (intrinsic X-Y-Z Euler
    /// angles, degrees). The tracker then also reads the probe's orientation, written as
    /// `rx, ry, rz` (degrees, intrinsic X-Y-Z, in the tracker's frame).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub probe_rotation_deg: Option<[f64; 3]>,
    /// Noise of one sample's orientation about each axis, µrad (a 6-D probe).
    #[serde(default, skip_serializing_if = "is_zero")]
    pub orientation_noise_urad: f64,
    /// Decimals of a written angle, degrees (a 6-D probe).
    #[serde(default = "Tracker::default_angle_decimals", skip_serializing_if = "is_default_angle_decimals")]
    pub angle_decimals: usize,
    /// Write each row's standard deviation of a coordinate (the noise above, averaged over the
    /// samples: what a tracker logs beside its point) as the dataset's `sx, sy, sz`, mm.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub write_std: bool,
    /// Where the tracker stood from a pose on, when it was re-stationed, re-registered or bumped
    /// during the acquisition: each move a station of its own (`2`, `3`, ... after the first,
    /// `1`), in the order of their `from_pose`.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub moves: Vec<TrackerMove>,
    /// Write each row's station as the dataset's `station` column (else the calibration must
    /// find the moves itself).
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub write_station: bool,
}

/// A tracker moved during the acquisition ([`Tracker::moves`]).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TrackerMove {
    /// The first pose (0-based, in acquisition order) read from the new station.
    pub from_pose: usize,
    /// The base-to-tracker translation from then on, mm (as [`Tracker::translation_mm`]).
    pub translation_mm: [f64; 3],
    /// The base-to-tracker rotation from then on, degrees (as [`Tracker::rotation_deg`]).
    #[serde(default)]
    pub rotation_deg: [f64; 3],
}

fn is_zero(v: &f64) -> bool {
    *v == 0.0
}

fn is_default_angle_decimals(v: &usize) -> bool {
    *v == Tracker::default_angle_decimals()
}

/// One 6-D reading of [`Tracker::read_pose`]: position (mm) and intrinsic X-Y-Z angles (degrees).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PoseReading {
    /// What a perfect tracker reads.
    pub ideal: [f64; 6],
    /// The position as [`Tracker::read`] gives it (mean of the noisy samples, unrounded), then the
    /// noisy orientation.
    pub read: [f64; 6],
}

impl Tracker {
    fn default_decimals() -> usize {
        4
    }
    fn default_angle_decimals() -> usize {
        6
    }

    /// A 6-D reading of the probe whose origin is at `p` (base frame, m) on the flange rotated
    /// by `flange_rot`: the position as [`Self::read`] gives it (same noise draws), then the
    /// orientation turned by a small rotation of `orientation_noise_urad / √samples` per axis.
    pub fn read_pose(&self, p: &Vector3<f64>, flange_rot: &nalgebra::Matrix3<f64>, samples: usize, rng: &mut impl Rng) -> (TrackerReading, PoseReading) {
        use crate::measurement::pose::xyz_angles;
        let point = self.read(p, samples, rng);
        let probe = crate::measurement::Euler::XYZ.matrix(self.probe_rotation_deg.unwrap_or_default().map(f64::to_radians));
        let r = crate::measurement::point::tracker_rotation(&self.own()) * flange_rot * probe;
        let sd = self.orientation_noise_urad * 1e-6 / (samples.max(1) as f64).sqrt();
        let d = Vector3::from_fn(|_, _| sd * rng.sample::<f64, _>(rand_distr::StandardNormal));
        let noisy = r * nalgebra::Rotation3::new(d).into_inner();
        let deg = |m: &nalgebra::Matrix3<f64>| xyz_angles(m).map(f64::to_degrees);
        let (a, b) = (deg(&r), deg(&noisy));
        let pose = PoseReading {
            ideal: [point.ideal_mm[0], point.ideal_mm[1], point.ideal_mm[2], a[0], a[1], a[2]],
            read: [point.read_mm[0], point.read_mm[1], point.read_mm[2], b[0], b[1], b[2]],
        };
        (point, pose)
    }

    /// The placement parameters [`Measurement::Point`] reads (m, rad).
    pub fn own(&self) -> Vec<f64> {
        crate::measurement::Placement::tracker(self.translation_mm, self.rotation_deg, None, Vector3::zeros()).own
    }

    /// The noise-free reading of reflector position `p` (base frame, m), mm.
    pub fn ideal_mm(&self, p: &Vector3<f64>) -> [f64; 3] {
        let mut y = [0.0; 3];
        Measurement::Point.reading(&self.own(), p, &mut y);
        y.map(crate::units::to_mm)
    }

    /// A reading of reflector position `p` (m): the mean of `samples` noisy samples.
    pub fn read(&self, p: &Vector3<f64>, samples: usize, rng: &mut impl Rng) -> TrackerReading {
        let ideal_mm = self.ideal_mm(p);
        // One sample's noise grows with the distance from the tracker.
        let distance_m = crate::units::to_m(ideal_mm.iter().map(|v| v * v).sum::<f64>().sqrt());
        let std_mm = (self.noise_um + self.noise_um_per_m * distance_m) * 1e-3 / (samples.max(1) as f64).sqrt();
        let read_mm = ideal_mm.map(|v| v + std_mm * rng.sample::<f64, _>(rand_distr::StandardNormal));
        TrackerReading { ideal_mm, read_mm, std_mm }
    }

    /// The station pose `i` (0-based, acquisition order) is read from: 0 before the first move.
    pub fn station_of_pose(&self, i: usize) -> usize {
        self.moves.iter().take_while(|m| m.from_pose <= i).count()
    }

    /// The tracker as it stood at station `k` ([`Self::station_of_pose`]).
    pub fn at_station(&self, k: usize) -> Tracker {
        match k.checked_sub(1).and_then(|m| self.moves.get(m)) {
            Some(m) => Tracker { translation_mm: m.translation_mm, rotation_deg: m.rotation_deg, moves: Vec::new(), write_station: false, ..self.clone() },
            None => Tracker { moves: Vec::new(), write_station: false, ..self.clone() },
        }
    }

    /// An error naming the key whose value is out of range.
    fn check(&self) -> Result<(), String> {
        for (k, m) in self.moves.iter().enumerate() {
            if m.from_pose == 0 || (k > 0 && m.from_pose <= self.moves[k - 1].from_pose) {
                return Err(format!("tracker.moves[{k}].from_pose = {}: the moves start after pose 0, each after the one before", m.from_pose));
            }
            let at = self.at_station(k + 1);
            at.check().map_err(|e| e.replacen("tracker.", &format!("tracker.moves[{k}]."), 1))?;
        }
        if self.write_station && self.moves.is_empty() {
            return Err("tracker.write_station writes the stations of tracker.moves: give the moves too".into());
        }
        if let Some(v) = self.translation_mm.iter().find(|v| !(v.is_finite() && v.abs() <= MAX_DISTANCE_MM)) {
            return Err(format!("tracker.translation_mm holds {v}: each coordinate must be finite and within ±{MAX_DISTANCE_MM} mm"));
        }
        if let Some(v) = self.rotation_deg.iter().find(|v| !(v.is_finite() && v.abs() <= 360.0)) {
            return Err(format!("tracker.rotation_deg holds {v}: each angle must be finite and within ±360 degrees"));
        }
        for (key, v) in [("noise_um", self.noise_um), ("noise_um_per_m", self.noise_um_per_m)] {
            if !(v.is_finite() && (0.0..=1000.0).contains(&v)) {
                return Err(format!("tracker.{key} = {v} must be in [0, 1000]"));
            }
        }
        if let Some(v) = self.probe_rotation_deg.iter().flatten().find(|v| !(v.is_finite() && v.abs() <= 360.0)) {
            return Err(format!("tracker.probe_rotation_deg holds {v}: each angle must be finite and within ±360 degrees"));
        }
        if !(self.orientation_noise_urad.is_finite() && (0.0..=10_000.0).contains(&self.orientation_noise_urad)) {
            return Err(format!("tracker.orientation_noise_urad = {} must be in [0, 10000]", self.orientation_noise_urad));
        }
        if self.orientation_noise_urad > 0.0 && self.probe_rotation_deg.is_none() {
            return Err("tracker.orientation_noise_urad is a 6-D probe's: give tracker.probe_rotation_deg too".into());
        }
        if self.angle_decimals > 9 {
            return Err(format!("tracker.angle_decimals = {} must be at most 9", self.angle_decimals));
        }
        if self.decimals > MAX_DECIMALS {
            return Err(format!("tracker.decimals = {} must be at most {MAX_DECIMALS}", self.decimals));
        }
        Ok(())
    }
}

impl super::TwinInstrument for Tracker {
    fn key(&self) -> &'static str {
        "tracker"
    }
    /// A point, or a pose with a 6-D probe.
    fn measurement(&self) -> Measurement {
        if self.probe_rotation_deg.is_some() {
            Measurement::Pose
        } else {
            Measurement::Point
        }
    }
    fn placement(&self, tool: Vector3<f64>) -> crate::measurement::Placement {
        crate::measurement::Placement::tracker(self.translation_mm, self.rotation_deg, self.probe_rotation_deg, tool)
    }
    fn station(&self, pose: usize) -> (usize, bool) {
        (self.station_of_pose(pose), self.write_station)
    }
    fn reading_at(
        &self,
        pose: usize,
        p: &Vector3<f64>,
        flange_rot: &nalgebra::Matrix3<f64>,
        samples: usize,
        rng: &mut rand_chacha::ChaCha8Rng,
    ) -> super::TwinReading {
        match self.station_of_pose(pose) {
            0 => self.reading(p, flange_rot, samples, rng),
            k => self.at_station(k).reading(p, flange_rot, samples, rng),
        }
    }
    fn reading(&self, p: &Vector3<f64>, flange_rot: &nalgebra::Matrix3<f64>, samples: usize, rng: &mut rand_chacha::ChaCha8Rng) -> super::TwinReading {
        use crate::units::round_decimals;
        if self.probe_rotation_deg.is_some() {
            // A 6-D probe also reads the flange's orientation.
            let (r, pose) = self.read_pose(p, flange_rot, samples, rng);
            let read = pose.read.iter().enumerate().map(|(k, v)| round_decimals(*v, if k < 3 { self.decimals } else { self.angle_decimals })).collect();
            super::TwinReading { ideal: pose.ideal.to_vec(), read, std_mm: r.std_mm, write_std: self.write_std }
        } else {
            let r = self.read(p, samples, rng);
            super::TwinReading {
                ideal: r.ideal_mm.to_vec(),
                read: r.read_mm.map(|v| round_decimals(v, self.decimals)).to_vec(),
                std_mm: r.std_mm,
                write_std: self.write_std,
            }
        }
    }
    fn raw_sample(&self, p: &Vector3<f64>, rng: &mut rand_chacha::ChaCha8Rng) -> Vec<f64> {
        self.read(p, 1, rng).read_mm.to_vec()
    }
    fn validate(&self) -> Result<(), String> {
        self.check()
    }
    /// Its noise grows with the distance.
    fn noise(&self) -> String {
        format!("tracker noise {} µm + {} µm/m", self.noise_um, self.noise_um_per_m)
    }
    /// The reflector's point as `point_true_mm` / `point_measured_mm`, a probe's pose as
    /// `pose_true` (the truth's tracker fields).
    fn record(&self, r: &super::TwinReading, t: &mut crate::dataset::truth::PoseTruth) {
        t.point_true_mm = Some([r.ideal[0], r.ideal[1], r.ideal[2]]);
        t.point_measured_mm = Some([r.read[0], r.read[1], r.read[2]]);
        t.pose_true = (r.ideal.len() == 6).then(|| [r.ideal[0], r.ideal[1], r.ideal[2], r.ideal[3], r.ideal[4], r.ideal[5]]);
    }
    fn own_truth_table(&self) -> bool {
        true
    }
}
