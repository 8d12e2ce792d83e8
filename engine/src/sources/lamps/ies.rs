//! IES LM-63 photometric files (`profile = { type = "ies", file = "…" }`): the candela
//! distribution of a luminaire.
//!
//! Read: the `IESNA:LM-63-1995/2002/2019` header lines (keywords are skipped), `TILT=NONE`
//! (other tilts are refused: they describe lamp-position corrections this reader does not
//! apply), then the numbers: lamp count, lumens per lamp, candela multiplier, the counts of
//! vertical and horizontal angles, the photometric type (only **type C**, 1, the one of road
//! and area luminaires), units, three dimensions, ballast factor, a reserved value, input
//! watts, the vertical angles (increasing, from 0 or 90 to 90 or 180), the horizontal angles
//! (increasing from 0), and the candela values (for each horizontal angle, one per vertical
//! angle). Values are candela × multiplier × ballast factor.
//!
//! Type C angles: the vertical angle γ from the luminaire's photometric nadir (0 = straight
//! down), the horizontal angle C counter-clockwise seen from above from the luminaire's first
//! axis. The horizontal range says the symmetry: one angle (0) — the same in every plane; last
//! 90° — quadrant symmetric; last 180° — symmetric about the 0–180° plane; up to 360° — none.
//! Between angles the intensity is bilinear; beyond the last vertical angle it is 0.
//!
//! Reference: IES LM-63-02, *Standard File Format for the Electronic Transfer of Photometric
//! Data* (Illuminating Engineering Society, 2002).

use std::path::Path;

/// A type C candela table.
#[derive(Clone, Debug, PartialEq)]
pub struct Photometry {
    /// Vertical angles γ, degrees, increasing.
    pub vertical: Vec<f64>,
    /// Horizontal angles C, degrees, increasing from 0.
    pub horizontal: Vec<f64>,
    /// cd, `[ih][iv]`.
    pub candela: Vec<Vec<f64>>,
}

/// Why an IES file cannot be used (the message names what).
pub type IesError = String;

impl Photometry {
    /// Read an LM-63 file.
    pub fn read(path: &Path) -> Result<Self, IesError> {
        let text =
            std::fs::read(path).map_err(|e| format!("cannot read {}: {e}", path.display()))?;
        // Files are ASCII in practice; other bytes are tolerated in keyword lines.
        let text = String::from_utf8_lossy(&text);
        Self::parse(&text).map_err(|e| format!("{}: {e}", path.display()))
    }

    /// Parse the text of an LM-63 file.
    pub fn parse(text: &str) -> Result<Self, IesError> {
        let mut lines = text.lines();
        let mut tilt = None;
        for line in lines.by_ref() {
            let l = line.trim().trim_start_matches('\u{feff}');
            if let Some(t) = l.strip_prefix("TILT=") {
                tilt = Some(t.trim().to_string());
                break;
            }
        }
        match tilt.as_deref() {
            None => return Err("no TILT= line: not an IES LM-63 file".into()),
            Some("NONE") => {}
            Some(t) => {
                return Err(format!(
                    "TILT={t}: tilted lamp data are not supported (TILT=NONE only)"
                ))
            }
        }
        let nums: Vec<f64> = lines
            .flat_map(|l| l.split(|c: char| c.is_whitespace() || c == ','))
            .filter(|s| !s.is_empty())
            .map(|s| {
                s.parse::<f64>()
                    .map_err(|_| format!("\"{s}\" is not a number in the photometric data"))
            })
            .collect::<Result<_, _>>()?;
        if nums.len() < 13 {
            return Err("the photometric data end before the angle counts".into());
        }
        let count = |v: f64, what: &str| {
            if (1.0..=10_000.0).contains(&v) && v.fract() == 0.0 {
                Ok(v as usize)
            } else {
                Err(format!("{what} = {v} must be a whole number in 1..=10000"))
            }
        };
        let multiplier = nums[2];
        let nv = count(nums[3], "the number of vertical angles")?;
        let nh = count(nums[4], "the number of horizontal angles")?;
        if nums[5] != 1.0 {
            return Err(format!(
                "photometric type {} is not supported (type C, 1, only)",
                nums[5]
            ));
        }
        let ballast = nums[10];
        let factor = multiplier * ballast;
        if !(factor.is_finite() && factor > 0.0) {
            return Err(format!(
                "candela multiplier × ballast factor = {factor} must be positive"
            ));
        }
        let need = 13 + nv + nh + nv * nh;
        if nums.len() < need {
            return Err(format!(
                "{} numbers after TILT=NONE, {need} expected for {nv} vertical × {nh} horizontal angles",
                nums.len()
            ));
        }
        let vertical = nums[13..13 + nv].to_vec();
        let horizontal = nums[13 + nv..13 + nv + nh].to_vec();
        let increasing = |v: &[f64]| v.windows(2).all(|w| w[1] > w[0]);
        if !increasing(&vertical) || vertical[0] < 0.0 || vertical[nv - 1] > 180.0 {
            return Err("vertical angles must increase within [0, 180]".into());
        }
        if !increasing(&horizontal) || horizontal[0] != 0.0 || horizontal[nh - 1] > 360.0 {
            return Err("horizontal angles must increase from 0 to at most 360".into());
        }
        let mut candela = Vec::with_capacity(nh);
        for ih in 0..nh {
            let row: Vec<f64> = nums[13 + nv + nh + ih * nv..13 + nv + nh + (ih + 1) * nv]
                .iter()
                .map(|c| c * factor)
                .collect();
            if let Some(c) = row.iter().find(|c| !(c.is_finite() && **c >= 0.0)) {
                return Err(format!(
                    "candela value {c} at horizontal angle {} must be finite and ≥ 0",
                    horizontal[ih]
                ));
            }
            candela.push(row);
        }
        if candela.iter().flatten().all(|c| *c == 0.0) {
            return Err("every candela value is 0".into());
        }
        Ok(Photometry {
            vertical,
            horizontal,
            candela,
        })
    }

    /// The largest candela value.
    pub fn max(&self) -> f64 {
        self.candela.iter().flatten().fold(0.0, |a, &c| a.max(c))
    }

    /// Candela at vertical angle `gamma` and horizontal angle `c` (degrees).
    pub fn at(&self, gamma: f64, c: f64) -> f64 {
        let last = *self.horizontal.last().unwrap_or(&0.0);
        let c = c.rem_euclid(360.0);
        // Fold C into the table's range by its symmetry.
        let c = if self.horizontal.len() == 1 {
            0.0
        } else if last <= 90.0 {
            let q = c % 180.0;
            let q = if q > 90.0 { 180.0 - q } else { q };
            q.min(last)
        } else if last <= 180.0 {
            let q = if c > 180.0 { 360.0 - c } else { c };
            q.min(last)
        } else {
            c.min(last)
        };
        let (ih, fh) = bracket(&self.horizontal, c);
        let (iv, fv) = match self.vertical.first() {
            Some(&v0) if gamma < v0 => return 0.0,
            _ => {
                if gamma > *self.vertical.last().unwrap_or(&0.0) {
                    return 0.0;
                }
                bracket(&self.vertical, gamma)
            }
        };
        let row = |i: usize| {
            let r = &self.candela[i];
            r[iv] * (1.0 - fv) + r[(iv + 1).min(r.len() - 1)] * fv
        };
        row(ih) * (1.0 - fh) + row((ih + 1).min(self.candela.len() - 1)) * fh
    }

    /// `∫ I dΩ` over the sphere (cd·sr = lm), by the midpoint rule.
    pub fn flux(&self) -> f64 {
        let (nt, np) = (360, 144);
        let mut s = 0.0;
        for i in 0..nt {
            let g = (i as f64 + 0.5) * 180.0 / nt as f64;
            let w = g.to_radians().sin() * std::f64::consts::PI / nt as f64;
            for j in 0..np {
                s += self.at(g, (j as f64 + 0.5) * 360.0 / np as f64) * w;
            }
        }
        s * 2.0 * std::f64::consts::PI / np as f64
    }
}

/// Index `i` and fraction `f` with `x` between `v[i]` and `v[i + 1]` (clamped at the ends).
fn bracket(v: &[f64], x: f64) -> (usize, f64) {
    if v.len() < 2 || x <= v[0] {
        return (0, 0.0);
    }
    let i = v.partition_point(|&a| a <= x).saturating_sub(1);
    if i + 1 >= v.len() {
        return (v.len() - 1, 0.0);
    }
    (i, (x - v[i]) / (v[i + 1] - v[i]))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A rotationally symmetric file (one horizontal angle): I(γ) = 1000·cos γ below the
    /// horizon, written as an LM-63-2002 file with keywords, a multiplier and a ballast factor.
    const COSINE: &str = "IESNA:LM-63-2002\n[TEST] cosine\n[MANUFAC] none\nTILT=NONE\n\
        1 -1 2.0 7 1 1 2 0.0 0.0 0.0\n0.5 1.0 100\n\
        0 15 30 45 60 75 90\n0\n\
        1000 965.926 866.025 707.107 500 258.819 0\n";

    #[test]
    fn reads_and_interpolates_a_type_c_file() {
        let p = Photometry::parse(COSINE).unwrap();
        // multiplier 2 × ballast 0.5.
        assert_eq!(p.at(0.0, 0.0), 1000.0);
        assert!((p.at(60.0, 123.0) - 500.0).abs() < 1e-9);
        assert!((p.at(52.5, 0.0) - 603.5535).abs() < 1e-3);
        assert_eq!(p.at(120.0, 0.0), 0.0);
        // Flux of I0 cos γ over the lower hemisphere: π·I0 (the table's linear interpolation
        // between 15° nodes is within 1 %).
        assert!((p.flux() / (std::f64::consts::PI * 1000.0) - 1.0).abs() < 0.01);
    }

    #[test]
    fn symmetries_of_the_horizontal_angles() {
        // Bilateral (0–180°): C = 270° is C = 90°.
        let t = "TILT=NONE\n1 -1 1 2 3 1 2 0 0 0\n1 1 0\n0 90\n0 90 180\n10 5 20 8 30 9\n";
        let p = Photometry::parse(t).unwrap();
        assert_eq!(p.at(90.0, 270.0), p.at(90.0, 90.0));
        assert_eq!(p.at(0.0, 45.0), 15.0);
        // Quadrant (0–90°): C = 135° is 45°, C = 300° is 60°.
        let q = "TILT=NONE\n1 -1 1 1 2 1 2 0 0 0\n1 1 0\n0\n0 90\n10 20\n";
        let p = Photometry::parse(q).unwrap();
        assert_eq!(p.at(0.0, 135.0), p.at(0.0, 45.0));
        assert!((p.at(0.0, 300.0) - p.at(0.0, 60.0)).abs() < 1e-12);
    }

    #[test]
    fn bad_files_are_refused_naming_why() {
        for (text, says) in [
            ("no tilt here", "TILT"),
            ("TILT=INCLUDE\n", "TILT=INCLUDE"),
            (
                "TILT=NONE\n1 -1 1 2 1 2 2 0 0 0\n1 1 0\n0 90\n0\n1 1\n",
                "type",
            ),
            (
                "TILT=NONE\n1 -1 1 2 1 1 2 0 0 0\n1 1 0\n0 90\n0\n1\n",
                "expected",
            ),
            (
                "TILT=NONE\n1 -1 1 2 1 1 2 0 0 0\n1 1 0\n90 0\n0\n1 1\n",
                "increase",
            ),
            (
                "TILT=NONE\n1 -1 1 2 1 1 2 0 0 0\n1 1 0\n0 90\n0\n1 x\n",
                "not a number",
            ),
            (
                "TILT=NONE\n1 -1 1 2 1 1 2 0 0 0\n1 1 0\n0 90\n0\n1 -3\n",
                "≥ 0",
            ),
            (
                "TILT=NONE\n1 -1 1 2 1 1 2 0 0 0\n1 1 0\n0 90\n0\n0 0\n",
                "every candela",
            ),
        ] {
            let e = Photometry::parse(text).unwrap_err();
            assert!(e.contains(says), "{text:?}: {e}");
        }
    }
}
