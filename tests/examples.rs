//! Every example file runs as its header says (issue 20, item 5).
//!
//! Discovers every `examples/**/*.toml` (region files, experiment files, `simulate pics` site
//! files) and reads the commands its header states (`scenegen build …`, `simulate run …`,
//! `simulate pics …`, `simulate cloud-field …`); each file must state at least one command
//! that names the file itself.
//! The examples folder is copied verbatim into a temporary tree `T/repo/examples`, beside links
//! to the repository's other folders, with `T/shared` linked to the shared data folder, so the files' relative paths
//! (`../../../shared/data/…`, `../../out/…`) resolve exactly as in a fresh clone, and the
//! commands run there with the release binaries: region builds first (experiments read their
//! bundles), then surface temperatures, then experiments, then calibration sites. Expected: exit 0 and the products
//! present (a bundle manifest; `results.nc` and `results.csv`; `pics.csv` and `pics.nc`).
//!
//! To stay quick, `simulate run` gets `--spp 8` (its documented override; CKD runs round up to
//! whole g-point cycles) and the copy of `examples/pics/acquisitions.csv` keeps its first two
//! acquisitions (site files have no `spp` override on the command line). Files whose text
//! reads the shared data folder (or a bundle built from it) are skipped, with a message, when
//! that folder is absent.

use std::collections::BTreeSet;
use std::path::Path;

use e2e::{binary, copy_tree, header_commands, output_arg, repo_root, run, shared_dir, temp_dir};

const QUICK_SPP: &str = "8";

/// The order in which commands run: bundles before the surface temperatures computed on them,
/// both before the experiments that read them.
fn stage(words: &[String]) -> u8 {
    match words[1].as_str() {
        "build" | "cloud-field" => 0,
        "temperatures" => 1,
        "run" => 2,
        _ => 3,
    }
}

/// The products a command must leave in its output folder.
fn products(words: &[String]) -> &'static [&'static str] {
    match words[1].as_str() {
        "build" => &["manifest.toml"],
        // `-o` names the field file itself.
        "cloud-field" => &[""],
        "run" => &["results.nc", "results.csv"],
        "temperatures" => &["materials.csv", "diurnal.csv"],
        _ => &["pics.csv", "pics.nc"],
    }
}

#[test]
fn every_example_runs_as_its_header_says() {
    let root = repo_root();
    let shared = shared_dir();
    let (scenegen, simulate) = (binary("scenegen").unwrap(), binary("simulate").unwrap());

    let t = temp_dir("examples");
    let repo = t.join("repo");
    copy_tree(&root.join("examples"), &repo.join("examples")).unwrap();
    // Examples may read other folders of the repository (e.g. simulator/tests/data): link them.
    for e in std::fs::read_dir(&root).unwrap().flatten() {
        let name = e.file_name();
        if !["examples", "out", "target", ".git"].contains(&name.to_str().unwrap_or("")) {
            std::os::unix::fs::symlink(e.path(), repo.join(&name)).unwrap();
        }
    }
    if let Some(s) = &shared {
        std::os::unix::fs::symlink(s.canonicalize().unwrap(), t.join("shared")).unwrap();
    }
    let acq = repo.join("examples/pics/acquisitions.csv");
    if let Ok(text) = std::fs::read_to_string(&acq) {
        let short: Vec<&str> = text.lines().take(3).collect();
        std::fs::write(&acq, short.join("\n") + "\n").unwrap();
    }

    let mut problems = Vec::new();
    let mut commands: Vec<(String, Vec<String>)> = Vec::new();
    let files = e2e::toml_files(&repo.join("examples"));
    assert!(
        files.len() >= 10,
        "only {} example files found",
        files.len()
    );
    for f in &files {
        let rel = f.strip_prefix(&repo).unwrap().display().to_string();
        // Land-cover scheme files (`*_scheme.toml`) are data read by a region, not run.
        if rel.ends_with("_scheme.toml") {
            continue;
        }
        let text = std::fs::read_to_string(f).unwrap();
        let cmds = header_commands(&text);
        if !cmds.iter().any(|c| c.contains(&rel)) {
            problems.push(format!(
                "{rel}: its header states no `scenegen build`, `simulate run` or `simulate pics` command naming the file (found {cmds:?})"
            ));
        }
        // Without the shared data, files that read it, or a bundle built from it, are skipped.
        if shared.is_none() && (text.contains("shared/") || text.contains("/out/")) {
            eprintln!("skipped {rel}: it reads ../shared, which is absent");
            continue;
        }
        commands.extend(cmds.into_iter().map(|c| (rel.clone(), c)));
    }
    // The same build may be stated by a region and by the experiments that read its bundle.
    let mut seen = BTreeSet::new();
    commands.retain(|(_, c)| seen.insert(c.clone()));
    commands.sort_by_key(|(_, c)| stage(c));

    let t0 = std::time::Instant::now();
    for (file, words) in &commands {
        let mut args: Vec<String> = words[1..].to_vec();
        match words[1].as_str() {
            "run" if !args.iter().any(|a| a == "--spp") => {
                args.extend(["--spp".into(), QUICK_SPP.into(), "-q".into()]);
            }
            _ => args.push("-q".into()),
        }
        let program = if words[0] == "scenegen" {
            &scenegen
        } else {
            &simulate
        };
        let o = run(program, &args, &repo);
        println!("{:6.1} s  {}", o.seconds, words.join(" "));
        if o.code != Some(0) {
            problems.push(format!(
                "{file}: `{}` exited with {:?}:\n{}",
                words.join(" "),
                o.code,
                o.stderr
                    .lines()
                    .rev()
                    .take(8)
                    .collect::<Vec<_>>()
                    .join("\n")
            ));
            continue;
        }
        let Some(out) = output_arg(words) else {
            problems.push(format!("{file}: `{}` names no -o folder", words.join(" ")));
            continue;
        };
        for p in products(words) {
            let product = if p.is_empty() {
                Path::new(&repo).join(out)
            } else {
                Path::new(&repo).join(out).join(p)
            };
            if !product.is_file() {
                problems.push(format!("{file}: `{}` wrote no {out}/{p}", words.join(" ")));
            }
        }
    }
    println!(
        "{} commands from {} example files in {:.1} s",
        commands.len(),
        files.len(),
        t0.elapsed().as_secs_f64()
    );
    assert!(problems.is_empty(), "\n{}", problems.join("\n\n"));
    let _ = std::fs::remove_dir_all(&t);
}
