//! Perception deficits: objects blacked out of the image, as in the LLM-RCO paper.
//!
//! Given a frame's object boxes, the boxes of the chosen objects (every object, a class, or a
//! track) are filled (black by default) and, optionally, outlined (red, 2 px by default: the
//! paper's cue that tells a model *where* the deficit is). Because targets are classes or
//! track ids, the same object is masked in every frame of its track. The masked regions are
//! returned as [`DeficitRegion`]s so that a controller can reason about them.

use serde::{Deserialize, Serialize};

use crate::PerturbError;
use crate::frame::{FrameMut, ObjectBox, PixelRect};

/// Which objects a deficit hides.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum DeficitTarget {
    /// Every box in the frame.
    All,
    /// Boxes of this class.
    Class(String),
    /// Boxes of this track.
    Track(u64),
}

impl DeficitTarget {
    /// Whether `b` is hidden.
    pub fn selects(&self, b: &ObjectBox) -> bool {
        match self {
            Self::All => true,
            Self::Class(c) => &b.class == c,
            Self::Track(t) => b.track_id == Some(*t),
        }
    }
}

/// An outline drawn along the inside of a masked box.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct Outline {
    /// Colour.
    pub rgb: [u8; 3],
    /// Width in pixels (>= 1).
    pub width_px: u32,
}

impl Default for Outline {
    fn default() -> Self {
        Self {
            rgb: [255, 0, 0],
            width_px: 2,
        }
    }
}

/// A perception deficit: what to hide and how.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct DeficitParams {
    /// The objects to hide.
    pub target: DeficitTarget,
    /// Fill colour of the hidden boxes.
    #[serde(default)]
    pub fill_rgb: [u8; 3],
    /// Outline (`None`: no outline).
    #[serde(default = "default_outline")]
    pub outline: Option<Outline>,
}

fn default_outline() -> Option<Outline> {
    Some(Outline::default())
}

impl Default for DeficitParams {
    fn default() -> Self {
        Self {
            target: DeficitTarget::All,
            fill_rgb: [0, 0, 0],
            outline: default_outline(),
        }
    }
}

/// A region of a frame hidden by a deficit.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct DeficitRegion {
    /// The object's class.
    pub class: String,
    /// The object's track, if known.
    pub track_id: Option<u64>,
    /// The pixels hidden (outline included).
    pub rect: PixelRect,
}

/// Validates every box against the frame (the first bad one is the error).
pub fn validate_boxes(boxes: &[ObjectBox], width: u32, height: u32) -> Result<(), PerturbError> {
    boxes
        .iter()
        .enumerate()
        .try_for_each(|(i, b)| b.validate(i, width, height))
}

/// Fills the selected boxes, then outlines them; returns the hidden regions in box order.
pub(crate) fn apply(
    frame: &mut FrameMut<'_>,
    boxes: &[ObjectBox],
    p: &DeficitParams,
) -> Vec<DeficitRegion> {
    let regions: Vec<DeficitRegion> = boxes
        .iter()
        .filter(|b| p.target.selects(b))
        .map(|b| DeficitRegion {
            class: b.class.clone(),
            track_id: b.track_id,
            rect: b.pixel_rect(),
        })
        .filter(|r| r.rect.x1 > r.rect.x0 && r.rect.y1 > r.rect.y0)
        .collect();
    for r in &regions {
        fill(frame, r.rect, p.fill_rgb);
    }
    if let Some(o) = p.outline {
        for r in &regions {
            let PixelRect { x0, y0, x1, y1 } = r.rect;
            let wd = o.width_px;
            let (top, bottom) = ((y0 + wd).min(y1), y1.saturating_sub(wd).max(y0));
            let (left, right) = ((x0 + wd).min(x1), x1.saturating_sub(wd).max(x0));
            fill(
                frame,
                PixelRect {
                    x0,
                    y0,
                    x1,
                    y1: top,
                },
                o.rgb,
            );
            fill(
                frame,
                PixelRect {
                    x0,
                    y0: bottom,
                    x1,
                    y1,
                },
                o.rgb,
            );
            fill(
                frame,
                PixelRect {
                    x0,
                    y0,
                    x1: left,
                    y1,
                },
                o.rgb,
            );
            fill(
                frame,
                PixelRect {
                    x0: right,
                    y0,
                    x1,
                    y1,
                },
                o.rgb,
            );
        }
    }
    regions
}

fn fill(frame: &mut FrameMut<'_>, r: PixelRect, rgb: [u8; 3]) {
    let stride = frame.stride();
    let data = frame.data_mut();
    for y in r.y0..r.y1 {
        let row = &mut data[y as usize * stride..(y as usize + 1) * stride];
        for px in row[r.x0 as usize * 3..r.x1 as usize * 3].chunks_exact_mut(3) {
            px.copy_from_slice(&rgb);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Frame;

    #[test]
    fn masks_then_outlines_the_selected_box_only() {
        let mut f = Frame::filled(8, 6, [100, 100, 100]).unwrap();
        let boxes = [
            ObjectBox {
                class: "car".into(),
                track_id: Some(1),
                x_px: 1.0,
                y_px: 1.0,
                width_px: 5.0,
                height_px: 4.0,
            },
            ObjectBox {
                class: "tree".into(),
                track_id: None,
                x_px: 7.0,
                y_px: 0.0,
                width_px: 1.0,
                height_px: 1.0,
            },
        ];
        let p = DeficitParams {
            target: DeficitTarget::Class("car".into()),
            outline: Some(Outline {
                rgb: [255, 0, 0],
                width_px: 1,
            }),
            ..DeficitParams::default()
        };
        let r = apply(&mut f.view_mut(), &boxes, &p);
        assert_eq!(r.len(), 1);
        assert_eq!(
            r[0].rect,
            PixelRect {
                x0: 1,
                y0: 1,
                x1: 6,
                y1: 5
            }
        );
        assert_eq!(f.pixel(0, 0), [100, 100, 100]);
        assert_eq!(f.pixel(1, 1), [255, 0, 0]);
        assert_eq!(f.pixel(5, 4), [255, 0, 0]);
        assert_eq!(f.pixel(3, 2), [0, 0, 0]);
        assert_eq!(f.pixel(6, 2), [100, 100, 100]);
        assert_eq!(f.pixel(7, 0), [100, 100, 100]);
    }
}
