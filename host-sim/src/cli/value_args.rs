//! Command-line mirrors of the domain's option enums: the domain types stay free of clap; each
//! mirror carries the `--help` text of its values and converts into the domain type.

use crate::machine::lighting::diffuse::{FrustumBlocks, OracleSkip};
use crate::machine::loading::engines::Engine;
use crate::precompute::{Contour, Thickness};

/// Plane thickness (§3.5, §3.8).
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum ThicknessArg {
    /// σ = ½: the thinnest hole-free plane; stops 6-connected rays only.
    Naive,
    /// The thesis's σ = max σ_ij, σ_ij = ½(1 + min/max) (§3.8): chosen from experiments.
    Thesis,
    /// Kσ = (|a|+|b|+|c|)/2: the standard arithmetic plane, provably free of 26-tunnels.
    Standard,
}

impl From<ThicknessArg> for Thickness {
    fn from(a: ThicknessArg) -> Self {
        match a {
            ThicknessArg::Naive => Thickness::Naive,
            ThicknessArg::Thesis => Thickness::Thesis,
            ThicknessArg::Standard => Thickness::Standard,
        }
    }
}

/// Contour of a facet (§3.6, §3.8).
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum ContourArg {
    /// The thesis's projected contour: the voxel centre's projection lies in the facet's.
    Projected,
    /// Edges pushed out by the voxel's half-extent: every voxel whose square touches the
    /// projected facet is kept; closes gaps between facets and holes in thin facets.
    Conservative,
}

impl From<ContourArg> for Contour {
    fn from(a: ContourArg) -> Self {
        match a {
            ContourArg::Projected => Contour::Projected,
            ContourArg::Conservative => Contour::Conservative,
        }
    }
}

/// How the grid is loaded.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum EngineArg {
    /// The RC² wave, cycle by cycle (the machine).
    Wave,
    /// The direct host evaluation of the same integer formulas (reference and baseline).
    Direct,
}

impl From<EngineArg> for Engine {
    fn from(a: EngineArg) -> Self {
        match a {
            EngineArg::Wave => Engine::Wave,
            EngineArg::Direct => Engine::Direct,
        }
    }
}

/// Blocks per axis of the occupancy summary the beam skips test against.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum FrustumBlocksArg {
    /// 8 × 8 × 8 blocks, `u8` rows: 232 bytes per cell (what a cell trace carries).
    #[value(name = "8")]
    B8,
    /// 16 × 16 × 16 blocks, `u16` rows: 1 348 bytes per cell.
    #[value(name = "16")]
    B16,
    /// 32 × 32 × 32 blocks, `u32` rows: 9 384 bytes per cell.
    #[value(name = "32")]
    B32,
}

/// `--oracle-skip`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum OracleSkipArg {
    /// The machine as it is.
    Off,
    /// Drop beams whose voxel lies on no pixel's target ray before its target.
    Voxels,
    /// Drop beams that hold no pixel's target ray of a later layer.
    Rays,
}

impl From<OracleSkipArg> for OracleSkip {
    fn from(a: OracleSkipArg) -> Self {
        match a {
            OracleSkipArg::Off => OracleSkip::Off,
            OracleSkipArg::Voxels => OracleSkip::Voxels,
            OracleSkipArg::Rays => OracleSkip::Rays,
        }
    }
}

/// `--visibility`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum VisibilityArg {
    /// Lit iff the pixel's target ray arrives.
    Target,
    /// The share of the target voxel's rays that arrive weighs the light.
    Ratio,
    /// Lit iff more than half of them arrive.
    Majority,
}

impl From<VisibilityArg> for cell_core::visibility::Visibility {
    fn from(a: VisibilityArg) -> Self {
        use cell_core::visibility::Visibility;
        match a {
            VisibilityArg::Target => Visibility::Target,
            VisibilityArg::Ratio => Visibility::Ratio,
            VisibilityArg::Majority => Visibility::Majority,
        }
    }
}

/// How the ranks of an MPI run share a lighting run (`--spread`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum SpreadArg {
    /// Sources when there are at least as many as ranks (and they can be split), tiles
    /// otherwise.
    Auto,
    /// Each rank diffuses its share of the light sources on its own copy of the grid.
    Sources,
    /// The grid cut into bands of rows, one per rank; the messages that cross a band's edge go
    /// between the ranks every cycle.
    Tiles,
}

impl From<SpreadArg> for crate::dist::Spread {
    fn from(a: SpreadArg) -> Self {
        use crate::dist::Spread;
        match a {
            SpreadArg::Auto => Spread::Auto,
            SpreadArg::Sources => Spread::Sources,
            SpreadArg::Tiles => Spread::Tiles,
        }
    }
}

impl From<FrustumBlocksArg> for FrustumBlocks {
    fn from(a: FrustumBlocksArg) -> Self {
        match a {
            FrustumBlocksArg::B8 => FrustumBlocks::B8,
            FrustumBlocksArg::B16 => FrustumBlocks::B16,
            FrustumBlocksArg::B32 => FrustumBlocks::B32,
        }
    }
}
