//! Pixel buffers and what comes with them: depth maps, object boxes, and the key that names
//! a frame's random streams.

use serde::{Deserialize, Serialize};

use crate::PerturbError;

/// An 8-bit RGB image, rows top to bottom, pixels left to right, channels interleaved
/// (`R G B R G B …`), `width × height × 3` bytes, at least 1×1.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Frame {
    width: u32,
    height: u32,
    data: Vec<u8>,
}

impl Frame {
    /// A frame over `data`; fails when the size is zero or `data` has the wrong length.
    pub fn new(width: u32, height: u32, data: Vec<u8>) -> Result<Self, PerturbError> {
        check_layout(width, height, data.len())?;
        Ok(Self {
            width,
            height,
            data,
        })
    }

    /// A frame of one colour.
    pub fn filled(width: u32, height: u32, rgb: [u8; 3]) -> Result<Self, PerturbError> {
        let n = width as usize * height as usize;
        let mut data = Vec::with_capacity(n * 3);
        for _ in 0..n {
            data.extend_from_slice(&rgb);
        }
        Self::new(width, height, data)
    }

    /// Width in pixels.
    pub fn width(&self) -> u32 {
        self.width
    }

    /// Height in pixels.
    pub fn height(&self) -> u32 {
        self.height
    }

    /// The interleaved RGB bytes.
    pub fn data(&self) -> &[u8] {
        &self.data
    }

    /// The interleaved RGB bytes, mutable (the size cannot change).
    pub fn data_mut(&mut self) -> &mut [u8] {
        &mut self.data
    }

    /// The bytes, consuming the frame.
    pub fn into_data(self) -> Vec<u8> {
        self.data
    }

    /// The pixel at column `x`, row `y` (panics outside the frame).
    pub fn pixel(&self, x: u32, y: u32) -> [u8; 3] {
        let i = (y as usize * self.width as usize + x as usize) * 3;
        [self.data[i], self.data[i + 1], self.data[i + 2]]
    }

    /// The frame as a borrowed view.
    pub fn view(&self) -> FrameRef<'_> {
        FrameRef {
            width: self.width,
            height: self.height,
            data: &self.data,
        }
    }

    /// The frame as a writable borrowed view.
    pub fn view_mut(&mut self) -> FrameMut<'_> {
        FrameMut {
            width: self.width,
            height: self.height,
            data: &mut self.data,
        }
    }

    /// Makes `self` a `width × height` frame, reusing its allocation; contents unspecified.
    pub(crate) fn reshape(&mut self, width: u32, height: u32) {
        self.width = width;
        self.height = height;
        self.data.resize(width as usize * height as usize * 3, 0);
    }

    /// An empty placeholder to be [`reshape`](Self::reshape)d (0×0, not a valid frame).
    pub(crate) fn scratch() -> Self {
        Self {
            width: 0,
            height: 0,
            data: Vec::new(),
        }
    }
}

/// A frame over borrowed bytes (a numpy array, a decoded buffer): the layout of [`Frame`]
/// without owning it, so callers perturb their own buffers without a copy.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FrameRef<'a> {
    width: u32,
    height: u32,
    data: &'a [u8],
}

impl<'a> FrameRef<'a> {
    /// A view of `data` as a `width × height` RGB8 frame; fails as [`Frame::new`] does.
    pub fn new(width: u32, height: u32, data: &'a [u8]) -> Result<Self, PerturbError> {
        check_layout(width, height, data.len())?;
        Ok(Self {
            width,
            height,
            data,
        })
    }

    /// Width in pixels.
    pub fn width(&self) -> u32 {
        self.width
    }

    /// Height in pixels.
    pub fn height(&self) -> u32 {
        self.height
    }

    /// The interleaved RGB bytes.
    pub fn data(&self) -> &'a [u8] {
        self.data
    }

    /// The pixel at column `x`, row `y` (panics outside the frame).
    pub fn pixel(&self, x: u32, y: u32) -> [u8; 3] {
        let i = (y as usize * self.width as usize + x as usize) * 3;
        [self.data[i], self.data[i + 1], self.data[i + 2]]
    }

    /// An owned copy.
    pub fn to_frame(&self) -> Frame {
        Frame {
            width: self.width,
            height: self.height,
            data: self.data.to_vec(),
        }
    }

    /// Bytes per row.
    pub(crate) fn stride(&self) -> usize {
        self.width as usize * 3
    }
}

impl<'a> From<&'a Frame> for FrameRef<'a> {
    fn from(f: &'a Frame) -> Self {
        f.view()
    }
}

/// A frame over borrowed, writable bytes: where [`Prepared::apply_to`](crate::Prepared::apply_to)
/// writes its output (a caller's `out=` array, one image of a batch).
#[derive(Debug, PartialEq, Eq)]
pub struct FrameMut<'a> {
    width: u32,
    height: u32,
    data: &'a mut [u8],
}

impl<'a> FrameMut<'a> {
    /// A writable view of `data` as a `width × height` RGB8 frame; fails as [`Frame::new`]
    /// does.
    pub fn new(width: u32, height: u32, data: &'a mut [u8]) -> Result<Self, PerturbError> {
        check_layout(width, height, data.len())?;
        Ok(Self {
            width,
            height,
            data,
        })
    }

    /// Width in pixels.
    pub fn width(&self) -> u32 {
        self.width
    }

    /// Height in pixels.
    pub fn height(&self) -> u32 {
        self.height
    }

    /// The interleaved RGB bytes.
    pub fn data(&self) -> &[u8] {
        self.data
    }

    /// The interleaved RGB bytes, mutable (the size cannot change).
    pub fn data_mut(&mut self) -> &mut [u8] {
        self.data
    }

    /// The frame as it stands, read-only.
    pub fn as_ref(&self) -> FrameRef<'_> {
        FrameRef {
            width: self.width,
            height: self.height,
            data: self.data,
        }
    }

    /// The pixel at column `x`, row `y` (panics outside the frame).
    pub fn pixel(&self, x: u32, y: u32) -> [u8; 3] {
        self.as_ref().pixel(x, y)
    }

    /// Bytes per row.
    pub(crate) fn stride(&self) -> usize {
        self.width as usize * 3
    }
}

/// Checks that `len` bytes hold a `width × height` RGB8 frame.
fn check_layout(width: u32, height: u32, len: usize) -> Result<(), PerturbError> {
    if width == 0 || height == 0 {
        return Err(PerturbError::EmptyFrame { width, height });
    }
    let expected = width as usize * height as usize * 3;
    if len != expected {
        return Err(PerturbError::BufferSize {
            width,
            height,
            len,
            expected,
        });
    }
    Ok(())
}

/// Distance from the camera per pixel, in metres, row-major like [`Frame`].
///
/// Values are finite and >= 0, or `+inf` for pixels with nothing in front of the camera
/// (sky): Koschmieder fog turns those into pure airlight.
#[derive(Debug, Clone, PartialEq)]
pub struct DepthMap {
    width: u32,
    height: u32,
    depth_m: Vec<f32>,
}

impl DepthMap {
    /// A depth map over `depth_m`; fails on a zero size, a wrong length, or a negative or NaN
    /// value (naming the first such pixel).
    pub fn new(width: u32, height: u32, depth_m: Vec<f32>) -> Result<Self, PerturbError> {
        if width == 0 || height == 0 {
            return Err(PerturbError::EmptyFrame { width, height });
        }
        let expected = width as usize * height as usize;
        if depth_m.len() != expected {
            return Err(PerturbError::BufferSize {
                width,
                height,
                len: depth_m.len(),
                expected,
            });
        }
        if let Some(i) = depth_m.iter().position(|d| d.is_nan() || *d < 0.0) {
            return Err(PerturbError::DepthValue {
                x: (i % width as usize) as u32,
                y: (i / width as usize) as u32,
                value: depth_m[i],
            });
        }
        Ok(Self {
            width,
            height,
            depth_m,
        })
    }

    /// Width in pixels.
    pub fn width(&self) -> u32 {
        self.width
    }

    /// Height in pixels.
    pub fn height(&self) -> u32 {
        self.height
    }

    /// The distances in metres.
    pub fn depth_m(&self) -> &[f32] {
        &self.depth_m
    }

    /// Fails unless the map has the frame's size.
    pub fn check_size<'f>(&self, frame: impl Into<FrameRef<'f>>) -> Result<(), PerturbError> {
        let frame = frame.into();
        if (self.width, self.height) == (frame.width, frame.height) {
            Ok(())
        } else {
            Err(PerturbError::DepthSize {
                depth_width: self.width,
                depth_height: self.height,
                frame_width: frame.width,
                frame_height: frame.height,
            })
        }
    }
}

/// An object in a frame: its class, its track id (the same object across frames) and its
/// axis-aligned 2-D box in pixels (origin top-left, x right, y down).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ObjectBox {
    /// Class label (`car`, `pedestrian`, …).
    pub class: String,
    /// Track id, when the source tracks objects across frames.
    #[serde(default)]
    pub track_id: Option<u64>,
    /// Left edge, px.
    pub x_px: f64,
    /// Top edge, px.
    pub y_px: f64,
    /// Width, px (>= 0).
    pub width_px: f64,
    /// Height, px (>= 0).
    pub height_px: f64,
}

impl ObjectBox {
    /// Checks the box against a `width × height` frame; `index` names it in the error.
    pub fn validate(&self, index: usize, width: u32, height: u32) -> Result<(), PerturbError> {
        let finite = [self.x_px, self.y_px, self.width_px, self.height_px]
            .iter()
            .all(|v| v.is_finite());
        if !finite || self.width_px < 0.0 || self.height_px < 0.0 {
            return Err(PerturbError::BoxSize {
                index,
                class: self.class.clone(),
                width_px: self.width_px,
                height_px: self.height_px,
            });
        }
        let (x1, y1) = (self.x_px + self.width_px, self.y_px + self.height_px);
        if self.x_px < 0.0 || self.y_px < 0.0 || x1 > f64::from(width) || y1 > f64::from(height) {
            return Err(PerturbError::BoxOutside {
                index,
                class: self.class.clone(),
                x_px: self.x_px,
                x_end_px: x1,
                y_px: self.y_px,
                y_end_px: y1,
                frame_width: width,
                frame_height: height,
            });
        }
        Ok(())
    }

    /// The pixels the box covers, `[x0, x1) × [y0, y1)`: every pixel whose centre lies in the
    /// box (edges rounded to the nearest pixel boundary).
    pub fn pixel_rect(&self) -> PixelRect {
        let r = |v: f64| v.round().max(0.0) as u32;
        PixelRect {
            x0: r(self.x_px),
            y0: r(self.y_px),
            x1: r(self.x_px + self.width_px),
            y1: r(self.y_px + self.height_px),
        }
    }
}

/// A rectangle of whole pixels, `[x0, x1) × [y0, y1)`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct PixelRect {
    /// First column.
    pub x0: u32,
    /// First row.
    pub y0: u32,
    /// One past the last column.
    pub x1: u32,
    /// One past the last row.
    pub y1: u32,
}

/// Names a frame for its random streams: which clip, which camera, which frame.
///
/// Use [`crate::rng::name_id`] to turn string ids into numbers. Two frames with the same key,
/// seed and condition get the same perturbation, whatever else is processed around them.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, Serialize, Deserialize)]
pub struct FrameKey {
    /// The clip.
    pub clip: u64,
    /// The camera within the clip.
    pub camera: u64,
    /// The frame index within the camera's sequence.
    pub frame: u64,
}

impl FrameKey {
    /// A key from its parts.
    pub fn new(clip: u64, camera: u64, frame: u64) -> Self {
        Self {
            clip,
            camera,
            frame,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frame_rejects_bad_sizes() {
        assert!(matches!(
            Frame::new(0, 4, vec![]),
            Err(PerturbError::EmptyFrame { .. })
        ));
        assert!(matches!(
            Frame::new(2, 2, vec![0; 11]),
            Err(PerturbError::BufferSize { expected: 12, .. })
        ));
        assert!(Frame::new(2, 2, vec![0; 12]).is_ok());
    }

    #[test]
    fn depth_rejects_nan_and_negative_but_takes_infinity() {
        assert!(DepthMap::new(2, 1, vec![1.0, f32::INFINITY]).is_ok());
        let e = DepthMap::new(2, 1, vec![1.0, -2.0]).unwrap_err();
        assert!(
            matches!(e, PerturbError::DepthValue { x: 1, y: 0, .. }),
            "{e}"
        );
        assert!(DepthMap::new(2, 1, vec![f32::NAN, 1.0]).is_err());
    }

    #[test]
    fn boxes_are_checked_against_the_frame() {
        let b = |x, y, w, h| ObjectBox {
            class: "car".into(),
            track_id: None,
            x_px: x,
            y_px: y,
            width_px: w,
            height_px: h,
        };
        assert!(b(0.0, 0.0, 10.0, 10.0).validate(0, 10, 10).is_ok());
        assert!(matches!(
            b(1.0, 1.0, 10.0, 2.0).validate(3, 10, 10),
            Err(PerturbError::BoxOutside { index: 3, .. })
        ));
        assert!(matches!(
            b(1.0, 1.0, -1.0, 2.0).validate(0, 10, 10),
            Err(PerturbError::BoxSize { .. })
        ));
        assert!(b(-0.5, 1.0, 1.0, 2.0).validate(0, 10, 10).is_err());
        assert!(b(f64::NAN, 1.0, 1.0, 2.0).validate(0, 10, 10).is_err());
    }
}
