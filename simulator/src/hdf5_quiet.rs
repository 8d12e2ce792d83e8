//! Silence HDF5's automatic error printing.
//!
//! netCDF-C probes optional attributes (e.g. `_QuantizeBitRoundNumberOfSignificantBits`) of
//! netCDF-4 files; each failed probe makes the HDF5 library print a multi-line `HDF5-DIAG`
//! trace to stderr, although netCDF handles the failure and nothing is wrong. Those traces
//! buried real messages (hundreds of lines per run with aerosol or absorption files). HDF5 is
//! loaded with libnetcdf; [`quiet`] looks up `H5Eset_auto2` at run time (no link-time
//! dependency on the HDF5 library's name, which differs between distributions) and switches the
//! default error stack's printing off, once per thread. Errors are still returned to netCDF, and from
//! netCDF to us, with their codes.

use std::cell::Cell;

thread_local! {
    static DONE: Cell<bool> = const { Cell::new(false) };
}

/// Turn off HDF5's automatic error printing for the calling thread (thread-safe HDF5 builds,
/// such as Debian's, keep one error stack per thread); idempotent, cheap after the first call,
/// a no-op if HDF5 is not loaded.
pub fn quiet() {
    if DONE.with(|d| d.replace(true)) {
        return;
    }
    {
        // herr_t H5Eset_auto2(hid_t estack_id, H5E_auto2_t func, void *client_data);
        // hid_t is int64_t since HDF5 1.10; H5E_DEFAULT is 0.
        type SetAuto = unsafe extern "C" fn(i64, *const libc::c_void, *mut libc::c_void) -> i32;
        let name = c"H5Eset_auto2";
        // SAFETY: dlsym with RTLD_DEFAULT only looks a symbol up; the function, when present, has
        // the signature above in every HDF5 ≥ 1.10 (the netCDF crate requires such a build).
        unsafe {
            let f = libc::dlsym(libc::RTLD_DEFAULT, name.as_ptr());
            if !f.is_null() {
                let set: SetAuto = std::mem::transmute::<*mut libc::c_void, SetAuto>(f);
                set(0, std::ptr::null(), std::ptr::null_mut());
            }
        }
    }
}
