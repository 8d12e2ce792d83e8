//! Allowed ranges of BRDF parameters: [`Range`] (an interval, each end open or closed) and
//! [`ParamRange`] (one row of the table [`crate::BRDF_PARAM_RANGES`], which lives beside the
//! model specs in `spec.rs` with its lookups `param_range` and `check_param`).

use std::fmt;

/// An interval of allowed values; each end closed or open.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Range {
    pub lo: f64,
    pub hi: f64,
    /// `lo` itself is excluded.
    pub lo_open: bool,
    /// `hi` itself is excluded.
    pub hi_open: bool,
}

impl Range {
    /// `[lo, hi]`.
    pub const fn closed(lo: f64, hi: f64) -> Self {
        Range {
            lo,
            hi,
            lo_open: false,
            hi_open: false,
        }
    }
    /// `[lo, hi)`.
    pub const fn closed_open(lo: f64, hi: f64) -> Self {
        Range {
            lo,
            hi,
            lo_open: false,
            hi_open: true,
        }
    }
    /// `(lo, hi]`.
    pub const fn open_closed(lo: f64, hi: f64) -> Self {
        Range {
            lo,
            hi,
            lo_open: true,
            hi_open: false,
        }
    }
    /// `(lo, hi)`.
    pub const fn open(lo: f64, hi: f64) -> Self {
        Range {
            lo,
            hi,
            lo_open: true,
            hi_open: true,
        }
    }
    /// Whether `v` lies in the range (never for NaN).
    pub fn contains(&self, v: f64) -> bool {
        let lo = if self.lo_open {
            v > self.lo
        } else {
            v >= self.lo
        };
        let hi = if self.hi_open {
            v < self.hi
        } else {
            v <= self.hi
        };
        lo && hi
    }
}

impl fmt::Display for Range {
    /// Interval notation: `[0, 2]`, `(-1, 1)`, `[0, 90)`.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{}{}, {}{}",
            if self.lo_open { '(' } else { '[' },
            self.lo,
            self.hi,
            if self.hi_open { ')' } else { ']' }
        )
    }
}

/// One row of [`BRDF_PARAM_RANGES`](crate::BRDF_PARAM_RANGES).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ParamRange {
    /// The BRDF's `type` tag (`rpv`, …).
    pub brdf: &'static str,
    /// The parameter's key, as written in TOML (`rho_0`, `B_0`, …).
    pub param: &'static str,
    /// Unit ("" for dimensionless).
    pub unit: &'static str,
    pub range: Range,
}

impl ParamRange {
    /// `Err` with the message "`label` = v [unit] must lie in RANGE" when `v` is outside.
    /// `label` is how the caller names the parameter (usually [`ParamRange::param`]).
    pub fn check(&self, label: &str, v: f64) -> Result<(), String> {
        if self.range.contains(v) {
            Ok(())
        } else {
            let unit = if self.unit.is_empty() {
                String::new()
            } else {
                format!(" {}", self.unit)
            };
            Err(format!("`{label}` = {v}{unit} must lie in {}", self.range))
        }
    }
}
