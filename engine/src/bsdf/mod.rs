//! Surface reflection models (BRDFs), dispatched by an enum: one file per model.
//!
//! Frame and conventions, shared by every model:
//! * directions are unit vectors in the surface's local frame, `z` along the surface normal;
//! * `wi` points from the surface towards the light (the Sun, or the next vertex of a path),
//!   `wo` from the surface towards the viewer; both must have `z > 0`, else the BRDF is 0;
//! * `eval` returns the BRDF `f_r(wi, wo)` in sr⁻¹ (so a Lambertian of reflectance ρ gives ρ/π;
//!   the BRF is π·f_r);
//! * `sample` draws `wi` given `wo` from two uniforms and returns the weight
//!   `f_r(wi, wo)·cos θ_i / pdf(wi)` and the pdf (solid-angle measure); [`Bsdf::pdf`] is the true
//!   density of [`Bsdf::sample`] (tested by χ² for every model), so a direction drawn by one
//!   model can be weighted for another (`f_other·cos θ_i / pdf`, spectral ALIS walks).
//!
//! **Sampling, per model** (issue 14):
//! * Lambertian: the cosine-weighted hemisphere, exact (weight = ρ);
//! * ocean: facet normals from the Cox–Munk slope distribution, `wo` mirrored about them
//!   (`ocean.rs`): weight ≈ Fresnel × shadowing however narrow the glint; draws below the
//!   horizon have weight 0 (the path is absorbed);
//! * RPV, RTLS, RTLS-H, Hapke, tabulated BRDFs: a table of `f_r` built from the model when it
//!   is constructed (`table_sampler.rs`), mixed with the cosine density (a defensive one-sample MIS mixture, so
//!   the weight stays bounded where the table misses a narrow feature);
//! * bi-Lambertian leaves (`scene/material.rs`): reflection or transmission in proportion to
//!   ρ and τ, then the cosine lobe of that side: exact importance sampling (weight = ρ + τ).
//!
//! **MIS with the next-event estimate**: the Sun is a delta direction, so a sampled direction
//! never hits it and next-event estimation is the only estimator of direct sunlight; there is no
//! pair of strategies to weigh, and no MIS weight. The one place two strategies meet is the
//! defensive mixture above (cosine and table), combined by its one-sample MIS density.
//!
//! **One vocabulary.** A model is written in TOML as a `bundle::BrdfSpec` (one spec struct per
//! model, spectral parameters as `bundle::Spectrum`), the same in the experiment's 1D
//! `[surface]` (`config.rs`: the spec plus `temperature` and `solver`) and in every material of
//! a 3D scene; [`Bsdf::build`] turns a spec into the model at one run wavelength for both, by
//! the model's one constructor, which checks the ranges of `bundle::BRDF_PARAM_RANGES`.
//!
//! Adding a model touches four files (see CONTRIBUTING.md, "Adding a BRDF"): its file here (doc
//! header with parameters, units, ranges and reference; its constructor checking the ranges;
//! its tests), a variant of [`Bsdf`] with its arms here (dispatch and [`Bsdf::build`]), its spec
//! struct, variant and range rows in `bundle/src/brdf/spec.rs`, and its keys in
//! `docs/experiment.md`. It then works in 1D and in 3D scenes.

pub mod bi_lambertian;
pub mod config;
pub mod emissivity;
pub mod error;
pub mod fresnel;
pub mod hapke;
pub mod lambertian;
pub mod lommel_seeliger;
pub mod ocean;
pub mod rough_dielectric;
pub mod rpv;
pub mod rtls;
pub mod rtls_hotspot;
pub mod table_sampler;
pub mod tabulated;
pub mod thin_dielectric;

use glam::DVec3;

pub use bi_lambertian::BiLambertian;
pub use config::SurfaceConfig;
pub use emissivity::SurfaceEmission;
pub use error::BrdfError;
pub use hapke::Hapke;
pub use lambertian::Lambertian;
pub use lommel_seeliger::LommelSeeliger;
pub use ocean::Ocean;
pub use rough_dielectric::RoughDielectric;
pub use rpv::Rpv;
pub use rtls::Rtls;
pub use rtls_hotspot::RtlsHotspot;
pub use table_sampler::TableSampler;
pub use tabulated::Tabulated;
pub use thin_dielectric::ThinDielectric;

use crate::frame::sample_cosine_hemisphere;
use bundle::{BrdfSpec, Spectrum};

/// A sampled incident direction with its Monte Carlo weight.
#[derive(Clone, Copy, Debug)]
pub struct BsdfSample {
    /// Sampled direction towards the light (local frame, `z > 0`).
    pub wi: DVec3,
    /// `f_r(wi, wo)·cos θ_i / pdf(wi)`, dimensionless.
    pub weight: f64,
    /// Solid-angle pdf of `wi`, sr⁻¹.
    pub pdf: f64,
}

/// A BRDF: a closed set of models.
#[derive(Clone, Debug)]
pub enum Bsdf {
    Lambertian(Lambertian),
    Rpv(Rpv),
    Rtls(Rtls),
    /// RTLS with the Maignan et al. (2004) hot spot.
    RtlsHotspot(RtlsHotspot),
    Hapke(Hapke),
    /// Single scattering of a semi-infinite isotropic medium (`lommel_seeliger.rs`).
    LommelSeeliger(LommelSeeliger),
    Ocean(Ocean),
    /// A measured BRDF read from a netCDF table (`tabulated.rs`).
    Tabulated(Tabulated),
}

/// What a BRDF spec builds at one wavelength ([`Bsdf::build`]): an opaque BRDF, a
/// two-sided bi-Lambertian leaf (3D scenes; a 1D ground keeps its reflection only), or a
/// transmitting dielectric (3D scenes only).
#[derive(Clone, Debug)]
pub enum Built {
    Opaque(Bsdf),
    Leaf(BiLambertian),
    /// A rough dielectric interface (`rough_dielectric.rs`).
    Dielectric(RoughDielectric),
    /// A thin dielectric slab, a pane (`thin_dielectric.rs`).
    Pane(ThinDielectric),
}

impl Built {
    /// The BRDF of a 1D ground: a leaf's transmitted light enters the ground and is absorbed,
    /// so it is the Lambertian of its reflectance (`bi_lambertian.rs`). A dielectric has no
    /// ground to transmit into: an error naming its type.
    pub fn into_opaque(self) -> Result<Bsdf, BrdfError> {
        match self {
            Built::Opaque(b) => Ok(b),
            Built::Leaf(l) => Ok(Bsdf::Lambertian(Lambertian {
                reflectance: l.reflectance,
            })),
            Built::Dielectric(_) => Err(BrdfError::SceneOnly {
                model: "rough_dielectric",
            }),
            Built::Pane(_) => Err(BrdfError::SceneOnly {
                model: "thin_dielectric",
            }),
        }
    }
}

impl Bsdf {
    /// The model of `spec` at run wavelength `iw` (`wavelength_nm`, nm), by the model's one
    /// constructor (ranges of `bundle::BRDF_PARAM_RANGES`; the error names the parameter). A
    /// tabulated BRDF's `file` must be a usable path (relative paths are taken from the
    /// current folder: callers anchor them first, `scene/material.rs::with_files_in`).
    pub fn build(spec: &BrdfSpec, iw: usize, wavelength_nm: f64) -> Result<Built, BrdfError> {
        let at = |s: &Spectrum| s.at_run(iw, wavelength_nm);
        let opaque = |b: Bsdf| Ok(Built::Opaque(b));
        match spec {
            BrdfSpec::Lambertian(s) => {
                opaque(Bsdf::Lambertian(Lambertian::new(at(&s.reflectance))?))
            }
            BrdfSpec::BiLambertian(s) => Ok(Built::Leaf(BiLambertian::new(
                at(&s.reflectance),
                at(&s.transmittance),
                wavelength_nm,
            )?)),
            BrdfSpec::Rpv(s) => opaque(Bsdf::Rpv(Rpv::new(
                at(&s.rho_0),
                at(&s.k),
                at(&s.g),
                at(s.rho_c.as_ref().unwrap_or(&s.rho_0)),
            )?)),
            BrdfSpec::Rtls(s) => opaque(Bsdf::Rtls(Rtls::new(
                at(&s.f_iso),
                at(&s.f_vol),
                at(&s.f_geo),
            )?)),
            BrdfSpec::RtlsHotspot(s) => opaque(Bsdf::RtlsHotspot(RtlsHotspot::new(
                at(&s.f_iso),
                at(&s.f_vol),
                at(&s.f_geo),
                at(&s.xi0),
            )?)),
            BrdfSpec::Hapke(s) => opaque(Bsdf::Hapke(Hapke::new(
                at(&s.w),
                at(&s.b),
                at(&s.c),
                at(&s.theta),
                at(&s.b_0),
                at(&s.h),
            )?)),
            BrdfSpec::LommelSeeliger(s) => {
                opaque(Bsdf::LommelSeeliger(LommelSeeliger::new(at(&s.w))?))
            }
            BrdfSpec::Ocean(s) => opaque(Bsdf::Ocean(Ocean::new(
                at(&s.wind_speed),
                s.refractive_index
                    .as_ref()
                    .map_or(bundle::DEFAULT_WATER_INDEX, at),
                s.shadowing,
            )?)),
            BrdfSpec::RoughDielectric(s) => Ok(Built::Dielectric(RoughDielectric::new(
                at(&s.refractive_index),
                at(&s.roughness),
            )?)),
            BrdfSpec::ThinDielectric(s) => Ok(Built::Pane(ThinDielectric::new(
                at(&s.refractive_index),
                s.internal_transmittance.as_ref().map_or(1.0, at),
            )?)),
            BrdfSpec::Tabulated(s) => {
                let table = tabulated::BrdfTable::load(std::path::Path::new(&s.file))?;
                opaque(Bsdf::Tabulated(Tabulated::new(
                    table,
                    wavelength_nm,
                    s.symmetrize,
                )))
            }
        }
    }

    /// BRDF value in sr⁻¹; 0 when either direction is below the horizon.
    #[inline]
    pub fn eval(&self, wi: DVec3, wo: DVec3) -> f64 {
        if wi.z <= 0.0 || wo.z <= 0.0 {
            return 0.0;
        }
        match self {
            Bsdf::Lambertian(m) => m.eval(wi, wo),
            Bsdf::Rpv(m) => m.eval(wi, wo),
            Bsdf::Rtls(m) => m.eval(wi, wo),
            Bsdf::RtlsHotspot(m) => m.eval(wi, wo),
            Bsdf::Hapke(m) => m.eval(wi, wo),
            Bsdf::LommelSeeliger(m) => m.eval(wi, wo),
            Bsdf::Ocean(m) => m.eval(wi, wo),
            Bsdf::Tabulated(m) => m.eval(wi, wo),
        }
    }

    /// The reflection Mueller matrix in the scattering-plane frame of light going from `−wi` to
    /// `wo` (`stokes.rs`), for polarizing models; `None` for depolarizing ones (the reflected
    /// light is unpolarized with intensity `eval`).
    #[inline]
    pub fn matrix(&self, wi: DVec3, wo: DVec3) -> Option<crate::stokes::PhaseMatrix> {
        match self {
            Bsdf::Ocean(m) if wi.z > 0.0 && wo.z > 0.0 => Some(m.matrix(wi, wo)),
            Bsdf::Ocean(_) => Some(crate::stokes::PhaseMatrix::depolarizing(0.0)),
            _ => None,
        }
    }

    /// The tabulated sampler of a smooth model (`None` for the Lambertian and the ocean, which
    /// sample exactly or by facets).
    #[inline]
    fn table(&self) -> Option<&TableSampler> {
        match self {
            Bsdf::Lambertian(_) | Bsdf::Ocean(_) => None,
            Bsdf::Rpv(m) => Some(&m.sampler),
            Bsdf::Rtls(m) => Some(&m.sampler),
            Bsdf::RtlsHotspot(m) => Some(&m.sampler),
            Bsdf::Hapke(m) => Some(&m.sampler),
            Bsdf::LommelSeeliger(m) => Some(&m.sampler),
            Bsdf::Tabulated(m) => Some(&m.sampler),
        }
    }

    /// Solid-angle pdf (sr⁻¹) with which [`Bsdf::sample`] draws `wi` given `wo`; 0 when either
    /// is below the horizon.
    #[inline]
    pub fn pdf(&self, wi: DVec3, wo: DVec3) -> f64 {
        if wi.z <= 0.0 || wo.z <= 0.0 {
            return 0.0;
        }
        match self {
            Bsdf::Lambertian(_) => wi.z * std::f64::consts::FRAC_1_PI,
            Bsdf::Ocean(m) => m.pdf(wi, wo),
            _ => self.table().map_or(0.0, |t| t.pdf(wi, wo)),
        }
    }

    /// Draw `wi` given `wo` from two uniform numbers in [0, 1). A draw below the horizon (the
    /// ocean's facets turned away from `wo`) has pdf and weight 0: the path is absorbed.
    #[inline]
    pub fn sample(&self, wo: DVec3, u1: f64, u2: f64) -> BsdfSample {
        let wi = match self {
            Bsdf::Lambertian(m) => {
                // Exact: the weight is ρ (bit for bit as before samplers differed).
                let wi = sample_cosine_hemisphere(u1, u2);
                let pdf = wi.z * std::f64::consts::FRAC_1_PI;
                return BsdfSample {
                    wi,
                    weight: m.reflectance,
                    pdf,
                };
            }
            Bsdf::Ocean(m) => m.sample(wo, u1, u2),
            _ => match self.table() {
                Some(t) => t.sample(wo, u1, u2),
                None => sample_cosine_hemisphere(u1, u2),
            },
        };
        let pdf = self.pdf(wi, wo);
        let weight = if pdf > 0.0 {
            self.eval(wi, wo) * wi.z / pdf
        } else {
            0.0
        };
        BsdfSample { wi, weight, pdf }
    }

    /// The weight `f_r(wi, wo)·cos θ_i / pdf` of a direction `wi` that another sampler drew
    /// with density `pdf` (spectral ALIS: the reference surface draws, every channel weighs);
    /// `drawn_by` is that sampler's model. Lambertian channels drawn by a Lambertian get ρ
    /// exactly (the densities cancel).
    #[inline]
    pub fn weight_of(&self, wi: DVec3, wo: DVec3, pdf: f64, drawn_by: &Bsdf) -> f64 {
        match (self, drawn_by) {
            (Bsdf::Lambertian(m), Bsdf::Lambertian(_)) => m.reflectance,
            _ if pdf > 0.0 => self.eval(wi, wo) * wi.z / pdf,
            _ => 0.0,
        }
    }

    /// A line about the model for `simulate check` and logs, where there is more to say than
    /// its parameters (a tabulated BRDF: its file, grids and reciprocity error).
    pub fn info(&self) -> Option<String> {
        match self {
            Bsdf::Tabulated(m) => Some(m.table.summary()),
            _ => None,
        }
    }

    /// Directional-hemispherical reflectance for light incident from `wi` (numerical quadrature,
    /// for tests and products; `n` is the number of nodes per axis).
    pub fn directional_albedo(&self, wi: DVec3, n: usize) -> f64 {
        // Midpoint rule in (cos²θ, φ): the measure cos θ dω = ½ d(cos²θ) dφ.
        let mut sum = 0.0;
        for i in 0..n {
            let c2 = (i as f64 + 0.5) / n as f64;
            let ct = c2.sqrt();
            let st = (1.0 - c2).sqrt();
            for j in 0..(2 * n) {
                let phi = std::f64::consts::PI * (j as f64 + 0.5) / n as f64;
                let wo = DVec3::new(st * phi.cos(), st * phi.sin(), ct);
                sum += self.eval(wi, wo);
            }
        }
        // ∫ f cosθ dω = ∫∫ f · ½ d(c²) dφ ; cells: Δ(c²) = 1/n, Δφ = π/n.
        sum * 0.5 * (1.0 / n as f64) * (std::f64::consts::PI / n as f64)
    }
}

#[cfg(test)]
pub(crate) mod test_support {
    use glam::DVec3;
    use std::f64::consts::PI;

    /// The 0.1 % upper quantile of χ² with `dof` degrees of freedom (Wilson–Hilferty: within
    /// 0.5 % of the exact quantile from 30 degrees of freedom on).
    pub fn chi2_quantile_999(dof: usize) -> f64 {
        let k = dof as f64;
        let z = 3.090_232; // the standard normal's 0.999 quantile
        let c = 2.0 / (9.0 * k);
        k * (1.0 - c + z * c.sqrt()).powi(3)
    }

    /// Where directions are binned: a rectangle in (x, φ), x = cos²θ (`cos2`, in which a
    /// cosine-weighted density is uniform) or cos θ, and φ the azimuth relative to `wo`'s
    /// horizontal direction (the axes of `table_sampler.rs`) minus `phi0`, wrapped into
    /// (−π, π]; `nx × nphi` bins, each integrated with `sub × sub` midpoints.
    #[derive(Clone, Copy, Debug)]
    pub struct Chart {
        pub cos2: bool,
        pub x: (f64, f64),
        pub phi0: f64,
        pub phi: (f64, f64),
        pub nx: usize,
        pub nphi: usize,
        pub sub: usize,
    }

    impl Chart {
        /// The whole hemisphere in (cos²θ, φ).
        pub fn hemisphere(nx: usize, nphi: usize, sub: usize) -> Self {
            Chart {
                cos2: true,
                x: (0.0, 1.0),
                phi0: 0.0,
                phi: (-PI, PI),
                nx,
                nphi,
                sub,
            }
        }

        /// The chart coordinates (x, φ) of a direction.
        fn coords(&self, wo: DVec3, d: DVec3) -> (f64, f64) {
            let (a, b) = super::table_sampler::azimuth_axes(wo);
            let x = if self.cos2 { d.z * d.z } else { d.z };
            let phi = (d.dot(b).atan2(d.dot(a)) - self.phi0 + PI).rem_euclid(2.0 * PI) - PI;
            (x, phi)
        }

        /// The direction at chart coordinates (x, φ) and the solid angle per unit dx dφ.
        fn direction(&self, wo: DVec3, x: f64, phi: f64) -> (DVec3, f64) {
            let (a, b) = super::table_sampler::azimuth_axes(wo);
            let ct = if self.cos2 { x.sqrt() } else { x };
            let st = (1.0 - ct * ct).max(0.0).sqrt();
            let (sp, cp) = (phi + self.phi0).sin_cos();
            let jac = if self.cos2 { 0.5 / ct } else { 1.0 };
            (a * (st * cp) + b * (st * sp) + DVec3::Z * ct, jac)
        }

        /// ∫ pdf dω over each bin (midpoint rule on `sub × sub` points per bin).
        pub fn expected(&self, wo: DVec3, pdf: &impl Fn(DVec3) -> f64) -> Vec<f64> {
            let (dx, dp) = (
                (self.x.1 - self.x.0) / self.nx as f64,
                (self.phi.1 - self.phi.0) / self.nphi as f64,
            );
            let m = self.sub as f64;
            let mut out = vec![0.0; self.nx * self.nphi];
            for i in 0..self.nx {
                for j in 0..self.nphi {
                    let mut sum = 0.0;
                    for ii in 0..self.sub {
                        for jj in 0..self.sub {
                            let x = self.x.0 + (i as f64 + (ii as f64 + 0.5) / m) * dx;
                            let phi = self.phi.0 + (j as f64 + (jj as f64 + 0.5) / m) * dp;
                            let (d, jac) = self.direction(wo, x, phi);
                            sum += pdf(d) * jac;
                        }
                    }
                    out[i * self.nphi + j] = sum * dx * dp / (m * m);
                }
            }
            out
        }
    }

    /// χ² test of a sampler against its own pdf: `draw(u1, u2)` gives a direction (`None`: the
    /// draw was absorbed, e.g. below the horizon), `pdf` its solid-angle density (0 below the
    /// horizon). `n` draws from a fixed stream are binned by `chart`; every draw outside the
    /// chart (or absorbed) goes to one more bin whose probability is 1 − Σ(bins); bins expecting
    /// fewer than 5 draws are pooled into that one. Returns (χ², degrees of freedom); compare
    /// with [`chi2_quantile_999`].
    pub fn chi2_pdf(
        wo: DVec3,
        chart: &Chart,
        n: usize,
        mut draw: impl FnMut(f64, f64) -> Option<DVec3>,
        pdf: impl Fn(DVec3) -> f64,
    ) -> (f64, usize) {
        let p = chart.expected(wo, &pdf);
        let mut counts = vec![0u64; p.len()];
        let mut rest = 0u64;
        let mut rng = crate::rng::Stream::new(1234, [1, 2, 3, 4]);
        for _ in 0..n {
            let (u1, u2) = (rng.next_f64(), rng.next_f64());
            let Some(d) = draw(u1, u2) else {
                rest += 1;
                continue;
            };
            assert!((d.length() - 1.0).abs() < 1e-9, "not a unit vector: {d}");
            let (x, phi) = chart.coords(wo, d);
            let fi = (x - chart.x.0) / (chart.x.1 - chart.x.0) * chart.nx as f64;
            let fj = (phi - chart.phi.0) / (chart.phi.1 - chart.phi.0) * chart.nphi as f64;
            if d.z > 0.0 && fi >= 0.0 && fj >= 0.0 && fi < chart.nx as f64 && fj < chart.nphi as f64
            {
                counts[fi as usize * chart.nphi + fj as usize] += 1;
            } else {
                rest += 1;
            }
        }
        let nf = n as f64;
        let mut p_rest = 1.0 - p.iter().sum::<f64>();
        let (mut chi2, mut bins) = (0.0, 0usize);
        for (&pk, &c) in p.iter().zip(&counts) {
            if pk * nf < 5.0 {
                p_rest += pk;
                rest += c;
            } else {
                chi2 += (c as f64 - pk * nf).powi(2) / (pk * nf);
                bins += 1;
            }
        }
        let e_rest = p_rest.max(0.0) * nf;
        if e_rest > 1e-6 || rest > 0 {
            chi2 += (rest as f64 - e_rest).powi(2) / e_rest.max(1e-6);
            bins += 1;
        }
        (chi2, bins - 1)
    }

    /// [`chi2_pdf`] for a model's `Bsdf::sample`/`Bsdf::pdf`, asserting χ² below the 0.1 %
    /// quantile; prints the statistic.
    pub fn assert_chi2(name: &str, m: &super::Bsdf, wo: DVec3, chart: &Chart, n: usize) {
        let (chi2, dof) = chi2_pdf(
            wo,
            chart,
            n,
            |u1, u2| {
                let s = m.sample(wo, u1, u2);
                (s.pdf > 0.0).then_some(s.wi)
            },
            |wi| m.pdf(wi, wo),
        );
        let q = chi2_quantile_999(dof);
        println!("{name}, wo = {wo:.3}: chi2 = {chi2:.1}, {dof} dof (0.1 % quantile {q:.1})");
        assert!(
            chi2 < q,
            "{name}, wo = {wo}: chi2 = {chi2} > {q} ({dof} dof)"
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::frame::direction_from_angles;

    fn models() -> Vec<Bsdf> {
        vec![
            Bsdf::Lambertian(Lambertian::new(0.3).unwrap()),
            Bsdf::Rpv(Rpv::new(0.2, 0.8, -0.2, 0.2).unwrap()),
            Bsdf::Rtls(Rtls::new(0.2, 0.05, 0.03).unwrap()),
            Bsdf::RtlsHotspot(RtlsHotspot::new(0.2, 0.05, 0.03, 1.5).unwrap()),
            Bsdf::Hapke(Hapke::new(0.5, 0.3, 0.4, 15.0, 0.8, 0.06).unwrap()),
            Bsdf::LommelSeeliger(LommelSeeliger::new(0.7).unwrap()),
        ]
    }

    /// Every sampled model, with more parameter sets than [`models`]: RPV bell- and bowl-shaped
    /// with a strong hot spot, RTLS with a strong geometric kernel, Hapke without roughness,
    /// and the ocean at 2 and 10 m/s.
    fn sampled_models() -> Vec<(&'static str, Bsdf)> {
        vec![
            (
                "lambertian",
                Bsdf::Lambertian(Lambertian::new(0.3).unwrap()),
            ),
            ("rpv", Bsdf::Rpv(Rpv::new(0.2, 0.8, -0.2, 0.2).unwrap())),
            ("rpv bell", Bsdf::Rpv(Rpv::new(0.1, 1.6, 0.4, 0.0).unwrap())),
            (
                "rpv bowl",
                Bsdf::Rpv(Rpv::new(0.05, 0.5, -0.4, 0.0).unwrap()),
            ),
            ("rtls", Bsdf::Rtls(Rtls::new(0.2, 0.05, 0.03).unwrap())),
            ("rtls geo", Bsdf::Rtls(Rtls::new(0.3, 0.4, 0.2).unwrap())),
            (
                "rtls_hotspot",
                Bsdf::RtlsHotspot(RtlsHotspot::new(0.2, 0.3, 0.03, 1.5).unwrap()),
            ),
            (
                "hapke",
                Bsdf::Hapke(Hapke::new(0.5, 0.3, 0.4, 15.0, 0.8, 0.06).unwrap()),
            ),
            (
                "lommel_seeliger",
                Bsdf::LommelSeeliger(LommelSeeliger::new(0.7).unwrap()),
            ),
            (
                "hapke smooth",
                Bsdf::Hapke(Hapke::new(0.9, 0.6, 0.9, 0.0, 1.0, 0.1).unwrap()),
            ),
            (
                "ocean 2 m/s",
                Bsdf::Ocean(Ocean::new(2.0, 1.33, true).unwrap()),
            ),
            (
                "ocean 10 m/s",
                Bsdf::Ocean(Ocean::new(10.0, 1.33, true).unwrap()),
            ),
        ]
    }

    /// Views from nadir to grazing (zenith 0°, 29°, 57°, 80°, 88.8°), at an azimuth that is no
    /// axis of the frame.
    fn views() -> Vec<DVec3> {
        [0.0, 0.5, 1.0, 1.4, 1.55]
            .iter()
            .map(|&z| direction_from_angles(z, 0.7))
            .collect()
    }

    /// Sampling weight equals eval·cos/pdf and the returned pdf equals `Bsdf::pdf`, for every
    /// model and view (the integrators and ALIS rely on both); draws below the horizon have
    /// pdf and weight 0.
    #[test]
    fn sample_weight_is_eval_cos_over_pdf() {
        let mut rng = crate::rng::Stream::new(7, [0, 0, 0, 1]);
        for (name, m) in sampled_models() {
            for wo in views() {
                for _ in 0..2000 {
                    let s = m.sample(wo, rng.next_f64(), rng.next_f64());
                    assert!(s.weight.is_finite() && s.weight >= 0.0, "{name}: {s:?}");
                    assert_eq!(s.pdf, m.pdf(s.wi, wo), "{name}");
                    if s.wi.z <= 0.0 {
                        assert!(s.pdf == 0.0 && s.weight == 0.0, "{name}: {s:?}");
                        continue;
                    }
                    assert!(s.pdf > 0.0, "{name}: {s:?}");
                    let expect = m.eval(s.wi, wo) * s.wi.z / s.pdf;
                    assert!(
                        (s.weight - expect).abs() <= 1e-12 * expect.max(1.0),
                        "{name}: {} vs {expect}",
                        s.weight
                    );
                }
            }
        }
        // The Lambertian's weight is its reflectance, exactly.
        let lam = Bsdf::Lambertian(Lambertian::new(0.3).unwrap());
        assert_eq!(lam.sample(views()[1], 0.3, 0.6).weight, 0.3);
    }

    /// χ² of every sampler against its own pdf at every view (fixed seed, 0.1 % quantile).
    /// Smooth models: 12 × 24 bins in (cos²θ, φ) over the hemisphere, aligned with the table
    /// cells, where every pdf here is piecewise constant (quadrature exact). The ocean: 16 × 16
    /// bins in (cos θ, φ) around the specular direction (the glint holds nearly all draws) plus
    /// one bin for the rest of the sphere, draws below the horizon included.
    #[test]
    fn chi2_every_sampler() {
        use std::f64::consts::PI;
        for (name, m) in sampled_models() {
            for wo in views() {
                let chart = match &m {
                    Bsdf::Ocean(o) => {
                        // ±4 standard deviations of the reflected direction (2β), within the
                        // hemisphere.
                        let spread = (8.0 * o.sigma2().sqrt()).min(1.4);
                        let tz = wo.z.acos();
                        test_support::Chart {
                            cos2: false,
                            x: (
                                (tz + spread).min(std::f64::consts::FRAC_PI_2).cos(),
                                (tz - spread).max(0.0).cos(),
                            ),
                            phi0: PI,
                            phi: if tz < spread {
                                (-PI, PI)
                            } else {
                                let w = (spread / tz.sin()).min(PI);
                                (-w, w)
                            },
                            nx: 16,
                            nphi: 16,
                            // The density changes by e^0.9 across the bins next to the glint's
                            // centre at 2 m/s: the midpoint rule needs fine steps there.
                            sub: 32,
                        }
                    }
                    _ => test_support::Chart::hemisphere(12, 24, 4),
                };
                test_support::assert_chi2(name, &m, wo, &chart, 200_000);
            }
        }
    }

    /// The pdf integrates to 1 over the hemisphere for every sampler that stays above it (the
    /// table's cells and the cosine density: exact quadrature on the table's grid); the ocean's
    /// integrates to the share of its draws above the horizon (`ocean.rs` integrates its density
    /// over the whole sphere; the χ² test's last bin checks the share).
    #[test]
    fn pdf_integrates_to_one() {
        let chart = test_support::Chart::hemisphere(48, 96, 2);
        for (name, m) in sampled_models() {
            if matches!(m, Bsdf::Ocean(_)) {
                continue;
            }
            for wo in views() {
                let total: f64 = chart.expected(wo, &|wi| m.pdf(wi, wo)).iter().sum();
                assert!(
                    (total - 1.0).abs() < 1e-9,
                    "{name}, wo = {wo}: ∫pdf = {total}"
                );
            }
        }
    }

    /// Energy conservation: directional albedo ≤ 1 for every model at several incidences.
    #[test]
    fn directional_albedo_at_most_one() {
        for m in models() {
            for &z in &[0.0, 0.5, 1.0, 1.4] {
                let a = m.directional_albedo(direction_from_angles(z, 0.0), 200);
                assert!(a > 0.0 && a <= 1.0, "{m:?} zenith {z}: albedo {a}");
            }
        }
        let lam = Bsdf::Lambertian(Lambertian::new(0.3).unwrap());
        let a = lam.directional_albedo(DVec3::Z, 100);
        assert!((a - 0.3).abs() < 1e-9, "{a}");
    }
}
