//! What a calibration from an artifact reports beside the rows' errors: each socket's centre
//! and scatter (each face's normal, offset and scatter), each stated spacing (step) against the
//! fitted one, and what such rows cannot determine, said in words a user acts on.

use crate::calib::fit::Samples;
use crate::calib::model::CalibModel;
use crate::measurement::FeatureKind;
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

/// One face of one placement, as fitted.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct FaceFit {
    /// Its station label (`placement/face`).
    pub label: String,
    /// Training rows on it.
    pub rows: usize,
    /// Its unit normal in the base frame (toward the probe's side).
    pub normal: [f64; 3],
    /// Its offset along the normal from the base frame's origin, with the stylus' radius and
    /// pre-travel, mm.
    pub offset_mm: f64,
    /// RMS distance of the modelled stylus centres of its training rows from where the face
    /// holds them, mm.
    pub scatter_mm: f64,
}

/// A stated spacing and the one the fit reached.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SpacingFit {
    /// The two sockets' (faces') station labels.
    pub sockets: (String, String),
    /// The distance stated, mm.
    pub stated_mm: f64,
    /// The distance between the fitted centres, mm.
    pub fitted_mm: f64,
    /// The stated standard uncertainty, mm, where one was given.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub std_mm: Option<f64>,
}

/// The artifact's part of a calibration's result.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ArtifactReport {
    /// What read rows beside the seated ones (a tracker's points), if anything.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub beside: Option<String>,
    /// The features' kind.
    pub feature: FeatureKind,
    /// The target on the flange as fitted (the ball's centre, the stylus' centre), mm.
    pub target_mm: [f64; 3],
    /// Every socket of every placement.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub sockets: Vec<SocketFit>,
    /// Every face of every placement.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub faces: Vec<FaceFit>,
    /// Every stated spacing.
    pub spacings: Vec<SpacingFit>,
    /// What rows of this kind cannot determine, each a sentence.
    pub cannot_see: Vec<String>,
    /// Where the stated spacings between sockets and the stated steps between faces give the
    /// arm scales apart beyond what their scatter explains: the sentence that says so.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub disagreement: Option<String>,
}

impl ArtifactReport {
    /// The lines a summary prints.
    pub fn lines(&self) -> Vec<String> {
        let b = self.target_mm;
        let (target, spacing) = match self.feature {
            FeatureKind::Socket => ("ball's centre", "spacing"),
            FeatureKind::Plane => ("stylus' centre (indicator's zero point)", "step"),
        };
        let mut out = vec![format!("{target} on the flange: ({:.3}, {:.3}, {:.3}) mm", b[0], b[1], b[2])];
        out.extend(self.beside.clone());
        for s in &self.sockets {
            out.push(format!("  socket {}: {} training rows, scatter {:.4} mm about its centre", s.label, s.rows, s.scatter_mm));
        }
        for f in &self.faces {
            let n = f.normal;
            out.push(format!(
                "  face {}: {} training rows, normal ({:.4}, {:.4}, {:.4}), scatter {:.4} mm about it",
                f.label, f.rows, n[0], n[1], n[2], f.scatter_mm
            ));
        }
        for s in &self.spacings {
            let sd = s.std_mm.map_or(String::new(), |sd| format!(" ± {sd:.4}"));
            out.push(format!("  {spacing} {}-{}: stated {:.4}{sd} mm, fitted {:.4} mm", s.sockets.0, s.sockets.1, s.stated_mm, s.fitted_mm));
        }
        out.extend(self.cannot_see.iter().map(|c| format!("cannot see: {c}")));
        out.extend(self.disagreement.iter().map(|d| format!("stated distances disagree: {d}")));
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

/// The report of `model` at `x` on its training rows `train`; `None` for an instrument at no
/// artifact's feature. `fixed`: the parameters the rows leave free (held at nominal); `loose`:
/// the arm's parameters they determine no better than their tolerance, each with its
/// uncertainty ([`loose`]).
pub fn report(model: &CalibModel, x: &[f64], train: &Samples, fixed: &[String], loose: &[String]) -> Option<ArtifactReport> {
    let feature = model.measurement.feature()?;
    let labels: Vec<String> = if model.stations.is_empty() { vec![String::new()] } else { model.stations.clone() };
    let mut w = model.work();
    let mut y = [0.0; crate::measurement::MAX_DIM];
    let dim = train.dim;
    // Faces touched beside sockets seated stand at stations of the same list.
    let shared = model.also.is_some_and(|m| model.shares_stations_with(m));
    let (mut sockets, mut faces) = (Vec::new(), Vec::new());
    for (s, label) in labels.iter().enumerate() {
        let rows: Vec<usize> = (0..train.len()).filter(|&i| train.inputs[i].station == s && (shared || train.inputs[i].instrument == 0)).collect();
        let sq: f64 = rows
            .iter()
            .map(|&i| {
                model.readings(x, &train.q[i], &train.inputs[i], &mut w, &mut y[..dim]);
                (0..train.width(i)).map(|k| (y[k] - train.y[i * dim + k]).powi(2)).sum::<f64>()
            })
            .sum();
        let scatter_mm = crate::units::to_mm((sq / rows.len().max(1) as f64).sqrt());
        let c = model.station_placement(x, s).own;
        let face = shared && rows.iter().any(|&i| train.inputs[i].instrument == 1);
        match if face { FeatureKind::Plane } else { feature } {
            FeatureKind::Socket => {
                sockets.push(SocketFit { label: label.clone(), rows: rows.len(), centre_mm: [c[0], c[1], c[2]].map(crate::units::to_mm), scatter_mm })
            }
            FeatureKind::Plane => {
                let n = crate::measurement::plane::normal(c[0], c[1]).0;
                faces.push(FaceFit { label: label.clone(), rows: rows.len(), normal: [n.x, n.y, n.z], offset_mm: crate::units::to_mm(c[2]), scatter_mm })
            }
        }
    }
    let spacings = (0..model.spacings.len())
        .map(|k| {
            let sp = &model.spacings[k];
            SpacingFit { sockets: (labels[sp.a].clone(), labels[sp.b].clone()), stated_mm: sp.mm, fitted_mm: model.spacing_mm(x, k), std_mm: sp.std_mm }
        })
        .collect();
    let target = model.placement(x).tool;
    let beside = (0..train.len()).filter(|&i| train.inputs[i].instrument == 1).count();
    let cannot_see = cannot_see(model, x, train, feature, &labels, (fixed, loose), if shared { 0 } else { beside });
    let beside_line = (beside > 0).then(|| match shared {
        true => format!(
            "{beside} rows of a {} beside the seated ones, the same ball: the faces are stations beside the sockets, each instrument weighted by its own scatter ({})",
            model.also.map_or("other", |m| m.def().describe()),
            instrument_scatter(model, x, train)
        ),
        false => format!(
            "{beside} {} rows beside the artifact's: the arm's scale from them as well as from the spacings",
            model.also.map_or("other", |m| m.def().describe())
        ),
    });
    Some(ArtifactReport {
        beside: beside_line,
        feature,
        target_mm: [target.x, target.y, target.z].map(crate::units::to_mm),
        sockets,
        faces,
        disagreement: disagreement(model, x),
        spacings,
        cannot_see,
    })
}

/// How many standard errors of their means the spacings' and the steps' relative misfits must
/// lie apart to be said to disagree (with three placements a mean's error has two degrees of
/// freedom); they must also lie apart by [`DISAGREE_STATED`] times what the distances' stated
/// uncertainties allow.
pub const DISAGREE_SE: f64 = 4.0;

/// See [`DISAGREE_SE`].
pub const DISAGREE_STATED: f64 = 3.0;

/// Where sockets' spacings and faces' steps stand in one fit: the sentence saying that the
/// scale each kind gives (its mean relative misfit, fitted over stated) differs beyond
/// [`DISAGREE_SE`] standard errors and [`DISAGREE_STATED`] times the stated uncertainties
/// (relative, each kind's mean; [`crate::calib::model::SPACING_SD_MM`] where none is stated);
/// `None` where they agree or one kind is absent.
fn disagreement(model: &CalibModel, x: &[f64]) -> Option<String> {
    let of = |step: bool| -> Vec<(f64, f64)> {
        (0..model.spacings.len())
            .filter(|&k| model.spacings[k].is_step() == step)
            .map(|k| {
                let sp = &model.spacings[k];
                (1e6 * (model.spacing_mm(x, k) / sp.mm - 1.0), 1e6 * sp.sd_mm() / sp.mm)
            })
            .collect()
    };
    let stats = |v: &[(f64, f64)]| -> (f64, f64, f64) {
        let n = v.len() as f64;
        let m = v.iter().map(|e| e.0).sum::<f64>() / n;
        let sd = if v.len() > 1 { (v.iter().map(|e| (e.0 - m).powi(2)).sum::<f64>() / (n - 1.0)).sqrt() } else { 0.0 };
        (m, sd / n.sqrt(), v.iter().map(|e| e.1).sum::<f64>() / n)
    };
    let (s, f) = (of(false), of(true));
    if s.is_empty() || f.is_empty() {
        return None;
    }
    let ((ms, ses, us), (mf, sef, uf)) = (stats(&s), stats(&f));
    let gap = (ms - mf).abs();
    (gap > DISAGREE_STATED * (us * us + uf * uf).sqrt() && gap > DISAGREE_SE * (ses * ses + sef * sef).sqrt()).then(|| {
        format!(
            "the sockets' spacings come out {ms:+.0} ppm off their stated values and the faces' steps {mf:+.0} ppm ({gap:.0} ppm apart, {:.1} standard errors; the stated uncertainties allow {:.0} ppm): one of them is not as stated, and the fit's scale lies between them; state each as made and at its temperature, with its uncertainty (--spacing-mm A:B=50±0.02 for a printed plate)",
            gap / (ses * ses + sef * sef).sqrt().max(1e-9),
            (us * us + uf * uf).sqrt()
        )
    })
}

/// Each instrument's robust residual spread at `x` on the rows `train` (values it holds), as
/// "seated 0.0094 mm, faces 0.0004 mm".
fn instrument_scatter(model: &CalibModel, x: &[f64], train: &Samples) -> String {
    let r = crate::calib::fit::ReadingFit { model, data: &train.unweighted() }.residuals_mm(x);
    let sd = |g: usize| crate::stats::robust_scale(&train.values_of(&r, g, 0..train.len())).1;
    format!("robust sd: seated {:.4} mm, faces {:.4} mm", sd(0), sd(1))
}

/// What the artifact's rows cannot determine, each a sentence ([`ArtifactReport::cannot_see`]):
/// `held` the parameters left free and those held by the pull ([`loose`]).
fn cannot_see(
    model: &CalibModel,
    x: &[f64],
    train: &Samples,
    feature: FeatureKind,
    labels: &[String],
    held: (&[String], &[String]),
    beside: usize,
) -> Vec<String> {
    let (fixed, loose) = held;
    let (many, spacing, moves) = match feature {
        FeatureKind::Socket => ("sockets", "spacing", "every socket moves with it"),
        FeatureKind::Plane => ("faces", "step", "every face moves with it"),
    };
    let shortest = model.spacings.iter().map(|s| s.mm).fold(f64::INFINITY, f64::min);
    let placements: std::collections::BTreeSet<&str> = labels.iter().map(|l| l.rsplit_once('/').map_or("", |(p, _)| p)).collect();
    let mut out = vec![format!(
        "the base frame: {moves}, so the arm is placed relative to its {many}, not to the robot's base (register a tracker, or touch points known in the base frame, to place it)"
    )];
    if beside == 0 {
        out.push(format!(
            "the arm's scale beyond the stated {spacing}: an error of e mm in the stated {shortest:.1} mm scales every length by e/{shortest:.1} (0.01 mm: {:.0} ppm, {:.3} mm at 500 mm); state it as made and at the artifact's temperature (PLA grows about 68 ppm/K, steel 12)",
            0.01 / shortest * 1e6,
            0.01 / shortest * 500.0
        ));
    }
    if let Some(d) = off_last_axis_mm(model, x, train).filter(|d| *d < BALL_OFF_AXIS_MM) {
        let what = if feature == FeatureKind::Socket { "ball" } else { "stylus" };
        out.push(format!(
            "the last joint's axis: the {what} sits {d:.1} mm from it, so turning that joint hardly moves the {what} and the wrist's last link is seen as one point (held by the tolerances' pull); put the {what} {BALL_OFF_AXIS_MM:.0} mm or more off the flange's axis (an offset stylus) to see it"
        ));
    }
    if placements.len() < 2 {
        out.push("the arm away from this one placement of the artifact: place it at two or more places across the workspace".into());
    }
    if !fixed.is_empty() {
        out.push(format!("{} (held at nominal: the rows leave them free)", fixed.join(", ")));
    }
    if !loose.is_empty() {
        out.push(format!(
            "{}: the rows determine them no better than their documented tolerance, and the pull toward the nominal holds them{}",
            loose.join(", "),
            if loose.iter().any(|l| l.starts_with("joint_1.theta")) {
                format!(" (joint 1's zero: a turn about the base's axis moves every {} with the arm)", &many[..many.len() - 1])
            } else {
                String::new()
            }
        ));
    }
    out
}
