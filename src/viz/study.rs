//! Recording of `twincal study hold`: bias and spread of the readings' transient error against
//! the hold time (timeline `hold`), one series per approach speed.

use super::Recorder;
use crate::error::Result;
use crate::io::OutputSet;
use crate::twin::study::HoldStudyRow;
use std::path::Path;

/// Staged in `outputs` as `path`: `study/bias_um/speed_<v>`, `study/spread_um/speed_<v>` and
/// `study/max_um/speed_<v>` (µm) at each hold time, with `noise_floor_mm` (the averaged reading's
/// noise) in the legend.
pub fn record_hold_study(rows: &[HoldStudyRow], scenario: &str, noise_floor_mm: f64, outputs: &mut OutputSet, path: &Path) -> Result<()> {
    let mut rec = Recorder::staged("twincal", outputs, path)?;
    rec.static_text(
        "legend",
        &format!(
            "# twincal hold study `{scenario}`\n\nTimeline `hold`: the hold time, s. Per approach speed (fraction of the URDF \
             speed limits): `study/bias_um` the mean transient error of the readings (window mean of the noise-free length \
             minus that of the arm at rest), `study/spread_um` its standard deviation, `study/max_um` its largest magnitude, \
             all in µm. The averaged reading's noise is {:.2} µm.\n",
            noise_floor_mm * 1e3
        ),
    );
    let mut ordered: Vec<&HoldStudyRow> = rows.iter().collect();
    ordered.sort_by(|a, b| a.hold_s.total_cmp(&b.hold_s));
    for r in ordered {
        rec.set_time_seconds("hold", r.hold_s);
        let v = format!("speed_{:.2}", r.speed_fraction);
        rec.scalar(&format!("study/bias_um/{v}"), r.bias_mm * 1e3);
        rec.scalar(&format!("study/spread_um/{v}"), r.spread_mm * 1e3);
        rec.scalar(&format!("study/max_um/{v}"), r.max_mm * 1e3);
    }
    rec.finish()
}
