//! Errors of the phase-function models: a parameter out of range (Rayleigh, Henyey–Greenstein),
//! bad mixture weights, and a table that cannot be a phase function (angles, values, span).
//! Reading a libRadtran file has its own error, [`super::tabulated::PhaseTableError`], which
//! names the file and wraps these. The messages are those users and tests match.

/// What is wrong with the parameters or the table of a phase function.
#[derive(Debug, thiserror::Error)]
pub enum PhaseError {
    /// A parameter outside its range (`range` in interval notation, e.g. `(-1, 1)`).
    #[error("`{param}` = {value} must lie in {range}")]
    OutOfRange {
        /// The model (`rayleigh`, `hg`).
        model: &'static str,
        param: &'static str,
        value: f64,
        range: &'static str,
    },
    /// Mixture weight number `index` (from 0) negative or not finite.
    #[error("mixture weight {index} is {weight}; it must be finite and ≥ 0")]
    MixtureWeight { index: usize, weight: f64 },
    /// Mixture weights that add up to zero (or to nothing).
    #[error("mixture weights are all zero")]
    MixtureZero,
    /// A table with angles and values of different lengths, or fewer than two of them.
    #[error("need at least two (theta, phase) pairs of equal length")]
    TooFewPairs { angles: usize, values: usize },
    /// A scattering angle (degrees) outside [0, 180] or not a number.
    #[error("scattering angle {theta} outside [0, 180] degrees")]
    Angle { theta: f64 },
    /// A phase value negative or not finite at `theta` degrees.
    #[error("phase value {value} at {theta} degrees is negative or not finite")]
    Value { theta: f64, value: f64 },
    /// A table that does not reach both 0 and 180 degrees (`first`, `last`: its ends).
    #[error("the table must span 0 to 180 degrees (it spans {first} to {last})")]
    Span { first: f64, last: f64 },
    /// Phase-matrix element `element` (2 = b1, …, 6 = a4 in the table's order) with angles and
    /// values of different lengths, or fewer than two of them.
    #[error("phase-matrix element {element} needs at least two (theta, value) pairs")]
    ElementTooFewPairs { element: usize },
    /// Phase-matrix element `element` with a non-finite angle or value.
    #[error("phase-matrix element {element} has non-finite values")]
    ElementNotFinite { element: usize },
    /// A table whose integral over cos Θ is zero or not a number.
    #[error("phase function integrates to zero")]
    ZeroIntegral,
}
