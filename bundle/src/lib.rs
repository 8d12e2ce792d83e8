//! Scene bundle: the versioned contract between `scenegen` (writer) and `simulate` (reader).
//!
//! A bundle is a directory (format described for people in `docs/bundle.md`):
//!
//! ```text
//! BUNDLE/
//!   manifest.toml   format version, CRS, local frame, extent, materials, templates, provenance
//!   terrain.bin     terrain tiles: f32 positions (local frame of each tile), f32 uv, u32 indices
//!   templates.bin   template meshes: f32 positions (template frame), u32 indices, u8 materials
//!   instances.bin   one 64-byte record per instance: f64 translation, f32 3x3 linear, u32 template
//!   materials.u8    the 8-bit material-index raster, row-major from the north-west corner
//! ```
//!
//! Units: metres everywhere; the working frame is the projected CRS named in the manifest with
//! x = easting, y = northing, z = height above the DEM's vertical datum (East-North-Up, as in
//! `docs/conventions.md`). Geometry is stored in f32 relative to f64 origins: over 100 km an f32
//! resolves only about 1 cm, relative to a tile origin it resolves well under 1 mm.
//! Binary buffers are little-endian and tightly packed; byte offsets are given in the manifest.
//!
//! Material ids: the raster's bytes and the templates' per-triangle bytes are the `index` of a
//! `[[materials]]` entry (unique, 0–254, not necessarily contiguous or in order; 255 in the
//! raster means "no material"). [`Bundle::open`] and [`Bundle::write`] refuse an id without an
//! entry, naming the file and the pixel or triangle count of each such id, and any material
//! whose BRDF parameters lie outside [`BRDF_PARAM_RANGES`].
//!
//! This crate needs no GDAL and no netCDF: georeferencing is carried as WKT and a geotransform.
//! Its users: `scenegen` (writer), `landcover` (the BRDF vocabulary and ranges), `simulator`
//! (reader; re-exported there as `simulator::bundle`).

mod brdf;
mod checks;
mod io;
mod manifest;
mod solver;

pub use brdf::*;
pub use io::{
    check_replaceable, Bundle, Instance, TemplateMesh, TerrainTile, INSTANCE_RECORD_BYTES,
};
pub use manifest::*;
pub use solver::*;

use std::path::PathBuf;

/// The format version written by this code. Readers refuse other major versions.
pub const FORMAT_VERSION: u32 = 1;
/// The `format` key of every manifest.
pub const FORMAT_NAME: &str = "eo-scene-bundle";
/// Material-raster value meaning "no material" (outside the land-cover data).
pub const NO_MATERIAL: u8 = 255;
/// The templates buffer's file name (fixed: the manifest has no key for it).
pub(crate) const TEMPLATES_FILE: &str = "templates.bin";

/// Errors from reading or writing a bundle; each names the file and what is wrong.
#[derive(Debug, thiserror::Error)]
pub enum BundleError {
    #[error("cannot read {}: {source}", path.display())]
    Read {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("cannot write {}: {source}", path.display())]
    Write {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("{}: invalid manifest: {message}", path.display())]
    Manifest { path: PathBuf, message: String },
    #[error("{}: bundle format version {found} is not supported (this build reads version {FORMAT_VERSION})", path.display())]
    Version { path: PathBuf, found: i64 },
    #[error("{}: {message}", path.display())]
    Corrupt { path: PathBuf, message: String },
    #[error("output directory {} already exists (use --force to replace it)", path.display())]
    Exists { path: PathBuf },
    /// `--force` replaces bundles (and empty directories) only, never other data.
    #[error("{} exists and is not a scene bundle ({reason}); --force replaces only a bundle or an empty directory: remove it yourself or choose another output path", path.display())]
    NotABundle { path: PathBuf, reason: String },
    /// A material of the manifest whose BRDF parameters are out of range or malformed.
    #[error("{}: material `{name}` (index {index}): {source}", path.display())]
    Brdf {
        path: PathBuf,
        index: u8,
        name: String,
        source: BrdfError,
    },
    /// Ids used by the material raster (`materials.u8`, counted in pixels) or by template
    /// triangles (`templates.bin`, counted in triangles) that have no `[[materials]]` entry.
    #[error("{}: {} material id(s) not in the manifest's material table: {}; the table has {}",
        path.display(), ids.len(), format_id_counts(ids, counted), format_known(known))]
    UnknownMaterialIds {
        path: PathBuf,
        /// "pixel" or "triangle".
        counted: &'static str,
        /// (id, count), by id.
        ids: Vec<(u8, u64)>,
        /// The manifest's indices, sorted.
        known: Vec<u8>,
    },
}

fn format_id_counts(ids: &[(u8, u64)], counted: &str) -> String {
    ids.iter()
        .map(|(id, n)| format!("{id} ({n} {counted}{})", if *n == 1 { "" } else { "s" }))
        .collect::<Vec<_>>()
        .join(", ")
}

fn format_known(known: &[u8]) -> String {
    if known.is_empty() {
        "no materials".into()
    } else {
        format!(
            "ids {}",
            known
                .iter()
                .map(|i| i.to_string())
                .collect::<Vec<_>>()
                .join(", ")
        )
    }
}

/// Peak resident memory of this process (VmHWM), bytes; `None` where /proc is not available.
/// Used by the benchmarks that write (`scenegen bench`) and load (`simulate bench-scene`) bundles.
pub fn peak_rss_bytes() -> Option<u64> {
    kib_field("/proc/self/status", "VmHWM:")
}

/// A memory figure of this machine from `/proc/meminfo` (`"MemTotal:"`, `"MemAvailable:"`),
/// bytes; `None` where it is not available. Used by the memory checks of `simulate` (the
/// run's estimate against the total) and `scenegen` (the build's against what is available).
pub fn meminfo_bytes(field: &str) -> Option<u64> {
    kib_field("/proc/meminfo", field)
}

/// The `field` line (`NAME:  1234 kB`) of a /proc file, in bytes.
fn kib_field(file: &str, field: &str) -> Option<u64> {
    let s = std::fs::read_to_string(file).ok()?;
    let line = s.lines().find(|l| l.starts_with(field))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    kib.checked_mul(1024)
}
