//! The parameters of every family: one `XxxParams` struct each, public fields, `Default` (the
//! identity where the family has one), serde, and `validate()`.

use serde::{Deserialize, Serialize};

use crate::PerturbError;

fn check(
    ok: bool,
    family: &'static str,
    parameter: &'static str,
    value: f64,
    expected: &'static str,
) -> Result<(), PerturbError> {
    if ok {
        Ok(())
    } else {
        Err(PerturbError::InvalidParameter {
            family,
            parameter,
            value,
            expected,
        })
    }
}

/// Default airlight `A` of the fog models: 204 on the 0–255 scale (0.8 of full scale, a bright
/// grey sky). The envelope paper names no value; imagecorruptions uses the frame maximum and
/// 3D Common Corruptions the frame mean, both of which make `A` depend on the content.
pub const DEFAULT_AIRLIGHT: f64 = 204.0;

/// Default reference distance of Koschmieder fog: the distance at which the opacity is `α`.
/// 50 m turns `fog_03` into β = 0.0071 m⁻¹ (visibility 548 m) and `fog_07` into
/// β = 0.0241 m⁻¹ (visibility 162 m), inside Foggy Cityscapes' range (β 0.005–0.02 m⁻¹).
pub const DEFAULT_REFERENCE_DIST_M: f64 = 50.0;

/// Gaussian noise (`noise_<σ>`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct GaussianNoiseParams {
    /// Standard deviation on the 0–255 scale, in [0, 1000]; 0 is the identity.
    pub sigma: f64,
}

impl Default for GaussianNoiseParams {
    fn default() -> Self {
        Self { sigma: 0.0 }
    }
}

impl GaussianNoiseParams {
    /// Checks the ranges.
    pub fn validate(&self) -> Result<(), PerturbError> {
        check(
            self.sigma.is_finite() && (0.0..=1000.0).contains(&self.sigma),
            "gaussian_noise",
            "sigma",
            self.sigma,
            "a number in [0, 1000]",
        )
    }
}

/// Photometric gain (`dark`, `bright`, `gain_<g>`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct GainParams {
    /// The factor, in [0, 255]; 1 is the identity.
    pub gain: f64,
}

impl Default for GainParams {
    fn default() -> Self {
        Self { gain: 1.0 }
    }
}

impl GainParams {
    /// Checks the ranges.
    pub fn validate(&self) -> Result<(), PerturbError> {
        check(
            self.gain.is_finite() && (0.0..=255.0).contains(&self.gain),
            "brightness",
            "gain",
            self.gain,
            "a number in [0, 255]",
        )
    }
}

/// Which fog model to use.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum FogModel {
    /// Koschmieder when a depth map is given, homogeneous otherwise.
    #[default]
    Auto,
    /// Always the homogeneous blend.
    Homogeneous,
    /// Always Koschmieder (a depth map is required).
    Koschmieder,
}

/// Fog (`fog_<α·10 as two digits>`, e.g. `fog_03`, or `fog_<α>` such as `fog_0.35`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct FogParams {
    /// Opacity in [0, 1]: everywhere (homogeneous), or at `reference_dist_m` (Koschmieder).
    pub alpha: f64,
    /// Airlight `A` on the 0–255 scale.
    pub airlight: f64,
    /// Koschmieder only: the distance whose opacity is `alpha`; `β = −ln(1 − α) / d_ref`.
    pub reference_dist_m: f64,
    /// The model.
    pub model: FogModel,
}

impl Default for FogParams {
    fn default() -> Self {
        Self {
            alpha: 0.0,
            airlight: DEFAULT_AIRLIGHT,
            reference_dist_m: DEFAULT_REFERENCE_DIST_M,
            model: FogModel::Auto,
        }
    }
}

impl FogParams {
    /// Checks the ranges.
    pub fn validate(&self) -> Result<(), PerturbError> {
        check(
            (0.0..=1.0).contains(&self.alpha),
            "fog",
            "alpha",
            self.alpha,
            "a number in [0, 1]",
        )?;
        check_airlight("fog", self.airlight)?;
        check(
            self.reference_dist_m.is_finite() && self.reference_dist_m > 0.0,
            "fog",
            "reference_dist_m",
            self.reference_dist_m,
            "a distance > 0",
        )
    }

    /// The extinction coefficient of the Koschmieder model, `−ln(1 − α) / d_ref` (m⁻¹).
    pub fn beta_per_m(&self) -> f64 {
        -(1.0 - self.alpha).ln() / self.reference_dist_m
    }
}

fn check_airlight(family: &'static str, a: f64) -> Result<(), PerturbError> {
    check(
        (0.0..=255.0).contains(&a),
        family,
        "airlight",
        a,
        "a number in [0, 255]",
    )
}

/// Koschmieder fog by meteorological visibility (`visibility_<m>`); needs a depth map.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct VisibilityParams {
    /// Meteorological visibility `V` in metres (> 0): `β = −ln(0.02) / V = 3.912 / V`.
    pub visibility_m: f64,
    /// Airlight `A` on the 0–255 scale.
    pub airlight: f64,
}

impl Default for VisibilityParams {
    fn default() -> Self {
        Self {
            visibility_m: 300.0,
            airlight: DEFAULT_AIRLIGHT,
        }
    }
}

impl VisibilityParams {
    /// Checks the ranges.
    pub fn validate(&self) -> Result<(), PerturbError> {
        check(
            self.visibility_m.is_finite() && self.visibility_m > 0.0,
            "fog_visibility",
            "visibility_m",
            self.visibility_m,
            "a distance > 0",
        )?;
        check_airlight("fog_visibility", self.airlight)
    }

    /// `β = −ln(0.02) / V` (m⁻¹).
    pub fn beta_per_m(&self) -> f64 {
        -(0.02f64.ln()) / self.visibility_m
    }
}

macro_rules! single_param {
    (
        $(#[$meta:meta])* $name:ident, $field:ident: $ty:ty = $default:expr,
        $family:literal, $ok:expr, $expected:literal, $fdoc:literal
    ) => {
        $(#[$meta])*
        #[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
        #[serde(default)]
        pub struct $name {
            #[doc = $fdoc]
            pub $field: $ty,
        }

        impl Default for $name {
            fn default() -> Self {
                Self { $field: $default }
            }
        }

        impl $name {
            /// Checks the ranges.
            pub fn validate(&self) -> Result<(), PerturbError> {
                let v = self.$field;
                #[allow(clippy::redundant_closure_call)]
                let ok = ($ok)(v);
                check(ok, $family, stringify!($field), v as f64, $expected)
            }
        }
    };
}

single_param!(
    /// Shot (Poisson) noise (`shot_<s>`).
    ShotNoiseParams, units_per_photon: f64 = 0.0, "shot_noise",
    |v: f64| v == 0.0 || (0.01..=10_000.0).contains(&v),
    "0 (identity) or a number in [0.01, 10000]",
    "Intensity units per photon `s` (0–255 scale): variance `s·x` at intensity `x`; 0 is the identity."
);
single_param!(
    /// Impulse (salt-and-pepper) noise (`impulse_<p>`).
    ImpulseNoiseParams, fraction: f64 = 0.0, "impulse_noise",
    |v: f64| (0.0..=1.0).contains(&v),
    "a fraction in [0, 1]",
    "Fraction of samples replaced, half by 0 and half by 255; 0 is the identity."
);
single_param!(
    /// Contrast (`contrast_<c>`).
    ContrastParams, factor: f64 = 1.0, "contrast",
    |v: f64| (0.0..=100.0).contains(&v),
    "a number in [0, 100]",
    "Factor `c` around the frame's mean grey; 1 is the identity, 0 a flat grey frame."
);
single_param!(
    /// Saturation (`saturation_<s>`).
    SaturationParams, factor: f64 = 1.0, "saturation",
    |v: f64| (0.0..=100.0).contains(&v),
    "a number in [0, 100]",
    "Factor `s` around each pixel's luma; 1 is the identity, 0 greyscale."
);
single_param!(
    /// Defocus blur (`defocus_<r>`).
    DefocusParams, radius_px: f64 = 0.0, "defocus_blur",
    |v: f64| (0.0..=100.0).contains(&v),
    "a radius in [0, 100] px",
    "Disk radius in pixels; below 1 is the identity."
);
single_param!(
    /// Pixelation (`pixelate_<b>`).
    PixelateParams, block_px: u32 = 1, "pixelate",
    |v: u32| (1..=4096).contains(&v),
    "a block size in [1, 4096] px",
    "Block size in pixels; 1 is the identity."
);
single_param!(
    /// Colour quantisation (`quantize_<bits>`).
    QuantizeParams, bits: u32 = 8, "quantize",
    |v: u32| (1..=8).contains(&v),
    "a bit depth in [1, 8]",
    "Bits per channel; 8 is the identity."
);
single_param!(
    /// Frame drop (`drop_<p>`).
    DropParams, probability: f64 = 0.0, "frame_drop",
    |v: f64| (0.0..=1.0).contains(&v),
    "a probability in [0, 1]",
    "Probability that a frame (after the first) repeats the previous one; 0 is the identity."
);
single_param!(
    /// Latency (`latency_<k>`).
    LatencyParams, frames: u64 = 0, "latency",
    |v: u64| v <= 1_000_000,
    "a whole number of frames in [0, 1000000]",
    "Delay in frames; 0 is the identity."
);
single_param!(
    /// Camera blackout (`blackout_<f>`).
    BlackoutParams, from_frame: u64 = 0, "blackout",
    |_v: u64| true,
    "a frame index",
    "First black frame (0: the whole clip)."
);
single_param!(
    /// Frozen camera (`freeze_<f>`).
    FreezeParams, from_frame: u64 = 0, "freeze",
    |_v: u64| true,
    "a frame index",
    "The frame the camera freezes at (every later frame repeats it)."
);

/// Motion blur (`motion_<length>`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct MotionParams {
    /// Length of the blur line in pixels, in [1, 1000]; 1 is the identity.
    pub length_px: u32,
    /// Direction, degrees counter-clockwise from the x axis (0 = horizontal).
    pub angle_deg: f64,
}

impl Default for MotionParams {
    fn default() -> Self {
        Self {
            length_px: 1,
            angle_deg: 0.0,
        }
    }
}

impl MotionParams {
    /// Checks the ranges.
    pub fn validate(&self) -> Result<(), PerturbError> {
        check(
            (1..=1000).contains(&self.length_px),
            "motion_blur",
            "length_px",
            f64::from(self.length_px),
            "a length in [1, 1000] px",
        )?;
        check(
            self.angle_deg.is_finite(),
            "motion_blur",
            "angle_deg",
            self.angle_deg,
            "a finite angle",
        )
    }
}

/// JPEG compression (`jpeg_<quality>`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct JpegParams {
    /// libjpeg quality in [1, 100].
    pub quality: u32,
    /// 4:2:0 chroma subsampling (libjpeg's default).
    pub chroma_subsampling: bool,
}

impl Default for JpegParams {
    fn default() -> Self {
        Self {
            quality: 75,
            chroma_subsampling: true,
        }
    }
}

impl JpegParams {
    /// Checks the ranges.
    pub fn validate(&self) -> Result<(), PerturbError> {
        check(
            (1..=100).contains(&self.quality),
            "jpeg",
            "quality",
            f64::from(self.quality),
            "a quality in [1, 100]",
        )
    }
}

/// Dead pixels (`dead_<p>`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct DeadPixelParams {
    /// Fraction of pixels that are dead, in [0, 1]; 0 is the identity.
    pub fraction: f64,
    /// What a dead pixel shows.
    pub rgb: [u8; 3],
}

impl Default for DeadPixelParams {
    fn default() -> Self {
        Self {
            fraction: 0.0,
            rgb: [0, 0, 0],
        }
    }
}

impl DeadPixelParams {
    /// Checks the ranges.
    pub fn validate(&self) -> Result<(), PerturbError> {
        check(
            (0.0..=1.0).contains(&self.fraction),
            "dead_pixels",
            "fraction",
            self.fraction,
            "a fraction in [0, 1]",
        )
    }
}

/// Glare (`glare_<s>`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct GlareParams {
    /// Peak strength in [0, 1]; 0 is the identity, 1 saturates the spot's centre to white.
    pub strength: f64,
    /// Spot centre as fractions of width and height.
    pub centre: [f64; 2],
    /// Spot radius (Gaussian σ) as a fraction of the frame diagonal, in (0, 10].
    pub radius: f64,
}

impl Default for GlareParams {
    fn default() -> Self {
        Self {
            strength: 0.0,
            centre: [0.7, 0.3],
            radius: 0.15,
        }
    }
}

impl GlareParams {
    /// Checks the ranges.
    pub fn validate(&self) -> Result<(), PerturbError> {
        check(
            (0.0..=1.0).contains(&self.strength),
            "glare",
            "strength",
            self.strength,
            "a number in [0, 1]",
        )?;
        for c in self.centre {
            check(c.is_finite(), "glare", "centre", c, "finite fractions")?;
        }
        check(
            self.radius > 0.0 && self.radius <= 10.0,
            "glare",
            "radius",
            self.radius,
            "a fraction of the diagonal in (0, 10]",
        )
    }
}
