//! The camera (thesis §1.3, the geometry stage): a scene seen through an orthographic or
//! perspective camera lands on the pixels an independent projection predicts, and its shadows
//! are the exact ones. The projection here is written out again from the camera's definition
//! (look-at basis, x toward the image's left; s = x/(w·z) + ½ in perspective, x/W + ½ in
//! orthographic), not taken from `host_sim::scene::camera`.

use cell_core::shade::NormalMode;
use host_sim::jobs::render::{render, RenderConfig, RenderInput};
use host_sim::machine::loading::loaded_scene::{load_scene, resolve_lights};
use host_sim::machine::shading::pixels::Image;
use host_sim::precompute::LoadConfig;
use host_sim::scene::camera::{to_screen, Camera, Projection};
use host_sim::scene::{Face, Material, Mesh, SceneLight};

type V = [f64; 3];

fn sub(a: V, b: V) -> V {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
fn dot(a: V, b: V) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
fn cross(a: V, b: V) -> V {
    [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
}
fn unit(a: V) -> V {
    let l = dot(a, a).sqrt();
    a.map(|c| c / l)
}

/// The camera's projection, independently: world point → pixel coordinates (x, y) in 0 ..= n.
struct Projector {
    eye: V,
    basis: [V; 3],
    /// Perspective: 2·tan(fov/2); orthographic: the view width.
    width: f64,
    perspective: bool,
    n: f64,
}

impl Projector {
    fn new(cam: &Camera, n: u32) -> Projector {
        let fwd = unit(sub(cam.look_at, cam.eye));
        let left = unit(cross(cam.up, fwd));
        let (width, perspective) = match cam.projection {
            Projection::Perspective { fov_deg } => (2.0 * (fov_deg.to_radians() / 2.0).tan(), true),
            Projection::Ortho { width } => (width, false),
        };
        Projector { eye: cam.eye, basis: [left, cross(fwd, left), fwd], width, perspective, n: n as f64 }
    }

    fn pixel(&self, p: V) -> [f64; 2] {
        let d = sub(p, self.eye);
        let v = self.basis.map(|a| dot(a, d));
        let k = if self.perspective { self.width * v[2] } else { self.width };
        [(v[0] / k + 0.5) * self.n, (v[1] / k + 0.5) * self.n]
    }

    /// The primary ray through pixel point (px, py): origin and direction.
    fn ray(&self, px: f64, py: f64) -> (V, V) {
        let (sx, sy) = (px / self.n - 0.5, py / self.n - 0.5);
        let [l, u, f] = self.basis;
        if self.perspective {
            let d = [0, 1, 2].map(|i| f[i] + sx * self.width * l[i] + sy * self.width * u[i]);
            (self.eye, d)
        } else {
            let o = [0, 1, 2].map(|i| self.eye[i] + sx * self.width * l[i] + sy * self.width * u[i]);
            (o, f)
        }
    }
}

fn quad(positions: &mut Vec<V>, faces: &mut Vec<Face>, corners: [V; 4], material: u16) {
    let base = positions.len() as u32;
    positions.extend(corners);
    faces.push(Face { verts: (base..base + 4).collect(), material });
}

fn material(name: &str) -> Material {
    Material { name: name.into(), ka: [0.2; 3], kd: [0.7; 3], ..Material::default() }
}

/// Render `mesh` through `cam` on an n-grid with the default diffusion.
fn render_through(mesh: Mesh, cam: &Camera, n: u32) -> Image {
    let mesh = to_screen(mesh, cam, n).expect("camera");
    let loaded = load_scene(&mesh, &LoadConfig::watertight(n)).unwrap();
    let lights = resolve_lights(&mesh, &loaded, &[]).unwrap();
    let cfg = RenderConfig::diffusion(host_sim::config::plane_rule(), NormalMode::Facet);
    render(&RenderInput::new(&mesh, &loaded, &lights), &cfg, |_, _| {}).unwrap().image
}

/// Distance from point p to the boundary of the convex hull `hull` (counter-clockwise), and
/// whether p is inside.
fn hull_side(hull: &[[f64; 2]], p: [f64; 2]) -> (bool, f64) {
    let mut inside = true;
    let mut dist = f64::INFINITY;
    for i in 0..hull.len() {
        let (a, b) = (hull[i], hull[(i + 1) % hull.len()]);
        let e = [b[0] - a[0], b[1] - a[1]];
        let len = (e[0] * e[0] + e[1] * e[1]).sqrt();
        let c = (e[0] * (p[1] - a[1]) - e[1] * (p[0] - a[0])) / len;
        inside &= c >= 0.0;
        // Distance to the segment.
        let t = (((p[0] - a[0]) * e[0] + (p[1] - a[1]) * e[1]) / (len * len)).clamp(0.0, 1.0);
        let q = [a[0] + t * e[0] - p[0], a[1] + t * e[1] - p[1]];
        dist = dist.min((q[0] * q[0] + q[1] * q[1]).sqrt());
    }
    (inside, dist)
}

/// Andrew's monotone chain, counter-clockwise.
fn convex_hull(mut pts: Vec<[f64; 2]>) -> Vec<[f64; 2]> {
    pts.sort_by(|a, b| a.partial_cmp(b).unwrap());
    let turn = |o: [f64; 2], a: [f64; 2], b: [f64; 2]| (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0]);
    let mut h: Vec<[f64; 2]> = Vec::new();
    for pass in 0..2 {
        let start = h.len();
        let it: Box<dyn Iterator<Item = &[f64; 2]>> =
            if pass == 0 { Box::new(pts.iter()) } else { Box::new(pts.iter().rev()) };
        for &p in it {
            while h.len() >= start + 2 && turn(h[h.len() - 2], h[h.len() - 1], p) <= 0.0 {
                h.pop();
            }
            h.push(p);
        }
        h.pop();
    }
    h
}

fn cube() -> Mesh {
    let c = |i: u32| [0, 1, 2].map(|k| if i >> k & 1 == 1 { 1.0 } else { -1.0 });
    let faces = [[0, 2, 3, 1], [4, 5, 7, 6], [0, 1, 5, 4], [2, 6, 7, 3], [0, 4, 6, 2], [1, 3, 7, 5]];
    Mesh {
        name: "cube".into(),
        positions: (0..8).map(c).collect(),
        faces: faces.iter().map(|f| Face { verts: f.to_vec(), material: 0 }).collect(),
        materials: vec![material("cube")],
        lights: vec![SceneLight::world([1.6, 2.2, -3.0])],
        ..Mesh::default()
    }
}

/// A cube seen from a known eye covers exactly the pixels whose centre lies inside the
/// projection of its corners (their convex hull), except within a tenth of a pixel of the
/// silhouette, where the vertices' quantisation to 1/16 voxel decides.
#[test]
fn a_cube_lands_on_the_predicted_pixels() {
    let n = 64;
    for projection in [Projection::Perspective { fov_deg: 40.0 }, Projection::Ortho { width: 5.0 }] {
        let cam = Camera {
            eye: [3.0, 2.5, -6.0],
            look_at: [0.2, -0.1, 0.0],
            up: [0.1, 1.0, 0.0],
            projection,
            near: None,
            far: None,
        };
        let image = render_through(cube(), &cam, n);
        let pr = Projector::new(&cam, n);
        let hull = convex_hull((0..8).map(|i| pr.pixel(cube().positions[i])).collect());
        let (mut checked, mut inside_count) = (0, 0);
        for y in 0..n {
            for x in 0..n {
                let (inside, d) = hull_side(&hull, [x as f64 + 0.5, y as f64 + 0.5]);
                if d < 0.1 {
                    continue;
                }
                checked += 1;
                inside_count += inside as u32;
                let covered = image.covered[(y * n + x) as usize];
                assert_eq!(covered, inside, "{projection:?}: pixel ({x}, {y}), {d:.3} px from the silhouette");
            }
        }
        assert!(inside_count > 400 && checked > 3900, "{projection:?}: {inside_count} inside of {checked}");
    }
}

/// A square's shadow on a floor, seen in perspective and orthographically: every pixel whose
/// neighbourhood (the pixel and two pixels around it: a voxel of the tilted floor spans up to
/// two pixels' worth of floor in depth, and a grid is right to a voxel) is entirely in the
/// exact shadow or entirely out of it, and entirely on the floor, is lit exactly when the exact
/// floor point sees the light. The floor is an open sheet: wound with its outward side up,
/// toward the light, or down, away from it, the result is the same.
#[test]
fn a_square_shadow_is_the_exact_one() {
    for floor_up in [true, false] {
        square_shadow(floor_up);
    }
}

fn square_shadow(floor_up: bool) {
    let n = 96;
    let (floor_y, square_y, h) = (0.0, 1.5, 0.7);
    let mut positions = Vec::new();
    let mut faces = Vec::new();
    // Counter-clockwise seen from above: the floor's outward side is up.
    let mut floor = [[-4.0, floor_y, -4.0], [-4.0, floor_y, 4.0], [4.0, floor_y, 4.0], [4.0, floor_y, -4.0]];
    if !floor_up {
        floor.reverse();
    }
    quad(&mut positions, &mut faces, floor, 0);
    quad(&mut positions, &mut faces, [[-h, square_y, -h], [-h, square_y, h], [h, square_y, h], [h, square_y, -h]], 1);
    let mesh = Mesh {
        name: "square".into(),
        positions,
        faces,
        materials: vec![material("floor"), material("square")],
        ..Mesh::default()
    };
    // The floor point seen along pixel point (px, py), or None (off the floor, or the square
    // in front of it).
    let floor_point = |pr: &Projector, px: f64, py: f64| -> Option<V> {
        let (o, d) = pr.ray(px, py);
        let t_square = (square_y - o[1]) / d[1];
        let q = [0, 1, 2].map(|i| o[i] + t_square * d[i]);
        if t_square > 0.0 && q[0].abs() <= h + 1e-9 && q[2].abs() <= h + 1e-9 {
            return None;
        }
        let t = (floor_y - o[1]) / d[1];
        let p = [0, 1, 2].map(|i| o[i] + t * d[i]);
        (t > 0.0 && p[0].abs() < 4.0 && p[2].abs() < 4.0).then_some(p)
    };
    let in_shadow = |p: V, light: V| {
        let t = (square_y - p[1]) / (light[1] - p[1]);
        let q = [0, 1, 2].map(|i| p[i] + t * (light[i] - p[i]));
        q[0].abs() <= h && q[2].abs() <= h
    };
    // Each light is inside its camera's view (a source lies in the grid).
    let views = [
        (Projection::Perspective { fov_deg: 50.0 }, [0.3, 4.0, -0.2]),
        (Projection::Ortho { width: 8.0 }, [0.3, 4.0, -0.2]),
    ];
    for (projection, light) in views {
        let cam = Camera {
            eye: [1.0, 6.0, -7.0],
            look_at: [0.0, 0.0, 0.0],
            up: [0.0, 1.0, 0.0],
            projection,
            near: None,
            far: None,
        };
        let lit_mesh = Mesh { lights: vec![SceneLight::world(light)], ..mesh.clone() };
        let image = render_through(lit_mesh, &cam, n);
        let pr = Projector::new(&cam, n);
        let (mut shadowed, mut lit) = (0, 0);
        for y in 0..n {
            for x in 0..n {
                let samples: Option<Vec<bool>> = (0..25)
                    .map(|k| {
                        let (dx, dy) = ((k % 5) as f64 - 2.0, (k / 5) as f64 - 2.0);
                        floor_point(&pr, x as f64 + 0.5 + dx, y as f64 + 0.5 + dy).map(|p| in_shadow(p, light))
                    })
                    .collect();
                let Some(s) = samples else { continue };
                if s.iter().any(|&v| v != s[0]) {
                    continue;
                }
                let i = (y * n + x) as usize;
                assert!(image.covered[i], "{projection:?}, floor up {floor_up}: floor pixel ({x}, {y}) not covered");
                let want = !s[0];
                assert_eq!(
                    image.lit[i] & 1 == 1,
                    want,
                    "{projection:?}, floor up {floor_up}: pixel ({x}, {y}) lit should be {want}"
                );
                if want {
                    lit += 1
                } else {
                    shadowed += 1
                }
            }
        }
        assert!(shadowed > 100 && lit > 1000, "{projection:?}: {shadowed} shadowed, {lit} lit pixels checked");
    }
}

/// A lamp in the plane of its ceiling, through the Cornell box's camera: the published
/// geometry puts the light's quad in the ceiling's plane. Planar in the world, the two are
/// quantised separately in screen space and their planes come out up to a fraction of a voxel
/// apart, either way; the cells' depth test takes two surfaces of one normal within 1/8 voxel
/// (`cell_core::visible::DEPTH_TIE`) as a tie and keeps the first in the scene's order, as
/// the f64 reference keeps the lowest facet id among hits within its rounding. So the pixels
/// that show the lamp are the reference's, up to its outline: a pixel may differ only where
/// one of its 8 neighbours is on the other side of the reference's lamp outline. (Before the
/// tie, at n = 512 the ceiling showed over the whole lamp.)
#[test]
fn a_lamp_in_its_ceiling_shows_where_the_reference_shows_it() {
    use host_sim::scene::camera::{apply, ViewChoice};
    for n in [128u32, 256, 512] {
        let mesh = apply(host_sim::scene::load("cornell").unwrap(), &ViewChoice::Scene, n).unwrap();
        let loaded = load_scene(&mesh, &LoadConfig::watertight(n)).unwrap();
        let lights = resolve_lights(&mesh, &loaded, &[]).unwrap();
        let cfg = RenderConfig::diffusion(host_sim::config::plane_rule(), NormalMode::Facet);
        let reference = host_sim::jobs::render::reference_image(&mesh, &loaded, &lights, &cfg).unwrap();
        // The machine's facet ids count the pieces of split polygons; materials are the mesh's.
        let emissive = |m: usize| mesh.materials[m].ke.iter().any(|&k| k > 0.0);
        let emits = |f: u32| emissive(mesh.faces[f as usize].material as usize);
        let idx = |x: u32, y: u32| (y * n + x) as usize;
        let lamp_ref = |x: u32, y: u32| reference.covered[idx(x, y)] && emits(reference.facet[idx(x, y)]);
        let (mut lamp_pixels, mut outline, mut inside) = (0, 0, Vec::new());
        for y in 0..n {
            for x in 0..n {
                let machine = loaded.grid.cell(x, y).visible.is_some_and(|v| emissive(v.material as usize));
                lamp_pixels += lamp_ref(x, y) as u32;
                if machine == lamp_ref(x, y) {
                    continue;
                }
                let (xs, ys) = (x.saturating_sub(1)..=(x + 1).min(n - 1), y.saturating_sub(1)..=(y + 1).min(n - 1));
                let on_outline = xs.clone().any(|u| ys.clone().any(|v| lamp_ref(u, v) != lamp_ref(x, y)));
                if on_outline {
                    outline += 1;
                } else {
                    inside.push((x, y, machine));
                }
            }
        }
        eprintln!("n = {n}: {lamp_pixels} lamp pixels in the reference, {outline} differ on its outline");
        assert!(lamp_pixels > n * n / 400, "n = {n}: the reference shows the lamp on {lamp_pixels} pixels only");
        assert!(
            inside.is_empty(),
            "n = {n}: {} pixels off the lamp's outline differ (x, y, machine shows the lamp): {:?}",
            inside.len(),
            &inside[..inside.len().min(8)]
        );
    }
}
