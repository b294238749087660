//! Adaptive wavelet network (AWNN): a one-hidden-layer network on the commanded joint angles
//! whose neurons are wavelets along learned projections of the input.
//!
//! With the joint angles standardised, `u_i = (q_i − mean_i) / scale_i`, neuron `j` sees
//! `z_j = (v_j · u − b_j) / a_j` and the output (mm) is
//!
//! ```text
//! f(q) = Σ_j w_j ψ(z_j)
//! ```
//!
//! with output weights `w`, translations `b`, dilations `a > 0` and input projection weights `v`
//! (one row of `d` per neuron). Every one of them is learned. The activation `ψ` is
//! * the Mexican hat `(1 − z²)·exp(−z²/2)` (zero mean over the line, so a neuron cannot hold a
//!   constant offset: what is constant belongs to the geometry),
//! * the real Morlet wavelet `cos(ω₀z)·exp(−z²/2)` with `ω₀ = 1.75` (the usual choice of wavelet
//!   networks, one oscillation inside the envelope), the paper's kernel ablation, or
//! * the rectifier `max(0, z)`, which makes the same structure an ordinary ReLU multilayer
//!   perceptron (the MLP ablation).
//!
//! Two layouts:
//! * [`Awnn::library`], what PSO-EKF-AWNN starts from: a multiresolution [`Library`] along every
//!   input axis and the sum/difference diagonals of joint pairs, translations spread evenly over
//!   the range each direction takes on the training poses, dilations that range over the
//!   level's neuron count (neighbours overlap); its output layer is then fitted by
//!   cross-validated least squares ([`crate::calib::methods::awnn_select`]).
//! * [`Awnn::init`]: a few neurons dealt to the joints in turn, each on its joint's axis (tilted
//!   by a small seeded random amount, [`TILT`], so that learning can mix joints), spread and
//!   dilated alike, with zero output weights (the network starts as "no correction").
//!
//! Learning ([`Awnn::sgd_step`]) is plain stochastic gradient descent on `½e²` with
//! `e = target − f(q)`: `θ ← θ + η·e·∂f/∂θ` for all four groups. Dilations are kept above
//! [`MIN_DILATION`] (in standardised units) so that no neuron collapses to a spike.
//!
//! As a [`Correct`] the network gives its value and its analytic gradient with respect to `q`:
//! `∂f/∂q_i = Σ_j w_j ψ'(z_j) v_ji / (a_j · scale_i)`.

use super::correct::Correct;
use crate::calib::effects::RowInputs;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

/// Smallest dilation (standardised input units) learning may reach.
pub const MIN_DILATION: f64 = 0.05;
/// Largest off-axis component of an initial projection (before normalisation).
pub const TILT: f64 = 0.05;
/// Largest initial component of a projection along an extra (non-joint) input: large enough that
/// every neuron starts as a mixed function of its joint and those inputs.
pub const EXTRA_TILT: f64 = 0.5;
/// Centre frequency of the real Morlet wavelet.
pub const MORLET_OMEGA: f64 = 1.75;

/// The neurons' activation, see the module docs.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Activation {
    /// The Mexican-hat wavelet (1 − z²)·e^(−z²/2).
    MexicanHat,
    /// The real Morlet wavelet cos(ω₀z)·e^(−z²/2), ω₀ = [`MORLET_OMEGA`].
    Morlet,
    /// The rectifier max(z, 0).
    Relu,
}

impl Activation {
    /// ψ(z) and ψ'(z).
    #[inline]
    pub fn eval(self, z: f64) -> (f64, f64) {
        match self {
            Activation::MexicanHat => {
                let g = (-0.5 * z * z).exp();
                ((1.0 - z * z) * g, z * (z * z - 3.0) * g)
            }
            Activation::Morlet => {
                let g = (-0.5 * z * z).exp();
                let (s, c) = (MORLET_OMEGA * z).sin_cos();
                (c * g, -(MORLET_OMEGA * s + z * c) * g)
            }
            Activation::Relu => {
                if z > 0.0 {
                    (z, 1.0)
                } else {
                    (0.0, 0.0)
                }
            }
        }
    }
    /// The name reports give it (`mexican hat`, `morlet`, `relu`).
    pub fn label(self) -> &'static str {
        match self {
            Activation::MexicanHat => "mexican hat",
            Activation::Morlet => "morlet",
            Activation::Relu => "relu",
        }
    }
}

/// An input of the network besides the joint angles, read from the row's [`RowInputs`]. The
/// network's input vector is `[q1..q6, extra...]`; every input is standardised with its mean and
/// standard deviation over the training rows (so the temperature enters as its rise above the
/// training rows' mean). A row that lacks the value (no temp column at predict time) gets the
/// training mean, i.e. no contribution along that input.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Feature {
    /// Measured temperature, °C.
    Temperature,
    /// Time since the start of acquisition, s (when the data have no temperature).
    Time,
    /// Backlash flank of a joint (0-based), ±1, from the calibration's own rule
    /// ([`crate::calib::effects::inputs::row_inputs`]).
    Side(usize),
    /// Static gravity (and payload/cable) torque on a joint (0-based), N·m, from the result's
    /// torque model.
    Torque(usize),
}

impl Feature {
    /// The value at a row, `None` when the row lacks it.
    pub fn value(self, inp: &RowInputs) -> Option<f64> {
        match self {
            Feature::Temperature => inp.temp_c,
            Feature::Time => inp.t_s,
            Feature::Side(j) => inp.side.get(j).copied(),
            Feature::Torque(j) => inp.torque.get(j).copied(),
        }
    }
    /// The short name reports give it (`temp`, `t`, `side2`, `tau2`; joints 1-based).
    pub fn label(self) -> String {
        match self {
            Feature::Temperature => "temp".into(),
            Feature::Time => "t".into(),
            Feature::Side(j) => format!("side{}", j + 1),
            Feature::Torque(j) => format!("tau{}", j + 1),
        }
    }
}

/// Joints whose pairs get diagonal directions in a [`Library`] (the wrist roll, joint 6, turns
/// the tool about its own axis and couples little).
pub const PAIR_JOINTS: usize = 5;

/// A multiresolution layout of neurons ([`Awnn::library`]). Directions (in standardised input
/// units): every input axis and, with `pairs`, the sum and difference diagonals
/// `(e_i ± e_j)/√2` of every pair among the first [`PAIR_JOINTS`] joints, where configuration
/// coupling lives (the gravity torque on joint 2 depends on joints 2 and 3 together). Along
/// each direction and for each `per` in `levels`, `per` neurons with translations spread over
/// the direction's range on the training rows and dilation that range over `per`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Library {
    /// Neurons per direction at each resolution level.
    pub levels: &'static [usize],
    /// Whether the pair diagonals are directions too.
    pub pairs: bool,
}

impl Library {
    /// The unnormalised directions for `nq` joints among `d` inputs.
    fn directions(&self, nq: usize, d: usize) -> Vec<Vec<f64>> {
        let axis = |i: usize| (0..d).map(|c| if c == i { 1.0 } else { 0.0 }).collect::<Vec<f64>>();
        let mut dirs: Vec<Vec<f64>> = (0..d).map(axis).collect();
        if self.pairs {
            let c = PAIR_JOINTS.min(nq);
            for i in 0..c {
                for j in i + 1..c {
                    for s in [1.0, -1.0] {
                        let mut v = axis(i);
                        v[j] = s;
                        dirs.push(v);
                    }
                }
            }
        }
        dirs
    }
    /// E.g. "axes + pair diagonals, 2+4 per direction".
    pub fn label(&self) -> String {
        let levels = self.levels.iter().map(|l| l.to_string()).collect::<Vec<_>>().join("+");
        format!("{}, {levels} per direction", if self.pairs { "axes + pair diagonals" } else { "axes" })
    }
}

/// An adaptive wavelet network, see the module docs. Stored in result.json as the corrector
/// `{"kind": "awnn", ...}`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Awnn {
    /// The neurons' activation.
    pub activation: Activation,
    /// Inputs after the joint angles (empty: the paper's network on q alone).
    #[serde(default)]
    pub extra: Vec<Feature>,
    /// Mean of each input (joint angles in rad, then `extra`) over the training rows.
    pub input_mean: Vec<f64>,
    /// Standard deviation of each input over the training rows.
    pub input_scale: Vec<f64>,
    /// Input projection weights, one row of `d` per neuron.
    pub projection: Vec<Vec<f64>>,
    /// Translations `b`.
    pub translation: Vec<f64>,
    /// Dilations `a` (> 0).
    pub dilation: Vec<f64>,
    /// Output weights `w`, mm.
    pub weights: Vec<f64>,
    /// The range of outputs (mm) the network may give as a corrector: what it gave on its
    /// training rows, widened by [`OUTPUT_MARGIN`] of the span. A network that fits sharp
    /// features of its training rows (a stretch of slipped readings) with large opposing weights
    /// can return tens of millimetres at a pose between them; a corrector never corrects more
    /// than it learned. Absent: no limit (files written before the guard).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub output_range: Option<[f64; 2]>,
    /// Held at zero output weights while the method trains (the network's choice found it no
    /// better than the geometry alone by one standard error): SGD, the refinement and V5's
    /// joint problem leave it as it is. Not stored.
    #[serde(skip)]
    pub frozen: bool,
}

/// Widening of [`Awnn::output_range`] beyond the training outputs, as a share of their span.
pub const OUTPUT_MARGIN: f64 = 0.1;

impl Awnn {
    /// A fresh network of `neurons` neurons on the joint angles `qs` alone (the paper's network,
    /// see the module docs); `seed` draws the projections. Errors on empty or non-finite input.
    pub fn init(qs: &[Vec<f64>], neurons: usize, activation: Activation, seed: u64) -> Result<Awnn, String> {
        let inputs = vec![RowInputs::default(); qs.len()];
        Awnn::init_with(qs, &inputs, &[], neurons, activation, seed)
    }

    /// A fresh network on the joint angles `qs` and the `extra` inputs of each row `inputs`.
    /// Neurons are dealt to the joint axes as in [`init`](Self::init); their components along
    /// the extra inputs start at a small seeded tilt, like the off-axis joint components, so
    /// the network starts as a function of q and learning moves weight onto the extra inputs.
    /// Every training row must carry every extra input.
    pub fn init_with(qs: &[Vec<f64>], inputs: &[RowInputs], extra: &[Feature], neurons: usize, activation: Activation, seed: u64) -> Result<Awnn, String> {
        if neurons == 0 {
            return Err("awnn: needs at least one neuron".into());
        }
        let (mut net, std) = Awnn::empty(qs, inputs, extra, activation)?;
        let (nq, d) = (net.joints(), net.inputs());
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        for j in 0..neurons {
            // Neuron j starts on joint i = j mod nq (per = its joint's neuron count, k = its rank
            // there), its projection that joint's axis plus a small seeded tilt so that learning
            // can mix inputs; translations spread over the projection's range on the training rows.
            let (i, k) = (j % nq, j / nq);
            let per = (neurons - i).div_ceil(nq);
            let v: Vec<f64> = (0..d)
                .map(|c| {
                    let tilt = if c < nq { TILT } else { EXTRA_TILT };
                    if c == i {
                        1.0
                    } else {
                        tilt * (2.0 * rng.random::<f64>() - 1.0)
                    }
                })
                .collect();
            net.place(v, &std, k, per);
        }
        Ok(net)
    }

    /// A network laid out as a multiresolution library of `shape` (see [`Library`]) with zero
    /// output weights: its output layer is then fitted by least squares
    /// ([`crate::calib::methods::awnn_select`]).
    pub fn library(qs: &[Vec<f64>], inputs: &[RowInputs], extra: &[Feature], shape: &Library, activation: Activation) -> Result<Awnn, String> {
        let (mut net, std) = Awnn::empty(qs, inputs, extra, activation)?;
        for v in shape.directions(net.joints(), net.inputs()) {
            for &per in shape.levels {
                for k in 0..per {
                    net.place(v.clone(), &std, k, per);
                }
            }
        }
        Ok(net)
    }

    /// A network without neurons whose input standardisation comes from the training rows, and
    /// those rows standardised.
    fn empty(qs: &[Vec<f64>], inputs: &[RowInputs], extra: &[Feature], activation: Activation) -> Result<(Awnn, Vec<Vec<f64>>), String> {
        let nq = qs.first().map(|q| q.len()).ok_or("awnn: no training poses")?;
        if nq == 0 {
            return Err("awnn: needs at least one input".into());
        }
        if qs.iter().any(|q| q.len() != nq || q.iter().any(|v| !v.is_finite())) {
            return Err("awnn: joint angles of unequal length or not finite".into());
        }
        if inputs.len() != qs.len() {
            return Err("awnn: one row of inputs per pose needed".into());
        }
        let mut xs = Vec::with_capacity(qs.len());
        for (q, inp) in qs.iter().zip(inputs) {
            let mut x = q.clone();
            for f in extra {
                match f.value(inp).filter(|v| v.is_finite()) {
                    Some(v) => x.push(v),
                    None => return Err(format!("awnn: input {} missing on a training row", f.label())),
                }
            }
            xs.push(x);
        }
        let d = nq + extra.len();
        let n = xs.len() as f64;
        let input_mean: Vec<f64> = (0..d).map(|i| xs.iter().map(|x| x[i]).sum::<f64>() / n).collect();
        let input_scale: Vec<f64> = (0..d)
            .map(|i| {
                let s = (xs.iter().map(|x| (x[i] - input_mean[i]).powi(2)).sum::<f64>() / n).sqrt();
                if s > 1e-9 {
                    s
                } else {
                    1.0
                }
            })
            .collect();
        let std = xs.iter().map(|x| x.iter().enumerate().map(|(i, v)| (v - input_mean[i]) / input_scale[i]).collect()).collect();
        let net = Awnn {
            activation,
            extra: extra.to_vec(),
            input_mean,
            input_scale,
            projection: Vec::new(),
            translation: Vec::new(),
            dilation: Vec::new(),
            weights: Vec::new(),
            output_range: None,
            frozen: false,
        };
        Ok((net, std))
    }

    /// Adds a neuron along direction `v` (normalised here): the `k`-th of `per` translations
    /// spread evenly over the range `v` takes on the standardised training rows `std`, dilation
    /// that range over `per` (neighbours overlap), zero output weight.
    fn place(&mut self, mut v: Vec<f64>, std: &[Vec<f64>], k: usize, per: usize) {
        let norm = v.iter().map(|x| x * x).sum::<f64>().sqrt();
        v.iter_mut().for_each(|x| *x /= norm);
        let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
        for u in std {
            let s: f64 = v.iter().zip(u).map(|(a, b)| a * b).sum();
            lo = lo.min(s);
            hi = hi.max(s);
        }
        let span = (hi - lo).max(1e-6);
        self.projection.push(v);
        self.translation.push(lo + span * (k as f64 + 0.5) / per as f64);
        self.dilation.push((span / per as f64).max(MIN_DILATION));
        self.weights.push(0.0);
    }

    /// Number of neurons.
    pub fn neurons(&self) -> usize {
        self.weights.len()
    }
    /// Number of inputs: the joint angles and the extra inputs.
    pub fn inputs(&self) -> usize {
        self.input_scale.len()
    }
    /// Number of joint-angle inputs.
    pub fn joints(&self) -> usize {
        self.inputs().saturating_sub(self.extra.len())
    }
    /// Number of learned values: `M·(d + 3)`.
    pub fn n_params(&self) -> usize {
        self.neurons() * (self.inputs() + 3)
    }
    /// The inputs, e.g. "q1..q6" or "q1..q6, temp, side1..side6".
    pub fn input_label(&self) -> String {
        let mut s = format!("q1..q{}", self.joints());
        for f in &self.extra {
            s.push_str(", ");
            s.push_str(&f.label());
        }
        s
    }

    /// Standardised input vector of a row (a missing extra input sits at its training mean).
    fn standardise(&self, q: &[f64], inp: &RowInputs, u: &mut [f64]) {
        let nq = self.joints();
        for (i, ui) in u.iter_mut().enumerate().take(nq) {
            *ui = (q[i] - self.input_mean[i]) / self.input_scale[i];
        }
        for (k, f) in self.extra.iter().enumerate() {
            let i = nq + k;
            u[i] = f.value(inp).filter(|v| v.is_finite()).map_or(0.0, |v| (v - self.input_mean[i]) / self.input_scale[i]);
        }
    }

    /// Neuron `j`'s argument `z_j` at standardised input `u`.
    #[inline]
    fn arg(&self, j: usize, u: &[f64]) -> f64 {
        let s: f64 = self.projection[j].iter().zip(u).map(|(a, b)| a * b).sum();
        (s - self.translation[j]) / self.dilation[j]
    }

    /// Output (mm) at joint angles `q` (rad) with no row inputs (for the q-only network).
    pub fn eval(&self, q: &[f64]) -> f64 {
        self.eval_row(q, &RowInputs::default())
    }

    /// Output (mm) at joint angles `q` (rad) and the row's inputs. NaN when `q` has the wrong
    /// length.
    pub fn eval_row(&self, q: &[f64], inp: &RowInputs) -> f64 {
        if q.len() != self.joints() {
            return f64::NAN;
        }
        let mut buf = [0.0; 32];
        let mut heap = Vec::new();
        let u: &mut [f64] = if self.inputs() <= 32 {
            &mut buf[..self.inputs()]
        } else {
            heap.resize(self.inputs(), 0.0);
            &mut heap
        };
        self.standardise(q, inp, u);
        (0..self.neurons()).map(|j| self.weights[j] * self.activation.eval(self.arg(j, u)).0).sum()
    }

    /// Every neuron's activation `ψ(z_j)` at every row: one row per pose, one column per
    /// neuron (the output is this matrix times `weights`).
    pub fn hidden_matrix(&self, qs: &[Vec<f64>], inputs: &[RowInputs]) -> nalgebra::DMatrix<f64> {
        let mut h = nalgebra::DMatrix::zeros(qs.len(), self.neurons());
        let mut u = vec![0.0; self.inputs()];
        for (i, (q, inp)) in qs.iter().zip(inputs).enumerate() {
            self.standardise(q, inp, &mut u);
            for j in 0..self.neurons() {
                h[(i, j)] = self.activation.eval(self.arg(j, &u)).0;
            }
        }
        h
    }

    /// Output and its gradient with respect to every learned value, in the order of
    /// [`params`](Self::params): `[w (M), b (M), a (M), v (M·d, row by row)]`.
    pub fn eval_param_grad(&self, q: &[f64], inp: &RowInputs, g: &mut [f64]) -> f64 {
        let (m, d) = (self.neurons(), self.inputs());
        let mut u = vec![0.0; d];
        self.standardise(q, inp, &mut u);
        let mut f = 0.0;
        for j in 0..m {
            let z = self.arg(j, &u);
            let (psi, dpsi) = self.activation.eval(z);
            let a = self.dilation[j];
            let wd = self.weights[j] * dpsi / a;
            f += self.weights[j] * psi;
            g[j] = psi;
            g[m + j] = -wd;
            g[2 * m + j] = -wd * z;
            for i in 0..d {
                g[3 * m + j * d + i] = wd * u[i];
            }
        }
        f
    }

    /// The learned values as one vector (see [`eval_param_grad`](Self::eval_param_grad)).
    pub fn params(&self) -> Vec<f64> {
        let mut p = Vec::with_capacity(self.n_params());
        p.extend(&self.weights);
        p.extend(&self.translation);
        p.extend(&self.dilation);
        for row in &self.projection {
            p.extend(row);
        }
        p
    }

    /// Sets the learned values from one vector (dilations kept above [`MIN_DILATION`]).
    pub fn set_params(&mut self, p: &[f64]) {
        let (m, d) = (self.neurons(), self.inputs());
        self.weights.copy_from_slice(&p[..m]);
        self.translation.copy_from_slice(&p[m..2 * m]);
        for (a, v) in self.dilation.iter_mut().zip(&p[2 * m..3 * m]) {
            *a = v.max(MIN_DILATION);
        }
        for (j, row) in self.projection.iter_mut().enumerate() {
            row.copy_from_slice(&p[3 * m + j * d..3 * m + (j + 1) * d]);
        }
    }

    /// One SGD step on `½e²`, `e = target − f(q, inputs)`, given `e`: every learned value moves
    /// by `η·e·∂f/∂θ`. A step that would make anything non-finite is skipped. `g` is scratch of
    /// length [`n_params`](Self::n_params).
    pub fn sgd_step(&mut self, q: &[f64], inp: &RowInputs, e: f64, lr: f64, g: &mut [f64]) {
        if self.frozen || !(e.is_finite() && lr.is_finite()) {
            return;
        }
        self.eval_param_grad(q, inp, g);
        if g.iter().any(|v| !v.is_finite()) {
            return;
        }
        let (m, d) = (self.neurons(), self.inputs());
        let s = lr * e;
        for j in 0..m {
            self.weights[j] += s * g[j];
            self.translation[j] += s * g[m + j];
            self.dilation[j] = (self.dilation[j] + s * g[2 * m + j]).max(MIN_DILATION);
            for i in 0..d {
                self.projection[j][i] += s * g[3 * m + j * d + i];
            }
        }
    }

    /// Sets [`Self::output_range`] from the outputs on the training rows `qs` / `inputs`.
    pub fn limit_to(&mut self, qs: &[Vec<f64>], inputs: &[RowInputs]) {
        self.output_range = None;
        let out: Vec<f64> = qs.iter().zip(inputs).map(|(q, inp)| self.eval_row(q, inp)).filter(|v| v.is_finite()).collect();
        let (lo, hi) = out.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| (a.min(*v), b.max(*v)));
        if lo <= hi {
            let m = OUTPUT_MARGIN * (hi - lo);
            self.output_range = Some([lo - m, hi + m]);
        }
    }

    /// Checks a deserialised network (a hand-edited or truncated file must not give NaN).
    pub fn validate(&self, n_joints: usize) -> Result<(), String> {
        let (m, d) = (self.neurons(), self.inputs());
        let ok = self.joints() == n_joints
            && d >= n_joints
            && self.extra.iter().all(|f| !matches!(f, Feature::Side(j) | Feature::Torque(j) if *j >= n_joints))
            && self.input_mean.len() == d
            && self.translation.len() == m
            && self.dilation.len() == m
            && self.projection.len() == m
            && self.projection.iter().all(|r| r.len() == d && r.iter().all(|v| v.is_finite()))
            && self.input_scale.iter().all(|v| v.is_finite() && *v > 0.0)
            && self.dilation.iter().all(|v| v.is_finite() && *v >= MIN_DILATION)
            && self.input_mean.iter().chain(&self.translation).chain(&self.weights).all(|v| v.is_finite())
            && self.output_range.is_none_or(|[lo, hi]| lo.is_finite() && hi.is_finite() && lo <= hi);
        if ok {
            Ok(())
        } else {
            Err("the AWNN corrector is inconsistent".into())
        }
    }
}

impl Correct for Awnn {
    fn label(&self) -> String {
        format!("awnn ({}, {} neurons on {})", self.activation.label(), self.neurons(), self.input_label())
    }
    fn n_weights(&self) -> usize {
        self.n_params()
    }
    fn correction_mm(&self, q: &[f64], inp: &RowInputs) -> f64 {
        let f = self.eval_row(q, inp);
        match self.output_range {
            Some([lo, hi]) => f.clamp(lo, hi),
            None => f,
        }
    }
    /// The gradient with respect to q only: the row's other inputs (temperature, flanks,
    /// torques) are held fixed. Zero where the output is held at a limit of its range.
    fn correction_grad_mm(&self, q: &[f64], inp: &RowInputs, g: &mut [f64]) -> f64 {
        let f = self.correction_grad_unlimited(q, inp, g);
        match self.output_range {
            Some([lo, hi]) if !(lo..=hi).contains(&f) => {
                g.iter_mut().for_each(|v| *v = 0.0);
                f.clamp(lo, hi)
            }
            _ => f,
        }
    }
}

impl Awnn {
    /// The output and its q-gradient without the output range.
    fn correction_grad_unlimited(&self, q: &[f64], inp: &RowInputs, g: &mut [f64]) -> f64 {
        let (d, nq) = (self.inputs(), self.joints());
        g.iter_mut().for_each(|v| *v = 0.0);
        let mut u = vec![0.0; d];
        self.standardise(q, inp, &mut u);
        let mut f = 0.0;
        for j in 0..self.neurons() {
            let (psi, dpsi) = self.activation.eval(self.arg(j, &u));
            f += self.weights[j] * psi;
            let c = self.weights[j] * dpsi / self.dilation[j];
            for i in 0..nq {
                g[i] += c * self.projection[j][i] / self.input_scale[i];
            }
        }
        f
    }
}

#[cfg(test)]
mod tests {
    use super::super::correct::gradient_error;
    use super::*;

    fn poses(n: usize, seed: u64) -> Vec<Vec<f64>> {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        (0..n).map(|_| (0..6).map(|_| rng.random_range(-1.5..1.5)).collect()).collect()
    }

    /// A trained-looking network: random non-zero weights, moved translations and dilations.
    fn perturbed(act: Activation) -> Awnn {
        perturb(Awnn::init(&poses(50, 1), 12, act, 3).unwrap())
    }

    /// `net` with every parameter moved by a seeded uniform step in ±0.3.
    fn perturb(mut net: Awnn) -> Awnn {
        let mut rng = ChaCha8Rng::seed_from_u64(4);
        let mut p = net.params();
        for v in p.iter_mut() {
            *v += rng.random_range(-0.3..0.3);
        }
        net.set_params(&p);
        net
    }

    #[test]
    fn q_gradient_matches_finite_differences() {
        let qs = poses(8, 9);
        let inp = RowInputs::default();
        for act in [Activation::MexicanHat, Activation::Morlet, Activation::Relu] {
            let c = perturbed(act);
            c.validate(6).unwrap();
            // ReLU kinks: finite differences across one are wrong by design; a 1e-7 step at
            // these random poses does not straddle one (a failure would say so loudly).
            let err = gradient_error(&c, &qs, &inp, 1e-7);
            assert!(err < 1e-5, "{act:?}: relative gradient error {err}");
        }
    }

    #[test]
    fn parameter_gradient_matches_finite_differences() {
        for act in [Activation::MexicanHat, Activation::Morlet] {
            let net = perturbed(act);
            let q = &poses(1, 11)[0];
            let mut g = vec![0.0; net.n_params()];
            let f = net.eval_param_grad(q, &RowInputs::default(), &mut g);
            assert!((f - net.eval(q)).abs() < 1e-12);
            let p = net.params();
            for k in 0..p.len() {
                let (mut a, mut b) = (net.clone(), net.clone());
                let (mut pa, mut pb) = (p.clone(), p.clone());
                pa[k] += 1e-6;
                pb[k] -= 1e-6;
                a.set_params(&pa);
                b.set_params(&pb);
                let fd = (a.eval(q) - b.eval(q)) / 2e-6;
                assert!((fd - g[k]).abs() < 1e-6 * (1.0 + g[k].abs()), "{act:?} param {k}: {fd} vs {}", g[k]);
            }
        }
    }

    #[test]
    fn sgd_learns_a_smooth_field_and_mexican_hat_starts_at_zero() {
        let train = poses(300, 5);
        let test = poses(200, 6);
        let field = |q: &[f64]| 0.05 * (q[1] + q[2]).cos() + 0.02 * q[4].sin();
        let mut net = Awnn::init(&train, 20, Activation::MexicanHat, 7).unwrap();
        assert!(train.iter().all(|q| net.eval(q) == 0.0));
        let rms = |net: &Awnn, qs: &[Vec<f64>]| (qs.iter().map(|q| (field(q) - net.eval(q)).powi(2)).sum::<f64>() / qs.len() as f64).sqrt();
        let before = rms(&net, &test);
        let mut g = vec![0.0; net.n_params()];
        for _ in 0..60 {
            for q in &train {
                let e = field(q) - net.eval(q);
                net.sgd_step(q, &RowInputs::default(), e, 0.05, &mut g);
            }
        }
        let after = rms(&net, &test);
        assert!(after < 0.5 * before, "test RMS {before} -> {after}");
        // Reproducible from the seed.
        assert_eq!(Awnn::init(&train, 20, Activation::MexicanHat, 7).unwrap(), Awnn::init(&train, 20, Activation::MexicanHat, 7).unwrap());
    }

    /// Rows with a temperature and flanks besides q.
    fn rows(n: usize, seed: u64) -> (Vec<Vec<f64>>, Vec<RowInputs>) {
        let qs = poses(n, seed);
        let mut rng = ChaCha8Rng::seed_from_u64(seed + 100);
        let inp = (0..n)
            .map(|_| {
                let temp_c = Some(rng.random_range(20.0..26.0));
                let side = (0..6).map(|_| if rng.random::<bool>() { 1.0 } else { -1.0 }).collect();
                RowInputs { temp_c, side, ..Default::default() }
            })
            .collect();
        (qs, inp)
    }

    #[test]
    fn extra_inputs_learn_what_q_cannot_see_and_the_q_gradient_holds_them_fixed() {
        // A temperature-times-pose field and a flank-dependent offset along q2: invisible to a
        // network on q alone, learnable with the extra inputs.
        let extra = [Feature::Temperature, Feature::Side(1)];
        let field = |q: &[f64], r: &RowInputs| 0.3 * (r.temp_c.unwrap() - 23.0) * q[1].cos() + 0.5 * r.side[1] * q[2].sin();
        let (train, ti) = rows(400, 21);
        let (test, si) = rows(200, 22);
        let fit = |extra: &[Feature]| {
            let mut net = Awnn::init_with(&train, &ti, extra, 20, Activation::MexicanHat, 7).unwrap();
            let mut g = vec![0.0; net.n_params()];
            for _ in 0..80 {
                for (q, r) in train.iter().zip(&ti) {
                    let e = field(q, r) - net.eval_row(q, r);
                    net.sgd_step(q, r, e, 0.03, &mut g);
                }
            }
            let rms = (test.iter().zip(&si).map(|(q, r)| (field(q, r) - net.eval_row(q, r)).powi(2)).sum::<f64>() / test.len() as f64).sqrt();
            (net, rms)
        };
        let base = (test.iter().zip(&si).map(|(q, r)| field(q, r).powi(2)).sum::<f64>() / test.len() as f64).sqrt();
        let (net, with) = fit(&extra);
        let (_, without) = fit(&[]);
        assert!(with < 0.6 * base && with < 0.7 * without, "test RMS: field {base}, q only {without}, q + temp + flank {with}");
        assert_eq!(net.inputs(), 8);
        assert_eq!(net.input_label(), "q1..q6, temp, side2");
        // The q-gradient at fixed row inputs against finite differences, and through the
        // stored form (serde) with the inputs named.
        let c = perturbed_with(&extra);
        c.validate(6).unwrap();
        for r in &si[..4] {
            let err = gradient_error(&c, &test[..4], r, 1e-7);
            assert!(err < 1e-5, "relative gradient error {err}");
        }
        let json = serde_json::to_string(&c).unwrap();
        assert!(json.contains("\"extra\":[\"temperature\",{\"side\":1}]"), "{json}");
        let back: Awnn = serde_json::from_str(&json).unwrap();
        assert!((back.correction_mm(&test[0], &si[0]) - c.correction_mm(&test[0], &si[0])).abs() < 1e-9);
        // A row without the temperature sits at the training mean; one input too many is refused.
        let no_temp = RowInputs { temp_c: None, ..si[0].clone() };
        assert!(c.correction_mm(&test[0], &no_temp).is_finite());
        let mut bad = c;
        bad.extra.push(Feature::Time);
        assert!(bad.validate(6).is_err());
        // A training row missing an extra input is an error, not a silent zero.
        let mut ti2 = ti.clone();
        ti2[3].temp_c = None;
        assert!(Awnn::init_with(&train, &ti2, &extra, 4, Activation::MexicanHat, 0).is_err());
    }

    /// [`perturbed`] for a Mexican-hat network that also reads `extra` row inputs.
    fn perturbed_with(extra: &[Feature]) -> Awnn {
        let (qs, inp) = rows(50, 1);
        perturb(Awnn::init_with(&qs, &inp, extra, 12, Activation::MexicanHat, 3).unwrap())
    }

    #[test]
    fn inconsistent_network_is_refused() {
        let mut net = perturbed(Activation::MexicanHat);
        assert!(net.validate(5).is_err());
        net.dilation[2] = -1.0;
        assert!(net.validate(6).is_err());
        let mut net = perturbed(Activation::MexicanHat);
        net.projection[0].pop();
        assert!(net.validate(6).is_err());
        assert!(Awnn::init(&[], 4, Activation::Morlet, 0).is_err());
        assert!(Awnn::init(&[vec![f64::NAN; 6]], 4, Activation::Morlet, 0).is_err());
    }
}
