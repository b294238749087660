//! `twincal predict`: a calibrated model's reading for every row of a dataset.

use super::*;

/// The CSV `predict` writes: `q1..qN,L,L_pred,residual` when every row has a measured length,
/// `q1..qN,L_pred` otherwise.
pub fn prediction_csv(rows: &[(&[f64], Option<f64>)], predicted: &[f64]) -> String {
    let with_l = rows.iter().all(|(_, l)| l.is_some());
    let joints: Vec<String> = (1..=rows.first().map_or(0, |(q, _)| q.len())).map(|j| format!("q{j},")).collect();
    let mut text = joints.concat() + if with_l { "L,L_pred,residual\n" } else { "L_pred\n" };
    for ((q, l), p) in rows.iter().zip(predicted) {
        let q: Vec<String> = q.iter().map(|v| v.to_string()).collect();
        match (with_l, l) {
            (true, Some(l)) => text.push_str(&format!("{},{l},{p},{}\n", q.join(","), l - p)),
            _ => text.push_str(&format!("{},{p}\n", q.join(","))),
        }
    }
    text
}

/// `twincal predict`: the calibrated model's length for every row of a dataset (which needs no
/// measured lengths), with the residual where a length was measured.
pub fn predict(model: &Path, data: &Path, angles: AngleArg, out: &Path, quiet: bool) -> Result<()> {
    let data_files = data_inputs(data);
    check_outputs(&[("--model", model), ("--data", &data_files[0])], &[("--out", out)])?;
    let result = load_model(model)?;
    let ds = load_dataset(data, angles, false)?;
    ds.require_joints(result.model.chain.n_joints, &format!("the model {}", model.display()))?;
    result.require_columns(&ds)?;
    let rows: Vec<(&[f64], Option<f64>)> = ds.rows.iter().map(|r| (r.q_deg.as_slice(), r.l_mm())).collect();
    let predicted = result.predict_rows(&ds);
    for (i, p) in predicted.iter().enumerate() {
        if !p.is_finite() {
            return Err(Error::Calibration(format!("the model predicted a non-finite length for row {}", i + 1)));
        }
    }
    crate::io::write_atomic(out, prediction_csv(&rows, &predicted).as_bytes())?;
    if !quiet {
        let res: Vec<f64> = rows.iter().zip(&predicted).filter_map(|((_, l), p)| l.map(|l| l - p)).collect();
        if res.is_empty() {
            eprintln!("{} rows predicted; wrote {}", rows.len(), out.display());
        } else {
            let s = crate::calib::metrics::ErrorStats::of(&res);
            eprintln!("{} rows: RMSE {:.4} mm, STD {:.4} mm, MAX {:.4} mm; wrote {}", rows.len(), s.rmse, s.std, s.max, out.display());
        }
    }
    Ok(())
}
