//! A process-wide cache of parsed input files (correlated-k databases, aerosol datasets), so
//! that experiments resolved one after another in one process — the acquisitions of a PICS
//! sweep (`simulate pics`, the Python package), repeated Python runs — read and parse each file
//! once. An entry is keyed by the parsed type, the file's canonical path, a caller's key (e.g.
//! a size index), and the file's length and modification time: a replaced file is read again.
//! The cache keeps the last [`CAPACITY`] entries.

use std::any::{Any, TypeId};
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};
use std::time::SystemTime;

/// Entries kept (the oldest is dropped first).
pub const CAPACITY: usize = 16;

#[derive(Clone, PartialEq)]
struct Key {
    ty: TypeId,
    path: PathBuf,
    extra: String,
    len: u64,
    modified: Option<SystemTime>,
}

type Entry = (Key, Arc<dyn Any + Send + Sync>);

static CACHE: Mutex<Vec<Entry>> = Mutex::new(Vec::new());

fn key<T: 'static>(path: &Path, extra: &str) -> Option<Key> {
    let meta = std::fs::metadata(path).ok()?;
    Some(Key {
        ty: TypeId::of::<T>(),
        path: std::fs::canonicalize(path).ok()?,
        extra: extra.to_string(),
        len: meta.len(),
        modified: meta.modified().ok(),
    })
}

/// The parsed `path` (`load` runs on a miss; its errors are returned and not cached). A file
/// whose metadata cannot be read is loaded without caching (`load` reports the error).
pub fn cached<T, E>(
    path: &Path,
    extra: &str,
    load: impl FnOnce() -> Result<T, E>,
) -> Result<Arc<T>, E>
where
    T: Send + Sync + 'static,
{
    let Some(k) = key::<T>(path, extra) else {
        return load().map(Arc::new);
    };
    let hit = {
        let c = CACHE.lock().unwrap_or_else(|e| e.into_inner());
        c.iter()
            .find(|(ck, _)| *ck == k)
            .map(|(_, v)| Arc::clone(v))
    };
    if let Some(v) = hit.and_then(|v| v.downcast::<T>().ok()) {
        return Ok(v);
    }
    let v = Arc::new(load()?);
    let mut c = CACHE.lock().unwrap_or_else(|e| e.into_inner());
    c.retain(|(ck, _)| *ck != k);
    if c.len() >= CAPACITY {
        c.remove(0);
    }
    c.push((k, v.clone() as Arc<dyn Any + Send + Sync>));
    Ok(v)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn loads_once_and_again_after_a_change() {
        let dir = std::env::temp_dir().join(format!("file_cache_test_{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let f = dir.join("x.txt");
        std::fs::write(&f, "1").unwrap();
        let mut loads = 0;
        let read = |loads: &mut i32| {
            cached(&f, "", || {
                *loads += 1;
                std::fs::read_to_string(&f).map(|s| s.len())
            })
            .unwrap()
        };
        assert_eq!(*read(&mut loads), 1);
        assert_eq!(*read(&mut loads), 1);
        assert_eq!(loads, 1);
        std::fs::write(&f, "22").unwrap(); // another length: read again
        assert_eq!(*read(&mut loads), 2);
        assert_eq!(loads, 2);
        // errors are not cached
        let missing = dir.join("missing");
        let e: Result<Arc<u8>, &str> = cached(&missing, "", || Err("absent"));
        assert!(e.is_err());
        let _ = std::fs::remove_dir_all(&dir);
    }
}
