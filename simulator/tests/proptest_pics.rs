//! Property test of the PICS acquisitions reader (issue 43, item 8): starting from the
//! example's acquisitions table, any run of characters replaced by anything (dates, numbers,
//! separators, `nan`, a BOM, line breaks, any printable text) and any line deleted or doubled
//! gives acquisitions or an error naming the file — never a panic.

use std::path::Path;

use proptest::prelude::*;

const BASE: &str = include_str!("../../examples/pics/acquisitions.csv");

fn fill() -> impl Strategy<Value = String> {
    prop_oneof![
        "[0-9.,:TZ+\\- ]{0,10}",
        Just("nan".to_string()),
        Just("1e400".to_string()),
        Just("\u{feff}".to_string()),
        Just("\n".to_string()),
        Just(",,,".to_string()),
        "\\PC{0,10}",
    ]
}

fn reads_or_names_the_file(text: &str) -> Result<(), TestCaseError> {
    let path = Path::new("damaged_acquisitions.csv");
    match std::panic::catch_unwind(|| simulator::pics::parse_acquisitions(text, path)) {
        Err(_) => Err(TestCaseError::fail("parse_acquisitions panicked")),
        Ok(Ok(_)) => Ok(()),
        Ok(Err(e)) => {
            let msg = e.to_string();
            prop_assert!(
                msg.contains("damaged_acquisitions.csv"),
                "no file named: {msg}"
            );
            Ok(())
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 400, failure_persistence: None, ..ProptestConfig::default() })]

    #[test]
    fn characters_replaced(at in 0usize..400, len in 0usize..12, with in fill()) {
        let chars: Vec<char> = BASE.chars().collect();
        let at = at % (chars.len() + 1);
        let end = (at + len).min(chars.len());
        let text = chars[..at].iter().collect::<String>() + &with + &chars[end..].iter().collect::<String>();
        reads_or_names_the_file(&text)?;
    }

    #[test]
    fn lines_deleted_or_doubled(line in 0usize..16, double in any::<bool>()) {
        let mut lines: Vec<&str> = BASE.lines().collect();
        let i = line % lines.len();
        if double {
            lines.insert(i, lines[i]);
        } else {
            lines.remove(i);
        }
        reads_or_names_the_file(&(lines.join("\n") + "\n"))?;
    }
}

#[test]
fn base_is_valid() {
    simulator::pics::parse_acquisitions(BASE, Path::new("a.csv")).unwrap();
}
