//! Property tests of the bundle reader (issue 15): whatever is done to a bundle's manifest text
//! or buffers, `Bundle::open` returns (a bundle or an error naming a file) and never panics.
//! Buffer damage is resealed (digests recomputed) half of the time, so the checks behind the
//! digests (offsets, counts, indices, vertices, ids) are exercised too.

use proptest::prelude::*;

use super::tests::{reseal, sample};
use super::*;

fn fresh(tag: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("bundle-prop-{tag}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    sample().write(&dir, false).unwrap();
    dir
}

fn opens_without_panic(dir: &Path) -> Result<(), TestCaseError> {
    let r = std::panic::catch_unwind(|| Bundle::open(dir));
    match r {
        Err(_) => Err(TestCaseError::fail("Bundle::open panicked")),
        Ok(Ok(_)) => Ok(()),
        Ok(Err(e)) => {
            let msg = e.to_string();
            prop_assert!(msg.contains(dir.to_str().unwrap()), "no file named: {msg}");
            Ok(())
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 96, failure_persistence: None, ..ProptestConfig::default() })]

    /// A manifest with a run of characters replaced (numbers, signs, brackets, letters).
    #[test]
    fn damaged_manifest_never_panics(at in 0.0f64..1.0, len in 1usize..12, fill in "[-0-9.e+nainf\\[\\]=\" a-z]{1,12}") {
        let dir = fresh("manifest");
        let p = dir.join(MANIFEST_FILE);
        let text = std::fs::read_to_string(&p).unwrap();
        let start = ((text.len() as f64 * at) as usize).min(text.len() - 1);
        let start = (0..=start).rev().find(|&i| text.is_char_boundary(i)).unwrap();
        let end = (start + len).min(text.len());
        let end = (end..=text.len()).find(|&i| text.is_char_boundary(i)).unwrap();
        let damaged = format!("{}{}{}", &text[..start], fill, &text[end..]);
        std::fs::write(&p, damaged).unwrap();
        let r = opens_without_panic(&dir);
        std::fs::remove_dir_all(&dir).unwrap();
        r?;
    }

    /// A buffer with bytes overwritten or cut, resealed or not.
    #[test]
    fn damaged_buffers_never_panic(
        file in 0usize..4,
        at in 0.0f64..1.0,
        bytes in proptest::collection::vec(any::<u8>(), 1..16),
        cut in any::<bool>(),
        seal in any::<bool>(),
    ) {
        let dir = fresh("buffer");
        let name = ["terrain.bin", "templates.bin", "instances.bin", "materials.u8"][file];
        let p = dir.join(name);
        let mut b = std::fs::read(&p).unwrap();
        if !b.is_empty() {
            let start = ((b.len() as f64 * at) as usize).min(b.len() - 1);
            if cut {
                b.truncate(start);
            } else {
                for (k, v) in bytes.iter().enumerate() {
                    if let Some(x) = b.get_mut(start + k) {
                        *x = *v;
                    }
                }
            }
        }
        std::fs::write(&p, &b).unwrap();
        if seal {
            reseal(&dir);
        }
        let r = opens_without_panic(&dir);
        std::fs::remove_dir_all(&dir).unwrap();
        r?;
    }
}
