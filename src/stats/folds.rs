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

/// Interleaved folds over whole blocks: `groups[i]` is row i's block (non-decreasing, as
/// [`crate::dataset::blocks::Blocks::ids_of`] gives them); block b goes to fold `b mod k`, so no
/// block is ever on both sides of a split. With every row its own block, [`interleaved`].
pub fn interleaved_groups(groups: &[usize], k: usize) -> Vec<Vec<usize>> {
    let n_groups = groups.last().map_or(0, |g| g + 1);
    let k = k.clamp(2, n_groups.max(2));
    let mut folds = vec![Vec::new(); k];
    for (i, &g) in groups.iter().enumerate() {
        folds[g % k].push(i);
    }
    folds.retain(|f| !f.is_empty());
    folds
}

/// Blocked folds over whole blocks: the `k` contiguous stretches of [`blocked`], each boundary
/// moved to the block start nearest to it (a stretch left empty is dropped). With every row its
/// own block, [`blocked`].
pub fn blocked_groups(groups: &[usize], k: usize) -> Vec<Vec<usize>> {
    let n = groups.len();
    let k = k.clamp(2, n.max(2));
    // First row of each row's block, and every block's first row.
    let mut start = vec![0; n];
    for i in 1..n {
        start[i] = if groups[i] == groups[i - 1] { start[i - 1] } else { i };
    }
    let firsts: Vec<usize> = (0..n).filter(|&i| start[i] == i).collect();
    let snap = |b: usize| firsts.iter().copied().min_by_key(|&s| (s.abs_diff(b), s)).unwrap_or(0);
    let bounds: Vec<usize> = (0..k).map(|f| snap(f * n / k)).collect();
    let mut folds = vec![Vec::new(); k];
    for i in 0..n {
        let f = (0..k).rev().find(|&f| bounds[f] <= start[i]).unwrap_or(0);
        folds[f].push(i);
    }
    folds.retain(|f| !f.is_empty());
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

    #[test]
    fn folds_over_blocks_never_split_a_block_and_reduce_to_rows_for_singletons() {
        for n in [2, 7, 10, 23] {
            for k in [2, 3, 5] {
                let single: Vec<usize> = (0..n).collect();
                assert_eq!(interleaved_groups(&single, k), interleaved(n, k));
                assert_eq!(blocked_groups(&single, k), blocked(n, k));
            }
        }
        let groups = [0, 0, 0, 1, 1, 2, 3, 3, 3, 3, 4];
        for folds in [interleaved_groups(&groups, 3), blocked_groups(&groups, 3)] {
            let mut all: Vec<usize> = folds.iter().flatten().copied().collect();
            all.sort_unstable();
            assert_eq!(all, (0..groups.len()).collect::<Vec<_>>());
            for f in &folds {
                for g in f.iter().map(|&i| groups[i]) {
                    assert!(groups.iter().enumerate().filter(|(_, h)| **h == g).all(|(i, _)| f.contains(&i)), "{folds:?}");
                }
            }
        }
        assert_eq!(interleaved_groups(&groups, 3), vec![vec![0, 1, 2, 6, 7, 8, 9], vec![3, 4, 10], vec![5]]);
        assert_eq!(blocked_groups(&groups, 3), vec![vec![0, 1, 2], vec![3, 4, 5], vec![6, 7, 8, 9, 10]]);
    }
}
