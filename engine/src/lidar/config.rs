//! The `[[measures]]` table of a lidar (`type = "lidar"`), checked and resolved into a
//! [`Lidar`]. Keys, units and defaults: docs/experiment.md, "Lidar".

use glam::DVec3;
use serde::Deserialize;

use super::bins::Bins;
use super::{Footprint, Lidar, LidarMode, Slope, C_M_PER_NS};
use crate::error::{ConfigCtx, ConfigError};
use crate::frame::direction_from_angles;
use crate::scene::Scene;

/// Footprint shapes of the experiment file.
#[derive(Clone, Copy, Debug, Default, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "snake_case")]
pub enum FootprintShape {
    #[default]
    Gaussian,
    Tophat,
}

/// How the photons leave the laser.
#[derive(Clone, Copy, Debug, Default, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "snake_case")]
pub enum Rays {
    /// From the sensor's point through the footprint, back to that point.
    #[default]
    Point,
    /// Parallel to the beam axis (far-field limit).
    Parallel,
}

#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LidarConfig {
    pub id: String,
    #[serde(default)]
    pub mode: LidarMode,
    /// nm: one of `spectral.wavelengths`.
    pub wavelength: f64,
    /// Platform height above z = 0 of the scene's frame, m.
    pub altitude_m: f64,
    /// Beam direction: zenith and azimuth (clockwise from North) of the direction from the
    /// footprint towards the sensor, degrees.
    #[serde(default)]
    pub zenith: f64,
    #[serde(default)]
    pub azimuth: f64,
    #[serde(default)]
    pub footprint: FootprintShape,
    /// Gaussian: the 1/e² diameter (σ = D/4); tophat: the disc's diameter, m.
    #[serde(default)]
    pub footprint_diameter_m: Option<f64>,
    /// Gaussian: σ per axis, m (instead of `footprint_diameter_m`).
    #[serde(default)]
    pub footprint_sigma_m: Option<f64>,
    /// Gaussian pulse FWHM, ns (0: a delta pulse), or its standard deviation.
    #[serde(default)]
    pub pulse_fwhm_ns: Option<f64>,
    #[serde(default)]
    pub pulse_sigma_ns: Option<f64>,
    #[serde(default = "one")]
    pub pulse_energy_j: f64,
    #[serde(default = "one")]
    pub receiver_area_m2: f64,
    /// Receiver field of view: half-angle, µrad, or diameter at the footprint centre's range, m.
    #[serde(default)]
    pub fov_half_angle_urad: Option<f64>,
    #[serde(default)]
    pub fov_diameter_m: Option<f64>,
    /// Bins in time (ns, two-way delay after `2 R0 / c`): width and [first, last] centre.
    #[serde(default)]
    pub bin_ns: Option<f64>,
    #[serde(default)]
    pub bins_ns: Option<[f64; 2]>,
    /// Bins in apparent height above the footprint centre (m): width and [lowest, highest]
    /// centre.
    #[serde(default)]
    pub bin_m: Option<f64>,
    #[serde(default)]
    pub bins_m: Option<[f64; 2]>,
    /// Footprint centres [x, y] in the experiment's coordinates (default one at [0, 0]).
    #[serde(default)]
    pub shots: Option<Vec<[f64; 2]>>,
    /// Or a ground track: footprint centres every `track_spacing_m` from [x0, y0] to [x1, y1].
    #[serde(default)]
    pub track_m: Option<[f64; 4]>,
    #[serde(default)]
    pub track_spacing_m: Option<f64>,
    /// Height of the footprint centres, m (default: the ground under each, or the 1D ground).
    #[serde(default)]
    pub footprint_height_m: Option<f64>,
    /// Stop a shot once the relative standard error of its waveform's highest bin is at most
    /// this (`spp` is then the most photon paths).
    #[serde(default)]
    pub target_rel_stderr: Option<f64>,
    /// `"point"` (default) or `"parallel"`.
    #[serde(default)]
    pub rays: Rays,
    /// Photon paths per shot.
    pub spp: u64,
    /// Highest scattering order traced (default: all, ended by roulette).
    #[serde(default)]
    pub max_order: Option<u32>,
    /// 1D ground only (tests): tilt the ground plane by this slope (degrees) towards the
    /// downhill azimuth `ground_aspect_deg` (clockwise from North).
    #[serde(default)]
    pub ground_slope_deg: f64,
    #[serde(default)]
    pub ground_aspect_deg: f64,
    /// Photon counting: detector efficiency in (0, 1].
    #[serde(default = "one")]
    pub detector_efficiency: f64,
    #[serde(default)]
    pub dead_time_ns: f64,
    #[serde(default = "default_shots")]
    pub shots_per_location: u64,
    /// Photon counting under the Sun: the receiver's filter width (nm) and range gate (ns) that
    /// set the solar background (0: none).
    #[serde(default)]
    pub filter_width_nm: f64,
    #[serde(default)]
    pub range_gate_ns: Option<f64>,
    /// Canopy-cover metric: vegetation and ground reflectances (gediMetric's 0.57 and 0.4).
    #[serde(default = "rho_v")]
    pub cover_rho_v: f64,
    #[serde(default = "rho_g")]
    pub cover_rho_g: f64,
    /// Discrete returns: detection threshold (fraction of the waveform's peak), minimum
    /// separation of returns (m of range; default the pulse's FWHM in range, at least two
    /// bins), most returns per shot, shot rate (Hz) for the points' GPS time.
    #[serde(default = "default_threshold")]
    pub detect_threshold: f64,
    #[serde(default)]
    pub min_separation_m: Option<f64>,
    #[serde(default = "default_max_returns")]
    pub max_returns: u32,
    #[serde(default = "default_rate")]
    pub pulse_rate_hz: f64,
    /// Discrete returns: ASPRS LAS classes of scene materials by name (`{ roof = 6 }`).
    #[serde(default)]
    pub las_classes: std::collections::BTreeMap<String, u8>,
}

fn default_threshold() -> f64 {
    0.05
}
fn default_max_returns() -> u32 {
    5
}
fn default_rate() -> f64 {
    242.0
}

fn rho_v() -> f64 {
    0.57
}
fn rho_g() -> f64 {
    0.4
}

fn one() -> f64 {
    1.0
}
fn default_shots() -> u64 {
    10_000
}

/// Most photon paths per shot and shots per location (counts are checked before anything is
/// sized).
pub const MAX_SPP: u64 = 1 << 40;
pub const MAX_BINS: usize = 1 << 22;
pub const MAX_SHOTS: usize = 1 << 20;

impl LidarConfig {
    /// The lidar `measures[index]` of an experiment whose run wavelengths are
    /// `ctx.wavelengths`; `ground`: the 1D ground's altitude (m), `scene`: the 3D scene.
    pub fn resolve(
        &self,
        ctx: &ConfigCtx,
        index: usize,
        ground: f64,
        scene: Option<&Scene>,
    ) -> Result<Lidar, ConfigError> {
        let key = |k: &str| format!("measures[{index}].{k}");
        let finite = |k: &str, x: f64| ctx.finite(&key(k), x);
        let positive = |k: &str, x: f64| -> Result<f64, ConfigError> {
            let x = finite(k, x)?;
            if x > 0.0 {
                Ok(x)
            } else {
                Err(ctx.err(key(k), format!("{x} must be > 0")))
            }
        };
        let wl = positive("wavelength", self.wavelength)?;
        let iw = ctx
            .wavelengths
            .iter()
            .position(|&w| (w - wl).abs() <= 1e-9 * wl)
            .ok_or_else(|| {
                ctx.err(
                    key("wavelength"),
                    format!(
                        "{wl} nm is not one of the run's wavelengths ({:?} nm): add it to `spectral.wavelengths`, where the atmosphere and the materials are evaluated",
                        ctx.wavelengths
                    ),
                )
            })?;
        let zen = finite("zenith", self.zenith)?;
        if !(0.0..80.0).contains(&zen) {
            return Err(ctx.err(key("zenith"), format!("{zen}° must lie in [0, 80)")));
        }
        let az = finite("azimuth", self.azimuth)?;
        let to_sensor = direction_from_angles(zen.to_radians(), az.to_radians());

        let footprint = match self.footprint {
            FootprintShape::Gaussian => match (self.footprint_sigma_m, self.footprint_diameter_m) {
                (Some(s), None) => Footprint::Gaussian {
                    sigma: positive("footprint_sigma_m", s)?,
                },
                (None, Some(d)) => Footprint::Gaussian {
                    sigma: positive("footprint_diameter_m", d)? / 4.0,
                },
                (Some(_), Some(_)) => {
                    return Err(ctx.err(
                        key("footprint_sigma_m"),
                        "give `footprint_sigma_m` or `footprint_diameter_m`, not both",
                    ))
                }
                (None, None) => {
                    return Err(ctx.err(
                        key("footprint_diameter_m"),
                        "a Gaussian footprint needs `footprint_diameter_m` (1/e² diameter, m) or `footprint_sigma_m`",
                    ))
                }
            },
            FootprintShape::Tophat => {
                if self.footprint_sigma_m.is_some() {
                    return Err(ctx.err(
                        key("footprint_sigma_m"),
                        "is for Gaussian footprints; a tophat takes `footprint_diameter_m`",
                    ));
                }
                let d = self.footprint_diameter_m.ok_or_else(|| {
                    ctx.err(
                        key("footprint_diameter_m"),
                        "a tophat footprint needs `footprint_diameter_m` (m)",
                    )
                })?;
                Footprint::TopHat {
                    radius: positive("footprint_diameter_m", d)? / 2.0,
                }
            }
        };
        let fwhm_per_sigma = (8.0 * std::f64::consts::LN_2).sqrt();
        let (k, sigma) = match (self.pulse_fwhm_ns, self.pulse_sigma_ns) {
            (Some(f), None) => (
                "pulse_fwhm_ns",
                finite("pulse_fwhm_ns", f)? / fwhm_per_sigma,
            ),
            (None, Some(s)) => ("pulse_sigma_ns", finite("pulse_sigma_ns", s)?),
            (None, None) => ("pulse_fwhm_ns", 0.0),
            (Some(_), Some(_)) => {
                return Err(ctx.err(
                    key("pulse_sigma_ns"),
                    "give `pulse_fwhm_ns` or `pulse_sigma_ns`, not both",
                ))
            }
        };
        if sigma < 0.0 {
            return Err(ctx.err(key(k), format!("{sigma} must be ≥ 0 (0: a delta pulse)")));
        }
        let pulse_sigma_ns = sigma;
        let pulse_energy_j = positive("pulse_energy_j", self.pulse_energy_j)?;
        let receiver_area_m2 = positive("receiver_area_m2", self.receiver_area_m2)?;

        // Shots: footprint centres in the local frame.
        let given = match (&self.shots, self.track_m) {
            (Some(_), Some(_)) => {
                return Err(ctx.err(key("track_m"), "give `shots` or `track_m`, not both"))
            }
            (Some(s), None) => s.clone(),
            (None, None) => vec![[0.0, 0.0]],
            (None, Some(t)) => {
                let sp = self.track_spacing_m.ok_or_else(|| {
                    ctx.err(key("track_spacing_m"), "a `track_m` needs its spacing (m)")
                })?;
                let sp = positive("track_spacing_m", sp)?;
                for (i, v) in t.iter().enumerate() {
                    finite(&format!("track_m[{i}]"), *v)?;
                }
                let len = ((t[2] - t[0]).powi(2) + (t[3] - t[1]).powi(2)).sqrt();
                let n = (len / sp + 1e-9).floor() + 1.0;
                if n > MAX_SHOTS as f64 {
                    return Err(ctx.err(
                        key("track_spacing_m"),
                        format!("{n} shots along the track: at most {MAX_SHOTS}"),
                    ));
                }
                let n = n as usize;
                (0..n)
                    .map(|i| {
                        let f = if len > 0.0 { i as f64 * sp / len } else { 0.0 };
                        [t[0] + f * (t[2] - t[0]), t[1] + f * (t[3] - t[1])]
                    })
                    .collect()
            }
        };
        if self.track_spacing_m.is_some() && self.track_m.is_none() {
            return Err(ctx.err(key("track_spacing_m"), "goes with `track_m`"));
        }
        if given.is_empty() || given.len() > MAX_SHOTS {
            return Err(ctx.err(
                key("shots"),
                format!(
                    "needs 1 to {MAX_SHOTS} footprint centres, got {}",
                    given.len()
                ),
            ));
        }
        // The experiment's coordinates of the scene's local origin (a bundle's working CRS).
        let origin = scene.and_then(|s| s.georef.as_ref().map(|g| (g.origin.x, g.origin.y)));
        let mut shots = Vec::with_capacity(given.len());
        for (i, s) in given.iter().enumerate() {
            let k = format!("shots[{i}]");
            let (x, y) = (finite(&k, s[0])?, finite(&k, s[1])?);
            let (lx, ly) = origin.map_or((x, y), |(ox, oy)| (x - ox, y - oy));
            let z = match (self.footprint_height_m, scene) {
                (Some(z), _) => finite("footprint_height_m", z)?,
                (None, Some(sc)) => sc.ground_height(lx, ly).ok_or_else(|| {
                    ctx.err(
                        key(&k),
                        format!("no ground under the footprint centre ({x}, {y}): it lies outside the scene; give `footprint_height_m` or move the shot"),
                    )
                })?,
                (None, None) => ground,
            };
            shots.push(DVec3::new(lx, ly, z));
        }
        // An airborne sensor may fly below the scene's highest point, but above its footprints.
        let altitude = finite("altitude_m", self.altitude_m)?;
        let highest = shots.iter().map(|c| c.z).fold(f64::NEG_INFINITY, f64::max);
        if altitude <= highest + 1.0 {
            return Err(ctx.err(
                key("altitude_m"),
                format!("{altitude} m must lie more than 1 m above every footprint centre (highest {highest:.1} m)"),
            ));
        }
        let r0 = (altitude - shots[0].z) / to_sensor.z;

        let fov_half_angle = match (self.fov_half_angle_urad, self.fov_diameter_m) {
            (Some(a), None) => positive("fov_half_angle_urad", a)? * 1e-6,
            (None, Some(d)) => (positive("fov_diameter_m", d)? / 2.0 / r0).atan(),
            (None, None) => (2.0 * footprint.extent() / r0).atan(),
            (Some(_), Some(_)) => {
                return Err(ctx.err(
                    key("fov_half_angle_urad"),
                    "give `fov_half_angle_urad` or `fov_diameter_m`, not both",
                ))
            }
        };
        if fov_half_angle >= 0.1 {
            return Err(ctx.err(
                key("fov_half_angle_urad"),
                format!(
                    "the field of view's half-angle ({:.3} rad) must be below 0.1 rad",
                    fov_half_angle
                ),
            ));
        }

        let bins = self.bins(ctx, index, scene, &shots, ground)?;

        if self.spp < 2 || self.spp > MAX_SPP {
            return Err(ctx.err(
                key("spp"),
                format!("{} photon paths per shot: must lie in [2, 2⁴⁰]", self.spp),
            ));
        }
        if let Some(t) = self.target_rel_stderr {
            if !(t > 0.0 && t < 1.0) {
                return Err(ctx.err(key("target_rel_stderr"), format!("{t} must lie in (0, 1)")));
            }
        }
        let max_order = self.max_order.unwrap_or(u32::MAX);
        if max_order == 0 {
            return Err(ctx.err(key("max_order"), "must be ≥ 1 (1: first order only)"));
        }
        let slope_deg = finite("ground_slope_deg", self.ground_slope_deg)?;
        let aspect = finite("ground_aspect_deg", self.ground_aspect_deg)?;
        let slope = if slope_deg != 0.0 {
            if scene.is_some() {
                return Err(ctx.err(
                    key("ground_slope_deg"),
                    "tilts the 1D ground only; a scene's slopes are its terrain",
                ));
            }
            if !(0.0..80.0).contains(&slope_deg) {
                return Err(ctx.err(
                    key("ground_slope_deg"),
                    format!("{slope_deg}° must lie in [0, 80)"),
                ));
            }
            Some(Slope {
                normal: direction_from_angles(slope_deg.to_radians(), aspect.to_radians()),
            })
        } else {
            None
        };
        let efficiency = finite("detector_efficiency", self.detector_efficiency)?;
        if !(efficiency > 0.0 && efficiency <= 1.0) {
            return Err(ctx.err(
                key("detector_efficiency"),
                format!("{efficiency} must lie in (0, 1]"),
            ));
        }
        let dead_time_ns = finite("dead_time_ns", self.dead_time_ns)?;
        if dead_time_ns < 0.0 {
            return Err(ctx.err(key("dead_time_ns"), format!("{dead_time_ns} must be ≥ 0")));
        }
        if self.shots_per_location == 0 || self.shots_per_location > MAX_SPP {
            return Err(ctx.err(
                key("shots_per_location"),
                format!("{} must lie in [1, 2⁴⁰]", self.shots_per_location),
            ));
        }
        let filter_width_nm = finite("filter_width_nm", self.filter_width_nm)?;
        if filter_width_nm < 0.0 {
            return Err(ctx.err(
                key("filter_width_nm"),
                format!("{filter_width_nm} must be ≥ 0 (0: no solar background)"),
            ));
        }
        let gate_ns = match self.range_gate_ns {
            Some(g) => positive("range_gate_ns", g)?,
            None => bins.count as f64 * bins.width_ns,
        };
        let detect_threshold = finite("detect_threshold", self.detect_threshold)?;
        if !(detect_threshold > 0.0 && detect_threshold < 1.0) {
            return Err(ctx.err(
                key("detect_threshold"),
                format!(
                    "{detect_threshold} must lie in (0, 1) (a fraction of the waveform's peak)"
                ),
            ));
        }
        let fwhm_range = 0.5 * C_M_PER_NS * pulse_sigma_ns * fwhm_per_sigma;
        let min_sep_m = match self.min_separation_m {
            Some(m) => positive("min_separation_m", m)?,
            None => fwhm_range.max(C_M_PER_NS * bins.width_ns),
        };
        if !(1..=15).contains(&self.max_returns) {
            return Err(ctx.err(
                key("max_returns"),
                format!(
                    "{} must lie in [1, 15] (LAS 1.4 return numbers)",
                    self.max_returns
                ),
            ));
        }
        let pulse_rate_hz = positive("pulse_rate_hz", self.pulse_rate_hz)?;
        for name in self.las_classes.keys() {
            let known = scene.is_some_and(|s| s.materials.iter().any(|(n, _)| n == name));
            if !known {
                let list = scene.map_or_else(
                    || "a 1D ground has no materials to name".to_string(),
                    |s| {
                        format!(
                            "the scene's materials are {}",
                            s.materials
                                .iter()
                                .map(|(n, _)| n.as_str())
                                .collect::<Vec<_>>()
                                .join(", ")
                        )
                    },
                );
                return Err(ctx.err(
                    format!("measures[{index}].las_classes.{name}"),
                    format!("no material `{name}`: {list}"),
                ));
            }
        }
        let cover_rho = (
            positive("cover_rho_v", self.cover_rho_v)?,
            positive("cover_rho_g", self.cover_rho_g)?,
        );
        Ok(Lidar {
            id: self.id.clone(),
            index,
            mode: self.mode,
            wavelength: wl,
            iw,
            altitude,
            to_sensor,
            zenith_deg: zen,
            azimuth_deg: az,
            footprint,
            pulse_sigma_ns,
            pulse_energy_j,
            receiver_area_m2,
            fov_half_angle,
            bins,
            shots,
            shots_given: given,
            parallel: self.rays == Rays::Parallel,
            spp: self.spp,
            target_rel_stderr: self.target_rel_stderr,
            max_order,
            slope,
            efficiency,
            dead_time_ns,
            shots_per_location: self.shots_per_location,
            filter_width_nm,
            gate_ns,
            cover_rho,
            detect_threshold,
            min_separation_ns: 2.0 * min_sep_m / C_M_PER_NS,
            max_returns: self.max_returns as usize,
            pulse_rate_hz,
            las_classes: self.las_classes.clone().into_iter().collect(),
        })
    }

    /// The time bins from `bin_ns`/`bins_ns` or `bin_m`/`bins_m` (default range: the scene's
    /// heights ± 5 m, or ±30 m about a 1D ground).
    fn bins(
        &self,
        ctx: &ConfigCtx,
        index: usize,
        scene: Option<&Scene>,
        shots: &[DVec3],
        ground: f64,
    ) -> Result<Bins, ConfigError> {
        let key = |k: &str| format!("measures[{index}].{k}");
        let zc = shots[0].z;
        let default_heights = match scene {
            Some(s) => [s.z_range[0] - zc - 5.0, s.z_range[1] - zc + 5.0],
            None => [ground - zc - 30.0, ground - zc + 30.0],
        };
        let (width, range, in_height, k) = match (self.bin_ns, self.bin_m) {
            (Some(w), None) => {
                if self.bins_m.is_some() {
                    return Err(ctx.err(key("bins_m"), "goes with `bin_m`, not `bin_ns`"));
                }
                let r = self.bins_ns.unwrap_or([
                    -2.0 * default_heights[1] / C_M_PER_NS,
                    -2.0 * default_heights[0] / C_M_PER_NS,
                ]);
                (w, r, false, "bins_ns")
            }
            (None, Some(w)) => {
                if self.bins_ns.is_some() {
                    return Err(ctx.err(key("bins_ns"), "goes with `bin_ns`, not `bin_m`"));
                }
                (w, self.bins_m.unwrap_or(default_heights), true, "bins_m")
            }
            (None, None) => {
                return Err(ctx.err(
                    key("bin_ns"),
                    "a lidar needs its bins: `bin_ns` (two-way time, ns) or `bin_m` (apparent height, m)",
                ))
            }
            (Some(_), Some(_)) => {
                return Err(ctx.err(key("bin_ns"), "give `bin_ns` or `bin_m`, not both"))
            }
        };
        let wkey = if in_height { "bin_m" } else { "bin_ns" };
        let width = ctx.finite(&key(wkey), width)?;
        if width <= 0.0 {
            return Err(ctx.err(key(wkey), format!("{width} must be > 0")));
        }
        let (a, b) = (
            ctx.finite(&key(k), range[0])?,
            ctx.finite(&key(k), range[1])?,
        );
        if b < a {
            return Err(ctx.err(
                key(k),
                format!("[{a}, {b}]: the first centre must not exceed the last"),
            ));
        }
        let n = ((b - a) / width + 1e-9).floor() + 1.0;
        if n > MAX_BINS as f64 {
            return Err(ctx.err(key(k), format!("{n} bins of {width}: at most {MAX_BINS}")));
        }
        let count = n as usize;
        Ok(if in_height {
            // Height centres a + k·w, highest first: time centres from −2(b)/c upwards.
            let width_ns = 2.0 * width / C_M_PER_NS;
            let highest = a + (count - 1) as f64 * width;
            Bins {
                first_ns: -2.0 * highest / C_M_PER_NS,
                width_ns,
                count,
                in_height: true,
            }
        } else {
            Bins {
                first_ns: a,
                width_ns: width,
                count,
                in_height: false,
            }
        })
    }
}
