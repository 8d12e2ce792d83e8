//! Solar position from time and place: NREL's Solar Position Algorithm (Reda & Andreas 2004,
//! Solar Energy 76:577–589; accuracy ±0.0003°) through the `solar-positioning` crate.
//!
//! | config key (`[illumination]`) | unit | default | meaning                                   |
//! |-------------------------------|------|---------|-------------------------------------------|
//! | `time`                        | —    | —       | RFC 3339 (`…Z` or `…+hh:mm`), taken in UTC  |
//! | `latitude`, `longitude`       | deg  | —       | WGS84, north and east positive             |
//! | `elevation`                   | m    | 0       | height of the target above sea level       |
//!
//! The topocentric zenith and azimuth (clockwise from North) are geometric: **no atmospheric
//! refraction** is applied, since the transport itself is refraction-free. ΔT = TT − UT is
//! estimated from the date (Espenak & Meeus polynomials, in the crate). The Earth–Sun distance
//! (AU) from the same computation scales the 1 AU irradiance by `1/r²`.

use chrono::{DateTime, Datelike, SecondsFormat, Timelike, Utc};
use solar_positioning::time::JulianDate;
use solar_positioning::{Location, SolarPositions};

use super::EphemerisError;

#[derive(Clone, Copy, Debug)]
pub struct SunPosition {
    /// Topocentric zenith angle, degrees (0–180).
    pub zenith: f64,
    /// Azimuth, degrees clockwise from North.
    pub azimuth: f64,
    /// Earth–Sun distance, AU.
    pub distance_au: f64,
}

/// Parse an RFC 3339 time (`2026-06-15T09:45:00Z`, `2026-06-15T11:45:00.5+02:00`; a space or
/// a lower-case `t` may separate date and time) into UTC. The offset is required: a time without
/// one is ambiguous.
pub fn parse_time(t: &str) -> Result<DateTime<Utc>, EphemerisError> {
    DateTime::parse_from_rfc3339(t.trim())
        .map(|d| d.with_timezone(&Utc))
        .map_err(|source| EphemerisError::BadTime {
            value: t.to_string(),
            source,
        })
}

/// The canonical UTC form of a time: `YYYY-MM-DDTHH:MM:SS[.f]Z`.
pub fn format_utc(t: &DateTime<Utc>) -> String {
    t.to_rfc3339_opts(SecondsFormat::AutoSi, true)
}

/// Seconds since 1970-01-01T00:00:00Z (the netCDF time coordinate of `pics.nc`).
pub fn unix_seconds(t: &DateTime<Utc>) -> f64 {
    t.timestamp() as f64 + f64::from(t.timestamp_subsec_nanos()) * 1e-9
}

/// (y, m, d, h, mi, s) of an RFC 3339 time, in UTC.
fn parse_utc(t: &str) -> Result<(i32, u32, u32, u32, u32, f64), EphemerisError> {
    let u = parse_time(t)?;
    // A leap second is held by chrono as nanoseconds ≥ 1e9 of second 59.
    let s = f64::from(u.second()) + f64::from(u.nanosecond()) * 1e-9;
    Ok((u.year(), u.month(), u.day(), u.hour(), u.minute(), s))
}

/// Sun position for a UTC time and a place; `delta_t` (s) overrides the estimate when given.
pub fn sun_position(
    time: &str,
    latitude: f64,
    longitude: f64,
    elevation: f64,
    delta_t: Option<f64>,
) -> Result<SunPosition, EphemerisError> {
    let (y, mo, d, h, mi, s) = parse_utc(time)?;
    if !(-90.0..=90.0).contains(&latitude) || !(-180.0..=180.0).contains(&longitude) {
        return Err(EphemerisError::PlaceOutOfRange {
            latitude,
            longitude,
        });
    }
    let spa_time = |source| EphemerisError::SpaTime {
        time: time.to_string(),
        source,
    };
    let dt = match delta_t {
        Some(v) => v,
        None => solar_positioning::delta_t::estimate(y as f64 + (mo as f64 - 0.5) / 12.0).map_err(
            |source| EphemerisError::DeltaT {
                time: time.to_string(),
                source,
            },
        )?,
    };
    let jd = JulianDate::from_utc(y, mo, d, h, mi, s, dt).map_err(spa_time)?;
    let prepared = SolarPositions::new()
        .for_time_from_julian(jd)
        .map_err(spa_time)?;
    let p = prepared
        .at(
            Location {
                latitude,
                longitude,
            },
            elevation,
            None,
        )
        .map_err(|source| EphemerisError::SpaPlace {
            latitude,
            longitude,
            elevation,
            source,
        })?;
    let r = prepared
        .earth_radius_vector()
        .ok_or_else(|| EphemerisError::NoSunDistance {
            time: time.to_string(),
        })?;
    Ok(SunPosition {
        zenith: p.zenith_angle(),
        azimuth: p.azimuth(),
        distance_au: r,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The SPA paper's example (Reda & Andreas 2004, table A5.1): 2003-10-17 12:30:30 local
    /// (UTC−7), 39.742476 N, 105.1786 W, 1830.14 m, ΔT = 67 s: topocentric zenith 50.11162°
    /// *with* refraction (820 hPa, 11 °C), azimuth 194.34024°, r = 0.9965422974 AU. Our angles
    /// are geometric, so the zenith is compared after adding the paper's refraction correction
    /// (0.016332°, from its e − e0 at that elevation): 50.12795°. Tolerance 0.0005°.
    #[test]
    fn spa_reference_case() {
        let p = sun_position(
            "2003-10-17T19:30:30Z",
            39.742476,
            -105.1786,
            1830.14,
            Some(67.0),
        )
        .unwrap();
        assert!(
            (p.azimuth - 194.34024).abs() < 5e-4,
            "azimuth {}",
            p.azimuth
        );
        assert!((p.zenith - 50.12795).abs() < 5e-4, "zenith {}", p.zenith);
        assert!(
            (p.distance_au - 0.9965422974).abs() < 1e-9,
            "r {}",
            p.distance_au
        );
        assert!(sun_position("2003-10-17 19:30:30", 0.0, 0.0, 0.0, None).is_err());
        assert!(sun_position("2003-10-17T19:30:30Z", 95.0, 0.0, 0.0, None).is_err());
    }

    /// The same SPA case given in the paper's local time (UTC−7): an RFC 3339 offset is the same
    /// instant, so the same Sun; a time without an offset, or with a bad one, is refused.
    #[test]
    fn offsets_are_converted_to_utc() {
        let utc = sun_position("2003-10-17T19:30:30Z", 39.742476, -105.1786, 1830.14, None);
        let local = sun_position(
            "2003-10-17T12:30:30-07:00",
            39.742476,
            -105.1786,
            1830.14,
            None,
        );
        let (a, b) = (utc.unwrap(), local.unwrap());
        assert_eq!(
            (a.zenith, a.azimuth, a.distance_au),
            (b.zenith, b.azimuth, b.distance_au)
        );
        let t = parse_time("2026-01-15t11:45:00.25+02:00").unwrap();
        assert_eq!(format_utc(&t), "2026-01-15T09:45:00.250Z");
        assert_eq!(unix_seconds(&t), 1_768_470_300.25);
        for bad in [
            "2026-01-15T09:45:00",
            "2026-01-15T09:45:00+25:00",
            "2026-13-15T09:45:00Z",
        ] {
            assert!(parse_time(bad).is_err(), "{bad}");
        }
    }
}
