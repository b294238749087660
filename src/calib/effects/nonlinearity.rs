//! Sensor nonlinearity: the reading plus Σ p_k·P_k(v), Legendre polynomials P2..P4 over the
//! data's reading range (the correction itself is applied by the model, on the reading).

use super::*;

pub struct Nonlinearity;

impl Effect for Nonlinearity {
    fn name(&self) -> &'static str {
        "nonlinearity"
    }
    fn per_joint(&self) -> bool {
        false
    }
    fn n_params(&self, _b: &EffectBlock) -> usize {
        3
    }
    fn params(&self, _b: &EffectBlock) -> Vec<(String, EffectUnit)> {
        (2..=4).map(|k| (format!("sensor_nl.p{k}"), EffectUnit::Length)).collect()
    }
    fn configure(&self, b: &mut EffectBlock, data: &Dataset, _has_torques: bool) -> Result<()> {
        if let Some(m) = data.measurement().filter(|m| *m != crate::measurement::Measurement::Length) {
            return Err(Error::Invalid(format!("nonlinearity is a draw-wire's reading error; these rows hold a {}", m.def().describe())));
        }
        let (lo, hi) = data.rows.iter().filter_map(|r| r.l_mm()).fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), l| (a.min(l), b.max(l)));
        if !(lo < hi) {
            return Err(Error::Invalid("nonlinearity needs measured lengths over a range".into()));
        }
        b.range_m = Some([crate::units::to_m(lo), crate::units::to_m(hi)]);
        Ok(())
    }
    fn size(&self, _b: &EffectBlock, x: &[f64], k: usize, var: &dyn Fn(usize, usize) -> f64) -> Size {
        // Largest |correction| over the reading range, and its uncertainty there.
        let (mut best, mut at) = (0.0f64, [0.0; 3]);
        for s in 0..=200 {
            let v = -1.0 + s as f64 / 100.0;
            let (p, _) = legendre(v);
            let val = (0..3).map(|m| x[k + m] * p[m]).sum::<f64>();
            if val.abs() > best.abs() {
                best = val;
                at = p;
            }
        }
        let mut v = 0.0;
        for a in 0..3 {
            for b in 0..3 {
                v += at[a] * at[b] * var(k + a, k + b);
            }
        }
        Size::new("largest reading correction", crate::units::to_mm(best.abs()), "mm", crate::units::to_mm(v.max(0.0).sqrt()))
    }
}
