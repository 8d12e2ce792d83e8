//! Surface materials of 3D scenes, at one wavelength.
//!
//! A scene carries a table of materials (name + [`BrdfSpec`], spectra in nm); at each wavelength
//! the table becomes a list of [`SurfaceModel`]s indexed by the same material id. Hits carry that
//! id: terrain hits get it from the 8-bit material raster (the *selector*: nearest lookup of the
//! hit's horizontal position), template triangles from their per-triangle ids, leaves from their
//! object.
//!
//! Frame: at a hit, `n` is the unit geometric normal on the side the path arrives from (the
//! viewer side in a backward walk). Directions are world unit vectors: `wo` towards the viewer
//! (`n·wo > 0`), `wi` towards the light.
//!
//! * `Opaque(bsdf)`: any BRDF of the 1D surfaces, evaluated in a local frame with `z = n`. The
//!   BRDFs are isotropic, so the orientation of the frame about `n` does not matter. Light from
//!   the other side (`n·wi ≤ 0`) contributes nothing.
//! * `Leaf { reflectance, transmittance }`: a thin two-sided bi-Lambertian leaf (RAMI):
//!   `f = ρ/π` when `wi` is on the viewer's side, `τ/π` on the other side, identical on both
//!   faces. Sampling picks reflection with probability ρ/(ρ+τ) and a cosine lobe on that side:
//!   the density `(ρ or τ)/(ρ+τ)·|cos|/π` is exactly proportional to `f·|cos|`, so this is exact
//!   importance sampling and the weight is the constant ρ+τ ([`SurfaceModel::pdf`]; tested by
//!   χ² below).
//! * `Dielectric(RoughDielectric)`: a rough interface between the outside (the side of the
//!   primitive's front normal) and an inside of relative index n (`bsdf/rough_dielectric.rs`);
//!   the scene hands the walks the interface as seen from the viewer's side
//!   (`SurfaceHit::front`: from the inside its index is 1/n). Reflection and transmission are
//!   continuous lobes: next-event estimates and sampling as for any BRDF.
//! * `Pane(ThinDielectric)`: a thin slab (`bsdf/thin_dielectric.rs`), delta reflection and
//!   straight transmission: `eval_cos` is 0 (a Sun seen through or in a pane is a delta), the
//!   sampler picks the mirror or the straight direction in proportion to R and T (weight
//!   R + T, exact), and shadow rays cross a pane with factor T (`Scene::visibility`).
//! * `Black`: absorbs everything (cells of the material raster without a material, undersides of
//!   the terrain).
//!
//! Reference: bi-Lambertian leaves as in the RAMI-3 protocol, Widlowski et al. (2007), JGR 112,
//! D09111.

use glam::DVec3;

use crate::bsdf::{BrdfError, Bsdf, Built, RoughDielectric, ThinDielectric};
use crate::frame::{basis_around, sample_cosine_hemisphere};
use bundle::BrdfSpec;

/// The reflection model of one material at one wavelength.
#[derive(Clone, Debug)]
pub enum SurfaceModel {
    Opaque(Bsdf),
    Leaf {
        reflectance: f64,
        transmittance: f64,
    },
    /// A rough dielectric interface, seen from the outside.
    Dielectric(RoughDielectric),
    /// A thin dielectric slab.
    Pane(ThinDielectric),
    Black,
}

/// A sampled direction towards the light with its weight `f·|cos|/pdf`.
#[derive(Clone, Copy, Debug)]
pub struct SurfaceSample {
    pub wi: DVec3,
    pub weight: f64,
    /// Solid-angle density of `wi`, sr⁻¹.
    pub pdf: f64,
}

fn to_local(v: DVec3, n: DVec3, t: DVec3, b: DVec3) -> DVec3 {
    DVec3::new(v.dot(t), v.dot(b), v.dot(n))
}

impl SurfaceModel {
    /// The model of `spec` at run wavelength `iw` (`wavelength_nm`), by [`Bsdf::build`] (the
    /// same constructors as the 1D surface; the error says which parameter is wrong). The
    /// ranges are those of `bundle::BRDF_PARAM_RANGES`, so a spec that passes
    /// `BrdfSpec::validate` builds at every wavelength.
    pub fn from_spec(spec: &BrdfSpec, iw: usize, wavelength_nm: f64) -> Result<Self, BrdfError> {
        Ok(match Bsdf::build(spec, iw, wavelength_nm)? {
            Built::Opaque(b) => SurfaceModel::Opaque(b),
            Built::Leaf(l) => SurfaceModel::Leaf {
                reflectance: l.reflectance,
                transmittance: l.transmittance,
            },
            Built::Dielectric(d) => SurfaceModel::Dielectric(d),
            Built::Pane(p) => SurfaceModel::Pane(p),
        })
    }

    /// `spec` with its file (a tabulated BRDF's table) taken relative to `dir` and made
    /// absolute; other specs unchanged. Scenes apply it with the bundle's folder to manifest
    /// materials and with the experiment's folder to the experiment's own materials.
    pub fn with_files_in(spec: &BrdfSpec, dir: &std::path::Path) -> BrdfSpec {
        match spec {
            BrdfSpec::Tabulated(bundle::TabulatedSpec { file, symmetrize }) => {
                let p = dir.join(file);
                BrdfSpec::Tabulated(bundle::TabulatedSpec {
                    file: std::path::absolute(&p)
                        .unwrap_or(p)
                        .to_string_lossy()
                        .into_owned(),
                    symmetrize: *symmetrize,
                })
            }
            _ => spec.clone(),
        }
    }

    /// `f(wi, wo)·|n·wi|`: the factor that turns the irradiance arriving along `−wi` (normal to
    /// the beam) into radiance leaving along `wo`. `n` faces the viewer (`n·wo > 0`).
    #[inline]
    pub fn eval_cos(&self, n: DVec3, wi: DVec3, wo: DVec3) -> f64 {
        let ci = n.dot(wi);
        match self {
            SurfaceModel::Opaque(bsdf) => {
                if ci <= 0.0 {
                    return 0.0;
                }
                if let Bsdf::Lambertian(l) = bsdf {
                    return l.reflectance * std::f64::consts::FRAC_1_PI * ci;
                }
                let (t, b) = basis_around(n);
                bsdf.eval(to_local(wi, n, t, b), to_local(wo, n, t, b)) * ci
            }
            SurfaceModel::Leaf {
                reflectance,
                transmittance,
            } => {
                if ci > 0.0 {
                    reflectance * std::f64::consts::FRAC_1_PI * ci
                } else {
                    transmittance * std::f64::consts::FRAC_1_PI * -ci
                }
            }
            SurfaceModel::Dielectric(d) => {
                let (t, b) = basis_around(n);
                d.eval(to_local(wi, n, t, b), to_local(wo, n, t, b)) * ci.abs()
            }
            SurfaceModel::Pane(_) | SurfaceModel::Black => 0.0,
        }
    }

    /// A pane's transmittance for a beam of direction `d` crossing a surface of normal `n`
    /// (what a shadow ray keeps); `None` for every other model (opaque to shadow rays).
    #[inline]
    pub fn pane_transmittance(&self, n: DVec3, d: DVec3) -> Option<f64> {
        match self {
            SurfaceModel::Pane(p) => Some(p.reflect_transmit(n.dot(d)).1),
            _ => None,
        }
    }

    /// Solid-angle density (sr⁻¹) with which [`SurfaceModel::sample`] draws `wi` given `wo`.
    pub fn pdf(&self, n: DVec3, wi: DVec3, wo: DVec3) -> f64 {
        let ci = n.dot(wi);
        match self {
            SurfaceModel::Opaque(bsdf) => {
                let (t, b) = basis_around(n);
                bsdf.pdf(to_local(wi, n, t, b), to_local(wo, n, t, b))
            }
            SurfaceModel::Leaf {
                reflectance,
                transmittance,
            } => {
                let total = reflectance + transmittance;
                if total <= 0.0 {
                    return 0.0;
                }
                let side = if ci > 0.0 { reflectance } else { transmittance };
                side / total * ci.abs() * std::f64::consts::FRAC_1_PI
            }
            SurfaceModel::Dielectric(d) => {
                let (t, b) = basis_around(n);
                d.pdf(to_local(wi, n, t, b), to_local(wo, n, t, b))
            }
            // Delta lobes have no density with respect to solid angle.
            SurfaceModel::Pane(_) | SurfaceModel::Black => 0.0,
        }
    }

    /// Draw the next direction of a backward path (towards the light) given `wo`, from three
    /// uniform numbers; `None` when the surface absorbs everything.
    #[inline]
    pub fn sample(&self, n: DVec3, wo: DVec3, u: [f64; 3]) -> Option<SurfaceSample> {
        match self {
            SurfaceModel::Opaque(bsdf) => {
                let (t, b) = basis_around(n);
                let s = bsdf.sample(to_local(wo, n, t, b), u[0], u[1]);
                let wi = t * s.wi.x + b * s.wi.y + n * s.wi.z;
                (s.weight > 0.0).then_some(SurfaceSample {
                    wi,
                    weight: s.weight,
                    pdf: s.pdf,
                })
            }
            SurfaceModel::Leaf {
                reflectance,
                transmittance,
            } => {
                let total = reflectance + transmittance;
                if total <= 0.0 {
                    return None;
                }
                let reflect = u[2] * total < *reflectance;
                let side = if reflect { n } else { -n };
                let (t, b) = basis_around(side);
                let l = sample_cosine_hemisphere(u[0], u[1]);
                let p_side = if reflect {
                    *reflectance
                } else {
                    *transmittance
                } / total;
                Some(SurfaceSample {
                    wi: t * l.x + b * l.y + side * l.z,
                    weight: total,
                    pdf: p_side * l.z * std::f64::consts::FRAC_1_PI,
                })
            }
            SurfaceModel::Dielectric(d) => {
                let (t, b) = basis_around(n);
                let (wi, weight, pdf) = d.sample(to_local(wo, n, t, b), u)?;
                (weight > 0.0).then_some(SurfaceSample {
                    wi: t * wi.x + b * wi.y + n * wi.z,
                    weight,
                    pdf,
                })
            }
            SurfaceModel::Pane(p) => {
                let c = n.dot(wo);
                let (r, tr) = p.reflect_transmit(c);
                let total = r + tr;
                if total <= 0.0 {
                    return None;
                }
                // Mirror or straight on, in proportion to R and T: a delta of weight R + T.
                let wi = if u[2] * total < r {
                    2.0 * c * n - wo
                } else {
                    -wo
                };
                Some(SurfaceSample {
                    wi,
                    weight: total,
                    pdf: 1.0,
                })
            }
            SurfaceModel::Black => None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use bundle::{BiLambertianSpec, LambertianSpec, RpvSpec, Spectrum};

    /// ∫ f dω over the sphere by the midpoint rule in cos θ (`nt` cells) and φ (`np` cells)
    /// about the axis `n` of the frame `(t, b, n)`.
    fn sphere_integral(
        (nt, np): (usize, usize),
        (t, b, n): (DVec3, DVec3, DVec3),
        f: impl Fn(DVec3) -> f64,
    ) -> f64 {
        let mut sum = 0.0;
        for i in 0..nt {
            let ct = -1.0 + 2.0 * (i as f64 + 0.5) / nt as f64;
            let st = (1.0 - ct * ct).sqrt();
            for j in 0..np {
                let p = std::f64::consts::TAU * (j as f64 + 0.5) / np as f64;
                sum += f(t * (st * p.cos()) + b * (st * p.sin()) + n * ct);
            }
        }
        sum * 4.0 * std::f64::consts::PI / (nt * np) as f64
    }

    /// The sampler's weight equals `eval_cos/pdf` on average: E[weight·g(wi)] = ∫ f·|cos|·g dω
    /// for a test function g, checked by quadrature for a leaf and an RPV surface on a tilted
    /// normal.
    #[test]
    fn sampling_matches_evaluation() {
        let n = DVec3::new(0.3, -0.2, 0.9).normalize();
        let wo = DVec3::new(-0.1, 0.4, 0.8).normalize();
        let g = |w: DVec3| 1.0 + w.x + 0.5 * w.z * w.z;
        let models = [
            SurfaceModel::Leaf {
                reflectance: 0.45,
                transmittance: 0.3,
            },
            SurfaceModel::from_spec(
                &BrdfSpec::Rpv(RpvSpec {
                    rho_0: Spectrum::Constant(0.2),
                    k: Spectrum::Constant(0.7),
                    g: Spectrum::Constant(-0.1),
                    rho_c: None,
                }),
                0,
                550.0,
            )
            .unwrap(),
            SurfaceModel::Dielectric(crate::bsdf::RoughDielectric::new(1.5, 0.3).unwrap()),
            SurfaceModel::Dielectric(
                crate::bsdf::RoughDielectric::new(1.5, 0.4)
                    .unwrap()
                    .flipped(),
            ),
        ];
        for m in &models {
            // Quadrature over the sphere.
            let quad = sphere_integral((400, 800), (DVec3::X, DVec3::Y, DVec3::Z), |w| {
                m.eval_cos(n, w, wo) * g(w)
            });
            let mut rng = crate::rng::Stream::new(1, [0, 0, 0, 0]);
            let k = 400_000;
            let (mut sum, mut sum2) = (0.0, 0.0);
            for _ in 0..k {
                let u = [rng.next_f64(), rng.next_f64(), rng.next_f64()];
                let x = m.sample(n, wo, u).map_or(0.0, |s| s.weight * g(s.wi));
                sum += x;
                sum2 += x * x;
            }
            let mean = sum / k as f64;
            let se = ((sum2 / k as f64 - mean * mean) / k as f64).sqrt();
            assert!(
                (mean - quad).abs() < 4.5 * se + 1e-3 * quad,
                "{m:?}: MC {mean} ± {se} vs quadrature {quad}"
            );
        }
    }

    /// Leaves are sampled exactly: χ² of the drawn directions against `SurfaceModel::pdf`
    /// (2 sides × 10 × 10 cells in (cos²θ, φ) about the side's normal, equal in probability
    /// within a side; 100 000 draws, fixed seed), and every draw's weight is `eval_cos/pdf`
    /// = ρ + τ; the pdf integrates to 1 over the sphere.
    #[test]
    fn leaf_sampling_is_exact() {
        let (rho, tau) = (0.45, 0.3);
        let leaf = SurfaceModel::Leaf {
            reflectance: rho,
            transmittance: tau,
        };
        let n = DVec3::new(0.3, -0.2, 0.9).normalize();
        let wo = DVec3::new(-0.1, 0.4, 0.8).normalize();
        let (t, b) = basis_around(n);
        let mut rng = crate::rng::Stream::new(3, [0, 0, 0, 0]);
        let total = 100_000;
        let mut counts = vec![0u64; 200];
        for _ in 0..total {
            let s = leaf
                .sample(n, wo, [rng.next_f64(), rng.next_f64(), rng.next_f64()])
                .unwrap();
            let want = leaf.eval_cos(n, s.wi, wo) / leaf.pdf(n, s.wi, wo);
            assert!((s.weight - want).abs() < 1e-12 && (s.weight - (rho + tau)).abs() < 1e-12);
            assert!((s.pdf / leaf.pdf(n, s.wi, wo) - 1.0).abs() < 1e-12);
            let l = to_local(s.wi, n, t, b);
            let side = usize::from(l.z < 0.0);
            let c2 = l.z * l.z;
            let phi = l.y.atan2(l.x).rem_euclid(std::f64::consts::TAU);
            let i = ((c2 * 10.0) as usize).min(9);
            let j = ((phi / std::f64::consts::TAU * 10.0) as usize).min(9);
            counts[side * 100 + i * 10 + j] += 1;
        }
        let mut chi2 = 0.0;
        for (k, &c) in counts.iter().enumerate() {
            let p_side = if k < 100 { rho } else { tau } / (rho + tau);
            let e = total as f64 * p_side / 100.0;
            chi2 += (c as f64 - e).powi(2) / e;
        }
        let q = crate::bsdf::test_support::chi2_quantile_999(199);
        assert!(chi2 < q, "chi2 = {chi2} > {q}");
        // ∫pdf over the sphere (midpoint rule in cos θ and φ about n).
        let sum = sphere_integral((200, 400), (t, b, n), |w| leaf.pdf(n, w, wo));
        assert!((sum - 1.0).abs() < 1e-4, "∫pdf = {sum}");
    }

    #[test]
    fn leaf_sides_and_bad_parameters() {
        let leaf = SurfaceModel::Leaf {
            reflectance: 0.5,
            transmittance: 0.25,
        };
        let n = DVec3::Z;
        let wo = DVec3::new(0.0, 0.6, 0.8);
        let up = DVec3::new(0.6, 0.0, 0.8);
        let down = DVec3::new(0.6, 0.0, -0.8);
        let pi = std::f64::consts::PI;
        assert!((leaf.eval_cos(n, up, wo) - 0.5 / pi * 0.8).abs() < 1e-15);
        assert!((leaf.eval_cos(n, down, wo) - 0.25 / pi * 0.8).abs() < 1e-15);
        let bad = BrdfSpec::BiLambertian(BiLambertianSpec {
            reflectance: Spectrum::Constant(0.7),
            transmittance: Spectrum::Constant(0.4),
        });
        assert!(SurfaceModel::from_spec(&bad, 0, 550.0)
            .unwrap_err()
            .to_string()
            .contains("sum"));
        // Opaque surfaces see nothing from behind.
        let lam = SurfaceModel::from_spec(
            &BrdfSpec::Lambertian(LambertianSpec {
                reflectance: Spectrum::Constant(0.3),
            }),
            0,
            550.0,
        )
        .unwrap();
        assert_eq!(lam.eval_cos(n, down, wo), 0.0);
        assert!(SurfaceModel::Black.sample(n, wo, [0.1, 0.2, 0.3]).is_none());
    }
}
