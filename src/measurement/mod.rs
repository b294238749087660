//! What the instrument reads on each row, as a calibration model predicts it from the target
//! point the kinematic chain gives: the reading, its derivatives, the instrument's placement
//! parameters and how to place it from nominal target points. One module per measurement type,
//! each implementing [`Instrument`]; [`Measurement`] names them and [`Measurement::def`] is the
//! registry. [`CalibModel`](crate::calib::model::CalibModel) appends the placement parameters after the
//! chain's and asks the measurement for the reading.
//!
//! | type | per row (dataset columns, mm) | placement parameters (internal units: m, rad) |
//! |---|---|---|
//! | `length` ([`length`]) | a draw-wire's cable length `L` | exit point (base frame, 3), length offset (1), tool point (flange frame, 3) |
//! | `point` ([`point`]) | a laser tracker's target position `x, y, z` | base-to-tracker translation (3) and rotation (3), target point (flange frame, 3) |
//! | `pose` ([`pose`]) | a 6-D probe's position and orientation `x, y, z, rx, ry, rz` (degrees, Euler angles), read by the model as nine lengths | base-to-tracker translation and rotation (6), probe orientation on the flange (3), probe origin (flange frame, 3) |
//! | `socket` ([`socket`]) | none: a ball on the flange seated in a socket (`socket` and `placement` columns name which); the model reads the ball's centre minus the socket's, always zero | the socket's centre (base frame, 3; one station per socket), the ball's centre (flange frame, 3) |
//! | `plane` ([`plane`]) | none: a touch probe's contact with a face (`plane` and `placement` columns name which); the model reads how far the stylus' centre stands below the face's offset, always zero | the face's normal (2 angles) and offset (one station per face), the stylus' centre (flange frame, 3) |
//! | `indicator` ([`plane`]) | a dial indicator's plunger travel `indicator` on a face (`plane`, `placement` columns) | as `plane`, the indicator's zero point the target |
//!
//! The placement is split in two: the instrument's own parameters (where it sits and its reading
//! offset) and the **target** on the flange (the tool point the cable is hooked to, or the
//! reflector a tracker follows), which the chain carries to the base frame. An instrument reads
//! one point of the flange (the target), or several rigidly attached to it (a pose reads its
//! probe's origin and the tips of two of its axes: [`Block::targets`]), so every derivative is a
//! point Jacobian of the chain. Derivatives are analytic; the tests below check every type
//! against finite differences.
//!
//! An [`Instrument`] is three parts: its residual block ([`Block`]: the reading of the target
//! point(s) for its own unknowns, and the derivatives), its rows in files ([`FileRows`]: columns,
//! plausibility, the artifact's feature they name) and its placing ([`Placing`]: its start from
//! nominal flange frames, its frame). Adding a measurement type means one module implementing
//! the three and its variant with its line in [`Measurement::def`]; the rows' residual vectors
//! follow from [`Measurement::dim`].

pub mod length;
mod placement;
pub mod plane;
pub mod point;
pub mod pose;
pub mod socket;

use nalgebra::{Matrix3, Vector3};
pub use placement::Placement;
pub use pose::Euler;
use serde::{Deserialize, Serialize};

pub use length::CABLE_PARAMS;

/// Largest reading dimension and number of instrument parameters of any measurement type (stack
/// buffers of the hot loops).
pub const MAX_DIM: usize = 9;
/// Largest number of an instrument's own placement parameters.
pub const MAX_OWN: usize = 12;
/// Most points of the flange an instrument reads.
pub const MAX_TARGETS: usize = 3;

/// An instrument's residual block: what the model reads of the target point(s) for the
/// instrument's own unknowns (its placement), with the derivatives, row by row.
pub trait Block: Sync {
    /// The name in result files and messages.
    fn name(&self) -> &'static str;
    /// The values of one reading as the model predicts them (millimetres in a dataset, metres
    /// inside), in reading order: their labels.
    fn columns(&self) -> &'static [&'static str];
    /// The group of each reading value, when the values are not all alike (a pose's position
    /// and its axes, whose residuals have their own scales): robust screens judge each group
    /// on its own scale. Empty: one group.
    fn value_groups(&self) -> &'static [usize] {
        &[]
    }
    /// The number of points of the flange frame the reading depends on (one target; a pose's
    /// three).
    fn n_targets(&self) -> usize {
        1
    }
    /// Those points in the flange frame, for the instrument's own parameters `own` and the
    /// target `tool`, and their derivatives with respect to `own` into `dlocal` (row-major,
    /// `n_targets × own.len()`); the derivative with respect to the target is the identity.
    fn targets(&self, _own: &[f64], tool: &Vector3<f64>, local: &mut [Vector3<f64>], dlocal: &mut [Vector3<f64>]) {
        local[0] = *tool;
        dlocal.iter_mut().for_each(|v| *v = Vector3::zeros());
    }
    /// The placement parameters' names, the instrument's own first, then the target's three.
    fn placement_names(&self) -> &'static [&'static str];
    /// How many of the instrument's own placement parameters (the first ones) say where it
    /// stands: what re-stationing it changes (a tracker's base-to-tracker transform, a
    /// draw-wire's exit point and length offset). The others (a probe's orientation on the
    /// flange) and the target go with the arm.
    fn n_station(&self) -> usize {
        self.placement_names().len() - 3
    }
    /// Whether placement parameter `k` is an angle (rad); the others are lengths (m).
    fn placement_is_angle(&self, _k: usize) -> bool {
        false
    }
    /// Index (among the placement parameters) of the constant every reading carries, if the
    /// instrument has one (the draw-wire's length offset).
    fn offset_index(&self) -> Option<usize> {
        None
    }
    /// The reading(s) `y` (m) of the target points `p` (base frame, m; [`Self::n_targets`] of
    /// them) for the instrument's own placement parameters `own` (the placement without the
    /// target).
    fn reading(&self, own: &[f64], p: &[Vector3<f64>], y: &mut [f64]);
    /// [`Self::reading`] with its derivatives: `dy_dp[i * n_targets + t]` is ∂y_i/∂p_t and
    /// `dy_down` (row-major, `dim × own.len()`) is ∂y/∂own.
    fn reading_grad(&self, own: &[f64], p: &[Vector3<f64>], y: &mut [f64], dy_dp: &mut [Vector3<f64>], dy_down: &mut [f64]);
    /// Whether [`Self::reading_grad`]'s readings equal [`Self::reading`]'s to the bit, so one
    /// pass gives residuals and Jacobian alike.
    fn exact_grad_reading(&self) -> bool {
        false
    }
}

/// How an instrument's rows are written: its dataset columns and their values, what is
/// implausible in them, and the artifact's feature the rows name.
pub trait FileRows: Block {
    /// What the instrument is, for messages ("draw-wire cable length").
    fn describe(&self) -> &'static str;
    /// The dataset columns of one reading, when they are not the values themselves (a pose's
    /// Euler angles): [`Self::values_of_file`] turns them into the values.
    fn file_columns(&self) -> &'static [&'static str] {
        self.columns()
    }
    /// The reading values (mm) of a dataset row's reading columns `file` (in
    /// [`Self::file_columns`] order; angles in degrees, intrinsic X-Y-Z as a loaded row holds
    /// them).
    fn values_of_file(&self, file: &[f64], out: &mut [f64]) {
        out.copy_from_slice(file);
    }
    /// The trailing dataset columns that are angles (degrees; a pose's `rx, ry, rz`).
    fn file_angles(&self) -> usize {
        0
    }
    /// `None` when dataset column `k` of a reading ([`Self::file_columns`], mm or degrees) is
    /// plausible, else what is wrong with it ("cable length must be positive, found -3").
    fn implausible(&self, k: usize, v: f64) -> Option<String>;
    /// A row's dataset columns (mm, angles in degrees in the convention `euler`) of the
    /// model's values `v` (mm): the inverse of [`Self::values_of_file`].
    fn file_of_values(&self, v: &[f64], _euler: Euler) -> Vec<f64> {
        v.to_vec()
    }
    /// The artifact's feature its rows name (a socket, a face), when the instrument stands at
    /// one: each feature of each placement is then a station of its own.
    fn feature(&self) -> Option<FeatureKind> {
        None
    }
}

/// Where an instrument starts and how it is shown: its placement located from nominal flange
/// frames, its frame, its panels.
pub trait Placing: Sync {
    /// The instrument's own placement and the target on the flange, from the flange's origins
    /// `p` (base frame, m, as the nominal arm puts them), its rotations `rot` and the readings
    /// `y` (m, `dim` per row): the starting guess a calibration refines. An instrument that
    /// cannot tell its target from the data gives a zero one. `None` when the rows cannot place
    /// it.
    fn locate(&self, p: &[Vector3<f64>], rot: &[Matrix3<f64>], y: &[f64]) -> Option<(Vec<f64>, Vector3<f64>)>;
    /// Where the instrument sits for its own placement parameters `own` (m, rad): its origin
    /// in the base frame and, for an instrument reading coordinates in a frame of its own, that
    /// frame's axes (columns, base frame).
    fn frame(&self, own: &[f64]) -> InstrumentFrame;
    /// The orientation of the target on the flange (a 6-D probe's; identity for a point).
    fn target_rotation(&self, _own: &[f64]) -> Matrix3<f64> {
        Matrix3::identity()
    }
    /// The titles of the report's panels of the instrument's placement: its lengths (mm) and
    /// its angles (degrees).
    fn panel_titles(&self) -> (&'static str, &'static str);
    /// The instrument's own placement from the rows as [`Self::locate`] takes them, the target
    /// on the flange already known (`tool`, flange frame, m): a second face of an artifact
    /// touched by the stylus the first face placed. `None`: locate it as the first.
    fn locate_about(&self, _p: &[Vector3<f64>], _rot: &[Matrix3<f64>], _y: &[f64], _tool: &Vector3<f64>) -> Option<Vec<f64>> {
        None
    }
    /// The target on the flange every station's rows agree on (each station's flange origins,
    /// rotations and readings, as [`Self::locate`] takes them), where the instrument finds it
    /// from all of them together (the stylus touching several faces); `None`: from the first
    /// station's rows.
    fn locate_target(&self, _stations: &[plane::FaceRows]) -> Option<Vector3<f64>> {
        None
    }
}

/// One measurement type: its residual block, its rows in files and its placement
/// ([`Block`], [`FileRows`], [`Placing`]; every type implementing the three is one).
pub trait Instrument: Block + FileRows + Placing {}

impl<T: Block + FileRows + Placing> Instrument for T {}

/// The [`FileRows`] of an instrument that reads nothing (a ball seated in a socket, a probe's
/// contact with a face): no dataset column, every model value zero, nothing implausible.
macro_rules! reads_nothing {
    () => {
        fn file_columns(&self) -> &'static [&'static str] {
            &[]
        }
        fn values_of_file(&self, _file: &[f64], out: &mut [f64]) {
            out.iter_mut().for_each(|v| *v = 0.0);
        }
        fn file_of_values(&self, _v: &[f64], _euler: $crate::measurement::Euler) -> Vec<f64> {
            Vec::new()
        }
        fn implausible(&self, _k: usize, _v: f64) -> Option<String> {
            None
        }
    };
}
pub(crate) use reads_nothing;

/// The kind of an artifact's feature a row names: what held the target still (a socket) or
/// where it touched (a face). The rows' column of that name carries the feature's label.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum FeatureKind {
    /// A socket a ball on the flange was seated in.
    Socket,
    /// A face touched by a probe or read by a dial indicator.
    Plane,
}

impl FeatureKind {
    /// Every kind.
    pub const ALL: [FeatureKind; 2] = [FeatureKind::Socket, FeatureKind::Plane];

    /// The column naming the feature, and the word for it.
    pub fn column(self) -> &'static str {
        match self {
            FeatureKind::Socket => "socket",
            FeatureKind::Plane => "plane",
        }
    }
}

/// Where an instrument sits ([`Placing::frame`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct InstrumentFrame {
    /// Its origin (a cable's exit point, a tracker's origin), base frame, m.
    pub origin: Vector3<f64>,
    /// The axes its reading's coordinates are taken along (columns, base frame), when it reads
    /// coordinates.
    pub axes: Option<Matrix3<f64>>,
}

/// A measurement type.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
pub enum Measurement {
    /// The cable length of a draw-wire sensor: |tool point − exit point| + length offset.
    #[default]
    Length,
    /// A laser tracker's 3-D position of its target, in the tracker's frame.
    Point,
    /// A laser tracker's 6-D pose of a probe (position and orientation), in the tracker's frame.
    Pose,
    /// A ball on the flange seated in a socket of an artifact: no reading, the ball's centre
    /// held at the socket's.
    Socket,
    /// A touch-trigger probe on the flange touching a face of an artifact: no reading, the
    /// stylus' centre on the face (its radius and pre-travel above it).
    Plane,
    /// A dial indicator on the flange reading a face of an artifact: its plunger's travel.
    Indicator,
}

impl Measurement {
    /// Every measurement type.
    pub const ALL: [Measurement; 6] =
        [Measurement::Length, Measurement::Point, Measurement::Pose, Measurement::Socket, Measurement::Plane, Measurement::Indicator];

    /// The registry: the type's implementation.
    pub fn def(self) -> &'static dyn Instrument {
        match self {
            Measurement::Length => &length::Length,
            Measurement::Point => &point::Point,
            Measurement::Pose => &pose::Pose,
            Measurement::Socket => &socket::Socket,
            Measurement::Plane => &plane::Plane,
            Measurement::Indicator => &plane::Indicator,
        }
    }

    /// The name in result files and messages.
    pub fn name(self) -> &'static str {
        self.def().name()
    }

    /// Values per row as the model reads them (1 for a length, 3 for a point, 9 for a pose).
    pub fn dim(self) -> usize {
        self.def().columns().len()
    }

    /// Reading columns per dataset row (1 for a length, 3 for a point, 6 for a pose).
    pub fn file_dim(self) -> usize {
        self.def().file_columns().len()
    }

    /// The leading dataset columns that are lengths (mm): all of them, but a pose's angles.
    pub fn file_lengths(self) -> usize {
        self.def().file_columns().len() - self.def().file_angles()
    }

    /// The reading values (mm) the model reads of a row's dataset columns `file` (mm and
    /// degrees): [`FileRows::values_of_file`] into a new vector.
    pub fn values_of_file(self, file: &[f64]) -> Vec<f64> {
        let mut v = vec![0.0; self.dim()];
        self.def().values_of_file(file, &mut v);
        v
    }

    /// A row's dataset columns (mm, and a pose's angles in degrees in the convention `euler`)
    /// of the model's values `v` (mm): the inverse of [`Self::values_of_file`] (a pose's axes
    /// made orthonormal first; NaN angles when they are degenerate).
    pub fn file_of_values(self, v: &[f64], euler: Euler) -> Vec<f64> {
        self.def().file_of_values(v, euler)
    }

    /// The number of value groups ([`Block::value_groups`]): 1 when the values are alike.
    pub fn n_value_groups(self) -> usize {
        self.def().value_groups().iter().max().map_or(1, |g| g + 1)
    }

    /// The values of group `g` ([`Block::value_groups`]; every value where they are
    /// alike) of row-major `values`, [`Self::dim`] a row: a pose's positions (group 0) or axes.
    pub fn group_values(self, values: &[f64], g: usize) -> Vec<f64> {
        let (dim, groups) = (self.dim(), self.def().value_groups());
        let cols: Vec<usize> = (0..dim).filter(|&c| groups.get(c).copied().unwrap_or(0) == g).collect();
        values.chunks(dim).flat_map(|row| cols.iter().map(move |&c| row[c])).collect()
    }

    /// The placement parameters' names, the instrument's own first, then the target's.
    pub fn placement_names(self) -> &'static [&'static str] {
        self.def().placement_names()
    }

    /// Number of placement parameters.
    pub fn n_placement(self) -> usize {
        self.placement_names().len()
    }

    /// Index (among the placement parameters) of the target's first coordinate; the target is
    /// the last three.
    pub fn target_index(self) -> usize {
        self.n_placement() - 3
    }

    /// See [`Block::offset_index`].
    pub fn offset_index(self) -> Option<usize> {
        self.def().offset_index()
    }

    /// The reading of one target point `p` (an instrument of one target: a draw-wire, a point
    /// tracker). See [`Block::reading`].
    pub fn reading(self, own: &[f64], p: &Vector3<f64>, y: &mut [f64]) {
        debug_assert_eq!(self.def().n_targets(), 1);
        self.def().reading(own, std::slice::from_ref(p), y)
    }

    /// The measurement type with `n` reading columns per dataset row when the row names no
    /// artifact's feature (each such type has its own number; the instruments at a feature are
    /// told by it: [`Self::of_feature`]).
    pub fn of_file_dim(n: usize) -> Option<Measurement> {
        Self::ALL.into_iter().find(|m| m.file_dim() == n && n > 0 && m.feature().is_none())
    }

    /// Whether the rows of this type read nothing and hold a constant instead (a ball seated in
    /// a socket, a probe's contact with a face).
    pub fn is_constant(self) -> bool {
        self.file_dim() == 0
    }

    /// See [`FileRows::feature`].
    pub fn feature(self) -> Option<FeatureKind> {
        self.def().feature()
    }

    /// The instrument whose rows name a feature of kind `kind` and read `file_dim` columns.
    pub fn of_feature(kind: FeatureKind, file_dim: usize) -> Option<Measurement> {
        Self::ALL.into_iter().find(|m| m.feature() == Some(kind) && m.file_dim() == file_dim)
    }
    /// Whether `other`'s rows beside this one's stand at stations of one list and read the same
    /// target: an artifact's other kind of feature (faces touched by the ball that is seated in
    /// the sockets), each feature a station whose own parameters are its instrument's (as many
    /// for both: a socket's centre, a face's normal and offset).
    pub fn shares_stations_with(self, other: Measurement) -> bool {
        other != self
            && other.feature().is_some()
            && self.feature().is_some()
            && other.def().n_station() == self.def().n_station()
            && other.n_placement() == self.n_placement()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Rotation3;

    fn own_of(m: Measurement, phase: f64) -> Vec<f64> {
        (0..m.target_index()).map(|k| 0.3 * (k as f64 * phase).sin() + 0.1).collect()
    }

    #[test]
    fn reading_derivatives_match_finite_differences() {
        for m in Measurement::ALL {
            let n_own = m.target_index();
            let own = own_of(m, 0.7);
            let nt = m.def().n_targets();
            let p: Vec<Vector3<f64>> = (0..nt).map(|t| Vector3::new(0.41 + 0.05 * t as f64, -0.22 + 0.03 * t as f64, 0.35 - 0.04 * t as f64)).collect();
            let d = m.dim();
            let (mut y, mut dy_dp, mut dy_down) = (vec![0.0; d], vec![Vector3::zeros(); d * nt], vec![0.0; d * n_own]);
            m.def().reading_grad(&own, &p, &mut y, &mut dy_dp, &mut dy_down);
            let mut plain = vec![0.0; d];
            m.def().reading(&own, &p, &mut plain);
            assert!(y.iter().zip(&plain).all(|(a, b)| (a - b).abs() < 1e-15), "{}: {y:?} vs {plain:?}", m.name());
            let h = 1e-7;
            let (mut yp, mut ym) = (vec![0.0; d], vec![0.0; d]);
            for t in 0..nt {
                for axis in 0..3 {
                    let (mut a, mut b) = (p.clone(), p.clone());
                    a[t][axis] += h;
                    b[t][axis] -= h;
                    m.def().reading(&own, &a, &mut yp);
                    m.def().reading(&own, &b, &mut ym);
                    for i in 0..d {
                        let fd = (yp[i] - ym[i]) / (2.0 * h);
                        assert!((fd - dy_dp[i * nt + t][axis]).abs() < 1e-7, "{} dy{i}/dp{t}.{axis}: {fd} vs {}", m.name(), dy_dp[i * nt + t][axis]);
                    }
                }
            }
            for k in 0..n_own {
                let (mut a, mut b) = (own.clone(), own.clone());
                a[k] += h;
                b[k] -= h;
                m.def().reading(&a, &p, &mut yp);
                m.def().reading(&b, &p, &mut ym);
                for i in 0..d {
                    let fd = (yp[i] - ym[i]) / (2.0 * h);
                    assert!((fd - dy_down[i * n_own + k]).abs() < 1e-7, "{} dy{i}/down{k}: {fd} vs {}", m.name(), dy_down[i * n_own + k]);
                }
            }
        }
    }

    #[test]
    fn target_derivatives_match_finite_differences() {
        for m in Measurement::ALL {
            let (n_own, nt) = (m.target_index(), m.def().n_targets());
            assert!(nt <= MAX_TARGETS, "{}", m.name());
            let own = own_of(m, 1.1);
            let tool = Vector3::new(0.01, -0.02, 0.15);
            let (mut local, mut dlocal) = (vec![Vector3::zeros(); nt], vec![Vector3::repeat(9.0); nt * n_own]);
            m.def().targets(&own, &tool, &mut local, &mut dlocal);
            assert_eq!(local[0], tool, "{}: the first target is the tool point", m.name());
            let h = 1e-7;
            let (mut lp, mut lm, mut scratch) = (vec![Vector3::zeros(); nt], vec![Vector3::zeros(); nt], vec![Vector3::zeros(); nt * n_own]);
            for k in 0..n_own {
                let (mut a, mut b) = (own.clone(), own.clone());
                a[k] += h;
                b[k] -= h;
                m.def().targets(&a, &tool, &mut lp, &mut scratch);
                m.def().targets(&b, &tool, &mut lm, &mut scratch);
                for t in 0..nt {
                    let fd = (lp[t] - lm[t]) / (2.0 * h);
                    assert!((fd - dlocal[t * n_own + k]).norm() < 1e-7, "{} dlocal{t}/down{k}: {fd:?} vs {:?}", m.name(), dlocal[t * n_own + k]);
                }
            }
        }
    }

    #[test]
    fn the_target_is_the_last_three_placement_parameters() {
        for m in Measurement::ALL {
            let names = m.placement_names();
            assert_eq!(&names[m.target_index()..], &["tool.x", "tool.y", "tool.z"], "{}", m.name());
            assert!(m.dim() <= MAX_DIM && m.target_index() <= MAX_OWN, "{}", m.name());
        }
    }

    #[test]
    fn every_type_that_reads_columns_has_its_own_number_of_them() {
        for m in Measurement::ALL.into_iter().filter(|m| m.feature().is_none()) {
            assert_eq!(Measurement::of_file_dim(m.file_dim()), Some(m), "{}", m.name());
        }
        assert_eq!(Measurement::of_file_dim(0), None, "no reading column: poses only, or a socket's rows");
    }

    /// (A socket's placement is found by the pivot fit, a face's with its stylus: tested in
    /// [`socket`] and [`plane`].)
    #[test]
    fn locate_recovers_the_placement_of_exact_readings() {
        for m in Measurement::ALL.into_iter().filter(|m| m.feature().is_none()) {
            let n_own = m.target_index();
            let own: Vec<f64> = (0..n_own).map(|k| 0.2 * (k as f64 * 1.3).cos() + 0.05).collect();
            let (pts, rots): (Vec<Vector3<f64>>, Vec<Matrix3<f64>>) = (0..40)
                .map(|i| {
                    let i = i as f64;
                    let p = Vector3::new(0.3 + 0.2 * (i * 0.37).sin(), 0.25 * (i * 0.71).cos(), 0.4 + 0.15 * (i * 0.23).sin());
                    (p, Rotation3::from_euler_angles(1.2 * (i * 0.53).sin(), 0.6 * (i * 0.29).cos(), 2.0 * (i * 0.17).sin()).into_inner())
                })
                .unzip();
            // A pose also finds its probe's origin on the flange; the others cannot tell it.
            let tool = if m.def().n_targets() > 1 { Vector3::new(0.02, -0.03, 0.12) } else { Vector3::zeros() };
            let nt = m.def().n_targets();
            let (mut local, mut dlocal) = (vec![Vector3::zeros(); nt], vec![Vector3::zeros(); nt * n_own]);
            m.def().targets(&own, &tool, &mut local, &mut dlocal);
            let mut y = vec![0.0; pts.len() * m.dim()];
            for ((p, r), yi) in pts.iter().zip(&rots).zip(y.chunks_mut(m.dim())) {
                let at: Vec<Vector3<f64>> = local.iter().map(|l| p + r * l).collect();
                m.def().reading(&own, &at, yi);
            }
            let (found, found_tool) = m.def().locate(&pts, &rots, &y).unwrap_or_else(|| panic!("{}: not located", m.name()));
            for (k, (a, b)) in found.iter().zip(&own).enumerate() {
                assert!((a - b).abs() < 1e-8, "{} own[{k}]: {a} vs {b}", m.name());
            }
            assert!((found_tool - tool).norm() < 1e-8, "{} tool: {found_tool:?}", m.name());
        }
    }
}
