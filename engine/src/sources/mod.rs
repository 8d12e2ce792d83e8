//! Light sources and their ephemerides: the Sun's direction, distance and irradiance
//! (`illumination.rs`; `sun_position.rs`: the solar position for a time and place), the Moon
//! (`moon.rs`) and Planck's law of thermal emission (`planck.rs`). Solar spectra are spectral
//! data (`spectral/solar.rs`).

pub mod illumination;
pub mod moon;
pub mod planck;
pub mod sun_position;
