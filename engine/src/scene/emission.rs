//! Thermal emission of a 3D scene's surfaces at one wavelength (`emission = true`).
//!
//! Every material has a kinetic temperature T (K): the bundle's `temperature`, replaced by name
//! in the experiment's `[scene.temperatures]`; on the terrain a land-surface-temperature raster
//! (`scene.land_surface_temperature`, [`TemperatureMap`](super::texture::TemperatureMap)) replaces it wherever it has a pixel.
//! A hit emits towards the viewer `ε(μ)·B_λ(T)` (tally units: divided by the irradiance that
//! normalises the run, times a CKD g-point's Planck-fraction factor), μ = n·wo against the
//! geometric normal on the viewer's side, with Kirchhoff's emissivity:
//! * opaque BRDFs: `1 − ρ_dh(μ)` (`bsdf/emissivity.rs`, per material once per wavelength); a
//!   reflectance texture's pixel ρ gives `1 − ρ`;
//! * bi-Lambertian leaves: `1 − ρ − τ` on both faces (a thin leaf at one temperature: what it
//!   neither reflects nor transmits it absorbs, and so emits, into each side);
//! * panes (`thin_dielectric`): `1 − R(μ) − T(μ)` on both faces; a `rough_dielectric`
//!   interface absorbs nothing and emits nothing;
//! * `mirror` solvers: `1 − R_Fresnel(μ)`; `null` surfaces and [`BLACK`] (undersides, cells
//!   without a material) emit nothing.
//!
//! Reference: Kirchhoff's law for opaque surfaces as in `bsdf/emissivity.rs`; thin leaves as in
//! DART's and LESS's thermal modes (Gastellu-Etchegorry 2008, Remote Sens. Environ. 112,
//! 2878–2895: leaf emissivity 1 − ρ − τ).

use glam::DVec3;

use super::material::SurfaceModel;
use super::world::BLACK;
use super::{Scene, SurfaceHit};
use crate::bsdf::SurfaceEmission;
use bundle::SolverSpec;

/// How one material emits.
#[derive(Clone, Debug)]
enum Emitter {
    /// Emissivity table of an opaque BRDF (source 1).
    Opaque(SurfaceEmission),
    /// Isotropic emissivity (leaves).
    Grey(f64),
    /// A pane: emissivity `1 − R(μ) − T(μ)` (its absorptance, Kirchhoff).
    Pane(crate::bsdf::ThinDielectric),
    /// Emits nothing.
    None,
}

/// The emission of every material of a scene at one wavelength.
#[derive(Clone, Debug)]
pub struct SceneEmission {
    emitters: Vec<Emitter>,
    /// Per material id: `B_λ(T)·k` (tally units).
    source: Vec<f64>,
    /// nm, and the factor `k` on B (1/E0 and a g-point's factor), for LST pixels.
    wavelength: f64,
    k: f64,
}

impl SceneEmission {
    /// The emission of `scene`'s materials (`models`: at `wavelength` nm) with every B scaled by
    /// `k`. Every material must have a temperature (checked by the resolver).
    pub fn new(scene: &Scene, models: &[SurfaceModel], wavelength: f64, k: f64) -> Self {
        let emitters = models
            .iter()
            .enumerate()
            .map(|(id, m)| match (scene.solver(id as u16), m) {
                (SolverSpec::Null {}, _) => Emitter::None,
                // An interface absorbs nothing, so emits nothing (its inside's emission is not
                // modelled: the medium behind it is transparent).
                (_, SurfaceModel::Black | SurfaceModel::Dielectric(_)) => Emitter::None,
                (_, SurfaceModel::Pane(p)) => Emitter::Pane(*p),
                (
                    _,
                    SurfaceModel::Leaf {
                        reflectance,
                        transmittance,
                    },
                ) => Emitter::Grey((1.0 - reflectance - transmittance).clamp(0.0, 1.0)),
                (_, SurfaceModel::Opaque(bsdf)) => Emitter::Opaque(SurfaceEmission::new(bsdf, 1.0)),
            })
            .collect();
        let source = (0..models.len())
            .map(|id| {
                scene
                    .temperature(id as u16)
                    .map_or(0.0, |t| crate::sources::planck::radiance(wavelength, t) * k)
            })
            .collect();
        SceneEmission {
            emitters,
            source,
            wavelength,
            k,
        }
    }

    /// Radiance (tally units) emitted by the surface at `h` towards `wo` (unit, on the side of
    /// `h.normal`). `fresnel(n, k, μ)` is the Fresnel reflectance of `mirror` solvers (the
    /// integrator's `solver::fresnel_reflectance`, passed in so that scenes do not depend on
    /// the integrator).
    pub fn radiance(
        &self,
        scene: &Scene,
        h: &SurfaceHit,
        wo: DVec3,
        fresnel: impl Fn(f64, f64, f64) -> f64,
    ) -> f64 {
        if h.material == BLACK {
            return 0.0;
        }
        let id = h.material as usize;
        let mu = h.normal.dot(wo).clamp(0.0, 1.0);
        let eps = match scene.solver(h.material) {
            SolverSpec::Null {} => return 0.0,
            SolverSpec::Mirror {
                refractive_index,
                absorption_index,
            } => 1.0 - fresnel(refractive_index, absorption_index, mu.max(1e-6)),
            _ => match scene.texture_reflectance(h, self.wavelength) {
                Some(r) => 1.0 - r,
                None => match self.emitters.get(id) {
                    Some(Emitter::Opaque(e)) => e.emissivity(mu),
                    Some(Emitter::Grey(e)) => *e,
                    Some(Emitter::Pane(p)) => {
                        let (r, t) = p.reflect_transmit(mu);
                        (1.0 - r - t).max(0.0)
                    }
                    _ => 0.0,
                },
            },
        };
        if eps <= 0.0 {
            return 0.0;
        }
        let source = match scene.land_surface_temperature(h) {
            Some(t) => crate::sources::planck::radiance(self.wavelength, t) * self.k,
            None => self.source.get(id).copied().unwrap_or(0.0),
        };
        eps * source
    }
}
