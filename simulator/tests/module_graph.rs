//! The simulator's top-level modules form a directed acyclic graph: no import circles.
//!
//! Rationale: data flows one way (config → models → transport core → run → products); a circle
//! means two modules can only be understood, tested and changed together. This test reads every
//! file under `src/`, takes the edges `a → b` for each `crate::b` path in module `a` (outside
//! `#[cfg(test)]` items, which may use anything), and fails naming every strongly connected
//! component with more than one module, with the files that make its edges.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

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
/// matching closing brace).
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

/// Edges between top-level modules: (from, to) → files that make them.
fn edges(src: &Path) -> BTreeMap<(String, String), BTreeSet<String>> {
    let mut files = Vec::new();
    rust_files(src, &mut files);
    let mut e: BTreeMap<(String, String), BTreeSet<String>> = BTreeMap::new();
    for f in files {
        let rel = f.strip_prefix(src).unwrap();
        if rel.starts_with("bin") || rel == Path::new("lib.rs") {
            continue;
        }
        let first = rel
            .components()
            .next()
            .unwrap()
            .as_os_str()
            .to_string_lossy();
        let module = first.trim_end_matches(".rs").to_string();
        let text = without_tests(&std::fs::read_to_string(&f).unwrap());
        for (i, _) in text.match_indices("crate::") {
            let rest = &text[i + 7..];
            let name: String = rest
                .chars()
                .take_while(|c| c.is_ascii_alphanumeric() || *c == '_')
                .collect();
            // Items of the crate root (lib.rs) are not a module.
            let is_module = src.join(format!("{name}.rs")).exists() || src.join(&name).is_dir();
            if is_module && name != module {
                e.entry((module.clone(), name))
                    .or_default()
                    .insert(rel.display().to_string());
            }
        }
    }
    e
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

#[test]
fn simulator_modules_have_no_import_circle() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let e = edges(&src);
    let mut nodes = BTreeSet::new();
    let mut adj: BTreeMap<String, Vec<String>> = BTreeMap::new();
    for (a, b) in e.keys() {
        nodes.insert(a.clone());
        nodes.insert(b.clone());
        adj.entry(a.clone()).or_default().push(b.clone());
    }
    assert!(nodes.len() > 10, "too few modules found: {nodes:?}");
    let found = circles(&nodes, &adj);
    let mut msg = String::new();
    for comp in &found {
        msg.push_str(&format!("circle among {comp:?}:\n"));
        for ((a, b), files) in &e {
            if comp.contains(a) && comp.contains(b) {
                msg.push_str(&format!("  {a} -> {b} in {files:?}\n"));
            }
        }
    }
    assert!(found.is_empty(), "{msg}");
}

/// The detector itself finds a planted circle (a test that cannot fail is no test).
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
}
