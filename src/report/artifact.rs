//! An artifact as the figures show it: its sockets or faces as fitted, the stated spacings, and
//! each feature's rows after the fit — how far each seated ball's centre lies from its socket's,
//! each stylus centre from where its face holds it — from a result's `artifact` and the rows.

use crate::calib::pipeline::artifact::ArtifactReport;
use crate::dataset::Dataset;
use crate::measurement::FeatureKind;

/// One socket or face with its rows.
#[derive(Clone, Debug, PartialEq)]
pub struct FeatureRows {
    /// Its station label (`placement/socket`, `placement/face`).
    pub label: String,
    /// Where it is, base frame, mm: a socket's centre, or the mean of the modelled stylus
    /// centres on a face.
    pub at_mm: [f64; 3],
    /// A face's unit normal (toward the probe's side); `None` for a socket.
    pub normal: Option<[f64; 3]>,
    /// The rows read at it (0-based, file order).
    pub rows: Vec<usize>,
    /// Each row's residual after the fit, µm: the distance of the ball's modelled centre from
    /// the socket's (never negative), or the stylus centre's signed distance from the face.
    pub after_um: Vec<f64>,
    /// RMS of the fit's rows about it, mm (the result's scatter).
    pub scatter_mm: f64,
}

/// What a figure draws of an artifact.
#[derive(Clone, Debug, PartialEq)]
pub struct ArtifactFigure {
    /// The features' kind.
    pub feature: FeatureKind,
    /// The ball's or stylus' centre on the flange, mm.
    pub target_mm: [f64; 3],
    /// Every socket or face, in the result's order.
    pub features: Vec<FeatureRows>,
    /// Every stated spacing: the two features' indices into `features`, stated and fitted, mm.
    pub spacings: Vec<(usize, usize, f64, f64)>,
    /// What the rows cannot determine, each a sentence.
    pub cannot_see: Vec<String>,
}

impl ArtifactFigure {
    /// The figure of result artifact `a` on `data`, whose rows have the residuals `after_mm`
    /// (`dim` values per row) and the modelled target points `tool_mm`.
    pub fn new(a: &ArtifactReport, data: &Dataset, after_mm: &[f64], dim: usize, tool_mm: &[[f64; 3]]) -> ArtifactFigure {
        let feature = |label: &String, at: Option<[f64; 3]>, normal: Option<[f64; 3]>, scatter_mm: f64| FeatureRows {
            label: label.clone(),
            at_mm: at.unwrap_or([0.0; 3]),
            normal,
            rows: Vec::new(),
            after_um: Vec::new(),
            scatter_mm,
        };
        let mut features: Vec<FeatureRows> = match a.feature {
            FeatureKind::Socket => a.sockets.iter().map(|s| feature(&s.label, Some(s.centre_mm), None, s.scatter_mm)).collect(),
            FeatureKind::Plane => a.faces.iter().map(|f| feature(&f.label, None, Some(f.normal), f.scatter_mm)).collect(),
        };
        for (i, row) in data.rows.iter().enumerate() {
            let Some(f) = &row.feature else { continue };
            let label = crate::dataset::feature_station(row.station.as_deref(), &f.label);
            // One feature only: the model named no stations.
            let Some(k) = features.iter().position(|x| x.label == label).or_else(|| (features.len() == 1).then_some(0)) else { continue };
            let r = &after_mm[(i * dim).min(after_mm.len())..((i + 1) * dim).min(after_mm.len())];
            if r.len() != dim || r.iter().any(|v| !v.is_finite()) {
                continue;
            }
            let um = match a.feature {
                FeatureKind::Socket => 1e3 * r.iter().map(|v| v * v).sum::<f64>().sqrt(),
                FeatureKind::Plane => 1e3 * r[0],
            };
            features[k].rows.push(i);
            features[k].after_um.push(um);
        }
        // A face is drawn where its rows touched it.
        for f in features.iter_mut().filter(|f| f.normal.is_some() && !f.rows.is_empty()) {
            let mut c = [0.0; 3];
            for &i in &f.rows {
                (0..3).for_each(|k| c[k] += tool_mm[i][k] / f.rows.len() as f64);
            }
            f.at_mm = c;
        }
        let index = |l: &str| features.iter().position(|f| f.label == l);
        let spacings = a.spacings.iter().filter_map(|s| Some((index(&s.sockets.0)?, index(&s.sockets.1)?, s.stated_mm, s.fitted_mm))).collect();
        ArtifactFigure { feature: a.feature, target_mm: a.target_mm, features, spacings, cannot_see: a.cannot_see.clone() }
    }

    /// The word for a feature (`socket`, `face`) and for the target (`ball`, `stylus`).
    pub fn words(&self) -> (&'static str, &'static str) {
        match self.feature {
            FeatureKind::Socket => ("socket", "ball"),
            FeatureKind::Plane => ("face", "stylus"),
        }
    }

    /// Each feature's placement, numbered in the order they first appear (0, 1, …): the part of
    /// its label before `/`.
    pub fn placement_numbers(&self) -> Vec<usize> {
        let mut seen: Vec<&str> = Vec::new();
        self.features
            .iter()
            .map(|f| {
                let p = f.label.split('/').next().unwrap_or("");
                seen.iter().position(|q| *q == p).unwrap_or_else(|| {
                    seen.push(p);
                    seen.len() - 1
                })
            })
            .collect()
    }

    /// The y-axis title of the rows' residuals.
    pub fn residual_axis(&self) -> &'static str {
        match self.feature {
            FeatureKind::Socket => "ball's centre from the socket's (µm)",
            FeatureKind::Plane => "stylus centre from the face (µm)",
        }
    }
}
