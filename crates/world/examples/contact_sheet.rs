//! Writes a contact sheet: one clip per scenario (rows), the four cameras at `t0` (columns),
//! each at half size.
//!
//! `cargo run --release -p fogline-world --example contact_sheet -- OUT.png [SEED]`

use fogline_world::config::{SCENARIOS, ScenarioMix};
use fogline_world::{WorldConfig, generate_clip};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let out = args.next().ok_or("usage: contact_sheet OUT.png [SEED]")?;
    let seed: u64 = args.next().map_or(Ok(7), |s| s.parse())?;
    let config = WorldConfig {
        seed,
        mix: ScenarioMix::uniform(1),
        ..WorldConfig::default()
    };
    let (w, h) = (config.width as usize / 2, config.height as usize / 2);
    let cols = 4;
    let rows = SCENARIOS.len();
    let mut sheet = vec![0u8; cols * w * rows * h * 3];
    for r in 0..rows {
        let clip = generate_clip(&config, r)?;
        for (c, cam) in clip.cameras.iter().enumerate() {
            let img = &cam.frames[cam.frames.len() - 1].image;
            let src = img.data();
            let sw = img.width() as usize;
            for y in 0..h {
                for x in 0..w {
                    for ch in 0..3 {
                        let mut acc = 0u32;
                        for (dy, dx) in [(0, 0), (0, 1), (1, 0), (1, 1)] {
                            acc += u32::from(src[((2 * y + dy) * sw + 2 * x + dx) * 3 + ch]);
                        }
                        let o = ((r * h + y) * cols * w + c * w + x) * 3 + ch;
                        sheet[o] = ((acc + 2) / 4) as u8;
                    }
                }
            }
        }
        eprintln!("{}: {:?}", clip.scenario, clip.scene.decision);
    }
    image::save_buffer(
        &out,
        &sheet,
        (cols * w) as u32,
        (rows * h) as u32,
        image::ExtendedColorType::Rgb8,
    )?;
    Ok(())
}
