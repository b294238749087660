//! A calibrated model's readings for a dataset's rows, and the CSV `predict` writes of them.

use crate::calib::pipeline::CalibResult;
use crate::dataset::Dataset;
use crate::error::{Error, Result};
use crate::measurement::Euler;

/// The CSV `predict` writes for readings with `columns` (`["L"]`, `["x", "y", "z"]`, a pose's
/// `x, y, z, rx, ry, rz`): `q1..qN,L,L_pred,residual` when every row has a measured reading,
/// `q1..qN,L_pred` otherwise (for a point, `x_pred,y_pred,z_pred` and residuals
/// `x_residual,...`). `rows` pairs each row's angles with its measured reading (empty when none),
/// `predicted` holds the readings row after row. With `angles` (a pose), the last three columns
/// are Euler angles in degrees in that convention, and their residual is the orientation error
/// as a rotation vector, `wx_residual, wy_residual, wz_residual` (degrees, in the frame the pose
/// is read in: measured · predictedᵀ as axis × angle): differences of Euler angles mean nothing
/// near gimbal lock, where a thousandth of a degree turns two of them by tens of degrees.
pub fn prediction_csv(columns: &[&str], angles: Option<Euler>, rows: &[(&[f64], &[f64])], predicted: &[f64]) -> String {
    let d = columns.len();
    let lengths = if angles.is_some() { d - 3 } else { d };
    let measured = rows.iter().all(|(_, y)| y.len() == d);
    let joints: Vec<String> = (1..=rows.first().map_or(0, |(q, _)| q.len())).map(|j| format!("q{j},")).collect();
    let mut head: Vec<String> = Vec::new();
    if measured {
        head.extend(columns.iter().map(|c| c.to_string()));
    }
    head.extend(columns.iter().map(|c| format!("{c}_pred")));
    if measured {
        head.extend(columns[..lengths].iter().map(|c| if d == 1 { "residual".to_string() } else { format!("{c}_residual") }));
        if angles.is_some() {
            head.extend(["wx_residual", "wy_residual", "wz_residual"].map(String::from));
        }
    }
    let mut text = joints.concat() + &head.join(",") + "\n";
    for ((q, y), p) in rows.iter().zip(predicted.chunks(d)) {
        let mut cells: Vec<String> = q.iter().map(|v| v.to_string()).collect();
        if measured {
            cells.extend(y.iter().map(|v| v.to_string()));
        }
        cells.extend(p.iter().map(|v| v.to_string()));
        if measured {
            cells.extend(residuals(&y[..lengths], &p[..lengths], lengths).iter().map(|v| v.to_string()));
            if let Some(e) = angles {
                cells.extend(rotation_residual_deg(&y[lengths..], &p[lengths..], e).iter().map(|v| (v + 0.0).to_string()));
            }
        }
        text.push_str(&cells.join(","));
        text.push('\n');
    }
    text
}

/// The orientation error of a pose as a rotation vector, degrees: `measured · predictedᵀ` as axis
/// × angle, from Euler angles (degrees) in the convention `euler`.
pub fn rotation_residual_deg(measured: &[f64], predicted: &[f64], euler: Euler) -> [f64; 3] {
    let r = |a: &[f64]| euler.matrix([a[0], a[1], a[2]].map(f64::to_radians));
    let err = nalgebra::Rotation3::from_matrix_unchecked(r(measured) * r(predicted).transpose());
    err.scaled_axis().map(f64::to_degrees).into()
}

/// Measured − predicted of one row; values from `lengths` on are angles (degrees), wrapped into
/// (−180°, 180°].
pub fn residuals(y: &[f64], p: &[f64], lengths: usize) -> Vec<f64> {
    let wrap = |d: f64| {
        // (+ 0.0 writes a whole turn's −0 as 0.)
        let w = d.rem_euclid(360.0) + 0.0;
        if w > 180.0 {
            w - 360.0
        } else {
            w
        }
    };
    y.iter().zip(p).enumerate().map(|(k, (a, b))| if k < lengths { a - b } else { wrap(a - b) }).collect()
}

/// A calibrated model's readings of a dataset's rows ([`predicted_readings`]).
#[derive(Clone, Debug, Default)]
pub struct Predicted {
    /// The readings in the file's columns, `file_dim` values a row.
    pub values: Vec<f64>,
    /// The readings as the model's values (mm; a pose's origin and axis tips), `dim` a row.
    pub model_values: Vec<f64>,
    /// What the user should know: rows beyond the joint limits the model knows.
    pub warnings: Vec<String>,
    /// Stations the model was not calibrated at, each registered on its first rows: those rows
    /// are not unseen.
    pub registered: Vec<crate::calib::pipeline::Registration>,
}

impl Predicted {
    /// The data rows (0-based) a registration fitted: a judgement of unseen rows leaves them out.
    pub fn registration_rows(&self) -> Vec<usize> {
        self.registered.iter().flat_map(|r| r.rows.iter().map(|i| i - 1)).collect()
    }
}

/// A calibrated model's readings of every row of `ds` (which need no measured readings), in
/// the file's columns: `file_dim` values a row, a pose's angles in the `euler` convention. Also
/// a warning when rows lie beyond the joint limits the model knows (it extrapolates there).
/// Rows at a station the model was not calibrated at are predicted with that station's
/// placement registered on its first `register_rows` rows (0: refused).
/// `model` names the model in errors.
pub fn predicted_readings(result: &CalibResult, ds: &Dataset, euler: Euler, model: &str, register_rows: usize) -> Result<Predicted> {
    ds.require_joints(result.model.chain.n_joints, model)?;
    if result.model.measurement.is_constant() {
        return Err(Error::Invalid(format!(
            "{model} was calibrated from rows of a {}, which read nothing to predict: its held-out rows are judged by calibrate, and on another instrument's rows once that instrument is registered",
            result.model.measurement.def().describe()
        )));
    }
    result.require_columns(ds)?;
    let outside: Vec<(usize, usize, f64)> = crate::calib::pipeline::outside_limits(ds, &result.model.limits).collect();
    let mut warnings: Vec<String> = outside
        .first()
        .map(|(i, j, q)| {
            format!(
                "{} value(s) lie outside the model's joint limits (first: row {}, q{} = {} deg); the model extrapolates there",
                outside.len(),
                i + 1,
                j + 1,
                crate::error::shown(*q)
            )
        })
        .into_iter()
        .collect();
    result.require_measurement(ds)?;
    let registered = result.at_stations(ds, register_rows)?;
    let (result, ds) = match &registered {
        Some((r, d, _)) => (r, d),
        None => (result, ds),
    };
    let registered = registered.as_ref().map(|(_, _, g)| g.clone()).unwrap_or_default();
    warnings.extend(registered.iter().map(crate::calib::pipeline::Registration::line));
    let m = result.model.measurement;
    let predicted = result.predict_rows(ds);
    if let Some(i) = predicted.iter().position(|p| !p.is_finite()) {
        return Err(Error::Calibration(format!("the model predicted a non-finite reading for row {}", i / m.dim() + 1)));
    }
    Ok(Predicted { values: predicted.chunks(m.dim()).flat_map(|v| m.file_of_values(v, euler)).collect(), model_values: predicted, warnings, registered })
}
