//! The error type of fogline-perturb.

/// Why a perturbation could not be parsed, prepared or applied.
///
/// Every variant names what was wrong and what was expected; the caller adds which file it
/// came from.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum PerturbError {
    /// A condition name that none of the families recognises.
    #[error("unknown condition {name:?}: {reason}")]
    UnknownCondition {
        /// The name as given.
        name: String,
        /// What was expected instead.
        reason: String,
    },
    /// A family parameter outside its valid range.
    #[error("{family}: {parameter} = {value} is invalid, expected {expected}")]
    InvalidParameter {
        /// The family (`gaussian_noise`, `fog`, …).
        family: &'static str,
        /// The parameter (`sigma`, `alpha`, …).
        parameter: &'static str,
        /// The value given.
        value: f64,
        /// The valid range.
        expected: &'static str,
    },
    /// A frame with no pixels.
    #[error("the frame is empty ({width}×{height} pixels); expected at least 1×1")]
    EmptyFrame {
        /// Width in pixels.
        width: u32,
        /// Height in pixels.
        height: u32,
    },
    /// A pixel buffer whose length does not match its declared size.
    #[error(
        "the pixel buffer has {len} bytes, expected {expected} ({width}×{height} RGB, 8 bits per channel)"
    )]
    BufferSize {
        /// Width in pixels.
        width: u32,
        /// Height in pixels.
        height: u32,
        /// Bytes given.
        len: usize,
        /// Bytes expected.
        expected: usize,
    },
    /// An output buffer whose size differs from the input frame's.
    #[error(
        "the output is {width}×{height} pixels but the input frame is {expected_width}×{expected_height}"
    )]
    OutputSize {
        /// Output width.
        width: u32,
        /// Output height.
        height: u32,
        /// Input width.
        expected_width: u32,
        /// Input height.
        expected_height: u32,
    },
    /// A depth map whose size differs from the frame's.
    #[error(
        "the depth map is {depth_width}×{depth_height} pixels but the frame is {frame_width}×{frame_height}"
    )]
    DepthSize {
        /// Depth map width.
        depth_width: u32,
        /// Depth map height.
        depth_height: u32,
        /// Frame width.
        frame_width: u32,
        /// Frame height.
        frame_height: u32,
    },
    /// A depth value that is negative or NaN.
    #[error("depth at pixel ({x}, {y}) is {value} m; expected a distance >= 0 (or +inf for sky)")]
    DepthValue {
        /// Column.
        x: u32,
        /// Row.
        y: u32,
        /// The value found.
        value: f32,
    },
    /// A family that needs a depth map was given none.
    #[error("condition {condition:?} needs a depth map (Koschmieder fog with a visibility)")]
    DepthRequired {
        /// The condition.
        condition: String,
    },
    /// An object box with a negative or non-finite size.
    #[error(
        "box {index} ({class}): size {width_px}×{height_px} px is invalid, expected finite sizes >= 0"
    )]
    BoxSize {
        /// Index of the box in the frame's list.
        index: usize,
        /// Its class.
        class: String,
        /// Its width.
        width_px: f64,
        /// Its height.
        height_px: f64,
    },
    /// An object box that reaches outside the frame.
    #[error(
        "box {index} ({class}): [{x_px}, {x_end_px}) × [{y_px}, {y_end_px}) px reaches outside the \
         {frame_width}×{frame_height} frame"
    )]
    BoxOutside {
        /// Index of the box in the frame's list.
        index: usize,
        /// Its class.
        class: String,
        /// Left edge.
        x_px: f64,
        /// Right edge (exclusive).
        x_end_px: f64,
        /// Top edge.
        y_px: f64,
        /// Bottom edge (exclusive).
        y_end_px: f64,
        /// Frame width.
        frame_width: u32,
        /// Frame height.
        frame_height: u32,
    },
    /// A clip plan asked for with zero frames, or a frame index past the clip.
    #[error("clip has {n_frames} frames; {what}")]
    Clip {
        /// Frames in the clip.
        n_frames: usize,
        /// What was wrong.
        what: String,
    },
}
