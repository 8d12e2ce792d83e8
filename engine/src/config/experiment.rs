//! The runtime experiment: every part of the experiment file resolved into validated types
//! (`resolve.rs` builds it; the memory estimate, the blocks and the products read it).

use std::path::PathBuf;
use std::sync::Arc;

use glam::DVec3;

use crate::integrator::settings::IntegratorSettings;
use crate::measure::Measure;
use crate::optics::OpticalState;
use crate::scene::Scene;
use crate::spectral::Band;

/// A validated experiment.
#[derive(Clone, Debug)]
pub struct Experiment {
    pub wavelengths: Vec<f64>,
    /// The sensor band the wavelengths sample, if `spectral.srf` was given.
    pub band: Option<Band>,
    /// `spectral.bands`: the run's outputs are these bands (`wavelengths` and `optics` then
    /// hold one entry per band: its effective wavelength and band irradiance), walked by
    /// spectral Monte Carlo over their nodes (`spectral/bands.rs`).
    pub bands: Option<super::bands::BandWalks>,
    /// One per wavelength.
    pub optics: Vec<OpticalState>,
    /// Solar zenith and azimuth, radians.
    pub sun_zenith: f64,
    pub sun_azimuth: f64,
    /// Unit vector from the target towards the Sun.
    pub sun_dir: DVec3,
    /// The solar angles as given, degrees (azimuth normalised to [0, 360)).
    pub sun_zenith_deg: f64,
    pub sun_azimuth_deg: f64,
    /// Earth–Sun distance (AU) when the Sun comes from `illumination.time` (or `date`).
    pub sun_distance_au: Option<f64>,
    pub measures: Vec<Measure>,
    /// Lidar measures (`type = "lidar"` in `[[measures]]`; `lidar/`).
    pub lidars: Vec<crate::lidar::Lidar>,
    pub integrator: IntegratorSettings,
    pub seed: u64,
    /// Stokes-vector transport.
    pub polarized: bool,
    /// Spherical-shell geometry: the planet radius, m (None: plane-parallel).
    pub planet_radius: Option<f64>,
    /// The 3D scene, when the experiment renders one (shared: it can be large).
    pub scene: Option<Arc<Scene>>,
    /// A gridded cloud field in the scene's frame (`[[clouds]]`).
    pub clouds: Option<Arc<crate::clouds::config::PlacedClouds>>,
    /// Thermal emission (`emission = true`): radiances then carry brightness temperatures.
    pub emission: bool,
    /// Whether a Sun shines (`illumination.type = "none"`: false, no BRF).
    pub sun_shines: bool,
    /// The Moon shining beside the Sun (`illumination.moon = true`): every sample then adds a
    /// Moon-lit walk to the Sun-lit one (`blocks/walks.rs`), and the products' radiances and fluxes are
    /// the sum; BRFs stay in units of the Sun's irradiance.
    pub moon: Option<crate::sources::illumination::Moonlight>,
    /// Lamps (`[[lights]]`), in the scene's local frame; their light is added by next-event
    /// estimates at every interaction of the Sun's walks (`sources/lamps/`).
    pub lamps: Option<Arc<crate::sources::lamps::Lamps>>,
    /// The experiment file's text (written into the products for provenance).
    pub source_text: String,
    pub source_path: PathBuf,
}

impl Experiment {
    /// Whether the Sun is above the target's horizon (SZA below 90° by more than 0.2″). The
    /// target is the origin of the local frame: a large bent scene near the terminator has the
    /// Sun up or down by this one vertical, not by each pixel's.
    pub fn sun_up(&self) -> bool {
        self.sun_shines && self.sun_dir.z > 1e-6
    }

    /// With the Moon beside the Sun: E_moon/E_sun at wavelength `iw`, the factor that brings a
    /// Moon-lit path's score into the units of the Sun's (1 without a Moon, unused).
    pub fn moon_ratio(&self, iw: usize) -> f64 {
        match &self.moon {
            Some(m) => m.irradiance[iw] / self.optics[iw].irradiance,
            None => 1.0,
        }
    }

    /// The pixels of measure `m` when forward photons carry its lamps' light
    /// (`integrator/lamp_photons.rs`): a nadir `ortho` image of a flat-frame scene (not bent
    /// onto the planet) without rough dielectric interfaces (their radiance transmission is not
    /// reciprocal), in a run with point lamps and `integrator.lamp_estimator` not
    /// `"backward"`. `None`: the backward walks' next-event estimates carry them.
    pub fn lamp_photon_pixels(
        &self,
        m: &Measure,
    ) -> Option<crate::integrator::lamp_photons::NadirPixels> {
        use crate::sources::lamps::LampEstimator;
        let lamps = self.lamps.as_deref()?;
        if lamps.lamps.is_empty() || lamps.estimator == LampEstimator::Backward {
            return None;
        }
        let crate::measure::MeasureKind::Ortho(g) = &m.kind else {
            return None;
        };
        let scene = self.scene.as_deref()?;
        let rough = self.optics.iter().any(|o| {
            o.scene_models
                .iter()
                .any(|s| matches!(s, crate::scene::material::SurfaceModel::Dielectric(_)))
        });
        if g.vza != 0.0 || scene.curvature.is_some() || rough || self.planet_radius.is_some() {
            return None;
        }
        Some(crate::integrator::lamp_photons::NadirPixels {
            x0: g.geotransform[0],
            y1: g.geotransform[3],
            pixel: g.geotransform[1],
            width: g.width,
            height: g.height,
        })
    }

    /// The cosine that normalises samples and BRFs: cos SZA when the Sun is above the target's
    /// horizon, else 1 (twilight in spherical shells: radiance only, no BRF).
    pub fn mu_norm(&self) -> f64 {
        if self.sun_up() {
            self.sun_dir.z
        } else {
            1.0
        }
    }
}
