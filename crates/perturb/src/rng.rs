//! Seeds and the generator behind every random draw.
//!
//! - [`child`] derives a child seed from a parent seed and a path of integers with the
//!   SplitMix64 finaliser: `fogline_stats::seed::child`, the one seed derivation of fogline.
//! - [`name_id`] turns a name (a clip id, a condition name) into a path element: 64-bit
//!   FNV-1a of its UTF-8 bytes, stable across platforms and releases.
//! - [`WyRand`] is the generator: Wang Yi's *wyrand* (a 64-bit counter with the `wymum`
//!   128-bit multiply-fold output), period 2^64 per stream, which passes BigCrush and
//!   PractRand. It is used rather than ChaCha8 because the noise families draw one 64-bit
//!   word per four samples and the generator would otherwise dominate their cost; every
//!   stream is short (one image row, or one camera) and seeded from [`child`].
//!
//! - [`Xoshiro8`] runs eight *xoshiro256++* generators side by side (Blackman and Vigna; 256
//!   bits of state each, seeded from one [`WyRand`] stream). Gaussian noise draws 25 bits per
//!   sample, and eight independent 64-bit lanes are what one AVX-512 register holds, so the
//!   vector kernel and the portable one produce the same stream.
//!
//! A stream therefore depends only on *what* is computed — (seed, clip, camera, frame,
//! condition, step, row) — never on the thread that computes it or the order of the work.

pub use fogline_stats::seed::{child, mix64};

/// 64-bit FNV-1a hash of `name`: how names (clip ids, condition names) enter seed paths.
pub fn name_id(name: &str) -> u64 {
    name.bytes().fold(0xCBF2_9CE4_8422_2325, |h, b| {
        (h ^ u64::from(b)).wrapping_mul(0x0000_0100_0000_01B3)
    })
}

/// The *wyrand* generator (see the module docs).
#[derive(Debug, Clone)]
pub struct WyRand {
    state: u64,
}

impl WyRand {
    /// A generator whose stream is determined by `seed`.
    pub fn new(seed: u64) -> Self {
        Self { state: seed }
    }

    /// The generator of the item at `path` under `seed` (`WyRand::new(child(seed, path))`).
    pub fn at(seed: u64, path: &[u64]) -> Self {
        Self::new(child(seed, path))
    }

    /// The next 64 uniform bits.
    #[inline(always)]
    pub fn next_u64(&mut self) -> u64 {
        self.state = self.state.wrapping_add(0xA076_1D64_78BD_642F);
        let t = u128::from(self.state) * u128::from(self.state ^ 0xE703_7ED1_A0B4_28DB);
        ((t >> 64) as u64) ^ (t as u64)
    }

    /// A uniform double in [0, 1) with 53 random bits.
    #[inline]
    pub fn next_f64(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }

    /// A uniform integer in [0, n), exactly uniform (Lemire's multiply-and-reject), `n > 0`.
    pub fn below(&mut self, n: u64) -> u64 {
        assert!(n > 0, "WyRand::below(0)");
        let threshold = n.wrapping_neg() % n;
        loop {
            let m = u128::from(self.next_u64()) * u128::from(n);
            if (m as u64) >= threshold {
                return (m >> 64) as u64;
            }
        }
    }

    /// `true` with probability `p` (to 2^-64), for `p` in [0, 1].
    #[inline]
    pub fn bernoulli(&mut self, p: f64) -> bool {
        self.next_u64() < probability_threshold(p)
    }
}

/// Eight *xoshiro256++* generators in lock-step: each call of [`Xoshiro8::next_words`] advances all
/// eight and returns one 64-bit output per lane.
///
/// Lane `k`'s state words `s0..s3` are draws `4k .. 4k + 3` of `WyRand::new(seed)` (a lane
/// whose four words are all zero, probability 2^-256, gets `s0 = 1`). The state is stored
/// word-major (`s[j][k]` is word `j` of lane `k`) so that it loads straight into vector
/// registers.
#[derive(Debug, Clone)]
pub struct Xoshiro8 {
    /// `s[j][k]`: state word `j` of lane `k`.
    pub(crate) s: [[u64; 8]; 4],
}

impl Xoshiro8 {
    /// The eight generators of `seed` (see the type docs).
    pub fn new(seed: u64) -> Self {
        let mut w = WyRand::new(seed);
        let mut s = [[0u64; 8]; 4];
        for k in 0..8 {
            for word in s.iter_mut() {
                word[k] = w.next_u64();
            }
            if s.iter().all(|word| word[k] == 0) {
                s[0][k] = 1;
            }
        }
        Self { s }
    }

    /// The next output of every lane (xoshiro256++: `rotl(s0 + s3, 23) + s0`, then the
    /// xoshiro256 state transition).
    #[inline(always)]
    pub fn next_words(&mut self) -> [u64; 8] {
        let mut out = [0u64; 8];
        let [s0, s1, s2, s3] = &mut self.s;
        for k in 0..8 {
            out[k] = s0[k]
                .wrapping_add(s3[k])
                .rotate_left(23)
                .wrapping_add(s0[k]);
            let t = s1[k] << 17;
            s2[k] ^= s0[k];
            s3[k] ^= s1[k];
            s1[k] ^= s2[k];
            s0[k] ^= s3[k];
            s2[k] ^= t;
            s3[k] = s3[k].rotate_left(45);
        }
        out
    }
}

/// ⌊p·2^64⌋ saturated to [0, 2^64 − 1]: `u < threshold` has probability `p` to within 2^-64.
pub fn probability_threshold(p: f64) -> u64 {
    if p <= 0.0 {
        0
    } else if p >= 1.0 {
        u64::MAX
    } else {
        (p * 18_446_744_073_709_551_616.0) as u64
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn wyrand_matches_the_reference_stream() {
        // Reference: wyrand from wyhash.h (seed 0), first four outputs, computed with
        // Python's arbitrary-precision integers.
        let mut r = WyRand::new(0);
        let got: Vec<u64> = (0..4).map(|_| r.next_u64()).collect();
        assert_eq!(got, REFERENCE_SEED0);
    }

    // python3 -c "
    // M=2**64; s=0
    // for _ in range(4):
    //   s=(s+0xa0761d6478bd642f)%M; t=s*(s^0xe7037ed1a0b428db); print(hex((t>>64)^(t%M)))"
    const REFERENCE_SEED0: [u64; 4] = [
        0x111c_b3a7_8f59_a58e,
        0xceab_d938_ff4e_856d,
        0x61fb_5131_8f47_d2a4,
        0x78bd_03c4_9190_9760,
    ];

    #[test]
    fn every_xoshiro8_lane_is_the_reference_xoshiro256plusplus() {
        // The state below is lane 0 of `Xoshiro8::new(0)`: the first four outputs of
        // wyrand(0) (`REFERENCE_SEED0`). The expected outputs come from the reference
        // algorithm (xoshiro256plusplus.c) run with Python's integers:
        // python3 -c "
        // M=2**64-1; r=lambda x,k:((x<<k)|(x>>(64-k)))&M
        // s=[0x111cb3a78f59a58e,0xceabd938ff4e856d,0x61fb51318f47d2a4,0x78bd03c491909760]
        // for _ in range(3):
        //   print(hex((r((s[0]+s[3])&M,23)+s[0])&M)); t=(s[1]<<17)&M
        //   s[2]^=s[0]; s[3]^=s[1]; s[1]^=s[2]; s[0]^=s[3]; s[2]^=t; s[3]=r(s[3],45)"
        let mut g = Xoshiro8::new(0);
        assert_eq!(
            [g.s[0][0], g.s[1][0], g.s[2][0], g.s[3][0]],
            REFERENCE_SEED0
        );
        let got: Vec<u64> = (0..3).map(|_| g.next_words()[0]).collect();
        assert_eq!(got, XOSHIRO_FROM_SEED0);
        // Lane 3 is seeded by draws 12..16 of the same wyrand stream.
        let mut w = WyRand::new(0);
        let draws: Vec<u64> = (0..16).map(|_| w.next_u64()).collect();
        let g = Xoshiro8::new(0);
        assert_eq!([g.s[0][3], g.s[1][3], g.s[2][3], g.s[3][3]], draws[12..16]);
    }

    #[test]
    fn below_is_in_range_and_hits_every_value() {
        let mut r = WyRand::new(7);
        let mut seen = [false; 7];
        for _ in 0..1000 {
            let v = r.below(7);
            seen[v as usize] = true;
        }
        assert!(seen.iter().all(|&s| s));
    }

    const XOSHIRO_FROM_SEED0: [u64; 3] = [
        0xc72d_28c6_069e_9269,
        0xb668_dcfe_90bc_5d93,
        0xb7c3_7f5e_15ee_45d8,
    ];

    #[test]
    fn xoshiro8_lanes_give_the_published_xoshiro256plusplus_outputs() {
        // State (1, 2, 3, 4): the first outputs published with the rand_xoshiro crate's tests.
        let mut g = Xoshiro8::new(5);
        for (j, word) in g.s.iter_mut().enumerate() {
            word[5] = j as u64 + 1;
        }
        let got: Vec<u64> = (0..4).map(|_| g.next_words()[5]).collect();
        assert_eq!(
            got,
            [
                41_943_041,
                58_720_359,
                3_588_806_011_781_223,
                3_591_011_842_654_386
            ]
        );
    }

    #[test]
    fn name_id_is_fnv1a() {
        assert_eq!(name_id(""), 0xCBF2_9CE4_8422_2325);
        assert_eq!(name_id("a"), 0xAF63_DC4C_8601_EC8C);
    }
}
