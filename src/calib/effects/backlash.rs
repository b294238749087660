//! Gear backlash: a joint sits h_j rad to one side of its band, the side the load pushes it to
//! (or, unloaded, the side the motion approached from).

use super::*;

pub struct Backlash;

impl Effect for Backlash {
    fn name(&self) -> &'static str {
        "backlash"
    }
    fn per_joint(&self) -> bool {
        true
    }
    fn constant_on_still_joint(&self) -> bool {
        true
    }
    fn n_params(&self, _b: &EffectBlock) -> usize {
        1
    }
    fn params(&self, b: &EffectBlock) -> Vec<(String, EffectUnit)> {
        vec![(format!("backlash.j{}", b.joint_number()), EffectUnit::SmallAngle)]
    }
    fn apply(&self, b: &EffectBlock, x: &[f64], k: usize, _q: &[f64], inp: &RowInputs, st: &mut EffectState) {
        let j = b.joint.unwrap_or(0);
        st.dq[j] += x[k] * inp.side(j);
        st.joint_terms.push((k, j, inp.side(j)));
    }
    fn twin_size(&self, _b: &EffectBlock, x: &[f64], k: usize) -> std::result::Result<(f64, f64), String> {
        match x[k] > 0.0 {
            true => Ok((x[k], 0.0)),
            false => Err(format!("identified as {} (not physical)", x[k])),
        }
    }
    fn size(&self, _b: &EffectBlock, x: &[f64], k: usize, var: &dyn Fn(usize, usize) -> f64) -> Size {
        Size::new("band width (2 x half band)", 2.0 * x[k] * DEG, "deg", 2.0 * var(k, k).max(0.0).sqrt() * DEG)
    }
    fn physical_sign(&self, x: &[f64], k: usize) -> bool {
        x[k] > 0.0
    }
    fn plausible(&self, _joint: Option<usize>) -> f64 {
        0.25f64.to_radians()
    }
    fn reported(&self, _joint: Option<usize>, v: f64) -> f64 {
        2.0 * v.to_degrees()
    }
}
