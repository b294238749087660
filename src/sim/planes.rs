//! The twin touching the faces of an artifact (`[planes]` in a scenario): a block with flat
//! faces (a step of two parallel faces a known height apart, a side), placed in the cell one or
//! more times; a touch-trigger probe on the flange touches each face in many configurations
//! (the tool tilted about the face's normal, turned about its own axis) and the joint angles
//! are latched at the trigger — or a dial indicator on the flange is pressed onto each face and
//! its plunger's travel is read with the joints. What really happens is simulated: the stylus'
//! ball touches the face with its radius, the probe travels on past the touch before it
//! triggers (its pre-travel, larger in some directions than others: lobing) and its trigger
//! scatters; the probe's trigger force and gravity load the joints against their compliance on
//! a backlash flank; the indicator's plunger, tilted from the face's normal, reads its travel
//! along its own axis (a cosine error) to its resolution; the step was made off its drawing
//! and the block grows with its temperature; the encoders log what the motors read.

use super::artifact::{flange_for, logged_angles, reach, ArtifactPlacement, IK_STARTS, REFERENCE_TEMP_C};
use crate::dataset::{Dataset, Feature, Row, Split};
use crate::error::{Error, Result};
use crate::robot::Robot;
use crate::seed::{stream_seed, Stream};
use crate::sim::twin::Twin;
use nalgebra::Vector3;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use serde::{Deserialize, Serialize};

/// The file `generate` writes a faces dataset's truth to, beside dataset.csv.
pub const PLANES_TRUTH_FILE: &str = "planes.json";

/// One face of the block, in the block's frame.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Face {
    /// Its label (the `plane` column).
    pub label: String,
    /// A point of the face (its middle), mm.
    pub point_mm: [f64; 3],
    /// Its outward normal (need not be unit).
    pub normal: [f64; 3],
    /// Half the side of the square around `point_mm` the probe touches within, mm.
    #[serde(default = "Face::default_extent")]
    pub extent_mm: f64,
}

impl Face {
    fn default_extent() -> f64 {
        15.0
    }
    fn unit_normal(&self) -> Vector3<f64> {
        Vector3::from(self.normal).normalize()
    }
}

/// A block of faces and the probe (or dial indicator) that touches them (`[planes]`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Planes {
    /// The stylus ball's centre on the flange (flange frame), mm; with `indicator`, the
    /// indicator's zero point (its plunger's tip at zero travel).
    pub stylus_mm: [f64; 3],
    /// The stylus ball's radius, mm.
    #[serde(default = "Planes::default_radius")]
    pub stylus_radius_mm: f64,
    /// How far the probe travels on past the touch before it triggers, µm (mean).
    #[serde(default)]
    pub pretravel_um: f64,
    /// The pre-travel's variation with the direction of the touch in the probe's frame (a
    /// kinematic probe's three lobes), amplitude, µm.
    #[serde(default)]
    pub lobing_um: f64,
    /// The trigger's scatter (one standard deviation), µm.
    #[serde(default)]
    pub trigger_std_um: f64,
    /// The probe's trigger force (the indicator's spring) along the approach, N.
    #[serde(default)]
    pub force_n: f64,
    /// A dial indicator instead of a touch probe: each row reads the plunger's travel.
    #[serde(default)]
    pub indicator: bool,
    /// The indicator's travel the plunger is pressed to, at random within, mm.
    #[serde(default = "Planes::default_travel")]
    pub travel_mm: f64,
    /// The indicator's resolution (the reading is rounded to it), mm.
    #[serde(default = "Planes::default_resolution")]
    pub resolution_mm: f64,
    /// The block's faces.
    pub faces: Vec<Face>,
    /// How far each face was made from its drawing along its normal, mm (zero by default).
    #[serde(default)]
    pub made_error_mm: Vec<f64>,
    /// The block's thermal expansion, ppm/K (steel 12, aluminium 23, printed PLA about 68).
    #[serde(default)]
    pub expansion_ppm_per_k: f64,
    /// The block's temperature while touched, °C (it was made at 20 °C).
    #[serde(default = "Planes::default_temp")]
    pub temp_c: f64,
    /// Contacts per face and placement.
    pub per_face: usize,
    /// Largest angle between the approach and the face's normal, degrees.
    #[serde(default = "Planes::default_tilt")]
    pub tilt_deg: f64,
    /// Seconds between two contacts (the rows' `t`).
    #[serde(default = "Planes::default_step")]
    pub step_s: f64,
    /// Fraction of the rows marked `test` (held out), drawn at random.
    #[serde(default = "Planes::default_test")]
    pub test_fraction: f64,
    /// The block's placements in the cell (its z axis up the first face's normal as drawn).
    pub placements: Vec<ArtifactPlacement>,
}

impl Planes {
    fn default_radius() -> f64 {
        1.5
    }
    fn default_travel() -> f64 {
        2.0
    }
    fn default_resolution() -> f64 {
        0.001
    }
    fn default_temp() -> f64 {
        REFERENCE_TEMP_C
    }
    fn default_tilt() -> f64 {
        30.0
    }
    fn default_step() -> f64 {
        10.0
    }
    fn default_test() -> f64 {
        0.2
    }

    /// What is wrong with the table, if anything.
    pub fn validate(&self) -> std::result::Result<(), String> {
        if self.faces.len() < 2 {
            return Err(format!("[planes] faces: {} face(s); at least two (a step of two parallel faces gives the arm its scale)", self.faces.len()));
        }
        if self.faces.iter().any(|f| !(Vector3::from(f.normal).norm() > 1e-9) || f.extent_mm <= 0.0 || f.label.trim().is_empty()) {
            return Err("[planes] every face needs a label, a non-zero normal and a positive extent_mm".into());
        }
        if !self.made_error_mm.is_empty() && self.made_error_mm.len() != self.faces.len() {
            return Err(format!("[planes] made_error_mm has {} entries for {} faces", self.made_error_mm.len(), self.faces.len()));
        }
        if self.placements.is_empty() {
            return Err("[planes] placements: at least one placement of the block".into());
        }
        if self.per_face < crate::measurement::plane::MIN_ROWS_PER_FACE {
            return Err(format!("[planes] per_face = {}: at least {} contacts per face", self.per_face, crate::measurement::plane::MIN_ROWS_PER_FACE));
        }
        if !(0.0..=70.0).contains(&self.tilt_deg) || !(0.0..0.9).contains(&self.test_fraction) {
            return Err("[planes] tilt_deg must be in [0, 70] and test_fraction in [0, 0.9)".into());
        }
        let v = [self.stylus_radius_mm, self.pretravel_um, self.lobing_um, self.trigger_std_um, self.force_n, self.travel_mm, self.resolution_mm, self.step_s];
        if v.iter().any(|x| !x.is_finite() || *x < 0.0) || self.step_s == 0.0 || !self.expansion_ppm_per_k.is_finite() || !self.temp_c.is_finite() {
            return Err(
                "[planes] radius, pre-travel, lobing, trigger scatter, force, travel, resolution and step_s must be finite and not negative (step_s positive)"
                    .into(),
            );
        }
        Ok(())
    }

    /// The steps a user states: the designed distance between each pair of parallel faces
    /// facing the same way, as (first, second, mm).
    pub fn designed_steps_mm(&self) -> Vec<(String, String, f64)> {
        let mut out = Vec::new();
        for a in 0..self.faces.len() {
            for b in a + 1..self.faces.len() {
                let (fa, fb) = (&self.faces[a], &self.faces[b]);
                let n = fa.unit_normal();
                if (n - fb.unit_normal()).norm() < 1e-9 {
                    out.push((fa.label.clone(), fb.label.clone(), n.dot(&(Vector3::from(fb.point_mm) - Vector3::from(fa.point_mm))).abs()));
                }
            }
        }
        out
    }

    /// Face `k`'s point as made, at the block's temperature, in its frame, m.
    fn made_point_m(&self, k: usize) -> Vector3<f64> {
        let f = &self.faces[k];
        let e = self.made_error_mm.get(k).copied().unwrap_or(0.0);
        let grow = 1.0 + self.expansion_ppm_per_k * 1e-6 * (self.temp_c - REFERENCE_TEMP_C);
        crate::units::to_m(Vector3::from(f.point_mm) + f.unit_normal() * e) * grow
    }
}

/// What is true of a faces dataset: the target on the flange, each face as it was, the steps as
/// made and as designed.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PlaneTruth {
    /// The stylus' centre (the indicator's zero point) on the flange, mm.
    pub stylus_mm: [f64; 3],
    /// Each face (unit normal, base frame; offset along it, mm) by its station label
    /// (`placement/face`), as made: without the stylus' radius and pre-travel.
    pub faces: Vec<(String, [f64; 3], f64)>,
    /// The steps between parallel faces as made, at the block's temperature, mm.
    pub steps_mm: Vec<(String, String, f64)>,
    /// The designed steps a user states, mm.
    pub designed_steps_mm: Vec<(String, String, f64)>,
    /// Contacts the twin could not reach (redrawn).
    pub unreachable: usize,
}

/// Face data from the twin: joint angles with `plane` and `placement` labels (an `indicator`
/// column with the dial indicator), rows in acquisition order, a `split` column; and the truth.
pub fn touch(twin: &Twin, robot: &Robot, art: &Planes, decimals: usize, seed: u64) -> Result<(Dataset, PlaneTruth)> {
    art.validate().map_err(Error::Invalid)?;
    let n = robot.dof();
    let limits = robot.limits();
    let stylus = crate::units::to_m(Vector3::from(art.stylus_mm));
    let made_steps = art
        .designed_steps_mm()
        .iter()
        .map(|(a, b, _)| {
            let (ia, ib) = (art.faces.iter().position(|f| &f.label == a).unwrap_or(0), art.faces.iter().position(|f| &f.label == b).unwrap_or(0));
            let nrm = art.faces[ia].unit_normal();
            (a.clone(), b.clone(), crate::units::to_mm(nrm.dot(&(art.made_point_m(ib) - art.made_point_m(ia))).abs()))
        })
        .collect();
    let mut truth =
        PlaneTruth { stylus_mm: art.stylus_mm, faces: Vec::new(), steps_mm: made_steps, designed_steps_mm: art.designed_steps_mm(), unreachable: 0 };
    let unit = |sd: f64| Normal::new(0.0, sd.max(1e-300)).map_err(|e| Error::Invalid(e.to_string()));
    let trigger = unit(art.trigger_std_um * 1e-6)?;
    let (mut rows, mut t) = (Vec::new(), 0.0);
    for (pi, placement) in art.placements.iter().enumerate() {
        let frame = placement.frame();
        let plabel = crate::sim::artifact::placement_label(pi);
        for (k, face) in art.faces.iter().enumerate() {
            let normal = frame.rot * face.unit_normal();
            let on = frame.point(&art.made_point_m(k));
            truth.faces.push((crate::dataset::feature_station(Some(&plabel), &face.label), normal.into(), crate::units::to_mm(normal.dot(&on))));
            // Two directions along the face.
            let u = normal.cross(&if normal.x.abs() < 0.9 { Vector3::x() } else { Vector3::y() }).normalize();
            let v = normal.cross(&u);
            let mut rng = ChaCha8Rng::seed_from_u64(stream_seed(seed, Stream::Touching, (pi * 64 + k) as u64));
            let (mut q_prev, mut touched, mut tries): (Option<Vec<f64>>, usize, usize) = (None, 0, 0);
            while touched < art.per_face {
                tries += 1;
                if tries > 20 * art.per_face {
                    return Err(Error::Invalid(format!(
                        "[planes] placement {} face {}: the arm reaches only {touched} of {} contacts within its limits; move the placement into the arm's reach",
                        pi + 1,
                        face.label,
                        art.per_face
                    )));
                }
                let half = crate::units::to_m(face.extent_mm);
                let foot = on + u * rng.random_range(-half..half) + v * rng.random_range(-half..half);
                let (tilt, azim, spin) = (
                    rng.random::<f64>().sqrt() * art.tilt_deg.to_radians(),
                    rng.random_range(0.0..std::f64::consts::TAU),
                    rng.random_range(-std::f64::consts::PI..std::f64::consts::PI),
                );
                // The approach: into the face, tilted from its normal.
                let approach = -(normal * tilt.cos() + (u * azim.cos() + v * azim.sin()) * tilt.sin());
                let (centre, reading) = if art.indicator {
                    // The plunger along the approach, pressed in by `travel` from its tip on the
                    // face: the zero point that far beyond the tip; read along the plunger.
                    let travel = rng.random_range(0.1 * art.travel_mm..art.travel_mm.max(1e-6));
                    let read = (crate::units::to_m(travel) + trigger.sample(&mut rng)) / crate::units::to_m(art.resolution_mm);
                    (foot + approach * crate::units::to_m(travel), Some(read.round() * art.resolution_mm))
                } else {
                    // The ball touches the face, the probe travels on past the touch before it
                    // triggers, by its pre-travel in the touch's direction in the probe's frame.
                    let local = flange_for(&foot, &approach, spin, &stylus).rot.transpose() * normal;
                    let phi = local.y.atan2(local.x);
                    let pre = 1e-6 * (art.pretravel_um + art.lobing_um * (3.0 * phi).cos()) + trigger.sample(&mut rng);
                    (foot + normal * crate::units::to_m(art.stylus_radius_mm) + approach * pre, None)
                };
                let sides: Vec<f64> = (0..n).map(|_| if rng.random::<bool>() { 1.0 } else { -1.0 }).collect();
                let (p, scale) = twin.params_at(t);
                let target = flange_for(&centre, &approach, spin, &stylus);
                let starts: Vec<Vec<f64>> = (0..IK_STARTS)
                    .map(|s| match (&q_prev, s) {
                        (Some(q), 0) => q.clone(),
                        _ => limits.iter().map(|(lo, hi)| lo + (hi - lo) * (0.2 + 0.6 * rng.random::<f64>())).collect(),
                    })
                    .collect();
                let Some(q_link) = starts.into_iter().find_map(|q0| reach(twin, &p, scale, &target, q0, &limits)) else {
                    truth.unreachable += 1;
                    continue;
                };
                let q_read = logged_angles(twin, &q_link, (&p, scale), &stylus, &(-approach * art.force_n), &sides);
                let split = if rng.random::<f64>() < art.test_fraction { Split::Test } else { Split::Train };
                rows.push(Row {
                    q_deg: q_read.iter().map(|v| crate::units::round_decimals(v.to_degrees(), decimals)).collect(),
                    reading_mm: reading.into_iter().collect(),
                    t_s: Some(crate::units::round_decimals(t, crate::units::T_DECIMALS)),
                    split: Some(split),
                    station: Some(plabel.clone()),
                    feature: Some(Feature::plane(face.label.clone())),
                    ..Default::default()
                });
                q_prev = Some(q_link);
                touched += 1;
                t += art.step_s;
            }
        }
    }
    Ok((Dataset { rows, source: "planes".into() }, truth))
}
