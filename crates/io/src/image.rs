//! Frame encoding: one PNG and JPEG encoder for every crate (the wire formats of the remote
//! planners, the clip format's frames and depth maps, the perturbed frames the CLI writes,
//! the images sent to a language model), and the `data:` URL of an encoded frame (what a
//! language model receives and what the HTML report inlines).

use image::codecs::png::{CompressionType, FilterType, PngEncoder};
use image::{ExtendedColorType, ImageEncoder};

/// How a frame is encoded.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum ImageFormat {
    /// PNG: lossless, so a reader sees exactly the pixels fogline produced (the default).
    #[default]
    Png,
    /// JPEG at a quality of 1–100: smaller, lossy.
    Jpeg {
        /// The JPEG quality, 1–100.
        quality: u8,
    },
}

impl ImageFormat {
    /// `png` or `jpeg`.
    pub fn name(self) -> &'static str {
        match self {
            ImageFormat::Png => "png",
            ImageFormat::Jpeg { .. } => "jpeg",
        }
    }

    /// The media type: `image/png` or `image/jpeg`.
    pub fn mime(self) -> &'static str {
        match self {
            ImageFormat::Png => "image/png",
            ImageFormat::Jpeg { .. } => "image/jpeg",
        }
    }
}

/// The `data:` URL of an encoded frame (`data:image/png;base64,…`, standard base64 with
/// padding): how frames travel to an OpenAI-compatible model and into the HTML report.
pub fn data_url(encoded: &[u8], format: ImageFormat) -> String {
    use base64::Engine as _;
    let b64 = base64::engine::general_purpose::STANDARD;
    format!("data:{};base64,{}", format.mime(), b64.encode(encoded))
}

/// How hard the PNG encoder works.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum PngSpeed {
    /// Fast deflate with adaptive filters: files and images for a model.
    #[default]
    Fast,
    /// Fast deflate with the Sub filter (no per-row filter search): remote planner calls,
    /// where the encode on one side and the decode on the other are the whole cost. About
    /// 45 % less encode and 20 % less decode time than `Fast` on the world's 576×320
    /// frames, for 4 % more bytes. A frame that does not compress (sensor noise: σ 30
    /// leaves deflate nothing to find) is sent in stored deflate blocks instead: every
    /// 32nd row is compressed first, and when that sample shrinks by less than
    /// [`WIRE_MIN_SAVING`] the whole frame is not tried — deflate would spend ~2 ms per
    /// 576×320 frame to save nothing.
    Wire,
    /// Paeth filters and light deflate: files written once and read often (the clip format).
    Archive,
}

/// Which encoder writes `format` (PNG at `speed`), in words, for benchmarks and logs:
/// `png crate, fast deflate, adaptive filter` or `fogline's encoder, quality 95, 4:4:4, AVX2`.
pub fn encoder_name(format: ImageFormat, speed: PngSpeed) -> String {
    match format {
        ImageFormat::Png => format!(
            "png crate, fast deflate, {}",
            match speed {
                PngSpeed::Fast => "adaptive filter",
                PngSpeed::Wire => "Sub filter, stored when a sample of rows saves < 10 %",
                PngSpeed::Archive => "Paeth filter",
            }
        ),
        ImageFormat::Jpeg { quality } => format!(
            "fogline's encoder, quality {quality}, 4:4:4, {}",
            if crate::jpeg::avx2_available() {
                "AVX2"
            } else {
                "portable"
            }
        ),
    }
}

/// Encodes one RGB8 row-major frame of `width × height` pixels (PNG at [`PngSpeed::Fast`]).
pub fn encode(rgb: &[u8], width: u32, height: u32, format: ImageFormat) -> Result<Vec<u8>, String> {
    encode_with(rgb, width, height, format, PngSpeed::Fast)
}

/// Encodes one RGB8 row-major frame of `width × height` pixels, a PNG at `speed`. JPEG is
/// written by fogline's own encoder ([`crate::jpeg`]: baseline, libjpeg's quality scaling,
/// no chroma subsampling — 4:4:4 — the same bytes on every CPU).
pub fn encode_with(
    rgb: &[u8],
    width: u32,
    height: u32,
    format: ImageFormat,
    speed: PngSpeed,
) -> Result<Vec<u8>, String> {
    check_frame(rgb.len(), width, height, format)?;
    match format {
        ImageFormat::Png => encode_png(rgb, width, height, ExtendedColorType::Rgb8, speed),
        ImageFormat::Jpeg { quality } => crate::jpeg::encode_rgb(rgb, width, height, quality),
    }
}

/// Whether a frame of `len` bytes, `width × height` RGB8, can be encoded as `format`: the
/// checks [`encode_with`] makes before encoding, with its error text, so a caller that
/// encodes later (in a pipeline) can refuse bad input up front.
pub fn check_frame(len: usize, width: u32, height: u32, format: ImageFormat) -> Result<(), String> {
    let expected = width as usize * height as usize * 3;
    if len != expected {
        return Err(format!(
            "{len} bytes, expected {expected} ({width}x{height} RGB8)"
        ));
    }
    if let ImageFormat::Jpeg { quality } = format {
        if !(1..=100).contains(&quality) {
            return Err(format!("JPEG quality {quality} is not in 1..=100"));
        }
        if u16::try_from(width).is_err() || u16::try_from(height).is_err() {
            return Err(format!(
                "{width}x{height}: JPEG frames are at most 65535 pixels on a side"
            ));
        }
    }
    Ok(())
}

/// Encodes a PNG of any colour type the `image` crate writes (RGB8 frames, 16-bit grey
/// depth maps as big-endian bytes).
pub fn encode_png(
    data: &[u8],
    width: u32,
    height: u32,
    color: ExtendedColorType,
    speed: PngSpeed,
) -> Result<Vec<u8>, String> {
    let (compression, filter) = match (speed, color) {
        (PngSpeed::Fast, _) => (CompressionType::Fast, FilterType::Adaptive),
        (PngSpeed::Wire, _) if !worth_compressing(data, width, height, color)? => {
            (CompressionType::Uncompressed, FilterType::NoFilter)
        }
        (PngSpeed::Wire, _) => (CompressionType::Fast, FilterType::Sub),
        (PngSpeed::Archive, ExtendedColorType::L16) => {
            (CompressionType::Level(1), FilterType::Paeth)
        }
        (PngSpeed::Archive, _) => (CompressionType::Fast, FilterType::Paeth),
    };
    let mut out = Vec::with_capacity(data.len() / 4 + 1024);
    PngEncoder::new_with_quality(&mut out, compression, filter)
        .write_image(data, width, height, color)
        .map_err(|e| format!("cannot encode as png: {e}"))?;
    Ok(out)
}

/// The least share of its bytes a sample of a frame must lose to deflate for
/// [`PngSpeed::Wire`] to compress the frame (otherwise it is stored).
pub const WIRE_MIN_SAVING: f64 = 0.10;

/// One row in this many is the sample [`PngSpeed::Wire`] compresses to decide (ten rows of
/// a 576×320 frame: enough for deflate to show what it finds, at 3 % of the frame's cost).
const WIRE_SAMPLE_STEP: usize = 32;

/// Whether deflate finds enough in `data` to be worth running over all of it: every 32nd
/// row (Sub filter, fast deflate) must shrink by at least [`WIRE_MIN_SAVING`].
fn worth_compressing(
    data: &[u8],
    width: u32,
    height: u32,
    color: ExtendedColorType,
) -> Result<bool, String> {
    let row = data.len() / height.max(1) as usize;
    if row == 0 || (height as usize) < 2 * WIRE_SAMPLE_STEP {
        return Ok(true);
    }
    // Row by row (a byte-wise iterator copy costs as much as the sample's deflate).
    let mut sample = Vec::with_capacity(row * (height as usize).div_ceil(WIRE_SAMPLE_STEP));
    for r in data.chunks_exact(row).step_by(WIRE_SAMPLE_STEP) {
        sample.extend_from_slice(r);
    }
    let rows = (sample.len() / row) as u32;
    let mut out = Vec::with_capacity(sample.len() / 2 + 1024);
    PngEncoder::new_with_quality(&mut out, CompressionType::Fast, FilterType::Sub)
        .write_image(&sample, width, rows, color)
        .map_err(|e| format!("cannot encode as png: {e}"))?;
    Ok((out.len() as f64) < (1.0 - WIRE_MIN_SAVING) * sample.len() as f64)
}

pub use image::ExtendedColorType as ColorType;

/// A decoded RGB8 frame.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct DecodedRgb {
    /// Width, px.
    pub width: u32,
    /// Height, px.
    pub height: u32,
    /// RGB8, row-major, `width × height × 3` bytes.
    pub rgb: Vec<u8>,
}

/// Decodes a PNG or JPEG file's bytes (the format guessed from its signature) to RGB8; an
/// image with another colour type is converted.
pub fn decode_rgb(bytes: &[u8]) -> Result<DecodedRgb, String> {
    let img = image::load_from_memory(bytes).map_err(|e| format!("cannot decode: {e}"))?;
    let rgb = img.to_rgb8();
    Ok(DecodedRgb {
        width: rgb.width(),
        height: rgb.height(),
        rgb: rgb.into_raw(),
    })
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    #[test]
    fn png_round_trips_exactly_and_sizes_are_checked() {
        let rgb: Vec<u8> = (0..(7 * 5 * 3)).map(|i| (i * 13 % 256) as u8).collect();
        for speed in [PngSpeed::Fast, PngSpeed::Wire, PngSpeed::Archive] {
            let png = encode_png(&rgb, 7, 5, ColorType::Rgb8, speed).unwrap();
            let back = image::load_from_memory(&png).unwrap().to_rgb8();
            assert_eq!(back.as_raw(), &rgb);
        }
        assert!(
            encode(&rgb[1..], 7, 5, ImageFormat::Png)
                .unwrap_err()
                .contains("expected 105")
        );
        assert!(encode(&rgb, 7, 5, ImageFormat::Jpeg { quality: 0 }).is_err());
        let jpeg = encode(&rgb, 7, 5, ImageFormat::Jpeg { quality: 90 }).unwrap();
        assert_eq!(&jpeg[..2], &[0xFF, 0xD8]);
        let png = encode(&rgb, 7, 5, ImageFormat::Png).unwrap();
        let back = decode_rgb(&png).unwrap();
        assert_eq!((back.width, back.height, back.rgb), (7, 5, rgb.clone()));
        assert_eq!(decode_rgb(&jpeg).unwrap().rgb.len(), rgb.len());
        assert!(decode_rgb(b"not an image").is_err());
        assert_eq!(
            data_url(b"abc", ImageFormat::Png),
            "data:image/png;base64,YWJj"
        );
        assert!(
            data_url(&jpeg, ImageFormat::Jpeg { quality: 90 })
                .starts_with("data:image/jpeg;base64,/9j/")
        );
    }

    /// A smooth 96 × 64 scene with edges (a gradient sky, a road, a box), as frames look.
    fn scene() -> Vec<u8> {
        let (w, h) = (96usize, 64usize);
        let mut rgb = Vec::with_capacity(w * h * 3);
        for y in 0..h {
            for x in 0..w {
                let px = if (40..56).contains(&x) && (30..44).contains(&y) {
                    [200, 30, 40]
                } else if y > 32 {
                    [90, 92, 95]
                } else {
                    [100 + (y * 3) as u8, 140 + (x / 2) as u8, 230]
                };
                rgb.extend_from_slice(&px);
            }
        }
        rgb
    }

    #[test]
    fn wire_png_stores_frames_deflate_cannot_shrink_and_compresses_the_rest() {
        // A smooth scene compresses; the same scene under σ 30 noise (a seeded LCG, Box-Muller)
        // is stored; both round-trip exactly.
        let smooth = scene();
        let mut state = 0x2545_f491_4f6c_dd1du64;
        let mut uniform = || {
            state = state
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            ((state >> 11) as f64 + 0.5) / (1u64 << 53) as f64
        };
        let noisy: Vec<u8> = smooth
            .iter()
            .map(|&v| {
                let g = (-2.0 * uniform().ln()).sqrt() * (std::f64::consts::TAU * uniform()).cos();
                (f64::from(v) + 30.0 * g).round().clamp(0.0, 255.0) as u8
            })
            .collect();
        let wire = |rgb: &[u8]| encode_png(rgb, 96, 64, ColorType::Rgb8, PngSpeed::Wire).unwrap();
        let (a, b) = (wire(&smooth), wire(&noisy));
        assert!(a.len() < smooth.len() / 4, "{} bytes", a.len());
        // Stored: the pixels, one filter byte per row and the chunks' framing.
        let raw = noisy.len() + 64;
        assert!(b.len() >= raw && b.len() < raw + 200, "{} bytes", b.len());
        assert!(worth_compressing(&smooth, 96, 64, ColorType::Rgb8).unwrap());
        assert!(!worth_compressing(&noisy, 96, 64, ColorType::Rgb8).unwrap());
        for (png, rgb) in [(a, smooth), (b, noisy)] {
            assert_eq!(
                image::load_from_memory(&png).unwrap().to_rgb8().as_raw(),
                &rgb
            );
        }
    }

    #[test]
    fn jpeg_95_decodes_close_to_the_source_with_full_chroma() {
        let rgb = scene();
        let jpeg = encode(&rgb, 96, 64, ImageFormat::Jpeg { quality: 95 }).unwrap();
        // Decoded by the `image` crate's decoder (zune-jpeg), not by the encoder's crate.
        let back = image::load_from_memory(&jpeg).unwrap().to_rgb8();
        let mse = rgb
            .iter()
            .zip(back.as_raw())
            .map(|(&a, &b)| (f64::from(a) - f64::from(b)).powi(2))
            .sum::<f64>()
            / rgb.len() as f64;
        let psnr = 10.0 * (255.0f64 * 255.0 / mse.max(1e-9)).log10();
        assert!(psnr > 38.0, "PSNR {psnr:.1} dB");
        // The red box keeps its colour at its edge pixels (no 2×2 chroma averaging).
        let at = |x: usize, y: usize| &back.as_raw()[(y * 96 + x) * 3..(y * 96 + x) * 3 + 3];
        let edge = at(40, 30);
        assert!(edge[0] > 170 && edge[1] < 70, "{edge:?}");
        // The same frame gives the same bytes.
        assert_eq!(
            jpeg,
            encode(&rgb, 96, 64, ImageFormat::Jpeg { quality: 95 }).unwrap()
        );
        assert!(
            encode(
                &vec![0; 70_000 * 3],
                70_000,
                1,
                ImageFormat::Jpeg { quality: 95 }
            )
            .unwrap_err()
            .contains("65535")
        );
    }
}
