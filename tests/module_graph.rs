//! No import circles in the workspace: neither between the top-level modules of a crate nor
//! between its files.
//!
//! Rationale: data flows one way (config → models → transport core → blocks → run →
//! products); a circle means two modules or files can only be understood, tested and changed
//! together. This test reads every file under each crate's `src/` (outside `#[cfg(test)]`
//! items, which may use anything, and outside comments), resolves each path that starts with
//! `crate::` or `super::` (grouped `use` lists included) to the file that defines the deepest
//! module it names, and fails naming every strongly connected component of more than one node,
//! with the files that make its edges.
//!
//! A folder's face (`mod.rs`, `lib.rs`) naming its own children is not an edge: it declares
//! them, re-exports them and dispatches over them (one enum arm per model file, STYLE.md), so a
//! child using its face's types forms no circle. A child naming its face, and files naming
//! their siblings or cousins, are edges.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// The workspace's library crates whose sources are checked (binaries' `main.rs` and `bin/` are
/// leaves: nothing imports them).
const CRATES: [&str; 7] = [
    "bundle",
    "engine",
    "simulator",
    "scenegen",
    "landcover",
    "tiles",
    "python",
];

fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    for e in std::fs::read_dir(dir).unwrap() {
        let p = e.unwrap().path();
        if p.is_dir() {
            rust_files(&p, out);
        } else if p.extension().is_some_and(|x| x == "rs") {
            out.push(p);
        }
    }
}

/// The file's text without `#[cfg(test)]` items (an attribute line, then the item up to its
/// matching closing brace) and without comments.
fn without_tests(text: &str) -> String {
    let mut out = String::new();
    let mut lines = text.lines();
    while let Some(line) = lines.next() {
        if line.trim_start().starts_with("#[cfg(test)]") {
            let mut depth = 0i32;
            let mut opened = false;
            for l in lines.by_ref() {
                depth += l.matches('{').count() as i32 - l.matches('}').count() as i32;
                opened |= l.contains('{');
                if (opened && depth <= 0) || (!opened && l.trim_end().ends_with(';')) {
                    break;
                }
            }
            continue;
        }
        // Comments may name modules freely.
        let code = line.split("//").next().unwrap_or("");
        out.push_str(code);
        out.push('\n');
    }
    out
}

/// The module path of a source file relative to `src/` (`a/b.rs` and `a/b/mod.rs` → `[a, b]`,
/// `lib.rs` → `[]`), and whether it is a folder's face (`mod.rs`, `lib.rs`).
fn module_of(rel: &Path) -> (Vec<String>, bool) {
    let mut parts: Vec<String> = rel
        .components()
        .map(|c| c.as_os_str().to_string_lossy().into_owned())
        .collect();
    let last = parts.pop().unwrap();
    let face = last == "mod.rs" || last == "lib.rs";
    if !face {
        parts.push(last.trim_end_matches(".rs").to_string());
    }
    (parts, face)
}

/// Every path of `text` that starts at `crate::`, `super::` or `self::`, as segments (the
/// first one `crate`, `super` or `self`), with grouped `use` lists expanded
/// (`crate::a::{b::C, d}` → `crate::a::b::C`, `crate::a::d`).
fn paths(text: &str) -> Vec<Vec<String>> {
    let mut out = Vec::new();
    let bytes = text.as_bytes();
    let ident = |c: u8| c.is_ascii_alphanumeric() || c == b'_';
    for start_kw in ["crate::", "super::", "self::"] {
        for (i, _) in text.match_indices(start_kw) {
            if i > 0 && (ident(bytes[i - 1]) || bytes[i - 1] == b':') {
                continue;
            }
            expand(text, i, Vec::new(), &mut out);
        }
    }
    out
}

/// Expand the path starting at byte `i` of `text` into `out`, after the segments `prefix`.
fn expand(text: &str, mut i: usize, mut prefix: Vec<String>, out: &mut Vec<Vec<String>>) {
    let bytes = text.as_bytes();
    let ident = |c: u8| c.is_ascii_alphanumeric() || c == b'_';
    loop {
        while i < bytes.len() && bytes[i].is_ascii_whitespace() {
            i += 1;
        }
        if i < bytes.len() && bytes[i] == b'{' {
            // A group: its comma-separated members at depth 1, each expanded after `prefix`.
            let mut depth = 0;
            let mut member_start = i + 1;
            let mut j = i;
            while j < bytes.len() {
                match bytes[j] {
                    b'{' => depth += 1,
                    b'}' => {
                        depth -= 1;
                        if depth == 0 {
                            expand(text, member_start, prefix.clone(), out);
                            return;
                        }
                    }
                    b',' if depth == 1 => {
                        expand(text, member_start, prefix.clone(), out);
                        member_start = j + 1;
                    }
                    _ => {}
                }
                j += 1;
            }
            return;
        }
        let s = i;
        while i < bytes.len() && ident(bytes[i]) {
            i += 1;
        }
        if i == s {
            break;
        }
        prefix.push(text[s..i].to_string());
        if text[i..].starts_with("::") {
            i += 2;
        } else {
            break;
        }
    }
    if !prefix.is_empty() {
        out.push(prefix);
    }
}

/// One crate's file graph: file → files it imports (with the names that make each edge).
struct Graph {
    /// Edges (from, to) between files (paths relative to the workspace root).
    edges: BTreeMap<(String, String), BTreeSet<String>>,
}

fn file_graph(root: &Path, krate: &str) -> Graph {
    let src = root.join(krate).join("src");
    let mut files = Vec::new();
    rust_files(&src, &mut files);
    // Module path → file that defines it.
    let mut module_file: BTreeMap<Vec<String>, String> = BTreeMap::new();
    let mut parsed = Vec::new();
    for f in &files {
        let rel = f.strip_prefix(&src).unwrap();
        if rel.starts_with("bin") || rel == Path::new("main.rs") {
            continue;
        }
        let (module, face) = module_of(rel);
        let name = format!("{krate}/src/{}", rel.display());
        module_file.insert(module.clone(), name.clone());
        parsed.push((
            name,
            module,
            face,
            without_tests(&std::fs::read_to_string(f).unwrap()),
        ));
    }
    let mut edges: BTreeMap<(String, String), BTreeSet<String>> = BTreeMap::new();
    for (name, module, face, text) in &parsed {
        for p in paths(text) {
            // Resolve the path's start to a module path.
            let mut at: Vec<String> = match p[0].as_str() {
                "crate" => Vec::new(),
                _ => module.clone(),
            };
            let mut rest = &p[1..];
            if p[0] == "super" {
                // `super` of a face is the folder's parent; of a file, the file's folder.
                at.pop();
                while rest.first().is_some_and(|s| s == "super") {
                    at.pop();
                    rest = &rest[1..];
                }
            }
            // The deepest module the path names.
            let mut target = at.clone();
            for seg in rest {
                let mut next = target.clone();
                next.push(seg.clone());
                if module_file.contains_key(&next) {
                    target = next;
                } else {
                    break;
                }
            }
            let Some(to) = module_file.get(&target) else {
                continue;
            };
            if to == name {
                continue;
            }
            // A face naming its own descendants declares or dispatches over them.
            if *face && target.len() > module.len() && target.starts_with(module) {
                continue;
            }
            edges
                .entry((name.clone(), to.clone()))
                .or_default()
                .insert(p.join("::"));
        }
    }
    Graph { edges }
}

/// Strongly connected components with more than one node (Tarjan).
fn circles(nodes: &BTreeSet<String>, adj: &BTreeMap<String, Vec<String>>) -> Vec<Vec<String>> {
    struct T<'a> {
        adj: &'a BTreeMap<String, Vec<String>>,
        index: BTreeMap<String, usize>,
        low: BTreeMap<String, usize>,
        stack: Vec<String>,
        on: BTreeSet<String>,
        next: usize,
        out: Vec<Vec<String>>,
    }
    fn visit(t: &mut T, v: &str) {
        t.index.insert(v.into(), t.next);
        t.low.insert(v.into(), t.next);
        t.next += 1;
        t.stack.push(v.into());
        t.on.insert(v.into());
        for w in t.adj.get(v).cloned().unwrap_or_default() {
            if !t.index.contains_key(&w) {
                visit(t, &w);
                let lw = t.low[&w];
                let lv = t.low.get_mut(v).unwrap();
                *lv = (*lv).min(lw);
            } else if t.on.contains(&w) {
                let iw = t.index[&w];
                let lv = t.low.get_mut(v).unwrap();
                *lv = (*lv).min(iw);
            }
        }
        if t.low[v] == t.index[v] {
            let mut comp = Vec::new();
            loop {
                let w = t.stack.pop().unwrap();
                t.on.remove(&w);
                let done = w == v;
                comp.push(w);
                if done {
                    break;
                }
            }
            if comp.len() > 1 {
                comp.sort();
                t.out.push(comp);
            }
        }
    }
    let mut t = T {
        adj,
        index: BTreeMap::new(),
        low: BTreeMap::new(),
        stack: Vec::new(),
        on: BTreeSet::new(),
        next: 0,
        out: Vec::new(),
    };
    for v in nodes {
        if !t.index.contains_key(v) {
            visit(&mut t, v);
        }
    }
    t.out
}

/// Circles of `edges`, each with the edges inside it, as a report ("" when none).
fn report(edges: &BTreeMap<(String, String), BTreeSet<String>>) -> (usize, String) {
    let mut nodes = BTreeSet::new();
    let mut adj: BTreeMap<String, Vec<String>> = BTreeMap::new();
    for (a, b) in edges.keys() {
        nodes.insert(a.clone());
        nodes.insert(b.clone());
        adj.entry(a.clone()).or_default().push(b.clone());
    }
    let found = circles(&nodes, &adj);
    let mut msg = String::new();
    for comp in &found {
        msg.push_str(&format!("circle among {comp:?}:\n"));
        for ((a, b), names) in edges {
            if comp.contains(a) && comp.contains(b) {
                msg.push_str(&format!("  {a} -> {b}: {names:?}\n"));
            }
        }
    }
    (found.len(), msg)
}

/// The top-level module (first folder or file under `src/`) of a file named
/// `krate/src/...`; the crate root for `lib.rs`.
fn top_level(file: &str) -> String {
    let rel = file.splitn(3, '/').nth(2).unwrap();
    rel.split('/')
        .next()
        .unwrap()
        .trim_end_matches(".rs")
        .to_string()
}

fn workspace() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

#[test]
fn no_file_of_the_workspace_is_in_an_import_circle() {
    let mut msg = String::new();
    let mut total = 0;
    for krate in CRATES {
        let g = file_graph(&workspace(), krate);
        if krate == "engine" || krate == "simulator" {
            assert!(
                g.edges.len() > 50,
                "{krate}: too few imports found ({})",
                g.edges.len()
            );
        }
        let (n, m) = report(&g.edges);
        total += n;
        msg.push_str(&m);
    }
    assert_eq!(total, 0, "{msg}");
}

#[test]
fn no_top_level_module_is_in_an_import_circle() {
    let mut msg = String::new();
    let mut total = 0;
    for krate in CRATES {
        let g = file_graph(&workspace(), krate);
        let mut edges: BTreeMap<(String, String), BTreeSet<String>> = BTreeMap::new();
        for ((a, b), names) in g.edges {
            let (ta, tb) = (top_level(&a), top_level(&b));
            if ta != tb && ta != "lib" && tb != "lib" {
                edges
                    .entry((format!("{krate}::{ta}"), format!("{krate}::{tb}")))
                    .or_default()
                    .extend(names.into_iter().map(|n| format!("{a}: {n}")));
            }
        }
        let (n, m) = report(&edges);
        total += n;
        msg.push_str(&m);
    }
    assert_eq!(total, 0, "{msg}");
}

/// The engine names none of the application's modules (it is a separate crate, so the compiler
/// already refuses `crate::run`; this catches the application's name used as a path).
#[test]
fn the_engine_does_not_name_the_application() {
    let mut files = Vec::new();
    rust_files(&workspace().join("engine/src"), &mut files);
    for f in files {
        let text = without_tests(&std::fs::read_to_string(&f).unwrap());
        assert!(
            !text.contains("simulator::"),
            "{} names the application crate",
            f.display()
        );
    }
}

/// The detector finds planted circles (a test that cannot fail is no test): between three
/// nodes, and between two files of a crate through `super::` and a grouped `use`; a face
/// dispatching over its children is not one.
#[test]
fn the_detector_finds_a_circle() {
    let nodes: BTreeSet<String> = ["a", "b", "c"].iter().map(|s| s.to_string()).collect();
    let mut adj = BTreeMap::new();
    adj.insert("a".to_string(), vec!["b".to_string()]);
    adj.insert("b".to_string(), vec!["c".to_string()]);
    adj.insert("c".to_string(), vec!["a".to_string()]);
    assert_eq!(circles(&nodes, &adj), vec![vec!["a", "b", "c"]]);
    adj.insert("c".to_string(), vec![]);
    assert!(circles(&nodes, &adj).is_empty());
    assert_eq!(
        without_tests("use crate::x;\n#[cfg(test)]\nmod tests {\n  use crate::y;\n}\nfn f() {}\n"),
        "use crate::x;\nfn f() {}\n"
    );
    assert_eq!(
        paths("use crate::a::{b::C, d, e::{F, g::H}};"),
        vec![
            vec!["crate", "a", "b", "C"],
            vec!["crate", "a", "d"],
            vec!["crate", "a", "e", "F"],
            vec!["crate", "a", "e", "g", "H"],
        ]
    );

    let dir = std::env::temp_dir().join(format!("module_graph_{}", std::process::id()));
    let src = dir.join("planted/src");
    std::fs::create_dir_all(src.join("m")).unwrap();
    std::fs::write(src.join("lib.rs"), "pub mod m;\n").unwrap();
    std::fs::write(
        src.join("m/mod.rs"),
        "pub mod a;\npub mod b;\npub use a::A;\npub fn f() { b::g() }\npub struct Face;\n",
    )
    .unwrap();
    std::fs::write(
        src.join("m/a.rs"),
        "use super::{b::B, Face};\npub struct A;\n",
    )
    .unwrap();
    std::fs::write(src.join("m/b.rs"), "pub struct B;\npub fn g() {}\n").unwrap();
    let g = file_graph(&dir, "planted");
    assert_eq!(report(&g.edges).0, 0, "{:?}", g.edges);
    assert!(g
        .edges
        .contains_key(&("planted/src/m/a.rs".into(), "planted/src/m/b.rs".into())));
    std::fs::write(
        src.join("m/b.rs"),
        "pub struct B;\npub fn g() { crate::m::a::A; }\n",
    )
    .unwrap();
    let g = file_graph(&dir, "planted");
    let (n, msg) = report(&g.edges);
    assert_eq!(n, 1, "{msg}");
    assert!(
        msg.contains("planted/src/m/b.rs -> planted/src/m/a.rs"),
        "{msg}"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}
