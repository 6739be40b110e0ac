//! PNG output of the machine's images.

use std::path::Path;

use anyhow::Result;

use crate::report::files::create;

/// Write an n × n RGB image (index y·n + x, y up) as PNG, top row first, seen from the camera:
/// looking along +z with y up, +x points to the viewer's left (so the Cornell box shows its red
/// wall on the left, as in the published pictures).
pub fn write_png(path: &Path, n: u32, rgb: &[[u8; 3]]) -> Result<()> {
    let mut enc = png::Encoder::new(create(path)?, n, n);
    enc.set_color(png::ColorType::Rgb);
    enc.set_depth(png::BitDepth::Eight);
    let mut w = enc.write_header()?;
    let mut data = Vec::with_capacity((n * n * 3) as usize);
    for y in (0..n).rev() {
        for x in (0..n).rev() {
            data.extend_from_slice(&rgb[(y * n + x) as usize]);
        }
    }
    w.write_image_data(&data)?;
    Ok(())
}

/// Write a `w` × `h` RGB picture (index y·w + x, top row first, as drawn) as PNG.
pub fn write_png_rect(path: &Path, w: u32, h: u32, rgb: &[[u8; 3]]) -> Result<()> {
    let mut enc = png::Encoder::new(create(path)?, w, h);
    enc.set_color(png::ColorType::Rgb);
    enc.set_depth(png::BitDepth::Eight);
    let mut out = enc.write_header()?;
    out.write_image_data(&rgb.iter().flatten().copied().collect::<Vec<u8>>())?;
    Ok(())
}
