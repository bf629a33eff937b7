//! Seed derivation: child seeds from a parent seed and an item path.
//!
//! Every random stream in fogline is a [`ChaCha8Rng`] seeded from `child(seed, path)`, where
//! `path` names the item (e.g. `[scenario_index, chunk_index]`). Streams therefore depend on
//! what is computed, never on which thread computes it or in what order.

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

/// SplitMix64 finaliser: a bijective 64-bit mixer.
#[inline]
pub fn mix64(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// The child seed of `seed` at `path`.
pub fn child(seed: u64, path: &[u64]) -> u64 {
    path.iter().fold(mix64(seed), |acc, &p| {
        mix64(acc ^ mix64(p.wrapping_add(0x5851_F42D_4C95_7F2D)))
    })
}

/// A generator for the item at `path` under `seed`.
pub fn rng(seed: u64, path: &[u64]) -> ChaCha8Rng {
    ChaCha8Rng::seed_from_u64(child(seed, path))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn children_differ_by_path_and_are_stable() {
        assert_ne!(child(0, &[0]), child(0, &[1]));
        assert_ne!(child(0, &[0, 1]), child(0, &[1, 0]));
        assert_ne!(child(0, &[1]), child(1, &[1]));
        assert_eq!(child(42, &[3, 4]), child(42, &[3, 4]));
    }
}
