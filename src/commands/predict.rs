//! `twincal predict`: a calibrated model's reading for every row of a dataset.

use super::*;

/// The CSV `predict` writes for readings with `columns` (`["L"]`, `["x", "y", "z"]`):
/// `q1..qN,L,L_pred,residual` when every row has a measured reading, `q1..qN,L_pred` otherwise
/// (for a point, `x_pred,y_pred,z_pred` and residuals `x_residual,...`). `rows` pairs each row's
/// angles with its measured reading (empty when none), `predicted` holds the readings row after row.
pub fn prediction_csv(columns: &[&str], rows: &[(&[f64], &[f64])], predicted: &[f64]) -> String {
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
            cells.extend(y.iter().zip(p).map(|(a, b)| (a - b).to_string()));
        }
        text.push_str(&cells.join(","));
        text.push('\n');
    }
    text
}

/// `twincal predict`: the calibrated model's length for every row of a dataset (which needs no
/// measured lengths), with the residual where a length was measured.
pub fn predict(model: &Path, data: &Path, angles: AngleArg, reading: &ReadingArgs, out: &Path, quiet: bool) -> Result<()> {
    let data_files = data_inputs(data);
    let mut inputs: Vec<(&str, &Path)> = vec![("--model", model)];
    inputs.extend(data_files.iter().map(|p| ("--data", p.as_path())));
    check_outputs(&inputs, &[("--out", out)])?;
    let result = load_model(model)?;
    let ds = load_dataset(data, angles, reading, false)?;
    ds.require_joints(result.model.chain.n_joints, &format!("the model {}", model.display()))?;
    result.require_columns(&ds)?;
    // Poses beyond the joint ranges the model knows: it extrapolates there (calibrate refuses
    // them; predict answers, and says so).
    let outside: Vec<(usize, usize, f64)> = crate::calib::run::outside_limits(&ds, &result.model.limits).collect();
    if let Some((i, j, q)) = outside.first() {
        eprintln!(
            "warning: {} value(s) lie outside the model's joint limits (first: row {}, q{} = {} deg); the model extrapolates there",
            outside.len(),
            i + 1,
            j + 1,
            crate::error::shown(*q)
        );
    }
    result.require_measurement(&ds)?;
    let m = result.model.measurement;
    // The measured values as the model reads them (a pose's origin and axes).
    let values: Vec<Vec<f64>> = ds.rows.iter().map(|r| r.values_mm().unwrap_or_default()).collect();
    let rows: Vec<(&[f64], &[f64])> = ds.rows.iter().zip(&values).map(|(r, v)| (r.q_deg.as_slice(), v.as_slice())).collect();
    let predicted = result.predict_rows(&ds);
    if let Some(i) = predicted.iter().position(|p| !p.is_finite()) {
        return Err(Error::Calibration(format!("the model predicted a non-finite reading for row {}", i / m.dim() + 1)));
    }
    crate::io::write_atomic(out, prediction_csv(m.def().columns(), &rows, &predicted).as_bytes())?;
    if !quiet {
        let res: Vec<f64> = rows.iter().zip(predicted.chunks(m.dim())).flat_map(|((_, y), p)| y.iter().zip(p).map(|(a, b)| a - b)).collect();
        if res.is_empty() {
            eprintln!("{} rows predicted; wrote {}", rows.len(), out.display());
        } else {
            let s = crate::calib::metrics::ErrorStats::of(&res);
            eprintln!("{} rows: RMSE {:.4} mm, STD {:.4} mm, MAX {:.4} mm; wrote {}", rows.len(), s.rmse, s.std, s.max, out.display());
        }
    }
    Ok(())
}
