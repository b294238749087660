//! The corrector interface ([`Correct`]), the model's own effect blocks seen through it
//! ([`EffectCorrection`]) and the finite-difference check of any corrector's gradient.

use crate::calib::effects::RowInputs;
use crate::calib::model::{CalibModel, ModelWork};

/// A non-geometric length correction, see the module docs.
pub trait Correct: Send + Sync {
    /// Short name for reports ("rbf", "effects", ...).
    fn label(&self) -> String;
    /// Number of fitted values (weights, centres, ...) it carries.
    fn n_weights(&self) -> usize;
    /// Length correction (mm) at commanded joint angles `q` (rad).
    fn correction_mm(&self, q: &[f64], inp: &RowInputs) -> f64;
    /// The correction (mm) and its gradient with respect to `q` (mm/rad) into `g` (len 6).
    fn correction_grad_mm(&self, q: &[f64], inp: &RowInputs, g: &mut [f64]) -> f64;
    /// Reading values it corrects per row: 1 (a cable length) unless it says otherwise.
    fn dim(&self) -> usize {
        1
    }
    /// The correction (mm) of each of the row's [`Self::dim`] reading values into `out`.
    fn corrections_mm(&self, q: &[f64], inp: &RowInputs, out: &mut [f64]) {
        out[0] = self.correction_mm(q, inp);
    }
    /// [`Self::corrections_mm`] and their gradients with respect to `q` (mm/rad) into `g`
    /// (row-major, one row of `q.len()` per value).
    fn corrections_grad_mm(&self, q: &[f64], inp: &RowInputs, out: &mut [f64], g: &mut [f64]) {
        out[0] = self.correction_grad_mm(q, inp, &mut g[..q.len()]);
    }
}

impl<T: Correct + ?Sized> Correct for &T {
    fn label(&self) -> String {
        (**self).label()
    }
    fn n_weights(&self) -> usize {
        (**self).n_weights()
    }
    fn correction_mm(&self, q: &[f64], inp: &RowInputs) -> f64 {
        (**self).correction_mm(q, inp)
    }
    fn correction_grad_mm(&self, q: &[f64], inp: &RowInputs, g: &mut [f64]) -> f64 {
        (**self).correction_grad_mm(q, inp, g)
    }
    fn dim(&self) -> usize {
        (**self).dim()
    }
    fn corrections_mm(&self, q: &[f64], inp: &RowInputs, out: &mut [f64]) {
        (**self).corrections_mm(q, inp, out)
    }
    fn corrections_grad_mm(&self, q: &[f64], inp: &RowInputs, out: &mut [f64], g: &mut [f64]) {
        (**self).corrections_grad_mm(q, inp, out, g)
    }
}

/// The model's physical effect blocks as a corrector: the length (mm) with every effect minus
/// the length of the same geometry without them.
pub struct EffectCorrection<'a> {
    /// The calibrated model.
    pub model: &'a CalibModel,
    /// Its parameter vector (internal units).
    pub x: &'a [f64],
    /// The same parameters with every effect parameter at "no effect".
    x_off: Vec<f64>,
}

impl<'a> EffectCorrection<'a> {
    /// The effect correction of `model` at `x`.
    pub fn new(model: &'a CalibModel, x: &'a [f64]) -> Self {
        let mut x_off = x.to_vec();
        let k = model.first_effect();
        x_off[k..].copy_from_slice(&model.nominal[k..]);
        EffectCorrection { model, x, x_off }
    }
    fn value(&self, q: &[f64], inp: &RowInputs, w: &mut ModelWork) -> f64 {
        crate::units::to_mm(self.model.length(self.x, q, inp, w) - self.model.length(&self.x_off, q, inp, w))
    }
}

impl Correct for EffectCorrection<'_> {
    fn label(&self) -> String {
        let names: Vec<String> = self.model.effects.iter().map(|e| e.label()).collect();
        if names.is_empty() {
            "no effects".into()
        } else {
            format!("effects ({})", names.join(", "))
        }
    }
    fn n_weights(&self) -> usize {
        self.model.n_params() - self.model.first_effect()
    }
    fn correction_mm(&self, q: &[f64], inp: &RowInputs) -> f64 {
        self.value(q, inp, &mut self.model.work())
    }
    fn correction_grad_mm(&self, q: &[f64], inp: &RowInputs, g: &mut [f64]) -> f64 {
        // The joint torques behind the compliance block are row inputs (fixed here), so the
        // correction's dependence on q is through the joint angles and the effects that read
        // them (eccentricity): both differences are differentiated through the one chain
        // Jacobian, ∂L/∂q_j = u · ∂p/∂q_j at the effect-applied angles.
        let mut w = self.model.work();
        let with = self.model.length_grad_q(self.x, q, inp, &mut w, g);
        let mut g0 = vec![0.0; g.len()];
        let without = self.model.length_grad_q(&self.x_off, q, inp, &mut w, &mut g0);
        for (a, b) in g.iter_mut().zip(g0) {
            *a = crate::units::to_mm(*a - b);
        }
        crate::units::to_mm(with - without)
    }
}

/// Largest difference between a corrector's analytic q-gradient and central finite differences
/// (step `h` rad), relative to max(1, |gradient|), over the given configurations.
pub fn gradient_error(c: &dyn Correct, qs: &[Vec<f64>], inp: &RowInputs, h: f64) -> f64 {
    let mut worst = 0.0f64;
    let mut g = vec![0.0; qs.first().map_or(0, |q| q.len())];
    for q in qs {
        c.correction_grad_mm(q, inp, &mut g);
        let scale = g.iter().fold(1.0f64, |m, v| m.max(v.abs()));
        for j in 0..q.len() {
            let mut qp = q.clone();
            let mut qm = q.clone();
            qp[j] += h;
            qm[j] -= h;
            let fd = (c.correction_mm(&qp, inp) - c.correction_mm(&qm, inp)) / (2.0 * h);
            worst = worst.max((fd - g[j]).abs() / scale);
        }
    }
    worst
}
