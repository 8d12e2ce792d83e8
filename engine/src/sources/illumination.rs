//! The `[illumination]` table of the experiment file (raw serde type) and its resolution into
//! the Sun of a run: its direction (given, or from a time and place with `sun_position`), its
//! distance, and the solar irradiance at every run wavelength (`solar`). Keys and units are
//! documented in `docs/experiment.md`; angles in degrees there, radians here.

use glam::DVec3;
use serde::Deserialize;

use crate::error::{ConfigCtx, ConfigError};
use crate::frame::direction_from_angles;
use crate::sources::sun_position::sun_position;
use crate::spectral::solar::{day_of_year, earth_sun_factor, Spectrum as SolarSpectrum};
use crate::spectral::{Spectrum, SpectrumExt};

#[derive(Clone, Debug, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
pub enum IlluminationConfig {
    Directional {
        /// degrees, [0, 90) (or from `time` and the place).
        #[serde(default)]
        zenith: Option<f64>,
        /// degrees, clockwise from North.
        #[serde(default)]
        azimuth: Option<f64>,
        /// RFC 3339 time (any offset, converted to UTC): the Sun's position (NREL SPA) at `latitude`/`longitude`.
        #[serde(default)]
        time: Option<String>,
        /// degrees north.
        #[serde(default)]
        latitude: Option<f64>,
        /// degrees east.
        #[serde(default)]
        longitude: Option<f64>,
        /// m above sea level.
        #[serde(default)]
        elevation: Option<f64>,
        /// W m⁻² nm⁻¹, normal to the beam: a number, a list, or a spectrum name / file.
        #[serde(default = "one_irradiance")]
        irradiance: IrradianceValue,
        /// "YYYY-MM-DD": scale the irradiance by the Earth–Sun distance of that day.
        #[serde(default)]
        date: Option<String>,
        /// AU: scale the irradiance by 1/r² for this Earth–Sun distance (with `zenith`; e.g. a
        /// PICS acquisition whose Sun angles are given, its distance from SPA at its time).
        #[serde(default)]
        distance_au: Option<f64>,
        /// With `time`: the Moon at the same time and place shines as well (twilight), its
        /// irradiance from the lunar model on this `irradiance` (at 1 AU), or `moon_irradiance`.
        #[serde(default)]
        moon: bool,
        /// W m⁻² nm⁻¹ normal to the Moon's beam, with `moon = true`: a lunar spectrum used as
        /// given (numbers, built-in name or CSV file).
        #[serde(default)]
        moon_irradiance: Option<IrradianceValue>,
    },
    /// The Moon as the source (`moon.rs`): its position for a time and place, its irradiance
    /// from a lunar spectrum or the grey magnitude law with its phase dependence.
    Moon {
        /// RFC 3339 time (any offset, converted to UTC).
        time: String,
        /// degrees north.
        latitude: f64,
        /// degrees east.
        longitude: f64,
        /// m above the ellipsoid.
        #[serde(default)]
        elevation: Option<f64>,
        /// W m⁻² nm⁻¹ normal to the beam: a lunar irradiance spectrum used as given (number,
        /// list, built-in name or CSV file). Default: the magnitude law times `solar_spectrum`.
        #[serde(default)]
        irradiance: Option<IrradianceValue>,
        /// The solar spectrum the magnitude law scales (default "thuillier_2003").
        #[serde(default)]
        solar_spectrum: Option<String>,
    },
    /// No Sun: thermal emission only (`emission = true`). Radiances are then normalised by a
    /// nominal irradiance of 1 (no BRF).
    None {},
}

/// Solar irradiance: numbers, or the name of a built-in spectrum / a CSV file.
#[derive(Clone, Debug, Deserialize)]
#[serde(untagged)]
pub enum IrradianceValue {
    Value(Spectrum),
    Spectrum(String),
}

fn one_irradiance() -> IrradianceValue {
    IrradianceValue::Value(Spectrum::Constant(1.0))
}

/// The Sun of a run.
#[derive(Clone, Debug)]
pub struct Sun {
    /// Solar zenith as given (or computed), degrees.
    pub zenith_deg: f64,
    /// Solar azimuth, degrees clockwise from North, in [0, 360).
    pub azimuth_deg: f64,
    /// Unit vector from the target towards the Sun.
    pub dir: DVec3,
    /// Earth–Sun distance (AU) when the Sun comes from `time` (or `date`).
    pub distance_au: Option<f64>,
    /// E0 at each run wavelength (W m⁻² nm⁻¹), scaled to the Earth–Sun distance when known;
    /// without a Sun, a nominal 1 (the unit of the tallies).
    pub irradiance: Vec<f64>,
    /// Whether there is a Sun at all (`type = "none"`: false; the direction is then the
    /// zenith, a placeholder).
    pub shines: bool,
    /// The Moon shining with the Sun (`moon = true`), if it does.
    pub moon: Option<Moonlight>,
}

/// The Moon as a second source beside the Sun (`[illumination] moon = true`).
#[derive(Clone, Debug, PartialEq)]
pub struct Moonlight {
    /// Lunar zenith (up to 180° in spherical shells) and azimuth (clockwise from North, in
    /// [0, 360)), degrees.
    pub zenith_deg: f64,
    pub azimuth_deg: f64,
    /// Unit vector from the target towards the Moon.
    pub dir: DVec3,
    /// The Moon's irradiance normal to its beam at each run wavelength, W m⁻² nm⁻¹.
    pub irradiance: Vec<f64>,
}

impl IlluminationConfig {
    /// The Sun at the run `wavelengths` (nm). `spherical`: a spherical-shell atmosphere, where
    /// the Sun may be below the horizon (zenith up to 180°).
    pub fn resolve(
        &self,
        ctx: &ConfigCtx,
        wavelengths: &[f64],
        spherical: bool,
    ) -> Result<Sun, ConfigError> {
        if let IlluminationConfig::Moon {
            time,
            latitude,
            longitude,
            elevation,
            irradiance,
            solar_spectrum,
        } = self
        {
            return resolve_moon(
                ctx,
                wavelengths,
                spherical,
                time,
                (*latitude, *longitude, elevation.unwrap_or(0.0)),
                irradiance.as_ref(),
                solar_spectrum.as_deref(),
            );
        }
        let IlluminationConfig::Directional {
            zenith,
            azimuth,
            irradiance,
            date,
            time,
            latitude,
            longitude,
            elevation,
            distance_au: given_distance,
            moon,
            moon_irradiance,
        } = self
        else {
            return Ok(Sun {
                zenith_deg: 0.0,
                azimuth_deg: 0.0,
                dir: DVec3::Z,
                distance_au: None,
                irradiance: vec![1.0; wavelengths.len()],
                shines: false,
                moon: None,
            });
        };
        let (zenith, azimuth, distance_from_time) = sun_angles(
            ctx,
            time,
            zenith,
            azimuth,
            date,
            Place {
                latitude: *latitude,
                longitude: *longitude,
                elevation: *elevation,
            },
        )?;
        let sun_distance_factor = distance_from_time.map(|d| 1.0 / (d * d));
        let (zenith, azimuth) = check_sun_angles(ctx, zenith, azimuth, spherical)?;
        let mut irradiance =
            irradiance_at(ctx, "illumination.irradiance", irradiance, wavelengths)?;
        let (sun_distance_factor, distance_au) = sun_distance(
            ctx,
            given_distance,
            time,
            date,
            (sun_distance_factor, distance_from_time),
        )?;
        let moonlight = match (moon, time) {
            (false, _) => {
                if moon_irradiance.is_some() {
                    return Err(ctx.err(
                        "illumination.moon_irradiance",
                        "is used only with `moon = true`",
                    ));
                }
                None
            }
            (true, None) => {
                return Err(ctx.err(
                    "illumination.moon",
                    "needs `time` with `latitude` and `longitude` (the Moon's position is computed for that time and place)",
                ))
            }
            (true, Some(t)) => Some(moon_at(
                ctx,
                wavelengths,
                spherical,
                t,
                (
                    latitude.unwrap_or(0.0),
                    longitude.unwrap_or(0.0),
                    elevation.unwrap_or(0.0),
                ),
                "illumination.moon",
                ("moon_irradiance", moon_irradiance.as_ref()),
                || Ok(irradiance.clone()),
            )?),
        };
        if let Some(k) = sun_distance_factor {
            irradiance.iter_mut().for_each(|e| *e *= k);
        }
        if moonlight.is_some() {
            if let Some((w, e)) = wavelengths
                .iter()
                .zip(&irradiance)
                .find(|(_, e)| **e <= 0.0)
            {
                return Err(ctx.err(
                    "illumination.irradiance",
                    format!("is {e} at {w} nm: with `moon = true` the Sun's irradiance must be positive at every wavelength (the Moon's light is carried in units of the Sun's)"),
                ));
            }
        }
        let azimuth_deg = azimuth.rem_euclid(360.0);
        Ok(Sun {
            zenith_deg: zenith,
            azimuth_deg,
            dir: direction_from_angles(zenith.to_radians(), azimuth_deg.to_radians()),
            distance_au,
            irradiance,
            shines: true,
            moon: moonlight,
        })
    }
}

/// The place of a Sun given by `time`: `latitude`, `longitude` and `elevation` as given.
#[derive(Clone, Copy, Debug)]
struct Place {
    latitude: Option<f64>,
    longitude: Option<f64>,
    elevation: Option<f64>,
}

/// The Sun's zenith and azimuth (degrees, not yet range-checked) from `time` and place (NREL
/// SPA; then also its distance, AU) or as given.
fn sun_angles(
    ctx: &ConfigCtx,
    time: &Option<String>,
    zenith: &Option<f64>,
    azimuth: &Option<f64>,
    date: &Option<String>,
    place: Place,
) -> Result<(f64, f64, Option<f64>), ConfigError> {
    let Place {
        latitude,
        longitude,
        elevation,
    } = place;
    Ok(match (time, zenith) {
        (Some(t), None) => {
            if azimuth.is_some() {
                return Err(ctx.err(
                    "illumination.azimuth",
                    "is computed from `time`; give one or the other",
                ));
            }
            if date.is_some() {
                return Err(ctx.err(
                    "illumination.date",
                    "is implied by `time`; give one or the other",
                ));
            }
            let lat = latitude
                .ok_or_else(|| ctx.err("illumination.latitude", "is required with `time`"))?;
            let lon = longitude
                .ok_or_else(|| ctx.err("illumination.longitude", "is required with `time`"))?;
            let p = sun_position(
                t,
                ctx.finite("illumination.latitude", lat)?,
                ctx.finite("illumination.longitude", lon)?,
                elevation.unwrap_or(0.0),
                None,
            )
            .map_err(|e| ctx.err("illumination.time", e.to_string()))?;
            tracing::debug!(
                "Sun at {t}: zenith {:.4}°, azimuth {:.4}°, distance {:.6} AU",
                p.zenith,
                p.azimuth,
                p.distance_au
            );
            (p.zenith, p.azimuth, Some(p.distance_au))
        }
        (None, Some(z)) => {
            if latitude.is_some() || longitude.is_some() || elevation.is_some() {
                return Err(ctx.err(
                    "illumination",
                    "`latitude`/`longitude`/`elevation` are used only with `time`",
                ));
            }
            (*z, azimuth.unwrap_or(0.0), None)
        }
        (Some(_), Some(_)) => {
            return Err(ctx.err(
                "illumination.zenith",
                "give either `zenith` (and `azimuth`) or `time` with a place, not both",
            ))
        }
        (None, None) => {
            return Err(ctx.err(
                "illumination",
                "give `zenith` (and `azimuth`), or `time` with `latitude` and `longitude`",
            ))
        }
    })
}

/// Check the Sun's zenith (beyond 90° only in spherical shells) and azimuth, degrees.
fn check_sun_angles(
    ctx: &ConfigCtx,
    zenith: f64,
    azimuth: f64,
    spherical: bool,
) -> Result<(f64, f64), ConfigError> {
    let zenith = ctx.finite("illumination.zenith", zenith)?;
    if !spherical && !(0.0..90.0).contains(&zenith) {
        return Err(ctx.err("illumination.zenith", format!("{zenith} degrees must lie in [0, 90) (a plane-parallel atmosphere has no twilight; use geometry.type = \"spherical_shell\")")));
    }
    if !(0.0..=180.0).contains(&zenith) {
        return Err(ctx.err(
            "illumination.zenith",
            format!("{zenith} degrees must lie in [0, 180]"),
        ));
    }
    let azimuth = ctx.finite("illumination.azimuth", azimuth)?;
    if !(-360.0..=360.0).contains(&azimuth) {
        return Err(ctx.err(
            "illumination.azimuth",
            format!("{azimuth} degrees must lie in [-360, 360]"),
        ));
    }
    Ok((zenith, azimuth))
}

/// The irradiance factor 1/r² and the Earth–Sun distance r (AU): `from_time`'s, or r as given
/// (`distance_au`) or implied by `date`.
fn sun_distance(
    ctx: &ConfigCtx,
    given_distance: &Option<f64>,
    time: &Option<String>,
    date: &Option<String>,
    from_time: (Option<f64>, Option<f64>),
) -> Result<(Option<f64>, Option<f64>), ConfigError> {
    let (mut sun_distance_factor, mut distance_au) = from_time;
    if let Some(d) = given_distance {
        if time.is_some() || date.is_some() {
            return Err(ctx.err(
                "illumination.distance_au",
                "is implied by `time` or `date`; give one of the three",
            ));
        }
        let d = ctx.finite("illumination.distance_au", *d)?;
        if !(0.9..=1.1).contains(&d) {
            return Err(ctx.err(
                "illumination.distance_au",
                format!("{d} AU must lie in [0.9, 1.1] (the Earth's orbit)"),
            ));
        }
        sun_distance_factor = Some(1.0 / (d * d));
        distance_au = Some(d);
    }
    if let Some(d) = date {
        let doy = day_of_year(d).map_err(|e| ctx.err("illumination.date", e.to_string()))?;
        sun_distance_factor = Some(earth_sun_factor(doy));
        distance_au = Some(1.0 / earth_sun_factor(doy).sqrt());
    }
    Ok((sun_distance_factor, distance_au))
}

/// E0 at each run wavelength from an irradiance value (numbers, a built-in spectrum or a CSV
/// file) given at `key`, W m⁻² nm⁻¹.
fn irradiance_at(
    ctx: &ConfigCtx,
    key: &str,
    irradiance: &IrradianceValue,
    wavelengths: &[f64],
) -> Result<Vec<f64>, ConfigError> {
    Ok(match irradiance {
        IrradianceValue::Value(v) => v.expand(ctx, key, 0.0, 1e9)?,
        IrradianceValue::Spectrum(name) => {
            let spectrum = match SolarSpectrum::builtin(name) {
                Some(s) => s,
                None => {
                    let fpath = ctx.file(name);
                    let text = std::fs::read_to_string(&fpath).map_err(|e| {
                            ctx.err(key, format!("\"{name}\" is neither a built-in spectrum (\"tsis_1\", \"thuillier_2003\") nor a readable file ({}: {e})", fpath.display()))
                        })?;
                    SolarSpectrum::from_csv(name, &text)
                        .map_err(|e| ctx.err(key, format!("{}: {e}", fpath.display())))?
                }
            };
            wavelengths
                .iter()
                .map(|&w| {
                    spectrum.at(w).ok_or_else(|| {
                        ctx.err(
                            key,
                            format!(
                                "wavelength {w} nm is outside the spectrum \"{name}\" ({}–{} nm)",
                                spectrum.wavelength[0],
                                spectrum.wavelength[spectrum.wavelength.len() - 1]
                            ),
                        )
                    })
                })
                .collect::<Result<Vec<f64>, _>>()?
        }
    })
}

/// The Moon at `time` and place (both Moon keys): its position (refused below the horizon of a
/// plane-parallel run, an error at `key`) and its irradiance at the run wavelengths, `given` as
/// (key, lunar spectrum) or the lunar magnitude law applied to the solar spectrum at 1 AU that
/// `solar_1au` reads (a phase beyond the law is an error at `key` asking for the given key).
#[allow(clippy::too_many_arguments)]
fn moon_at(
    ctx: &ConfigCtx,
    wavelengths: &[f64],
    spherical: bool,
    time: &str,
    (lat, lon, elevation): (f64, f64, f64),
    key: &str,
    given: (&str, Option<&IrradianceValue>),
    solar_1au: impl FnOnce() -> Result<Vec<f64>, ConfigError>,
) -> Result<Moonlight, ConfigError> {
    let lat = ctx.finite("illumination.latitude", lat)?;
    let lon = ctx.finite("illumination.longitude", lon)?;
    let elevation = ctx.finite("illumination.elevation", elevation)?;
    let p = crate::sources::moon::moon_position(time, lat, lon, elevation)
        .map_err(|e| ctx.err("illumination.time", e.to_string()))?;
    tracing::info!(
        "Moon at {time}: zenith {:.4}°, azimuth {:.4}°, phase angle {:.2}°, distance {:.0} km",
        p.zenith,
        p.azimuth,
        p.phase_angle,
        p.distance_km
    );
    if !spherical && p.zenith >= 90.0 {
        return Err(ctx.err(
            key,
            format!("the Moon is below the horizon at {time} (zenith {:.2}°); a plane-parallel atmosphere has no twilight (use geometry.type = \"spherical_shell\")", p.zenith),
        ));
    }
    let (given_key, given) = given;
    let irradiance = match given {
        Some(v) => irradiance_at(ctx, &format!("illumination.{given_key}"), v, wavelengths)?,
        None => {
            let ratio = crate::sources::moon::irradiance_ratio(&p).map_err(|e| {
                ctx.err(
                    key,
                    e.to_string()
                        .replace("give `irradiance`", &format!("give `{given_key}`")),
                )
            })?;
            solar_1au()?.into_iter().map(|e| e * ratio).collect()
        }
    };
    Ok(Moonlight {
        zenith_deg: p.zenith,
        azimuth_deg: p.azimuth,
        dir: direction_from_angles(p.zenith.to_radians(), p.azimuth.to_radians()),
        irradiance,
    })
}

/// `type = "moon"`: the Moon's position at `time` and place, and its irradiance (given, or the
/// lunar model on `solar_spectrum`).
fn resolve_moon(
    ctx: &ConfigCtx,
    wavelengths: &[f64],
    spherical: bool,
    time: &str,
    place: (f64, f64, f64),
    irradiance: Option<&IrradianceValue>,
    solar_spectrum: Option<&str>,
) -> Result<Sun, ConfigError> {
    if irradiance.is_some() && solar_spectrum.is_some() {
        return Err(ctx.err(
            "illumination.solar_spectrum",
            "is used only by the lunar model, not with a given `irradiance`",
        ));
    }
    let m = moon_at(
        ctx,
        wavelengths,
        spherical,
        time,
        place,
        "illumination.time",
        ("irradiance", irradiance),
        || {
            let name = solar_spectrum.unwrap_or("thuillier_2003").to_string();
            let spectrum = IrradianceValue::Spectrum(name);
            irradiance_at(ctx, "illumination.solar_spectrum", &spectrum, wavelengths)
        },
    )?;
    Ok(Sun {
        zenith_deg: m.zenith_deg,
        azimuth_deg: m.azimuth_deg,
        dir: m.dir,
        distance_au: None,
        irradiance: m.irradiance,
        shines: true,
        moon: None,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sun(text: &str) -> Result<Sun, ConfigError> {
        let cfg: IlluminationConfig = toml::from_str(text).unwrap();
        let ctx = ConfigCtx {
            path: std::path::Path::new("exp.toml"),
            base: std::path::Path::new("."),
            nw: 1,
            wavelengths: &[550.0],
        };
        cfg.resolve(&ctx, &[550.0], false)
    }

    /// `distance_au` scales E0 by 1/r² with given angles (a PICS acquisition with its own Sun
    /// angles), and excludes `time` and `date`.
    #[test]
    fn distance_au_scales_the_irradiance() {
        let s =
            sun("type = \"directional\"\nzenith = 30.0\nirradiance = 2.0\ndistance_au = 1.01\n")
                .unwrap();
        assert_eq!(s.distance_au, Some(1.01));
        assert!((s.irradiance[0] - 2.0 / (1.01 * 1.01)).abs() < 1e-15);
        for bad in [
            "type = \"directional\"\nzenith = 30.0\ndistance_au = 1.5\n",
            "type = \"directional\"\nzenith = 30.0\ndistance_au = 1.0\ndate = \"2026-01-01\"\n",
            "type = \"directional\"\ntime = \"2026-01-01T12:00:00Z\"\nlatitude = 0.0\nlongitude = 0.0\ndistance_au = 1.0\n",
        ] {
            let e = sun(bad).unwrap_err().to_string();
            assert!(e.contains("exp.toml") && e.contains("distance_au"), "{e}");
        }
    }
}
