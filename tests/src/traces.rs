//! Helpers for the trace tests: the Cornell-box job the firmware test records, and re-encoding a
//! trace with a changed value (valid frames, different meaning).

use cell_core::beam::FracBits;
use cell_core::light::Policy;
use cell_core::trace::{write_event, Event, Parser};
use host_sim::machine::diffuse::{source_at, LightConfig};
use host_sim::precompute::LoadConfig;
use host_sim::scene::Mesh;

/// The Cornell box at side `n` (tunnel-free surfaces, the plane rule), and cells to record: near a corner, the
/// centre, and the light's own cell (the one the source emitter feeds).
pub fn cornell_job_cells(n: u32) -> (Mesh, LoadConfig, LightConfig, Vec<[u32; 2]>) {
    let mesh = host_sim::scene::load("cornell").unwrap();
    let load = LoadConfig::watertight(n);
    let light =
        LightConfig { fa: 16, policy: Policy::Wavefront, merge: true, record_visits: false, ..Default::default() };
    let scene = host_sim::machine::loaded::load_scene(&mesh, &load).unwrap();
    let lights = host_sim::machine::loaded::resolve_lights(&mesh, &scene, &[]).unwrap();
    let s = source_at(0, lights[0], n).unwrap().voxel();
    (mesh, load, light, vec![[3, 3], [n / 2, n / 2], [s[0] as u32, s[1] as u32]])
}

/// The trace with the material of every row packet changed (re-encoded, so every CRC is
/// valid); `None` when the trace holds no row packet.
pub fn mutate_row_material<F: FracBits>(bytes: &[u8]) -> Option<Vec<u8>> {
    let mut p = Parser::<F>::new(bytes);
    let mut out = Vec::new();
    let mut changed = false;
    let mut buf = [0u8; 2048];
    while let Some(ev) = p.next_event() {
        let mut ev = ev.ok()?;
        if let Event::Row(r) = &mut ev {
            r.tag.material = r.tag.material.wrapping_add(1);
            changed = true;
        }
        let len = write_event(&ev, &mut buf).ok()?;
        out.extend_from_slice(&buf[..len]);
    }
    changed.then_some(out)
}
