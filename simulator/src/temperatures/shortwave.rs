//! Broadband sunlight and sky light at the ground through the file's atmosphere, by our own 1D
//! Monte Carlo runs: for each solar zenith of a grid, a `distant_flux` measure looking down at
//! the ground (altitude 0) over a Lambertian ground of the surroundings' albedo gives, at every
//! `shortwave.wavelengths`, the direct beam (exact) and the diffuse sky irradiance (Monte
//! Carlo). Their trapezoid integrals over wavelength, scaled by `S/∫E0` (S the total solar
//! irradiance, 1361 W m⁻² at 1 AU, scaled to the date's Earth–Sun distance; E0 the TSIS-1
//! spectrum at the same wavelengths), are the broadband direct-normal and diffuse-horizontal
//! irradiances; a step's Sun takes them linearly interpolated in zenith.

use std::path::Path;

use anyhow::Context;
use engine::config::Experiment;

use super::config::TemperatureConfig;

/// Total solar irradiance at 1 AU, W m⁻² (Kopp & Lean 2011).
pub const TSI: f64 = 1361.0;

/// Solar zeniths (degrees) of the table.
const ZENITHS: [f64; 15] = [
    0.0, 10.0, 20.0, 30.0, 40.0, 50.0, 60.0, 65.0, 70.0, 75.0, 80.0, 83.0, 86.0, 88.0, 89.5,
];

/// Broadband irradiances against solar zenith.
#[derive(Clone, Debug)]
pub struct Table {
    pub zenith_deg: Vec<f64>,
    /// Direct irradiance normal to the beam, W m⁻².
    pub direct_normal: Vec<f64>,
    /// Diffuse irradiance on a horizontal plane, W m⁻², and its standard error.
    pub diffuse: Vec<f64>,
    pub diffuse_stderr: Vec<f64>,
}

impl Table {
    /// (direct normal, diffuse horizontal) at zenith `z` degrees (0 beyond the last zenith).
    pub fn at(&self, z: f64) -> (f64, f64) {
        let zs = &self.zenith_deg;
        if z >= zs[zs.len() - 1] {
            let k = zs.len() - 1;
            // Fade to 0 at the horizon.
            let f = ((90.0 - z) / (90.0 - zs[k])).clamp(0.0, 1.0);
            return (self.direct_normal[k] * f, self.diffuse[k] * f);
        }
        let k = zs.partition_point(|&v| v <= z).clamp(1, zs.len() - 1);
        let f = (z - zs[k - 1]) / (zs[k] - zs[k - 1]);
        let lerp = |v: &[f64]| v[k - 1] * (1.0 - f) + v[k] * f;
        (lerp(&self.direct_normal), lerp(&self.diffuse))
    }
}

/// The experiment text of one zenith's flux run.
fn experiment_text(cfg: &TemperatureConfig, zenith: f64) -> anyhow::Result<String> {
    let s = &cfg.shortwave;
    let mut doc = toml::Table::new();
    if let Some(mode) = &s.mode {
        doc.insert("mode".into(), mode.clone().into());
    }
    doc.insert("seed".into(), (s.seed as i64).into());
    let mut spectral = toml::Table::new();
    spectral.insert(
        "wavelengths".into(),
        toml::Value::Array(s.grid().into_iter().map(|w| w.into()).collect()),
    );
    doc.insert("spectral".into(), spectral.into());
    let atmosphere = s.atmosphere.clone().unwrap_or_else(|| {
        let mut a = toml::Table::new();
        a.insert("type".into(), "molecular".into());
        a.insert("profile".into(), "afgl_1986-us_standard".into());
        a
    });
    doc.insert("atmosphere".into(), atmosphere.into());
    let mut surface = toml::Table::new();
    surface.insert("type".into(), "lambertian".into());
    surface.insert("reflectance".into(), s.surround_albedo.into());
    doc.insert("surface".into(), surface.into());
    let mut ill = toml::Table::new();
    ill.insert("type".into(), "directional".into());
    ill.insert("zenith".into(), zenith.into());
    ill.insert("azimuth".into(), 0.0.into());
    ill.insert("irradiance".into(), "tsis_1".into());
    ill.insert("date".into(), cfg.date.clone().into());
    doc.insert("illumination".into(), ill.into());
    let mut m = toml::Table::new();
    m.insert("type".into(), "distant_flux".into());
    m.insert("id".into(), "ground".into());
    m.insert("altitude".into(), 0.0.into());
    m.insert("direction".into(), "down".into());
    m.insert("spp".into(), (s.spp.min(i64::MAX as u64) as i64).into());
    doc.insert(
        "measures".into(),
        toml::Value::Array(vec![toml::Value::Table(m)]),
    );
    Ok(toml::to_string(&doc)?)
}

/// The table for the file's atmosphere (`path` anchors its relative paths and names it in
/// errors).
pub fn table(cfg: &TemperatureConfig, path: &Path) -> anyhow::Result<Table> {
    let doy = engine::spectral::solar::day_of_year(&cfg.date)
        .map_err(|e| anyhow::anyhow!("{}: at key `date`: {e}", path.display()))?;
    let s_total = TSI * engine::spectral::solar::earth_sun_factor(doy);
    let mut out = Table {
        zenith_deg: ZENITHS.to_vec(),
        direct_normal: vec![],
        diffuse: vec![],
        diffuse_stderr: vec![],
    };
    for &z in &ZENITHS {
        let text = experiment_text(cfg, z)?;
        let exp = Experiment::from_str(&text, path).map_err(|e| {
            anyhow::anyhow!(
                "{}: the [shortwave] sky run (solar zenith {z}°) is not a valid experiment: {e}",
                path.display()
            )
        })?;
        let results = crate::run::run_without_tail_warnings(&exp);
        let rows = crate::products::rows(&exp, &results);
        let wl = &exp.wavelengths;
        let (mut dir, mut dif, mut var) = (
            vec![0.0; wl.len()],
            vec![0.0; wl.len()],
            vec![0.0; wl.len()],
        );
        for r in &rows {
            let i = wl
                .iter()
                .position(|&w| w == r.wavelength_nm)
                .context("a row of an unknown wavelength")?;
            dir[i] = r.flux_direct.map_or(0.0, |v| v.0);
            dif[i] = r.flux_diffuse.map_or(0.0, |v| v.0);
            var[i] = r.flux_diffuse.map_or(0.0, |v| v.1 * v.1);
        }
        let e0: Vec<f64> = exp.optics.iter().map(|o| o.irradiance).collect();
        let k = s_total / trapezoid(wl, &e0);
        let mu = z.to_radians().cos();
        out.direct_normal.push(k * trapezoid(wl, &dir) / mu);
        let diffuse = k * trapezoid(wl, &dif);
        // Standard error of the broadband diffuse: the wavelengths' runs are independent.
        let weights = trapezoid_weights(wl);
        let se = k * weights
            .iter()
            .zip(&var)
            .map(|(w, v)| w * w * v)
            .sum::<f64>()
            .sqrt();
        if diffuse > 0.0 && se > 0.02 * diffuse {
            tracing::warn!(
                "the diffuse sky irradiance at solar zenith {z}° has a {:.1} % standard error: raise shortwave.spp",
                100.0 * se / diffuse
            );
        }
        out.diffuse.push(diffuse);
        out.diffuse_stderr.push(se);
    }
    tracing::info!(
        "broadband irradiance at the ground, Sun at the zenith: direct {:.1} W m-2, diffuse {:.1} ± {:.1} W m-2",
        out.direct_normal[0],
        out.diffuse[0],
        out.diffuse_stderr[0]
    );
    Ok(out)
}

/// The trapezoid rule's weight of each sample.
fn trapezoid_weights(x: &[f64]) -> Vec<f64> {
    let mut w = vec![0.0; x.len()];
    for (i, p) in x.windows(2).enumerate() {
        w[i] += 0.5 * (p[1] - p[0]);
        w[i + 1] += 0.5 * (p[1] - p[0]);
    }
    w
}

fn trapezoid(x: &[f64], y: &[f64]) -> f64 {
    x.windows(2)
        .zip(y.windows(2))
        .map(|(x, y)| 0.5 * (x[1] - x[0]) * (y[0] + y[1]))
        .sum()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_table_interpolates_in_zenith_and_fades_at_the_horizon() {
        let t = Table {
            zenith_deg: vec![0.0, 60.0, 89.5],
            direct_normal: vec![900.0, 800.0, 10.0],
            diffuse: vec![100.0, 80.0, 5.0],
            diffuse_stderr: vec![0.0; 3],
        };
        assert_eq!(t.at(30.0), (850.0, 90.0));
        assert_eq!(t.at(0.0), (900.0, 100.0));
        assert_eq!(t.at(90.0), (0.0, 0.0));
        let (a, b) = t.at(89.75);
        assert!((a - 5.0).abs() < 1e-9 && (b - 2.5).abs() < 1e-9);
    }
}
