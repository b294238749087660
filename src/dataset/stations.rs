//! Where the instrument stood for each row. A laser tracker is re-stationed between sessions (and
//! a draw-wire's housing re-mounted): each station is a placement of its own while the arm stays
//! the same, so a calibration fits one placement per station. Stations come from the rows'
//! `station` column (declared), from a declared `block` column when the user says blocks are
//! stations, or from change points a first fit finds in the residuals
//! ([`crate::calib::pipeline::setup`]), which label the rows the same way. The target's mounts on the
//! flange (a probe re-mounted) are labelled alike, in a `mount` column.

use super::types::Dataset;

/// The stations of a dataset's rows: their labels in the order of their first rows, and each
/// row's index into them.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Stations {
    /// The labels, in the order of their first rows; empty when the rows name no station (one
    /// station).
    pub labels: Vec<String>,
    /// Each row's station (index into `labels`; 0 without labels).
    pub of_row: Vec<usize>,
}

impl Stations {
    /// The stations of rows labelled `labels` (`None`: the row names none; rows without a label
    /// go with the first station).
    pub fn of_labels<'a>(labels: impl Iterator<Item = Option<&'a str>>) -> Stations {
        let mut out = Stations { labels: Vec::new(), of_row: Vec::new() };
        for label in labels {
            let k = match label {
                Some(l) => match out.labels.iter().position(|x| x == l) {
                    Some(k) => k,
                    None => {
                        out.labels.push(l.to_string());
                        out.labels.len() - 1
                    }
                },
                None => 0,
            };
            out.of_row.push(k);
        }
        out
    }

    /// How many stations (1 when the rows name none).
    pub fn len(&self) -> usize {
        self.labels.len().max(1)
    }

    /// Whether the rows stand at one station only.
    pub fn is_single(&self) -> bool {
        self.len() == 1
    }

    /// Always false: a dataset's rows stand at one station at least.
    pub fn is_empty(&self) -> bool {
        false
    }

    /// The rows (0-based, in order) of station `s`.
    pub fn rows(&self, s: usize) -> Vec<usize> {
        self.of_row.iter().enumerate().filter(|(_, k)| **k == s).map(|(i, _)| i).collect()
    }
}

/// The station of the rows at feature `feature` (a socket, a face) of the artifact at
/// `placement`: `placement/feature`, or the feature's label alone when the rows name no
/// placement.
pub fn feature_station(placement: Option<&str>, feature: &str) -> String {
    match placement {
        Some(p) => format!("{p}/{feature}"),
        None => feature.to_string(),
    }
}

impl Dataset {
    /// The stations the rows name in their `station` column (one when it is absent). Rows at
    /// an artifact's feature stand at it: each socket or face of each placement of the artifact
    /// is a station of its own, labelled `placement/feature` ([`feature_station`]).
    pub fn stations(&self) -> Stations {
        if self.rows.iter().any(|r| r.feature.is_some()) {
            let labels: Vec<Option<String>> = self.rows.iter().map(|r| r.feature.as_ref().map(|f| feature_station(r.station.as_deref(), &f.label))).collect();
            let mut out = Stations::of_labels(labels.iter().map(|l| l.as_deref()));
            // Faces touched beside sockets seated: the sockets' stations first (the first
            // instrument's placement is a socket's), each kind in the order of its first rows.
            let is_face = |k: usize| {
                self.rows[out.of_row.iter().position(|&s| s == k).unwrap_or(0)]
                    .feature
                    .as_ref()
                    .is_some_and(|f| f.kind == crate::measurement::FeatureKind::Plane)
            };
            if self.rows.iter().any(|r| r.socket().is_some()) {
                let order: Vec<usize> = (0..out.labels.len()).filter(|&k| !is_face(k)).chain((0..out.labels.len()).filter(|&k| is_face(k))).collect();
                let mut new_of = vec![0; order.len()];
                order.iter().enumerate().for_each(|(new, &old)| new_of[old] = new);
                out.labels = order.iter().map(|&k| out.labels[k].clone()).collect();
                out.of_row.iter_mut().for_each(|s| *s = new_of[*s]);
            }
            return out;
        }
        Stations::of_labels(self.rows.iter().map(|r| r.station.as_deref()))
    }

    /// The target's mounts the rows name in their `mount` column (one when it is absent),
    /// numbered as [`Self::stations`] numbers stations.
    pub fn mounts(&self) -> Stations {
        Stations::of_labels(self.rows.iter().map(|r| r.mount.as_deref()))
    }

    /// This dataset with each declared block its own station (`station` set to the block's
    /// label); rows without a block keep theirs.
    pub fn blocks_as_stations(&self) -> Dataset {
        let mut d = self.clone();
        for r in &mut d.rows {
            if let Some(b) = &r.block {
                r.station = Some(b.clone());
            }
        }
        d
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stations_are_numbered_by_their_first_rows() {
        let s = Stations::of_labels([Some("b"), Some("a"), Some("b"), Some("c"), Some("a")].into_iter());
        assert_eq!(s.labels, vec!["b", "a", "c"]);
        assert_eq!(s.of_row, vec![0, 1, 0, 2, 1]);
        assert_eq!(s.rows(1), vec![1, 4]);
        assert_eq!(s.len(), 3);
        let none = Stations::of_labels([None, None].into_iter());
        assert!(none.is_single() && none.labels.is_empty() && none.of_row == vec![0, 0]);
    }
}
