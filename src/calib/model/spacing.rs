//! Known distances between features of one artifact: residual blocks on two stations' own
//! parameters alone, no row behind them. Sockets seated by a ball (faces touched by a probe) fix
//! where the features are relative to the arm, not how large the arm is (the whole arm, the ball
//! and the sockets scaled together read the same); a known spacing between two sockets of one
//! placement, or a known step between two parallel faces, is what gives the arm its scale.

use super::{CalibModel, SetupKind};
use crate::measurement::FeatureKind;
use nalgebra::Vector3;
use serde::{Deserialize, Serialize};

/// A known distance between the sockets of stations `a` and `b` (one placement of one artifact).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Spacing {
    /// The first socket's station (index into the model's stations).
    pub a: usize,
    /// The second socket's station.
    pub b: usize,
    /// The distance between their centres (two faces: between the faces) as the artifact was
    /// made, mm.
    pub mm: f64,
    /// Where a step between faces is taken (base frame, m): the point of the second face
    /// nearest this one, measured from the first face along its normal. Near the artifact (the
    /// second face's contacts' middle at the start), so that a lean of the faces' normals does
    /// not trade for a step across the cell. Unused between sockets.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub at: Option<[f64; 3]>,
    /// Its standard uncertainty as stated, mm; `None`: [`SPACING_SD_MM`].
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub std_mm: Option<f64>,
}

impl Spacing {
    /// Whether it is a step between two faces (taken at [`Self::at`]) rather than a distance
    /// between two sockets' centres.
    pub fn is_step(&self) -> bool {
        self.at.is_some()
    }
    /// Its standard uncertainty, mm (as stated, else [`SPACING_SD_MM`]).
    pub fn sd_mm(&self) -> f64 {
        self.std_mm.unwrap_or(SPACING_SD_MM)
    }
    /// What one millimetre of its misfit weighs in its residual ([`SPACING_SD_MM`] per stated
    /// standard uncertainty; 1 without one).
    fn weight(&self) -> f64 {
        SPACING_SD_MM / self.sd_mm()
    }
    /// Its residuals: a distance's one, a step's three (the step and the faces' lean).
    fn residuals(&self) -> usize {
        if self.is_step() {
            3
        } else {
            1
        }
    }
}

/// A pull of one parameter toward its nominal value, one standard deviation `std` (internal
/// units) apart: a prior from the documented tolerances, for rows that leave some directions of
/// the arm nearly free (a ball on the last joint's axis sees no part of the wrist beyond one
/// point, so its links' parameters could wander by tens of degrees along a valley the rows cannot
/// tell from the bottom). Its residual is [`PULL_SCALE_MM`] per standard deviation.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Pull {
    /// The parameter's index.
    pub k: usize,
    /// Its nominal value, internal units.
    pub to: f64,
    /// One standard deviation, internal units.
    pub std: f64,
}

/// The residual (mm) of a pull one standard deviation off: a seated ball's scatter, so that a
/// tolerance's worth of departure weighs as one seating does.
pub const PULL_SCALE_MM: f64 = 0.001;

/// How far apart (mm) the two faces of a stated step may lean, per radian between their
/// normals: the residual of two normals one radian apart is this many millimetres (a gauge
/// block's faces are parallel within a micrometre over its length).
pub const PARALLEL_LEVER_MM: f64 = 100.0;

impl CalibModel {
    /// Residuals beside the rows': the spacings' ([`Spacing`]), then the pulls' ([`Pull`]).
    pub fn n_block_residuals(&self) -> usize {
        self.n_spacing_residuals() + self.pulls.len()
    }

    /// The spacings' residuals: one per spacing between sockets (the distance), three per step
    /// between faces (the step and the faces' lean from parallel, two angles).
    pub fn n_spacing_residuals(&self) -> usize {
        self.spacings.iter().map(Spacing::residuals).sum()
    }

    /// The pulls' residuals (mm) into `r`, one per pull.
    pub fn pull_residuals(&self, x: &[f64], r: &mut [f64]) {
        for (p, rk) in self.pulls.iter().zip(r.iter_mut()) {
            *rk = PULL_SCALE_MM * (p.to - x[p.k]) / p.std;
        }
    }

    /// The first three own parameters of station `s`'s feature (a socket's centre, m; a face's
    /// normal angles and offset) and their indices.
    fn feature_own(&self, x: &[f64], s: usize) -> (Vector3<f64>, [usize; 3]) {
        debug_assert!(self.measurement.feature().is_some());
        let start = if s == 0 { self.placement_range().start } else { self.setup_block(SetupKind::Station, s).start };
        let cols = [start, start + 1, start + 2];
        (Vector3::new(x[cols[0]], x[cols[1]], x[cols[2]]), cols)
    }

    /// The distance (mm) between the features of spacing `k` at `x`: two sockets' centres, or
    /// two parallel faces (the step: the second face's point nearest [`Spacing::at`], from the first along its normal).
    pub fn spacing_mm(&self, x: &[f64], k: usize) -> f64 {
        let sp = &self.spacings[k];
        let ((a, _), (b, _)) = (self.feature_own(x, sp.a), self.feature_own(x, sp.b));
        if sp.is_step() {
            crate::units::to_mm(self.step_m(x, k).0.abs())
        } else {
            crate::units::to_mm((a - b).norm())
        }
    }

    /// The signed step of spacing `k` between two faces (m): the second face's point nearest
    /// [`Spacing::at`], measured from the first face along its normal; and its derivatives with
    /// respect to the faces' own parameters (first face's three, second's three).
    fn step_m(&self, x: &[f64], k: usize) -> (f64, [f64; 6]) {
        use crate::measurement::plane::normal;
        let sp = &self.spacings[k];
        let ((a, _), (b, _)) = (self.feature_own(x, sp.a), self.feature_own(x, sp.b));
        let (na, daa, dab) = normal(a.x, a.y);
        let (nb, dba, dbb) = normal(b.x, b.y);
        let r = Vector3::from(sp.at.unwrap_or([0.0; 3]));
        let lift = b.z - nb.dot(&r);
        let pb = r + nb * lift;
        let s = na.dot(&pb) - a.z;
        let dpb = |dn: &Vector3<f64>| nb * (-dn.dot(&r)) + dn * lift;
        (s, [daa.dot(&pb), dab.dot(&pb), -1.0, na.dot(&dpb(&dba)), na.dot(&dpb(&dbb)), na.dot(&nb)])
    }

    /// The spacings' residuals (mm: known minus modelled distance; a step's faces' lean from
    /// parallel after it) into `r`, [`Self::n_spacing_residuals`] of them.
    pub fn spacing_residuals(&self, x: &[f64], r: &mut [f64]) {
        let mut at = 0;
        for (k, sp) in self.spacings.iter().enumerate() {
            // (A buffer of the rows' residuals alone has no room for them.)
            let Some(rk) = r.get_mut(at..at + sp.residuals()) else { return };
            at += sp.residuals();
            rk[0] = sp.weight() * (sp.mm - self.spacing_mm(x, k));
            if sp.is_step() {
                let sp = &self.spacings[k];
                let ((a, _), (b, _)) = (self.feature_own(x, sp.a), self.feature_own(x, sp.b));
                rk[1] = PARALLEL_LEVER_MM * (b.x - a.x).sin() * a.y.cos();
                rk[2] = PARALLEL_LEVER_MM * (b.y - a.y);
            }
        }
    }

    /// The spacings' residuals' derivatives (mm per parameter unit) into `jac`, row-major, one
    /// row of [`Self::n_params`] per residual.
    pub fn spacing_jacobian(&self, x: &[f64], jac: &mut [f64]) {
        let n = self.n_params();
        jac.iter_mut().take(n * self.n_spacing_residuals()).for_each(|v| *v = 0.0);
        let mut at = 0;
        for (k, sp) in self.spacings.iter().enumerate() {
            let block = &mut jac[at * n..(at + sp.residuals()) * n];
            at += sp.residuals();
            let ((pa, ca), (pb, cb)) = (self.feature_own(x, sp.a), self.feature_own(x, sp.b));
            if !sp.is_step() {
                let d = pa - pb;
                let u = d / d.norm().max(1e-12);
                for i in 0..3 {
                    block[ca[i]] -= sp.weight() * crate::units::MM_PER_M * u[i];
                    block[cb[i]] += sp.weight() * crate::units::MM_PER_M * u[i];
                }
                continue;
            }
            // The step's residual is stated − |step|.
            let (s, ds) = self.step_m(x, k);
            let sign = if s >= 0.0 { 1.0 } else { -1.0 };
            for i in 0..3 {
                block[ca[i]] -= sp.weight() * crate::units::MM_PER_M * sign * ds[i];
                block[cb[i]] -= sp.weight() * crate::units::MM_PER_M * sign * ds[3 + i];
            }
            let (da, ca_b) = ((pb.x - pa.x).cos() * pa.y.cos(), (pb.x - pa.x).sin() * pa.y.sin());
            block[n + cb[0]] += PARALLEL_LEVER_MM * da;
            block[n + ca[0]] -= PARALLEL_LEVER_MM * da;
            block[n + ca[1]] -= PARALLEL_LEVER_MM * ca_b;
            block[2 * n + cb[1]] += PARALLEL_LEVER_MM;
            block[2 * n + ca[1]] -= PARALLEL_LEVER_MM;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::calib::model::{DrawWireGuess, Placement};
    use crate::measurement::Measurement;
    use crate::robot::Robot;

    #[test]
    fn step_derivatives_match_finite_differences() {
        let guess = DrawWireGuess { exit_m: [0.0; 3], offset_m: 0.0, tool_m: [0.0; 3] };
        let face = Placement { measurement: Measurement::Plane, own: vec![0.5, 0.6, 0.2], tool: Vector3::new(0.0, 0.0, 0.05) };
        let model = CalibModel::dh(&Robot::irb120(), &guess, true).with_placement(&face);
        let mut model = model.with_setups((vec!["p/a".into(), "p/b".into()], &[vec![0.52, 0.57, 0.226]]), (Vec::new(), &[]));
        model.spacings = vec![Spacing { a: 0, b: 1, mm: 25.0, at: Some([0.45, 0.12, 0.25]), std_mm: Some(0.004) }];
        let (x, n) = (model.nominal.clone(), model.n_params());
        assert_eq!(model.n_spacing_residuals(), 3);
        let mut jac = vec![0.0; 3 * n];
        model.spacing_jacobian(&x, &mut jac);
        let mut r0 = [0.0; 3];
        model.spacing_residuals(&x, &mut r0);
        let step = model.spacing_mm(&x, 0);
        assert!((r0[0] - 0.25 * (25.0 - step)).abs() < 1e-9 && step > 0.0, "25 stated, {step} fitted: {r0:?}");
        let h = 1e-7;
        for p in 0..n {
            let (mut a, mut b) = (x.clone(), x.clone());
            a[p] += h;
            b[p] -= h;
            let (mut ra, mut rb) = ([0.0; 3], [0.0; 3]);
            model.spacing_residuals(&a, &mut ra);
            model.spacing_residuals(&b, &mut rb);
            for k in 0..3 {
                let fd = (ra[k] - rb[k]) / (2.0 * h);
                assert!((fd - jac[k * n + p]).abs() < 1e-4, "step residual {k} d/d{}: {fd} vs {}", model.names[p], jac[k * n + p]);
            }
        }
    }

    #[test]
    fn a_stated_uncertainty_is_read_written_and_weighs_the_residual() {
        for text in ["A:B=50±0.02", "A:B=50+-0.02", " A : B = 50 ± 0.02 "] {
            let k: KnownSpacing = text.parse().unwrap();
            assert_eq!(k, KnownSpacing { sockets: Some(("A".into(), "B".into())), mm: 50.0, std_mm: Some(0.02) }, "{text}");
            assert_eq!(k.to_string().parse::<KnownSpacing>().unwrap(), k);
        }
        assert_eq!("25".parse::<KnownSpacing>().unwrap().std_mm, None);
        for bad in ["A:B=50±", "A:B=50±x", "A:B=50±0", "A:B=50±-1", "A:B=50±60"] {
            let e = bad.parse::<KnownSpacing>().unwrap_err().to_string();
            assert!(e.contains("uncertainty after ±"), "{bad}: {e}");
        }
        // One stated standard uncertainty off weighs as SPACING_SD_MM of residual.
        let sp = Spacing { a: 0, b: 1, mm: 50.0, at: None, std_mm: Some(0.02) };
        assert!((sp.weight() * 0.02 - SPACING_SD_MM).abs() < 1e-15);
        assert_eq!(Spacing { std_mm: None, ..sp }.weight(), 1.0);
    }

    #[test]
    fn spacing_derivatives_match_finite_differences() {
        let guess = DrawWireGuess { exit_m: [0.0; 3], offset_m: 0.0, tool_m: [0.0; 3] };
        let socket = Placement { measurement: Measurement::Socket, own: vec![0.4, 0.1, 0.2], tool: Vector3::new(0.0, 0.0, 0.05) };
        let model = CalibModel::dh(&Robot::irb120(), &guess, true).with_placement(&socket);
        let mut model = model.with_setups((vec!["p/a".into(), "p/b".into(), "p/c".into()], &[vec![0.45, 0.1, 0.2], vec![0.43, 0.14, 0.21]]), (Vec::new(), &[]));
        let x = model.nominal.clone();
        model.spacings = vec![Spacing { a: 0, b: 1, mm: 50.01, at: None, std_mm: None }, Spacing { a: 1, b: 2, mm: 49.0, at: None, std_mm: Some(0.02) }];
        let n = model.n_params();
        let mut jac = vec![0.0; 2 * n];
        model.spacing_jacobian(&x, &mut jac);
        let mut r0 = [0.0; 2];
        model.spacing_residuals(&x, &mut r0);
        assert!((r0[0] - 0.01).abs() < 1e-9, "{r0:?}");
        let h = 1e-7;
        for p in 0..n {
            let (mut a, mut b) = (x.clone(), x.clone());
            a[p] += h;
            b[p] -= h;
            let (mut ra, mut rb) = ([0.0; 2], [0.0; 2]);
            model.spacing_residuals(&a, &mut ra);
            model.spacing_residuals(&b, &mut rb);
            for k in 0..2 {
                let fd = (ra[k] - rb[k]) / (2.0 * h);
                assert!((fd - jac[k * n + p]).abs() < 1e-5, "spacing {k} d/d{}: {fd} vs {}", model.names[p], jac[k * n + p]);
            }
        }
    }
}

/// The spacings of the stated distances `known` where sockets and faces stand beside each other
/// in one fit (`face[s]`: whether station `s` is a face; `labels`: the stations'): a distance
/// naming two sockets, or naming none, ties sockets ([`resolve_spacings`]); one naming two
/// faces is a step between them. Either kind alone fixes the arm's scale; none is an error.
pub fn resolve_mixed_spacings(labels: &[String], face: &[bool], known: &[KnownSpacing]) -> crate::error::Result<Vec<Spacing>> {
    let feature = |l: &str| l.rsplit_once('/').map_or(l, |(_, f)| f).to_string();
    let of_kind = |want: bool| -> Vec<usize> { (0..labels.len()).filter(|&s| face.get(s).copied().unwrap_or(false) == want).collect() };
    let all: Vec<(bool, String)> = (0..labels.len()).map(|s| (face.get(s).copied().unwrap_or(false), feature(&labels[s]))).collect();
    for k in known {
        if let Some((a, b)) = &k.sockets {
            if ![false, true].iter().any(|w| all.contains(&(*w, a.clone())) && all.contains(&(*w, b.clone()))) {
                return Err(crate::error::Error::Calibration(format!(
                    "--spacing-mm {k}: {a} and {b} are not two sockets nor two faces of the rows (sockets and faces in the rows: {})",
                    labels.join(", ")
                )));
            }
        }
    }
    let mut out = Vec::new();
    for (want, kind) in [(false, FeatureKind::Socket), (true, FeatureKind::Plane)] {
        let idx = of_kind(want);
        let names: Vec<String> = idx.iter().map(|&s| feature(&labels[s])).collect();
        let mine: Vec<KnownSpacing> = known
            .iter()
            .filter(|k| match &k.sockets {
                Some((a, b)) => names.contains(a) && names.contains(b),
                None => !want,
            })
            .cloned()
            .collect();
        if mine.is_empty() {
            continue;
        }
        let sub: Vec<String> = idx.iter().map(|&s| labels[s].clone()).collect();
        out.extend(resolve_spacings(&sub, &mine, kind)?.into_iter().map(|sp| Spacing { a: idx[sp.a], b: idx[sp.b], ..sp }));
    }
    if out.is_empty() {
        return Err(crate::error::Error::Calibration(format!(
            "no known spacing between sockets nor step between faces ties two features of one placement in the rows (stated: {}; in the rows: {}): without one nothing fixes the arm's scale; give --spacing-mm A:B=50 naming two sockets or two faces",
            if known.is_empty() { "none".to_string() } else { known.iter().map(|k| k.to_string()).collect::<Vec<_>>().join(", ") },
            labels.join(", ")
        )));
    }
    Ok(out)
}

/// A known distance between two sockets of an artifact as a user states it (`--spacing-mm`):
/// `50` for an artifact of two sockets, `A:B=50` between the sockets labelled `A` and `B`, with
/// its standard uncertainty after `±` (or `+-`) where the user knows it (`A:B=50±0.02`: a
/// printed plate); it holds on every placement of the artifact.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(try_from = "String", into = "String")]
pub struct KnownSpacing {
    /// The two sockets' labels; `None`: the artifact's only two.
    pub sockets: Option<(String, String)>,
    /// The distance between their centres, mm.
    pub mm: f64,
    /// Its standard uncertainty as made, mm; `None`: held to [`SPACING_SD_MM`].
    pub std_mm: Option<f64>,
}

/// The standard uncertainty a stated distance is held to where none is given, mm: a distance
/// one such step off weighs as a seated row's residual of the same size (as
/// [`PULL_SCALE_MM`] weighs a pull).
pub const SPACING_SD_MM: f64 = PULL_SCALE_MM;

/// Largest spacing between two sockets an artifact may state, mm (a plate is no wider than a
/// cell).
pub const MAX_SPACING_MM: f64 = 5000.0;

impl std::str::FromStr for KnownSpacing {
    type Err = crate::error::Error;
    fn from_str(s: &str) -> crate::error::Result<KnownSpacing> {
        let bad = |why: &str| {
            crate::error::Error::Invalid(format!(
                "--spacing-mm '{s}': {why} (give 50 for an artifact of two sockets or a step of two faces, or A:B=50 between sockets or faces A and B)"
            ))
        };
        let (sockets, value) = match s.rsplit_once('=') {
            Some((pair, v)) => {
                let (a, b) = pair.split_once(':').ok_or_else(|| bad("name the two features as A:B"))?;
                let (a, b) = (a.trim(), b.trim());
                if a.is_empty() || b.is_empty() || a == b {
                    return Err(bad("two different labels are needed"));
                }
                (Some((a.to_string(), b.to_string())), v)
            }
            None => (None, s),
        };
        let (value, std) = match value.split_once('±').or_else(|| value.split_once("+-")) {
            Some((v, sd)) => (v, Some(sd)),
            None => (value, None),
        };
        let mm: f64 = value.trim().parse().map_err(|_| bad("the distance is not a number"))?;
        if !(mm > 0.0 && mm <= MAX_SPACING_MM) {
            return Err(bad(&format!("the distance must be in (0, {MAX_SPACING_MM}] mm")));
        }
        let std_mm = match std {
            Some(sd) => {
                let sd: f64 = sd.trim().parse().map_err(|_| bad("the uncertainty after ± is not a number"))?;
                if !(sd > 0.0 && sd < mm) {
                    return Err(bad("the uncertainty after ± must be positive and below the distance"));
                }
                Some(sd)
            }
            None => None,
        };
        Ok(KnownSpacing { sockets, mm, std_mm })
    }
}

impl TryFrom<String> for KnownSpacing {
    type Error = crate::error::Error;
    fn try_from(s: String) -> crate::error::Result<KnownSpacing> {
        s.parse()
    }
}

impl From<KnownSpacing> for String {
    fn from(k: KnownSpacing) -> String {
        k.to_string()
    }
}

impl std::fmt::Display for KnownSpacing {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        if let Some((a, b)) = &self.sockets {
            write!(f, "{a}:{b}=")?;
        }
        write!(f, "{}", self.mm)?;
        match self.std_mm {
            Some(sd) => write!(f, "±{sd}"),
            None => Ok(()),
        }
    }
}

/// The spacings of the stated distances `known` between the sockets of each placement, the
/// model's stations being `labels` (`placement/socket`, as
/// [`crate::dataset::feature_station`] names them). An error says what the rows cannot determine:
/// no spacing (no scale), one socket, a stated socket no row was seated in.
pub fn resolve_spacings(labels: &[String], known: &[KnownSpacing], kind: FeatureKind) -> crate::error::Result<Vec<Spacing>> {
    use crate::error::Error;
    let (many, known_as) = match kind {
        FeatureKind::Socket => ("sockets", "spacing"),
        FeatureKind::Plane => ("faces", "step"),
    };
    let split = |l: &str| -> (String, String) {
        match l.rsplit_once('/') {
            Some((p, s)) => (p.to_string(), s.to_string()),
            None => (String::new(), l.to_string()),
        }
    };
    let parts: Vec<(String, String)> = labels.iter().map(|l| split(l)).collect();
    let mut placements: Vec<String> = Vec::new();
    for (p, _) in &parts {
        if !placements.contains(p) {
            placements.push(p.clone());
        }
    }
    if labels.len() < 2 {
        return Err(Error::Calibration(match kind {
            FeatureKind::Socket => "the ball was seated in one socket only: one fixed point shows neither the arm's scale nor most of its geometry; seat it in two or more sockets a known distance apart (--spacing-mm)".into(),
            FeatureKind::Plane => "the probe touched one face only: one face fixes the stylus along its normal alone, and neither the arm's scale nor most of its geometry; touch two or more faces, two of them parallel a known step apart (--spacing-mm), and place the artifact turned differently".into(),
        }));
    }
    if known.is_empty() {
        return Err(Error::Calibration(format!(
            "no known {known_as} between {many}: the rows fix where the {many} are relative to the arm, not how large the arm is (the arm, its target and {} {many} scaled together read the same); give the distance between two {many} of the artifact with --spacing-mm",
            labels.len()
        )));
    }
    let mut out = Vec::new();
    for p in &placements {
        let at = |s: &str| parts.iter().position(|(pp, ss)| pp == p && ss == s);
        let here: Vec<usize> = (0..parts.len()).filter(|&k| &parts[k].0 == p).collect();
        let name = if p.is_empty() { String::new() } else { format!(" at placement {p}") };
        for k in known {
            match &k.sockets {
                None if here.len() == 2 => out.push(Spacing { a: here[0], b: here[1], mm: k.mm, at: None, std_mm: k.std_mm }),
                // A placement with one socket seated is a fixed point and no spacing.
                None if here.len() < 2 => {}
                None => {
                    return Err(Error::Calibration(format!(
                        "--spacing-mm {} names no {many}, but the artifact{name} has {} {many} in the rows ({}): name them as A:B={}",
                        k.mm,
                        here.len(),
                        here.iter().map(|&i| parts[i].1.as_str()).collect::<Vec<_>>().join(", "),
                        k.mm
                    )))
                }
                // A placement where one of the two was not seated carries no such spacing.
                Some((a, b)) => {
                    if let (Some(ia), Some(ib)) = (at(a), at(b)) {
                        out.push(Spacing { a: ia, b: ib, mm: k.mm, at: None, std_mm: k.std_mm });
                    }
                }
            }
        }
    }
    if out.is_empty() {
        return Err(Error::Calibration(format!(
            "no stated {known_as} ties two {many} of one placement in the rows (stated: {}; in the rows: {}): without one nothing fixes the arm's scale",
            known.iter().map(|k| k.to_string()).collect::<Vec<_>>().join(", "),
            labels.join(", ")
        )));
    }
    Ok(out)
}
