//! The oracle skip ([`OracleSkip`]): how much of a render's diffusion no pixel needs.
//!
//! Under exact occluders with the visible-only lit store, a pixel is lit iff its one target ray
//! arrives at its target voxel ([`cell_core::receiver`]); a beam that carries no pixel's target
//! ray to a later layer can change no pixel. The host, which holds every column's target ray,
//! drops such beams when a cell processes them (as the empty-frustum skip drops a beam, its rays
//! counted as skipped), so the image is the same and what is left is the work the image needs.
//!
//! It is *not* a rule a cell can run: a cell would have to know every target ray through its
//! column, which only a wave from every pixel back toward the light could tell it. It measures
//! the surplus (BENCHMARKS.md, "How fast is the host?") and bounds what such a rule could save.
//! Two resolutions: per lattice ray (exact: the beam's rectangle holds a target ray whose target
//! layer is later), and per voxel (the beam's voxel lies on some target ray's path before its
//! target: what a cell could be told with one bit per voxel and direction).

use cell_core::beam::{trace_ray_voxel, Beam, Direction, FarDistance, FarOffset, FracBits, Layer, Source};
use cell_core::occupancy::FrustumTest;

use crate::machine::grid::Grid;
use crate::machine::lighting::occluders::SourceOccluders;

/// Which beams the host drops as no pixel's ([`super::LightConfig::oracle_skip`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum OracleSkip {
    /// None: the machine as it is.
    #[default]
    Off,
    /// Beams whose voxel is on no pixel's target ray before that ray's target layer.
    Voxels,
    /// Beams whose rectangle holds no pixel's target ray of a later target layer.
    Rays,
}

/// Lattice rays per side of a tile of [`Needed`]'s ray table (the tile's largest layer lets a
/// query pass over the whole tile).
const TILE: usize = 16;

/// The oracle's frustum test for one source: "empty" when the beam is no pixel's, or when the
/// cells' own test (`inner`) says so.
pub(super) struct Needed<'a, F: FracBits> {
    inner: Option<&'a dyn FrustumTest<F>>,
    source: Source,
    what: What,
}

enum What {
    /// Per direction, per lattice ray `(a + N)·side + (b + N)`, the largest target layer of the
    /// pixels whose target ray it is (0: none), and the same per [`TILE`]² tile.
    Rays { n: i64, side: usize, tiles: usize, layer: Vec<Vec<u32>>, tile: Vec<Vec<u32>> },
    /// Per direction, one bit per voxel `(y·n + x)·depth + z`: on a target ray's path before
    /// its target.
    Voxels { n: usize, depth: usize, bits: Vec<Vec<u64>> },
}

impl<'a, F: FracBits> Needed<'a, F> {
    /// The test for `source`'s pixels (their target rays in `occluders`), or `None` when the
    /// skip is off.
    pub(super) fn new<const D: usize>(
        skip: OracleSkip,
        inner: Option<&'a dyn FrustumTest<F>>,
        occluders: &SourceOccluders<'_>,
        source: &Source,
        far: FarDistance<F>,
        grid: &Grid<D>,
    ) -> Option<Self> {
        let targets = occluders.targets().iter().flatten();
        let what = match skip {
            OracleSkip::Off => return None,
            OracleSkip::Rays => {
                let n = far.scaled();
                let side = (2 * n + 1) as usize;
                let tiles = side.div_ceil(TILE);
                let mut layer = vec![vec![0u32; side * side]; 6];
                let mut tile = vec![vec![0u32; tiles * tiles]; 6];
                for t in targets {
                    let (a, b) = ((t.a + n) as usize, (t.b + n) as usize);
                    let d = t.dir.index() as usize;
                    layer[d][a * side + b] = layer[d][a * side + b].max(t.layer);
                    let tl = &mut tile[d][a / TILE * tiles + b / TILE];
                    *tl = (*tl).max(t.layer);
                }
                What::Rays { n, side, tiles, layer, tile }
            }
            OracleSkip::Voxels => {
                let (n, depth) = (grid.n as usize, grid.depth as usize);
                let mut bits = vec![vec![0u64; (n * n * depth).div_ceil(64)]; 6];
                for t in targets {
                    let (a, b) = (FarOffset::<F>::from_bits(t.a as i32), FarOffset::<F>::from_bits(t.b as i32));
                    for j in 0..t.layer {
                        if let Some(i) = voxel_index(source, t.dir, Layer(j), (a, b), far, n, depth) {
                            bits[t.dir.index() as usize][i / 64] |= 1 << (i % 64);
                        }
                    }
                }
                What::Voxels { n, depth, bits }
            }
        };
        Some(Needed { inner, source: *source, what })
    }

    /// Whether `beam` carries a target ray whose target layer is `k0` or later.
    fn needed(&self, beam: &Beam<F>, far: FarDistance<F>, k0: u32) -> bool {
        let d = beam.direction().index() as usize;
        match &self.what {
            What::Rays { n, side, tiles, layer, tile } => {
                let (u, v) = (beam.u(), beam.v());
                let (a0, a1) = ((u.lo().to_bits() as i64 + n) as usize, (u.hi().to_bits() as i64 + n) as usize);
                let (b0, b1) = ((v.lo().to_bits() as i64 + n) as usize, (v.hi().to_bits() as i64 + n) as usize);
                let (layer, tile) = (&layer[d], &tile[d]);
                for ta in a0 / TILE..=a1 / TILE {
                    for tb in b0 / TILE..=b1 / TILE {
                        if tile[ta * tiles + tb] < k0 {
                            continue; // nothing in this tile reaches k0
                        }
                        let (ra, rb) = (ta * TILE, tb * TILE);
                        if a0 <= ra && ra + TILE - 1 <= a1 && b0 <= rb && rb + TILE - 1 <= b1 {
                            return true; // the whole tile is in the beam
                        }
                        for a in a0.max(ra)..=a1.min(ra + TILE - 1) {
                            let row = &layer[a * side..][..*side];
                            if row[b0.max(rb)..=b1.min(rb + TILE - 1)].iter().any(|&l| l >= k0) {
                                return true;
                            }
                        }
                    }
                }
                false
            }
            What::Voxels { n, depth, bits } => {
                // The beam's voxel: its (u_min, v_min) ray's at its layer.
                let rays = (beam.u().lo(), beam.v().lo());
                voxel_index(&self.source, beam.direction(), beam.layer(), rays, far, *n, *depth)
                    .is_some_and(|i| bits[d][i / 64] >> (i % 64) & 1 == 1)
            }
        }
    }
}

/// The index `(y·n + x)·depth + z` of lattice ray `(a, b)`'s voxel at `layer` along `dir`, if it
/// is in an `n` × `n` × `depth` grid.
fn voxel_index<F: FracBits>(
    source: &Source,
    dir: Direction,
    layer: Layer,
    (a, b): (FarOffset<F>, FarOffset<F>),
    far: FarDistance<F>,
    n: usize,
    depth: usize,
) -> Option<usize> {
    let (w, (ua, va)) = (dir.principal().index(), dir.transverse());
    let (pu, pv) = trace_ray_voxel(source, dir, a, b, far, layer);
    let mut p = [0i64; 3];
    p[w] = source.slab(dir, layer);
    p[ua.index()] = pu;
    p[va.index()] = pv;
    let inside = p.iter().all(|&c| c >= 0) && p[0] < n as i64 && p[1] < n as i64 && p[2] < depth as i64;
    inside.then(|| (p[1] as usize * n + p[0] as usize) * depth + p[2] as usize)
}

impl<F: FracBits> FrustumTest<F> for Needed<'_, F> {
    fn frustum_empty(&self, beam: &Beam<F>, source: &Source, far: FarDistance<F>, k0: u32) -> bool {
        debug_assert!(source.id == self.source.id && source.pos == self.source.pos);
        !self.needed(beam, far, k0) || self.inner.is_some_and(|i| i.frustum_empty(beam, source, far, k0))
    }

    /// What the cells hold: the oracle's tables are the host's.
    fn bytes(&self) -> usize {
        self.inner.map_or(0, |i| i.bytes())
    }
}
