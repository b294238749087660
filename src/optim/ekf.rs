//! Extended Kalman filter for *static* parameter estimation from scalar observations.
//!
//! The state is the parameter vector itself, with a random-walk process model `x_{k+1} = x_k + w`,
//! `w ~ N(0, q·I)` on the free parameters (a small `q` keeps the filter from becoming
//! overconfident and lets it track mismodelling; `q = 0` gives recursive least squares).
//! Each scalar observation `z_i = h_i(x) + v`, `v ~ N(0, r)`, is processed as:
//!
//! ```text
//! P ← P + q·I_free                        (predict)
//! y = z_i − h_i(x),  H = ∂h_i/∂x          (innovation, linearised at the current x)
//! s = H·P·Hᵀ + r,    K = P·Hᵀ / s         (scalar innovation variance, gain)
//! x ← x + K·y
//! P ← (I − K·H)·P·(I − K·H)ᵀ + r·K·Kᵀ      (Joseph form)
//! P ← ½(P + Pᵀ)                           (symmetry enforcement)
//! ```
//!
//! The Joseph form stays positive semi-definite for any gain and is robust to round-off.
//! Because `H` is a single row, the product is evaluated exactly with rank-one updates in
//! O(n²) per observation and no allocation: with `u = P·Hᵀ`,
//! `(I − KH)P = P − K·uᵀ`, then `(I − KH)P(I − KH)ᵀ = (P − K·uᵀ) − w·Kᵀ` with `w = u − s₀·K`,
//! `s₀ = H·P·Hᵀ`.
//!
//! An *epoch* processes the observations listed in `order` once. After every epoch the cost
//! `½ Σ_{i∈order} (z_i − h_i(x))²` is evaluated, an [`Event`] is emitted, and the run stops when
//! the relative cost change falls below `tol`.
//!
//! Observations whose innovation, gradient or innovation variance is not finite are skipped
//! (the state is left unchanged), so a NaN prediction never corrupts the filter.
//!
//! A per-observation [`ObservationHook`] ([`Ekf::run_with`]) can add a term of its own to every
//! prediction, `ẑ_i = h_i(x) + c_i`, and receives every innovation `y = z_i − h_i(x) − c_i`:
//! a learned correction trained online from the filter's innovations (the PSO-EKF-AWNN method)
//! uses it. The hook's term does not depend on `x`, so `H` is unchanged; the epoch cost includes it.
//!
//! Caveat: running several epochs re-uses the same data, so `P` keeps shrinking roughly like
//! 1/epochs (the data are counted once per epoch). With one epoch, a diffuse prior and `q ≈ 0`,
//! `P` equals the least-squares covariance `r·(JᵀJ)⁻¹`.

use nalgebra::{DMatrix, DVector};

use super::util::{free_indices, sanitize};
use super::{Event, Observations, Observer, Report, Termination};

const METHOD: &str = "ekf";

/// Adds a term to each predicted observation and learns from the innovations (see the module docs).
pub trait ObservationHook {
    /// The term added to observation `i`'s prediction (units of the observation).
    fn offset(&self, i: usize) -> f64;
    /// The innovation `y = z_i − h_i(x) − offset(i)` of an update that was applied (after the
    /// state update, which used the same `y`).
    fn innovation(&mut self, i: usize, y: f64);
    /// Called after every epoch, before the epoch cost is evaluated.
    fn end_epoch(&mut self) {}
}

/// No term, nothing learned: the plain filter.
pub struct NoHook;
impl ObservationHook for NoHook {
    fn offset(&self, _i: usize) -> f64 {
        0.0
    }
    fn innovation(&mut self, _i: usize, _y: f64) {}
}

/// Extended Kalman filter settings. See the module documentation.
#[derive(Clone, Debug, PartialEq)]
pub struct Ekf {
    /// Maximum number of passes over `order`.
    pub epochs: usize,
    /// Process-noise variance added to every free state before each measurement update.
    pub q: f64,
    /// Measurement-noise variance.
    pub r: f64,
    /// Initial variance per state. A single value applies to all states; missing entries repeat
    /// the last one; empty means 1.
    pub p0: Vec<f64>,
    /// Stop when the relative change of the epoch cost is below this.
    pub tol: f64,
}

impl Default for Ekf {
    fn default() -> Self {
        Ekf { epochs: 10, q: 0.0, r: 1.0, p0: vec![1.0], tol: 1e-9 }
    }
}

impl Ekf {
    /// Run the filter from `x0`. `fixed[k] == true` keeps `x[k] = x0[k]` with zero variance.
    /// `order` lists the observation indices processed in every epoch (repeats allowed).
    ///
    /// `Report::covariance` is the final `P` (zero rows/columns for fixed states);
    /// `Report::evaluations` counts calls to `predict`. `converged` means the relative
    /// cost change dropped below `tol` (or the cost reached zero) before `epochs` ran out.
    ///
    /// # Panics
    /// If `x0.len() != o.n_params()`.
    pub fn run<O: Observations>(&self, o: &O, x0: &[f64], fixed: &[bool], order: &[usize], obs: &mut dyn Observer) -> Report {
        self.run_with(o, x0, fixed, order, &mut NoHook, obs)
    }

    /// [`run`](Self::run) with a per-observation hook (see the module docs).
    pub fn run_with<O: Observations>(
        &self,
        o: &O,
        x0: &[f64],
        fixed: &[bool],
        order: &[usize],
        hook: &mut dyn ObservationHook,
        obs: &mut dyn Observer,
    ) -> Report {
        let n = o.n_params();
        assert_eq!(x0.len(), n, "x0 has {} entries, problem has {n} parameters", x0.len());
        let free = free_indices(fixed, n);
        let mut is_free = vec![false; n];
        for &k in &free {
            is_free[k] = true;
        }

        let mut x = x0.to_vec();
        let mut p = DMatrix::<f64>::zeros(n, n);
        for &k in &free {
            let v = self.p0.get(k).or(self.p0.last()).copied().unwrap_or(1.0);
            p[(k, k)] = v;
        }
        let q = if self.q.is_finite() { self.q.max(0.0) } else { 0.0 };
        let r = self.r;

        let mut buffers = UpdateBuffers::new(n);

        let mut evaluations = order.len();
        let cost_of = |x: &[f64], hook: &dyn ObservationHook| {
            sanitize(
                0.5 * order
                    .iter()
                    .map(|&i| {
                        let e = o.measured(i) - o.predict(x, i) - hook.offset(i);
                        e * e
                    })
                    .sum::<f64>(),
            )
        };
        let mut cost = cost_of(&x, hook);
        let mut iterations = 0;
        let mut termination = Termination::Budget;
        let mut reason = String::from("maximum number of epochs reached");
        let mut skipped = 0usize;

        if free.is_empty() || order.is_empty() {
            return Report {
                x,
                cost,
                iterations,
                evaluations,
                termination: Termination::NothingToDo,
                reason: "nothing to estimate (no free parameters or no observations)".into(),
                covariance: Some(p),
            };
        }

        while iterations < self.epochs {
            iterations += 1;
            for &i in order {
                if q > 0.0 {
                    for &k in &free {
                        p[(k, k)] += q;
                    }
                }
                let y = o.measured(i) - o.predict(&x, i) - hook.offset(i);
                evaluations += 1;
                if !buffers.update(o, Innovation { row: i, value: y, variance: r }, &mut x, &mut p, (&free, &is_free)) {
                    skipped += 1;
                    continue;
                }
                hook.innovation(i, y);
                symmetrize(&mut p);
            }

            hook.end_epoch();
            let new_cost = cost_of(&x, hook);
            evaluations += order.len();
            obs.observe(&Event { method: METHOD, iteration: iterations, cost: new_cost, x: &x });
            let change = (cost - new_cost).abs();
            let rel = if cost.is_finite() && new_cost.is_finite() { change / cost.abs().max(f64::MIN_POSITIVE) } else { f64::INFINITY };
            cost = new_cost;
            if cost == 0.0 {
                termination = Termination::ZeroCost;
                reason = "zero cost".into();
                break;
            }
            if rel < self.tol {
                termination = Termination::CostTolerance;
                reason = "relative cost change below tol".into();
                break;
            }
        }
        if skipped > 0 {
            reason.push_str(&format!(" ({skipped} non-finite observation updates skipped)"));
        }

        Report { x, cost, iterations, evaluations, termination, reason, covariance: Some(p) }
    }
}

/// The work buffers of one observation's update (an allocation-free inner loop).
struct UpdateBuffers {
    hrow: Vec<f64>,
    /// The observation's gradient over the free parameters.
    h: DVector<f64>,
    /// P·Hᵀ.
    u: DVector<f64>,
    gain: DVector<f64>,
    w: DVector<f64>,
}

/// One observation's innovation: its row, the reading less the prediction, and the reading's
/// variance.
#[derive(Clone, Copy)]
struct Innovation {
    row: usize,
    value: f64,
    variance: f64,
}

impl UpdateBuffers {
    fn new(n: usize) -> Self {
        UpdateBuffers { hrow: vec![0.0; n], h: DVector::zeros(n), u: DVector::zeros(n), gain: DVector::zeros(n), w: DVector::zeros(n) }
    }

    /// Updates `x` and `p` by an observation's innovation (its reading variance with it), in
    /// Joseph form; false, with nothing changed, when the innovation, the gradient or the
    /// innovation variance is not finite.
    fn update<O: Observations>(&mut self, o: &O, inn: Innovation, x: &mut [f64], p: &mut DMatrix<f64>, (free, is_free): (&[usize], &[bool])) -> bool {
        let Innovation { row: i, value: y, variance: r } = inn;
        let (h, u, gain, w) = (&mut self.h, &mut self.u, &mut self.gain, &mut self.w);
        o.gradient(x, i, &mut self.hrow);
        for k in 0..h.len() {
            h[k] = if is_free[k] { self.hrow[k] } else { 0.0 };
        }
        if !y.is_finite() || h.iter().any(|v| !v.is_finite()) {
            return false;
        }
        u.gemv(1.0, p, h, 0.0);
        let s0 = h.dot(u);
        let s = s0 + r;
        if !(s > 0.0 && s.is_finite()) {
            return false;
        }
        gain.copy_from(u);
        *gain /= s;
        for &k in free {
            x[k] += gain[k] * y;
        }
        // Joseph form via rank-one updates:
        // P ← P − K·uᵀ;  w = u − s₀·K;  P ← P − w·Kᵀ + r·K·Kᵀ = P + (r·K − w)·Kᵀ.
        p.ger(-1.0, gain, u, 1.0);
        w.copy_from(gain);
        *w *= r + s0;
        *w -= &*u; // w = r·K − (u − s₀·K)
        p.ger(1.0, w, gain, 1.0);
        true
    }
}

/// Makes `p` exactly symmetric (the mean of its two triangles).
fn symmetrize(p: &mut DMatrix<f64>) {
    let n = p.nrows();
    for a in 0..n {
        for b in a + 1..n {
            let m = 0.5 * (p[(a, b)] + p[(b, a)]);
            p[(a, b)] = m;
            p[(b, a)] = m;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::NoObserver;
    use super::*;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;
    use rand_distr::{Distribution, Normal};

    /// z = a + b·t + c·t² with Gaussian noise of standard deviation `sigma`.
    pub(crate) struct Poly {
        pub t: Vec<f64>,
        pub z: Vec<f64>,
    }
    impl Poly {
        pub fn new(truth: &[f64], m: usize, sigma: f64, seed: u64) -> Self {
            let mut rng = ChaCha8Rng::seed_from_u64(seed);
            let nd = Normal::new(0.0, sigma).unwrap();
            let t: Vec<f64> = (0..m).map(|i| -1.0 + 2.0 * i as f64 / (m - 1) as f64).collect();
            let z = t.iter().map(|&t| truth.iter().enumerate().map(|(k, c)| c * t.powi(k as i32)).sum::<f64>() + nd.sample(&mut rng)).collect();
            Poly { t, z }
        }
        pub fn design(&self, n: usize) -> DMatrix<f64> {
            DMatrix::from_fn(self.t.len(), n, |i, k| self.t[i].powi(k as i32))
        }
    }
    impl Observations for Poly {
        fn n_params(&self) -> usize {
            3
        }
        fn n_obs(&self) -> usize {
            self.t.len()
        }
        fn predict(&self, x: &[f64], i: usize) -> f64 {
            x[0] + x[1] * self.t[i] + x[2] * self.t[i] * self.t[i]
        }
        fn measured(&self, i: usize) -> f64 {
            self.z[i]
        }
        fn gradient(&self, _x: &[f64], i: usize, g: &mut [f64]) {
            g[0] = 1.0;
            g[1] = self.t[i];
            g[2] = self.t[i] * self.t[i];
        }
    }

    #[test]
    fn linear_model_matches_least_squares() {
        let sigma = 0.1;
        let p = Poly::new(&[0.7, -1.2, 0.5], 60, sigma, 3);
        let xm = p.design(3);
        let xtx = xm.transpose() * &xm;
        let xtx_inv = xtx.clone().try_inverse().unwrap();
        let ls = &xtx_inv * (xm.transpose() * DVector::from_column_slice(&p.z));
        let ls_cov = &xtx_inv * (sigma * sigma);

        let order: Vec<usize> = (0..p.t.len()).collect();
        let ekf = Ekf { epochs: 1, q: 1e-16, r: sigma * sigma, p0: vec![1e6], tol: 1e-12 };
        let rep = ekf.run(&p, &[0.0; 3], &[], &order, &mut NoObserver);
        for k in 0..3 {
            let rel = (rep.x[k] - ls[k]).abs() / ls[k].abs();
            assert!(rel < 1e-6, "x {:?} vs LS {ls}", rep.x);
        }
        let pm = rep.covariance.clone().unwrap();
        for a in 0..3 {
            for b in 0..3 {
                let rel = (pm[(a, b)] - ls_cov[(a, b)]).abs() / (ls_cov[(a, a)] * ls_cov[(b, b)]).sqrt();
                assert!(rel < 1e-4, "P {pm} vs LS cov {ls_cov}");
            }
            assert_eq!(pm[(a, a)], pm[(a, a)].abs());
        }
        assert!(pm.iter().zip(pm.transpose().iter()).all(|(a, b)| a == b), "P symmetric");

        // More epochs: the estimate stays at the LS solution and the run stops on tol.
        let ekf = Ekf { epochs: 50, tol: 1e-10, ..ekf };
        let mut hist = super::super::History::default();
        let rep = ekf.run(&p, &[0.0; 3], &[], &order, &mut hist);
        assert!(rep.converged() && rep.iterations < 50, "{rep:?}");
        assert_eq!(hist.cost.len(), rep.iterations);
        for k in 0..3 {
            assert!((rep.x[k] - ls[k]).abs() / ls[k].abs() < 1e-6);
        }
    }

    #[test]
    fn fixed_state_untouched() {
        let p = Poly::new(&[0.7, -1.2, 0.5], 40, 0.05, 5);
        let order: Vec<usize> = (0..p.t.len()).collect();
        let ekf = Ekf { epochs: 3, q: 0.0, r: 0.0025, p0: vec![100.0], tol: 1e-12 };
        let rep = ekf.run(&p, &[0.0, 0.0, 0.5], &[false, false, true], &order, &mut NoObserver);
        assert_eq!(rep.x[2].to_bits(), 0.5f64.to_bits());
        let pm = rep.covariance.clone().unwrap();
        for k in 0..3 {
            assert_eq!(pm[(2, k)], 0.0);
            assert_eq!(pm[(k, 2)], 0.0);
        }
        assert!((rep.x[0] - 0.7).abs() < 0.05 && (rep.x[1] + 1.2).abs() < 0.05, "{rep:?}");
    }

    struct NanObs;
    impl Observations for NanObs {
        fn n_params(&self) -> usize {
            1
        }
        fn n_obs(&self) -> usize {
            4
        }
        fn predict(&self, x: &[f64], i: usize) -> f64 {
            if i == 2 {
                f64::NAN
            } else {
                x[0]
            }
        }
        fn measured(&self, _i: usize) -> f64 {
            1.0
        }
        fn gradient(&self, _x: &[f64], _i: usize, g: &mut [f64]) {
            g[0] = 1.0;
        }
    }

    /// z = poly(t) + 0.3·sin(5t): a hook that learns the coefficient of sin(5t) from the
    /// innovations (one SGD step per observation) lets the filter recover the polynomial.
    struct SineHook<'a> {
        t: &'a [f64],
        k: f64,
        seen: usize,
        epochs: usize,
    }
    impl ObservationHook for SineHook<'_> {
        fn offset(&self, i: usize) -> f64 {
            self.k * (5.0 * self.t[i]).sin()
        }
        fn innovation(&mut self, i: usize, y: f64) {
            self.k += 0.2 * y * (5.0 * self.t[i]).sin();
            self.seen += 1;
        }
        fn end_epoch(&mut self) {
            self.epochs += 1;
        }
    }

    #[test]
    fn hook_term_is_learned_beside_the_states() {
        let truth = [0.7, -1.2, 0.5];
        let mut p = Poly::new(&truth, 80, 0.01, 8);
        for (z, t) in p.z.iter_mut().zip(&p.t) {
            *z += 0.3 * (5.0 * t).sin();
        }
        let order: Vec<usize> = (0..p.t.len()).collect();
        let ekf = Ekf { epochs: 30, q: 1e-6, r: 1e-4, p0: vec![10.0], tol: 0.0 };
        let plain = ekf.run(&p, &[0.0; 3], &[], &order, &mut NoObserver);
        let mut hook = SineHook { t: &p.t, k: 0.0, seen: 0, epochs: 0 };
        let rep = ekf.run_with(&p, &[0.0; 3], &[], &order, &mut hook, &mut NoObserver);
        assert_eq!((hook.seen, hook.epochs), (30 * 80, 30));
        assert!((hook.k - 0.3).abs() < 0.02, "learned {}", hook.k);
        let err = |x: &[f64]| x.iter().zip(&truth).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
        assert!(err(&rep.x) < 0.03 && err(&rep.x) < 0.3 * err(&plain.x), "with hook {:?}, plain {:?}", rep.x, plain.x);
        // The reported cost includes the hook's term.
        let direct = 0.5 * order.iter().map(|&i| (p.z[i] - p.predict(&rep.x, i) - hook.offset(i)).powi(2)).sum::<f64>();
        assert!((rep.cost - direct).abs() < 1e-12 * direct.max(1.0));
    }

    #[test]
    fn nan_observation_skipped() {
        let rep = Ekf { epochs: 2, q: 0.0, r: 0.01, p0: vec![10.0], tol: 0.0 }.run(&NanObs, &[0.0], &[], &[0, 1, 2, 3], &mut NoObserver);
        assert!(rep.x[0].is_finite() && (rep.x[0] - 1.0).abs() < 1e-2, "{rep:?}");
        assert!(rep.cost.is_infinite());
    }
}
