//! Conditions: named chains of family steps, their parsing, and their application.

use fogline_types::{Condition, Family};
use serde::{Deserialize, Serialize};

use crate::PerturbError;
use crate::bytemap::ByteMap;
use crate::deficit::{self, DeficitParams, DeficitRegion, DeficitTarget};
use crate::frame::{DepthMap, Frame, FrameKey, FrameMut, FrameRef, ObjectBox};
use crate::noise::{self, GaussianTable, ShotTable};
use crate::occlusion::{self, DirtParams};
use crate::params::*;
use crate::rng::{child, name_id};
use crate::temporal::{self, Fault, FrameSource};
use crate::{blur, jpeg, photometric};

/// One family with its parameters.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "family", rename_all = "snake_case")]
#[non_exhaustive]
pub enum Step {
    /// Exact Gaussian noise.
    GaussianNoise(GaussianNoiseParams),
    /// Photometric gain.
    #[serde(rename = "brightness")]
    Gain(GainParams),
    /// Fog: homogeneous blend, or Koschmieder with a depth map.
    Fog(FogParams),
    /// Koschmieder fog by visibility (needs a depth map).
    FogVisibility(VisibilityParams),
    /// Shot (Poisson) noise.
    ShotNoise(ShotNoiseParams),
    /// Impulse (salt-and-pepper) noise.
    ImpulseNoise(ImpulseNoiseParams),
    /// Contrast around the frame's mean grey.
    Contrast(ContrastParams),
    /// Saturation around each pixel's luma.
    Saturation(SaturationParams),
    /// Defocus (disk) blur.
    DefocusBlur(DefocusParams),
    /// Motion (line) blur.
    MotionBlur(MotionParams),
    /// JPEG compression artefacts.
    Jpeg(JpegParams),
    /// Pixelation.
    Pixelate(PixelateParams),
    /// Colour quantisation.
    Quantize(QuantizeParams),
    /// Dead pixels (fixed per camera).
    DeadPixels(DeadPixelParams),
    /// Lens dirt (fixed per camera).
    LensDirt(DirtParams),
    /// Glare.
    Glare(GlareParams),
    /// Frame drop (temporal).
    FrameDrop(DropParams),
    /// Latency (temporal).
    Latency(LatencyParams),
    /// Camera blackout (temporal).
    Blackout(BlackoutParams),
    /// Frozen camera (temporal).
    Freeze(FreezeParams),
    /// Perception deficit: boxes blacked out.
    DeficitMask(DeficitParams),
}

/// The family prefixes [`Perturbation::parse`] knows, for error messages.
const GRAMMAR: &str = "clean, noise_<sigma>, dark, bright, gain_<g>, fog_<NN> or fog_<alpha>, \
    visibility_<m>, shot_<s>, impulse_<p>, contrast_<c>, saturation_<s>, defocus_<r>, \
    motion_<length>, jpeg_<quality>, pixelate_<block>, quantize_<bits>, dead_<p>, dirt_<n>, \
    glare_<s>, drop_<p>, latency_<frames>, blackout_<frame>, freeze_<frame>, mask_all, \
    mask_class_<class>, mask_track_<id>, or several joined by +";

impl Step {
    /// The family name (the pairs table's `family` column).
    pub fn family(&self) -> &'static str {
        match self {
            Self::GaussianNoise(_) => "gaussian_noise",
            Self::Gain(_) => "brightness",
            Self::Fog(_) => "fog",
            Self::FogVisibility(_) => "fog_visibility",
            Self::ShotNoise(_) => "shot_noise",
            Self::ImpulseNoise(_) => "impulse_noise",
            Self::Contrast(_) => "contrast",
            Self::Saturation(_) => "saturation",
            Self::DefocusBlur(_) => "defocus_blur",
            Self::MotionBlur(_) => "motion_blur",
            Self::Jpeg(_) => "jpeg",
            Self::Pixelate(_) => "pixelate",
            Self::Quantize(_) => "quantize",
            Self::DeadPixels(_) => "dead_pixels",
            Self::LensDirt(_) => "lens_dirt",
            Self::Glare(_) => "glare",
            Self::FrameDrop(_) => "frame_drop",
            Self::Latency(_) => "latency",
            Self::Blackout(_) => "blackout",
            Self::Freeze(_) => "freeze",
            Self::DeficitMask(_) => "deficit_mask",
        }
    }

    /// The level (the pairs table's `level` column): the number in the step's name.
    pub fn level(&self) -> f64 {
        match self {
            Self::GaussianNoise(p) => p.sigma,
            Self::Gain(p) => p.gain,
            Self::Fog(p) => p.alpha,
            Self::FogVisibility(p) => p.visibility_m,
            Self::ShotNoise(p) => p.units_per_photon,
            Self::ImpulseNoise(p) => p.fraction,
            Self::Contrast(p) => p.factor,
            Self::Saturation(p) => p.factor,
            Self::DefocusBlur(p) => p.radius_px,
            Self::MotionBlur(p) => f64::from(p.length_px),
            Self::Jpeg(p) => f64::from(p.quality),
            Self::Pixelate(p) => f64::from(p.block_px),
            Self::Quantize(p) => f64::from(p.bits),
            Self::DeadPixels(p) => p.fraction,
            Self::LensDirt(p) => f64::from(p.n_blobs),
            Self::Glare(p) => p.strength,
            Self::FrameDrop(p) => p.probability,
            Self::Latency(p) => p.frames as f64,
            Self::Blackout(p) => p.from_frame as f64,
            Self::Freeze(p) => p.from_frame as f64,
            Self::DeficitMask(_) => 1.0,
        }
    }

    /// The step's canonical name (which [`Perturbation::parse`] reads back).
    pub fn name(&self) -> String {
        match self {
            Self::GaussianNoise(p) => format!("noise_{}", p.sigma),
            Self::Gain(p) if p.gain == 0.4 => "dark".into(),
            Self::Gain(p) if p.gain == 1.6 => "bright".into(),
            Self::Gain(p) => format!("gain_{}", p.gain),
            Self::Fog(p) => {
                let tenths = (p.alpha * 10.0).round();
                if (p.alpha * 10.0 - tenths).abs() < 1e-9 {
                    format!("fog_{:02}", tenths as u32)
                } else {
                    format!("fog_{}", p.alpha)
                }
            }
            Self::FogVisibility(p) => format!("visibility_{}", p.visibility_m),
            Self::DeficitMask(p) => match &p.target {
                DeficitTarget::All => "mask_all".into(),
                DeficitTarget::Class(c) => format!("mask_class_{c}"),
                DeficitTarget::Track(t) => format!("mask_track_{t}"),
            },
            other => {
                let prefix = match other {
                    Self::ShotNoise(_) => "shot",
                    Self::ImpulseNoise(_) => "impulse",
                    Self::Contrast(_) => "contrast",
                    Self::Saturation(_) => "saturation",
                    Self::DefocusBlur(_) => "defocus",
                    Self::MotionBlur(_) => "motion",
                    Self::Jpeg(_) => "jpeg",
                    Self::Pixelate(_) => "pixelate",
                    Self::Quantize(_) => "quantize",
                    Self::DeadPixels(_) => "dead",
                    Self::LensDirt(_) => "dirt",
                    Self::Glare(_) => "glare",
                    Self::FrameDrop(_) => "drop",
                    Self::Latency(_) => "latency",
                    Self::Blackout(_) => "blackout",
                    _ => "freeze",
                };
                format!("{prefix}_{}", other.level())
            }
        }
    }

    /// Checks the parameters.
    pub fn validate(&self) -> Result<(), PerturbError> {
        match self {
            Self::GaussianNoise(p) => p.validate(),
            Self::Gain(p) => p.validate(),
            Self::Fog(p) => p.validate(),
            Self::FogVisibility(p) => p.validate(),
            Self::ShotNoise(p) => p.validate(),
            Self::ImpulseNoise(p) => p.validate(),
            Self::Contrast(p) => p.validate(),
            Self::Saturation(p) => p.validate(),
            Self::DefocusBlur(p) => p.validate(),
            Self::MotionBlur(p) => p.validate(),
            Self::Jpeg(p) => p.validate(),
            Self::Pixelate(p) => p.validate(),
            Self::Quantize(p) => p.validate(),
            Self::DeadPixels(p) => p.validate(),
            Self::LensDirt(p) => {
                let ok = p.n_blobs <= 1000
                    && (0.0..=1.0).contains(&p.radius_min)
                    && (0.0..=1.0).contains(&p.radius_max)
                    && p.radius_min <= p.radius_max;
                if ok {
                    Ok(())
                } else {
                    Err(PerturbError::InvalidParameter {
                        family: "lens_dirt",
                        parameter: "n_blobs / radius_min / radius_max",
                        value: f64::from(p.n_blobs),
                        expected: "at most 1000 blobs and 0 <= radius_min <= radius_max <= 1",
                    })
                }
            }
            Self::Glare(p) => p.validate(),
            Self::FrameDrop(p) => p.validate(),
            Self::Latency(p) => p.validate(),
            Self::Blackout(p) => p.validate(),
            Self::Freeze(p) => p.validate(),
            Self::DeficitMask(p) => match p.outline {
                Some(o) if o.width_px == 0 || o.width_px > 1000 => {
                    Err(PerturbError::InvalidParameter {
                        family: "deficit_mask",
                        parameter: "outline.width_px",
                        value: f64::from(o.width_px),
                        expected: "a width in [1, 1000] px (or no outline)",
                    })
                }
                _ => Ok(()),
            },
        }
    }

    /// Whether the step leaves every frame unchanged (severity 0).
    pub fn is_identity(&self) -> bool {
        match self {
            Self::GaussianNoise(p) => p.sigma == 0.0,
            Self::Gain(p) => p.gain == 1.0,
            Self::Fog(p) => p.alpha == 0.0,
            Self::FogVisibility(_) => false,
            Self::ShotNoise(p) => p.units_per_photon == 0.0,
            Self::ImpulseNoise(p) => p.fraction == 0.0,
            Self::Contrast(p) => p.factor == 1.0,
            Self::Saturation(p) => p.factor == 1.0,
            Self::DefocusBlur(p) => p.radius_px < 1.0,
            Self::MotionBlur(p) => p.length_px == 1,
            Self::Jpeg(_) => false,
            Self::Pixelate(p) => p.block_px == 1,
            Self::Quantize(p) => p.bits == 8,
            Self::DeadPixels(p) => p.fraction == 0.0,
            Self::LensDirt(p) => p.n_blobs == 0,
            Self::Glare(p) => p.strength == 0.0,
            Self::FrameDrop(p) => p.probability == 0.0,
            Self::Latency(p) => p.frames == 0,
            Self::Blackout(_) | Self::Freeze(_) | Self::DeficitMask(_) => false,
        }
    }

    /// Whether the step acts on a clip's timeline rather than on pixels.
    pub fn is_temporal(&self) -> bool {
        matches!(
            self,
            Self::FrameDrop(_) | Self::Latency(_) | Self::Blackout(_) | Self::Freeze(_)
        )
    }

    /// Parses one step name (no `+`).
    pub fn parse(name: &str) -> Result<Self, PerturbError> {
        let bad = |reason: String| PerturbError::UnknownCondition {
            name: name.to_string(),
            reason,
        };
        if let Ok(c) = Condition::parse(name) {
            return Ok(match c.family {
                Family::GaussianNoise => {
                    Self::GaussianNoise(GaussianNoiseParams { sigma: c.level })
                }
                Family::Brightness => Self::Gain(GainParams { gain: c.level }),
                _ => Self::Fog(FogParams {
                    alpha: c.level,
                    ..FogParams::default()
                }),
            });
        }
        if let Some(rest) = name.strip_prefix("mask_") {
            let target =
                if rest == "all" {
                    DeficitTarget::All
                } else if let Some(c) = rest.strip_prefix("class_").filter(|c| !c.is_empty()) {
                    DeficitTarget::Class(c.to_string())
                } else if let Some(t) = rest.strip_prefix("track_") {
                    DeficitTarget::Track(int(t).ok_or_else(|| {
                        bad("a track id is a whole number (mask_track_<id>)".into())
                    })?)
                } else {
                    return Err(bad(
                        "a mask is mask_all, mask_class_<class> or mask_track_<id>".into(),
                    ));
                };
            return Ok(Self::DeficitMask(DeficitParams {
                target,
                ..DeficitParams::default()
            }));
        }
        let Some((prefix, text)) = name.split_once('_') else {
            return Err(bad(format!("expected one of {GRAMMAR}")));
        };
        let number = || {
            num(text).ok_or_else(|| {
                bad(format!(
                    "{text:?} is not a plain number (write e.g. {prefix}_0.5)"
                ))
            })
        };
        let whole = || {
            int(text).ok_or_else(|| {
                bad(format!(
                    "{text:?} is not a whole number (write e.g. {prefix}_3)"
                ))
            })
        };
        let small = |v: u64| u32::try_from(v).unwrap_or(u32::MAX);
        let step = match prefix {
            "noise" | "fog" if prefix == "fog" && text.contains('.') => Self::Fog(FogParams {
                alpha: number()?,
                ..FogParams::default()
            }),
            "noise" => {
                return Err(bad(
                    "Gaussian noise is noise_<sigma>, sigma a plain number >= 0 (e.g. noise_30)"
                        .into(),
                ));
            }
            "fog" => {
                return Err(bad(
                    "fog is fog_<alpha*10 as two digits> (e.g. fog_07) or fog_<alpha> with a \
                     decimal point (e.g. fog_0.35), alpha in [0, 1]"
                        .into(),
                ));
            }
            "dark" | "bright" => {
                return Err(bad(
                    "dark and bright take no level (write gain_<g> for other gains)".into(),
                ));
            }
            "gain" => Self::Gain(GainParams { gain: number()? }),
            "visibility" => Self::FogVisibility(VisibilityParams {
                visibility_m: number()?,
                ..VisibilityParams::default()
            }),
            "shot" => Self::ShotNoise(ShotNoiseParams {
                units_per_photon: number()?,
            }),
            "impulse" => Self::ImpulseNoise(ImpulseNoiseParams {
                fraction: number()?,
            }),
            "contrast" => Self::Contrast(ContrastParams { factor: number()? }),
            "saturation" => Self::Saturation(SaturationParams { factor: number()? }),
            "defocus" => Self::DefocusBlur(DefocusParams {
                radius_px: number()?,
            }),
            "motion" => Self::MotionBlur(MotionParams {
                length_px: small(whole()?),
                ..MotionParams::default()
            }),
            "jpeg" => Self::Jpeg(JpegParams {
                quality: small(whole()?),
                ..JpegParams::default()
            }),
            "pixelate" => Self::Pixelate(PixelateParams {
                block_px: small(whole()?),
            }),
            "quantize" => Self::Quantize(QuantizeParams {
                bits: small(whole()?),
            }),
            "dead" => Self::DeadPixels(DeadPixelParams {
                fraction: number()?,
                ..DeadPixelParams::default()
            }),
            "dirt" => Self::LensDirt(DirtParams {
                n_blobs: small(whole()?),
                ..DirtParams::default()
            }),
            "glare" => Self::Glare(GlareParams {
                strength: number()?,
                ..GlareParams::default()
            }),
            "drop" => Self::FrameDrop(DropParams {
                probability: number()?,
            }),
            "latency" => Self::Latency(LatencyParams { frames: whole()? }),
            "blackout" => Self::Blackout(BlackoutParams {
                from_frame: whole()?,
            }),
            "freeze" => Self::Freeze(FreezeParams {
                from_frame: whole()?,
            }),
            _ => return Err(bad(format!("expected one of {GRAMMAR}"))),
        };
        step.validate()?;
        Ok(step)
    }
}

/// A plain decimal number: digits, an optional `.` and fraction, an optional leading `-`
/// (which validation then rejects with a range message); no `+`, exponent, `inf` or `nan`.
fn num(s: &str) -> Option<f64> {
    let digits = s.strip_prefix('-').unwrap_or(s);
    let ok = !digits.is_empty()
        && digits.bytes().all(|b| b.is_ascii_digit() || b == b'.')
        && digits.bytes().filter(|&b| b == b'.').count() <= 1
        && digits.bytes().any(|b| b.is_ascii_digit());
    if ok { s.parse().ok() } else { None }
}

/// A whole number of at most 18 digits.
fn int(s: &str) -> Option<u64> {
    if !s.is_empty() && s.len() <= 18 && s.bytes().all(|b| b.is_ascii_digit()) {
        s.parse().ok()
    } else {
        None
    }
}

/// A condition: a name and the steps it chains, applied left to right.
///
/// The identity condition (`clean`) has no steps.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Perturbation {
    /// The name; it also keys the random streams (two conditions with different names draw
    /// independent noise).
    pub name: String,
    /// The steps, applied in order.
    pub steps: Vec<Step>,
}

impl Perturbation {
    /// Parses a condition name: `clean` (or `identity`), one step name, or several joined by
    /// `+` (e.g. `noise_30+jpeg_20`). See the crate docs for every family's name.
    pub fn parse(name: &str) -> Result<Self, PerturbError> {
        let name = name.trim();
        if name.is_empty() {
            return Err(PerturbError::UnknownCondition {
                name: String::new(),
                reason: format!("the name is empty; expected one of {GRAMMAR}"),
            });
        }
        let steps = if name == "clean" || name == "identity" {
            Vec::new()
        } else {
            name.split('+')
                .map(|part| {
                    if part.is_empty() {
                        Err(PerturbError::UnknownCondition {
                            name: name.to_string(),
                            reason: "an empty step between + signs".into(),
                        })
                    } else {
                        Step::parse(part)
                    }
                })
                .collect::<Result<Vec<_>, _>>()?
        };
        Ok(Self {
            name: name.to_string(),
            steps,
        })
    }

    /// A condition of `steps`, named by their canonical names joined with `+`.
    pub fn from_steps(steps: Vec<Step>) -> Self {
        let name = if steps.is_empty() {
            "clean".to_string()
        } else {
            steps.iter().map(Step::name).collect::<Vec<_>>().join("+")
        };
        Self { name, steps }
    }

    /// The identity condition.
    pub fn identity() -> Self {
        Self {
            name: "clean".into(),
            steps: Vec::new(),
        }
    }

    /// Checks every step.
    pub fn validate(&self) -> Result<(), PerturbError> {
        self.steps.iter().try_for_each(Step::validate)
    }

    /// Whether every step is an identity.
    pub fn is_identity(&self) -> bool {
        self.steps.iter().all(Step::is_identity)
    }

    /// Whether a step acts on the clip's timeline (use [`Prepared::plan_clip`]).
    pub fn is_temporal(&self) -> bool {
        self.steps.iter().any(Step::is_temporal)
    }

    /// Whether a step needs a depth map whatever happens (`visibility_<m>`, or fog forced to
    /// the Koschmieder model).
    pub fn needs_depth(&self) -> bool {
        self.steps.iter().any(|s| match s {
            Step::FogVisibility(_) => true,
            Step::Fog(p) => p.model == FogModel::Koschmieder && p.alpha > 0.0,
            _ => false,
        })
    }

    /// Whether a step reads object boxes.
    pub fn uses_boxes(&self) -> bool {
        self.steps.iter().any(|s| matches!(s, Step::DeficitMask(_)))
    }

    /// The condition as the pairs table names it, for a single-step condition (`None` for the
    /// identity and for chains).
    pub fn condition(&self) -> Option<Condition> {
        let [step] = self.steps.as_slice() else {
            return None;
        };
        let family = Family::from_name(step.family());
        Some(Condition::new(self.name.clone(), family, step.level()))
    }

    /// Validates and builds the tables (Gaussian and shot-noise samplers, byte maps) once, for
    /// every frame to come; `seed` is the campaign seed.
    pub fn prepare(&self, seed: u64) -> Result<Prepared, PerturbError> {
        self.validate()?;
        let mut spatial = Vec::new();
        let mut faults = Vec::new();
        for (i, step) in self.steps.iter().enumerate() {
            if step.is_identity() {
                continue;
            }
            let i = i as u64;
            let kernel = match step {
                Step::GaussianNoise(p) => Kernel::Gaussian(Box::new(GaussianTable::new(p.sigma))),
                Step::Gain(p) => Kernel::Map(photometric::gain_map(p.gain)),
                Step::Fog(p) => Kernel::Fog {
                    map: photometric::fog_map(p.alpha, p.airlight),
                    params: p.clone(),
                },
                Step::FogVisibility(p) => Kernel::Koschmieder {
                    beta_per_m: p.beta_per_m(),
                    airlight: p.airlight,
                },
                Step::ShotNoise(p) => Kernel::Shot(Box::new(ShotTable::new(p.units_per_photon))),
                Step::ImpulseNoise(p) => Kernel::Impulse(p.fraction),
                Step::Contrast(p) => Kernel::Contrast(p.factor),
                Step::Saturation(p) => Kernel::Saturation(p.factor),
                Step::DefocusBlur(p) => Kernel::Defocus(p.radius_px),
                Step::MotionBlur(p) => Kernel::Motion(p.length_px, p.angle_deg),
                Step::Jpeg(p) => Kernel::Jpeg(p.quality, p.chroma_subsampling),
                Step::Pixelate(p) => Kernel::Pixelate(p.block_px),
                Step::Quantize(p) => Kernel::Map(photometric::quantize_map(p.bits)),
                Step::DeadPixels(p) => Kernel::Dead(p.fraction, p.rgb),
                Step::LensDirt(p) => Kernel::Dirt(p.clone()),
                Step::Glare(p) => Kernel::Glare(p.clone()),
                Step::DeficitMask(p) => Kernel::Deficit(p.clone()),
                Step::FrameDrop(p) => {
                    faults.push((i, Fault::Drop(p.probability)));
                    continue;
                }
                Step::Latency(p) => {
                    faults.push((i, Fault::Latency(p.frames)));
                    continue;
                }
                Step::Blackout(p) => {
                    faults.push((i, Fault::Blackout(p.from_frame)));
                    continue;
                }
                Step::Freeze(p) => {
                    faults.push((i, Fault::Freeze(p.from_frame)));
                    continue;
                }
            };
            spatial.push((i, kernel));
        }
        Ok(Prepared {
            perturbation: self.clone(),
            seed,
            condition_id: name_id(&self.name),
            spatial,
            faults,
        })
    }
}

/// A frame to perturb and what comes with it.
#[derive(Debug, Clone, Copy)]
pub struct FrameInput<'a> {
    /// The pixels (`&frame` converts: `FrameInput::new(&frame, key)`).
    pub frame: FrameRef<'a>,
    /// Which clip, camera and frame (keys the random streams).
    pub key: FrameKey,
    /// Distances per pixel, for Koschmieder fog.
    pub depth: Option<&'a DepthMap>,
    /// Object boxes, for deficits.
    pub boxes: &'a [ObjectBox],
}

impl<'a> FrameInput<'a> {
    /// A frame with no depth map and no boxes.
    pub fn new(frame: impl Into<FrameRef<'a>>, key: FrameKey) -> Self {
        Self {
            frame: frame.into(),
            key,
            depth: None,
            boxes: &[],
        }
    }
}

/// The result of [`Prepared::apply`].
#[derive(Debug, Clone, PartialEq)]
pub struct Applied {
    /// The perturbed frame.
    pub frame: Frame,
    /// The regions hidden by deficit steps.
    pub deficits: Vec<DeficitRegion>,
}

/// A condition ready to apply: tables built, seed fixed. `Sync`: share it across threads.
#[derive(Debug, Clone)]
pub struct Prepared {
    perturbation: Perturbation,
    seed: u64,
    condition_id: u64,
    spatial: Vec<(u64, Kernel)>,
    faults: Vec<(u64, Fault)>,
}

#[derive(Debug, Clone)]
enum Kernel {
    Gaussian(Box<GaussianTable>),
    Map(ByteMap),
    Fog { map: ByteMap, params: FogParams },
    Koschmieder { beta_per_m: f64, airlight: f64 },
    Shot(Box<ShotTable>),
    Impulse(f64),
    Contrast(f64),
    Saturation(f64),
    Defocus(f64),
    Motion(u32, f64),
    Jpeg(u32, bool),
    Pixelate(u32),
    Dead(f64, [u8; 3]),
    Dirt(DirtParams),
    Glare(GlareParams),
    Deficit(DeficitParams),
}

struct StepCtx<'a> {
    frame_stream: u64,
    camera_stream: u64,
    depth: Option<&'a DepthMap>,
    boxes: &'a [ObjectBox],
    name: &'a str,
}

impl Kernel {
    fn run(
        &self,
        src: FrameRef<'_>,
        dst: &mut FrameMut<'_>,
        ctx: &StepCtx<'_>,
        deficits: &mut Vec<DeficitRegion>,
    ) -> Result<(), PerturbError> {
        match self {
            Self::Gaussian(t) => t.apply(src, dst, ctx.frame_stream),
            Self::Map(m) => m.apply(src.data(), dst.data_mut()),
            Self::Fog { map, params } => match (ctx.depth, params.model) {
                (Some(d), FogModel::Auto | FogModel::Koschmieder) => {
                    photometric::koschmieder(src, dst, d, params.beta_per_m(), params.airlight);
                }
                (None, FogModel::Koschmieder) => {
                    return Err(PerturbError::DepthRequired {
                        condition: ctx.name.to_string(),
                    });
                }
                _ => map.apply(src.data(), dst.data_mut()),
            },
            Self::Koschmieder {
                beta_per_m,
                airlight,
            } => {
                let d = ctx.depth.ok_or_else(|| PerturbError::DepthRequired {
                    condition: ctx.name.to_string(),
                })?;
                photometric::koschmieder(src, dst, d, *beta_per_m, *airlight);
            }
            Self::Shot(t) => t.apply(src, dst, ctx.frame_stream),
            Self::Impulse(p) => noise::impulse(src, dst, *p, ctx.frame_stream),
            Self::Contrast(c) => {
                let m = photometric::contrast_map(*c, photometric::mean_level(src));
                m.apply(src.data(), dst.data_mut());
            }
            Self::Saturation(s) => photometric::saturation(src, dst, *s),
            Self::Defocus(r) => blur::defocus(src, dst, *r),
            Self::Motion(l, a) => blur::motion(src, dst, *l, *a),
            Self::Jpeg(q, sub) => jpeg::jpeg(src, dst, *q, *sub),
            Self::Pixelate(b) => blur::pixelate(src, dst, *b),
            Self::Glare(p) => photometric::glare(src, dst, p.strength, p.centre, p.radius),
            Self::Dead(p, rgb) => {
                dst.data_mut().copy_from_slice(src.data());
                occlusion::dead_pixels(dst, *p, *rgb, ctx.camera_stream);
            }
            Self::Dirt(p) => {
                dst.data_mut().copy_from_slice(src.data());
                occlusion::lens_dirt(dst, p, ctx.camera_stream);
            }
            Self::Deficit(p) => {
                dst.data_mut().copy_from_slice(src.data());
                deficits.extend(deficit::apply(dst, ctx.boxes, p));
            }
        }
        Ok(())
    }
}

impl Prepared {
    /// The condition.
    pub fn perturbation(&self) -> &Perturbation {
        &self.perturbation
    }

    /// The campaign seed.
    pub fn seed(&self) -> u64 {
        self.seed
    }

    /// Which captured frame each of `n_frames` time steps of `(clip, camera)` delivers, after
    /// the condition's temporal faults (the identity plan when it has none).
    pub fn plan_clip(&self, clip: u64, camera: u64, n_frames: usize) -> Vec<FrameSource> {
        let mut plan: Vec<FrameSource> = (0..n_frames).map(FrameSource::Captured).collect();
        for &(step, fault) in &self.faults {
            let stream = child(self.seed, &[clip, camera, self.condition_id, step]);
            temporal::rewrite(&mut plan, fault, stream);
        }
        plan
    }

    /// Applies the condition's pixel steps to one frame (temporal steps are planned by
    /// [`plan_clip`](Self::plan_clip)). The identity returns the input unchanged.
    pub fn apply(&self, input: &FrameInput<'_>) -> Result<Applied, PerturbError> {
        let mut frame = Frame::scratch();
        let deficits = self.apply_into(input, &mut frame)?;
        Ok(Applied { frame, deficits })
    }

    /// [`apply`](Self::apply) into `out`, reusing its allocation.
    pub fn apply_into(
        &self,
        input: &FrameInput<'_>,
        out: &mut Frame,
    ) -> Result<Vec<DeficitRegion>, PerturbError> {
        out.reshape(input.frame.width(), input.frame.height());
        self.apply_to(input, &mut out.view_mut())
    }

    /// [`apply`](Self::apply) into a caller's buffer of the input's size (a numpy array, one
    /// image of a batch): the same bytes, no allocation for a one-step condition and one
    /// scratch frame for a chain.
    pub fn apply_to(
        &self,
        input: &FrameInput<'_>,
        out: &mut FrameMut<'_>,
    ) -> Result<Vec<DeficitRegion>, PerturbError> {
        let src = input.frame;
        let (w, h) = (src.width(), src.height());
        if (out.width(), out.height()) != (w, h) {
            return Err(PerturbError::OutputSize {
                width: out.width(),
                height: out.height(),
                expected_width: w,
                expected_height: h,
            });
        }
        if let Some(d) = input.depth {
            d.check_size(src)?;
        }
        deficit::validate_boxes(input.boxes, w, h)?;
        let mut deficits = Vec::new();
        if self.spatial.is_empty() {
            out.data_mut().copy_from_slice(src.data());
            return Ok(deficits);
        }
        let k = input.key;
        let ctx = |step: u64| StepCtx {
            frame_stream: child(
                self.seed,
                &[k.clip, k.camera, k.frame, self.condition_id, step],
            ),
            camera_stream: child(self.seed, &[k.clip, k.camera, self.condition_id, step]),
            depth: input.depth,
            boxes: input.boxes,
            name: &self.perturbation.name,
        };
        // A chain ping-pongs between `out` and one scratch frame, starting where it makes
        // the last step write into `out`.
        let n = self.spatial.len();
        let mut spare = Frame::scratch();
        if n > 1 {
            spare.reshape(w, h);
        }
        for (i, (step, kernel)) in self.spatial.iter().enumerate() {
            let into_out = (n - 1 - i).is_multiple_of(2);
            let c = ctx(*step);
            match (i, into_out) {
                (0, true) => kernel.run(src, out, &c, &mut deficits)?,
                (0, false) => kernel.run(src, &mut spare.view_mut(), &c, &mut deficits)?,
                (_, true) => kernel.run(spare.view(), out, &c, &mut deficits)?,
                (_, false) => kernel.run(out.as_ref(), &mut spare.view_mut(), &c, &mut deficits)?,
            }
        }
        Ok(deficits)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn apply_to_a_borrowed_buffer_gives_the_same_bytes_for_chains_of_any_length() {
        let mut data = Vec::new();
        for i in 0..(40 * 24 * 3) {
            data.push((i * 37 % 251) as u8);
        }
        let frame = Frame::new(40, 24, data).unwrap();
        let key = FrameKey::new(3, 1, 9);
        for name in [
            "clean",
            "noise_30",
            "noise_30+fog_03",
            "noise_30+fog_03+dark",
            "dark+noise_10+defocus_2+jpeg_20",
        ] {
            let p = Perturbation::parse(name).unwrap().prepare(5).unwrap();
            let owned = p.apply(&FrameInput::new(&frame, key)).unwrap().frame;
            let mut buf = vec![7u8; frame.data().len()];
            let mut out = FrameMut::new(40, 24, &mut buf).unwrap();
            p.apply_to(&FrameInput::new(frame.view(), key), &mut out)
                .unwrap();
            assert_eq!(buf, owned.data(), "{name}");
        }
        // A deterministic chain of any length (odd and even: the ping-pong starts in
        // either buffer) equals its steps applied one after the other.
        let steps = ["fog_03", "dark", "defocus_2", "jpeg_20"];
        let mut one_by_one = frame.clone();
        for n in 1..=steps.len() {
            let step = Perturbation::parse(steps[n - 1])
                .unwrap()
                .prepare(5)
                .unwrap();
            one_by_one = step
                .apply(&FrameInput::new(&one_by_one, key))
                .unwrap()
                .frame;
            let chain = Perturbation::parse(&steps[..n].join("+"))
                .unwrap()
                .prepare(5)
                .unwrap();
            let mut buf = vec![0u8; frame.data().len()];
            chain
                .apply_to(
                    &FrameInput::new(&frame, key),
                    &mut FrameMut::new(40, 24, &mut buf).unwrap(),
                )
                .unwrap();
            assert_eq!(buf, one_by_one.data(), "{n} steps");
        }
        let p = Perturbation::parse("noise_30").unwrap().prepare(5).unwrap();
        let mut small = vec![0u8; 40 * 23 * 3];
        let err = p
            .apply_to(
                &FrameInput::new(&frame, key),
                &mut FrameMut::new(40, 23, &mut small).unwrap(),
            )
            .unwrap_err();
        assert!(
            matches!(err, PerturbError::OutputSize { height: 23, .. }),
            "{err}"
        );
        assert!(FrameRef::new(40, 24, &small).is_err());
    }

    #[test]
    fn names_round_trip() {
        for name in [
            "noise_10",
            "noise_2.5",
            "dark",
            "bright",
            "gain_1.2",
            "fog_03",
            "fog_07",
            "fog_0.35",
            "visibility_150",
            "shot_4",
            "impulse_0.03",
            "contrast_0.4",
            "saturation_0.2",
            "defocus_3",
            "motion_15",
            "jpeg_10",
            "pixelate_8",
            "quantize_3",
            "dead_0.001",
            "dirt_5",
            "glare_0.8",
            "drop_0.2",
            "latency_3",
            "blackout_0",
            "freeze_10",
            "mask_all",
            "mask_class_pedestrian",
            "mask_track_7",
        ] {
            let p = Perturbation::parse(name).unwrap();
            assert_eq!(p.steps.len(), 1, "{name}");
            assert_eq!(p.steps[0].name(), name);
            assert_eq!(Perturbation::from_steps(p.steps.clone()), p);
        }
        let c = Perturbation::parse("noise_30+fog_03").unwrap();
        assert_eq!(c.steps.len(), 2);
        assert!(c.condition().is_none());
        assert!(Perturbation::parse("clean").unwrap().is_identity());
    }

    #[test]
    fn the_paper_grid_maps_to_the_types_families() {
        let c = Perturbation::parse("noise_30")
            .unwrap()
            .condition()
            .unwrap();
        assert_eq!((c.family, c.level), (Family::GaussianNoise, 30.0));
        let c = Perturbation::parse("fog_07").unwrap().condition().unwrap();
        assert_eq!((c.family, c.level), (Family::Fog, 0.7));
        let c = Perturbation::parse("dark").unwrap().condition().unwrap();
        assert_eq!((c.family, c.level), (Family::Brightness, 0.4));
        let c = Perturbation::parse("jpeg_10").unwrap().condition().unwrap();
        assert_eq!(c.family, Family::Other("jpeg".into()));
    }

    #[test]
    fn bad_names_say_what_is_expected() {
        for (name, needle) in [
            ("blur_3", "expected one of"),
            ("noise_x", "noise_<sigma>"),
            ("noise_-3", "noise_<sigma>"),
            ("fog_3", "fog_<alpha*10"),
            ("fog_1.5", "[0, 1]"),
            ("dark_2", "gain_<g>"),
            ("jpeg_0", "quality in [1, 100]"),
            ("jpeg_1.5", "not a whole number"),
            ("impulse_2", "fraction in [0, 1]"),
            ("contrast_-1", "[0, 100]"),
            ("shot_inf", "not a plain number"),
            ("mask_", "mask_all"),
            ("noise_10++dark", "empty step"),
            ("", "expected one of"),
        ] {
            let e = Perturbation::parse(name).unwrap_err().to_string();
            assert!(e.contains(needle), "{name}: {e}");
        }
    }

    #[test]
    fn steps_serialise_with_their_family() {
        let p = Perturbation::parse("noise_30+dark").unwrap();
        let v = serde_json::to_value(&p).unwrap();
        assert_eq!(v["steps"][0]["family"], "gaussian_noise");
        assert_eq!(v["steps"][0]["sigma"], 30.0);
        assert_eq!(v["steps"][1]["family"], "brightness");
        let back: Perturbation = serde_json::from_value(v).unwrap();
        assert_eq!(back, p);
    }
}
