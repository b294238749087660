use super::*;

#[test]
fn prediction_csv_has_residuals_only_when_every_row_has_a_length() {
    let q: &[f64] = &[1.0, 2.0, 3.0, 4.0, 5.0, 6.5];
    let with = prediction_csv(&["L"], 0, &[(q, &[300.5]), (q, &[301.0])], &[300.25, 301.0]);
    assert_eq!(with, "q1,q2,q3,q4,q5,q6,L,L_pred,residual\n1,2,3,4,5,6.5,300.5,300.25,0.25\n1,2,3,4,5,6.5,301,301,0\n");
    let without = prediction_csv(&["L"], 0, &[(q, &[]), (q, &[301.0])], &[300.25, 301.0]);
    assert_eq!(without, "q1,q2,q3,q4,q5,q6,L_pred\n1,2,3,4,5,6.5,300.25\n1,2,3,4,5,6.5,301\n");
    // A tracker's point: three values per row, each with its prediction and residual.
    let point = prediction_csv(&["x", "y", "z"], 0, &[(q, &[400.5, -20.0, 600.0])], &[400.25, -20.5, 600.0]);
    assert_eq!(
        point,
        "q1,q2,q3,q4,q5,q6,x,y,z,x_pred,y_pred,z_pred,x_residual,y_residual,z_residual\n1,2,3,4,5,6.5,400.5,-20,600,400.25,-20.5,600,0.25,0.5,0\n"
    );
    // A pose: the angles' residuals wrap around ±180°.
    let pose = prediction_csv(&["x", "y", "z", "rx", "ry", "rz"], 3, &[(q, &[1.0, 2.0, 3.0, 179.5, 10.0, -90.0])], &[1.0, 2.0, 3.0, -179.5, 10.25, 270.0]);
    assert!(pose.starts_with("q1,q2,q3,q4,q5,q6,x,y,z,rx,ry,rz,x_pred,y_pred,z_pred,rx_pred,ry_pred,rz_pred,x_residual,"), "{pose}");
    assert!(pose.trim_end().ends_with(",0,0,0,-1,-0.25,0"), "{pose}");
}

#[test]
fn data_inputs_name_the_files_read() {
    let dir = tempfile::tempdir().unwrap();
    assert_eq!(data_inputs(dir.path()), vec![dir.path().join("dataset.csv"), dir.path().join("truth.json")]);
    let x = dir.path().join("m.xlsx#Sheet1");
    assert_eq!(data_inputs(&x), vec![dir.path().join("m.xlsx"), dir.path().join("truth.json")]);
}
