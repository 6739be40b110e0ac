//! `host-sim form-factors`: the projective form-factor methods of the radiosity thesis
//! (ch. 2, [`crate::truth::projective`]); `--tables` computes §2.5's Tables 2.1–2.3 from each
//! method's own surface, prints them beside the published values and writes them as CSV;
//! `--ray-traced` compares ch. 3's rays and beam toward the source ([`super::ray_traced`]).

use std::io::Write;
use std::path::PathBuf;

use anyhow::{bail, Result};

use parry3d_f64::math::Vector;

use crate::report::files::create;
use crate::scene::{Face, Material, Mesh};
use crate::truth::closed_form::point_to_polygon;
use crate::truth::projective::figure::{FigurePoint, DISTANCES, FACETS};
use crate::truth::projective::{figure, tables};

/// Options of the `form-factors` job.
#[derive(Clone, Debug, Default)]
pub struct FormFactorsOptions {
    /// Compute and print Tables 2.1–2.3.
    pub tables: bool,
    /// Write the tables as CSV here.
    pub csv: Option<PathBuf>,
    /// Draw §2.5.4's comparison (Fig. 2.18) into this PNG.
    pub figure: Option<PathBuf>,
    /// Write the figure's points as CSV here.
    pub figure_csv: Option<PathBuf>,
    /// Compare the ray-traced form factors (ch. 3, Tables 3.2–3.3) on these scenes.
    pub ray_traced: Option<super::ray_traced::RayTracedOptions>,
}

/// The hemicube resolutions of the figure's x axis: every even R from 16 to 96.
fn figure_resolutions() -> Vec<u32> {
    (16..=96).step_by(2).collect()
}

/// Run the job: the tables, printed, and the CSV if asked; the figure if asked.
pub fn run(o: &FormFactorsOptions) -> Result<()> {
    if !o.tables && o.figure.is_none() && o.ray_traced.is_none() {
        bail!("form-factors: nothing to do (pass --tables, --figure F.png or --ray-traced SCENE)");
    }
    if o.tables {
        run_tables(o)?;
    }
    if let Some(png) = &o.figure {
        run_figure(png, o.figure_csv.as_deref())?;
    }
    if let Some(r) = &o.ray_traced {
        super::ray_traced::run(r)?;
    }
    Ok(())
}

/// §2.5.4's figure: computed, drawn, and its points written as CSV if asked.
fn run_figure(png: &std::path::Path, csv: Option<&std::path::Path>) -> Result<()> {
    let mut file = csv.map(create).transpose()?;
    // The picture's file too, before any work: a path that cannot be written fails first.
    drop(create(png)?);
    let mut points = figure::compute(&figure_resolutions())?;
    points.extend(beam_points(&figure_resolutions())?);
    crate::report::ff_figure::plot_figure(&points, png)?;
    eprintln!("figure written to {}", png.display());
    if let (Some(f), Some(path)) = (file.as_mut(), csv) {
        f.write_all(figure::csv(&points).as_bytes())?;
        f.flush()?;
        eprintln!("figure points written to {}", path.display());
    }
    Ok(())
}

/// The tables, printed, and the CSV if asked.
fn run_tables(o: &FormFactorsOptions) -> Result<()> {
    // The file first, so that a path that cannot be written fails before any work.
    let mut file = o.csv.as_ref().map(|p| create(p)).transpose()?;
    let mut cells = tables::compute()?;
    cells.extend(beam_cells()?);
    print!("{}", tables::render(&cells));
    let published = cells.iter().filter(|c| !c.published.is_empty()).count();
    let off: Vec<String> =
        cells.iter().filter(|c| !c.agrees).map(|c| format!("{} {} {}", c.table, c.row, c.method)).collect();
    println!(
        "{} of {} published cells within one unit of the published last digit; disagreeing: {}",
        published - off.len(),
        published,
        if off.is_empty() { "none".into() } else { off.join(", ") }
    );
    if let (Some(f), Some(path)) = (file.as_mut(), &o.csv) {
        f.write_all(tables::csv(&cells).as_bytes())?;
        f.flush()?;
        eprintln!("written to {}", path.display());
    }
    Ok(())
}

/// The figure's scene for the grid: a small emitting square at the origin facing +z (the
/// differential area) and the four squares at `distance` facing it.
fn figure_mesh(distance: f64) -> Mesh {
    let e = 0.01;
    let emitter = [[-e, -e, 0.0], [e, -e, 0.0], [e, e, 0.0], [-e, e, 0.0]];
    let squares = figure::squares(distance).map(|c| [c[3], c[2], c[1], c[0]].map(|v| v.to_array()));
    let mut m = Mesh { name: format!("fig-2.17-at-{distance}"), ..Default::default() };
    m.materials = vec![
        Material { name: "emitter".into(), ke: [1.0; 3], ..Material::default() },
        Material { name: "grey".into(), kd: [0.5; 3], ..Material::default() },
    ];
    for (k, quad) in std::iter::once(emitter).chain(squares).enumerate() {
        let base = m.positions.len() as u32;
        m.positions.extend(quad);
        m.faces.push(Face { verts: (base..base + 4).collect(), material: u16::from(k > 0) });
    }
    m
}

/// The grid's beam shot in the figure: for the hemicube resolution R, the grid at the far
/// distance equivalent to it ([`beam_far_equivalent`]), facets 1 and 4 ([`beam_shot`]).
pub fn beam_points(rs: &[u32]) -> Result<Vec<FigurePoint>> {
    let mut out = Vec::new();
    for &r in rs {
        let n = beam_far_equivalent(r)? + 1;
        for distance in DISTANCES {
            let shot = beam_shot(distance, n)?;
            for facet in FACETS {
                out.push(FigurePoint {
                    distance,
                    facet,
                    method: "beams",
                    hemicube_r: r,
                    resolution: n.to_string(),
                    computed: shot.computed[facet - 1],
                    exact: shot.exact[facet - 1],
                });
            }
        }
    }
    Ok(out)
}

/// The grid's shot on the figure's four squares at `distance`, grid side `n`.
#[derive(Clone, Debug)]
pub struct BeamShot {
    /// Each square's form factor: quanta its voxels received over those emitted.
    pub computed: [f64; 4],
    /// Each square's exact form factor from the shot's apex (Eq. 2.2).
    pub exact: [f64; 4],
    /// The voxel's side, world units.
    pub voxel: f64,
    /// The shot's apex, world units.
    pub apex: [f64; 3],
}

/// The small square at the origin (`figure_mesh`) shoots once, `radiosity`'s machine shot
/// (the thesis's lit rule, its source pushed off the patch), on the figure's scene loaded at
/// grid side `n`.
pub fn beam_shot(distance: f64, n: u32) -> Result<BeamShot> {
    use crate::machine::shooting::shots::{shot_form_factors, RadiosityConfig};
    let mesh = figure_mesh(distance);
    let scene =
        crate::machine::loading::loaded_scene::load_scene(&mesh, &crate::precompute::LoadConfig::watertight(n))?;
    let patches = crate::scene::patches::subdivide(&mesh, 1e9, 16)?;
    let cfg = RadiosityConfig::new(crate::config::plane_rule(), 0.0, 1);
    let patch_of = |face: usize| patches.patches.iter().position(|p| p.face == face).expect("one patch per face");
    let (ff, source) =
        shot_form_factors(&scene.grid, &scene.fit, &scene.source_face, &patches.patches, patch_of(0), &cfg)?;
    // Every ray reaching the squares is one of the +z face's: they leave from the source voxel's
    // centre plane in z, from the source's position in x and y.
    let pos = source.pos.map(|c| c.to_num::<f64>());
    let v = [pos[0], pos[1], f64::from(source.voxel()[2])];
    let apex = Vector::from(crate::machine::loading::loaded_scene::voxel_to_world(&scene.fit, v));
    let sq = figure::squares(distance);
    Ok(BeamShot {
        computed: std::array::from_fn(|k| ff[patch_of(k + 1)]),
        exact: std::array::from_fn(|k| point_to_polygon(apex, Vector::Z, &sq[k], Vector::NEG_Z)),
        voxel: scene.fit.voxel,
        apex: apex.to_array(),
    })
}

/// The far distance D of the grid whose shot is as fine as a hemicube of resolution `r`, by
/// Table 2.1's criterion (§2.5.2): the smallest D whose largest delta form factor is at most the
/// hemicube's largest. A shot gives each lattice ray the cosine-weighted solid angle of a unit
/// square of its face at distance D (`cell_core::radiosity`): a hemicube with proxels at the far
/// plane, its largest the central ray's square, centred on the axis ([`central_ray_ff`]; f = 0,
/// the grid side is n = D + 1).
pub fn beam_far_equivalent(r: u32) -> Result<u32> {
    use crate::truth::projective::{hemicube::Hemicube, ProjectionSurface};
    let reference = Hemicube::new(r)?.largest_delta_ff();
    tables::smallest(reference, (r / 2).max(1), 1, |d| Ok(central_ray_ff(d)))
}

/// The delta form factor of a shot's central lattice ray at far distance `d`: the exact form
/// factor (Eq. 2.2) of the unit square centred on the axis at distance d, as the hemicube's
/// FFEs are exact integrals over their proxels.
pub fn central_ray_ff(d: u32) -> f64 {
    let (h, z) = (0.5, f64::from(d));
    let square = [Vector::new(-h, -h, z), Vector::new(h, -h, z), Vector::new(h, h, z), Vector::new(-h, h, z)];
    point_to_polygon(Vector::ZERO, Vector::Z, &square, Vector::NEG_Z)
}

/// The lattice rays a shot from a patch facing an axis carries quanta on, at far distance d
/// (f = 0): the whole front face, (2d + 1)², and the front half of each of the four side faces,
/// horizon row included (half its square is in front), (2d + 1)(d + 1) each.
pub fn beam_rays(d: u64) -> u64 {
    (2 * d + 1) * (2 * d + 1) + 4 * (2 * d + 1) * (d + 1)
}

/// The grid's beam shot in Tables 2.1–2.3 (nothing published: the thesis has no such method),
/// at each row's equivalent far distance D ([`beam_far_equivalent`]):
/// * 2.1: the grid side n = D + 1;
/// * 2.2: the rays carrying quanta ([`beam_rays`]), against the projective surfaces' proxels;
/// * 2.3: the memory the cells add for radiosity ([`bytes_per_cell_added`] per cell, over the
///   n² cells), against one projection surface's.
///
/// [`bytes_per_cell_added`]: crate::machine::shooting::shots::bytes_per_cell_added
pub fn beam_cells() -> Result<Vec<tables::Cell>> {
    let bytes = crate::machine::shooting::shots::bytes_per_cell_added() as f64;
    let mut out = Vec::new();
    for (i, &r) in tables::ROWS.iter().enumerate() {
        let d = u64::from(beam_far_equivalent(r)?);
        let n = d + 1;
        let cell = |table, reference: String, computed: String| tables::Cell {
            table,
            reference,
            row: r,
            method: "beams",
            computed,
            published: String::new(),
            agrees: true,
        };
        out.push(cell("2.1", tables::TABLE_2_1[i].0.to_string(), n.to_string()));
        out.push(cell("2.2", r.to_string(), beam_rays(d).to_string()));
        out.push(cell("2.3", r.to_string(), format!("{:.2}", (n * n) as f64 * bytes / 1e6)));
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use cell_core::beam::Direction;
    use cell_core::radiosity::{corner_quanta, FORM_FACTOR_ONE};

    /// [`beam_rays`] is the number of lattice rays the cells' own quanta
    /// (`cell_core::radiosity::corner_quanta`, inclusion–exclusion per ray) give a positive
    /// share to, for a patch facing +z; and the quanta of all rays add up to one form factor:
    /// a face's rays telescope to its whole-face corner, one f32 contour integral rounded to
    /// quanta, so each face is off by at most half a quantum plus its f32 error (taken as 8
    /// roundings of 2⁻²⁴ relative: four atan2 terms and their sum, on a value ≤ 1).
    #[test]
    fn beam_rays_are_the_rays_the_cells_give_quanta() {
        let n = [0.0f32, 0.0, 1.0];
        for d in 2u32..=9 {
            let (mut rays, mut total) = (0u64, 0i64);
            for dir in Direction::ALL {
                let c = |a: i64, b: i64| corner_quanta(n, dir, d, 0, a, b);
                for u in -(d as i64)..=d as i64 {
                    for v in -(d as i64)..=d as i64 {
                        let q = c(2 * u + 1, 2 * v + 1) - c(2 * u - 1, 2 * v + 1) - c(2 * u + 1, 2 * v - 1)
                            + c(2 * u - 1, 2 * v - 1);
                        rays += u64::from(q > 0);
                        total += q;
                    }
                }
            }
            assert_eq!(rays, beam_rays(u64::from(d)), "d = {d}");
            let per_face = 0.5 + 8.0 * FORM_FACTOR_ONE as f64 / (1u64 << 24) as f64;
            let off = (total - FORM_FACTOR_ONE).abs() as f64;
            assert!(off <= 6.0 * per_face, "d = {d}: {total} quanta for one form factor");
        }
    }

    /// The equivalent far distance is the smallest with a largest delta form factor at most the
    /// hemicube's; the central ray sits on the axis where the hemicube's largest proxel is half
    /// a proxel off it, so D is R/2 or R/2 + 1, never further.
    #[test]
    fn beam_far_equivalent_is_the_smallest_as_fine_as_the_hemicube() {
        use crate::truth::projective::{hemicube::Hemicube, ProjectionSurface};
        for r in [16, 18, 64, 96].into_iter().chain(tables::ROWS) {
            let d = beam_far_equivalent(r).unwrap();
            let reference = Hemicube::new(r).unwrap().largest_delta_ff();
            let ff = |d: u32| 1.0 / (std::f64::consts::PI * f64::from(d).powi(2));
            // The exact square's factor against the point formula it tends to.
            assert!((central_ray_ff(d) / ff(d) - 1.0).abs() < 1.0 / f64::from(d * d), "R = {r}: D = {d}");
            assert!(
                central_ray_ff(d) <= reference * (1.0 + 1e-12) && central_ray_ff(d - 1) > reference,
                "R = {r}: D = {d}"
            );
            assert!(d == r / 2 || d == r / 2 + 1, "R = {r}: D = {d}");
        }
    }

    /// The grid's shot on the figure's squares. Together the four squares are the block
    /// [−0.43, 0.57] × [−0.46, 0.54] (no shared edge inside), so what they receive is bounded by
    /// exact form factors from the shot's apex: at least the block's shrunk by one ray spacing
    /// (a ray whose lattice square reaches into the block may miss it; rays are at most one
    /// voxel apart at the squares, nearer than the far plane), at most the block's grown by
    /// that spacing and the conservative contour's dilation, a voxel's in-plane diagonal
    /// (√2 voxels). A single square can also win its neighbours' voxels along a shared edge, so
    /// squares are checked for convergence only: the mean relative error falls from the
    /// resolution equivalent to a hemicube of 16 to that of 64, as the projective methods' do.
    #[test]
    fn the_grids_shot_on_the_figures_squares_converges_within_the_voxel_bound() {
        let block = |d: f64, apex: Vector, grow: f64| {
            let (x0, x1, y0, y1) = (-0.43 - grow, 0.57 + grow, -0.46 - grow, 0.54 + grow);
            let rect = [Vector::new(x0, y0, d), Vector::new(x1, y0, d), Vector::new(x1, y1, d), Vector::new(x0, y1, d)];
            point_to_polygon(apex, Vector::Z, &rect, Vector::NEG_Z)
        };
        let mut mean = Vec::new();
        for r in [16, 64] {
            let n = beam_far_equivalent(r).unwrap() + 1;
            let mut err = 0.0;
            for distance in DISTANCES {
                let s = beam_shot(distance, n).unwrap();
                let apex = Vector::from(s.apex);
                let got: f64 = s.computed.iter().sum();
                let lo = block(distance, apex, -s.voxel);
                let hi = block(distance, apex, (1.0 + std::f64::consts::SQRT_2) * s.voxel);
                assert!(lo <= got && got <= hi, "R = {r}, distance {distance}: {got} not in [{lo}, {hi}]: {s:?}");
                err += (0..4).map(|k| (s.computed[k] / s.exact[k] - 1.0).abs()).sum::<f64>();
            }
            mean.push(err / (4 * DISTANCES.len()) as f64);
        }
        assert!(mean[1] < mean[0], "mean relative error {} at 64 against {} at 16", mean[1], mean[0]);
        let points = beam_points(&[16]).unwrap();
        assert_eq!(points.len(), DISTANCES.len() * FACETS.len());
    }
}
