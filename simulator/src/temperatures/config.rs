//! The temperature solver's file (`simulate temperatures FILE.toml`; keys in
//! `docs/temperatures.md`): raw serde types and their checks, each error naming its key.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use engine::temperature::slab::{Bottom, Layer};
use engine::temperature::{preset, ThermalMaterial, PRESETS};
use serde::Deserialize;

/// The whole file.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TemperatureConfig {
    /// The day, "YYYY-MM-DD" (repeated until its temperatures are periodic).
    pub date: String,
    /// Offset of the local clock from UTC, "+02:00", "-05:00" or "Z".
    #[serde(default = "utc")]
    pub utc_offset: String,
    /// Degrees north and east (default: the bundle's centre).
    #[serde(default)]
    pub latitude: Option<f64>,
    #[serde(default)]
    pub longitude: Option<f64>,
    /// Local clock times of the LST rasters, "HH:MM".
    pub times: Vec<String>,
    #[serde(default = "ten")]
    pub step_minutes: f64,
    #[serde(default = "sixty")]
    pub max_days: usize,
    #[serde(default = "hundredth")]
    pub tolerance_k: f64,
    pub weather: Weather,
    #[serde(default)]
    pub shortwave: Shortwave,
    #[serde(default)]
    pub scene: Option<SceneRef>,
    /// Thermal description per material name: a preset name or a table.
    #[serde(default)]
    pub materials: BTreeMap<String, MaterialSpec>,
}

fn utc() -> String {
    "Z".into()
}
fn ten() -> f64 {
    10.0
}
fn sixty() -> usize {
    60
}
fn hundredth() -> f64 {
    0.01
}

/// The day's weather (fair, repeating).
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Weather {
    /// The day's lowest and highest air temperature, K.
    pub air_temperature_k: [f64; 2],
    /// Local solar hour of the highest air temperature.
    #[serde(default = "fifteen")]
    pub hour_of_max: f64,
    /// 0–1.
    #[serde(default = "half")]
    pub relative_humidity: f64,
    /// m s⁻¹.
    #[serde(default = "two")]
    pub wind_speed_m_s: f64,
    /// K per km: the air cools by this much per km above `reference_altitude_m`.
    #[serde(default = "six_and_a_half")]
    pub lapse_rate_k_per_km: f64,
    /// m above sea level where the air has `air_temperature_k` (default: the bundle's mean
    /// terrain height).
    #[serde(default)]
    pub reference_altitude_m: Option<f64>,
}

fn six_and_a_half() -> f64 {
    6.5
}

fn fifteen() -> f64 {
    15.0
}
fn half() -> f64 {
    0.5
}
fn two() -> f64 {
    2.0
}

/// How the broadband sunlight and sky light at the ground are computed.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Shortwave {
    /// Wavelengths (nm) at which the atmosphere's transmittances are computed; the broadband
    /// irradiances are their trapezoid integrals scaled to the total solar irradiance.
    #[serde(default = "default_wavelengths")]
    pub wavelengths: Vec<f64>,
    /// With two `wavelengths` [first, last]: sample every this many nm between them.
    #[serde(default)]
    pub wavelength_step: Option<f64>,
    /// Samples per flux computation.
    #[serde(default = "default_spp")]
    pub spp: u64,
    /// Albedo of the ground under the sky runs and of the surroundings a facet sees.
    #[serde(default = "fifth")]
    pub surround_albedo: f64,
    /// `"mono"` or `"ckd"` (the experiment file's `mode`).
    #[serde(default)]
    pub mode: Option<String>,
    /// The experiment file's `[atmosphere]` table (default: the AFGL US standard molecular
    /// atmosphere).
    #[serde(default)]
    pub atmosphere: Option<toml::Table>,
    #[serde(default)]
    pub seed: u64,
}

impl Default for Shortwave {
    fn default() -> Self {
        Shortwave {
            wavelengths: default_wavelengths(),
            wavelength_step: None,
            spp: default_spp(),
            surround_albedo: fifth(),
            mode: None,
            atmosphere: None,
            seed: 0,
        }
    }
}

fn default_wavelengths() -> Vec<f64> {
    vec![
        320.0, 360.0, 400.0, 450.0, 500.0, 550.0, 600.0, 650.0, 700.0, 760.0, 800.0, 870.0, 940.0,
        1000.0, 1130.0, 1250.0, 1400.0, 1650.0, 1900.0, 2200.0, 2500.0, 2700.0,
    ]
}
fn default_spp() -> u64 {
    8192
}
fn fifth() -> f64 {
    0.2
}

/// The scene whose terrain gets temperatures.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SceneRef {
    /// A scene bundle folder.
    pub path: PathBuf,
    /// LST pixel size, m (default: the bundle's material raster's).
    #[serde(default)]
    pub pixel_size_m: Option<f64>,
    /// Rays per facet for its sky-view factor.
    #[serde(default = "sixty_four")]
    pub sky_rays: usize,
}

fn sixty_four() -> usize {
    64
}

/// A material's thermal description in the file.
#[derive(Clone, Debug, Deserialize)]
#[serde(untagged)]
pub enum MaterialSpec {
    Preset(String),
    Table(MaterialTable),
}

#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MaterialTable {
    #[serde(default)]
    pub preset: Option<String>,
    #[serde(default)]
    pub layers: Option<Vec<Layer>>,
    #[serde(default)]
    pub albedo: Option<f64>,
    #[serde(default)]
    pub emissivity: Option<f64>,
    /// Fraction of open-water evaporation, [0, 1].
    #[serde(default)]
    pub wetness: Option<f64>,
    /// K: hold the slab's bottom at this temperature (default: no heat through it).
    #[serde(default)]
    pub bottom_temperature_k: Option<f64>,
    /// K: the surface melts rather than warm past this (default: the preset's; snow 273.15).
    #[serde(default)]
    pub melting_point_k: Option<f64>,
}

/// The preset a material of scenegen's built-in land-cover schemes takes when the file does not
/// name it (docs/temperatures.md).
pub const SCENEGEN_DEFAULTS: &[(&str, &str)] = &[
    ("urban", "asphalt"),
    ("road", "asphalt"),
    ("rock", "rock"),
    ("soil", "dry_soil"),
    ("bare", "dry_soil"),
    ("sand", "dry_soil"),
    ("grass", "grass"),
    ("crop", "grass"),
    ("shrub", "grass"),
    ("wetland", "moist_soil"),
    ("forest_floor", "forest"),
    ("snow", "snow"),
    ("water", "water"),
    ("leaf", "leaf"),
    ("bark", "bark"),
    ("wall", "brick"),
    ("roof", "roof_tile"),
    ("ground", "dry_soil"),
];

/// A resolved material: its thermal model and where it came from (for the tables).
#[derive(Clone, Debug)]
pub struct Resolved {
    pub model: ThermalMaterial,
    pub source: String,
}

/// An error in the file, naming the key (exit status 2, as experiment files' errors).
pub type KeyError = engine::error::ConfigError;

pub fn key_error(path: &Path, key: &str, message: impl Into<String>) -> KeyError {
    engine::error::ConfigError::Invalid {
        path: path.to_path_buf(),
        key: key.to_string(),
        message: message.into(),
    }
}

fn preset_list() -> String {
    PRESETS
        .iter()
        .map(|(n, _)| *n)
        .collect::<Vec<_>>()
        .join(", ")
}

impl Shortwave {
    /// The wavelengths of the sky runs (nm).
    pub fn grid(&self) -> Vec<f64> {
        match (self.wavelength_step, self.wavelengths.as_slice()) {
            (Some(step), [a, b]) => {
                let n = ((b - a) / step + 1e-9).floor() as usize;
                (0..=n).map(|i| a + i as f64 * step).collect()
            }
            _ => self.wavelengths.clone(),
        }
    }
}

impl TemperatureConfig {
    /// Read and check `path`.
    pub fn load(path: &Path) -> Result<TemperatureConfig, KeyError> {
        let text = std::fs::read_to_string(path).map_err(|source| KeyError::Read {
            path: path.to_path_buf(),
            source,
        })?;
        let parse = |message: String| KeyError::Parse {
            path: path.to_path_buf(),
            message,
        };
        let de = toml::Deserializer::parse(&text).map_err(|e| parse(e.to_string()))?;
        let cfg: TemperatureConfig = serde_path_to_error::deserialize(de).map_err(|e| {
            let key = e.path().to_string();
            parse(format!("at key `{key}`: {}", e.into_inner()))
        })?;
        cfg.check(path)?;
        Ok(cfg)
    }

    fn check(&self, path: &Path) -> Result<(), KeyError> {
        let bad = |key: &str, message: String| Err(key_error(path, key, message));
        let positive = |v: f64| v.is_finite() && v > 0.0;
        if !(positive(self.step_minutes) && self.step_minutes <= 60.0)
            || (1440.0 / self.step_minutes).fract().abs() > 1e-9
        {
            return bad(
                "step_minutes",
                format!(
                    "{} must divide the day (1440 minutes) and be at most 60",
                    self.step_minutes
                ),
            );
        }
        if self.max_days == 0 || self.max_days > 3650 {
            return bad(
                "max_days",
                format!("{} must lie in 1..=3650", self.max_days),
            );
        }
        if !positive(self.tolerance_k) {
            return bad(
                "tolerance_k",
                format!("{} must be positive", self.tolerance_k),
            );
        }
        if chrono::NaiveDate::parse_from_str(&self.date, "%Y-%m-%d").is_err() {
            return bad(
                "date",
                format!("\"{}\" is not a calendar date YYYY-MM-DD", self.date),
            );
        }
        let offset = format!("2000-01-01T00:00:00{}", self.utc_offset);
        if chrono::DateTime::parse_from_rfc3339(&offset).is_err() {
            return bad(
                "utc_offset",
                format!(
                    "\"{}\" is not an offset from UTC (\"+02:00\", \"-05:00\" or \"Z\")",
                    self.utc_offset
                ),
            );
        }
        if self.times.is_empty() {
            return bad("times", "give at least one local time \"HH:MM\"".into());
        }
        for (i, t) in self.times.iter().enumerate() {
            if parse_clock(t).is_none() {
                return bad(
                    &format!("times[{i}]"),
                    format!("\"{t}\" is not a clock time HH:MM (00:00–23:59)"),
                );
            }
        }
        if let Some(v) = self.latitude {
            if !(-90.0..=90.0).contains(&v) {
                return bad("latitude", format!("{v} must lie in [-90, 90]"));
            }
        }
        if let Some(v) = self.longitude {
            if !(-180.0..=180.0).contains(&v) {
                return bad("longitude", format!("{v} must lie in [-180, 180]"));
            }
        }
        let w = &self.weather;
        let [lo, hi] = w.air_temperature_k;
        if !(lo.is_finite() && hi.is_finite() && lo > 150.0 && hi < 350.0 && lo <= hi) {
            return bad(
                "weather.air_temperature_k",
                format!("[{lo}, {hi}] must be [min, max] with 150 K < min ≤ max < 350 K"),
            );
        }
        if !(0.0..=24.0).contains(&w.hour_of_max) {
            return bad(
                "weather.hour_of_max",
                format!("{} must lie in [0, 24]", w.hour_of_max),
            );
        }
        if !(0.0..=1.0).contains(&w.relative_humidity) {
            return bad(
                "weather.relative_humidity",
                format!("{} must lie in [0, 1]", w.relative_humidity),
            );
        }
        if !(w.wind_speed_m_s.is_finite() && (0.0..=60.0).contains(&w.wind_speed_m_s)) {
            return bad(
                "weather.wind_speed_m_s",
                format!("{} must lie in [0, 60] m/s", w.wind_speed_m_s),
            );
        }
        if !(w.lapse_rate_k_per_km.is_finite() && (-20.0..=20.0).contains(&w.lapse_rate_k_per_km)) {
            return bad(
                "weather.lapse_rate_k_per_km",
                format!("{} must lie in [-20, 20] K/km", w.lapse_rate_k_per_km),
            );
        }
        if let Some(z) = w.reference_altitude_m {
            if !(z.is_finite() && (-500.0..=9000.0).contains(&z)) {
                return bad(
                    "weather.reference_altitude_m",
                    format!("{z} must lie in [-500, 9000] m"),
                );
            }
        }
        let s = &self.shortwave;
        if s.wavelengths.len() < 2
            || s.wavelengths
                .windows(2)
                .any(|p| p[1].partial_cmp(&p[0]) != Some(std::cmp::Ordering::Greater))
            || s.wavelengths.iter().any(|&v| !(positive(v) && v < 1e5))
        {
            return bad(
                "shortwave.wavelengths",
                "give at least two increasing wavelengths in nm".into(),
            );
        }
        if let Some(step) = s.wavelength_step {
            if !(positive(step) && s.wavelengths.len() == 2)
                || (s.wavelengths[1] - s.wavelengths[0]) / step > 10_000.0
            {
                return bad(
                    "shortwave.wavelength_step",
                    format!(
                        "{step} needs `wavelengths = [first, last]` and at most 10 000 steps between them"
                    ),
                );
            }
        }
        if s.spp == 0 {
            return bad("shortwave.spp", "must be at least 1".into());
        }
        if !(0.0..=1.0).contains(&s.surround_albedo) {
            return bad(
                "shortwave.surround_albedo",
                format!("{} must lie in [0, 1]", s.surround_albedo),
            );
        }
        if let Some(sc) = &self.scene {
            if let Some(p) = sc.pixel_size_m {
                if !positive(p) {
                    return bad("scene.pixel_size_m", format!("{p} must be positive"));
                }
            }
            if !(1..=4096).contains(&sc.sky_rays) {
                return bad(
                    "scene.sky_rays",
                    format!("{} must lie in 1..=4096", sc.sky_rays),
                );
            }
        }
        for name in self.materials.keys() {
            self.material(path, name)?;
        }
        Ok(())
    }

    /// The thermal model of material `name`: the file's entry, else scenegen's default for
    /// that name, else an error naming the key.
    pub fn material(&self, path: &Path, name: &str) -> Result<Resolved, KeyError> {
        let key = format!("materials.{name}");
        let from_preset = |p: &str, key: &str| {
            preset(p).ok_or_else(|| {
                key_error(
                    path,
                    key,
                    format!("unknown preset \"{p}\" (presets: {})", preset_list()),
                )
            })
        };
        let spec = match self.materials.get(name) {
            Some(s) => s,
            None => {
                return match SCENEGEN_DEFAULTS.iter().find(|(n, _)| *n == name) {
                    Some((_, p)) => Ok(Resolved {
                        model: from_preset(p, &key)?,
                        source: format!("preset {p} (default for {name})"),
                    }),
                    None => Err(key_error(
                        path,
                        &key,
                        format!(
                            "the scene has a material \"{name}\" with no thermal description: \
                             add `{name} = \"PRESET\"` or a table under [materials] (presets: {})",
                            preset_list()
                        ),
                    )),
                };
            }
        };
        match spec {
            MaterialSpec::Preset(p) => Ok(Resolved {
                model: from_preset(p, &key)?,
                source: format!("preset {p}"),
            }),
            MaterialSpec::Table(t) => {
                let mut model = match (&t.preset, &t.layers) {
                    (Some(p), _) => from_preset(p, &format!("{key}.preset"))?,
                    (None, Some(_)) => ThermalMaterial {
                        layers: vec![],
                        albedo: f64::NAN,
                        emissivity: f64::NAN,
                        wetness: 0.0,
                        bottom: Bottom::Adiabatic,
                        melting_point: None,
                    },
                    (None, None) => {
                        return Err(key_error(
                            path,
                            &key,
                            "give `preset` or `layers` (with `albedo` and `emissivity`)",
                        ))
                    }
                };
                if let Some(layers) = &t.layers {
                    for (i, l) in layers.iter().enumerate() {
                        for (what, v) in [
                            ("thickness_m", l.thickness_m),
                            ("conductivity", l.conductivity),
                            ("density", l.density),
                            ("heat_capacity", l.heat_capacity),
                        ] {
                            if !(v.is_finite() && v > 0.0) {
                                return Err(key_error(
                                    path,
                                    &format!("{key}.layers[{i}].{what}"),
                                    format!("{v} must be a positive number"),
                                ));
                            }
                        }
                    }
                    if layers.is_empty() {
                        return Err(key_error(path, &format!("{key}.layers"), "is empty"));
                    }
                    model.layers = layers.clone();
                }
                if let Some(a) = t.albedo {
                    model.albedo = a;
                }
                if let Some(e) = t.emissivity {
                    model.emissivity = e;
                }
                if let Some(w) = t.wetness {
                    if !(0.0..=1.0).contains(&w) {
                        return Err(key_error(
                            path,
                            &format!("{key}.wetness"),
                            format!("{w} must lie in [0, 1]"),
                        ));
                    }
                    model.wetness = w;
                }
                if !(0.0..=1.0).contains(&model.albedo) {
                    return Err(key_error(
                        path,
                        &format!("{key}.albedo"),
                        format!("{} must be given and lie in [0, 1]", model.albedo),
                    ));
                }
                if !(model.emissivity > 0.0 && model.emissivity <= 1.0) {
                    return Err(key_error(
                        path,
                        &format!("{key}.emissivity"),
                        format!("{} must be given and lie in (0, 1]", model.emissivity),
                    ));
                }
                if let Some(tb) = t.bottom_temperature_k {
                    if !(tb.is_finite() && tb > 150.0 && tb < 400.0) {
                        return Err(key_error(
                            path,
                            &format!("{key}.bottom_temperature_k"),
                            format!("{tb} must lie in (150, 400) K"),
                        ));
                    }
                    model.bottom = Bottom::Fixed(tb);
                }
                if let Some(tm) = t.melting_point_k {
                    if !(tm.is_finite() && tm > 150.0 && tm < 400.0) {
                        return Err(key_error(
                            path,
                            &format!("{key}.melting_point_k"),
                            format!("{tm} must lie in (150, 400) K"),
                        ));
                    }
                    model.melting_point = Some(tm);
                }
                Ok(Resolved {
                    model,
                    source: match &t.preset {
                        Some(p) => format!("preset {p}, modified"),
                        None => "layers given".into(),
                    },
                })
            }
        }
    }
}

/// Minutes after midnight of a clock time "HH:MM".
pub fn parse_clock(t: &str) -> Option<u32> {
    let (h, m) = t.trim().split_once(':')?;
    let (h, m): (u32, u32) = (h.parse().ok()?, m.parse().ok()?);
    (h < 24 && m < 60 && t.trim().len() == 5).then_some(h * 60 + m)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(text: &str) -> Result<TemperatureConfig, KeyError> {
        let dir = std::env::temp_dir().join(format!("tconf_{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        // One file per call: tests run in parallel, and two texts may have the same length.
        static NEXT: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);
        let k = NEXT.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        let p = dir.join(format!("t{k}.toml"));
        std::fs::write(&p, text).unwrap();
        TemperatureConfig::load(&p)
    }

    const BASE: &str = "date = \"2026-07-15\"\ntimes = [\"10:30\"]\n[weather]\nair_temperature_k = [288.0, 300.0]\n";

    #[test]
    fn errors_name_the_key() {
        assert!(parse(BASE).is_ok());
        for (extra, key) in [
            ("step_minutes = 7.0\n", "step_minutes"),
            ("latitude = 95.0\n", "latitude"),
        ] {
            let e = parse(&format!("{extra}{BASE}")).unwrap_err().to_string();
            assert!(e.contains(&format!("`{key}`")), "{e}");
        }
        let e = parse(&BASE.replace("10:30", "25:00"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("`times[0]`"), "{e}");
        // Date and offset are checked with the file (`simulate check`), not when the run starts.
        for (from, to, key) in [
            ("2026-07-15", "2026-02-30", "`date`"),
            ("2026-07-15", "15/07/2026", "`date`"),
        ] {
            let e = parse(&BASE.replace(from, to)).unwrap_err().to_string();
            assert!(e.contains(key), "{e}");
        }
        let e = parse(&format!("utc_offset = \"+2h\"\n{BASE}"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("`utc_offset`") && e.contains("+2h"), "{e}");
        assert!(parse(&format!("utc_offset = \"-05:00\"\n{BASE}")).is_ok());
        let e = parse(&BASE.replace("[288.0, 300.0]", "[300.0, 288.0]"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("`weather.air_temperature_k`"), "{e}");
        let e = parse(&format!("{BASE}wind = 3.0\n"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("wind"), "{e}");
        let e = parse(&format!("{BASE}[materials]\nurban = \"lava\"\n"))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("`materials.urban`") && e.contains("asphalt"),
            "{e}"
        );
        let e = parse(&format!(
            "{BASE}[materials]\nx = {{ layers = [{{ thickness_m = 0.1, conductivity = -1.0, density = 1.0, heat_capacity = 1.0 }}], albedo = 0.1, emissivity = 0.9 }}\n"
        ))
        .unwrap_err()
        .to_string();
        assert!(e.contains("`materials.x.layers[0].conductivity`"), "{e}");
        let e = parse(&format!(
            "{BASE}[materials]\nx = {{ layers = [{{ thickness_m = 0.1, conductivity = 1.0, density = 1.0, heat_capacity = 1.0 }}] }}\n"
        ))
        .unwrap_err()
        .to_string();
        assert!(e.contains("`materials.x.albedo`"), "{e}");
        let e = parse(&format!(
            "{BASE}[materials]\nx = {{ preset = \"snow\", melting_point_k = 500.0 }}\n"
        ))
        .unwrap_err()
        .to_string();
        assert!(e.contains("`materials.x.melting_point_k`"), "{e}");
        let cfg = parse(BASE).unwrap();
        let snow = cfg.material(Path::new("t.toml"), "snow").unwrap();
        assert_eq!(snow.model.melting_point, Some(273.15));
    }

    #[test]
    fn scenegen_names_have_presets_and_unknown_names_are_refused() {
        let cfg = parse(BASE).unwrap();
        let p = Path::new("t.toml");
        for (name, _) in SCENEGEN_DEFAULTS {
            assert!(cfg.material(p, name).is_ok(), "{name}");
        }
        let e = cfg.material(p, "greenhouse").unwrap_err().to_string();
        assert!(e.contains("materials.greenhouse"), "{e}");
        assert_eq!(parse_clock("22:00"), Some(1320));
        assert_eq!(parse_clock("7:00"), None);
    }
}
