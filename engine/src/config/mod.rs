//! The experiment file: its top-level serde type ([`ExperimentConfig`]) and the orchestration
//! of its resolution into an [`Experiment`] ([`resolve`](mod@resolve)).
//!
//! Each part of the file is declared and resolved beside the models it configures, so adding a
//! model stays local (CONTRIBUTING.md):
//!
//! | table | raw type and resolver |
//! |---|---|
//! | `mode`, `[spectral]` | `spectral.rs` ([`SpectralConfig::resolve`]) |
//! | `[geometry]`, `[atmosphere]` (homogeneous, layered, molecular, particle layers) | `atmosphere/config.rs` |
//! | gas absorption keys of `[atmosphere]` | `absorption/config.rs` |
//! | phase tables | `phase/config.rs` ([`PhaseResolver`]) |
//! | `[surface]` | `bsdf/config.rs` ([`SurfaceConfig::resolve`]) |
//! | `[scene]` | `config/scene.rs` |
//! | `[illumination]` | `illumination.rs` |
//! | `[[measures]]` | `measure/config.rs` |
//! | `[integrator]` | `integrator/settings.rs` ([`IntegratorSettings::from_config`]) |
//!
//! Every struct denies unknown fields, so a misspelt key is an error naming its path; closed
//! choices are serde enums, so an unknown value is an error naming the key and the allowed
//! values. Every key, its unit and its default are documented in `docs/experiment.md`; keep the
//! two in step. Units at this boundary: wavelengths in nm, altitudes in km, angles in degrees;
//! the resolvers convert to SI (m, radians) and check ranges. The parts report errors through
//! [`crate::error::ConfigCtx`], which names the file and the key path.

pub mod bands;
pub mod diagnostics;
pub mod experiment;
pub mod memory;
pub mod resolve;
pub mod scene;
pub mod thermal;

use serde::Deserialize;

pub use crate::absorption::config::{AbsorptionBoundsConfig, CrossSectionConfig};
pub use crate::atmosphere::config::{
    AtmosphereConfig, DistributionConfig, GeometryConfig, LayerConfig, ParticleLayerConfig,
};
pub use crate::bsdf::SurfaceConfig;
pub use crate::integrator::settings::{IntegratorConfig, IntegratorSettings};
pub use crate::measure::config::MeasureConfig;
pub use crate::phase::{PhaseConfig, PhaseResolver};
pub use crate::sources::illumination::{IlluminationConfig, IrradianceValue};
pub use crate::spectral::{Mode, SpectralConfig, Spectrum};
pub use resolve::{resolve, Experiment};

#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ExperimentConfig {
    /// "mono" (default) or "ckd".
    #[serde(default)]
    pub mode: Mode,
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
    /// Gridded cloud fields among the layers over the scene (`clouds/config.rs`).
    #[serde(default)]
    pub clouds: Vec<crate::clouds::config::CloudConfig>,
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
    /// Thermal emission of the layers and the surface (temperatures in `[atmosphere]` and
    /// `[surface]`; `docs/experiment.md`, "Thermal emission").
    #[serde(default)]
    pub emission: bool,
    /// Lamps (`[[lights]]`, `sources/lamps/`).
    #[serde(default)]
    pub lights: Vec<crate::sources::lamps::LampConfig>,
}

impl ExperimentConfig {
    /// Whether the run has lamps or emitters of its own: `[[lights]]`, a bundle's template
    /// lamps (`scene.lamps = true`) or emitting materials (`scene.emitters`).
    pub fn has_lamps(&self) -> bool {
        !self.lights.is_empty()
            || matches!(
                &self.scene,
                Some(scene::SceneConfig::Bundle { lamps, emitters, .. })
                    if *lamps || !emitters.is_empty()
            )
    }
}
