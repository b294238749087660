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

/// `v` rounded to `decimals` decimals, as an instrument writes it: the f64 nearest to the
/// decimal text `v` prints as with that precision, so the dataset writer prints it with at most
/// `decimals` decimals and reading it back gives the same value.
pub fn round_decimals(v: f64, decimals: usize) -> f64 {
    format!("{v:.decimals$}").parse().unwrap_or(v)
}

#[cfg(test)]
mod tests {
    use super::*;

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
