//! Blind condition estimates of image files (what `fogline monitor estimate` runs): each
//! PNG or JPEG is decoded to RGB8 and measured by `fogline_monitor::estimate_frame` —
//! Gaussian noise σ, photometric gain and fog opacity, each with its standard error.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, Result};
use fogline_monitor::{ConditionParams, estimate_frame};
use serde::Serialize;

/// The estimates of one image.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ImageEstimate {
    /// The file, as given.
    pub path: String,
    /// Width, px.
    pub width: u32,
    /// Height, px.
    pub height: u32,
    /// Gaussian noise σ, 0–255 scale (`noise_<σ>`).
    pub noise_sigma: f64,
    /// Standard error of `noise_sigma`.
    pub noise_sigma_se: f64,
    /// Photometric gain (1 = as the reference; `dark` 0.4, `bright` 1.6).
    pub gain: f64,
    /// Standard error of `gain`.
    pub gain_se: f64,
    /// Fog opacity α in [0, 1] (`fog_07`: 0.7).
    pub fog: f64,
    /// Standard error of `fog`.
    pub fog_se: f64,
    /// Share of the noise residuals left out because a pixel in them clipped.
    pub clipped_share: f64,
    /// Milliseconds the estimates took (decoding excluded), one thread.
    pub ms: f64,
}

/// Decodes and measures one image; the error names the file.
pub fn estimate_image(path: &Path, params: &ConditionParams) -> Result<ImageEstimate> {
    let bytes = std::fs::read(path).with_context(|| format!("cannot read {}", path.display()))?;
    let img = fogline_io::image::decode_rgb(&bytes)
        .map_err(anyhow::Error::msg)
        .with_context(|| format!("{} is not a readable PNG or JPEG image", path.display()))?;
    let (w, h) = (img.width as usize, img.height as usize);
    let start = Instant::now();
    let e = estimate_frame(&img.rgb, w, h, params)
        .with_context(|| format!("cannot measure {}", path.display()))?;
    let ms = start.elapsed().as_secs_f64() * 1e3;
    Ok(ImageEstimate {
        path: path.display().to_string(),
        width: img.width,
        height: img.height,
        noise_sigma: e.noise.sigma,
        noise_sigma_se: e.noise.sigma_se,
        gain: e.condition.gain,
        gain_se: e.condition.gain_se,
        fog: e.condition.fog,
        fog_se: e.condition.fog_se,
        clipped_share: e.noise.clipped_share,
        ms,
    })
}

/// Measures every image in order (one thread, so `ms` is a one-thread figure); a file that
/// cannot be read or decoded gives its error in its place, the others are still measured.
pub fn estimate_images(paths: &[PathBuf], params: &ConditionParams) -> Vec<Result<ImageEstimate>> {
    paths.iter().map(|p| estimate_image(p, params)).collect()
}

/// Writes one result: a JSON object on one line with `json`, else a row of the table
/// (after [`write_header`]).
pub fn write_row(e: &ImageEstimate, json: bool, out: &mut dyn Write) -> Result<()> {
    if json {
        writeln!(out, "{}", serde_json::to_string(e)?)?;
    } else {
        writeln!(
            out,
            "{:>6.2} ±{:<5.2} {:>5.2} ±{:<5.2} {:>5.2} ±{:<5.2} {:>7.2}  {}",
            e.noise_sigma, e.noise_sigma_se, e.gain, e.gain_se, e.fog, e.fog_se, e.ms, e.path
        )?;
    }
    Ok(())
}

/// The table's header (nothing with `json`).
pub fn write_header(json: bool, out: &mut dyn Write) -> Result<()> {
    if !json {
        writeln!(
            out,
            "{:>6} {:6} {:>5} {:6} {:>5} {:6} {:>7}  path",
            "sigma", "±", "gain", "±", "fog", "±", "ms"
        )?;
    }
    Ok(())
}
