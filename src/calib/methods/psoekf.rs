//! Method `pso-ekf-awnn`: PSO meta-optimisation, an EKF whose observation carries an adaptive
//! wavelet network, and a decoupled Levenberg–Marquardt refinement (after Mao, Lai & Li,
//! "Hybrid neuro-symbolic state-space modeling for industrial robot calibration via adaptive
//! wavelet networks and PSO").
//!
//! ```text
//! Start    LM over the geometry; the network's layout, output-magnitude weight and ridge chosen
//!          by 5-fold CV on its residuals, output layer by least squares (awnn_select)
//! Stage 0  PSO over (Q, R, η) in a fixed box          fitness: training innovation RMSE of Stage I
//! Stage I  EKF over the geometric states; per row     ẑ = h(x, q) + f_AWNN(q),  y = z − ẑ
//!          x ← x + K·y (Kalman), θ ← θ + η·y·∂f/∂θ (SGD on every AWNN parameter)
//! Stage II AWNN frozen; LM over the geometry on       r = z − h(x, q) − f_AWNN(q)
//!          (damping λ/β on success, λ·β on failure; stop on step or relative loss change)
//! ```
//!
//! **Where the network starts** is not fixed by the paper beyond translations spread over the
//! input space and wide dilations. Started from zero output weights, Stage I's per-sample SGD
//! learns next to nothing in three passes over 300 rows (its fitness, the training innovation,
//! is already at the noise without a network), and the method ties LM. So Stage I starts from a
//! network whose output layer already holds what the rows say, chosen on the training rows only
//! ([`super::awnn_select`]); Stage 0 and Stage I then adapt every parameter from there
//! ([`NetStart::Zero`] keeps the zero start for comparison, `bench awnn` reports both).
//!
//! The network is the EKF's [`ObservationHook`]: the filter itself is [`Ekf`], unchanged.
//!
//! **Readings of several values per row** (a laser tracker's x, y, z): one network per reading
//! value, all with the layout and penalties chosen once for all values (their CV fits the shared
//! geometry with one network block per value, folds by row, see [`super::awnn_select`]). As EKF
//! observations, observation `i` is value `i % dim` of row `i / dim`: the hook adds network
//! `i % dim`'s output at row `i / dim` and trains that network alone on the innovation; the
//! learning rate's scale `ḡ²` is the mean over every value's network. Stage II subtracts each
//! value's network from that value's residual; V5 fits the geometry and every network's output
//! layer (`Σ M` weights); `-x` refines each network on its value's residuals. The corrector is
//! [`Corrector::Values`] of one [`Corrector::Awnn`] per value. With one value (a cable length)
//! it is a plain [`Corrector::Awnn`], and every stage computes what it did before.
//!
//! **Search box of Stage 0** (log-uniform, [`SearchSpace::default`]): the process noise is
//! `Q = q_rel·σ̄²` per state with `σ̄²` the median prior variance of the free parameters (from
//! the documented tolerances) and `q_rel ∈ [1e-8, 1e-2]`; the measurement noise is
//! `R = r_rel·σ²` with `σ` the reading noise estimated from the data and `r_rel ∈ [1e-2, 1e2]`;
//! the learning rate `η ∈ [1e-5, 1]`, relative: the SGD step on a row is `η/ḡ²·y·∂f/∂θ` with
//! `ḡ²` the mean of `‖∂f/∂θ‖²` over the training rows at the start, so that `η = 1` moves an
//! average row's prediction by its whole innovation whatever the network's size (above about 2
//! plain SGD diverges). Nothing comes from the generator of the data.
//!
//! **Ablations** (the paper's V1–V5, [`Ablation`]): V1 no network (EKF then LM), V2 the three
//! hyperparameters drawn at random from the same box instead of searched, V3 ReLU hinges in
//! the same layout instead of wavelets (an MLP of one hidden layer), V4 the Morlet wavelet, V5
//! Stage II over the geometry *and* the network's output layer jointly, unpenalised, instead of
//! with the network frozen.
//!
//! The report's `reason` names the chosen hyperparameters, each stage's outcome and the
//! condition number of the (column-scaled) observation Jacobian of the free parameters over the
//! training poses, the paper's identifiability check.

use super::awnn_select::{select, Selection};
use super::solver::{Problem, Solution, Solver};
use crate::calib::correctors::awnn::{Activation, Awnn, Feature};
use crate::calib::correctors::Corrector;
use crate::calib::effects::RowInputs;
use crate::calib::fit::ReadingFit;
use crate::calib::fit::Samples;
use crate::calib::methods::ridge_cv::GeometricFit;
use crate::error::{Error, Result};
use crate::optim::{Bounds, Cost, Damping, Ekf, Event, LeastSquares, LevenbergMarquardt, NoObserver, ObservationHook, Observer, Pso, Report};
use nalgebra::DMatrix;
use rand::seq::SliceRandom;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

/// The paper's ablation variants; `Full` is the method itself (V6).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum Ablation {
    /// V1: symbolic EKF then LM, no network.
    V1Symbolic,
    /// V2: hyperparameters drawn at random from the search box instead of PSO.
    V2RandomInit,
    /// V3: ReLU MLP instead of the wavelet network.
    V3Mlp,
    /// V4: Morlet instead of Mexican-hat wavelets.
    V4Morlet,
    /// V5: Stage II optimises the geometry and the network jointly.
    V5Joint,
    /// V6: the full method.
    Full,
    /// Extended: the network also sees the temperature (or time) and the backlash flanks, and
    /// two network/LM alternations follow Stage II (see [`PsoEkfAwnn::refine_net`]).
    Extended,
}

impl Ablation {
    /// Every variant, the full method first.
    pub const ALL: [Ablation; 7] =
        [Ablation::Full, Ablation::V1Symbolic, Ablation::V2RandomInit, Ablation::V3Mlp, Ablation::V4Morlet, Ablation::V5Joint, Ablation::Extended];
    /// The method name of this variant on the command line.
    pub const fn method_name(self) -> &'static str {
        match self {
            Ablation::Full => "pso-ekf-awnn",
            Ablation::V1Symbolic => "pso-ekf-awnn-v1",
            Ablation::V2RandomInit => "pso-ekf-awnn-v2",
            Ablation::V3Mlp => "pso-ekf-awnn-v3",
            Ablation::V4Morlet => "pso-ekf-awnn-v4",
            Ablation::V5Joint => "pso-ekf-awnn-v5",
            Ablation::Extended => "pso-ekf-awnn-x",
        }
    }
    fn activation(self) -> Option<Activation> {
        match self {
            Ablation::V1Symbolic => None,
            Ablation::V3Mlp => Some(Activation::Relu),
            Ablation::V4Morlet => Some(Activation::Morlet),
            _ => Some(Activation::MexicanHat),
        }
    }
}

/// What the network sees besides the joint angles (see [`crate::calib::correctors::awnn::Feature`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum NetInputs {
    /// The joint angles alone (the paper's network).
    Joints,
    /// q and the temperature (the time when the data have no temp column).
    Thermal,
    /// q, temperature (or time) and the backlash flank of every joint.
    ThermalFlanks,
    /// q, temperature (or time), flanks and the static joint torques (when the calibration has
    /// a torque model).
    ThermalFlanksTorques,
}

impl NetInputs {
    /// The extra inputs these training rows can supply.
    pub fn features(self, data: &Samples) -> Vec<Feature> {
        let mut f = Vec::new();
        if self == NetInputs::Joints || data.inputs.is_empty() {
            return f;
        }
        if data.inputs.iter().all(|i| i.temp_c.is_some_and(f64::is_finite)) {
            f.push(Feature::Temperature);
        } else if data.inputs.iter().all(|i| i.t_s.is_some_and(f64::is_finite)) {
            f.push(Feature::Time);
        }
        let nq = data.q.first().map_or(0, |q| q.len()).min(6);
        if matches!(self, NetInputs::ThermalFlanks | NetInputs::ThermalFlanksTorques) {
            f.extend((0..nq).filter(|&j| data.inputs.iter().any(|i| i.side[j] != data.inputs[0].side[j])).map(Feature::Side));
        }
        if self == NetInputs::ThermalFlanksTorques {
            f.extend((0..nq).filter(|&j| data.inputs.iter().any(|i| i.torque[j].abs() > 1e-9)).map(Feature::Torque));
        }
        f
    }
}

/// The network Stage I starts from (see [`PsoEkfAwnn::new_net`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum NetStart {
    /// Layout and output layer chosen by cross-validation on the training rows.
    Selected,
    /// 20 neurons on the joint axes with zero output weights (the network starts as "no
    /// correction").
    Zero,
}

/// Stage I's hyperparameters, relative to documented scales (see the module docs).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Hyper {
    /// Process noise per state relative to the median prior variance of the free parameters.
    pub q_rel: f64,
    /// Measurement noise relative to the data's estimated reading variance.
    pub r_rel: f64,
    /// SGD learning rate of the network relative to the inverse mean squared norm of its
    /// parameter gradient over the training rows at the start (see the module docs).
    pub lr: f64,
}

/// Stage 0's box: log10 bounds of `q_rel`, `r_rel` and `lr` (see the module docs).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SearchSpace {
    /// log10 bounds of `q_rel`.
    pub log10_q_rel: (f64, f64),
    /// log10 bounds of `r_rel`.
    pub log10_r_rel: (f64, f64),
    /// log10 bounds of `lr`.
    pub log10_lr: (f64, f64),
}

impl Default for SearchSpace {
    fn default() -> Self {
        SearchSpace { log10_q_rel: (-8.0, -2.0), log10_r_rel: (-2.0, 2.0), log10_lr: (-5.0, 0.0) }
    }
}

impl SearchSpace {
    fn bounds(&self) -> Bounds {
        let b = [self.log10_q_rel, self.log10_r_rel, self.log10_lr];
        Bounds::new(b.iter().map(|v| v.0).collect(), b.iter().map(|v| v.1).collect())
    }
    fn hyper(v: &[f64]) -> Hyper {
        Hyper { q_rel: 10f64.powf(v[0]), r_rel: 10f64.powf(v[1]), lr: 10f64.powf(v[2]) }
    }
    /// The box's centre (log scale), PSO's first particle.
    pub fn centre(&self) -> Hyper {
        let b = self.bounds();
        Self::hyper(&(0..3).map(|k| 0.5 * (b.lower[k] + b.upper[k])).collect::<Vec<_>>())
    }
}

/// The method's settings.
#[derive(Clone, Debug, PartialEq)]
pub struct PsoEkfAwnn {
    /// Which variant of the method runs.
    pub variant: Ablation,
    /// The network's inputs.
    pub inputs: NetInputs,
    /// Where the network starts.
    pub start: NetStart,
    /// Neurons of the [`NetStart::Zero`] network.
    pub neurons: usize,
    /// Stage I passes over the shuffled training rows.
    pub epochs: usize,
    /// Stage 0's search box of the hyperparameters.
    pub search: SearchSpace,
    /// PSO particles of Stage 0.
    pub pso_particles: usize,
    /// PSO iterations of Stage 0.
    pub pso_iterations: usize,
    /// Fixed hyperparameters: Stage 0 is skipped (the sensitivity study sets these).
    pub hyper: Option<Hyper>,
    /// Stage II.
    pub lm: LevenbergMarquardt,
    /// Alternations after Stage II (0: the paper's three stages): the network is trained on the
    /// residuals of the frozen geometry (see [`PsoEkfAwnn::refine_net`]), then LM refits the
    /// geometry with that network frozen.
    pub rounds: usize,
}

impl Default for PsoEkfAwnn {
    fn default() -> Self {
        PsoEkfAwnn {
            variant: Ablation::Full,
            inputs: NetInputs::Joints,
            start: NetStart::Selected,
            neurons: 20,
            epochs: 3,
            search: SearchSpace::default(),
            pso_particles: 10,
            pso_iterations: 10,
            hyper: None,
            rounds: 0,
            lm: LevenbergMarquardt {
                max_iter: 1000,
                ftol: 1e-10,
                xtol: 1e-10,
                gtol: 1e-10,
                initial_lambda: 1e-3,
                damping: Damping::Factor(10.0),
                ..Default::default()
            },
        }
    }
}

impl PsoEkfAwnn {
    /// The default settings of `variant` (the extended one sees temperature or time and the flanks,
    /// with two alternations).
    pub fn variant(variant: Ablation) -> Self {
        match variant {
            Ablation::Extended => PsoEkfAwnn { variant, inputs: NetInputs::ThermalFlanks, rounds: 2, ..Default::default() },
            _ => PsoEkfAwnn { variant, ..Default::default() },
        }
    }
}

/// The networks as the EKF's observation hook: observation `i` is value `i % dim` of row
/// `i / dim`, corrected by network `i % dim`, which takes one SGD step on its innovation; keeps
/// the innovation RMSE of the last finished epoch.
struct Learner<'a> {
    nets: Option<Vec<Awnn>>,
    dim: usize,
    q: &'a [Vec<f64>],
    inputs: &'a [RowInputs],
    lr: f64,
    scratch: Vec<f64>,
    sse: f64,
    count: usize,
    last_rmse: f64,
}

impl ObservationHook for Learner<'_> {
    fn offset(&self, i: usize) -> f64 {
        let (row, c) = (i / self.dim, i % self.dim);
        self.nets.as_ref().map_or(0.0, |n| n[c].eval_row(&self.q[row], &self.inputs[row]))
    }
    fn innovation(&mut self, i: usize, y: f64) {
        self.sse += y * y;
        self.count += 1;
        let (row, c) = (i / self.dim, i % self.dim);
        if let Some(n) = self.nets.as_mut() {
            let g = &mut self.scratch[..n[c].n_params()];
            n[c].sgd_step(&self.q[row], &self.inputs[row], y, self.lr, g);
        }
    }
    fn end_epoch(&mut self) {
        self.last_rmse = if self.count > 0 { (self.sse / self.count as f64).sqrt() } else { f64::INFINITY };
        self.sse = 0.0;
        self.count = 0;
    }
}

/// What Stage I leaves.
pub struct StageOne {
    /// The parameter vector after Stage I (internal units).
    pub x: Vec<f64>,
    /// One network per reading value (none for V1).
    pub nets: Option<Vec<Awnn>>,
    /// RMS innovation (mm) over the last epoch: Stage 0's fitness.
    pub innovation_rmse: f64,
    /// The EKF's report of Stage I.
    pub report: Report,
}

/// The least-squares problem of Stage II: the fit's residuals minus a frozen correction.
pub struct Corrected<'a, 'b> {
    /// The geometric fit whose residuals are corrected.
    pub fit: &'a ReadingFit<'b>,
    /// The frozen correction per training reading value (row after row, as the residuals), mm.
    pub offset: Vec<f64>,
}

impl LeastSquares for Corrected<'_, '_> {
    fn n_params(&self) -> usize {
        self.fit.model.n_params()
    }
    fn n_residuals(&self) -> usize {
        self.offset.len()
    }
    fn residuals(&self, x: &[f64], r: &mut [f64]) {
        LeastSquares::residuals(self.fit, x, r);
        r.iter_mut().zip(&self.offset).for_each(|(ri, c)| *ri -= c);
    }
    fn jacobian(&self, x: &[f64], j: &mut DMatrix<f64>) {
        LeastSquares::jacobian(self.fit, x, j);
    }
}

/// Stage II of ablation V5: the geometry and every network's output layer in one least-squares
/// problem (the output weights are what a network's fit is made of; its hidden layer stays
/// where Stage I left it, which keeps the problem at geometry + Σ M unknowns). Value `c` of a
/// row is corrected by network `c` alone: its residual sees that network's weights only.
struct Joint<'a, 'b> {
    fit: &'a ReadingFit<'b>,
    nets: &'a [Awnn],
    /// Per network, every neuron's activation at every training row.
    hidden: Vec<DMatrix<f64>>,
}

impl<'a, 'b> Joint<'a, 'b> {
    fn new(fit: &'a ReadingFit<'b>, nets: &'a [Awnn]) -> Self {
        Joint { fit, nets, hidden: nets.iter().map(|n| n.hidden_matrix(&fit.data.q, &fit.data.inputs)).collect() }
    }
    /// Where network `c`'s output weights start in the parameter vector.
    fn start(&self, c: usize) -> usize {
        self.fit.model.n_params() + self.nets[..c].iter().map(|n| n.neurons()).sum::<usize>()
    }
    fn nets_at(&self, x: &[f64]) -> Vec<Awnn> {
        (0..self.nets.len())
            .map(|c| {
                let mut n = self.nets[c].clone();
                let k = self.start(c);
                let m = n.neurons();
                n.weights.copy_from_slice(&x[k..k + m]);
                n
            })
            .collect()
    }
}

impl LeastSquares for Joint<'_, '_> {
    fn n_params(&self) -> usize {
        self.fit.model.n_params() + self.nets.iter().map(|n| n.neurons()).sum::<usize>()
    }
    fn n_residuals(&self) -> usize {
        self.fit.data.y.len()
    }
    fn residuals(&self, x: &[f64], r: &mut [f64]) {
        let (nm, d) = (self.fit.model.n_params(), self.fit.data.dim);
        LeastSquares::residuals(self.fit, &x[..nm], r);
        for (k, rk) in r.iter_mut().enumerate() {
            let (i, c) = (k / d, k % d);
            *rk -= self.hidden[c].row(i).iter().zip(&x[self.start(c)..]).map(|(h, w)| h * w).sum::<f64>();
        }
    }
    fn jacobian(&self, x: &[f64], j: &mut DMatrix<f64>) {
        let (nm, d) = (self.fit.model.n_params(), self.fit.data.dim);
        let mut jm = DMatrix::zeros(self.fit.data.y.len(), nm);
        LeastSquares::jacobian(self.fit, &x[..nm], &mut jm);
        j.fill(0.0);
        j.view_mut((0, 0), jm.shape()).copy_from(&jm);
        for (c, h) in self.hidden.iter().enumerate() {
            let k = self.start(c);
            for i in 0..h.nrows() {
                for (m, v) in h.row(i).iter().enumerate() {
                    j[(i * d + c, k + m)] = -v;
                }
            }
        }
    }
}

/// The training rows in a seeded random order.
fn shuffled(n: usize, seed: u64) -> Vec<usize> {
    let mut order: Vec<usize> = (0..n).collect();
    order.shuffle(&mut ChaCha8Rng::seed_from_u64(seed));
    order
}

/// Mean over the reading values of `data` of `‖∂f/∂θ‖²`, the squared norm of the gradient of
/// the value's network with respect to all its parameters (the scale of the learning rate).
fn mean_gradient_square(nets: &[Awnn], data: &Samples) -> f64 {
    let mut g = vec![0.0; nets.iter().map(|n| n.n_params()).max().unwrap_or(0)];
    let s: f64 = data
        .q
        .iter()
        .zip(&data.inputs)
        .map(|(q, inp)| {
            nets.iter()
                .map(|net| {
                    let g = &mut g[..net.n_params()];
                    net.eval_param_grad(q, inp, g);
                    g.iter().map(|v| v * v).sum::<f64>()
                })
                .sum::<f64>()
        })
        .sum();
    let m = s / (data.len() * nets.len()).max(1) as f64;
    if m.is_finite() && m > 1e-12 {
        m
    } else {
        1.0
    }
}

/// Median prior variance of the free parameters (the scale of Q).
fn prior_var_scale(p: &Problem) -> f64 {
    let v: Vec<f64> = (0..p.x0.len()).filter(|k| !p.fixed[*k]).map(|k| p.prior_std[k].powi(2)).collect();
    if v.is_empty() {
        1e-6
    } else {
        crate::stats::median(&v)
    }
}

/// Condition number of the column-scaled Jacobian of the free parameters.
pub fn observation_condition(fit: &ReadingFit, x: &[f64], fixed: &[bool]) -> f64 {
    let mut j = DMatrix::zeros(fit.data.y.len(), fit.model.n_params());
    LeastSquares::jacobian(fit, x, &mut j);
    let cols: Vec<usize> = (0..x.len()).filter(|k| !fixed[*k]).collect();
    let mut m = DMatrix::zeros(j.nrows(), cols.len());
    for (c, &k) in cols.iter().enumerate() {
        let n = j.column(k).norm();
        if n > 0.0 {
            m.set_column(c, &(j.column(k) / n));
        }
    }
    if m.ncols() == 0 {
        return 1.0;
    }
    let sv = m.svd(false, false).singular_values;
    let (lo, hi) = sv.iter().fold((f64::INFINITY, 0.0f64), |(lo, hi), s| (lo.min(*s), hi.max(*s)));
    if lo > 0.0 {
        hi / lo
    } else {
        f64::INFINITY
    }
}

impl PsoEkfAwnn {
    /// The networks Stage I starts from, one per reading value (none for V1): with
    /// [`NetStart::Selected`] the layout and output layers chosen by cross-validation on what a
    /// geometric LM fit leaves on the training rows ([`super::awnn_select`]), with
    /// [`NetStart::Zero`] the small zero-output network of [`Awnn::init_with`] for every value.
    pub fn new_net(&self, p: &Problem) -> Result<(Option<Vec<Awnn>>, Option<Selection>)> {
        let d = p.fit.data;
        let extra = self.inputs.features(d);
        let Some(act) = self.variant.activation() else { return Ok((None, None)) };
        match self.start {
            NetStart::Zero => {
                let net = Awnn::init_with(&d.q, &d.inputs, &extra, self.neurons.max(1), act, p.seed ^ 0xA5A5_0001).map_err(Error::Calibration)?;
                Ok((Some(vec![net; d.dim.max(1)]), None))
            }
            NetStart::Selected => {
                let geometric = GeometricFit::new(p.fit, &self.lm, p.x0, p.fixed);
                let sel = select(&d.q, &d.inputs, &extra, act, &geometric)?;
                Ok((Some(sel.nets.clone()), Some(sel)))
            }
        }
    }

    /// The inputs of the network this solver would use on these data's kind, e.g.
    /// "q1..q6, temp, side1..side6" (as far as known without data: the setting's name).
    pub fn new_net_label(&self) -> String {
        match (self.variant.activation(), self.inputs) {
            (None, _) => String::new(),
            (_, NetInputs::Joints) => "q only".into(),
            (_, NetInputs::Thermal) => "q + temperature (or time)".into(),
            (_, NetInputs::ThermalFlanks) => "q + temperature (or time) + backlash flanks".into(),
            (_, NetInputs::ThermalFlanksTorques) => "q + temperature (or time) + flanks + torques".into(),
        }
    }

    /// Stage I with hyperparameters `h`, from `p.x0` and the fresh networks `nets` (one per
    /// reading value).
    pub fn stage_one(&self, p: &Problem, h: &Hyper, nets: Option<Vec<Awnn>>, obs: &mut dyn Observer) -> StageOne {
        let scale = nets.as_ref().map_or(1.0, |n| mean_gradient_square(n, p.fit.data));
        self.stage_one_scaled(p, h, nets, scale, obs)
    }

    /// [`stage_one`](Self::stage_one) with the learning rate's scale `ḡ²` of `nets` given.
    fn stage_one_scaled(&self, p: &Problem, h: &Hyper, nets: Option<Vec<Awnn>>, scale: f64, obs: &mut dyn Observer) -> StageOne {
        let p0 = p.prior_std.iter().map(|s| (3.0 * s).powi(2)).collect();
        let noise = if p.noise_mm.is_finite() && p.noise_mm > 0.0 { p.noise_mm } else { 0.01 };
        let ekf = Ekf { epochs: self.epochs.max(1), q: h.q_rel * prior_var_scale(p), r: h.r_rel * noise * noise, p0, tol: 0.0 };
        let scratch = vec![0.0; nets.as_ref().map_or(0, |n| n.iter().map(|n| n.n_params()).max().unwrap_or(0))];
        let lr = h.lr / scale;
        let d = p.fit.data;
        let mut learner = Learner { nets, dim: d.dim.max(1), q: &d.q, inputs: &d.inputs, lr, scratch, sse: 0.0, count: 0, last_rmse: f64::INFINITY };
        // Every reading value is one observation (value i % dim of row i / dim).
        let order = shuffled(d.y.len(), p.seed);
        let report = ekf.run_with(p.fit, p.x0, p.fixed, &order, &mut learner, obs);
        let rmse = if learner.last_rmse.is_finite() && report.x.iter().all(|v| v.is_finite()) { learner.last_rmse } else { f64::INFINITY };
        StageOne { x: report.x.clone(), nets: learner.nets, innovation_rmse: rmse, report }
    }

    /// Stage 0: the hyperparameters (PSO, or drawn at random for V2, or the fixed ones), the
    /// fitness of the chosen ones and the number of Stage I runs spent.
    pub fn stage_zero(&self, p: &Problem, nets: &Option<Vec<Awnn>>) -> Result<(Hyper, f64, usize)> {
        if let Some(h) = self.hyper {
            return Ok((h, f64::NAN, 0));
        }
        let b = self.search.bounds();
        if self.variant == Ablation::V2RandomInit {
            let mut rng = ChaCha8Rng::seed_from_u64(p.seed ^ 0x5EED_0002);
            let v: Vec<f64> = (0..3).map(|k| rng.random_range(b.lower[k]..=b.upper[k])).collect();
            return Ok((SearchSpace::hyper(&v), f64::NAN, 0));
        }
        let scale = nets.as_ref().map_or(1.0, |n| mean_gradient_square(n, p.fit.data));
        let fitness = Fitness { solver: self, p, nets, scale };
        let centre: Vec<f64> = (0..3).map(|k| 0.5 * (b.lower[k] + b.upper[k])).collect();
        let pso =
            Pso { particles: self.pso_particles.max(2), iterations: self.pso_iterations.max(1), seed: p.seed, patience: 4, tol: 1e-4, ..Default::default() };
        let rep = pso.minimize(&fitness, &b, Some(&centre), &mut NoObserver);
        Ok((SearchSpace::hyper(&rep.x), rep.cost, rep.evaluations))
    }

    /// Stage II: LM on the geometry with the networks frozen (V5: jointly with their output
    /// layers).
    pub fn stage_two(&self, p: &Problem, x1: &[f64], nets: Option<Vec<Awnn>>, obs: &mut dyn Observer) -> (Report, Option<Vec<Awnn>>) {
        match (self.variant, nets) {
            (Ablation::V5Joint, Some(nets)) => {
                let joint = Joint::new(p.fit, &nets);
                let mut x = x1.to_vec();
                for n in &nets {
                    x.extend(&n.weights);
                }
                let mut fixed = p.fixed.to_vec();
                // A frozen network's output weights stay where they are (zero).
                for n in &nets {
                    fixed.extend(std::iter::repeat_n(n.frozen, n.weights.len()));
                }
                let nm = p.x0.len();
                let mut rep = self.lm.minimize(&joint, &x, &fixed, &mut Truncate { n: nm, inner: obs });
                let nets = joint.nets_at(&rep.x);
                rep.x.truncate(nm);
                (rep, Some(nets))
            }
            (_, nets) => {
                let d = p.fit.data;
                let offset = match &nets {
                    None => vec![0.0; d.y.len()],
                    Some(n) => d.q.iter().zip(&d.inputs).flat_map(|(q, inp)| n.iter().map(move |n| n.eval_row(q, inp))).collect(),
                };
                let rep = self.lm.minimize(&Corrected { fit: p.fit, offset }, x1, p.fixed, obs);
                (rep, nets)
            }
        }
    }
}

/// Learning rates tried by [`PsoEkfAwnn::refine_net`] (plain SGD on mm).
pub const REFINE_RATES: [f64; 4] = [0.003, 0.01, 0.03, 0.1];
/// Largest number of passes of one [`PsoEkfAwnn::refine_net`] run.
pub const REFINE_EPOCHS: usize = 200;

impl PsoEkfAwnn {
    /// Every value's network trained on what the frozen geometry `x` leaves of that value on
    /// the training rows ([`refine_net`](Self::refine_net) per value, the same held-out rows for
    /// all). Returns the networks and their held-out RMSE over every value.
    pub fn refine_nets(&self, p: &Problem, x: &[f64], nets: &[Awnn]) -> (Vec<Awnn>, f64) {
        let raw = p.fit.residuals_mm(x);
        let dim = nets.len().max(1);
        let (nets, held): (Vec<Awnn>, Vec<f64>) =
            nets.iter().enumerate().map(|(c, n)| self.refine_net(p, &crate::stats::value_column(&raw, dim, c), n)).unzip();
        let rmse = if held.len() == 1 { held[0] } else { (held.iter().map(|v| v * v).sum::<f64>() / held.len().max(1) as f64).sqrt() };
        (nets, rmse)
    }

    /// The network trained on `raw`, what the frozen geometry leaves of its reading value on
    /// the training rows (one per row, mm), with its own validation: a seeded fifth of the
    /// training rows is held out, each rate of [`REFINE_RATES`] trains a copy of `net` by SGD on
    /// the rest (up to [`REFINE_EPOCHS`] passes, stopping 10 passes after the held-out RMSE last
    /// improved), and the copy with the lowest held-out RMSE is kept, unless `net` itself is
    /// better there. The test rows are never seen. Returns the network and its held-out RMSE.
    pub fn refine_net(&self, p: &Problem, raw: &[f64], net: &Awnn) -> (Awnn, f64) {
        if net.frozen {
            return (net.clone(), crate::stats::rms(raw));
        }
        let d = p.fit.data;
        // SGD runs on the residuals in units of their RMS (output weights scaled alike, exact
        // since the output is linear in them), so that the rates mean the same at any error size.
        let scale = crate::stats::rms(raw).max(1e-9);
        let target: Vec<f64> = raw.iter().map(|v| v / scale).collect();
        let mut net = net.clone();
        net.weights.iter_mut().for_each(|w| *w /= scale);
        let net = &net;
        let order = shuffled(d.len(), p.seed ^ 0x0DD5_0003);
        let n_val = (d.len() / 5).max(1).min(d.len().saturating_sub(1));
        let (val, train) = order.split_at(n_val);
        let val_rmse = |n: &Awnn| (val.iter().map(|&i| (target[i] - n.eval_row(&d.q[i], &d.inputs[i])).powi(2)).sum::<f64>() / val.len() as f64).sqrt();
        let mut best = (net.clone(), val_rmse(net));
        let mut g = vec![0.0; net.n_params()];
        let mut rng = ChaCha8Rng::seed_from_u64(p.seed ^ 0x0DD5_0004);
        for lr in REFINE_RATES {
            let mut cur = net.clone();
            let mut rows = train.to_vec();
            let (mut run_best, mut since) = (f64::INFINITY, 0);
            for _ in 0..REFINE_EPOCHS {
                rows.shuffle(&mut rng);
                for &i in &rows {
                    let e = target[i] - cur.eval_row(&d.q[i], &d.inputs[i]);
                    cur.sgd_step(&d.q[i], &d.inputs[i], e, lr, &mut g);
                }
                let v = val_rmse(&cur);
                if !v.is_finite() {
                    break;
                }
                if v < run_best {
                    run_best = v;
                    since = 0;
                    if v < best.1 {
                        best = (cur.clone(), v);
                    }
                } else {
                    since += 1;
                    if since >= 10 {
                        break;
                    }
                }
            }
        }
        best.0.weights.iter_mut().for_each(|w| *w *= scale);
        (best.0, best.1 * scale)
    }
}

/// Passes only the first `n` entries of `x` on (V5's geometry) to the caller's observer.
struct Truncate<'a> {
    n: usize,
    inner: &'a mut dyn Observer,
}

impl Observer for Truncate<'_> {
    fn observe(&mut self, e: &Event) {
        self.inner.observe(&Event { x: &e.x[..self.n], ..e.clone() });
    }
}

/// Stage 0's cost: Stage I's last-epoch innovation RMSE at log10 (q_rel, r_rel, lr).
struct Fitness<'a, 'b> {
    solver: &'a PsoEkfAwnn,
    p: &'a Problem<'b>,
    nets: &'a Option<Vec<Awnn>>,
    /// The learning rate's scale for `nets`, computed once.
    scale: f64,
}

impl Cost for Fitness<'_, '_> {
    fn dim(&self) -> usize {
        3
    }
    fn cost(&self, v: &[f64]) -> f64 {
        self.solver.stage_one_scaled(self.p, &SearchSpace::hyper(v), self.nets.clone(), self.scale, &mut NoObserver).innovation_rmse
    }
}

impl Solver for PsoEkfAwnn {
    fn learns_corrector(&self) -> bool {
        true
    }
    fn name(&self) -> &'static str {
        self.variant.method_name()
    }
    fn needs_noise(&self) -> bool {
        true
    }
    fn needs_row_inputs(&self) -> bool {
        self.inputs != NetInputs::Joints
    }
    fn solve(&self, p: &Problem, obs: &mut dyn Observer) -> Result<Solution> {
        let start = self.new_net(p)?;
        let zero = self.stage_zero(p, &start.0)?;
        self.finish(p, start, zero, obs)
    }
}

impl PsoEkfAwnn {
    /// Stage I, Stage II and the report from the network's start ([`new_net`](Self::new_net))
    /// and Stage 0's outcome ([`stage_zero`](Self::stage_zero)).
    pub fn finish(&self, p: &Problem, start: (Option<Vec<Awnn>>, Option<Selection>), zero: (Hyper, f64, usize), obs: &mut dyn Observer) -> Result<Solution> {
        let ((net, selection), (h, fitness, runs)) = (start, zero);
        let one = self.stage_one(p, &h, net, obs);
        if one.x.iter().any(|v| !v.is_finite()) {
            return Err(Error::Calibration("pso-ekf-awnn: Stage I diverged (non-finite geometric states)".into()));
        }
        let (mut rep, mut net) = self.stage_two(p, &one.x, one.nets, obs);
        let mut refined = Vec::new();
        if self.variant != Ablation::V5Joint {
            for _ in 0..self.rounds {
                let Some(n) = net.as_ref() else { break };
                let (n, v) = self.refine_nets(p, &rep.x, n);
                refined.push(v);
                let (r, n) = self.stage_two(p, &rep.x, Some(n), obs);
                rep.iterations += r.iterations;
                rep.evaluations += r.evaluations;
                rep = Report { iterations: rep.iterations, evaluations: rep.evaluations, ..r };
                net = n;
            }
        }
        let cond = observation_condition(p.fit, &rep.x, p.fixed);
        let stage0 = match (self.hyper, self.variant) {
            (Some(_), _) => "fixed".to_string(),
            (None, Ablation::V2RandomInit) => "drawn at random".to_string(),
            _ => format!("PSO, {runs} Stage I runs, fitness {fitness:.4} mm"),
        };
        let start = selection.map_or_else(String::new, |s| format!("network: {}; ", s.summary()));
        rep.reason = format!(
            "{start}stage 0 ({stage0}): Q = {:.2e}·σ̄², R = {:.2e}·σ², η = {:.3e}; stage I: {} epochs, innovation RMSE {:.4} mm; stage II{}: {}; \
             {}observation Jacobian condition number {cond:.3e} over {} training poses",
            h.q_rel,
            h.r_rel,
            h.lr,
            one.report.iterations,
            one.innovation_rmse,
            if self.variant == Ablation::V5Joint { " (joint)" } else { "" },
            rep.reason,
            if refined.is_empty() {
                String::new()
            } else {
                format!(
                    "{} network/LM alternations (held-out RMSE {}); ",
                    refined.len(),
                    refined.iter().map(|v| format!("{v:.4}")).collect::<Vec<_>>().join(", ")
                )
            },
            p.fit.data.len()
        );
        rep.iterations += one.report.iterations;
        rep.evaluations += one.report.evaluations;
        // As a corrector a network never gives more than it learned (see `Awnn::output_range`).
        // One value (a cable length): the network itself; several: one network per value.
        let corrector = net.map(|nets| {
            Corrector::of_values(
                nets.into_iter()
                    .map(|mut n| {
                        n.limit_to(&p.fit.data.q, &p.fit.data.inputs);
                        Corrector::Awnn(n)
                    })
                    .collect(),
            )
        });
        Ok(Solution { report: rep, corrector })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::calib::correctors::awnn::Activation;
    use crate::calib::model::{CalibModel, DrawWireGuess, Placement};
    use crate::measurement::Measurement;
    use crate::robot::Robot;
    use nalgebra::Vector3;

    /// A tracker model (three values per row) and `n` rows of its readings at seeded poses.
    fn tracker_rows(n: usize) -> (CalibModel, Samples) {
        let robot = Robot::irb120();
        let cable = DrawWireGuess { exit_m: [0.0; 3], offset_m: 0.0, tool_m: [0.0; 3] };
        let tracker = Placement { measurement: Measurement::Point, own: vec![2.5, -0.4, 0.3, 0.02, -0.015, 0.7], tool: Vector3::new(0.03, -0.02, 0.08) };
        let model = CalibModel::dh(&robot, &cable, true).with_placement(&tracker);
        let q: Vec<Vec<f64>> = (0..n).map(|k| (0..6).map(|j| ((k * 7 + j * 3) as f64 * 0.37).sin() * 1.2).collect()).collect();
        let mut w = model.work();
        let mut y = vec![0.0; 3 * n];
        for (qi, yi) in q.iter().zip(y.chunks_mut(3)) {
            model.readings(&model.nominal, qi, &Default::default(), &mut w, yi);
        }
        (model, Samples::readings(q, y, 3))
    }

    /// One network per value, each with its own (seeded) non-zero parameters.
    fn nets(data: &Samples, dim: usize) -> Vec<Awnn> {
        (0..dim)
            .map(|c| {
                let mut n = Awnn::init(&data.q, 5 + c, Activation::MexicanHat, 3 + c as u64).unwrap();
                let mut p = n.params();
                p.iter_mut().enumerate().for_each(|(k, v)| *v += 0.2 * ((k * (c + 2)) as f64 * 0.71).sin());
                n.set_params(&p);
                n
            })
            .collect()
    }

    /// V5's joint problem on a tracker's points: residual `k` is value `k % 3` of row `k / 3`
    /// less that value's network, and the Jacobian (geometry and every network's output layer)
    /// agrees with central finite differences.
    #[test]
    fn joint_problem_on_points_matches_finite_differences() {
        let (model, data) = tracker_rows(12);
        let fit = ReadingFit { model: &model, data: &data };
        let nets = nets(&data, 3);
        let joint = Joint::new(&fit, &nets);
        let nm = model.n_params();
        assert_eq!(joint.n_residuals(), 36);
        assert_eq!(joint.n_params(), nm + 5 + 6 + 7);
        let mut x = model.nominal.clone();
        x.iter_mut().enumerate().for_each(|(k, v)| *v += 1e-4 * (k as f64 * 0.3).cos());
        for n in &nets {
            x.extend(&n.weights);
        }
        let mut r = vec![0.0; 36];
        joint.residuals(&x, &mut r);
        let geo = fit.residuals_mm(&x[..nm]);
        for (k, rk) in r.iter().enumerate() {
            let want = geo[k] - nets[k % 3].eval(&data.q[k / 3]);
            assert!((rk - want).abs() < 1e-12, "residual {k}: {rk} vs {want}");
        }
        let back = joint.nets_at(&x);
        assert_eq!(back, nets);
        let mut j = DMatrix::from_element(36, joint.n_params(), f64::NAN);
        joint.jacobian(&x, &mut j);
        let (mut rp, mut rm) = (vec![0.0; 36], vec![0.0; 36]);
        for p in 0..x.len() {
            let h = if p < nm { 1e-7 } else { 1e-5 };
            let (mut xp, mut xm) = (x.clone(), x.clone());
            xp[p] += h;
            xm[p] -= h;
            joint.residuals(&xp, &mut rp);
            joint.residuals(&xm, &mut rm);
            for k in 0..36 {
                let fd = (rp[k] - rm[k]) / (2.0 * h);
                assert!((fd - j[(k, p)]).abs() < 1e-5 * (1.0 + fd.abs()), "residual {k}, parameter {p}: {fd} vs {}", j[(k, p)]);
            }
        }
    }

    /// The EKF's hook corrects observation `i` with network `i % dim` at row `i / dim`, and its
    /// SGD step moves that network alone; Stage II's frozen offsets are laid out as the residuals.
    #[test]
    fn each_value_has_its_own_network() {
        let (model, data) = tracker_rows(10);
        let nets = nets(&data, 3);
        let mut l = Learner {
            nets: Some(nets.clone()),
            dim: 3,
            q: &data.q,
            inputs: &data.inputs,
            lr: 0.1,
            scratch: vec![0.0; 1000],
            sse: 0.0,
            count: 0,
            last_rmse: f64::INFINITY,
        };
        for i in 0..30 {
            assert_eq!(l.offset(i), nets[i % 3].eval(&data.q[i / 3]), "observation {i}");
        }
        l.innovation(7, 0.5);
        let after = l.nets.as_ref().unwrap();
        assert_eq!(after[0], nets[0]);
        assert_eq!(after[2], nets[2]);
        assert_ne!(after[1], nets[1]);
        // Value 1 of row 2 moved towards its innovation.
        assert!(after[1].eval(&data.q[2]) > nets[1].eval(&data.q[2]));
        // Stage II with the networks frozen: its residuals are the fit's less each value's network.
        let fit = ReadingFit { model: &model, data: &data };
        let p =
            Problem { fit: &fit, x0: &model.nominal, fixed: &vec![true; model.n_params()], prior_std: &vec![1e-3; model.n_params()], noise_mm: 0.01, seed: 1 };
        let (_, back) = PsoEkfAwnn::default().stage_two(&p, &model.nominal, Some(nets.clone()), &mut NoObserver);
        assert_eq!(back.unwrap(), nets);
        let offset: Vec<f64> = data.q.iter().flat_map(|q| nets.iter().map(move |n| n.eval(q))).collect();
        let c = Corrected { fit: &fit, offset };
        let mut r = vec![0.0; 30];
        c.residuals(&model.nominal, &mut r);
        for (k, rk) in r.iter().enumerate() {
            assert!((rk + nets[k % 3].eval(&data.q[k / 3])).abs() < 1e-12);
        }
        // The learning rate's scale is the mean over every value's network.
        let per: Vec<f64> = nets.iter().map(|n| mean_gradient_square(std::slice::from_ref(n), &data)).collect();
        assert!((mean_gradient_square(&nets, &data) - per.iter().sum::<f64>() / 3.0).abs() < 1e-9 * per[0]);
    }
}
