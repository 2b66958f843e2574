//! Prim names from object and collider names: the documented mapping rule (docs/usd.md).

/// A valid USD prim name (`[A-Za-z_][A-Za-z0-9_]*`) for `name`, unique among `taken` (which it
/// is added to): every character outside `[A-Za-z0-9_]` becomes `_`, a leading digit (or an
/// empty name) gets a `_` in front, and a name already taken gets `_2`, `_3`, ... appended
/// (the first free one).
pub fn unique_prim_name(name: &str, taken: &mut Vec<String>) -> String {
    let mut base: String = name
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '_' {
                c
            } else {
                '_'
            }
        })
        .collect();
    if base.is_empty() || base.starts_with(|c: char| c.is_ascii_digit()) {
        base.insert(0, '_');
    }
    let mut candidate = base.clone();
    let mut n = 2;
    while taken.contains(&candidate) {
        candidate = format!("{base}_{n}");
        n += 1;
    }
    taken.push(candidate.clone());
    candidate
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_are_valid_and_unique() {
        let mut taken = Vec::new();
        let names: Vec<String> = ["ball", "ball-1", "ball_1", "3d", "", "ball", "naïve"]
            .iter()
            .map(|n| unique_prim_name(n, &mut taken))
            .collect();
        assert_eq!(
            names,
            ["ball", "ball_1", "ball_1_2", "_3d", "_", "ball_2", "na_ve"]
        );
        for n in &names {
            let mut chars = n.chars();
            let first = chars.next().unwrap();
            assert!(first.is_ascii_alphabetic() || first == '_', "{n}");
            assert!(chars.all(|c| c.is_ascii_alphanumeric() || c == '_'), "{n}");
        }
    }
}
