//! The `[[measures]]` tables of the experiment file: the raw serde type, one variant per measure
//! type, and its resolution into a [`Measure`]. Keys and units are documented in
//! `docs/experiment.md`; altitudes in km and angles in degrees there, m and radians here.
//! Measures of 3D scenes see the scene through a [`SceneFrame`], so this module does not
//! depend on the scene's types.

use glam::DVec3;
use serde::Deserialize;

use super::{Area, Camera, FluxDirection, Measure, MeasureKind, OrthoGrid};
use crate::error::{ConfigCtx, ConfigError};
use crate::frame::direction_from_angles;

/// `spp` left out of a measure: filled by a run's override (`simulate run --spp N`,
/// `eosim.run(..., spp=N)`), else refused naming `measures[k].spp`.
pub const SPP_UNSET: u64 = u64::MAX;

fn spp_unset() -> u64 {
    SPP_UNSET
}

#[derive(Clone, Debug, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
pub enum MeasureConfig {
    Mdistant {
        id: String,
        /// "hplane" (default unless `azimuths` is given) or "directions".
        #[serde(default)]
        construct: Option<Construct>,
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
        #[serde(default = "spp_unset")]
        spp: u64,
        #[serde(default)]
        #[serde(deserialize_with = "target_list")]
        target_rel_stderr: Option<Vec<f64>>,
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
        #[serde(default = "spp_unset")]
        spp: u64,
        /// Stop when the **median** relative standard error of the pixels' BRF is at most this.
        #[serde(default)]
        #[serde(deserialize_with = "target_list")]
        target_rel_stderr: Option<Vec<f64>>,
        /// The fraction of pixels that must meet `target_rel_stderr` (default 0.5: the median).
        #[serde(default)]
        target_fraction: Option<f64>,
        /// With a target: sample only the pixels above it after the first round (default true).
        #[serde(default)]
        adaptive: Option<bool>,
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
        #[serde(default = "spp_unset")]
        spp: u64,
        #[serde(default)]
        #[serde(deserialize_with = "target_list")]
        target_rel_stderr: Option<Vec<f64>>,
        /// As for `ortho`.
        #[serde(default)]
        target_fraction: Option<f64>,
        #[serde(default)]
        adaptive: Option<bool>,
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
        #[serde(default = "spp_unset")]
        spp: u64,
        #[serde(default)]
        #[serde(deserialize_with = "target_list")]
        target_rel_stderr: Option<Vec<f64>>,
    },
    DistantFlux {
        id: String,
        /// km; default: top of the atmosphere.
        #[serde(default)]
        altitude: Option<f64>,
        /// "up" (default): upwelling flux; "down": downwelling (direct + diffuse).
        #[serde(default)]
        direction: Option<FluxDirection>,
        #[serde(default = "spp_unset")]
        spp: u64,
        #[serde(default)]
        #[serde(deserialize_with = "target_list")]
        target_rel_stderr: Option<Vec<f64>>,
    },
    /// The hemispherical–directional reflectance factor at a level of a 1D atmosphere (the
    /// surface by default) in a list of directions laid out as an `mdistant`'s.
    Hdrf {
        id: String,
        /// km; default: the ground (BOA).
        #[serde(default)]
        altitude: Option<f64>,
        #[serde(default)]
        construct: Option<Construct>,
        /// degrees; hplane: the half-plane azimuth.
        #[serde(default)]
        azimuth: Option<f64>,
        /// degrees.
        zeniths: Vec<f64>,
        /// degrees.
        #[serde(default)]
        azimuths: Option<Vec<f64>>,
        #[serde(default = "spp_unset")]
        spp: u64,
        #[serde(default)]
        #[serde(deserialize_with = "target_list")]
        target_rel_stderr: Option<Vec<f64>>,
    },
    /// A pulsed laser and its receiver (`lidar/`): resolved apart from the passive measures
    /// into the experiment's `lidars`.
    Lidar(Box<crate::lidar::LidarConfig>),
}

/// `mdistant.construct`: how the directions are laid out.
#[derive(Clone, Copy, Debug, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "snake_case")]
pub enum Construct {
    /// A half-plane through `azimuth`: signed zeniths, negative ones at `azimuth + 180`.
    Hplane,
    /// Explicit (zenith, azimuth) pairs.
    Directions,
    /// A hemispherical grid: every zenith of `zeniths` at every azimuth of `azimuths`
    /// (zenith-major), as Eradiate's hemispherical construct.
    Hemisphere,
}

/// What measures need of a 3D scene, in its local frame (m).
#[derive(Clone, Debug)]
pub struct SceneFrame {
    /// Horizontal extent of the scene's content [xmin, ymin, xmax, ymax].
    pub extent: [f64; 4],
    /// Highest point of the geometry.
    pub top: f64,
    /// The experiment file's coordinates of the local origin (a bundle's working CRS), if any.
    pub origin: Option<(f64, f64)>,
    /// A bundle's polygonal area of interest: target areas of distant measures are masked by it.
    pub mask: Option<std::sync::Arc<crate::scene::area_mask::AreaMask>>,
}

impl SceneFrame {
    /// Scene coordinates of the experiment file → the scene's local frame.
    pub fn to_local(&self, x: f64, y: f64) -> (f64, f64) {
        match self.origin {
            Some((ox, oy)) => (x - ox, y - oy),
            None => (x, y),
        }
    }
}

/// The resolved geometry the measures refer to, m.
#[derive(Clone, Copy, Debug)]
pub struct MeasureContext<'a> {
    pub ground: f64,
    pub toa: f64,
    /// The 3D scene, when the experiment renders one.
    pub scene: Option<&'a SceneFrame>,
}

impl MeasureConfig {
    fn common(&self) -> (&String, u64, Option<&[f64]>) {
        match self {
            MeasureConfig::Mdistant {
                id,
                spp,
                target_rel_stderr,
                ..
            }
            | MeasureConfig::Radiancemeter {
                id,
                spp,
                target_rel_stderr,
                ..
            }
            | MeasureConfig::DistantFlux {
                id,
                spp,
                target_rel_stderr,
                ..
            }
            | MeasureConfig::Hdrf {
                id,
                spp,
                target_rel_stderr,
                ..
            }
            | MeasureConfig::Ortho {
                id,
                spp,
                target_rel_stderr,
                ..
            }
            | MeasureConfig::Perspective {
                id,
                spp,
                target_rel_stderr,
                ..
            } => (id, *spp, target_rel_stderr.as_deref()),
            MeasureConfig::Lidar(l) => (&l.id, l.spp, None),
        }
    }

    /// Samples per direction or pixel ([`SPP_UNSET`] where the file leaves `spp` out).
    pub fn spp(&self) -> u64 {
        self.common().1
    }

    /// The measure's `id`.
    pub fn id(&self) -> &str {
        self.common().0
    }

    /// Replace the samples per direction/pixel (`simulate run --spp`).
    pub fn set_spp(&mut self, n: u64) {
        match self {
            MeasureConfig::Mdistant { spp, .. }
            | MeasureConfig::Radiancemeter { spp, .. }
            | MeasureConfig::DistantFlux { spp, .. }
            | MeasureConfig::Hdrf { spp, .. }
            | MeasureConfig::Ortho { spp, .. }
            | MeasureConfig::Perspective { spp, .. } => *spp = n,
            MeasureConfig::Lidar(l) => l.spp = n,
        }
    }

    /// The measure `measures[index]`; `earlier` are the measures before it (ids are unique).
    pub fn resolve(
        &self,
        ctx: &ConfigCtx,
        index: usize,
        earlier: &[Measure],
        at: &MeasureContext,
    ) -> Result<Measure, ConfigError> {
        let key = format!("measures[{index}]");
        let (id, spp, target) = self.common();
        let (fraction, adaptive) = self.check_sampling(ctx, &key, earlier)?;
        let kind = self.kind(ctx, &key, at)?;
        // The tightest target drives the rounds; the others are scales of it (checked against
        // the run's outputs by `finish_targets` once they are known).
        let tightest = target.map(|t| t.iter().copied().fold(f64::INFINITY, f64::min));
        Ok(Measure {
            id: id.clone(),
            spp,
            target_rel_stderr: tightest,
            target_scale: target
                .filter(|t| t.len() > 1)
                .map(|t| t.iter().map(|x| x / tightest.unwrap_or(1.0)).collect())
                .unwrap_or_default(),
            target_fraction: fraction.unwrap_or(0.5),
            adaptive: adaptive.unwrap_or(true),
            kind,
            block_override: None,
        })
    }

    /// Check the id, the sample count and the noise target; the images' target fraction and
    /// adaptive flag (as given).
    fn check_sampling(
        &self,
        ctx: &ConfigCtx,
        key: &str,
        earlier: &[Measure],
    ) -> Result<(Option<f64>, Option<bool>), ConfigError> {
        let (id, spp, target) = self.common();
        if id.is_empty()
            || !id.chars().all(|c| c.is_ascii_alphanumeric() || c == '_')
            || id.starts_with(|c: char| c.is_ascii_digit())
        {
            return Err(ctx.err(format!("{key}.id"), format!("\"{id}\" must be a non-empty identifier of letters, digits and _ (not starting with a digit)")));
        }
        if earlier.iter().any(|x| &x.id == id) {
            return Err(ctx.err(
                format!("{key}.id"),
                format!("\"{id}\" is used by another measure"),
            ));
        }
        if spp < 2 {
            return Err(ctx.err(
                format!("{key}.spp"),
                format!("{spp} must be at least 2 (a standard error needs two samples)"),
            ));
        }
        if let Some(list) = target {
            if list.is_empty() {
                return Err(ctx.err(
                    format!("{key}.target_rel_stderr"),
                    "must be a number or list one per wavelength (or band) of the run",
                ));
            }
            for (i, &t) in list.iter().enumerate() {
                if !(t > 0.0 && t < 1.0) {
                    let at = if list.len() > 1 {
                        format!("[{i}]")
                    } else {
                        String::new()
                    };
                    return Err(ctx.err(
                        format!("{key}.target_rel_stderr{at}"),
                        format!("{t} must lie in (0, 1)"),
                    ));
                }
            }
        }
        let (fraction, adaptive) = match self {
            MeasureConfig::Ortho {
                target_fraction,
                adaptive,
                ..
            }
            | MeasureConfig::Perspective {
                target_fraction,
                adaptive,
                ..
            } => (*target_fraction, *adaptive),
            MeasureConfig::Mdistant { .. }
            | MeasureConfig::Radiancemeter { .. }
            | MeasureConfig::DistantFlux { .. }
            | MeasureConfig::Hdrf { .. }
            | MeasureConfig::Lidar(_) => (None, None),
        };
        if adaptive.is_some() && target.is_none() {
            return Err(ctx.err(
                format!("{key}.adaptive"),
                "is used only with target_rel_stderr",
            ));
        }
        if let Some(f) = fraction {
            let fkey = format!("{key}.target_fraction");
            if !(f > 0.0 && f <= 1.0) {
                return Err(ctx.err(
                    fkey,
                    format!("{f} must lie in (0, 1] (the fraction of pixels that must meet the target; 1: every pixel)"),
                ));
            }
            if target.is_none() {
                return Err(ctx.err(fkey, "is used only with target_rel_stderr"));
            }
        }
        Ok((fraction, adaptive))
    }

    /// What the measure observes (its directions, level, image or area), checked against the
    /// atmosphere's levels and the scene.
    fn kind(
        &self,
        ctx: &ConfigCtx,
        key: &str,
        at: &MeasureContext,
    ) -> Result<MeasureKind, ConfigError> {
        let key = key.to_string();
        let scene = at.scene;
        Ok(match self {
            MeasureConfig::Mdistant {
                construct,
                azimuth,
                zeniths,
                azimuths,
                target_m,
                target_height_m,
                ..
            } => {
                let (directions, vza, vaa) =
                    view_directions(ctx, &key, *construct, *azimuth, zeniths, azimuths)?;
                let area = match (scene, target_m, target_height_m) {
                    (Some(sc), r, h) => Some(
                        masked_area(sc, *r, *h)
                            .map_err(|e| ctx.err(format!("{key}.target_m"), e.to_string()))?,
                    ),
                    (None, None, None) => None,
                    (None, _, _) => {
                        return Err(ctx.err(
                            format!("{key}.target_m"),
                            "a target area needs a 3D `scene`",
                        ))
                    }
                };
                MeasureKind::Distant {
                    directions,
                    vza,
                    vaa,
                    area,
                }
            }
            MeasureConfig::Ortho {
                pixel_size_m,
                window_m,
                zenith,
                azimuth,
                ..
            } => {
                let sc = scene
                    .ok_or_else(|| ctx.err(key.clone(), "an ortho measure needs a 3D `scene`"))?;
                MeasureKind::Ortho(
                    ortho_grid(sc, *pixel_size_m, *window_m, *zenith, *azimuth)
                        .map_err(|(k, m)| ctx.err(format!("{key}.{k}"), m))?,
                )
            }
            MeasureConfig::Perspective {
                origin_m,
                target_m,
                up,
                fov,
                width,
                height,
                ..
            } => {
                let sc = scene.ok_or_else(|| {
                    ctx.err(key.clone(), "a perspective measure needs a 3D `scene`")
                })?;
                MeasureKind::Perspective(
                    camera(sc, *origin_m, *target_m, *up, *fov, *width, *height)
                        .map_err(|(k, m)| ctx.err(format!("{key}.{k}"), m))?,
                )
            }
            MeasureConfig::DistantFlux { .. } | MeasureConfig::Hdrf { .. } if scene.is_some() => {
                return Err(ctx.err(
                    key.clone(),
                    "distant_flux and hdrf measures are 1D; with a 3D scene use `perspective`, a `radiancemeter` or an `mdistant` with a target area",
                ))
            }
            MeasureConfig::Hdrf {
                altitude,
                construct,
                azimuth,
                zeniths,
                azimuths,
                ..
            } => {
                let a = altitude.map(|a| a * 1e3).unwrap_or(at.ground);
                check_level(ctx, &key, a, at)?;
                let (directions, vza, vaa) =
                    view_directions(ctx, &key, *construct, *azimuth, zeniths, azimuths)?;
                MeasureKind::Hdrf {
                    directions,
                    vza,
                    vaa,
                    altitude: a,
                }
            }
            MeasureConfig::Radiancemeter {
                origin,
                direction,
                frame_azimuth,
                ..
            } => radiancemeter(ctx, &key, origin, direction, *frame_azimuth, at)?,
            MeasureConfig::DistantFlux {
                altitude,
                direction,
                ..
            } => {
                let a = altitude.map(|a| a * 1e3).unwrap_or(at.toa);
                check_level(ctx, &key, a, at)?;
                MeasureKind::DistantFlux {
                    altitude: a,
                    direction: direction.unwrap_or(FluxDirection::Up),
                }
            }
            MeasureConfig::Lidar(_) => {
                return Err(ctx.err(
                    key.clone(),
                    "a lidar is resolved by `LidarConfig::resolve`, not as a passive measure",
                ))
            }
        })
    }
}

/// A radiancemeter at `origin` (km) looking along `direction`, checked finite, non-zero and
/// above the ground.
fn radiancemeter(
    ctx: &ConfigCtx,
    key: &str,
    origin: &[f64; 3],
    direction: &[f64; 3],
    frame_azimuth: Option<f64>,
    at: &MeasureContext,
) -> Result<MeasureKind, ConfigError> {
    for i in 0..3 {
        ctx.finite(&format!("{key}.origin[{i}]"), origin[i])?;
        ctx.finite(&format!("{key}.direction[{i}]"), direction[i])?;
    }
    let mut o = DVec3::from_array(*origin) * 1e3;
    if let Some(sc) = at.scene {
        // In a scene the position is in the scene's coordinates (km).
        let (x, y) = sc.to_local(o.x, o.y);
        o = DVec3::new(x, y, o.z);
    }
    let d = DVec3::from_array(*direction);
    if d.length() < 1e-12 {
        return Err(ctx.err(format!("{key}.direction"), "must not be the zero vector"));
    }
    if o.z < at.ground {
        return Err(ctx.err(
            format!("{key}.origin[2]"),
            format!(
                "altitude {} km is below the ground ({} km)",
                origin[2],
                at.ground / 1e3
            ),
        ));
    }
    let frame_azimuth = match frame_azimuth {
        Some(a) => ctx.finite(&format!("{key}.frame_azimuth"), a)?.to_radians(),
        None => 0.0,
    };
    Ok(MeasureKind::Radiancemeter {
        origin: o,
        look: d.normalize(),
        frame_azimuth,
    })
}

/// A level's altitude `a` (m) lies between the ground and the top of the atmosphere.
fn check_level(ctx: &ConfigCtx, key: &str, a: f64, at: &MeasureContext) -> Result<(), ConfigError> {
    if !a.is_finite() || a < at.ground || a > at.toa {
        return Err(ctx.err(
            format!("{key}.altitude"),
            format!(
                "{} km must lie between the ground and the top of the atmosphere",
                a / 1e3
            ),
        ));
    }
    Ok(())
}

/// Unit vectors towards the sensor, their zeniths and azimuths (degrees).
type ViewDirections = (Vec<DVec3>, Vec<f64>, Vec<f64>);

/// The view directions of an `mdistant` or `hdrf` measure: unit vectors towards the sensor
/// with their zeniths and azimuths (degrees); `construct` defaults to `"directions"` when
/// `azimuths` is given, else `"hplane"`.
fn view_directions(
    ctx: &ConfigCtx,
    key: &str,
    construct: Option<Construct>,
    azimuth: Option<f64>,
    zeniths: &[f64],
    azimuths: &Option<Vec<f64>>,
) -> Result<ViewDirections, ConfigError> {
    let construct = construct.unwrap_or(if azimuths.is_some() {
        Construct::Directions
    } else {
        Construct::Hplane
    });
    if zeniths.is_empty() {
        return Err(ctx.err(format!("{key}.zeniths"), "must list at least one zenith"));
    }
    let (vza, vaa) = distant_directions(ctx, key, construct, azimuth, zeniths, azimuths)?;
    let directions = vza
        .iter()
        .zip(&vaa)
        .map(|(z, a)| direction_from_angles(z.to_radians(), a.to_radians()))
        .collect();
    Ok((directions, vza, vaa))
}

/// View zeniths and azimuths (degrees, azimuths in [0, 360)) of an `mdistant` measure.
fn distant_directions(
    ctx: &ConfigCtx,
    key: &str,
    construct: Construct,
    azimuth: Option<f64>,
    zeniths: &[f64],
    azimuths: &Option<Vec<f64>>,
) -> Result<(Vec<f64>, Vec<f64>), ConfigError> {
    let (mut vza, mut vaa) = (Vec::new(), Vec::new());
    match construct {
        Construct::Hplane => {
            if azimuths.is_some() {
                return Err(ctx.err(
                    format!("{key}.azimuths"),
                    "is not used by construct \"hplane\" (use `azimuth`)",
                ));
            }
            let az = azimuth.ok_or_else(|| {
                ctx.err(
                    format!("{key}.azimuth"),
                    "is required by construct \"hplane\"",
                )
            })?;
            let az = ctx.finite(&format!("{key}.azimuth"), az)?;
            for (i, &z) in zeniths.iter().enumerate() {
                if !z.is_finite() || z <= -90.0 || z >= 90.0 {
                    return Err(ctx.err(
                        format!("{key}.zeniths[{i}]"),
                        format!("{z} degrees must lie in (-90, 90)"),
                    ));
                }
                vza.push(z.abs());
                vaa.push(if z >= 0.0 { az } else { az + 180.0 }.rem_euclid(360.0));
            }
        }
        Construct::Directions => {
            if azimuth.is_some() {
                return Err(ctx.err(
                    format!("{key}.azimuth"),
                    "is not used by construct \"directions\" (use `azimuths`)",
                ));
            }
            let azs = azimuths.as_ref().ok_or_else(|| {
                ctx.err(
                    format!("{key}.azimuths"),
                    "is required by construct \"directions\"",
                )
            })?;
            if azs.len() != zeniths.len() {
                return Err(ctx.err(
                    format!("{key}.azimuths"),
                    format!(
                        "has {} values but `zeniths` has {}",
                        azs.len(),
                        zeniths.len()
                    ),
                ));
            }
            for (i, (&z, &a)) in zeniths.iter().zip(azs).enumerate() {
                if !z.is_finite() || !(0.0..90.0).contains(&z) {
                    return Err(ctx.err(
                        format!("{key}.zeniths[{i}]"),
                        format!("{z} degrees must lie in [0, 90)"),
                    ));
                }
                let a = ctx.finite(&format!("{key}.azimuths[{i}]"), a)?;
                vza.push(z);
                vaa.push(a.rem_euclid(360.0));
            }
        }
        Construct::Hemisphere => {
            if azimuth.is_some() {
                return Err(ctx.err(
                    format!("{key}.azimuth"),
                    "is not used by construct \"hemisphere\" (use `azimuths`)",
                ));
            }
            let azs = azimuths.as_ref().filter(|a| !a.is_empty()).ok_or_else(|| {
                ctx.err(
                    format!("{key}.azimuths"),
                    "is required by construct \"hemisphere\" (at least one azimuth)",
                )
            })?;
            if zeniths.len().saturating_mul(azs.len()) > 1_000_000 {
                return Err(ctx.err(
                    format!("{key}.zeniths"),
                    format!(
                        "{} zeniths × {} azimuths is more than 10⁶ directions",
                        zeniths.len(),
                        azs.len()
                    ),
                ));
            }
            for (i, &z) in zeniths.iter().enumerate() {
                if !z.is_finite() || !(0.0..90.0).contains(&z) {
                    return Err(ctx.err(
                        format!("{key}.zeniths[{i}]"),
                        format!("{z} degrees must lie in [0, 90)"),
                    ));
                }
                for (j, &a) in azs.iter().enumerate() {
                    let a = ctx.finite(&format!("{key}.azimuths[{j}]"), a)?;
                    vza.push(z);
                    vaa.push(a.rem_euclid(360.0));
                }
            }
        }
    }
    Ok((vza, vaa))
}

/// A (sub-key, message) error of a scene measure; the caller prefixes the measure's key.
type SubErr = (String, String);

/// Why the target area of a distant measure (`target_m`, an ortho measure's `window_m`) is
/// refused; the caller names the key.
#[derive(Debug, thiserror::Error)]
pub enum AreaError {
    #[error("must be [xmin, ymin, xmax, ymax] with min < max")]
    BadRect { rect: [f64; 4] },
    #[error("target height {height} is not finite")]
    Height { height: f64 },
    /// `share`: the fraction of the rectangle inside the bundle's area polygon.
    #[error(
        "only {:.3} % of the target area lies inside the bundle's area polygon (manifest [area]); at least {} % must",
        100.0 * .share,
        100.0 * MIN_SHARE_INSIDE
    )]
    OutsideMask { share: f64 },
}

/// The target area of a distant measure (default: the scene's extent at its top).
fn area(
    scene: &SceneFrame,
    rect: Option<[f64; 4]>,
    height: Option<f64>,
) -> Result<Area, AreaError> {
    let rect = match rect {
        None => scene.extent,
        Some(r) => {
            if !(r.iter().all(|v| v.is_finite()) && r[0] < r[2] && r[1] < r[3]) {
                return Err(AreaError::BadRect { rect: r });
            }
            let (a, b) = scene.to_local(r[0], r[1]);
            let (c, d) = scene.to_local(r[2], r[3]);
            [a, b, c, d]
        }
    };
    let height = height.unwrap_or(scene.top);
    if !height.is_finite() {
        return Err(AreaError::Height { height });
    }
    Ok(Area {
        rect,
        height,
        mask: None,
    })
}

/// [`area`] masked by the bundle's area polygon, if any; refused when (almost) none of the
/// rectangle lies inside it (the sample points are redrawn until inside, sensor.rs).
fn masked_area(
    scene: &SceneFrame,
    rect: Option<[f64; 4]>,
    height: Option<f64>,
) -> Result<Area, AreaError> {
    let mut a = area(scene, rect, height)?;
    if let Some(m) = &scene.mask {
        let share = m.share_inside(a.rect);
        if share < MIN_SHARE_INSIDE {
            return Err(AreaError::OutsideMask { share });
        }
        a.mask = Some(m.clone());
    }
    Ok(a)
}

/// The least inside share of a masked target area (bounds the redraws of a sample point).
pub const MIN_SHARE_INSIDE: f64 = 1e-3;

/// The pixel grid of an ortho measure, snapped outwards to whole pixels.
fn ortho_grid(
    scene: &SceneFrame,
    pixel: f64,
    window: Option<[f64; 4]>,
    zenith: f64,
    azimuth: f64,
) -> Result<OrthoGrid, SubErr> {
    if !(pixel.is_finite() && pixel > 0.0) {
        return Err(("pixel_size_m".into(), format!("{pixel} must be > 0")));
    }
    if !(zenith.is_finite() && (0.0..89.0).contains(&zenith)) {
        return Err((
            "zenith".into(),
            format!("{zenith} degrees must lie in [0, 89)"),
        ));
    }
    if !azimuth.is_finite() {
        return Err(("azimuth".into(), format!("{azimuth} is not finite")));
    }
    let a = area(scene, window, None).map_err(|e| ("window_m".into(), e.to_string()))?;
    let r = a.rect;
    let width = ((r[2] - r[0]) / pixel).ceil().max(1.0) as usize;
    let height = ((r[3] - r[1]) / pixel).ceil().max(1.0) as usize;
    if width.saturating_mul(height) > 50_000_000 {
        // Name the key that made the grid large: the window when one is given.
        let (key, advice) = match window {
            Some(w) => (
                "window_m",
                format!(
                    "a {:.0} m × {:.0} m window at {pixel} m",
                    w[2] - w[0],
                    w[3] - w[1]
                ),
            ),
            None => ("pixel_size_m", format!("the scene at {pixel} m")),
        };
        return Err((
            key.into(),
            format!("{advice} makes {width} × {height} pixels, too many (limit 5·10⁷); use a larger pixel_size_m or a smaller window_m"),
        ));
    }
    // Centre the snapped grid on the requested window.
    let x0 = 0.5 * (r[0] + r[2]) - 0.5 * width as f64 * pixel;
    let y1 = 0.5 * (r[1] + r[3]) + 0.5 * height as f64 * pixel;
    let azimuth = azimuth.rem_euclid(360.0);
    Ok(OrthoGrid {
        width,
        height,
        geotransform: [x0, pixel, 0.0, y1, 0.0, -pixel],
        view: direction_from_angles(zenith.to_radians(), azimuth.to_radians()),
        vza: zenith,
        vaa: azimuth,
    })
}

/// A pinhole camera from origin, target, up and horizontal field of view.
fn camera(
    scene: &SceneFrame,
    origin: [f64; 3],
    target: [f64; 3],
    up: Option<[f64; 3]>,
    fov: f64,
    width: usize,
    height: usize,
) -> Result<Camera, SubErr> {
    if origin.iter().chain(&target).any(|v| !v.is_finite()) {
        return Err(("origin_m".into(), "origin and target must be finite".into()));
    }
    if !(fov > 0.0 && fov < 179.0) {
        return Err(("fov".into(), format!("{fov} degrees must lie in (0, 179)")));
    }
    if width == 0 || height == 0 || width.saturating_mul(height) > 50_000_000 {
        return Err((
            "width".into(),
            "width and height must be 1..; at most 5·10⁷ pixels".into(),
        ));
    }
    let (ox, oy) = scene.to_local(origin[0], origin[1]);
    let (tx, ty) = scene.to_local(target[0], target[1]);
    let o = DVec3::new(ox, oy, origin[2]);
    let t = DVec3::new(tx, ty, target[2]);
    let forward = (t - o).normalize_or_zero();
    if forward == DVec3::ZERO {
        return Err(("target_m".into(), "must differ from origin_m".into()));
    }
    let upv = DVec3::from_array(up.unwrap_or([0.0, 0.0, 1.0]));
    let right = forward.cross(upv).normalize_or_zero();
    if right == DVec3::ZERO {
        return Err((
            "up".into(),
            "must not be parallel to the viewing direction".into(),
        ));
    }
    let true_up = right.cross(forward);
    let tan_x = (0.5 * fov).to_radians().tan();
    let tan_y = tan_x * height as f64 / width as f64;
    Ok(Camera {
        origin: o,
        forward,
        right,
        up: true_up,
        tan_x,
        tan_y,
        width,
        height,
    })
}

/// `target_rel_stderr`: a number, or a list with one per output of the run (wavelength, or
/// band with `spectral.bands`).
fn target_list<'de, D: serde::Deserializer<'de>>(d: D) -> Result<Option<Vec<f64>>, D::Error> {
    #[derive(serde::Deserialize)]
    #[serde(untagged)]
    enum T {
        One(f64),
        Many(Vec<f64>),
    }
    Ok(Some(
        match T::deserialize(d).map_err(|_| {
            serde::de::Error::custom(
                "expected a number or a list of numbers, one per wavelength or band",
            )
        })? {
            T::One(x) => vec![x],
            T::Many(v) => v,
        },
    ))
}

/// Per-output targets (`target_rel_stderr` as a list) checked against the run's `outputs`
/// (wavelengths, or bands): one value each.
pub fn finish_targets(
    ctx: &ConfigCtx,
    measures: &[Measure],
    outputs: usize,
    what: &str,
) -> Result<(), ConfigError> {
    for (i, m) in measures.iter().enumerate() {
        if !m.target_scale.is_empty() && m.target_scale.len() != outputs {
            return Err(ctx.err(
                format!("measures[{i}].target_rel_stderr"),
                format!(
                    "lists {} targets: give one number, or one per {what} of the run ({outputs})",
                    m.target_scale.len()
                ),
            ));
        }
    }
    Ok(())
}

/// With a sensor band, `target_rel_stderr` is the target of the band-weighted result: each of
/// the N independent wavelengths may then be √N_eff times noisier, with
/// N_eff = (Σ a_k)² / Σ a_k² and a_k = w_k·E0_k (equal relative errors combine this way).
pub fn relax_targets_for_band(measures: &mut [Measure], weights: &[f64], irradiance: &[f64]) {
    let a: Vec<f64> = weights.iter().zip(irradiance).map(|(w, e)| w * e).collect();
    let (s1, s2) = (a.iter().sum::<f64>(), a.iter().map(|x| x * x).sum::<f64>());
    if s2 > 0.0 {
        let n_eff = s1 * s1 / s2;
        for m in measures {
            if let Some(t) = m.target_rel_stderr {
                m.target_rel_stderr = Some((t * n_eff.sqrt()).min(0.5));
            }
        }
    }
}

/// CKD runs whose blocks of samples cycle through `ng` g-points: every measure's sample count
/// becomes a whole number of cycles (rounded up, logged).
pub fn round_to_g_point_cycles(measures: &mut [Measure], ng: usize) {
    for m in measures {
        // Images: blocks of IMAGE_BLOCK/ng samples (but at least one sample of each of the
        // 16 replicates, `accum::REPLICATES`), so that one cycle through the g-points is
        // IMAGE_BLOCK samples per pixel rather than IMAGE_BLOCK per g-point.
        if m.is_image() {
            m.block_override =
                Some((super::IMAGE_BLOCK / ng as u64).max(crate::accum::REPLICATES as u64));
        }
        let unit = m.block_size() * ng as u64;
        let spp = m.spp.div_ceil(unit) * unit;
        if spp != m.spp {
            tracing::info!(
                "measure `{}`: spp {} rounded up to {spp} (whole cycles of {ng} g-points × {} samples)",
                m.id,
                m.spp,
                unit / ng as u64
            );
            m.spp = spp;
        }
    }
}
