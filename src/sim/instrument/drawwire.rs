//! Draw-wire length sensor: a cable from a fixed exit point in the base frame to a tool point
//! on the flange. A reading is the cable length plus a length offset, with a smooth linearity error,
//! Gaussian noise and quantisation, averaged over a stationary window.

use crate::measurement::Measurement;
use crate::sim::effects::statics::CableLoad;
use nalgebra::Vector3;
use rand::Rng;
use rand_distr::{Distribution, Normal};
use serde::{Deserialize, Serialize};

/// Most raw samples averaged per pose (100 s at 1 kHz).
pub const MAX_SAMPLES: usize = 100_000;
/// Sampling rate bounds, Hz.
pub const RATE_HZ_RANGE: [f64; 2] = [1.0, 1e6];
/// Longest hold time before sampling, s.
pub const MAX_HOLD_S: f64 = 3600.0;
/// Largest noise standard deviation and resolution, as a fraction of the range width.
pub const MAX_FRACTION_OF_RANGE: f64 = 0.1;
/// Finest step a written reading is rounded to, mm.
pub const FINEST_READING_STEP_MM: f64 = 1e-6;

/// A draw-wire sensor (the scenario's `[sensor]`): its placement, reading errors, hold and
/// sampling.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DrawWire {
    /// Cable exit point in the base frame, mm.
    pub exit_point_mm: [f64; 3],
    /// Cable attachment point in the flange frame, mm.
    pub tool_point_mm: [f64; 3],
    /// Added to the geometric distance, mm.
    #[serde(default)]
    pub length_offset_mm: f64,
    /// Standard deviation of one raw sample, mm.
    #[serde(default)]
    pub noise_std_mm: f64,
    /// Quantisation step of one raw sample, mm (0 = none).
    #[serde(default)]
    pub resolution_mm: f64,
    /// Amplitude of the linearity error, % of full scale (range width).
    #[serde(default)]
    pub linearity_pct_fs: f64,
    /// Valid reading range [min, max], mm.
    #[serde(default = "DrawWire::default_range")]
    pub range_mm: [f64; 2],
    /// Cable tension acting on the tool, N.
    #[serde(default)]
    pub tension_n: f64,
    /// Hold time before sampling, s.
    #[serde(default = "DrawWire::default_hold")]
    pub hold_s: f64,
    /// Samples averaged per pose.
    #[serde(default = "DrawWire::default_samples")]
    pub samples: usize,
    /// Sampling rate, Hz.
    #[serde(default = "DrawWire::default_rate")]
    pub rate_hz: f64,
    /// A smooth reading error beside the linearity's: Σ c_k·P_k(v), Legendre polynomials
    /// P2..P4 of v = (l − mid)/half over `range_mm` (what `calibrate --effects nonlinearity`
    /// identifies; an identified twin carries it).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub polynomial: Option<ReadingPolynomial>,
    /// Heavy-tailed noise: each raw sample's noise is Student-t with these degrees of freedom
    /// (> 2), scaled to the standard deviation `noise_std_mm`, instead of Gaussian (what an
    /// identified twin writes when the data's residuals have heavier tails than a Gaussian's).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub noise_t_dof: Option<f64>,
}

/// See [`DrawWire::polynomial`].
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ReadingPolynomial {
    /// The readings [lo, hi] (mm) that v = −1 and 1 stand for.
    pub range_mm: [f64; 2],
    /// c2, c3, c4, mm.
    pub legendre_mm: [f64; 3],
}

impl ReadingPolynomial {
    /// The error at reading `l`, mm. Beyond the readings it was identified on it holds its end
    /// value: the quadratic extrapolated grows without bound (metres a few ranges out).
    pub fn at(&self, l: f64) -> f64 {
        let [lo, hi] = self.range_mm;
        let half = 0.5 * (hi - lo);
        let (p, _) = crate::math::legendre(((l - 0.5 * (lo + hi)) / half).clamp(-1.0, 1.0));
        (0..3).map(|k| self.legendre_mm[k] * p[k]).sum()
    }

    /// How many of the readings `lengths_mm` lie beyond the range the polynomial was identified
    /// on, and how far the farthest does: a warning (the polynomial holds its end values there,
    /// which the data never showed), or `None` when every reading is within it.
    pub fn beyond_range(&self, lengths_mm: &[f64]) -> Option<String> {
        let [lo, hi] = self.range_mm;
        let beyond: Vec<f64> = lengths_mm.iter().map(|l| (lo - l).max(l - hi)).filter(|d| *d > 0.0).collect();
        let far = beyond.iter().fold(0.0f64, |a, d| a.max(*d));
        (!beyond.is_empty()).then(|| {
            format!(
                "{} of {} readings lie outside sensor.polynomial.range_mm [{lo}, {hi}] mm (the farthest {far:.1} mm beyond it): there the reading polynomial holds its end value, which no data showed",
                beyond.len(),
                lengths_mm.len()
            )
        })
    }
}

/// A reading the sensor could not give.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct OutOfRange {
    /// The value asked for, mm.
    pub value_mm: f64,
    /// The sensor's valid range [min, max], mm.
    pub range_mm: [f64; 2],
}

impl std::fmt::Display for OutOfRange {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "cable length {:.3} mm is outside the sensor range [{}, {}] mm", self.value_mm, self.range_mm[0], self.range_mm[1])
    }
}

impl Default for DrawWire {
    /// No draw-wire: the target at the flange's origin, the acquisition's defaults (a scenario
    /// without `[sensor]` reads with another instrument).
    fn default() -> DrawWire {
        DrawWire {
            exit_point_mm: [0.0; 3],
            tool_point_mm: [0.0; 3],
            length_offset_mm: 0.0,
            noise_std_mm: 0.0,
            resolution_mm: 0.0,
            linearity_pct_fs: 0.0,
            range_mm: Self::default_range(),
            tension_n: 0.0,
            hold_s: Self::default_hold(),
            samples: Self::default_samples(),
            rate_hz: Self::default_rate(),
            polynomial: None,
            noise_t_dof: None,
        }
    }
}

impl DrawWire {
    fn default_range() -> [f64; 2] {
        [0.0, 2000.0]
    }
    fn default_hold() -> f64 {
        2.0
    }
    fn default_samples() -> usize {
        50
    }
    fn default_rate() -> f64 {
        1000.0
    }

    /// Checks every value, naming the key (`sensor.<key>`) of the first bad one.
    pub fn validate(&self) -> Result<(), String> {
        let arrays = [("exit_point_mm", &self.exit_point_mm[..]), ("tool_point_mm", &self.tool_point_mm[..]), ("range_mm", &self.range_mm[..])];
        for (key, v) in arrays {
            if v.iter().any(|x| !x.is_finite()) {
                return Err(format!("sensor.{key} must be finite, got {v:?}"));
            }
        }
        let scalars = [
            ("length_offset_mm", self.length_offset_mm),
            ("noise_std_mm", self.noise_std_mm),
            ("resolution_mm", self.resolution_mm),
            ("linearity_pct_fs", self.linearity_pct_fs),
            ("tension_n", self.tension_n),
            ("hold_s", self.hold_s),
            ("rate_hz", self.rate_hz),
        ];
        for (key, v) in scalars {
            if !v.is_finite() {
                return Err(format!("sensor.{key} must be finite, got {v}"));
            }
        }
        if self.range_mm[0] >= self.range_mm[1] {
            return Err(format!("sensor.range_mm must be [min, max] with min < max, got {:?}", self.range_mm));
        }
        if let Some(nu) = self.noise_t_dof.filter(|nu| !(nu.is_finite() && *nu > 2.0 && *nu <= 1000.0)) {
            return Err(format!("sensor.noise_t_dof = {nu} must be in (2, 1000] (Student-t degrees of freedom; leave it out for Gaussian noise)"));
        }
        if let Some(p) = &self.polynomial {
            if !(p.range_mm.iter().all(|v| v.is_finite()) && p.range_mm[0] < p.range_mm[1]) {
                return Err(format!("sensor.polynomial.range_mm must be [lo, hi] with lo < hi, got {:?}", p.range_mm));
            }
            if !p.legendre_mm.iter().all(|c| c.is_finite() && c.abs() <= 100.0) {
                return Err(format!("sensor.polynomial.legendre_mm must be finite and at most 100 mm each, got {:?}", p.legendre_mm));
            }
        }
        let width = self.range_mm[1] - self.range_mm[0];
        let limit = MAX_FRACTION_OF_RANGE * width;
        for (key, v) in [("noise_std_mm", self.noise_std_mm), ("resolution_mm", self.resolution_mm)] {
            if !(0.0..=limit).contains(&v) {
                return Err(format!(
                    "sensor.{key} = {v} must be in [0, {limit}] mm (at most {} % of the range \
                     width {width} mm)",
                    MAX_FRACTION_OF_RANGE * 100.0
                ));
            }
        }
        if self.tension_n < 0.0 {
            return Err(format!("sensor.tension_n must be >= 0, got {}", self.tension_n));
        }
        if !(0.0..=MAX_HOLD_S).contains(&self.hold_s) {
            return Err(format!("sensor.hold_s = {} must be in [0, {MAX_HOLD_S}] s", self.hold_s));
        }
        if !(1..=MAX_SAMPLES).contains(&self.samples) {
            return Err(format!("sensor.samples = {} must be in 1..={MAX_SAMPLES}", self.samples));
        }
        let [lo, hi] = RATE_HZ_RANGE;
        if !(lo..=hi).contains(&self.rate_hz) {
            return Err(format!("sensor.rate_hz = {} must be in [{lo}, {hi}] Hz", self.rate_hz));
        }
        if self.linearity_pct_fs.abs() > 5.0 {
            return Err(format!("sensor.linearity_pct_fs = {} must be within ±5 %", self.linearity_pct_fs));
        }
        Ok(())
    }

    /// Decimals a reading is written with: the step of an averaged reading, `resolution_mm /
    /// samples` (the mean of `samples` readings quantised at `resolution_mm` is a multiple of it),
    /// rounded down to a power of ten and no finer than [`FINEST_READING_STEP_MM`] (so 6
    /// decimals at most, and 6 for a sensor without quantisation, `resolution_mm = 0`); 0
    /// decimals for steps of 1 mm and more. E.g. 0.01 mm averaged over 50 samples: step 0.0002
    /// mm, 4 decimals.
    pub fn reading_decimals(&self) -> usize {
        let finest = (-FINEST_READING_STEP_MM.log10()).round() as usize;
        let step = self.resolution_mm / self.samples.max(1) as f64;
        if !(step.is_finite() && step > FINEST_READING_STEP_MM) {
            return finest;
        }
        // A tiny epsilon keeps exact powers of ten (0.001) from flooring one decimal too far.
        let d = (-step.log10() - 1e-9).ceil();
        d.clamp(0.0, finest as f64) as usize
    }

    /// The cable exit point in the base frame, m.
    pub fn exit_point_m(&self) -> Vector3<f64> {
        crate::units::to_m(Vector3::from(self.exit_point_mm))
    }
    /// The cable attachment point in the flange frame, m.
    pub fn tool_point_m(&self) -> Vector3<f64> {
        crate::units::to_m(Vector3::from(self.tool_point_mm))
    }
    /// Duration of the sampling window, s.
    pub fn window_s(&self) -> f64 {
        self.samples as f64 / self.rate_hz
    }

    /// The cable's pull on the tool, for the statics and the simulation.
    pub fn cable_load(&self) -> Option<CableLoad> {
        (self.tension_n > 0.0).then(|| CableLoad { exit_point: self.exit_point_m(), tool_point: self.tool_point_m(), tension: self.tension_n })
    }

    /// The placement [`Measurement::Length`] reads, in mm (the reading |p − exit| + offset is the
    /// same in any length unit): the exit point and the length offset.
    pub fn own_mm(&self) -> [f64; 4] {
        let [x, y, z] = self.exit_point_mm;
        [x, y, z, self.length_offset_mm]
    }

    /// Noise-free length (mm) for a tool point at `p_m` (base frame, m): the calibration's own
    /// [`Measurement::Length`] reading, distance + offset, taken in mm.
    pub fn ideal_length(&self, p_m: &Vector3<f64>) -> f64 {
        let mut y = [0.0];
        Measurement::Length.reading(&self.own_mm(), &crate::units::to_mm(p_m), &mut y);
        y[0]
    }

    /// Smooth linearity error at a true reading `l` (mm): zero at both range ends.
    pub fn linearity_error(&self, l: f64) -> f64 {
        let fs = self.range_mm[1] - self.range_mm[0];
        let u = ((l - self.range_mm[0]) / fs).clamp(0.0, 1.0);
        let linearity = self.linearity_pct_fs / 100.0 * fs * (2.0 * std::f64::consts::PI * u).sin();
        match &self.polynomial {
            Some(p) => linearity + p.at(l),
            None => linearity,
        }
    }

    /// One raw sample's noise, mm: Gaussian (`normal`), or Student-t of `noise_t_dof` degrees of
    /// freedom with the same standard deviation.
    fn noise<R: Rng>(&self, normal: &Normal<f64>, rng: &mut R) -> f64 {
        match self.noise_t_dof {
            None => normal.sample(rng),
            Some(nu) => {
                let t = rand_distr::StudentT::new(nu).map(|d| d.sample(rng)).unwrap_or(0.0);
                t * ((nu - 2.0) / nu).sqrt() * self.noise_std_mm
            }
        }
    }

    /// One raw sample for a true length `l` (mm): linearity error, noise, quantisation (no range check).
    pub fn raw_sample<R: Rng>(&self, l: f64, rng: &mut R) -> f64 {
        let mut s = l + self.linearity_error(l);
        if self.noise_std_mm > 0.0 {
            s += match self.noise_t_dof {
                None => self.noise_std_mm * rng.sample::<f64, _>(rand_distr::StandardNormal),
                Some(_) => self.noise(&Normal::new(0.0, self.noise_std_mm).expect("a finite std"), rng),
            };
        }
        if self.resolution_mm > 0.0 {
            s = (s / self.resolution_mm).round() * self.resolution_mm;
        }
        s
    }

    /// The averaged reading of raw samples whose true lengths (mm) are `lengths`, one per sample
    /// (a moving arm): each sample as in [`Self::read`]; out of range if any sample's signal is.
    pub fn read_series<R: Rng>(&self, lengths: &[f64], rng: &mut R) -> Result<f64, OutOfRange> {
        let normal = Normal::new(0.0, self.noise_std_mm.max(0.0)).map_err(|_| OutOfRange { value_mm: f64::NAN, range_mm: self.range_mm })?;
        let mut sum = 0.0;
        for l in lengths {
            let signal = l + self.linearity_error(*l);
            if !(self.range_mm[0]..=self.range_mm[1]).contains(&signal) {
                return Err(OutOfRange { value_mm: signal, range_mm: self.range_mm });
            }
            let mut s = signal + if self.noise_std_mm > 0.0 { self.noise(&normal, rng) } else { 0.0 };
            if self.resolution_mm > 0.0 {
                s = (s / self.resolution_mm).round() * self.resolution_mm;
            }
            sum += s;
        }
        Ok(sum / lengths.len().max(1) as f64)
    }

    /// The instrument's reading for a true length `l` (mm): linearity error, then `samples` noisy,
    /// quantised samples averaged. Out-of-range readings are errors, never clipped.
    pub fn read<R: Rng>(&self, l: f64, rng: &mut R) -> Result<f64, OutOfRange> {
        let signal = l + self.linearity_error(l);
        if !(self.range_mm[0]..=self.range_mm[1]).contains(&signal) {
            return Err(OutOfRange { value_mm: signal, range_mm: self.range_mm });
        }
        let normal = Normal::new(0.0, self.noise_std_mm.max(0.0)).map_err(|_| OutOfRange { value_mm: f64::NAN, range_mm: self.range_mm })?;
        let mut sum = 0.0;
        for _ in 0..self.samples {
            let mut s = signal + if self.noise_std_mm > 0.0 { self.noise(&normal, rng) } else { 0.0 };
            if self.resolution_mm > 0.0 {
                s = (s / self.resolution_mm).round() * self.resolution_mm;
            }
            sum += s;
        }
        Ok(sum / self.samples as f64)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Readings beyond the polynomial's range are counted and the farthest named; none beyond, no
    /// warning.
    #[test]
    fn readings_beyond_the_polynomials_range_are_counted() {
        let p = ReadingPolynomial { range_mm: [450.0, 500.0], legendre_mm: [0.05, 0.0, 0.0] };
        let w = p.beyond_range(&[440.0, 460.0, 499.0, 530.5]).expect("two readings beyond");
        assert!(w.contains("2 of 4 readings") && w.contains("the farthest 30.5 mm"), "{w}");
        assert_eq!(p.beyond_range(&[450.0, 475.0, 500.0]), None);
        // Beyond it the error holds its end value.
        assert_eq!(p.at(700.0), p.at(500.0));
    }
}
