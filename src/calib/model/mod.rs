//! Calibration models: a kinematic chain plus the instrument's placement (a draw-wire's or a
//! tracker's, see [`crate::measurement`]), as one parameter vector. All models predict the
//! instrument's readings through the same [`Chain`] evaluator.
//!
//! * `dh`: the papers' 24-parameter standard D-H model (Δa, Δd, Δα, Δθ per joint), derived from the
//!   robot's URDF so that at zero deviation it reproduces the URDF exactly.
//! * `hayati`: the same, with Δd replaced by a rotation β about y on joints whose axis is parallel
//!   to the next one (IRB 120 joints 2–3), where Δd is not identifiable.
//! * `frame`: the twin's own per-joint frame errors (7 per joint), heavily redundant; the
//!   identifiability analysis reduces it to its base parameters.
//! * `generic6r` / `generic7r`: an arm without a published nominal, a product of exponentials
//!   around axis lines found by a global search ([`crate::calib::pipeline::generic`]).
//!
//! Every model ends with its instrument's placement parameters ([`Measurement`]; for the
//! draw-wire: cable exit point (base frame), length offset and tool point (flange frame); for a
//! tracker: base-to-tracker translation and rotation and the reflector (flange frame)), then its
//! effect blocks. Internal units are metres and radians; readings are predicted in metres.

mod dh;
mod setup;
mod spacing;
pub mod tolerance;

pub use crate::measurement::Placement;
pub use dh::{DhRow, DhTable, NEARLY_PARALLEL_RAD};
pub use setup::SetupKind;
pub use spacing::{resolve_mixed_spacings, resolve_spacings, KnownSpacing, Pull, Spacing, MAX_SPACING_MM, PULL_SCALE_MM, SPACING_SD_MM};

use crate::calib::effects::{joint_and_scale_effects, legendre, EffectBlock, EffectKind, EffectState, EffectUnit, RowInputs};
use crate::measurement::{Measurement, MAX_DIM, MAX_OWN, MAX_TARGETS};
use crate::robot::kinematics::{Chain, FkWork, Frame, PointJacobian};
use crate::robot::GeoKind;
use crate::robot::Robot;
use nalgebra::Vector3;
use serde::{Deserialize, Serialize};

/// Physical kind of a parameter (for units and scaling).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Kind {
    /// A length: internal m, displayed in mm.
    Length,
    /// An angle: internal rad, displayed in degrees.
    Angle,
    /// A parameter of a non-geometric effect block.
    Effect(EffectUnit),
}

impl Kind {
    /// Factor from internal units to display units (mm, degrees).
    pub fn display(self) -> f64 {
        match self {
            Kind::Length => crate::units::MM_PER_M,
            Kind::Angle => 180.0 / std::f64::consts::PI,
            Kind::Effect(u) => u.display(),
        }
    }
    /// The display unit (`mm`, `deg`, or the effect's own).
    pub fn unit(self) -> &'static str {
        match self {
            Kind::Length => "mm",
            Kind::Angle => "deg",
            Kind::Effect(u) => u.unit(),
        }
    }
}

/// How a nominal robot's geometric errors are parametrised (`--params`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
pub enum Parametrisation {
    /// Denavit–Hartenberg: θ, d, a, α per joint.
    Dh,
    /// D-H with Hayati's β for nearly parallel consecutive axes (the default).
    #[default]
    Hayati,
    /// A full frame (3 translations, 3 rotations) per link.
    Frame,
}

impl Parametrisation {
    /// Every parametrisation.
    pub const ALL: [Parametrisation; 3] = [Parametrisation::Dh, Parametrisation::Hayati, Parametrisation::Frame];
    /// Its name in options, files and messages.
    pub fn name(self) -> &'static str {
        match self {
            Parametrisation::Dh => "dh",
            Parametrisation::Hayati => "hayati",
            Parametrisation::Frame => "frame",
        }
    }
    /// The parametrisation called `s` (any case), or an error listing them.
    pub fn parse(s: &str) -> crate::error::Result<Parametrisation> {
        Self::ALL
            .into_iter()
            .find(|p| p.name().eq_ignore_ascii_case(s.trim()))
            .ok_or_else(|| crate::error::Error::Invalid(format!("unknown parametrisation '{s}' (expected dh, hayati or frame)")))
    }
}

impl std::str::FromStr for Parametrisation {
    type Err = crate::error::Error;
    fn from_str(s: &str) -> crate::error::Result<Parametrisation> {
        Parametrisation::parse(s)
    }
}

/// A calibration model: a kinematic chain, the instrument's placement and effect blocks, with one
/// named parameter vector (internal units m and rad).
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct CalibModel {
    /// The model's name (`dh`, `hayati`, `frame`, `generic6r`).
    pub name: String,
    /// The kinematic chain the parameters' first [`Self::n_chain`] entries act on.
    pub chain: Chain,
    /// Parameter names, one per parameter (`joint_2.dtheta`, a placement name, an effect
    /// parameter).
    pub names: Vec<String>,
    /// Physical kind of each parameter.
    pub kinds: Vec<Kind>,
    /// Nominal parameter vector (deviations zero, instrument at its nominal guess, effects off).
    pub nominal: Vec<f64>,
    /// Non-geometric effect blocks; their parameters follow the instrument placement's.
    #[serde(default)]
    pub effects: Vec<EffectBlock>,
    /// Joint limits (rad) of the nominal robot, one pair per joint; empty for a model without a
    /// robot (a generic arm). See [`Self::joint_limits`].
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub limits: Vec<(f64, f64)>,
    /// What the instrument reads; its placement parameters follow the chain's. Result files
    /// written before there was a choice are draw-wire lengths.
    #[serde(default)]
    pub measurement: Measurement,
    /// The instrument's stations by label, in the order of their first rows, when it was
    /// re-stationed during the measurements (a tracker moved between sessions): the first stands
    /// where the placement parameters say, each other one has its own
    /// [`n_station`](crate::measurement::Block::n_station) parameters after them
    /// ([`Self::setup_block`]); the arm and the target's mount are shared. Empty: one station.
    /// A row says its station in [`RowInputs::station`].
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub stations: Vec<String>,
    /// The target's mounts on the flange by label (a probe or a reflector re-mounted between
    /// sessions): the first is the placement's, each other one has its own placement parameters
    /// after the stations' (the target, and a probe's orientation on the flange). Empty: one
    /// mount. A row says its mount in [`RowInputs::mount`].
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub mounts: Vec<String>,
    /// Known distances between sockets of one artifact placement (a ball seated in sockets:
    /// [`Measurement::Socket`]), each a residual of its own beside the rows'. Empty for every
    /// other instrument.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub spacings: Vec<Spacing>,
    /// Pulls of the arm's parameters toward their nominal values from the documented
    /// tolerances, where the rows leave directions nearly free (a ball in sockets); residuals
    /// after the spacings'.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub pulls: Vec<Pull>,
    /// A second instrument whose rows share the arm (a tracker's points beside seated rows):
    /// its placement parameters (its own, then its target on the flange) follow the first
    /// instrument's, before the set-ups' blocks; a row it read says so
    /// ([`RowInputs::instrument`] = 1). One station, one mount.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub also: Option<Measurement>,
}

/// The instrument's placement one row is read with: its own parameters (its station's where the
/// row's station is not the first, its mount's likewise) and the target on the flange, with the
/// parameter index each value comes from.
struct Placed {
    vals: [f64; MAX_OWN + 3],
    cols: [usize; MAX_OWN + 3],
    n_own: usize,
}

impl Placed {
    fn own(&self) -> &[f64] {
        &self.vals[..self.n_own]
    }
    fn tool(&self) -> Vector3<f64> {
        Vector3::new(self.vals[self.n_own], self.vals[self.n_own + 1], self.vals[self.n_own + 2])
    }
}

/// Reusable buffers for model evaluations.
pub struct ModelWork {
    /// Forward-kinematics workspace of the chain.
    pub fk: FkWork,
    /// Point Jacobian of the instrument's (first) target point.
    pub jac: PointJacobian,
    /// The Jacobians of an instrument's other target points (a pose's axis tips).
    extra: Vec<PointJacobian>,
    /// The effect blocks' state at the row evaluated (joint-angle shifts, length scale).
    pub eff: EffectState,
    q: Vec<f64>,
}

impl CalibModel {
    /// Number of parameters: chain, instrument placement and effects.
    pub fn n_params(&self) -> usize {
        self.names.len()
    }
    /// Number of chain parameters (the first entries of the vector).
    pub fn n_chain(&self) -> usize {
        self.chain.n_params()
    }
    /// A workspace sized for this model.
    pub fn work(&self) -> ModelWork {
        let most = self.measurement.def().n_targets().max(self.also.map_or(1, |m| m.def().n_targets()));
        let extra = (1..most).map(|_| PointJacobian::new(&self.chain)).collect();
        ModelWork { fk: FkWork::new(&self.chain), jac: PointJacobian::new(&self.chain), extra, eff: EffectState::default(), q: vec![0.0; self.chain.n_joints] }
    }
    /// The instrument placement held in `x` (the public way to read it: no index arithmetic).
    pub fn placement(&self, x: &[f64]) -> Placement {
        self.placement_at(x, 0, 0)
    }
    /// The placement at station `station` with mount `mount` (their own parameters in place of
    /// the first ones').
    pub fn placement_at(&self, x: &[f64], station: usize, mount: usize) -> Placement {
        let s = self.placed(x, station, mount);
        Placement { measurement: self.measurement, own: s.own().to_vec(), tool: s.tool() }
    }
    /// The placement of station `s` (the first mount).
    pub fn station_placement(&self, x: &[f64], s: usize) -> Placement {
        self.placement_at(x, s, 0)
    }
    /// Writes a placement into `x` (the inverse of [`Self::placement`]); the placement must be
    /// of this model's measurement.
    pub fn set_placement(&self, x: &mut [f64], p: &Placement) {
        debug_assert_eq!(p.measurement, self.measurement);
        let r = self.placement_range();
        let t = r.start + self.measurement.target_index();
        x[r.start..t].copy_from_slice(&p.own);
        x[t..r.end].copy_from_slice(p.tool.as_slice());
    }
    /// This model measured by another instrument placed at `p`: the placement parameters are
    /// replaced (a model without effect blocks, as the constructors give it).
    pub fn with_placement(mut self, p: &Placement) -> CalibModel {
        assert!(self.effects.is_empty(), "the instrument is chosen before effect blocks are added");
        let nc = self.n_chain();
        let m = p.measurement;
        self.names.truncate(nc);
        self.kinds.truncate(nc);
        self.nominal.truncate(nc);
        self.names.extend(m.placement_names().iter().map(|s| s.to_string()));
        self.kinds.extend((0..m.n_placement()).map(|k| if m.def().placement_is_angle(k) { Kind::Angle } else { Kind::Length }));
        self.nominal.extend(&p.own);
        self.nominal.extend(p.tool.iter());
        self.measurement = m;
        self.stations = Vec::new();
        self.mounts = Vec::new();
        self.spacings = Vec::new();
        self.pulls = Vec::new();
        self.also = None;
        self
    }
    /// This model with a second instrument placed at `p` whose rows share the arm: its
    /// placement parameters after the first's (and before the set-ups' blocks).
    pub fn with_also(mut self, p: &Placement) -> CalibModel {
        assert!(self.effects.is_empty() && self.also.is_none(), "the second instrument is placed before effect blocks are added");
        let at = self.placement_range().end;
        let m = p.measurement;
        if self.shares_stations_with(m) {
            self.also = Some(m);
            return self;
        }
        let values: Vec<f64> = p.own.iter().chain(p.tool.iter()).copied().collect();
        for (k, v) in values.iter().enumerate().rev() {
            self.names.insert(at, format!("{}@{}", m.placement_names()[k], m.name()));
            self.kinds.insert(at, if m.def().placement_is_angle(k) { Kind::Angle } else { Kind::Length });
            self.nominal.insert(at, *v);
        }
        self.also = Some(m);
        self
    }
    /// Indices of the second instrument's placement parameters (empty without one, and for one
    /// that shares the first's stations and target: [`Self::shares_stations_with`]).
    pub fn also_range(&self) -> std::ops::Range<usize> {
        let at = self.placement_range().end;
        at..at + self.also.filter(|m| !self.shares_stations_with(*m)).map_or(0, |m| m.n_placement())
    }
    /// The instrument that read a row.
    pub fn measurement_of(&self, inp: &RowInputs) -> Measurement {
        match (inp.instrument, self.also) {
            (1, Some(m)) => m,
            _ => self.measurement,
        }
    }
    /// Indices of the instrument's placement parameters in the parameter vector.
    pub fn placement_range(&self) -> std::ops::Range<usize> {
        self.n_chain()..self.n_chain() + self.measurement.n_placement()
    }
    /// Index of the reading offset (the draw-wire's length offset) in the parameter vector.
    pub fn length_offset_index(&self) -> Option<usize> {
        self.measurement.offset_index().map(|k| self.n_chain() + k)
    }
    /// Index of the first effect parameter.
    pub fn first_effect(&self) -> usize {
        self.also_range().end + SetupKind::ALL.iter().map(|k| (self.n_setups(*k) - 1) * self.setup_params(*k).len()).sum::<usize>()
    }
    /// Adds an effect block (no-op if an equal block is present); its parameters start at
    /// "no effect" in `nominal`. `t_span_s` is the data's time span (warm-up starting value).
    pub fn add_effect(&mut self, block: EffectBlock, t_span_s: f64) {
        if self.effects.contains(&block) {
            return;
        }
        for ((name, unit), v) in block.params().into_iter().zip(block.start(t_span_s)) {
            self.names.push(name);
            self.kinds.push(Kind::Effect(unit));
            self.nominal.push(v);
        }
        self.effects.push(block);
    }
    /// The point at which the data's view of the parameters is judged from `x`: every block
    /// whose later parameters act only through its size
    /// ([`Effect::later_params_scaled_by_size`](crate::calib::effects::Effect::later_params_scaled_by_size))
    /// and whose size is zero there takes its plausible size, so that a warm-up's time constant
    /// or a sensor's lag is not held as invisible merely because the fit starts without a drift.
    pub fn identifiability_point(&self, x: &[f64]) -> Vec<f64> {
        let mut p = x.to_vec();
        for (b, block) in self.effects.iter().enumerate() {
            let k = self.effect_params(b).start;
            let def = block.kind.def();
            if def.later_params_scaled_by_size(block) && p[k] == 0.0 {
                p[k] = def.plausible(block.joint);
            }
        }
        p
    }
    /// Parameter range of effect block `b`.
    pub fn effect_params(&self, b: usize) -> std::ops::Range<usize> {
        let start = self.first_effect() + self.effects[..b].iter().map(EffectBlock::n_params).sum::<usize>();
        start..start + self.effects[b].n_params()
    }
    /// The sensor nonlinearity block: its first parameter and normalisation range.
    fn nonlinearity(&self) -> Option<(usize, [f64; 2])> {
        let b = self.effects.iter().position(|e| e.kind == EffectKind::Nonlinearity)?;
        Some((self.effect_params(b).start, self.effects[b].range_m.unwrap_or([0.0, 1.0])))
    }
    /// Joint angles and scale with the joint-offset and thermal effects applied (into `w`).
    fn apply_effects(&self, x: &[f64], q: &[f64], inp: &RowInputs, w: &mut ModelWork) -> f64 {
        w.q.clear();
        w.q.extend_from_slice(q);
        if self.effects.is_empty() {
            return 1.0;
        }
        joint_and_scale_effects(&self.effects, self.first_effect(), x, q, inp, &mut w.eff);
        for (qj, d) in w.q.iter_mut().zip(&w.eff.dq) {
            *qj += d;
        }
        w.eff.scale
    }
    /// Reading correction of the sensor nonlinearity at geometric length `l` (m) and its
    /// derivative with respect to `l`.
    fn reading_correction(&self, x: &[f64], l: f64) -> (f64, f64, Option<(usize, [f64; 3])>) {
        let Some((k, [lo, hi])) = self.nonlinearity() else { return (0.0, 0.0, None) };
        let half = 0.5 * (hi - lo).max(1e-9);
        let v = (l - 0.5 * (lo + hi)) / half;
        let (p, dp) = legendre(v);
        let val = (0..3).map(|m| x[k + m] * p[m]).sum::<f64>();
        let dval = (0..3).map(|m| x[k + m] * dp[m]).sum::<f64>() / half;
        (val, dval, Some((k, p)))
    }
    /// Index of the parameter called `name`.
    pub fn index(&self, name: &str) -> Option<usize> {
        self.names.iter().position(|n| n == name)
    }

    /// The instrument's own placement parameters at `station` and the target point on the
    /// flange (m) of `mount`, with the parameter each comes from. A set-up the model does not
    /// have reads the first's.
    fn placed(&self, x: &[f64], station: usize, mount: usize) -> Placed {
        let r = self.placement_range();
        let n = r.len();
        let mut out = Placed { vals: [0.0; MAX_OWN + 3], cols: [0; MAX_OWN + 3], n_own: self.measurement.target_index() };
        out.vals[..n].copy_from_slice(&x[r.clone()]);
        for (k, c) in out.cols[..n].iter_mut().enumerate() {
            *c = r.start + k;
        }
        for (kind, s) in [(SetupKind::Station, station), (SetupKind::Mount, mount)] {
            debug_assert!(s < self.n_setups(kind), "{} {s} of {}", kind.name(), self.n_setups(kind));
            if s > 0 && s < self.n_setups(kind) {
                let block = self.setup_block(kind, s);
                for (p, c) in self.setup_params(kind).zip(block) {
                    out.vals[p] = x[c];
                    out.cols[p] = c;
                }
            }
        }
        out
    }

    /// [`Self::placed`] of a row (the second instrument's placement for a row it read).
    fn placed_of(&self, x: &[f64], inp: &RowInputs) -> Placed {
        if let (1, Some(m)) = (inp.instrument, self.also.filter(|m| !self.shares_stations_with(*m))) {
            let r = self.also_range();
            let mut out = Placed { vals: [0.0; MAX_OWN + 3], cols: [0; MAX_OWN + 3], n_own: m.target_index() };
            out.vals[..r.len()].copy_from_slice(&x[r.clone()]);
            for (k, c) in out.cols[..r.len()].iter_mut().enumerate() {
                *c = r.start + k;
            }
            return out;
        }
        self.placed(x, inp.station, inp.mount)
    }

    /// Tool point in the base frame for joint angles `q` (rad), m (geometry only).
    pub fn tool_point(&self, x: &[f64], q: &[f64], w: &mut ModelWork) -> Vector3<f64> {
        self.tool_point_with(x, q, &RowInputs::default(), w)
    }

    /// Tool point with the joint-offset and thermal effects of the row applied, m.
    pub fn tool_point_with(&self, x: &[f64], q: &[f64], inp: &RowInputs, w: &mut ModelWork) -> Vector3<f64> {
        let tool = self.placed_of(x, inp).tool();
        self.flange_frame_with(x, q, inp, w).point(&tool)
    }

    /// The flange frame in the base frame for joint angles `q` (rad), geometry only.
    pub fn flange_frame(&self, x: &[f64], q: &[f64], w: &mut ModelWork) -> Frame {
        self.flange_frame_with(x, q, &RowInputs::default(), w)
    }

    /// The flange frame with the joint-offset and thermal effects of the row applied.
    pub fn flange_frame_with(&self, x: &[f64], q: &[f64], inp: &RowInputs, w: &mut ModelWork) -> Frame {
        let scale = self.apply_effects(x, q, inp, w);
        self.chain.forward(&w.q, &x[..self.n_chain()], scale, &mut w.fk);
        self.chain.frame(&w.fk, self.chain.flange())
    }

    /// The predicted reading of a one-value measurement (the draw-wire's length, m), every
    /// effect included: [`Self::readings`]'s only value.
    pub fn length(&self, x: &[f64], q: &[f64], inp: &RowInputs, w: &mut ModelWork) -> f64 {
        debug_assert_eq!(self.measurement.dim(), 1);
        let mut y = [0.0; MAX_DIM];
        self.readings(x, q, inp, w, &mut y);
        y[0]
    }

    /// Predicted readings (m, [`Measurement::dim`] values into `y`), every effect included.
    pub fn readings(&self, x: &[f64], q: &[f64], inp: &RowInputs, w: &mut ModelWork, y: &mut [f64]) {
        let placed = self.placed_of(x, inp);
        let (own, tool) = (placed.own(), placed.tool());
        let m = self.measurement_of(inp);
        let def = m.def();
        if def.n_targets() == 1 {
            def.reading(own, std::slice::from_ref(&self.tool_point_with(x, q, inp, w)), y);
        } else {
            let flange = self.flange_frame_with(x, q, inp, w);
            let (local, nt) = Self::targets(def, own, &tool, &mut [Vector3::zeros(); MAX_TARGETS * MAX_OWN]);
            let pts = local.map(|l| flange.point(&l));
            def.reading(own, &pts[..nt], y);
        }
        if m.dim() == 1 {
            let l = y[0];
            y[0] = l + self.reading_correction(x, l).0;
        }
        let width = self.width().min(y.len()).max(m.dim());
        y[m.dim()..width].iter_mut().for_each(|v| *v = 0.0);
    }

    /// The instrument's points of the flange frame (flange coordinates; the first is the
    /// target) with their number, and their derivatives with respect to the instrument's own
    /// parameters into `dlocal`.
    fn targets(
        def: &dyn crate::measurement::Instrument,
        own: &[f64],
        tool: &Vector3<f64>,
        dlocal: &mut [Vector3<f64>],
    ) -> ([Vector3<f64>; MAX_TARGETS], usize) {
        let nt = def.n_targets();
        let mut local = [Vector3::zeros(); MAX_TARGETS];
        def.targets(own, tool, &mut local[..nt], &mut dlocal[..nt * own.len()]);
        (local, nt)
    }

    /// Point Jacobians of the instrument's points of the flange frame at the last forward
    /// evaluation (into `w.jac` and `w.extra`), and the points' derivatives with respect to
    /// the instrument's own parameters into `dlocal`; returns the points (base frame) and their
    /// number.
    fn target_jacobians(
        &self,
        def: &dyn crate::measurement::Instrument,
        own: &[f64],
        tool: &Vector3<f64>,
        w: &mut ModelWork,
        dlocal: &mut [Vector3<f64>],
    ) -> ([Vector3<f64>; MAX_TARGETS], usize) {
        let flange = self.chain.flange();
        let (local, nt) = Self::targets(def, own, tool, dlocal);
        self.chain.point_jacobian(&w.fk, flange, &local[0], &mut w.jac);
        if w.extra.len() + 1 < nt {
            w.extra.resize_with(nt - 1, || PointJacobian::new(&self.chain));
        }
        let mut pts = [Vector3::zeros(); MAX_TARGETS];
        pts[0] = w.jac.point;
        for t in 1..nt {
            self.chain.point_jacobian(&w.fk, flange, &local[t], &mut w.extra[t - 1]);
            pts[t] = w.extra[t - 1].point;
        }
        (pts, nt)
    }

    /// The predicted reading of a one-value measurement (m) and its gradient with respect to
    /// every parameter into `g`.
    pub fn length_grad(&self, x: &[f64], q: &[f64], inp: &RowInputs, w: &mut ModelWork, g: &mut [f64]) -> f64 {
        debug_assert_eq!(self.measurement.dim(), 1);
        let mut y = [0.0; MAX_DIM];
        self.readings_grad(x, q, inp, w, &mut y, g);
        y[0]
    }

    /// Predicted readings (m) into `y` and their Jacobian with respect to every parameter into
    /// `jac` (row-major, one row of [`Self::n_params`] per reading value).
    pub fn readings_grad(&self, x: &[f64], q: &[f64], inp: &RowInputs, w: &mut ModelWork, y: &mut [f64], jac: &mut [f64]) {
        let m = self.measurement_of(inp);
        let (nc, n, dim) = (self.n_chain(), self.n_params(), m.dim());
        let placed = self.placed_of(x, inp);
        let (own, tool) = (placed.own(), placed.tool());
        let n_own = own.len();
        let setup = self.setup_range();
        let scale = self.apply_effects(x, q, inp, w);
        self.chain.forward(&w.q, &x[..nc], scale, &mut w.fk);
        let mut dlocal = [Vector3::zeros(); MAX_TARGETS * MAX_OWN];
        let (pts, nt) = self.target_jacobians(m.def(), own, &tool, w, &mut dlocal);
        let (mut dy_dp, mut dy_down) = ([Vector3::zeros(); MAX_DIM * MAX_TARGETS], [0.0; MAX_DIM * MAX_OWN]);
        m.def().reading_grad(own, &pts[..nt], y, &mut dy_dp[..dim * nt], &mut dy_down[..dim * n_own]);
        let rot = self.chain.frame(&w.fk, self.chain.flange()).rot;
        let (jac0, extra) = (&w.jac, &w.extra);
        for i in 0..dim {
            let g = &mut jac[i * n..(i + 1) * n];
            let u = &dy_dp[i * nt..(i + 1) * nt];
            g[setup.clone()].iter_mut().for_each(|v| *v = 0.0);
            for m in 0..n_own {
                g[placed.cols[m]] = dy_down[i * n_own + m];
            }
            for k in 0..nc {
                g[k] = u[0].dot(&jac0.dparam[k]);
                for t in 1..nt {
                    g[k] += u[t].dot(&extra[t - 1].dparam[k]);
                }
            }
            // The other points move with the instrument's own parameters (a probe's orientation).
            for t in 1..nt {
                let ur = rot.transpose() * u[t];
                for m in 0..n_own {
                    g[placed.cols[m]] += ur.dot(&dlocal[t * n_own + m]);
                }
            }
            // Every point moves with the target as the flange turns it.
            let u_sum = u[1..].iter().fold(u[0], |a, b| a + b);
            let ut = rot.transpose() * u_sum;
            for (c, v) in placed.cols[n_own..n_own + 3].iter().zip(ut.iter()) {
                g[*c] = *v;
            }
            if self.effects.is_empty() {
                continue;
            }
            g[self.first_effect()..].iter_mut().for_each(|v| *v = 0.0);
            for &(k, j, d) in &w.eff.joint_terms {
                let mut dj = u[0].dot(&jac0.dq[j]);
                for t in 1..nt {
                    dj += u[t].dot(&extra[t - 1].dq[j]);
                }
                g[k] += dj * d;
            }
            let mut ds = u[0].dot(&jac0.dscale);
            for t in 1..nt {
                ds += u[t].dot(&extra[t - 1].dscale);
            }
            for &(k, d) in &w.eff.scale_terms {
                g[k] += ds * d;
            }
        }
        if dim == 1 && !self.effects.is_empty() {
            let l = y[0];
            let (corr, dcorr, nl) = self.reading_correction(x, l);
            if let Some((k, p)) = nl {
                // The correction depends on the geometric length: chain rule on everything else.
                jac[..n].iter_mut().for_each(|v| *v *= 1.0 + dcorr);
                jac[k..k + 3].copy_from_slice(&p);
            }
            y[0] = l + corr;
        }
        // A narrower instrument's row reads zeros after its values, whatever the parameters.
        let width = self.width().min(y.len()).max(dim);
        y[dim..width].iter_mut().for_each(|v| *v = 0.0);
        let end = (width * n).min(jac.len()).max(dim * n);
        jac[dim * n..end].iter_mut().for_each(|v| *v = 0.0);
    }

    /// Predicted length (m) and its gradient with respect to the commanded joint angles (m/rad)
    /// into `g`, every effect included; the row's inputs (torques, flanks, time) are held fixed.
    /// A one-value measurement's [`Self::readings_grad_q`].
    pub fn length_grad_q(&self, x: &[f64], q: &[f64], inp: &RowInputs, w: &mut ModelWork, g: &mut [f64]) -> f64 {
        debug_assert_eq!(self.measurement.dim(), 1);
        let mut y = [0.0; MAX_DIM];
        self.readings_grad_q(x, q, inp, w, &mut y, g);
        y[0]
    }

    /// Predicted readings (m) into `y` and their derivatives with respect to the commanded joint
    /// angles (m/rad) into `g` (row-major, one row of N joints per reading value), every effect
    /// included; the row's inputs (torques, flanks, time) are held fixed.
    pub fn readings_grad_q(&self, x: &[f64], q: &[f64], inp: &RowInputs, w: &mut ModelWork, y: &mut [f64], g: &mut [f64]) {
        let m = self.measurement_of(inp);
        let (nc, nj, dim) = (self.n_chain(), self.chain.n_joints, m.dim());
        let placed = self.placed_of(x, inp);
        let (own, tool) = (placed.own(), placed.tool());
        let scale = self.apply_effects(x, q, inp, w);
        self.chain.forward(&w.q, &x[..nc], scale, &mut w.fk);
        let mut dlocal = [Vector3::zeros(); MAX_TARGETS * MAX_OWN];
        let (pts, nt) = self.target_jacobians(m.def(), own, &tool, w, &mut dlocal);
        let (mut dy_dp, mut dy_down) = ([Vector3::zeros(); MAX_DIM * MAX_TARGETS], [0.0; MAX_DIM * MAX_OWN]);
        m.def().reading_grad(own, &pts[..nt], y, &mut dy_dp[..dim * nt], &mut dy_down[..dim * own.len()]);
        let (corr, dcorr) = if dim == 1 {
            let (c, d, _) = self.reading_correction(x, y[0]);
            (c, d)
        } else {
            (0.0, 0.0)
        };
        let own = |j: usize| if self.effects.is_empty() { 0.0 } else { w.eff.ddq_dq[j] };
        for c in 0..dim {
            let u = &dy_dp[c * nt..(c + 1) * nt];
            for (j, gj) in g[c * nj..(c + 1) * nj].iter_mut().enumerate() {
                let mut d = u[0].dot(&w.jac.dq[j]);
                for t in 1..nt {
                    d += u[t].dot(&w.extra[t - 1].dq[j]);
                }
                *gj = (1.0 + dcorr) * d * (1.0 + own(j));
            }
        }
        y[0] += corr;
        let width = self.width().min(y.len()).max(dim);
        y[dim..width].iter_mut().for_each(|v| *v = 0.0);
        let end = (width * nj).min(g.len()).max(dim * nj);
        g[dim * nj..end].iter_mut().for_each(|v| *v = 0.0);
    }

    /// Tool point (m, effects of the row applied) and its derivative with respect to each
    /// commanded joint angle (m/rad) into `dp`; the row's inputs are held fixed.
    pub fn tool_point_jac_q(&self, x: &[f64], q: &[f64], inp: &RowInputs, w: &mut ModelWork, dp: &mut [Vector3<f64>]) -> Vector3<f64> {
        let nc = self.n_chain();
        let tool = self.placed_of(x, inp).tool();
        let scale = self.apply_effects(x, q, inp, w);
        self.chain.forward(&w.q, &x[..nc], scale, &mut w.fk);
        self.chain.point_jacobian(&w.fk, self.chain.flange(), &tool, &mut w.jac);
        let own = |j: usize| if self.effects.is_empty() { 0.0 } else { w.eff.ddq_dq[j] };
        for (j, d) in dp.iter_mut().enumerate().take(self.chain.n_joints) {
            *d = w.jac.dq[j] * (1.0 + own(j));
        }
        w.jac.point
    }

    /// Tool point (m, base frame, effects of the row applied) and its derivative with respect to
    /// every parameter into `dx` (m per parameter unit; [`Self::n_params`] vectors): the chain's,
    /// the target point's on the flange and the effects'; the instrument's own placement does
    /// not move the tool (zero). The row's inputs are held fixed.
    pub fn tool_point_grad_with(&self, x: &[f64], q: &[f64], inp: &RowInputs, w: &mut ModelWork, dx: &mut [Vector3<f64>]) -> Vector3<f64> {
        let nc = self.n_chain();
        let placed = self.placed_of(x, inp);
        let tool = placed.tool();
        let scale = self.apply_effects(x, q, inp, w);
        self.chain.forward(&w.q, &x[..nc], scale, &mut w.fk);
        self.chain.point_jacobian(&w.fk, self.chain.flange(), &tool, &mut w.jac);
        dx.iter_mut().for_each(|d| *d = Vector3::zeros());
        dx[..nc].copy_from_slice(&w.jac.dparam[..nc]);
        let rot = self.chain.frame(&w.fk, self.chain.flange()).rot;
        for m in 0..3 {
            dx[placed.cols[placed.n_own + m]] = rot.column(m).into_owned();
        }
        if !self.effects.is_empty() {
            for &(k, j, d) in &w.eff.joint_terms {
                dx[k] += w.jac.dq[j] * d;
            }
            for &(k, d) in &w.eff.scale_terms {
                dx[k] += w.jac.dscale * d;
            }
        }
        w.jac.point
    }

    /// The tool's orientation in the base frame at the configuration of the last
    /// [`Self::tool_point_jac_q`] on `w` (the flange's axes, turned by a pose probe's calibrated
    /// orientation on the flange when the instrument reads poses), and its angular Jacobian with
    /// respect to each commanded joint angle (rad/rad, base frame) into `dw`.
    pub fn tool_rotation_jac_q(&self, x: &[f64], w: &ModelWork, dw: &mut [Vector3<f64>]) -> nalgebra::Matrix3<f64> {
        let flange = self.chain.flange();
        self.chain.angular_jacobian(&w.fk, flange, dw);
        if !self.effects.is_empty() {
            for (j, d) in dw.iter_mut().enumerate().take(self.chain.n_joints) {
                *d *= 1.0 + w.eff.ddq_dq[j];
            }
        }
        let rot = self.chain.frame(&w.fk, flange).rot;
        match self.measurement {
            crate::measurement::Measurement::Pose => rot * crate::measurement::pose::probe_rotation(self.placed(x, 0, 0).own()),
            _ => rot,
        }
    }

    /// Display value (mm / degrees) of parameter `k`.
    pub fn display(&self, k: usize, v: f64) -> f64 {
        v * self.kinds[k].display()
    }

    /// A model of `chain` (its parameters' `kinds`) measured by a draw-wire placed as `guess`.
    pub fn with_draw_wire(name: &str, chain: Chain, kinds: Vec<Kind>, guess: &DrawWireGuess) -> CalibModel {
        CalibModel::of_chain(name, chain, kinds, &Placement::cable(guess.exit_m.into(), guess.offset_m, guess.tool_m.into()))
    }

    /// A model of `chain` (its parameters' `kinds`, all at zero) measured by the instrument
    /// placed as `placement`: one station, one mount, no effect block.
    pub fn of_chain(name: &str, chain: Chain, kinds: Vec<Kind>, placement: &Placement) -> CalibModel {
        let nominal = vec![0.0; chain.n_params()];
        let model = CalibModel {
            name: name.into(),
            names: chain.param_names.clone(),
            chain,
            kinds,
            nominal,
            effects: Vec::new(),
            limits: Vec::new(),
            measurement: placement.measurement,
            stations: Vec::new(),
            mounts: Vec::new(),
            spacings: Vec::new(),
            pulls: Vec::new(),
            also: None,
        };
        model.with_placement(placement)
    }

    /// Joint limits (rad) for inverse kinematics and sampling: the nominal robot's, else a full
    /// turn either way (−π, π) on every joint.
    pub fn joint_limits(&self) -> Vec<(f64, f64)> {
        if self.limits.len() == self.chain.n_joints {
            return self.limits.clone();
        }
        vec![(-std::f64::consts::PI, std::f64::consts::PI); self.chain.n_joints]
    }

    /// The twin's per-joint frame-error model.
    pub fn frame(robot: &Robot, sensor: &DrawWireGuess) -> CalibModel {
        let chain = robot.error_chain();
        let kinds = chain.param_names.iter().map(|n| if GeoKind::of_name(n) == Some(GeoKind::Length) { Kind::Length } else { Kind::Angle }).collect();
        CalibModel { limits: robot.limits(), ..CalibModel::with_draw_wire(Parametrisation::Frame.name(), chain, kinds, sensor) }
    }

    /// Standard D-H (`hayati = false`) or D-H with Hayati's β on parallel axes.
    pub fn dh(robot: &Robot, sensor: &DrawWireGuess, hayati: bool) -> CalibModel {
        let p = if hayati { Parametrisation::Hayati } else { Parametrisation::Dh };
        let table = if hayati { DhTable::from_robot_hayati(robot) } else { DhTable::from_robot(robot) };
        let m = CalibModel::from_table(p.name(), &table, sensor, hayati, true);
        CalibModel { limits: robot.limits(), ..m }
    }

    /// A model of D-H deviations from `table` (Hayati's β on its parallel rows when `hayati`),
    /// with the table's base and flange frames when `with_fixed`.
    pub fn from_table(name: &str, table: &DhTable, sensor: &DrawWireGuess, hayati: bool, with_fixed: bool) -> CalibModel {
        let (chain, kinds) = table.chain(hayati, with_fixed);
        CalibModel::with_draw_wire(name, chain, kinds, sensor)
    }

    /// A 6R model with absolute D-H values as parameters (no nominal robot), base = D-H frame 0.
    pub fn generic(n: usize, sensor: &DrawWireGuess) -> CalibModel {
        let table = DhTable {
            base: Frame::identity(),
            rows: vec![DhRow { theta: 0.0, d: 0.0, a: 0.0, alpha: 0.0, parallel: false, beta: 0.0 }; n],
            tool: Frame::identity(),
        };
        let (chain, kinds) = table.chain(false, false);
        CalibModel::with_draw_wire("generic6r", chain, kinds, sensor)
    }
}

/// Initial guess of the sensor geometry.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct DrawWireGuess {
    /// Cable exit point in the base frame, m.
    pub exit_m: [f64; 3],
    /// Length offset added to the geometric distance, m.
    pub offset_m: f64,
    /// Cable attachment point in the flange frame, m.
    pub tool_m: [f64; 3],
}

#[cfg(test)]
mod tests;
