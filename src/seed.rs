//! Randomness: every random draw of twincal flows from one recorded seed through these streams.

/// Independent random streams derived from one recorded seed.
#[derive(Clone, Copy)]
pub enum Stream {
    /// The scenario's true geometric deviations.
    Geometry = 1,
    /// Pose sampling (the Halton start, the shuffled order).
    Sampling = 2,
    /// The train / test split.
    Split = 3,
    /// Noise of the draw-wire's readings, one item per pose.
    Noise = 4,
    /// Noise of the temperature sensor (`effects.thermal.temp_noise_k`), one item per pose.
    TempNoise = 5,
    /// Raw readings the stability gate of a simulated acquisition watches during the hold, one item per pose.
    Gate = 6,
    /// Placement and sign of the glitch runs.
    Glitches = 7,
    /// Noise of a tracker's readings, one item per pose.
    TrackerNoise = 8,
    /// Where within its logging step a replayed row's true joint angle sits, one item per row.
    LoggedAngle = 9,
    /// A measurement plan's candidate pool (the Halton start) and its random comparison sets.
    Plan = 10,
    /// A pose list's payload runs after the first: each run's noise and acquisition.
    PayloadRun = 11,
    /// A ball seated in an artifact's sockets: each seated configuration's orientation, seat
    /// and backlash flanks, one item per socket of each placement.
    Seating = 12,
    /// A probe touching an artifact's faces: each contact's point, orientation, trigger and
    /// backlash flanks, one item per face of each placement.
    Touching = 13,
}

/// A seed for stream `s`, item `i` (SplitMix64 of the mixed inputs).
pub fn stream_seed(seed: u64, s: Stream, i: u64) -> u64 {
    let mut z = seed ^ ((s as u64) << 56) ^ i.wrapping_mul(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}
