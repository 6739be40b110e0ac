//! The `light-accuracy` job: the lit state of surface voxels against exact f64 visibility, for
//! several grid sizes and fraction bits, against the lighting phase's run time (CSV).

use std::io::Write;
use std::path::PathBuf;

use anyhow::Result;
use cell_core::light::Policy;
use parry3d_f64::math::Vector;

use crate::machine::lighting::diffuse::{LightConfig, Lighting};
use crate::machine::lighting::run::{run_diffusion, LightStats};
use crate::machine::loading::loaded_scene::{load_scene, resolve_lights, voxel_to_world, LoadedScene};
use crate::precompute::LoadConfig;
use crate::report::files::create;
use crate::scene::Mesh;

/// What the `light-accuracy` job measures and writes.
#[derive(Clone, Debug)]
pub struct AccuracyOptions {
    /// An .obj file or a built-in scene name.
    pub scene: String,
    /// Grid sizes (watertight surfaces).
    pub n: Vec<u32>,
    /// Fraction bits f to compare.
    pub frac_bits: Vec<u32>,
    /// FIFO size.
    pub fa: usize,
    /// Scheduling policy (merging on for the policies that pick by layer).
    pub policy: Policy,
    /// The lit rule (exact occluders with rays from the light, the others from the source
    /// voxel: as the presets pair them).
    pub rule: cell_core::lit::LitRule,
    /// Lights at grid-normalised positions (empty: the scene's own).
    pub lights: Vec<[f64; 3]>,
    /// The point of each surface voxel whose f64 visibility the lit state is compared with.
    pub measure: Measure,
    /// Output CSV.
    pub out: PathBuf,
}

/// Where a surface voxel's f64 visibility is measured, along the exact segment from the light
/// to its centre (docs/LIGHTING.md, "The lit set").
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Measure {
    /// The centre, the voxel's own face ignored (the centre of a surface voxel often lies
    /// behind its own face).
    #[default]
    Centre,
    /// Where the segment enters the voxel's cube; no face ignored.
    Entry,
    /// One voxel before the centre along the segment's major axis: the previous layer's
    /// centre plane, up to which the machine's voxel ray must arrive unstopped for the voxel
    /// to be lit under exact occluders (`cell_core::receiver::voxel_ray`). No face ignored.
    Reach,
}

impl Measure {
    /// The CSV's name of the measure.
    pub fn name(self) -> &'static str {
        match self {
            Measure::Centre => "centre",
            Measure::Entry => "entry",
            Measure::Reach => "reach",
        }
    }

    /// The measured point of voxel `v` (centre at `v`, voxel units) for a light at `l` (voxel
    /// units), or `None` when the light is inside the voxel's cube (or, for `Reach`, within a
    /// voxel of the centre along the major axis): then the voxel's centre itself.
    fn point(self, v: [f64; 3], l: [f64; 3]) -> Option<[f64; 3]> {
        let d = [0, 1, 2].map(|i| v[i] - l[i]);
        let t = match self {
            Measure::Centre => return None,
            // The last of the slabs' entries.
            Measure::Entry => {
                (0..3).filter(|&i| d[i] != 0.0).map(|i| (v[i] - 0.5 * d[i].signum() - l[i]) / d[i]).fold(0.0, f64::max)
            }
            Measure::Reach => {
                let w = d.iter().map(|c| c.abs()).fold(0.0, f64::max);
                (w - 1.0) / w
            }
        };
        (t > 0.0 && t < 1.0).then(|| [0, 1, 2].map(|i| l[i] + t * d[i]))
    }
}

/// Run the `light-accuracy` job: one CSV row and one Markdown row (stderr) per n and f.
pub fn run(o: &AccuracyOptions) -> Result<()> {
    let mesh = crate::scene::load(&o.scene)?;
    let mut csv = create(&o.out)?;
    writeln!(csv, "scene,n,frac_bits,surface_voxels,lit_discrete,lit_continuous,false_lit,false_dark,disagreement_pct,cycles,lower_bound,beams_processed,wall_seconds,measure,grazing_voxels,grazing_disagreements,disagreement_pct_not_grazing")?;
    eprintln!("| n | f | surface voxels | false lit | false dark | disagreement % | cycles | beams | wall s |");
    eprintln!("|---|---|---|---|---|---|---|---|---|");
    let rays = if o.rule.is_exact() { cell_core::beam::Origin::Light } else { cell_core::beam::Origin::SourceVoxel };
    let lcfg = LightConfig {
        fa: o.fa,
        policy: o.policy,
        merge: o.policy.by_layer(),
        rule: o.rule,
        rays,
        ..crate::config::Preset::Light.light()
    };
    for &n in &o.n {
        let loaded = load_scene(&mesh, &LoadConfig::watertight(n))?;
        let lights = resolve_lights(&mesh, &loaded, &o.lights)?;
        for &f in &o.frac_bits {
            let (l, s) = run_diffusion(&mesh, &loaded, &lights, &LightConfig { frac_bits: f, ..lcfg }, |_, _| {})?;
            let acc = accuracy(&mesh, &loaded, &lights, &l, o.measure)?;
            write_row(&mut csv, &mesh.name, n, f, &acc, &s, o.measure)?;
        }
    }
    csv.flush()?;
    eprintln!("wrote {}", o.out.display());
    Ok(())
}

/// One row of the CSV and of the Markdown table.
fn write_row(
    csv: &mut impl Write,
    scene: &str,
    n: u32,
    f: u32,
    acc: &Accuracy,
    s: &LightStats,
    m: Measure,
) -> Result<()> {
    writeln!(
        csv,
        "{},{n},{f},{},{},{},{},{},{:.4},{},{},{},{:.4},{},{},{},{:.4}",
        scene,
        acc.surface_voxels,
        acc.lit_discrete,
        acc.lit_continuous,
        acc.false_lit,
        acc.false_dark,
        acc.disagreement_pct,
        s.totals.cycles,
        s.totals.lower_bound,
        s.totals.beams_processed,
        s.wall_seconds,
        m.name(),
        acc.grazing_voxels,
        acc.grazing_disagreements,
        acc.disagreement_pct_not_grazing
    )?;
    eprintln!(
        "| {n} | {f} | {} | {} | {} | {:.2} | {} | {} | {:.2} |",
        acc.surface_voxels,
        acc.false_lit,
        acc.false_dark,
        acc.disagreement_pct,
        s.totals.cycles,
        s.totals.beams_processed,
        s.wall_seconds
    );
    Ok(())
}

/// Lit state of surface voxels against exact continuous visibility (docs/LIGHTING.md, "light-accuracy").
///
/// A *surface voxel* for a light is an occupied voxel with an empty 6-neighbour whose centre
/// lies on the light's side of the voxel's own face (the face's plane separates them): the
/// voxels a beam from that light can enter first. Voxels of a thick wall's back layer are not
/// surface voxels for a light in front of it (their centres see the light only through their
/// own face, which the measure ignores).
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct Accuracy {
    /// Surface voxels, summed over lights.
    pub surface_voxels: u64,
    /// Of those, lit by beam diffusion.
    pub lit_discrete: u64,
    /// Of those, whose measured point ([`Measure`]) sees the light in the continuous scene.
    pub lit_continuous: u64,
    /// Lit by diffusion, dark in the continuous scene.
    pub false_lit: u64,
    /// Dark by diffusion, lit in the continuous scene.
    pub false_dark: u64,
    /// (false_lit + false_dark) / surface_voxels, in percent.
    pub disagreement_pct: f64,
    /// Surface voxels whose face the light grazes: it lies less than [`GRAZING_DEGREES`] from
    /// the face's plane (where a sixteenth of a voxel moves the shadow's edge by many voxels).
    pub grazing_voxels: u64,
    /// Of those, lit differently by diffusion and in f64.
    pub grazing_disagreements: u64,
    /// The disagreement over the other surface voxels, in percent.
    pub disagreement_pct_not_grazing: f64,
}

/// Below this angle between the light's direction and a face's plane, a surface voxel's light
/// is grazing ([`Accuracy::grazing_voxels`]).
pub const GRAZING_DEGREES: f64 = 15.0;

/// Compare the discrete lit state of every surface voxel with f64 visibility from each light
/// of the point `measure` names (docs/LIGHTING.md, "light-accuracy").
pub fn accuracy(
    mesh: &Mesh,
    scene: &LoadedScene,
    lights: &[[f64; 3]],
    lighting: &Lighting,
    measure: Measure,
) -> Result<Accuracy> {
    let (tris, ids) = crate::truth::refrender::mesh_triangles(mesh)?;
    let planes = face_planes(mesh);
    let reference = crate::truth::visibility::Reference::new(tris, ids)?;
    let world_lights: Vec<Vector> = lights.iter().map(|l| Vector::from(voxel_to_world(&scene.fit, *l))).collect();
    let mut a = Accuracy::default();
    for c in &scene.grid.cells {
        for d in c.store.dexels() {
            let face = scene.source_face.get(d.facet as usize).copied().unwrap_or(u32::MAX);
            let (nrm, o) = planes.get(face as usize).copied().unwrap_or((Vector::ZERO, Vector::ZERO));
            for z in d.span.lo..=d.span.hi {
                let v = [c.x as i64, c.y as i64, z as i64];
                let empty = empty_neighbours(scene, v);
                if empty.is_empty() {
                    continue;
                }
                let centre = voxel_to_world(&scene.fit, v.map(|k| k as f64));
                let mask = lighting.mask(c.x as u32, c.y as u32, z);
                for (si, l) in world_lights.iter().enumerate() {
                    // A surface voxel for this light: an empty neighbour on the light's side.
                    let side = nrm.dot(*l - o).signum();
                    if side == 0.0 || !empty.iter().any(|q| nrm.dot(*q - o).signum() == side) {
                        continue;
                    }
                    let seen = match measure.point(v.map(|k| k as f64), lights[si]) {
                        Some(p) => reference.visible(voxel_to_world(&scene.fit, p), l.to_array(), &[]),
                        None => reference.visible(centre, l.to_array(), &[face]),
                    };
                    let to_light = *l - Vector::from(centre);
                    let sine = nrm.dot(to_light).abs() / (nrm.length() * to_light.length());
                    a.count(mask >> si & 1 == 1, seen, sine < GRAZING_DEGREES.to_radians().sin());
                }
            }
        }
    }
    a.finish();
    Ok(a)
}

impl Accuracy {
    /// The percentages, from the counts.
    fn finish(&mut self) {
        let wrong = self.false_lit + self.false_dark;
        self.disagreement_pct = 100.0 * wrong as f64 / self.surface_voxels.max(1) as f64;
        let (rest, rest_wrong) = (self.surface_voxels - self.grazing_voxels, wrong - self.grazing_disagreements);
        self.disagreement_pct_not_grazing = 100.0 * rest_wrong as f64 / rest.max(1) as f64;
    }

    /// One surface voxel and light: lit by diffusion (`disc`), visible in f64 (`cont`), the
    /// light grazing its face or not.
    fn count(&mut self, disc: bool, cont: bool, grazing: bool) {
        self.surface_voxels += 1;
        self.grazing_voxels += grazing as u64;
        self.grazing_disagreements += (grazing && disc != cont) as u64;
        self.lit_discrete += disc as u64;
        self.lit_continuous += cont as u64;
        self.false_lit += (disc && !cont) as u64;
        self.false_dark += (!disc && cont) as u64;
    }
}

/// World centres of the empty 6-neighbours of voxel `v` (outside the grid counts as empty).
fn empty_neighbours(scene: &LoadedScene, v: [i64; 3]) -> Vec<Vector> {
    let g = &scene.grid;
    let n = g.n as i64;
    let occupied = |[x, y, z]: [i64; 3]| {
        (0..n).contains(&x)
            && (0..n).contains(&y)
            && (0..n).contains(&z)
            && g.cell(x as u32, y as u32).store.occupied(z as u16).is_some()
    };
    [[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]]
        .iter()
        .map(|d: &[i64; 3]| [v[0] + d[0], v[1] + d[1], v[2] + d[2]])
        .filter(|&q| !occupied(q))
        .map(|q| Vector::from(voxel_to_world(&scene.fit, q.map(|k| k as f64))))
        .collect()
}

/// Each face's plane: the normal of its first non-degenerate corner, and its first vertex.
fn face_planes(mesh: &Mesh) -> Vec<(Vector, Vector)> {
    mesh.faces
        .iter()
        .map(|f| {
            let p = |i: usize| Vector::from(mesh.positions[f.verts[i] as usize]);
            let o = p(0);
            let nrm = (2..f.verts.len()).map(|k| (p(k - 1) - o).cross(p(k) - o)).find(|c| c.dot(*c) > 0.0);
            (nrm.unwrap_or(Vector::ZERO), o)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::{Accuracy, Measure};

    #[test]
    fn grazing_voxels_are_counted_apart() {
        let mut a = Accuracy::default();
        // (lit by diffusion, visible in f64, grazing)
        for (d, c, g) in
            [(true, true, false), (true, false, false), (false, false, false), (false, true, true), (true, true, true)]
        {
            a.count(d, c, g);
        }
        a.finish();
        assert_eq!((a.surface_voxels, a.false_lit, a.false_dark), (5, 1, 1));
        assert_eq!((a.grazing_voxels, a.grazing_disagreements), (2, 1));
        assert_eq!(a.disagreement_pct, 40.0);
        assert!((a.disagreement_pct_not_grazing - 100.0 / 3.0).abs() < 1e-12);
    }

    fn close(a: [f64; 3], b: [f64; 3]) -> bool {
        a.iter().zip(b).all(|(x, y)| (x - y).abs() < 1e-12)
    }

    #[test]
    fn the_measured_points_on_hand_worked_segments() {
        let (v, l) = ([10.0, 3.0, 0.0], [0.0; 3]);
        // Entry: the x slab is entered last, at t = 9.5 / 10.
        assert!(close(Measure::Entry.point(v, l).unwrap(), [9.5, 2.85, 0.0]));
        // Reach: one voxel back along x, the major axis.
        assert!(close(Measure::Reach.point(v, l).unwrap(), [9.0, 2.7, 0.0]));
        assert!(close(Measure::Reach.point([0.0, -5.0, 1.0], [0.0, 5.0, 1.0]).unwrap(), [0.0, -4.0, 1.0]));
        assert_eq!(Measure::Centre.point(v, l), None);
        // A light inside the voxel, or within a voxel of it along the major axis.
        assert_eq!(Measure::Entry.point(v, [10.2, 3.4, -0.1]), None);
        assert_eq!(Measure::Reach.point(v, [9.5, 3.0, 0.0]), None);
    }

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig::with_cases(10_000))]
        /// The entry point lies on the cube's boundary, the segment just before it outside the
        /// cube and just after it inside; a light inside the cube has none.
        #[test]
        fn the_entry_point_is_where_the_segment_meets_the_voxel(
            v in proptest::array::uniform3(0i32..40),
            l in proptest::array::uniform3(-0.3f64..39.7),
        ) {
            let v = v.map(f64::from);
            let inside = |p: [f64; 3]| (0..3).all(|i| (p[i] - v[i]).abs() <= 0.5);
            match Measure::Entry.point(v, l) {
                None => proptest::prop_assert!(inside(l), "{l:?} outside {v:?} has an entry"),
                Some(p) => {
                    let edge = (0..3).map(|i| (p[i] - v[i]).abs()).fold(0.0, f64::max);
                    proptest::prop_assert!((edge - 0.5).abs() < 1e-9, "{p:?} not on the boundary of {v:?}");
                    let at = |t: f64| [0, 1, 2].map(|i| p[i] + t * (v[i] - l[i]));
                    let len = (0..3).map(|i| (v[i] - l[i]).powi(2)).sum::<f64>().sqrt();
                    proptest::prop_assert!(!inside(at(-1e-6 / len)) && inside(at(1e-6 / len)), "{l:?} → {v:?}: {p:?}");
                }
            }
        }
    }
}
