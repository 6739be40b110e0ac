//! Proxel-parallel shots (radiosity thesis §6.2): the grid computes a shot's form factors by
//! projection — the shooter's hemicube or projection disk distributed over the cells — instead
//! of by beam diffusion. What each cell runs is [`cell_core::proxel`]; this module schedules it
//! and costs every phase in grid cycles (one proxel test, or one 32-bit word on a link, per
//! cycle).
//!
//! The data (§6.2.2–6.2.3): each plane of the surface (the hemicube's five faces, the disk's
//! bounding square) is cut into zones of n × n proxels and cell (x, y) holds proxel (x, y) of
//! every zone (the cyclic distribution), with its direction and its delta form factor in quanta;
//! patch `p` lives on cell `p mod n²` (the modulo distribution, in modelling order) with its
//! triangles.
//!
//! One shot, in phases (docs/RADIOSITY.md, "Shots by projection"):
//! 1. **select** — the patch with the most unshot power, by a max-reduction over the cells
//!    (rows westward, then column 0 northward: 2(n − 1) cycles, n² − 1 messages), and the
//!    shooter's frame (position and normal, 12 words) flooded from its owner;
//! 2. **projection** — each owner culls its triangles whose projection misses the surface
//!    (one test per triangle it owns), then triangle after triangle in modelling order the
//!    projection parameters ([`ProxelCone`], patch id, the bounding rectangles) go from the owner
//!    to cell (0, 0) and are flooded over the grid (the broadcast the grid has: its 8 links;
//!    one word per link per cycle, pipelined); every cell z-tests its proxel in each zone the
//!    rectangles cover (§6.2.4): `words + zones` cycles per triangle, SIMD as on the MasPar;
//! 3. **update** (§6.2.6) — each kept proxel's quanta reach the cell of its patch. The thesis's
//!    alternatives are all costed from the same depth buffer ([`UpdateCosts`]); `--update`
//!    chooses the one the shot's cycles count;
//! 4. the owners add `ρ_j U_i F_ij A_i / A_j` to their patches (⌈P/n²⌉ updates per cell; the
//!    arithmetic is the supervisor's of [`super::shots`], shared, so the two methods differ in
//!    their form factors only).
//!
//! **Invariants (tested):** the depth buffer gathered from the cells is the host projective
//! method's ([`crate::truth::projective::depth_buffer`]) proxel for proxel; per shot, quanta
//! received by front-facing patches + quanta kept by triangles seen from behind + quanta of
//! proxels that saw nothing = the surface's quanta, exactly.

use anyhow::{bail, Result};
use cell_core::proxel::{FacetShare, ProxelCone, ProxelStore};
use cell_core::radiosity::{PatchId, FORM_FACTOR_ONE};
use parry3d_f64::math::Vector;

use crate::machine::grid::capacity::{FACET_SHARE_CAP, PROXEL_CAP};
use crate::scene::patches::Patch;
use crate::truth::projective::{disk::Disk, frame, hemicube::Hemicube, Planar, PlaneRect};

use super::reduce::reduce_entries;

/// The projection surface the cells share.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum SurfaceKind {
    /// Cohen's hemicube (§2.3.1), R × R on top, R × R/2 on each side.
    Hemicube,
    /// The projection disk (§2.4.2), R × R bounding square.
    Disk,
}

/// How the kept proxels' quanta reach their patches' cells (§6.2.6).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Update {
    /// Moving proxels over the 8 links, east then south, zone after zone (every cell sends its
    /// proxel of the same zone): per round n horizontal cycles and n per proxel piled on the
    /// busiest cell (Eq. 6.1).
    XnetProxels,
    /// The same, each cell starting at a different zone: cell (x, y) sends its proxel of zone
    /// `(x + y·n + z) mod Z` in round z (the thesis's "modulo" strategy).
    XnetModulo,
    /// Moving facets (Eq. 6.2): each cell's patches visit every cell, which adds the proxels
    /// of the zones their bounding rectangles cover; n² steps per pass, ⌈P/n²⌉ passes.
    XnetFacets,
    /// Moving proxels through a global router of 16-cell groups (the MasPar's): per round
    /// each group sends and receives one message per cycle; rounds zone after zone.
    RouterProxels,
    /// The router with the "modulo" zone choice.
    RouterModulo,
    /// rc2's own: each cell sums its proxels per patch, and the sums are merged along the rows
    /// and column 0 to cell (0, 0) as a beam shot's are ([`super::reduce`]).
    #[default]
    Reduce,
}

impl Update {
    /// Every strategy, in the CSV's column order.
    pub const ALL: [Update; 6] = [
        Update::XnetProxels,
        Update::XnetModulo,
        Update::XnetFacets,
        Update::RouterProxels,
        Update::RouterModulo,
        Update::Reduce,
    ];

    /// Its place in [`Update::ALL`] (and in [`UpdateCosts`]).
    pub fn index(self) -> usize {
        Update::ALL.iter().position(|&u| u == self).expect("every strategy is in ALL")
    }

    /// Its name (`--update`, the CSV's columns `update_<name>` with `-` as `_`).
    pub fn name(self) -> &'static str {
        match self {
            Update::XnetProxels => "xnet-proxels",
            Update::XnetModulo => "xnet-modulo",
            Update::XnetFacets => "xnet-facets",
            Update::RouterProxels => "router-proxels",
            Update::RouterModulo => "router-modulo",
            Update::Reduce => "reduce",
        }
    }
}

/// Settings of proxel-parallel shots.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
pub struct ProxelConfig {
    /// The surface.
    pub surface: SurfaceKind,
    /// Its resolution R.
    pub resolution: u32,
    /// The update the shot's cycles count.
    pub update: Update,
    /// Project by the hybrid method of §6.4 (spans per triangle on their owners, z-buffered
    /// along the rows) instead of broadcasting each triangle (hemicube only).
    pub hybrid: bool,
}

impl ProxelConfig {
    /// The default resolution on an n × n grid: R = 2n (the hemicube then gives each cell 12
    /// proxels, the disk about 3).
    pub fn default_resolution(n: u32) -> u32 {
        2 * n
    }
}

/// Words on a link for the shooter's frame (position and normal, six `f64`).
const FRAME_WORDS: u64 = 12;

/// Cells per global-router group (the MasPar's clusters of 4 × 4 PEs).
const GROUP_SIDE: u32 = 4;

/// One round of point-to-point messages, each cell sending at most one, costed both ways the
/// thesis compares (§6.2.6): over the 8 links, east-west on the sender's row to the
/// destination's column then north-south, n cycles and n more per message piled on the busiest
/// cell of that column walk (Eq. 6.1); and through a global router of 4 × 4-cell groups, one
/// message per cycle in and out of each group (the busiest group's count).
struct Round {
    n: u64,
    groups_side: u64,
    /// Per cell, the messages that turn north-south there.
    turns: Vec<u32>,
    /// Per group, messages sent (even slots) and received (odd slots).
    router: Vec<u32>,
    /// Link hops of the round.
    hops: u64,
    /// Messages of the round.
    messages: u64,
}

impl Round {
    fn new(n: u32) -> Round {
        let groups_side = n.div_ceil(GROUP_SIDE) as u64;
        let n = n as u64;
        Round {
            n,
            groups_side,
            turns: vec![0; (n * n) as usize],
            router: vec![0; 2 * (groups_side * groups_side) as usize],
            hops: 0,
            messages: 0,
        }
    }

    /// Start the next round.
    fn clear(&mut self) {
        self.turns.iter_mut().for_each(|c| *c = 0);
        self.router.iter_mut().for_each(|c| *c = 0);
        (self.hops, self.messages) = (0, 0);
    }

    /// Cell `from` sends one message to cell `to` (row-major indices).
    fn send(&mut self, from: u64, to: u64) {
        let n = self.n;
        let (x, y, dx, dy) = (from % n, from / n, to % n, to / n);
        let group = |x: u64, y: u64| ((y / GROUP_SIDE as u64) * self.groups_side + x / GROUP_SIDE as u64) as usize;
        self.router[2 * group(x, y)] += 1;
        self.router[2 * group(dx, dy) + 1] += 1;
        self.turns[(y * n + dx) as usize] += 1;
        self.hops += x.abs_diff(dx) + y.abs_diff(dy);
        self.messages += 1;
    }

    /// The round over the 8 links (zero for a round without messages).
    fn xnet(&self) -> UpdateCost {
        let peak = *self.turns.iter().max().unwrap_or(&0) as u64;
        let cycles = if self.messages > 0 { self.n + self.n * peak } else { 0 };
        UpdateCost { cycles, messages: self.hops }
    }

    /// The round through the router.
    fn routed(&self) -> UpdateCost {
        UpdateCost { cycles: *self.router.iter().max().unwrap_or(&0) as u64, messages: self.messages }
    }
}

impl std::ops::AddAssign for UpdateCost {
    fn add_assign(&mut self, o: UpdateCost) {
        self.cycles += o.cycles;
        self.messages += o.messages;
    }
}

/// The cost of an update strategy on one shot.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct UpdateCost {
    /// Cycles.
    pub cycles: u64,
    /// Messages (link hops for the 8-link strategies, routed messages for the router).
    pub messages: u64,
}

/// Every strategy's cost on one shot, in [`Update::ALL`]'s order.
pub type UpdateCosts = [UpdateCost; 6];

/// The cost of a proxel shot's phases.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct ProxelCost {
    /// Select and shooter broadcast: cycles.
    pub select_cycles: u64,
    /// Messages of select and shooter broadcast.
    pub select_messages: u64,
    /// Projection: cull, parameter broadcasts and z-tests, cycles.
    pub projection_cycles: u64,
    /// Messages of the parameter broadcasts (one per triangle per cell reached, and the hops
    /// to cell (0, 0)).
    pub projection_messages: u64,
    /// Triangles broadcast (those whose projection reaches the surface).
    pub triangles: u64,
    /// Zone tests: for each broadcast triangle, the zones its rectangles cover, times n² —
    /// what the SIMD cells evaluate.
    pub zone_tests: u64,
    /// Proxels inside a rectangle (a MIMD cell's tests).
    pub rect_tests: u64,
    /// Proxel tests that found the triangle (inside its cone and in front).
    pub hits: u64,
    /// The chosen update's cycles (and the others' in `updates`).
    pub update: Update,
    /// Every update strategy's cost.
    pub updates: UpdateCosts,
    /// The patches' radiosity updates in their cells: ⌈P/n²⌉ cycles.
    pub apply_cycles: u64,
    /// The hybrid projection's phases (§6.4; zero for the broadcast projection).
    pub hybrid: HybridCost,
}

/// The phases of a hybrid projection (§6.4).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct HybridCost {
    /// Span pieces (a span cut at zone edges: each piece lies on consecutive cells of a row).
    pub spans: u64,
    /// Proxels the pieces cover (the z-tests made).
    pub span_proxels: u64,
    /// Generation on the triangles' owners: the busiest cell's rows (one per row, one per
    /// triangle set up).
    pub generate_cycles: u64,
    /// Distribution of the pieces to their first cells over the links (rounds of one piece per
    /// cell: n east-west cycles and n per piece piled on the busiest cell), counted.
    pub distribute_cycles: u64,
    /// The same distribution through a global router of 4 × 4-cell groups (not counted).
    pub distribute_router_cycles: u64,
    /// Propagation along the rows (a piece moves one cell east per cycle, z-testing there;
    /// a cell whose incoming slot is free starts one of its own): the slowest row's cycles.
    pub propagate_cycles: u64,
}

impl ProxelCost {
    /// The chosen update's cost.
    fn chosen(&self) -> UpdateCost {
        self.updates[self.update.index()]
    }

    /// Cycles of the shot under its chosen update.
    pub fn cycles(&self) -> u64 {
        self.select_cycles + self.projection_cycles + self.chosen().cycles + self.apply_cycles
    }

    /// Messages of the shot under its chosen update.
    pub fn messages(&self) -> u64 {
        self.select_messages + self.projection_messages + self.chosen().messages
    }
}

/// What one proxel shot delivered: per patch (id, quanta) after the update, and the shot's
/// quanta accounted for (`received + hidden + left = emitted`, exactly).
#[derive(Clone, Debug, PartialEq)]
pub struct ProxelShot {
    /// (patch, quanta) of the front-facing patches, by patch id.
    pub totals: Vec<(PatchId, i64)>,
    /// Quanta of the whole surface.
    pub emitted: i64,
    /// Quanta the front-facing patches received.
    pub received: i64,
    /// Quanta of proxels whose nearest triangle is seen from behind.
    pub hidden: i64,
    /// Quanta of proxels that saw nothing.
    pub left: i64,
    /// The phases' costs.
    pub cost: ProxelCost,
}

impl ProxelShot {
    /// What the patches' cells hold + hidden + left = emitted, exactly (nothing lost between
    /// the proxels and the patch shares).
    pub fn balanced(&self) -> bool {
        self.totals.iter().map(|e| e.1).sum::<i64>() + self.hidden + self.left == self.emitted
    }
}

/// The cells' proxel stores.
pub type CellProxels = ProxelStore<PROXEL_CAP>;
/// The cells' patch shares.
pub type CellFacets = FacetShare<FACET_SHARE_CAP>;

/// The grid loaded for proxel shots: the surface distributed over the cells, the patches'
/// triangles, their owners.
pub struct ProxelGrid {
    /// Grid side.
    pub n: u32,
    cfg: ProxelConfig,
    surface: Box<dyn Planar>,
    /// Per cell, row-major.
    cells: Vec<CellProxels>,
    /// Per cell, its patches.
    shares: Vec<CellFacets>,
    /// Per sample: (cell, slot), `None` for a proxel that does not exist (outside the disk).
    place: Vec<Option<(u32, u32)>>,
    /// Per zone (all planes, in order): its plane and zone coordinates.
    zones: Vec<(usize, u32, u32)>,
    /// Quanta of the whole surface.
    total_quanta: u64,
    triangles: Vec<[Vector; 3]>,
    /// Per triangle, its patch.
    owner: Vec<u32>,
    /// The most triangles one cell owns.
    triangles_per_cell: u64,
    /// With the hybrid projection: the hemicube that cuts triangles into spans.
    spanner: Option<Hemicube>,
}

/// Groups of the global router on an n × n grid (4 × 4 cells each, the last row and column
/// of groups partial when n is not a multiple of 4).
pub const fn router_groups(n: u32) -> u32 {
    n.div_ceil(GROUP_SIDE).pow(2)
}

/// Bytes one cell holds for proxel shots (its proxel store and patch share).
pub const fn bytes_per_cell() -> usize {
    std::mem::size_of::<CellProxels>() + std::mem::size_of::<CellFacets>()
}

/// Integer delta form factors: each `delta · 2^30` rounded down, the remainder handed out one
/// quantum at a time to the largest fractions, so that they sum to 2^30 (when the deltas sum to
/// 1) and each is within one quantum of its delta.
fn quantize(deltas: &[f64]) -> Vec<u32> {
    let one = FORM_FACTOR_ONE as f64;
    let sum: f64 = deltas.iter().sum();
    let target = (sum * one).round() as u64;
    let mut q: Vec<u32> = deltas.iter().map(|d| (d * one).floor() as u32).collect();
    let have: u64 = q.iter().map(|&v| v as u64).sum();
    let mut order: Vec<usize> = (0..deltas.len()).collect();
    order.sort_by(|&a, &b| {
        let fa = deltas[a] * one - q[a] as f64;
        let fb = deltas[b] * one - q[b] as f64;
        fb.total_cmp(&fa).then(a.cmp(&b))
    });
    for &k in order.iter().take(target.saturating_sub(have) as usize) {
        q[k] += 1;
    }
    q
}

impl ProxelGrid {
    /// Distribute the surface and the patches over an n × n grid. Fails when a cell's proxels
    /// or patches do not fit its store (counted, then reported).
    pub fn new(n: u32, patches: &[Patch], cfg: ProxelConfig) -> Result<ProxelGrid> {
        let surface: Box<dyn Planar> = match cfg.surface {
            SurfaceKind::Hemicube => Box::new(Hemicube::new(cfg.resolution)?),
            SurfaceKind::Disk => Box::new(Disk::new(cfg.resolution)?),
        };
        if n == 0 {
            bail!("proxel shots: the grid side must be at least 1");
        }
        let spanner = match (cfg.hybrid, cfg.surface) {
            (false, _) => None,
            (true, SurfaceKind::Hemicube) => Some(Hemicube::new(cfg.resolution)?),
            (true, SurfaceKind::Disk) => bail!("the hybrid projection (§6.4) runs on the hemicube, not the disk"),
        };
        let cells_n = (n as usize).pow(2);
        let deltas: Vec<f64> = (0..surface.samples()).map(|k| surface.delta(k)).collect();
        let quanta = quantize(&deltas);
        let mut cells: Vec<CellProxels> = (0..cells_n).map(|_| CellProxels::new()).collect();
        let mut place = vec![None; surface.samples()];
        let mut zones = Vec::new();
        for (plane, &(w, h)) in surface.planes().iter().enumerate() {
            let (zw, zh) = (w.div_ceil(n), h.div_ceil(n));
            for zy in 0..zh {
                for zx in 0..zw {
                    zones.push((plane, zx, zy));
                    for y in 0..n {
                        for x in 0..n {
                            let Some(k) = surface.sample_at(plane, zx * n + x, zy * n + y) else { continue };
                            let c = (y * n + x) as usize;
                            let slot = cells[c].len() as u32;
                            if cells[c].push(surface.direction(k), quanta[k]) {
                                place[k] = Some((c as u32, slot));
                            }
                        }
                    }
                }
            }
        }
        let overflows: u64 = cells.iter().map(|c| c.overflows() as u64).sum();
        if overflows > 0 {
            bail!(
                "proxel shots: {} proxels of the {} at R = {} do not fit the cells' stores ({} proxels per cell \
                 compiled, {} needed): lower --resolution or raise --n",
                overflows,
                surface.name(),
                cfg.resolution,
                PROXEL_CAP,
                (surface.samples() as u64).div_ceil(cells_n as u64)
            );
        }
        let total_quanta = place.iter().zip(&quanta).filter(|(p, _)| p.is_some()).map(|(_, &q)| q as u64).sum();
        let shares: Vec<CellFacets> =
            (0..cells_n).map(|c| CellFacets::new(c as u32, cells_n as u32, patches.len() as u32)).collect();
        let lost: u64 = shares.iter().map(|s| s.overflows() as u64).sum();
        if lost > 0 {
            bail!(
                "proxel shots: {} patches do not fit the cells' patch shares ({} per cell compiled, {} patches on \
                 {} cells): raise --patch-size or --n",
                lost,
                FACET_SHARE_CAP,
                patches.len(),
                cells_n
            );
        }
        let (mut triangles, mut owner) = (Vec::new(), Vec::new());
        for (k, p) in patches.iter().enumerate() {
            triangles.extend(p.triangles.iter().copied());
            owner.extend(std::iter::repeat_n(k as u32, p.triangles.len()));
        }
        let mut per_cell = vec![0u64; cells_n];
        for &p in &owner {
            per_cell[p as usize % cells_n] += 1;
        }
        let triangles_per_cell = per_cell.into_iter().max().unwrap_or(0);
        Ok(ProxelGrid {
            n,
            cfg,
            surface,
            cells,
            shares,
            place,
            zones,
            total_quanta,
            triangles,
            owner,
            triangles_per_cell,
            spanner,
        })
    }

    /// The surface's quanta (what a shot emits).
    pub fn total_quanta(&self) -> u64 {
        self.total_quanta
    }

    /// Zones a rectangle covers.
    fn zones_covered(&self, r: &PlaneRect) -> u64 {
        let n = self.n;
        ((r.i1 / n - r.i0 / n + 1) * (r.j1 / n - r.j0 / n + 1)) as u64
    }

    /// The depth buffer as the cells hold it: per sample, the triangle kept (or
    /// [`crate::truth::projective::NONE`]).
    pub fn depth_buffer(&self) -> Vec<u32> {
        self.place
            .iter()
            .map(|p| {
                p.and_then(|(c, s)| self.cells[c as usize].kept(s as usize))
                    .map_or(crate::truth::projective::NONE, |(t, _)| t)
            })
            .collect()
    }

    /// Phase 2: every triangle's projection z-tested by the cells (the shooter at `x` with unit
    /// normal `normal`). Returns per triangle its zones covered (0: culled), and fills `cost`.
    fn project(&mut self, x: Vector, normal: Vector, cost: &mut ProxelCost) -> Vec<u64> {
        let n = self.n as u64;
        let (t, b, nn) = frame(normal);
        self.cells.iter_mut().for_each(|c| c.clear());
        let mut zones = vec![0u64; self.triangles.len()];
        let cells = n * n;
        // Culling: one test per triangle its owner holds.
        cost.projection_cycles += self.triangles_per_cell;
        for (f, tri) in self.triangles.iter().enumerate() {
            let local = tri.map(|p| {
                let d = p - x;
                [d.dot(t), d.dot(b), d.dot(nn)]
            });
            let Some(cone) = ProxelCone::new(local) else { continue };
            let rects = self.surface.rects(&local);
            if rects.is_empty() {
                continue;
            }
            let words = ProxelCone::WORDS as u64 + 2 + 2 * rects.len() as u64;
            let z: u64 = rects.iter().map(|r| self.zones_covered(r)).sum();
            zones[f] = z;
            cost.triangles += 1;
            cost.zone_tests += z * cells;
            cost.projection_cycles += words + z;
            let owner_cell = self.owner[f] as u64 % cells;
            cost.projection_messages += cells - 1 + owner_cell % n + owner_cell / n;
            for r in &rects {
                for i in r.i0..=r.i1 {
                    for j in r.j0..=r.j1 {
                        let Some(k) = self.surface.sample_at(r.plane, i, j) else { continue };
                        let Some((c, s)) = self.place[k] else { continue };
                        cost.rect_tests += 1;
                        if self.cells[c as usize].z_test(s as usize, f as u32, &cone) {
                            cost.hits += 1;
                        }
                    }
                }
            }
        }
        // Pipeline fill: the first parameters' way to (0, 0) and its flood.
        cost.projection_cycles += 2 * (n - 1);
        zones
    }

    /// Phase 2 by the hybrid method (§6.4): each owner cuts its triangles into spans (one per
    /// proxel row of each face), cut again at zone edges into pieces; each piece goes to the cell
    /// holding its first proxel, then moves east along its row, z-tested by every cell it
    /// passes. Returns per triangle its zones covered (for the moving-facets update), and fills
    /// `cost`.
    fn project_hybrid(&mut self, x: Vector, normal: Vector, cost: &mut ProxelCost) -> Vec<u64> {
        let n = self.n;
        let cells = (n as usize).pow(2);
        let (t, b, nn) = frame(normal);
        self.cells.iter_mut().for_each(|c| c.clear());
        let spanner = self.spanner.as_ref().expect("a hybrid grid has its spanner");
        let mut zones = vec![0u64; self.triangles.len()];
        let mut cones = vec![None; self.triangles.len()];
        let mut generate = vec![0u64; cells];
        // Per owner cell, its pieces: (triangle, plane, row, first column, length).
        let mut pieces: Vec<Vec<Piece>> = vec![Vec::new(); cells];
        for (f, tri) in self.triangles.iter().enumerate() {
            let local = tri.map(|p| {
                let d = p - x;
                [d.dot(t), d.dot(b), d.dot(nn)]
            });
            let Some(cone) = ProxelCone::new(local) else { continue };
            let spans = spanner.spans(&local);
            if spans.is_empty() {
                continue;
            }
            cones[f] = Some(cone);
            zones[f] = self.surface.rects(&local).iter().map(|r| self.zones_covered(r)).sum();
            cost.triangles += 1;
            let owner = self.owner[f] as usize % cells;
            generate[owner] += 1 + spans.len() as u64;
            for sp in spans {
                let mut i = sp.i0;
                while i <= sp.i1 {
                    let end = sp.i1.min((i / n + 1) * n - 1);
                    pieces[owner].push((f as u32, sp.plane, sp.j, i, end - i + 1));
                    i = end + 1;
                }
            }
        }
        let h = &mut cost.hybrid;
        h.generate_cycles = generate.iter().copied().max().unwrap_or(0);
        // Distribution: round r, every cell sends its r-th piece.
        let rounds = pieces.iter().map(Vec::len).max().unwrap_or(0);
        let mut round = Round::new(n);
        // Per grid row, per cell, the pieces that start there.
        let mut starts: Vec<Vec<std::collections::VecDeque<Piece>>> =
            vec![vec![std::collections::VecDeque::new(); n as usize]; n as usize];
        for r in 0..rounds {
            round.clear();
            for (c, list) in pieces.iter().enumerate() {
                let Some(&piece) = list.get(r) else { continue };
                let (dx, dy) = (piece.3 % n, piece.2 % n);
                round.send(c as u64, (dy * n + dx) as u64);
                starts[dy as usize][dx as usize].push_back(piece);
                h.spans += 1;
                h.span_proxels += piece.4 as u64;
            }
            let (xnet, routed) = (round.xnet(), round.routed());
            cost.projection_messages += xnet.messages;
            h.distribute_cycles += xnet.cycles;
            h.distribute_router_cycles += routed.cycles;
        }
        // Propagation, row by row of cells: a belt of one piece per cell.
        for row in starts.iter_mut() {
            let mut slot: Vec<Option<(Piece, u32)>> = vec![None; n as usize];
            let mut cycles = 0u64;
            loop {
                for (x, s) in slot.iter_mut().enumerate() {
                    if s.is_none() {
                        *s = row[x].pop_front().map(|p| (p, 0));
                    }
                }
                if slot.iter().all(Option::is_none) {
                    break;
                }
                cycles += 1;
                let mut next = vec![None; n as usize];
                for (x, s) in slot.iter().enumerate() {
                    let Some(((f, plane, j, i0, len), off)) = *s else { continue };
                    let k = self.surface.sample_at(plane, i0 + off, j);
                    if let Some((c, sl)) = k.and_then(|k| self.place[k]) {
                        cost.rect_tests += 1;
                        let cone = cones[f as usize].as_ref().expect("a piece's triangle has its cone");
                        if self.cells[c as usize].z_test(sl as usize, f, cone) {
                            cost.hits += 1;
                        }
                    }
                    if off + 1 < len {
                        next[x + 1] = Some(((f, plane, j, i0, len), off + 1));
                        cost.projection_messages += 1;
                    }
                }
                slot = next;
            }
            h.propagate_cycles = h.propagate_cycles.max(cycles);
        }
        cost.zone_tests = h.span_proxels;
        cost.projection_cycles = h.generate_cycles + h.distribute_cycles + h.propagate_cycles;
        zones
    }

    /// One proxel shot of patch `i`.
    pub fn shoot(&mut self, patches: &[Patch], i: usize) -> Result<ProxelShot> {
        let n = self.n as u64;
        let cells = n * n;
        let mut cost = ProxelCost { update: self.cfg.update, ..Default::default() };
        // Phase 1: select by a max-reduction, then the shooter's frame flooded by its owner.
        let owner = i as u64 % cells;
        let eccentricity = (owner % n).max(n - 1 - owner % n).max((owner / n).max(n - 1 - owner / n));
        cost.select_cycles = 2 * (n - 1) + eccentricity + FRAME_WORDS;
        cost.select_messages = 2 * (cells - 1);
        let p = &patches[i];
        let tri_zones = if self.spanner.is_some() {
            self.project_hybrid(p.centroid, p.normal, &mut cost)
        } else {
            self.project(p.centroid, p.normal, &mut cost)
        };
        // Phase 3: what each proxel kept goes to its patch's cell.
        let sends = self.sends(patches, p.centroid);
        self.shares.iter_mut().for_each(|s| s.clear());
        let (mut received, mut hidden) = (0u64, 0u64);
        for send in sends.iter().flatten().flatten() {
            match send {
                Send::To { patch, quanta } => {
                    let ok = self.shares[(*patch as u64 % cells) as usize].add(*patch, *quanta);
                    debug_assert!(ok, "a patch is on the cell its id names");
                    received += *quanta as u64;
                }
                Send::Hidden { quanta } => hidden += *quanta as u64,
            }
        }
        cost.updates = self.update_costs(&sends, &tri_zones, patches.len());
        cost.apply_cycles = (patches.len() as u64).div_ceil(cells);
        let totals: Vec<(PatchId, i64)> = self
            .shares
            .iter()
            .flat_map(|s| s.entries())
            .filter(|e| e.1 > 0)
            .map(|(f, q)| (f as PatchId, q as i64))
            .collect::<std::collections::BTreeMap<_, _>>()
            .into_iter()
            .collect();
        let emitted = self.total_quanta as i64;
        let left = emitted - received as i64 - hidden as i64;
        if left < 0 {
            bail!("proxel shot of patch {i}: received {received} + hidden {hidden} exceed the surface's {emitted}");
        }
        let shot = ProxelShot { totals, emitted, received: received as i64, hidden: hidden as i64, left, cost };
        if !shot.balanced() {
            bail!("proxel shot of patch {i}: the patches' cells hold less than the {received} quanta sent to them");
        }
        Ok(shot)
    }

    /// Per cell, per zone (in zone order), what its proxel sends: to a front-facing patch, or
    /// hidden by a triangle seen from behind (no message); `None` when it saw nothing or does
    /// not exist.
    fn sends(&self, patches: &[Patch], x: Vector) -> Vec<Vec<Option<Send>>> {
        let n = self.n;
        let mut out = vec![vec![None; self.zones.len()]; (n * n) as usize];
        for (z, &(plane, zx, zy)) in self.zones.iter().enumerate() {
            for y in 0..n {
                for xx in 0..n {
                    let Some(k) = self.surface.sample_at(plane, zx * n + xx, zy * n + y) else { continue };
                    let Some((c, s)) = self.place[k] else { continue };
                    let Some((t, q)) = self.cells[c as usize].kept(s as usize) else { continue };
                    let patch = self.owner[t as usize];
                    // A triangle seen from behind hides what is beyond it but receives nothing
                    // (as the host's projective rows).
                    let front = (x - self.triangles[t as usize][0]).dot(patches[patch as usize].normal) > 0.0;
                    out[c as usize][z] =
                        Some(if front { Send::To { patch, quanta: q } } else { Send::Hidden { quanta: q } });
                }
            }
        }
        out
    }

    /// Every update strategy's cost, from what each cell sends per zone.
    fn update_costs(&self, sends: &[Vec<Option<Send>>], tri_zones: &[u64], patches: usize) -> UpdateCosts {
        let n = self.n as u64;
        let cells = n * n;
        let nz = self.zones.len() as u64;
        let dest = |s: &Send| match s {
            Send::To { patch, .. } => Some(*patch as u64 % cells),
            Send::Hidden { .. } => None,
        };
        let mut out = UpdateCosts::default();
        // Moving proxels, by rounds: which zone cell c sends in round z.
        let mut round = Round::new(self.n);
        for (modulo, xnet, routed) in
            [(false, Update::XnetProxels, Update::RouterProxels), (true, Update::XnetModulo, Update::RouterModulo)]
        {
            for z in 0..nz {
                round.clear();
                for c in 0..cells {
                    let zone = if modulo { (c + z) % nz } else { z };
                    if let Some(d) = sends[c as usize][zone as usize].as_ref().and_then(dest) {
                        round.send(c, d);
                    }
                }
                out[xnet.index()] += round.xnet();
                out[routed.index()] += round.routed();
            }
        }
        // Moving facets: passes of one patch per cell, each visiting the n² cells; a step
        // costs one hop and the busiest visitor's zone tests.
        let mut patch_zones = vec![0u64; patches];
        for (t, &z) in tri_zones.iter().enumerate() {
            patch_zones[self.owner[t] as usize] += z;
        }
        let mut facets = UpdateCost::default();
        for pass in patch_zones.chunks(cells as usize) {
            let busiest = pass.iter().copied().max().unwrap_or(0);
            facets.cycles += cells * (1 + busiest);
            facets.messages += pass.len() as u64 * cells;
        }
        out[Update::XnetFacets.index()] = facets;
        // rc2's reduction: per cell its sums per patch, merged to (0, 0).
        let entries: Vec<Vec<(PatchId, i64)>> = sends
            .iter()
            .map(|cell| {
                let mut m = std::collections::BTreeMap::<PatchId, i64>::new();
                for s in cell.iter().flatten() {
                    if let Send::To { patch, quanta } = s {
                        *m.entry(*patch as PatchId).or_insert(0) += *quanta as i64;
                    }
                }
                m.into_iter().collect()
            })
            .collect();
        let (_, cycles, messages) = reduce_entries(self.n, &entries);
        out[Update::Reduce.index()] = UpdateCost { cycles, messages };
        out
    }
}

/// A span piece of the hybrid projection: (triangle, plane, row, first column, length).
type Piece = (u32, usize, u32, u32, u32);

/// What one proxel sends in the update.
#[derive(Clone, Copy, Debug)]
enum Send {
    /// Its quanta to a patch.
    To { patch: u32, quanta: u32 },
    /// Kept by a triangle seen from behind: absorbed, no message.
    Hidden { quanta: u32 },
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::truth::projective::{depth_buffer, local_cones, ProjectionSurface, NONE};

    fn cornell(size: f64) -> Vec<Patch> {
        let mesh = crate::scene::load("cornell").unwrap();
        crate::scene::patches::subdivide(&mesh, size, 5000).unwrap().patches
    }

    fn cfg(surface: SurfaceKind, resolution: u32) -> ProxelConfig {
        ProxelConfig { surface, resolution, update: Update::Reduce, hybrid: false }
    }

    /// The host's sequential projective method on the same triangles: its depth buffer (every
    /// proxel against every triangle, no rectangles) and its form factors per patch (a
    /// triangle seen from behind receives nothing).
    fn host(surface: &dyn ProjectionSurface, patches: &[Patch], i: usize) -> (Vec<u32>, Vec<f64>) {
        let tris: Vec<[Vector; 3]> = patches.iter().flat_map(|p| p.triangles.iter().copied()).collect();
        let owner: Vec<usize> =
            patches.iter().enumerate().flat_map(|(k, p)| std::iter::repeat_n(k, p.triangles.len())).collect();
        let (x, n) = (patches[i].centroid, patches[i].normal);
        // The disk's square has no proxel outside the disk (their deltas are 0; the full scan
        // still tests their horizon directions).
        let ids: Vec<u32> = depth_buffer(surface, &local_cones(x, n, &tris))
            .into_iter()
            .enumerate()
            .map(|(k, t)| if surface.delta(k) > 0.0 { t } else { NONE })
            .collect();
        let mut ff = vec![0.0; patches.len()];
        for (k, &t) in ids.iter().enumerate() {
            if t != NONE && (x - tris[t as usize][0]).dot(patches[owner[t as usize]].normal) > 0.0 {
                ff[owner[t as usize]] += surface.delta(k);
            }
        }
        (ids, ff)
    }

    /// The cells' depth buffer is the host's full scan, proxel for proxel, whatever the grid
    /// side against the resolution (zones cut by the plane's edge, a disk's missing corners),
    /// and each patch's form factor is the host's to the quantization (half a quantum per
    /// proxel at most). Per shot, received + hidden + nothing = the surface's quanta exactly,
    /// each of the three counted independently from the host's depth buffer.
    #[test]
    fn the_cells_depth_buffer_is_the_host_projective_methods() {
        let patches = cornell(150.0);
        for (surface, r, n, hybrid) in [
            (SurfaceKind::Hemicube, 16, 4, false),
            (SurfaceKind::Hemicube, 22, 5, false),
            (SurfaceKind::Disk, 21, 4, false),
            (SurfaceKind::Disk, 32, 7, false),
            (SurfaceKind::Hemicube, 8, 16, false),
            (SurfaceKind::Hemicube, 16, 4, true),
            (SurfaceKind::Hemicube, 30, 7, true),
            (SurfaceKind::Hemicube, 64, 8, true),
        ] {
            let mut grid = ProxelGrid::new(n, &patches, ProxelConfig { hybrid, ..cfg(surface, r) }).unwrap();
            let reference: Box<dyn ProjectionSurface> = match surface {
                SurfaceKind::Hemicube => Box::new(Hemicube::new(r).unwrap()),
                SurfaceKind::Disk => Box::new(Disk::new(r).unwrap()),
            };
            for i in (0..patches.len()).step_by(7) {
                let shot = grid.shoot(&patches, i).unwrap();
                let (ids, ff) = host(reference.as_ref(), &patches, i);
                assert_eq!(grid.depth_buffer(), ids, "{surface:?} R = {r}, n = {n}, hybrid {hybrid}, shooter {i}");
                assert!(ids.iter().any(|&t| t != NONE), "shooter {i} sees something");
                let one = FORM_FACTOR_ONE as f64;
                let mut got = vec![0i64; patches.len()];
                for &(j, q) in &shot.totals {
                    got[j as usize] += q;
                }
                for (j, (&g, &f)) in got.iter().zip(&ff).enumerate() {
                    let proxels = ids.iter().filter(|&&t| t != NONE).count() as f64;
                    assert!(
                        (g as f64 / one - f).abs() <= (proxels / 2.0 + 1.0) / one + 1e-12,
                        "patch {j}: cells {} host {f}",
                        g as f64 / one
                    );
                }
                let l = &shot;
                assert!(l.balanced(), "{l:?}");
                assert_eq!(l.emitted as u64, grid.total_quanta());
                let nothing = (0..ids.len()).filter(|&k| ids[k] == NONE && reference.delta(k) > 0.0).count();
                assert_eq!(l.left == 0, nothing == 0, "left {} with {nothing} empty proxels", l.left);
            }
            // The surface's quanta: 2^30 for a hemicube (its deltas sum to 1), the disk's the
            // same (its used proxels share 1 equally).
            assert!(grid.total_quanta().abs_diff(FORM_FACTOR_ONE as u64) <= 1, "{}", grid.total_quanta());
        }
    }

    #[test]
    fn quantized_deltas_sum_exactly_and_stay_within_a_quantum() {
        let deltas: Vec<f64> = (1..=97).map(|k| k as f64).collect();
        let s: f64 = deltas.iter().sum();
        let deltas: Vec<f64> = deltas.iter().map(|d| d / s).collect();
        let q = quantize(&deltas);
        assert_eq!(q.iter().map(|&v| v as u64).sum::<u64>(), FORM_FACTOR_ONE as u64);
        for (d, &v) in deltas.iter().zip(&q) {
            assert!((d * FORM_FACTOR_ONE as f64 - v as f64).abs() < 1.0);
        }
    }

    /// The update strategies against hand counts on a 2 × 2 grid.
    #[test]
    fn update_costs_follow_the_thesis_models() {
        let patches = cornell(150.0);
        let mut grid = ProxelGrid::new(2, &patches, cfg(SurfaceKind::Hemicube, 4)).unwrap();
        let i = 0;
        let shot = grid.shoot(&patches, i).unwrap();
        let cost = &shot.cost;
        let sends = grid.sends(&patches, patches[i].centroid);
        let zones = grid.zones.len();
        // Eq. 6.1's bounds per round with a message: 2n ≤ cycles ≤ n + n².
        let rounds =
            (0..zones).filter(|&z| (0..4).any(|c| matches!(sends[c][z], Some(Send::To { .. })))).count() as u64;
        let x = cost.updates[Update::XnetProxels.index()].cycles;
        assert!(x >= rounds * 4 && x <= rounds * (2 + 4), "xnet {x}, {rounds} rounds");
        // One group of 16 holds the whole 2 × 2 grid: a round costs its messages.
        let messages: u64 = sends.iter().flatten().filter(|s| matches!(s, Some(Send::To { .. }))).count() as u64;
        assert_eq!(cost.updates[Update::RouterProxels.index()].messages, messages);
        assert_eq!(cost.updates[Update::RouterModulo.index()].messages, messages);
        // Moving facets: ⌈P/4⌉ passes of 4 steps.
        assert!(cost.updates[Update::XnetFacets.index()].cycles >= patches.len().div_ceil(4) as u64 * 4);
    }

    #[test]
    fn a_surface_too_fine_for_the_cells_is_refused_with_the_count() {
        let patches = cornell(150.0);
        let e = ProxelGrid::new(2, &patches, cfg(SurfaceKind::Hemicube, 64)).err().unwrap().to_string();
        assert!(e.contains("do not fit") && e.contains("--resolution"), "{e}");
        let e = ProxelGrid::new(2, &patches, cfg(SurfaceKind::Hemicube, 7)).err().unwrap().to_string();
        assert!(e.contains("even"), "{e}");
        let hybrid_disk = ProxelConfig { hybrid: true, ..cfg(SurfaceKind::Disk, 8) };
        let e = ProxelGrid::new(2, &patches, hybrid_disk).err().unwrap().to_string();
        assert!(e.contains("hemicube"), "{e}");
    }
}
