//! Build identity: a digest of the simulator's and the bundle crate's sources, so that
//! checkpoints and cluster plans made by one build are not reused by a build whose estimators
//! differ while the crate version stays the same (`SIMULATOR_BUILD_ID`, read by
//! `simulator::BUILD_ID`).

use std::path::{Path, PathBuf};

fn sources(dir: &Path, out: &mut Vec<PathBuf>) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for e in entries.flatten() {
        let p = e.path();
        if p.is_dir() {
            sources(&p, out);
        } else if p.extension().is_some_and(|x| x == "rs") {
            out.push(p);
        }
    }
}

fn main() {
    let manifest = PathBuf::from(std::env::var("CARGO_MANIFEST_DIR").expect("set by cargo"));
    // The bundle crate is absent from a source package of the simulator alone: then only its
    // own sources count.
    let roots = [manifest.join("src"), manifest.join("../bundle/src")];
    let mut files = Vec::new();
    for r in &roots {
        if r.is_dir() {
            println!("cargo:rerun-if-changed={}", r.display());
            sources(r, &mut files);
        }
    }
    files.sort();
    // FNV-1a 64 over each file's path (relative to the manifest) and bytes.
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    let mut eat = |bytes: &[u8]| {
        for &b in bytes {
            h ^= b as u64;
            h = h.wrapping_mul(0x0000_0100_0000_01b3);
        }
    };
    for f in &files {
        let rel = f.strip_prefix(&manifest).unwrap_or(f);
        eat(rel.to_string_lossy().replace('\\', "/").as_bytes());
        eat(&[0]);
        eat(&std::fs::read(f).unwrap_or_default());
        eat(&[0]);
    }
    println!(
        "cargo:rustc-env=SIMULATOR_BUILD_ID={}+src.{:016x}",
        std::env::var("CARGO_PKG_VERSION").expect("set by cargo"),
        h
    );
}
