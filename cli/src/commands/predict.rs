//! `twincal predict`: a calibrated model's reading for every row of a dataset.

use super::*;
use twincal::jobs::{predicted_readings, prediction_csv, residuals};
use twincal::measurement::Euler;

/// `twincal predict`: the calibrated model's length for every row of a dataset (which needs no
/// measured lengths), with the residual where a length was measured.
pub fn predict(model: &Path, data: &Path, reading: &Reading, register_rows: usize, out: &Path, quiet: bool) -> Result<()> {
    let data_files = data_inputs(data);
    let mut inputs: Vec<(&str, &Path)> = vec![("--model", model)];
    inputs.extend(data_files.iter().map(|p| ("--data", p.as_path())));
    check_outputs(&inputs, &[("--out", out)])?;
    let result = load_model(model)?;
    let ds = load_dataset(data, reading, false)?;
    let euler = reading.euler;
    let p = predicted_readings(&result, &ds, euler, &format!("the model {}", model.display()), register_rows)?;
    for w in &p.warnings {
        eprintln!("warning: {w}");
    }
    let (file_predicted, predicted) = (&p.values, &p.model_values);
    let m = result.model.measurement;
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
    twincal::output::write_atomic(out, prediction_csv(m.def().file_columns(), (d > lengths).then_some(euler), &rows, file_predicted).as_bytes())?;
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
