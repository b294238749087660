//! Thermal drift: the links grow by α·(T − T_ref) with a measured temperature (or by a warm-up
//! s·(1 − e^(−t/τ)) with time only), and a joint's zero drifts by z_j per kelvin (or z_j at full
//! warm-up). One whole-arm block (the length scale) and one block per joint (the zero drift).

use super::*;

/// Least spread of a `temp` column (K) that drives a thermal block: below it the column is a
/// constant, and the block runs on `t` (a warm-up) when the rows have it.
pub const MIN_TEMP_SPREAD_K: f64 = 0.01;

pub struct ThermalDrift;

fn by_temperature(b: &EffectBlock) -> bool {
    matches!(b.thermal, Some(ThermalDrive::Temperature { .. }))
}

impl Effect for ThermalDrift {
    fn name(&self) -> &'static str {
        "thermal_drift"
    }
    fn short(&self) -> Option<&'static str> {
        Some("thermal")
    }
    fn per_joint(&self) -> bool {
        false
    }
    fn joint_options(&self, n: usize) -> Vec<Option<usize>> {
        std::iter::once(None).chain((0..n).map(Some)).collect()
    }
    fn params(&self, b: &EffectBlock) -> Vec<(String, EffectUnit)> {
        let j = b.joint_number();
        match (by_temperature(b), b.joint) {
            (true, None) => vec![("thermal.alpha".into(), EffectUnit::PerKelvin)],
            (false, None) => vec![("thermal.scale".into(), EffectUnit::Ratio), ("thermal.tau".into(), EffectUnit::Seconds)],
            (true, Some(_)) => vec![(format!("thermal.zero_drift.j{j}"), EffectUnit::AnglePerKelvin)],
            (false, Some(_)) => {
                vec![(format!("thermal.zero_drift.j{j}"), EffectUnit::SmallAngle), (format!("thermal.zero_drift.j{j}.tau"), EffectUnit::Seconds)]
            }
        }
    }
    fn n_params(&self, b: &EffectBlock) -> usize {
        // A warm-up (time only) has its time constant besides the size.
        if by_temperature(b) {
            1
        } else {
            2
        }
    }
    fn start(&self, b: &EffectBlock, t_span_s: f64) -> Vec<f64> {
        let mut v = vec![0.0; self.n_params(b)];
        if !by_temperature(b) {
            // The warm-up time constant starts at a third of the data's time span.
            v[1] = (t_span_s / 3.0).max(1.0);
        }
        v
    }
    fn configure(&self, b: &mut EffectBlock, data: &Dataset, _has_torques: bool) -> Result<()> {
        // A temperature that never changes drives nothing: a drift the rows show over time
        // must then be fitted against t (a sensor that did not move, or an ambient written as
        // a constant, would otherwise hide it).
        let temps: Option<Vec<f64>> = data.rows.iter().map(|r| r.temp_c).collect();
        let spread = temps.as_ref().map(|t| t.iter().fold(f64::NEG_INFINITY, |a, v| a.max(*v)) - t.iter().fold(f64::INFINITY, |a, v| a.min(*v)));
        let has_t = !data.rows.is_empty() && data.rows.iter().all(|r| r.t_s.is_some());
        match (temps, spread) {
            (Some(t), Some(s)) if !t.is_empty() && s >= MIN_TEMP_SPREAD_K => b.thermal = Some(ThermalDrive::Temperature { ref_c: t[0] }),
            _ if has_t => b.thermal = Some(ThermalDrive::WarmUp),
            (Some(t), Some(_)) if !t.is_empty() => {
                return Err(Error::Invalid(format!(
                    "thermal_drift: the temp column reads {} °C on every row (it spans less than {MIN_TEMP_SPREAD_K} K) and there is no t column: nothing drives a drift",
                    t[0]
                )))
            }
            _ => return Err(Error::Invalid("thermal_drift needs a temp or t column on every row".into())),
        }
        Ok(())
    }
    fn apply(&self, b: &EffectBlock, x: &[f64], k: usize, _q: &[f64], inp: &RowInputs, st: &mut EffectState) {
        // The thermal state: temperature rise (with `temp`) or warm-up fraction.
        let (f, dfdtau) = match b.thermal {
            Some(ThermalDrive::Temperature { ref_c }) => (inp.temp_c.map(|t| t - ref_c).unwrap_or(0.0), None),
            _ => {
                let t = inp.t_s.unwrap_or(0.0);
                let tau = x[k + 1].max(1e-3);
                let e = (-t / tau).exp();
                (1.0 - e, Some(-e * t / (tau * tau)))
            }
        };
        match b.joint {
            None => {
                st.scale += x[k] * f;
                st.scale_terms.push((k, f));
                if let Some(d) = dfdtau {
                    st.scale_terms.push((k + 1, x[k] * d));
                }
            }
            Some(j) => {
                st.dq[j] += x[k] * f;
                st.joint_terms.push((k, j, f));
                if let Some(d) = dfdtau {
                    st.joint_terms.push((k + 1, j, x[k] * d));
                }
            }
        }
    }
    fn size(&self, b: &EffectBlock, x: &[f64], k: usize, var: &dyn Fn(usize, usize) -> f64) -> Size {
        let sd = var(k, k).max(0.0).sqrt();
        match (by_temperature(b), b.joint) {
            (true, None) => Size::new("expansion coefficient", x[k] * 1e6, "ppm/K", sd * 1e6),
            (false, None) => Size::new("warm-up length growth", x[k] * 1e6, "ppm", sd * 1e6),
            (true, Some(_)) => Size::new("joint-zero drift", x[k] * DEG, "deg/K", sd * DEG),
            (false, Some(_)) => Size::new("joint-zero drift at full warm-up", x[k] * DEG, "deg", sd * DEG),
        }
    }
    fn plausible(&self, joint: Option<usize>) -> f64 {
        match joint {
            None => 100e-6,
            Some(_) => 0.02f64.to_radians(),
        }
    }
    fn reported(&self, joint: Option<usize>, v: f64) -> f64 {
        match joint {
            None => v * 1e6,
            Some(_) => v.to_degrees(),
        }
    }
}
