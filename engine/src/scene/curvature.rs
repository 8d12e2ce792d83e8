//! Earth curvature for 3D scenes under spherical-shell atmospheres: the scene is *bent* onto the
//! planet once, when it is built, so that rays stay straight lines in one planet-centred frame.
//!
//! | parameter | unit | meaning                                                        |
//! |-----------|------|----------------------------------------------------------------|
//! | `radius`  | m    | planet radius R (the sphere of altitude 0)                     |
//!
//! Frames: a scene point is given in its local frame (x east, y north, z = altitude above the
//! sphere of radius R, m). The spherical-shell walk works in planet-centred coordinates with the
//! local origin's vertical as the z axis (`atmosphere::spherical`): the point of altitude `z`
//! above local (x, y) is
//!
//! ```text
//! P = (x, y, √((R + z)² − x² − y²)),        |P| = R + z exactly,
//! ```
//!
//! i.e. local (x, y) are the orthographic coordinates of the point on the tangent plane at the
//! origin (they differ from distances along the ground by r³/(6R²): 4 mm at r = 10 km, 0.5 m at
//! 70 km). The *bent* scene frame is the planet frame shifted by R along z, `s = P − (0, 0, R)`,
//! so that s = (x, y, z − sag) with `sag = z + R − √((R + z)² − r²) ≈ r²/(2R)` (7.8 m at 10 km,
//! 0.4 km at 70 km). Terrain vertices and instance positions are moved exactly; inside a triangle
//! of edge e the bent surface is the chord of the sphere, at most e²/(8R) below it (0.2 mm for
//! e = 100 m). The flat ground plane of a bundle becomes the sphere of radius R + altitude
//! around (0, 0, −R) in the bent frame. Instances are translated, not rotated: their vertical
//! axis stays the origin's, tilted from the local vertical by r/R (0.09° at 10 km).
//!
//! Reference: any text on map projections (orthographic projection), e.g. Snyder (1987),
//! "Map projections — a working manual", USGS PP 1395, ch. 20.

use glam::DVec3;

/// The bending of a scene onto a sphere of radius `radius` (m).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Curvature {
    pub radius: f64,
}

impl Curvature {
    /// Bent-frame z of the point of altitude `z` above local (x, y): `√((R + z)² − r²) − R`,
    /// computed without cancellation. Beyond the horizon of the tangent plane (r ≥ R + z) there
    /// is no such point; the result is then the sphere's equator height (−R), never NaN.
    #[inline]
    pub fn bent_z(&self, x: f64, y: f64, z: f64) -> f64 {
        let r = self.radius;
        let rr = x * x + y * y;
        let a = (r + z) * (r + z) - rr;
        if a <= 0.0 {
            return -r;
        }
        // √a − R = (a − R²)/(√a + R), a − R² = 2Rz + z² − r².
        (2.0 * r * z + z * z - rr) / (a.sqrt() + r)
    }

    /// The bent position of local point `p` (altitude in z).
    #[inline]
    pub fn bend(&self, p: DVec3) -> DVec3 {
        DVec3::new(p.x, p.y, self.bent_z(p.x, p.y, p.z))
    }

    /// Altitude above the sphere of a bent-frame point.
    #[inline]
    pub fn altitude(&self, s: DVec3) -> f64 {
        (s + DVec3::new(0.0, 0.0, self.radius)).length() - self.radius
    }

    /// Closest intersection `t ∈ (0, tmax)` of the ray `o + t·d` (bent frame, `d` unit) with the
    /// sphere of altitude `h`, and whether the ray arrives from outside.
    pub fn intersect_sphere(&self, o: DVec3, d: DVec3, h: f64, tmax: f64) -> Option<(f64, bool)> {
        let c = DVec3::new(0.0, 0.0, -self.radius);
        let oc = o - c;
        let rs = self.radius + h;
        let b = oc.dot(d);
        // |oc|² − rs² = (|oc| − rs)(|oc| + rs): no cancellation near the surface.
        let len = oc.length();
        let cc = (len - rs) * (len + rs);
        let disc = b * b - cc;
        if disc < 0.0 {
            return None;
        }
        let sq = disc.sqrt();
        // Stable roots: q = −b − sign(b)·√disc; t1 = q, t2 = cc/q.
        let q = if b > 0.0 { -b - sq } else { -b + sq };
        let (mut t1, mut t2) = (q, if q != 0.0 { cc / q } else { q });
        if t1 > t2 {
            std::mem::swap(&mut t1, &mut t2);
        }
        let outside = cc > 0.0;
        for t in [t1, t2] {
            if t > 0.0 && t < tmax {
                return Some((t, outside));
            }
        }
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const R: f64 = 6_378_100.0;

    /// Bent points lie exactly at their altitude above the sphere; the sag is r²/(2R) to first
    /// order.
    #[test]
    fn bending_keeps_altitudes() {
        let c = Curvature { radius: R };
        for &(x, y, z) in &[
            (0.0, 0.0, 0.0),
            (10_000.0, 0.0, 150.0),
            (-7_000.0, 7_000.0, 1_200.0),
            (70_000.0, 10.0, 3.0),
        ] {
            let s = c.bend(DVec3::new(x, y, z));
            assert!((c.altitude(s) - z).abs() < 1e-8, "{x} {y} {z}");
            let sag = z - s.z;
            let approx = (x * x + y * y) / (2.0 * R);
            assert!(
                (sag - approx).abs() < 1e-3 * approx.max(1e-3),
                "{sag} {approx}"
            );
        }
        assert_eq!(c.bent_z(2.0 * R, 0.0, 0.0), -R);
    }

    /// Ray–sphere hits: from above straight down, grazing misses, from inside going up, and a
    /// slant hit lands on the sphere.
    #[test]
    fn sphere_hits() {
        let c = Curvature { radius: R };
        let (t, out) = c
            .intersect_sphere(DVec3::new(0.0, 0.0, 100.0), -DVec3::Z, 10.0, f64::INFINITY)
            .unwrap();
        assert!((t - 90.0).abs() < 1e-9 && out);
        assert!(c
            .intersect_sphere(DVec3::new(0.0, 0.0, 100.0), DVec3::X, 10.0, f64::INFINITY)
            .is_none());
        assert!(c
            .intersect_sphere(DVec3::new(0.0, 0.0, 100.0), -DVec3::Z, 10.0, 50.0)
            .is_none());
        let (t, out) = c
            .intersect_sphere(DVec3::new(0.0, 0.0, 5.0), DVec3::Z, 10.0, f64::INFINITY)
            .unwrap();
        assert!((t - 5.0).abs() < 1e-9 && !out);
        let d = DVec3::new(0.6, 0.0, -0.8);
        let o = DVec3::new(-5_000.0, 0.0, 3_000.0);
        let (t, _) = c.intersect_sphere(o, d, 0.0, f64::INFINITY).unwrap();
        assert!(c.altitude(o + d * t).abs() < 1e-6);
    }
}
