//! Levenberg–Marquardt for nonlinear least squares, `min ½‖r(x)‖²`.
//!
//! # Algorithm
//!
//! Every outer iteration evaluates the Jacobian `J` once and forms the normal equations over
//! the free parameters only, `A = JᵀJ`, `g = Jᵀr`. A step δ then solves the damped system
//!
//! ```text
//! (A + λ·D) δ = −g,      D = diag(A) (Marquardt scaling, kept as a running maximum)
//! ```
//!
//! The running maximum of `diag(A)` (Moré's variant) keeps the damping from collapsing in a
//! direction whose curvature temporarily vanishes; a floor keeps `D` positive for parameters
//! the residuals do not depend on, so their step is exactly zero.
//!
//! The step is accepted when the gain ratio `ρ = (f − f(x+δ)) / (L(0) − L(δ))` of actual to
//! predicted (quadratic-model) reduction is positive. λ follows Nielsen's rule:
//! on acceptance `λ ← λ·max(⅓, 1 − (2ρ − 1)³)`, `ν ← 2`; on rejection `λ ← λ·ν`, `ν ← 2ν`.
//!
//! The damped system is solved by an in-place Cholesky factorisation (no allocation). If it is
//! not numerically positive definite (NaN entries, extreme ill-conditioning) the solver falls
//! back to an SVD pseudo-solve, and if that fails too it simply raises λ and tries again.
//!
//! With [`Damping::Factor`]`(β)` λ follows a fixed adjustment factor instead: `λ ← λ/β` on
//! acceptance, `λ ← λ·β` on rejection (the classic schedule, and the one of the PSO-EKF-AWNN
//! paper's refinement stage).
//!
//! A NaN or infinite cost at a trial point counts as +∞: the step is rejected and λ grows.
//!
//! # Stopping
//!
//! * `gtol`: the largest cosine between `r` and a column of `J` (MINPACK's scale-free gradient
//!   test) is at most `gtol` — a stationary point of a non-zero-residual problem;
//! * `ftol`: both actual and predicted relative reductions of an accepted step are at most `ftol`
//!   (with [`Damping::Factor`]: the actual relative loss reduction alone);
//! * `xtol`: `‖δ‖ ≤ xtol·(‖x_free‖ + xtol)`;
//! * `stall`: over the last `stall_window` outer iterations the cost fell by at most
//!   `stall_rtol` of the mean cost per degree of freedom, `f / (m − n_free)` (half a residual
//!   variance): the fit is creeping along a flat valley of an ill-conditioned problem, where
//!   per-step tests never fire, and what it still gains is statistically nothing (with the
//!   default 1e-3, χ² changes by 0.002 over the window);
//! * the cost is exactly zero;
//! * `max_iter` outer iterations (Jacobian evaluations) — reported as not converged.
//!
//! See also [`covariance`] for the parameter covariance at the solution.

use nalgebra::{DMatrix, DVector};

use super::normal::{normal_equations, SparseRows};
use super::util::free_indices;
use super::{Event, LeastSquares, Observer, Report, Termination};

const METHOD: &str = "levenberg-marquardt";
/// Consecutive rejected steps tolerated inside one outer iteration before giving up.
const MAX_REJECTIONS: usize = 60;
/// λ above this means no step along the gradient lowers the cost any more.
const LAMBDA_MAX: f64 = 1e32;

/// How the damping factor λ moves between trial steps (see the module docs).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Damping {
    /// Nielsen's gain-ratio rule.
    Nielsen,
    /// A fixed adjustment factor β > 1 (a β that is not a finite number above 1 means 10).
    Factor(f64),
}

/// Levenberg–Marquardt settings. See the module documentation for the algorithm.
#[derive(Clone, Debug, PartialEq)]
pub struct LevenbergMarquardt {
    /// Maximum number of outer iterations (Jacobian evaluations).
    pub max_iter: usize,
    /// Relative cost-reduction tolerance.
    pub ftol: f64,
    /// Relative step-size tolerance.
    pub xtol: f64,
    /// Tolerance on the cosine between the residual and the Jacobian columns.
    pub gtol: f64,
    /// Initial damping factor λ (relative to `diag(JᵀJ)`).
    pub initial_lambda: f64,
    /// The damping schedule.
    pub damping: Damping,
    /// Window (outer iterations) of the stall test; 0 switches it off.
    pub stall_window: usize,
    /// Cost change over the window, relative to the mean cost per degree of freedom, below
    /// which the fit has stalled.
    pub stall_rtol: f64,
}

impl Default for LevenbergMarquardt {
    fn default() -> Self {
        LevenbergMarquardt {
            max_iter: 200,
            ftol: 1e-12,
            xtol: 1e-12,
            gtol: 1e-10,
            initial_lambda: 1e-3,
            damping: Damping::Nielsen,
            stall_window: 10,
            stall_rtol: 1e-3,
        }
    }
}

/// ½‖r‖², with NaN mapped to +∞.
fn half_sq(r: &[f64]) -> f64 {
    let s = 0.5 * r.iter().map(|v| v * v).sum::<f64>();
    if s.is_nan() {
        f64::INFINITY
    } else {
        s
    }
}

/// In-place Cholesky factorisation `M = L·Lᵀ` of the symmetric matrix in `l` (only the lower
/// triangle is read; `L` overwrites it). Returns false if `M` is not numerically positive definite.
fn cholesky_in_place(l: &mut DMatrix<f64>) -> bool {
    let n = l.nrows();
    for j in 0..n {
        let mut d = l[(j, j)];
        for k in 0..j {
            d -= l[(j, k)] * l[(j, k)];
        }
        if !(d > 0.0 && d.is_finite()) {
            return false;
        }
        let djj = d.sqrt();
        l[(j, j)] = djj;
        for i in j + 1..n {
            let mut s = l[(i, j)];
            for k in 0..j {
                s -= l[(i, k)] * l[(j, k)];
            }
            l[(i, j)] = s / djj;
        }
    }
    true
}

/// Solve `L·Lᵀ·x = b` in place (`x` holds `b` on entry) given the factor from [`cholesky_in_place`].
fn cholesky_solve(l: &DMatrix<f64>, x: &mut [f64]) {
    let n = l.nrows();
    for i in 0..n {
        let mut s = x[i];
        for k in 0..i {
            s -= l[(i, k)] * x[k];
        }
        x[i] = s / l[(i, i)];
    }
    for i in (0..n).rev() {
        let mut s = x[i];
        for k in i + 1..n {
            s -= l[(k, i)] * x[k];
        }
        x[i] = s / l[(i, i)];
    }
}

/// Fallback: minimum-norm solution of `M·x = b` by SVD (allocates; only used when Cholesky fails).
fn svd_solve(m: &DMatrix<f64>, b: &[f64], x: &mut [f64]) -> bool {
    if m.iter().any(|v| !v.is_finite()) || b.iter().any(|v| !v.is_finite()) {
        return false;
    }
    let svd = m.clone().svd(true, true);
    let smax = svd.singular_values.iter().cloned().fold(0.0, f64::max);
    if !(smax > 0.0) {
        return false;
    }
    match svd.solve(&DVector::from_column_slice(b), 1e-14 * smax) {
        Ok(sol) if sol.iter().all(|v| v.is_finite()) => {
            x.copy_from_slice(sol.as_slice());
            true
        }
        _ => false,
    }
}

impl LevenbergMarquardt {
    /// The default settings with a budget of `max_iter` outer iterations: how every fit in
    /// twincal names its settings (with [`Self::tolerances`] where it stops earlier).
    pub fn budget(max_iter: usize) -> Self {
        LevenbergMarquardt { max_iter, ..Default::default() }
    }
    /// A refit from a near start (a diagnosis's candidates and folds, the noise model's fits):
    /// 100 iterations, tolerances 1e-9 (held-out residuals need a few significant digits, not
    /// the last one).
    pub fn refit() -> Self {
        Self::budget(100).tolerances(1e-9, 1e-9)
    }
    /// These settings with relative cost and step tolerances `ftol`, `xtol`.
    pub fn tolerances(self, ftol: f64, xtol: f64) -> Self {
        LevenbergMarquardt { ftol, xtol, ..self }
    }

    /// Minimise `½‖r(x)‖²` from `x0`. Parameters with `fixed[k] == true` stay exactly at `x0[k]`
    /// (a `fixed` slice shorter than `x0` leaves the remaining parameters free).
    ///
    /// One [`Event`] is emitted per outer iteration with the current (best) cost and `x`.
    /// `Report::evaluations` counts residual-vector evaluations (Jacobians not included);
    /// `Report::covariance` is `None` — use [`covariance`].
    ///
    /// # Panics
    /// If `x0.len() != p.n_params()`.
    pub fn minimize<P: LeastSquares>(&self, p: &P, x0: &[f64], fixed: &[bool], obs: &mut dyn Observer) -> Report {
        let n = p.n_params();
        let m = p.n_residuals();
        assert_eq!(x0.len(), n, "x0 has {} entries, problem has {n} parameters", x0.len());
        let free = free_indices(fixed, n);
        let nf = free.len();
        let mut pt = Point::start(p, x0, nf > 0);
        let early = if !pt.f.is_finite() {
            Some((Termination::NonFinite, "non-finite cost at the initial point"))
        } else if nf == 0 {
            Some((Termination::NothingToDo, "no free parameters"))
        } else if pt.f == 0.0 {
            Some((Termination::ZeroCost, "zero cost at the initial point"))
        } else {
            None
        };
        if let Some((termination, reason)) = early {
            return pt.report(0, termination, reason);
        }
        if !pt.joint {
            pt.jac = DMatrix::<f64>::zeros(m, n);
        }
        let mut w = Work::new(free, &pt.x, m);
        let mut damper = Damper::new(self);
        // Cost at the start of each of the last `stall_window` outer iterations (ring buffer).
        let mut window = vec![f64::INFINITY; self.stall_window];
        let mut iterations = 0;
        let (termination, reason) = loop {
            if iterations >= self.max_iter {
                break (Termination::Budget, "maximum number of iterations reached");
            }
            if self.stalled(&mut window, iterations, pt.f, m.saturating_sub(nf).max(1)) {
                break (Termination::Stalled, "cost change over the stall window below stall_rtol of the cost per degree of freedom");
            }
            iterations += 1;
            // (Every way back here goes through an accepted step, which sets `jac_at_x`.)
            if !pt.jac_at_x {
                p.jacobian(&pt.x, &mut pt.jac);
            }
            // Normal equations over the free columns (J is column-major: columns are contiguous).
            normal_equations(&pt.jac, &w.free, &pt.r, (&mut w.a, &mut w.g), &mut w.sparse);
            if w.g.iter().chain(w.a.iter()).any(|v| !v.is_finite()) {
                break (Termination::NonFinite, "non-finite Jacobian");
            }
            if gradient_cosine(&w.a, &w.g, pt.f) <= self.gtol {
                obs.observe(&Event { method: METHOD, iteration: iterations, cost: pt.f, x: &pt.x });
                break (Termination::GradientTolerance, "gradient tolerance (gtol) reached");
            }
            w.scale_floor = update_scale(&mut w.scale, &w.a);
            if let Some(stop) = self.step(p, &mut pt, &mut w, &mut damper, iterations, obs) {
                break stop;
            }
        };
        pt.report(iterations, termination, reason)
    }

    /// Whether the cost fell by no more than `stall_rtol` of the cost per degree of freedom
    /// (`dof`) over the last `stall_window` iterations; records the cost `f` in `window`.
    fn stalled(&self, window: &mut [f64], iterations: usize, f: f64, dof: usize) -> bool {
        if self.stall_window == 0 {
            return false;
        }
        let slot = iterations % self.stall_window;
        if iterations >= self.stall_window && window[slot] - f <= self.stall_rtol * f / dof as f64 {
            return true;
        }
        window[slot] = f;
        false
    }

    /// One outer iteration's steps from the normal equations in `w`: damped steps, more damping
    /// after each rejection, until one is accepted (None, or the stop it reached) or the damping
    /// gives out (the stop).
    fn step<P: LeastSquares>(&self, p: &P, pt: &mut Point, w: &mut Work, damper: &mut Damper, iteration: usize, obs: &mut dyn Observer) -> Option<Stop> {
        let mut rejections = 0;
        loop {
            for (d, s) in w.damping.iter_mut().zip(&w.scale) {
                *d = damper.lambda * s.max(w.scale_floor);
            }
            let solved = damped_step(&w.a, &w.g, &w.damping, &mut w.chol, &mut w.delta);
            let mut step_small = false;
            if solved {
                let pred;
                (pred, step_small) = predicted_reduction(&w.delta, &w.damping, &w.g, &pt.x, &w.free, self.xtol);
                let f_new = pt.trial(p, w);
                let actual = pt.f - f_new;
                let rho = if pred > 0.0 { actual / pred } else { -1.0 };
                if rho > 0.0 && f_new < pt.f {
                    let f_old = pt.f;
                    pt.accept(w, f_new);
                    damper.lambda = lambda_after_accept(damper.factor, damper.lambda, rho);
                    damper.nu = 2.0;
                    obs.observe(&Event { method: METHOD, iteration, cost: pt.f, x: &pt.x });
                    let pred_small = damper.factor.is_some() || pred <= self.ftol * f_old;
                    return if pt.f == 0.0 {
                        Some((Termination::ZeroCost, "zero cost"))
                    } else if actual <= self.ftol * f_old && pred_small {
                        Some((Termination::CostTolerance, "relative cost reduction below ftol"))
                    } else if step_small {
                        Some((Termination::StepTolerance, "relative step below xtol"))
                    } else {
                        None
                    };
                }
                // Restore the trial buffer to the current point for the free entries.
                for &c in &w.free {
                    w.x_new[c] = pt.x[c];
                }
                pt.speculate = false;
            }
            // Rejected (or unsolvable): more damping.
            let stop = if step_small {
                Some((Termination::StepTolerance, "relative step below xtol"))
            } else {
                (damper.lambda, damper.nu) = match damper.factor {
                    Some(beta) => (damper.lambda * beta, damper.nu),
                    None => (damper.lambda * damper.nu, damper.nu * 2.0),
                };
                rejections += 1;
                let overflow = !(damper.lambda < LAMBDA_MAX) || rejections >= MAX_REJECTIONS || !damper.nu.is_finite();
                overflow.then_some((Termination::NoDescent, "no step reduces the cost (damping overflow)"))
            };
            if stop.is_some() {
                obs.observe(&Event { method: METHOD, iteration, cost: pt.f, x: &pt.x });
                return stop;
            }
        }
    }
}

/// Why a fit stopped, and the reason's words.
type Stop = (Termination, &'static str);

/// Where a fit stands: the current point, its residuals, its cost and (when `jac_at_x`) its
/// Jacobian.
struct Point {
    x: Vec<f64>,
    r: Vec<f64>,
    jac: DMatrix<f64>,
    f: f64,
    evaluations: usize,
    /// A problem with a joint pass (residuals and Jacobian for little more than the Jacobian)
    /// gets both at every trial point that follows an accepted step or starts the fit: nearly
    /// every such point is accepted, and its Jacobian is then the next iteration's, computed
    /// without a second pass. After a rejection, trials take residuals alone until a step is
    /// accepted again (and the Jacobian then takes its own pass).
    joint: bool,
    /// Whether `jac` holds the Jacobian at `x`.
    jac_at_x: bool,
    /// Whether the next trial takes the Jacobian with the residuals.
    speculate: bool,
}

impl Point {
    /// The fit's start at `x0` (`any_free`: whether any parameter is free).
    fn start<P: LeastSquares>(p: &P, x0: &[f64], any_free: bool) -> Self {
        let (m, n) = (p.n_residuals(), p.n_params());
        let x = x0.to_vec();
        let mut r = vec![0.0; m];
        let joint = p.joint_pass() && any_free;
        let mut jac = DMatrix::<f64>::zeros(if joint { m } else { 0 }, if joint { n } else { 0 });
        if joint {
            p.residuals_and_jacobian(&x, &mut r, &mut jac);
        } else {
            p.residuals(&x, &mut r);
        }
        let f = half_sq(&r);
        Point { x, r, jac, f, evaluations: 1, joint, jac_at_x: joint, speculate: joint }
    }

    /// The cost at the trial point `x + delta` (residuals into `w.r_new`, and the Jacobian into
    /// `jac` when speculating).
    fn trial<P: LeastSquares>(&mut self, p: &P, w: &mut Work) -> f64 {
        for (k, &c) in w.free.iter().enumerate() {
            w.x_new[c] = self.x[c] + w.delta[k];
        }
        if self.speculate {
            p.residuals_and_jacobian(&w.x_new, &mut w.r_new, &mut self.jac);
        } else {
            p.residuals(&w.x_new, &mut w.r_new);
        }
        self.evaluations += 1;
        half_sq(&w.r_new)
    }

    /// Moves to the trial point, whose cost is `f_new`.
    fn accept(&mut self, w: &mut Work, f_new: f64) {
        self.jac_at_x = self.speculate;
        self.speculate = self.joint;
        std::mem::swap(&mut self.x, &mut w.x_new);
        std::mem::swap(&mut self.r, &mut w.r_new);
        self.f = f_new;
    }

    fn report(self, iterations: usize, termination: Termination, reason: &str) -> Report {
        Report { x: self.x, cost: self.f, iterations, evaluations: self.evaluations, termination, reason: reason.to_owned(), covariance: None }
    }
}

/// The damping: λ, Nielsen's ν, and the fixed factor (None: Nielsen's rule).
struct Damper {
    lambda: f64,
    nu: f64,
    factor: Option<f64>,
}

impl Damper {
    fn new(lm: &LevenbergMarquardt) -> Self {
        let lambda = if lm.initial_lambda.is_finite() && lm.initial_lambda > 0.0 { lm.initial_lambda } else { 1e-3 };
        let factor = match lm.damping {
            Damping::Factor(b) if b.is_finite() && b > 1.0 => Some(b),
            Damping::Factor(_) => Some(10.0),
            Damping::Nielsen => None,
        };
        Damper { lambda, nu: 2.0, factor }
    }
}

/// A fit's work buffers over its free parameters, allocated once.
struct Work {
    free: Vec<usize>,
    /// JᵀJ over the free parameters.
    a: DMatrix<f64>,
    /// A + λD, then its Cholesky factor.
    chol: DMatrix<f64>,
    /// Jᵀr.
    g: Vec<f64>,
    /// D: running max of diag(A).
    scale: Vec<f64>,
    /// The floor of D's entries in the damping (from `scale` at this iteration).
    scale_floor: f64,
    /// The sparse normal equations' scratch.
    sparse: SparseRows,
    delta: Vec<f64>,
    /// λD, floored.
    damping: Vec<f64>,
    x_new: Vec<f64>,
    r_new: Vec<f64>,
}

impl Work {
    fn new(free: Vec<usize>, x: &[f64], m: usize) -> Self {
        let nf = free.len();
        Work {
            free,
            a: DMatrix::zeros(nf, nf),
            chol: DMatrix::zeros(nf, nf),
            g: vec![0.0; nf],
            scale: vec![0.0; nf],
            scale_floor: 0.0,
            sparse: SparseRows::default(),
            delta: vec![0.0; nf],
            damping: vec![0.0; nf],
            x_new: x.to_vec(),
            r_new: vec![0.0; m],
        }
    }
}

/// Scale-free gradient test statistic at cost `f`: max_k |cos∠(r, J_k)| from `a` = JᵀJ and
/// `g` = Jᵀr over the free parameters.
fn gradient_cosine(a: &DMatrix<f64>, g: &[f64], f: f64) -> f64 {
    let rnorm = (2.0 * f).sqrt();
    let mut gcos: f64 = 0.0;
    for k in 0..g.len() {
        let cn = a[(k, k)].sqrt();
        if cn > 0.0 {
            gcos = gcos.max(g[k].abs() / (cn * rnorm));
        }
    }
    gcos
}

/// Raises the damping scale D to the running maximum of diag(A); returns the floor under which
/// a scale counts as that floor (1e-15 of the largest).
fn update_scale(scale: &mut [f64], a: &DMatrix<f64>) -> f64 {
    let mut dmax: f64 = 0.0;
    for k in 0..scale.len() {
        scale[k] = scale[k].max(a[(k, k)]);
        dmax = dmax.max(scale[k]);
    }
    (dmax * 1e-15).max(f64::MIN_POSITIVE)
}

/// Solves (A + diag(damping)) δ = −g into `delta` by Cholesky (`chol` its work matrix), or by SVD
/// when the factorisation fails; false when neither gives a finite step.
fn damped_step(a: &DMatrix<f64>, g: &[f64], damping: &[f64], chol: &mut DMatrix<f64>, delta: &mut [f64]) -> bool {
    let nf = g.len();
    for k in 0..nf {
        for i in k..nf {
            chol[(i, k)] = a[(i, k)];
        }
        chol[(k, k)] += damping[k];
    }
    let mut solved = cholesky_in_place(chol);
    if solved {
        for k in 0..nf {
            delta[k] = -g[k];
        }
        cholesky_solve(chol, delta);
        solved = delta.iter().all(|v| v.is_finite());
    }
    if !solved {
        let mut damped = a.clone();
        for k in 0..nf {
            damped[(k, k)] += damping[k];
        }
        let neg_g: Vec<f64> = g.iter().map(|v| -v).collect();
        solved = svd_solve(&damped, &neg_g, delta);
    }
    solved
}

/// The quadratic model's predicted cost reduction ½ δᵀ(λDδ − g) for the step `delta`, and
/// whether the step is below `xtol` relative to the free parameters of `x`.
fn predicted_reduction(delta: &[f64], damping: &[f64], g: &[f64], x: &[f64], free: &[usize], xtol: f64) -> (f64, bool) {
    let mut pred = 0.0;
    let mut dnorm2 = 0.0;
    let mut xnorm2 = 0.0;
    for k in 0..delta.len() {
        pred += delta[k] * (damping[k] * delta[k] - g[k]);
        dnorm2 += delta[k] * delta[k];
        xnorm2 += x[free[k]] * x[free[k]];
    }
    (0.5 * pred, dnorm2.sqrt() <= xtol * (xnorm2.sqrt() + xtol))
}

/// λ after an accepted step with gain ratio `rho`: divided by the fixed factor, or Nielsen's
/// update; never below the smallest positive number.
fn lambda_after_accept(factor: Option<f64>, lambda: f64, rho: f64) -> f64 {
    let next = match factor {
        Some(beta) => lambda / beta,
        None => {
            let t = 2.0 * rho - 1.0;
            lambda * (1.0 - t * t * t).max(1.0 / 3.0)
        }
    };
    next.max(f64::MIN_POSITIVE)
}

/// Covariance of the least-squares estimate at `x`: `σ²·(JᵀJ)⁺` over the free parameters with
/// `σ² = 2·cost / (m − n_free)` (the residual variance), embedded in an `n × n` matrix whose
/// rows and columns for fixed parameters are zero.
///
/// The pseudo-inverse is formed from the SVD of the free Jacobian columns, `J = UΣVᵀ`, as
/// `V·Σ⁻²·Vᵀ`, dropping singular values with `σ_i² < 1e-10·σ_max²` — the same truncation as a
/// pseudo-inverse of `JᵀJ` with relative tolerance 1e-10, without squaring the condition number.
/// Caveat of the pseudo-inverse convention: a direction that the data do not determine at all
/// gets *zero* variance, not infinite variance; check identifiability separately.
///
/// Returns `None` if there are no more residuals than free parameters, or if the cost or the
/// Jacobian at `x` is not finite.
pub fn covariance<P: LeastSquares>(p: &P, x: &[f64], fixed: &[bool]) -> Option<DMatrix<f64>> {
    match Scaled::at(p, x, fixed) {
        Ok(s) => s.classical(),
        Err(early) => early,
    }
}

/// The cluster-robust ("sandwich", CR1) covariance of the least-squares estimate at `x` for
/// residuals that come in clusters sharing an error: `cluster[i]` is residual i's cluster.
/// (JᵀJ)⁺ · Σ_g (J_gᵀ r_g)(J_gᵀ r_g)ᵀ · (JᵀJ)⁺, scaled by G/(G − 1) · (m − 1)/(m − p) for G
/// clusters, m residuals and p free parameters; the pseudo-inverse as in [`covariance`]. Unlike
/// [`covariance`] it does not assume independent residuals of one variance. `None` where
/// [`covariance`] is, or with fewer than two clusters.
pub fn cluster_covariance<P: LeastSquares>(p: &P, x: &[f64], fixed: &[bool], cluster: &[usize]) -> Option<DMatrix<f64>> {
    covariances(p, x, fixed, Some(cluster)).1
}

/// [`covariance`] and, given the clusters, [`cluster_covariance`] from one evaluation of the
/// residuals and the Jacobian.
pub fn covariances<P: LeastSquares>(p: &P, x: &[f64], fixed: &[bool], cluster: Option<&[usize]>) -> (Option<DMatrix<f64>>, Option<DMatrix<f64>>) {
    let groups = cluster.filter(|c| c.len() == p.n_residuals()).map(|c| (c, c.iter().copied().max().map_or(0, |v| v + 1))).filter(|(_, g)| *g >= 2);
    match Scaled::at(p, x, fixed) {
        Ok(s) => (s.classical(), groups.and_then(|(c, g)| s.cluster_robust(c, g))),
        Err(early) => (early.clone(), groups.and(early)),
    }
}

/// What both covariances start from: the free parameters of `fixed`, and at `x` the residuals
/// and the free Jacobian columns scaled to unit norm (so that parameters in mm and in rad do not
/// spoil the conditioning), with the norms to undo it.
struct Scaled {
    n: usize,
    free: Vec<usize>,
    norms: Vec<f64>,
    jf: DMatrix<f64>,
    r: Vec<f64>,
    cost: f64,
}

impl Scaled {
    /// `Err` holds what a covariance is without evaluating anything further: zero with no free
    /// parameter, `None` with too few residuals or a non-finite cost or Jacobian.
    fn at<P: LeastSquares>(p: &P, x: &[f64], fixed: &[bool]) -> Result<Scaled, Option<DMatrix<f64>>> {
        let n = p.n_params();
        let m = p.n_residuals();
        if x.len() != n {
            return Err(None);
        }
        let free = free_indices(fixed, n);
        let nf = free.len();
        if nf == 0 {
            return Err(Some(DMatrix::<f64>::zeros(n, n)));
        }
        if m <= nf {
            return Err(None);
        }
        let mut r = vec![0.0; m];
        p.residuals(x, &mut r);
        let cost = half_sq(&r);
        if !cost.is_finite() {
            return Err(None);
        }
        let mut jac = DMatrix::<f64>::zeros(m, n);
        p.jacobian(x, &mut jac);
        let norms: Vec<f64> = free.iter().map(|&k| jac.column(k).norm().max(1e-300)).collect();
        let jf = DMatrix::from_fn(m, nf, |i, k| jac[(i, free[k])] / norms[k]);
        if jf.iter().any(|v| !v.is_finite()) {
            return Err(None);
        }
        Ok(Scaled { n, free, norms, jf, r, cost })
    }

    /// The SVD of the scaled Jacobian: Vᵀ and the singular values, with σ_max² (None when the
    /// decomposition gives no Vᵀ).
    fn svd(&self) -> Option<(DMatrix<f64>, nalgebra::DVector<f64>, f64)> {
        let svd = self.jf.clone().svd(false, true);
        let vt = svd.v_t?;
        let smax2 = svd.singular_values.iter().map(|v| v * v).fold(0.0, f64::max);
        Some((vt, svd.singular_values, smax2))
    }

    /// σ²·(JᵀJ)⁺, see [`covariance`].
    fn classical(&self) -> Option<DMatrix<f64>> {
        let (free, norms, nf) = (&self.free, &self.norms, self.free.len());
        let mut out = DMatrix::<f64>::zeros(self.n, self.n);
        let sigma2 = 2.0 * self.cost / (self.r.len() - nf) as f64;
        let (vt, s, smax2) = self.svd()?;
        if !(smax2 > 0.0) {
            return Some(out);
        }
        for (i, &si) in s.iter().enumerate() {
            let s2 = si * si;
            if s2 < 1e-10 * smax2 {
                continue;
            }
            let w = sigma2 / s2;
            for a in 0..nf {
                let va = vt[(i, a)] * w / norms[a];
                for b in 0..nf {
                    out[(free[a], free[b])] += va * vt[(i, b)] / norms[b];
                }
            }
        }
        Some(out)
    }

    /// The sandwich over `g` clusters, see [`cluster_covariance`].
    fn cluster_robust(&self, cluster: &[usize], g: usize) -> Option<DMatrix<f64>> {
        let (free, norms, nf, m) = (&self.free, &self.norms, self.free.len(), self.r.len());
        let mut out = DMatrix::<f64>::zeros(self.n, self.n);
        // The bread: the pseudo-inverse of JᵀJ from the SVD of J (small singular values dropped).
        let (vt, s, smax2) = self.svd()?;
        if !(smax2 > 0.0) {
            return Some(out);
        }
        let mut bread = DMatrix::<f64>::zeros(nf, nf);
        for (i, &si) in s.iter().enumerate() {
            let s2 = si * si;
            if s2 >= 1e-10 * smax2 {
                let row = vt.row(i);
                bread += row.transpose() * row / s2;
            }
        }
        // The meat: the outer products of each cluster's score.
        let mut scores = DMatrix::<f64>::zeros(g, nf);
        for i in 0..m {
            for k in 0..nf {
                scores[(cluster[i], k)] += self.jf[(i, k)] * self.r[i];
            }
        }
        let meat = scores.transpose() * &scores;
        let scale = g as f64 / (g - 1) as f64 * (m - 1) as f64 / (m - nf) as f64;
        let v = &bread * meat * &bread * scale;
        for a in 0..nf {
            for b in 0..nf {
                out[(free[a], free[b])] = v[(a, b)] / (norms[a] * norms[b]);
            }
        }
        Some(out)
    }
}

#[cfg(test)]
mod tests {
    use super::super::NoObserver;
    use super::*;

    /// y = a·exp(−b·t) + c, noiseless.
    struct ExpDecay {
        t: Vec<f64>,
        y: Vec<f64>,
    }
    impl ExpDecay {
        fn new(truth: [f64; 3]) -> Self {
            let t: Vec<f64> = (0..40).map(|i| i as f64 * 0.1).collect();
            let y = t.iter().map(|&t| truth[0] * (-truth[1] * t).exp() + truth[2]).collect();
            ExpDecay { t, y }
        }
    }
    impl LeastSquares for ExpDecay {
        fn n_params(&self) -> usize {
            3
        }
        fn n_residuals(&self) -> usize {
            self.t.len()
        }
        fn residuals(&self, x: &[f64], r: &mut [f64]) {
            for i in 0..self.t.len() {
                r[i] = x[0] * (-x[1] * self.t[i]).exp() + x[2] - self.y[i];
            }
        }
    }

    struct Rosen;
    impl LeastSquares for Rosen {
        fn n_params(&self) -> usize {
            2
        }
        fn n_residuals(&self) -> usize {
            2
        }
        fn residuals(&self, x: &[f64], r: &mut [f64]) {
            r[0] = 10.0 * (x[1] - x[0] * x[0]);
            r[1] = 1.0 - x[0];
        }
        fn jacobian(&self, x: &[f64], j: &mut DMatrix<f64>) {
            j[(0, 0)] = -20.0 * x[0];
            j[(0, 1)] = 10.0;
            j[(1, 0)] = -1.0;
            j[(1, 1)] = 0.0;
        }
    }

    /// y = a + b·t with deterministic pseudo-noise.
    struct Linear {
        t: Vec<f64>,
        y: Vec<f64>,
    }
    impl Linear {
        fn new() -> Self {
            let t: Vec<f64> = (0..25).map(|i| i as f64 * 0.2 - 1.0).collect();
            let y = t.iter().enumerate().map(|(i, &t)| 1.0 + 2.0 * t + 0.05 * ((i * 7 % 11) as f64 - 5.0) / 5.0).collect();
            Linear { t, y }
        }
    }
    impl LeastSquares for Linear {
        fn n_params(&self) -> usize {
            2
        }
        fn n_residuals(&self) -> usize {
            self.t.len()
        }
        fn residuals(&self, x: &[f64], r: &mut [f64]) {
            for i in 0..self.t.len() {
                r[i] = x[0] + x[1] * self.t[i] - self.y[i];
            }
        }
    }

    #[test]
    fn exp_decay_noiseless() {
        let truth = [2.5, 1.3, 0.4];
        let p = ExpDecay::new(truth);
        let rep = LevenbergMarquardt::default().minimize(&p, &[1.0, 0.5, 0.0], &[], &mut NoObserver);
        assert!(rep.converged(), "{rep:?}");
        for k in 0..3 {
            assert!((rep.x[k] - truth[k]).abs() < 1e-9, "{:?} vs {truth:?}", rep.x);
        }
    }

    #[test]
    fn rosenbrock() {
        let mut hist = super::super::History::default();
        let rep = LevenbergMarquardt::default().minimize(&Rosen, &[-1.2, 1.0], &[false, false], &mut hist);
        assert!(rep.converged(), "{rep:?}");
        assert!((rep.x[0] - 1.0).abs() < 1e-8 && (rep.x[1] - 1.0).abs() < 1e-8, "{rep:?}");
        assert!(!hist.cost.is_empty());
        assert!(hist.cost.windows(2).all(|w| w[1] <= w[0]), "costs must not increase");
    }

    /// The termination says why, and `converged` follows from it.
    #[test]
    fn termination_says_why_it_stopped() {
        let rep = LevenbergMarquardt::budget(3).minimize(&Rosen, &[-1.2, 1.0], &[false, false], &mut NoObserver);
        assert_eq!(rep.termination, Termination::Budget, "{rep:?}");
        assert!(!rep.converged() && rep.reason == "maximum number of iterations reached");
        let rep = LevenbergMarquardt::default().minimize(&Rosen, &[-1.2, 1.0], &[false, false], &mut NoObserver);
        assert!(rep.termination.converged() && rep.converged(), "{rep:?}");
        let rep = LevenbergMarquardt::default().minimize(&Rosen, &[-1.2, 1.0], &[true, true], &mut NoObserver);
        assert_eq!(rep.termination, Termination::NothingToDo);
    }

    #[test]
    fn adjustment_factor_schedule_converges() {
        let lm = LevenbergMarquardt { damping: Damping::Factor(10.0), initial_lambda: 1e-2, ftol: 1e-10, xtol: 1e-10, ..Default::default() };
        let truth = [2.5, 1.3, 0.4];
        let rep = lm.minimize(&ExpDecay::new(truth), &[1.0, 0.5, 0.0], &[], &mut NoObserver);
        assert!(rep.converged(), "{rep:?}");
        for k in 0..3 {
            assert!((rep.x[k] - truth[k]).abs() < 1e-7, "{:?} vs {truth:?}", rep.x);
        }
        let mut hist = super::super::History::default();
        let rep = lm.minimize(&Rosen, &[-1.2, 1.0], &[], &mut hist);
        assert!((rep.x[0] - 1.0).abs() < 1e-6 && (rep.x[1] - 1.0).abs() < 1e-6, "{rep:?}");
        assert!(hist.cost.windows(2).all(|w| w[1] <= w[0]), "costs must not increase");
    }

    #[test]
    fn fixed_parameters_untouched() {
        let truth = [2.5, 1.3, 0.4];
        let p = ExpDecay::new(truth);
        // Fixed at the true value: the others are recovered.
        let rep = LevenbergMarquardt::default().minimize(&p, &[1.0, 0.5, 0.4], &[false, false, true], &mut NoObserver);
        assert_eq!(rep.x[2].to_bits(), 0.4f64.to_bits());
        assert!((rep.x[0] - 2.5).abs() < 1e-9 && (rep.x[1] - 1.3).abs() < 1e-9, "{rep:?}");
        // Fixed at a wrong value: stays there, bit for bit.
        let rep = LevenbergMarquardt::default().minimize(&p, &[1.0, 0.777, 0.0], &[false, true, false], &mut NoObserver);
        assert_eq!(rep.x[1].to_bits(), 0.777f64.to_bits());
        assert!(rep.cost > 0.0);
    }

    #[test]
    fn linear_covariance_matches_closed_form() {
        let p = Linear::new();
        let rep = LevenbergMarquardt::default().minimize(&p, &[0.0, 0.0], &[], &mut NoObserver);
        assert!(rep.converged(), "{rep:?}");
        let cov = covariance(&p, &rep.x, &[]).unwrap();
        let m = p.t.len();
        let xm = DMatrix::from_fn(m, 2, |i, k| if k == 0 { 1.0 } else { p.t[i] });
        let sigma2 = 2.0 * rep.cost / (m - 2) as f64;
        let expect = (xm.transpose() * &xm).try_inverse().unwrap() * sigma2;
        for i in 0..2 {
            for j in 0..2 {
                let rel = (cov[(i, j)] - expect[(i, j)]).abs() / expect[(i, i)].abs().max(1e-300);
                assert!(rel < 1e-6, "cov {cov} expect {expect}");
            }
        }
        // Fixed intercept: zero row/column, slope variance from the one-column design.
        let cov = covariance(&p, &rep.x, &[true, false]).unwrap();
        assert_eq!(cov[(0, 0)], 0.0);
        assert_eq!(cov[(0, 1)], 0.0);
        assert!(cov[(1, 1)] > 0.0);
    }

    #[test]
    fn cluster_covariance_counts_shared_errors() {
        // Deterministic scrambled values in [-1, 1].
        let h = |k: usize| ((k as f64 * 12.9898).sin() * 43_758.545_3).fract();
        let (g, m) = (60, 10);
        // y = a + b·t with t constant within clusters of 10 and an error shared by each cluster.
        let t: Vec<f64> = (0..g * m).map(|i| h(i / m + 1000)).collect();
        let y: Vec<f64> = (0..g * m).map(|i| 1.0 + 2.0 * t[i] + h(i / m + 5000) + 0.2 * h(i + 9000)).collect();
        let p = Linear { t, y };
        let x = LevenbergMarquardt::default().minimize(&p, &[0.0, 0.0], &[], &mut NoObserver).x;
        let classic = covariance(&p, &x, &[]).unwrap();
        let clusters: Vec<usize> = (0..g * m).map(|i| i / m).collect();
        let robust = cluster_covariance(&p, &x, &[], &clusters).unwrap();
        // The slope's regressor is shared by each cluster, and so is most of the error: its
        // variance is several times the one that assumes independent rows.
        assert!(robust[(1, 1)] > 4.0 * classic[(1, 1)], "{robust} {classic}");
        // One cluster per residual: close to the classical covariance (homoscedastic errors).
        let single: Vec<usize> = (0..g * m).collect();
        let hc = cluster_covariance(&p, &x, &[], &single).unwrap();
        assert!((hc[(1, 1)] / classic[(1, 1)] - 1.0).abs() < 0.5, "{hc} {classic}");
        assert!(cluster_covariance(&p, &x, &[], &vec![0; g * m]).is_none());
    }

    /// Residuals that are NaN for x > 2: Gauss–Newton steps on atan overshoot into the NaN region,
    /// and the solver must reject those steps, not panic.
    struct NanWall;
    impl LeastSquares for NanWall {
        fn n_params(&self) -> usize {
            1
        }
        fn n_residuals(&self) -> usize {
            1
        }
        fn residuals(&self, x: &[f64], r: &mut [f64]) {
            r[0] = if x[0] > 2.0 { f64::NAN } else { (x[0] - 1.5).atan() };
        }
    }

    #[test]
    fn nan_cost_rejected() {
        let rep = LevenbergMarquardt { initial_lambda: 1e-9, ..Default::default() }.minimize(&NanWall, &[-5.0], &[], &mut NoObserver);
        assert!((rep.x[0] - 1.5).abs() < 1e-9, "{rep:?}");
        assert!(rep.cost.is_finite());
    }
}
