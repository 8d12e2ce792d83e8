//! The BRDF models as written in TOML: one spec struct per model, the tagged enum
//! [`BrdfSpec`] over them, and **the one table of allowed parameter ranges**,
//! [`BRDF_PARAM_RANGES`]. The same spec serves the experiment's 1D `[surface]`, the materials
//! of bundle manifests, land-cover schemes, region files and experiments, and canopy grounds.
//!
//! Adding a model here is one struct, one variant, one arm in [`BrdfSpec::type_name`] and
//! [`BrdfSpec::params`] and its rows in [`BRDF_PARAM_RANGES`]; the simulator's side is its file
//! in `engine/src/bsdf/` and its arm in `Bsdf::build` (CONTRIBUTING.md, "Adding a BRDF").

use serde::{Deserialize, Serialize};

use super::range::{ParamRange, Range};
use super::spectrum::Spectrum;

/// Lambertian: hemispherical reflectance in [0, 1].
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LambertianSpec {
    pub reflectance: Spectrum,
}

/// A two-sided leaf: Lambertian reflection and transmission (reflectance + transmittance ≤ 1).
/// As a 1D ground the transmitted light enters the ground and is absorbed, so it is the
/// Lambertian of the same reflectance there.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BiLambertianSpec {
    pub reflectance: Spectrum,
    pub transmittance: Spectrum,
}

/// Rahman–Pinty–Verstraete; `rho_c` defaults to `rho_0`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RpvSpec {
    pub rho_0: Spectrum,
    pub k: Spectrum,
    pub g: Spectrum,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rho_c: Option<Spectrum>,
}

/// Ross-Thick Li-Sparse (MODIS kernels).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RtlsSpec {
    pub f_iso: Spectrum,
    pub f_vol: Spectrum,
    pub f_geo: Spectrum,
}

/// RTLS with the Maignan et al. (2004) hot-spot factor; `xi0` in degrees (default 1.5°).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RtlsHotspotSpec {
    pub f_iso: Spectrum,
    pub f_vol: Spectrum,
    pub f_geo: Spectrum,
    #[serde(default = "default_xi0")]
    pub xi0: Spectrum,
}

/// ξ0 of Maignan et al. (2004), degrees.
pub const DEFAULT_XI0_DEG: f64 = 1.5;

fn default_xi0() -> Spectrum {
    Spectrum::Constant(DEFAULT_XI0_DEG)
}

/// Hapke (`theta` in degrees).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct HapkeSpec {
    pub w: Spectrum,
    pub b: Spectrum,
    pub c: Spectrum,
    pub theta: Spectrum,
    #[serde(rename = "B_0")]
    pub b_0: Spectrum,
    pub h: Spectrum,
}

/// Lommel–Seeliger: single scattering of a semi-infinite isotropic medium (`w`: the particles'
/// single-scattering albedo).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LommelSeeligerSpec {
    pub w: Spectrum,
}

/// Rough water surface (Cox–Munk, Fresnel, shadowing); wind speed in m/s, refractive index
/// 1.33 by default; polarizing.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OceanSpec {
    pub wind_speed: Spectrum,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub refractive_index: Option<Spectrum>,
    #[serde(default = "yes")]
    pub shadowing: bool,
}

/// The refractive index of water when none is given.
pub const DEFAULT_WATER_INDEX: f64 = 1.33;

fn yes() -> bool {
    true
}

/// A rough dielectric interface (GGX microfacets, Walter et al. 2007): reflection and
/// refraction between the outside (the side the surface's front normal points to: a template
/// triangle's winding, the terrain's upper side) and an inside of relative `refractive_index`;
/// `roughness` is the GGX α. Scene materials only (a 1D ground cannot transmit).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RoughDielectricSpec {
    pub refractive_index: Spectrum,
    pub roughness: Spectrum,
}

/// A thin dielectric slab (a glass pane): specular reflection and straight transmission with
/// the slab's internal reflections summed in closed form; `internal_transmittance` is the
/// transmittance of one pass through the slab at normal incidence (1: no absorption). Both
/// faces alike. Scene materials only.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ThinDielectricSpec {
    pub refractive_index: Spectrum,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub internal_transmittance: Option<Spectrum>,
}

/// A measured BRDF: a netCDF table over (wavelength, θi, θr, Δφ) in sr⁻¹, layout in the
/// simulator's `bsdf/tabulated.rs` and `docs/experiment.md`. `file` is relative to the bundle
/// folder (in a manifest) or to the experiment file (in an experiment); `symmetrize` averages
/// f(i, r) and f(r, i).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TabulatedSpec {
    pub file: String,
    #[serde(default)]
    pub symmetrize: bool,
}

/// A BRDF, named by its `type` tag as in `docs/experiment.md`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case")]
pub enum BrdfSpec {
    Lambertian(LambertianSpec),
    BiLambertian(BiLambertianSpec),
    Rpv(RpvSpec),
    Rtls(RtlsSpec),
    RtlsHotspot(RtlsHotspotSpec),
    Hapke(HapkeSpec),
    LommelSeeliger(LommelSeeligerSpec),
    Ocean(OceanSpec),
    Tabulated(TabulatedSpec),
    RoughDielectric(RoughDielectricSpec),
    ThinDielectric(ThinDielectricSpec),
}

impl BrdfSpec {
    /// The `type` tag.
    pub fn type_name(&self) -> &'static str {
        match self {
            BrdfSpec::Lambertian(_) => "lambertian",
            BrdfSpec::BiLambertian(_) => "bi_lambertian",
            BrdfSpec::Rpv(_) => "rpv",
            BrdfSpec::Rtls(_) => "rtls",
            BrdfSpec::RtlsHotspot(_) => "rtls_hotspot",
            BrdfSpec::Hapke(_) => "hapke",
            BrdfSpec::LommelSeeliger(_) => "lommel_seeliger",
            BrdfSpec::Ocean(_) => "ocean",
            BrdfSpec::Tabulated(_) => "tabulated",
            BrdfSpec::RoughDielectric(_) => "rough_dielectric",
            BrdfSpec::ThinDielectric(_) => "thin_dielectric",
        }
    }

    /// The parameter that sets the model's reflectance level (a Lambertian's reflectance, RPV's
    /// ρ0, RTLS's f_iso, Hapke's w…), for quicklooks and colours; `None` where no parameter
    /// does (an ocean, a measured table).
    pub fn reflectance_level(&self) -> Option<&Spectrum> {
        match self {
            BrdfSpec::Lambertian(s) => Some(&s.reflectance),
            BrdfSpec::BiLambertian(s) => Some(&s.reflectance),
            BrdfSpec::Rpv(s) => Some(&s.rho_0),
            BrdfSpec::Rtls(s) => Some(&s.f_iso),
            BrdfSpec::RtlsHotspot(s) => Some(&s.f_iso),
            BrdfSpec::Hapke(s) => Some(&s.w),
            BrdfSpec::LommelSeeliger(s) => Some(&s.w),
            BrdfSpec::Ocean(_)
            | BrdfSpec::Tabulated(_)
            | BrdfSpec::RoughDielectric(_)
            | BrdfSpec::ThinDielectric(_) => None,
        }
    }

    /// The spectral parameters present, by key, in the order of the table (a tabulated BRDF
    /// has none: its values are checked when the simulator reads its file).
    pub fn params(&self) -> Vec<(&'static str, &Spectrum)> {
        match self {
            BrdfSpec::Lambertian(s) => vec![("reflectance", &s.reflectance)],
            BrdfSpec::BiLambertian(s) => vec![
                ("reflectance", &s.reflectance),
                ("transmittance", &s.transmittance),
            ],
            BrdfSpec::Rpv(s) => {
                let mut v = vec![("rho_0", &s.rho_0), ("k", &s.k), ("g", &s.g)];
                if let Some(c) = &s.rho_c {
                    v.push(("rho_c", c));
                }
                v
            }
            BrdfSpec::Rtls(s) => vec![
                ("f_iso", &s.f_iso),
                ("f_vol", &s.f_vol),
                ("f_geo", &s.f_geo),
            ],
            BrdfSpec::RtlsHotspot(s) => vec![
                ("f_iso", &s.f_iso),
                ("f_vol", &s.f_vol),
                ("f_geo", &s.f_geo),
                ("xi0", &s.xi0),
            ],
            BrdfSpec::Hapke(s) => vec![
                ("w", &s.w),
                ("b", &s.b),
                ("c", &s.c),
                ("theta", &s.theta),
                ("B_0", &s.b_0),
                ("h", &s.h),
            ],
            BrdfSpec::LommelSeeliger(s) => vec![("w", &s.w)],
            BrdfSpec::Ocean(s) => {
                let mut v = vec![("wind_speed", &s.wind_speed)];
                if let Some(n) = &s.refractive_index {
                    v.push(("refractive_index", n));
                }
                v
            }
            BrdfSpec::Tabulated(_) => Vec::new(),
            BrdfSpec::RoughDielectric(s) => vec![
                ("refractive_index", &s.refractive_index),
                ("roughness", &s.roughness),
            ],
            BrdfSpec::ThinDielectric(s) => {
                let mut v = vec![("refractive_index", &s.refractive_index)];
                if let Some(t) = &s.internal_transmittance {
                    v.push(("internal_transmittance", t));
                }
                v
            }
        }
    }

    /// Whether the model transmits light through a surface into another medium or across a
    /// slab (`rough_dielectric`, `thin_dielectric`): scene materials only.
    pub fn is_dielectric(&self) -> bool {
        matches!(
            self,
            BrdfSpec::RoughDielectric(_) | BrdfSpec::ThinDielectric(_)
        )
    }
}

const fn row(
    brdf: &'static str,
    param: &'static str,
    unit: &'static str,
    range: Range,
) -> ParamRange {
    ParamRange {
        brdf,
        param,
        unit,
        range,
    }
}

/// Allowed values of every BRDF parameter, at every wavelength. The single source of truth:
/// the simulator's surface models (`engine/src/bsdf/`), land-cover schemes, region files and
/// the bundle reader and writer all check against it. The model files' `//!` headers say why
/// each range is what it is.
pub const BRDF_PARAM_RANGES: &[ParamRange] = &[
    row("lambertian", "reflectance", "", Range::closed(0.0, 1.0)),
    // bi_lambertian: also reflectance + transmittance ≤ BI_LAMBERTIAN_MAX_SUM.
    row("bi_lambertian", "reflectance", "", Range::closed(0.0, 1.0)),
    row(
        "bi_lambertian",
        "transmittance",
        "",
        Range::closed(0.0, 1.0),
    ),
    row("rpv", "rho_0", "", Range::closed(0.0, 1.0)),
    row("rpv", "k", "", Range::closed(0.0, 2.0)),
    row("rpv", "g", "", Range::open(-1.0, 1.0)),
    row("rpv", "rho_c", "", Range::closed(0.0, 1.0)),
    row("rtls", "f_iso", "", Range::closed(0.0, 2.0)),
    row("rtls", "f_vol", "", Range::closed(-1.0, 1.0)),
    row("rtls", "f_geo", "", Range::closed(-1.0, 1.0)),
    row("rtls_hotspot", "f_iso", "", Range::closed(0.0, 2.0)),
    row("rtls_hotspot", "f_vol", "", Range::closed(-1.0, 1.0)),
    row("rtls_hotspot", "f_geo", "", Range::closed(-1.0, 1.0)),
    row("rtls_hotspot", "xi0", "deg", Range::open_closed(0.0, 90.0)),
    row("hapke", "w", "", Range::closed(0.0, 1.0)),
    row("hapke", "b", "", Range::closed_open(0.0, 1.0)),
    row("hapke", "c", "", Range::closed(0.0, 1.0)),
    row("hapke", "theta", "deg", Range::closed_open(0.0, 90.0)),
    row("hapke", "B_0", "", Range::closed(0.0, 1.0)),
    row("hapke", "h", "", Range::closed(0.0, 1.0)),
    row("lommel_seeliger", "w", "", Range::closed(0.0, 1.0)),
    row("ocean", "wind_speed", "m/s", Range::closed(0.0, 40.0)),
    row("ocean", "refractive_index", "", Range::closed(1.0, 3.0)),
    row(
        "rough_dielectric",
        "refractive_index",
        "",
        Range::closed(1.0, 3.0),
    ),
    // Below 0.001 the lobes are too narrow for f64 sampling; thin_dielectric is the smooth pane.
    row(
        "rough_dielectric",
        "roughness",
        "",
        Range::closed(0.001, 1.0),
    ),
    row(
        "thin_dielectric",
        "refractive_index",
        "",
        Range::closed(1.0, 3.0),
    ),
    row(
        "thin_dielectric",
        "internal_transmittance",
        "",
        Range::closed(0.0, 1.0),
    ),
];

/// Upper bound of `reflectance + transmittance` of a `bi_lambertian` material (energy).
pub const BI_LAMBERTIAN_MAX_SUM: f64 = 1.0;

/// The row of (`brdf`, `param`) in [`BRDF_PARAM_RANGES`].
pub fn param_range(brdf: &str, param: &str) -> Option<&'static ParamRange> {
    BRDF_PARAM_RANGES
        .iter()
        .find(|r| r.brdf == brdf && r.param == param)
}

/// Checks `v` against the row of (`brdf`, `param`); the message names `label`.
///
/// # Panics
/// If the table has no such row (a programming error, caught by the callers' tests).
pub fn check_param(brdf: &str, param: &str, label: &str, v: f64) -> Result<(), String> {
    param_range(brdf, param)
        .unwrap_or_else(|| panic!("no range for {brdf}.{param} in BRDF_PARAM_RANGES"))
        .check(label, v)
}

/// One spec of every type with every optional parameter given (tests of `mod.rs`); a new
/// model adds its spec here.
#[cfg(test)]
pub(crate) fn every_type() -> Vec<BrdfSpec> {
    vec![
        BrdfSpec::Lambertian(LambertianSpec {
            reflectance: Spectrum::Constant(0.2),
        }),
        BrdfSpec::BiLambertian(BiLambertianSpec {
            reflectance: Spectrum::Constant(0.4),
            transmittance: Spectrum::Constant(0.5),
        }),
        BrdfSpec::Rpv(RpvSpec {
            rho_0: Spectrum::Constant(0.1),
            k: Spectrum::Constant(0.8),
            g: Spectrum::Constant(-0.1),
            rho_c: Some(Spectrum::Constant(0.3)),
        }),
        BrdfSpec::Rtls(RtlsSpec {
            f_iso: Spectrum::Constant(0.2),
            f_vol: Spectrum::Constant(0.1),
            f_geo: Spectrum::Constant(0.05),
        }),
        BrdfSpec::RtlsHotspot(RtlsHotspotSpec {
            f_iso: Spectrum::Constant(0.2),
            f_vol: Spectrum::Constant(0.1),
            f_geo: Spectrum::Constant(0.05),
            xi0: Spectrum::Constant(2.0),
        }),
        BrdfSpec::Hapke(HapkeSpec {
            w: Spectrum::Constant(0.5),
            b: Spectrum::Constant(0.3),
            c: Spectrum::Constant(0.4),
            theta: Spectrum::Constant(15.0),
            b_0: Spectrum::Constant(0.8),
            h: Spectrum::Constant(0.06),
        }),
        BrdfSpec::LommelSeeliger(LommelSeeligerSpec {
            w: Spectrum::Constant(0.3),
        }),
        BrdfSpec::Ocean(OceanSpec {
            wind_speed: Spectrum::Constant(5.0),
            refractive_index: Some(Spectrum::Constant(1.33)),
            shadowing: true,
        }),
        BrdfSpec::Tabulated(TabulatedSpec {
            file: "brdf/sand.nc".into(),
            symmetrize: false,
        }),
        BrdfSpec::RoughDielectric(RoughDielectricSpec {
            refractive_index: Spectrum::Constant(1.5),
            roughness: Spectrum::Constant(0.2),
        }),
        BrdfSpec::ThinDielectric(ThinDielectricSpec {
            refractive_index: Spectrum::Constant(1.52),
            internal_transmittance: Some(Spectrum::Constant(0.9)),
        }),
    ]
}
