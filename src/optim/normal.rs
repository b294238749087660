//! The normal equations of a least-squares step, `A = JᵀJ` and `g = Jᵀr`, over the free
//! columns of a column-major Jacobian: dense (tiled) or, where the Jacobian is sparse, summed row
//! by row over its non-zero products.

use nalgebra::DMatrix;

/// Side of the square tiles of [`normal_equations`]: a tile's 16 sums are independent, so they
/// run side by side instead of waiting on one another.
const TILE: usize = 4;

/// `A = JᵀJ` and `g = Jᵀr` over the free columns of the column-major `jac`.
///
/// Every entry is the dot product of two columns summed in row order from −0.0, exactly as
/// `iter().map(x·y).sum()` sums it, so the results are bit for bit those of one dot product per
/// entry; they are only computed [`TILE`] × [`TILE`] at a time (four columns against four,
/// `r` counted as one more column for `g`), which reads each column a quarter as often and
/// keeps sixteen independent sums in flight instead of one.
///
/// Where at most a quarter of the free columns' entries are non-zero (a learned corrector per
/// reading value beside the geometry: each value's coefficients touch its own rows only), the
/// products of two non-zero entries are summed row by row instead ([`sparse_normal_equations`]):
/// the same sums in the same order without the zero products, so equal to the dense ones but
/// for the sign of an entry that is zero.
/// `rows` is the sparse path's scratch, kept by the caller across iterations (nothing allocated
/// once it has grown to the Jacobian's size).
pub(super) fn normal_equations(jac: &DMatrix<f64>, free: &[usize], r: &[f64], (a, g): (&mut DMatrix<f64>, &mut [f64]), rows: &mut SparseRows) {
    let m = r.len();
    let js = jac.as_slice();
    let nf = free.len();
    let nonzero: usize = free.iter().map(|&c| js[c * m..(c + 1) * m].iter().filter(|v| **v != 0.0).count()).sum();
    if nonzero * SPARSE_SHARE < m * nf {
        sparse_normal_equations(jac, free, r, (a, g), rows);
    } else {
        dense_normal_equations(jac, free, r, a, g);
    }
}

/// [`normal_equations`] column against column, [`TILE`] × [`TILE`] at a time.
fn dense_normal_equations(jac: &DMatrix<f64>, free: &[usize], r: &[f64], a: &mut DMatrix<f64>, g: &mut [f64]) {
    let m = r.len();
    let js = jac.as_slice();
    let nf = free.len();
    // Column `k` of the list: free column `k` of J, or `r` for `k == nf`.
    let col = |k: usize| -> &[f64] {
        if k < nf {
            &js[free[k] * m..(free[k] + 1) * m]
        } else {
            r
        }
    };
    let mut ia0 = 0;
    while ia0 < nf {
        // Columns past the end repeat the last one; their sums are computed and dropped.
        let ca: [&[f64]; TILE] = std::array::from_fn(|t| &col((ia0 + t).min(nf - 1))[..m]);
        let mut jb0 = ia0;
        while jb0 <= nf {
            let cb: [&[f64]; TILE] = std::array::from_fn(|u| &col((jb0 + u).min(nf))[..m]);
            let mut acc = [[-0.0f64; TILE]; TILE];
            for i in 0..m {
                let av: [f64; TILE] = std::array::from_fn(|t| ca[t][i]);
                let bv: [f64; TILE] = std::array::from_fn(|u| cb[u][i]);
                for t in 0..TILE {
                    for u in 0..TILE {
                        acc[t][u] += av[t] * bv[u];
                    }
                }
            }
            for (t, row) in acc.iter().enumerate() {
                let ia = ia0 + t;
                for (u, &v) in row.iter().enumerate() {
                    let jb = jb0 + u;
                    if ia >= nf || jb > nf {
                        continue;
                    }
                    if jb == nf {
                        g[ia] = v;
                    } else {
                        a[(ia, jb)] = v;
                        a[(jb, ia)] = v;
                    }
                }
            }
            jb0 += TILE;
        }
        ia0 += TILE;
    }
}

/// The non-zero free entries of a Jacobian row by row (compressed rows), reused from one
/// iteration to the next.
#[derive(Default)]
pub(super) struct SparseRows {
    /// Where each row's entries start in `entries` (one more than the rows).
    start: Vec<usize>,
    /// The next free slot of each row while filling.
    fill: Vec<usize>,
    /// (free column, value) of each non-zero entry, each row's in column order.
    entries: Vec<(usize, f64)>,
}

/// Below one non-zero entry in this many, the normal equations are summed row by row.
const SPARSE_SHARE: usize = 4;

/// [`normal_equations`] over the non-zero entries only: each row's non-zero free entries (in
/// column order) add their products to the lower triangle, rows in order, which is then
/// mirrored.
fn sparse_normal_equations(jac: &DMatrix<f64>, free: &[usize], r: &[f64], (a, g): (&mut DMatrix<f64>, &mut [f64]), rows: &mut SparseRows) {
    let m = r.len();
    let js = jac.as_slice();
    let nf = free.len();
    let SparseRows { start, fill, entries } = rows;
    start.clear();
    start.resize(m + 1, 0);
    for &c in free {
        for (i, v) in js[c * m..(c + 1) * m].iter().enumerate() {
            if *v != 0.0 {
                start[i + 1] += 1;
            }
        }
    }
    for i in 0..m {
        start[i + 1] += start[i];
    }
    fill.clear();
    fill.extend_from_slice(start);
    entries.clear();
    entries.resize(start[m], (0, 0.0));
    for (k, &c) in free.iter().enumerate() {
        for (i, v) in js[c * m..(c + 1) * m].iter().enumerate() {
            if *v != 0.0 {
                entries[fill[i]] = (k, *v);
                fill[i] += 1;
            }
        }
    }
    a.fill(-0.0);
    g.fill(-0.0);
    let (rows, cols) = (a.nrows(), a.ncols());
    debug_assert_eq!((rows, cols), (nf, nf));
    let av = a.as_mut_slice();
    for i in 0..m {
        let row = &entries[start[i]..start[i + 1]];
        for (e, &(p, vp)) in row.iter().enumerate() {
            g[p] += vp * r[i];
            // Column p of the lower triangle: entries (q, p) for q >= p, contiguous.
            let col = &mut av[p * nf..(p + 1) * nf];
            for &(q, vq) in &row[e..] {
                col[q] += vp * vq;
            }
        }
    }
    for p in 0..nf {
        for q in p + 1..nf {
            a[(p, q)] = a[(q, p)];
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::optim::util::free_indices;

    /// On a block-sparse Jacobian (a corrector's coefficients per reading value) the row-by-row
    /// sums equal one dot product per entry.
    #[test]
    fn sparse_normal_equations_match_plain_dot_products() {
        let dot = |a: &[f64], b: &[f64]| -> f64 { a.iter().zip(b).map(|(x, y)| x * y).sum() };
        let (m, n) = (90, 64);
        // Columns 0..4 shared by every row, then 6 per value of ten, each on its value's rows.
        let jac = DMatrix::from_fn(m, n, |i, k| if k < 4 || (k - 4) / 6 == i % 10 { ((i * 31 + k * 17) as f64 * 0.7311).sin() } else { 0.0 });
        let r: Vec<f64> = (0..m).map(|i| (i as f64 * 1.37).cos()).collect();
        let free: Vec<usize> = (0..n).filter(|k| k % 7 != 5).collect();
        let nf = free.len();
        let nonzero = free.iter().map(|&c| jac.column(c).iter().filter(|v| **v != 0.0).count()).sum::<usize>();
        assert!(nonzero * SPARSE_SHARE < m * nf, "the case must take the sparse path");
        let (mut a, mut g) = (DMatrix::<f64>::zeros(nf, nf), vec![0.0; nf]);
        // Twice with the same scratch: what the first call left in it changes nothing.
        let mut rows = SparseRows::default();
        for _ in 0..2 {
            normal_equations(&jac, &free, &r, (&mut a, &mut g), &mut rows);
            for (ia, &ca) in free.iter().enumerate() {
                assert_eq!(g[ia], dot(jac.column(ca).as_slice(), &r));
                for (ib, &cb) in free.iter().enumerate() {
                    assert_eq!(a[(ia, ib)], dot(jac.column(ca).as_slice(), jac.column(cb).as_slice()), "({ia}, {ib})");
                }
            }
        }
    }

    /// The tiled normal equations are bit for bit one dot product per entry, summed in row order.
    #[test]
    fn normal_equations_match_plain_dot_products_bit_for_bit() {
        let dot = |a: &[f64], b: &[f64]| -> f64 { a.iter().zip(b).map(|(x, y)| x * y).sum() };
        for (m, n) in [(1, 1), (7, 3), (37, 9), (101, 13)] {
            let jac = DMatrix::from_fn(m, n, |i, k| ((i * 31 + k * 17) as f64 * 0.7311).sin() * 10f64.powi((k % 5) as i32 - 2));
            let r: Vec<f64> = (0..m).map(|i| (i as f64 * 1.37).cos()).collect();
            for fixed in [vec![false; n], (0..n).map(|k| k % 3 == 1).collect::<Vec<bool>>()] {
                let free = free_indices(&fixed, n);
                let nf = free.len();
                let (mut a, mut g) = (DMatrix::<f64>::zeros(nf, nf), vec![0.0; nf]);
                dense_normal_equations(&jac, &free, &r, &mut a, &mut g);
                for (ia, &ca) in free.iter().enumerate() {
                    assert_eq!(g[ia].to_bits(), dot(jac.column(ca).as_slice(), &r).to_bits());
                    for (ib, &cb) in free.iter().enumerate() {
                        assert_eq!(a[(ia, ib)].to_bits(), dot(jac.column(ca).as_slice(), jac.column(cb).as_slice()).to_bits(), "m {m} n {n} ({ia}, {ib})");
                    }
                }
            }
        }
    }
}
