//! What a calibration from a ball seated in an artifact's sockets reports beside the rows'
//! errors: each socket's centre and scatter, each stated spacing against the fitted one, and
//! what such rows cannot determine, said in words a user acts on.

use crate::calib::fit::Samples;
use crate::calib::model::CalibModel;
use crate::measurement::Measurement;
use serde::{Deserialize, Serialize};

/// One socket of one placement, as fitted.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SocketFit {
    /// Its station label (`placement/socket`).
    pub label: String,
    /// Training rows seated in it.
    pub rows: usize,
    /// Its centre in the base frame as the model places it, mm.
    pub centre_mm: [f64; 3],
    /// RMS distance of the modelled ball centres of its training rows from its centre, mm: how
    /// well the rows agree on one point.
    pub scatter_mm: f64,
}

/// A stated spacing and the one the fit reached.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SpacingFit {
    /// The two sockets' station labels.
    pub sockets: (String, String),
    /// The distance stated, mm.
    pub stated_mm: f64,
    /// The distance between the fitted centres, mm.
    pub fitted_mm: f64,
}

/// The artifact's part of a calibration's result.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ArtifactReport {
    /// What read rows beside the seated ones (a tracker's points), if anything.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub beside: Option<String>,
    /// The ball's centre on the flange as fitted, mm.
    pub ball_mm: [f64; 3],
    /// Every socket of every placement.
    pub sockets: Vec<SocketFit>,
    /// Every stated spacing.
    pub spacings: Vec<SpacingFit>,
    /// What rows of this kind cannot determine, each a sentence.
    pub cannot_see: Vec<String>,
}

impl ArtifactReport {
    /// The lines a summary prints.
    pub fn lines(&self) -> Vec<String> {
        let b = self.ball_mm;
        let mut out = vec![format!("ball's centre on the flange: ({:.3}, {:.3}, {:.3}) mm", b[0], b[1], b[2])];
        out.extend(self.beside.clone());
        for s in &self.sockets {
            out.push(format!("  socket {}: {} training rows, scatter {:.4} mm about its centre", s.label, s.rows, s.scatter_mm));
        }
        for s in &self.spacings {
            out.push(format!("  spacing {}-{}: stated {:.4} mm, fitted {:.4} mm", s.sockets.0, s.sockets.1, s.stated_mm, s.fitted_mm));
        }
        out.extend(self.cannot_see.iter().map(|c| format!("cannot see: {c}")));
        out
    }
}

/// The arm's parameters of `model` (named `names`, with their standard uncertainties `sd` and
/// units `unit`, display units; `None` where held) whose uncertainty exceeds their documented
/// `tolerances`: the pull toward the nominal holds them, not the rows.
pub fn loose(model: &CalibModel, params: &[(String, Option<f64>, String)], tolerances: &crate::calib::model::tolerance::Tolerances) -> Vec<String> {
    let prior = tolerances.prior_std(model);
    (0..model.n_chain().min(params.len()))
        .filter_map(|k| {
            let (name, sd, unit) = &params[k];
            sd.filter(|sd| *sd > model.display(k, prior[k])).map(|sd| format!("{name} (±{sd:.3} {unit})"))
        })
        .collect()
}

/// A ball nearer than this to the last joint's axis (mm) leaves that axis unseen.
pub const BALL_OFF_AXIS_MM: f64 = 20.0;

/// How far the ball sits from the last joint's axis (mm), at the first training row: half the
/// chord it moves through when that joint turns by a small angle, over the angle's sine.
fn off_last_axis_mm(model: &CalibModel, x: &[f64], train: &Samples) -> Option<f64> {
    let q = train.q.first()?.clone();
    let mut w = model.work();
    let h = 0.01;
    let (mut a, mut b) = (q.clone(), q);
    *a.last_mut()? += h;
    *b.last_mut()? -= h;
    let chord = (model.tool_point(x, &a, &mut w) - model.tool_point(x, &b, &mut w)).norm();
    Some(crate::units::to_mm(chord / (2.0 * h.sin())))
}

/// The report of `model` at `x` on its training rows `train`; `None` for another instrument.
/// `fixed`: the parameters the rows leave free (held at nominal); `loose`: the arm's parameters
/// they determine no better than their tolerance, each with its uncertainty ([`loose`]).
pub fn report(model: &CalibModel, x: &[f64], train: &Samples, fixed: &[String], loose: &[String]) -> Option<ArtifactReport> {
    if model.measurement != Measurement::Socket {
        return None;
    }
    let labels: Vec<String> = if model.stations.is_empty() { vec![String::new()] } else { model.stations.clone() };
    let mut w = model.work();
    let mut y = [0.0; crate::measurement::MAX_DIM];
    let sockets = labels
        .iter()
        .enumerate()
        .map(|(s, label)| {
            let rows: Vec<usize> = (0..train.len()).filter(|&i| train.inputs[i].station == s && train.inputs[i].instrument == 0).collect();
            let sq: f64 = rows
                .iter()
                .map(|&i| {
                    model.readings(x, &train.q[i], &train.inputs[i], &mut w, &mut y[..3]);
                    y[..3].iter().map(|v| v * v).sum::<f64>()
                })
                .sum();
            let c = model.station_placement(x, s).own;
            SocketFit {
                label: label.clone(),
                rows: rows.len(),
                centre_mm: [c[0], c[1], c[2]].map(crate::units::to_mm),
                scatter_mm: crate::units::to_mm((sq / rows.len().max(1) as f64).sqrt()),
            }
        })
        .collect();
    let spacings = (0..model.spacings.len())
        .map(|k| {
            let sp = &model.spacings[k];
            SpacingFit { sockets: (labels[sp.a].clone(), labels[sp.b].clone()), stated_mm: sp.mm, fitted_mm: model.spacing_mm(x, k) }
        })
        .collect();
    let ball = model.placement(x).tool;
    let shortest = model.spacings.iter().map(|s| s.mm).fold(f64::INFINITY, f64::min);
    let placements: std::collections::BTreeSet<&str> = labels.iter().map(|l| l.rsplit_once('/').map_or("", |(p, _)| p)).collect();
    let beside = (0..train.len()).filter(|&i| train.inputs[i].instrument == 1).count();
    let mut cannot_see = vec![
        "the base frame: every socket moves with it, so the arm is placed relative to its sockets, not to the robot's base (register a tracker, or touch points known in the base frame, to place it)".to_string(),
    ];
    if beside == 0 {
        cannot_see.push(format!(
            "the arm's scale beyond the stated spacing: an error of e mm in the stated {shortest:.1} mm scales every length by e/{shortest:.1} (0.01 mm: {:.0} ppm, {:.3} mm at 500 mm); state the spacing as made and at the artifact's temperature (PLA grows about 68 ppm/K)",
            0.01 / shortest * 1e6,
            0.01 / shortest * 500.0
        ));
    }
    if let Some(d) = off_last_axis_mm(model, x, train).filter(|d| *d < BALL_OFF_AXIS_MM) {
        cannot_see.push(format!(
            "the last joint's axis: the ball sits {d:.1} mm from it, so turning that joint hardly moves the ball and the wrist's last link is seen as one point (held by the tolerances' pull); put the ball {BALL_OFF_AXIS_MM:.0} mm or more off the flange's axis (an offset stylus) to see it"
        ));
    }
    if placements.len() < 2 {
        cannot_see.push("the arm away from this one placement of the artifact: place it at two or more places across the workspace".into());
    }
    if !fixed.is_empty() {
        cannot_see.push(format!("{} (held at nominal: the rows leave them free)", fixed.join(", ")));
    }
    if !loose.is_empty() {
        cannot_see.push(format!(
            "{}: the rows determine them no better than their documented tolerance, and the pull toward the nominal holds them{}",
            loose.join(", "),
            if loose.iter().any(|l| l.starts_with("joint_1.theta")) {
                " (joint 1's zero: a turn about the base's axis moves every socket with the arm)"
            } else {
                ""
            }
        ));
    }
    let beside_line = (beside > 0).then(|| {
        format!(
            "{beside} {} rows beside the seated ones: the arm's scale from them as well as from the spacings",
            model.also.map_or("other", |m| m.def().describe())
        )
    });
    Some(ArtifactReport { beside: beside_line, ball_mm: [ball.x, ball.y, ball.z].map(crate::units::to_mm), sockets, spacings, cannot_see })
}
