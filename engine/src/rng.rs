//! Counter-based random numbers: Philox4x32-10 (Salmon et al. 2011, "Parallel random numbers:
//! as easy as 1, 2, 3", SC'11).
//!
//! A [`Stream`] is keyed by the run seed and a 4-word *stream id* — in the integrators
//! (wavelength index, measure index, direction or pixel index, sample index) — and draws by
//! incrementing a counter. A path's random numbers thus depend only on *which* sample it is,
//! never on which thread ran it or in what order: results are bit-identical for any thread count.

const M0: u64 = 0xD251_1F53;
const M1: u64 = 0xCD9E_8D57;
const W0: u32 = 0x9E37_79B9;
const W1: u32 = 0xBB67_AE85;

#[inline(always)]
fn mulhilo(a: u64, b: u32) -> (u32, u32) {
    let p = a * b as u64;
    ((p >> 32) as u32, p as u32)
}

/// One Philox4x32-10 block: 4 counter words and a 2-word key → 4 random words.
#[inline]
pub fn philox4x32(ctr: [u32; 4], key: [u32; 2]) -> [u32; 4] {
    let mut c = ctr;
    let mut k = key;
    for round in 0..10 {
        if round > 0 {
            k[0] = k[0].wrapping_add(W0);
            k[1] = k[1].wrapping_add(W1);
        }
        let (hi0, lo0) = mulhilo(M0, c[0]);
        let (hi1, lo1) = mulhilo(M1, c[2]);
        c = [hi1 ^ c[1] ^ k[0], lo1, hi0 ^ c[3] ^ k[1], lo0];
    }
    c
}

/// SplitMix64 finaliser, used to fold a seed and ids into Philox keys.
#[inline]
pub fn mix64(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// Draws of a sample taken from the Sobol sequence with `integrator.sampler = "sobol"` (the
/// pixel or area position, the first flight and scattering); later draws come from Philox.
pub const QMC_DIMS: u32 = 8;
/// Points per Owen-scrambled Sobol sequence (sobol_burley's limit); point `j` of a replicate is
/// point `j mod 2¹⁶` of its sequence `j / 2¹⁶`, each sequence independently scrambled.
const QMC_POINTS: u64 = 1 << 16;
/// Independently scrambled sequences per cell ([`crate::accum::REPLICATES`]).
const REPLICATES: u64 = crate::accum::REPLICATES as u64;

/// A random stream identified by a seed and four ids.
#[derive(Clone, Debug)]
pub struct Stream {
    key: [u32; 2],
    ctr: [u32; 4],
    buf: [u32; 4],
    pos: usize,
    /// Quasi-random draws left (0: Philox only), the point index and the scrambling seed.
    qmc_left: u32,
    qmc_dim: u32,
    qmc_index: u32,
    qmc_seed: u32,
    /// With `sobol`: the sample's first surface fan has not yet taken its points
    /// ([`Stream::take_fan`]).
    qmc_fan: bool,
    /// The last four Sobol dimensions computed together (`sobol_burley::sample_4d`, the same
    /// values as four `sample` calls) and their (point index, seed, dimension set).
    qmc_cache: [f32; 4],
    qmc_cache_key: [u32; 3],
}

/// Quasi-random draws of a fan's copy: the two numbers of its direction. (Taking the first
/// draws of the path it continues from the same point as well, up to 8, measured no better on
/// the street canyon of BENCHMARKS.md.)
pub const FAN_DIMS: u32 = 2;

/// The quasi-random numbers of one surface fan of `n` copies ([`Stream::take_fan`]): copy `j`
/// of the sample with point index `i` draws its direction's two numbers from point `i·n + j` of
/// a 2D Owen-scrambled Sobol sequence of its own (keyed by the sample's replicate sequence),
/// so over a replicate's samples their first fans' directions form one low-discrepancy set.
#[derive(Clone, Copy, Debug)]
pub struct FanPoints {
    first: u64,
    seed: u32,
}

/// A stream's quasi-random state, saved around a fan ([`Stream::qmc_state`]).
#[derive(Clone, Copy, Debug)]
pub struct QmcState {
    left: u32,
    dim: u32,
    index: u32,
    seed: u32,
}

impl FanPoints {
    /// Make `rng`'s next [`FAN_DIMS`] draws those of copy `j`'s point.
    pub fn enter(&self, j: u32, rng: &mut Stream) {
        let g = self.first + u64::from(j);
        rng.qmc_seed = mix64(u64::from(self.seed) ^ ((g / QMC_POINTS) << 32)) as u32;
        rng.qmc_index = (g % QMC_POINTS) as u32;
        rng.qmc_left = FAN_DIMS;
        rng.qmc_dim = 0;
    }
}

impl Stream {
    /// A stream for `seed` and the ids `(a, b, c, d)`; distinct ids give independent streams.
    pub fn new(seed: u64, ids: [u64; 4]) -> Self {
        // The key carries the seed and ids a, b; the upper counter words carry ids c, d; the
        // lower counter words count draws (2⁶⁴ blocks per stream).
        let k = mix64(seed ^ mix64(ids[0] ^ mix64(ids[1].wrapping_add(0x1234_5678))));
        let hi = mix64(ids[2] ^ mix64(ids[3] ^ 0xA5A5_A5A5));
        Self {
            key: [k as u32, (k >> 32) as u32],
            ctr: [0, 0, hi as u32, (hi >> 32) as u32],
            buf: [0; 4],
            pos: 4,
            qmc_left: 0,
            qmc_dim: 0,
            qmc_index: 0,
            qmc_seed: 0,
            qmc_fan: false,
            qmc_cache: [0.0; 4],
            qmc_cache_key: [0, 0, u32::MAX],
        }
    }

    /// The stream of sample `ids[3]` of the cell `ids[0..3]`: with `sobol`, its first
    /// [`QMC_DIMS`] draws are dimensions of an Owen-scrambled Sobol point (Burley 2020,
    /// "Practical hash-based Owen scrambling", JCGT 9(4)). The cell's samples form
    /// [`crate::accum::REPLICATES`] independently scrambled sequences (sample s: point s div R of replicate
    /// s mod R), each a (0, m, s)-net per 2¹⁶ of its points; every scrambling is keyed by the
    /// seed, the cell and the replicate, so results stay independent of the thread count.
    /// Without `sobol`, [`Stream::new`].
    pub fn for_sample(seed: u64, ids: [u64; 4], sobol: bool) -> Self {
        let mut s = Self::new(seed, ids);
        if sobol {
            // Replicate r = s mod R is its own scrambled sequence of the points j = s div R,
            // so the replicates' means are independent (`accum.rs`).
            let (r, j) = (
                crate::accum::replicate_of(ids[3]) as u64,
                ids[3] / REPLICATES,
            );
            let seq = j / QMC_POINTS;
            let h = mix64(
                seed ^ mix64(ids[0] ^ mix64(ids[1] ^ mix64(ids[2] ^ mix64(seq ^ (r << 48))))),
            );
            s.qmc_left = QMC_DIMS;
            s.qmc_index = (j % QMC_POINTS) as u32;
            s.qmc_seed = h as u32;
            s.qmc_fan = true;
        }
        s
    }

    /// The quasi-random state, to be restored after a fan ([`Stream::restore_qmc`]).
    pub fn qmc_state(&self) -> QmcState {
        QmcState {
            left: self.qmc_left,
            dim: self.qmc_dim,
            index: self.qmc_index,
            seed: self.qmc_seed,
        }
    }

    pub fn restore_qmc(&mut self, q: QmcState) {
        self.qmc_left = q.left;
        self.qmc_dim = q.dim;
        self.qmc_index = q.index;
        self.qmc_seed = q.seed;
    }

    /// With `sobol`, once per sample: the quasi-random points of a surface fan of `n` copies
    /// (the first fan the sample's walk makes; later fans, and runs without `sobol`, draw
    /// stratified pseudo-random numbers: `None`).
    pub fn take_fan(&mut self, n: u32) -> Option<FanPoints> {
        if !self.qmc_fan {
            return None;
        }
        self.qmc_fan = false;
        // The sample's point index within its replicate's sequence and that sequence's key
        // (`for_sample`), salted so the fan's points are independent of the sample's own.
        Some(FanPoints {
            first: u64::from(self.qmc_index) * u64::from(n),
            seed: mix64(u64::from(self.qmc_seed) ^ 0xFA17_0000_0000_0001) as u32,
        })
    }

    /// A quasi-random draw: the Sobol coordinate (23 bits: sobol_burley's f32 in [0, 1)) plus
    /// Philox bits below them, so the value keeps 53 random bits (and `-ln u` its full range)
    /// within the stratum.
    #[cold]
    fn next_qmc(&mut self) -> f64 {
        let dim = self.qmc_dim;
        self.qmc_dim += 1;
        self.qmc_left -= 1;
        // A sample's quasi-random draws come in order: one SIMD call serves four of them.
        let key = [self.qmc_index, self.qmc_seed, dim / 4];
        if self.qmc_cache_key != key {
            self.qmc_cache = sobol_burley::sample_4d(key[0], key[2], key[1]);
            self.qmc_cache_key = key;
        }
        let v = f64::from(self.qmc_cache[(dim % 4) as usize]);
        let jitter = self.next_philox_f64() * (1.0 / (1u64 << 23) as f64);
        (v + jitter).min(1.0 - f64::EPSILON)
    }

    #[inline]
    fn refill(&mut self) {
        self.buf = philox4x32(self.ctr, self.key);
        self.ctr[0] = self.ctr[0].wrapping_add(1);
        if self.ctr[0] == 0 {
            self.ctr[1] = self.ctr[1].wrapping_add(1);
        }
        self.pos = 0;
    }

    #[inline]
    pub fn next_u32(&mut self) -> u32 {
        if self.pos == 4 {
            self.refill();
        }
        let v = self.buf[self.pos];
        self.pos += 1;
        v
    }

    /// Uniform in [0, 1) with 53 random bits (quasi-random for the first draws of a Sobol
    /// sample, see [`Stream::for_sample`]).
    #[inline]
    pub fn next_f64(&mut self) -> f64 {
        if self.qmc_left > 0 {
            return self.next_qmc();
        }
        self.next_philox_f64()
    }

    #[inline]
    fn next_philox_f64(&mut self) -> f64 {
        let hi = (self.next_u32() as u64) << 21;
        let lo = (self.next_u32() >> 11) as u64;
        ((hi | lo) as f64) * (1.0 / (1u64 << 53) as f64)
    }

    /// Uniform in (0, 1]: safe for `-ln(u)`.
    #[inline]
    pub fn next_f64_open0(&mut self) -> f64 {
        1.0 - self.next_f64()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A surface fan's quasi-random points: taken once per Sobol sample (never without Sobol);
    /// the 4 copies of a sample's fan are one aligned block of its 2D sequence, so each of the
    /// 2 × 2, 4 × 1 and 1 × 4 cells of [0, 1)² holds exactly one of their directions' numbers;
    /// the stream's own quasi-random state comes back with `restore_qmc`.
    /// The four-at-once Sobol draws equal sobol_burley's one-dimension `sample` (the stratum
    /// of each quasi-random draw), for every dimension of several samples, and across a fan's
    /// save and restore of the stream's state.
    #[test]
    fn cached_sobol_draws_equal_single_dimension_samples() {
        let stratum = |x: f64| (x * (1u64 << 23) as f64).floor() as u32;
        for sample in [0u64, 1, 17, 4099, 1 << 20] {
            let mut s = Stream::for_sample(7, [1, 2, 3, sample], true);
            let (index, seed) = (s.qmc_index, s.qmc_seed);
            for d in 0..QMC_DIMS {
                let want = sobol_burley::sample(index, d, seed);
                let got = s.next_f64();
                assert_eq!(
                    stratum(got),
                    (f64::from(want) * (1u64 << 23) as f64) as u32,
                    "sample {sample}, dimension {d}"
                );
            }
        }
        let mut s = Stream::for_sample(7, [1, 2, 3, 5], true);
        let (index, seed) = (s.qmc_index, s.qmc_seed);
        let _ = s.next_f64();
        let saved = s.qmc_state();
        if let Some(points) = s.take_fan(4) {
            points.enter(1, &mut s);
            let _ = (s.next_f64(), s.next_f64());
        }
        s.restore_qmc(saved);
        let got = s.next_f64();
        let want = sobol_burley::sample(index, 1, seed);
        assert_eq!(stratum(got), (f64::from(want) * (1u64 << 23) as f64) as u32);
    }

    #[test]
    fn fan_points_are_taken_once_and_stratified() {
        assert!(Stream::for_sample(3, [1, 2, 3, 4], false)
            .take_fan(4)
            .is_none());
        let sobol_part = |u: f64| (u * (1u64 << 23) as f64).floor();
        for sample in [0u64, 5, 16 * 7 + 3, 16 * 40_000 + 9] {
            let mut s = Stream::for_sample(3, [1, 2, 3, sample], true);
            let mut plain = s.clone();
            // The sample's own first two dimensions, then the fan.
            for _ in 0..2 {
                assert_eq!(sobol_part(s.next_f64()), sobol_part(plain.next_f64()));
            }
            let before = s.qmc_state();
            let fan = s.take_fan(4).expect("a Sobol sample's first fan");
            assert!(s.take_fan(4).is_none(), "a second fan of the sample");
            let mut cells = [[0u32; 4]; 3];
            for j in 0..4 {
                fan.enter(j, &mut s);
                let (u0, u1) = (s.next_f64(), s.next_f64());
                assert!((0.0..1.0).contains(&u0) && (0.0..1.0).contains(&u1));
                let (a, b) = ((u0 * 2.0) as usize, (u1 * 2.0) as usize);
                cells[0][a * 2 + b] += 1;
                cells[1][(u0 * 4.0) as usize] += 1;
                cells[2][(u1 * 4.0) as usize] += 1;
            }
            assert_eq!(cells, [[1; 4]; 3], "sample {sample}");
            s.restore_qmc(before);
            let q = s.qmc_state();
            assert_eq!(
                (q.left, q.dim, q.index, q.seed),
                (before.left, before.dim, before.index, before.seed)
            );
            // After the fan the sample's remaining quasi-random dimensions go on where they
            // stopped (their Sobol parts equal those of a stream that made no fan).
            for _ in 2..QMC_DIMS {
                assert_eq!(sobol_part(s.next_f64()), sobol_part(plain.next_f64()));
            }
        }
    }

    /// Without Sobol a sample's stream is `Stream::new` (bit-identical default runs); with it
    /// the first draws of each replicate's 64 samples among a cell's 1024 are stratified (each
    /// of 64 equal bins of every quasi-random dimension holds exactly one), later draws are
    /// Philox, and a smooth integral converges much faster than with independent samples.
    #[test]
    fn sobol_samples_are_stratified_and_default_is_unchanged() {
        let mut a = Stream::new(9, [1, 2, 3, 4]);
        let mut b = Stream::for_sample(9, [1, 2, 3, 4], false);
        for _ in 0..20 {
            assert_eq!(a.next_f64().to_bits(), b.next_f64().to_bits());
        }
        let n = 1024u64;
        let per = n / REPLICATES;
        // Each replicate's points (samples r, r + R, r + 2R, …) stratify every dimension.
        let mut bins = vec![vec![vec![0u32; per as usize]; QMC_DIMS as usize]; REPLICATES as usize];
        let (mut q_err, mut r_err) = (0.0f64, 0.0f64);
        for cell in 0..8u64 {
            let (mut q, mut r) = (0.0, 0.0);
            for s in 0..n {
                let mut st = Stream::for_sample(9, [0, 0, cell, s], true);
                let mut ps = Stream::for_sample(9, [0, 0, cell, s], false);
                let rep = crate::accum::replicate_of(s);
                for (d, bin) in bins[rep].iter_mut().enumerate() {
                    let u = st.next_f64();
                    assert!((0.0..1.0).contains(&u));
                    if cell == 0 {
                        bin[(u * per as f64) as usize] += 1;
                    }
                    if d == 0 {
                        q += u * u;
                        r += ps.next_f64().powi(2);
                    }
                }
                let _ = st.next_f64(); // Philox beyond the quasi-random dimensions.
            }
            q_err += (q / n as f64 - 1.0 / 3.0).powi(2);
            r_err += (r / n as f64 - 1.0 / 3.0).powi(2);
        }
        for rep in &bins {
            for bin in rep {
                assert!(bin.iter().all(|&c| c == 1), "a dimension is not stratified");
            }
        }
        assert!(
            q_err * 100.0 < r_err,
            "Sobol error² {q_err:e} vs random {r_err:e}"
        );
    }

    /// Known-answer test from the Random123 distribution (kat_vectors, philox4x32_10).
    #[test]
    fn philox_known_answers() {
        assert_eq!(
            philox4x32([0; 4], [0; 2]),
            [0x6627e8d5, 0xe169c58d, 0xbc57ac4c, 0x9b00dbd8]
        );
        assert_eq!(
            philox4x32([u32::MAX; 4], [u32::MAX; 2]),
            [0x408f276d, 0x41c83b0e, 0xa20bc7c6, 0x6d5451fd]
        );
        assert_eq!(
            philox4x32(
                [0x243f6a88, 0x85a308d3, 0x13198a2e, 0x03707344],
                [0xa4093822, 0x299f31d0]
            ),
            [0xd16cfe09, 0x94fdcceb, 0x5001e420, 0x24126ea1]
        );
    }

    /// Uniform draws have mean ½ and variance 1/12 (1e6 draws, 5σ bounds).
    #[test]
    fn uniform_moments() {
        let mut s = Stream::new(42, [0, 1, 2, 3]);
        let n = 1_000_000;
        let (mut m, mut m2) = (0.0, 0.0);
        for _ in 0..n {
            let u = s.next_f64();
            assert!((0.0..1.0).contains(&u));
            m += u;
            m2 += u * u;
        }
        m /= n as f64;
        m2 /= n as f64;
        assert!((m - 0.5).abs() < 5.0 * (1.0 / 12.0 / n as f64).sqrt());
        assert!((m2 - m * m - 1.0 / 12.0).abs() < 1e-3);
    }

    #[test]
    fn distinct_ids_give_distinct_streams() {
        let a: Vec<u32> = (0..8)
            .map({
                let mut s = Stream::new(1, [0, 0, 0, 0]);
                move |_| s.next_u32()
            })
            .collect();
        let b: Vec<u32> = (0..8)
            .map({
                let mut s = Stream::new(1, [0, 0, 0, 1]);
                move |_| s.next_u32()
            })
            .collect();
        let c: Vec<u32> = (0..8)
            .map({
                let mut s = Stream::new(2, [0, 0, 0, 0]);
                move |_| s.next_u32()
            })
            .collect();
        assert_ne!(a, b);
        assert_ne!(a, c);
    }
}
