use super::*;
use crate::random::SplitMix64;
use std::collections::BTreeMap;

/// A random symmetric K x K matrix as (row, col) -> value over both triangles: every row has
/// a diagonal, local neighbours (a band, like a spatially ordered pencil) and a few entries
/// far away (cross-segment runs in both passes).
fn random_symmetric(k: usize, seed: u64) -> BTreeMap<(usize, usize), f64> {
    let mut rng = SplitMix64::new(seed);
    let mut entries = BTreeMap::new();
    for i in 0..k {
        entries.insert((i, i), rng.uniform(1.0, 2.0));
        for _ in 0..6 {
            let far = rng.uniform(0.0, 1.0) < 0.2;
            let j = if far {
                (rng.uniform(0.0, k as f64) as usize).min(k - 1)
            } else {
                (i + (rng.uniform(1.0, 40.0) as usize)).min(k - 1)
            };
            if j != i {
                let v = rng.uniform(-1.0, 1.0);
                entries.insert((i, j), v);
                entries.insert((j, i), v);
            }
        }
    }
    entries
}

/// The upper triangle's pattern and values of `entries`.
fn upper(k: usize, entries: &BTreeMap<(usize, usize), f64>) -> (UpperPattern, Vec<f64>) {
    let mut cols: Vec<Vec<(u32, f64)>> = vec![Vec::new(); k];
    for (&(i, j), &v) in entries {
        if i <= j {
            cols[j].push((i as u32, v));
        }
    }
    let mut ptr = vec![0u32];
    let (mut idx, mut val) = (Vec::new(), Vec::new());
    for col in &mut cols {
        col.sort_by_key(|e| e.0);
        idx.extend(col.iter().map(|e| e.0));
        val.extend(col.iter().map(|e| e.1));
        ptr.push(idx.len() as u32);
    }
    (UpperPattern::new(k, ptr, idx).unwrap(), val)
}

/// Both triangles of `entries` as a SparseMatrix.
fn full(k: usize, entries: &BTreeMap<(usize, usize), f64>) -> SparseMatrix {
    let mut cols: Vec<Vec<(u32, f64)>> = vec![Vec::new(); k];
    for (&(i, j), &v) in entries {
        cols[j].push((i as u32, v));
    }
    let mut ptr = vec![0u32];
    let (mut idx, mut val) = (Vec::new(), Vec::new());
    for col in &mut cols {
        col.sort_by_key(|e| e.0);
        idx.extend(col.iter().map(|e| e.0));
        val.extend(col.iter().map(|e| e.1));
        ptr.push(idx.len() as u32);
    }
    sparse::from_compressed(k, ptr, idx, val)
}

fn block(k: usize, ld: usize, seed: u64) -> Vec<f64> {
    let mut rng = SplitMix64::new(seed);
    (0..k * ld).map(|_| rng.uniform(-1.0, 1.0)).collect()
}

#[test]
fn products_match_the_full_storage() {
    // 1,500 rows: 6 segments of 256, so both passes and the narrow last group (ncols 11 =
    // 8 + 3) run; ncols 1 runs only the narrow path.
    let k = 1500;
    let entries = random_symmetric(k, 7);
    let (pattern, val) = upper(k, &entries);
    assert!(pattern.cross.iter().filter(|c| !c.is_empty()).count() >= 3);
    let a = UpperRef::new(&pattern, &val);
    let f = full(k, &entries);
    for (ncols, ld) in [(11, 13), (1, 1), (16, 16)] {
        let x = block(k, ld, 3);
        let (mut y, mut z) = (vec![0.0; k * ld], vec![0.0; k * ld]);
        a.mul_row_major(&x, ld, &mut y, ld, ncols);
        sparse::sym_mul_row_major(f.as_ref(), &x, ld, &mut z, ld, ncols);
        for i in 0..k {
            for c in 0..ncols {
                // The two sum the same terms in another order: each row has ~13 terms of
                // magnitude <= 2, so the difference is a few ulps of ~10.
                let (u, v) = (y[i * ld + c], z[i * ld + c]);
                assert!((u - v).abs() <= 1e-13, "row {i} col {c}: {u} vs {v}");
            }
        }
    }
}

#[test]
fn pair_equals_two_products_and_any_thread_count() {
    let k = 900;
    let entries = random_symmetric(k, 11);
    let (pattern, va) = upper(k, &entries);
    let vb: Vec<f64> = va.iter().map(|v| 0.5 * v + 0.25).collect();
    let (a, b) = (UpperRef::new(&pattern, &va), UpperRef::new(&pattern, &vb));
    let (ncols, ld) = (20, 20);
    let x = block(k, ld, 5);
    let run = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| {
            let (mut ya, mut yb) = (vec![0.0; k * ld], vec![0.0; k * ld]);
            mul_pair_row_major(a, b, &x, ld, &mut ya, &mut yb, ld, ncols);
            (ya, yb)
        })
    };
    let (ya, yb) = run(1);
    let mut single = vec![0.0; k * ld];
    a.mul_row_major(&x, ld, &mut single, ld, ncols);
    assert_eq!(
        ya, single,
        "the pair's first product is the single product, bit for bit"
    );
    b.mul_row_major(&x, ld, &mut single, ld, ncols);
    assert_eq!(yb, single);
    assert_eq!(run(3), (ya, yb), "bits independent of the thread count");
}

#[test]
fn full_copy_norms_and_sums_match_both_triangles() {
    let k = 700;
    let entries = random_symmetric(k, 13);
    let (pattern, val) = upper(k, &entries);
    let a = UpperRef::new(&pattern, &val);
    let f = full(k, &entries);
    let back = a.to_full();
    assert_eq!(back.symbolic().col_ptr(), f.symbolic().col_ptr());
    assert_eq!(back.symbolic().row_idx(), f.symbolic().row_idx());
    assert_eq!(back.val(), f.val());
    assert_eq!(a.diagonal(), sparse::diagonal(f.as_ref()));
    // Row sums of |a_ij| in another order than the column sums: a few ulps.
    let (n1, n2) = (a.norm_1(), sparse::norm_1(f.as_ref()));
    assert!((n1 - n2).abs() <= 1e-14 * n2, "{n1} vs {n2}");
    let plain: f64 = f.val().iter().sum();
    assert!((a.sum_all() - plain).abs() <= 1e-12 * f.val().iter().map(|v| v.abs()).sum::<f64>());
    let pencil = UpperPencil::new(
        pattern.clone(),
        val.clone(),
        val.iter().map(|v| -v).collect(),
    );
    let (sym, first, second) = pencil.to_full();
    assert_eq!(sym.row_idx(), f.symbolic().row_idx());
    assert_eq!(first, f.val());
    assert!(first.iter().zip(&second).all(|(p, q)| *p == -q));
}

#[test]
fn non_finite_entries_are_found_where_they_are() {
    let k = 300;
    let entries = random_symmetric(k, 17);
    let (pattern, mut val) = upper(k, &entries);
    assert_eq!(UpperRef::new(&pattern, &val).first_non_finite(), None);
    let p = val.len() / 2;
    val[p] = f64::NAN;
    let col = pattern.col_ptr().partition_point(|&s| s as usize <= p) - 1;
    assert_eq!(
        UpperRef::new(&pattern, &val).first_non_finite(),
        Some((pattern.row_idx()[p] as usize, col))
    );
}

#[test]
fn patterns_that_are_not_upper_triangles_are_refused() {
    // Column 1 holds row 2 (below the diagonal).
    let bad = UpperPattern::new(3, vec![0, 1, 3, 4], vec![0, 1, 2, 2]);
    assert_eq!(bad.unwrap_err(), PatternError::NotUpper(1));
    // Column 2 without its diagonal.
    let bad = UpperPattern::new(3, vec![0, 1, 2, 3], vec![0, 1, 1]);
    assert_eq!(bad.unwrap_err(), PatternError::NotUpper(2));
    let bad = UpperPattern::new(3, vec![0, 1, 2], vec![0, 1]);
    assert!(matches!(bad.unwrap_err(), PatternError::Layout(_)));
}
