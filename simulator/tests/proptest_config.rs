//! Property tests of the experiment-file resolver (issue 15): any value put in place of any
//! value of a valid experiment (numbers of every size and sign, NaN, infinities, strings,
//! lists, tables), any line deleted, and any run of characters replaced, gives either a valid
//! experiment or an error that names the file — never a panic or an abort.

use std::path::Path;

use engine::config::Experiment;
use proptest::prelude::*;

const BASE: &str = r#"seed = 3
polarized = false
[spectral]
wavelengths = [450.0, 550.0]
[geometry]
type = "plane_parallel"
toa_altitude = 100.0
ground_altitude = 0.0
[atmosphere]
type = "homogeneous"
optical_thickness = [0.2, 0.1]
single_scattering_albedo = 1.0
phase = { type = "hg", g = 0.7 }
[surface]
type = "rpv"
rho_0 = 0.1
k = 0.8
g = -0.1
[illumination]
type = "directional"
zenith = 30.0
azimuth = 10.0
[[measures]]
id = "pp"
type = "mdistant"
construct = "hplane"
azimuth = 0.0
zeniths = [-30.0, 0.0, 30.0]
spp = 100
[[measures]]
id = "flux"
type = "distant_flux"
spp = 100
[integrator]
detector_sampling = 0.1
"#;

fn value() -> impl Strategy<Value = String> {
    prop_oneof![
        any::<f64>().prop_map(|v| format!("{v:?}")),
        any::<i64>().prop_map(|v| v.to_string()),
        Just("nan".to_string()),
        Just("inf".to_string()),
        Just("-inf".to_string()),
        Just("1e308".to_string()),
        Just("-0.0".to_string()),
        Just("18446744073709551615".to_string()),
        "[a-z_]{0,12}".prop_map(|s| format!("\"{s}\"")),
        proptest::collection::vec(-1e6f64..1e6, 0..4).prop_map(|v| format!("{v:?}")),
        Just("{ type = \"rayleigh\" }".to_string()),
        Just("true".to_string()),
        Just("[]".to_string()),
    ]
}

fn resolves_or_names_the_file(text: &str) -> Result<(), TestCaseError> {
    let path = Path::new("prop-experiment.toml");
    match std::panic::catch_unwind(|| Experiment::from_str(text, path)) {
        Err(_) => Err(TestCaseError::fail(format!("panicked on:\n{text}"))),
        Ok(Ok(_)) => Ok(()),
        Ok(Err(e)) => {
            let m = e.to_string();
            prop_assert!(m.contains("prop-experiment.toml"), "{m}");
            prop_assert!(m.len() < 4000, "message of {} bytes", m.len());
            Ok(())
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 400, failure_persistence: None, ..ProptestConfig::default() })]

    /// The value of one `key = value` line replaced.
    #[test]
    fn any_value_anywhere(line in 0usize..64, v in value()) {
        let lines: Vec<&str> = BASE.lines().collect();
        let assigns: Vec<usize> = (0..lines.len()).filter(|&k| lines[k].contains(" = ")).collect();
        let k = assigns[line % assigns.len()];
        let key = lines[k].split(" = ").next().unwrap();
        let mut out: Vec<String> = lines.iter().map(|l| l.to_string()).collect();
        out[k] = format!("{key} = {v}");
        resolves_or_names_the_file(&out.join("\n"))?;
    }

    /// One line deleted, or two swapped.
    #[test]
    fn lines_deleted_or_swapped(a in 0usize..64, b in 0usize..64, delete in any::<bool>()) {
        let mut lines: Vec<&str> = BASE.lines().collect();
        let (a, b) = (a % lines.len(), b % lines.len());
        if delete {
            lines.remove(a);
        } else {
            lines.swap(a, b);
        }
        resolves_or_names_the_file(&lines.join("\n"))?;
    }

    /// A run of characters replaced by arbitrary text.
    #[test]
    fn characters_replaced(at in 0usize..2000, len in 0usize..8, fill in "\\PC{0,8}") {
        let at = at % BASE.len();
        let end = (at + len).min(BASE.len());
        let text = format!("{}{}{}", &BASE[..at], fill, &BASE[end..]);
        resolves_or_names_the_file(&text)?;
    }
}

/// The base experiment itself is valid (so the mutations start from a working file).
#[test]
fn base_is_valid() {
    Experiment::from_str(BASE, Path::new("prop-experiment.toml")).unwrap();
}
