//! Stokes vectors, Mueller matrices of scattering, and the project's polarization convention.
//!
//! **Convention** (the one of `shared/reference/CONVENTIONS.md`, written once here):
//! a Stokes vector `(I, Q, U, V)` of light travelling along the unit vector `w` refers to a pair
//! of unit axes `(e1, e2)` with `(e1, e2, w)` right-handed (`e2 = w × e1`);
//! `Q = I(∥e1) − I(∥e2)`, `U = I(∥(e1+e2)/√2) − I(∥(e1−e2)/√2)` (i.e. `2 Re(E1 E2*)`),
//! `V = 2 Im(E1 E2*)`; the sign of V enters only through the `b2` element of phase matrices,
//! taken as in libRadtran and Hovenier et al. (2004): F34 = b2, F43 = −b2.
//!
//! Outputs use the **meridian frame** of the direction towards the sensor: `e1 = e_θ`, the unit
//! vector in the meridian plane towards increasing zenith, `e2 = w × e_θ`. For a zenith direction
//! (θ = 0) the meridian plane is that of the measure's stated azimuth. With this frame the singly
//! scattered Rayleigh light in the principal plane has `Q < 0` (polarized perpendicular to the
//! meridian plane). Relation to the references: the corrected Coulson tables of Natraj et al.
//! (2009) give `(Q, U)` of opposite sign (their `Q = I_r − I_l`); IPRT (Emde et al. 2015) uses a
//! meridian frame too — see docs/conventions.md.
//!
//! Scattering (van de Hulst 1957; Hovenier et al. 2004): for light going from `d` to `d'`, the
//! scattering-plane frame has `r = (d × d')/|d × d'|` (perpendicular) and `l = r × d` (parallel);
//! the phase matrix `F(Θ) = [[a1, b1, 0, 0], [b1, a2, 0, 0], [0, 0, a3, b2], [0, 0, −b2, a4]]`
//! maps the Stokes vector in `(l, r)` before to that in `(l' = r × d', r)` after.

use glam::DVec3;

pub type Stokes = [f64; 4];

/// Rotate a Stokes vector from axes `(e1, e2)` to axes `(f1, f2)` of the same direction, given
/// `cos ψ = f1·e1` and `sin ψ = f1·e2` (ψ the angle from e1 to f1, towards e2).
#[inline]
pub fn rotate(s: Stokes, cos_psi: f64, sin_psi: f64) -> Stokes {
    // cos 2ψ, sin 2ψ without trigonometric calls (the axes are unit vectors).
    if s[1] == 0.0 && s[2] == 0.0 {
        return s;
    }
    let c2 = cos_psi * cos_psi - sin_psi * sin_psi;
    let s2 = 2.0 * cos_psi * sin_psi;
    [s[0], c2 * s[1] + s2 * s[2], -s2 * s[1] + c2 * s[2], s[3]]
}

/// Rotate `s`, referred to `(e1, w × e1)`, into the frame whose first axis is `f1` (⊥ w).
#[inline]
pub fn rotate_to(s: Stokes, w: DVec3, e1: DVec3, f1: DVec3) -> Stokes {
    if s[1] == 0.0 && s[2] == 0.0 {
        return s;
    }
    let e2 = w.cross(e1);
    rotate(s, f1.dot(e1), f1.dot(e2))
}

/// The meridian axis `e_θ` of direction `w` (towards increasing zenith); for |w_z| ≈ 1, the
/// horizontal axis of azimuth `azimuth_hint` (radians, clockwise from North) instead.
#[inline]
pub fn meridian_axis(w: DVec3, azimuth_hint: f64) -> DVec3 {
    let h = (w.x * w.x + w.y * w.y).sqrt();
    if h < 1e-9 {
        // θ = 0 (w up): e_θ points horizontally towards the azimuth; θ = π: away from it.
        let (s, c) = azimuth_hint.sin_cos();
        return DVec3::new(s, c, 0.0) * w.z.signum();
    }
    // e_θ = ∂w/∂θ = (cos θ sin φ, cos θ cos φ, −sin θ) with sin φ = x/h, cos φ = y/h.
    DVec3::new(w.z * w.x / h, w.z * w.y / h, -h)
}

/// Any unit axis perpendicular to `w` (to start an unpolarized beam's frame).
#[inline]
pub fn any_perpendicular(w: DVec3) -> DVec3 {
    let (s, _) = crate::frame::basis_around(w);
    s
}

/// The six independent elements of a phase matrix at one scattering angle.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PhaseMatrix {
    pub a1: f64,
    pub b1: f64,
    pub a2: f64,
    pub a3: f64,
    pub b2: f64,
    pub a4: f64,
}

impl PhaseMatrix {
    /// A depolarizer with phase function value `p`: only I scatters.
    pub fn depolarizing(p: f64) -> Self {
        Self {
            a1: p,
            b1: 0.0,
            a2: 0.0,
            a3: 0.0,
            b2: 0.0,
            a4: 0.0,
        }
    }

    #[inline]
    pub fn apply(&self, s: Stokes) -> Stokes {
        [
            self.a1 * s[0] + self.b1 * s[1],
            self.b1 * s[0] + self.a2 * s[1],
            self.a3 * s[2] + self.b2 * s[3],
            -self.b2 * s[2] + self.a4 * s[3],
        ]
    }

    #[inline]
    pub fn scaled(&self, k: f64) -> Self {
        Self {
            a1: self.a1 * k,
            b1: self.b1 * k,
            a2: self.a2 * k,
            a3: self.a3 * k,
            b2: self.b2 * k,
            a4: self.a4 * k,
        }
    }

    #[inline]
    pub fn add(&mut self, o: &PhaseMatrix) {
        self.a1 += o.a1;
        self.b1 += o.b1;
        self.a2 += o.a2;
        self.a3 += o.a3;
        self.b2 += o.b2;
        self.a4 += o.a4;
    }
}

/// Scatter Stokes vector `s` (travelling along `d`, first axis `e1`) into direction `d2` through
/// `f` (evaluated at cos Θ = d·d2). Returns the scattered Stokes vector and its first axis `l'`.
#[inline]
pub fn scatter(s: Stokes, d: DVec3, e1: DVec3, d2: DVec3, f: &PhaseMatrix) -> (Stokes, DVec3) {
    let mut r = d.cross(d2);
    let len = r.length();
    if len < 1e-12 {
        // Forward or backward scattering: any plane through d; keep the current frame.
        r = d.cross(e1);
    } else {
        r /= len;
    }
    let l = r.cross(d);
    let s_in = rotate_to(s, d, e1, l);
    let out = f.apply(s_in);
    (out, r.cross(d2))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::frame::direction_from_angles;

    /// Rotation by ψ then −ψ is the identity; by 90° flips Q and U; I and V are invariant.
    #[test]
    fn rotations() {
        let s = [1.0, 0.3, -0.2, 0.1];
        let (c, sn) = (0.4f64.cos(), 0.4f64.sin());
        let r = rotate(rotate(s, c, sn), c, -sn);
        for k in 0..4 {
            assert!((r[k] - s[k]).abs() < 1e-14);
        }
        let r = rotate(s, 0.0, 1.0);
        assert!((r[1] + 0.3).abs() < 1e-14 && (r[2] - 0.2).abs() < 1e-14);
    }

    /// Meridian axes are unit, perpendicular to w, in the vertical plane, pointing to larger θ.
    #[test]
    fn meridian_frame() {
        for &(t, p) in &[(0.3, 0.2), (1.2, 4.0), (2.0, 1.0)] {
            let w = direction_from_angles(t, p);
            let e = meridian_axis(w, p);
            let w2 = direction_from_angles(t + 1e-6, p);
            let de = (w2 - w).normalize();
            assert!((e - de).length() < 1e-5, "{e} vs {de}");
            assert!(e.dot(w).abs() < 1e-12);
        }
        // Zenith: the hint's azimuth, horizontal.
        let e = meridian_axis(DVec3::Z, 90f64.to_radians());
        assert!((e - DVec3::X).length() < 1e-12);
    }

    /// Rayleigh single scattering of unpolarized light at 90° is fully polarized perpendicular to
    /// the scattering plane: in the (l, r) frame, Q = −I.
    #[test]
    fn rayleigh_at_90_degrees() {
        let f = PhaseMatrix {
            a1: 0.75,
            b1: -0.75,
            a2: 0.75,
            a3: 0.0,
            b2: 0.0,
            a4: 0.0,
        };
        let d = DVec3::new(0.0, 0.0, -1.0);
        let (s, l2) = scatter([1.0, 0.0, 0.0, 0.0], d, DVec3::X, DVec3::Y, &f);
        assert!((s[0] - 0.75).abs() < 1e-15 && (s[1] + 0.75).abs() < 1e-15);
        // l' lies in the scattering plane (the y–z plane) and is perpendicular to d'.
        assert!(l2.dot(DVec3::X).abs() < 1e-12 && l2.dot(DVec3::Y).abs() < 1e-12);
    }
}
