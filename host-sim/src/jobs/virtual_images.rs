//! Thesis §5.5.4 reproduced: a point source's rays reflected by a voxelized mirror, with the
//! cell's own arithmetic (`cell_core::reflect`: the walk, the hit point of `--hit`, the mirror
//! of `--reflect-normal`).
//!
//! A flat square mirror, tilted by `--tilt` degrees about y so that it voxelizes as a staircase,
//! faces a point source S. Each ray from S toward a point of a mirror column (`--rays-per-voxel`
//! k × k points a column) walks the grid to the first occupied voxel, is mirrored there as a
//! cell mirrors it, and leaves from its hit point. Continuous geometry reflects every such ray
//! through one point, S′ (S mirrored about the plane: "les rayons réfléchis semblent provenir
//! d'un point virtuel unique"); the discrete ones pass near it, a **cloud** (§5.5.4 cases 2 and
//! 3). For each reflected line the job takes its closest approach to S′ (voxels): the cloud's
//! spread. A **screen** between the source and the mirror (the plane z = `SCREEN_Z`, one cell per
//! voxel) counts the reflected rays that cross it: the cells of the mirror's continuous
//! footprint (seen from S′) that no discrete ray reaches are the **dark zone** ("une zone d'ombre
//! vers laquelle aucun rayon n'est réfléchi"), set beside the same rays reflected exactly at their
//! exact hit points (what sampling alone leaves dark).

use std::path::PathBuf;

use anyhow::{bail, Result};
use cell_core::ray::{Connectivity, Q};
use cell_core::reflect::{
    hit_point, reflected_dir, scaled, walk_start, HitPoint, Incident, ReflectNormal, ReflectRay, ReflectStep,
};

use crate::machine::loading::loaded_scene::{load_scene, world_to_voxel, LoadedScene};
use crate::precompute::LoadConfig;
use crate::report::files::create;

/// Where the screen lies (world z; the source is at 0.1, the mirror's centre at 0.6).
pub const SCREEN_Z: f64 = 0.35;
/// The mirror's centre and half side (world units, the unit cube).
const CENTRE: [f64; 3] = [0.5, 0.5, 0.6];
const HALF: f64 = 0.3;
/// The source (world).
const SOURCE: [f64; 3] = [0.5, 0.5, 0.1];

/// What to run.
#[derive(Clone, Debug)]
pub struct VirtualImagesOptions {
    /// Grid side.
    pub n: u32,
    /// Where reflected rays leave their voxel (§5.3).
    pub hit: HitPoint,
    /// The normal that mirrors them (§5.2).
    pub normal: ReflectNormal,
    /// Connectivity of the rays' walks.
    pub connectivity: Connectivity,
    /// Mirror tilt about y (degrees).
    pub tilt_deg: f64,
    /// Rays per mirror column: k × k points of the column's voxel.
    pub rays_per_voxel: u32,
    /// The picture: the cloud around S′ (left) and the screen (right).
    pub out: PathBuf,
    /// One CSV line of figures, if asked.
    pub csv: Option<PathBuf>,
}

/// The figures of a run.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct VirtualImages {
    /// Rays emitted from S.
    pub rays: u64,
    /// Rays that hit the mirror and reflected (a degenerate mirror direction does not).
    pub reflected: u64,
    /// Closest approach of the reflected lines to S′ (voxels): mean, root mean square, largest.
    pub spread_mean: f64,
    /// See `spread_mean`.
    pub spread_rms: f64,
    /// See `spread_mean`.
    pub spread_max: f64,
    /// Share of the reflected lines passing within one voxel of S′.
    pub within_one_voxel: f64,
    /// Screen cells of the mirror's continuous footprint.
    pub footprint_cells: u64,
    /// Of those, the share no discrete reflected ray reaches (%).
    pub dark_pct: f64,
    /// The same with the rays reflected exactly at their exact hit points (%).
    pub dark_continuous_pct: f64,
}

/// The mirror's in-plane axes and its normal (toward the source), world.
fn frame(tilt_deg: f64) -> ([f64; 3], [f64; 3], [f64; 3]) {
    let t = tilt_deg.to_radians();
    let u = [t.cos(), 0.0, t.sin()];
    let v = [0.0, 1.0, 0.0];
    (u, v, [t.sin(), 0.0, -t.cos()])
}

fn add(a: [f64; 3], b: [f64; 3], s: f64) -> [f64; 3] {
    [a[0] + s * b[0], a[1] + s * b[1], a[2] + s * b[2]]
}

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// The scene: the mirror (two triangles wound toward the source) and two tiny frame triangles at
/// the unit cube's corners, which fix the fit.
fn scene_obj(tilt_deg: f64) -> String {
    let (u, v, _) = frame(tilt_deg);
    let c = |a: f64, b: f64| add(add(CENTRE, u, a * HALF), v, b * HALF);
    let [p0, p1, p2, p3] = [c(-1.0, -1.0), c(1.0, -1.0), c(1.0, 1.0), c(-1.0, 1.0)];
    let mut s = String::from("mtllib mirror.mtl\n");
    for p in [p0, p1, p2, p3] {
        s += &format!("v {} {} {}\n", p[0], p[1], p[2]);
    }
    s += "v 0 0 0\nv 0.01 0 0\nv 0 0.01 0\nv 1 1 1\nv 0.99 1 1\nv 1 0.99 1\n";
    // Wound 1 4 3 and 1 3 2: the normal (p3 − p0) × (p2 − p0) = v × u faces −z, the source.
    s += "usemtl mirror\nf 1 4 3\nf 1 3 2\nusemtl frame\nf 5 6 7\nf 8 9 10\n";
    s
}

/// Run the experiment and write its picture (and CSV line).
pub fn run(o: &VirtualImagesOptions) -> Result<VirtualImages> {
    let r = measure(o)?;
    if let Some(p) = &o.csv {
        use std::io::Write;
        let mut f = create(p)?;
        writeln!(f, "n,hit,normal,connectivity,tilt_deg,rays_per_voxel,rays,reflected,spread_mean_voxels,spread_rms_voxels,spread_max_voxels,within_one_voxel,footprint_cells,dark_pct,dark_continuous_pct")?;
        writeln!(
            f,
            "{},{:?},{:?},{},{},{},{},{},{:.4},{:.4},{:.4},{:.4},{},{:.2},{:.2}",
            o.n,
            o.hit,
            o.normal,
            o.connectivity.k(),
            o.tilt_deg,
            o.rays_per_voxel,
            r.rays,
            r.reflected,
            r.spread_mean,
            r.spread_rms,
            r.spread_max,
            r.within_one_voxel,
            r.footprint_cells,
            r.dark_pct,
            r.dark_continuous_pct
        )?;
    }
    Ok(r)
}

/// The experiment (see the module doc); writes the picture to `o.out`.
pub fn measure(o: &VirtualImagesOptions) -> Result<VirtualImages> {
    validate(o)?;
    let mesh = crate::scene::load_obj_bytes(
        "mirror",
        scene_obj(o.tilt_deg).as_bytes(),
        Some(b"newmtl mirror\nKd 0.1 0.1 0.1\nKr 0.9\nnewmtl frame\nKd 0.5 0.5 0.5\n"),
    )?;
    let s = load_scene(&mesh, &LoadConfig::watertight(o.n))?;
    let mirror = mesh.materials.iter().position(|m| m.name == "mirror").unwrap_or(0) as u16;
    let g = Geometry::new(&s, o.tilt_deg);
    let traced = reflect_rays(o, &s, mirror, &g)?;
    let footprint = footprint(&g);
    let r = summarise(&traced, &footprint);
    picture(o, &traced.cloud, &traced.counts, &footprint)?;
    Ok(r)
}

/// Refuse what the experiment cannot run.
fn validate(o: &VirtualImagesOptions) -> Result<()> {
    if !(8..=512).contains(&o.n) {
        bail!("--n must be within 8 ..= 512 (got {})", o.n);
    }
    if !(0.0..=60.0).contains(&o.tilt_deg) {
        bail!("--tilt must be within 0 ..= 60 degrees (got {})", o.tilt_deg);
    }
    if !(1..=8).contains(&o.rays_per_voxel) {
        bail!("--rays-per-voxel must be within 1 ..= 8 (got {})", o.rays_per_voxel);
    }
    Ok(())
}

/// The experiment's points and planes in the rays' lattice (voxel v's centre at Q·v).
struct Geometry {
    n: u32,
    /// The source, and its lattice point.
    src: [f64; 3],
    src_i: [i32; 3],
    /// S′, the source mirrored about the continuous mirror.
    image: [f64; 3],
    /// The mirror's centre, in-plane axes, normal (toward the source) and half side.
    centre: [f64; 3],
    u: [f64; 3],
    v: [f64; 3],
    normal: [f64; 3],
    half: f64,
    /// The screen plane's z.
    screen_z: f64,
}

impl Geometry {
    fn new(s: &LoadedScene, tilt_deg: f64) -> Self {
        let lat = |w: [f64; 3]| world_to_voxel(&s.fit, w).map(|c| c * Q as f64);
        let (u, v, normal) = frame(tilt_deg);
        let src = lat(SOURCE);
        let image = lat(add(SOURCE, normal, -2.0 * dot(sub(SOURCE, CENTRE), normal)));
        Geometry {
            n: s.grid.n,
            src,
            src_i: src.map(|c| c.round() as i32),
            image,
            centre: lat(CENTRE),
            u,
            v,
            normal,
            half: HALF / s.fit.voxel * Q as f64,
            screen_z: lat([0.0, 0.0, SCREEN_Z])[2],
        }
    }

    /// The screen cell (index y·n + x) where a line from `a` along `d` crosses the screen plane
    /// going toward it, if inside the grid.
    fn on_screen(&self, a: [f64; 3], d: [f64; 3]) -> Option<usize> {
        let t = (self.screen_z - a[2]) / d[2];
        if d[2] == 0.0 || t <= 0.0 {
            return None;
        }
        let (q, n) = (Q as f64, self.n);
        let p = add(a, d, t);
        let (x, y) = ((p[0] / q + 0.5).floor(), (p[1] / q + 0.5).floor());
        (x >= 0.0 && y >= 0.0 && x < n as f64 && y < n as f64).then(|| (y as u32 * n + x as u32) as usize)
    }
}

/// What the reflected rays did.
struct Traced {
    rays: u64,
    /// Per reflected ray: its closest approach to S′ (voxels), and that point in the mirror's
    /// (u, v) axes relative to S′.
    spreads: Vec<f64>,
    cloud: Vec<[f64; 2]>,
    /// Rays per screen cell: the discrete reflected rays, and the same rays reflected exactly.
    counts: Vec<u32>,
    exact_counts: Vec<u32>,
}

/// Walk the source's rays to the mirror, reflect each as a cell does, and follow it back.
fn reflect_rays(o: &VirtualImagesOptions, s: &LoadedScene, mirror: u16, g: &Geometry) -> Result<Traced> {
    let (n, depth) = (s.grid.n, s.grid.depth);
    let span = 2 * Q * n.max(depth) as i32;
    let q = Q as f64;
    let mut t = Traced {
        rays: 0,
        spreads: Vec::new(),
        cloud: Vec::new(),
        counts: vec![0; (n * n) as usize],
        exact_counts: vec![0; (n * n) as usize],
    };
    let k = o.rays_per_voxel as i32;
    for c in &s.grid.cells {
        let Some(d0) = c.store.dexels().first() else { continue };
        if d0.material != mirror {
            continue;
        }
        for (i, j) in (0..k).flat_map(|i| (0..k).map(move |j| (i, j))) {
            // A point of the column's first voxel: k × k sub-positions in x and y.
            let off = |m: i32| (2 * m + 1) * Q / (2 * k) - Q / 2;
            let target = [c.x as i32 * Q + off(i), c.y as i32 * Q + off(j), d0.span.lo as i32 * Q];
            let Some(dir) = scaled([0, 1, 2].map(|a| (target[a] - g.src_i[a]) as i64), span) else { continue };
            t.rays += 1;
            let mut ray = ReflectRay::leaving(g.src_i, dir, o.connectivity, [0, 0], 0, u32::MAX, 1, 1.0)
                .map_err(|e| anyhow::anyhow!("a ray from the source cannot be walked: {e:?}"))?;
            let Some((h, at)) = first_hit(&mut ray, s).filter(|(h, _)| h.material == mirror) else { continue };
            let inc = Incident::of(&ray);
            let Some(r) = reflected_dir(inc.dir, inc.entry, h.normal, o.normal, span) else { continue };
            let from = walk_start(hit_point(at, &inc, &h.plane, h.span.lo, o.hit), r, at, o.connectivity);
            let (a, rd) = (from.map(f64::from), r.map(f64::from));
            // Closest approach of the line a + t·rd to S′.
            let p = add(a, rd, dot(sub(g.image, a), rd) / dot(rd, rd));
            let w = sub(p, g.image).map(|c| c / q);
            t.spreads.push(dot(w, w).sqrt());
            t.cloud.push([dot(w, g.u), dot(w, g.v)]);
            if let Some(cell) = g.on_screen(a, rd) {
                t.counts[cell] += 1;
            }
            // The continuous ray: S → target meets the plane at X, reflected through S′.
            let sd = sub(target.map(f64::from), g.src);
            let xp = add(g.src, sd, dot(sub(g.centre, g.src), g.normal) / dot(sd, g.normal));
            if let Some(cell) = g.on_screen(xp, sub(xp, g.image)) {
                t.exact_counts[cell] += 1;
            }
        }
    }
    Ok(t)
}

/// The first occupied voxel `ray` meets (its dexel and voxel), walking the grid as the cells
/// do; `None` when it leaves the grid.
fn first_hit(ray: &mut ReflectRay, s: &LoadedScene) -> Option<(cell_core::dexel::Dexel, [u16; 3])> {
    let (n, depth) = (s.grid.n, s.grid.depth);
    loop {
        let w = ray.line.voxel();
        if w[0] < 0 || w[1] < 0 || w[0] >= n as i32 || w[1] >= n as i32 {
            return None;
        }
        match ray.advance(&s.grid.cell(w[0] as u32, w[1] as u32).store, n, depth, false) {
            ReflectStep::Hit(h, z) => return Some((h, [w[0] as u16, w[1] as u16, z])),
            ReflectStep::Exit => return None,
            _ => {}
        }
    }
}

/// The mirror's continuous footprint: the screen cells whose line to S′ crosses the mirror
/// square.
fn footprint(g: &Geometry) -> Vec<bool> {
    let (n, q) = (g.n, Q as f64);
    (0..n * n)
        .map(|idx| {
            let p = [(idx % n) as f64 * q, (idx / n) as f64 * q, g.screen_z];
            let d = sub(p, g.image);
            let t = dot(sub(g.centre, g.image), g.normal) / dot(d, g.normal);
            let rel = sub(add(g.image, d, t), g.centre);
            t > 0.0 && dot(rel, g.u).abs() < g.half && dot(rel, g.v).abs() < g.half
        })
        .collect()
}

/// The figures of the traced rays against the footprint.
fn summarise(t: &Traced, footprint: &[bool]) -> VirtualImages {
    let fp = footprint.iter().filter(|&&f| f).count() as u64;
    let dark =
        |cs: &[u32]| 100.0 * footprint.iter().zip(cs).filter(|(&f, &c)| f && c == 0).count() as f64 / fp.max(1) as f64;
    let spreads = &t.spreads;
    let m = spreads.len().max(1) as f64;
    VirtualImages {
        rays: t.rays,
        reflected: spreads.len() as u64,
        spread_mean: spreads.iter().sum::<f64>() / m,
        spread_rms: (spreads.iter().map(|x| x * x).sum::<f64>() / m).sqrt(),
        spread_max: spreads.iter().cloned().fold(0.0, f64::max),
        within_one_voxel: spreads.iter().filter(|&&x| x <= 1.0).count() as f64 / m,
        footprint_cells: fp,
        dark_pct: dark(&t.counts),
        dark_continuous_pct: dark(&t.exact_counts),
    }
}

/// Side of the cloud panel: ±`CLOUD_VOXELS` voxels around S′, `CLOUD_PX` pixels a voxel.
const CLOUD_VOXELS: f64 = 4.0;
const CLOUD_PX: f64 = 32.0;

/// The picture: left, the reflected lines' closest points to S′ in the mirror's (u, v) axes
/// (white dots on black; the cross is S′, the grid lines one voxel apart); right, the screen:
/// the rays per cell (grey), the footprint's cells no ray reached in red.
fn picture(o: &VirtualImagesOptions, cloud: &[[f64; 2]], counts: &[u32], footprint: &[bool]) -> Result<()> {
    let side = (2.0 * CLOUD_VOXELS * CLOUD_PX) as usize;
    let n = (counts.len() as f64).sqrt() as usize;
    let scale = side / n.max(1);
    let (w, h) = (2 * side + 8, side);
    let mut px = vec![[255u8; 3]; w * h];
    for y in 0..side {
        for x in 0..side {
            let grid = |c: usize| c % CLOUD_PX as usize == 0;
            px[y * w + x] = if grid(x) || grid(y) { [40, 40, 40] } else { [0, 0, 0] };
            if x == side / 2 || y == side / 2 {
                px[y * w + x] = [0, 90, 160];
            }
        }
    }
    for p in cloud {
        let (x, y) = ((p[0] + CLOUD_VOXELS) * CLOUD_PX, (CLOUD_VOXELS - p[1]) * CLOUD_PX);
        if x >= 0.0 && y >= 0.0 && (x as usize) < side && (y as usize) < side {
            px[y as usize * w + x as usize] = [255, 255, 255];
        }
    }
    let most = counts.iter().copied().max().unwrap_or(1).max(1) as f64;
    for y in 0..(n * scale).min(h) {
        for x in 0..(n * scale).min(side) {
            let i = (n - 1 - y / scale) * n + x / scale;
            let c = counts[i];
            px[y * w + side + 8 + x] = if footprint[i] && c == 0 {
                [200, 30, 30]
            } else {
                let g = (40.0 + 215.0 * (c as f64 / most).sqrt()) as u8;
                if c == 0 {
                    [0, 0, 0]
                } else {
                    [g, g, g]
                }
            };
        }
    }
    crate::report::png::write_png_rect(&o.out, w as u32, h as u32, &px)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn opts(n: u32, hit: HitPoint, normal: ReflectNormal, tilt_deg: f64) -> VirtualImagesOptions {
        let out =
            std::env::temp_dir().join(format!("rc2-vi-{}-{n}-{hit:?}-{normal:?}-{tilt_deg}.png", std::process::id()));
        VirtualImagesOptions {
            n,
            hit,
            normal,
            connectivity: Connectivity::Six,
            tilt_deg,
            rays_per_voxel: 2,
            out,
            csv: None,
        }
    }

    /// A mirror parallel to the grid's faces: its normal and plane are exact in the dexel, so
    /// the exact hit (§5.3.3) leaves each reflected ray on the continuous one but for the
    /// lattice's rounding and the clamp into the hit voxel, while the centre (§5.3.2) moves it
    /// by up to half a voxel on each axis: the exact rule's virtual images lie at least twice as
    /// close to S′. Two rays a column, the footprint magnified about 1.4× from the mirror: the
    /// same rays reflected exactly reach every footprint cell.
    #[test]
    fn exact_hits_image_the_source_closer_than_the_centre_rule() {
        let exact = measure(&opts(32, HitPoint::Exact, ReflectNormal::Facet, 0.0)).unwrap();
        let centre = measure(&opts(32, HitPoint::Centre, ReflectNormal::Facet, 0.0)).unwrap();
        assert!(exact.reflected > 1000 && exact.reflected == centre.reflected, "{exact:?} {centre:?}");
        assert!(2.0 * exact.spread_mean < centre.spread_mean, "{exact:?} {centre:?}");
        assert_eq!(exact.dark_continuous_pct, 0.0, "{exact:?}");
    }

    /// On a tilted (staircase) mirror the face flip mirrors about the voxels' faces, not the
    /// mirror: the virtual images scatter far from S′ (§5.5.4), while facet normals with the
    /// exact hit keep them within about a voxel.
    #[test]
    fn the_face_flip_scatters_the_virtual_images_of_a_tilted_mirror() {
        let face = measure(&opts(32, HitPoint::Centre, ReflectNormal::Face, 20.0)).unwrap();
        let exact = measure(&opts(32, HitPoint::Exact, ReflectNormal::Facet, 20.0)).unwrap();
        assert!(face.spread_mean > 5.0 * exact.spread_mean && exact.spread_mean < 1.0, "{face:?} {exact:?}");
        assert!(
            measure(&VirtualImagesOptions { n: 4, ..opts(32, HitPoint::Exact, ReflectNormal::Facet, 20.0) }).is_err()
        );
    }
}
