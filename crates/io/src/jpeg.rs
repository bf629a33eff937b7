//! fogline's JPEG encoder: baseline sequential JPEG (JFIF), YCbCr 4:4:4, libjpeg's quality
//! scaling of the standard (Annex K) quantisation tables and the standard Huffman tables —
//! the file a `cjpeg -quality Q -sample 1x1` writer produces, in one pass over the frame.
//!
//! Written for the remote planner calls, where a frame is encoded on one side and decoded on
//! the other for every call, so the encoder's time is the runner's overhead:
//!
//! - **Colour and DCT in single precision**, eight lanes at a time: the colour conversion
//!   fills an 8×8 block per component, and the forward DCT is the AAN float algorithm
//!   (libjpeg's `jfdctflt`) run down the eight columns at once, then down the transposed
//!   rows; its scale factors are folded into the quantisation multipliers, and the second
//!   pass's transposition into the zig-zag order.
//! - **Entropy coding by bit mask**: the block's non-zero coefficients are found as a 64-bit
//!   mask, and the coder jumps from one to the next with a trailing-zero count (runs of zeros
//!   cost nothing), appending each code and its value bits as one field to a 64-bit buffer
//!   that is written out eight bytes at a time (byte by byte, with stuffing, only when one of
//!   the eight is `0xFF`).
//!
//! The arithmetic is the same on every CPU (no fused multiply-adds; the vector and scalar
//! code compute the same operations in the same order), so a frame encodes to the same bytes
//! everywhere. [`encode_rgb`] is the only entry point.

/// The zig-zag order: `ZIGZAG[k]` is the natural (row-major) index of the `k`-th coefficient.
const ZIGZAG: [usize; 64] = [
    0, 1, 8, 16, 9, 2, 3, 10, 17, 24, 32, 25, 18, 11, 4, 5, 12, 19, 26, 33, 40, 48, 41, 34, 27, 20,
    13, 6, 7, 14, 21, 28, 35, 42, 49, 56, 57, 50, 43, 36, 29, 22, 15, 23, 30, 37, 44, 51, 58, 59,
    52, 45, 38, 31, 39, 46, 53, 60, 61, 54, 47, 55, 62, 63,
];

/// Annex K.1: the luminance quantisation table, natural (row-major) order. Also the table of
/// `fogline-perturb`'s JPEG-artefact perturbation.
pub const LUMA_Q: [u16; 64] = [
    16, 11, 10, 16, 24, 40, 51, 61, 12, 12, 14, 19, 26, 58, 60, 55, 14, 13, 16, 24, 40, 57, 69, 56,
    14, 17, 22, 29, 51, 87, 80, 62, 18, 22, 37, 56, 68, 109, 103, 77, 24, 35, 55, 64, 81, 104, 113,
    92, 49, 64, 78, 87, 103, 121, 120, 101, 72, 92, 95, 98, 112, 100, 103, 99,
];

/// Annex K.2: the chrominance quantisation table, natural order.
pub const CHROMA_Q: [u16; 64] = [
    17, 18, 24, 47, 99, 99, 99, 99, 18, 21, 26, 66, 99, 99, 99, 99, 24, 26, 56, 99, 99, 99, 99, 99,
    47, 66, 99, 99, 99, 99, 99, 99, 99, 99, 99, 99, 99, 99, 99, 99, 99, 99, 99, 99, 99, 99, 99, 99,
    99, 99, 99, 99, 99, 99, 99, 99, 99, 99, 99, 99, 99, 99, 99, 99,
];

/// Annex K.3: the standard Huffman tables, as (code counts per length 1–16, symbols).
const DC_LUMA: ([u8; 16], &[u8]) = (
    [0, 1, 5, 1, 1, 1, 1, 1, 1, 0, 0, 0, 0, 0, 0, 0],
    &[0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11],
);
const DC_CHROMA: ([u8; 16], &[u8]) = (
    [0, 3, 1, 1, 1, 1, 1, 1, 1, 1, 1, 0, 0, 0, 0, 0],
    &[0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11],
);
const AC_LUMA: ([u8; 16], &[u8]) = (
    [0, 2, 1, 3, 3, 2, 4, 3, 5, 5, 4, 4, 0, 0, 1, 0x7d],
    &[
        0x01, 0x02, 0x03, 0x00, 0x04, 0x11, 0x05, 0x12, 0x21, 0x31, 0x41, 0x06, 0x13, 0x51, 0x61,
        0x07, 0x22, 0x71, 0x14, 0x32, 0x81, 0x91, 0xa1, 0x08, 0x23, 0x42, 0xb1, 0xc1, 0x15, 0x52,
        0xd1, 0xf0, 0x24, 0x33, 0x62, 0x72, 0x82, 0x09, 0x0a, 0x16, 0x17, 0x18, 0x19, 0x1a, 0x25,
        0x26, 0x27, 0x28, 0x29, 0x2a, 0x34, 0x35, 0x36, 0x37, 0x38, 0x39, 0x3a, 0x43, 0x44, 0x45,
        0x46, 0x47, 0x48, 0x49, 0x4a, 0x53, 0x54, 0x55, 0x56, 0x57, 0x58, 0x59, 0x5a, 0x63, 0x64,
        0x65, 0x66, 0x67, 0x68, 0x69, 0x6a, 0x73, 0x74, 0x75, 0x76, 0x77, 0x78, 0x79, 0x7a, 0x83,
        0x84, 0x85, 0x86, 0x87, 0x88, 0x89, 0x8a, 0x92, 0x93, 0x94, 0x95, 0x96, 0x97, 0x98, 0x99,
        0x9a, 0xa2, 0xa3, 0xa4, 0xa5, 0xa6, 0xa7, 0xa8, 0xa9, 0xaa, 0xb2, 0xb3, 0xb4, 0xb5, 0xb6,
        0xb7, 0xb8, 0xb9, 0xba, 0xc2, 0xc3, 0xc4, 0xc5, 0xc6, 0xc7, 0xc8, 0xc9, 0xca, 0xd2, 0xd3,
        0xd4, 0xd5, 0xd6, 0xd7, 0xd8, 0xd9, 0xda, 0xe1, 0xe2, 0xe3, 0xe4, 0xe5, 0xe6, 0xe7, 0xe8,
        0xe9, 0xea, 0xf1, 0xf2, 0xf3, 0xf4, 0xf5, 0xf6, 0xf7, 0xf8, 0xf9, 0xfa,
    ],
);
const AC_CHROMA: ([u8; 16], &[u8]) = (
    [0, 2, 1, 2, 4, 4, 3, 4, 7, 5, 4, 4, 0, 1, 2, 0x77],
    &[
        0x00, 0x01, 0x02, 0x03, 0x11, 0x04, 0x05, 0x21, 0x31, 0x06, 0x12, 0x41, 0x51, 0x07, 0x61,
        0x71, 0x13, 0x22, 0x32, 0x81, 0x08, 0x14, 0x42, 0x91, 0xa1, 0xb1, 0xc1, 0x09, 0x23, 0x33,
        0x52, 0xf0, 0x15, 0x62, 0x72, 0xd1, 0x0a, 0x16, 0x24, 0x34, 0xe1, 0x25, 0xf1, 0x17, 0x18,
        0x19, 0x1a, 0x26, 0x27, 0x28, 0x29, 0x2a, 0x35, 0x36, 0x37, 0x38, 0x39, 0x3a, 0x43, 0x44,
        0x45, 0x46, 0x47, 0x48, 0x49, 0x4a, 0x53, 0x54, 0x55, 0x56, 0x57, 0x58, 0x59, 0x5a, 0x63,
        0x64, 0x65, 0x66, 0x67, 0x68, 0x69, 0x6a, 0x73, 0x74, 0x75, 0x76, 0x77, 0x78, 0x79, 0x7a,
        0x82, 0x83, 0x84, 0x85, 0x86, 0x87, 0x88, 0x89, 0x8a, 0x92, 0x93, 0x94, 0x95, 0x96, 0x97,
        0x98, 0x99, 0x9a, 0xa2, 0xa3, 0xa4, 0xa5, 0xa6, 0xa7, 0xa8, 0xa9, 0xaa, 0xb2, 0xb3, 0xb4,
        0xb5, 0xb6, 0xb7, 0xb8, 0xb9, 0xba, 0xc2, 0xc3, 0xc4, 0xc5, 0xc6, 0xc7, 0xc8, 0xc9, 0xca,
        0xd2, 0xd3, 0xd4, 0xd5, 0xd6, 0xd7, 0xd8, 0xd9, 0xda, 0xe2, 0xe3, 0xe4, 0xe5, 0xe6, 0xe7,
        0xe8, 0xe9, 0xea, 0xf2, 0xf3, 0xf4, 0xf5, 0xf6, 0xf7, 0xf8, 0xf9, 0xfa,
    ],
);

/// The AAN algorithm's output scale per frequency (libjpeg's `aanscalefactor`):
/// `cos(k·π/16)·√2` for k > 0, 1 for k = 0.
const AAN_SCALE: [f64; 8] = [
    1.0,
    1.387_039_845,
    1.306_562_965,
    1.175_875_602,
    1.0,
    0.785_694_958,
    0.541_196_100,
    0.275_899_379,
];

/// A Huffman table as codes per symbol: `code[s]` in the low `len[s]` bits.
#[derive(Clone)]
struct Codes {
    code: [u16; 256],
    len: [u8; 256],
}

impl Codes {
    /// Canonical codes from the counts per length (Annex C).
    fn new(spec: &([u8; 16], &[u8])) -> Self {
        let (counts, symbols) = spec;
        let mut codes = Codes {
            code: [0; 256],
            len: [0; 256],
        };
        let mut code = 0u16;
        let mut k = 0;
        for (i, &n) in counts.iter().enumerate() {
            for _ in 0..n {
                let s = symbols[k] as usize;
                codes.code[s] = code;
                codes.len[s] = i as u8 + 1;
                code += 1;
                k += 1;
            }
            code <<= 1;
        }
        codes
    }

    /// The code of symbol `s` followed by `size` value bits, as one field: (bits, length).
    #[inline(always)]
    fn with_value(&self, s: usize, size: u32, value: u32) -> (u64, u32) {
        let len = self.len[s] as u32;
        (((self.code[s] as u64) << size) | value as u64, len + size)
    }
}

/// `base` ([`LUMA_Q`] or [`CHROMA_Q`]) scaled to `quality` (1–100; outside, the nearest end)
/// as libjpeg scales it (`5000/q` below 50, else `200 − 2q`, in per cent, rounded), each
/// entry within 1–255 as baseline JPEG allows; natural order.
pub fn scaled_table(base: &[u16; 64], quality: u32) -> [u16; 64] {
    let q = quality.clamp(1, 100);
    let scale = if q < 50 { 5000 / q } else { 200 - 2 * q };
    std::array::from_fn(|i| ((base[i] as u32 * scale + 50) / 100).clamp(1, 255) as u16)
}

/// The multiplier that turns the DCT's output at position `p` of its transposed layout into
/// the quantised coefficient: `1 / (8 · q · aan[u] · aan[v])`. The two passes leave the
/// horizontal frequency in the row (`p = v·8 + u`).
fn multipliers(table: &[u16; 64]) -> [f32; 64] {
    std::array::from_fn(|p| {
        let (v, u) = (p / 8, p % 8); // v: horizontal frequency, u: vertical
        let q = table[u * 8 + v] as f64;
        (1.0 / (8.0 * q * AAN_SCALE[u] * AAN_SCALE[v])) as f32
    })
}

/// `ZIGZAG` read in the DCT's transposed layout: the position of the `k`-th coefficient.
const fn transposed_zigzag() -> [usize; 64] {
    let mut t = [0usize; 64];
    let mut k = 0;
    while k < 64 {
        let n = ZIGZAG[k];
        t[k] = (n % 8) * 8 + n / 8;
        k += 1;
    }
    t
}
const ZIGZAG_T: [usize; 64] = transposed_zigzag();

/// One pass of the AAN float DCT down the eight columns of `d` at once (each row a vector
/// of eight lanes), in place: `d[k]` becomes frequency `k` of every column (unscaled).
#[inline(always)]
fn dct_columns(d: &mut [[f32; 8]; 8]) {
    for c in 0..8 {
        let t0 = d[0][c] + d[7][c];
        let t7 = d[0][c] - d[7][c];
        let t1 = d[1][c] + d[6][c];
        let t6 = d[1][c] - d[6][c];
        let t2 = d[2][c] + d[5][c];
        let t5 = d[2][c] - d[5][c];
        let t3 = d[3][c] + d[4][c];
        let t4 = d[3][c] - d[4][c];
        // Even part.
        let t10 = t0 + t3;
        let t13 = t0 - t3;
        let t11 = t1 + t2;
        let t12 = t1 - t2;
        d[0][c] = t10 + t11;
        d[4][c] = t10 - t11;
        let z1 = (t12 + t13) * 0.707_106_77;
        d[2][c] = t13 + z1;
        d[6][c] = t13 - z1;
        // Odd part.
        let t10 = t4 + t5;
        let t11 = t5 + t6;
        let t12 = t6 + t7;
        let z5 = (t10 - t12) * 0.382_683_43;
        let z2 = t10 * 0.541_196_1 + z5;
        let z4 = t12 * 1.306_563 + z5;
        let z3 = t11 * 0.707_106_77;
        let z11 = t7 + z3;
        let z13 = t7 - z3;
        d[5][c] = z13 + z2;
        d[3][c] = z13 - z2;
        d[1][c] = z11 + z4;
        d[7][c] = z11 - z4;
    }
}

#[inline(always)]
fn transpose(d: &mut [[f32; 8]; 8]) {
    for r in 0..8 {
        for c in r + 1..8 {
            let t = d[r][c];
            d[r][c] = d[c][r];
            d[c][r] = t;
        }
    }
}

/// The 64-bit bit buffer with JPEG's byte stuffing: bits fill `acc` from the top; `free`
/// (1–64) bits are left at its bottom.
struct BitWriter {
    out: Vec<u8>,
    acc: u64,
    free: u32,
}

impl BitWriter {
    /// Appends the low `len` (≤ 32) bits of `bits` (no bit above them is set).
    #[inline(always)]
    fn put(&mut self, bits: u64, len: u32) {
        if len < self.free {
            self.free -= len;
            self.acc |= bits << self.free;
        } else {
            let rest = len - self.free;
            let word = self.acc | (bits >> rest);
            self.word(word);
            self.free = 64 - rest;
            self.acc = if rest == 0 { 0 } else { bits << self.free };
        }
    }

    /// Writes eight bytes, each `0xFF` followed by a stuffed `0x00`.
    #[inline(always)]
    fn word(&mut self, word: u64) {
        const ONES: u64 = 0x0101_0101_0101_0101;
        const HIGHS: u64 = 0x8080_8080_8080_8080;
        let inv = !word; // a 0xFF byte of `word` is a zero byte of `inv`
        if inv.wrapping_sub(ONES) & !inv & HIGHS == 0 {
            self.out.extend_from_slice(&word.to_be_bytes());
        } else {
            for b in word.to_be_bytes() {
                self.out.push(b);
                if b == 0xFF {
                    self.out.push(0);
                }
            }
        }
    }

    /// Pads the last byte with one bits and writes what is left.
    fn finish(mut self) -> Vec<u8> {
        let used = 64 - self.free;
        if used > 0 {
            let pad = (8 - used % 8) % 8;
            let acc = self.acc | (((1u64 << pad) - 1) << (self.free - pad));
            for b in acc.to_be_bytes().iter().take(((used + pad) / 8) as usize) {
                self.out.push(*b);
                if *b == 0xFF {
                    self.out.push(0);
                }
            }
        }
        self.out
    }
}

/// A value's size category and its value bits (negative values as `v − 1` in `size` bits).
#[inline(always)]
fn magnitude(v: i32) -> (u32, u32) {
    let size = 32 - v.unsigned_abs().leading_zeros();
    let bits = if v < 0 { (v - 1) as u32 } else { v as u32 };
    (size, bits & ((1u32 << size) - 1))
}

/// One component's tables and DC predictor.
#[derive(Clone)]
struct Component {
    mult: [f32; 64],
    dc: Codes,
    ac: Codes,
    pred: i32,
}

impl Component {
    /// A component quantised by `table` (natural order) and coded by the Huffman tables
    /// `dc` and `ac`, its DC predictor at 0.
    fn new(table: &[u16; 64], dc: &([u8; 16], &[u8]), ac: &([u8; 16], &[u8])) -> Self {
        Component {
            mult: multipliers(table),
            dc: Codes::new(dc),
            ac: Codes::new(ac),
            pred: 0,
        }
    }

    /// Transforms, quantises and codes one level-shifted 8×8 block.
    #[inline(always)]
    fn block(&mut self, d: &mut [[f32; 8]; 8], bits: &mut BitWriter) {
        dct_columns(d);
        transpose(d);
        dct_columns(d);
        let mut q = [0i32; 64];
        for (qp, (&v, &m)) in q.iter_mut().zip(d.as_flattened().iter().zip(&self.mult)) {
            // Within ±1023 (AC fits 10 bits and DC 11, as baseline allows; reached only by
            // extreme synthetic input), then rounded half to even by adding 1.5·2²³: the sum's
            // low mantissa bits are then the integer, read off its bit pattern (exact for
            // |x| < 2²²; vector adds, where `round_ties_even` may be a call and `as i32` a
            // scalar conversion per lane).
            const MAGIC: f32 = 12_582_912.0;
            let x = (v * m).clamp(-1023.0, 1023.0);
            *qp = (x + MAGIC).to_bits() as i32 - MAGIC.to_bits() as i32;
        }
        let mut zz = [0i32; 64];
        let mut mask = 0u64;
        for k in 0..64 {
            zz[k] = q[ZIGZAG_T[k]];
            mask |= ((zz[k] != 0) as u64) << k;
        }
        let diff = zz[0] - self.pred;
        self.pred = zz[0];
        let (size, value) = magnitude(diff);
        let (b, l) = self.dc.with_value(size as usize, size, value);
        bits.put(b, l);
        let mut rest = mask >> 1; // bit i: coefficient i + 1
        let mut k = 1usize;
        while rest != 0 {
            let zeros = rest.trailing_zeros();
            let mut run = zeros;
            while run >= 16 {
                let (b, l) = self.ac.with_value(0xF0, 0, 0);
                bits.put(b, l);
                run -= 16;
            }
            let pos = k + zeros as usize;
            let (size, value) = magnitude(zz[pos]);
            let (b, l) = self
                .ac
                .with_value(((run << 4) | size) as usize, size, value);
            bits.put(b, l);
            rest >>= zeros + 1;
            k = pos + 1;
        }
        if k < 64 {
            let (b, l) = self.ac.with_value(0x00, 0, 0);
            bits.put(b, l);
        }
    }
}

/// Fills the level-shifted Y, Cb and Cr blocks of the 8×8 pixels at (`x0`, `y0`), the
/// frame's last column and row repeated past its edge.
#[inline(always)]
fn fill_blocks(
    rgb: &[u8],
    width: usize,
    height: usize,
    x0: usize,
    y0: usize,
    out: &mut [[[f32; 8]; 8]; 3],
) {
    let inside = x0 + 8 <= width;
    for r in 0..8 {
        let y = (y0 + r).min(height - 1);
        let row = &rgb[y * width * 3..(y + 1) * width * 3];
        let mut px = [[0f32; 8]; 3];
        if inside {
            let s = &row[x0 * 3..x0 * 3 + 24];
            for c in 0..8 {
                px[0][c] = s[c * 3] as f32;
                px[1][c] = s[c * 3 + 1] as f32;
                px[2][c] = s[c * 3 + 2] as f32;
            }
        } else {
            for c in 0..8 {
                let x = (x0 + c).min(width - 1);
                px[0][c] = row[x * 3] as f32;
                px[1][c] = row[x * 3 + 1] as f32;
                px[2][c] = row[x * 3 + 2] as f32;
            }
        }
        for c in 0..8 {
            let (red, green, blue) = (px[0][c], px[1][c], px[2][c]);
            out[0][r][c] = red * 0.299 + green * 0.587 + blue * 0.114 - 128.0;
            out[1][r][c] = red * -0.168_736 + green * -0.331_264 + blue * 0.5;
            out[2][r][c] = red * 0.5 + green * -0.418_688 + blue * -0.081_312;
        }
    }
}

/// Encodes a row-major RGB8 frame (`width × height × 3` bytes, sides 1–65535) as a baseline
/// JFIF JPEG at `quality` (1–100), 4:4:4.
pub fn encode_rgb(rgb: &[u8], width: u32, height: u32, quality: u8) -> Result<Vec<u8>, String> {
    encode_rgb_on(rgb, width, height, quality, avx2_available())
}

/// [`encode_rgb`] on the AVX2 build when `avx2` (the CPU checked by the caller).
fn encode_rgb_on(
    rgb: &[u8],
    width: u32,
    height: u32,
    quality: u8,
    avx2: bool,
) -> Result<Vec<u8>, String> {
    let (w, h) = (width as usize, height as usize);
    if w == 0 || h == 0 || w > 65535 || h > 65535 {
        return Err(format!(
            "{width}x{height}: JPEG frames are 1 to 65535 pixels on a side"
        ));
    }
    if rgb.len() != w * h * 3 {
        return Err(format!(
            "{} bytes, expected {} ({width}x{height} RGB8)",
            rgb.len(),
            w * h * 3
        ));
    }
    if !(1..=100).contains(&quality) {
        return Err(format!("JPEG quality {quality} is not in 1..=100"));
    }
    let luma = scaled_table(&LUMA_Q, quality.into());
    let chroma = scaled_table(&CHROMA_Q, quality.into());
    let mut out = Vec::with_capacity(w * h / 2 + 1024);
    header(&mut out, width as u16, height as u16, &luma, &chroma);
    let mut bits = BitWriter {
        out,
        acc: 0,
        free: 64,
    };
    let chroma = Component::new(&chroma, &DC_CHROMA, &AC_CHROMA);
    let mut comps = [
        Component::new(&luma, &DC_LUMA, &AC_LUMA),
        chroma.clone(),
        chroma,
    ];
    scan(rgb, w, h, &mut comps, &mut bits, avx2);
    let mut out = bits.finish();
    out.extend_from_slice(&[0xFF, 0xD9]); // EOI
    Ok(out)
}

/// Whether this CPU runs [`scan_avx2`] (and `FOGLINE_SIMD` is not `portable`).
pub(crate) fn avx2_available() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        static YES: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
        *YES.get_or_init(|| {
            std::env::var("FOGLINE_SIMD").as_deref() != Ok("portable")
                && std::is_x86_feature_detected!("avx2")
                && std::is_x86_feature_detected!("bmi1")
                && std::is_x86_feature_detected!("lzcnt")
        })
    }
    #[cfg(not(target_arch = "x86_64"))]
    false
}

/// Codes every block of the frame, MCU by MCU (one 8×8 block of each component), with the
/// AVX2 build of the same code when `avx2` (which the caller has checked the CPU for).
fn scan(
    rgb: &[u8],
    w: usize,
    h: usize,
    comps: &mut [Component; 3],
    bits: &mut BitWriter,
    avx2: bool,
) {
    #[cfg(target_arch = "x86_64")]
    if avx2 {
        #[allow(unsafe_code)]
        // SAFETY: `avx2` is true only when the CPU has AVX2, BMI1 and LZCNT
        // (`avx2_available`, or a test that checked the same).
        unsafe {
            scan_avx2(rgb, w, h, comps, bits)
        };
        return;
    }
    let _ = avx2;
    scan_blocks(rgb, w, h, comps, bits);
}

/// [`scan_blocks`] compiled for AVX2: the block kernels are inlined here, so the colour
/// conversion, the DCT and the quantisation run eight lanes to a register, and the entropy
/// coder's bit counts are single instructions. The same operations as the portable build,
/// so the same bytes.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,bmi1,lzcnt")]
fn scan_avx2(rgb: &[u8], w: usize, h: usize, comps: &mut [Component; 3], bits: &mut BitWriter) {
    scan_blocks(rgb, w, h, comps, bits);
}

#[inline(always)]
fn scan_blocks(rgb: &[u8], w: usize, h: usize, comps: &mut [Component; 3], bits: &mut BitWriter) {
    let mut blocks = [[[0f32; 8]; 8]; 3];
    for y0 in (0..h).step_by(8) {
        for x0 in (0..w).step_by(8) {
            fill_blocks(rgb, w, h, x0, y0, &mut blocks);
            for (comp, block) in comps.iter_mut().zip(blocks.iter_mut()) {
                comp.block(block, bits);
            }
        }
    }
}

/// SOI, JFIF APP0, the two quantisation tables, SOF0, the four Huffman tables and SOS.
fn header(out: &mut Vec<u8>, width: u16, height: u16, luma: &[u16; 64], chroma: &[u16; 64]) {
    out.extend_from_slice(&[0xFF, 0xD8]);
    // APP0: "JFIF\0", version 1.1, no density unit, 1:1, no thumbnail.
    out.extend_from_slice(&[
        0xFF, 0xE0, 0, 16, b'J', b'F', b'I', b'F', 0, 1, 1, 0, 0, 1, 0, 1, 0, 0,
    ]);
    for (id, table) in [(0u8, luma), (1, chroma)] {
        out.extend_from_slice(&[0xFF, 0xDB, 0, 67, id]);
        out.extend(ZIGZAG.iter().map(|&n| table[n] as u8));
    }
    let [wh, wl] = width.to_be_bytes();
    let [hh, hl] = height.to_be_bytes();
    out.extend_from_slice(&[0xFF, 0xC0, 0, 17, 8, hh, hl, wh, wl, 3]);
    out.extend_from_slice(&[1, 0x11, 0, 2, 0x11, 1, 3, 0x11, 1]);
    for (class_id, (counts, symbols)) in [
        (0x00u8, DC_LUMA),
        (0x10, AC_LUMA),
        (0x01, DC_CHROMA),
        (0x11, AC_CHROMA),
    ] {
        let len = 2 + 1 + 16 + symbols.len();
        out.extend_from_slice(&[0xFF, 0xC4]);
        out.extend_from_slice(&(len as u16).to_be_bytes());
        out.push(class_id);
        out.extend_from_slice(&counts);
        out.extend_from_slice(symbols);
    }
    // SOS: three components (Y: tables 0/0, Cb and Cr: 1/1), full spectral range.
    out.extend_from_slice(&[0xFF, 0xDA, 0, 12, 3, 1, 0x00, 2, 0x11, 3, 0x11, 0, 63, 0]);
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    fn psnr(a: &[u8], b: &[u8]) -> f64 {
        let mse = a
            .iter()
            .zip(b)
            .map(|(&x, &y)| (x as f64 - y as f64).powi(2))
            .sum::<f64>()
            / a.len() as f64;
        10.0 * (255.0f64 * 255.0 / mse.max(1e-12)).log10()
    }

    /// A smooth scene with hard edges and saturated colours, deterministic.
    fn scene(w: usize, h: usize, seed: u64) -> Vec<u8> {
        let mut s = seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1;
        let mut rng = move || {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            s
        };
        let mut px = vec![0u8; w * h * 3];
        for y in 0..h {
            for x in 0..w {
                let i = (y * w + x) * 3;
                px[i] = (x * 255 / w.max(1)) as u8;
                px[i + 1] = (y * 255 / h.max(1)) as u8;
                px[i + 2] = if (x / 7 + y / 5) % 2 == 0 { 30 } else { 220 };
            }
        }
        // Rectangles of flat colour, one of them pure red (a lamp), one white.
        for _ in 0..6 {
            let (x0, y0) = ((rng() % w as u64) as usize, (rng() % h as u64) as usize);
            let (rw, rh) = (1 + (rng() % 12) as usize, 1 + (rng() % 12) as usize);
            let c = [
                (rng() % 256) as u8,
                (rng() % 256) as u8,
                (rng() % 256) as u8,
            ];
            for y in y0..(y0 + rh).min(h) {
                for x in x0..(x0 + rw).min(w) {
                    px[(y * w + x) * 3..(y * w + x) * 3 + 3].copy_from_slice(&c);
                }
            }
        }
        px
    }

    fn decode(jpeg: &[u8]) -> (u32, u32, Vec<u8>) {
        let img = image::load_from_memory_with_format(jpeg, image::ImageFormat::Jpeg)
            .unwrap()
            .to_rgb8();
        (img.width(), img.height(), img.into_raw())
    }

    #[test]
    fn frames_of_every_shape_decode_to_their_size_and_close_to_the_source() {
        for (w, h) in [
            (1, 1),
            (8, 8),
            (7, 5),
            (9, 17),
            (33, 8),
            (64, 48),
            (192, 144),
        ] {
            for quality in [10u8, 50, 75, 95, 100] {
                let src = scene(w, h, (w * 31 + h) as u64);
                let jpeg = encode_rgb(&src, w as u32, h as u32, quality).unwrap();
                assert_eq!(&jpeg[..2], &[0xFF, 0xD8]);
                assert_eq!(&jpeg[jpeg.len() - 2..], &[0xFF, 0xD9]);
                let (dw, dh, back) = decode(&jpeg);
                assert_eq!((dw, dh), (w as u32, h as u32));
                // As close to the source as an independent writer at the same setting.
                let (p, p_theirs) = (
                    psnr(&src, &back),
                    psnr(&src, &decode(&theirs(&src, w, h, quality)).2),
                );
                assert!(
                    p > p_theirs - 0.5,
                    "{w}x{h} q{quality}: PSNR {p:.1} dB, theirs {p_theirs:.1}"
                );
                if quality >= 95 {
                    assert!(p > 30.0, "{w}x{h} q{quality}: PSNR {p:.1} dB");
                }
            }
        }
    }

    /// The jpeg-encoder crate's file at `quality`, 4:4:4 (the same tables).
    fn theirs(src: &[u8], w: usize, h: usize, quality: u8) -> Vec<u8> {
        let mut out = Vec::new();
        let mut enc = jpeg_encoder::Encoder::new(&mut out, quality);
        enc.set_sampling_factor(jpeg_encoder::SamplingFactor::F_1_1);
        enc.encode(src, w as u16, h as u16, jpeg_encoder::ColorType::Rgb)
            .unwrap();
        out
    }

    #[test]
    fn quality_95_is_as_faithful_as_another_encoder_at_the_same_setting() {
        // The jpeg-encoder crate (4:4:4, the same tables) as an independent writer: the
        // decoded frames must be as close to the source and the files about as large.
        let (w, h) = (576usize, 320usize);
        let src = scene(w, h, 7);
        let ours = encode_rgb(&src, w as u32, h as u32, 95).unwrap();
        let theirs = theirs(&src, w, h, 95);
        let (p_ours, p_theirs) = (psnr(&src, &decode(&ours).2), psnr(&src, &decode(&theirs).2));
        assert!(
            p_ours > 30.0 && p_ours > p_theirs - 0.3,
            "{p_ours} vs {p_theirs}"
        );
        let ratio = ours.len() as f64 / theirs.len() as f64;
        assert!((0.9..1.1).contains(&ratio), "size ratio {ratio}");
    }

    #[test]
    fn stuffing_and_extreme_values_decode() {
        // Full-range noise makes many 0xFF bytes in the entropy data and the largest
        // coefficients; flat black and white frames the largest DC values.
        let (w, h) = (40usize, 24usize);
        let mut s = 0x1234_5678u32;
        let noise: Vec<u8> = (0..w * h * 3)
            .map(|_| {
                s = s.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
                (s >> 24) as u8
            })
            .collect();
        let checker: Vec<u8> = (0..w * h)
            .flat_map(|i| {
                let v = if ((i % w) + (i / w)) % 2 == 0 { 0 } else { 255 };
                [v, v, v]
            })
            .collect();
        for src in [noise, checker, vec![0u8; w * h * 3], vec![255u8; w * h * 3]] {
            for quality in [1u8, 50, 100] {
                let jpeg = encode_rgb(&src, w as u32, h as u32, quality).unwrap();
                let (_, _, back) = decode(&jpeg);
                assert_eq!(back.len(), src.len());
                if quality == 100 {
                    assert!(psnr(&src, &back) > 20.0);
                }
            }
        }
        assert_eq!(
            decode(&encode_rgb(&[255u8; 48], 4, 4, 100).unwrap()).2,
            vec![255u8; 48]
        );
    }

    #[test]
    fn the_avx2_build_writes_the_portable_builds_bytes() {
        if !avx2_available() {
            return; // nothing to compare on this CPU: the portable build is the only one
        }
        for (w, h) in [(1, 1), (9, 17), (64, 48), (576, 320)] {
            for quality in [1u8, 50, 95, 100] {
                let src = scene(w, h, (w + h) as u64);
                let vector = encode_rgb_on(&src, w as u32, h as u32, quality, true).unwrap();
                let portable = encode_rgb_on(&src, w as u32, h as u32, quality, false).unwrap();
                assert!(vector == portable, "{w}x{h} q{quality}");
            }
        }
    }

    #[test]
    fn bad_frames_are_refused_with_the_reason() {
        assert!(
            encode_rgb(&[0; 3], 0, 1, 90)
                .unwrap_err()
                .contains("1 to 65535")
        );
        assert!(
            encode_rgb(&[0; 5], 1, 2, 90)
                .unwrap_err()
                .contains("expected 6")
        );
        assert!(
            encode_rgb(&[0; 3], 1, 1, 0)
                .unwrap_err()
                .contains("quality 0")
        );
    }

    #[test]
    fn the_bit_writer_stuffs_every_ff_and_pads_with_ones() {
        let mut bw = BitWriter {
            out: Vec::new(),
            acc: 0,
            free: 64,
        };
        // 0xFF in the middle of a full word, then 3 bits: 101 → padded 10111111 = 0xBF.
        for byte in [0x12u64, 0xFF, 0x34, 0x56, 0x78, 0x9A, 0xBC, 0xDE] {
            bw.put(byte, 8);
        }
        bw.put(0b101, 3);
        assert_eq!(
            bw.finish(),
            vec![0x12, 0xFF, 0x00, 0x34, 0x56, 0x78, 0x9A, 0xBC, 0xDE, 0xBF]
        );
        let mut bw = BitWriter {
            out: Vec::new(),
            acc: 0,
            free: 64,
        };
        // Fields that straddle the word boundary, of every length.
        let mut expect_bits = Vec::new();
        let mut s = 99u32;
        for _ in 0..500 {
            s = s.wrapping_mul(1_103_515_245).wrapping_add(12345);
            let len = 1 + (s >> 16) % 27;
            let v = (s as u64) & ((1u64 << len) - 1);
            bw.put(v, len);
            for i in (0..len).rev() {
                expect_bits.push(((v >> i) & 1) as u8);
            }
        }
        while expect_bits.len() % 8 != 0 {
            expect_bits.push(1);
        }
        let mut expect = Vec::new();
        for byte in expect_bits.chunks(8) {
            let b = byte.iter().fold(0u8, |a, &x| (a << 1) | x);
            expect.push(b);
            if b == 0xFF {
                expect.push(0);
            }
        }
        assert_eq!(bw.finish(), expect);
    }
}
