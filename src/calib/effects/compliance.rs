//! Joint compliance: each joint gives way c_j rad per N·m of the static torque it carries
//! (links, payload, cable), so the arm sags under its own weight as a pose changes.

use super::*;

pub struct Compliance;

impl Effect for Compliance {
    fn name(&self) -> &'static str {
        "compliance"
    }
    fn per_joint(&self) -> bool {
        true
    }
    fn n_params(&self, _b: &EffectBlock) -> usize {
        1
    }
    fn params(&self, b: &EffectBlock) -> Vec<(String, EffectUnit)> {
        vec![(format!("compliance.j{}", b.joint_number()), EffectUnit::Compliance)]
    }
    fn reads_torques(&self) -> bool {
        true
    }
    fn configure(&self, _b: &mut EffectBlock, _data: &Dataset, has_torques: bool) -> Result<()> {
        if !has_torques {
            return Err(Error::Invalid("compliance needs joint torques, and nothing loads the joints here: give a URDF with its links' <inertial> masses (--robot FILE), a payload (--payload-kg) or a cable tension (--cable-tension-n)".into()));
        }
        Ok(())
    }
    fn apply(&self, b: &EffectBlock, x: &[f64], k: usize, _q: &[f64], inp: &RowInputs, st: &mut EffectState) {
        let j = b.joint.unwrap_or(0);
        st.dq[j] += x[k] * inp.torque(j);
        st.joint_terms.push((k, j, inp.torque(j)));
    }
    fn twin_size(&self, _b: &EffectBlock, x: &[f64], k: usize) -> std::result::Result<(f64, f64), String> {
        match x[k] > 0.0 {
            true => Ok((x[k], 0.0)),
            false => Err(format!("identified as {} (not physical)", x[k])),
        }
    }
    fn size(&self, _b: &EffectBlock, x: &[f64], k: usize, var: &dyn Fn(usize, usize) -> f64) -> Size {
        Size::new("compliance", x[k] * 1e6, "urad/Nm", var(k, k).max(0.0).sqrt() * 1e6)
    }
    fn physical_sign(&self, x: &[f64], k: usize) -> bool {
        x[k] > 0.0
    }
    fn plausible(&self, _joint: Option<usize>) -> f64 {
        200e-6
    }
    fn reported(&self, _joint: Option<usize>, v: f64) -> f64 {
        v * 1e6
    }
}
