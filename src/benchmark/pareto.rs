//! Pareto fronts of (cost, error) pairs: the settings that no other setting beats on both.

/// Which of `points` = (cost, error), both to be minimized, lie on the Pareto front.
///
/// A point is on the front when no other point dominates it, that is, no other point is at
/// most as large in both coordinates and strictly smaller in at least one.
/// - **Ties and duplicates**: equal points do not dominate each other, so every copy of a
///   front point is on the front; of two points with the same cost, only the one with the
///   smaller error is (and likewise for equal errors).
/// - **Non-finite values** (NaN, infinities): such a point is never on the front and
///   dominates nothing (a failed or diverged run must not hide the others).
///
/// O(n^2) comparisons: sweeps have tens to hundreds of runs.
pub fn pareto_front(points: &[[f64; 2]]) -> Vec<bool> {
    let finite = |p: &[f64; 2]| p[0].is_finite() && p[1].is_finite();
    let dominates =
        |q: &[f64; 2], p: &[f64; 2]| q[0] <= p[0] && q[1] <= p[1] && (q[0] < p[0] || q[1] < p[1]);
    points
        .iter()
        .map(|p| finite(p) && !points.iter().any(|q| finite(q) && dominates(q, p)))
        .collect()
}

/// The indices of the front points (`on_front` from [`pareto_front`]) in the order of
/// increasing cost (then error): the front as a polyline from cheapest to most accurate.
pub fn front_by_cost(points: &[[f64; 2]], on_front: &[bool]) -> Vec<usize> {
    let mut idx: Vec<usize> = (0..points.len().min(on_front.len()))
        .filter(|&i| on_front[i])
        .collect();
    idx.sort_by(|&a, &b| {
        points[a][0]
            .total_cmp(&points[b][0])
            .then(points[a][1].total_cmp(&points[b][1]))
    });
    idx
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn known_front_with_ties_and_duplicates() {
        let pts = [
            [1.0, 10.0], // 0 front: cheapest
            [2.0, 5.0],  // 1 front
            [2.0, 6.0],  // 2 same cost as 1, worse error: dominated
            [3.0, 5.0],  // 3 same error as 1, dearer: dominated
            [4.0, 1.0],  // 4 front
            [4.0, 1.0],  // 5 duplicate of 4: also front
            [5.0, 0.5],  // 6 front: most accurate
            [6.0, 0.5],  // 7 dominated by 6
            [3.0, 7.0],  // 8 dominated by 1
            [0.5, 20.0], // 9 front: cheaper than all
        ];
        let f = pareto_front(&pts);
        let expect = [
            true, true, false, false, true, true, true, false, false, true,
        ];
        assert_eq!(f, expect);
        assert_eq!(front_by_cost(&pts, &f), vec![9, 0, 1, 4, 5, 6]);
    }

    #[test]
    fn non_finite_points_are_neither_on_nor_dominating() {
        let pts = [
            [1.0, 1.0],
            [f64::NAN, 0.0],
            [0.5, f64::INFINITY],
            [2.0, 0.5],
        ];
        assert_eq!(pareto_front(&pts), vec![true, false, false, true]);
        let nan_only = [[f64::NAN, f64::NAN]];
        assert_eq!(pareto_front(&nan_only), vec![false]);
    }

    #[test]
    fn degenerate_sets() {
        assert!(pareto_front(&[]).is_empty());
        assert_eq!(pareto_front(&[[3.0, 3.0]]), vec![true]);
        // All equal: all on the front.
        assert_eq!(pareto_front(&[[1.0, 2.0]; 3]), vec![true; 3]);
        // A chain where each point dominates the next: only the first.
        let chain = [[1.0, 1.0], [2.0, 2.0], [3.0, 3.0]];
        assert_eq!(pareto_front(&chain), vec![true, false, false]);
    }

    #[test]
    fn front_matches_brute_force_definition_on_a_grid() {
        // Every point of a 5 x 5 grid of costs/errors plus a staircase below it.
        let mut pts = Vec::new();
        for i in 0..5 {
            for j in 0..5 {
                pts.push([2.0 + i as f64, 2.0 + j as f64]);
            }
        }
        let stairs = [[1.0, 6.0], [1.5, 3.0], [3.0, 1.5], [6.0, 1.0]];
        pts.extend(stairs);
        let f = pareto_front(&pts);
        // The grid's corner (2, 2) is not dominated by any stair point.
        let on: Vec<[f64; 2]> = (0..pts.len()).filter(|&i| f[i]).map(|i| pts[i]).collect();
        assert_eq!(
            on,
            vec![[2.0, 2.0], [1.0, 6.0], [1.5, 3.0], [3.0, 1.5], [6.0, 1.0]]
        );
    }
}
