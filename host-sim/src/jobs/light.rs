//! The `light` job's defaults and outputs.

use std::io::Write;

use anyhow::Result;
use cell_core::beam::FracBits;

use crate::machine::diffuse::Lighting;

/// Fraction bits the lighting jobs use unless told otherwise: under the plane rule f = 0 meets
/// the accuracy goals at a quarter to four fifths of the former default's cycles; f = 1 is the
/// accuracy knob for faces lit at extreme grazing angles (BENCHMARKS.md, "Is the light right?").
pub const DEFAULT_FRAC_BITS: u32 = 0;

/// Write `x,y,z,source_mask` for every lit voxel.
pub fn write_lit_csv<F: FracBits>(l: &Lighting<F>, mut w: impl Write) -> Result<()> {
    writeln!(w, "x,y,z,source_mask")?;
    for ([x, y, z], m) in l.lit_voxels() {
        writeln!(w, "{x},{y},{z},{m}")?;
    }
    Ok(())
}
