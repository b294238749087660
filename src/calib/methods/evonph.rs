//! Evo-NPH (method `dsade-gkan`): joint identification of the geometry and a GKAN length
//! corrector by dual-strategy adaptive differential evolution, then a joint Gauss–Newton
//! polish of the same objective.
//!
//! # Decision vector and objective
//!
//! `z = [θ; w]`: the identifiable geometric (and sensor) parameters θ of the calibration model
//! (every parametrisation works: `--params dh` gives the paper's D-H form) and the network's
//! flattened coefficients w (196 to 414 spline coefficients, the shape chosen by
//! cross-validation). With `y_i(θ)` the training residual of the geometric model (mm) and
//! `δ_i(w)` the network's correction at pose i, the objective has four parts (mm²):
//!
//! ```text
//! J = 1/N Σ (y_i − δ_i)²                       data term on the distance residuals
//!   + λ_g Σ_k ((θ_k − θ0_k) / s_k)²            geometric deviation, diagonal scaling s_k
//!   + λ_n 1/N Σ δ_i²                             neural magnitude
//!   + λ_s 1/N (Σ (D w)² + κ Σ w²)                 spline roughness (second differences)
//! ```
//!
//! * `s_k` is the documented manufacturing tolerance of parameter k
//!   ([`crate::calib::model::tolerance::Tolerances`]) and `λ_g = σ²/N` with σ the reading noise estimated from
//!   the data: the geometric term is then exactly the tolerance prior of a MAP estimate
//!   (`J·N/σ²` = −2 log posterior up to a constant). Geometry may move where the data demand it
//!   and is held near its nominal where they do not.
//! * `λ_n` (neural magnitude): the network may not explain everything; a correction costs λ_n
//!   times its square, so it only takes residual structure that is consistent over many poses.
//! * `λ_s` (roughness, per unit second difference): keeps the edge functions smooth between the
//!   training poses (the gradient that the IK uses must be meaningful there); κ = 0.01 adds a
//!   small ridge that pins the constants the edge functions could otherwise trade among
//!   themselves.
//!
//! The network's shape and λ_n, λ_s are chosen on every run by 5-fold cross-validation on the
//! training rows ([`super::gkan_select`]: LM geometry, then each candidate network fitted to its
//! residuals on four folds and scored on the fifth, against the geometry refitted without it);
//! the test rows play no part. Without the
//! choice (`select = false`) the defaults are grid 4, chain-edge grid 2, λ_n = 0.05, λ_s = 0.02.
//!
//! # Search
//!
//! DS-ADE ([`DeVariant::DsAde`], population 40, 100 generations at effort 1) over the box:
//! geometry within ±5 tolerances of the start, each spline coefficient within ± the starting
//! residual RMS (a B-spline coefficient is a local value of its edge function). The start (nominal
//! geometry, zero network) is individual 0. Because J is quadratic in w, each evaluated trial's
//! coefficients are replaced by their exact minimiser for its geometry (a Lamarckian step
//! through one Cholesky factor computed before the search; the spline bases at the training
//! poses are computed once as well): the evolution then spends its budget on the nonlinear
//! geometry. `refine_coefficients = false` gives the paper's literal search over all
//! dimensions (compare both in `twincal bench dsade`). Finally the best vector is polished by
//! Levenberg–Marquardt on all of z at once (the same J written as a least-squares problem).
//!
//! # Ablations (the paper's Table 9)
//!
//! * V1 `dsade-gkan-v1` — sequential: LM geometry alone, then the GKAN fitted to the frozen
//!   residuals (same λ_n, λ_s).
//! * V2 `dsade-gkan-v2` — the GKAN replaced by a ReLU perceptron with as many weights; an MLP is
//!   not linear in its weights, so its DE searches every dimension; then the same joint polish.
//! * V3 `dsade-gkan-v3` — single-strategy DE (rand-to-pbest/1 with the same success-history
//!   adaptation, no strategy scheduler), otherwise V4.
//! * V4 `dsade-gkan` — the full method.

pub use super::gkan_select::EvoWeights;
use super::gkan_select::{penalty_gram, penalty_rows, select, Selection};
use super::solver::{Problem, Solution, Solver};
use crate::calib::correctors::gkan::{Gkan, GkanShape, Mlp};
use crate::calib::correctors::Corrector;
use crate::calib::fit::ReadingFit;
use crate::error::{Error, Result};
use crate::optim::{Bounds, Cost, De, DeVariant, Event, LeastSquares, LevenbergMarquardt, NoObserver, Observer, Report};
use nalgebra::{DMatrix, DVector};

/// Which Evo-NPH variant (see the module docs).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum EvoVariant {
    /// V4, the full method.
    Full,
    /// V1: LM geometry, then the GKAN on the frozen residuals.
    Sequential,
    /// V2: a ReLU perceptron of matched size instead of the GKAN.
    Mlp,
    /// V3: single-strategy DE.
    SingleStrategy,
}

impl EvoVariant {
    /// The name the variant is registered under ([`super::Method`]).
    pub const fn method_name(self) -> &'static str {
        match self {
            EvoVariant::Full => "dsade-gkan",
            EvoVariant::Sequential => "dsade-gkan-v1",
            EvoVariant::Mlp => "dsade-gkan-v2",
            EvoVariant::SingleStrategy => "dsade-gkan-v3",
        }
    }
}

/// Evo-NPH settings.
#[derive(Clone, Debug, PartialEq)]
pub struct EvoNphSolver {
    /// Which variant of the method runs.
    pub variant: EvoVariant,
    /// The DE engine's strategy (DS-ADE for V4, rand-to-pbest/1 for V3; others for Table 10).
    pub de: DeVariant,
    /// DE population size.
    pub pop: usize,
    /// DE generations.
    pub generations: usize,
    /// Cap on objective evaluations (equal budgets across DE variants; L-SHADE's horizon).
    pub max_evals: Option<usize>,
    /// Shape of the GKAN.
    pub shape: GkanShape,
    /// Weights of the objective's terms.
    pub weights: EvoWeights,
    /// Geometry box half-width in tolerances.
    pub width_sigmas: f64,
    /// Replace each trial's coefficients by their exact minimiser (GKAN only).
    pub refine_coefficients: bool,
    /// Joint LM polish of the DE's best vector.
    pub polish: bool,
    /// Choose `shape` and the network weights by cross-validation on the training rows first
    /// ([`super::gkan_select`]); `false` keeps them as set.
    pub select: bool,
    /// Whether there is a network at all: the choice turns it off when no candidate beat the
    /// geometry alone by one standard error (the corrector then has zero coefficients).
    pub network: bool,
}

impl EvoNphSolver {
    /// The variant with its default settings; `effort` scales the number of generations.
    pub fn new(variant: EvoVariant, effort: f64) -> Self {
        let de = match variant {
            EvoVariant::SingleStrategy => DeVariant::RandToPBest { memory: 6, p: 0.11 },
            _ => DeVariant::DsAde { memory: 6, p: 0.11, p_min: 0.1 },
        };
        EvoNphSolver {
            variant,
            de,
            pop: 40,
            generations: (100.0 * effort).ceil().max(2.0) as usize,
            max_evals: None,
            shape: GkanShape::default(),
            weights: EvoWeights::default(),
            width_sigmas: 5.0,
            refine_coefficients: variant != EvoVariant::Mlp,
            polish: true,
            select: true,
            network: true,
        }
    }
}

/// The network part of the decision vector.
enum Net {
    /// Spline bases at the training poses (row-major N × n) and the Cholesky factor of the
    /// normal matrix of the coefficient sub-problem.
    Gkan {
        net: Gkan,
        basis: Vec<f64>,
        chol: Option<nalgebra::Cholesky<f64, nalgebra::Dyn>>,
        rough: Vec<[(usize, f64); 3]>,
    },
    Mlp(Mlp),
}

/// The Evo-NPH objective over `z = [θ_free; w]` (see the module docs).
pub struct Objective<'a> {
    fit: &'a ReadingFit<'a>,
    base: Vec<f64>,
    free: Vec<usize>,
    x0_free: Vec<f64>,
    s_free: Vec<f64>,
    net: Net,
    lambda_g: f64,
    lambda_n: f64,
    lambda_s: f64,
    /// Number of network parameters in the decision vector (the DE's box for them is in the
    /// [`Bounds`]): one network per reading value, [`Self::per_net`] each; 0 without a network.
    n_w: usize,
    /// Coefficients (or weights) of one network.
    per_net: usize,
    /// Reading values per row (1 for a cable length, 3 for a tracker's point).
    dim: usize,
    refine: bool,
}

impl<'a> Objective<'a> {
    fn new(p: &'a Problem<'a>, s: &EvoNphSolver, mlp: bool) -> Result<(Objective<'a>, Bounds)> {
        let fit = p.fit;
        let n = fit.data.len();
        let dim = fit.data.dim;
        let free: Vec<usize> = (0..p.x0.len()).filter(|k| !p.fixed[*k]).collect();
        let x0_free: Vec<f64> = free.iter().map(|&k| p.x0[k]).collect();
        let s_free: Vec<f64> = free.iter().map(|&k| p.prior_std[k]).collect();
        let y0 = fit.residuals_mm(p.x0);
        let rms0 = crate::stats::rms(&y0);
        if !rms0.is_finite() || rms0 <= 0.0 {
            return Err(Error::Calibration("the starting residuals are not finite or all zero; nothing for the network to learn".into()));
        }
        let (lo, hi) = Gkan::range_of(&fit.data.q);
        let sigma = if p.noise_mm.is_finite() && p.noise_mm > 0.0 { p.noise_mm } else { 0.01 * rms0 };
        let w = &s.weights;
        let (net, w_half): (Net, Vec<f64>) = if mlp {
            let probe = Gkan::new(s.shape, lo.clone(), hi.clone());
            let h = Mlp::matched_hidden(probe.n_coef(), lo.len());
            let m = Mlp::new(h, lo, hi);
            let nj = m.lo.len();
            let half = (0..m.n_weights() * dim)
                .map(|k| k % m.n_weights())
                .map(|k| {
                    if k == h * (nj + 2) {
                        rms0
                    } else if k % (nj + 2) == nj + 1 {
                        rms0 / (h as f64).sqrt()
                    } else {
                        3.0
                    }
                })
                .collect();
            (Net::Mlp(m), half)
        } else {
            let net = Gkan::new(s.shape, lo, hi);
            let nw = net.n_coef();
            let mut basis = vec![0.0; n * nw];
            for (i, row) in basis.chunks_exact_mut(nw).enumerate() {
                net.basis_row(&fit.data.q[i], row);
            }
            let rough = penalty_rows(&net);
            let bm = DMatrix::from_row_slice(n, nw, &basis);
            let a = bm.transpose() * &bm * (1.0 + w.neural) + penalty_gram(&rough, nw) * w.roughness;
            let chol = nalgebra::Cholesky::new(a);
            let half = vec![rms0; nw * dim];
            (Net::Gkan { net, basis, chol, rough }, half)
        };
        let per_net = w_half.len() / dim;
        let w_half = if s.network { w_half } else { Vec::new() };
        let zero_w = vec![0.0; w_half.len()];
        let mut centre = x0_free.clone();
        centre.extend_from_slice(&zero_w);
        let mut half: Vec<f64> = s_free.iter().map(|sd| sd * s.width_sigmas).collect();
        half.extend_from_slice(&w_half);
        let bounds = Bounds::around(&centre, &half);
        let obj = Objective {
            fit,
            base: p.x0.to_vec(),
            free,
            x0_free,
            s_free,
            net,
            lambda_g: w.geometry * sigma * sigma / fit.data.y.len() as f64,
            lambda_n: w.neural,
            lambda_s: w.roughness,
            n_w: w_half.len(),
            per_net,
            dim,
            refine: s.refine_coefficients && !mlp,
        };
        Ok((obj, bounds))
    }

    fn m(&self) -> usize {
        self.free.len()
    }
    /// The full model vector of `z`.
    pub fn expand(&self, z: &[f64]) -> Vec<f64> {
        let mut x = self.base.clone();
        for (k, &i) in self.free.iter().enumerate() {
            x[i] = z[k];
        }
        x
    }
    /// The networks' corrections at the training poses for coefficients `w` (`dim` values per
    /// row, row after row; network `c`'s coefficients are block `c` of `w`).
    fn corrections(&self, w: &[f64], out: &mut [f64]) {
        let (d, nw) = (self.dim, self.per_net);
        if w.is_empty() {
            out.fill(0.0);
            return;
        }
        match &self.net {
            Net::Gkan { basis, .. } => {
                for (o, row) in out.chunks_exact_mut(d).zip(basis.chunks_exact(nw)) {
                    for (oc, wc) in o.iter_mut().zip(w.chunks_exact(nw)) {
                        *oc = row.iter().zip(wc).map(|(a, b)| a * b).sum();
                    }
                }
            }
            Net::Mlp(m) => {
                for (o, q) in out.chunks_exact_mut(d).zip(&self.fit.data.q) {
                    for (oc, wc) in o.iter_mut().zip(w.chunks_exact(nw)) {
                        *oc = m.eval(wc, q, None, None);
                    }
                }
            }
        }
    }
    /// The roughness penalty Σ (D w)² of every network (0 for the perceptron).
    fn roughness(&self, w: &[f64]) -> f64 {
        match &self.net {
            Net::Gkan { rough, .. } => {
                w.chunks_exact(self.per_net).map(|wc| rough.iter().map(|r| r.iter().map(|(k, v)| wc[*k] * v).sum::<f64>().powi(2)).sum::<f64>()).sum()
            }
            Net::Mlp(_) => 0.0,
        }
    }
    /// J at z given the geometric residuals y (mm).
    fn objective(&self, z: &[f64], y: &[f64]) -> f64 {
        let m = self.m();
        let (theta, w) = z.split_at(m);
        let n = y.len() as f64;
        let mut delta = vec![0.0; y.len()];
        self.corrections(w, &mut delta);
        let data: f64 = y.iter().zip(&delta).map(|(a, b)| (a - b) * (a - b)).sum::<f64>() / n;
        let mag: f64 = delta.iter().map(|d| d * d).sum::<f64>() / n;
        let geo: f64 = (0..m).map(|k| ((theta[k] - self.x0_free[k]) / self.s_free[k]).powi(2)).sum();
        let rough = self.roughness(w) / n;
        data + self.lambda_g * geo + self.lambda_n * mag + self.lambda_s * rough
    }
    fn geometric_residuals(&self, z: &[f64]) -> Vec<f64> {
        self.fit.residuals_mm(&self.expand(&z[..self.m()]))
    }
    /// The exact minimiser of J over w for the geometry in z (GKAN only), written into `w`.
    /// Returns `b·w` (b = Bᵀy): the data, magnitude and roughness terms together equal
    /// `(‖y‖² − b·w)/N` at the minimiser, with no further pass over the bases. The minimiser is
    /// not clamped to the DE's box for the coefficients (that box only seeds the literal search;
    /// the penalties keep the minimiser bounded).
    /// With several values per row, each value's network is its own sub-problem with the same
    /// normal matrix: one factor, `dim` solves.
    fn solve_coefficients(&self, y: &[f64], w: &mut [f64]) -> Option<f64> {
        let Net::Gkan { basis, chol: Some(chol), .. } = &self.net else {
            return None;
        };
        if w.is_empty() {
            return None;
        }
        if self.dim == 1 {
            return Some(Self::solve_one(basis, chol, y, w));
        }
        let (d, nw) = (self.dim, self.per_net);
        let mut bw = 0.0;
        let mut yc = vec![0.0; y.len() / d];
        for (c, wc) in w.chunks_exact_mut(nw).enumerate() {
            for (v, row) in yc.iter_mut().zip(y.chunks_exact(d)) {
                *v = row[c];
            }
            bw += Self::solve_one(basis, chol, &yc, wc);
        }
        Some(bw)
    }
    /// One network's coefficients for one value's residuals `y` (one per row), and `b·w`.
    fn solve_one(basis: &[f64], chol: &nalgebra::Cholesky<f64, nalgebra::Dyn>, y: &[f64], w: &mut [f64]) -> f64 {
        let nw = w.len();
        // b = Bᵀy on plain slices, four rows per pass (this is the DE's inner loop).
        let mut rhs = vec![0.0; nw];
        let mut rows = basis.chunks_exact(4 * nw).zip(y.chunks_exact(4));
        for (block, yy) in &mut rows {
            let (b0, rest) = block.split_at(nw);
            let (b1, rest) = rest.split_at(nw);
            let (b2, b3) = rest.split_at(nw);
            for k in 0..nw {
                rhs[k] += b0[k] * yy[0] + b1[k] * yy[1] + b2[k] * yy[2] + b3[k] * yy[3];
            }
        }
        let done = y.len() / 4 * 4;
        for (yi, row) in y[done..].iter().zip(basis[done * nw..].chunks_exact(nw)) {
            for (r, b) in rhs.iter_mut().zip(row) {
                *r += b * yi;
            }
        }
        let rhs = DVector::from_vec(rhs);
        let sol = chol.solve(&rhs);
        w.copy_from_slice(sol.as_slice());
        rhs.dot(&sol)
    }
    /// The learned corrector for coefficients `w`: one network, or one per reading value.
    fn corrector(&self, w: &[f64]) -> Corrector {
        let zero;
        let w = if w.is_empty() {
            zero = vec![0.0; self.per_net * self.dim];
            &zero[..]
        } else {
            w
        };
        let one = |wc: &[f64]| match &self.net {
            Net::Gkan { net, .. } => Corrector::Gkan(Gkan { coef: wc.to_vec(), ..net.clone() }),
            Net::Mlp(m) => Corrector::Mlp(Mlp { w: wc.to_vec(), ..m.clone() }),
        };
        Corrector::of_values(w.chunks_exact(self.per_net).map(one).collect())
    }
}

impl Cost for Objective<'_> {
    fn dim(&self) -> usize {
        self.m() + self.n_w
    }
    fn cost(&self, z: &[f64]) -> f64 {
        let y = self.geometric_residuals(z);
        self.objective(z, &y)
    }
    fn cost_refine(&self, z: &mut [f64]) -> f64 {
        let y = self.geometric_residuals(z);
        if self.refine {
            let m = self.m();
            if let Some(bw) = self.solve_coefficients(&y, &mut z[m..]) {
                let n = y.len() as f64;
                let geo: f64 = (0..m).map(|k| ((z[k] - self.x0_free[k]) / self.s_free[k]).powi(2)).sum();
                return (y.iter().map(|v| v * v).sum::<f64>() - bw) / n + self.lambda_g * geo;
            }
        }
        self.objective(z, &y)
    }
}

/// J as a least-squares problem for the joint polish: ½‖R‖² = N·J/2 with rows
/// `y_i − δ_i`, `√(Nλ_g)·(θ_k − θ0_k)/s_k`, `√λ_n·δ_i` and `√λ_s·(D w)_r`.
struct JointLs<'a, 'b> {
    obj: &'b Objective<'a>,
}

impl JointLs<'_, '_> {
    /// Row counts of the four blocks: data (one per reading value), geometry, magnitude,
    /// roughness (every network's).
    fn rows(&self) -> (usize, usize, usize, usize) {
        let n = self.obj.fit.data.y.len();
        if self.obj.n_w == 0 {
            return (n, self.obj.m(), 0, 0);
        }
        let r = match &self.obj.net {
            Net::Gkan { rough, .. } => rough.len() * self.obj.dim,
            Net::Mlp(_) => 0,
        };
        (n, self.obj.m(), n, r)
    }
}

impl LeastSquares for JointLs<'_, '_> {
    fn n_params(&self) -> usize {
        self.obj.dim()
    }
    fn n_residuals(&self) -> usize {
        let (a, b, c, d) = self.rows();
        a + b + c + d
    }
    fn residuals(&self, z: &[f64], r: &mut [f64]) {
        let o = self.obj;
        let (n, m, nm, _) = self.rows();
        let y = o.geometric_residuals(z);
        let mut delta = vec![0.0; n];
        o.corrections(&z[m..], &mut delta);
        let (sg, sn, ss) = ((n as f64 * o.lambda_g).sqrt(), o.lambda_n.sqrt(), o.lambda_s.sqrt());
        for i in 0..n {
            r[i] = y[i] - delta[i];
        }
        for i in 0..nm {
            r[n + m + i] = sn * delta[i];
        }
        for k in 0..m {
            r[n + k] = sg * (z[k] - o.x0_free[k]) / o.s_free[k];
        }
        if let Net::Gkan { rough, .. } = &o.net {
            for (c, wc) in z[m..].chunks_exact(o.per_net).enumerate() {
                for (t, row) in rough.iter().enumerate() {
                    r[2 * n + m + c * rough.len() + t] = ss * row.iter().map(|(k, v)| wc[*k] * v).sum::<f64>();
                }
            }
        }
    }
    fn jacobian(&self, z: &[f64], j: &mut DMatrix<f64>) {
        let o = self.obj;
        let (n, m, _, _) = self.rows();
        j.fill(0.0);
        let x = o.expand(&z[..m]);
        let mut jg = DMatrix::zeros(n, x.len());
        LeastSquares::jacobian(o.fit, &x, &mut jg);
        let (sg, sn, ss) = ((n as f64 * o.lambda_g).sqrt(), o.lambda_n.sqrt(), o.lambda_s.sqrt());
        for (k, &c) in o.free.iter().enumerate() {
            for i in 0..n {
                j[(i, k)] = jg[(i, c)];
            }
            j[(n + k, k)] = sg / o.s_free[k];
        }
        let (d, nw) = (o.dim, o.per_net);
        if o.n_w == 0 {
            return;
        }
        let mut gw = vec![0.0; nw];
        // Value i of the data belongs to row i / d and to network i % d (columns of block i % d).
        for i in 0..n {
            let (row, c) = (i / d, i % d);
            let wc = &z[m + c * nw..m + (c + 1) * nw];
            match &o.net {
                Net::Gkan { basis, .. } => gw.copy_from_slice(&basis[row * nw..(row + 1) * nw]),
                Net::Mlp(mlp) => {
                    mlp.eval(wc, &o.fit.data.q[row], Some(&mut gw), None);
                }
            }
            for k in 0..nw {
                j[(i, m + c * nw + k)] = -gw[k];
                j[(n + m + i, m + c * nw + k)] = sn * gw[k];
            }
        }
        if let Net::Gkan { rough, .. } = &o.net {
            for c in 0..d {
                for (t, row) in rough.iter().enumerate() {
                    for &(k, v) in row {
                        j[(2 * n + m + c * rough.len() + t, m + c * nw + k)] += ss * v;
                    }
                }
            }
        }
    }
}

/// Re-expresses observed decision vectors as model vectors for the caller's observer.
struct ExpandObs<'a, 'b, 'c> {
    obj: &'a Objective<'b>,
    inner: &'c mut dyn Observer,
}

impl Observer for ExpandObs<'_, '_, '_> {
    fn observe(&mut self, e: &Event) {
        let x = self.obj.expand(&e.x[..self.obj.m()]);
        self.inner.observe(&Event { x: &x, ..e.clone() });
    }
}

/// What one Evo-NPH run produced, beyond the [`Solution`]: for benchmarks and ablation tables.
#[derive(Clone, Debug)]
pub struct EvoRun {
    /// The calibrated parameter vector, every model parameter (internal units).
    pub solution_x: Vec<f64>,
    /// The learned corrector.
    pub corrector: Corrector,
    /// J after the DE (before the polish) and at the end.
    pub de_objective: f64,
    /// J at the end, after the polish (see `de_objective`).
    pub objective: f64,
    /// Best J after every generation.
    pub curve: Vec<f64>,
    /// DE generations run.
    pub generations: usize,
    /// Objective evaluations, the polish's included.
    pub evaluations: usize,
    /// Decision-vector dimension.
    pub dim: usize,
    /// Identifiable geometric parameters in it.
    pub n_geometry: usize,
    /// Wall time of the DE (or, for V1, of its LM fit and coefficient solve), s.
    pub de_seconds: f64,
    /// The cross-validated choice of the network's shape and weights, when made.
    pub selection: Option<Selection>,
}

struct Curve<'a> {
    costs: Vec<f64>,
    inner: &'a mut dyn Observer,
}
impl Observer for Curve<'_> {
    fn observe(&mut self, e: &Event) {
        self.costs.push(e.cost);
        self.inner.observe(e);
    }
}

impl EvoNphSolver {
    /// Runs the method and returns everything it measured.
    pub fn run(&self, p: &Problem, obs: &mut dyn Observer) -> Result<EvoRun> {
        let selection = if self.select { Some(select(p)?) } else { None };
        let chosen;
        let me = match &selection {
            Some(sel) => {
                chosen =
                    EvoNphSolver { shape: sel.chosen.shape, weights: sel.weights(self.weights.geometry), select: false, network: sel.fitted, ..self.clone() };
                &chosen
            }
            None => self,
        };
        me.run_as_set(p, obs, selection)
    }

    fn run_as_set(&self, p: &Problem, obs: &mut dyn Observer, selection: Option<Selection>) -> Result<EvoRun> {
        let mlp = self.variant == EvoVariant::Mlp;
        let (obj, bounds) = Objective::new(p, self, mlp)?;
        let m = obj.m();
        let dim = obj.dim();
        let t0 = std::time::Instant::now();
        let (mut z, de_report, curve) = if self.variant == EvoVariant::Sequential {
            // V1: LM on the geometry alone, then the coefficients for the frozen residuals.
            let lm = super::lm::LmSolver::default();
            let rep = lm.lm.minimize(p.fit, p.x0, p.fixed, obs);
            let mut z: Vec<f64> = obj.free.iter().map(|&k| rep.x[k]).collect();
            z.extend(std::iter::repeat_n(0.0, dim - m));
            let y = obj.geometric_residuals(&z);
            obj.solve_coefficients(&y, &mut z[m..]);
            let cost = obj.cost(&z);
            (z, Report { cost, ..rep }, Vec::new())
        } else {
            let de =
                De { variant: self.de.clone(), pop: self.pop, generations: self.generations, max_evals: self.max_evals, seed: p.seed, tol: 1e-12, patience: 0 };
            let mut start = obj.x0_free.clone();
            start.extend(std::iter::repeat_n(0.0, dim - m));
            let mut curve = Curve { costs: Vec::new(), inner: obs };
            let rep = de.minimize(&obj, &bounds, Some(&start), &mut ExpandObs { obj: &obj, inner: &mut curve });
            (rep.x.clone(), rep, curve.costs)
        };
        let de_seconds = t0.elapsed().as_secs_f64();
        let de_objective = obj.cost(&z);
        let mut evaluations = de_report.evaluations;
        if self.polish && self.variant != EvoVariant::Sequential {
            let ls = JointLs { obj: &obj };
            let lm = LevenbergMarquardt::budget(100);
            let rep = lm.minimize(&ls, &z, &vec![false; dim], &mut NoObserver);
            if rep.x.iter().all(|v| v.is_finite()) && obj.cost(&rep.x) <= de_objective {
                z = rep.x;
            }
            evaluations += rep.evaluations;
        }
        let objective = obj.cost(&z);
        Ok(EvoRun {
            solution_x: obj.expand(&z[..m]),
            corrector: obj.corrector(&z[m..]),
            de_objective,
            objective,
            curve,
            generations: de_report.iterations,
            evaluations,
            dim,
            n_geometry: m,
            de_seconds,
            selection,
        })
    }
}

impl Solver for EvoNphSolver {
    fn learns_corrector(&self) -> bool {
        true
    }
    fn name(&self) -> &'static str {
        self.variant.method_name()
    }
    fn needs_noise(&self) -> bool {
        true
    }
    fn solve(&self, p: &Problem, obs: &mut dyn Observer) -> Result<Solution> {
        let r = self.run(p, obs)?;
        let polished = self.polish && self.variant != EvoVariant::Sequential;
        let mut reason = match self.variant {
            EvoVariant::Sequential => "LM geometry, then the GKAN on the frozen residuals".to_string(),
            _ => format!("{} generations of {:?} over {} dimensions{}", r.generations, self.de, r.dim, if polished { ", then a joint LM polish" } else { "" }),
        };
        if let Some(sel) = &r.selection {
            reason = format!("{}; {reason}", sel.summary());
        }
        let report = Report {
            x: r.solution_x,
            cost: r.objective,
            iterations: r.generations,
            evaluations: r.evaluations,
            termination: crate::optim::Termination::Completed,
            reason,
            covariance: None,
        };
        Ok(Solution { report, corrector: Some(r.corrector) })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::calib::fit::Samples;
    use crate::calib::model::{CalibModel, DrawWireGuess, Placement};
    use crate::measurement::Measurement;
    use crate::robot::Robot;
    use nalgebra::Vector3;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// A model reading `m` and readings of it at 40 random poses, off by a smooth field.
    fn problem_data(m: Measurement) -> (CalibModel, Samples) {
        let robot = Robot::irb120();
        let cable = DrawWireGuess { exit_m: [0.8, 0.3, 0.05], offset_m: 0.12, tool_m: [0.06, 0.004, -0.003] };
        let mut model = CalibModel::dh(&robot, &cable, true);
        if m == Measurement::Point {
            model = model.with_placement(&Placement { measurement: m, own: vec![1.8, 0.6, -0.2, -0.01, 0.02, -2.1], tool: Vector3::new(-0.025, 0.03, 0.07) });
        }
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let limits = robot.limits();
        let (mut qs, mut ys) = (Vec::new(), Vec::new());
        let mut w = model.work();
        let d = m.dim();
        for _ in 0..40 {
            let q: Vec<f64> = limits.iter().map(|(lo, hi)| lo + (hi - lo) * (0.2 + 0.6 * rng.random::<f64>())).collect();
            let mut y = vec![0.0; d];
            model.readings(&model.nominal, &q, &Default::default(), &mut w, &mut y);
            for (c, v) in y.iter_mut().enumerate() {
                *v += 1e-4 * (q[1] * (c + 1) as f64).sin() + 2e-5 * rng.random::<f64>();
            }
            qs.push(q);
            ys.extend(y);
        }
        (model, Samples::readings(qs, ys, d))
    }

    /// The joint polish's Jacobian matches central differences of its residuals, for a cable
    /// and a tracker's point (one network per coordinate), with the GKAN and the perceptron;
    /// and the Lamarckian step's closed-form objective equals the objective at the coefficients
    /// it writes.
    #[test]
    fn joint_jacobian_matches_finite_differences_and_the_coefficient_step_is_exact() {
        for m in [Measurement::Length, Measurement::Point] {
            let (model, data) = problem_data(m);
            let fit = ReadingFit { model: &model, data: &data };
            let fixed: Vec<bool> = (0..model.n_params()).map(|k| k % 3 == 0).collect();
            let prior = vec![1e-3; model.n_params()];
            let p = Problem { fit: &fit, x0: &model.nominal, fixed: &fixed, prior_std: &prior, noise_mm: 0.01, seed: 1 };
            // The GKAN, the perceptron, and no network (the choice's one-standard-error rule).
            for (mlp, network) in [(false, true), (true, true), (false, false)] {
                let s = EvoNphSolver { shape: GkanShape { grid: 3, edge_grid: 1, chain_joints: 5 }, network, ..EvoNphSolver::new(EvoVariant::Full, 1.0) };
                let (obj, _) = Objective::new(&p, &s, mlp).unwrap();
                assert_eq!(obj.n_w, if network { obj.per_net * m.dim() } else { 0 });
                let mut rng = ChaCha8Rng::seed_from_u64(9);
                let mut z: Vec<f64> = obj.x0_free.iter().map(|v| v + 1e-4 * (rng.random::<f64>() - 0.5)).collect();
                z.extend((0..obj.n_w).map(|_| 0.01 * (rng.random::<f64>() - 0.5)));
                let ls = JointLs { obj: &obj };
                let (nr, np) = (ls.n_residuals(), ls.n_params());
                let mut j = DMatrix::zeros(nr, np);
                ls.jacobian(&z, &mut j);
                let (mut rp, mut rm) = (vec![0.0; nr], vec![0.0; nr]);
                let mut worst = 0.0f64;
                for k in 0..np {
                    let h = 1e-6 * z[k].abs().max(1.0);
                    let (mut zp, mut zm) = (z.clone(), z.clone());
                    zp[k] += h;
                    zm[k] -= h;
                    ls.residuals(&zp, &mut rp);
                    ls.residuals(&zm, &mut rm);
                    for i in 0..nr {
                        let fd = (rp[i] - rm[i]) / (2.0 * h);
                        worst = worst.max((fd - j[(i, k)]).abs() / (1.0 + fd.abs()));
                    }
                }
                assert!(worst < 1e-5, "{m:?} mlp {mlp}: worst relative Jacobian error {worst}");
                // ½‖R‖² = N·J/2.
                ls.residuals(&z, &mut rp);
                let half: f64 = rp.iter().map(|v| v * v).sum::<f64>() / 2.0;
                let n = data.y.len() as f64;
                assert!((half - n * obj.cost(&z) / 2.0).abs() < 1e-9 * half.max(1.0), "{m:?} mlp {mlp}");
                if !mlp && network {
                    let mut zr = z.clone();
                    let refined = obj.cost_refine(&mut zr);
                    assert!((refined - obj.cost(&zr)).abs() < 1e-9 * refined, "{m:?}: {refined} vs {}", obj.cost(&zr));
                    assert!(refined < obj.cost(&z));
                }
                if !network {
                    // No network: the corrector holds zero coefficients of the chosen shape.
                    let c = obj.corrector(&[]);
                    assert_eq!(c.as_correct().dim(), m.dim());
                    let mut out = vec![1.0; m.dim()];
                    c.as_correct().corrections_mm(&data.q[0], &Default::default(), &mut out);
                    assert!(out.iter().all(|v| *v == 0.0));
                }
            }
        }
    }
}
