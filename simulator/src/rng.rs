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
fn mix64(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// A random stream identified by a seed and four ids.
#[derive(Clone, Debug)]
pub struct Stream {
    key: [u32; 2],
    ctr: [u32; 4],
    buf: [u32; 4],
    pos: usize,
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
        }
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

    /// Uniform in [0, 1) with 53 random bits.
    #[inline]
    pub fn next_f64(&mut self) -> f64 {
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
