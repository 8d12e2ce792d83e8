//! Property tests of the text-table readers (issue 43, item 8): spectral response functions,
//! solar spectra, AFGL-style and user atmosphere profiles. Starting from a valid table (an
//! embedded one, cut short so each case is quick), any run of characters replaced by
//! anything (digits, separators, signs, exponents, `nan`, `inf`, a BOM, line breaks, any
//! printable text), any line deleted or doubled, gives either a table or an error whose
//! message is not empty — never a panic. Run in CI with the workspace tests (400 cases each).

use proptest::prelude::*;

use engine::atmosphere::{molecular::Profile, thermo};
use engine::spectral::{solar, srf::Srf};

/// The first `n` lines of an embedded table.
fn head(text: &str, n: usize) -> String {
    text.lines().take(n).collect::<Vec<_>>().join("\n") + "\n"
}

/// A user SRF (`wavelength_nm,response`): OLI's coastal band (its first 30 rows) from the embedded family table.
fn srf_text() -> String {
    let mut out = String::from("wavelength_nm,response\n");
    for line in include_str!("../data/srf/landsat_8-oli.csv")
        .lines()
        .skip(1)
        .take(30)
    {
        let f: Vec<&str> = line.split(',').collect();
        out += &format!("{},{}\n", f[1], f[2]);
    }
    out
}
fn solar_text() -> String {
    head(include_str!("../data/solar/thuillier_2003.csv"), 40)
}
fn afgl_text() -> String {
    head(include_str!("../data/afgl_1986/table_1a.csv"), 30)
}
/// A user profile (docs/experiment.md "profile tables"): the AFGL columns with units.
fn user_text() -> String {
    let mut out = String::from("z_km,p_hpa,t_k,H2O_ppmv,O3_ppmv\n");
    for line in afgl_text().lines().skip(1) {
        let f: Vec<&str> = line.split(',').collect();
        let n: f64 = f[3].parse().unwrap();
        let ppmv = |x: &str| x.parse::<f64>().unwrap() / n * 1e6;
        out += &format!("{},{},{},{},{}\n", f[0], f[1], f[2], ppmv(f[4]), ppmv(f[5]));
    }
    out
}

/// Pieces a damaged table is made of.
fn fill() -> impl Strategy<Value = String> {
    prop_oneof![
        "[0-9.,eE+\\- ]{0,8}",
        Just("nan".to_string()),
        Just("-inf".to_string()),
        Just("1e400".to_string()),
        Just("\u{feff}".to_string()),
        Just("\n".to_string()),
        Just(",,,".to_string()),
        "\\PC{0,8}",
    ]
}

/// Every reader on `text`: a value or an error with a message, never a panic.
fn readers_cope(text: &str) -> Result<(), TestCaseError> {
    let r = std::panic::catch_unwind(|| {
        [
            Srf::from_csv("damaged.csv", text)
                .err()
                .map(|e| e.to_string()),
            solar::Spectrum::from_csv("damaged.csv", text)
                .err()
                .map(|e| e.to_string()),
            Profile::from_csv("damaged.csv", text)
                .err()
                .map(|e| e.to_string()),
            thermo::from_user_csv("damaged.csv", text)
                .err()
                .map(|e| e.to_string()),
        ]
    });
    match r {
        Err(_) => Err(TestCaseError::fail("a table reader panicked")),
        Ok(errors) => {
            for e in errors.into_iter().flatten() {
                prop_assert!(!e.trim().is_empty(), "an empty error message");
            }
            Ok(())
        }
    }
}

fn base(k: usize) -> String {
    match k % 4 {
        0 => srf_text(),
        1 => solar_text(),
        2 => afgl_text(),
        _ => user_text(),
    }
}

fn replace(text: &str, at: usize, len: usize, with: &str) -> String {
    let chars: Vec<char> = text.chars().collect();
    let at = at % (chars.len() + 1);
    let end = (at + len).min(chars.len());
    chars[..at].iter().collect::<String>() + with + &chars[end..].iter().collect::<String>()
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 400, failure_persistence: None, ..ProptestConfig::default() })]

    #[test]
    fn characters_replaced(k in 0usize..4, at in 0usize..4000, len in 0usize..12, with in fill()) {
        readers_cope(&replace(&base(k), at, len, &with))?;
    }

    #[test]
    fn lines_deleted_or_doubled(k in 0usize..4, line in 0usize..40, double in any::<bool>()) {
        let mut lines: Vec<String> = base(k).lines().map(str::to_string).collect();
        let i = line % lines.len();
        if double {
            let l = lines[i].clone();
            lines.insert(i, l);
        } else {
            lines.remove(i);
        }
        readers_cope(&(lines.join("\n") + "\n"))?;
    }
}

/// The bases are valid for their own reader (so the damage is what the cases test).
#[test]
fn bases_are_valid() {
    Srf::from_csv("s", &srf_text()).unwrap();
    solar::Spectrum::from_csv("s", &solar_text()).unwrap();
    Profile::from_csv("s", &afgl_text()).unwrap();
    thermo::from_user_csv("s", &user_text()).unwrap();
}
