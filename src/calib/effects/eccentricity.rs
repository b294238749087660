//! Encoder eccentricity: the true joint angle is the reading plus a first harmonic,
//! a_j·sin q_j + b_j·cos q_j.

use super::*;

pub struct Eccentricity;

impl Effect for Eccentricity {
    fn name(&self) -> &'static str {
        "eccentricity"
    }
    fn per_joint(&self) -> bool {
        true
    }
    fn constant_on_still_joint(&self) -> bool {
        true
    }
    fn n_params(&self, _b: &EffectBlock) -> usize {
        2
    }
    fn params(&self, b: &EffectBlock) -> Vec<(String, EffectUnit)> {
        let j = b.joint_number();
        vec![(format!("eccentricity.j{j}.sin"), EffectUnit::SmallAngle), (format!("eccentricity.j{j}.cos"), EffectUnit::SmallAngle)]
    }
    fn apply(&self, b: &EffectBlock, x: &[f64], k: usize, q: &[f64], _inp: &RowInputs, st: &mut EffectState) {
        let j = b.joint.unwrap_or(0);
        let (s, c) = q[j].sin_cos();
        st.dq[j] += x[k] * s + x[k + 1] * c;
        st.ddq_dq[j] += x[k] * c - x[k + 1] * s;
        st.joint_terms.push((k, j, s));
        st.joint_terms.push((k + 1, j, c));
    }
    fn size(&self, _b: &EffectBlock, x: &[f64], k: usize, var: &dyn Fn(usize, usize) -> f64) -> Size {
        let (a, b) = (x[k], x[k + 1]);
        let amp = a.hypot(b).max(1e-300);
        let v = (a * a * var(k, k) + b * b * var(k + 1, k + 1) + 2.0 * a * b * var(k, k + 1)) / (amp * amp);
        Size::new("first-harmonic amplitude", amp * DEG, "deg", v.max(0.0).sqrt() * DEG)
    }
    fn twin_size(&self, _b: &EffectBlock, x: &[f64], k: usize) -> std::result::Result<(f64, f64), String> {
        let (a, c) = (x[k], x[k + 1]);
        Ok((a.hypot(c), c.atan2(a)))
    }
    fn plausible(&self, _joint: Option<usize>) -> f64 {
        0.1f64.to_radians()
    }
    fn reported(&self, _joint: Option<usize>, v: f64) -> f64 {
        v.to_degrees()
    }
}
