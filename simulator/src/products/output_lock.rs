//! One run per output folder: `simulate run` holds an exclusive advisory lock on
//! `OUTDIR/.simulate.lock` (the operating system's `flock(LOCK_EX | LOCK_NB)`; `File::try_lock`
//! would do the same but needs Rust 1.89, above our MSRV)
//! for as long as it writes checkpoints and products there. A second run into the same folder
//! is refused at once ([`OutputError::Busy`]) instead of mixing its products with the first
//! one's. The lock dies with its process, so a run killed by `kill -9` leaves no stale lock and
//! resumes normally. Sharded runs (`--shard K/N`) do not take it: shards may share a folder of
//! checkpoints by design.

use std::fs::{File, OpenOptions};
use std::os::unix::io::AsRawFd;
use std::path::{Path, PathBuf};

use crate::error::OutputError;

/// The name of the lock file in an output folder.
pub const LOCK_FILE: &str = ".simulate.lock";

/// Held while a run writes into its output folder; released when dropped.
#[derive(Debug)]
pub struct OutputLock {
    _file: File,
    pub path: PathBuf,
}

/// Take the lock of `dir` (which must exist), or say who holds it.
pub fn lock(dir: &Path) -> Result<OutputLock, OutputError> {
    let path = dir.join(LOCK_FILE);
    let file = OpenOptions::new()
        .create(true)
        .truncate(false)
        .write(true)
        .open(&path)
        .map_err(|source| OutputError::Io {
            path: path.clone(),
            source,
        })?;
    // SAFETY: `flock` on a file descriptor that `file` owns for the whole call.
    let r = unsafe { libc::flock(file.as_raw_fd(), libc::LOCK_EX | libc::LOCK_NB) };
    if r == 0 {
        return Ok(OutputLock { _file: file, path });
    }
    let source = std::io::Error::last_os_error();
    if source.kind() == std::io::ErrorKind::WouldBlock {
        Err(OutputError::Busy {
            dir: dir.to_path_buf(),
            lock: path,
        })
    } else {
        Err(OutputError::Io { path, source })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A second lock on the same folder is refused while the first is held, and granted once
    /// it is dropped.
    #[test]
    fn one_run_per_folder() {
        let dir = std::env::temp_dir().join(format!("simulate-lock-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let a = lock(&dir).unwrap();
        let e = lock(&dir).unwrap_err();
        assert!(matches!(e, OutputError::Busy { .. }), "{e}");
        assert!(e.to_string().contains("another simulate run"), "{e}");
        drop(a);
        let _b = lock(&dir).unwrap();
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
