//! All-or-nothing products. A run writes every product into `OUTPUT/.staging-PID/` and, only
//! when all of them are complete, moves them into `OUTPUT` (one `rename` each, on the same
//! filesystem) and records their names in `OUTPUT/.products`. Products of the previous run that
//! this run does not make again (an image measure removed from the experiment, a band table)
//! are deleted at the same moment, so the folder never mixes two runs. A failure before the
//! commit (a full disk, a GDAL or netCDF error) leaves the previous products untouched and the
//! staging folder removed. The output folder's lock (`output_lock.rs`) makes this the only
//! writer, so a leftover `.staging-*` folder is from a killed run and is removed.
//!
//! The moves themselves are not one atomic step: while they run, `OUTPUT/.products-incomplete`
//! lists the new products, and it is removed only after the last move and deletion. A kill in
//! between leaves it, so a reader (or the next run, which warns and replaces the set) can tell
//! a complete product set from a mixed one.

use std::path::{Path, PathBuf};

use crate::error::OutputError;

/// The list of the last committed run's products, one file name per line.
pub const PRODUCTS_LIST: &str = ".products";

/// Present only while a commit moves products into place: a folder holding it (after a kill
/// during those renames) has a mixed product set, the new products listed in it beside the
/// previous run's others. The next commit into the folder replaces the set and removes it.
pub const INCOMPLETE_MARKER: &str = ".products-incomplete";

/// Products being written; see the module doc.
pub struct Staging {
    out: PathBuf,
    dir: PathBuf,
    names: Vec<String>,
    committed: bool,
}

fn io(path: &Path) -> impl FnOnce(std::io::Error) -> OutputError + '_ {
    move |source| OutputError::Io {
        path: path.to_path_buf(),
        source,
    }
}

impl Staging {
    /// Create `out/.staging-PID/`, removing staging folders of killed runs.
    pub fn new(out: &Path) -> Result<Staging, OutputError> {
        if let Ok(rd) = std::fs::read_dir(out) {
            for e in rd.flatten() {
                if e.file_name().to_string_lossy().starts_with(".staging-") {
                    let _ = std::fs::remove_dir_all(e.path());
                }
            }
        }
        let marker = out.join(INCOMPLETE_MARKER);
        if marker.is_file() {
            tracing::warn!(
                "{} holds a mixed product set: a previous run was stopped while moving its products into place ({} lists the new ones); this run replaces the set",
                out.display(),
                marker.display()
            );
        }
        let dir = out.join(format!(".staging-{}", std::process::id()));
        std::fs::create_dir_all(&dir).map_err(io(&dir))?;
        Ok(Staging {
            out: out.to_path_buf(),
            dir,
            names: Vec::new(),
            committed: false,
        })
    }

    /// The staging folder (writers that name their own files write here, then [`Self::add`]).
    pub fn dir(&self) -> &Path {
        &self.dir
    }

    /// Where to write the product `name` (a plain file name); records it.
    pub fn path(&mut self, name: &str) -> PathBuf {
        self.add(name);
        self.dir.join(name)
    }

    /// Record a product written into [`Self::dir`] under `name`.
    pub fn add(&mut self, name: &str) {
        if !self.names.iter().any(|n| n == name) {
            self.names.push(name.to_string());
        }
    }

    /// The final path of product `name`.
    pub fn final_path(&self, name: &str) -> PathBuf {
        self.out.join(name)
    }

    /// Move every product into the output folder, delete the previous run's products that
    /// were not made again, and record the new list. Returns the final paths.
    pub fn commit(mut self) -> Result<Vec<PathBuf>, OutputError> {
        // Every file in the staging folder is a product (writers may add side-cars such as
        // GDAL's `.aux.xml`); hidden names are temporaries of unfinished writes.
        let rd = std::fs::read_dir(&self.dir).map_err(io(&self.dir))?;
        for e in rd.flatten() {
            let n = e.file_name().to_string_lossy().into_owned();
            if !n.starts_with('.') && e.path().is_file() {
                self.add(&n);
            }
        }
        if let Some(n) = self.names.iter().find(|n| !self.dir.join(n).is_file()) {
            return Err(OutputError::Io {
                path: self.dir.join(n),
                source: std::io::Error::new(
                    std::io::ErrorKind::NotFound,
                    "a staged product is missing",
                ),
            });
        }
        let list = self.out.join(PRODUCTS_LIST);
        let old: Vec<String> = std::fs::read_to_string(&list)
            .map(|t| t.lines().map(str::to_string).collect())
            .unwrap_or_default();
        // The new list first (atomically): if the moves are interrupted, the next run's commit
        // still knows every file that may be a product.
        let mut all: Vec<String> = self.names.clone();
        all.extend(old.iter().filter(|o| !self.names.contains(o)).cloned());
        crate::products::write_atomic(&list, (all.join("\n") + "\n").as_bytes())?;
        // The marker says "mixed" until every move and deletion is done.
        let marker = self.out.join(INCOMPLETE_MARKER);
        crate::products::write_atomic(&marker, (self.names.join("\n") + "\n").as_bytes())?;
        for n in &self.names {
            let to = self.out.join(n);
            std::fs::rename(self.dir.join(n), &to).map_err(io(&to))?;
        }
        for o in old.iter().filter(|o| !self.names.contains(o)) {
            // Only plain names from our own list: never a path outside the folder.
            if !o.is_empty() && !o.contains('/') && !o.starts_with('.') {
                let _ = std::fs::remove_file(self.out.join(o));
            }
        }
        crate::products::write_atomic(&list, (self.names.join("\n") + "\n").as_bytes())?;
        std::fs::remove_file(&marker).map_err(io(&marker))?;
        let _ = std::fs::remove_dir_all(&self.dir);
        self.committed = true;
        Ok(self.names.iter().map(|n| self.out.join(n)).collect())
    }
}

impl Drop for Staging {
    fn drop(&mut self) {
        if !self.committed {
            let _ = std::fs::remove_dir_all(&self.dir);
        }
    }
}

/// Free bytes on the filesystem holding `path` (statvfs), if known.
pub fn free_bytes(path: &Path) -> Option<u64> {
    use std::os::unix::ffi::OsStrExt;
    let c = std::ffi::CString::new(path.as_os_str().as_bytes()).ok()?;
    let mut s: libc::statvfs = unsafe { std::mem::zeroed() };
    // SAFETY: `c` is a valid NUL-terminated path and `s` a writable statvfs.
    if unsafe { libc::statvfs(c.as_ptr(), &mut s) } != 0 {
        return None;
    }
    Some(s.f_bavail as u64 * s.f_frsize as u64)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tmp(name: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("staging-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        d
    }

    #[test]
    fn commit_replaces_the_previous_set_and_failure_keeps_it() {
        let out = tmp("commit");
        let mut s = Staging::new(&out).unwrap();
        std::fs::write(s.path("a.csv"), "1").unwrap();
        std::fs::write(s.path("img.tif"), "1").unwrap();
        s.commit().unwrap();
        // Second run: a.csv again, no image, a new b.nc.
        let mut s = Staging::new(&out).unwrap();
        std::fs::write(s.path("a.csv"), "2").unwrap();
        std::fs::write(s.path("b.nc"), "2").unwrap();
        s.commit().unwrap();
        assert_eq!(std::fs::read_to_string(out.join("a.csv")).unwrap(), "2");
        assert!(!out.join("img.tif").exists());
        assert!(out.join("b.nc").exists());
        // A failed third run (dropped before commit) leaves the second's products.
        {
            let mut s = Staging::new(&out).unwrap();
            std::fs::write(s.path("a.csv"), "3").unwrap();
        }
        assert_eq!(std::fs::read_to_string(out.join("a.csv")).unwrap(), "2");
        let left: Vec<_> = std::fs::read_dir(&out)
            .unwrap()
            .flatten()
            .map(|e| e.file_name().to_string_lossy().into_owned())
            .collect();
        assert!(!left.iter().any(|n| n.starts_with(".staging")), "{left:?}");
        // A file that is not a product (the user's) is never deleted.
        std::fs::write(out.join("notes.txt"), "mine").unwrap();
        let mut s = Staging::new(&out).unwrap();
        std::fs::write(s.path("c.csv"), "4").unwrap();
        s.commit().unwrap();
        assert!(out.join("notes.txt").exists() && !out.join("a.csv").exists());
        std::fs::remove_dir_all(&out).unwrap();
    }

    /// Rationale (issue 43): a kill while products move into place left a new results.nc
    /// beside the old GeoTIFFs with nothing saying so. The marker exists exactly while the
    /// moves run: a complete commit leaves none, and one left by a killed commit (simulated
    /// here by the state it leaves: the marker and part of the moves) is replaced by the next.
    #[test]
    fn interrupted_commit_is_marked_until_the_next_one() {
        let out = tmp("marker");
        let mut s = Staging::new(&out).unwrap();
        std::fs::write(s.path("a.csv"), "1").unwrap();
        s.commit().unwrap();
        assert!(!out.join(INCOMPLETE_MARKER).exists());
        // A killed commit: marker written, a.csv moved, img.tif not yet.
        std::fs::write(out.join(INCOMPLETE_MARKER), "a.csv\nimg.tif\n").unwrap();
        std::fs::write(out.join("a.csv"), "2").unwrap();
        let mut s = Staging::new(&out).unwrap();
        std::fs::write(s.path("a.csv"), "3").unwrap();
        std::fs::write(s.path("img.tif"), "3").unwrap();
        s.commit().unwrap();
        assert!(!out.join(INCOMPLETE_MARKER).exists());
        assert_eq!(std::fs::read_to_string(out.join("img.tif")).unwrap(), "3");
        std::fs::remove_dir_all(&out).unwrap();
    }
}
