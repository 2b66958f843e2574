//! What every tet-mesh reader shares: the file's text, its tokens with line numbers, node
//! numbering and the final compaction into a [`TetMesh`].

use crate::fem::{FemError, TetMesh};
use crate::Point3;
use std::path::{Path, PathBuf};

pub(crate) fn read_text(path: &Path) -> Result<String, FemError> {
    std::fs::read_to_string(path).map_err(|source| FemError::Io {
        path: path.to_path_buf(),
        source,
    })
}

/// Whitespace-separated tokens with their 1-based line numbers; text after `comment` on a
/// line is ignored.
pub(crate) struct Tokens<'a> {
    path: PathBuf,
    items: Vec<(usize, &'a str)>,
    pos: usize,
}

impl<'a> Tokens<'a> {
    pub(crate) fn new(text: &'a str, path: &Path, comment: Option<char>) -> Self {
        let mut items = Vec::new();
        for (i, line) in text.lines().enumerate() {
            let line = match comment.and_then(|c| line.find(c)) {
                Some(k) => &line[..k],
                None => line,
            };
            items.extend(line.split_whitespace().map(|t| (i + 1, t)));
        }
        Self {
            path: path.to_path_buf(),
            items,
            pos: 0,
        }
    }

    /// A parse error at the current token's line (or the last line at end of input).
    pub(crate) fn error(&self, reason: impl Into<String>) -> FemError {
        let line = self
            .items
            .get(
                self.pos
                    .saturating_sub(1)
                    .min(self.items.len().saturating_sub(1)),
            )
            .map_or(0, |t| t.0);
        FemError::Parse {
            path: self.path.clone(),
            line,
            reason: reason.into(),
        }
    }

    pub(crate) fn at_end(&self) -> bool {
        self.pos >= self.items.len()
    }

    /// The next token without consuming it.
    pub(crate) fn peek(&self) -> Option<&'a str> {
        self.items.get(self.pos).map(|t| t.1)
    }

    /// The next token, or an "unexpected end of file" error naming `what` was expected.
    pub(crate) fn next(&mut self, what: &str) -> Result<&'a str, FemError> {
        match self.items.get(self.pos) {
            Some(&(_, t)) => {
                self.pos += 1;
                Ok(t)
            }
            None => Err(FemError::Parse {
                path: self.path.clone(),
                line: self.items.last().map_or(0, |t| t.0),
                reason: format!("unexpected end of file: expected {what}"),
            }),
        }
    }

    pub(crate) fn usize(&mut self, what: &str) -> Result<usize, FemError> {
        let t = self.next(what)?;
        t.parse().map_err(|_| {
            self.error(format!(
                "expected {what} (a non-negative integer), found '{t}'"
            ))
        })
    }

    pub(crate) fn i64(&mut self, what: &str) -> Result<i64, FemError> {
        let t = self.next(what)?;
        t.parse()
            .map_err(|_| self.error(format!("expected {what} (an integer), found '{t}'")))
    }

    pub(crate) fn f64(&mut self, what: &str) -> Result<f64, FemError> {
        let t = self.next(what)?;
        match t.parse::<f64>() {
            Ok(v) if v.is_finite() => Ok(v),
            _ => Err(self.error(format!("expected {what} (a finite number), found '{t}'"))),
        }
    }

    pub(crate) fn point(&mut self, what: &str) -> Result<Point3, FemError> {
        Ok([self.f64(what)?, self.f64(what)?, self.f64(what)?])
    }

    pub(crate) fn skip(&mut self, n: usize, what: &str) -> Result<(), FemError> {
        for _ in 0..n {
            self.next(what)?;
        }
        Ok(())
    }
}

/// Drop nodes that no tet uses, renumber in input order, and validate.
pub(crate) fn compact(nodes: Vec<Point3>, tets: Vec<[u32; 4]>) -> Result<TetMesh, FemError> {
    let mut new_index = vec![u32::MAX; nodes.len()];
    for t in &tets {
        for &i in t {
            if let Some(slot) = new_index.get_mut(i as usize) {
                *slot = 0;
            }
        }
    }
    let mut kept = Vec::new();
    for (i, p) in nodes.into_iter().enumerate() {
        if new_index[i] == 0 {
            new_index[i] = kept.len() as u32;
            kept.push(p);
        }
    }
    let tets = tets
        .into_iter()
        .map(|t| t.map(|i| new_index[i as usize]))
        .collect();
    TetMesh::new(kept, tets)
}

/// Map 0- or 1-based (or any) node numbers to positions in the node list.
pub(crate) struct NodeIds {
    base: Option<i64>,
    map: std::collections::HashMap<i64, u32>,
}

impl NodeIds {
    /// `ids[k]` is the number the file gives the k-th node.
    pub(crate) fn new(ids: &[i64]) -> Self {
        let consecutive = ids.windows(2).all(|w| w[1] == w[0] + 1);
        if consecutive {
            Self {
                base: Some(ids.first().copied().unwrap_or(0)),
                map: Default::default(),
            }
        } else {
            Self {
                base: None,
                map: ids
                    .iter()
                    .enumerate()
                    .map(|(k, &i)| (i, k as u32))
                    .collect(),
            }
        }
    }

    pub(crate) fn get(&self, id: i64, count: usize) -> Option<u32> {
        match self.base {
            Some(b) => {
                let k = id - b;
                (k >= 0 && (k as usize) < count).then_some(k as u32)
            }
            None => self.map.get(&id).copied(),
        }
    }
}
