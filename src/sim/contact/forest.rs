//! Union-find over object indices: which objects share an island.

use std::collections::BTreeMap;

/// A union-find forest over objects 0..n (path compression; the smaller index is the root,
/// so groups come out in a fixed order).
#[derive(Debug, Clone)]
pub struct Forest {
    parent: Vec<usize>,
}

impl Forest {
    /// n objects, each alone.
    pub fn new(n: usize) -> Forest {
        Forest {
            parent: (0..n).collect(),
        }
    }

    /// The root of `i`'s group.
    pub fn find(&mut self, i: usize) -> usize {
        let mut r = i;
        while self.parent[r] != r {
            r = self.parent[r];
        }
        let mut i = i;
        while self.parent[i] != r {
            let next = self.parent[i];
            self.parent[i] = r;
            i = next;
        }
        r
    }

    /// Join the groups of `a` and `b`.
    pub fn union(&mut self, a: usize, b: usize) {
        let (ra, rb) = (self.find(a), self.find(b));
        if ra != rb {
            self.parent[ra.max(rb)] = ra.min(rb);
        }
    }

    /// Whether `a` and `b` are in one group.
    pub fn joined(&mut self, a: usize, b: usize) -> bool {
        self.find(a) == self.find(b)
    }

    /// The groups, each sorted, ordered by their first object.
    pub fn groups(&mut self) -> Vec<Vec<usize>> {
        let mut by_root: BTreeMap<usize, Vec<usize>> = BTreeMap::new();
        for i in 0..self.parent.len() {
            let r = self.find(i);
            by_root.entry(r).or_default().push(i);
        }
        by_root.into_values().collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unions_make_sorted_groups_in_order() {
        let mut f = Forest::new(6);
        f.union(4, 1);
        f.union(5, 4);
        f.union(2, 3);
        assert!(f.joined(1, 5) && !f.joined(0, 1));
        assert_eq!(f.groups(), vec![vec![0], vec![1, 4, 5], vec![2, 3]]);
    }
}
