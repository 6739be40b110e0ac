//! Procedural office scenes: large, many-light test scenes without downloads.
//!
//! The radiosity thesis this project compares against (Renaud 1993, appendix A) measured its
//! algorithms on three interiors: **Bureau1** (an office, 7 994 facets, 1 light), **Bureau2** (a
//! larger office, 17 279 facets, 2 large lights) and **Classe** (a classroom, 38 532 facets, 26
//! lights). Their geometry was never published, so [`generate`] builds stand-ins of the same
//! kind and size: rooms with desks, rolling chairs, bookshelves full of books, CRT monitors,
//! keyboards, desk lamps, plants, windows and doors (the classroom: 20 two-seat pupil desks and
//! 40 chairs, a teacher's platform, desk and globe, a blackboard, an overhead projector on its
//! cart, cupboards, shelves) — and the same facet counts (±1 %) and light counts.
//!
//! Conventions: metres, y up, floor at y = 0; the room spans `[0, W] × [0, H] × [0, D]` and has
//! no front wall (z = 0), so an orthographic camera looking along +z from z < 0 sees the
//! interior, as in the Cornell box. Room surfaces face into the room, solids face outwards.
//! Faces are planar convex quads (room and furniture surfaces are split into tiles and
//! patches, as a radiosity mesher would) and triangles (cylinder caps, sphere poles). The room's
//! tile size is chosen so that the total facet count lands on the thesis's figure.
//!
//! The generator is deterministic (a fixed-seed SplitMix64 for books, chair placement and such).
//! Materials of surfaces that run along z (floor, ceiling, side walls) are uniform so that the
//! RC² dexel columns (along z) stay short: at n = 256 the classroom needs fewer than 64 dexels in
//! every cell.

use crate::rng::Rng;
use anyhow::{bail, Result};
use parry3d_f64::math::Vector;

use crate::scene::{Face, Material, Mesh, SceneLight};

/// The generator's vectors (glam's `DVec3`, through parry3d-f64). Furniture is written with
/// `[f64; 3]` literals in local coordinates; the builder takes anything `Into<V>`.
type V = Vector;

/// An axis-aligned box (room bounds, bounding boxes of generated solids).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Aabb {
    /// Low corner.
    pub lo: [f64; 3],
    /// High corner.
    pub hi: [f64; 3],
}

impl Aabb {
    /// Bounding box of points.
    fn of(pts: &[V]) -> Aabb {
        let mut b = Aabb { lo: [f64::INFINITY; 3], hi: [f64::NEG_INFINITY; 3] };
        for p in pts {
            b.lo = [0, 1, 2].map(|i| b.lo[i].min(p[i]));
            b.hi = [0, 1, 2].map(|i| b.hi[i].max(p[i]));
        }
        b
    }

    /// Euclidean distance from a point to the box (0 inside).
    pub fn distance(&self, p: [f64; 3]) -> f64 {
        V::from([0, 1, 2].map(|i| (self.lo[i] - p[i]).max(p[i] - self.hi[i]).max(0.0))).length()
    }

    /// Whether the point lies inside or on the box.
    pub fn contains(&self, p: [f64; 3]) -> bool {
        (0..3).all(|i| self.lo[i] <= p[i] && p[i] <= self.hi[i])
    }
}

/// The three scenes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kind {
    /// A small office (the thesis's "Bureau1": 7 994 facets, one light).
    Bureau1,
    /// A larger office for two (the thesis's "Bureau 2": 17 279 facets, two large lights).
    Bureau2,
    /// A classroom (the thesis's "Classe": 38 532 facets, 26 lights).
    Classe,
}

impl Kind {
    /// All kinds.
    pub const ALL: [Kind; 3] = [Kind::Bureau1, Kind::Bureau2, Kind::Classe];

    /// The built-in scene name.
    pub fn name(self) -> &'static str {
        match self {
            Kind::Bureau1 => "bureau1",
            Kind::Bureau2 => "bureau2",
            Kind::Classe => "classe",
        }
    }

    /// The kind of a built-in name.
    pub fn from_name(name: &str) -> Option<Kind> {
        Kind::ALL.into_iter().find(|k| k.name() == name)
    }

    /// The thesis's facet count (appendix A), which the generator matches.
    pub fn target_facets(self) -> usize {
        match self {
            Kind::Bureau1 => 7_994,
            Kind::Bureau2 => 17_279,
            Kind::Classe => 38_532,
        }
    }

    /// The thesis's number of primary light sources.
    pub fn lights(self) -> usize {
        match self {
            Kind::Bureau1 => 1,
            Kind::Bureau2 => 2,
            Kind::Classe => 26,
        }
    }
}

/// Which way a face must point, for checks: away from a solid's centre, or into the room.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Orient {
    /// A face of a convex solid: its normal points away from this interior point.
    Outward([f64; 3]),
    /// A room surface: its normal points towards this point (the room's centre).
    Inward([f64; 3]),
}

/// A generated scene with what checks need besides the mesh.
#[derive(Clone, Debug)]
pub struct Office {
    /// The mesh (materials and lights included).
    pub mesh: Mesh,
    /// The room's bounds `[0, W] × [0, H] × [0, D]`.
    pub room: Aabb,
    /// Bounding boxes of every generated solid (furniture parts, fixtures, frames).
    pub solids: Vec<Aabb>,
    /// How each face is oriented (parallel to `mesh.faces`).
    pub orient: Vec<Orient>,
    /// Side of the room's tiles (chosen to match the facet count), metres.
    pub tile: f64,
    /// Faces of the room surfaces (the first faces of the mesh); the rest are furniture.
    pub room_faces: usize,
}

/// Generate a built-in office scene by name (`bureau1`, `bureau2`, `classe`).
pub fn generate(name: &str) -> Result<Mesh> {
    match Kind::from_name(name) {
        Some(k) => Ok(build(k).mesh),
        None => bail!("'{name}' is not a procedural office scene (bureau1, bureau2, classe)"),
    }
}

// ---------------------------------------------------------------------------------------------
// Materials.

mod mat {
    pub const WALL: u16 = 1;
    pub const FLOOR: u16 = 2;
    pub const CEILING: u16 = 3;
    pub const WOOD: u16 = 4;
    pub const WOOD_DARK: u16 = 5;
    pub const METAL: u16 = 6;
    pub const FABRIC: u16 = 7;
    pub const PLASTIC: u16 = 8;
    pub const SCREEN: u16 = 9;
    pub const GLASS: u16 = 10;
    pub const BOARD: u16 = 11;
    pub const LIGHT: u16 = 12;
    pub const HOUSING: u16 = 13;
    pub const BOOK0: u16 = 14;
    pub const BOOKS: u16 = 5;
    pub const PLANT: u16 = 19;
    pub const POT: u16 = 20;
    pub const DOOR: u16 = 21;
    pub const BEIGE: u16 = 22;
    pub const PAPER: u16 = 23;
}

fn materials() -> Vec<Material> {
    let m = |name: &str, kd: [f32; 3], ks: f32, ns: f32| Material {
        name: name.into(),
        ka: [0.05; 3],
        kd,
        ks: [ks; 3],
        ns,
        ke: [0.0; 3],
        ..Material::default()
    };
    vec![
        Material::default(),
        m("wall", [0.78, 0.76, 0.70], 0.0, 1.0),
        m("floor", [0.42, 0.33, 0.25], 0.08, 20.0),
        m("ceiling", [0.85, 0.85, 0.83], 0.0, 1.0),
        m("wood", [0.62, 0.45, 0.28], 0.15, 30.0),
        m("wood_dark", [0.36, 0.24, 0.15], 0.1, 25.0),
        m("metal", [0.45, 0.46, 0.48], 0.55, 50.0),
        m("fabric", [0.16, 0.22, 0.50], 0.0, 1.0),
        m("plastic", [0.10, 0.10, 0.11], 0.30, 40.0),
        m("screen", [0.04, 0.06, 0.06], 0.80, 60.0),
        m("glass", [0.55, 0.68, 0.78], 0.50, 60.0),
        m("blackboard", [0.08, 0.20, 0.13], 0.05, 10.0),
        Material { name: "light".into(), ka: [1.0; 3], kd: [0.8; 3], ke: [12.0, 11.5, 10.0], ..Material::default() },
        m("housing", [0.80, 0.80, 0.78], 0.25, 30.0),
        m("book_red", [0.60, 0.08, 0.07], 0.05, 20.0),
        m("book_green", [0.10, 0.40, 0.15], 0.05, 20.0),
        m("book_blue", [0.08, 0.15, 0.50], 0.05, 20.0),
        m("book_yellow", [0.75, 0.62, 0.12], 0.05, 20.0),
        m("book_white", [0.80, 0.78, 0.72], 0.05, 20.0),
        m("plant", [0.12, 0.42, 0.10], 0.0, 1.0),
        m("pot", [0.62, 0.30, 0.16], 0.0, 1.0),
        m("door", [0.55, 0.40, 0.26], 0.1, 25.0),
        m("beige", [0.80, 0.76, 0.64], 0.2, 30.0),
        m("paper", [0.90, 0.90, 0.88], 0.0, 1.0),
    ]
}

// Deterministic PRNG: crate::rng::Rng (SplitMix64).

// ---------------------------------------------------------------------------------------------
// Local frames: a furniture piece is modelled with its front facing local −z, centred on local
// x = 0, standing on local y = 0; a frame places it (rotation about y, then translation).

#[derive(Clone, Copy, Debug)]
struct Frame {
    o: V,
    c: f64,
    s: f64,
}

impl Frame {
    /// Front facing world −z.
    fn at(o: impl Into<V>) -> Frame {
        Frame { o: o.into(), c: 1.0, s: 0.0 }
    }
    /// Rotated by `q` quarter turns about +y (exact): q = 1 faces −x, 2 faces +z, 3 faces +x.
    fn quarter(o: impl Into<V>, q: i32) -> Frame {
        let o = o.into();
        let (c, s) = match q.rem_euclid(4) {
            0 => (1.0, 0.0),
            1 => (0.0, 1.0),
            2 => (-1.0, 0.0),
            _ => (0.0, -1.0),
        };
        Frame { o, c, s }
    }
    /// Rotated by an angle (radians) about +y, relative to this frame, at local point `p`.
    fn child(&self, p: impl Into<V>, a: f64) -> Frame {
        let (sa, ca) = a.sin_cos();
        Frame { o: self.pt(p), c: self.c * ca - self.s * sa, s: self.s * ca + self.c * sa }
    }
    /// Translated to local point `p`, same rotation.
    fn at_local(&self, p: impl Into<V>) -> Frame {
        Frame { o: self.pt(p), ..*self }
    }
    fn dir(&self, l: impl Into<V>) -> V {
        let l = l.into();
        V::new(self.c * l.x + self.s * l.z, l.y, -self.s * l.x + self.c * l.z)
    }
    fn pt(&self, l: impl Into<V>) -> V {
        self.o + self.dir(l)
    }
}

// ---------------------------------------------------------------------------------------------
// Mesh builder.

/// Number of parts of a length split into patches no longer than `patch`.
fn parts(len: f64, patch: f64) -> usize {
    ((len / patch) - 1e-9).ceil().max(1.0) as usize
}

/// Refine sorted breakpoints (fractions of a side of length `len`) into patches ≤ `patch`.
fn refine(bps: &[f64], len: f64, patch: f64) -> Vec<f64> {
    let mut out = vec![bps[0]];
    for w in bps.windows(2) {
        let k = parts((w[1] - w[0]) * len, patch);
        for i in 1..=k {
            out.push(if i == k { w[1] } else { w[0] + (w[1] - w[0]) * i as f64 / k as f64 });
        }
    }
    out
}

#[derive(Default)]
struct Builder {
    positions: Vec<[f64; 3]>,
    faces: Vec<Face>,
    orient: Vec<Orient>,
    solids: Vec<Aabb>,
    /// Largest patch side on furniture.
    patch: f64,
}

impl Builder {
    fn vert(&mut self, p: V) -> u32 {
        self.positions.push(p.to_array());
        (self.positions.len() - 1) as u32
    }

    /// Push a face, reversing it if its normal does not agree with `o`.
    fn face(&mut self, mut idx: Vec<u32>, m: u16, o: Orient) {
        let p: Vec<V> = idx.iter().map(|&i| V::from(self.positions[i as usize])).collect();
        let mut n = V::ZERO;
        for i in 0..p.len() {
            let (a, b) = (p[i], p[(i + 1) % p.len()]);
            n[0] += (a[1] - b[1]) * (a[2] + b[2]);
            n[1] += (a[2] - b[2]) * (a[0] + b[0]);
            n[2] += (a[0] - b[0]) * (a[1] + b[1]);
        }
        let c = p.iter().fold(V::ZERO, |s, &q| s + q) * (1.0 / p.len() as f64);
        let away = match o {
            Orient::Outward(k) => c - V::from(k),
            Orient::Inward(k) => V::from(k) - c,
        };
        if n.dot(away) < 0.0 {
            idx.reverse();
        }
        self.faces.push(Face { verts: idx, material: m });
        self.orient.push(o);
    }

    /// A rectangle `o + a·u + b·v` split at the breakpoints `us`, `vs` (fractions, including 0
    /// and 1) and further into patches no longer than `patch`; `mat(a, b)` gives the material
    /// of the patch centred at (a, b), or `None` to leave a hole.
    #[allow(clippy::too_many_arguments)]
    fn grid(
        &mut self,
        o: V,
        u: V,
        v: V,
        us: &[f64],
        vs: &[f64],
        patch: f64,
        mat: &dyn Fn(f64, f64) -> Option<u16>,
        or: Orient,
    ) {
        let uf = refine(us, u.length(), patch);
        let vf = refine(vs, v.length(), patch);
        let base = self.positions.len() as u32;
        for &b in &vf {
            for &a in &uf {
                self.vert(o + (u * a + v * b));
            }
        }
        let nu = uf.len() as u32;
        for j in 0..vf.len() - 1 {
            for i in 0..uf.len() - 1 {
                let Some(m) = mat((uf[i] + uf[i + 1]) / 2.0, (vf[j] + vf[j + 1]) / 2.0) else { continue };
                let k = base + j as u32 * nu + i as u32;
                self.face(vec![k, k + 1, k + 1 + nu, k + nu], m, or);
            }
        }
    }

    /// A parallelepiped `o + a·ex + b·ey + c·ez` (a, b, c ∈ [0, 1]; orthogonal edges), faces
    /// split into patches; materials per face in the order −x, +x, −y, +y, −z, +z.
    fn block(&mut self, o: V, ex: V, ey: V, ez: V, mats: [u16; 6]) {
        let c = o + (ex + (ey + ez)) * 0.5;
        let sides = [(o, ez, ey), (o + ex, ey, ez), (o, ex, ez), (o + ey, ez, ex), (o, ey, ex), (o + ez, ex, ey)];
        let patch = self.patch;
        for (k, &(p, u, v)) in sides.iter().enumerate() {
            let m = mats[k];
            self.grid(p, u, v, &[0.0, 1.0], &[0.0, 1.0], patch, &|_, _| Some(m), Orient::Outward(c.to_array()));
        }
        let corners: Vec<V> = (0..8)
            .map(|i| o + (ex * (i & 1) as f64 + (ey * ((i >> 1) & 1) as f64 + ez * ((i >> 2) & 1) as f64)))
            .collect();
        self.solids.push(Aabb::of(&corners));
    }

    /// A box in a frame, between local corners `lo` and `hi`.
    fn lbox6(&mut self, f: &Frame, lo: impl Into<V>, hi: impl Into<V>, mats: [u16; 6]) {
        let (lo, hi) = (lo.into(), hi.into());
        let d = hi - lo;
        debug_assert!(d.min_element() > 0.0, "empty box {lo:?} {hi:?}");
        self.block(f.pt(lo), f.dir([d.x, 0.0, 0.0]), V::new(0.0, d.y, 0.0), f.dir([0.0, 0.0, d.z]), mats);
    }
    fn lbox(&mut self, f: &Frame, lo: impl Into<V>, hi: impl Into<V>, m: u16) {
        self.lbox6(f, lo, hi, [m; 6]);
    }

    /// A closed frustum (cylinder when r0 = r1) from `base` along the unit `axis` over `h`,
    /// radius `r0` at the base and `r1` at the top, `seg` sides; caps are triangle fans.
    #[allow(clippy::too_many_arguments)]
    fn frustum(
        &mut self,
        base: impl Into<V>,
        axis: impl Into<V>,
        h: f64,
        r0: f64,
        r1: f64,
        seg: usize,
        side: u16,
        caps: u16,
    ) {
        // glam's normalize multiplies by 1 / length, as the former helper did.
        let (base, axis) = (base.into(), axis.into().normalize());
        let helper = if axis.y.abs() < 0.9 { V::Y } else { V::X };
        let e1 = axis.cross(helper).normalize();
        let e2 = axis.cross(e1);
        let top = base + axis * h;
        let centre = base + axis * (h / 2.0);
        let ring = |c: V, r: f64, k: usize| {
            let t = std::f64::consts::TAU * k as f64 / seg as f64;
            c + (e1 * (r * t.cos()) + e2 * (r * t.sin()))
        };
        let mut pts = Vec::new();
        let b0 = self.positions.len() as u32;
        for k in 0..seg {
            let p = ring(base, r0, k);
            pts.push(p);
            self.vert(p);
        }
        let t0 = self.positions.len() as u32;
        for k in 0..seg {
            let p = ring(top, r1, k);
            pts.push(p);
            self.vert(p);
        }
        let cb = self.vert(base);
        let ct = self.vert(top);
        let o = Orient::Outward(centre.to_array());
        for k in 0..seg as u32 {
            let k1 = (k + 1) % seg as u32;
            self.face(vec![b0 + k, b0 + k1, t0 + k1, t0 + k], side, o);
            self.face(vec![cb, b0 + k1, b0 + k], caps, o);
            self.face(vec![ct, t0 + k, t0 + k1], caps, o);
        }
        pts.push(base);
        pts.push(top);
        self.solids.push(Aabb::of(&pts));
    }

    /// A vertical cylinder standing at local point `p` of a frame.
    #[allow(clippy::too_many_arguments)]
    fn lcyl(&mut self, f: &Frame, p: impl Into<V>, h: f64, r: f64, seg: usize, side: u16, caps: u16) {
        self.frustum(f.pt(p), [0.0, 1.0, 0.0], h, r, r, seg, side, caps);
    }

    /// A UV sphere (`nlat` bands, `nlon` sectors); quads between rings, triangles at the poles.
    fn sphere(&mut self, c: V, r: f64, nlat: usize, nlon: usize, m: u16) {
        let o = Orient::Outward(c.to_array());
        let north = self.vert(c + V::new(0.0, r, 0.0));
        let south = self.vert(c + V::new(0.0, -r, 0.0));
        let mut rings = Vec::new();
        for i in 1..nlat {
            let phi = std::f64::consts::PI * i as f64 / nlat as f64;
            let start = self.positions.len() as u32;
            for j in 0..nlon {
                let th = std::f64::consts::TAU * j as f64 / nlon as f64;
                self.vert(c + V::new(r * phi.sin() * th.cos(), r * phi.cos(), r * phi.sin() * th.sin()));
            }
            rings.push(start);
        }
        let nl = nlon as u32;
        for j in 0..nl {
            let j1 = (j + 1) % nl;
            self.face(vec![north, rings[0] + j, rings[0] + j1], m, o);
            let last = *rings.last().expect("nlat ≥ 2");
            self.face(vec![south, last + j1, last + j], m, o);
            for w in rings.windows(2) {
                self.face(vec![w[0] + j, w[0] + j1, w[1] + j1, w[1] + j], m, o);
            }
        }
        self.solids.push(Aabb { lo: (c - V::splat(r)).to_array(), hi: (c + V::splat(r)).to_array() });
    }

    /// Append another builder's faces (index offset).
    fn append(&mut self, other: Builder) {
        let off = self.positions.len() as u32;
        self.positions.extend(other.positions);
        self.faces.extend(other.faces.into_iter().map(|mut f| {
            f.verts.iter_mut().for_each(|v| *v += off);
            f
        }));
        self.orient.extend(other.orient);
        self.solids.extend(other.solids);
    }
}

// ---------------------------------------------------------------------------------------------
// The room: floor, ceiling, back and side walls (no front wall), tiled; wall openings (windows,
// doors, the blackboard's recess) are tiles of another material in the wall's plane.

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Wall {
    /// x = 0, horizontal coordinate z.
    Left,
    /// x = W, horizontal coordinate z.
    Right,
    /// z = D, horizontal coordinate x.
    Back,
}

/// A rectangle of another material in a wall's plane: horizontal `u0..u1`, vertical `v0..v1`.
#[derive(Clone, Copy, Debug)]
struct Opening {
    wall: Wall,
    u0: f64,
    u1: f64,
    v0: f64,
    v1: f64,
    mat: u16,
}

struct Room {
    w: f64,
    h: f64,
    d: f64,
    openings: Vec<Opening>,
}

/// One room surface: origin, the two edge vectors, and the breakpoints.
struct Surface {
    o: V,
    u: V,
    v: V,
    us: Vec<f64>,
    vs: Vec<f64>,
    mat: u16,
    wall: Option<Wall>,
}

impl Room {
    fn surfaces(&self) -> Vec<Surface> {
        let (w, h, d) = (self.w, self.h, self.d);
        let mut out = vec![
            Surface {
                o: V::ZERO,
                u: V::new(w, 0.0, 0.0),
                v: V::new(0.0, 0.0, d),
                us: vec![],
                vs: vec![],
                mat: mat::FLOOR,
                wall: None,
            },
            Surface {
                o: V::new(0.0, h, 0.0),
                u: V::new(w, 0.0, 0.0),
                v: V::new(0.0, 0.0, d),
                us: vec![],
                vs: vec![],
                mat: mat::CEILING,
                wall: None,
            },
            Surface {
                o: V::new(0.0, 0.0, d),
                u: V::new(w, 0.0, 0.0),
                v: V::new(0.0, h, 0.0),
                us: vec![],
                vs: vec![],
                mat: mat::WALL,
                wall: Some(Wall::Back),
            },
            Surface {
                o: V::ZERO,
                u: V::new(0.0, 0.0, d),
                v: V::new(0.0, h, 0.0),
                us: vec![],
                vs: vec![],
                mat: mat::WALL,
                wall: Some(Wall::Left),
            },
            Surface {
                o: V::new(w, 0.0, 0.0),
                u: V::new(0.0, 0.0, d),
                v: V::new(0.0, h, 0.0),
                us: vec![],
                vs: vec![],
                mat: mat::WALL,
                wall: Some(Wall::Right),
            },
        ];
        for s in &mut out {
            let (lu, lv) = (s.u.length(), s.v.length());
            let mut us = vec![0.0, 1.0];
            let mut vs = vec![0.0, 1.0];
            for op in self.openings.iter().filter(|op| Some(op.wall) == s.wall) {
                us.extend([op.u0 / lu, op.u1 / lu]);
                vs.extend([op.v0 / lv, op.v1 / lv]);
            }
            us.sort_by(f64::total_cmp);
            vs.sort_by(f64::total_cmp);
            us.dedup_by(|a, b| (*a - *b).abs() < 1e-9);
            vs.dedup_by(|a, b| (*a - *b).abs() < 1e-9);
            s.us = us;
            s.vs = vs;
        }
        out
    }

    /// Tiles the room has with tiles of side ≤ `tile`.
    fn count(&self, tile: f64) -> usize {
        self.surfaces()
            .iter()
            .map(|s| (refine(&s.us, s.u.length(), tile).len() - 1) * (refine(&s.vs, s.v.length(), tile).len() - 1))
            .sum()
    }

    fn build(&self, b: &mut Builder, tile: f64) {
        let centre = [self.w / 2.0, self.h / 2.0, self.d / 2.0];
        for s in self.surfaces() {
            let (lu, lv) = (s.u.length(), s.v.length());
            let ops: Vec<Opening> = self.openings.iter().copied().filter(|op| Some(op.wall) == s.wall).collect();
            let base = s.mat;
            let mat = move |a: f64, c: f64| {
                let (x, y) = (a * lu, c * lv);
                Some(ops.iter().find(|op| op.u0 < x && x < op.u1 && op.v0 < y && y < op.v1).map_or(base, |op| op.mat))
            };
            b.grid(s.o, s.u, s.v, &s.us, &s.vs, tile, &mat, Orient::Inward(centre));
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Furniture. Every piece is modelled in a frame: front towards local −z, centred on x = 0.

struct Scene {
    b: Builder,
    rng: Rng,
    lights: Vec<[f64; 3]>,
}

impl Scene {
    /// An office desk `w × d`, height `h`: top, drawer pedestal on the left, a panel leg on the
    /// right, a modesty panel at the back.
    fn office_desk(&mut self, f: &Frame, w: f64, d: f64, h: f64) {
        let b = &mut self.b;
        let t = 0.03;
        b.lbox(f, [-w / 2.0, h - t, 0.0], [w / 2.0, h, d], mat::WOOD);
        let (px0, px1) = (-w / 2.0 + 0.02, -w / 2.0 + 0.44);
        b.lbox(f, [px0, 0.0, 0.05], [px1, h - t, d - 0.02], mat::WOOD_DARK);
        let dh = (h - t - 0.06) / 3.0;
        for i in 0..3 {
            let y0 = 0.04 + i as f64 * dh;
            b.lbox(f, [px0 + 0.01, y0 + 0.01, 0.035], [px1 - 0.01, y0 + dh - 0.01, 0.05], mat::WOOD);
            b.lbox(
                f,
                [(px0 + px1) / 2.0 - 0.05, y0 + dh - 0.06, 0.02],
                [(px0 + px1) / 2.0 + 0.05, y0 + dh - 0.045, 0.035],
                mat::METAL,
            );
        }
        b.lbox(f, [w / 2.0 - 0.05, 0.0, 0.05], [w / 2.0 - 0.02, h - t, d - 0.02], mat::WOOD_DARK);
        b.lbox(f, [px1, 0.25, d - 0.05], [w / 2.0 - 0.05, h - t, d - 0.03], mat::WOOD_DARK);
    }

    /// A CRT monitor on a swivel base (standing at the frame's origin).
    fn crt(&mut self, f: &Frame) {
        let b = &mut self.b;
        b.lcyl(f, [0.0, 0.0, 0.2], 0.02, 0.11, 16, mat::BEIGE, mat::BEIGE);
        b.lbox(f, [-0.06, 0.02, 0.14], [0.06, 0.07, 0.26], mat::BEIGE);
        b.lbox(f, [-0.21, 0.07, 0.0], [0.21, 0.43, 0.07], mat::BEIGE);
        b.lbox(f, [-0.175, 0.10, -0.006], [0.175, 0.40, 0.0], mat::SCREEN);
        b.lbox(f, [-0.17, 0.10, 0.07], [0.17, 0.40, 0.26], mat::BEIGE);
        b.lbox(f, [-0.11, 0.14, 0.26], [0.11, 0.34, 0.38], mat::BEIGE);
        b.lbox(f, [0.14, 0.085, -0.004], [0.17, 0.095, 0.0], mat::PLASTIC);
    }

    /// A keyboard with 5 × 14 keys, and a mouse beside it.
    fn keyboard(&mut self, f: &Frame) {
        let b = &mut self.b;
        b.lbox(f, [-0.23, 0.0, 0.0], [0.23, 0.025, 0.17], mat::BEIGE);
        for r in 0..5 {
            for c in 0..14 {
                let x = -0.21 + c as f64 * 0.03;
                let z = 0.02 + r as f64 * 0.03;
                b.lbox(f, [x, 0.025, z], [x + 0.025, 0.035, z + 0.025], if r == 0 { mat::PLASTIC } else { mat::PAPER });
            }
        }
        b.lbox(f, [0.30, 0.0, 0.04], [0.36, 0.03, 0.14], mat::BEIGE);
    }

    /// An articulated desk lamp (base, post, arm, conical shade).
    fn desk_lamp(&mut self, f: &Frame) {
        let b = &mut self.b;
        b.lcyl(f, [0.0, 0.0, 0.0], 0.025, 0.08, 16, mat::PLASTIC, mat::PLASTIC);
        b.lcyl(f, [0.0, 0.025, 0.0], 0.38, 0.01, 8, mat::METAL, mat::METAL);
        b.frustum(f.pt([0.0, 0.40, 0.0]), f.dir([0.0, 0.0, -1.0]), 0.25, 0.012, 0.012, 8, mat::METAL, mat::METAL);
        b.frustum(f.pt([0.0, 0.42, -0.25]), [0.0, -1.0, 0.0], 0.13, 0.035, 0.09, 16, mat::PLASTIC, mat::METAL);
    }

    /// A rolling office chair ("chaise à roulettes"): five-star base with casters, gas lift,
    /// seat, backrest, armrests.
    fn office_chair(&mut self, f: &Frame) {
        let a0 = self.rng.range(0.0, 1.2);
        let b = &mut self.b;
        for k in 0..5 {
            let g = f.child([0.0; 3], a0 + std::f64::consts::TAU * k as f64 / 5.0);
            b.lbox(&g, [-0.02, 0.055, 0.04], [0.02, 0.085, 0.30], mat::PLASTIC);
            b.lcyl(&g, [0.0, 0.0, 0.28], 0.055, 0.025, 8, mat::PLASTIC, mat::PLASTIC);
        }
        b.lcyl(f, [0.0, 0.05, 0.0], 0.05, 0.055, 12, mat::PLASTIC, mat::PLASTIC);
        b.lcyl(f, [0.0, 0.10, 0.0], 0.30, 0.025, 12, mat::METAL, mat::METAL);
        b.lbox(f, [-0.23, 0.40, -0.23], [0.23, 0.47, 0.23], mat::FABRIC);
        b.lbox(f, [-0.04, 0.42, 0.23], [0.04, 0.58, 0.27], mat::PLASTIC);
        b.lbox(f, [-0.21, 0.55, 0.25], [0.21, 0.98, 0.31], mat::FABRIC);
        for s in [-1.0, 1.0] {
            b.lbox(f, [s * 0.25 - 0.015, 0.47, -0.02], [s * 0.25 + 0.015, 0.64, 0.02], mat::PLASTIC);
            b.lbox(f, [s * 0.25 - 0.03, 0.64, -0.16], [s * 0.25 + 0.03, 0.67, 0.10], mat::PLASTIC);
        }
    }

    /// A bookshelf `w × h × d` with `n` shelves of books (books line up along local x).
    fn bookshelf(&mut self, f: &Frame, w: f64, h: f64, d: f64, n: usize) {
        let t = 0.02;
        {
            let b = &mut self.b;
            b.lbox(f, [-w / 2.0, 0.0, 0.0], [-w / 2.0 + t, h, d], mat::WOOD);
            b.lbox(f, [w / 2.0 - t, 0.0, 0.0], [w / 2.0, h, d], mat::WOOD);
            b.lbox(f, [-w / 2.0 + t, h - t, 0.0], [w / 2.0 - t, h, d], mat::WOOD);
            b.lbox(f, [-w / 2.0 + t, 0.0, 0.01], [w / 2.0 - t, 0.08, d], mat::WOOD_DARK);
            b.lbox(f, [-w / 2.0 + t, 0.08, d - 0.01], [w / 2.0 - t, h - t, d], mat::WOOD_DARK);
        }
        let pitch = (h - t - 0.08) / n as f64;
        for i in 0..n {
            let y0 = 0.08 + i as f64 * pitch;
            self.b.lbox(f, [-w / 2.0 + t, y0, 0.0], [w / 2.0 - t, y0 + t, d - 0.01], mat::WOOD);
            let clear = pitch - t - 0.03;
            let mut x = -w / 2.0 + t + 0.005;
            let end = w / 2.0 - t - 0.005;
            let stop = self.rng.range(0.55, 0.95);
            while x < end - 0.06 && (x + w / 2.0) / w < stop {
                if self.rng.f() < 0.08 {
                    x += self.rng.range(0.03, 0.1);
                    continue;
                }
                let bw = self.rng.range(0.018, 0.05);
                let bh = clear * self.rng.range(0.62, 0.95);
                let bd = (d - 0.03) * self.rng.range(0.65, 0.95);
                let m = mat::BOOK0 + self.rng.below(mat::BOOKS as u64) as u16;
                let z0 = d - 0.015 - bd;
                self.b.lbox(f, [x, y0 + t, z0], [(x + bw).min(end), y0 + t + bh, d - 0.015], m);
                x += bw + 0.002;
            }
        }
    }

    /// A four-drawer filing cabinet.
    fn cabinet(&mut self, f: &Frame, h: f64, drawers: usize) {
        let b = &mut self.b;
        b.lbox(f, [-0.23, 0.0, 0.02], [0.23, h, 0.62], mat::METAL);
        let dh = (h - 0.04) / drawers as f64;
        for i in 0..drawers {
            let y0 = 0.02 + i as f64 * dh;
            b.lbox(f, [-0.22, y0 + 0.01, 0.0], [0.22, y0 + dh - 0.01, 0.02], mat::HOUSING);
            b.frustum(
                f.pt([-0.06, y0 + dh - 0.06, 0.0]),
                f.dir([1.0, 0.0, 0.0]),
                0.12,
                0.008,
                0.008,
                6,
                mat::METAL,
                mat::METAL,
            );
        }
    }

    /// A waste-paper bin.
    fn bin(&mut self, f: &Frame) {
        self.b.lcyl(f, [0.0; 3], 0.01, 0.13, 16, mat::PLASTIC, mat::PLASTIC);
        self.b.frustum(f.pt([0.0, 0.01, 0.0]), [0.0, 1.0, 0.0], 0.33, 0.13, 0.16, 16, mat::PLASTIC, mat::PAPER);
    }

    /// A potted plant: pot, stem and a spherical crown.
    fn plant(&mut self, f: &Frame, h: f64) {
        let b = &mut self.b;
        b.frustum(f.pt([0.0; 3]), [0.0, 1.0, 0.0], 0.30, 0.12, 0.16, 16, mat::POT, mat::WOOD_DARK);
        b.lcyl(f, [0.0, 0.30, 0.0], h - 0.55, 0.015, 6, mat::WOOD_DARK, mat::WOOD_DARK);
        b.sphere(f.pt([0.0, h - 0.25, 0.0]), 0.25, 12, 16, mat::PLANT);
    }

    /// A round table on a pedestal.
    fn round_table(&mut self, f: &Frame, r: f64, h: f64) {
        let b = &mut self.b;
        b.lcyl(f, [0.0; 3], 0.03, 0.28, 24, mat::METAL, mat::METAL);
        b.lcyl(f, [0.0, 0.03, 0.0], h - 0.07, 0.04, 12, mat::METAL, mat::METAL);
        b.lcyl(f, [0.0, h - 0.04, 0.0], 0.04, r, 32, mat::WOOD_DARK, mat::WOOD);
    }

    /// A printer on a side table.
    fn printer_table(&mut self, f: &Frame) {
        let b = &mut self.b;
        b.lbox(f, [-0.4, 0.62, 0.0], [0.4, 0.65, 0.5], mat::WOOD);
        for (x, z) in [(-0.37, 0.03), (0.34, 0.03), (-0.37, 0.44), (0.34, 0.44)] {
            b.lbox(f, [x, 0.0, z], [x + 0.03, 0.62, z + 0.03], mat::METAL);
        }
        b.lbox(f, [-0.37, 0.12, 0.03], [0.37, 0.14, 0.47], mat::WOOD);
        b.lbox(f, [-0.22, 0.65, 0.08], [0.22, 0.83, 0.45], mat::BEIGE);
        b.lbox(f, [-0.15, 0.83, 0.25], [0.15, 0.86, 0.44], mat::PAPER);
        b.lbox(f, [-0.18, 0.70, 0.02], [0.18, 0.71, 0.08], mat::PLASTIC);
    }

    /// A coat stand.
    fn coat_stand(&mut self, f: &Frame) {
        let b = &mut self.b;
        b.lcyl(f, [0.0; 3], 0.03, 0.22, 16, mat::WOOD_DARK, mat::WOOD_DARK);
        b.lcyl(f, [0.0, 0.03, 0.0], 1.72, 0.02, 8, mat::WOOD_DARK, mat::WOOD_DARK);
        b.sphere(f.pt([0.0, 1.78, 0.0]), 0.035, 6, 8, mat::WOOD_DARK);
        for k in 0..4 {
            let g = f.child([0.0, 1.62, 0.0], std::f64::consts::FRAC_PI_4 + k as f64 * std::f64::consts::FRAC_PI_2);
            b.frustum(
                g.pt([0.0, 0.0, 0.015]),
                g.dir([0.0, 0.5, 1.0]),
                0.14,
                0.01,
                0.008,
                6,
                mat::WOOD_DARK,
                mat::WOOD_DARK,
            );
        }
    }

    /// A window in a side or back wall: glass in the wall's plane (an opening), a frame, a
    /// sill and a mullion. `u0..u1` along the wall, `v0..v1` height.
    fn window(&mut self, room: &mut Room, wall: Wall, u0: f64, u1: f64, v0: f64, v1: f64) {
        room.openings.push(Opening { wall, u0, u1, v0, v1, mat: mat::GLASS });
        let (f, u0, u1) = Self::wall_local(room, wall, u0, u1);
        let b = &mut self.b;
        let t = 0.05;
        b.lbox(&f, [u0 - t, v0 - t, -0.04], [u1 + t, v0, 0.0], mat::HOUSING);
        b.lbox(&f, [u0 - t, v1, -0.04], [u1 + t, v1 + t, 0.0], mat::HOUSING);
        b.lbox(&f, [u0 - t, v0, -0.04], [u0, v1, 0.0], mat::HOUSING);
        b.lbox(&f, [u1, v0, -0.04], [u1 + t, v1, 0.0], mat::HOUSING);
        let um = (u0 + u1) / 2.0;
        b.lbox(&f, [um - 0.025, v0, -0.03], [um + 0.025, v1, 0.0], mat::HOUSING);
        b.lbox(&f, [u0 - 0.08, v0 - t - 0.03, -0.20], [u1 + 0.08, v0 - t, 0.0], mat::BEIGE);
    }

    /// A door: the leaf in the wall's plane (an opening), a frame and a handle.
    fn door(&mut self, room: &mut Room, wall: Wall, u0: f64, u1: f64) {
        let v1 = 2.05;
        room.openings.push(Opening { wall, u0, u1, v0: 0.0, v1, mat: mat::DOOR });
        let (f, u0, u1) = Self::wall_local(room, wall, u0, u1);
        let b = &mut self.b;
        let t = 0.06;
        b.lbox(&f, [u0 - t, 0.0, -0.025], [u0, v1 + t, 0.0], mat::WOOD_DARK);
        b.lbox(&f, [u1, 0.0, -0.025], [u1 + t, v1 + t, 0.0], mat::WOOD_DARK);
        b.lbox(&f, [u0, v1, -0.025], [u1, v1 + t, 0.0], mat::WOOD_DARK);
        b.frustum(f.pt([u1 - 0.08, 1.02, 0.0]), f.dir([0.0, 0.0, -1.0]), 0.06, 0.01, 0.01, 8, mat::METAL, mat::METAL);
        b.lbox(&f, [u1 - 0.20, 1.0, -0.08], [u1 - 0.06, 1.04, -0.06], mat::METAL);
    }

    /// A flat panel radiator on a wall, `u0..u1`, below `top`.
    fn radiator(&mut self, room: &Room, wall: Wall, u0: f64, u1: f64, top: f64) {
        let (f, u0, u1) = Self::wall_local(room, wall, u0, u1);
        let b = &mut self.b;
        b.lbox(&f, [u0, top - 0.55, -0.12], [u1, top, -0.05], mat::HOUSING);
        for (v, r) in [(top - 0.58, 0.015), (top - 0.62, 0.015)] {
            b.frustum(
                f.pt([u0 - 0.1, v, -0.085]),
                f.dir([1.0, 0.0, 0.0]),
                u1 - u0 + 0.2,
                r,
                r,
                8,
                mat::METAL,
                mat::METAL,
            );
        }
    }

    /// A frame whose local x runs along a wall, y up, z = 0 on the wall and −z into the room,
    /// and the local x range of the wall span `u0..u1` (u as the room's surfaces measure it:
    /// z on the side walls, x on the back wall).
    fn wall_local(room: &Room, wall: Wall, u0: f64, u1: f64) -> (Frame, f64, f64) {
        match wall {
            // local x → world +z, local −z → world +x.
            Wall::Left => (Frame::quarter([0.0; 3], 3), u0, u1),
            // local x → world −z (from z = D), local −z → world −x.
            Wall::Right => (Frame::quarter([room.w, 0.0, room.d], 1), room.d - u1, room.d - u0),
            Wall::Back => (Frame::at([0.0, 0.0, room.d]), u0, u1),
        }
    }

    /// A ceiling light fixture centred at (x, z): housing of `lx × lz`, hung `drop` below the
    /// ceiling on two rods (flush when `drop` = 0), diffuser underneath (the emitter); the point
    /// light sits 3 cm below the diffuser.
    fn fixture(&mut self, room: &Room, x: f64, z: f64, lx: f64, lz: f64, drop: f64) {
        let b = &mut self.b;
        let th = 0.07;
        let top = room.h - drop;
        let f = Frame::at([x, 0.0, z]);
        b.lbox6(
            &f,
            [-lx / 2.0, top - th, -lz / 2.0],
            [lx / 2.0, top, lz / 2.0],
            [mat::HOUSING, mat::HOUSING, mat::LIGHT, mat::HOUSING, mat::HOUSING, mat::HOUSING],
        );
        if drop > 0.0 {
            for s in [-1.0, 1.0] {
                b.lcyl(&f, [s * (lx / 2.0 - 0.1), top, 0.0], drop, 0.006, 6, mat::METAL, mat::METAL);
            }
        }
        self.lights.push([x, top - th - 0.03, z]);
    }

    // --- classroom pieces ---

    /// A two-seat pupil desk: top, side panels, book tray, foot bar.
    fn pupil_desk(&mut self, f: &Frame, w: f64, d: f64, h: f64) {
        let b = &mut self.b;
        b.lbox(f, [-w / 2.0, h - 0.025, 0.0], [w / 2.0, h, d], mat::WOOD);
        for s in [-1.0, 1.0] {
            let x = s * (w / 2.0 - 0.05);
            b.lbox(f, [x - 0.015, 0.0, 0.04], [x + 0.015, h - 0.025, d - 0.04], mat::METAL);
        }
        b.lbox(f, [-w / 2.0 + 0.065, h - 0.17, 0.12], [w / 2.0 - 0.065, h - 0.155, d - 0.04], mat::WOOD);
        b.lbox(f, [-w / 2.0 + 0.065, h - 0.155, d - 0.06], [w / 2.0 - 0.065, h - 0.025, d - 0.045], mat::WOOD);
        b.frustum(
            f.pt([-w / 2.0 + 0.065, 0.12, d - 0.10]),
            f.dir([1.0, 0.0, 0.0]),
            w - 0.13,
            0.012,
            0.012,
            8,
            mat::METAL,
            mat::METAL,
        );
    }

    /// A school chair: four tubular legs, seat, two back posts and a backrest.
    fn school_chair(&mut self, f: &Frame) {
        let b = &mut self.b;
        let (hw, hd, sy) = (0.20, 0.19, 0.44);
        for (x, z) in
            [(-hw + 0.02, -hd + 0.02), (hw - 0.02, -hd + 0.02), (-hw + 0.02, hd - 0.02), (hw - 0.02, hd - 0.02)]
        {
            b.lcyl(f, [x, 0.0, z], sy - 0.02, 0.012, 8, mat::METAL, mat::PLASTIC);
        }
        b.lbox(f, [-hw, sy - 0.02, -hd], [hw, sy, hd], mat::WOOD);
        for s in [-1.0, 1.0] {
            b.lcyl(f, [s * (hw - 0.03), sy, hd - 0.03], 0.28, 0.012, 8, mat::METAL, mat::METAL);
        }
        b.lbox(f, [-hw + 0.01, sy + 0.14, hd - 0.02], [hw - 0.01, sy + 0.36, hd], mat::WOOD);
    }

    /// The teacher's desk: top, two drawer pedestals, modesty panel; a globe and books on it.
    fn teacher_desk(&mut self, f: &Frame, y: f64) {
        let (w, d, h) = (1.6, 0.8, 0.75);
        {
            let b = &mut self.b;
            b.lbox(f, [-w / 2.0, y + h - 0.03, 0.0], [w / 2.0, y + h, d], mat::WOOD_DARK);
            for s in [-1.0, 1.0] {
                let (x0, x1) =
                    if s < 0.0 { (-w / 2.0 + 0.02, -w / 2.0 + 0.45) } else { (w / 2.0 - 0.45, w / 2.0 - 0.02) };
                b.lbox(f, [x0, y, 0.04], [x1, y + h - 0.03, d - 0.02], mat::WOOD);
                for i in 0..3 {
                    let y0 = y + 0.04 + i as f64 * 0.22;
                    b.lbox(f, [x0 + 0.01, y0, 0.025], [x1 - 0.01, y0 + 0.2, 0.04], mat::WOOD_DARK);
                    b.lbox(
                        f,
                        [(x0 + x1) / 2.0 - 0.05, y0 + 0.14, 0.01],
                        [(x0 + x1) / 2.0 + 0.05, y0 + 0.155, 0.025],
                        mat::METAL,
                    );
                }
            }
            b.lbox(f, [-w / 2.0 + 0.45, y + 0.2, d - 0.05], [w / 2.0 - 0.45, y + h - 0.03, d - 0.03], mat::WOOD);
        }
        // A globe on a stand.
        let g = f.at_local([0.5, y + h, 0.45]);
        self.b.lcyl(&g, [0.0; 3], 0.02, 0.08, 16, mat::WOOD_DARK, mat::WOOD_DARK);
        self.b.lcyl(&g, [0.0, 0.02, 0.0], 0.10, 0.008, 6, mat::METAL, mat::METAL);
        self.b.sphere(g.pt([0.0, 0.28, 0.0]), 0.16, 16, 24, mat::BOOK0 + 2);
        // A pile of exercise books.
        for i in 0..6 {
            let dx = self.rng.range(-0.02, 0.02);
            let dz = self.rng.range(-0.02, 0.02);
            let m = mat::BOOK0 + self.rng.below(mat::BOOKS as u64) as u16;
            let y0 = y + h + i as f64 * 0.012;
            self.b.lbox(f, [-0.45 + dx, y0, 0.3 + dz], [-0.24 + dx, y0 + 0.011, 0.6 + dz], m);
        }
    }

    /// An overhead projector (rétroprojecteur) on a wheeled cart.
    fn projector_cart(&mut self, f: &Frame) {
        let b = &mut self.b;
        for (x, z) in [(-0.27, 0.03), (0.24, 0.03), (-0.27, 0.44), (0.24, 0.44)] {
            b.lcyl(f, [x + 0.015, 0.0, z + 0.015], 0.06, 0.03, 8, mat::PLASTIC, mat::PLASTIC);
            b.lbox(f, [x, 0.06, z], [x + 0.03, 0.72, z + 0.03], mat::METAL);
        }
        b.lbox(f, [-0.3, 0.72, 0.0], [0.3, 0.75, 0.5], mat::METAL);
        b.lbox(f, [-0.27, 0.20, 0.03], [0.27, 0.22, 0.47], mat::METAL);
        b.lbox(f, [-0.2, 0.75, 0.05], [0.2, 0.87, 0.45], mat::HOUSING);
        b.lbox(f, [-0.16, 0.87, 0.09], [0.16, 0.875, 0.41], mat::GLASS);
        b.lbox(f, [-0.03, 0.87, 0.43], [0.03, 1.25, 0.46], mat::METAL);
        b.lbox(f, [-0.07, 1.20, 0.28], [0.07, 1.30, 0.46], mat::HOUSING);
        b.frustum(f.pt([0.0, 1.25, 0.28]), [0.0, 0.0, -1.0], 0.04, 0.04, 0.04, 12, mat::PLASTIC, mat::GLASS);
    }

    /// A tall two-door cupboard.
    fn cupboard(&mut self, f: &Frame, w: f64, h: f64, d: f64) {
        let b = &mut self.b;
        b.lbox(f, [-w / 2.0, 0.0, 0.02], [w / 2.0, h, d], mat::WOOD);
        for s in [-1.0, 1.0] {
            let (x0, x1) = if s < 0.0 { (-w / 2.0 + 0.01, -0.005) } else { (0.005, w / 2.0 - 0.01) };
            b.lbox(f, [x0, 0.05, 0.0], [x1, h - 0.02, 0.02], mat::WOOD_DARK);
            b.lbox(f, [s * 0.04 - 0.01, h / 2.0 - 0.1, -0.02], [s * 0.04 + 0.01, h / 2.0 + 0.1, 0.0], mat::METAL);
        }
    }

    /// The blackboard on the back wall, centred at `x`: board, aluminium frame, chalk tray,
    /// a duster and chalk; a rolled-up projection screen above.
    fn blackboard(&mut self, room: &Room, x: f64, w: f64) {
        let f = Frame::at([x, 0.0, room.d]);
        let b = &mut self.b;
        let (y0, y1) = (0.9, 2.1);
        b.lbox(&f, [-w / 2.0, y0, -0.02], [w / 2.0, y1, 0.0], mat::BOARD);
        b.lbox(&f, [-w / 2.0 - 0.03, y1, -0.03], [w / 2.0 + 0.03, y1 + 0.03, 0.0], mat::METAL);
        b.lbox(&f, [-w / 2.0 - 0.03, y0 - 0.03, -0.03], [w / 2.0 + 0.03, y0, 0.0], mat::METAL);
        b.lbox(&f, [-w / 2.0 - 0.03, y0, -0.03], [-w / 2.0, y1, 0.0], mat::METAL);
        b.lbox(&f, [w / 2.0, y0, -0.03], [w / 2.0 + 0.03, y1, 0.0], mat::METAL);
        b.lbox(&f, [-w / 2.0 + 0.1, y0 - 0.05, -0.10], [w / 2.0 - 0.1, y0 - 0.03, 0.0], mat::METAL);
        b.lbox(&f, [-w / 2.0 + 0.1, y0 - 0.03, -0.10], [w / 2.0 - 0.1, y0 - 0.01, -0.09], mat::METAL);
        b.lbox(&f, [0.4, y0 - 0.03, -0.08], [0.52, y0 + 0.01, -0.03], mat::WOOD_DARK);
        for i in 0..3 {
            let xc = -0.6 + 0.12 * i as f64;
            b.frustum(f.pt([xc, y0 - 0.02, -0.06]), [1.0, 0.0, 0.0], 0.08, 0.006, 0.006, 6, mat::PAPER, mat::PAPER);
        }
        b.frustum(
            f.pt([-w / 2.0 + 0.2, 2.45, -0.08]),
            [1.0, 0.0, 0.0],
            w - 0.4,
            0.05,
            0.05,
            16,
            mat::HOUSING,
            mat::PLASTIC,
        );
    }

    /// A wall clock on the back wall at (x, y).
    fn clock(&mut self, room: &Room, x: f64, y: f64) {
        let f = Frame::at([x, y, room.d]);
        let b = &mut self.b;
        b.frustum(f.pt([0.0; 3]), [0.0, 0.0, -1.0], 0.04, 0.15, 0.15, 24, mat::PLASTIC, mat::PAPER);
        b.lbox(&f, [-0.006, -0.01, -0.05], [0.006, 0.11, -0.043], mat::PLASTIC);
        b.lbox(&f, [-0.01, -0.006, -0.05], [0.08, 0.006, -0.043], mat::PLASTIC);
    }

    /// Coat hooks on a rail along a wall.
    fn coat_rail(&mut self, room: &Room, wall: Wall, u0: f64, n: usize) {
        let len = 0.3 * n as f64;
        let (f, u0, _) = Self::wall_local(room, wall, u0, u0 + len);
        let b = &mut self.b;
        b.lbox(&f, [u0, 1.55, -0.02], [u0 + len, 1.65, 0.0], mat::WOOD);
        for i in 0..n {
            let u = u0 + 0.15 + 0.3 * i as f64;
            b.frustum(f.pt([u, 1.6, -0.02]), f.dir([0.0, 0.4, -1.0]), 0.09, 0.008, 0.008, 6, mat::METAL, mat::METAL);
        }
    }

    /// A poster (a thin board) on a wall.
    #[allow(clippy::too_many_arguments)]
    fn poster(&mut self, room: &Room, wall: Wall, u0: f64, u1: f64, v0: f64, v1: f64, m: u16) {
        let (f, u0, u1) = Self::wall_local(room, wall, u0, u1);
        self.b.lbox(&f, [u0, v0, -0.01], [u1, v1, 0.0], m);
    }
}

// ---------------------------------------------------------------------------------------------
// The three scenes.

fn bureau1(s: &mut Scene) -> Room {
    let mut room = Room { w: 4.5, h: 2.7, d: 4.0, openings: vec![] };
    // Desk against the back wall with a CRT, keyboard, lamp; the chair in front of it.
    let desk = Frame::at([1.6, 0.0, room.d - 0.75]);
    s.office_desk(&desk, 1.5, 0.75, 0.74);
    s.crt(&desk.at_local([0.15, 0.74, 0.25]));
    s.keyboard(&desk.at_local([0.1, 0.74, 0.05]));
    s.desk_lamp(&desk.at_local([-0.55, 0.74, 0.45]));
    for i in 0..4 {
        let m = mat::BOOK0 + i as u16;
        s.b.lbox(&desk, [0.5, 0.74 + i as f64 * 0.02, 0.1 + i as f64 * 0.01], [0.72, 0.759 + i as f64 * 0.02, 0.4], m);
    }
    let chair = Frame::quarter([1.75, 0.0, room.d - 1.2], 2).child([0.0; 3], 0.25);
    s.office_chair(&chair);
    // Bookshelf on the back wall, right of the desk.
    s.bookshelf(&Frame::at([3.35, 0.0, room.d - 0.32]), 1.0, 1.9, 0.32, 5);
    // Filing cabinet against the right wall (front facing −x).
    s.cabinet(&Frame::quarter([room.w - 0.62, 0.0, 1.6], 1), 1.32, 4);
    s.bin(&Frame::at([0.6, 0.0, room.d - 0.5]));
    s.plant(&Frame::at([0.45, 0.0, 1.0]), 1.25);
    s.window(&mut room, Wall::Left, 1.2, 2.8, 0.95, 2.2);
    s.radiator(&room, Wall::Left, 1.35, 2.65, 0.85);
    s.door(&mut room, Wall::Right, 2.6, 3.5);
    s.poster(&room, Wall::Back, 0.25, 0.8, 1.3, 2.0, mat::BOOK0 + 3);
    s.fixture(&room, 2.25, 2.0, 1.25, 0.35, 0.35);
    room
}

fn bureau2(s: &mut Scene) -> Room {
    let mut room = Room { w: 7.0, h: 2.8, d: 5.5, openings: vec![] };
    // Two workstations against the back wall.
    for (x, q) in [(1.3, 0.2), (3.6, -0.3)] {
        let desk = Frame::at([x, 0.0, room.d - 0.8]);
        s.office_desk(&desk, 1.6, 0.8, 0.74);
        s.crt(&desk.at_local([0.2, 0.74, 0.3]));
        s.keyboard(&desk.at_local([0.15, 0.74, 0.06]));
        s.desk_lamp(&desk.at_local([-0.6, 0.74, 0.5]));
        s.office_chair(&Frame::quarter([x + 0.2, 0.0, room.d - 1.3], 2).child([0.0; 3], q));
    }
    // A third desk against the left wall (facing +x), with its chair.
    let desk = Frame::quarter([0.8, 0.0, 2.5], 3);
    s.office_desk(&desk, 1.6, 0.8, 0.74);
    s.keyboard(&desk.at_local([0.1, 0.74, 0.1]));
    s.crt(&desk.at_local([0.1, 0.74, 0.35]));
    s.office_chair(&Frame::quarter([1.35, 0.0, 2.4], 1).child([0.0; 3], 0.15));
    // Meeting table with four chairs.
    let (tx, tz) = (4.6, 2.0);
    s.round_table(&Frame::at([tx, 0.0, tz]), 0.6, 0.73);
    for k in 0..4 {
        let a = 0.4 + k as f64 * std::f64::consts::FRAC_PI_2;
        let (sa, ca) = a.sin_cos();
        let p = [tx + 0.85 * sa, 0.0, tz - 0.85 * ca];
        // Chair front faces the table centre.
        let f = Frame::at(p).child([0.0; 3], -a + std::f64::consts::PI + s.rng.range(-0.2, 0.2));
        s.office_chair(&f);
    }
    // Two bookshelves on the back wall, filing cabinets, printer.
    s.bookshelf(&Frame::at([5.35, 0.0, room.d - 0.35]), 1.0, 2.0, 0.35, 5);
    s.bookshelf(&Frame::at([6.4, 0.0, room.d - 0.35]), 1.0, 2.0, 0.35, 5);
    s.cabinet(&Frame::quarter([room.w - 0.62, 0.0, 1.2], 1), 1.32, 4);
    s.cabinet(&Frame::quarter([room.w - 0.62, 0.0, 1.7], 1), 1.0, 3);
    s.printer_table(&Frame::quarter([room.w - 0.5, 0.0, 3.3], 1));
    s.bin(&Frame::at([2.5, 0.0, room.d - 0.4]));
    s.bin(&Frame::at([1.0, 0.0, 1.4]));
    s.plant(&Frame::at([0.5, 0.0, 0.3]), 1.4);
    s.plant(&Frame::at([6.5, 0.0, 0.6]), 1.1);
    s.coat_stand(&Frame::at([6.6, 0.0, 4.3]));
    s.window(&mut room, Wall::Left, 3.5, 5.0, 0.95, 2.3);
    s.window(&mut room, Wall::Left, 0.5, 1.6, 0.95, 2.3);
    s.radiator(&room, Wall::Left, 3.65, 4.85, 0.85);
    s.door(&mut room, Wall::Right, 4.0, 4.9);
    s.poster(&room, Wall::Right, 2.2, 3.0, 1.2, 2.0, mat::BOOK0 + 2);
    s.poster(&room, Wall::Back, 2.3, 3.0, 1.3, 2.1, mat::BOOK0);
    s.clock(&room, 0.9, 2.3);
    // Two large fixtures.
    s.fixture(&room, 2.2, 3.3, 1.5, 0.6, 0.3);
    s.fixture(&room, 4.8, 2.2, 1.5, 0.6, 0.3);
    room
}

fn classe(s: &mut Scene) -> Room {
    let mut room = Room { w: 11.0, h: 3.2, d: 9.0, openings: vec![] };
    // 5 rows × 4 columns of two-seat pupil desks facing the blackboard (+z), chairs behind.
    let cols = [1.7, 4.2, 6.8, 9.3];
    for r in 0..5 {
        let z = 1.2 + 1.25 * r as f64;
        for &x in &cols {
            let desk = Frame::at([x, 0.0, z]);
            s.pupil_desk(&desk, 1.3, 0.55, 0.72);
            for side in [-0.33, 0.33] {
                let jx = s.rng.range(-0.08, 0.08);
                let jz = s.rng.range(-0.12, 0.05);
                let ja = s.rng.range(-0.15, 0.15);
                let chair = Frame::quarter([x + side + jx, 0.0, z - 0.12 + jz], 2).child([0.0; 3], ja);
                s.school_chair(&chair);
            }
            // Exercise books on about half the desks.
            if s.rng.f() < 0.5 {
                let m = mat::BOOK0 + s.rng.below(mat::BOOKS as u64) as u16;
                let bx = x + s.rng.range(-0.5, 0.3);
                s.b.lbox(&Frame::at([bx, 0.72, z + 0.1]), [0.0; 3], [0.21, 0.012, 0.3], m);
            }
        }
    }
    // Teacher's platform, desk and chair; the blackboard behind.
    let py = 0.18;
    s.b.lbox(&Frame::at([5.5, 0.0, room.d - 2.0]), [-3.0, 0.0, 0.0], [3.0, py, 2.0], mat::WOOD_DARK);
    s.teacher_desk(&Frame::quarter([5.5, 0.0, room.d - 0.9], 2), py);
    s.office_chair(&Frame::at([5.6, py, room.d - 0.55]).child([0.0; 3], 0.2));
    s.blackboard(&room, 5.5, 4.0);
    s.clock(&room, 8.4, 2.5);
    s.projector_cart(&Frame::quarter([8.05, 0.0, room.d - 2.15], 2));
    // Bookshelves in the back corners, flanking the board (books run along x).
    s.bookshelf(&Frame::at([0.95, 0.0, room.d - 0.35]), 1.2, 2.0, 0.35, 5);
    s.bookshelf(&Frame::at([10.05, 0.0, room.d - 0.35]), 1.2, 2.0, 0.35, 5);
    // Left wall: four windows with radiators.
    for k in 0..4 {
        let u0 = 0.8 + 2.0 * k as f64;
        s.window(&mut room, Wall::Left, u0, u0 + 1.4, 1.0, 2.6);
        s.radiator(&room, Wall::Left, u0 + 0.1, u0 + 1.3, 0.9);
    }
    // Right wall: door at the front, coat rail, cupboards, posters.
    s.door(&mut room, Wall::Right, 0.6, 1.5);
    s.coat_rail(&room, Wall::Right, 2.0, 8);
    s.cupboard(&Frame::quarter([room.w - 0.5, 0.0, 5.6], 1), 1.2, 2.0, 0.5);
    s.cupboard(&Frame::quarter([room.w - 0.5, 0.0, 6.9], 1), 1.2, 2.0, 0.5);
    s.poster(&room, Wall::Right, 4.45, 4.9, 1.2, 1.9, mat::BOOK0 + 4);
    s.poster(&room, Wall::Back, 1.8, 3.0, 1.0, 1.8, mat::BOOK0 + 1);
    s.bin(&Frame::at([room.w - 0.4, 0.0, 1.9]));
    s.bin(&Frame::at([2.9, py, room.d - 0.6]));
    s.plant(&Frame::at([0.5, 0.0, room.d - 1.0]), 1.2);
    // 26 flush ceiling fixtures in a staggered grid: rows of 7 and 6.
    for (r, z) in [1.1, 3.35, 5.6, 7.85].into_iter().enumerate() {
        let n = if r % 2 == 0 { 7 } else { 6 };
        for k in 0..n {
            let x = if n == 7 { 0.85 + 1.55 * k as f64 } else { 1.625 + 1.55 * k as f64 };
            s.fixture(&room, x, z, 1.2, 0.3, 0.0);
        }
    }
    room
}

/// Build a scene, with what checks need.
pub fn build(kind: Kind) -> Office {
    let seed = match kind {
        Kind::Bureau1 => 0x0B0E_A001,
        Kind::Bureau2 => 0x0B0E_A002,
        Kind::Classe => 0x0C1A_55E0,
    };
    let patch = match kind {
        Kind::Bureau1 => 0.12,
        Kind::Bureau2 => 0.15,
        Kind::Classe => 0.25,
    };
    let mut s = Scene { b: Builder { patch, ..Default::default() }, rng: Rng(seed), lights: vec![] };
    let room = match kind {
        Kind::Bureau1 => bureau1(&mut s),
        Kind::Bureau2 => bureau2(&mut s),
        Kind::Classe => classe(&mut s),
    };
    // The room's tile size: the one that brings the total closest to the thesis's count.
    let target = kind.target_facets();
    let furniture = s.b.faces.len();
    let tile = (0..=1900)
        .map(|i| 0.05 + i as f64 * 0.0005)
        .min_by_key(|&t| (furniture + room.count(t)).abs_diff(target))
        .expect("non-empty range");
    let mut all = Builder { patch, ..Default::default() };
    room.build(&mut all, tile);
    let room_faces = all.faces.len();
    all.append(s.b);
    let mesh = Mesh {
        name: kind.name().into(),
        positions: all.positions,
        faces: all.faces,
        materials: materials(),
        lights: s.lights.into_iter().map(SceneLight::world).collect(),
        // Built wound as `orient` says: closed solids outward, the open room inward.
        rewound: 0,
        screen: None,
        normals: Vec::new(),
        face_normals: Vec::new(),
    };
    Office {
        mesh,
        room: Aabb { lo: [0.0; 3], hi: [room.w, room.h, room.d] },
        solids: all.solids,
        orient: all.orient,
        tile,
        room_faces,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::machine::loading::engines::{voxelize, Engine};
    use crate::precompute::LoadConfig;

    #[test]
    fn facet_and_light_counts_match_the_thesis() {
        for k in Kind::ALL {
            let o = build(k);
            let f = o.mesh.faces.len();
            let t = k.target_facets();
            eprintln!(
                "{}: {f} facets (target {t}, {:+.2} %), {} room tiles of {:.3} m, {} furniture faces, {} solids, {} vertices, {} lights",
                k.name(),
                100.0 * (f as f64 - t as f64) / t as f64,
                o.room_faces,
                o.tile,
                f - o.room_faces,
                o.solids.len(),
                o.mesh.positions.len(),
                o.mesh.lights.len()
            );
            assert!(f.abs_diff(t) * 100 <= t, "{}: {f} facets, target {t} ± 1 %", k.name());
            assert_eq!(o.mesh.lights.len(), k.lights(), "{}", k.name());
            assert_eq!(o.orient.len(), f);
            // Furniture, not just tiles: at least a third of the faces.
            assert!(f - o.room_faces > f / 3, "{}: {} furniture faces of {f}", k.name(), f - o.room_faces);
        }
    }

    #[test]
    fn faces_are_planar_convex_non_degenerate_and_oriented() {
        for k in Kind::ALL {
            let o = build(k);
            let m = &o.mesh;
            assert!(m.positions.iter().all(|p| p.iter().all(|c| c.is_finite())));
            assert!(m.materials.iter().any(|x| x.ke.iter().any(|&e| e > 0.0)), "an emitter material");
            assert!(m.materials.iter().filter(|x| x.ks[0] > 0.0 && (20.0..=60.0).contains(&x.ns)).count() >= 2);
            for (fi, f) in m.faces.iter().enumerate() {
                let p: Vec<V> = f.verts.iter().map(|&v| V::from(m.positions[v as usize])).collect();
                assert!(p.len() == 3 || p.len() == 4, "{} face {fi}: {} vertices", k.name(), p.len());
                assert!((f.material as usize) < m.materials.len() && f.material != 0);
                let diam = p.iter().flat_map(|a| p.iter().map(move |b| (*a - *b).length())).fold(0.0, f64::max);
                for i in 0..p.len() {
                    let e = (p[(i + 1) % p.len()] - p[i]).length();
                    assert!(e > 1e-4, "{} face {fi}: edge of {e} m", k.name());
                }
                let n = (p[1] - p[0]).cross(p[2] - p[0]);
                assert!(n.length() > 1e-6 * diam * diam, "{} face {fi}: degenerate", k.name());
                let nu = n.normalize();
                for q in &p[3..] {
                    let off = nu.dot(*q - p[0]).abs();
                    assert!(off <= 1e-9 * diam, "{} face {fi}: vertex {off:e} off the plane", k.name());
                }
                // Convex, all turns agreeing with the normal.
                for i in 0..p.len() {
                    let (a, b, c) = (p[i], p[(i + 1) % p.len()], p[(i + 2) % p.len()]);
                    assert!((b - a).cross(c - b).dot(nu) > 0.0, "{} face {fi}: not strictly convex", k.name());
                }
                let centroid = p.iter().fold(V::ZERO, |s, &q| s + q) * (1.0 / p.len() as f64);
                let away = match o.orient[fi] {
                    Orient::Outward(c) => centroid - V::from(c),
                    Orient::Inward(c) => V::from(c) - centroid,
                };
                assert!(nu.dot(away) > 0.0, "{} face {fi}: normal {nu:?} points the wrong way", k.name());
                for q in &p {
                    assert!(o.room.contains(q.to_array()), "{} face {fi}: vertex {q:?} outside the room", k.name());
                }
            }
            // The room surfaces face into the room.
            assert!(o.orient[..o.room_faces].iter().all(|x| matches!(x, Orient::Inward(_))));
        }
    }

    #[test]
    fn lights_are_in_free_space_below_fixtures() {
        for k in Kind::ALL {
            let o = build(k);
            for (i, l) in o.mesh.lights.iter().enumerate() {
                let crate::scene::LightAt::World(p) = l.at else { panic!("world lights") };
                assert!(o.room.contains(p), "{} light {i} outside the room", k.name());
                for ((c, lo), hi) in p.iter().zip(o.room.lo).zip(o.room.hi) {
                    let gap = (c - lo).min(hi - c);
                    assert!(gap >= 0.02, "{} light {i}: {gap} m from a room surface", k.name());
                }
                for s in &o.solids {
                    assert!(
                        s.distance(p) >= 0.02 - 1e-12,
                        "{} light {i} at {p:?}: {} m from solid {s:?}",
                        k.name(),
                        s.distance(p)
                    );
                }
                // Just below an emitter: the nearest solid above is within 5 cm.
                let above = o
                    .solids
                    .iter()
                    .filter(|s| s.lo[1] > p[1] && s.contains([p[0], s.lo[1], p[2]]))
                    .map(|s| s.lo[1] - p[1])
                    .fold(f64::INFINITY, f64::min);
                assert!(above <= 0.05, "{} light {i}: nearest surface above at {above} m", k.name());
            }
        }
    }

    #[test]
    fn generation_is_deterministic() {
        for k in Kind::ALL {
            let (a, b) = (build(k).mesh, build(k).mesh);
            assert_eq!(a.positions, b.positions);
            assert_eq!(a.faces, b.faces);
            assert_eq!(a.materials, b.materials);
            assert_eq!(a.lights, b.lights);
        }
        assert!(generate("bureau3").is_err());
        assert_eq!(crate::scene::load("classe").unwrap().faces.len(), build(Kind::Classe).mesh.faces.len());
    }

    #[test]
    fn voxelizes_at_64_and_fits_the_dexel_store_at_128() {
        for k in Kind::ALL {
            let mesh = build(k).mesh;
            let v = voxelize::<64>(&mesh, &LoadConfig::watertight(64), Engine::Direct, |_, _| {}).unwrap();
            v.check_overflow().unwrap();
            let v = voxelize::<64>(&mesh, &LoadConfig::watertight(128), Engine::Direct, |_, _| {}).unwrap();
            eprintln!(
                "{}: n = 128: {} packets, {} skipped, {} split, dexels max {} mean/occupied {:.2}",
                k.name(),
                v.stats.facets,
                v.stats.facets_skipped,
                v.stats.polygons_split,
                v.stats.grid.dexels_max_per_cell,
                v.stats.grid.dexels_mean_per_occupied_cell
            );
            v.check_overflow().unwrap();
        }
    }
}
