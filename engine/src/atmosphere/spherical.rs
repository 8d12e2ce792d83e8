//! Spherical-shell atmospheres: the plane-parallel layers wrapped into concentric shells around a
//! spherical planet.
//!
//! | parameter       | unit | default   | meaning                                   |
//! |-----------------|------|-----------|-------------------------------------------|
//! | `planet_radius` | km   | 6378.1    | radius of the sphere at altitude 0        |
//!
//! Frame: planet-centred, metres, f64; the measures' target point (the origin of the local
//! East-North-Up frame of the experiment) is at `(0, 0, R + ground)`, so local axes and global
//! axes coincide there. Each shell is homogeneous: its extinction coefficient is its vertical
//! optical thickness divided by its thickness. Free paths are sampled analytically, shell by
//! shell, from exact ray–sphere intersections (no null collisions), and transmittances are exact
//! chord sums; a ray that meets the ground has zero transmittance (Earth's shadow).
//!
//! Numerics: the walk keeps the index of the shell it is in rather than recomputing it from the
//! radius, so rounding at shell boundaries cannot make a path oscillate between shells.

use glam::DVec3;

use super::PlaneParallel;
use crate::phase::PhaseFunction;

#[derive(Clone, Debug)]
pub struct SphericalShell {
    /// Boundary radii from the ground up, m (len = shells + 1).
    radius: Vec<f64>,
    /// Per shell, bottom up: extinction coefficient (m⁻¹), albedo, phase function.
    sigma: Vec<f64>,
    albedo: Vec<f64>,
    phase: Vec<PhaseFunction>,
    /// Per shell, bottom up: the thermal source `[at its bottom, at its top]` in tally units
    /// (the plane-parallel layer's, `atmosphere/emission.rs`); empty without emission.
    source: Vec<[f64; 2]>,
    /// Planet radius (altitude 0), m.
    pub planet_radius: f64,
}

/// The transmittance of a flight from its start to its end ([`SphericalShell::emission_within`]),
/// and to the ground when it ends there.
#[derive(Clone, Copy, Debug)]
pub struct FlightTransmittance {
    pub total: f64,
    pub ground: Option<f64>,
}

/// Where a flight in a spherical shell ends.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ShellEnd {
    /// Collision at a point, in a shell.
    Collision(DVec3, usize),
    /// Reaches the ground at a point.
    Surface(DVec3),
    /// Leaves through the top.
    Escape,
}

impl SphericalShell {
    /// Wrap a plane-parallel atmosphere's layers around a sphere of radius `planet_radius` (m).
    pub fn new(pp: &PlaneParallel, planet_radius: f64) -> Self {
        // PlaneParallel stores boundaries top-down; shells go bottom-up.
        let b: Vec<(f64, f64)> = pp.boundaries().collect();
        let n = pp.layer_count();
        let mut radius = Vec::with_capacity(n + 1);
        let mut sigma = Vec::with_capacity(n);
        let mut albedo = Vec::with_capacity(n);
        let mut phase = Vec::with_capacity(n);
        let mut source = Vec::new();
        radius.push(planet_radius + b[n].0);
        for i in (0..n).rev() {
            let (z_top, tau_top) = b[i];
            let (z_bot, tau_bot) = b[i + 1];
            let dz = z_top - z_bot;
            sigma.push(if dz > 0.0 {
                (tau_bot - tau_top) / dz
            } else {
                0.0
            });
            albedo.push(pp.albedo(i));
            phase.push(pp.phase(i).clone());
            radius.push(planet_radius + z_top);
            if pp.emits() {
                let [top, bottom] = pp.source(i);
                source.push([bottom, top]);
            }
        }
        Self {
            radius,
            sigma,
            albedo,
            phase,
            source,
            planet_radius,
        }
    }

    /// Whether any shell emits.
    pub fn emits(&self) -> bool {
        !self.source.is_empty()
    }

    /// Thermal emission over the flight from `p` (in shell `l`) along `d`, estimated without
    /// bias from one uniform `u`, and the transmittance to the ground if the flight reaches it
    /// (`None`: it leaves through the top). The expectation of the collision estimator is
    /// `Σ_segments e^{−τ_before}·∫₀^L k e^{−k s}(1 − ω)S(r(s)) ds` over the shell segments the
    /// flight crosses (S linear in radius inside a shell: linear in radial optical depth, as in
    /// the plane-parallel layer). Each segment's integral is `P·E[(1 − ω)S(r(s))]` with
    /// `P = 1 − e^{−kL}` and s drawn from the truncated exponential by inversion of `u`
    /// (`s = −ln(1 − u·P)/k`); the same `u` serves every segment (each term stays unbiased).
    /// Along a slant chord r(s) is not linear in s, which is why there is no closed form here;
    /// the estimate's variance is that of S across one segment, small for thin shells.
    pub fn emission_along(&self, p: DVec3, l: usize, d: DVec3, u: f64) -> (f64, Option<f64>) {
        let (e, end) = self.emission_within(p, l, d, u, f64::INFINITY);
        (e, end.ground)
    }

    /// [`Self::emission_along`] over at most the distance `tmax` (a 3D scene's surface hit):
    /// the emission, and the transmittance to wherever the flight ends.
    pub fn emission_within(
        &self,
        mut p: DVec3,
        mut l: usize,
        d: DVec3,
        u: f64,
        tmax: f64,
    ) -> (f64, FlightTransmittance) {
        let n = self.sigma.len() as isize;
        let (mut tau, mut e) = (0.0_f64, 0.0_f64);
        let mut left = tmax;
        loop {
            let (t_exit, next) = self.exit(p, d, l);
            let stop = t_exit >= left;
            let t = if stop { left } else { t_exit };
            let k = self.sigma[l];
            let dd = k * t;
            if dd > 0.0 && !self.source.is_empty() {
                let prob = -(-dd).exp_m1();
                let s = -(-u * prob).ln_1p() / k;
                let r = (p + d * s.min(t)).length();
                let (r0, r1) = (self.radius[l], self.radius[l + 1]);
                let f = ((r - r0) / (r1 - r0)).clamp(0.0, 1.0);
                let [sb, st] = self.source[l];
                e += (-tau).exp() * prob * (1.0 - self.albedo[l]) * (sb + (st - sb) * f);
            }
            tau += dd;
            p += d * t;
            let end = |ground: bool| FlightTransmittance {
                total: (-tau).exp(),
                ground: ground.then(|| (-tau).exp()),
            };
            if stop {
                return (e, end(false));
            }
            left -= t;
            if next < 0 {
                return (e, end(true));
            }
            if next >= n {
                return (e, end(false));
            }
            l = next as usize;
        }
    }

    pub fn ground_radius(&self) -> f64 {
        self.radius[0]
    }

    pub fn toa_radius(&self) -> f64 {
        *self.radius.last().unwrap()
    }

    pub fn shell_count(&self) -> usize {
        self.sigma.len()
    }

    #[inline]
    pub fn albedo(&self, i: usize) -> f64 {
        self.albedo[i]
    }

    #[inline]
    pub fn phase(&self, i: usize) -> &PhaseFunction {
        &self.phase[i]
    }

    /// Shell holding radius `r` (clamped to the atmosphere).
    pub fn shell_at(&self, r: f64) -> usize {
        let i = self.radius.partition_point(|&x| x <= r);
        i.clamp(1, self.sigma.len()) - 1
    }

    /// Distance along `d` from `p` (inside shell `l`) to the shell's boundary, and the shell
    /// entered (`None` below the ground or above TOA is encoded as -1 / n).
    #[inline]
    fn exit(&self, p: DVec3, d: DVec3, l: usize) -> (f64, isize) {
        let b = p.dot(d);
        let pp = p.length_squared();
        // Inner sphere, only when moving inwards and the ray reaches it. A point on the inner
        // sphere (or inside it by rounding) moving inwards crosses it at once: `t` is then 0,
        // never the far root of the outer sphere through the planet (a path starting on the
        // ground and looking down, e.g. an upwelling flux at altitude 0).
        let r_in = self.radius[l];
        let disc_in = b * b - (pp - r_in * r_in);
        if b < 0.0 && disc_in > 0.0 {
            return ((-b - disc_in.sqrt()).max(0.0), l as isize - 1);
        }
        let r_out = self.radius[l + 1];
        let disc_out = (b * b - (pp - r_out * r_out)).max(0.0);
        ((-b + disc_out.sqrt()).max(0.0), l as isize + 1)
    }

    /// Flight of optical path `s` from `p` in shell `l` along unit `d`.
    pub fn fly(&self, mut p: DVec3, mut l: usize, d: DVec3, mut s: f64) -> ShellEnd {
        let n = self.sigma.len() as isize;
        loop {
            let (t, next) = self.exit(p, d, l);
            let tau = self.sigma[l] * t;
            if s < tau {
                return ShellEnd::Collision(p + d * (s / self.sigma[l]), l);
            }
            s -= tau;
            p += d * t;
            if next < 0 {
                // Snap onto the ground sphere.
                return ShellEnd::Surface(p * (self.radius[0] / p.length()));
            }
            if next >= n {
                return ShellEnd::Escape;
            }
            l = next as usize;
        }
    }

    /// Optical depth from `p` (in shell `l`) to infinity along `d`; `None` if the ray meets the
    /// ground.
    pub fn optical_depth_to_space(&self, mut p: DVec3, mut l: usize, d: DVec3) -> Option<f64> {
        let n = self.sigma.len() as isize;
        let mut tau = 0.0;
        loop {
            let (t, next) = self.exit(p, d, l);
            tau += self.sigma[l] * t;
            p += d * t;
            if next < 0 {
                return None;
            }
            if next >= n {
                return Some(tau);
            }
            l = next as usize;
        }
    }

    /// Optical depth from `p` (in shell `l`) along `d` over the distance `tmax` or until the ray
    /// leaves the atmosphere (through the top or into the ground), whichever comes first
    /// (`tmax = ∞`: the whole flight).
    pub fn optical_depth_within(&self, mut p: DVec3, mut l: usize, d: DVec3, tmax: f64) -> f64 {
        let n = self.sigma.len() as isize;
        let (mut tau, mut left) = (0.0, tmax);
        loop {
            let (t, next) = self.exit(p, d, l);
            if t >= left {
                return tau + self.sigma[l] * left;
            }
            tau += self.sigma[l] * t;
            left -= t;
            p += d * t;
            if next < 0 || next >= n {
                return tau;
            }
            l = next as usize;
        }
    }

    /// Transmittance from `p` to space along `d` (0 in the planet's shadow).
    #[inline]
    pub fn transmittance_to_space(&self, p: DVec3, l: usize, d: DVec3) -> f64 {
        self.optical_depth_to_space(p, l, d)
            .map_or(0.0, |t| (-t).exp())
    }

    /// Where the ray from `p` along `d` enters the atmosphere from space, if it does (`p` outside
    /// or on the top sphere).
    pub fn entry_point(&self, p: DVec3, d: DVec3) -> Option<DVec3> {
        let r = self.toa_radius();
        if p.length() <= r {
            return Some(p);
        }
        let b = p.dot(d);
        let disc = b * b - (p.length_squared() - r * r);
        if disc <= 0.0 {
            return None;
        }
        let t = -b - disc.sqrt();
        if t < 0.0 {
            return None;
        }
        Some(p + d * t)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::atmosphere::LayerOptics;
    use crate::phase::{PhaseFunction, Rayleigh};

    fn shell(r: f64) -> SphericalShell {
        let ray = PhaseFunction::Rayleigh(Rayleigh::new(0.0).unwrap());
        let layers = vec![
            LayerOptics {
                bottom: 0.0,
                top: 10_000.0,
                tau_sca: 0.3,
                tau_abs: 0.0,
                phase: ray.clone(),
            },
            LayerOptics {
                bottom: 10_000.0,
                top: 100_000.0,
                tau_sca: 0.2,
                tau_abs: 0.0,
                phase: ray,
            },
        ];
        SphericalShell::new(&PlaneParallel::new(layers, 0.0, 100_000.0), r)
    }

    /// Vertical optical depths equal the layers' optical thicknesses; a slant path through a flat
    /// enough sphere approaches τ/μ; a ray aimed at the ground is in shadow.
    #[test]
    fn optical_depths() {
        let s = shell(6_378_100.0);
        let g = DVec3::new(0.0, 0.0, s.ground_radius() + 1e-6);
        let up = s.optical_depth_to_space(g, 0, DVec3::Z).unwrap();
        assert!((up - 0.5).abs() < 1e-9, "{up}");
        let mid = DVec3::new(0.0, 0.0, s.ground_radius() + 10_000.0 + 1.0);
        assert!(
            (s.optical_depth_to_space(mid, 1, DVec3::Z).unwrap()
                - 0.2 * (90_000.0 - 1.0) / 90_000.0)
                .abs()
                < 1e-9
        );
        // A very large planet behaves like a plane-parallel slab at 60°.
        let big = shell(1e12);
        let g = DVec3::new(0.0, 0.0, big.ground_radius() + 1e-3);
        let d = crate::frame::direction_from_angles(60f64.to_radians(), 0.3);
        let t = big.optical_depth_to_space(g, 0, d).unwrap();
        assert!((t - 1.0).abs() < 1e-6, "{t}");
        // Downwards: into the ground.
        assert!(s.optical_depth_to_space(mid, 1, -DVec3::Z).is_none());
        // Horizontal ray from the ground top: grazing path through the whole atmosphere.
        let h = s
            .optical_depth_to_space(g.normalize() * (s.ground_radius() + 1.0), 0, DVec3::X)
            .unwrap();
        assert!(h > 10.0, "{h}");
    }

    /// Sampled free paths: the fraction of flights from the ground straight up that escape is
    /// e^{−τ}, and collision points lie in the right shell.
    #[test]
    fn flights() {
        let s = shell(6_378_100.0);
        let g = DVec3::new(0.0, 0.0, s.ground_radius());
        assert_eq!(s.fly(g, 0, DVec3::Z, 0.6), ShellEnd::Escape);
        match s.fly(g, 0, DVec3::Z, 0.15) {
            ShellEnd::Collision(p, l) => {
                assert_eq!(l, 0);
                assert!((p.z - s.ground_radius() - 5_000.0).abs() < 1e-6);
            }
            e => panic!("{e:?}"),
        }
        match s.fly(g, 0, DVec3::Z, 0.4) {
            ShellEnd::Collision(p, l) => {
                assert_eq!(l, 1);
                assert!((p.z - s.ground_radius() - 55_000.0).abs() < 1e-6);
            }
            e => panic!("{e:?}"),
        }
        let top = DVec3::new(0.0, 0.0, s.toa_radius());
        match s.fly(top, 1, -DVec3::Z, 10.0) {
            ShellEnd::Surface(p) => assert!((p.length() - s.ground_radius()).abs() < 1e-6),
            e => panic!("{e:?}"),
        }
    }
}
