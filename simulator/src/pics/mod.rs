//! Pseudo-invariant calibration sites (PICS): simulated TOA reflectance of a site for a list of
//! acquisitions (UTC time, view geometry, sensor band).
//!
//! A **site file** (TOML) describes the place and the physics shared by all acquisitions:
//!
//! ```toml
//! name = "libya4"
//! catalogue = "libya4"    # optional: coordinates (etc.) from the site catalogue (`catalogue.rs`)
//! latitude = 28.55        # deg N
//! longitude = 23.39       # deg E
//! elevation = 118.0       # m
//! spp = 200000            # samples per acquisition and wavelength (maximum)
//! target_rel_stderr = 0.002
//! wavelength_step = 5.0   # nm, sampling of each band (mode = "mono")
//! irradiance = "tsis_1"   # solar spectrum (see docs/experiment.md)
//! mode = "ckd"            # optional: gas absorption by correlated-k (bins sample each band)
//! [integrator]            # optional: any experiment [integrator] table (e.g. ckd_walk = "alis")
//! [geometry]              # any experiment [geometry] table (default: plane-parallel 0–100 km)
//! [atmosphere]            # any experiment [atmosphere] table (e.g. type = "molecular")
//! [surface]               # any experiment [surface] table (the site's BRDF, with its source)
//! ```
//!
//! An **acquisitions file** (CSV, `acquisitions`) has the columns `time_utc,vza,vaa,srf` (an RFC
//! 3339 time, taken in UTC; view zenith and azimuth in degrees, azimuth clockwise from North, of
//! the direction from the site to the sensor; an SRF name or file) and optionally `sza,saa` (the
//! Sun's angles, replacing the computed ones). Each acquisition becomes one experiment — the Sun
//! from NREL SPA at the site and time (unless given), E0 scaled by 1/r² with SPA's distance, the
//! band sampled and weighted (`srf.rs`) — validated and run by the same code as `simulate run`,
//! so every key error names the site file and key. The result per acquisition: band TOA
//! radiance and reflectance with standard errors, the solar geometry and the Earth–Sun distance,
//! written as `pics.csv` (`to_csv`) and CF netCDF `pics.nc` (`dataset`).
//!
//! A runnable example of the library API: `simulator/examples/pics.rs`.

use std::path::Path;

mod acquisitions;
pub mod catalogue;
mod dataset;

pub use acquisitions::{parse_acquisitions, read_acquisitions, Acquisition};
pub use dataset::{fill as fill_netcdf, times as acquisition_times, write_netcdf};

use crate::products::{band_rows, rows};
use engine::config::Experiment;
use engine::error::ConfigError;

/// The simulated result of one acquisition.
#[derive(Clone, Debug)]
pub struct PicsRow {
    pub acquisition: Acquisition,
    pub sza: f64,
    pub saa: f64,
    pub earth_sun_distance_au: f64,
    /// Band TOA reflectance π L/(E0 cos SZA) and its standard error.
    pub reflectance: (f64, f64),
    /// Band TOA radiance (W m⁻² sr⁻¹ nm⁻¹) and its standard error.
    pub radiance: (f64, f64),
    pub band_irradiance: f64,
}

/// The experiment text of one acquisition at a site (the site file's tables are kept verbatim).
pub fn experiment_text(site: &toml::Table, acq: &Acquisition, seed: u64) -> Result<String, String> {
    let get_f = |k: &str| {
        site.get(k)
            .and_then(|v| v.as_float().or_else(|| v.as_integer().map(|i| i as f64)))
    };
    let lat = get_f("latitude").ok_or("`latitude` (deg) is required")?;
    let lon = get_f("longitude").ok_or("`longitude` (deg) is required")?;
    let elev = get_f("elevation").unwrap_or(0.0);
    let spp = site
        .get("spp")
        .and_then(|v| v.as_integer())
        .unwrap_or(200_000);
    let mode = match site.get("mode") {
        None => "mono",
        Some(v) => v.as_str().ok_or("`mode` must be a string")?,
    };
    let step = get_f("wavelength_step");
    if mode == "ckd" && step.is_some() {
        return Err(
            "`wavelength_step` is not used with mode = \"ckd\": the absorption data's bins sample each band"
                .into(),
        );
    }
    let known = [
        "name",
        "mode",
        "integrator",
        "latitude",
        "longitude",
        "elevation",
        "spp",
        "target_rel_stderr",
        "wavelength_step",
        "irradiance",
        "geometry",
        "atmosphere",
        "surface",
        "scene",
        "target_m",
        "target_height_m",
        "polarized",
    ];
    if let Some(k) = site.keys().find(|k| !known.contains(&k.as_str())) {
        return Err(format!("unknown key `{k}` (known: {})", known.join(", ")));
    }
    let mut t = toml::Table::new();
    t.insert("mode".into(), toml::Value::String(mode.into()));
    t.insert("seed".into(), toml::Value::Integer(seed as i64));
    if let Some(p) = site.get("polarized") {
        t.insert("polarized".into(), p.clone());
    }
    let mut spectral = toml::Table::new();
    spectral.insert("srf".into(), toml::Value::String(acq.srf.clone()));
    if mode != "ckd" {
        spectral.insert(
            "wavelength_step".into(),
            toml::Value::Float(step.unwrap_or(5.0)),
        );
    }
    t.insert("spectral".into(), toml::Value::Table(spectral));
    for k in ["geometry", "atmosphere", "surface", "scene", "integrator"] {
        if let Some(v) = site.get(k) {
            t.insert(k.into(), v.clone());
        }
    }
    let mut ill = toml::Table::new();
    ill.insert("type".into(), toml::Value::String("directional".into()));
    match acq.sun {
        None => {
            ill.insert("time".into(), toml::Value::String(acq.time_utc.clone()));
            ill.insert("latitude".into(), toml::Value::Float(lat));
            ill.insert("longitude".into(), toml::Value::Float(lon));
            ill.insert("elevation".into(), toml::Value::Float(elev));
        }
        Some((sza, saa)) => {
            // The user's Sun angles; the Earth–Sun distance still comes from SPA at the time.
            let p =
                engine::sources::sun_position::sun_position(&acq.time_utc, lat, lon, elev, None)
                    .map_err(|e| e.to_string())?;
            ill.insert("zenith".into(), toml::Value::Float(sza));
            ill.insert("azimuth".into(), toml::Value::Float(saa));
            ill.insert("distance_au".into(), toml::Value::Float(p.distance_au));
        }
    }
    if let Some(i) = site.get("irradiance") {
        ill.insert("irradiance".into(), i.clone());
    }
    t.insert("illumination".into(), toml::Value::Table(ill));
    let mut m = toml::Table::new();
    m.insert("id".into(), toml::Value::String("toa".into()));
    m.insert("type".into(), toml::Value::String("mdistant".into()));
    m.insert("construct".into(), toml::Value::String("directions".into()));
    m.insert(
        "zeniths".into(),
        toml::Value::Array(vec![toml::Value::Float(acq.vza)]),
    );
    m.insert(
        "azimuths".into(),
        toml::Value::Array(vec![toml::Value::Float(acq.vaa)]),
    );
    for k in ["target_m", "target_height_m"] {
        if let Some(v) = site.get(k) {
            m.insert(k.into(), v.clone());
        }
    }
    m.insert("spp".into(), toml::Value::Integer(spp));
    if let Some(x) = site.get("target_rel_stderr") {
        m.insert("target_rel_stderr".into(), x.clone());
    }
    t.insert(
        "measures".into(),
        toml::Value::Array(vec![toml::Value::Table(m)]),
    );
    toml::to_string(&t).map_err(|e| e.to_string())
}

/// A site file's `catalogue = "KEY"`: the catalogued site's name, coordinates (and elevation and
/// surface when catalogued, `catalogue.rs`), with the file's own keys on top.
pub fn with_catalogue(mut site: toml::Table) -> Result<toml::Table, String> {
    let Some(v) = site.remove("catalogue") else {
        return Ok(site);
    };
    let key = v
        .as_str()
        .ok_or("`catalogue` must be a site key such as \"libya4\"")?;
    let entry = crate::pics::catalogue::find(key)?;
    Ok(crate::pics::catalogue::site_table(&entry, &site))
}

/// Read a site file (`catalogue` resolved); a catalogue key given instead of a file is told how
/// to write one.
pub fn load_site(site_path: &Path) -> Result<toml::Table, ConfigError> {
    let text = match std::fs::read_to_string(site_path) {
        Ok(t) => t,
        Err(source) => {
            // A catalogue key instead of a file: say how to use it.
            if let Ok(entry) = crate::pics::catalogue::find(&site_path.display().to_string()) {
                return Err(ConfigError::Invalid {
                    path: site_path.into(),
                    key: "site".into(),
                    message: format!(
                        "\"{}\" is the catalogue site {} ({} N, {} E), but a run needs a surface and \
                         an atmosphere: write a site file with `catalogue = \"{}\"` and its [surface] \
                         and [atmosphere] tables (docs/pics.md; examples/pics/libya4_site.toml)",
                        site_path.display(),
                        entry.name,
                        entry.latitude,
                        entry.longitude,
                        entry.key
                    ),
                });
            }
            return Err(ConfigError::Read {
                path: site_path.into(),
                source,
            });
        }
    };
    let site: toml::Table = text
        .parse()
        .map_err(|e: toml::de::Error| ConfigError::Parse {
            path: site_path.into(),
            message: e.to_string(),
        })?;
    with_catalogue(site).map_err(|message| ConfigError::Invalid {
        path: site_path.into(),
        key: "catalogue".into(),
        message,
    })
}

/// Whether a TOML document is a PICS site file rather than an experiment: it places the site
/// (`latitude` or `catalogue`) and has neither `[illumination]` nor `[[measures]]`.
pub fn is_site_file(doc: &toml::Table) -> bool {
    (doc.contains_key("latitude") || doc.contains_key("catalogue"))
        && !doc.contains_key("illumination")
        && !doc.contains_key("measures")
}

/// The experiment of acquisition `k` (0-based; seed `k`) at a loaded site; errors name the site
/// file and the acquisition.
pub fn acquisition_experiment(
    site: &toml::Table,
    site_path: &Path,
    acq: &Acquisition,
    k: usize,
) -> Result<Experiment, ConfigError> {
    let exp_text =
        experiment_text(site, acq, k as u64).map_err(|message| ConfigError::Invalid {
            path: site_path.into(),
            key: "site".into(),
            message,
        })?;
    Experiment::from_str(&exp_text, site_path).map_err(|e| ConfigError::Invalid {
        path: site_path.into(),
        key: format!(
            "acquisition {} ({}{})",
            k + 1,
            acq.time_utc,
            if acq.sun.is_some() {
                "; sza, saa from the acquisitions file"
            } else {
                ""
            }
        ),
        message: e.to_string(),
    })
}

/// The acquisition `simulate check` validates a site file with when no acquisitions are given:
/// Sentinel-2A band 4, nadir view, the Sun at 30° zenith (so that any site has daylight).
pub fn sample_acquisition() -> Acquisition {
    Acquisition {
        time_utc: "2020-06-21T10:00:00Z".into(),
        vza: 0.0,
        vaa: 0.0,
        srf: "sentinel_2a-msi-4".into(),
        sun: Some((30.0, 150.0)),
    }
}

/// Validate a site file without running: every acquisition's experiment (or the
/// `sample_acquisition`'s) resolves. Returns the resolved site table.
pub fn check_site(
    site_path: &Path,
    acquisitions: Option<&[Acquisition]>,
) -> Result<toml::Table, ConfigError> {
    let site = load_site(site_path)?;
    let sample = [sample_acquisition()];
    for (k, acq) in acquisitions.unwrap_or(&sample).iter().enumerate() {
        acquisition_experiment(&site, site_path, acq, k)?;
    }
    Ok(site)
}

/// Run every acquisition; `site_path` names the site file in errors. Acquisition `k` uses seed
/// `k`, so results do not depend on the order of other acquisitions or on threads.
pub fn run(
    site_path: &Path,
    acquisitions: &[Acquisition],
    progress: impl Fn(usize),
) -> Result<Vec<PicsRow>, ConfigError> {
    let site = load_site(site_path)?;
    let never = std::sync::atomic::AtomicBool::new(false);
    Ok(run_site(&site, site_path, acquisitions, progress, &never)?
        .expect("a run without cancellation completes"))
}

/// [`run`] of a loaded site table ([`load_site`], or a table built in memory; `site_path` names
/// it in errors and anchors its relative paths), checking `cancel` between and inside
/// acquisitions: `Ok(None)` once it is set.
pub fn run_site(
    site: &toml::Table,
    site_path: &Path,
    acquisitions: &[Acquisition],
    progress: impl Fn(usize),
    cancel: &std::sync::atomic::AtomicBool,
) -> Result<Option<Vec<PicsRow>>, ConfigError> {
    let mut out = Vec::with_capacity(acquisitions.len());
    // Keeps a 3D site's scene alive, so that every acquisition reuses it (built once).
    let mut _scene: Option<std::sync::Arc<engine::scene::Scene>> = None;
    for (k, acq) in acquisitions.iter().enumerate() {
        let exp = acquisition_experiment(site, site_path, acq, k)?;
        if _scene.is_none() {
            _scene = exp.scene.clone();
        }
        let bar = indicatif::ProgressBar::hidden();
        let Some(res) = crate::run::run_cancellable(&exp, &bar, cancel) else {
            return Ok(None);
        };
        let r = rows(&exp, &res);
        let b = band_rows(&exp, &r);
        let Some(band) = b.first() else {
            return Err(ConfigError::Invalid {
                path: site_path.into(),
                key: format!("acquisition {} ({})", k + 1, acq.time_utc),
                message: "the experiment gave no band result (is the band covered?)".into(),
            });
        };
        let d = exp.sun_distance_au.unwrap_or(f64::NAN);
        out.push(PicsRow {
            acquisition: acq.clone(),
            sza: exp.sun_zenith_deg,
            saa: exp.sun_azimuth_deg,
            earth_sun_distance_au: d,
            reflectance: band.brf.unwrap_or((f64::NAN, f64::NAN)),
            radiance: band.radiance.unwrap_or((f64::NAN, f64::NAN)),
            band_irradiance: band.irradiance,
        });
        progress(k + 1);
    }
    Ok(Some(out))
}

/// `pics.csv`: one row per acquisition.
pub fn to_csv(rows: &[PicsRow]) -> String {
    use std::fmt::Write;
    let mut s = String::from(
        "time_utc,srf,vza,vaa,sza,saa,earth_sun_distance_au,reflectance,reflectance_stderr,radiance,radiance_stderr,band_irradiance\n",
    );
    for r in rows {
        let a = &r.acquisition;
        let _ = writeln!(
            s,
            "{},{},{},{},{:.6},{:.6},{:.9},{:.8e},{:.3e},{:.8e},{:.3e},{:.8e}",
            a.time_utc,
            csv_field(&a.srf),
            a.vza,
            a.vaa,
            r.sza,
            r.saa,
            r.earth_sun_distance_au,
            r.reflectance.0,
            r.reflectance.1,
            r.radiance.0,
            r.radiance.1,
            r.band_irradiance
        );
    }
    s
}

/// A CSV field, quoted (RFC 4180) when it holds a comma, a quote or a line break: an SRF file
/// name may.
fn csv_field(v: &str) -> String {
    if v.contains([',', '"', '\n', '\r']) {
        format!("\"{}\"", v.replace('"', "\"\""))
    } else {
        v.to_string()
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn csv_fields_are_quoted_when_needed() {
        assert_eq!(super::csv_field("sentinel_2a-msi-4"), "sentinel_2a-msi-4");
        assert_eq!(
            super::csv_field("my, \"srf\".csv"),
            "\"my, \"\"srf\"\".csv\""
        );
    }
}
