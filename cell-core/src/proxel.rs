//! Radiosity thesis §6.2 — proxel-parallel form factors: what one cell runs when the grid
//! computes a shot's form factors by projection instead of by beam diffusion.
//!
//! The projection surface of the shooter (a hemicube or a projection disk, ch. 2) is cut into
//! *zones* of n × n proxels, and cell (x, y) holds proxel (x, y) of every zone (the cyclic
//! distribution of §6.2.3): its [`ProxelStore`]. Each proxel keeps its centre direction in the
//! shooter's frame, its delta form factor as an integer number of quanta (2^−30 of the shot,
//! [`crate::radiosity::FORM_FACTOR_ONE`]), and the nearest facet seen through it so far.
//!
//! A shot, as the cell sees it:
//! 1. the store is cleared ([`ProxelStore::clear`]);
//! 2. facet after facet, the projection parameters arrive — the facet's [`ProxelCone`] (three
//!    edge planes through the shooter and its own plane) and the zones its projection's bounding
//!    rectangle covers (§6.2.4, the *réalisation partielle*) — and the cell z-tests its proxels
//!    there ([`ProxelStore::z_test`]);
//! 3. each proxel's quanta go to the facet it kept ([`ProxelStore::kept`]), to the cell that owns
//!    that facet, where a [`FacetShare`] adds them up.
//!
//! **Invariants.** A proxel keeps the nearest facet whose cone contains its centre direction, the
//! first one in modelling order among equals, whatever order the facets arrive in: exactly the
//! host's sequential depth buffer. The quanta of a shot are integers: every proxel's quanta end in exactly one facet's
//! sum or in the count of proxels that saw nothing, so the sums add up to the surface's total
//! exactly. A full store refuses a proxel and counts it ([`ProxelStore::overflows`]).
//!
//! Arithmetic: the cone test is three dot products and a division in `f64` (software floating
//! point on a Cortex-M4F, as the MasPar's PEs did it in microcode), in the order the host's
//! projective methods use, so that the two depth buffers agree proxel for proxel.
//!
//! ```
//! use cell_core::proxel::{FacetShare, ProxelCone, ProxelStore};
//! let mut store = ProxelStore::<4>::new();
//! assert!(store.push([0.0, 0.0, 1.0], 1000));
//! // A triangle above the shooter, at height 2, seen through the proxel straight up.
//! let v = [[-1.0, -1.0, 2.0], [1.0, -1.0, 2.0], [0.0, 1.0, 2.0]];
//! let cone = ProxelCone::new(v).unwrap();
//! store.clear();
//! assert!(store.z_test(0, 7, &cone));
//! assert_eq!(store.kept(0), Some((7, 1000)));
//! // Facet 7 lives on cell 7 mod 4 = 3 of a 4-cell grid, as its second facet.
//! let mut share = FacetShare::<2>::new(3, 4, 8);
//! assert!(share.add(7, 1000));
//! assert_eq!(share.quanta(7), Some(1000));
//! ```

use heapless::Vec;

/// A facet's id, as the grid numbers them (its index in modelling order).
pub type FacetId = u32;

/// No facet: what a proxel keeps until one is seen through it.
pub const NO_FACET: FacetId = FacetId::MAX;

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
}

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

/// A triangular facet seen from the shooter (at the origin of its frame): the three planes
/// through the origin and each edge, oriented so that the facet's projection is where all three
/// are ≥ 0, and the facet's own plane `plane · d = h`. These are a facet's projection
/// parameters: 13 `f64`, what the grid broadcasts per facet.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ProxelCone {
    edges: [[f64; 3]; 3],
    plane: [f64; 3],
    h: f64,
}

impl ProxelCone {
    /// Words of 32 bits a cone takes on a link (13 `f64`).
    pub const WORDS: u32 = 26;

    /// The cone of the triangle `v` (vertices in the shooter's frame); `None` when its plane
    /// passes through the shooter (seen edge-on, it covers no direction). The edge-on test is
    /// relative: `|h| ≤ 10⁻¹² |plane| |v₀|`, compared squared (no square root in a cell).
    pub fn new(v: [[f64; 3]; 3]) -> Option<ProxelCone> {
        let plane = cross(sub(v[1], v[0]), sub(v[2], v[0]));
        let h = dot(plane, v[0]);
        let scale2 = dot(plane, plane) * dot(v[0], v[0]);
        if h.is_nan() || h * h <= 1e-24 * scale2 {
            return None;
        }
        let s = if h < 0.0 { -1.0 } else { 1.0 };
        let e = |a: [f64; 3], b: [f64; 3]| {
            let c = cross(a, b);
            [c[0] * s, c[1] * s, c[2] * s]
        };
        Some(ProxelCone { edges: [e(v[0], v[1]), e(v[1], v[2]), e(v[2], v[0])], plane, h })
    }

    /// The distance parameter `t` (the point `t·d` is on the facet) when direction `d` is inside
    /// the facet's projection and the facet is in front.
    pub fn hit(&self, d: [f64; 3]) -> Option<f64> {
        if self.edges.iter().all(|e| dot(*e, d) >= 0.0) {
            let t = self.h / dot(self.plane, d);
            (t > 0.0).then_some(t)
        } else {
            None
        }
    }
}

/// One proxel a cell holds.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Proxel {
    /// Its centre direction in the shooter's frame (not unit length).
    pub dir: [f64; 3],
    /// Its delta form factor, in quanta.
    pub quanta: u32,
    depth: f64,
    facet: FacetId,
}

/// The proxels of one cell (capacity `N`), in the order they were loaded.
#[derive(Clone, Debug, Default)]
pub struct ProxelStore<const N: usize> {
    slots: Vec<Proxel, N>,
    overflows: u32,
}

impl<const N: usize> ProxelStore<N> {
    /// An empty store.
    pub const fn new() -> Self {
        ProxelStore { slots: Vec::new(), overflows: 0 }
    }

    /// Load one proxel (with the surface, once); `false`, counted, when the store is full.
    pub fn push(&mut self, dir: [f64; 3], quanta: u32) -> bool {
        let p = Proxel { dir, quanta, depth: f64::INFINITY, facet: NO_FACET };
        if self.slots.push(p).is_err() {
            self.overflows = self.overflows.saturating_add(1);
            return false;
        }
        true
    }

    /// Proxels held.
    pub fn len(&self) -> usize {
        self.slots.len()
    }

    /// No proxel held.
    pub fn is_empty(&self) -> bool {
        self.slots.is_empty()
    }

    /// Proxels refused because the store was full.
    pub fn overflows(&self) -> u32 {
        self.overflows
    }

    /// The proxel in `slot`.
    pub fn proxel(&self, slot: usize) -> Option<&Proxel> {
        self.slots.get(slot)
    }

    /// Start a shot: every proxel sees nothing.
    pub fn clear(&mut self) {
        for p in &mut self.slots {
            p.depth = f64::INFINITY;
            p.facet = NO_FACET;
        }
    }

    /// The depth test of facet `facet` at the proxel in `slot`: it keeps the facet when the
    /// proxel's direction is inside the facet's cone and nearer than what it kept, or as near
    /// and earlier in modelling order (so that the facet kept does not depend on the order the
    /// facets arrive in: the broadcast sends them in order, the hybrid method's spans come in
    /// any). Returns whether it kept it; `false` for a slot out of range.
    pub fn z_test(&mut self, slot: usize, facet: FacetId, cone: &ProxelCone) -> bool {
        let Some(p) = self.slots.get_mut(slot) else { return false };
        match cone.hit(p.dir) {
            Some(t) if t < p.depth || (t == p.depth && facet < p.facet) => {
                p.depth = t;
                p.facet = facet;
                true
            }
            _ => false,
        }
    }

    /// What the proxel in `slot` kept: (facet, quanta), or `None` when it saw nothing.
    pub fn kept(&self, slot: usize) -> Option<(FacetId, u32)> {
        self.slots.get(slot).filter(|p| p.facet != NO_FACET).map(|p| (p.facet, p.quanta))
    }
}

/// The facets one cell owns under the modulo distribution (§6.2.2: facet `f` lives on cell
/// `f mod cells`, in modelling order) and the quanta each received this shot.
#[derive(Clone, Debug)]
pub struct FacetShare<const N: usize> {
    first: FacetId,
    stride: u32,
    quanta: Vec<u64, N>,
    overflows: u32,
}

impl<const N: usize> FacetShare<N> {
    /// The share of the cell numbered `cell` on a grid of `cells` cells, for `facets` facets in
    /// all. Facets past the capacity are counted ([`Self::overflows`]) and receive nothing.
    pub fn new(cell: u32, cells: u32, facets: u32) -> Self {
        let mut s = FacetShare { first: cell, stride: cells.max(1), quanta: Vec::new(), overflows: 0 };
        let mut f = cell;
        while f < facets {
            if s.quanta.push(0).is_err() {
                s.overflows = s.overflows.saturating_add(1);
            }
            f = f.saturating_add(s.stride);
        }
        s
    }

    /// Facets held.
    pub fn len(&self) -> usize {
        self.quanta.len()
    }

    /// No facet held.
    pub fn is_empty(&self) -> bool {
        self.quanta.is_empty()
    }

    /// Facets that did not fit.
    pub fn overflows(&self) -> u32 {
        self.overflows
    }

    fn local(&self, facet: FacetId) -> Option<usize> {
        let d = facet.checked_sub(self.first)?;
        (d % self.stride == 0).then_some((d / self.stride) as usize).filter(|&k| k < self.quanta.len())
    }

    /// Add a proxel's quanta to facet `facet`; `false` when the facet is not this cell's.
    pub fn add(&mut self, facet: FacetId, quanta: u32) -> bool {
        match self.local(facet) {
            Some(k) => {
                self.quanta[k] += quanta as u64;
                true
            }
            None => false,
        }
    }

    /// The quanta facet `facet` received, if it is this cell's.
    pub fn quanta(&self, facet: FacetId) -> Option<u64> {
        self.local(facet).map(|k| self.quanta[k])
    }

    /// The facets held and their quanta, in order.
    pub fn entries(&self) -> impl Iterator<Item = (FacetId, u64)> + '_ {
        self.quanta.iter().enumerate().map(|(k, &q)| (self.first + k as u32 * self.stride, q))
    }

    /// Start a shot: every facet has received nothing.
    pub fn clear(&mut self) {
        self.quanta.iter_mut().for_each(|q| *q = 0);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_nearest_facet_is_kept_and_the_first_among_equals() {
        let mut s = ProxelStore::<2>::new();
        assert!(s.push([0.1, 0.0, 1.0], 5));
        let tri = |z: f64| [[-1.0, -1.0, z], [1.0, -1.0, z], [0.0, 1.0, z]];
        let (far, near) = (ProxelCone::new(tri(3.0)).unwrap(), ProxelCone::new(tri(2.0)).unwrap());
        s.clear();
        assert!(s.z_test(0, 1, &far));
        assert!(s.z_test(0, 2, &near));
        assert!(!s.z_test(0, 3, &far));
        assert!(!s.z_test(0, 4, &near), "an equal depth keeps the first facet");
        assert!(s.z_test(0, 0, &near), "an equal depth and an earlier facet: it is kept, whatever the order");
        assert_eq!(s.kept(0), Some((0, 5)));
        assert!(!s.z_test(9, 1, &near), "a slot out of range is no test");
        s.clear();
        assert_eq!(s.kept(0), None);
    }

    #[test]
    fn a_facet_behind_or_edge_on_hides_nothing() {
        let below = [[-1.0, -1.0, -2.0], [1.0, -1.0, -2.0], [0.0, 1.0, -2.0]];
        let c = ProxelCone::new(below).unwrap();
        assert_eq!(c.hit([0.0, 0.0, 1.0]), None);
        let edge_on = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [2.0, 2.0, 0.0]];
        assert!(ProxelCone::new(edge_on).is_none());
    }

    #[test]
    fn full_stores_count_what_they_refuse() {
        let mut s = ProxelStore::<1>::new();
        assert!(s.push([0.0, 0.0, 1.0], 1));
        assert!(!s.push([0.0, 0.0, 1.0], 1));
        assert_eq!((s.len(), s.overflows()), (1, 1));
        let share = FacetShare::<2>::new(1, 3, 10); // facets 1, 4, 7: one too many
        assert_eq!((share.len(), share.overflows()), (2, 1));
    }

    #[test]
    fn a_share_holds_exactly_its_modulo_facets() {
        let mut share = FacetShare::<8>::new(2, 5, 23); // 2, 7, 12, 17, 22
        assert_eq!(share.entries().map(|e| e.0).collect::<heapless::Vec<_, 8>>().as_slice(), &[2, 7, 12, 17, 22]);
        for f in 0..30 {
            assert_eq!(share.add(f, 1), f % 5 == 2 && f < 23, "facet {f}");
        }
        assert_eq!(share.quanta(12), Some(1));
        share.clear();
        assert_eq!(share.quanta(12), Some(0));
    }
}
