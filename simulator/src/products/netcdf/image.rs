//! The variables of one `ortho` or `perspective` image measure `ID` in `results.nc`.
//!
//! * dimensions `ID_y`, `ID_x` (row 0 = north / top);
//! * ortho images: coordinates `ID_x(ID_x)`, `ID_y(ID_y)`, the pixel centres in the scene's CRS
//!   (m, `standard_name` `projection_x_coordinate` / `projection_y_coordinate`, `axis` X / Y),
//!   and, when the scene has a CRS, the grid-mapping variable `ID_spatial_ref`
//!   (`grid_mapping.rs`) named by every image variable's `grid_mapping` attribute; GDAL opens
//!   `NETCDF:"results.nc":ID_brf` with the same geotransform and CRS as `ID_brf.tif`;
//! * data `ID_brf`, `ID_brf_stderr`, `ID_brf_single`, `ID_brf_multiple`, `ID_radiance`,
//!   `ID_radiance_stderr` on `(wavelength, ID_y, ID_x)`; polarized runs add `ID_q`, `ID_u`,
//!   `ID_dolp`, `ID_dolp_stderr`; ortho images carry the view angles as attributes `vza`, `vaa`;
//!   without the Sun above the horizon (thermal emission only, twilight) the BRF-normalised
//!   ones (`ID_brf*`, `ID_q`, `ID_u`) are NaN;
//! * `ID_n_samples(wavelength)`: the fewest samples of any pixel;
//! * `ID_pixel_samples(wavelength, y, x)`: the samples of each pixel (adaptive rounds stop
//!   pixels that meet the target early).

use crate::products::imagery::ImageProduct;

/// The variables of one image measure.
pub(super) fn write(f: &mut netcdf::FileMut, p: &ImageProduct) -> Result<(), netcdf::Error> {
    let id = &p.id;
    let (dy, dx) = (format!("{id}_y"), format!("{id}_x"));
    let mapping = format!("{id}_spatial_ref");
    f.add_dimension(&dy, p.height)?;
    f.add_dimension(&dx, p.width)?;
    if let Some(gt) = p.geotransform {
        let xs: Vec<f64> = (0..p.width)
            .map(|c| gt[0] + (c as f64 + 0.5) * gt[1])
            .collect();
        let ys: Vec<f64> = (0..p.height)
            .map(|r| gt[3] + (r as f64 + 0.5) * gt[5])
            .collect();
        for (name, data, standard, axis, long) in [
            (
                &dx,
                xs,
                "projection_x_coordinate",
                "X",
                "easting of pixel centres",
            ),
            (
                &dy,
                ys,
                "projection_y_coordinate",
                "Y",
                "northing of pixel centres",
            ),
        ] {
            let mut v = f.add_variable::<f64>(name, &[name.as_str()])?;
            v.put_attribute("units", "m")?;
            v.put_attribute("standard_name", standard)?;
            v.put_attribute("axis", axis)?;
            v.put_attribute("long_name", long)?;
            v.put_values(&data, ..)?;
        }
        if !p.wkt.trim().is_empty() {
            super::grid_mapping::write(f, &mapping, &p.wkt, &gt)?;
        }
    }
    let georeferenced = p.geotransform.is_some() && !p.wkt.trim().is_empty();
    let mut sets: Vec<(&str, &Vec<Vec<f64>>, &str, &str)> = vec![
        (
            "brf",
            &p.brf,
            "1",
            "bidirectional reflectance factor pi L / (E0 cos SZA)",
        ),
        ("brf_stderr", &p.brf_stderr, "1", "standard error of brf"),
        (
            "brf_single",
            &p.brf_single,
            "1",
            "single-scattering part of brf",
        ),
        (
            "brf_multiple",
            &p.brf_multiple,
            "1",
            "multiple-scattering part of brf",
        ),
        ("radiance", &p.radiance, "W m-2 sr-1 nm-1", "radiance"),
        (
            "radiance_stderr",
            &p.radiance_stderr,
            "W m-2 sr-1 nm-1",
            "standard error of radiance",
        ),
    ];
    if let Some(st) = &p.stokes {
        sets.extend([
            (
                "q",
                &st.q,
                "1",
                "Stokes Q pi Q / (E0 cos SZA), meridian frame of the view",
            ),
            (
                "u",
                &st.u,
                "1",
                "Stokes U pi U / (E0 cos SZA), meridian frame of the view",
            ),
            ("dolp", &st.dolp, "1", "degree of linear polarization"),
            (
                "dolp_stderr",
                &st.dolp_stderr,
                "1",
                "standard error of dolp",
            ),
        ]);
    }
    // No Sun (thermal emission only) or the Sun below the horizon: the BRF-normalised variables
    // stay (the file's layout does not change) but are left empty (NaN), as in the tables.
    let empty = |name: &str| !p.has_brf && (name.starts_with("brf") || name == "q" || name == "u");
    for (name, data, units, long) in sets {
        let flat: Vec<f64> = if empty(name) {
            vec![f64::NAN; data.iter().map(|v| v.len()).sum()]
        } else {
            data.iter().flatten().copied().collect()
        };
        let mut v = f.add_variable::<f64>(&format!("{id}_{name}"), &["wavelength", &dy, &dx])?;
        v.put_attribute("units", units)?;
        v.put_attribute("long_name", long)?;
        if georeferenced {
            v.put_attribute("grid_mapping", mapping.as_str())?;
        }
        if let Some((vza, vaa)) = p.view {
            v.put_attribute("vza", vza)?;
            v.put_attribute("vaa", vaa)?;
        }
        v.put_values(&flat, ..)?;
    }
    if let Some((cot, frac)) = &p.clouds {
        for (name, data, long) in [
            (
                "cloud_optical_thickness",
                cot,
                "cloud optical thickness along the line of sight times cos VZA, pixel mean",
            ),
            (
                "cloud_fraction",
                frac,
                "share of the pixel's lines of sight with cloud optical thickness >= 0.1",
            ),
        ] {
            let mut v = f.add_variable::<f64>(&format!("{id}_{name}"), &[&dy, &dx])?;
            v.put_attribute("units", "1")?;
            v.put_attribute("long_name", long)?;
            if georeferenced {
                v.put_attribute("grid_mapping", mapping.as_str())?;
            }
            v.put_values(data, ..)?;
        }
    }
    let n: Vec<i64> = p.n_samples.iter().map(|&x| x as i64).collect();
    let mut v = f.add_variable::<i64>(&format!("{id}_n_samples"), &["wavelength"])?;
    v.put_attribute("long_name", "fewest Monte Carlo samples of any pixel")?;
    v.put_values(&n, ..)?;
    let n: Vec<i64> = p
        .pixel_samples
        .iter()
        .flatten()
        .map(|&x| x as i64)
        .collect();
    let mut v = f.add_variable::<i64>(&format!("{id}_pixel_samples"), &["wavelength", &dy, &dx])?;
    v.put_attribute("long_name", "Monte Carlo samples of each pixel")?;
    if georeferenced {
        v.put_attribute("grid_mapping", mapping.as_str())?;
    }
    v.put_values(&n, ..)?;
    Ok(())
}
