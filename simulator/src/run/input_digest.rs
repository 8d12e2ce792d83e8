//! A digest of every input file an experiment names, so that checkpoints (and anything else
//! keyed by "the same run") change when an input changes, not only when the experiment text
//! does: rebuilding a scene bundle at the same path, or replacing a phase table, invalidates
//! the stored results.
//!
//! Every string value of the experiment file that names an existing file or folder (relative
//! to the experiment's folder, or absolute) is an input:
//! * a scene bundle (a folder with `manifest.toml`): its manifest, which records the size and
//!   SHA-256 of every buffer (checked on open, see `bundle::Bundle::open`);
//! * any other file: its SHA-256;
//! * any other folder (an absorption database): the names, sizes and modification times of its
//!   files, one level deep (hashing gigabytes of tables at every start would cost more than
//!   a resumed task saves).
//!
//! Built-in data found by name (solar spectra, AFGL profiles of the installation) are part of
//! the installation and covered by the simulator's version.

use std::path::{Path, PathBuf};

use sha2::{Digest, Sha256};

/// The paths the experiment text names that exist, in the order they appear.
pub fn named_inputs(text: &str, experiment: &Path) -> Vec<PathBuf> {
    let base = experiment.parent().unwrap_or(Path::new("."));
    let Ok(v) = text.parse::<toml::Table>() else {
        return Vec::new();
    };
    let mut out = Vec::new();
    fn walk(v: &toml::Value, base: &Path, out: &mut Vec<PathBuf>) {
        match v {
            toml::Value::String(s) if !s.is_empty() && s.len() < 4096 => {
                let p = base.join(s);
                if p.exists() && !out.contains(&p) {
                    out.push(p);
                }
            }
            toml::Value::Array(a) => a.iter().for_each(|x| walk(x, base, out)),
            toml::Value::Table(t) => t.values().for_each(|x| walk(x, base, out)),
            _ => {}
        }
    }
    for x in v.values() {
        walk(x, base, &mut out);
    }
    out
}

/// Hex SHA-256 over the named inputs' contents (see the module doc).
pub fn digest(text: &str, experiment: &Path) -> String {
    let mut h = Sha256::new();
    for p in named_inputs(text, experiment) {
        h.update(p.to_string_lossy().as_bytes());
        if p.is_dir() {
            let manifest = p.join("manifest.toml");
            if let Ok(bytes) = std::fs::read(&manifest) {
                h.update(&bytes);
                continue;
            }
            let mut entries: Vec<(String, u64, u128)> = std::fs::read_dir(&p)
                .map(|rd| {
                    rd.flatten()
                        .filter_map(|e| {
                            let m = e.metadata().ok()?;
                            let t = m
                                .modified()
                                .ok()?
                                .duration_since(std::time::UNIX_EPOCH)
                                .ok()?
                                .as_nanos();
                            Some((e.file_name().to_string_lossy().into_owned(), m.len(), t))
                        })
                        .collect()
                })
                .unwrap_or_default();
            entries.sort();
            for (n, len, t) in entries {
                h.update(format!("{n}\0{len}\0{t}\n").as_bytes());
            }
        } else if let Ok(mut f) = std::fs::File::open(&p) {
            let _ = std::io::copy(&mut f, &mut h);
        }
    }
    h.finalize().iter().map(|b| format!("{b:02x}")).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn digest_follows_named_files_and_bundles() {
        let d = std::env::temp_dir().join(format!("input-digest-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(d.join("bundle")).unwrap();
        std::fs::write(d.join("phase.cdf"), "a").unwrap();
        std::fs::write(d.join("bundle/manifest.toml"), "x = 1").unwrap();
        let exp = d.join("exp.toml");
        let text =
            "a = { file = \"phase.cdf\" }\n[scene]\npath = \"bundle\"\nid = \"not a file\"\n";
        assert_eq!(
            named_inputs(text, &exp),
            vec![d.join("phase.cdf"), d.join("bundle")]
        );
        let d0 = digest(text, &exp);
        assert_eq!(d0, digest(text, &exp));
        std::fs::write(d.join("bundle/manifest.toml"), "x = 2").unwrap();
        let d1 = digest(text, &exp);
        assert_ne!(d0, d1);
        std::fs::write(d.join("phase.cdf"), "b").unwrap();
        assert_ne!(d1, digest(text, &exp));
        std::fs::remove_dir_all(&d).unwrap();
    }
}
