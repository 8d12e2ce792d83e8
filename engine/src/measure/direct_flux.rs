//! The direct (unscattered) solar flux on a horizontal plane at a level of a 1D atmosphere, in
//! closed form: `F_dir(z) = E0·μ0·T(z)`, with `μ0` the cosine of the solar zenith angle and `T`
//! the beam's transmittance from the top of the atmosphere to altitude `z`:
//!
//! * plane-parallel layers: `T = exp(−τ(z)/μ0)`, `τ(z)` the extinction optical depth above `z`
//!   (Beer–Lambert; e.g. Liou (2002), *An Introduction to Atmospheric Radiation*, eq. 1.4.8);
//! * spherical shells: `T = exp(−∫σ ds)` along the straight ray from the point above the target
//!   towards the Sun, crossing the shells exactly ([`crate::atmosphere::spherical::SphericalShell::transmittance_to_space`]),
//!   0 when the planet hides the Sun;
//! * correlated-k bins: the g-point quadrature `Σ_g w_g·T_g` (the bin-mean transmittance).
//!
//! The walks estimate only the scattered (diffuse) part of downwelling flux; a delta-directed
//! beam is met by no sampled direction. The products add this term, which has no Monte Carlo
//! error. Returned here divided by `E0·μ0` (the units of the `albedo` column): `T(z)`.

use glam::DVec3;

use crate::optics::OpticalState;

/// Direct-beam transmittance from TOA to altitude `z` (m) for a Sun in direction `sun`
/// (unit vector towards the Sun, `z` component μ0 > 0). 0 when the Sun is below the horizon.
pub fn direct_transmittance(opt: &OpticalState, sun: DVec3, z: f64) -> f64 {
    if sun.z <= 0.0 {
        return 0.0;
    }
    if !opt.g_states.is_empty() {
        return opt
            .g_states
            .iter()
            .map(|(w, g)| w * direct_transmittance(g, sun, z))
            .sum();
    }
    match &opt.shell {
        Some(shell) => {
            let p = DVec3::new(0.0, 0.0, shell.planet_radius + z);
            let l = shell.shell_at(p.length()).min(shell.shell_count() - 1);
            shell.transmittance_to_space(p, l, sun)
        }
        None => (-opt.atmosphere.tau_at_altitude(z) / sun.z).exp(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::atmosphere::spherical::SphericalShell;
    use crate::atmosphere::{LayerOptics, PlaneParallel};
    use crate::bsdf::{Bsdf, Lambertian};
    use crate::phase::{PhaseFunction, Rayleigh};

    fn state(tau: f64, planet: Option<f64>) -> OpticalState {
        let layer = LayerOptics {
            bottom: 0.0,
            top: 100e3,
            tau_sca: tau,
            tau_abs: 0.0,
            phase: PhaseFunction::Rayleigh(Rayleigh::new(0.0).unwrap()),
        };
        let atmosphere = PlaneParallel::new(vec![layer], 0.0, 100e3);
        OpticalState {
            wavelength: 550.0,
            shell: planet.map(|r| SphericalShell::new(&atmosphere, r)),
            atmosphere,
            surface: Bsdf::Lambertian(Lambertian::new(0.0).unwrap()),
            surface_emission: None,
            scene_models: Vec::new(),
            scene_emission: None,
            irradiance: 1.0,
            g_states: Vec::new(),
        }
    }

    #[test]
    fn plane_parallel_is_beer_lambert() {
        let opt = state(0.5, None);
        let sun = DVec3::new(60f64.to_radians().sin(), 0.0, 60f64.to_radians().cos());
        let t = direct_transmittance(&opt, sun, 50e3);
        assert!((t - (-0.25f64 / 0.5).exp()).abs() < 1e-12, "{t}");
        assert_eq!(direct_transmittance(&opt, sun, 100e3), 1.0);
    }

    #[test]
    fn spherical_overhead_sun_equals_plane_parallel() {
        // A vertical beam crosses the shells as it crosses the layers.
        let opt = state(0.5, Some(6371e3));
        let t = direct_transmittance(&opt, DVec3::Z, 0.0);
        assert!((t - (-0.5f64).exp()).abs() < 1e-9, "{t}");
        // A grazing Sun: the spherical path is finite, the plane-parallel one 1/μ0 = 57×.
        let sun = DVec3::new(89f64.to_radians().sin(), 0.0, 89f64.to_radians().cos());
        let ts = direct_transmittance(&opt, sun, 0.0);
        let tp = direct_transmittance(&state(0.5, None), sun, 0.0);
        assert!(ts > tp && ts > 0.0 && ts < 1.0, "{ts} {tp}");
    }

    #[test]
    fn ckd_bins_average_their_g_points() {
        let mut opt = state(0.1, None);
        opt.g_states = vec![(0.25, state(0.2, None)), (0.75, state(1.0, None))];
        let t = direct_transmittance(&opt, DVec3::Z, 0.0);
        assert!((t - (0.25 * (-0.2f64).exp() + 0.75 * (-1.0f64).exp())).abs() < 1e-12);
    }
}
