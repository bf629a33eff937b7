//! Frame encoding for the wire (PNG or JPEG), decoding on the serving side, and session
//! identifiers.

use std::sync::atomic::{AtomicU64, Ordering};
use std::time::{SystemTime, UNIX_EPOCH};

use crate::ImageFormat;

/// Encodes one RGB8 row-major frame of `width × height` pixels for the wire
/// ([`fogline_io::encode_with`], PNG at [`fogline_io::PngSpeed::Wire`]).
pub(crate) fn encode(
    rgb: &[u8],
    width: u32,
    height: u32,
    format: ImageFormat,
) -> Result<Vec<u8>, String> {
    fogline_io::encode_with(rgb, width, height, format, fogline_io::PngSpeed::Wire)
}

/// A decoded frame: width, height and RGB8 row-major pixels.
pub(crate) struct Decoded {
    pub width: u32,
    pub height: u32,
    pub rgb: Vec<u8>,
}

/// The format of an image that must be PNG or JPEG, from its first bytes.
fn png_or_jpeg(bytes: &[u8]) -> Result<image::ImageFormat, String> {
    if bytes.is_empty() {
        return Err("the image is empty".into());
    }
    let format = image::guess_format(bytes)
        .map_err(|_| "the image is neither PNG nor JPEG (unrecognised header)".to_string())?;
    if !matches!(format, image::ImageFormat::Png | image::ImageFormat::Jpeg) {
        return Err(format!("the image is {format:?}; PNG or JPEG expected"));
    }
    Ok(format)
}

/// Decodes a PNG or JPEG image (any colour type) to RGB8.
pub(crate) fn decode(bytes: &[u8]) -> Result<Decoded, String> {
    let format = png_or_jpeg(bytes)?;
    let img = image::load_from_memory_with_format(bytes, format)
        .map_err(|e| format!("cannot decode the {format:?} image: {e}"))?
        .into_rgb8();
    Ok(Decoded {
        width: img.width(),
        height: img.height(),
        rgb: img.into_raw(),
    })
}

/// [`decode`] for an image that must be `width × height` (as `declared_by` says, for the
/// error): the size is read from the image's header first, so an image that claims more
/// pixels than expected is refused before anything is allocated for it.
pub(crate) fn decode_sized(
    bytes: &[u8],
    width: u32,
    height: u32,
    declared_by: &str,
) -> Result<Decoded, String> {
    let format = png_or_jpeg(bytes)?;
    let (w, h) = image::ImageReader::with_format(std::io::Cursor::new(bytes), format)
        .into_dimensions()
        .map_err(|e| format!("cannot read the {format:?} image's header: {e}"))?;
    if (w, h) != (width, height) {
        return Err(format!(
            "the image is {w}x{h} but {declared_by} says {width}x{height}"
        ));
    }
    let d = decode(bytes)?;
    if (d.width, d.height) != (width, height) {
        return Err(format!(
            "the image decodes to {}x{} but {declared_by} says {width}x{height}",
            d.width, d.height
        ));
    }
    Ok(d)
}

/// [`decode`] for an image of at most `max_pixels` pixels, read from its header before
/// anything is allocated for it.
pub(crate) fn decode_capped(bytes: &[u8], max_pixels: u64) -> Result<Decoded, String> {
    let format = png_or_jpeg(bytes)?;
    let (w, h) = image::ImageReader::with_format(std::io::Cursor::new(bytes), format)
        .into_dimensions()
        .map_err(|e| format!("cannot read the {format:?} image's header: {e}"))?;
    if u64::from(w) * u64::from(h) > max_pixels {
        return Err(format!(
            "the image is {w}x{h}, more than the limit of {max_pixels} pixels"
        ));
    }
    decode(bytes)
}

/// Work below this many bytes is not worth a thread.
pub(crate) const PARALLEL_BYTES: usize = 1 << 20;

/// Applies `f` to every item, spread over the machine's cores when `bytes` (the work's
/// size) is large enough to pay for the threads; the results keep the items' order.
pub(crate) fn par_map<T: Sync, R: Send>(
    items: &[T],
    bytes: usize,
    f: impl Fn(&T) -> R + Sync,
) -> Vec<R> {
    let threads = std::thread::available_parallelism()
        .map_or(1, |n| n.get())
        .min(items.len());
    if threads <= 1 || bytes < PARALLEL_BYTES {
        return items.iter().map(f).collect();
    }
    let chunk = items.len().div_ceil(threads);
    let f = &f;
    std::thread::scope(|s| {
        let handles: Vec<_> = items
            .chunks(chunk)
            .map(|c| s.spawn(move || c.iter().map(f).collect::<Vec<R>>()))
            .collect();
        handles
            .into_iter()
            .flat_map(|h| h.join().unwrap_or_else(|p| std::panic::resume_unwind(p)))
            .collect()
    })
}

fn splitmix(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// A fresh random-looking UUID (version 4 layout), unique within the process (a counter)
/// and, with the clock and the process id mixed in, across processes.
pub(crate) fn session_uuid() -> String {
    static COUNTER: AtomicU64 = AtomicU64::new(0);
    let count = COUNTER.fetch_add(1, Ordering::Relaxed);
    let nanos = SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map(|d| d.as_nanos() as u64)
        .unwrap_or(0);
    let base = splitmix(nanos ^ splitmix(u64::from(std::process::id())));
    let hi = splitmix(base ^ count);
    let lo = splitmix(hi ^ count.rotate_left(29) ^ 0x5EED);
    let hi = (hi & 0xFFFF_FFFF_FFFF_0FFF) | 0x0000_0000_0000_4000;
    let lo = (lo & 0x3FFF_FFFF_FFFF_FFFF) | 0x8000_0000_0000_0000;
    format!(
        "{:08x}-{:04x}-{:04x}-{:04x}-{:012x}",
        hi >> 32,
        (hi >> 16) & 0xFFFF,
        hi & 0xFFFF,
        lo >> 48,
        lo & 0xFFFF_FFFF_FFFF
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn png_round_trip_is_exact() {
        let rgb: Vec<u8> = (0..4 * 3 * 3).map(|i| (i * 7 % 251) as u8).collect();
        let png = encode(&rgb, 4, 3, ImageFormat::Png).expect("encode");
        let back = decode(&png).expect("decode");
        assert_eq!((back.width, back.height), (4, 3));
        assert_eq!(back.rgb, rgb);
    }

    #[test]
    fn wrong_sizes_and_garbage_are_errors() {
        assert!(encode(&[0; 5], 2, 2, ImageFormat::Png).is_err());
        assert!(encode(&[0; 12], 2, 2, ImageFormat::Jpeg { quality: 0 }).is_err());
        assert!(decode(b"not an image").is_err());
        assert!(decode(&[]).is_err());
    }

    #[test]
    fn par_map_keeps_order() {
        let items: Vec<usize> = (0..37).collect();
        assert_eq!(
            par_map(&items, 1 << 30, |i| i * 2),
            par_map(&items, 0, |i| i * 2)
        );
        assert_eq!(par_map(&items, 1 << 30, |i| i * 2)[36], 72);
    }

    #[test]
    fn uuids_are_distinct_and_well_formed() {
        let a = session_uuid();
        let b = session_uuid();
        assert_ne!(a, b);
        assert_eq!(a.len(), 36);
        assert_eq!(&a[14..15], "4");
    }
}
