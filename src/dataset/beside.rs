//! Sockets seated and faces touched by one ball in one file: each row names a socket or a face
//! (never both), the sockets' rows read nothing, the faces' a probe's contact (nothing) or a dial
//! indicator's reading; a socket and a face of one placement never share a label.

use super::types::Row;
use crate::error::{Error, Result};
use crate::measurement::{FeatureKind, Measurement};

/// An error where a socket and a face of one placement share a label (each is a station of
/// its own, named `placement/label`).
pub(super) fn same_label_for_socket_and_face(rows: &[Row], src: &str) -> Result<()> {
    let of = |kind: FeatureKind| -> std::collections::BTreeSet<(Option<&str>, &str)> {
        rows.iter().filter_map(|r| r.feature.as_ref().filter(|f| f.kind == kind).map(|f| (r.station.as_deref(), f.label.as_str()))).collect()
    };
    let faces = of(FeatureKind::Plane);
    match of(FeatureKind::Socket).into_iter().find(|k| faces.contains(k)) {
        Some((p, l)) => Err(Error::data(
            src,
            format!(
                "'{}' names a socket and a face{}: give the faces and the sockets labels of their own",
                l,
                p.map_or(String::new(), |p| format!(" at placement {p}"))
            ),
        )),
        None => Ok(()),
    }
}

/// Faces touched beside sockets seated, one ball and one fit: where the header's instruments
/// `complete` are a ball in sockets and a probe (or an indicator) on faces, the sockets' are the
/// file's and the faces' instrument is returned. Sockets and faces beside a tracker's points
/// (three instruments) are refused by name.
pub(super) fn faces_beside_sockets(complete: &mut Vec<Measurement>, source: &str, found: &str) -> Result<Option<Measurement>> {
    let face = complete.iter().copied().find(|m| m.feature() == Some(FeatureKind::Plane));
    let (true, Some(face)) = (complete.contains(&Measurement::Socket), face) else { return Ok(None) };
    if complete.len() > 2 {
        return Err(Error::data(
            source,
            format!(
                "line 1: the header holds three instruments ({}); one fit takes sockets beside faces, or sockets beside a tracker's points, not more; header found: {found}",
                complete.iter().map(|m| m.def().describe()).collect::<Vec<_>>().join(", ")
            ),
        ));
    }
    complete.retain(|m| *m == Measurement::Socket);
    Ok(Some(face))
}
