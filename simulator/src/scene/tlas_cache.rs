//! A disk cache of the instances' top-level tree, so that a scene rendered again (the same
//! bundle, another experiment, the next Python call or cluster shard) skips the binned-SAH
//! build and obvhs' conversion: about 1.7 of the 2.1 s that the Grenoble bundle's 1.27 M
//! instances take to build on 2 cores (BENCHMARKS.md).
//!
//! **Key.** The tree is a function of its input boxes (the instances' padded f32 boxes, in
//! input order) and of the code that builds it. A file is keyed by a 128-bit hash of every
//! box's bits and of [`crate::BUILD_ID`] (version and source digest), so a cached tree is used
//! only for exactly the boxes it was built from, by the build that built it: the tree, and so
//! every image, is bit-identical with and without the cache (`tests`).
//!
//! **Where.** `$EOSIM_CACHE_DIR/tlas` if that variable is set (`off` or empty: no cache),
//! else `$XDG_CACHE_HOME/eosim/tlas`, else `$HOME/.cache/eosim/tlas`. Only trees over at least
//! [`MIN_INSTANCES`] instances are cached; the [`KEEP`] most recently used files are kept.
//!
//! **Safety.** A file is written whole to a temporary name and renamed (concurrent shards
//! building the same scene never read a partial file), and read back only if its magic
//! number, key, lengths and FNV-1a checksum of the payload all match; otherwise the tree is
//! built as without a cache. A cache that cannot be written (read-only home, full disk) costs
//! nothing but a debug message.
//!
//! File layout (little-endian): magic `EOSIMTL1`, key (16 B), node count, record count,
//! cluster-start count, depth (u64 each), the tree's box (6 × f32), the 80-byte CWBVH nodes,
//! the cluster starts and the slot → instance order (u32), then the payload's checksum (u64).

use std::path::{Path, PathBuf};

use obvhs::aabb::Aabb;
use obvhs::cwbvh::node::CwBvhNode;
use obvhs::cwbvh::CwBvh;

/// Trees over fewer instances build in well under 0.1 s: not cached.
pub(crate) const MIN_INSTANCES: usize = 100_000;
/// Cache files kept (least recently used removed first).
pub(crate) const KEEP: usize = 8;

const MAGIC: &[u8; 8] = b"EOSIMTL1";
const HEADER: usize = 8 + 16 + 4 * 8 + 6 * 4;

/// What is cached: the tree and its record layout (`instances.rs`' `Tlas`).
#[derive(Debug, PartialEq)]
pub(crate) struct Cached {
    pub nodes: Vec<CwBvhNode>,
    pub total_aabb: Aabb,
    pub cluster_start: Vec<u32>,
    pub order: Vec<u32>,
    pub depth: usize,
}

impl Cached {
    /// The tree as built (`instances.rs` keeps no primitive indices: the clusters are the
    /// slots).
    pub fn tree(nodes: Vec<CwBvhNode>, total_aabb: Aabb) -> CwBvh {
        CwBvh {
            nodes,
            total_aabb,
            ..Default::default()
        }
    }
}

/// What [`store`] writes, borrowed from a built tree.
pub(crate) struct View<'a> {
    pub nodes: &'a [CwBvhNode],
    pub total_aabb: Aabb,
    pub cluster_start: &'a [u32],
    pub order: &'a [u32],
    pub depth: usize,
}

/// The cache folder (module header), `None` when turned off or no home is known.
pub(crate) fn dir() -> Option<PathBuf> {
    if let Some(v) = std::env::var_os("EOSIM_CACHE_DIR") {
        if v.is_empty() || v == "off" {
            return None;
        }
        return Some(PathBuf::from(v).join("tlas"));
    }
    let base = std::env::var_os("XDG_CACHE_HOME")
        .filter(|v| !v.is_empty())
        .map(PathBuf::from)
        .or_else(|| std::env::var_os("HOME").map(|h| PathBuf::from(h).join(".cache")))?;
    Some(base.join("eosim").join("tlas"))
}

/// 128-bit key of the boxes and this build: two FNV-1a-64 streams with different offsets,
/// fed 32-bit words.
pub(crate) fn key(boxes: &[Aabb]) -> [u8; 16] {
    let mut a: u64 = 0xcbf2_9ce4_8422_2325;
    let mut b: u64 = 0x6c62_272e_07bb_0142;
    let mut eat = |x: u32| {
        a = (a ^ x as u64).wrapping_mul(0x0000_0100_0000_01b3);
        b = (b ^ (x as u64).rotate_left(17)).wrapping_mul(0x0000_0100_0000_0193 | 1 << 40);
    };
    for byte in crate::BUILD_ID.bytes() {
        eat(byte as u32);
    }
    eat(boxes.len() as u32);
    for x in boxes {
        for v in [x.min, x.max] {
            eat(v.x.to_bits());
            eat(v.y.to_bits());
            eat(v.z.to_bits());
        }
    }
    let mut k = [0u8; 16];
    k[..8].copy_from_slice(&a.to_le_bytes());
    k[8..].copy_from_slice(&b.to_le_bytes());
    k
}

fn file(dir: &Path, key: &[u8; 16]) -> PathBuf {
    let hex: String = key.iter().map(|b| format!("{b:02x}")).collect();
    dir.join(format!("tlas-{hex}.bin"))
}

fn fnv(bytes: &[u8]) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    // Eight bytes at a time (the payload is 80-byte nodes and u32s: a multiple of 4).
    let mut chunks = bytes.chunks_exact(8);
    for c in &mut chunks {
        h = (h ^ u64::from_le_bytes(c.try_into().expect("8 bytes")))
            .wrapping_mul(0x0000_0100_0000_01b3);
    }
    for &b in chunks.remainder() {
        h = (h ^ b as u64).wrapping_mul(0x0000_0100_0000_01b3);
    }
    h
}

/// The cached tree of `key` in `dir`, if a valid one is there (touched, so that it counts as
/// recently used).
pub(crate) fn load(dir: &Path, key: &[u8; 16]) -> Option<Cached> {
    let path = file(dir, key);
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
    let (n_nodes, n_order, n_starts, depth) = (
        u64_at(24) as usize,
        u64_at(32) as usize,
        u64_at(40) as usize,
        u64_at(48) as usize,
    );
    let node = std::mem::size_of::<CwBvhNode>();
    let payload = n_nodes
        .checked_mul(node)?
        .checked_add(4 * (n_order + n_starts))?;
    if bytes.len() != HEADER.checked_add(payload)?.checked_add(8)? {
        return None;
    }
    let body = &bytes[HEADER..HEADER + payload];
    if fnv(body) != u64_at(HEADER + payload) {
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
    let cluster_start = words(n_nodes * node, n_starts);
    let order = words(n_nodes * node + 4 * n_starts, n_order);
    // The layout the renderer relies on: cluster starts rising from 0 to the record count.
    if cluster_start.first() != Some(&0)
        || cluster_start.last() != Some(&(n_order as u32))
        || cluster_start.windows(2).any(|w| w[0] > w[1])
    {
        return None;
    }
    Some(Cached {
        nodes,
        total_aabb,
        cluster_start,
        order,
        depth,
    })
}

/// Store `c` under `key` in `dir` (atomically), then keep only the [`KEEP`] most recently
/// used files. Errors are returned for the caller to log; they never stop a run.
pub(crate) fn store(dir: &Path, key: &[u8; 16], c: &View) -> Result<(), String> {
    std::fs::create_dir_all(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    let node_bytes: &[u8] = bytemuck::cast_slice(c.nodes);
    let mut body =
        Vec::with_capacity(node_bytes.len() + 4 * (c.order.len() + c.cluster_start.len()));
    body.extend_from_slice(node_bytes);
    for &x in c.cluster_start.iter().chain(c.order) {
        body.extend_from_slice(&x.to_le_bytes());
    }
    let mut out = Vec::with_capacity(HEADER + body.len() + 8);
    out.extend_from_slice(MAGIC);
    out.extend_from_slice(key);
    for n in [c.nodes.len(), c.order.len(), c.cluster_start.len(), c.depth] {
        out.extend_from_slice(&(n as u64).to_le_bytes());
    }
    let (lo, hi) = (c.total_aabb.min, c.total_aabb.max);
    for v in [lo.x, lo.y, lo.z, hi.x, hi.y, hi.z] {
        out.extend_from_slice(&v.to_le_bytes());
    }
    out.extend_from_slice(&body);
    out.extend_from_slice(&fnv(&body).to_le_bytes());
    let path = file(dir, key);
    crate::products::write_atomic(&path, &out).map_err(|e| e.to_string())?;
    prune(dir);
    Ok(())
}

/// Remove all but the [`KEEP`] most recently modified cache files.
fn prune(dir: &Path) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    let mut files: Vec<(std::time::SystemTime, PathBuf)> = entries
        .flatten()
        .filter(|e| {
            let name = e.file_name();
            let name = name.to_string_lossy();
            name.starts_with("tlas-") && name.ends_with(".bin")
        })
        .filter_map(|e| Some((e.metadata().ok()?.modified().ok()?, e.path())))
        .collect();
    files.sort_by_key(|f| std::cmp::Reverse(f.0));
    for (_, p) in files.into_iter().skip(KEEP) {
        let _ = std::fs::remove_file(p);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn view(c: &Cached) -> View<'_> {
        View {
            nodes: &c.nodes,
            total_aabb: c.total_aabb,
            cluster_start: &c.cluster_start,
            order: &c.order,
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
            cluster_start: vec![0, 2, 5],
            order: vec![4, 0, 3, 1, 2],
            depth: 2,
        }
    }

    /// A stored tree reads back equal; another key, a flipped byte or a cut file read as no
    /// tree; the key depends on every box bit; only the most recent files are kept.
    #[test]
    fn round_trip_and_rejections() {
        let dir = std::env::temp_dir().join(format!("eosim-tlas-cache-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        let boxes = vec![Aabb::new(glam::Vec3A::ZERO, glam::Vec3A::ONE); 4];
        let k = key(&boxes);
        let mut other = boxes.clone();
        other[3].max.z = f32::from_bits(1.0f32.to_bits() + 1);
        assert_ne!(k, key(&other));
        assert_eq!(k, key(&boxes.clone()));
        let c = sample();
        store(&dir, &k, &view(&c)).unwrap();
        assert_eq!(load(&dir, &k), Some(sample()));
        assert_eq!(load(&dir, &key(&other)), None);
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
        // Pruning keeps KEEP files.
        for i in 0..KEEP as u32 + 3 {
            let b = vec![Aabb::new(
                glam::Vec3A::ZERO,
                glam::Vec3A::splat(i as f32 + 2.0),
            )];
            store(&dir, &key(&b), &view(&c)).unwrap();
        }
        let n = std::fs::read_dir(&dir)
            .unwrap()
            .flatten()
            .filter(|e| e.file_name().to_string_lossy().starts_with("tlas-"))
            .count();
        assert_eq!(n, KEEP);
        let _ = std::fs::remove_dir_all(&dir);
    }
}
