//! Completeness of classic-format netCDF files (CDF-1, CDF-2, CDF-5).
//!
//! The netCDF-C library reads the data of a truncated classic file as fill values (zeros)
//! without an error, so a phase table or absorption file cut short by a failed copy would give
//! a silently wrong result. [`check`] parses the classic header (format specification:
//! <https://docs.unidata.ucar.edu/netcdf-c/current/file_format_specifications.html>) and
//! compares the file's length with the end of the last byte any variable needs: for a fixed
//! variable `begin + vsize`; for record variables `begin + (numrecs − 1)·recsize + vsize`.
//! netCDF-4 (HDF5) files are left to HDF5, which reports truncation itself.

use std::io::Read;
use std::path::{Path, PathBuf};

const NC_DIMENSION: u32 = 0x0A;
const NC_VARIABLE: u32 = 0x0B;
const NC_ATTRIBUTE: u32 = 0x0C;
/// Headers larger than this are not classic netCDF headers we can believe.
const MAX_HEADER: u64 = 64 << 20;

/// Why a classic netCDF file is refused. The messages do not name the file (`path` is kept for
/// callers that need it): the readers prefix it with their own wording.
#[derive(Debug, thiserror::Error)]
pub enum NcError {
    /// The file's length or header bytes could not be read.
    #[error("cannot read it: {source}")]
    Unreadable {
        path: PathBuf,
        source: std::io::Error,
    },
    /// The header does not parse.
    #[error("damaged classic netCDF header ({source})")]
    Header { path: PathBuf, source: HeaderError },
    /// The file is shorter than its header declares.
    #[error(
        "truncated: its header declares {needed} bytes (variable `{variable}` ends there), the file has {length}; copy it again"
    )]
    Truncated {
        path: PathBuf,
        needed: u64,
        length: u64,
        /// The variable that ends last.
        variable: String,
    },
}

/// What is wrong in a classic netCDF header; byte offsets count from the start of the file.
#[derive(Debug, thiserror::Error)]
pub enum HeaderError {
    #[error("the header ends early at byte {at}")]
    EndsEarly { at: usize },
    #[error("unexpected tag {tag:#x} at byte {at}")]
    UnexpectedTag { tag: u32, at: usize },
    #[error("unknown type {ty}")]
    UnknownType { ty: u32 },
    #[error("an attribute size overflows")]
    AttributeSizeOverflow,
    /// The padded size of an attribute overflows.
    #[error("overflow")]
    PaddingOverflow,
    #[error("an attribute is too large")]
    AttributeTooLarge,
    #[error("variable `{variable}` names dimension {id} of {count}")]
    NoSuchDimension {
        variable: String,
        id: usize,
        count: usize,
    },
    #[error("a variable size overflows")]
    VariableSizeOverflow,
    #[error("variable `{variable}` ends beyond 2^64 bytes")]
    EndsBeyond { variable: String },
}

/// Checks that `path`, if it is a classic-format netCDF file, holds every byte its header
/// declares. `Ok` for netCDF-4/HDF5 and other files (their readers check them).
pub fn check(path: &Path) -> Result<(), NcError> {
    // A file that cannot be opened is left to the netCDF reader, which names the cause.
    let Ok(mut f) = std::fs::File::open(path) else {
        return Ok(());
    };
    let unreadable = |source| NcError::Unreadable {
        path: path.to_path_buf(),
        source,
    };
    let len = f.metadata().map_err(unreadable)?.len();
    let mut magic = [0u8; 4];
    if f.read_exact(&mut magic).is_err() || &magic[..3] != b"CDF" {
        return Ok(());
    }
    let version = magic[3];
    if !matches!(version, 1 | 2 | 5) {
        return Ok(());
    }
    // Read a small prefix first; headers are rarely larger, and grow the read only if needed.
    let mut head = Vec::new();
    let mut want = 64 << 10;
    let need = loop {
        let have = head.len() as u64;
        (&mut f)
            .take(want - have)
            .read_to_end(&mut head)
            .map_err(unreadable)?;
        match required_length(&head, version) {
            Ok(n) => break n,
            Err(HeaderError::EndsEarly { .. })
                if head.len() as u64 == want && want < MAX_HEADER =>
            {
                want *= 4;
            }
            Err(source) => {
                return Err(NcError::Header {
                    path: path.to_path_buf(),
                    source,
                })
            }
        }
    };
    if let Some((need, var)) = need {
        if len < need {
            return Err(NcError::Truncated {
                path: path.to_path_buf(),
                needed: need,
                length: len,
                variable: var,
            });
        }
    }
    Ok(())
}

/// A cursor over the header bytes after the magic number.
struct Header<'a> {
    b: &'a [u8],
    at: usize,
    /// CDF-5 uses 64-bit counts.
    wide: bool,
}

impl Header<'_> {
    fn bytes(&mut self, n: usize) -> Result<&[u8], HeaderError> {
        let end = self
            .at
            .checked_add(n)
            .filter(|&e| e <= self.b.len())
            .ok_or(HeaderError::EndsEarly { at: self.at + 4 })?;
        let s = &self.b[self.at..end];
        self.at = end;
        Ok(s)
    }
    fn u32(&mut self) -> Result<u32, HeaderError> {
        Ok(u32::from_be_bytes(self.bytes(4)?.try_into().unwrap()))
    }
    fn u64(&mut self) -> Result<u64, HeaderError> {
        Ok(u64::from_be_bytes(self.bytes(8)?.try_into().unwrap()))
    }
    /// NON_NEG: 4 bytes, 8 in CDF-5.
    fn count(&mut self) -> Result<u64, HeaderError> {
        if self.wide {
            self.u64()
        } else {
            self.u32().map(u64::from)
        }
    }
    fn name(&mut self) -> Result<String, HeaderError> {
        let n = self.count()? as usize;
        let s = String::from_utf8_lossy(self.bytes(n)?).into_owned();
        self.bytes((4 - n % 4) % 4)?;
        Ok(s)
    }
    /// A tag and its element count (ABSENT is a zero tag and zero count).
    fn list(&mut self, tag: u32) -> Result<u64, HeaderError> {
        let t = self.u32()?;
        let n = self.count()?;
        if t != tag && !(t == 0 && n == 0) {
            return Err(HeaderError::UnexpectedTag {
                tag: t,
                at: self.at,
            });
        }
        Ok(n)
    }
    fn attributes(&mut self) -> Result<(), HeaderError> {
        let n = self.list(NC_ATTRIBUTE)?;
        for _ in 0..n {
            self.name()?;
            let ty = self.u32()?;
            let count = self.count()?;
            let size = count
                .checked_mul(type_size(ty)?)
                .ok_or(HeaderError::AttributeSizeOverflow)?;
            let padded = size
                .checked_add((4 - size % 4) % 4)
                .ok_or(HeaderError::PaddingOverflow)?;
            self.bytes(usize::try_from(padded).map_err(|_| HeaderError::AttributeTooLarge)?)?;
        }
        Ok(())
    }
}

fn type_size(ty: u32) -> Result<u64, HeaderError> {
    Ok(match ty {
        1 | 2 | 7 => 1,
        3 | 8 => 2,
        4 | 5 | 9 => 4,
        6 | 10 | 11 => 8,
        t => return Err(HeaderError::UnknownType { ty: t }),
    })
}

/// The length the file must have and the variable that ends last, or `None` if no variable
/// holds data (or the record count is "streaming", unknown).
fn required_length(b: &[u8], version: u8) -> Result<Option<(u64, String)>, HeaderError> {
    let mut h = Header {
        b,
        at: 0,
        wide: version == 5,
    };
    let numrecs = h.count()?;
    let streaming = if h.wide {
        numrecs == u64::MAX
    } else {
        numrecs == u32::MAX as u64
    };
    let ndims = h.list(NC_DIMENSION)?;
    let mut dims = Vec::new();
    for _ in 0..ndims {
        h.name()?;
        dims.push(h.count()?);
    }
    h.attributes()?;
    let nvars = h.list(NC_VARIABLE)?;
    struct Var {
        name: String,
        begin: u64,
        size: u64,
        record: bool,
    }
    let mut vars = Vec::new();
    for _ in 0..nvars {
        let name = h.name()?;
        let rank = h.count()?;
        let mut shape = Vec::new();
        for _ in 0..rank {
            let id = h.count()? as usize;
            shape.push(*dims.get(id).ok_or_else(|| HeaderError::NoSuchDimension {
                variable: name.clone(),
                id,
                count: dims.len(),
            })?);
        }
        h.attributes()?;
        let ty = h.u32()?;
        let _vsize = h.count()?;
        let begin = if version == 1 {
            h.u32()? as u64
        } else {
            h.u64()?
        };
        let record = shape.first() == Some(&0);
        // The size of one record (or of the whole fixed variable), from the shape: vsize is
        // not trustworthy beyond 4 GiB.
        let mut size = type_size(ty)?;
        for &d in shape.iter().skip(record as usize) {
            size = size
                .checked_mul(d)
                .ok_or(HeaderError::VariableSizeOverflow)?;
        }
        vars.push(Var {
            name,
            begin,
            size,
            record,
        });
    }
    let pad = |s: u64| s + (4 - s % 4) % 4;
    let records: Vec<&Var> = vars.iter().filter(|v| v.record).collect();
    // One record variable alone is not padded inside a record.
    let recsize = match records.len() {
        1 => records[0].size,
        _ => records.iter().map(|v| pad(v.size)).sum(),
    };
    let mut need: Option<(u64, String)> = None;
    for v in &vars {
        let end = if v.record {
            if streaming || numrecs == 0 {
                continue;
            }
            (numrecs - 1)
                .checked_mul(recsize)
                .and_then(|r| r.checked_add(v.begin))
                .and_then(|r| r.checked_add(v.size))
        } else {
            v.begin.checked_add(v.size)
        }
        .ok_or_else(|| HeaderError::EndsBeyond {
            variable: v.name.clone(),
        })?;
        if need.as_ref().is_none_or(|(n, _)| end > *n) {
            need = Some((end, v.name.clone()));
        }
    }
    Ok(need)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every classic file of the shared data is complete (no false alarms), and each one cut
    /// short by a byte is caught.
    #[test]
    fn shared_classic_files_are_complete_and_truncation_is_caught() {
        let root = std::env::var_os("SIMULATOR_SHARED_DATA")
            .map(std::path::PathBuf::from)
            .unwrap_or_else(|| Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/data"));
        let mut classic = Vec::new();
        let mut stack = vec![root];
        while let Some(d) = stack.pop() {
            let Ok(rd) = std::fs::read_dir(&d) else {
                continue;
            };
            for e in rd.flatten() {
                let p = e.path();
                if p.is_dir() {
                    stack.push(p);
                } else if p.extension().is_some_and(|x| x == "nc" || x == "cdf") {
                    let mut m = [0u8; 4];
                    if std::fs::File::open(&p)
                        .and_then(|mut f| f.read_exact(&mut m))
                        .is_ok()
                        && &m[..3] == b"CDF"
                    {
                        classic.push(p);
                    }
                }
            }
        }
        assert!(classic.len() >= 3, "{classic:?}");
        for p in &classic {
            check(p).unwrap_or_else(|e| panic!("{}: {e}", p.display()));
        }
        let Some(small) = classic
            .iter()
            .filter(|p| std::fs::metadata(p).unwrap().len() < 50 << 20)
            .min_by_key(|p| std::fs::metadata(p).unwrap().len())
        else {
            panic!("no classic netCDF file in the shared data");
        };
        let bytes = std::fs::read(small).unwrap();
        let cut = std::env::temp_dir().join(format!("nc-cut-{}.nc", std::process::id()));
        std::fs::write(&cut, &bytes[..bytes.len() - 1]).unwrap();
        let e = check(&cut).unwrap_err().to_string();
        assert!(e.contains("truncated"), "{e}");
        std::fs::write(&cut, &bytes[..bytes.len() / 2]).unwrap();
        assert!(check(&cut).is_err());
        std::fs::write(&cut, &bytes[..10]).unwrap();
        assert!(check(&cut).unwrap_err().to_string().contains("header"));
        std::fs::remove_file(&cut).unwrap();
    }
}
