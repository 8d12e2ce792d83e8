//! A disk cache of the scene's large BVHs (the instances' top level and the terrain's tree),
//! so that a scene rendered again (the same bundle, another experiment, the next Python call
//! or cluster shard) skips their builds: the binned-SAH build and obvhs' conversion of the
//! instances' top level, obvhs' PLOC build of the terrain (BENCHMARKS.md).
//!
//! **Key.** A tree is a function of its input boxes (padded f32 boxes, in input order) and of
//! the code that builds it. A file is keyed by 128 bits of a SHA-256 over its [`Kind`], every
//! box's bits, the node size and [`crate::BUILD_ID`] (version, source and data digest, and
//! the dependency versions of `Cargo.lock`, obvhs' included), so a cached tree is used only
//! for exactly the boxes it was built from, by the build that built it: the tree, and so every
//! image, is bit-identical with and without the cache (`tests`).
//!
//! **Where.** `$EOSIM_CACHE_DIR/bvh` if that variable is set (`off` or empty: no cache), else
//! `$XDG_CACHE_HOME/eosim/bvh`, else `$HOME/.cache/eosim/bvh`. Only trees over at least
//! [`MIN_PRIMITIVES`] boxes are cached; the [`KEEP`] most recently used files are kept, within
//! [`KEEP_BYTES`] (1 GiB) in all.
//!
//! **Safety.** A file is written whole to a temporary name of its own (process and call) and
//! renamed (concurrent shards or threads building the same scene never read a partial file;
//! temporaries left by a killed process are removed after an hour), and read back only if its
//! magic number, key, lengths and checksum (SHA-256) of the payload all match and the caller
//! finds its index lists a valid layout; otherwise the tree is built as without a cache. A cache that cannot be written (read-only home, full disk) costs
//! nothing but a debug message.
//!
//! File layout (native byte order, little-endian on every supported machine): magic `EOSIMBV1`, key (16 B), node count, lengths of the two
//! index lists, depth (u64 each), the tree's box (6 × f32), the 80-byte CWBVH nodes, the two
//! index lists (u32; the top level's cluster starts and slot → instance order, the terrain's
//! slot → triangle order and nothing), then the payload's checksum (8 bytes of its SHA-256).

use std::path::{Path, PathBuf};

use obvhs::aabb::Aabb;
use obvhs::cwbvh::node::CwBvhNode;
use obvhs::cwbvh::CwBvh;

use super::error::SceneError;

/// Trees over fewer boxes build in about 0.1 s or less: not cached.
pub(crate) const MIN_PRIMITIVES: usize = 50_000;
/// Cache files kept (least recently used removed first), and the most bytes they may hold
/// together (the most recent file is always kept).
pub(crate) const KEEP: usize = 8;
pub(crate) const KEEP_BYTES: u64 = 1 << 30;

const MAGIC: &[u8; 8] = b"EOSIMBV1";

/// Which tree a file holds (part of its key and name).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Kind {
    /// The instances' top level (`instances.rs`): lists = cluster starts, slot order.
    Instances,
    /// The terrain's tree (`terrain.rs`): lists = slot → triangle order, nothing.
    Terrain,
}

impl Kind {
    fn name(self) -> &'static str {
        match self {
            Kind::Instances => "instances",
            Kind::Terrain => "terrain",
        }
    }
}
const HEADER: usize = 8 + 16 + 4 * 8 + 6 * 4;

/// What is cached: the tree (no primitive indices) and two index lists ([`Kind`]).
#[derive(Debug, PartialEq)]
pub(crate) struct Cached {
    pub nodes: Vec<CwBvhNode>,
    pub total_aabb: Aabb,
    pub first: Vec<u32>,
    pub second: Vec<u32>,
    pub depth: usize,
}

impl Cached {
    /// The tree with the given primitive indices.
    pub fn tree(nodes: Vec<CwBvhNode>, total_aabb: Aabb, primitive_indices: Vec<u32>) -> CwBvh {
        CwBvh {
            nodes,
            total_aabb,
            primitive_indices,
            ..Default::default()
        }
    }
}

/// What [`store`] writes, borrowed from a built tree.
pub(crate) struct View<'a> {
    pub nodes: &'a [CwBvhNode],
    pub total_aabb: Aabb,
    pub first: &'a [u32],
    pub second: &'a [u32],
    pub depth: usize,
}

/// The cache folder (module header), `None` when turned off or no home is known.
pub(crate) fn dir() -> Option<PathBuf> {
    if let Some(v) = std::env::var_os("EOSIM_CACHE_DIR") {
        if v.is_empty() || v == "off" {
            return None;
        }
        return Some(PathBuf::from(v).join("bvh"));
    }
    let base = std::env::var_os("XDG_CACHE_HOME")
        .filter(|v| !v.is_empty())
        .map(PathBuf::from)
        .or_else(|| std::env::var_os("HOME").map(|h| PathBuf::from(h).join(".cache")))?;
    Some(base.join("eosim").join("bvh"))
}

/// 128-bit key of the kind, the boxes and this build: the first half of a SHA-256 over the
/// build id (which covers the dependency versions, obvhs' included), the node size, the kind
/// and every box's bits.
pub(crate) fn key(kind: Kind, boxes: &[Aabb]) -> [u8; 16] {
    use sha2::{Digest, Sha256};
    let mut h = Sha256::new();
    h.update(crate::BUILD_ID.as_bytes());
    h.update((std::mem::size_of::<CwBvhNode>() as u64).to_le_bytes());
    h.update(kind.name().as_bytes());
    h.update((boxes.len() as u64).to_le_bytes());
    // In chunks, so the boxes' bits are fed without a copy of them all.
    let mut buf = Vec::with_capacity(24 * 4096);
    for chunk in boxes.chunks(4096) {
        buf.clear();
        for x in chunk {
            for v in [x.min, x.max] {
                for c in [v.x, v.y, v.z] {
                    buf.extend_from_slice(&c.to_bits().to_le_bytes());
                }
            }
        }
        h.update(&buf);
    }
    let d = h.finalize();
    let mut k = [0u8; 16];
    k.copy_from_slice(&d[..16]);
    k
}

fn file(dir: &Path, key: &[u8; 16]) -> PathBuf {
    let hex: String = key.iter().map(|b| format!("{b:02x}")).collect();
    dir.join(format!("bvh-{hex}.bin"))
}

/// The payload's checksum: the first 8 bytes of its SHA-256.
fn checksum(bytes: &[u8]) -> u64 {
    use sha2::{Digest, Sha256};
    let d = Sha256::digest(bytes);
    u64::from_le_bytes(d[..8].try_into().expect("8 bytes"))
}

/// The cached tree of `key` in `dir`, if a valid one is there (touched, so that it counts as
/// recently used).
pub(crate) fn load(dir: &Path, key: &[u8; 16]) -> Option<Cached> {
    let path = file(dir, key);
    // Only a regular file is opened: a FIFO (or device) in its place would block the read.
    if !std::fs::metadata(&path).is_ok_and(|m| m.is_file()) {
        if path.exists() {
            tracing::debug!("{}: not a regular file, ignored", path.display());
        }
        return None;
    }
    let bytes = std::fs::read(&path).ok()?;
    let parsed = parse(&bytes, key);
    match &parsed {
        Some(_) => {
            // Mark it used (its modification time orders the pruning).
            let _ = std::fs::File::options()
                .append(true)
                .open(&path)
                .and_then(|f| f.set_modified(std::time::SystemTime::now()));
        }
        None => tracing::debug!("{}: not a valid cached tree, rebuilt", path.display()),
    }
    parsed
}

fn parse(bytes: &[u8], key: &[u8; 16]) -> Option<Cached> {
    if bytes.len() < HEADER + 8 || &bytes[..8] != MAGIC || &bytes[8..24] != key {
        return None;
    }
    let u64_at = |o: usize| u64::from_le_bytes(bytes[o..o + 8].try_into().expect("8 bytes"));
    let f32_at = |o: usize| f32::from_le_bytes(bytes[o..o + 4].try_into().expect("4 bytes"));
    let (n_nodes, n_first, n_second, depth) = (
        u64_at(24) as usize,
        u64_at(32) as usize,
        u64_at(40) as usize,
        u64_at(48) as usize,
    );
    let node = std::mem::size_of::<CwBvhNode>();
    let payload = n_nodes
        .checked_mul(node)?
        .checked_add(n_first.checked_add(n_second)?.checked_mul(4)?)?;
    if bytes.len() != HEADER.checked_add(payload)?.checked_add(8)? {
        return None;
    }
    let body = &bytes[HEADER..HEADER + payload];
    if checksum(body) != u64_at(HEADER + payload) {
        return None;
    }
    let b = |i: usize| f32_at(56 + 4 * i);
    let total_aabb = Aabb::new(
        glam::Vec3A::new(b(0), b(1), b(2)),
        glam::Vec3A::new(b(3), b(4), b(5)),
    );
    let mut nodes = vec![CwBvhNode::default(); n_nodes];
    bytemuck::cast_slice_mut::<CwBvhNode, u8>(&mut nodes).copy_from_slice(&body[..n_nodes * node]);
    let words = |from: usize, n: usize| -> Vec<u32> {
        body[from..from + 4 * n]
            .chunks_exact(4)
            .map(|c| u32::from_le_bytes(c.try_into().expect("4 bytes")))
            .collect()
    };
    Some(Cached {
        nodes,
        total_aabb,
        first: words(n_nodes * node, n_first),
        second: words(n_nodes * node + 4 * n_first, n_second),
        depth,
    })
}

/// Store `c` under `key` in `dir` (atomically), then keep only the [`KEEP`] most recently
/// used files. Errors are returned for the caller to log; they never stop a run.
pub(crate) fn store(dir: &Path, key: &[u8; 16], c: &View) -> Result<(), SceneError> {
    std::fs::create_dir_all(dir).map_err(|source| SceneError::Cache {
        path: dir.to_path_buf(),
        source,
    })?;
    let node_bytes: &[u8] = bytemuck::cast_slice(c.nodes);
    let mut body = Vec::with_capacity(node_bytes.len() + 4 * (c.first.len() + c.second.len()));
    body.extend_from_slice(node_bytes);
    for &x in c.first.iter().chain(c.second) {
        body.extend_from_slice(&x.to_le_bytes());
    }
    let mut out = Vec::with_capacity(HEADER + body.len() + 8);
    out.extend_from_slice(MAGIC);
    out.extend_from_slice(key);
    for n in [c.nodes.len(), c.first.len(), c.second.len(), c.depth] {
        out.extend_from_slice(&(n as u64).to_le_bytes());
    }
    let (lo, hi) = (c.total_aabb.min, c.total_aabb.max);
    for v in [lo.x, lo.y, lo.z, hi.x, hi.y, hi.z] {
        out.extend_from_slice(&v.to_le_bytes());
    }
    out.extend_from_slice(&body);
    out.extend_from_slice(&checksum(&body).to_le_bytes());
    // A temporary name of this process and call (threads of one process may store the same
    // tree at once), renamed into place.
    static CALLS: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
    let path = file(dir, key);
    let call = CALLS.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    let name = path.file_name().map(|n| n.to_string_lossy().to_string());
    // Process, call and clock: unique across the hosts of a cluster sharing the folder too.
    let nanos = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.subsec_nanos());
    let tmp = path.with_file_name(format!(
        ".{}.{}.{call}.{nanos}.partial",
        name.unwrap_or_default(),
        std::process::id()
    ));
    let written = std::fs::write(&tmp, &out).and_then(|()| std::fs::rename(&tmp, &path));
    if let Err(e) = written {
        let _ = std::fs::remove_file(&tmp);
        return Err(SceneError::Cache { path, source: e });
    }
    prune(dir);
    Ok(())
}

/// Remove all but the [`KEEP`] most recently modified cache files, and temporaries over an
/// hour old (left by a process killed while writing).
fn prune(dir: &Path) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    let now = std::time::SystemTime::now();
    let mut files: Vec<(std::time::SystemTime, u64, PathBuf)> = Vec::new();
    for e in entries.flatten() {
        let name = e.file_name().to_string_lossy().to_string();
        let Some((modified, len)) = e
            .metadata()
            .ok()
            .and_then(|m| Some((m.modified().ok()?, m.len())))
        else {
            continue;
        };
        if name.starts_with("bvh-") && name.ends_with(".bin") {
            files.push((modified, len, e.path()));
        } else if name.starts_with(".bvh-")
            && name.ends_with(".partial")
            && now
                .duration_since(modified)
                .is_ok_and(|age| age.as_secs() > 3600)
        {
            let _ = std::fs::remove_file(e.path());
        }
    }
    files.sort_by_key(|f| std::cmp::Reverse(f.0));
    let mut total = 0u64;
    for (k, (_, len, p)) in files.into_iter().enumerate() {
        total += len;
        if k >= KEEP || (k > 0 && total > KEEP_BYTES) {
            let _ = std::fs::remove_file(p);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn view(c: &Cached) -> View<'_> {
        View {
            nodes: &c.nodes,
            total_aabb: c.total_aabb,
            first: &c.first,
            second: &c.second,
            depth: c.depth,
        }
    }

    fn sample() -> Cached {
        let mut nodes = vec![CwBvhNode::default(); 3];
        nodes[1].child_base_idx = 7;
        nodes[2].p = glam::Vec3::new(1.5, -2.0, 3.25);
        nodes[2].child_meta = [1, 2, 3, 4, 5, 6, 7, 8];
        Cached {
            nodes,
            total_aabb: Aabb::new(
                glam::Vec3A::new(-1.0, -2.0, -3.0),
                glam::Vec3A::new(4.0, 5.0, 6.0),
            ),
            first: vec![0, 2, 5],
            second: vec![4, 0, 3, 1, 2],
            depth: 2,
        }
    }

    /// A stored tree reads back equal; another key, a flipped byte, a cut file or a FIFO read
    /// as no tree; the key depends on every box bit and the kind; only the most recent files are
    /// kept.
    #[test]
    fn round_trip_and_rejections() {
        let dir = std::env::temp_dir().join(format!("eosim-bvh-cache-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        let boxes = vec![Aabb::new(glam::Vec3A::ZERO, glam::Vec3A::ONE); 4];
        let k = key(Kind::Instances, &boxes);
        let mut other = boxes.clone();
        other[3].max.z = f32::from_bits(1.0f32.to_bits() + 1);
        assert_ne!(k, key(Kind::Instances, &other));
        assert_ne!(k, key(Kind::Terrain, &boxes));
        assert_eq!(k, key(Kind::Instances, &boxes.clone()));
        let c = sample();
        store(&dir, &k, &view(&c)).unwrap();
        assert_eq!(load(&dir, &k), Some(sample()));
        assert_eq!(load(&dir, &key(Kind::Instances, &other)), None);
        let path = file(&dir, &k);
        let good = std::fs::read(&path).unwrap();
        for at in [3, 20, 30, HEADER + 5, good.len() - 2] {
            let mut bad = good.clone();
            bad[at] ^= 0x10;
            std::fs::write(&path, &bad).unwrap();
            assert_eq!(load(&dir, &k), None, "byte {at} flipped");
        }
        std::fs::write(&path, &good[..good.len() - 9]).unwrap();
        assert_eq!(load(&dir, &k), None);
        // A FIFO in the file's place is passed over at once (issue 43: it blocked forever).
        std::fs::remove_file(&path).unwrap();
        let made = std::process::Command::new("mkfifo").arg(&path).status();
        if made.is_ok_and(|s| s.success()) {
            assert_eq!(load(&dir, &k), None);
            std::fs::remove_file(&path).unwrap();
        }
        // Pruning keeps KEEP files.
        for i in 0..KEEP as u32 + 3 {
            let b = vec![Aabb::new(
                glam::Vec3A::ZERO,
                glam::Vec3A::splat(i as f32 + 2.0),
            )];
            store(&dir, &key(Kind::Terrain, &b), &view(&c)).unwrap();
        }
        let n = std::fs::read_dir(&dir)
            .unwrap()
            .flatten()
            .filter(|e| e.file_name().to_string_lossy().starts_with("bvh-"))
            .count();
        assert_eq!(n, KEEP);
        let _ = std::fs::remove_dir_all(&dir);
    }
}
