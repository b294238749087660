//! The calibration problem in the three shapes the optimisers take: least squares (LM),
//! sequential scalar observations (EKF, PF) and a bounded scalar cost (PSO, DE).
//! Residuals are in millimetres: measured minus predicted reading, one per reading value
//! (one per row for a cable length, three for a tracker's point).

use super::effects::RowInputs;
use super::model::{CalibModel, ModelWork};
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
    /// What each row carries besides q and its reading (time, temperature, torques, backlash sides).
    pub inputs: Vec<RowInputs>,
}

impl Samples {
    /// One-value readings (cable lengths) with no per-row inputs.
    pub fn new(q: Vec<Vec<f64>>, l: Vec<f64>) -> Self {
        Samples::readings(q, l, 1)
    }
    /// Readings of `dim` values per row with no per-row inputs.
    pub fn readings(q: Vec<Vec<f64>>, y: Vec<f64>, dim: usize) -> Self {
        debug_assert_eq!(q.len() * dim, y.len());
        let inputs = vec![RowInputs::default(); q.len()];
        Samples { q, y, dim, inputs }
    }
    /// The rows `idx`.
    pub fn subset(&self, idx: &[usize]) -> Samples {
        Samples {
            q: idx.iter().map(|&i| self.q[i].clone()).collect(),
            y: idx.iter().flat_map(|&i| self.row(i).iter().copied()).collect(),
            dim: self.dim,
            inputs: idx.iter().map(|&i| self.inputs[i].clone()).collect(),
        }
    }
    /// The reading of row `i`.
    pub fn row(&self, i: usize) -> &[f64] {
        &self.y[i * self.dim..(i + 1) * self.dim]
    }
    pub fn len(&self) -> usize {
        self.q.len()
    }
    pub fn is_empty(&self) -> bool {
        self.q.is_empty()
    }
}

/// A model fitted to samples: one residual per reading value, row after row.
pub struct ReadingFit<'a> {
    pub model: &'a CalibModel,
    pub data: &'a Samples,
}

impl ReadingFit<'_> {
    /// Residuals (mm) at `x`.
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
        self.data.y.len()
    }
    fn residuals(&self, x: &[f64], r: &mut [f64]) {
        let d = self.data.dim;
        let mut y = [0.0; MAX_DIM];
        with_work(self.model, |w| {
            for (i, ri) in r.chunks_mut(d).enumerate() {
                self.model.readings_with(x, &self.data.q[i], &self.data.inputs[i], w, &mut y[..d]);
                for (k, rk) in ri.iter_mut().enumerate() {
                    *rk = (self.data.y[i * d + k] - y[k]) * 1e3;
                }
            }
        })
    }
    fn jacobian(&self, x: &[f64], j: &mut DMatrix<f64>) {
        let (n, d) = (self.model.n_params(), self.data.dim);
        let mut g = vec![0.0; n * d];
        let mut y = [0.0; MAX_DIM];
        with_work(self.model, |w| {
            for i in 0..self.data.len() {
                self.model.readings_grad_with(x, &self.data.q[i], &self.data.inputs[i], w, &mut y[..d], &mut g);
                for c in 0..d {
                    for k in 0..n {
                        j[(i * d + c, k)] = -g[c * n + k] * 1e3;
                    }
                }
            }
        })
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
        let d = self.data.dim;
        let (row, c) = (i / d, i % d);
        let mut y = [0.0; MAX_DIM];
        with_work(self.model, |w| self.model.readings_with(x, &self.data.q[row], &self.data.inputs[row], w, &mut y[..d]));
        y[c] * 1e3
    }
    fn measured(&self, i: usize) -> f64 {
        self.data.y[i] * 1e3
    }
    fn gradient(&self, x: &[f64], i: usize, g: &mut [f64]) {
        let (n, d) = (self.model.n_params(), self.data.dim);
        let (row, c) = (i / d, i % d);
        if d == 1 {
            with_work(self.model, |w| self.model.predict_grad_with(x, &self.data.q[row], &self.data.inputs[row], w, g));
        } else {
            // The row's whole Jacobian, in a reused buffer (the filters call this per value).
            JAC.with(|cell| {
                let mut jac = cell.borrow_mut();
                jac.resize(n * d, 0.0);
                let mut y = [0.0; MAX_DIM];
                with_work(self.model, |w| self.model.readings_grad_with(x, &self.data.q[row], &self.data.inputs[row], w, &mut y[..d], &mut jac));
                g.copy_from_slice(&jac[c * n..(c + 1) * n]);
            });
        }
        g.iter_mut().for_each(|v| *v *= 1e3);
    }
}

/// ½ Σ r² (mm²) over the free parameters only; the fixed ones keep the values of `base`.
pub struct FreeCost<'a> {
    pub fit: ReadingFit<'a>,
    pub base: Vec<f64>,
    pub free: Vec<usize>,
}

impl FreeCost<'_> {
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
