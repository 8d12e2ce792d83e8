//! The air a lidar's photons fly through: plane-parallel layers, or spherical shells around
//! the planet. Positions are the scene's (or the 1D ground's) frame, m; a planet-centred point
//! is that point plus `(0, 0, R)` (the frame of bent scenes, `integrator/geometry/
//! scene_shells.rs`). Both give the optical path along a straight line, the distance to a
//! collision for a sampled optical path, and the layer (albedo, phase function) at a point.

use glam::DVec3;

use crate::atmosphere::spherical::{ShellEnd, SphericalShell};
use crate::atmosphere::PlaneParallel;
use crate::phase::PhaseFunction;

/// Plane-parallel layers or spherical shells.
#[derive(Clone, Copy)]
pub enum Air<'a> {
    Layers(&'a PlaneParallel),
    Shells(&'a SphericalShell),
}

impl Air<'_> {
    /// Planet-centred point of `p`, and how far along `d` the ray enters the shells (`None`:
    /// it misses them).
    fn enter(shell: &SphericalShell, p: DVec3, d: DVec3) -> Option<(DVec3, f64)> {
        let pc = p + DVec3::new(0.0, 0.0, shell.planet_radius);
        let q = shell.entry_point(pc, d)?;
        Some((q, (q - pc).dot(d).max(0.0)))
    }

    /// Optical path (extinction) along `p + t·d`, `0 ≤ t ≤ len`.
    pub fn optical_path(&self, p: DVec3, d: DVec3, len: f64) -> f64 {
        match *self {
            Air::Layers(a) => a.optical_path(p.z, d.z, len),
            Air::Shells(s) => match Self::enter(s, p, d) {
                Some((q, t0)) if t0 < len => {
                    s.optical_depth_within(q, s.shell_at(q.length()), d, len - t0)
                }
                _ => 0.0,
            },
        }
    }

    /// Distance along `p + t·d` at which the optical path reaches `tau`, if before `tmax` and
    /// inside the air.
    pub fn march(&self, p: DVec3, d: DVec3, tau: f64, tmax: f64) -> Option<f64> {
        match *self {
            Air::Layers(a) => a.march(p.z, d.z, tau, tmax),
            Air::Shells(s) => {
                let (q, t0) = Self::enter(s, p, d)?;
                match s.fly(q, s.shell_at(q.length()), d, tau) {
                    ShellEnd::Collision(c, _) => {
                        let t = t0 + (c - q).dot(d);
                        (t < tmax).then_some(t)
                    }
                    _ => None,
                }
            }
        }
    }

    /// Single-scattering albedo and phase function of the air at `p`.
    pub fn at(&self, p: DVec3) -> (f64, &PhaseFunction) {
        match *self {
            Air::Layers(a) => {
                let l = a.layer_at_altitude(p.z);
                (a.albedo(l), a.phase(l))
            }
            Air::Shells(s) => {
                let r = (p + DVec3::new(0.0, 0.0, s.planet_radius)).length();
                let l = s.shell_at(r);
                (s.albedo(l), s.phase(l))
            }
        }
    }
}
