//! Helpers of the workspace's end-to-end tests (`tests/examples.rs`, `tests/pipeline.rs`): where
//! the repository, the shared data folder and the built binaries are, temporary folders, running
//! a binary with its output captured, and the commands an example file's header states.
//!
//! The tests run the real `scenegen` and `simulate` executables of the same build
//! (`target/<profile>/`), as a user would; `cargo test --workspace` builds them.

use std::path::{Path, PathBuf};
use std::process::Command;

/// The repository root (this package is its `tests/` folder).
pub fn repo_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .expect("tests/ has a parent")
        .to_path_buf()
}

/// The public data folder beside the repository (`../shared`), if present.
pub fn shared_dir() -> Option<PathBuf> {
    let p = repo_root().join("../shared");
    p.join("data").is_dir().then_some(p)
}

/// A built binary of the workspace (`scenegen`, `simulate`) beside this test executable.
pub fn binary(name: &str) -> Result<PathBuf, String> {
    let exe = std::env::current_exe().map_err(|e| format!("current_exe: {e}"))?;
    // target/<profile>/deps/<test> → target/<profile>/<name>
    let dir = exe
        .parent()
        .and_then(Path::parent)
        .ok_or("test executable has no target folder")?;
    let p = dir.join(name);
    if p.is_file() {
        Ok(p)
    } else {
        Err(format!(
            "{} is not built: run `cargo test --workspace` (which builds it) or `cargo build --bins` with the same profile",
            p.display()
        ))
    }
}

/// A fresh, empty temporary folder for one test.
pub fn temp_dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("e2e-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).expect("create a temporary folder");
    d
}

/// The result of one command.
#[derive(Debug)]
pub struct Outcome {
    pub code: Option<i32>,
    pub stdout: String,
    pub stderr: String,
    pub seconds: f64,
}

/// Run `program args` in `cwd`, capturing its output.
pub fn run(program: &Path, args: &[String], cwd: &Path) -> Outcome {
    let t0 = std::time::Instant::now();
    match Command::new(program).args(args).current_dir(cwd).output() {
        Ok(o) => Outcome {
            code: o.status.code(),
            stdout: String::from_utf8_lossy(&o.stdout).into_owned(),
            stderr: String::from_utf8_lossy(&o.stderr).into_owned(),
            seconds: t0.elapsed().as_secs_f64(),
        },
        Err(e) => Outcome {
            code: None,
            stdout: String::new(),
            stderr: format!("cannot start {}: {e}", program.display()),
            seconds: 0.0,
        },
    }
}

/// The commands an example file's header (its leading `#` lines) states: lines that begin
/// with `scenegen build`, `simulate run`, `simulate pics`, `simulate cloud-field` or
/// `simulate temperatures` (optionally `./target/release/`),
/// with `\` continuations joined, split into words (program first). Prose that merely mentions
/// a command mid-line is not a command.
pub fn header_commands(text: &str) -> Vec<Vec<String>> {
    let mut lines = Vec::new();
    let mut pending = String::new();
    for l in text.lines() {
        let Some(c) = l.trim_start().strip_prefix('#') else {
            break;
        };
        let c = c.trim();
        if let Some(head) = c.strip_suffix('\\') {
            pending.push_str(head);
            pending.push(' ');
            continue;
        }
        pending.push_str(c);
        lines.push(std::mem::take(&mut pending));
    }
    lines
        .iter()
        .filter_map(|l| {
            let l = l.strip_prefix("./target/release/").unwrap_or(l);
            let words: Vec<String> = l.split_whitespace().map(str::to_string).collect();
            let ok = matches!(
                (
                    words.first().map(String::as_str),
                    words.get(1).map(String::as_str)
                ),
                (Some("scenegen"), Some("build"))
                    | (Some("simulate"), Some("run"))
                    | (Some("simulate"), Some("pics"))
                    | (Some("simulate"), Some("cloud-field"))
                    | (Some("simulate"), Some("temperatures"))
            );
            ok.then_some(words)
        })
        .collect()
}

/// The value after `-o`/`--output` in a command's words.
pub fn output_arg(words: &[String]) -> Option<&str> {
    words
        .windows(2)
        .find(|w| w[0] == "-o" || w[0] == "--output")
        .map(|w| w[1].as_str())
}

/// Every `*.toml` file under `dir`, sorted.
pub fn toml_files(dir: &Path) -> Vec<PathBuf> {
    let mut out = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        let Ok(rd) = std::fs::read_dir(&d) else {
            continue;
        };
        for e in rd.flatten() {
            let p = e.path();
            if p.is_dir() {
                stack.push(p);
            } else if p.extension().is_some_and(|x| x == "toml") {
                out.push(p);
            }
        }
    }
    out.sort();
    out
}

/// Copy a folder tree (files and folders only).
pub fn copy_tree(from: &Path, to: &Path) -> std::io::Result<()> {
    std::fs::create_dir_all(to)?;
    for e in std::fs::read_dir(from)? {
        let e = e?;
        let (src, dst) = (e.path(), to.join(e.file_name()));
        if src.is_dir() {
            copy_tree(&src, &dst)?;
        } else {
            std::fs::copy(&src, &dst)?;
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Rationale: only lines that start with a command count, continuations are joined, and
    /// the header ends at the first non-comment line.
    #[test]
    fn header_commands_are_parsed() {
        let text = "# A region built by `scenegen build` (prose)\n\
                    #   ./target/release/scenegen build examples/a/region.toml \\\n\
                    #       -o out/a --force\n\
                    #   simulate run examples/a/x.toml -o out/x\n\
                    seed = 1\n\
                    #   simulate run not/in/header.toml -o out/y\n";
        let c = header_commands(text);
        assert_eq!(c.len(), 2, "{c:?}");
        assert_eq!(
            c[0],
            [
                "scenegen",
                "build",
                "examples/a/region.toml",
                "-o",
                "out/a",
                "--force"
            ]
        );
        assert_eq!(output_arg(&c[1]), Some("out/x"));
    }
}
