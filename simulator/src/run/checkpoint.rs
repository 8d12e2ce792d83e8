//! Checkpoints: after each work unit (`units.rs`) its sums are written to `DIR/wWWW_mMMM.json`
//! (a whole (wavelength, measure) task) or `DIR/wWWW_mMMM_tTTTTTofTTTTTT.json` (a pixel tile),
//! atomically, stamped with a hash of the experiment text, the simulator's build (its version
//! and a digest of its sources, [`crate::BUILD_ID`]: estimators can change while the version
//! does not) and every input file the experiment names (`input_digest.rs`: a rebuilt bundle,
//! a replaced phase table). A later run of the same experiment into the same folder reuses them, so an
//! interrupted run resumes where it stopped; any change to the experiment or its inputs
//! invalidates them. A whole task whose file is absent is assembled from a complete set of
//! tile files when the folder has one (the checkpoints of a run split into shards, collected
//! in one folder). Sums are written with enough digits to read back bit for bit
//! (`serde_json`'s `float_roundtrip`).
//!
//! **Integrity.** Each file carries `sums_digest`, FNV-1a 64 of its sums' bits (with the
//! experiment hash and the first cell), and its sums must satisfy the invariants of samples
//! (`Accum::check_invariants`: n·Σx² ≥ (Σx)², Σx² ≥ 0, finite values, lengths, replicates that
//! add up). A file of this run that fails either was edited or damaged: [`load`] refuses it,
//! naming the file (a resume, `simulate merge`), rather than resuming from it or silently
//! recomputing. Files of other runs are ignored as before.

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use super::units::Unit;
use super::{MeasureResult, Method};
use crate::error::OutputError;
use engine::config::resolve::Experiment;
use engine::integrator::Accum;

#[derive(Serialize, Deserialize)]
struct Stored {
    experiment_hash: String,
    version: String,
    measure: String,
    wavelength_nm: f64,
    method: String,
    /// First cell of a tile (0 for a whole task; absent in older files).
    #[serde(default)]
    first_cell: usize,
    /// FNV-1a 64 of the sums ([`sums_digest`]), in hex.
    #[serde(default)]
    sums_digest: String,
    acc: Accum,
}

/// FNV-1a 64 of the experiment hash, the first cell and every stored number of `acc` (their
/// bits, in a fixed order), in hex: a sum edited by hand no longer matches.
fn sums_digest(key: &str, first_cell: usize, acc: &Accum) -> String {
    let mut h = Fnv::new();
    let mut eat = |bytes: &[u8]| h.eat(bytes);
    eat(key.as_bytes());
    eat(&(first_cell as u64).to_le_bytes());
    eat(&(acc.ncomp as u64).to_le_bytes());
    for v in [&acc.n, &acc.rep_n] {
        eat(&(v.len() as u64).to_le_bytes());
        v.iter().for_each(|x| eat(&x.to_le_bytes()));
    }
    for v in [
        &acc.sum,
        &acc.sum2,
        &acc.cross,
        &acc.sum3,
        &acc.sum4,
        &acc.max,
        &acc.rep_sum,
        &acc.extra_mean,
        &acc.extra_var,
    ] {
        eat(&(v.len() as u64).to_le_bytes());
        v.iter().for_each(|x| eat(&x.to_bits().to_le_bytes()));
    }
    h.hex()
}

/// FNV-1a 64 of the experiment text, the simulator's build ([`crate::BUILD_ID`]: version and
/// source digest) and the digest of every input file the experiment names ([`crate::run::input_digest`]): identifies the run a checkpoint
/// belongs to. Computed once per run (it reads the inputs).
pub fn experiment_hash(exp: &Experiment) -> String {
    let inputs = crate::run::input_digest::digest(&exp.source_text, &exp.source_path);
    hash_of(&exp.source_text, crate::BUILD_ID, &inputs)
}

/// FNV-1a 64 of the experiment text, a build id and an input digest, in hex.
fn hash_of(text: &str, build: &str, inputs: &str) -> String {
    let mut h = Fnv::new();
    for part in [text, build, inputs] {
        h.eat(part.as_bytes());
    }
    h.hex()
}

/// FNV-1a 64, fed in pieces.
struct Fnv(u64);

impl Fnv {
    fn new() -> Self {
        Fnv(0xcbf2_9ce4_8422_2325)
    }
    fn eat(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.0 ^= b as u64;
            self.0 = self.0.wrapping_mul(0x0000_0100_0000_01b3);
        }
    }
    fn hex(&self) -> String {
        format!("{:016x}", self.0)
    }
}

/// The file of wavelength `iw` of unit `u` in `dir`.
pub fn path(dir: &Path, iw: usize, u: &Unit) -> PathBuf {
    if u.tiles == 1 {
        dir.join(format!("w{iw:03}_m{:03}.json", u.measure))
    } else {
        dir.join(format!(
            "w{iw:03}_m{:03}_t{:06}of{:06}.json",
            u.measure, u.tile, u.tiles
        ))
    }
}

/// Whether `name` is a file this module writes into a checkpoints folder: a unit's
/// `wIII_mMMM[_tTTTTTTofNNNNNN].json` ([`path`]) or the temporary `.NAME.PID.partial` of one
/// (`products::write_atomic`).
pub fn is_ours(name: &str) -> bool {
    let digits = |s: &str, n: usize| s.len() == n && s.bytes().all(|b| b.is_ascii_digit());
    let unit = |s: &str| -> bool {
        let Some(stem) = s.strip_suffix(".json") else {
            return false;
        };
        let (base, tile) = match stem.split_once("_t") {
            Some((b, t)) => (b, Some(t)),
            None => (stem, None),
        };
        let base_ok = base.len() == 9
            && base.starts_with('w')
            && digits(&base[1..4], 3)
            && &base[4..6] == "_m"
            && digits(&base[6..9], 3);
        let tile_ok = tile.is_none_or(|t| {
            t.len() == 14 && digits(&t[..6], 6) && &t[6..8] == "of" && digits(&t[8..], 6)
        });
        base_ok && tile_ok
    };
    if let Some(rest) = name
        .strip_prefix('.')
        .and_then(|r| r.strip_suffix(".partial"))
    {
        // `.NAME.PID.partial`
        return rest.rsplit_once('.').is_some_and(|(n, pid)| {
            !pid.is_empty() && pid.bytes().all(|b| b.is_ascii_digit()) && unit(n)
        });
    }
    unit(name)
}

/// Remove the checkpoints folder `dir` (after a complete run, or for `--fresh`): the files this
/// module wrote, then the folder if that leaves it empty. Anything else in it (a user's file)
/// stays, and is named in a warning; the number of files left is returned.
pub fn clear(dir: &Path) -> usize {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return 0;
    };
    let mut left = Vec::new();
    for e in entries.flatten() {
        let name = e.file_name().to_string_lossy().to_string();
        let file = e.file_type().is_ok_and(|t| t.is_file());
        if file && is_ours(&name) {
            if std::fs::remove_file(e.path()).is_err() {
                left.push(name);
            }
        } else {
            left.push(name);
        }
    }
    if left.is_empty() {
        let _ = std::fs::remove_dir(dir);
    } else {
        left.sort();
        tracing::warn!(
            "{}: left {} entr{} that simulate did not write: {}",
            dir.display(),
            left.len(),
            if left.len() == 1 { "y" } else { "ies" },
            left.join(", ")
        );
    }
    left.len()
}

/// A stored result of wavelength `iw` of unit `u`, if one exists and belongs to this
/// experiment; for a whole task, also from a complete set of tile files in `dir`. `Err` for a
/// file of this experiment whose sums fail their digest or the invariants of samples (module
/// header).
pub fn load(
    dir: &Path,
    exp: &Experiment,
    key: &str,
    iw: usize,
    u: &Unit,
) -> Result<Option<MeasureResult>, OutputError> {
    if let Some(r) = load_file(&path(dir, iw, u), exp, key, iw, u)? {
        return Ok(Some(r));
    }
    if u.tiles > 1 {
        return Ok(None);
    }
    load_tiles(dir, exp, key, iw, u.measure)
}

fn load_file(
    file: &Path,
    exp: &Experiment,
    key: &str,
    iw: usize,
    u: &Unit,
) -> Result<Option<MeasureResult>, OutputError> {
    let Ok(text) = std::fs::read_to_string(file) else {
        return Ok(None);
    };
    let Ok(s) = serde_json::from_str::<Stored>(&text) else {
        return Ok(None);
    };
    if s.experiment_hash == key {
        let bad = |problem: String| OutputError::Checkpoint {
            path: file.to_path_buf(),
            problem,
        };
        if s.sums_digest != sums_digest(key, s.first_cell, &s.acc) {
            return Err(bad("its sums do not match their digest".into()));
        }
        s.acc.check_invariants().map_err(bad)?;
    }
    let m = &exp.measures[u.measure];
    let method = match s.method.as_str() {
        "forward" => Method::Forward,
        "scene" => Method::Scene,
        _ => Method::Backward,
    };
    let cells = if method == Method::Forward {
        m.cell_count()
    } else {
        u.cells.len()
    };
    if s.experiment_hash != key
        || s.measure != m.id
        || s.acc.n.len() != cells
        || (method != Method::Forward && s.first_cell != u.cells.start)
    {
        return Ok(None);
    }
    Ok(Some(MeasureResult {
        measure: u.measure,
        wavelength: iw,
        method,
        acc: s.acc,
    }))
}

/// Measure `im` at wavelength `iw` from the tile files of one tiling found in `dir` (the
/// first tiling, by tile count, whose files are all present and valid).
fn load_tiles(
    dir: &Path,
    exp: &Experiment,
    key: &str,
    iw: usize,
    im: usize,
) -> Result<Option<MeasureResult>, OutputError> {
    let prefix = format!("w{iw:03}_m{im:03}_t");
    let Ok(entries) = std::fs::read_dir(dir) else {
        return Ok(None);
    };
    let mut counts: Vec<usize> = entries
        .flatten()
        .filter_map(|e| {
            let name = e.file_name().to_string_lossy().into_owned();
            let rest = name.strip_prefix(&prefix)?.strip_suffix(".json")?;
            rest.split_once("of")?.1.parse().ok()
        })
        .collect();
    counts.sort_unstable();
    counts.dedup();
    let cells = exp.measures[im].cell_count();
    for tiles in counts {
        let mut parts = Vec::with_capacity(tiles);
        for tile in 0..tiles {
            let u = Unit {
                group: vec![iw],
                measure: im,
                tile,
                tiles,
                cells: super::units::tile_cells(cells, tile, tiles),
            };
            match load_file(&path(dir, iw, &u), exp, key, iw, &u)? {
                Some(r) => parts.push((u.cells, r)),
                None => break,
            }
        }
        if parts.len() == tiles {
            if let Some(r) = super::units::assemble(exp, parts) {
                return Ok(Some(r));
            }
        }
    }
    Ok(None)
}

/// Store wavelength `r.wavelength` of unit `u` in `dir` (atomically).
pub fn store(
    dir: &Path,
    exp: &Experiment,
    key: &str,
    u: &Unit,
    r: &MeasureResult,
) -> Result<(), OutputError> {
    std::fs::create_dir_all(dir).map_err(|source| OutputError::Io {
        path: dir.to_path_buf(),
        source,
    })?;
    let first_cell = if r.method == Method::Forward {
        0
    } else {
        u.cells.start
    };
    let s = Stored {
        experiment_hash: key.to_string(),
        version: crate::BUILD_ID.into(),
        measure: exp.measures[r.measure].id.clone(),
        wavelength_nm: exp.wavelengths[r.wavelength],
        method: r.method.name().into(),
        first_cell,
        sums_digest: sums_digest(key, first_cell, &r.acc),
        acc: r.acc.clone(),
    };
    let text = serde_json::to_string(&s).expect("checkpoint serialises");
    crate::products::write_atomic(&path(dir, r.wavelength, u), text.as_bytes())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Rationale: clearing a checkpoints folder removes only what simulate wrote there (unit
    /// files and their temporaries); a user's file and folder stay, and so does the folder.
    #[test]
    fn clear_removes_only_our_files() {
        for name in [
            "w000_m000.json",
            "w012_m003_t000004of000010.json",
            ".w000_m001.json.4242.partial",
        ] {
            assert!(is_ours(name), "{name}");
        }
        for name in [
            "thesis.txt",
            "w000_m000.json.bak",
            "w0_m0.json",
            "w000_m000_t4of10.json",
            ".w000_m001.json.partial",
            ".thesis.txt.42.partial",
            "W000_M000.json",
        ] {
            assert!(!is_ours(name), "{name}");
        }
        let dir = std::env::temp_dir().join(format!("ckpt-clear-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(dir.join("photos")).unwrap();
        for f in ["w000_m000.json", ".w001_m000.json.7.partial", "thesis.txt"] {
            std::fs::write(dir.join(f), "x").unwrap();
        }
        assert_eq!(clear(&dir), 2);
        assert!(dir.join("thesis.txt").exists() && dir.join("photos").is_dir());
        assert!(!dir.join("w000_m000.json").exists());
        assert!(!dir.join(".w001_m000.json.7.partial").exists());
        std::fs::remove_dir_all(dir.join("photos")).unwrap();
        std::fs::remove_file(dir.join("thesis.txt")).unwrap();
        std::fs::write(dir.join("w000_m000.json"), "x").unwrap();
        assert_eq!(clear(&dir), 0);
        assert!(!dir.exists(), "an emptied folder is removed");
    }

    /// The build id is the crate version and a source digest, and it is part of the key: two
    /// builds of the same version whose sources differ never share checkpoints.
    #[test]
    fn build_id_keys_checkpoints() {
        let (version, digest) = crate::BUILD_ID
            .split_once("+src.")
            .expect("version+src.digest");
        assert_eq!(version, env!("CARGO_PKG_VERSION"));
        assert_eq!(digest.len(), 16);
        assert!(digest.chars().all(|c| c.is_ascii_hexdigit()));
        let a = hash_of("seed = 1", "0.1.0+src.0000000000000001", "inputs");
        let b = hash_of("seed = 1", "0.1.0+src.0000000000000002", "inputs");
        assert_ne!(a, b);
        assert_eq!(
            a,
            hash_of("seed = 1", "0.1.0+src.0000000000000001", "inputs")
        );
        assert_ne!(
            a,
            hash_of("seed = 2", "0.1.0+src.0000000000000001", "inputs")
        );
    }
}
