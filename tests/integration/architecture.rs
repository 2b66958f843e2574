//! The library's top-level modules import along the data flow only: the module graph has no
//! circles (the data flow drawn in src/lib.rs; leaves import no stage).
//!
//! The test reads every `.rs` file under `src/` except `src/bin/` (the CLI is a caller, not
//! part of the library), maps each file to its top-level module (`src/foo.rs` and
//! `src/foo/**` are module `foo`; `src/lib.rs` is the crate root and not a node: it only
//! declares the modules and re-exports), and collects every path that leaves the module:
//! `crate::foo...`, `$crate::foo...`, `use crate::{foo, bar::X}` groups and `super::...`
//! chains that climb to the root. Comments, doc comments, string and character literals are
//! skipped (doc examples are callers, like `tests/`).
//!
//! `#[cfg(test)]` code counts like any other code: a unit test that needs a later stage
//! belongs in `tests/`, and counting everything keeps the rule simple and sound.
//!
//! Root items: `crate::Error` and `crate::Result` are re-exports of module `error`;
//! `crate::Point3` is defined at the root (no edge). Any other root item fails the test until
//! it is added to [`root_item_module`].
//!
//! A second test checks that the leaves (errors, 3 x 3 algebra, the energy density, materials,
//! reports, progress, sparse kernels) import only each other, with one documented exception.
//!
//! `cargo test --test integration -- architecture:: --nocapture` prints the graph as a list of edges.

use std::collections::{BTreeMap, BTreeSet};
use std::fs;
use std::path::{Path, PathBuf};

/// Module graph: for each module, the modules it references, with one place (file:line) per
/// edge as evidence.
type Graph = BTreeMap<String, BTreeMap<String, String>>;

/// The module graph of the library's sources (see the file's doc comment for what counts).
fn module_graph() -> Graph {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let modules = top_level_modules(&src);
    let mut files = Vec::new();
    rust_files(&src, &mut files);
    files.sort();

    let mut graph: Graph = modules
        .iter()
        .map(|m| (m.clone(), BTreeMap::new()))
        .collect();
    let mut problems = Vec::new();
    for file in &files {
        let rel = file.strip_prefix(&src).unwrap();
        if rel.starts_with("bin") || rel == Path::new("lib.rs") {
            continue;
        }
        let module_path = module_path_of(rel);
        let text = fs::read_to_string(file).unwrap();
        for r in references(&text, &module_path) {
            let place = format!("src/{}:{}", rel.display(), r.line);
            let target = match r.target {
                Target::Module(m) => m,
                Target::RootItem(item) => match root_item_module(&item) {
                    Some(Some(m)) => m.to_string(),
                    Some(None) => continue,
                    None if modules.contains(&item) => item,
                    None => {
                        problems.push(format!(
                            "{place}: `{item}` is neither a top-level module nor a known root \
                             item (add it to root_item_module)"
                        ));
                        continue;
                    }
                },
                Target::Unresolvable(what) => {
                    problems.push(format!("{place}: cannot resolve `{what}`"));
                    continue;
                }
            };
            if target != module_path[0] {
                graph
                    .get_mut(&module_path[0])
                    .unwrap_or_else(|| panic!("{place}: module {} not in lib.rs", module_path[0]))
                    .entry(target)
                    .or_insert(place);
            }
        }
    }
    assert!(problems.is_empty(), "{}", problems.join("\n"));
    graph
}

#[test]
fn module_graph_has_no_cycles() {
    let graph = module_graph();
    println!("module graph (importer -> imported, one place that makes the edge):");
    for (from, tos) in &graph {
        if tos.is_empty() {
            println!("{from} (imports no module)");
        }
        for (to, place) in tos {
            println!("{from} -> {to}    ({place})");
        }
    }

    let plain: BTreeMap<String, BTreeSet<String>> = graph
        .iter()
        .map(|(k, v)| (k.clone(), v.keys().cloned().collect()))
        .collect();
    let cycles = find_cycles(&plain);
    if !cycles.is_empty() {
        let mut msg = format!(
            "the module graph has {} circle(s); move items along the data flow:\n",
            cycles.len()
        );
        for cycle in &cycles {
            msg += &format!("  {}\n", cycle.join(" -> "));
            for pair in cycle.windows(2) {
                msg += &format!(
                    "      {} -> {}: {}\n",
                    pair[0], pair[1], graph[&pair[0]][&pair[1]]
                );
            }
        }
        panic!("{msg}");
    }
}

#[test]
fn leaves_import_no_stage() {
    let graph = module_graph();
    let leaf_problems: Vec<String> = LEAVES
        .iter()
        .flat_map(|leaf| {
            graph
                .get(*leaf)
                .unwrap_or_else(|| panic!("leaf `{leaf}` is not a module"))
                .iter()
                .filter(|(to, _)| !LEAVES.contains(&to.as_str()))
                .filter(|(to, _)| !LEAF_EXCEPTIONS.contains(&(*leaf, to.as_str())))
                .map(move |(to, place)| format!("  {leaf} -> {to}: {place}"))
        })
        .collect();
    assert!(
        leaf_problems.is_empty(),
        "leaves import no stage, but:\n{}",
        leaf_problems.join("\n")
    );
}

/// Modules every stage may use (reports, 3 x 3 algebra, materials and the energy density, errors,
/// progress, the random generator, sparse kernels, the derivative checker, the option names):
/// they import no stage, only each other.
const LEAVES: [&str; 13] = [
    "derivatives",
    "elasticity",
    "error",
    "linalg3",
    "material",
    "names",
    "options",
    "progress",
    "random",
    "report",
    "simd",
    "sparse",
    "triangle",
];

/// Edges out of a leaf that are known and allowed. `error -> eigen`: `crate::Error` wraps
/// `EigenError`, which carries the eigensolver's partial result (`EigenSolution`) and so lives in
/// `eigen`; `eigen` must then never use `crate::Error` (the circle check catches it).
const LEAF_EXCEPTIONS: [(&str, &str); 1] = [("error", "eigen")];

/// The module a root item (`crate::X`) belongs to: `Some(Some(m))` for a re-export of module
/// `m`, `Some(None)` for an item defined at the root itself, `None` when unknown.
fn root_item_module(item: &str) -> Option<Option<&'static str>> {
    match item {
        "Error" | "Result" => Some(Some("error")),
        "Point3" => Some(None),
        _ => None,
    }
}

/// Top-level modules declared in `src/lib.rs` (`mod foo;`, any visibility).
fn top_level_modules(src: &Path) -> BTreeSet<String> {
    let text = fs::read_to_string(src.join("lib.rs")).unwrap();
    let toks = tokenize(&text);
    let mut modules = BTreeSet::new();
    for w in toks.windows(3) {
        if w[0].text == "mod" && w[2].text == ";" {
            modules.insert(w[1].text.clone());
        }
    }
    assert!(!modules.is_empty(), "no `mod` declarations in src/lib.rs");
    modules
}

fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    for entry in fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        if path.is_dir() {
            rust_files(&path, out);
        } else if path.extension().is_some_and(|e| e == "rs") {
            out.push(path);
        }
    }
}

/// Module path of a file relative to `src/`: `foo.rs` and `foo/mod.rs` are `[foo]`,
/// `foo/bar.rs` is `[foo, bar]`.
fn module_path_of(rel: &Path) -> Vec<String> {
    let mut parts: Vec<String> = rel
        .iter()
        .map(|p| p.to_string_lossy().into_owned())
        .collect();
    let last = parts.pop().unwrap();
    let stem = last.strip_suffix(".rs").unwrap();
    if stem != "mod" {
        parts.push(stem.to_string());
    }
    parts
}

#[derive(Debug, Clone, PartialEq)]
struct Token {
    text: String,
    line: usize,
}

/// Split Rust source into identifier and punctuation tokens (`::` is one token), dropping
/// whitespace, comments (line, block, nested, doc) and string, byte-string, raw-string and
/// character literals. Lifetimes are dropped too. Numbers come out as identifier-like tokens,
/// which is harmless here.
fn tokenize(src: &str) -> Vec<Token> {
    let c: Vec<char> = src.chars().collect();
    let mut toks = Vec::new();
    let mut i = 0;
    let mut line = 1;
    let n = c.len();
    let at = |i: usize| c.get(i).copied().unwrap_or('\0');
    while i < n {
        let ch = c[i];
        if ch == '\n' {
            line += 1;
            i += 1;
        } else if ch.is_whitespace() {
            i += 1;
        } else if ch == '/' && at(i + 1) == '/' {
            while i < n && c[i] != '\n' {
                i += 1;
            }
        } else if ch == '/' && at(i + 1) == '*' {
            let mut depth = 0;
            while i < n {
                if c[i] == '/' && at(i + 1) == '*' {
                    depth += 1;
                    i += 2;
                } else if c[i] == '*' && at(i + 1) == '/' {
                    depth -= 1;
                    i += 2;
                    if depth == 0 {
                        break;
                    }
                } else {
                    if c[i] == '\n' {
                        line += 1;
                    }
                    i += 1;
                }
            }
        } else if let Some(len) = raw_string_start(&c, i) {
            // r"..", r#".."#, br#".."#: ends at a quote followed by as many hashes.
            let hashes = len - if ch == 'b' { 3 } else { 2 };
            i += len;
            while i < n {
                if c[i] == '"' && (0..hashes).all(|k| at(i + 1 + k) == '#') {
                    i += 1 + hashes;
                    break;
                }
                if c[i] == '\n' {
                    line += 1;
                }
                i += 1;
            }
        } else if ch == '"' || (ch == 'b' && at(i + 1) == '"') {
            i += if ch == 'b' { 2 } else { 1 };
            while i < n && c[i] != '"' {
                if c[i] == '\\' {
                    i += 1;
                }
                if at(i) == '\n' {
                    line += 1;
                }
                i += 1;
            }
            i += 1;
        } else if ch == '\'' || (ch == 'b' && at(i + 1) == '\'') {
            let q = if ch == 'b' { i + 1 } else { i };
            if at(q + 1) == '\\' {
                // Escaped character literal: skip to the closing quote.
                i = q + 2;
                while i < n && c[i] != '\'' {
                    i += 1;
                }
                i += 1;
            } else if at(q + 2) == '\'' {
                i = q + 3;
            } else {
                // A lifetime or label: drop the quote, its name follows as an identifier.
                i = q + 1;
            }
        } else if ch.is_alphanumeric() || ch == '_' || ch == '$' {
            let start = i;
            i += 1;
            while i < n && (c[i].is_alphanumeric() || c[i] == '_') {
                i += 1;
            }
            toks.push(Token {
                text: c[start..i].iter().collect(),
                line,
            });
        } else if ch == ':' && at(i + 1) == ':' {
            toks.push(Token {
                text: "::".into(),
                line,
            });
            i += 2;
        } else {
            toks.push(Token {
                text: ch.to_string(),
                line,
            });
            i += 1;
        }
    }
    toks
}

/// Length of the opening of a raw string (`r"`, `r#"`, `br##"`, ...) starting at `i`, if any.
fn raw_string_start(c: &[char], i: usize) -> Option<usize> {
    if i > 0 && (c[i - 1].is_alphanumeric() || c[i - 1] == '_') {
        return None;
    }
    let mut j = i;
    if c.get(j) == Some(&'b') {
        j += 1;
    }
    if c.get(j) != Some(&'r') {
        return None;
    }
    j += 1;
    while c.get(j) == Some(&'#') {
        j += 1;
    }
    (c.get(j) == Some(&'"')).then(|| j + 1 - i)
}

#[derive(Debug, PartialEq)]
enum Target {
    /// A path into this top-level module (possibly the file's own).
    Module(String),
    /// `crate::X` where `X` may be a module or an item defined or re-exported at the root.
    RootItem(String),
    /// A path this test does not understand (e.g. `use crate::*`).
    Unresolvable(String),
}

#[derive(Debug)]
struct Reference {
    target: Target,
    line: usize,
}

/// Every reference that leaves the file's own module path, from source `text` of the file
/// with module path `module_path` (non-empty).
fn references(text: &str, module_path: &[String]) -> Vec<Reference> {
    let toks = tokenize(text);
    let mut out = Vec::new();
    // Inline modules (`mod tests { ... }`): name and the brace depth outside them.
    let mut inline: Vec<(String, usize)> = Vec::new();
    let mut depth = 0usize;
    let is = |i: usize, s: &str| toks.get(i).is_some_and(|t| t.text == s);
    let mut i = 0;
    while i < toks.len() {
        let t = &toks[i].text;
        if t == "mod" && is(i + 2, "{") {
            inline.push((toks[i + 1].text.clone(), depth));
        } else if t == "{" {
            depth += 1;
        } else if t == "}" {
            depth -= 1;
            if inline.last().is_some_and(|(_, d)| *d == depth) {
                inline.pop();
            }
        } else if (t == "crate" || t == "$crate") && is(i + 1, "::") && !(i > 0 && is(i - 1, "::"))
        {
            root_tail(&toks, i + 2, &mut out);
        } else if t == "super" && is(i + 1, "::") && !(i > 0 && is(i - 1, "::")) {
            let mut here: Vec<String> = module_path.to_vec();
            here.extend(inline.iter().map(|(m, _)| m.clone()));
            let mut j = i;
            let mut ok = true;
            while is(j, "super") && is(j + 1, "::") {
                if here.pop().is_none() {
                    ok = false;
                }
                j += 2;
            }
            if !ok {
                out.push(Reference {
                    target: Target::Unresolvable("super:: beyond the crate root".into()),
                    line: toks[i].line,
                });
            } else if let Some(top) = here.first() {
                out.push(Reference {
                    target: Target::Module(top.clone()),
                    line: toks[i].line,
                });
            } else {
                root_tail(&toks, j, &mut out);
            }
            i = j;
            continue;
        }
        i += 1;
    }
    out
}

/// Record the root items named by the path tail starting at token `i` (just after
/// `crate::`): one identifier, or a `{...}` group whose items each start with one.
fn root_tail(toks: &[Token], i: usize, out: &mut Vec<Reference>) {
    let Some(first) = toks.get(i) else { return };
    if first.text != "{" {
        let target = if first.text == "*" {
            Target::Unresolvable("a glob import of the crate root".into())
        } else {
            Target::RootItem(first.text.clone())
        };
        out.push(Reference {
            target,
            line: first.line,
        });
        return;
    }
    let mut depth = 0;
    let mut item_start = true;
    for t in &toks[i..] {
        match t.text.as_str() {
            "{" => depth += 1,
            "}" => {
                depth -= 1;
                if depth == 0 {
                    return;
                }
            }
            "," if depth == 1 => item_start = true,
            s if depth == 1 && item_start => {
                item_start = false;
                let target = match s {
                    "self" => continue,
                    "*" => Target::Unresolvable("a glob import of the crate root".into()),
                    _ => Target::RootItem(s.to_string()),
                };
                out.push(Reference {
                    target,
                    line: t.line,
                });
            }
            _ => {}
        }
    }
}

/// Elementary cycles of `graph`, each written from its smallest module and closed
/// (`[a, b, a]`); at most 100 (enough to read, and the search stays fast).
fn find_cycles(graph: &BTreeMap<String, BTreeSet<String>>) -> Vec<Vec<String>> {
    fn walk(
        graph: &BTreeMap<String, BTreeSet<String>>,
        start: &str,
        path: &mut Vec<String>,
        out: &mut Vec<Vec<String>>,
    ) {
        let last = path.last().unwrap().clone();
        for next in graph.get(&last).into_iter().flatten() {
            if out.len() >= 100 {
                return;
            }
            if next == start {
                let mut cycle = path.clone();
                cycle.push(start.to_string());
                out.push(cycle);
            } else if next.as_str() > start && !path.contains(next) {
                path.push(next.clone());
                walk(graph, start, path, out);
                path.pop();
            }
        }
    }
    let mut out = Vec::new();
    for start in graph.keys() {
        walk(graph, start, &mut vec![start.clone()], &mut out);
    }
    out
}

fn graph_of(edges: &[(&str, &str)]) -> BTreeMap<String, BTreeSet<String>> {
    let mut g: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
    for (a, b) in edges {
        g.entry(a.to_string()).or_default().insert(b.to_string());
        g.entry(b.to_string()).or_default();
    }
    g
}

#[test]
fn cycle_finder_finds_hand_made_cycles() {
    let acyclic = graph_of(&[
        ("sim", "precompute"),
        ("precompute", "eigen"),
        ("sim", "eigen"),
    ]);
    assert!(find_cycles(&acyclic).is_empty());

    let two = graph_of(&[
        ("elasticity", "linalg3"),
        ("linalg3", "elasticity"),
        ("sim", "elasticity"),
    ]);
    assert_eq!(
        find_cycles(&two),
        vec![vec!["elasticity", "linalg3", "elasticity"]]
    );

    let three = graph_of(&[("a", "b"), ("b", "c"), ("c", "a"), ("c", "b")]);
    assert_eq!(
        find_cycles(&three),
        vec![vec!["a", "b", "c", "a"], vec!["b", "c", "b"]]
    );
}

#[test]
fn references_skip_comments_and_literals_and_resolve_super() {
    let src = r##"
        //! Uses crate::io in a doc comment only.
        use crate::{linalg3::Mat3, Error, self};
        use super::sibling; // crate::sim in a comment
        /* crate::scene /* nested crate::fem */ */
        const S: &str = "crate::report";
        const R: &str = r#"crate::eigen "# ;
        const C: char = '"';
        fn f<'a>(x: &'a str) -> crate::Point3 { todo!() }
        mod tests {
            use super::*;
            use super::super::other::Thing;
        }
    "##;
    let here = vec!["geometry".to_string()];
    let got: Vec<Target> = references(src, &here)
        .into_iter()
        .map(|r| r.target)
        .collect();
    assert_eq!(
        got,
        vec![
            Target::RootItem("linalg3".into()),
            Target::RootItem("Error".into()),
            Target::RootItem("sibling".into()),
            Target::RootItem("Point3".into()),
            Target::Module("geometry".into()),
            Target::RootItem("other".into()),
        ]
    );
    assert_eq!(module_path_of(Path::new("geometry/mod.rs")), ["geometry"]);
    assert_eq!(
        module_path_of(Path::new("eigen/lobpcg/tests.rs")),
        ["eigen", "lobpcg", "tests"]
    );
}

// ---------------------------------------------------------------------------------------------
// File-level edges inside every folder.
//
// Each folder of `src/` (a module with submodule files: `foo/mod.rs` or `foo.rs` next to
// `foo/`) is a graph of its own: its nodes are the parent file (`mod.rs` or `foo.rs`), its
// files (`bar.rs`) and its subfolders (`baz/`, standing for every file under it). The rule:
//
// - A path names a module: `crate::a::b`, `$crate::a::b`, `self::b`, `super::b` (chains
//   climb, inline `mod tests { .. }` counted), and inside a parent file a bare `b::..` where
//   `b` is one of its submodules. `use` trees are expanded (`use super::{a::X, b}` names
//   `a` and `b`). A path from a file under the folder that goes to a sibling `x` (or into
//   it) is an edge `file -> x`; to the folder itself or to an item defined in the parent
//   file (`super::Item`, `crate::folder::Item`, `use super::*`) it is an edge
//   `file -> parent`. A name the parent file imports from a submodule (`pub use x::Y`,
//   private `use x::Y`) resolves to that submodule: `super::Y` is an edge `file -> x`.
// - The parent file's own `use` items (declaring, re-exporting) make no edge: the parent
//   uses a submodule only where its code (outside `use` items) names the submodule
//   (`x::f()`) or a name imported from it (`Y` not after `.` or `::`). `mod x;` is no edge.
// - Comments, doc comments and literals are skipped; `#[cfg(test)]` code counts; macros
//   used by bare name are not seen.
//
// Every folder's graph must be acyclic.

/// Folder graphs: folder (`scene`, `sim/contact`) -> node -> node -> one place.
type FolderGraphs = BTreeMap<String, Graph>;

/// A path found in a file: absolute module path segments (crate root first, without
/// `crate`), whether it came from a `use` item, and its line.
#[derive(Debug, Clone, PartialEq)]
struct PathRef {
    segments: Vec<String>,
    in_use: bool,
    line: usize,
}

/// What one file says: every path it names, and (outside inline modules) the names its
/// `use` items bring in, with their absolute paths (for re-export resolution).
#[derive(Debug, Default)]
struct FileRefs {
    paths: Vec<PathRef>,
    imports: BTreeMap<String, Vec<String>>,
    /// Identifiers outside `use` items, not after `.` or `::`, with their lines.
    idents: Vec<(String, usize)>,
}

/// Resolve the start of a path at token `i` (no `::` before it) to an absolute prefix and
/// the index of the next segment token; `None` for paths outside the crate.
fn path_start(
    toks: &[Token],
    i: usize,
    here: &[String],
    children: &BTreeSet<String>,
    in_inline: bool,
) -> Option<(Vec<String>, usize)> {
    let is = |k: usize, s: &str| toks.get(k).is_some_and(|t| t.text == s);
    let t = toks[i].text.as_str();
    match t {
        "crate" | "$crate" => Some((Vec::new(), i + 1)),
        "self" => Some((here.to_vec(), i + 1)),
        "super" => {
            let mut at = here.to_vec();
            let mut j = i;
            while is(j, "super") {
                at.pop();
                j += 1;
                if is(j, "::") && is(j + 1, "super") {
                    j += 1;
                } else {
                    break;
                }
            }
            Some((at, j))
        }
        _ if !in_inline && children.contains(t) => Some((here.to_vec(), i)),
        _ => None,
    }
}

/// Expand a use tree starting at token `i` (after the path start) under `prefix`; returns
/// the index after it. Each leaf is `(path, name it binds)`; a glob binds `*`.
fn use_tree(
    toks: &[Token],
    mut i: usize,
    prefix: Vec<String>,
    out: &mut Vec<(Vec<String>, String, usize)>,
) -> usize {
    let mut path = prefix;
    loop {
        if toks.get(i).is_some_and(|t| t.text == "::") {
            i += 1;
        }
        let Some(t) = toks.get(i) else { return i };
        match t.text.as_str() {
            "{" => {
                i += 1;
                loop {
                    match toks.get(i).map(|t| t.text.as_str()) {
                        None => return i,
                        Some("}") => return i + 1,
                        Some(",") => i += 1,
                        Some(_) => {
                            // A group item: `self`, `a::b`, `super::..` is not allowed here.
                            if toks[i].text == "self" {
                                let name = path.last().cloned().unwrap_or_default();
                                out.push((path.clone(), name, toks[i].line));
                                i += 1;
                                if toks.get(i).is_some_and(|t| t.text == "as") {
                                    i += 2;
                                }
                            } else {
                                i = use_tree(toks, i, path.clone(), out);
                            }
                        }
                    }
                }
            }
            "*" => {
                out.push((path, "*".into(), t.line));
                return i + 1;
            }
            "self" if path.is_empty() => i += 1,
            s if s
                .chars()
                .next()
                .is_some_and(|c| c.is_alphanumeric() || c == '_') =>
            {
                path.push(s.to_string());
                i += 1;
                if toks.get(i).is_some_and(|t| t.text == "::") {
                    continue;
                }
                let mut name = s.to_string();
                if toks.get(i).is_some_and(|t| t.text == "as") {
                    name = toks.get(i + 1).map(|t| t.text.clone()).unwrap_or_default();
                    i += 2;
                }
                out.push((path, name, t.line));
                return i;
            }
            _ => return i,
        }
    }
}

/// Every path of a file with module path `module_path` whose module has submodules
/// `children` (see the rule above).
fn file_refs(text: &str, module_path: &[String], children: &BTreeSet<String>) -> FileRefs {
    let toks = tokenize(text);
    let mut out = FileRefs::default();
    let mut inline: Vec<(String, usize)> = Vec::new();
    let mut depth = 0usize;
    let is = |i: usize, s: &str| toks.get(i).is_some_and(|t| t.text == s);
    let mut i = 0;
    while i < toks.len() {
        let t = toks[i].text.as_str();
        let after_sep = i > 0 && (is(i - 1, "::") || is(i - 1, "."));
        if t == "mod" && is(i + 2, "{") {
            inline.push((toks[i + 1].text.clone(), depth));
        } else if t == "{" {
            depth += 1;
        } else if t == "}" {
            depth = depth.saturating_sub(1);
            if inline.last().is_some_and(|(_, d)| *d == depth) {
                inline.pop();
            }
        } else if t == "use" {
            let mut here = module_path.to_vec();
            here.extend(inline.iter().map(|(m, _)| m.clone()));
            let j = i + 1;
            let mut leaves = Vec::new();
            let end = if is(j, "{") {
                // `use {a, b}`: each item starts a path of its own.
                let mut k = j + 1;
                while k < toks.len() && !is(k, "}") {
                    if is(k, ",") {
                        k += 1;
                        continue;
                    }
                    k = match path_start(&toks, k, &here, children, !inline.is_empty()) {
                        Some((prefix, next)) => use_tree(&toks, next, prefix, &mut leaves),
                        None => skip_use_item(&toks, k),
                    };
                }
                k
            } else {
                match path_start(&toks, j, &here, children, !inline.is_empty()) {
                    Some((prefix, next)) => use_tree(&toks, next, prefix, &mut leaves),
                    None => j,
                }
            };
            for (segments, name, line) in leaves {
                if inline.is_empty() && name != "*" {
                    out.imports.insert(name, segments.clone());
                }
                out.paths.push(PathRef {
                    segments,
                    in_use: true,
                    line,
                });
            }
            // Skip to the end of the `use` item.
            let mut k = end.max(i + 1);
            while k < toks.len() && !is(k, ";") {
                k += 1;
            }
            i = k + 1;
            continue;
        } else if !after_sep && is(i + 1, "::") {
            let mut here = module_path.to_vec();
            here.extend(inline.iter().map(|(m, _)| m.clone()));
            if let Some((mut segments, mut j)) =
                path_start(&toks, i, &here, children, !inline.is_empty())
            {
                let line = toks[i].line;
                loop {
                    if is(j, "::") {
                        j += 1;
                    }
                    match toks.get(j) {
                        Some(t)
                            if t.text.chars().next().is_some_and(|c| c.is_alphanumeric())
                                && t.text != "super"
                                && t.text != "self" =>
                        {
                            segments.push(t.text.clone());
                            j += 1;
                            if !is(j, "::") {
                                break;
                            }
                        }
                        _ => break,
                    }
                }
                out.paths.push(PathRef {
                    segments,
                    in_use: false,
                    line,
                });
                i = j;
                continue;
            }
        }
        if !after_sep
            && t.chars()
                .next()
                .is_some_and(|c| c.is_alphabetic() || c == '_')
        {
            out.idents.push((t.to_string(), toks[i].line));
        }
        i += 1;
    }
    out
}

/// Index after a `use` group item that is not a path into the crate (`std::..`, `rayon::..`).
fn skip_use_item(toks: &[Token], mut k: usize) -> usize {
    let mut depth = 0;
    while let Some(t) = toks.get(k) {
        match t.text.as_str() {
            "{" => depth += 1,
            "}" if depth == 0 => return k,
            "}" => depth -= 1,
            "," if depth == 0 => return k + 1,
            ";" => return k,
            _ => {}
        }
        k += 1;
    }
    k
}

/// The file-level graph of every folder of `src/` (see the rule above).
fn folder_graphs() -> FolderGraphs {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut files = Vec::new();
    rust_files(&src, &mut files);
    files.sort();
    // Module path -> (file relative to src, its references).
    let mut modules: BTreeMap<Vec<String>, PathBuf> = BTreeMap::new();
    for file in &files {
        let rel = file.strip_prefix(&src).unwrap();
        if rel.starts_with("bin") || rel == Path::new("lib.rs") {
            continue;
        }
        modules.insert(module_path_of(rel), rel.to_path_buf());
    }
    let children_of = |m: &[String]| -> BTreeSet<String> {
        modules
            .keys()
            .filter(|p| p.len() == m.len() + 1 && p.starts_with(m))
            .map(|p| p.last().unwrap().clone())
            .collect()
    };
    let refs: BTreeMap<Vec<String>, FileRefs> = modules
        .iter()
        .map(|(m, rel)| {
            let text = fs::read_to_string(src.join(rel)).unwrap();
            (m.clone(), file_refs(&text, m, &children_of(m)))
        })
        .collect();

    let mut graphs = FolderGraphs::new();
    for folder in modules.keys() {
        let children = children_of(folder);
        if children.is_empty() {
            continue;
        }
        let parent_rel = &modules[folder];
        let parent_name = parent_rel
            .file_name()
            .unwrap()
            .to_string_lossy()
            .into_owned();
        let node = |c: &str| -> String {
            let mut m = folder.clone();
            m.push(c.to_string());
            if children_of(&m).is_empty() {
                format!("{c}.rs")
            } else {
                format!("{c}/")
            }
        };
        // Where a segment after the folder leads: a submodule, or the parent (resolving a
        // name the parent imports from a submodule).
        let parent_imports = &refs[folder].imports;
        let target_of = |segments: &[String]| -> Option<String> {
            if !segments.starts_with(folder) {
                return None;
            }
            let Some(seg) = segments.get(folder.len()) else {
                return Some(parent_name.clone());
            };
            if children.contains(seg) {
                return Some(node(seg));
            }
            if let Some(path) = parent_imports.get(seg) {
                if path.len() > folder.len()
                    && path.starts_with(folder)
                    && children.contains(&path[folder.len()])
                {
                    return Some(node(&path[folder.len()]));
                }
            }
            Some(parent_name.clone())
        };
        let mut graph: Graph = BTreeMap::new();
        graph.insert(parent_name.clone(), BTreeMap::new());
        for c in &children {
            graph.insert(node(c), BTreeMap::new());
        }
        for (m, file_refs) in &refs {
            if !m.starts_with(folder) {
                continue;
            }
            let from = match m.get(folder.len()) {
                Some(c) => node(c),
                None => parent_name.clone(),
            };
            let place = |line: usize| format!("src/{}:{line}", modules[m].display());
            let is_parent = m == folder;
            for p in &file_refs.paths {
                if is_parent && p.in_use {
                    continue;
                }
                if let Some(to) = target_of(&p.segments) {
                    if to != from {
                        graph
                            .get_mut(&from)
                            .unwrap()
                            .entry(to)
                            .or_insert_with(|| place(p.line));
                    }
                }
            }
            if is_parent {
                for (name, line) in &file_refs.idents {
                    let Some(path) = file_refs.imports.get(name) else {
                        continue;
                    };
                    if path.len() > folder.len()
                        && path.starts_with(folder)
                        && children.contains(&path[folder.len()])
                    {
                        let to = node(&path[folder.len()]);
                        graph
                            .get_mut(&from)
                            .unwrap()
                            .entry(to)
                            .or_insert_with(|| place(*line));
                    }
                }
            }
        }
        graphs.insert(folder.join("/"), graph);
    }
    graphs
}

#[test]
fn every_folder_is_acyclic() {
    let graphs = folder_graphs();
    assert!(graphs.contains_key("scene") && graphs.contains_key("sim/contact"));
    let mut msg = String::new();
    for (folder, graph) in &graphs {
        println!("folder src/{folder}/ (importer -> imported, one place that makes the edge):");
        for (from, tos) in graph {
            for (to, place) in tos {
                println!("  {from} -> {to}    ({place})");
            }
        }
        let plain: BTreeMap<String, BTreeSet<String>> = graph
            .iter()
            .map(|(k, v)| (k.clone(), v.keys().cloned().collect()))
            .collect();
        for cycle in find_cycles(&plain) {
            msg += &format!("  src/{folder}/: {}\n", cycle.join(" -> "));
            for pair in cycle.windows(2) {
                msg += &format!(
                    "      {} -> {}: {}\n",
                    pair[0], pair[1], graph[&pair[0]][&pair[1]]
                );
            }
        }
    }
    assert!(
        msg.is_empty(),
        "files inside a folder import one way only; move shared items into a leaf file:\n{msg}"
    );
}

#[test]
fn file_refs_follow_the_rule() {
    let children: BTreeSet<String> = ["run", "world"].iter().map(|s| s.to_string()).collect();
    let here = vec!["scene".to_string()];
    let src = r#"
        mod run;
        pub use run::{run, RunSettings as Settings};
        use crate::io::{self, read_shape};
        pub(crate) use self::world::World;
        fn f() -> Settings { world::make() }
        mod tests { use super::*; }
    "#;
    let r = file_refs(src, &here, &children);
    let seg = |p: &PathRef| p.segments.join("::");
    let got: Vec<(String, bool)> = r.paths.iter().map(|p| (seg(p), p.in_use)).collect();
    assert_eq!(
        got,
        vec![
            ("scene::run::run".to_string(), true),
            ("scene::run::RunSettings".to_string(), true),
            ("io".to_string(), true),
            ("io::read_shape".to_string(), true),
            ("scene::world::World".to_string(), true),
            ("scene::world::make".to_string(), false),
            ("scene".to_string(), true),
        ]
    );
    assert_eq!(r.imports["Settings"], ["scene", "run", "RunSettings"]);
    assert!(r.idents.iter().any(|(n, _)| n == "Settings"));

    let child = "use super::{run::RunSettings, Scene};\nfn g() { super::super::io::x(); }";
    let r = file_refs(child, &["scene".into(), "world".into()], &BTreeSet::new());
    let got: Vec<String> = r.paths.iter().map(seg).collect();
    assert_eq!(got, ["scene::run::RunSettings", "scene::Scene", "io::x"]);
}
