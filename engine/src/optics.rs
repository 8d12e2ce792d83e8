//! The optical state of a run at one spectral point: everything the transport needs that depends
//! on wavelength. Built once per wavelength by the resolver; immutable during transport.

use crate::atmosphere::spherical::SphericalShell;
use crate::atmosphere::PlaneParallel;
use crate::bsdf::Bsdf;

#[derive(Clone, Debug)]
pub struct OpticalState {
    /// Wavelength, nm.
    pub wavelength: f64,
    pub atmosphere: PlaneParallel,
    /// The same layers as spherical shells, in spherical-shell experiments.
    pub shell: Option<SphericalShell>,
    pub surface: Bsdf,
    /// The 1D surface's thermal emission (`emission = true` with a surface temperature).
    pub surface_emission: Option<crate::bsdf::SurfaceEmission>,
    /// The 3D scene's material models at this wavelength (empty without a scene).
    pub scene_models: Vec<crate::scene::material::SurfaceModel>,
    /// The 3D scene's thermal emission at this wavelength (`emission = true` with a scene).
    pub scene_emission: Option<crate::scene::emission::SceneEmission>,
    /// Solar irradiance normal to the beam, W m⁻² nm⁻¹.
    pub irradiance: f64,
    /// `mode = "ckd"`: the bin's g-points, each (quadrature weight, optical state with that
    /// g-point's gas absorption); empty in monochromatic runs. Blocks of samples cycle through
    /// them (`blocks/single.rs` `run_block`).
    pub g_states: Vec<(f64, OpticalState)>,
}
