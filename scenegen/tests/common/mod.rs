//! Helpers shared by scenegen's integration tests (each test binary uses some of them).
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::process::Command;

/// A fresh, empty temporary folder for one test (the process id keeps concurrent runs apart).
pub fn tmp(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("scenegen-test-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// Run the `scenegen` binary of this build: (exit code, stdout, stderr).
pub fn scenegen(args: &[&str]) -> (i32, String, String) {
    let o = Command::new(env!("CARGO_BIN_EXE_scenegen"))
        .args(args)
        .output()
        .unwrap();
    (
        o.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&o.stdout).into_owned(),
        String::from_utf8_lossy(&o.stderr).into_owned(),
    )
}

/// The shared data folder beside the repository (as in CI), if present.
pub fn shared_data() -> Option<PathBuf> {
    let p = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/data");
    if p.is_dir() {
        Some(p)
    } else {
        eprintln!(
            "shared data not found at {}; real-data test skipped",
            p.display()
        );
        None
    }
}
