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
    acc: Accum,
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
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for b in text.bytes().chain(build.bytes()).chain(inputs.bytes()) {
        h ^= b as u64;
        h = h.wrapping_mul(0x0000_0100_0000_01b3);
    }
    format!("{h:016x}")
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

/// A stored result of wavelength `iw` of unit `u`, if one exists and belongs to this
/// experiment; for a whole task, also from a complete set of tile files in `dir`.
pub fn load(dir: &Path, exp: &Experiment, key: &str, iw: usize, u: &Unit) -> Option<MeasureResult> {
    if let Some(r) = load_file(&path(dir, iw, u), exp, key, iw, u) {
        return Some(r);
    }
    if u.tiles > 1 {
        return None;
    }
    load_tiles(dir, exp, key, iw, u.measure)
}

fn load_file(
    file: &Path,
    exp: &Experiment,
    key: &str,
    iw: usize,
    u: &Unit,
) -> Option<MeasureResult> {
    let text = std::fs::read_to_string(file).ok()?;
    let s: Stored = serde_json::from_str(&text).ok()?;
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
        return None;
    }
    Some(MeasureResult {
        measure: u.measure,
        wavelength: iw,
        method,
        acc: s.acc,
    })
}

/// Measure `im` at wavelength `iw` from the tile files of one tiling found in `dir` (the
/// first tiling, by tile count, whose files are all present and valid).
fn load_tiles(
    dir: &Path,
    exp: &Experiment,
    key: &str,
    iw: usize,
    im: usize,
) -> Option<MeasureResult> {
    let prefix = format!("w{iw:03}_m{im:03}_t");
    let mut counts: Vec<usize> = std::fs::read_dir(dir)
        .ok()?
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
    counts.into_iter().find_map(|tiles| {
        let parts = (0..tiles)
            .map(|tile| {
                let u = Unit {
                    group: vec![iw],
                    measure: im,
                    tile,
                    tiles,
                    cells: super::units::tile_cells(cells, tile, tiles),
                };
                let r = load_file(&path(dir, iw, &u), exp, key, iw, &u)?;
                Some((u.cells, r))
            })
            .collect::<Option<Vec<_>>>()?;
        super::units::assemble(exp, parts)
    })
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
    let s = Stored {
        experiment_hash: key.to_string(),
        version: crate::BUILD_ID.into(),
        measure: exp.measures[r.measure].id.clone(),
        wavelength_nm: exp.wavelengths[r.wavelength],
        method: r.method.name().into(),
        first_cell: if r.method == Method::Forward {
            0
        } else {
            u.cells.start
        },
        acc: r.acc.clone(),
    };
    let text = serde_json::to_string(&s).expect("checkpoint serialises");
    crate::products::write_atomic(&path(dir, r.wavelength, u), text.as_bytes())
}

#[cfg(test)]
mod tests {
    use super::*;

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
