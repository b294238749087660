//! The instrument's set-ups in a model: its stations (where it stood) and its target's mounts
//! (how the target sat on the flange), each beyond the first with a block of parameters of its
//! own after the placement's.

use super::{CalibModel, Kind};
use crate::calib::effects::RowInputs;
use crate::measurement::Measurement;
use serde::{Deserialize, Serialize};

/// What a set-up change moves: where the instrument stands (a tracker re-stationed,
/// re-registered or bumped), or how its target sits on the flange (a probe re-mounted).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum SetupKind {
    /// The instrument's own place: the first [`n_station`](crate::measurement::Block::n_station)
    /// placement parameters.
    Station,
    /// The target's mount on the flange: the other placement parameters.
    Mount,
}

impl SetupKind {
    /// Both kinds, stations first (their blocks' order in the parameter vector).
    pub const ALL: [SetupKind; 2] = [SetupKind::Station, SetupKind::Mount];
    /// Its name in messages and files.
    pub fn name(self) -> &'static str {
        match self {
            SetupKind::Station => "station",
            SetupKind::Mount => "mount",
        }
    }
    /// A row's index of this kind.
    pub fn of(self, inp: &RowInputs) -> usize {
        match self {
            SetupKind::Station => inp.station,
            SetupKind::Mount => inp.mount,
        }
    }
}

impl CalibModel {
    /// Whether instrument `m`'s rows beside the first's stand at stations of the same list and
    /// read the same target: an artifact's other kind of feature (faces touched by the ball
    /// that is seated in the sockets), each feature a station whose own parameters are `m`'s
    /// (as many as the first's: a socket's centre, a face's normal and offset).
    pub fn shares_stations_with(&self, m: Measurement) -> bool {
        self.measurement.shares_stations_with(m)
    }
    /// Values per row: the widest instrument's. A narrower instrument's rows (a face's contact
    /// beside seated rows) read their values first and zeros after.
    pub fn width(&self) -> usize {
        self.measurement.dim().max(self.also.map_or(0, |m| m.dim()))
    }
    /// The stations whose own parameters are the second instrument's (where it shares the
    /// first's stations), from the rows' stations and instruments (`inputs`).
    pub fn set_station_instruments(&mut self, inputs: &[RowInputs]) {
        let Some(m) = self.also.filter(|m| self.shares_stations_with(*m)) else { return };
        for s in 1..self.n_stations() {
            if inputs.iter().any(|i| i.station == s && i.instrument == 1) {
                let r = self.station_range(s);
                let label = &self.stations[s];
                for (k, c) in r.enumerate() {
                    self.names[c] = format!("{}@{label}", m.placement_names()[k]);
                    self.kinds[c] = if m.def().placement_is_angle(k) { Kind::Angle } else { Kind::Length };
                }
            }
        }
    }
    /// The labels of the set-ups of kind `k` (empty: one, unnamed).
    pub fn setups(&self, k: SetupKind) -> &[String] {
        match k {
            SetupKind::Station => &self.stations,
            SetupKind::Mount => &self.mounts,
        }
    }
    fn setups_mut(&mut self, k: SetupKind) -> &mut Vec<String> {
        match k {
            SetupKind::Station => &mut self.stations,
            SetupKind::Mount => &mut self.mounts,
        }
    }
    /// Number of set-ups of kind `k` (1 without a change).
    pub fn n_setups(&self, k: SetupKind) -> usize {
        self.setups(k).len().max(1)
    }
    /// Number of the instrument's stations (1 without re-stationing).
    pub fn n_stations(&self) -> usize {
        self.n_setups(SetupKind::Station)
    }
    /// The placement parameters (indices among them) a set-up of kind `k` has its own of.
    pub fn setup_params(&self, k: SetupKind) -> std::ops::Range<usize> {
        let ns = self.measurement.def().n_station();
        match k {
            SetupKind::Station => 0..ns,
            SetupKind::Mount => ns..self.measurement.n_placement(),
        }
    }
    /// Parameters of one station beyond the first ([`Block::n_station`](crate::measurement::Block::n_station)).
    pub fn n_station_params(&self) -> usize {
        self.setup_params(SetupKind::Station).len()
    }
    /// Indices of set-up `s`'s own parameters (`s` ≥ 1; the first's are the placement's).
    pub fn setup_block(&self, k: SetupKind, s: usize) -> std::ops::Range<usize> {
        debug_assert!(s >= 1 && s < self.n_setups(k));
        let mut start = self.also_range().end;
        for kind in SetupKind::ALL {
            let n = self.setup_params(kind).len();
            if kind == k {
                start += (s - 1) * n;
                return start..start + n;
            }
            start += (self.n_setups(kind) - 1) * n;
        }
        unreachable!("every kind is in SetupKind::ALL")
    }
    /// Indices of station `s`'s own parameters (`s` ≥ 1).
    pub fn station_range(&self, s: usize) -> std::ops::Range<usize> {
        self.setup_block(SetupKind::Station, s)
    }
    /// Adds a set-up of kind `k` labelled `label` whose own parameters are `values` (its
    /// [`Self::setup_params`]' values) after the others of its kind (effect blocks keep their
    /// parameters, after it), into the model and into the parameter vector `x`; returns its
    /// index. A model of one unnamed set-up of the kind names it `first` first.
    pub fn add_setup(&mut self, k: SetupKind, x: &mut Vec<f64>, label: &str, values: &[f64], first: &str) -> usize {
        if self.setups(k).is_empty() {
            self.setups_mut(k).push(first.to_string());
        }
        let m = self.measurement;
        let params = self.setup_params(k);
        let at = match k {
            SetupKind::Station => self.first_effect() - (self.n_setups(SetupKind::Mount) - 1) * self.setup_params(SetupKind::Mount).len(),
            SetupKind::Mount => self.first_effect(),
        };
        for (i, p) in params.enumerate().rev() {
            self.names.insert(at, format!("{}@{label}", m.placement_names()[p]));
            self.kinds.insert(at, if m.def().placement_is_angle(p) { Kind::Angle } else { Kind::Length });
            self.nominal.insert(at, values[i]);
            x.insert(at, values[i]);
        }
        self.setups_mut(k).push(label.to_string());
        self.setups(k).len() - 1
    }
    /// Indices of every parameter that places the instrument: the placement and the other
    /// stations' and mounts'.
    pub fn setup_range(&self) -> std::ops::Range<usize> {
        self.n_chain()..self.first_effect()
    }
    /// This model with the instrument at `stations.0.len()` stations and `mounts.0.len()`
    /// mounts, the first of each at the placement, the others at their values in `.1` (each
    /// its [`Self::setup_params`]' values); no label: one unnamed. Chosen before effect blocks
    /// are added.
    pub fn with_setups(mut self, stations: (Vec<String>, &[Vec<f64>]), mounts: (Vec<String>, &[Vec<f64>])) -> CalibModel {
        assert!(self.effects.is_empty(), "the set-ups are chosen before effect blocks are added");
        let end = self.also_range().end;
        self.names.truncate(end);
        self.kinds.truncate(end);
        self.nominal.truncate(end);
        self.stations = Vec::new();
        self.mounts = Vec::new();
        let mut x = self.nominal.clone();
        for (k, (labels, values)) in SetupKind::ALL.into_iter().zip([stations, mounts]) {
            if let Some(first) = labels.first() {
                self.setups_mut(k).push(first.clone());
            }
            for (label, v) in labels.iter().skip(1).zip(values) {
                self.add_setup(k, &mut x, label, v, "");
            }
        }
        self
    }
}
