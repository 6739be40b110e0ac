//! s × s samples per pixel on the grid (`cell_core::subpixel`, `render --samples S`).
//!
//! During loading a sampling cell also tests each packet at its S × S sample points and keeps,
//! per sample, the nearest facet's record ([`cell_core::visible::depth_test`]); the packets
//! carry their y slopes ([`cell_core::subpixel::RowSlopes`]) and reach one column and one row
//! more around their box ([`cell_core::subpixel::sampled_box`]). The records are a function of
//! the packets each column receives and of their order alone, so the host simulator computes
//! them after loading from the same packets at the same columns (as the smooth records are,
//! [`super::smooth_surface`]), the loading engines untouched; what the cells would spend on it
//! is counted in [`SampleStats`]. Lighting is the run's own. After it, each cell sends its
//! neighbours what its centre shows and which lights reached it ([`cell_core::subpixel::Shown`],
//! one message per link, one cycle), and shades the mean of its samples
//! ([`cell_core::subpixel::sample_reached`], [`cell_core::subpixel::mean_pixel`]).

use anyhow::{bail, Result};
use cell_core::light::SourceMask;
use cell_core::shade::{NormalMode, PointLight, ShadeParams};
use cell_core::subpixel::{
    mean_pixel, sample_colour, sample_lights, sampled_box, RowSlopes, Sample, SampleLights, Shown, MAX_SAMPLED_N,
    MAX_SAMPLES, NEIGHBOURS,
};
use cell_core::visible::VisibleSurface;

use super::pixels::{cell_material, eye_lights, ref_lights, weigh_lights, Image, AMBIENT};
use crate::machine::loading::loaded_scene::LoadedScene;
use crate::machine::loading::wave::row_packet_at;
use crate::precompute::LoadConfig;
use crate::scene::Mesh;

/// What the samples cost the cells and what they found, for `render --stats`.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct SampleStats {
    /// Samples per pixel side, S.
    pub samples_per_side: u32,
    /// Samples per pixel, S².
    pub samples_per_pixel: u32,
    /// How a sample takes its lights: "nearest" or "bilinear".
    pub lights: String,
    /// Bytes a cell adds: S² sample records and its 8 neighbours' messages.
    pub bytes_per_cell: usize,
    /// Most bytes a row packet adds (the y slopes of its plane and edges).
    pub bytes_per_packet: usize,
    /// Row steps (one packet processed by one row cell, and the message that brought it)
    /// loading adds: the packets reach one column and one row more around their boxes.
    pub load_extra_row_steps: u64,
    /// Loading cycles added, at most: the last packet's one more pipeline step and one more
    /// row step.
    pub load_extra_cycles_at_most: u64,
    /// Messages of the exchange after lighting (a cell that shows a surface tells each of its
    /// neighbours).
    pub exchange_messages: u64,
    /// Bytes of one.
    pub exchange_bytes_per_message: usize,
    /// Cycles of the exchange (one message per link, all links at once).
    pub exchange_cycles: u64,
    /// Samples that show a surface other than their cell's centre's facet (or a surface where
    /// the centre shows none, or none where it shows one).
    pub foreign_samples: u64,
    /// Pixels with at least one such sample.
    pub mixed_pixels: u64,
    /// Sample hits beyond the bit budget (not kept; 0 within `MAX_SAMPLED_N`).
    pub overflows: u64,
}

/// The cells' sample records: `surfaces[(y·n + x)·S² + j·S + i]` for sample (i, j) of column
/// (x, y) (`None`: its line meets no facet).
pub struct SampleGrid {
    /// Samples per side.
    pub s: u32,
    /// How a sample takes its lights from the cells around it.
    pub lights: SampleLights,
    /// Per cell, per sample.
    pub surfaces: Vec<Option<VisibleSurface>>,
    /// The statistics of loading (those of the exchange and the foreign samples come with
    /// [`shade_samples`]).
    pub stats: SampleStats,
}

/// Check S and the grid before any work.
pub fn check_samples(s: u32, n: u32) -> Result<()> {
    if !(1..=MAX_SAMPLES).contains(&s) {
        bail!("--samples {s}: between 1 and {MAX_SAMPLES} samples per pixel side");
    }
    if s > 1 && n > MAX_SAMPLED_N {
        bail!("--samples {s} at n = {n}: the samples' depths fit a cell's 64-bit record up to n = {MAX_SAMPLED_N}");
    }
    Ok(())
}

/// The sample records of `scene`, loaded with `load` from `mesh`, at S × S samples per pixel.
pub fn sample_grid(
    mesh: &Mesh,
    scene: &LoadedScene,
    load: &LoadConfig,
    s: u32,
    lights: SampleLights,
) -> Result<SampleGrid> {
    let (n, depth) = (scene.grid.n, scene.grid.depth);
    check_samples(s, n)?;
    let per = (s * s) as usize;
    let mut surfaces = vec![None; n as usize * n as usize * per];
    let mut stats = SampleStats {
        samples_per_side: s,
        samples_per_pixel: s * s,
        lights: match lights {
            SampleLights::Nearest => "nearest".into(),
            SampleLights::Bilinear => "bilinear".into(),
        },
        load_extra_cycles_at_most: 2,
        exchange_bytes_per_message: Shown::BYTES,
        exchange_cycles: 1,
        ..SampleStats::default()
    };
    if mesh.faces.is_empty() {
        return Ok(SampleGrid { s, lights, surfaces, stats });
    }
    let packets = crate::precompute::prepare(mesh, load)?.packets;
    let samples: Vec<Sample> = Sample::all(s).collect();
    for p in &packets {
        let slopes = RowSlopes::of(p);
        stats.bytes_per_packet = stats.bytes_per_packet.max(slopes.bytes());
        let (own, b) = (p.bbox, sampled_box(p.bbox, n));
        // A row runs from column 0 to its box's last column.
        let steps = |rows: u16, last: u16| (rows as u64 + 1) * (last as u64 + 1);
        stats.load_extra_row_steps += steps(b.y_max - b.y_min, b.x_max) - steps(own.y_max - own.y_min, own.x_max);
        let mut rp = p.to_row();
        for y in b.y_min as i64..=b.y_max as i64 {
            for x in b.x_min as i64..=b.x_max as i64 {
                row_packet_at(p, &mut rp, x, y);
                let cell = (y as usize * n as usize + x as usize) * per;
                for (k, &at) in samples.iter().enumerate() {
                    match cell_core::subpixel::surface_at(&rp, &slopes, at, depth) {
                        Ok(found) => cell_core::visible::depth_test(&mut surfaces[cell + k], found),
                        Err(cell_core::subpixel::DepthOverflow) => stats.overflows += 1,
                    }
                }
            }
        }
    }
    stats.bytes_per_cell = per * std::mem::size_of::<VisibleSurface>() + NEIGHBOURS.len() * Shown::BYTES;
    Ok(SampleGrid { s, lights, surfaces, stats })
}

/// The lights the cells' centres hold after lighting, which they lend their neighbours' samples.
pub enum CentreLights<'a> {
    /// The lit mask of column (x, y)'s visible surface.
    Masks(&'a dyn Fn(u32, u32) -> SourceMask),
    /// Each light's weight (0 ..= 255) at column (x, y): the lit-ray ratio
    /// ([`cell_core::visibility`]).
    Weights(&'a dyn Fn(u32, u32) -> Vec<u8>),
}

impl CentreLights<'_> {
    /// Column (x, y)'s lights as weights (a mask's lights 255, the others 0).
    fn weights(&self, x: u32, y: u32) -> [u8; 32] {
        match self {
            CentreLights::Masks(m) => {
                let m = m(x, y);
                std::array::from_fn(|s| if m >> s & 1 == 1 { 255 } else { 0 })
            }
            CentreLights::Weights(w) => {
                let w = w(x, y);
                std::array::from_fn(|s| w.get(s).copied().unwrap_or(0))
            }
        }
    }

    /// Bytes of a cell's message to its neighbours with `lights` lights.
    fn message_bytes(&self, lights: usize) -> usize {
        match self {
            CentreLights::Masks(_) => Shown::BYTES,
            CentreLights::Weights(_) => Shown::HEADER_BYTES + lights,
        }
    }
}

/// What shading a cell's samples reads besides the cell: the scene's materials (the cells'
/// and the f64 formula's), the lights in the shading space and the shading parameters.
struct ShadeCtx<'a> {
    materials: &'a [crate::scene::Material],
    mats: Vec<cell_core::shade::Material>,
    lights: &'a [PointLight],
    params: ShadeParams,
    lender: SampleLights,
}

/// One cell's samples shaded: the pixel, the same in f64, and how many samples show another
/// surface than the centre's.
struct CellSamples {
    rgb: [u8; 3],
    f64_rgb: [u8; 3],
    foreign: u64,
}

impl ShadeCtx<'_> {
    /// The mean of column (x, y)'s samples `records` (at `samples`), lit by the lights the cell
    /// (`own`) and its neighbours (`around`) lend them.
    fn cell(
        &self,
        (x, y): (u32, u32),
        samples: &[Sample],
        records: &[Option<VisibleSurface>],
        own: Option<Shown<[u8; 32]>>,
        around: &[Option<Shown<[u8; 32]>>; 8],
    ) -> CellSamples {
        let (mut cell, mut exact, mut foreign) = (Vec::with_capacity(samples.len()), Vec::new(), 0);
        for (&smp, rec) in samples.iter().zip(records) {
            let Some(surface) = rec else {
                foreign += own.is_some() as u64;
                cell.push(None);
                exact.push(None);
                continue;
            };
            foreign += own.is_none_or(|o| o.facet != surface.facet) as u64;
            let (c, e) = self.sample(x, y, smp, surface, own, around);
            cell.push(Some(c));
            exact.push(Some(e));
        }
        CellSamples { rgb: mean_pixel(cell), f64_rgb: crate::truth::refrender::mean_colour(&exact), foreign }
    }

    /// Sample `smp`'s linear colour, in the cell's arithmetic and in f64 from the same inputs:
    /// the sum over its lenders of their lights' colour, weighed.
    fn sample(
        &self,
        x: u32,
        y: u32,
        smp: Sample,
        surface: &VisibleSurface,
        own: Option<Shown<[u8; 32]>>,
        around: &[Option<Shown<[u8; 32]>>; 8],
    ) -> ([f32; 3], [f64; 3]) {
        let [px, py] = smp.point(x, y);
        let (p, v) = self.params.eye.shading_point([px, py, surface.depth()]);
        let nrm = cell_core::shade::shading_normal_toward(surface.normal, self.params.normal_mode, v);
        let m = &self.materials[(surface.material as usize).min(self.materials.len() - 1)];
        let (mut colour, mut colour_f64) = ([0.0f32; 3], [0.0f64; 3]);
        for (weights, w) in sample_lights(own, around, surface, smp, self.lender) {
            // The lender's lights, each scaled by its weight (a mask's by 1 or 0).
            let (mask, scaled) = weigh_lights(self.lights, &weights[..self.lights.len().min(32)]);
            let (c, lit) = sample_colour((x, y), smp, surface, mask, &self.mats, &scaled, &self.params);
            let e = crate::truth::refrender::shade_linear_view_f64(
                p.map(f64::from),
                nrm.map(f64::from),
                v.map(f64::from),
                m,
                &ref_lights(&scaled),
                lit,
                [AMBIENT as f64; 3],
            );
            for k in 0..3 {
                colour[k] += w * c[k];
                colour_f64[k] += w as f64 * e[k];
            }
        }
        (colour, colour_f64)
    }
}

/// Shade every cell as the mean of its samples (see the module doc), the lights of column
/// (x, y)'s visible surface given by `centre`. The image's coverage and lit masks are the
/// centre line's (as without samples: the lit state is unchanged); its colours the samples'
/// mean. Also the grid's statistics with the exchange and the foreign samples.
pub fn shade_samples(
    mesh: &Mesh,
    scene: &LoadedScene,
    lights: &[PointLight],
    centre: &CentreLights<'_>,
    mode: NormalMode,
    grid: &SampleGrid,
) -> (Image, SampleStats) {
    let n = scene.grid.n;
    let ctx = ShadeCtx {
        materials: &mesh.materials,
        mats: mesh.materials.iter().map(cell_material).collect(),
        lights: &eye_lights(&scene.eye, lights),
        params: ShadeParams { ambient: [AMBIENT; 3], normal_mode: mode, eye: scene.eye },
        lender: grid.lights,
    };
    let npix = n as usize * n as usize;
    let mut img = Image {
        n,
        rgb: vec![[0; 3]; npix],
        covered: vec![false; npix],
        lit: vec![0; npix],
        shading_max_err_levels: 0,
        shading_mean_err_levels: 0.0,
    };
    // What each cell tells its neighbours.
    let shown: Vec<Option<Shown<[u8; 32]>>> = scene
        .grid
        .cells
        .iter()
        .map(|c| {
            let v = c.visible.as_ref()?;
            Some(Shown { facet: v.facet, normal: v.normal, reached: centre.weights(c.x as u32, c.y as u32) })
        })
        .collect();
    let inside = |(x, y): (i64, i64)| (0..n as i64).contains(&x) && (0..n as i64).contains(&y);
    let samples: Vec<Sample> = Sample::all(grid.s).collect();
    let per = samples.len();
    let (mut err_sum, mut foreign, mut mixed, mut messages) = (0u64, 0u64, 0u64, 0u64);
    for (i, c) in scene.grid.cells.iter().enumerate() {
        let (x, y) = (c.x as u32, c.y as u32);
        let next = |(dx, dy): (i32, i32)| (x as i64 + dx as i64, y as i64 + dy as i64);
        let around =
            NEIGHBOURS.map(|d| inside(next(d)).then(|| shown[(next(d).1 * n as i64 + next(d).0) as usize]).flatten());
        let own = shown[i];
        if own.is_some() {
            messages += NEIGHBOURS.iter().filter(|&&d| inside(next(d))).count() as u64;
        }
        let r = ctx.cell((x, y), &samples, &grid.surfaces[i * per..(i + 1) * per], own, &around);
        for k in 0..3 {
            let e = r.rgb[k].abs_diff(r.f64_rgb[k]);
            img.shading_max_err_levels = img.shading_max_err_levels.max(e);
            err_sum += e as u64;
        }
        (foreign, mixed) = (foreign + r.foreign, mixed + (r.foreign > 0) as u64);
        img.rgb[i] = r.rgb;
        if let (Some(v), Some(o)) = (c.visible.as_ref(), own) {
            let (mask, scaled) = weigh_lights(ctx.lights, &o.reached[..ctx.lights.len().min(32)]);
            let px = cell_core::shade::surface_pixel(c.x, c.y, v, mask, &ctx.mats, &scaled, &ctx.params);
            img.covered[i] = true;
            img.lit[i] = px.lit;
        }
    }
    img.shading_mean_err_levels = err_sum as f64 / (3 * npix).max(1) as f64;
    let message = centre.message_bytes(ctx.lights.len());
    let stats = SampleStats {
        bytes_per_cell: per * std::mem::size_of::<VisibleSurface>() + NEIGHBOURS.len() * message,
        exchange_messages: messages,
        exchange_bytes_per_message: message,
        foreign_samples: foreign,
        mixed_pixels: mixed,
        ..grid.stats.clone()
    };
    (img, stats)
}
