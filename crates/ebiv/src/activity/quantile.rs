//! Quantiles of counted values: linear interpolation between the two nearest order
//! statistics (Hyndman & Fan, Am. Stat. 50:361, 1996, definition 7; NumPy's default), so
//! figures printed by `ebiv` match `numpy.percentile` on the same values.

/// The `q`-quantile (0 ≤ q ≤ 1) of a multiset given as `(value, count)` pairs in ascending
/// order of value; `None` when it is empty. With `n` values sorted as `v_0 ≤ … ≤ v_{n−1}`, the
/// result is `v_⌊h⌋ + (h − ⌊h⌋)(v_{⌊h⌋+1} − v_⌊h⌋)` at `h = (n − 1) q`.
pub fn quantile_of_counts(sorted: &[(f64, u64)], q: f64) -> Option<f64> {
    let n: u64 = sorted.iter().map(|&(_, c)| c).sum();
    if n == 0 {
        return None;
    }
    let h = (n - 1) as f64 * q.clamp(0.0, 1.0);
    let lower = h.floor() as u64;
    let frac = h - lower as f64;
    let a = value_at_rank(sorted, lower)?;
    if frac == 0.0 || lower + 1 >= n {
        return Some(a);
    }
    let b = value_at_rank(sorted, lower + 1)?;
    Some(a + frac * (b - a))
}

/// The value of rank `k` (from 0) of the multiset.
fn value_at_rank(sorted: &[(f64, u64)], k: u64) -> Option<f64> {
    let mut seen = 0u64;
    for &(v, c) in sorted {
        seen += c;
        if k < seen {
            return Some(v);
        }
    }
    None
}

/// Several quantiles of a multiset given as `(value, count)` pairs in any order.
pub fn quantiles(mut pairs: Vec<(f64, u64)>, qs: &[f64]) -> Option<Vec<f64>> {
    pairs.retain(|&(_, c)| c > 0);
    pairs.sort_by(|a, b| a.0.total_cmp(&b.0));
    qs.iter().map(|&q| quantile_of_counts(&pairs, q)).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn matches_numpy_linear_definition() {
        // numpy.percentile([1, 2, 3, 4], [0, 25, 50, 90, 100]) = 1, 1.75, 2.5, 3.7, 4
        let v: Vec<(f64, u64)> = (1..=4).map(|i| (i as f64, 1)).collect();
        let q = quantiles(v, &[0.0, 0.25, 0.5, 0.9, 1.0]).unwrap();
        let want = [1.0, 1.75, 2.5, 3.7, 4.0];
        for (a, b) in q.iter().zip(want) {
            assert!((a - b).abs() < 1e-12, "{q:?}");
        }
    }

    #[test]
    fn counted_values_equal_repeated_values() {
        // [1, 1, 1, 5]: median 1, 90th percentile 1 + 0.7·4 = 3.8.
        let q = quantiles(vec![(5.0, 1), (1.0, 3), (9.0, 0)], &[0.5, 0.9]).unwrap();
        assert_eq!(q[0], 1.0);
        assert!((q[1] - 3.8).abs() < 1e-12);
        assert!(quantiles(Vec::new(), &[0.5]).is_none());
        assert_eq!(
            quantiles(vec![(7.0, 1)], &[0.0, 0.5, 1.0]).unwrap(),
            [7.0; 3]
        );
    }
}
