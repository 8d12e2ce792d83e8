//! Build identity, shared by the engine's and the application's build scripts (each includes
//! this file with `#[path]`): a digest of a crate's sources, of the sources of the crates it
//! builds on, of the data compiled in (solar spectra, AFGL profiles, spectral responses, the
//! PICS catalogue) and of the dependency versions (`Cargo.lock`), so that checkpoints, cluster
//! plans and BVH cache files made by one build are not reused by a build whose estimators,
//! tables or libraries differ while the crate version stays the same.

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

/// Print `cargo:rustc-env={var}=<version>+src.<digest>`: the FNV-1a digest of every file under
/// `roots` (relative to the crate's manifest folder; `true`: Rust sources only) and of the
/// workspace's `Cargo.lock`, with a `rerun-if-changed` for each root. Roots absent from a
/// source package of the crate alone are skipped: then only what is there counts.
pub fn emit(var: &str, roots: &[(&str, bool)]) {
    let manifest = PathBuf::from(std::env::var("CARGO_MANIFEST_DIR").expect("set by cargo"));
    let roots: Vec<(PathBuf, bool)> = roots
        .iter()
        .map(|(r, rs)| (manifest.join(r), *rs))
        .collect();
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
        "cargo:rustc-env={var}={}+src.{:016x}",
        std::env::var("CARGO_PKG_VERSION").expect("set by cargo"),
        h
    );
}
