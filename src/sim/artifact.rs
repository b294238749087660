//! The twin seating a ball in the sockets of an artifact (`[sockets]` in a scenario): a plate
//! with sockets a known distance apart, placed in the cell one or more times; the ball on the
//! flange is brought into each socket in many configurations (the tool turned about the ball,
//! a 7-joint arm's elbow swept through its null space) and the joint angles are logged while it
//! is seated. What really happens is simulated: the ball rests off-centre within the socket's
//! clearance, the operator's preload along the approach pushes the joints against their
//! compliance (with gravity), each joint rests on a backlash flank the jog left it on, the
//! artifact was made with a spacing error and grows with its temperature (a printed PLA plate:
//! about 68 ppm/K), and the encoders log what the motors read, rounded to the logging step.

use crate::dataset::{Dataset, Row, Split};
use crate::error::{Error, Result};
use crate::robot::kinematics::{axis_rotation, FkWork, Frame, PointJacobian};
use crate::robot::Robot;
use crate::seed::{stream_seed, Stream};
use crate::sim::twin::Twin;
use nalgebra::{DMatrix, DVector, Matrix3, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use serde::{Deserialize, Serialize};

/// The label the twin gives its artifact's placement `i` (0-based) in a dataset's `placement`
/// column: `p1`, `p2`, ...
pub fn placement_label(i: usize) -> String {
    format!("p{}", i + 1)
}

/// The placement (0-based) a label [`placement_label`] wrote names.
pub fn placement_index(label: &str) -> Option<usize> {
    label.strip_prefix('p')?.parse::<usize>().ok()?.checked_sub(1)
}

/// The file `generate` writes a socket dataset's truth to, beside dataset.csv.
pub const SOCKETS_TRUTH_FILE: &str = "sockets.json";

/// The temperature an artifact's dimensions are stated at, °C.
pub const REFERENCE_TEMP_C: f64 = 20.0;

/// One placement of the artifact in the cell: its frame in the robot's base frame.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ArtifactPlacement {
    /// The artifact's origin (the middle between its sockets), base frame, mm.
    pub origin_mm: [f64; 3],
    /// Its orientation, roll-pitch-yaw about the base's x, y, z, degrees; its z axis is the
    /// plate's normal (the sockets open along +z).
    #[serde(default)]
    pub rpy_deg: [f64; 3],
}

/// A plate of sockets and the ball that is seated in them (`[sockets]`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Sockets {
    /// The ball's centre on the flange (flange frame), mm.
    pub ball_mm: [f64; 3],
    /// The sockets' centres in the artifact's frame as designed, mm (x, y; on its plane):
    /// what the user states as the spacing. Default: two sockets 50 mm apart on x.
    #[serde(default = "Sockets::default_layout")]
    pub layout_mm: Vec<[f64; 2]>,
    /// The sockets' labels, one per entry of `layout_mm` (default A, B, C, ...).
    #[serde(default)]
    pub labels: Vec<String>,
    /// How far each socket was made from where it was designed, mm (x, y per socket; zero by
    /// default).
    #[serde(default)]
    pub made_error_mm: Vec<[f64; 2]>,
    /// The artifact's thermal expansion, ppm/K (printed PLA about 68, aluminium 23, steel 12).
    #[serde(default)]
    pub expansion_ppm_per_k: f64,
    /// The artifact's temperature while the ball is seated, °C (it was made at 20 °C).
    #[serde(default = "Sockets::default_temp")]
    pub temp_c: f64,
    /// Where the ball rests within the socket's clearance: its centre off the socket's, per
    /// coordinate, standard deviation, mm.
    #[serde(default)]
    pub seat_std_mm: f64,
    /// The operator's push along the approach while the joints are logged, N.
    #[serde(default)]
    pub preload_n: f64,
    /// Seated configurations per socket and placement.
    pub per_socket: usize,
    /// Largest angle between the tool's approach and the socket's axis, degrees: the tool is
    /// turned about the ball within this cone (and about its own axis freely).
    #[serde(default = "Sockets::default_tilt")]
    pub tilt_deg: f64,
    /// Turn the configurations about each socket as a routine asks (each at `tilt_deg` from the
    /// socket's axis, their approaches spread evenly around it) instead of at random within the
    /// cone.
    #[serde(default)]
    pub spread: bool,
    /// Seconds between two seated configurations (the rows' `t`).
    #[serde(default = "Sockets::default_step")]
    pub step_s: f64,
    /// Fraction of the rows marked `test` (held out), drawn at random.
    #[serde(default = "Sockets::default_test")]
    pub test_fraction: f64,
    /// The artifact's placements in the cell.
    pub placements: Vec<ArtifactPlacement>,
}

impl Sockets {
    fn default_layout() -> Vec<[f64; 2]> {
        vec![[-25.0, 0.0], [25.0, 0.0]]
    }
    fn default_temp() -> f64 {
        REFERENCE_TEMP_C
    }
    fn default_tilt() -> f64 {
        35.0
    }
    fn default_step() -> f64 {
        20.0
    }
    fn default_test() -> f64 {
        0.2
    }

    /// What is wrong with the table, if anything.
    pub fn validate(&self) -> std::result::Result<(), String> {
        // One socket is a fixed point (the TCP routine's); a calibration needs two a known
        // distance apart, and says so.
        if self.layout_mm.is_empty() {
            return Err("[sockets] layout_mm places no socket".into());
        }
        if !self.labels.is_empty() && self.labels.len() != self.layout_mm.len() {
            return Err(format!("[sockets] labels names {} sockets, layout_mm places {}", self.labels.len(), self.layout_mm.len()));
        }
        if !self.made_error_mm.is_empty() && self.made_error_mm.len() != self.layout_mm.len() {
            return Err(format!("[sockets] made_error_mm has {} entries for {} sockets", self.made_error_mm.len(), self.layout_mm.len()));
        }
        if self.placements.is_empty() {
            return Err("[sockets] placements: at least one placement of the artifact".into());
        }
        if self.per_socket < 3 {
            return Err(format!("[sockets] per_socket = {}: at least 3 seated configurations per socket", self.per_socket));
        }
        if !(0.0..=80.0).contains(&self.tilt_deg) || !(0.0..0.9).contains(&self.test_fraction) {
            return Err("[sockets] tilt_deg must be in [0, 80] and test_fraction in [0, 0.9)".into());
        }
        let finite = [self.expansion_ppm_per_k, self.temp_c, self.seat_std_mm, self.preload_n, self.step_s].iter().all(|v| v.is_finite());
        if !finite || self.seat_std_mm < 0.0 || self.preload_n < 0.0 || self.step_s <= 0.0 {
            return Err(
                "[sockets] expansion, temperature, seat_std_mm, preload_n and step_s must be finite; the last three not negative (step_s positive)".into()
            );
        }
        Ok(())
    }

    /// Socket `k`'s label.
    pub fn label(&self, k: usize) -> String {
        self.labels.get(k).cloned().unwrap_or_else(|| ((b'A' + (k % 26) as u8) as char).to_string())
    }

    /// The designed distances from the first socket to each other one, mm: what a user states,
    /// as (first, other, mm).
    pub fn designed_spacings_mm(&self) -> Vec<(String, String, f64)> {
        (1..self.layout_mm.len()).map(|k| (self.label(0), self.label(k), self.designed_spacing_mm(0, k))).collect()
    }

    /// The designed distance between sockets `a` and `b`, mm: what a user states.
    pub fn designed_spacing_mm(&self, a: usize, b: usize) -> f64 {
        let (p, q) = (self.layout_mm[a], self.layout_mm[b]);
        ((p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2)).sqrt()
    }

    /// Socket `k`'s centre as made, at the artifact's temperature, in its frame, m.
    fn made_m(&self, k: usize) -> Vector3<f64> {
        let e = self.made_error_mm.get(k).copied().unwrap_or([0.0; 2]);
        let grow = 1.0 + self.expansion_ppm_per_k * 1e-6 * (self.temp_c - REFERENCE_TEMP_C);
        crate::units::to_m(Vector3::new(self.layout_mm[k][0] + e[0], self.layout_mm[k][1] + e[1], 0.0)) * grow
    }
}

impl ArtifactPlacement {
    /// The artifact's frame in the base frame (m).
    pub fn frame(&self) -> Frame {
        let [r, p, y] = self.rpy_deg.map(f64::to_radians);
        let rot = axis_rotation(&Vector3::z(), y) * axis_rotation(&Vector3::y(), p) * axis_rotation(&Vector3::x(), r);
        Frame { rot, pos: crate::units::to_m(Vector3::from(self.origin_mm)) }
    }
}

/// What is true of a socket dataset: every socket's centre as it was, the ball's, the spacings
/// as made.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SocketTruth {
    /// The ball's centre on the flange, mm.
    pub ball_mm: [f64; 3],
    /// Each socket's centre (base frame, mm) by its station label (`placement/socket`).
    pub sockets_mm: Vec<(String, [f64; 3])>,
    /// The distances between the first socket and each other one, as made and at the
    /// artifact's temperature, mm.
    pub spacings_mm: Vec<(String, String, f64)>,
    /// The designed distances a user states, mm.
    pub designed_spacings_mm: Vec<(String, String, f64)>,
    /// Configurations the twin could not seat (out of reach), per placement and socket.
    pub unreachable: usize,
}

/// Tries per seated configuration to find joint angles that reach it.
pub(crate) const IK_STARTS: usize = 12;

/// The joint angles (rad) the encoders log with the arm's links at `q_link` (true parameters
/// and scale `at`) held still by gravity and by `push` (N, base frame) on flange point `point`
/// (the socket pushing back on the ball against the operator's preload, a face on the probe's
/// trigger force): each joint deflected by its compliance from the backlash flank `sides` it
/// rests on, its encoder reading the motor less its eccentricity.
pub(crate) fn logged_angles(twin: &Twin, q_link: &[f64], at: (&[f64], f64), point: &Vector3<f64>, push: &Vector3<f64>, sides: &[f64]) -> Vec<f64> {
    let n = q_link.len();
    let (mut ws, mut jac) = (FkWork::new(&twin.chain), PointJacobian::new(&twin.chain));
    let mut tau = vec![0.0; n];
    twin.chain.forward(q_link, at.0, at.1, &mut ws);
    twin.load.torques(&twin.chain, &ws, &mut jac, &mut tau);
    twin.chain.point_jacobian(&ws, twin.chain.flange(), point, &mut jac);
    for (j, tj) in tau.iter_mut().enumerate() {
        *tj += jac.dq[j].dot(push);
    }
    let q_motor: Vec<f64> = (0..n).map(|j| q_link[j] - twin.transmission.as_ref().map_or(0.0, |tr| tr.deflection(j, tau[j], sides[j]).0)).collect();
    q_motor.iter().enumerate().map(|(j, q)| q - twin.effects.motor_offset_rad(j, *q).unwrap_or(0.0)).collect()
}

/// The joint angles (rad) that put the flange at `target` (base frame), starting from `q0`,
/// by damped least squares on the true arm at parameters `p` and length scale `scale`; `None`
/// when it does not converge within the joint limits.
pub(crate) fn reach(twin: &Twin, p: &[f64], scale: f64, target: &Frame, q0: Vec<f64>, limits: &[(f64, f64)]) -> Option<Vec<f64>> {
    let chain = &twin.chain;
    let n = chain.n_joints;
    let flange = chain.flange();
    let (mut ws, mut jac) = (FkWork::new(chain), PointJacobian::new(chain));
    let mut dw = vec![Vector3::zeros(); n];
    let mut q = q0;
    for _ in 0..200 {
        chain.forward(&q, p, scale, &mut ws);
        let f = chain.frame(&ws, flange);
        let ep = target.pos - f.pos;
        let er = rotation_vector(&(target.rot * f.rot.transpose()));
        if ep.norm() < 1e-11 && er.norm() < 1e-10 {
            return q.iter().zip(limits).all(|(v, (lo, hi))| v >= lo && v <= hi).then_some(q);
        }
        chain.point_jacobian(&ws, flange, &Vector3::zeros(), &mut jac);
        chain.angular_jacobian(&ws, flange, &mut dw);
        let mut j = DMatrix::zeros(6, n);
        for c in 0..n {
            for r in 0..3 {
                j[(r, c)] = jac.dq[c][r];
                j[(r + 3, c)] = dw[c][r];
            }
        }
        let e = DVector::from_column_slice(&[ep.x, ep.y, ep.z, er.x, er.y, er.z]);
        let lambda = if e.norm() > 1e-4 { 1e-3 } else { 1e-9 };
        let a = &j * j.transpose() + DMatrix::identity(6, 6) * lambda;
        let dq = j.transpose() * a.lu().solve(&e)?;
        for (qj, d) in q.iter_mut().zip(dq.iter()) {
            *qj += d.clamp(-0.3, 0.3);
        }
    }
    None
}

/// The rotation vector of `r` (axis times angle; never NaN near no turn, where an arccosine of
/// a cosine a rounding error above one had made every converged seating "unreachable").
fn rotation_vector(r: &Matrix3<f64>) -> Vector3<f64> {
    crate::math::rotation_vector(r)
}

/// The flange's frame for the ball at `ball_at` (base) approaching along `approach` (unit,
/// base: from the ball into the socket) turned by `spin` about it, the ball at `ball` on the
/// flange along its z axis or anywhere.
pub(crate) fn flange_for(ball_at: &Vector3<f64>, approach: &Vector3<f64>, spin: f64, ball: &Vector3<f64>) -> Frame {
    let helper = if approach.x.abs() < 0.9 { Vector3::x() } else { Vector3::y() };
    let x0 = helper.cross(approach).normalize();
    let x = axis_rotation(approach, spin) * x0;
    let y = approach.cross(&x);
    let rot = Matrix3::from_columns(&[x, y, *approach]);
    Frame { rot, pos: ball_at - rot * ball }
}

/// Socket data from the twin: a dataset of joint angles with `socket` and `placement` labels
/// (rows in acquisition order, a `split` column) and its truth.
pub fn seat(twin: &Twin, robot: &Robot, art: &Sockets, decimals: usize, seed: u64) -> Result<(Dataset, SocketTruth)> {
    art.validate().map_err(Error::Invalid)?;
    let n = robot.dof();
    let limits = robot.limits();
    let ball = crate::units::to_m(Vector3::from(art.ball_mm));
    let mut rows = Vec::new();
    let mut truth =
        SocketTruth { ball_mm: art.ball_mm, sockets_mm: Vec::new(), spacings_mm: Vec::new(), designed_spacings_mm: art.designed_spacings_mm(), unreachable: 0 };
    for k in 1..art.layout_mm.len() {
        let grow = (art.made_m(k) - art.made_m(0)).norm();
        truth.spacings_mm.push((art.label(0), art.label(k), crate::units::to_mm(grow)));
    }
    let mut t = 0.0;
    let seat = Normal::new(0.0, crate::units::to_m(art.seat_std_mm).max(1e-300)).map_err(|e| Error::Invalid(e.to_string()))?;
    for (pi, placement) in art.placements.iter().enumerate() {
        let frame = placement.frame();
        let plabel = placement_label(pi);
        for k in 0..art.layout_mm.len() {
            let centre = frame.point(&art.made_m(k));
            let station = crate::dataset::feature_station(Some(&plabel), &art.label(k));
            truth.sockets_mm.push((station, crate::units::to_mm(centre).into()));
            let mut rng = ChaCha8Rng::seed_from_u64(stream_seed(seed, Stream::Seating, (pi * 64 + k) as u64));
            let mut q_prev: Option<Vec<f64>> = None;
            let mut seated = 0;
            let mut tries = 0;
            while seated < art.per_socket {
                tries += 1;
                if tries > 20 * art.per_socket {
                    return Err(Error::Invalid(format!(
                        "[sockets] placement {} socket {}: the arm seats only {seated} of {} configurations within its limits; move the placement into the arm's reach",
                        pi + 1,
                        art.label(k),
                        art.per_socket
                    )));
                }
                let (mut tilt, mut azim, mut spin) = (
                    rng.random::<f64>().sqrt() * art.tilt_deg.to_radians(),
                    rng.random_range(0.0..std::f64::consts::TAU),
                    rng.random_range(-std::f64::consts::PI..std::f64::consts::PI),
                );
                if art.spread {
                    // Evenly around the socket's axis, the tool turned with the approach.
                    tilt = art.tilt_deg.to_radians();
                    azim = std::f64::consts::TAU * (seated as f64 + rng.random::<f64>()) / art.per_socket as f64;
                    spin = azim + 0.1 * spin;
                }
                let local = Vector3::new(tilt.sin() * azim.cos(), tilt.sin() * azim.sin(), -tilt.cos());
                let approach = frame.rot * local;
                let off =
                    if art.seat_std_mm > 0.0 { Vector3::new(seat.sample(&mut rng), seat.sample(&mut rng), seat.sample(&mut rng)) } else { Vector3::zeros() };
                let sides: Vec<f64> = (0..n).map(|_| if rng.random::<bool>() { 1.0 } else { -1.0 }).collect();
                let (p, scale) = twin.params_at(t);
                let target = flange_for(&(centre + off), &approach, spin, &ball);
                let starts = (0..IK_STARTS).map(|s| match (&q_prev, s) {
                    (Some(q), 0) => q.clone(),
                    _ => limits.iter().map(|(lo, hi)| lo + (hi - lo) * (0.2 + 0.6 * rng.random::<f64>())).collect(),
                });
                let starts: Vec<Vec<f64>> = starts.collect();
                let Some(q_link) = starts.into_iter().find_map(|q0| reach(twin, &p, scale, &target, q0, &limits)) else {
                    truth.unreachable += 1;
                    continue;
                };
                let push = -approach * art.preload_n;
                let q_read = logged_angles(twin, &q_link, (&p, scale), &ball, &push, &sides);
                let split = if rng.random::<f64>() < art.test_fraction { Split::Test } else { Split::Train };
                rows.push(Row {
                    q_deg: q_read.iter().map(|v| crate::units::round_decimals(v.to_degrees(), decimals)).collect(),
                    t_s: Some(crate::units::round_decimals(t, crate::units::T_DECIMALS)),
                    split: Some(split),
                    station: Some(plabel.clone()),
                    feature: Some(crate::dataset::Feature::socket(art.label(k))),
                    ..Default::default()
                });
                q_prev = Some(q_link);
                seated += 1;
                t += art.step_s;
            }
        }
    }
    Ok((Dataset { rows, source: "sockets".into() }, truth))
}

/// A planned seating: the placement and the socket (indices into the artifact's lists) and the
/// joint angles (rad) the plan seats the ball from.
pub type PlannedSeating = (usize, usize, Vec<f64>);

/// Planned seatings made on the twin, as an operator makes them: the arm jogged to the planned
/// joint angles, then the ball pushed into its socket (within the seating scatter) with the
/// flange kept turned as it stands there; the encoders logged as [`seat`] logs them. One row per
/// seating in the given order, but for those the arm cannot make within its limits (a planned
/// configuration at a joint's limit that the true arm needs beyond it: the operator skips it),
/// whose indices are returned beside; the scatter, the flanks and the time from `seed`.
pub fn seat_planned(twin: &Twin, robot: &Robot, art: &Sockets, decimals: usize, seed: u64, planned: &[PlannedSeating]) -> Result<(Dataset, Vec<usize>)> {
    art.validate().map_err(Error::Invalid)?;
    let (n, limits) = (robot.dof(), robot.limits());
    let ball = crate::units::to_m(Vector3::from(art.ball_mm));
    let seat = Normal::new(0.0, crate::units::to_m(art.seat_std_mm).max(1e-300)).map_err(|e| Error::Invalid(e.to_string()))?;
    let mut rng = ChaCha8Rng::seed_from_u64(stream_seed(seed, Stream::Seating, 1 << 20));
    let mut ws = FkWork::new(&twin.chain);
    let (mut rows, mut skipped) = (Vec::with_capacity(planned.len()), Vec::new());
    for (i, (pi, k, q)) in planned.iter().enumerate() {
        let (Some(placement), true) = (art.placements.get(*pi), *k < art.layout_mm.len()) else {
            return Err(Error::Invalid(format!("planned seating {}: no placement {} or socket {} on the artifact", i + 1, pi + 1, k + 1)));
        };
        let t = i as f64 * art.step_s;
        let (p, scale) = twin.params_at(t);
        let centre = placement.frame().point(&art.made_m(*k));
        twin.chain.forward(q, &p, scale, &mut ws);
        let rot = twin.chain.frame(&ws, twin.chain.flange()).rot;
        let off = if art.seat_std_mm > 0.0 { Vector3::new(seat.sample(&mut rng), seat.sample(&mut rng), seat.sample(&mut rng)) } else { Vector3::zeros() };
        let sides: Vec<f64> = (0..n).map(|_| if rng.random::<bool>() { 1.0 } else { -1.0 }).collect();
        let target = Frame { rot, pos: centre + off - rot * ball };
        let Some(q_link) = reach(twin, &p, scale, &target, q.clone(), &limits) else {
            skipped.push(i);
            continue;
        };
        let q_read = logged_angles(twin, &q_link, (&p, scale), &ball, &(-(rot * Vector3::z()) * art.preload_n), &sides);
        rows.push(Row {
            q_deg: q_read.iter().map(|v| crate::units::round_decimals(v.to_degrees(), decimals)).collect(),
            t_s: Some(crate::units::round_decimals(t, crate::units::T_DECIMALS)),
            split: Some(Split::Train),
            station: Some(placement_label(*pi)),
            feature: Some(crate::dataset::Feature::socket(art.label(*k))),
            ..Default::default()
        });
    }
    Ok((Dataset { rows, source: "planned seatings".into() }, skipped))
}
