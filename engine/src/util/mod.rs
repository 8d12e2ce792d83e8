//! Utilities below every model: CPU clocks (`cpu_time.rs`), the process-wide cache of parsed
//! input files (`file_cache.rs`), the completeness check of classic netCDF files
//! (`nc_complete.rs`) and [`without_bom`] for text tables.

pub mod cpu_time;
pub mod file_cache;
pub mod nc_complete;

/// `text` without a leading UTF-8 byte-order mark: spreadsheet exports of CSV and text tables
/// start with one, and it is not part of the first field.
pub fn without_bom(text: &str) -> &str {
    text.strip_prefix('\u{feff}').unwrap_or(text)
}
