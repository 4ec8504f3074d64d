//! The layout's rules, checked on the sources: no circle of imports between the files of any
//! crate; the vision front end importing nothing of the matcher; the root library's two sides of
//! the socket (`src/engine`, the MARVIN side, and `src/server`, the robot server) naming each
//! other only through `protocol`; and no source file over [`MAX_LINES`] lines.
//!
//! A file "imports" another when it names a path into it (`use crate::a::b`, `super::c::d`,
//! `crate::a::f(..)` in an expression). Paths are read with a simple scanner, not a parser:
//! good enough for this code base's style (imports at the top, one `mod tests` at the end).

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// The workspace's members (`.` is the root package).
const MEMBERS: [&str; 7] = ["mesh", "sim", "vision", "robot", "hand-eye", "camera-calib", "."];

/// The most lines a source file may have: more than one reader can hold.
const MAX_LINES: usize = 800;

/// A crate's source files by module path (`["front_end", "pmf"]`).
struct CrateFiles {
    name: String,
    files: BTreeMap<Vec<String>, PathBuf>,
}

fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        if path.is_dir() {
            rust_files(&path, out);
        } else if path.extension().is_some_and(|e| e == "rs") {
            out.push(path);
        }
    }
}

/// The module path of a file under `src`: `lib.rs`/`main.rs` are the root, `a/mod.rs` is `a`.
fn module_of(src: &Path, file: &Path) -> Vec<String> {
    let rel = file.strip_prefix(src).unwrap().with_extension("");
    let mut parts: Vec<String> = rel.iter().map(|p| p.to_string_lossy().into_owned()).collect();
    if matches!(parts.last().map(String::as_str), Some("mod" | "lib" | "main")) {
        parts.pop();
    }
    parts
}

/// The crates of the workspace: each member's library, and the root package's binary (`main.rs`
/// and `src/cli/`) apart from its library.
fn crates() -> Vec<CrateFiles> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut out = Vec::new();
    for member in MEMBERS {
        let src = root.join(member).join("src");
        let mut files = Vec::new();
        rust_files(&src, &mut files);
        let (mut lib, mut bin) = (BTreeMap::new(), BTreeMap::new());
        for f in files {
            let in_bin = member == "." && (f.ends_with("main.rs") || f.starts_with(src.join("cli")));
            let target = if in_bin { &mut bin } else { &mut lib };
            target.insert(module_of(&src, &f), f);
        }
        out.push(CrateFiles { name: format!("{member} (lib)"), files: lib });
        if !bin.is_empty() {
            out.push(CrateFiles { name: format!("{member} (bin)"), files: bin });
        }
    }
    out
}

/// Every `crate::`/`super::` path a file names, as module paths from the crate root (each
/// name of a `{..}` group expanded one level). `super` inside the file's trailing `mod tests`
/// means the file's own module.
fn paths_named(module: &[String], text: &str) -> Vec<Vec<String>> {
    let mut out = Vec::new();
    let mut in_tests = false;
    for line in text.lines() {
        let code = line.split("//").next().unwrap_or("");
        if line.trim_start().starts_with("mod tests") || line.trim_start().starts_with("pub(crate) mod tests") {
            in_tests = true;
        }
        let mut rest = code;
        while let Some(at) = rest.find("crate::").into_iter().chain(rest.find("super::")).min() {
            let tail = &rest[at..];
            let preceded =
                at > 0 && rest.as_bytes()[at - 1].is_ascii_alphanumeric() | (rest.as_bytes()[at - 1] == b'_');
            let (mut base, mut after) = if let Some(t) = tail.strip_prefix("crate::") {
                (Vec::new(), t)
            } else {
                // `super` of a file `a/b.rs` is `a`; of `a/mod.rs` (module `a`) it is the root;
                // inside the file's tests module it is the file's own module.
                let mut b = module.to_vec();
                if !in_tests {
                    b.pop();
                }
                (b, &tail["super::".len()..])
            };
            while let Some(t) = after.strip_prefix("super::") {
                base.pop();
                after = t;
            }
            if !preceded {
                if let Some(group) = after.strip_prefix('{') {
                    for item in group.split('}').next().unwrap_or("").split(',') {
                        let mut p = base.clone();
                        p.extend(idents(item.trim()));
                        out.push(p);
                    }
                } else {
                    let mut p = base.clone();
                    p.extend(idents(after));
                    out.push(p);
                }
            }
            rest = &tail[1..];
        }
    }
    out
}

/// The leading `a::b::c` of a path.
fn idents(s: &str) -> Vec<String> {
    let mut out = Vec::new();
    for part in s.split("::") {
        let word: String = part.chars().take_while(|c| c.is_ascii_alphanumeric() || *c == '_').collect();
        if word.is_empty() {
            break;
        }
        let whole = word.len() == part.len();
        out.push(word);
        if !whole {
            break;
        }
    }
    out
}

/// The file a module path lands in: its longest prefix that is a file of the crate.
fn file_of(files: &BTreeMap<Vec<String>, PathBuf>, path: &[String]) -> Option<Vec<String>> {
    (0..=path.len()).rev().map(|n| path[..n].to_vec()).find(|p| files.contains_key(p))
}

/// Which files each file imports (never itself).
fn import_graph(c: &CrateFiles) -> BTreeMap<Vec<String>, BTreeSet<Vec<String>>> {
    let mut graph = BTreeMap::new();
    for (module, file) in &c.files {
        let text = std::fs::read_to_string(file).unwrap();
        let targets: BTreeSet<Vec<String>> =
            paths_named(module, &text).iter().filter_map(|p| file_of(&c.files, p)).filter(|t| t != module).collect();
        graph.insert(module.clone(), targets);
    }
    graph
}

/// A circle of imports, if there is one (depth-first search).
fn find_circle(graph: &BTreeMap<Vec<String>, BTreeSet<Vec<String>>>) -> Option<Vec<Vec<String>>> {
    fn visit(
        node: &Vec<String>,
        graph: &BTreeMap<Vec<String>, BTreeSet<Vec<String>>>,
        stack: &mut Vec<Vec<String>>,
        done: &mut BTreeSet<Vec<String>>,
    ) -> Option<Vec<Vec<String>>> {
        if let Some(at) = stack.iter().position(|n| n == node) {
            let mut circle = stack[at..].to_vec();
            circle.push(node.clone());
            return Some(circle);
        }
        if done.contains(node) {
            return None;
        }
        stack.push(node.clone());
        for next in graph.get(node).into_iter().flatten() {
            if let Some(c) = visit(next, graph, stack, done) {
                return Some(c);
            }
        }
        stack.pop();
        done.insert(node.clone());
        None
    }
    let mut done = BTreeSet::new();
    graph.keys().find_map(|n| visit(n, graph, &mut Vec::new(), &mut done))
}

fn show(path: &[String]) -> String {
    if path.is_empty() { "(root)".into() } else { path.join("::") }
}

#[test]
fn no_crate_has_a_circle_of_imports_between_its_files() {
    for c in crates() {
        let graph = import_graph(&c);
        if let Some(circle) = find_circle(&graph) {
            let names: Vec<String> = circle.iter().map(|m| show(m)).collect();
            panic!("{}: a circle of imports: {}", c.name, names.join(" -> "));
        }
    }
}

#[test]
fn the_front_end_imports_nothing_of_the_matcher() {
    let vision = crates().into_iter().find(|c| c.name == "vision (lib)").unwrap();
    for (module, targets) in import_graph(&vision) {
        let in_front_end = module.first().is_some_and(|m| m == "front_end");
        if let Some(t) = targets.iter().find(|t| in_front_end && t.first().is_some_and(|m| m == "matcher")) {
            panic!("{} imports {}", show(&module), show(t));
        }
    }
}

/// The scanner itself: a known circle is found, and `super` resolves as Rust resolves it.
#[test]
fn the_scanner_finds_a_circle_and_resolves_super() {
    let m = |s: &str| s.split("::").map(String::from).collect::<Vec<_>>();
    let named = paths_named(&m("matcher::views"), "use super::model::{A, B};\nuse crate::front_end::pmf::Match;\n");
    assert!(named.contains(&m("matcher::model")), "{named:?}");
    assert!(named.contains(&m("front_end::pmf::Match")), "{named:?}");
    let in_tests = paths_named(&m("a::b"), "fn f() {}\n#[cfg(test)]\nmod tests {\n    use super::*;\n}\n");
    assert!(in_tests.iter().all(|p| p.starts_with(&m("a::b"))), "{in_tests:?}");
    let mut graph = BTreeMap::new();
    graph.insert(m("a"), BTreeSet::from([m("b")]));
    graph.insert(m("b"), BTreeSet::from([m("c")]));
    graph.insert(m("c"), BTreeSet::from([m("a")]));
    assert_eq!(find_circle(&graph).map(|c| c.len()), Some(4));
    graph.insert(m("c"), BTreeSet::new());
    assert_eq!(find_circle(&graph), None);
}

/// The side of the socket a module of the root library is on, if it is on one.
fn side_of(module: &[String]) -> Option<&'static str> {
    match module.first().map(String::as_str) {
        Some("engine") => Some("the MARVIN side"),
        Some("server") => Some("the robot server"),
        _ => None,
    }
}

/// Every import from one side of the socket into the other.
fn crossings(graph: &BTreeMap<Vec<String>, BTreeSet<Vec<String>>>) -> Vec<(Vec<String>, Vec<String>)> {
    let mut out = Vec::new();
    for (module, targets) in graph {
        for t in targets {
            if let (Some(a), Some(b)) = (side_of(module), side_of(t))
                && a != b
            {
                out.push((module.clone(), t.clone()));
            }
        }
    }
    out
}

#[test]
fn neither_side_of_the_socket_imports_the_other() {
    let root = crates().into_iter().find(|c| c.name == ". (lib)").unwrap();
    let graph = import_graph(&root);
    assert!(graph.keys().any(|m| side_of(m) == Some("the MARVIN side")), "no src/engine: the layout moved");
    assert!(graph.keys().any(|m| side_of(m) == Some("the robot server")), "no src/server: the layout moved");
    let found: Vec<String> = crossings(&graph)
        .iter()
        .map(|(a, b)| format!("{} ({}) imports {} ({})", show(a), side_of(a).unwrap(), show(b), side_of(b).unwrap()))
        .collect();
    assert!(found.is_empty(), "only `protocol` is shared between the sides: {found:#?}");
}

/// The rule itself: a crossing either way is found; imports of `protocol` or within a side are not.
#[test]
fn a_crossing_of_the_socket_is_found() {
    let m = |s: &str| s.split("::").map(String::from).collect::<Vec<_>>();
    let mut graph = BTreeMap::new();
    graph.insert(m("engine::run"), BTreeSet::from([m("protocol"), m("engine::client")]));
    graph.insert(m("server::cell"), BTreeSet::from([m("protocol"), m("server::pick")]));
    assert!(crossings(&graph).is_empty());
    graph.insert(m("engine::run"), BTreeSet::from([m("server::pick")]));
    graph.insert(m("server"), BTreeSet::from([m("engine::perception")]));
    assert_eq!(crossings(&graph).len(), 2);
}

/// Every Rust source of the workspace: each member's `src`, and the root's tests, examples and
/// benches.
fn all_sources() -> Vec<PathBuf> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut files = Vec::new();
    for member in MEMBERS {
        for dir in ["src", "tests", "examples", "benches"] {
            let d = root.join(member).join(dir);
            if d.is_dir() {
                rust_files(&d, &mut files);
            }
        }
    }
    files.sort();
    files.dedup();
    files
}

#[test]
fn no_source_file_is_over_800_lines() {
    let long: Vec<String> = all_sources()
        .iter()
        .filter_map(|f| {
            let n = std::fs::read_to_string(f).unwrap().lines().count();
            (n > MAX_LINES).then(|| format!("{} ({n} lines)", f.display()))
        })
        .collect();
    assert!(long.is_empty(), "split these along their seams (at most {MAX_LINES} lines): {long:#?}");
}
