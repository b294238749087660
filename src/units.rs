//! Units at the code's boundaries. The code computes lengths in metres and angles in radians;
//! files, reports and messages speak millimetres and degrees. A length crosses that boundary
//! through [`to_mm`] or [`to_m`] (angles through `f64::to_degrees` / `to_radians`), so that a
//! factor of a thousand in the code is never a length conversion written as a bare number.

use std::ops::Mul;

/// Millimetres per metre.
pub const MM_PER_M: f64 = 1e3;

/// A length in metres (a number, a vector), in millimetres.
#[inline]
pub fn to_mm<T: Mul<f64>>(metres: T) -> T::Output {
    metres * 1e3
}

/// A length in millimetres (a number, a vector), in metres.
#[inline]
pub fn to_m<T: Mul<f64>>(millimetres: T) -> T::Output {
    millimetres * 1e-3
}

/// Decimals of the time column the twin writes (ms).
pub const T_DECIMALS: usize = 3;

/// `v` rounded to `decimals` decimals, as an instrument writes it: the f64 nearest to the
/// decimal text `v` prints as with that precision, so the dataset writer prints it with at most
/// `decimals` decimals and reading it back gives the same value.
pub fn round_decimals(v: f64, decimals: usize) -> f64 {
    format!("{v:.decimals$}").parse().unwrap_or(v)
}

/// `value ± uncertainty` with the decimals that show the uncertainty to two significant digits,
/// never fewer than four (`0.0010 ± 0.0000` of a size in thousandths of a degree says nothing;
/// `0.00097 ± 0.000040` does).
pub fn with_uncertainty(value: f64, uncertainty: f64) -> String {
    let decimals = if uncertainty.is_finite() && uncertainty > 0.0 { (1.0 - uncertainty.log10().floor()).clamp(4.0, 12.0) as usize } else { 4 };
    format!("{value:.decimals$} ± {uncertainty:.decimals$}")
}

/// A duration in seconds as a reader takes it in: seconds up to two minutes, minutes up to two
/// hours, hours beyond (`45 s`, `12.5 min`, `3.80 h`).
pub fn duration(s: f64) -> String {
    match s {
        s if s < 120.0 => format!("{s:.0} s"),
        s if s < 7200.0 => format!("{:.1} min", s / 60.0),
        s => format!("{:.2} h", s / 3600.0),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_duration_reads_in_its_unit() {
        assert_eq!([duration(45.2), duration(750.0), duration(13_680.0)], ["45 s", "12.5 min", "3.80 h"]);
    }

    #[test]
    fn an_uncertainty_is_shown_to_two_significant_digits() {
        assert_eq!(with_uncertainty(9.664, 0.3127), "9.6640 ± 0.3127");
        assert_eq!(with_uncertainty(0.000_972_49, 0.000_040_43), "0.000972 ± 0.000040");
        assert_eq!(with_uncertainty(1.5, f64::NAN), "1.5000 ± NaN");
    }

    #[test]
    fn lengths_convert_exactly_as_the_factors_they_replace() {
        for v in [0.1234567, -3.3, 1e-9, 1234.5] {
            assert_eq!(to_mm(v).to_bits(), (v * 1e3).to_bits());
            assert_eq!(to_m(v).to_bits(), (v * 1e-3).to_bits());
        }
        let p = nalgebra::Vector3::new(0.1, 0.2, 0.3);
        assert_eq!(to_m(to_mm(p)), p * 1e3 * 1e-3);
        assert_eq!(to_mm(&p), p * MM_PER_M);
    }
}
