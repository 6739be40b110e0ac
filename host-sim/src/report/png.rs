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
