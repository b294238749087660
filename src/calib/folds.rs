//! Cross-validation folds over rows in acquisition order: the one generator of folds that every
//! cross-validation in twincal uses (network selection, diagnosis).
//!
//! * [`interleaved`]: fold `f` of `k` holds rows `f, f + k, f + 2k, ...`, so every fold spans
//!   the whole acquisition (held-out rows interleave with the training rows, as unseen rows of
//!   the same robot do);
//! * [`blocked`]: `k` contiguous blocks, so a fold is a stretch of time (what a time-dependent
//!   effect must extrapolate across);
//! * [`shuffled`]: a seeded random assignment (for rows with no order that matters).
//!
//! `k` is clamped to `2..=max(n, 2)`.

/// Interleaved folds of `n` rows, see the module docs.
pub fn interleaved(n: usize, k: usize) -> Vec<Vec<usize>> {
    let k = k.clamp(2, n.max(2));
    (0..k).map(|f| (f..n).step_by(k).collect()).collect()
}

/// Blocked folds of `n` rows, see the module docs.
pub fn blocked(n: usize, k: usize) -> Vec<Vec<usize>> {
    let k = k.clamp(2, n.max(2));
    (0..k).map(|f| (f * n / k..(f + 1) * n / k).collect()).collect()
}

/// Random folds of `n` rows: row `perm[p]` of a permutation drawn from `seed` goes to fold
/// `p mod k` (each fold ascending).
pub fn shuffled(n: usize, k: usize, seed: u64) -> Vec<Vec<usize>> {
    use rand::seq::SliceRandom;
    use rand::SeedableRng;
    let k = k.clamp(2, n.max(2));
    let mut perm: Vec<usize> = (0..n).collect();
    perm.shuffle(&mut rand_chacha::ChaCha8Rng::seed_from_u64(seed));
    let mut folds = vec![Vec::new(); k];
    for (p, &i) in perm.iter().enumerate() {
        folds[p % k].push(i);
    }
    folds.iter_mut().for_each(|f| f.sort_unstable());
    folds
}

/// The rows of `0..n` outside `fold` (ascending; `fold` ascending).
pub fn others(n: usize, fold: &[usize]) -> Vec<usize> {
    (0..n).filter(|i| fold.binary_search(i).is_err()).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn folds_partition_the_rows() {
        for n in [2, 7, 10, 23] {
            for k in [2, 3, 5] {
                for folds in [interleaved(n, k), blocked(n, k), shuffled(n, k, 7)] {
                    let mut all: Vec<usize> = folds.iter().flatten().copied().collect();
                    all.sort_unstable();
                    assert_eq!(all, (0..n).collect::<Vec<_>>(), "n {n} k {k}");
                    for f in &folds {
                        assert_eq!(others(n, f).len() + f.len(), n);
                    }
                }
            }
        }
        assert_eq!(interleaved(7, 3), vec![vec![0, 3, 6], vec![1, 4], vec![2, 5]]);
        assert_eq!(blocked(7, 3), vec![vec![0, 1], vec![2, 3], vec![4, 5, 6]]);
    }
}
