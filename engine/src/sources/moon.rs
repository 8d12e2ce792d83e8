//! The Moon as a light source: its topocentric direction for a time and place, and its
//! irradiance at the top of the atmosphere with its phase dependence.
//!
//! | config key (`[illumination] type = "moon"`) | unit | default | meaning |
//! |---|---|---|---|
//! | `time` | — | required | RFC 3339 (any offset, taken in UTC) |
//! | `latitude`, `longitude` | deg | required | WGS84, north and east positive |
//! | `elevation` | m | 0 | height of the target above the ellipsoid |
//! | `irradiance` | W m⁻² nm⁻¹ | the model below | a lunar irradiance spectrum normal to the beam (number, list, built-in name or CSV file), used as given |
//! | `solar_spectrum` | — | `"thuillier_2003"` | the solar spectrum the model scales |
//!
//! **Position.** Geocentric ecliptic longitude, latitude and distance of the Moon from the
//! `astro` crate (the truncated ELP-2000/82 series of Meeus, *Astronomical Algorithms*, 2nd ed.,
//! ch. 47: 10″ in longitude, 4″ in latitude), and of the Sun (ch. 25), at the ephemeris time
//! (TT = UT + ΔT, ΔT from the NASA polynomials). Apparent longitude adds the nutation in
//! longitude; ecliptic → equatorial with the true obliquity; equatorial → Earth-fixed by the
//! Greenwich apparent sidereal time (ch. 12); then the **topocentric** vector from the observer
//! (WGS84 geodetic → Earth-centred, Earth-fixed) to the Moon, in the observer's East–North–Up
//! frame: zenith angle and azimuth clockwise from North. The lunar parallax (up to 1°) is
//! therefore exact; no refraction (the transport is refraction-free); no light-time
//! correction (1.3 s of lunar motion, 0.6″). The same chain applied to the Sun agrees with
//! NREL's SPA (`sun_position.rs`) to 0.01° (`tests::sun_through_the_same_chain_matches_spa`).
//!
//! **Irradiance** (when `irradiance` is not given), a grey Moon:
//! `E_moon(λ) = E_sun(λ; 1 AU)·10^(−0.4·(m(α) − m_sun))·(d̄/d)²·(1 AU/r)²`, with
//! `m(α) = −12.73 + 0.026|α| + 4·10⁻⁹ α⁴` the Moon's V magnitude at its mean distance
//! `d̄ = 384 400 km` as a function of the phase angle α in degrees (Allen 1976, *Astrophysical
//! Quantities*, as used by Krisciunas & Schaefer 1991, *PASP* 103, 1033, eq. 9), `m_sun = −26.74`
//! (the Sun's V magnitude at 1 AU), `d` the observer–Moon distance and `r` the Sun–Moon distance
//! in AU. Full Moon (α = 0) at mean distance: `E_moon/E_sun = 2.49·10⁻⁶`. Limits: the law is
//! fitted to α ≤ 150° (a thinner crescent is refused); the Moon is treated as grey, while its
//! real albedo doubles from 400 to 1000 nm (so blue bands are overestimated and near-infrared
//! ones underestimated by tens of %): give a lunar spectrum (e.g. from ROLO or a lunar
//! irradiance model) as `irradiance` for band-accurate work.

use chrono::{DateTime, Datelike, Utc};
use glam::DVec3;

use super::EphemerisError;

/// Mean Earth–Moon distance, km (the distance of the magnitude law).
pub const MEAN_DISTANCE_KM: f64 = 384_400.0;
/// The Sun's apparent V magnitude at 1 AU.
pub const SUN_V_MAGNITUDE: f64 = -26.74;
/// Largest phase angle of the magnitude law's validity, degrees.
pub const MAX_PHASE_ANGLE: f64 = 150.0;
const AU_KM: f64 = 149_597_870.7;

#[derive(Clone, Copy, Debug)]
pub struct MoonPosition {
    /// Topocentric zenith angle, degrees (0–180).
    pub zenith: f64,
    /// Azimuth, degrees clockwise from North, [0, 360).
    pub azimuth: f64,
    /// Observer–Moon distance, km.
    pub distance_km: f64,
    /// Sun–Moon distance, AU.
    pub sun_distance_au: f64,
    /// Phase angle (Sun–Moon–observer), degrees: 0 at full Moon.
    pub phase_angle: f64,
}

/// Geocentric body position of date in the equatorial frame (km), from apparent ecliptic
/// longitude `lon`, latitude `lat` (radians) and distance `r` (km), for obliquity `eps`.
fn equatorial(lon: f64, lat: f64, r: f64, eps: f64) -> DVec3 {
    let ecl = DVec3::new(lat.cos() * lon.cos(), lat.cos() * lon.sin(), lat.sin()) * r;
    DVec3::new(
        ecl.x,
        ecl.y * eps.cos() - ecl.z * eps.sin(),
        ecl.y * eps.sin() + ecl.z * eps.cos(),
    )
}

/// Observer position in the Earth-fixed frame (km) and its local East, North, Up axes.
fn observer(lat_deg: f64, lon_deg: f64, elevation_m: f64) -> (DVec3, [DVec3; 3]) {
    // WGS84.
    let a = 6378.137;
    let f = 1.0 / 298.257_223_563;
    let e2 = f * (2.0 - f);
    let (phi, lam) = (lat_deg.to_radians(), lon_deg.to_radians());
    let n = a / (1.0 - e2 * phi.sin().powi(2)).sqrt();
    let h = elevation_m / 1e3;
    let p = DVec3::new(
        (n + h) * phi.cos() * lam.cos(),
        (n + h) * phi.cos() * lam.sin(),
        (n * (1.0 - e2) + h) * phi.sin(),
    );
    let east = DVec3::new(-lam.sin(), lam.cos(), 0.0);
    let north = DVec3::new(-phi.sin() * lam.cos(), -phi.sin() * lam.sin(), phi.cos());
    let up = DVec3::new(phi.cos() * lam.cos(), phi.cos() * lam.sin(), phi.sin());
    (p, [east, north, up])
}

/// Julian day (UT) of a UTC time.
fn julian_day(t: &DateTime<Utc>) -> f64 {
    t.timestamp() as f64 / 86_400.0 + f64::from(t.timestamp_subsec_nanos()) / 8.64e13 + 2_440_587.5
}

/// Topocentric (zenith, azimuth in degrees, distance in km) of a body given its geocentric
/// ecliptic coordinates of date (`(longitude, latitude)` radians, mean equinox) and distance
/// (km) at UT Julian day `jd` and ephemeris day `jde`.
fn topocentric(
    ecl: (f64, f64),
    r_km: f64,
    jd: f64,
    jde: f64,
    lat: f64,
    lon: f64,
    elevation: f64,
) -> (f64, f64, f64) {
    let (dpsi, deps) = astro::nutation::nutation(jde);
    let eps = astro::ecliptic::mn_oblq_IAU(jde) + deps;
    let gast = astro::time::apprnt_sidr(astro::time::mn_sidr(jd), dpsi, eps);
    let q = equatorial(ecl.0 + dpsi, ecl.1, r_km, eps);
    // Equatorial of date → Earth-fixed: rotate by −GAST about the pole.
    let (s, c) = gast.sin_cos();
    let fixed = DVec3::new(c * q.x + s * q.y, -s * q.x + c * q.y, q.z);
    let (o, [east, north, up]) = observer(lat, lon, elevation);
    let v = fixed - o;
    let d = v.length();
    let (e, n, u) = (v.dot(east) / d, v.dot(north) / d, v.dot(up) / d);
    let zenith = u.clamp(-1.0, 1.0).acos().to_degrees();
    let azimuth = e.atan2(n).to_degrees().rem_euclid(360.0);
    (zenith, azimuth, d)
}

/// Geocentric ecliptic position of the Sun: ((longitude, latitude) radians, distance km).
fn sun_ecliptic(jde: f64) -> ((f64, f64), f64) {
    let (p, r_au) = astro::sun::geocent_ecl_pos(jde);
    ((p.long, p.lat), r_au * AU_KM)
}

/// ΔT = TT − UT (s) for a time.
fn delta_t(t: &DateTime<Utc>) -> f64 {
    astro::time::delta_t(t.year(), t.month() as u8)
}

/// The Moon's geocentric phase angle (Sun–Moon–Earth, degrees) and Sun–Moon distance (AU) at
/// ephemeris day `jde`; the topocentric shift changes the angle by < 0.02°.
fn phase_angle_at(jde: f64) -> (f64, f64) {
    let (mp, r_moon) = astro::lunar::geocent_ecl_pos(jde);
    let (sp, r_sun) = sun_ecliptic(jde);
    let m = equatorial(mp.long, mp.lat, r_moon, 0.0);
    let s = equatorial(sp.0, sp.1, r_sun, 0.0);
    let moon_to_sun = s - m;
    let a = moon_to_sun
        .normalize()
        .dot((-m).normalize())
        .clamp(-1.0, 1.0)
        .acos()
        .to_degrees();
    (a, moon_to_sun.length() / AU_KM)
}

/// The Moon seen from (`lat`, `lon` degrees, `elevation` m) at `time` (RFC 3339).
pub fn moon_position(
    time: &str,
    lat: f64,
    lon: f64,
    elevation: f64,
) -> Result<MoonPosition, EphemerisError> {
    let t = crate::sources::sun_position::parse_time(time)?;
    if !(-90.0..=90.0).contains(&lat) {
        return Err(EphemerisError::MoonLatitude { latitude: lat });
    }
    if !(-180.0..=360.0).contains(&lon) {
        return Err(EphemerisError::MoonLongitude { longitude: lon });
    }
    if !(1900..=2100).contains(&t.year()) {
        return Err(EphemerisError::OutsideLunarSeries {
            time: time.to_string(),
        });
    }
    let jd = julian_day(&t);
    let jde = jd + delta_t(&t) / 86_400.0;
    let (mp, r_moon) = astro::lunar::geocent_ecl_pos(jde);
    let (zenith, azimuth, distance_km) =
        topocentric((mp.long, mp.lat), r_moon, jd, jde, lat, lon, elevation);
    let (phase_angle, sun_distance_au) = phase_angle_at(jde);
    Ok(MoonPosition {
        zenith,
        azimuth,
        distance_km,
        sun_distance_au,
        phase_angle,
    })
}

/// The lunar irradiance as a fraction of the solar irradiance at 1 AU (the grey magnitude
/// law of the module documentation). Err for phase angles beyond [`MAX_PHASE_ANGLE`].
pub fn irradiance_ratio(p: &MoonPosition) -> Result<f64, EphemerisError> {
    let a = p.phase_angle;
    if a > MAX_PHASE_ANGLE {
        return Err(EphemerisError::PhaseAngle { phase_angle: a });
    }
    let m = -12.73 + 0.026 * a + 4e-9 * a.powi(4);
    Ok(
        10f64.powf(-0.4 * (m - SUN_V_MAGNITUDE)) * (MEAN_DISTANCE_KM / p.distance_km).powi(2)
            / p.sun_distance_au.powi(2),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Meeus, *Astronomical Algorithms*, example 47.a: 1992 April 12, 0h TD: λ = 133.162655°,
    /// β = −3.229126°, Δ = 368 409.7 km; the series the module uses reproduces it.
    #[test]
    fn lunar_series_reproduces_meeus_example_47a() {
        let (p, r) = astro::lunar::geocent_ecl_pos(2_448_724.5);
        assert!(
            (p.long.to_degrees() - 133.162655).abs() < 1e-4,
            "{}",
            p.long.to_degrees()
        );
        assert!(
            (p.lat.to_degrees() + 3.229126).abs() < 1e-4,
            "{}",
            p.lat.to_degrees()
        );
        assert!((r - 368_409.7).abs() < 0.5, "{r}");
        // Obliquity of date (radians) and nutation are of the expected size.
        let eps = astro::ecliptic::mn_oblq_IAU(2_448_724.5).to_degrees();
        assert!((eps - 23.44).abs() < 0.01, "{eps}");
    }

    /// The position chain (nutation, obliquity, sidereal time, Earth-fixed, topocentric ENU)
    /// applied to the Sun agrees with NREL's SPA (an independent implementation) to 0.01°.
    #[test]
    fn sun_through_the_same_chain_matches_spa() {
        for (time, lat, lon) in [
            ("2026-06-21T10:00:00Z", 45.19, 5.72),
            ("2026-01-15T14:30:00Z", 28.55, 23.39),
            ("2025-09-30T04:00:00Z", -33.9, 151.2),
            ("2026-11-26T18:45:00Z", 40.0, -105.0),
        ] {
            let t = crate::sources::sun_position::parse_time(time).unwrap();
            let jd = julian_day(&t);
            let jde = jd + delta_t(&t) / 86_400.0;
            let (ecl, r) = sun_ecliptic(jde);
            // Annual aberration (−20.5″ in longitude), which SPA includes.
            let ecl = (
                ecl.0 - (20.4898 / 3600.0f64).to_radians() / (r / AU_KM),
                ecl.1,
            );
            let (z, a, _) = topocentric(ecl, r, jd, jde, lat, lon, 0.0);
            let spa =
                crate::sources::sun_position::sun_position(time, lat, lon, 0.0, None).unwrap();
            let dz = (z - spa.zenith).abs();
            let da =
                ((a - spa.azimuth + 540.0).rem_euclid(360.0) - 180.0).abs() * z.to_radians().sin();
            assert!(
                dz < 0.01 && da < 0.01,
                "{time}: ({z}, {a}) vs SPA ({}, {})",
                spa.zenith,
                spa.azimuth
            );
        }
    }

    /// The topocentric parallax: the Moon's apparent zenith is larger than the geocentric
    /// one by asin(ρ/Δ · sin z) (Meeus ch. 40), about 0.95° near the horizon.
    #[test]
    fn lunar_parallax_has_the_closed_form_size() {
        let time = "2026-03-03T20:00:00Z";
        let p = moon_position(time, 0.0, 0.0, 0.0).unwrap();
        // Geocentric direction: the same chain for an observer at the Earth's centre is
        // undefined, so take the difference with a point 10⁶ km further out along the
        // observer's vertical (no parallax there to first order).
        let t = crate::sources::sun_position::parse_time(time).unwrap();
        let jd = julian_day(&t);
        let jde = jd + delta_t(&t) / 86_400.0;
        let (mp, r) = astro::lunar::geocent_ecl_pos(jde);
        let (zg, _, _) = topocentric((mp.long, mp.lat), r * 1e6, jd, jde, 0.0, 0.0, 0.0);
        let expected = (6378.137 / r * zg.to_radians().sin()).asin().to_degrees();
        assert!(
            ((p.zenith - zg) - expected).abs() < 0.01,
            "parallax {} vs {expected}",
            p.zenith - zg
        );
    }

    /// Full Moon at mean distance: 10^(−0.4·(−12.73 + 26.74)) = 2.489e-6 of the Sun at 1 AU,
    /// before the distance factors; a quarter Moon (α = 90°) is 2.6 magnitudes fainter.
    #[test]
    fn irradiance_ratio_follows_the_magnitude_law() {
        let full = MoonPosition {
            zenith: 0.0,
            azimuth: 0.0,
            distance_km: MEAN_DISTANCE_KM,
            sun_distance_au: 1.0,
            phase_angle: 0.0,
        };
        let r0 = irradiance_ratio(&full).unwrap();
        assert!((r0 - 2.4889e-6).abs() < 0.0001e-6, "{r0}");
        let quarter = MoonPosition {
            phase_angle: 90.0,
            ..full
        };
        let dm = -2.5 * (irradiance_ratio(&quarter).unwrap() / r0).log10();
        assert!(
            (dm - (0.026 * 90.0 + 4e-9 * 90f64.powi(4))).abs() < 1e-9,
            "{dm}"
        );
        let thin = MoonPosition {
            phase_angle: 160.0,
            ..full
        };
        assert!(irradiance_ratio(&thin)
            .unwrap_err()
            .to_string()
            .contains("irradiance"));
    }

    /// Phase angle: Meeus example 48.a (1992 April 12, 0h TD: i = 69.0756°, k = 0.6786), and
    /// near 0 at the total lunar eclipse of 2026-03-03 (greatest at 11:33 UT).
    #[test]
    fn phase_angle_matches_meeus_and_the_2026_eclipse() {
        let (i, r) = phase_angle_at(2_448_724.5);
        assert!((i - 69.0756).abs() < 0.01, "{i}");
        assert!((r - 1.0).abs() < 0.02, "{r}");
        let k = (1.0 + i.to_radians().cos()) / 2.0;
        assert!((k - 0.6786).abs() < 1e-3, "{k}");
        let full = moon_position("2026-03-03T11:33:00Z", 0.0, 0.0, 0.0).unwrap();
        assert!(full.phase_angle < 1.5, "{}", full.phase_angle);
    }
}
