//! An artifact in a calibration's or a diagnosis's recording: its sockets (faces) where the fit
//! puts them, the stated spacings between them, the ball (stylus) on the flange, and a plot of
//! every row at its socket (face) after the fit.

use super::plot::{padded_range, Plot};
use super::{Layout, Recorder};
use nalgebra::Vector3;
use twincal::report::artifact::ArtifactFigure;

/// Colours of an artifact's placements, in turn.
const PLACEMENTS: [[u8; 4]; 6] = [[31, 119, 180, 255], [255, 127, 14, 255], [44, 160, 44, 255], [148, 103, 189, 255], [140, 86, 75, 255], [227, 119, 194, 255]];
/// The plate between two sockets, the edges of a face.
const PLATE: [u8; 4] = [235, 205, 120, 255];
/// The ball or stylus on the flange.
const TARGET: [u8; 4] = [250, 250, 250, 255];
/// Half the side of the square a face is drawn as, mm.
const FACE_HALF_MM: f64 = 30.0;

/// The entity of the rows-at-their-feature plot.
pub const PLOT_ENTITY: &str = "artifact_rows";

/// Draws the artifact under `world/artifact` (seen in both views of a before/after pair), the
/// target at the arm's tool point `target_at` (mm) when the arm is drawn, and the plot of every
/// row at its feature under [`PLOT_ENTITY`].
pub fn draw(rec: &mut Recorder, a: &ArtifactFigure, target_at: Option<[f64; 3]>) {
    let (word, target) = a.words();
    let colors: Vec<[u8; 4]> = a.placement_numbers().iter().map(|k| PLACEMENTS[k % PLACEMENTS.len()]).collect();
    let labels: Vec<String> = a.features.iter().map(|f| format!("{word} {}: {} rows, scatter {:.4} mm", f.label, f.rows.len(), f.scatter_mm)).collect();
    let at: Vec<[f64; 3]> = a.features.iter().map(|f| f.at_mm).collect();
    rec.points_hover(&format!("world/artifact/{word}s"), &at, Some(&colors), Some(6.0), &labels);
    let faces: Vec<Vec<[f64; 3]>> = a.features.iter().filter_map(|f| Some(square(f.at_mm, f.normal?))).collect();
    if !faces.is_empty() {
        rec.line_strips("world/artifact/faces", &faces, PLATE, 1.0);
        let normals: Vec<Vec<[f64; 3]>> =
            a.features.iter().filter_map(|f| f.normal.map(|n| vec![f.at_mm, [0, 1, 2].map(|k| f.at_mm[k] + 0.6 * FACE_HALF_MM * n[k])])).collect();
        rec.line_strips("world/artifact/normals", &normals, PLATE, 0.6);
    }
    if !a.spacings.is_empty() {
        let what = if faces.is_empty() { "spacing" } else { "step" };
        let lines: Vec<Vec<[f64; 3]>> = a.spacings.iter().map(|(i, j, _, _)| vec![at[*i], at[*j]]).collect();
        rec.line_strips("world/artifact/spacings", &lines, PLATE, 1.5);
        let mid: Vec<[f64; 3]> = a.spacings.iter().map(|(i, j, _, _)| [0, 1, 2].map(|k| 0.5 * (at[*i][k] + at[*j][k]))).collect();
        let text: Vec<String> = a
            .spacings
            .iter()
            .map(|(i, j, stated, fitted)| format!("{what} {}–{}: fitted {fitted:.4} mm, stated {stated:.4}", a.features[*i].label, a.features[*j].label))
            .collect();
        rec.points_hover("world/artifact/spacing_labels", &mid, Some(&[PLATE]), Some(2.0), &text);
    }
    if let Some(p) = target_at {
        let t = a.target_mm;
        let label = format!("the {target}'s centre, ({:.3}, {:.3}, {:.3}) mm on the flange", t[0], t[1], t[2]);
        rec.points(&format!("world/artifact/{target}"), &[p], Some(&[TARGET]), Some(5.0), Some(&[label]));
    }
    rows_plot(rec, a, &colors);
}

/// A face as a square of side 2·[`FACE_HALF_MM`] about `at` (mm) across `normal`.
fn square(at: [f64; 3], normal: [f64; 3]) -> Vec<[f64; 3]> {
    let n = Vector3::from(normal);
    let helper = if n.x.abs() < 0.9 { Vector3::x() } else { Vector3::y() };
    let u = n.cross(&helper).normalize() * FACE_HALF_MM;
    let v = n.cross(&u);
    let c = Vector3::from(at);
    [u + v, u - v, -u - v, -u + v, u + v].iter().map(|d| (c + d).into()).collect()
}

/// Every row at its feature after the fit (µm), one strip per feature in its placement's colour.
fn rows_plot(rec: &mut Recorder, a: &ArtifactFigure, colors: &[[u8; 4]]) {
    let names: Vec<String> = a.features.iter().map(|f| f.label.clone()).collect();
    let y = padded_range(a.features.iter().flat_map(|f| f.after_um.iter().copied()).chain([0.0]), 0.08).unwrap_or((-1.0, 1.0));
    let plot = Plot::categories("", &names, a.residual_axis(), y);
    plot.frame(rec, PLOT_ENTITY);
    let (word, _) = a.words();
    for (k, f) in a.features.iter().enumerate() {
        // A fixed spread by the row's place (golden-ratio steps), the same on every run.
        let xy: Vec<[f64; 2]> = f.after_um.iter().enumerate().map(|(r, v)| [k as f64 + ((r as f64 * 0.618_034).fract() - 0.5) * 0.5, *v]).collect();
        let labels: Vec<String> = f.rows.iter().zip(&f.after_um).map(|(i, v)| format!("row {} at {word} {}: {v:.1} µm", i + 1, f.label)).collect();
        plot.scatter(rec, &format!("{PLOT_ENTITY}/{k}"), &xy, &[colors[k]], 2.5, &labels);
    }
}

/// The artifact as markdown for a recording's text panel: the target on the flange, each socket
/// (face) with its scatter, each spacing stated and fitted, what the rows cannot see.
pub fn summary(a: &ArtifactFigure) -> String {
    let (word, target) = a.words();
    let t = a.target_mm;
    let mut doc = format!(
        "\n\n**The artifact.** The 3-D views draw each {word} where the fit puts it, coloured by placement, and the stated spacings; a plot shows every row at its {word} after the fit. The {target}'s centre on the flange: ({:.3}, {:.3}, {:.3}) mm.\n\n| {word} | rows | scatter (mm) |\n|---|---:|---:|\n",
        t[0], t[1], t[2]
    );
    for f in &a.features {
        doc.push_str(&format!("| {} | {} | {:.4} |\n", f.label, f.rows.len(), f.scatter_mm));
    }
    for (i, j, stated, fitted) in &a.spacings {
        doc.push_str(&format!("\n- {}–{}: stated {stated:.4} mm, fitted {fitted:.4} mm", a.features[*i].label, a.features[*j].label));
    }
    for c in &a.cannot_see {
        doc.push_str(&format!("\n- cannot see: {c}"));
    }
    doc
}

/// The view of the rows-at-their-feature plot.
pub fn view(a: &ArtifactFigure) -> Layout {
    let (word, _) = a.words();
    Layout::plot(&format!("Every row at its {word} after the fit ({})", a.residual_axis()), &format!("/{PLOT_ENTITY}"))
}
