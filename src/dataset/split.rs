//! Held-out rows drawn as a scenario or a calibration asks: stratified over a key (the nominal
//! cable length, a point's distance from the instrument).

use super::Split;
use crate::seed::{stream_seed, Stream};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// Test poses stratified over the nominal cable length: poses sorted by length are cut into
/// `test` strata of equal size and one pose per stratum, chosen at random, is held out.
pub fn stratified_split(lengths: &[f64], test: usize, seed: u64) -> Vec<Split> {
    let mut split = vec![Split::Train; lengths.len()];
    if test == 0 {
        return split;
    }
    let mut order: Vec<usize> = (0..lengths.len()).collect();
    order.sort_by(|a, b| lengths[*a].total_cmp(&lengths[*b]).then(a.cmp(b)));
    let mut rng = ChaCha8Rng::seed_from_u64(stream_seed(seed, Stream::Split, 0));
    for k in 0..test {
        let a = k * lengths.len() / test;
        let b = ((k + 1) * lengths.len() / test).max(a + 1);
        split[order[rng.random_range(a..b)]] = Split::Test;
    }
    split
}
