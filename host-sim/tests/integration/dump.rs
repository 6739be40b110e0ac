//! `light --dump-lit`: the JSON an outside tool reads must describe the same voxels, lights and
//! triangles as the machine, in the mapping it states. Checked against the grid itself
//! (exhaustive over all n³ voxels) and against continuous geometry (f64 point–triangle
//! distances), after a JSON round trip.

use cell_core::light::Policy;
use host_sim::jobs::dump::{lit_dump, write_lit_dump};
use host_sim::machine::lighting::diffuse::LightConfig;
use host_sim::machine::lighting::run::run_diffusion;
use host_sim::machine::loading::loaded_scene::{load_scene, resolve_lights};
use host_sim::precompute::LoadConfig;
use serde_json::Value;

type V3 = [f64; 3];

fn sub(a: V3, b: V3) -> V3 {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn dot(a: V3, b: V3) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn cross(a: V3, b: V3) -> V3 {
    [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
}

/// Distance from p to the segment ab.
fn point_segment_distance(p: V3, a: V3, b: V3) -> f64 {
    let (ab, ap) = (sub(b, a), sub(p, a));
    let t = (dot(ap, ab) / dot(ab, ab).max(f64::MIN_POSITIVE)).clamp(0.0, 1.0);
    let d = sub(ap, [t * ab[0], t * ab[1], t * ab[2]]);
    dot(d, d).sqrt()
}

/// Distance from p to triangle abc: to its plane when p projects inside it (all three edge
/// normals agree), else to the nearest edge.
fn point_triangle_distance(p: V3, a: V3, b: V3, c: V3) -> f64 {
    let nrm = cross(sub(b, a), sub(c, a));
    let len = dot(nrm, nrm).sqrt();
    let inside = [(a, b), (b, c), (c, a)].iter().all(|&(u, v)| dot(cross(sub(v, u), sub(p, u)), nrm) >= 0.0);
    if len > 0.0 && inside {
        return dot(sub(p, a), nrm).abs() / len;
    }
    [(a, b), (b, c), (c, a)].iter().map(|&(u, v)| point_segment_distance(p, u, v)).fold(f64::INFINITY, f64::min)
}

fn floats(v: &Value) -> Vec<f64> {
    v.as_array().expect("array").iter().map(|x| x.as_f64().expect("number")).collect()
}

fn ints(v: &Value) -> Vec<u64> {
    v.as_array().expect("array").iter().map(|x| x.as_u64().expect("integer")).collect()
}

#[test]
fn dump_matches_the_grid_the_lights_and_the_geometry() {
    let n = 24u32;
    let mesh = host_sim::scene::load("cornell").unwrap();
    let cfg = LoadConfig::watertight(n);
    let loaded = load_scene(&mesh, &cfg).unwrap();
    let lights = resolve_lights(&mesh, &loaded, &[]).unwrap();
    let lcfg = LightConfig {
        fa: 16,
        policy: Policy::Wavefront,
        merge: true,
        record_visits: false,
        ..host_sim::config::plane_rule()
    };
    let (lighting, stats) = run_diffusion(&mesh, &loaded, &lights, &lcfg, |_, _| {}).unwrap();
    let mut buf = Vec::new();
    write_lit_dump(&lit_dump(&mesh, &loaded.grid, &loaded.fit, &lighting, &stats), &mut buf).unwrap();
    let d: Value = serde_json::from_slice(&buf).unwrap();

    // Voxels: exactly the occupied ones (all n³ checked), each with the grid's lit mask.
    let vox = ints(&d["voxels"]);
    assert_eq!(vox.len() % 4, 0);
    let listed: std::collections::HashMap<[u64; 3], u64> = vox.chunks(4).map(|c| ([c[0], c[1], c[2]], c[3])).collect();
    assert_eq!(listed.len(), vox.len() / 4, "a voxel is listed twice");
    let mut occupied = 0usize;
    let mut lit = 0usize;
    for x in 0..n {
        for y in 0..n {
            for z in 0..n as u16 {
                let here = loaded.grid.cell(x, y).store.occupied(z).is_some();
                let key = [x as u64, y as u64, z as u64];
                assert_eq!(listed.contains_key(&key), here, "voxel {key:?}");
                if here {
                    occupied += 1;
                    assert_eq!(listed[&key], lighting.mask(x, y, z) as u64, "mask of {key:?}");
                    lit += (listed[&key] != 0) as usize;
                }
            }
        }
    }
    assert!(occupied > 0 && lit > 0 && lit < occupied, "a real scene: some lit, some dark");

    // Mapping: every voxel centre lies within half a voxel diagonal (plus the 1/16-voxel
    // lattice rounding) of a triangle — the conservative surface's defining property.
    let origin = floats(&d["origin"]);
    let voxel = d["voxel"].as_f64().unwrap();
    let verts = floats(&d["vertices"]);
    let vert = |i: u64| [verts[3 * i as usize], verts[3 * i as usize + 1], verts[3 * i as usize + 2]];
    let tris: Vec<[V3; 3]> = ints(&d["triangles"]).chunks(3).map(|t| [vert(t[0]), vert(t[1]), vert(t[2])]).collect();
    let fans: usize = mesh.faces.iter().map(|f| f.verts.len() - 2).sum();
    assert_eq!(tris.len(), fans);
    let limit = (3f64.sqrt() / 2.0 + 3f64.sqrt() / 16.0) * voxel;
    for c in vox.chunks(4) {
        let p = [0, 1, 2].map(|i| origin[i] + (c[i] as f64 + 0.5) * voxel);
        let near = tris.iter().map(|t| point_triangle_distance(p, t[0], t[1], t[2])).fold(f64::INFINITY, f64::min);
        assert!(near <= limit, "voxel {:?}: centre {:.3} voxels from every triangle", &c[..3], near / voxel);
    }

    // Lights: the world position maps back to the voxel-unit position the cells used.
    let lw = d["lights_world"].as_array().unwrap();
    let lv = d["lights_voxel"].as_array().unwrap();
    assert_eq!(lw.len(), lights.len());
    for (w, v) in lw.iter().zip(lv) {
        let (w, v) = (floats(w), floats(v));
        for i in 0..3 {
            assert!(((w[i] - origin[i]) / voxel - 0.5 - v[i]).abs() < 1e-9);
        }
    }
    assert_eq!(d["cycles"].as_u64().unwrap(), stats.totals.cycles);
    assert_eq!(d["beams_processed"].as_u64().unwrap(), stats.totals.beams_processed);
}
