//! Utilities below every model: CPU clocks (`cpu_time.rs`), the process-wide cache of parsed
//! input files (`file_cache.rs`) and the completeness check of classic netCDF files
//! (`nc_complete.rs`).

pub mod cpu_time;
pub mod file_cache;
pub mod nc_complete;
