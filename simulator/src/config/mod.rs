//! The experiment file: raw serde types (this module) and their validation into runtime types
//! ([`resolve`]).
//!
//! Every struct denies unknown fields, so a misspelt key is an error naming its path. Every key,
//! its unit and its default are documented in `docs/experiment.md`; keep the two in step.
//! Units at this boundary: wavelengths in nm, altitudes in km, angles in degrees. `resolve`
//! converts to SI (m, radians) and checks ranges.

pub mod resolve;
pub mod scene;

use serde::Deserialize;

pub use resolve::{resolve, Experiment};

/// A per-wavelength quantity: one number for every wavelength, or one per wavelength.
#[derive(Clone, Debug, Deserialize)]
#[serde(untagged)]
pub enum SpectralValue {
    Scalar(f64),
    List(Vec<f64>),
}

#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ExperimentConfig {
    /// "mono" (monochromatic).
    #[serde(default = "default_mode")]
    pub mode: String,
    pub spectral: SpectralConfig,
    #[serde(default)]
    pub geometry: GeometryConfig,
    #[serde(default)]
    pub atmosphere: Option<AtmosphereConfig>,
    /// The 1D surface (required unless `scene` is given).
    #[serde(default)]
    pub surface: Option<SurfaceConfig>,
    /// A 3D scene (bundle or canopy) instead of the 1D surface.
    #[serde(default)]
    pub scene: Option<scene::SceneConfig>,
    pub illumination: IlluminationConfig,
    pub measures: Vec<MeasureConfig>,
    #[serde(default)]
    pub integrator: IntegratorConfig,
    /// Seed of every random stream of the run.
    #[serde(default)]
    pub seed: u64,
    /// Vector (Stokes) transport instead of scalar.
    #[serde(default)]
    pub polarized: bool,
}

fn default_mode() -> String {
    "mono".into()
}

#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SpectralConfig {
    /// nm.
    #[serde(default)]
    pub wavelengths: Option<Vec<f64>>,
    /// A sensor band (embedded SRF name or CSV file): sample it and add band-weighted outputs.
    #[serde(default)]
    pub srf: Option<String>,
    /// nm: spacing of the wavelengths sampling an SRF (default 5).
    #[serde(default)]
    pub wavelength_step: Option<f64>,
    /// `mode = "ckd"`: use only this g-point (index from 0) with weight 1 (validation).
    #[serde(default)]
    pub g_point: Option<usize>,
    /// `mode = "ckd"` with an axsdb database: number of Gauss–Legendre g-points per bin.
    #[serde(default)]
    pub g_points: Option<usize>,
}

#[derive(Clone, Debug, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
pub enum GeometryConfig {
    PlaneParallel {
        /// km.
        #[serde(default = "default_toa")]
        toa_altitude: f64,
        /// km.
        #[serde(default)]
        ground_altitude: f64,
    },
    /// Concentric shells around a spherical planet.
    SphericalShell {
        /// km.
        #[serde(default = "default_toa")]
        toa_altitude: f64,
        /// km.
        #[serde(default)]
        ground_altitude: f64,
        /// km.
        #[serde(default = "default_planet_radius")]
        planet_radius: f64,
    },
}

fn default_planet_radius() -> f64 {
    6378.1
}

fn default_toa() -> f64 {
    100.0
}

impl Default for GeometryConfig {
    fn default() -> Self {
        GeometryConfig::PlaneParallel {
            toa_altitude: default_toa(),
            ground_altitude: 0.0,
        }
    }
}

#[derive(Clone, Debug, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
pub enum AtmosphereConfig {
    /// One layer from the ground to TOA.
    Homogeneous {
        optical_thickness: SpectralValue,
        #[serde(default = "one")]
        single_scattering_albedo: SpectralValue,
        #[serde(default)]
        phase: PhaseConfig,
    },
    /// Plane-parallel layers, each homogeneous.
    Layered { layers: Vec<LayerConfig> },
    /// Rayleigh-scattering air from a thermophysical profile, with gas absorption (`[absorption]`,
    /// cross sections) and particle layers.
    Molecular {
        #[serde(default = "default_profile")]
        profile: String,
        /// km.
        #[serde(default = "default_layer_thickness")]
        layer_thickness: f64,
        /// Aerosol (particle) layers mixed into the molecular layers.
        #[serde(default)]
        particle_layers: Vec<ParticleLayerConfig>,
        /// `mode = "ckd"`: a correlated-k absorption file (eradiate v0 k(z, bin, g) format).
        #[serde(default)]
        absorption_data: Option<String>,
        /// Rescale species' column amounts (`atmosphere::thermo`).
        #[serde(default)]
        rescale: std::collections::BTreeMap<String, crate::atmosphere::thermo::RescaleValue>,
        /// Out-of-range policy of absorption databases.
        #[serde(default)]
        absorption_bounds: AbsorptionBoundsConfig,
        /// Rayleigh scattering by the air (false: gas absorption and particles only).
        #[serde(default = "yes")]
        rayleigh: bool,
        /// Rayleigh depolarization factor; none: the value consistent with Bates' King factor.
        #[serde(default)]
        depolarization: Option<f64>,
        /// Continuum absorbers from cross-section tables (`absorption/cross_section.rs`).
        #[serde(default)]
        cross_sections: Vec<CrossSectionConfig>,
    },
    /// No atmosphere (same as omitting the table).
    None {},
}

/// One `[[atmosphere.cross_sections]]` table: a species' absorption cross-section σ(λ).
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CrossSectionConfig {
    pub species: String,
    pub file: String,
    /// 1-based column of σ (column 1: wavelength, nm).
    #[serde(default = "default_xs_column")]
    pub column: usize,
    /// `"cm^2"` or `"m^2"` per molecule.
    #[serde(default = "default_xs_units")]
    pub units: String,
    /// A wavelength outside the table: `"error"` (default) or `"zero"` (no absorption, logged).
    #[serde(default)]
    pub outside: Option<String>,
}

fn default_xs_column() -> usize {
    2
}

fn default_xs_units() -> String {
    "cm^2".into()
}

/// `atmosphere.absorption_bounds`: what an absorption database does with a state outside its
/// grid, per coordinate: "error", "clamp" (edge value) or "zero" (no absorption). Both clamp and
/// zero log a warning once per coordinate.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AbsorptionBoundsConfig {
    #[serde(default = "zero_str")]
    pub pressure: String,
    #[serde(default = "clamp_str")]
    pub temperature: String,
    #[serde(default = "error_str")]
    pub mole_fraction: String,
}

impl Default for AbsorptionBoundsConfig {
    fn default() -> Self {
        AbsorptionBoundsConfig {
            pressure: zero_str(),
            temperature: clamp_str(),
            mole_fraction: error_str(),
        }
    }
}

fn zero_str() -> String {
    "zero".into()
}
fn clamp_str() -> String {
    "clamp".into()
}
fn error_str() -> String {
    "error".into()
}

/// One `[[atmosphere.particle_layers]]` table (see `atmosphere::particles`).
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ParticleLayerConfig {
    /// km.
    pub bottom: f64,
    /// km.
    pub top: f64,
    /// Extinction optical thickness of the whole layer at `reference_wavelength`.
    pub optical_thickness: f64,
    /// nm.
    #[serde(default = "default_reference_wavelength")]
    pub reference_wavelength: f64,
    #[serde(default)]
    pub distribution: DistributionConfig,
    /// Aer-Core v2 netCDF or libRadtran `.mie.cdf` file (relative to the experiment file).
    pub dataset: String,
    /// libRadtran files: index along `reff`/`hum`.
    #[serde(default)]
    pub size_index: usize,
}

fn default_reference_wavelength() -> f64 {
    550.0
}

/// Vertical distribution of a particle layer; lengths in km.
#[derive(Clone, Debug, Default, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
pub enum DistributionConfig {
    #[default]
    Uniform,
    Exponential {
        scale_height: f64,
    },
    Gaussian {
        mean: f64,
        std: f64,
    },
}

fn default_profile() -> String {
    "afgl_1986-us_standard".into()
}

fn default_layer_thickness() -> f64 {
    1.0
}

/// Solar irradiance: numbers, or the name of a built-in spectrum / a CSV file.
#[derive(Clone, Debug, Deserialize)]
#[serde(untagged)]
pub enum IrradianceValue {
    Value(SpectralValue),
    Spectrum(String),
}

fn one_irradiance() -> IrradianceValue {
    IrradianceValue::Value(SpectralValue::Scalar(1.0))
}

fn one() -> SpectralValue {
    SpectralValue::Scalar(1.0)
}

#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LayerConfig {
    /// km.
    pub bottom: f64,
    /// km.
    pub top: f64,
    /// Vertical scattering optical thickness.
    #[serde(default)]
    pub tau_sca: Option<SpectralValue>,
    /// Vertical absorption optical thickness.
    #[serde(default)]
    pub tau_abs: Option<SpectralValue>,
    /// Alternative to tau_sca/tau_abs: total optical thickness and single-scattering albedo.
    #[serde(default)]
    pub optical_thickness: Option<SpectralValue>,
    #[serde(default)]
    pub single_scattering_albedo: Option<SpectralValue>,
    #[serde(default)]
    pub phase: PhaseConfig,
}

#[derive(Clone, Debug, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
pub enum PhaseConfig {
    Rayleigh {
        #[serde(default)]
        depolarization: f64,
    },
    Hg {
        g: f64,
    },
    Isotropic {},
    Tabulated {
        file: String,
        /// nm; default: each run wavelength.
        #[serde(default)]
        wavelength: Option<f64>,
        #[serde(default)]
        size_index: usize,
    },
}

impl Default for PhaseConfig {
    fn default() -> Self {
        PhaseConfig::Rayleigh {
            depolarization: 0.0,
        }
    }
}

#[derive(Clone, Debug, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
pub enum SurfaceConfig {
    Lambertian {
        reflectance: SpectralValue,
    },
    Rpv {
        rho_0: SpectralValue,
        k: SpectralValue,
        g: SpectralValue,
        #[serde(default)]
        rho_c: Option<SpectralValue>,
    },
    Rtls {
        f_iso: SpectralValue,
        f_vol: SpectralValue,
        f_geo: SpectralValue,
    },
    Hapke {
        w: SpectralValue,
        b: SpectralValue,
        c: SpectralValue,
        /// degrees.
        theta: SpectralValue,
        #[serde(rename = "B_0")]
        b_0: SpectralValue,
        h: SpectralValue,
    },
    /// Rough ocean (Cox–Munk, Fresnel, shadowing); polarizing.
    Ocean {
        /// m/s.
        wind_speed: SpectralValue,
        #[serde(default)]
        refractive_index: Option<SpectralValue>,
        #[serde(default = "yes")]
        shadowing: bool,
    },
}

fn yes() -> bool {
    true
}

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
        /// UTC "YYYY-MM-DDTHH:MM:SSZ": the Sun's position (NREL SPA) at `latitude`/`longitude`.
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
    },
}

#[derive(Clone, Debug, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
pub enum MeasureConfig {
    Mdistant {
        id: String,
        /// "hplane" (default when `azimuth` is given) or "directions".
        #[serde(default)]
        construct: Option<String>,
        /// degrees; hplane: the half-plane azimuth.
        #[serde(default)]
        azimuth: Option<f64>,
        /// degrees; hplane: signed zeniths; directions: view zeniths.
        zeniths: Vec<f64>,
        /// degrees; directions: view azimuths, one per zenith.
        #[serde(default)]
        azimuths: Option<Vec<f64>>,
        /// 3D scenes: the area whose mean BRF is measured, [xmin, ymin, xmax, ymax] in the
        /// scene's coordinates (m; a bundle's working CRS). Default: the scene's extent.
        #[serde(default)]
        target_m: Option<[f64; 4]>,
        /// 3D scenes: height of the target area, m (default: the top of the scene).
        #[serde(default)]
        target_height_m: Option<f64>,
        spp: u64,
        #[serde(default)]
        target_rel_stderr: Option<f64>,
    },
    /// A georeferenced TOA image of a 3D scene seen from one direction (parallel projection,
    /// orthorectified on the terrain).
    Ortho {
        id: String,
        /// m.
        pixel_size_m: f64,
        /// [xmin, ymin, xmax, ymax] in the scene's coordinates (m); default: the scene extent.
        #[serde(default)]
        window_m: Option<[f64; 4]>,
        /// degrees: view zenith and azimuth (clockwise from North) of the sensor.
        #[serde(default)]
        zenith: f64,
        #[serde(default)]
        azimuth: f64,
        /// Samples per pixel (the maximum when `target_rel_stderr` is set).
        spp: u64,
        /// Stop when the **median** relative standard error of the pixels' BRF is at most this.
        #[serde(default)]
        target_rel_stderr: Option<f64>,
    },
    /// A pinhole camera.
    Perspective {
        id: String,
        /// m, scene coordinates (x, y, height).
        origin_m: [f64; 3],
        /// m: the point the camera looks at.
        target_m: [f64; 3],
        /// Up vector (default [0, 0, 1]).
        #[serde(default)]
        up: Option<[f64; 3]>,
        /// degrees: horizontal field of view.
        fov: f64,
        /// pixels.
        width: usize,
        height: usize,
        spp: u64,
        #[serde(default)]
        target_rel_stderr: Option<f64>,
    },
    Radiancemeter {
        id: String,
        /// km, [x, y, z]; z is the altitude.
        origin: [f64; 3],
        /// Looking direction (need not be normalised).
        direction: [f64; 3],
        /// degrees: azimuth fixing the Stokes meridian plane when the view is vertical.
        #[serde(default)]
        frame_azimuth: Option<f64>,
        spp: u64,
        #[serde(default)]
        target_rel_stderr: Option<f64>,
    },
    DistantFlux {
        id: String,
        /// km; default: top of the atmosphere.
        #[serde(default)]
        altitude: Option<f64>,
        spp: u64,
        #[serde(default)]
        target_rel_stderr: Option<f64>,
    },
}

#[derive(Clone, Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct IntegratorConfig {
    /// "auto" (default), "forward" or "backward".
    #[serde(default, rename = "type")]
    pub kind: Option<String>,
    /// Maximum scattering order (1 = single scattering); default unlimited.
    #[serde(default)]
    pub max_depth: Option<u32>,
    /// Scattering order from which Russian roulette may end paths (default 5).
    #[serde(default)]
    pub rr_depth: Option<u32>,
    /// "expected" (default): expected local estimates along flights; "collision": at collisions.
    #[serde(default)]
    pub local_estimate: Option<String>,
    /// `mode = "ckd"`: "cycle" (default: blocks of samples cycle through the g-points) or
    /// "alis" (one backward walk carries every g-point of a bin).
    #[serde(default)]
    pub ckd_walk: Option<String>,
    /// `mode = "mono"`: "independent" (default: every wavelength has its own walks) or "alis"
    /// (one backward walk carries a group of neighbouring wavelengths).
    #[serde(default)]
    pub spectral_walk: Option<String>,
    /// `spectral_walk = "alis"`: wavelengths per group (1–64, default 32).
    #[serde(default)]
    pub alis_group: Option<usize>,
    /// Samples per direction before the first check of `target_rel_stderr` (default 8192).
    #[serde(default)]
    pub first_check_spp: Option<u64>,
}
