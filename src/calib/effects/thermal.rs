//! Thermal drift: the links grow by α·(T − T_ref) with a measured temperature (or by a warm-up
//! s·(1 − e^(−t/τ)) with time only), and a joint's zero drifts by z_j per kelvin (or z_j at full
//! warm-up). One whole-arm block (the length scale) and one block per joint (the zero drift).
//!
//! A temperature sensor rarely reads the structure itself: a probe on the casting or in the
//! cabinet follows it with a lag, and the structure follows the air with its own. Where the rows
//! have a time column, a temperature-driven block therefore also fits a signed lag L (s) and
//! takes the structure at T + L·dT/dt: exact for a first-order sensor lagging the structure
//! (L > 0), first order for a structure lagging the sensed air (L < 0). Left out, a lag of a
//! third of the warm-up's time constant sizes the expansion ten percent low.

use super::*;

/// The range of linear expansion (ppm/K) of what an arm's structure is made of: steel 11–13,
/// cast iron 10–12, aluminium 22–24, magnesium 25–26. A whole-arm expansion beyond it (by
/// three standard uncertainties) is not the arm's alone.
pub const STRUCTURE_EXPANSION_PPM_PER_K: (f64, f64) = (10.0, 26.0);

/// Least spread of a `temp` column (K) that drives a thermal block: below it the column is a
/// constant, and the block runs on `t` (a warm-up) when the rows have it.
pub const MIN_TEMP_SPREAD_K: f64 = 0.01;

pub struct Thermal;

fn by_temperature(b: &EffectBlock) -> bool {
    matches!(b.thermal, Some(ThermalDrive::Temperature { .. }))
}

impl Effect for Thermal {
    fn name(&self) -> &'static str {
        "thermal"
    }
    fn per_joint(&self) -> bool {
        false
    }
    fn varies_in_time(&self) -> bool {
        true
    }
    fn joint_options(&self, n: usize) -> Vec<Option<usize>> {
        std::iter::once(None).chain((0..n).map(Some)).collect()
    }
    fn params(&self, b: &EffectBlock) -> Vec<(String, EffectUnit)> {
        let j = b.joint_number();
        let mut out = match (by_temperature(b), b.joint) {
            (true, None) => vec![("thermal.alpha".into(), EffectUnit::PerKelvin)],
            (false, None) => vec![("thermal.scale".into(), EffectUnit::Ratio), ("thermal.tau".into(), EffectUnit::Seconds)],
            (true, Some(_)) => vec![(format!("thermal.zero_drift.j{j}"), EffectUnit::AnglePerKelvin)],
            (false, Some(_)) => {
                vec![(format!("thermal.zero_drift.j{j}"), EffectUnit::SmallAngle), (format!("thermal.zero_drift.j{j}.tau"), EffectUnit::Seconds)]
            }
        };
        if b.fits_sensor_lag() {
            out.push((format!("{}.sensor_lag", out[0].0), EffectUnit::Lag));
        }
        out
    }
    fn n_params(&self, b: &EffectBlock) -> usize {
        // A warm-up (time only) has its time constant besides the size, a lagged temperature
        // drive its lag.
        if by_temperature(b) && !b.fits_sensor_lag() {
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
            (Some(t), Some(s)) if !t.is_empty() && s >= MIN_TEMP_SPREAD_K => b.thermal = Some(ThermalDrive::Temperature { ref_c: t[0], sensor_lag: has_t }),
            _ if has_t => b.thermal = Some(ThermalDrive::WarmUp),
            (Some(t), Some(_)) if !t.is_empty() => {
                return Err(Error::Invalid(format!(
                "thermal: the temp column reads {} °C on every row (it spans less than {MIN_TEMP_SPREAD_K} K) and there is no t column: nothing drives a drift",
                t[0]
            )))
            }
            _ => return Err(Error::Invalid("thermal needs a temp or t column on every row".into())),
        }
        Ok(())
    }
    fn apply(&self, b: &EffectBlock, x: &[f64], k: usize, _q: &[f64], inp: &RowInputs, st: &mut EffectState) {
        // The thermal state: temperature rise (with `temp`) or warm-up fraction.
        // `dfdp`: the derivative of the state by the block's second parameter (a warm-up's time
        // constant, a sensor's lag), when it has one.
        let (f, dfdp) = match b.thermal {
            Some(ThermalDrive::Temperature { ref_c, sensor_lag }) => {
                let rate = inp.temp_rate_k_per_s.unwrap_or(0.0);
                let lag = if sensor_lag { x[k + 1] } else { 0.0 };
                (inp.temp_c.map(|t| t - ref_c + lag * rate).unwrap_or(0.0), sensor_lag.then_some(rate))
            }
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
                if let Some(d) = dfdp {
                    st.scale_terms.push((k + 1, x[k] * d));
                }
            }
            Some(j) => {
                st.dq[j] += x[k] * f;
                st.joint_terms.push((k, j, f));
                if let Some(d) = dfdp {
                    st.joint_terms.push((k + 1, j, x[k] * d));
                }
            }
        }
    }
    fn size(&self, b: &EffectBlock, x: &[f64], k: usize, var: &dyn Fn(usize, usize) -> f64) -> Size {
        let sd = var(k, k).max(0.0).sqrt();
        // The second parameter, a time (a warm-up's time constant, a sensor's lag), is said
        // beside the size.
        let time = |what: &str| match self.n_params(b) {
            1 => String::new(),
            _ => format!(" ({what} {:.0} ± {:.0} s)", x[k + 1], var(k + 1, k + 1).max(0.0).sqrt()),
        };
        let (quantity, value, unit, scale) = match (by_temperature(b), b.joint) {
            (true, None) => (format!("expansion coefficient{}", time("sensor lag")), x[k] * 1e6, "ppm/K", 1e6),
            (false, None) => (format!("warm-up length growth{}", time("time constant")), x[k] * 1e6, "ppm", 1e6),
            (true, Some(_)) => (format!("joint-zero drift{}", time("sensor lag")), x[k] * DEG, "deg/K", DEG),
            (false, Some(_)) => (format!("joint-zero drift at full warm-up{}", time("time constant")), x[k] * DEG, "deg", DEG),
        };
        Size::new(&quantity, value, unit, sd * scale)
    }
    fn attribution(&self, b: &EffectBlock, s: &Size) -> Option<String> {
        let (lo, hi) = STRUCTURE_EXPANSION_PPM_PER_K;
        if !(by_temperature(b) && b.joint.is_none()) || (s.value - 3.0 * s.uncertainty <= hi && s.value + 3.0 * s.uncertainty >= lo) {
            return None;
        }
        let why = if s.value > hi {
            format!("{:.1}x the most an arm's metal expands ({hi} ppm/K for magnesium; aluminium 23, steel 12)", s.value / hi)
        } else {
            format!("below what any arm's metal expands ({lo} ppm/K, cast iron)")
        };
        Some(format!(
            "thermal: an expansion of {} ppm/K of the whole arm is {why}: the drift that follows this temperature is not the arm's structure alone. \
             Whose it can be: the instrument's (a laser tracker's air compensation, whose weather station reads another air than the beam crosses), \
             the instrument's stand or the arm's base and floor (a grown or tilted mount scales every reading alike), or a temperature read somewhere \
             that moves less than the structure (then the structure's rise is larger than the reading's and the size stands for that ratio); \
             the model predicts it only while the temperature behaves as in these rows",
            crate::units::with_uncertainty(s.value, s.uncertainty)
        ))
    }
    fn later_params_scaled_by_size(&self, b: &EffectBlock) -> bool {
        self.n_params(b) > 1
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
