//! What this image's cell can do: the lighting options compiled in (cargo features of the
//! firmware crate: the default ones make `render`'s default cell, none the thesis's). A light setup asking for an option that is not compiled
//! in is refused (`CapacityMismatch`, counted as a bad frame); the setup the cell keeps has
//! those options as constants, so the optimiser removes their code from the image.

use cell_core::beam::frac::U0;
use cell_core::beam::SplitOrder;
use cell_core::cell::{Cell, DEFAULT_DEXELS};
use cell_core::facet::RowPacket;
use cell_core::light::{FrustumSummary, LightEnv, Policy};
use cell_core::lit::LitRule;
use cell_core::trace::{LightSetup, ReplayError};
use cell_core::wire::{DecodeError, Reader};

/// The frustum flag and summary of a light record: the summary is refused unless the
/// empty-frustum skip is compiled in (its decoder and its test then stay out of the image).
pub fn read_frustum(r: &mut Reader<'_>, n: u32, depth: u32) -> Result<Option<FrustumSummary>, DecodeError> {
    if cfg!(feature = "frustum") {
        cell_core::trace::read_frustum(r, n, depth)
    } else {
        match r.u8()? {
            0 => Ok(None),
            _ => Err(DecodeError::BadValue("frustum skip not compiled in")),
        }
    }
}

/// `s`, if this image can run it.
pub fn check(s: LightSetup) -> Result<LightSetup, ReplayError> {
    let ok = (cfg!(feature = "plane-rule") || s.rule == LitRule::Thesis)
        && (cfg!(feature = "policies") || s.policy == Policy::Thesis)
        && (cfg!(feature = "hold") || s.hold == 0)
        && (cfg!(feature = "skip") || s.skip.is_none())
        // The visible-only lit store keeps what the pixel reads: a cell that does not shade
        // keeps the full store (`light`'s).
        && (cfg!(feature = "shading") || !s.lit_visible_only);
    if ok {
        Ok(s)
    } else {
        Err(ReplayError::CapacityMismatch)
    }
}

/// The lit rule the cell shades with: a constant without the plane rule.
#[inline(always)]
pub fn rule(r: LitRule) -> LitRule {
    if cfg!(feature = "plane-rule") {
        r
    } else {
        LitRule::Thesis
    }
}

/// `s` with the options not compiled in fixed to "off", where the compiler sees them: the
/// kept setup is a value in memory, only a copy fixed here and passed to the (inlined)
/// `LightSetup::env_without_frustum` makes them constants in the step, and their code leaves
/// the image.
#[inline(always)]
pub fn fixed_options(mut s: LightSetup) -> LightSetup {
    if !cfg!(feature = "frustum") {
        s.frustum = None;
    }
    s.rule = rule(s.rule);
    if !cfg!(feature = "policies") {
        s.policy = Policy::Thesis;
    }
    if !cfg!(feature = "hold") {
        s.hold = 0;
    }
    if !cfg!(feature = "skip") {
        s.skip = None;
    }
    if !cfg!(feature = "shading") {
        s.lit_visible_only = false;
    }
    s
}

/// The environment the cell steps with. Without the empty-frustum skip it is built without a
/// summary reference at all: even a `None` one carries the summary's vtable, and with it the
/// skip's code and (through its `Debug` bound) the formatting machinery.
#[inline(always)]
pub fn env<'s>(s: &'s LightSetup, order: &'s SplitOrder) -> Result<LightEnv<'s, U0>, ReplayError> {
    if cfg!(feature = "frustum") {
        s.env(order)
    } else {
        s.env_without_frustum(order)
    }
}

/// The loading step (§3.9): without the plane rule, the cell's dexels need no plane and it
/// keeps no visible surface.
#[inline(always)]
pub fn load_step(cell: &mut Cell<DEFAULT_DEXELS>, pkt: &mut RowPacket, depth: u32) -> bool {
    if cfg!(feature = "plane-rule") {
        cell.load_step(pkt, depth)
    } else {
        cell.load_step_without_planes(pkt, depth)
    }
}
