//! Per-sample maps `u8 → u8` at memory speed.
//!
//! Gain, homogeneous fog, contrast (around a fixed grey) and colour quantisation all map each
//! sample through one 256-entry table `f`, computed once in double precision from the family's
//! formula. Applying a table byte by byte costs about a cycle per sample; so when `f` is a
//! clipped affine map `f(x) = min(255, ⌊(P·x + Q) / 2^16⌋)` for integers `P, Q < 2^24` — which
//! [`ByteMap::new`] checks against all 256 entries, it is no approximation — the map runs as
//! 16-bit integer arithmetic that the compiler vectorises (16 samples per step with SSE2).
//! Otherwise it falls back to the table.

/// A map `u8 → u8` applied to every sample.
#[derive(Debug, Clone)]
pub struct ByteMap {
    table: [u8; 256],
    affine: Option<Affine>,
}

/// `min(255, x·p_hi + q_hi + ⌊(x·p_lo + q_lo) / 2^16⌋)`, all in 16-bit lanes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct Affine {
    p_hi: u16,
    p_lo: u16,
    q_hi: u16,
    q_lo: u16,
}

impl Affine {
    #[inline(always)]
    fn eval(self, x: u8) -> u8 {
        let x = u16::from(x);
        let lo = x.wrapping_mul(self.p_lo);
        let hi = ((u32::from(x) * u32::from(self.p_lo)) >> 16) as u16;
        let (_, carry) = lo.overflowing_add(self.q_lo);
        let v = x
            .wrapping_mul(self.p_hi)
            .wrapping_add(hi + u16::from(carry) + self.q_hi);
        v.min(255) as u8
    }
}

impl ByteMap {
    /// The map with table `table`; `slope` and `offset` (when given) describe it as
    /// `⌊slope·x + offset⌋` clipped to [0, 255] and enable the fast path if exact.
    pub fn new(table: [u8; 256], affine_hint: Option<(f64, f64)>) -> Self {
        let affine = affine_hint.and_then(|(slope, offset)| find_affine(&table, slope, offset));
        Self { table, affine }
    }

    /// The map `f(x) = min(255, max(0, ⌊slope·x + offset⌋))`, evaluated in double precision
    /// as [`floor_guarded`]`(slope·x + offset)`.
    pub fn affine(slope: f64, offset: f64) -> Self {
        let mut table = [0u8; 256];
        for (x, t) in table.iter_mut().enumerate() {
            *t = floor_guarded(slope * x as f64 + offset).clamp(0.0, 255.0) as u8;
        }
        Self::new(table, Some((slope, offset)))
    }

    /// The table.
    pub fn table(&self) -> &[u8; 256] {
        &self.table
    }

    /// Whether the vectorised integer path is used.
    pub fn is_affine(&self) -> bool {
        self.affine.is_some()
    }

    /// Whether the map leaves every value unchanged.
    pub fn is_identity(&self) -> bool {
        self.table.iter().enumerate().all(|(i, &v)| v as usize == i)
    }

    /// `dst[i] = f(src[i])`.
    pub fn apply(&self, src: &[u8], dst: &mut [u8]) {
        match self.affine {
            Some(a) => {
                for (d, &s) in dst.iter_mut().zip(src) {
                    *d = a.eval(s);
                }
            }
            None => {
                let t = &self.table;
                for (d, &s) in dst.iter_mut().zip(src) {
                    *d = t[s as usize];
                }
            }
        }
    }
}

/// `⌊v⌋`, except that a `v` within 1e-9 below an integer counts as that integer.
///
/// Decimal parameters (0.3, 1.6, …) are not exact in binary, so a formula whose exact value
/// is a whole number — a rounding tie before the `+ ½` — can evaluate to 67.99999999999999
/// instead of 68. The guard restores the exact result; real values never lie that close to
/// an integer without being one, since the parameters have few decimals.
pub fn floor_guarded(v: f64) -> f64 {
    (v + 1e-9).floor()
}

/// `clip(floor_guarded(v), 0, 255)` as a byte, without a call to the maths library (a
/// saturating float-to-integer conversion truncates, which is the floor for `v >= 0`).
#[inline(always)]
pub fn floor_guarded_u8(v: f64) -> u8 {
    (v + 1e-9).clamp(0.0, 255.0) as u8
}

/// Integers `P = p_hi·2^16 + p_lo`, `Q = q_hi·2^16 + q_lo` reproducing `table` exactly, if any
/// near `slope·2^16`, `offset·2^16` does.
fn find_affine(table: &[u8; 256], slope: f64, offset: f64) -> Option<Affine> {
    if !(0.0..256.0).contains(&slope) || !(0.0..256.0).contains(&offset) {
        return None;
    }
    // Candidates slightly above the real coefficients first: then ⌊(P·x + Q)/2^16⌋ errs
    // upwards by less than the distance of the real value to the next integer.
    let p_up = (slope * 65536.0).ceil() as i64;
    let q_up = (offset * 65536.0).ceil() as i64;
    for (p0, q0) in [(p_up, q_up), ((slope * 65536.0).floor() as i64, q_up)] {
        for (dp, dq) in [0i64, 1, 2].into_iter().flat_map(|dp| {
            [0i64, 1, 2, 4, 8, 16, 32, 64, 128, 256]
                .into_iter()
                .map(move |dq| (dp, dq))
        }) {
            let (p, q) = (p0 + dp, q0 + dq);
            if p < 0 || q < 0 || p >= 1 << 24 || q >= 1 << 24 {
                continue;
            }
            let a = Affine {
                p_hi: (p >> 16) as u16,
                p_lo: (p & 0xFFFF) as u16,
                q_hi: (q >> 16) as u16,
                q_lo: (q & 0xFFFF) as u16,
            };
            if (0..256).all(|x| a.eval(x as u8) == table[x]) {
                return Some(a);
            }
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn paper_gains_and_fogs_take_the_fast_path_and_match_the_table() {
        let maps = [
            ByteMap::affine(0.4, 0.5),
            ByteMap::affine(1.6, 0.5),
            ByteMap::affine(0.7, 0.3 * 204.0 + 0.5),
            ByteMap::affine(0.3, 0.7 * 204.0 + 0.5),
            ByteMap::affine(1.0, 0.5),
        ];
        for m in &maps {
            assert!(m.is_affine());
            let src: Vec<u8> = (0..=255).collect();
            let mut dst = vec![0; 256];
            m.apply(&src, &mut dst);
            assert_eq!(&dst[..], &m.table()[..]);
        }
        assert!(maps[4].is_identity());
    }

    #[test]
    fn a_table_that_is_not_affine_falls_back() {
        let mut t = [0u8; 256];
        for (i, v) in t.iter_mut().enumerate() {
            *v = (255 - i) as u8;
        }
        let m = ByteMap::new(t, Some((1.0, 0.0)));
        assert!(!m.is_affine());
        let mut d = [0u8; 3];
        m.apply(&[0, 1, 255], &mut d);
        assert_eq!(d, [255, 254, 0]);
    }
}
