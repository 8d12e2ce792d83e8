//! The light of the atmosphere above a scene, pooled over the pixels of an ortho image
//! (`integrator.above_scene`).
//!
//! **What.** A backward path of an ortho image starts above the scene, at the same altitude and
//! along the same direction for every pixel. Until it first goes below the scene's top
//! `z_top` (the highest point of its geometry) it sees only the plane-parallel layers above,
//! which are the same over every pixel. So the part of its score made before that moment (the
//! next-event estimates of its flights above `z_top`: light that the air above the scene
//! scatters towards the sensor, in every order) has the same distribution in every pixel. Its
//! mean `C` (per wavelength) is the radiance of the layers above `z_top` over a black boundary
//! there. Every pixel's walks estimate `C` anew, with the noise of a few hundred samples; at
//! short wavelengths that noise is a large part of the pixel's (440 nm on the README render:
//! about half its variance).
//!
//! **Pooled.** A pixel sample `s` scores only what its walk sends from the moment it first goes
//! below `z_top` ([`Part::AfterEntry`]), plus entry `s` of a pool: the mean of [`batch`] walks
//! that end there and score only what comes before ([`Part::BeforeEntry`]), on random streams
//! of their own keyed by `s` (and the wavelength group and the measure, not the pixel). The
//! pool's walks also split their first flights into a forced collision and the uncollided rest,
//! though over the stretch above the top only, where the pixels' walks split theirs down to the
//! scene hit (without splitting a walk's before-part varies 20× more). The two walks' before-
//! parts are thus equal in mean, not in distribution. Both parts are unbiased for their own
//! means, so their sum is unbiased for the pixel's radiance.
//!
//! **Errors.** Sample `s` of every pixel shares pool entry `s`, so a pixel's sample variance,
//! from which its standard error is computed, holds the entry's variance (a before-part's
//! variance over [`batch`]): each pixel's error stays honest. Pixels' errors are then
//! correlated through that common term (its share of a pixel's variance is about
//! `σ²_before / (B·σ²_pixel)`, a few per cent to 15 % in the tests). The error of a mean over
//! many pixels of one image is then dominated by it: in the tests (1600 pixels at 440 nm) the
//! image mean scattered ±2.5·10⁻⁴ BRF over seeds, 6× the ±4·10⁻⁵ of whole walks, and far more
//! than the pixels' errors divided by √N suggest. Use `"walked"` where such means matter (area
//! means over a site are `mdistant` measures with an area, which are never pooled).
//!
//! **Cost.** [`batch`]`(pixels)` short walks per sample index, which cast no scene rays: at
//! most 1/16 of a walk per pixel sample. A run split into shards (`run/units.rs`) cuts images
//! without a target into tiles, and every tile computes the pool again (the same entries, so
//! the merged image is still the unsplit one): with T tiles, up to T/16 short walks per pixel
//! sample. For runs over many shards prefer `"walked"`.
//!
//! **Determinism.** The entries depend only on `s`, the seed, the group and the measure, so the
//! images do not depend on the thread count, the tiling or the shards of a run, and a resumed
//! run recomputes the same entries.
//!
//! **Where.** Ortho images of scenes in plane-parallel layers walked over wavelength groups
//! (`integrator.spectral_walk = "alis"`), lit by the Sun alone (the Moon beside the Sun adds a
//! walk per sample lit from the Moon, which has no pool of its own). `"auto"` (the default)
//! pools images of at least [`MIN_PIXELS`]
//! pixels, where the pool costs at most 1/16 of a short walk per pixel sample; `"pooled"` asks
//! for it on any ortho image; `"walked"` turns it off.
//!
//! **Why unbiased.** The before-part is a function of the walk up to its first entry below
//! `z_top` (a stopping time); the expectation of a sum is the sum of the expectations whatever
//! estimates each. Validated against whole walks (per-pixel z-scores: their mean and RMS) in
//! `simulator/tests/above_scene.rs`; BENCHMARKS.md measures the gain.

/// Which part of a walk's score is made ([`crate::integrator::scene_alis::SceneChannels`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Part {
    /// Every contribution (walked images, and every measure but pooled ortho images).
    #[default]
    Whole,
    /// Only what the walk sends once it has been below the scene's top (pooled pixels).
    AfterEntry,
    /// Only what it sends before; the walk ends where it first goes below the top (the pool).
    BeforeEntry,
}

impl Part {
    /// Whether a contribution is scored that the path makes after its first entry below the
    /// scene's top (`entered`) or before it.
    #[inline]
    pub fn scores(self, entered: bool) -> bool {
        match self {
            Part::Whole => true,
            Part::AfterEntry => entered,
            Part::BeforeEntry => !entered,
        }
    }
}

/// Pool walks per sample index for an image of `pixels` pixels: `pixels/16` within 64 … 1024,
/// so the pool costs at most 1/16 of a (short) walk per pixel sample, and its share of a
/// pixel's variance, about `1/B` of the before-part's, stays small.
pub fn batch(pixels: usize) -> u64 {
    (pixels as u64 / 16).clamp(64, 1024)
}

/// `above_scene = "auto"` pools ortho images with at least this many pixels.
pub const MIN_PIXELS: usize = 1024;
