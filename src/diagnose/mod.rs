//! `twincal diagnose`: from measured data alone (q, L and the optional t / temp columns), what
//! does the geometric model get wrong, which physical effect causes it, how big is it, and how
//! much better does the extended model predict rows it has not seen?
//!
//! 1. **Baseline.** The geometric model is calibrated (sensor placement unknown, as always).
//!    Rows far off the fit by a robust criterion (median ± k·1.4826·MAD of the residuals,
//!    iterated) are named as outliers and kept out of every fit and statistic.
//! 2. **Evidence.** The baseline residuals against per-row features: joint torques, their
//!    signs, approach directions, time, temperature, joint-angle harmonics, the reading.
//! 3. **Forward selection.** Every candidate effect block ([`crate::calib::effects`]) is added in
//!    turn, everything is refitted, and its held-out gain measured by cross-validation over
//!    contiguous blocks of acquisition order (so time-dependent effects must extrapolate). Its
//!    significance is the F test of the nested least-squares fits on every kept row,
//!    Bonferroni-corrected for the number of candidates. The candidate with the lowest held-out
//!    RMSE among those that are significant, gain at least `min_gain` and stay of a physical
//!    size ([`IMPLAUSIBLE`]) is kept, and the search repeats until nothing is left to gain.
//! 4. **Sizes.** Each kept effect's size with its standard uncertainty, in physical units.
//!
//! Nothing here reads how the data were made.

pub mod faults;
mod fit;
pub mod forward;
pub mod hidden;
mod options;
mod pipeline;
pub mod remainder;
mod report;
mod screen;
mod select;
#[cfg(test)]
mod tests;

pub use fit::{implausible_param, unphysical_causes, EXTRAPOLATION_FACTOR, IMPLAUSIBLE, WARM_UP_TAU_S};
pub use options::*;
pub use pipeline::diagnose;
pub use report::*;
pub use screen::{EFFECT_SCREEN_MAX_SCALE, EFFECT_SCREEN_MIN_ROWS, EFFECT_SCREEN_MIN_SHARE, EFFECT_SCREEN_TIGHTER};
pub use select::BELOW_FLOOR_SHARE;
