//! Light sources and their ephemerides: the Sun's direction, distance and irradiance
//! (`lamps/`: point and spot lights placed in the scene),
//! (`illumination.rs`; `sun_position.rs`: the solar position for a time and place), the Moon
//! (`moon.rs`) and Planck's law of thermal emission (`planck.rs`). Solar spectra are spectral
//! data (`spectral/solar.rs`).

pub mod illumination;
pub mod lamps;
pub mod moon;
pub mod planck;
pub mod sun_position;

/// Why the position of the Sun or the Moon at a time and place (`sun_position.rs`, `moon.rs`)
/// cannot be computed.
#[derive(Debug, thiserror::Error)]
pub enum EphemerisError {
    #[error(
        "\"{value}\" is not an RFC 3339 time such as 2026-06-15T09:45:00Z or \
         2026-06-15T11:45:00+02:00 ({source})"
    )]
    BadTime {
        value: String,
        source: chrono::ParseError,
    },
    /// The Sun's position (NREL SPA's own ranges).
    #[error("latitude {latitude} / longitude {longitude} out of range")]
    PlaceOutOfRange { latitude: f64, longitude: f64 },
    /// ΔT cannot be estimated for the date.
    #[error("{source}")]
    DeltaT {
        time: String,
        source: solar_positioning::Error,
    },
    /// The SPA refuses the time.
    #[error("\"{time}\": {source}")]
    SpaTime {
        time: String,
        source: solar_positioning::Error,
    },
    /// The SPA refuses the place.
    #[error("{source}")]
    SpaPlace {
        latitude: f64,
        longitude: f64,
        elevation: f64,
        source: solar_positioning::Error,
    },
    #[error("the SPA model gives no Earth–Sun distance")]
    NoSunDistance { time: String },
    #[error("latitude {latitude} must lie in [-90, 90]")]
    MoonLatitude { latitude: f64 },
    #[error("longitude {longitude} must lie in [-180, 360]")]
    MoonLongitude { longitude: f64 },
    #[error("{time}: the lunar series and ΔT are used between 1900 and 2100")]
    OutsideLunarSeries { time: String },
    /// The lunar magnitude law does not hold at this phase angle (degrees).
    #[error(
        "the Moon's phase angle is {phase_angle:.1}° (a {:.0} % lit crescent); the lunar magnitude law holds up to {}°: give `irradiance` (a lunar spectrum)",
        100.0 * (1.0 + .phase_angle.to_radians().cos()) / 2.0,
        moon::MAX_PHASE_ANGLE
    )]
    PhaseAngle { phase_angle: f64 },
}
