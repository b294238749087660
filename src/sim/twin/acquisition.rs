//! The acquisition's settings (`[acquisition]`), its schedule of moves and readings, and what the
//! tour gives for a pose.

use super::motion::Move;
use super::RestingPose;
use crate::robot::Robot;
use rapier3d_f64::prelude::*;
use serde::{Deserialize, Serialize};

/// How `generate` turns commanded poses into readings.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum AcquisitionModel {
    /// Each pose settled in a rapier world of its own, flanks from the load/approach rule, read
    /// at rest (no transient; `hold_s` and the damping change nothing).
    #[default]
    Settled,
    /// The quasi-static model only (torque equilibrium, same rule): the fastest.
    QuasiStatic,
    /// The whole tour simulated: moves, holds, sampling, gate.
    Simulated,
}

/// What a simulated acquisition does when the stability gate is still closed at the end of the hold.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum OnTimeout {
    /// The pose is left out of the dataset (listed under `rejected` in truth.json).
    #[default]
    Reject,
    /// The readings after the hold are taken anyway.
    Read,
}

/// The `[acquisition]` table of a scenario.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Acquisition {
    /// How the readings are taken (default `settled`).
    #[serde(default)]
    pub model: AcquisitionModel,
    /// Structural damping ratio ζ of each transmission in the simulated tour (real arms: a few
    /// percent), used where `effects.compliance.damping_nms_per_rad` is not given. (The settled
    /// model's `simulation.damping_ratio` only speeds up its settling.)
    #[serde(default = "Acquisition::default_zeta")]
    pub damping_ratio: f64,
    /// Time a joint takes to reach its cruise speed at its acceleration limit, s (acceleration
    /// limit = speed limit / ramp_s; URDF files give no acceleration limits).
    #[serde(default = "Acquisition::default_ramp")]
    pub ramp_s: f64,
    /// The gate compares the mean of the last `gate_window_s` of raw readings with the mean of
    /// the window before; it opens when they differ by less than `gate_mm`.
    #[serde(default = "Acquisition::default_gate_window")]
    pub gate_window_s: f64,
    /// Largest difference (mm) between the means of two consecutive gate windows at which the gate
    /// opens.
    #[serde(default = "Acquisition::default_gate_mm")]
    pub gate_mm: f64,
    /// What happens when the gate is still closed at the end of the hold (default `reject`).
    #[serde(default)]
    pub on_timeout: OnTimeout,
    /// Time step of the moves before their final deceleration, s.
    #[serde(default = "Acquisition::default_coarse_dt")]
    pub coarse_dt_s: f64,
    /// Poses per independently simulated chunk of the tour.
    #[serde(default = "Acquisition::default_chunk")]
    pub chunk_poses: usize,
    /// The target on the flange every instrument reads (flange frame, mm: a tracker's
    /// reflector), in a scenario without a draw-wire (`[sensor]`, whose `tool_point_mm` it is
    /// otherwise).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tool_point_mm: Option<[f64; 3]>,
    /// The hold at each pose, s, without a `[sensor]` (default 2).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub hold_s: Option<f64>,
    /// Raw samples averaged into a reading, without a `[sensor]` (default 50).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub samples: Option<usize>,
    /// The instrument's sampling rate, Hz, without a `[sensor]` (default 1000).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rate_hz: Option<f64>,
}

/// Largest `acquisition.coarse_dt_s`, s.
pub const MAX_COARSE_DT_S: f64 = 0.05;

impl Default for Acquisition {
    fn default() -> Self {
        Acquisition {
            model: AcquisitionModel::default(),
            damping_ratio: Self::default_zeta(),
            ramp_s: Self::default_ramp(),
            gate_window_s: Self::default_gate_window(),
            gate_mm: Self::default_gate_mm(),
            on_timeout: OnTimeout::default(),
            coarse_dt_s: Self::default_coarse_dt(),
            chunk_poses: Self::default_chunk(),
            tool_point_mm: None,
            hold_s: None,
            samples: None,
            rate_hz: None,
        }
    }
}

impl Acquisition {
    fn default_zeta() -> f64 {
        0.05
    }
    fn default_ramp() -> f64 {
        0.1
    }
    fn default_gate_window() -> f64 {
        0.02
    }
    fn default_gate_mm() -> f64 {
        0.02
    }
    fn default_coarse_dt() -> f64 {
        0.02
    }
    fn default_chunk() -> usize {
        25
    }

    /// Checks every value, naming the key (`acquisition.<key>`) of the first bad one. `fine_dt_s`
    /// is `simulation.dt_s`, `rate_hz` the sensor's sampling rate.
    pub fn validate(&self, fine_dt_s: f64, rate_hz: f64) -> std::result::Result<(), String> {
        if !(self.damping_ratio.is_finite() && self.damping_ratio > 0.0 && self.damping_ratio <= 10.0) {
            return Err(format!("acquisition.damping_ratio = {} must be in (0, 10]", self.damping_ratio));
        }
        if !(self.ramp_s.is_finite() && self.ramp_s > 0.0 && self.ramp_s <= 10.0) {
            return Err(format!("acquisition.ramp_s = {} must be in (0, 10] s", self.ramp_s));
        }
        if !(self.gate_window_s.is_finite() && self.gate_window_s > 0.0 && self.gate_window_s <= 10.0) {
            return Err(format!("acquisition.gate_window_s = {} must be in (0, 10] s", self.gate_window_s));
        }
        if self.model == AcquisitionModel::Simulated && self.gate_window_s * rate_hz < 1.0 - 1e-9 {
            return Err(format!("acquisition.gate_window_s = {} s holds no sample at sensor.rate_hz = {rate_hz} Hz", self.gate_window_s));
        }
        if !(self.gate_mm.is_finite() && self.gate_mm >= 0.0) {
            return Err(format!("acquisition.gate_mm = {} must be finite and >= 0", self.gate_mm));
        }
        if !(self.coarse_dt_s.is_finite() && self.coarse_dt_s >= fine_dt_s && self.coarse_dt_s <= MAX_COARSE_DT_S) {
            return Err(format!("acquisition.coarse_dt_s = {} must be in [simulation.dt_s = {fine_dt_s}, {MAX_COARSE_DT_S}] s", self.coarse_dt_s));
        }
        if !(1..=super::MAX_POSES).contains(&self.chunk_poses) {
            return Err(format!("acquisition.chunk_poses = {} must be in 1..={}", self.chunk_poses, super::MAX_POSES));
        }
        Ok(())
    }

    /// Raw samples in one gate window.
    pub fn gate_samples(&self, rate_hz: f64) -> usize {
        ((self.gate_window_s * rate_hz).round() as usize).max(1)
    }
}

/// Timing of a tour: every move and when each pose is reached and read.
#[derive(Clone, Debug)]
pub struct Schedule {
    /// The move to each pose, in order.
    pub moves: Vec<Move>,
    /// Start of the move to each pose, s from the start of acquisition.
    pub move_start: Vec<f64>,
    /// Arrival (end of the move), s.
    pub arrival: Vec<f64>,
    /// Middle of the reading window, s (the dataset's `t`).
    pub read_t: Vec<f64>,
}

/// How a tour moves and reads: the fraction of the URDF speed limits its moves run at, their
/// ramps, the hold still after each and the window of readings after the hold.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Timing {
    /// Fraction of each joint's URDF speed limit.
    pub speed_fraction: f64,
    /// Acceleration and deceleration ramp of a move, s.
    pub ramp_s: f64,
    /// Hold still before the readings, s.
    pub hold_s: f64,
    /// Window of readings after the hold, s.
    pub window_s: f64,
}

impl Schedule {
    /// The tour from `home` through `poses` (commanded angles, rad): each move at the timing's
    /// speed with its ramps, then its hold still and its window of readings. With `read_at` (s,
    /// one per pose, a measured acquisition's) the arm waits at rest before each move so that
    /// its reading window is centred on that time, or, when the move cannot end in time, reads
    /// as soon as it can.
    pub fn new(robot: &Robot, timing: &Timing, home: &[f64], poses: &[Vec<f64>], read_at: Option<&[f64]>) -> Schedule {
        let Timing { speed_fraction, ramp_s, hold_s, window_s } = *timing;
        let speed: Vec<f64> = robot.joints.iter().map(|j| speed_fraction * j.speed_limit()).collect();
        let mut s = Schedule { moves: Vec::new(), move_start: Vec::new(), arrival: Vec::new(), read_t: Vec::new() };
        let mut t = 0.0;
        let mut prev = home.to_vec();
        // (Each branch keeps its own sums: a dataset is byte-identical to what it was.)
        let n = read_at.map_or(poses.len(), |at| at.len().min(poses.len()));
        for (k, q) in poses[..n].iter().enumerate() {
            let m = Move::plan(&prev, q, &speed, ramp_s);
            match read_at {
                Some(at) => {
                    let start = t.max(at[k] - 0.5 * window_s - hold_s - m.duration);
                    s.move_start.push(start);
                    s.arrival.push(start + m.duration);
                    let read = start + m.duration + hold_s + 0.5 * window_s;
                    s.read_t.push(read);
                    t = read + 0.5 * window_s;
                }
                None => {
                    s.move_start.push(t);
                    t += m.duration;
                    s.arrival.push(t);
                    s.read_t.push(t + hold_s + 0.5 * window_s);
                    t += hold_s + window_s;
                }
            }
            s.moves.push(m);
            prev = q.clone();
        }
        s
    }

    /// When the pose before `i` was left (its move's start time): the chunk starting at `i` begins then.
    pub(super) fn chunk_start(&self, i: usize) -> f64 {
        self.move_start[i]
    }
}

/// Steps and wall time per phase of a pose's simulation.
#[derive(Clone, Copy, Debug, Default)]
pub struct PhaseStats {
    /// Rapier steps: coarse move, fine deceleration, hold (fine), the rest of the hold once the
    /// transient is negligible (no steps: the arm is put at rest), reading window.
    pub steps: [usize; 5],
    /// Wall time of the same phases, s (not part of any output file).
    pub seconds: [f64; 5],
}

/// Names of the phases of [`PhaseStats`].
pub const PHASES: [&str; 5] = ["move (coarse)", "deceleration (fine)", "hold (fine)", "rest of hold (at rest)", "reading window"];

/// One pose as the simulated acquisition read it.
#[derive(Clone, Debug)]
pub struct Acquired {
    /// The arm at the end of the reading window; `tool` is the mean tool point over the window.
    pub rest: RestingPose,
    /// Noise-free length (distance + offset, mm) at each raw sample of the reading window.
    pub lengths: Vec<f64>,
    /// When the stability gate opened, s after arrival (`None`: still closed at the end of the hold).
    pub gate_s: Option<f64>,
    /// Mean noise-free length of the window minus that of the arm at rest on the flanks it ends on, mm.
    pub transient_mm: f64,
    /// From when on the transient, decaying at the slowest modelled rate, could no longer reach 1 nm
    /// at the tool by the readings (fine stepping stopped), s after arrival.
    pub negligible_s: Option<f64>,
    /// Backlash flank the rule predicts (±1) for comparison.
    pub rule_sides: Vec<f64>,
    /// Steps and wall time per phase of the pose's simulation.
    pub stats: PhaseStats,
}

/// The sensor and gate settings a tour needs.
#[derive(Clone, Copy, Debug)]
pub struct TourSettings {
    /// Seed of the run (noise streams).
    pub seed: u64,
    /// Joint speed while moving, fraction of the URDF speed limits.
    pub speed_fraction: f64,
}
