//! `twincal predict`: a calibrated model's reading for every row of a dataset.

use super::*;
use twincal::measurement::Euler;

/// The CSV `predict` writes for readings with `columns` (`["L"]`, `["x", "y", "z"]`, a pose's
/// `x, y, z, rx, ry, rz`): `q1..qN,L,L_pred,residual` when every row has a measured reading,
/// `q1..qN,L_pred` otherwise (for a point, `x_pred,y_pred,z_pred` and residuals
/// `x_residual,...`). `rows` pairs each row's angles with its measured reading (empty when none),
/// `predicted` holds the readings row after row. The last `angles` columns are angles in
/// degrees: their residuals are wrapped into (−180°, 180°].
pub fn prediction_csv(columns: &[&str], angles: usize, rows: &[(&[f64], &[f64])], predicted: &[f64]) -> String {
    let d = columns.len();
    let measured = rows.iter().all(|(_, y)| y.len() == d);
    let joints: Vec<String> = (1..=rows.first().map_or(0, |(q, _)| q.len())).map(|j| format!("q{j},")).collect();
    let mut head: Vec<String> = Vec::new();
    if measured {
        head.extend(columns.iter().map(|c| c.to_string()));
    }
    head.extend(columns.iter().map(|c| format!("{c}_pred")));
    if measured {
        head.extend(columns.iter().map(|c| if d == 1 { "residual".to_string() } else { format!("{c}_residual") }));
    }
    let mut text = joints.concat() + &head.join(",") + "\n";
    for ((q, y), p) in rows.iter().zip(predicted.chunks(d)) {
        let mut cells: Vec<String> = q.iter().map(|v| v.to_string()).collect();
        if measured {
            cells.extend(y.iter().map(|v| v.to_string()));
        }
        cells.extend(p.iter().map(|v| v.to_string()));
        if measured {
            cells.extend(residuals(y, p, d - angles).iter().map(|v| v.to_string()));
        }
        text.push_str(&cells.join(","));
        text.push('\n');
    }
    text
}

/// Measured − predicted of one row; values from `lengths` on are angles (degrees), wrapped into
/// (−180°, 180°].
fn residuals(y: &[f64], p: &[f64], lengths: usize) -> Vec<f64> {
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

/// A calibrated model's readings of every row of `ds` (which need no measured readings), in
/// the file's columns: `file_dim` values a row, a pose's angles in the `euler` convention. Also
/// a warning when rows lie beyond the joint limits the model knows (it extrapolates there).
/// `model` names the model in errors.
pub fn predicted_readings(result: &twincal::calib::run::CalibResult, ds: &Dataset, euler: Euler, model: &str) -> Result<(Vec<f64>, Option<String>)> {
    ds.require_joints(result.model.chain.n_joints, model)?;
    result.require_columns(ds)?;
    let outside: Vec<(usize, usize, f64)> = twincal::calib::run::outside_limits(ds, &result.model.limits).collect();
    let warning = outside.first().map(|(i, j, q)| {
        format!(
            "{} value(s) lie outside the model's joint limits (first: row {}, q{} = {} deg); the model extrapolates there",
            outside.len(),
            i + 1,
            j + 1,
            twincal::error::shown(*q)
        )
    });
    result.require_measurement(ds)?;
    let m = result.model.measurement;
    let predicted = result.predict_rows(ds);
    if let Some(i) = predicted.iter().position(|p| !p.is_finite()) {
        return Err(Error::Calibration(format!("the model predicted a non-finite reading for row {}", i / m.dim() + 1)));
    }
    Ok((predicted.chunks(m.dim()).flat_map(|v| m.file_of_values(v, euler)).collect(), warning))
}

/// `twincal predict`: the calibrated model's length for every row of a dataset (which needs no
/// measured lengths), with the residual where a length was measured.
pub fn predict(model: &Path, data: &Path, reading: &Reading, out: &Path, quiet: bool) -> Result<()> {
    let data_files = data_inputs(data);
    let mut inputs: Vec<(&str, &Path)> = vec![("--model", model)];
    inputs.extend(data_files.iter().map(|p| ("--data", p.as_path())));
    check_outputs(&inputs, &[("--out", out)])?;
    let result = load_model(model)?;
    let ds = load_dataset(data, reading, false)?;
    let euler = reading.resolve()?.1;
    let (file_predicted, warning) = predicted_readings(&result, &ds, euler, &format!("the model {}", model.display()))?;
    if let Some(w) = warning {
        eprintln!("warning: {w}");
    }
    let m = result.model.measurement;
    let predicted = result.predict_rows(&ds);
    // Written in the file's own columns: a pose's origin and angles, in the convention it was
    // read in (the model's values are its origin and axes; the rows keep intrinsic X-Y-Z).
    let (d, lengths) = (m.file_dim(), m.file_lengths());
    let in_convention = |file: &[f64]| -> Vec<f64> {
        if lengths == d || euler == Euler::XYZ {
            return file.to_vec();
        }
        let r = Euler::XYZ.matrix([file[3], file[4], file[5]].map(f64::to_radians));
        file[..3].iter().copied().chain(euler.angles(&r).map(f64::to_degrees)).collect()
    };
    let measured: Vec<Vec<f64>> = ds.rows.iter().map(|r| if r.reading_mm.len() == d { in_convention(&r.reading_mm) } else { Vec::new() }).collect();
    let rows: Vec<(&[f64], &[f64])> = ds.rows.iter().zip(&measured).map(|(r, v)| (r.q_deg.as_slice(), v.as_slice())).collect();
    twincal::io::write_atomic(out, prediction_csv(m.def().file_columns(), d - lengths, &rows, &file_predicted).as_bytes())?;
    if !quiet {
        let res: Vec<f64> = rows
            .iter()
            .zip(file_predicted.chunks(d))
            .filter(|((_, y), _)| y.len() == d)
            .flat_map(|((_, y), p)| residuals(&y[..lengths], &p[..lengths], lengths))
            .collect();
        if res.is_empty() {
            eprintln!("{} rows predicted; wrote {}", rows.len(), out.display());
        } else {
            let s = twincal::stats::metrics::ErrorStats::of(&res);
            // A pose's orientation error: the angle between the measured and the predicted
            // rotation (Euler angles' residuals grow without meaning near gimbal lock).
            let angles = if d > lengths {
                let turn: Vec<f64> = ds
                    .rows
                    .iter()
                    .zip(predicted.chunks(m.dim()))
                    .filter_map(|(r, p)| {
                        let (a, b) = (twincal::measurement::pose::reading_rotation(&r.values_mm()?)?, twincal::measurement::pose::reading_rotation(p)?);
                        Some(nalgebra::Rotation3::from_matrix_unchecked(a.transpose() * b).angle().to_degrees())
                    })
                    .collect();
                let a = twincal::stats::metrics::ErrorStats::of(&turn);
                format!("; orientation error (angle between measured and predicted) RMS {:.5} deg, MAX {:.5} deg", a.rmse, a.max)
            } else {
                String::new()
            };
            let what = if lengths == 1 { "RMSE" } else { "RMSE per coordinate" };
            eprintln!("{} rows: {what} {:.4} mm, STD {:.4} mm, MAX {:.4} mm{angles}; wrote {}", rows.len(), s.rmse, s.std, s.max, out.display());
        }
    }
    Ok(())
}
