//! The random streams of a task's walks: every sample's own (Philox, or Owen-scrambled Sobol
//! as `integrator.sampler` says, keyed by seed, family, measure, cell and sample), and the tags
//! that keep the families apart: first-order split walks, the Moon's walks, spectral groups and
//! above-scene pools.

use crate::config::resolve::Experiment;
use crate::rng::Stream;

/// Tag of the Moon's random streams when it shines beside the Sun: its walks are independent of
/// the Sun's.
pub(super) const MOON_STREAM: u64 = 1 << 61;

/// Tag of the random streams of spectral ALIS groups (keyed by the group's first wavelength
/// index), apart from those of single wavelengths.
pub(super) const GROUP_STREAM: u64 = 1 << 62;

/// Tag of the random streams of the above-scene pools (`integrator/above_scene.rs`): keyed
/// by the group, the measure and the sample index, not the pixel.
pub(super) const POOL_STREAM: u64 = 1 << 60;

/// Tag of the streams of forward lamp photons (`blocks/lamp_photons.rs`): keyed by wavelength,
/// measure, batch and lamp.
pub(super) const LAMP_STREAM: u64 = 1 << 58;

/// Tag of the streams of first-order split walks (`integrator.first_order_splits`): they are
/// independent of the samples' own walks.
pub(super) const SPLIT_STREAM: u64 = 1 << 59;

/// The random stream of each sample `s` of the walks keyed `ids` (Sobol-scrambled or not, as
/// `integrator.sampler` says).
pub(super) fn sample_stream(exp: &Experiment, ids: [u64; 3]) -> impl Fn(u64) -> Stream + '_ {
    let streams = SampleStreams::new(exp, ids);
    move |s| streams.sample(s)
}

/// The random streams of the backward walks keyed `ids`: each sample's own, and its
/// first-order split walks'.
#[derive(Clone, Copy)]
pub(super) struct SampleStreams {
    seed: u64,
    sobol: bool,
    ids: [u64; 3],
}

impl SampleStreams {
    pub(super) fn new(exp: &Experiment, ids: [u64; 3]) -> Self {
        Self {
            seed: exp.seed,
            sobol: exp.integrator.sampler == crate::integrator::settings::Sampler::Sobol,
            ids,
        }
    }

    /// Sample `s`'s stream.
    pub(super) fn sample(&self, s: u64) -> Stream {
        let [a, b, c] = self.ids;
        Stream::for_sample(self.seed, [a, b, c, s], self.sobol)
    }

    /// The stream of first-order walk `j` (1 ≤ j < `k`) of sample `s`, `k` walks per sample:
    /// index [`split_index`] of the split family ([`SPLIT_STREAM`]).
    pub(super) fn split(&self, s: u64, j: u32, k: u32) -> Stream {
        let [a, b, c] = self.ids;
        Stream::for_sample(
            self.seed,
            [a | SPLIT_STREAM, b, c, split_index(s, j, k)],
            self.sobol,
        )
    }
}

/// The sample index, in the split family, of first-order walk `j` (1 ≤ j < `k`) of sample
/// `s`: in the same replicate as `s` (the replicates' means stay independent, `accum.rs`),
/// whose points the samples of that replicate share out `k − 1` each, in sample order (so with
/// the Sobol sampler a replicate's split walks are stratified among themselves, as its samples
/// are).
pub(super) fn split_index(s: u64, j: u32, k: u32) -> u64 {
    let reps = crate::accum::REPLICATES as u64;
    let point = (s / reps) * u64::from(k - 1) + u64::from(j - 1);
    point * reps + crate::accum::replicate_of(s) as u64
}

#[cfg(test)]
mod tests {
    use super::*;

    /// First-order split walks get indices of their own: distinct per sample and walk, in
    /// the sample's replicate, and the first n samples of a replicate use exactly its first
    /// n·(k − 1) points (a prefix, as Sobol stratification needs); their streams differ from
    /// the samples' own.
    #[test]
    fn split_indices_are_distinct_prefixes_in_the_replicate() {
        let reps = crate::accum::REPLICATES as u64;
        for k in 2..=5u32 {
            let mut seen = std::collections::HashSet::new();
            for s in 0..(20 * reps) {
                for j in 1..k {
                    let i = split_index(s, j, k);
                    assert!(seen.insert(i), "k {k}, s {s}, j {j}: index {i} twice");
                    assert_eq!(
                        crate::accum::replicate_of(i),
                        crate::accum::replicate_of(s),
                        "k {k}, s {s}, j {j}"
                    );
                }
                // After sample s, replicate r holds the points 0..n·(k − 1) of its sequence.
                let r = crate::accum::replicate_of(s) as u64;
                let n = s / reps + 1;
                let points: std::collections::BTreeSet<u64> = seen
                    .iter()
                    .filter(|&&i| i % reps == r)
                    .map(|&i| i / reps)
                    .collect();
                let want: std::collections::BTreeSet<u64> = (0..n * u64::from(k - 1)).collect();
                assert_eq!(points, want, "k {k}, s {s}");
            }
        }
        for sobol in [false, true] {
            let streams = SampleStreams {
                seed: 3,
                sobol,
                ids: [1, 2, 3],
            };
            let own: std::collections::HashSet<u64> = (0..200)
                .map(|s| {
                    let mut r = streams.sample(s);
                    (u64::from(r.next_u32()) << 32) | u64::from(r.next_u32())
                })
                .collect();
            for s in 0..200 {
                let mut r = streams.split(s, 1, 2);
                let x = (u64::from(r.next_u32()) << 32) | u64::from(r.next_u32());
                assert!(!own.contains(&x), "sobol {sobol}, s {s}");
            }
        }
    }
}
