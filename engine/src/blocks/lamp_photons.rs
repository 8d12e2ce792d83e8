//! One batch of forward lamp photons for a nadir ortho image (`integrator/lamp_photons.rs`):
//! every lamp's photons at one wavelength, scored into per-pixel sums. The driver runs
//! [`LAMP_BATCHES`] independent batches and adds their mean, with the variance of that mean
//! from their scatter, to the image's accumulator (`Accum::add_extra`); the backward walks of
//! the same measure then leave the point lamps out (`blocks/single.rs`).

use glam::DVec3;

use crate::config::resolve::Experiment;
use crate::integrator::geometry::Geometry;
use crate::integrator::lamp_photons::{photon_count, trace_lamp};
use crate::integrator::weight::Scalar;
use crate::rng::Stream;

use super::streams::LAMP_STREAM;
use super::walks::scene_in_layers;

/// Independent batches of lamp photons per (wavelength, measure): their scatter is the
/// estimate's error (15 degrees of freedom).
pub const LAMP_BATCHES: u64 = 16;

/// Batch `batch` of the lamp photons of measure `im` at wavelength `iw`: per pixel, the sums
/// of first-order and higher-order scores `[2·cell]`, `[2·cell + 1]`, in the accumulator's
/// units (`π·L/(E0·μ)`, as the backward walks record). Empty when forward photons do not
/// serve this measure ([`Experiment::lamp_photon_pixels`]).
pub fn lamp_batch(exp: &Experiment, iw: usize, im: usize, batch: u64) -> Vec<f64> {
    let (Some(lamps), Some(px)) = (
        exp.lamps.as_deref(),
        exp.lamp_photon_pixels(&exp.measures[im]),
    ) else {
        return Vec::new();
    };
    let mut out = vec![0.0; 2 * px.width * px.height];
    let opt = &exp.optics[iw];
    let power = |l: &crate::sources::lamps::Lamp| l.intensity[iw] * l.solid_angle();
    let mean_power = lamps.lamps.iter().map(power).sum::<f64>() / lamps.lamps.len() as f64;
    if mean_power <= 0.0 {
        return out;
    }
    // The sensor's direction plays the Sun's part: `sun_at` is then T_v·V.
    let g = scene_in_layers(exp, DVec3::Z, &opt.atmosphere, opt, None);
    // As the backward walks record: the run's normalisation (π/μ of the Sun or Moon) times
    // radiance/E0; each photon carries Φ̄/n; a nadir pixel divides by its area.
    let norm = Geometry::<Scalar>::light(&scene_in_layers(
        exp,
        exp.sun_dir,
        &opt.atmosphere,
        opt,
        None,
    ))
    .normalization;
    // Photons per lamp of mean power in this batch (may be below 1: lamps then send one with
    // that probability).
    let n = f64::from(lamps.photons) / LAMP_BATCHES as f64;
    let k = norm / opt.irradiance * mean_power / n / (px.pixel * px.pixel);
    for (l, lamp) in lamps.lamps.iter().enumerate() {
        let mut rng = Stream::new(
            exp.seed,
            [LAMP_STREAM | iw as u64, im as u64, batch, l as u64],
        );
        let count = photon_count(n, power(lamp), mean_power, rng.next_f64());
        trace_lamp(&g, lamp, count, k, &px, &exp.integrator, &mut rng, &mut out);
    }
    out
}
