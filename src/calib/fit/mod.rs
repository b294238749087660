//! The calibration problem in the three shapes the optimisers take: least squares (LM),
//! sequential scalar observations (EKF, PF) and a bounded scalar cost (PSO, DE).
//! Residuals are in millimetres: measured minus predicted reading, one per reading value
//! (one per row for a cable length, three for a tracker's point).

pub mod floor;
pub mod gls;
pub mod identify;
pub mod noise_model;
pub mod robust;
pub mod weighting;

use crate::calib::effects::RowInputs;
use crate::calib::model::PULL_SCALE_MM;
use crate::calib::model::{CalibModel, ModelWork};
use crate::measurement::MAX_DIM;
use crate::optim::{Cost, LeastSquares, Observations};
use nalgebra::DMatrix;
use std::cell::RefCell;

thread_local! {
    static WORK: RefCell<Option<(usize, ModelWork)>> = const { RefCell::new(None) };
    static JAC: RefCell<Vec<f64>> = const { RefCell::new(Vec::new()) };
}

/// Runs `f` with a thread-local model workspace (hot loops allocate nothing after the first call).
fn with_work<R>(model: &CalibModel, f: impl FnOnce(&mut ModelWork) -> R) -> R {
    WORK.with(|cell| {
        let mut slot = cell.borrow_mut();
        let key = model as *const CalibModel as usize ^ model.chain.ops.len();
        if slot.as_ref().is_none_or(|(k, w)| *k != key || w.fk.values.len() != model.chain.ops.len() || w.jac.dparam.len() != model.n_chain()) {
            *slot = Some((key, model.work()));
        }
        f(&mut slot.as_mut().expect("set above").1)
    })
}

/// Readings at joint angles: the data a calibration fits.
#[derive(Clone, Debug)]
pub struct Samples {
    /// Joint angles, rad.
    pub q: Vec<Vec<f64>>,
    /// Measured readings, m: `dim` values per row, row after row (the cable length for a
    /// draw-wire; x, y, z for a tracker).
    pub y: Vec<f64>,
    /// Values per row ([`Measurement::dim`](crate::measurement::Measurement::dim)).
    pub dim: usize,
    /// What read the rows.
    pub measurement: crate::measurement::Measurement,
    /// What read the rows whose inputs say instrument 1 (a tracker's points or faces touched
    /// beside seated rows), if any; a narrower one's rows hold zeros after their values.
    pub also: Option<crate::measurement::Measurement>,
    /// What each row carries besides q and its reading (time, temperature, torques, backlash sides).
    pub inputs: Vec<RowInputs>,
    /// The square root of each value's weight in the fit, relative (about 1 for a typical
    /// value), or `None` for equal weights: a tracker's per-row standard deviations give them
    /// (see [`crate::calib::fit::weighting`]). Every residual the fit sees is scaled by it.
    pub w: Option<Vec<f64>>,
    /// The whitening of rows that share the joint angles' logging error in blocks
    /// ([`crate::calib::fit::gls`]): least-squares fits ([`ReadingFit`]) whiten their residuals by it. The
    /// sequential filters (EKF, PF) and [`Self::unweighted`] do not.
    pub gls: Option<crate::calib::fit::gls::Whitening>,
}

impl Samples {
    /// One-value readings (cable lengths) with no per-row inputs.
    pub fn new(q: Vec<Vec<f64>>, l: Vec<f64>) -> Self {
        Samples::readings(q, l, 1)
    }
    /// Readings of `dim` values per row with no per-row inputs: a draw-wire's lengths (1), a
    /// tracker's points (3) or poses (9).
    pub fn readings(q: Vec<Vec<f64>>, y: Vec<f64>, dim: usize) -> Self {
        use crate::measurement::Measurement;
        let m = [Measurement::Length, Measurement::Point, Measurement::Pose].into_iter().find(|m| m.dim() == dim).unwrap_or_default();
        Samples::of(m, q, y)
    }
    /// Readings of instrument `measurement` ([`Measurement::dim`](crate::measurement::Measurement::dim)
    /// values per row) with no per-row inputs.
    pub fn of(measurement: crate::measurement::Measurement, q: Vec<Vec<f64>>, y: Vec<f64>) -> Self {
        let dim = measurement.dim();
        debug_assert_eq!(q.len() * dim, y.len());
        let inputs = vec![RowInputs::default(); q.len()];
        Samples { q, y, dim, measurement, also: None, inputs, w: None, gls: None }
    }
    /// The values row `i` holds: its instrument's (a narrower second instrument's rows hold
    /// zeros after them).
    pub fn width(&self, i: usize) -> usize {
        match (self.inputs.get(i).map(|inp| inp.instrument), self.also) {
            (Some(1), Some(m)) => m.dim().min(self.dim),
            _ => self.dim,
        }
    }
    /// The instrument (0: the first, 1: the one beside it) that read row `i`.
    pub fn instrument(&self, i: usize) -> usize {
        self.inputs.get(i).map_or(0, |inp| inp.instrument.min(1))
    }
    /// The values of `r` (one per reading value, row after row, as residuals come) that the
    /// rows `rows` read by instrument `g` hold (a narrower instrument's zeros left out).
    pub fn values_of(&self, r: &[f64], g: usize, rows: impl Iterator<Item = usize>) -> Vec<f64> {
        rows.filter(|&i| self.instrument(i) == g).flat_map(|i| r[i * self.dim..i * self.dim + self.width(i)].iter().copied()).collect()
    }
    /// The rows `idx`.
    pub fn subset(&self, idx: &[usize]) -> Samples {
        Samples {
            q: idx.iter().map(|&i| self.q[i].clone()).collect(),
            y: idx.iter().flat_map(|&i| self.row(i).iter().copied()).collect(),
            dim: self.dim,
            measurement: self.measurement,
            also: self.also,
            inputs: idx.iter().map(|&i| self.inputs[i].clone()).collect(),
            w: self.w.as_ref().map(|w| idx.iter().flat_map(|&i| w[i * self.dim..(i + 1) * self.dim].iter().copied()).collect()),
            gls: self.gls.as_ref().map(|g| g.subset(idx)),
        }
    }
    /// The same readings with equal weights and no whitening: what the metrics judge (in mm,
    /// unweighted).
    pub fn unweighted(&self) -> Samples {
        Samples { w: None, gls: None, ..self.clone() }
    }
    /// The weight factor (square root of the relative weight) of value `k` (row-major).
    #[inline]
    pub fn weight(&self, k: usize) -> f64 {
        self.w.as_ref().map_or(1.0, |w| w[k])
    }
    /// The reading of row `i`.
    pub fn row(&self, i: usize) -> &[f64] {
        &self.y[i * self.dim..(i + 1) * self.dim]
    }
    /// Number of rows.
    pub fn len(&self) -> usize {
        self.q.len()
    }
    /// Whether there is no row.
    pub fn is_empty(&self) -> bool {
        self.q.is_empty()
    }
}

/// A model fitted to samples: one residual per reading value, row after row, each scaled by its
/// weight factor ([`Samples::w`]; mm as they are without weights), then one per known spacing of
/// the model's sockets ([`CalibModel::spacings`], mm), which no row carries.
pub struct ReadingFit<'a> {
    /// The model.
    pub model: &'a CalibModel,
    /// The samples it is fitted to.
    pub data: &'a Samples,
}

impl ReadingFit<'_> {
    /// The rows' residuals (mm, weighted as the fit sees them: [`Samples::w`]) at `x`, without
    /// the spacings'.
    pub fn residuals_mm(&self, x: &[f64]) -> Vec<f64> {
        let mut r = vec![0.0; self.data.y.len()];
        LeastSquares::residuals(self, x, &mut r);
        r
    }
}

impl LeastSquares for ReadingFit<'_> {
    fn n_params(&self) -> usize {
        self.model.n_params()
    }
    fn n_residuals(&self) -> usize {
        self.data.y.len() + self.model.n_block_residuals()
    }
    /// The rows' residuals, then the spacings' and the pulls' where `r` has room for them.
    fn residuals(&self, x: &[f64], r: &mut [f64]) {
        crate::progress::check_stop();
        let (d, ny, ns) = (self.data.dim, self.data.y.len(), self.model.n_spacing_residuals());
        let (r, blocks) = r.split_at_mut(ny);
        self.model.spacing_residuals(x, blocks);
        if blocks.len() > ns {
            self.model.pull_residuals(x, &mut blocks[ns..]);
        }
        let mut y = [0.0; MAX_DIM];
        with_work(self.model, |w| {
            for (i, ri) in r.chunks_mut(d).enumerate() {
                self.model.readings(x, &self.data.q[i], &self.data.inputs[i], w, &mut y[..d]);
                for (k, rk) in ri.iter_mut().enumerate() {
                    *rk = crate::units::to_mm(self.data.y[i * d + k] - y[k]) * self.data.weight(i * d + k);
                }
            }
        });
        if let Some(g) = &self.data.gls {
            g.apply(r);
        }
    }
    fn jacobian(&self, x: &[f64], j: &mut DMatrix<f64>) {
        self.jacobian_pass(x, j, None);
    }
    /// Where an instrument's reading is the same expression with and without its derivatives
    /// (a tracker's point), the readings of the Jacobian's pass are the residuals' bit for bit.
    /// (A cable length's derivative pass clamps the distance at 1 pm: it keeps two passes.)
    fn joint_pass(&self) -> bool {
        self.model.measurement.def().exact_grad_reading()
    }
    fn residuals_and_jacobian(&self, x: &[f64], r: &mut [f64], j: &mut DMatrix<f64>) {
        if self.joint_pass() {
            self.jacobian_pass(x, j, Some(r));
        } else {
            LeastSquares::residuals(self, x, r);
            self.jacobian(x, j);
        }
    }
}

impl ReadingFit<'_> {
    /// The Jacobian into `j` and, given `r`, the residuals from the same pass's readings.
    fn jacobian_pass(&self, x: &[f64], j: &mut DMatrix<f64>, mut r: Option<&mut [f64]>) {
        crate::progress::check_stop();
        let (n, d) = (self.model.n_params(), self.data.dim);
        // Column k of J starts at k·ld (column-major).
        let ld = j.nrows();
        assert!(ld >= self.data.y.len() && j.ncols() >= n, "the Jacobian needs a row per reading value and a column per parameter");
        // Rows are gathered in blocks of `BLOCK`, parameter-major, and written into J's columns
        // (column-major) one contiguous stretch per column: not one cache line per entry.
        const BLOCK: usize = 16;
        let mut g = vec![0.0; n * d];
        let mut block = vec![0.0; n * BLOCK * d];
        let mut y = [0.0; MAX_DIM];
        let js = j.as_mut_slice();
        with_work(self.model, |w| {
            for i0 in (0..self.data.len()).step_by(BLOCK) {
                let rows = BLOCK.min(self.data.len() - i0);
                let h = rows * d;
                for row in 0..rows {
                    let i = i0 + row;
                    self.model.readings_grad(x, &self.data.q[i], &self.data.inputs[i], w, &mut y[..d], &mut g);
                    if let Some(r) = r.as_deref_mut() {
                        for (k, rk) in r[i * d..(i + 1) * d].iter_mut().enumerate() {
                            *rk = crate::units::to_mm(self.data.y[i * d + k] - y[k]) * self.data.weight(i * d + k);
                        }
                    }
                    for c in 0..d {
                        let s = -crate::units::MM_PER_M * self.data.weight(i * d + c);
                        for k in 0..n {
                            block[k * h + row * d + c] = g[c * n + k] * s;
                        }
                    }
                }
                for k in 0..n {
                    js[k * ld + i0 * d..k * ld + i0 * d + h].copy_from_slice(&block[k * h..(k + 1) * h]);
                }
            }
        });
        let ny = self.data.y.len();
        // The spacings' rows where `j` has room for them (a Jacobian of the rows alone has not).
        let ns = self.model.n_spacing_residuals();
        if ns > 0 && ld >= ny + ns {
            let mut g = vec![0.0; n * ns];
            self.model.spacing_jacobian(x, &mut g);
            for (k, row) in g.chunks(n).enumerate() {
                for (c, v) in row.iter().enumerate() {
                    js[c * ld + ny + k] = *v;
                }
            }
            if let Some(r) = r.as_deref_mut().filter(|r| r.len() > ny) {
                self.model.spacing_residuals(x, &mut r[ny..]);
            }
        }
        // The pulls' rows likewise (an identifiability analysis of the rows and spacings has none).
        if !self.model.pulls.is_empty() && ld >= ny + ns + self.model.pulls.len() {
            for (i, p) in self.model.pulls.iter().enumerate() {
                for c in 0..n {
                    js[c * ld + ny + ns + i] = 0.0;
                }
                js[p.k * ld + ny + ns + i] = -PULL_SCALE_MM / p.std;
            }
            if let Some(r) = r.as_deref_mut().filter(|r| r.len() > ny + ns) {
                self.model.pull_residuals(x, &mut r[ny + ns..]);
            }
        }
        if let Some(g) = &self.data.gls {
            g.apply_rows(j);
            if let Some(r) = r {
                g.apply(&mut r[..ny]);
            }
        }
    }
}

/// The fit as sequential scalar observations: observation `i` is value `i % dim` of row `i / dim`.
impl Observations for ReadingFit<'_> {
    fn n_params(&self) -> usize {
        self.model.n_params()
    }
    fn n_obs(&self) -> usize {
        self.data.y.len()
    }
    fn predict(&self, x: &[f64], i: usize) -> f64 {
        crate::progress::check_stop();
        let d = self.data.dim;
        let (row, c) = (i / d, i % d);
        let mut y = [0.0; MAX_DIM];
        with_work(self.model, |w| self.model.readings(x, &self.data.q[row], &self.data.inputs[row], w, &mut y[..d]));
        crate::units::to_mm(y[c]) * self.data.weight(i)
    }
    fn measured(&self, i: usize) -> f64 {
        crate::units::to_mm(self.data.y[i]) * self.data.weight(i)
    }
    fn gradient(&self, x: &[f64], i: usize, g: &mut [f64]) {
        crate::progress::check_stop();
        let (n, d) = (self.model.n_params(), self.data.dim);
        let (row, c) = (i / d, i % d);
        if d == 1 {
            with_work(self.model, |w| self.model.length_grad(x, &self.data.q[row], &self.data.inputs[row], w, g));
        } else {
            // The row's whole Jacobian, in a reused buffer (the filters call this per value).
            JAC.with(|cell| {
                let mut jac = cell.borrow_mut();
                jac.resize(n * d, 0.0);
                let mut y = [0.0; MAX_DIM];
                with_work(self.model, |w| self.model.readings_grad(x, &self.data.q[row], &self.data.inputs[row], w, &mut y[..d], &mut jac));
                g.copy_from_slice(&jac[c * n..(c + 1) * n]);
            });
        }
        let s = crate::units::MM_PER_M * self.data.weight(i);
        g.iter_mut().for_each(|v| *v *= s);
    }
}

/// ½ Σ r² (mm²) over the free parameters only; the fixed ones keep the values of `base`.
pub struct FreeCost<'a> {
    /// The fit whose parameters are split into free and fixed.
    pub fit: ReadingFit<'a>,
    /// The full parameter vector the fixed parameters take their values from.
    pub base: Vec<f64>,
    /// Indices of the free parameters, in the order of the reduced vector.
    pub free: Vec<usize>,
}

impl FreeCost<'_> {
    /// The full parameter vector with the free parameters set to `xf`.
    pub fn expand(&self, xf: &[f64]) -> Vec<f64> {
        let mut x = self.base.clone();
        for (k, i) in self.free.iter().enumerate() {
            x[*i] = xf[k];
        }
        x
    }
}

impl Cost for FreeCost<'_> {
    fn dim(&self) -> usize {
        self.free.len()
    }
    fn cost(&self, xf: &[f64]) -> f64 {
        let x = self.expand(xf);
        let c = LeastSquares::cost(&self.fit, &x);
        if c.is_finite() {
            c
        } else {
            f64::INFINITY
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::calib::effects::{EffectBlock, EffectKind};
    use crate::calib::model::{DrawWireGuess, Placement};
    use crate::measurement::Measurement;
    use crate::optim::{LevenbergMarquardt, NoObserver};
    use crate::robot::Robot;
    use nalgebra::Vector3;

    /// The fit without its joint pass: residuals and Jacobian each in their own pass.
    struct TwoPasses<'a>(&'a ReadingFit<'a>);
    impl LeastSquares for TwoPasses<'_> {
        fn n_params(&self) -> usize {
            LeastSquares::n_params(self.0)
        }
        fn n_residuals(&self) -> usize {
            self.0.n_residuals()
        }
        fn residuals(&self, x: &[f64], r: &mut [f64]) {
            LeastSquares::residuals(self.0, x, r)
        }
        fn jacobian(&self, x: &[f64], j: &mut DMatrix<f64>) {
            self.0.jacobian(x, j)
        }
    }

    /// A tracker's joint pass gives the residuals and the Jacobian of the two passes bit for bit,
    /// and LM (which then takes it) the same fit.
    #[test]
    fn a_trackers_joint_pass_is_the_two_passes_bit_for_bit() {
        let robot = Robot::irb120();
        let guess = DrawWireGuess { exit_m: [0.8, 0.3, 0.05], offset_m: 0.12, tool_m: [0.06, 0.0, 0.0] };
        let tracker = Placement { measurement: Measurement::Point, own: vec![0.2, -0.1, 0.05, 0.03, -0.02, 0.6], tool: Vector3::new(0.01, 0.02, 0.08) };
        let mut model = CalibModel::dh(&robot, &guess, true).with_placement(&tracker);
        model.add_effect(EffectBlock::joint(EffectKind::Compliance, 1), 3600.0);
        let q: Vec<Vec<f64>> = (0..37).map(|i| (0..6).map(|j| ((i * 6 + j) as f64 * 0.37).sin() * 1.5).collect()).collect();
        let mut truth = model.nominal.clone();
        truth.iter_mut().enumerate().for_each(|(k, v)| *v += 1e-4 * ((k as f64) * 1.3).sin());
        let mut data = Samples::readings(q, vec![0.0; 37 * 3], 3);
        for (i, inp) in data.inputs.iter_mut().enumerate() {
            inp.torque = (0..6).map(|j| ((i + j) as f64).cos() * 20.0).collect();
        }
        let mut w = model.work();
        for i in 0..data.len() {
            let mut y = [0.0; MAX_DIM];
            model.readings(&truth, &data.q[i], &data.inputs[i], &mut w, &mut y[..3]);
            for c in 0..3 {
                data.y[i * 3 + c] = y[c] + 1e-6 * ((i * 3 + c) as f64).sin();
            }
        }
        let fit = ReadingFit { model: &model, data: &data };
        assert!(fit.joint_pass());
        let (m, n) = (fit.n_residuals(), LeastSquares::n_params(&fit));
        let (mut r1, mut r2) = (vec![0.0; m], vec![0.0; m]);
        let (mut j1, mut j2) = (DMatrix::zeros(m, n), DMatrix::zeros(m, n));
        fit.residuals_and_jacobian(&model.nominal, &mut r1, &mut j1);
        LeastSquares::residuals(&fit, &model.nominal, &mut r2);
        fit.jacobian(&model.nominal, &mut j2);
        let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<u64>>();
        assert_eq!(bits(&r1), bits(&r2));
        assert_eq!(bits(j1.as_slice()), bits(j2.as_slice()));
        let lm = LevenbergMarquardt::budget(50).tolerances(1e-12, 1e-12);
        let a = lm.minimize(&fit, &model.nominal, &[], &mut NoObserver);
        let b = lm.minimize(&TwoPasses(&fit), &model.nominal, &[], &mut NoObserver);
        assert!(a.iterations > 1);
        assert_eq!((bits(&a.x), a.cost.to_bits(), a.iterations, a.evaluations), (bits(&b.x), b.cost.to_bits(), b.iterations, b.evaluations));
        assert_eq!(a.termination, b.termination);
    }
}
