//! Build identity: a digest of the simulator's and the bundle crate's sources, of the data
//! compiled into the binary (`simulator/data`: solar spectra, AFGL profiles, spectral
//! responses, the PICS catalogue) and of the dependency versions (`Cargo.lock`), so that
//! checkpoints, cluster plans and BVH cache files made by one build are not reused by a build
//! whose estimators, tables or libraries differ while the crate version stays the same
//! (`SIMULATOR_BUILD_ID`, read by `simulator::BUILD_ID`).

use std::path::{Path, PathBuf};

/// Every file under `dir` (`rs` only: only Rust sources), symbolic links not followed.
fn files(dir: &Path, rs: bool, out: &mut Vec<PathBuf>) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for e in entries.flatten() {
        let Ok(kind) = e.file_type() else {
            continue;
        };
        let p = e.path();
        if kind.is_dir() {
            files(&p, rs, out);
        } else if kind.is_file() && (!rs || p.extension().is_some_and(|x| x == "rs")) {
            out.push(p);
        }
    }
}

fn main() {
    let manifest = PathBuf::from(std::env::var("CARGO_MANIFEST_DIR").expect("set by cargo"));
    // The bundle crate and the workspace's lock file are absent from a source package of the
    // simulator alone: then only what is there counts.
    let roots = [
        (manifest.join("src"), true),
        (manifest.join("../bundle/src"), true),
        (manifest.join("data"), false),
    ];
    let mut all = Vec::new();
    for (r, rs) in &roots {
        if r.is_dir() {
            println!("cargo:rerun-if-changed={}", r.display());
            files(r, *rs, &mut all);
        }
    }
    let lock = manifest.join("../Cargo.lock");
    if lock.is_file() {
        println!("cargo:rerun-if-changed={}", lock.display());
        all.push(lock);
    }
    all.sort();
    let files = all;
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
