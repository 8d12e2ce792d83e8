//! `simulate cloud-field`: write a generated cumulus field (`engine::clouds::cumulus`) as the
//! netCDF `[[clouds]] file` reads (`engine/src/clouds/netcdf.rs`), atomically (a `.part` file
//! renamed into place).

use std::path::Path;

use engine::clouds::cumulus::Cumulus;

/// Write `c`'s field with its rectangle's lower-left corner at `corner` (m, the scene's frame).
pub fn write(path: &Path, c: &Cumulus, corner: [f64; 2]) -> anyhow::Result<(usize, f64)> {
    let (levels, ext) = c.generate();
    let nz = levels.len() - 1;
    let part = path.with_extension("nc.part");
    {
        let _s = engine::netcdf_session();
        let mut f = netcdf::create(&part)
            .map_err(|e| anyhow::anyhow!("cannot create {}: {e}", part.display()))?;
        f.add_dimension("x", c.nx)?;
        f.add_dimension("y", c.ny)?;
        f.add_dimension("z", nz)?;
        f.add_dimension("z_edge", nz + 1)?;
        f.add_attribute(
            "title",
            "generated fair-weather cumulus field (engine/src/clouds/cumulus.rs)",
        )?;
        f.add_attribute(
            "parameters",
            format!(
                "count {} radius_m {:?} aspect {} base_m {} adiabatic_fraction {} r_eff_m {} seed {}",
                c.count, c.radius_m, c.aspect, c.base_m, c.adiabatic_fraction, c.r_eff_m, c.seed
            ),
        )?;
        let xs: Vec<f64> = (0..c.nx)
            .map(|i| corner[0] + (i as f64 + 0.5) * c.dx)
            .collect();
        let ys: Vec<f64> = (0..c.ny)
            .map(|j| corner[1] + (j as f64 + 0.5) * c.dx)
            .collect();
        for (name, dim, vals) in [
            ("x", "x", &xs),
            ("y", "y", &ys),
            ("z_edges", "z_edge", &levels),
        ] {
            let mut v = f.add_variable::<f64>(name, &[dim])?;
            v.put_attribute("units", "m")?;
            v.put_values(vals, ..)?;
        }
        let mut v = f.add_variable::<f32>("extinction", &["z", "y", "x"])?;
        v.put_attribute("units", "m-1")?;
        v.put_attribute(
            "long_name",
            "volume extinction coefficient of cloud droplets",
        )?;
        v.put_values(&ext, ..)?;
    }
    std::fs::rename(&part, path).map_err(|e| {
        anyhow::anyhow!("cannot move {} to {}: {e}", part.display(), path.display())
    })?;
    let cover = (0..c.nx * c.ny)
        .filter(|&col| (0..nz).any(|k| ext[k * c.nx * c.ny + col] > 0.0))
        .count() as f64
        / (c.nx * c.ny) as f64;
    Ok((ext.len(), cover))
}
