//! Recording of `twincal study hold`: the readings' transient error (bias, spread, largest
//! magnitude) against the hold time, one coloured series per approach speed, and the study's
//! table. Static: the hold times are the plots' categories (they usually span two decades).

use super::plot::{padded_range, Plot};
use super::scenes::PALETTE;
use super::{Blueprint, Layout, Recorder, ViewKind as K};
use std::path::Path;
use twincal::error::Result;
use twincal::output::OutputSet;
use twincal::sim::study::HoldStudyRow;

/// The three quantities plotted: entity name, view title, value of a row in µm.
type Quantity = (&'static str, &'static str, fn(&HoldStudyRow) -> f64);

const QUANTITIES: [Quantity; 3] = [
    ("bias_um", "Bias of the readings (µm) against the hold time", |r| r.bias_mm * 1e3),
    ("spread_um", "Spread (standard deviation, µm) against the hold time", |r| r.spread_mm * 1e3),
    ("max_um", "Largest |error| (µm) against the hold time", |r| r.max_mm * 1e3),
];

/// Names of [`PALETTE`]'s colours, for the table.
const COLOUR_NAMES: [&str; 10] = ["blue", "orange", "green", "red", "purple", "brown", "pink", "grey", "olive", "cyan"];

/// Staged in `outputs` as `path`: `study/<quantity>/frame` and per approach speed
/// `study/<quantity>/speed_<v>/{points,line}` and `study/<quantity>/legend` for `bias_um`, `spread_um` and `max_um`, plus the
/// markdown table `docs/table` with the colour of each speed and the reading noise.
pub fn record_hold_study(rows: &[HoldStudyRow], scenario: &str, noise_floor_mm: f64, outputs: &mut OutputSet, path: &Path) -> Result<()> {
    let mut rec = Recorder::staged("twincal", outputs, path)?;
    rec.set_static(true);
    let mut holds: Vec<f64> = rows.iter().map(|r| r.hold_s).collect();
    holds.sort_by(f64::total_cmp);
    holds.dedup();
    let mut speeds: Vec<f64> = rows.iter().map(|r| r.speed_fraction).collect();
    speeds.sort_by(f64::total_cmp);
    speeds.dedup();
    // Each speed's rows in hold order (the table and every plot walk them alike).
    let series: Vec<Vec<&HoldStudyRow>> = speeds
        .iter()
        .map(|v| {
            let mut mine: Vec<&HoldStudyRow> = rows.iter().filter(|r| r.speed_fraction == *v).collect();
            mine.sort_by(|a, b| a.hold_s.total_cmp(&b.hold_s));
            mine
        })
        .collect();
    let names: Vec<String> = holds.iter().map(|h| format!("{h} s")).collect();
    let column = |h: f64| holds.iter().position(|x| *x == h).unwrap_or(0) as f64;

    let mut doc = format!(
        "# Hold study `{scenario}`\n\nTransient error of the readings (window mean of the noise-free length minus that of the \
         arm at rest), in µm, against the hold time, per approach speed (fraction of the URDF speed limits). Readings are \
         taken even when the stability gate is still closed. The averaged reading's noise, not included, is {:.2} µm.\n\n\
         | speed | colour | hold s | bias µm | spread µm | max µm | gate closed | gate s (median) | s/pose |\n|---|---|---|---|---|---|---|---|---|\n",
        noise_floor_mm * 1e3
    );
    for (k, (v, mine)) in speeds.iter().zip(&series).enumerate() {
        for r in mine {
            doc.push_str(&format!(
                "| {:.2} | {} | {} | {:.3} | {:.3} | {:.3} | {}/{} | {} | {:.2} |\n",
                v,
                COLOUR_NAMES[k % COLOUR_NAMES.len()],
                r.hold_s,
                r.bias_mm * 1e3,
                r.spread_mm * 1e3,
                r.max_mm * 1e3,
                r.gate_closed,
                r.poses,
                r.median_gate_s.map(|g| format!("{g:.3}")).unwrap_or_else(|| "-".into()),
                r.time_per_pose_s
            ));
        }
    }
    rec.static_text("docs/table", &doc);

    for (what, title, value) in QUANTITIES {
        let Some(y) = padded_range(rows.iter().map(value).chain([0.0]), 0.1) else { continue };
        let plot = Plot::categories(title, &names, "µm", y);
        let base = format!("study/{what}");
        plot.frame(&mut rec, &base);
        for (k, (v, mine)) in speeds.iter().zip(&series).enumerate() {
            let c = PALETTE[k % PALETTE.len()];
            let xy: Vec<[f64; 2]> = mine.iter().map(|r| [column(r.hold_s), value(r)]).collect();
            let labels: Vec<String> =
                mine.iter().map(|r| format!("speed {v:.2}, hold {} s: {:.3} µm ({}/{} gates closed)", r.hold_s, value(r), r.gate_closed, r.poses)).collect();
            let series = format!("{base}/speed_{v:.2}");
            plot.scatter(&mut rec, &format!("{series}/points"), &xy, &[c], 4.0, &labels);
            let line: Vec<[f64; 2]> = xy.iter().map(|p| plot.map(p[0], p[1].clamp(plot.y.0, plot.y.1))).collect();
            rec.line_strips2d(&format!("{series}/line"), &[line], &[c], 1.5);
        }
        // Legend in the plot's top-right corner, one labelled dot per speed.
        let pos: Vec<[f64; 2]> = (0..speeds.len()).map(|k| [super::plot::PLOT_W - 70.0, 14.0 + 16.0 * k as f64]).collect();
        let colors: Vec<[u8; 4]> = (0..speeds.len()).map(|k| PALETTE[k % PALETTE.len()]).collect();
        let labels: Vec<String> = speeds.iter().map(|v| format!("speed {v:.2}")).collect();
        rec.points2d(&format!("{base}/legend"), &pos, Some(&colors), Some(0.5), Some(&labels), true);
    }
    rec.set_static(false);
    rec.layout(Blueprint {
        root: Layout::Vertical(
            vec![
                Layout::Horizontal(
                    vec![
                        Layout::plot("Bias (µm) vs hold time; one colour per approach speed", "/study/bias_um"),
                        Layout::plot("Spread (µm) vs hold time", "/study/spread_um"),
                        Layout::plot("Largest |error| (µm) vs hold time", "/study/max_um"),
                    ],
                    vec![],
                ),
                Layout::view(K::Text, "Hold study: table and colours", "/docs"),
            ],
            vec![1.3, 1.0],
        ),
        timeline: None,
        at_end: false,
    });
    rec.finish()
}
