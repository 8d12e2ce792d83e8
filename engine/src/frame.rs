//! Directions, angles and the local frame.
//!
//! Convention (used everywhere, see `docs/conventions.md`): the local frame is East-North-Up,
//! `x` = East, `y` = North, `z` = Up. An azimuth `phi` is measured **clockwise from North**
//! (geographic convention, as in satellite metadata), a zenith `theta` from the local vertical.
//! The unit vector of (theta, phi) is `(sin θ sin φ, sin θ cos φ, cos θ)`.
//!
//! "Direction of the Sun" and "direction of the sensor" are always directions *from the target
//! towards* the Sun or the sensor; light from the Sun propagates along the opposite vector.

use glam::DVec3;

/// Unit vector for a zenith and an azimuth given in radians.
#[inline]
pub fn direction_from_angles(zenith: f64, azimuth: f64) -> DVec3 {
    let (st, ct) = zenith.sin_cos();
    let (sp, cp) = azimuth.sin_cos();
    DVec3::new(st * sp, st * cp, ct)
}

/// Zenith and azimuth (radians, azimuth in [0, 2π)) of a unit vector.
#[inline]
pub fn angles_from_direction(d: DVec3) -> (f64, f64) {
    let zenith = d.z.clamp(-1.0, 1.0).acos();
    let mut azimuth = d.x.atan2(d.y);
    if azimuth < 0.0 {
        azimuth += std::f64::consts::TAU;
    }
    if zenith.sin() < 1e-12 {
        azimuth = 0.0;
    }
    (zenith, azimuth)
}

/// An orthonormal basis (s, t, n) around the unit vector `n` (Duff et al. 2017, branchless).
#[inline]
pub fn basis_around(n: DVec3) -> (DVec3, DVec3) {
    let sign = 1.0_f64.copysign(n.z);
    let a = -1.0 / (sign + n.z);
    let b = n.x * n.y * a;
    let s = DVec3::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x);
    let t = DVec3::new(b, sign + n.y * n.y * a, -n.y);
    (s, t)
}

/// The direction at angle `acos(cos_theta)` from `axis`, at azimuth `phi` around it.
#[inline]
pub fn rotate_about(axis: DVec3, cos_theta: f64, phi: f64) -> DVec3 {
    let sin_theta = (1.0 - cos_theta * cos_theta).max(0.0).sqrt();
    let (s, t) = basis_around(axis);
    let (sp, cp) = phi.sin_cos();
    (s * (sin_theta * cp) + t * (sin_theta * sp) + axis * cos_theta).normalize()
}

/// Cosine-weighted direction on the upper hemisphere (z > 0) from two uniform numbers;
/// its pdf with respect to solid angle is `cos θ / π`.
#[inline]
pub fn sample_cosine_hemisphere(u1: f64, u2: f64) -> DVec3 {
    let r = u1.sqrt();
    let phi = std::f64::consts::TAU * u2;
    let (sp, cp) = phi.sin_cos();
    DVec3::new(r * cp, r * sp, (1.0 - u1).max(0.0).sqrt())
}

/// A local frame `(t, b, n)` of a surface point.
#[derive(Clone, Copy, Debug)]
pub struct Frame {
    pub t: DVec3,
    pub b: DVec3,
    pub n: DVec3,
}

impl Frame {
    /// The frame about the unit normal `n`.
    pub fn around(n: DVec3) -> Self {
        let (t, b) = basis_around(n);
        Frame { t, b, n }
    }
    #[inline]
    pub fn local(&self, v: DVec3) -> DVec3 {
        DVec3::new(v.dot(self.t), v.dot(self.b), v.dot(self.n))
    }
    #[inline]
    pub fn world(&self, v: DVec3) -> DVec3 {
        self.t * v.x + self.b * v.y + self.n * v.z
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn angles_round_trip() {
        for &(z, a) in &[(0.3, 0.1), (1.2, 3.0), (2.5, 5.9), (0.01, 1.0)] {
            let d = direction_from_angles(z, a);
            let (z2, a2) = angles_from_direction(d);
            assert!(
                (z - z2).abs() < 1e-12 && (a - a2).abs() < 1e-12,
                "{z} {a} {z2} {a2}"
            );
        }
        // Azimuth 90° (clockwise from North) points East.
        let e = direction_from_angles(std::f64::consts::FRAC_PI_2, std::f64::consts::FRAC_PI_2);
        assert!((e - DVec3::X).length() < 1e-12);
    }

    #[test]
    fn basis_is_orthonormal() {
        for n in [DVec3::Z, -DVec3::Z, DVec3::new(0.3, -0.5, 0.2).normalize()] {
            let (s, t) = basis_around(n);
            assert!(s.dot(t).abs() < 1e-12 && s.dot(n).abs() < 1e-12 && t.dot(n).abs() < 1e-12);
            assert!((s.length() - 1.0).abs() < 1e-12 && (t.length() - 1.0).abs() < 1e-12);
            let d = rotate_about(n, 0.4, 1.3);
            assert!((d.dot(n) - 0.4).abs() < 1e-12);
        }
    }
}
