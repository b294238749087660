//! The calibration problem in the three shapes the optimisers take: least squares (LM),
//! sequential scalar observations (EKF, PF) and a bounded scalar cost (PSO, DE).
//! Residuals are in millimetres: measured minus predicted cable length.

use super::effects::RowInputs;
use super::model::{CalibModel, ModelWork};
use crate::optim::{Cost, LeastSquares, Observations};
use nalgebra::DMatrix;
use std::cell::RefCell;

thread_local! {
    static WORK: RefCell<Option<(usize, ModelWork)>> = const { RefCell::new(None) };
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

/// Measured lengths at joint angles: the data a calibration fits.
#[derive(Clone, Debug)]
pub struct Samples {
    /// Joint angles, rad.
    pub q: Vec<Vec<f64>>,
    /// Measured lengths, m.
    pub l: Vec<f64>,
    /// What each row carries besides q and L (time, temperature, torques, backlash sides).
    pub inputs: Vec<RowInputs>,
}

impl Samples {
    /// Samples with no per-row inputs.
    pub fn new(q: Vec<Vec<f64>>, l: Vec<f64>) -> Self {
        let inputs = vec![RowInputs::default(); l.len()];
        Samples { q, l, inputs }
    }
    /// The rows `idx`.
    pub fn subset(&self, idx: &[usize]) -> Samples {
        Samples {
            q: idx.iter().map(|&i| self.q[i].clone()).collect(),
            l: idx.iter().map(|&i| self.l[i]).collect(),
            inputs: idx.iter().map(|&i| self.inputs[i].clone()).collect(),
        }
    }
    pub fn len(&self) -> usize {
        self.l.len()
    }
    pub fn is_empty(&self) -> bool {
        self.l.is_empty()
    }
}

/// A model fitted to samples.
pub struct LengthFit<'a> {
    pub model: &'a CalibModel,
    pub data: &'a Samples,
}

impl LengthFit<'_> {
    /// Residuals (mm) at `x`.
    pub fn residuals_mm(&self, x: &[f64]) -> Vec<f64> {
        let mut r = vec![0.0; self.data.len()];
        LeastSquares::residuals(self, x, &mut r);
        r
    }
}

impl LeastSquares for LengthFit<'_> {
    fn n_params(&self) -> usize {
        self.model.n_params()
    }
    fn n_residuals(&self) -> usize {
        self.data.len()
    }
    fn residuals(&self, x: &[f64], r: &mut [f64]) {
        with_work(self.model, |w| {
            for (i, ri) in r.iter_mut().enumerate() {
                *ri = (self.data.l[i] - self.model.predict_with(x, &self.data.q[i], &self.data.inputs[i], w)) * 1e3;
            }
        })
    }
    fn jacobian(&self, x: &[f64], j: &mut DMatrix<f64>) {
        let n = self.model.n_params();
        let mut g = vec![0.0; n];
        with_work(self.model, |w| {
            for i in 0..self.data.len() {
                self.model.predict_grad_with(x, &self.data.q[i], &self.data.inputs[i], w, &mut g);
                for k in 0..n {
                    j[(i, k)] = -g[k] * 1e3;
                }
            }
        })
    }
}

impl Observations for LengthFit<'_> {
    fn n_params(&self) -> usize {
        self.model.n_params()
    }
    fn n_obs(&self) -> usize {
        self.data.len()
    }
    fn predict(&self, x: &[f64], i: usize) -> f64 {
        with_work(self.model, |w| self.model.predict_with(x, &self.data.q[i], &self.data.inputs[i], w) * 1e3)
    }
    fn measured(&self, i: usize) -> f64 {
        self.data.l[i] * 1e3
    }
    fn gradient(&self, x: &[f64], i: usize, g: &mut [f64]) {
        with_work(self.model, |w| self.model.predict_grad_with(x, &self.data.q[i], &self.data.inputs[i], w, g));
        g.iter_mut().for_each(|v| *v *= 1e3);
    }
}

/// ½ Σ r² (mm²) over the free parameters only; the fixed ones keep the values of `base`.
pub struct FreeCost<'a> {
    pub fit: LengthFit<'a>,
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
