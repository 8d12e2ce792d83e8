//! Lamps: point and spot lights with a spectral intensity and an angular profile, placed in
//! the experiment (`[[lights]]`), seen by the backward walks through next-event estimates
//! with many-light sampling (`tree.rs`).
//!
//! | key | type | unit | default | meaning |
//! |---|---|---|---|---|
//! | `type` | string | — | required | `"point"` (a profile about `direction`: isotropic by default) or `"spot"` (a cone about `direction`) |
//! | `position_m` | [x, y, z] | m | required | the lamp, in the scene's coordinates (a bundle's working CRS; heights in m); in 1D runs over the ground at z = 0 |
//! | `intensity` | number, list, table or name | W sr⁻¹ nm⁻¹ | required | the radiant intensity on the profile's axis (its maximum): a number, one value per run wavelength, a `{ wavelengths_nm, values }` table, or a lamp type (`spectra.rs`: `"hps"`, `"led_3000k"`, `"led_4000k"`, `"metal_halide"`) scaled to `luminous_intensity_cd` |
//! | `luminous_intensity_cd` | number > 0 | cd | `1000` | named lamp types: the luminous intensity on the axis (with an IES profile the file's candela are used instead) |
//! | `direction` | [x, y, z] | — | `[0, 0, -1]` | the profile's axis (spots: the cone's; IES: the photometric nadir) |
//! | `cone_angle` | number in (0, 180) | deg | required by `spot` | the cone's half angle: no light beyond it |
//! | `falloff_angle` | number in (0, `cone_angle`] | deg | `cone_angle` | spots: full intensity up to it, then a smooth (cubic) decrease to 0 at `cone_angle` |
//! | `profile` | table | — | isotropic | points: `{ type = "isotropic" }`, `{ type = "cosine_power", exponent = n }` (I₀ cosⁿθ about the axis, 0 behind; n ≥ 0) or `{ type = "ies", file = "….ies" }` (an IES LM-63 type C file, `ies.rs`, relative to the experiment file) |
//! | `rotation` | number | deg | `0` | IES profiles: azimuth (clockwise from North) of the luminaire's C = 0° plane about a vertical axis |
//!
//! Radiometry: a lamp at `q` of radiant intensity `I(λ, ω)` (W sr⁻¹ nm⁻¹) lights a point `p` at
//! distance r with irradiance `I(λ, (p − q)/r)·T/r²` normal to the beam, T the transmittance
//! (atmosphere along the segment, scene visibility, panes). A surface then reflects
//! `f·|cos θ|·I·T/r²` towards the viewer, the air `ω·P/(4π)·I·T/r²`. The walks add these at
//! every surface hit and collision for one lamp drawn by the light tree, divided by its
//! probability (or for every lamp with `integrator.lamp_sampling = "all"`), in units of the
//! run's irradiance (E0, or 1 without a Sun): radiances are then correct with any Sun, the
//! Moon or none (`illumination.type = "none"`: lamps alone, radiances only). Lamps are points:
//! the sensor never sees one directly (a delta in position), as it never sees the Sun.

pub mod ies;
pub mod spectra;
pub mod tree;

use std::sync::Arc;

use glam::DVec3;
use serde::Deserialize;

use crate::error::{ConfigCtx, ConfigError};
use crate::spectral::{Spectrum, SpectrumExt};
use ies::Photometry;
use tree::LightTree;

/// Most lamps an experiment may place (memory: about 200 B each with the tree).
pub const MAX_LAMPS: usize = 10_000_000;

/// `type` of a `[[lights]]` entry.
#[derive(Clone, Copy, Debug, Deserialize, PartialEq)]
#[serde(rename_all = "snake_case")]
pub enum LampKind {
    Point,
    Spot,
}

/// `profile` of a point lamp.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
pub enum ProfileConfig {
    Isotropic,
    CosinePower { exponent: f64 },
    Ies { file: String },
}

/// `intensity`: a lamp type's name or a spectral value.
#[derive(Clone, Debug, PartialEq)]
pub enum IntensityConfig {
    Named(String),
    Spectral(Spectrum),
}

impl<'de> Deserialize<'de> for IntensityConfig {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct V;
        impl<'de> serde::de::Visitor<'de> for V {
            type Value = IntensityConfig;
            fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                f.write_str("a number (W sr⁻¹ nm⁻¹), a list of numbers (one per wavelength), a table { wavelengths_nm, values } or a lamp type name")
            }
            fn visit_str<E: serde::de::Error>(self, v: &str) -> Result<IntensityConfig, E> {
                Ok(IntensityConfig::Named(v.to_string()))
            }
            fn visit_f64<E: serde::de::Error>(self, v: f64) -> Result<IntensityConfig, E> {
                Ok(IntensityConfig::Spectral(Spectrum::Constant(v)))
            }
            fn visit_i64<E: serde::de::Error>(self, v: i64) -> Result<IntensityConfig, E> {
                Ok(IntensityConfig::Spectral(Spectrum::Constant(v as f64)))
            }
            fn visit_u64<E: serde::de::Error>(self, v: u64) -> Result<IntensityConfig, E> {
                Ok(IntensityConfig::Spectral(Spectrum::Constant(v as f64)))
            }
            fn visit_seq<A: serde::de::SeqAccess<'de>>(
                self,
                seq: A,
            ) -> Result<Self::Value, A::Error> {
                Spectrum::deserialize(serde::de::value::SeqAccessDeserializer::new(seq))
                    .map(IntensityConfig::Spectral)
            }
            fn visit_map<A: serde::de::MapAccess<'de>>(
                self,
                map: A,
            ) -> Result<Self::Value, A::Error> {
                Spectrum::deserialize(serde::de::value::MapAccessDeserializer::new(map))
                    .map(IntensityConfig::Spectral)
            }
        }
        d.deserialize_any(V)
    }
}

/// One `[[lights]]` entry as written.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LampConfig {
    #[serde(rename = "type")]
    pub kind: LampKind,
    pub position_m: [f64; 3],
    pub intensity: IntensityConfig,
    #[serde(default)]
    pub luminous_intensity_cd: Option<f64>,
    #[serde(default)]
    pub direction: Option<[f64; 3]>,
    #[serde(default)]
    pub cone_angle: Option<f64>,
    #[serde(default)]
    pub falloff_angle: Option<f64>,
    #[serde(default)]
    pub profile: Option<ProfileConfig>,
    #[serde(default)]
    pub rotation: Option<f64>,
}

/// The angular shape of a lamp's intensity, relative to its axis value.
#[derive(Clone, Debug)]
pub enum Profile {
    Isotropic,
    /// `cosⁿθ` in front of the axis, 0 behind.
    CosinePower(f64),
    /// 1 within `cos_inner`, a smooth step down to 0 at `cos_outer`.
    Spot {
        cos_inner: f64,
        cos_outer: f64,
    },
    /// An IES table (candela) times `scale`, with the C = 0° direction `c0` (⟂ axis).
    Ies {
        table: Arc<Photometry>,
        scale: f64,
        c0: DVec3,
    },
}

/// A resolved lamp (scene-local frame).
#[derive(Clone, Debug)]
pub struct Lamp {
    pub position: DVec3,
    /// Unit axis of the profile.
    pub axis: DVec3,
    pub profile: Profile,
    /// Radiant intensity on the axis at each run wavelength, W sr⁻¹ nm⁻¹ (for IES profiles
    /// the intensity per candela of the table).
    pub intensity: Vec<f64>,
}

impl Lamp {
    /// The profile's factor towards unit direction `w` (from the lamp).
    #[inline]
    pub fn shape(&self, w: DVec3) -> f64 {
        let c = w.dot(self.axis);
        match &self.profile {
            Profile::Isotropic => 1.0,
            Profile::CosinePower(n) => {
                if c <= 0.0 {
                    0.0
                } else {
                    c.powf(*n)
                }
            }
            Profile::Spot {
                cos_inner,
                cos_outer,
            } => {
                if c >= *cos_inner {
                    1.0
                } else if c <= *cos_outer {
                    0.0
                } else {
                    let t = (c - cos_outer) / (cos_inner - cos_outer);
                    t * t * (3.0 - 2.0 * t)
                }
            }
            Profile::Ies { table, scale, c0 } => {
                let gamma = c.clamp(-1.0, 1.0).acos().to_degrees();
                // C counter-clockwise seen from the side the axis points away from.
                let c90 = self.axis.cross(*c0) * -1.0;
                let h = w.dot(c90).atan2(w.dot(*c0)).to_degrees();
                table.at(gamma, h) * scale
            }
        }
    }

    /// `∫ shape dΩ` over the sphere, sr.
    pub fn solid_angle(&self) -> f64 {
        use std::f64::consts::PI;
        match &self.profile {
            Profile::Isotropic => 4.0 * PI,
            Profile::CosinePower(n) => 2.0 * PI / (n + 1.0),
            Profile::Spot {
                cos_inner,
                cos_outer,
            } => 2.0 * PI * (1.0 - 0.5 * (cos_inner + cos_outer)),
            Profile::Ies { table, scale, .. } => table.flux() * scale,
        }
    }
}

/// Which estimator carries the lamps' light (`integrator.lamp_estimator`).
#[derive(Clone, Copy, Debug, Default, Deserialize, PartialEq)]
#[serde(rename_all = "snake_case")]
pub enum LampEstimator {
    /// Forward photons for nadir ortho images (`integrator/lamp_photons.rs`), next-event
    /// estimates in the backward walks for every other measure.
    #[default]
    Auto,
    /// Next-event estimates in the backward walks for every measure.
    Backward,
    /// Forward photons; every measure must be a nadir ortho image.
    Forward,
}

/// Default `integrator.lamp_photons`: photons per lamp and wavelength.
pub const LAMP_PHOTONS: u32 = 256;

/// How the walks pick lamps (`integrator.lamp_sampling`).
#[derive(Clone, Copy, Debug, Default, Deserialize, PartialEq)]
#[serde(rename_all = "snake_case")]
pub enum LampSampling {
    /// One lamp per estimate from the light tree.
    #[default]
    Tree,
    /// Every lamp at every estimate (a reference; cost ∝ the number of lamps).
    All,
}

/// The lamps of a run.
#[derive(Clone, Debug)]
pub struct Lamps {
    pub lamps: Vec<Lamp>,
    tree: LightTree,
    pub sampling: LampSampling,
    /// Lamps drawn per next-event estimate at a surface (`integrator.lamp_samples`), averaged.
    pub samples: u32,
    /// `integrator.lamp_estimator`.
    pub estimator: LampEstimator,
    /// `integrator.lamp_photons`: forward photons per lamp (on average, in proportion to its
    /// power) and wavelength.
    pub photons: u32,
    /// Emitting scene materials (`scene.emitters`): per material id, the radiance its surfaces
    /// send in every direction at each run wavelength, W m⁻² sr⁻¹ nm⁻¹ (empty: none).
    pub emitters: Vec<Vec<f64>>,
}

impl Lamps {
    /// Resolve the `[[lights]]` entries: positions through `to_local` (scene coordinates → the
    /// scene's local frame), intensities at the run wavelengths (`ctx.wavelengths`).
    pub fn resolve(
        cfgs: &[LampConfig],
        ctx: &ConfigCtx,
        to_local: impl Fn(f64, f64) -> (f64, f64),
        sampling: LampSampling,
    ) -> Result<Self, ConfigError> {
        Self::resolve_with(cfgs, ctx, to_local, sampling, Vec::new())
    }

    /// [`Lamps::resolve`] plus lamps resolved elsewhere (`more`: the bundle's template lamps).
    pub fn resolve_with(
        cfgs: &[LampConfig],
        ctx: &ConfigCtx,
        to_local: impl Fn(f64, f64) -> (f64, f64),
        sampling: LampSampling,
        more: Vec<Lamp>,
    ) -> Result<Self, ConfigError> {
        if cfgs.len() + more.len() > MAX_LAMPS {
            return Err(ctx.err(
                "lights",
                format!("{} lamps: at most {MAX_LAMPS}", cfgs.len() + more.len()),
            ));
        }
        let mut ies_cache: std::collections::HashMap<String, Arc<Photometry>> = Default::default();
        let mut lamps = Vec::with_capacity(cfgs.len() + more.len());
        for (i, c) in cfgs.iter().enumerate() {
            lamps.push(resolve_one(
                c,
                &format!("lights[{i}]"),
                ctx,
                &to_local,
                &mut ies_cache,
            )?);
        }
        lamps.extend(more);
        let power: Vec<f64> = lamps
            .iter()
            .map(|l| {
                let mean = l.intensity.iter().sum::<f64>() / l.intensity.len().max(1) as f64;
                mean * l.solid_angle()
            })
            .collect();
        let positions: Vec<DVec3> = lamps.iter().map(|l| l.position).collect();
        Ok(Lamps {
            tree: LightTree::new(&positions, &power),
            lamps,
            sampling,
            samples: 1,
            estimator: LampEstimator::Auto,
            photons: LAMP_PHOTONS,
            emitters: Vec::new(),
        })
    }

    /// The lamps' light reaching point `p` at run wavelength `iw`, gathered by
    /// `Σ g(l̂)·I(−l̂)·seen(l̂, r)/r²/P` over the lamps of [`Lamps::draw`] (`normal`, `u` as
    /// there): `l̂` the unit direction from `p` to the lamp, `g` the surface's or the air's
    /// factor for light arriving from `l̂` and `seen` the transmittance and visibility over the
    /// distance `r` (called only where `g` and the intensity are > 0).
    #[inline]
    pub fn gather(
        &self,
        iw: usize,
        p: DVec3,
        normal: Option<DVec3>,
        u: f64,
        mut g: impl FnMut(DVec3) -> f64,
        mut seen: impl FnMut(DVec3, f64) -> f64,
    ) -> f64 {
        self.draw(p, normal, u, |lamp| {
            let v = lamp.position - p;
            let r2 = v.length_squared();
            if r2 <= 0.0 {
                return 0.0;
            }
            let r = r2.sqrt();
            let l = v / r;
            let f = g(l);
            if f <= 0.0 {
                return 0.0;
            }
            let i = lamp.intensity[iw] * lamp.shape(-l);
            if i <= 0.0 {
                return 0.0;
            }
            let t = seen(l, r);
            if t <= 0.0 {
                return 0.0;
            }
            f * i * t / r2
        })
    }

    /// A lamp's estimate `est(lamp)` over the lamp's probability, for one lamp drawn from the
    /// tree at `p` with the uniform number `u` (`normal`: a one-sided surface's, for the tree's
    /// receiver term); with `lamp_sampling = "all"` the sum of every lamp's.
    #[inline]
    pub fn draw(
        &self,
        p: DVec3,
        normal: Option<DVec3>,
        u: f64,
        mut est: impl FnMut(&Lamp) -> f64,
    ) -> f64 {
        match self.sampling {
            LampSampling::All => self.lamps.iter().map(&mut est).sum(),
            LampSampling::Tree => match self.tree.sample(p, normal, u) {
                Some((k, prob)) => est(&self.lamps[k]) / prob,
                None => 0.0,
            },
        }
    }
}

/// The lamps that a bundle template carries on each of its instances: every spec (a
/// `[[lights]]` table in the template frame) resolved once (errors name `key`), then placed at
/// each site (translation, linear part): positions transformed, axes turned.
pub fn template_lamps(
    specs: &[toml::Table],
    sites: &[(DVec3, glam::Mat3)],
    key: &str,
    ctx: &ConfigCtx,
) -> Result<Vec<Lamp>, ConfigError> {
    let mut out = Vec::with_capacity(specs.len() * sites.len());
    let mut cache = Default::default();
    for (k, spec) in specs.iter().enumerate() {
        let key = format!("{key}[{k}]");
        let cfg = LampConfig::deserialize(toml::Value::Table(spec.clone()))
            .map_err(|e| ctx.err(key.clone(), e.to_string()))?;
        let base = resolve_one(&cfg, &key, ctx, &|x, y| (x, y), &mut cache)?;
        for (t, m) in sites {
            let m = m.as_dmat3();
            let turn = |v: DVec3| (m * v).try_normalize().unwrap_or(v);
            let mut lamp = base.clone();
            lamp.position = *t + m * base.position;
            lamp.axis = turn(base.axis);
            if let Profile::Ies { c0, .. } = &mut lamp.profile {
                *c0 = turn(*c0);
            }
            out.push(lamp);
        }
    }
    Ok(out)
}

fn resolve_one(
    c: &LampConfig,
    key: &str,
    ctx: &ConfigCtx,
    to_local: &impl Fn(f64, f64) -> (f64, f64),
    ies_cache: &mut std::collections::HashMap<String, Arc<Photometry>>,
) -> Result<Lamp, ConfigError> {
    for (k, v) in c.position_m.iter().enumerate() {
        ctx.finite(&format!("{key}.position_m[{k}]"), *v)?;
    }
    let (x, y) = to_local(c.position_m[0], c.position_m[1]);
    let position = DVec3::new(x, y, c.position_m[2]);
    let axis = match c.direction {
        Some(d) => {
            for (k, v) in d.iter().enumerate() {
                ctx.finite(&format!("{key}.direction[{k}]"), *v)?;
            }
            let d = DVec3::from_array(d);
            if d.length() < 1e-12 {
                return Err(ctx.err(format!("{key}.direction"), "must not be the zero vector"));
            }
            d.normalize()
        }
        None => DVec3::NEG_Z,
    };
    let named = match &c.intensity {
        IntensityConfig::Named(n) => Some(n.as_str()),
        IntensityConfig::Spectral(_) => None,
    };
    if c.luminous_intensity_cd.is_some() && named.is_none() {
        return Err(ctx.err(
            format!("{key}.luminous_intensity_cd"),
            "applies to named lamp types (`intensity = \"hps\"`…); a number gives W sr⁻¹ nm⁻¹ itself",
        ));
    }
    let cd = match c.luminous_intensity_cd {
        Some(v) => {
            let v = ctx.finite(&format!("{key}.luminous_intensity_cd"), v)?;
            if v <= 0.0 {
                return Err(ctx.err(
                    format!("{key}.luminous_intensity_cd"),
                    format!("{v} must be > 0"),
                ));
            }
            v
        }
        None => 1000.0,
    };
    let per_unit = |candela: f64| -> Result<Vec<f64>, ConfigError> {
        match &c.intensity {
            IntensityConfig::Named(n) => spectra::intensity(n, ctx.wavelengths, candela)
                .ok_or_else(|| {
                    ctx.err(
                        format!("{key}.intensity"),
                        format!(
                            "unknown lamp type \"{n}\": one of {}, or a number, list or table (W sr⁻¹ nm⁻¹)",
                            spectra::NAMES.join(", ")
                        ),
                    )
                }),
            IntensityConfig::Spectral(s) => s.expand(ctx, &format!("{key}.intensity"), 0.0, 1e12),
        }
    };
    let not_for = |k: &str, v: bool, why: &str| {
        if v {
            Err(ctx.err(format!("{key}.{k}"), why.to_string()))
        } else {
            Ok(())
        }
    };
    let (profile, intensity) = match c.kind {
        LampKind::Spot => {
            not_for("profile", c.profile.is_some(), "a spot's profile is its cone (`cone_angle`, `falloff_angle`); profiles are for `type = \"point\"`")?;
            let outer = c.cone_angle.ok_or_else(|| {
                ctx.err(
                    format!("{key}.cone_angle"),
                    "is required for a spot (its half angle, degrees)",
                )
            })?;
            let outer = ctx.finite(&format!("{key}.cone_angle"), outer)?;
            if !(outer > 0.0 && outer < 180.0) {
                return Err(ctx.err(
                    format!("{key}.cone_angle"),
                    format!("{outer}° must lie in (0, 180)"),
                ));
            }
            let inner = match c.falloff_angle {
                Some(a) => {
                    let a = ctx.finite(&format!("{key}.falloff_angle"), a)?;
                    if !(a > 0.0 && a <= outer) {
                        return Err(ctx.err(
                            format!("{key}.falloff_angle"),
                            format!("{a}° must lie in (0, cone_angle = {outer}°]"),
                        ));
                    }
                    a
                }
                None => outer,
            };
            (
                Profile::Spot {
                    cos_inner: inner.to_radians().cos(),
                    cos_outer: outer.to_radians().cos(),
                },
                per_unit(cd)?,
            )
        }
        LampKind::Point => {
            not_for(
                "cone_angle",
                c.cone_angle.is_some(),
                "is for `type = \"spot\"`",
            )?;
            not_for(
                "falloff_angle",
                c.falloff_angle.is_some(),
                "is for `type = \"spot\"`",
            )?;
            match &c.profile {
                None | Some(ProfileConfig::Isotropic) => (Profile::Isotropic, per_unit(cd)?),
                Some(ProfileConfig::CosinePower { exponent }) => {
                    let n = ctx.finite(&format!("{key}.profile.exponent"), *exponent)?;
                    if !(0.0..=1e4).contains(&n) {
                        return Err(ctx.err(
                            format!("{key}.profile.exponent"),
                            format!("{n} must lie in [0, 10000]"),
                        ));
                    }
                    (Profile::CosinePower(n), per_unit(cd)?)
                }
                Some(ProfileConfig::Ies { file }) => {
                    let path = ctx.file(file);
                    let table = match ies_cache.get(file) {
                        Some(t) => t.clone(),
                        None => {
                            let t = Arc::new(
                                Photometry::read(&path)
                                    .map_err(|e| ctx.err(format!("{key}.profile.file"), e))?,
                            );
                            ies_cache.insert(file.clone(), t.clone());
                            t
                        }
                    };
                    if c.luminous_intensity_cd.is_some() {
                        return Err(ctx.err(
                            format!("{key}.luminous_intensity_cd"),
                            "an IES profile gives the candela itself",
                        ));
                    }
                    // Named: the file's candela are absolute (intensity per candela); a
                    // number is the intensity at the table's maximum.
                    let scale = if named.is_some() {
                        1.0
                    } else {
                        1.0 / table.max()
                    };
                    let rot = ctx.finite(&format!("{key}.rotation"), c.rotation.unwrap_or(0.0))?;
                    // C = 0 towards azimuth `rotation` (clockwise from North), made ⟂ axis.
                    let r = rot.to_radians();
                    let h = DVec3::new(r.sin(), r.cos(), 0.0);
                    let c0 = (h - axis * h.dot(axis))
                        .try_normalize()
                        .unwrap_or_else(|| crate::frame::basis_around(axis).0);
                    (Profile::Ies { table, scale, c0 }, per_unit(1.0)?)
                }
            }
        }
    };
    if c.rotation.is_some() && !matches!(profile, Profile::Ies { .. }) {
        return Err(ctx.err(format!("{key}.rotation"), "applies to IES profiles only"));
    }
    Ok(Lamp {
        position,
        axis,
        profile,
        intensity,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ctx<'a>(w: &'a [f64]) -> ConfigCtx<'a> {
        ConfigCtx {
            path: std::path::Path::new("test.toml"),
            base: std::path::Path::new("."),
            nw: w.len(),
            wavelengths: w,
        }
    }

    fn lamps(text: &str, w: &[f64], sampling: LampSampling) -> Result<Lamps, ConfigError> {
        #[derive(Deserialize)]
        struct F {
            lights: Vec<LampConfig>,
        }
        let f: F = toml::from_str(text).unwrap();
        Lamps::resolve(&f.lights, &ctx(w), |x, y| (x, y), sampling)
    }

    #[test]
    fn profiles_and_keys() {
        let w = [550.0];
        let l = lamps(
            "[[lights]]\ntype = \"spot\"\nposition_m = [0, 0, 10]\nintensity = 2.0\ncone_angle = 30.0\nfalloff_angle = 20.0\n\
             [[lights]]\ntype = \"point\"\nposition_m = [5, 0, 10]\nintensity = [3.0]\nprofile = { type = \"cosine_power\", exponent = 2 }\n\
             [[lights]]\ntype = \"point\"\nposition_m = [5, 5, 10]\nintensity = \"hps\"\nluminous_intensity_cd = 500\n",
            &w,
            LampSampling::Tree,
        )
        .unwrap();
        let spot = &l.lamps[0];
        let at = |deg: f64| {
            let t = deg.to_radians();
            DVec3::new(t.sin(), 0.0, -t.cos())
        };
        assert_eq!(spot.shape(at(10.0)), 1.0);
        assert_eq!(spot.shape(at(31.0)), 0.0);
        assert!(spot.shape(at(25.0)) > 0.0 && spot.shape(at(25.0)) < 1.0);
        let cp = &l.lamps[1];
        assert!((cp.shape(at(60.0)) - 0.25).abs() < 1e-12);
        assert_eq!(cp.shape(-at(60.0)), 0.0);
        assert!(
            (l.lamps[2].intensity[0] - spectra::intensity("hps", &w, 500.0).unwrap()[0]).abs()
                < 1e-15
        );
        for (text, key) in [
            ("type = \"spot\"\nposition_m = [0, 0, 1]\nintensity = 1.0\n", "lights[0].cone_angle"),
            ("type = \"spot\"\nposition_m = [0, 0, 1]\nintensity = 1.0\ncone_angle = 190.0\n", "lights[0].cone_angle"),
            ("type = \"point\"\nposition_m = [0, 0, 1]\nintensity = \"candle\"\n", "lights[0].intensity"),
            ("type = \"point\"\nposition_m = [0, 0, 1]\nintensity = -1.0\n", "lights[0].intensity"),
            ("type = \"point\"\nposition_m = [0, 0, 1]\nintensity = 1.0\nluminous_intensity_cd = 3.0\n", "lights[0].luminous_intensity_cd"),
            ("type = \"point\"\nposition_m = [0, 0, 1]\nintensity = 1.0\ncone_angle = 3.0\n", "lights[0].cone_angle"),
            ("type = \"point\"\nposition_m = [0, 0, 1]\nintensity = 1.0\ndirection = [0, 0, 0]\n", "lights[0].direction"),
            ("type = \"point\"\nposition_m = [0, 0, 1]\nintensity = 1.0\nprofile = { type = \"ies\", file = \"missing.ies\" }\n", "lights[0].profile.file"),
        ] {
            let e = lamps(&format!("[[lights]]\n{text}"), &w, LampSampling::Tree).unwrap_err().to_string();
            assert!(e.contains(key), "{text}: {e}");
        }
    }

    /// The tree's one-lamp estimate is unbiased: its mean over many draws equals the sum over
    /// every lamp (`"all"`), for a point among 500 lamps of three kinds.
    #[test]
    fn one_drawn_lamp_estimates_the_sum_over_all() {
        let mut text = String::new();
        let mut rng = crate::rng::Stream::new(2, [0, 0, 0, 0]);
        for i in 0..500 {
            let (x, y) = (rng.next_f64() * 400.0, rng.next_f64() * 400.0);
            let kind = match i % 3 {
                0 => "type = \"point\"\nintensity = 5.0".to_string(),
                1 => "type = \"spot\"\nintensity = 9.0\ncone_angle = 50.0\nfalloff_angle = 30.0".to_string(),
                _ => "type = \"point\"\nintensity = \"led_4000k\"\nprofile = { type = \"cosine_power\", exponent = 1.5 }".to_string(),
            };
            text += &format!("[[lights]]\nposition_m = [{x}, {y}, 8.0]\n{kind}\n");
        }
        let w = [550.0];
        let tree = lamps(&text, &w, LampSampling::Tree).unwrap();
        let all = lamps(&text, &w, LampSampling::All).unwrap();
        let p = DVec3::new(150.0, 220.0, 0.0);
        // A Lambertian floor's cos θ, and a made-up visibility that hides some lamps.
        let g = |l: DVec3| l.z.max(0.0);
        let seen = |l: DVec3, r: f64| if l.x > 0.9 { 0.0 } else { (-r / 300.0).exp() };
        let exact = all.gather(0, p, Some(DVec3::Z), 0.0, g, seen);
        let n = 200_000;
        let (mut s, mut s2) = (0.0, 0.0);
        for _ in 0..n {
            let v = tree.gather(0, p, Some(DVec3::Z), rng.next_f64(), g, seen);
            s += v;
            s2 += v * v;
        }
        let mean = s / n as f64;
        let se = ((s2 / n as f64 - mean * mean) / n as f64).sqrt();
        assert!(
            (mean - exact).abs() < 4.0 * se,
            "tree {mean} ± {se}, all {exact}"
        );
        assert!(se / mean < 0.01, "relative error {}", se / mean);
    }
}
