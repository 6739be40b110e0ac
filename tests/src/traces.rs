//! Helpers for the trace tests: the Cornell-box job the firmware test records, re-encoding a
//! trace with a changed value (valid frames, different meaning), and corrupting a ray frame as
//! a wire would.

use cell_core::beam::FracBits;
use cell_core::light::Policy;
use cell_core::trace::{write_event, Event, Parser};
use cell_core::wire::{KIND_REFLECT_RAY, KIND_SHADOW_RAY};
use host_sim::jobs::trace::TraceJob;
use host_sim::machine::lighting::diffuse::{source_at, LightConfig};
use host_sim::precompute::LoadConfig;
use host_sim::scene::Mesh;

/// The Cornell box at side `n` (tunnel-free surfaces, the plane rule), and cells to record: near a corner, the
/// centre, and the light's own cell (the one the source emitter feeds).
pub fn cornell_job_cells(n: u32) -> (Mesh, LoadConfig, LightConfig, Vec<[u32; 2]>) {
    let mesh = host_sim::scene::load("cornell").unwrap();
    let load = LoadConfig::watertight(n);
    let light = LightConfig {
        fa: 16,
        policy: Policy::Wavefront,
        merge: true,
        record_visits: false,
        ..host_sim::config::plane_rule()
    };
    let scene = host_sim::machine::loading::loaded_scene::load_scene(&mesh, &load).unwrap();
    let lights = host_sim::machine::loading::loaded_scene::resolve_lights(&mesh, &scene, &[]).unwrap();
    let s = source_at(0, lights[0], n).unwrap().voxel();
    (mesh, load, light, vec![[3, 3], [n / 2, n / 2], [s[0] as u32, s[1] as u32]])
}

/// A trace job for `cells` of `mesh` with the scene's own lights: loading and beam diffusion,
/// no busiest cell, no ray phase (struct update sets those).
pub fn trace_job(mesh: &Mesh, load: LoadConfig, light: LightConfig, cells: Vec<[u32; 2]>) -> TraceJob<'_> {
    TraceJob { mesh, load, light, lights: Vec::new(), cells, busiest: false, classic: None, reflections: None }
}

/// The trace with the material of every row packet changed (re-encoded, so every CRC is
/// valid); `None` when the trace holds no row packet.
pub fn mutate_row_material<F: FracBits>(bytes: &[u8]) -> Option<Vec<u8>> {
    re_encode::<F>(bytes, |ev| match ev {
        Event::Row(r) => {
            r.tag.material = r.tag.material.wrapping_add(1);
            true
        }
        _ => false,
    })
}

/// The trace with every shadow-ray answer the router delivers turned from lit to shadow or back
/// (re-encoded); `None` when no answer came back.
pub fn flip_shadow_answers<F: FracBits>(bytes: &[u8]) -> Option<Vec<u8>> {
    re_encode::<F>(bytes, |ev| match ev {
        Event::ShadowAnswer(p) => {
            *p ^= cell_core::shadow::ANSWER_LIT;
            true
        }
        _ => false,
    })
}

/// The trace with every reflection answer the router delivers made greener by 1/8 (re-encoded);
/// `None` when no answer came back.
pub fn brighten_reflect_answers<F: FracBits>(bytes: &[u8]) -> Option<Vec<u8>> {
    re_encode::<F>(bytes, |ev| match ev {
        Event::ReflectAnswer { answer, .. } => {
            answer[1] = answer[1].wrapping_add(512);
            true
        }
        _ => false,
    })
}

/// What [`rewrite`] does with one record.
enum Edit {
    /// Write it as it is.
    Keep,
    /// Write it as changed in place.
    Changed,
    /// Leave it out.
    Drop,
}

/// The trace with every record re-encoded after `edit` saw it (so every CRC is valid); `None`
/// when no record was changed or dropped (or the trace does not parse).
fn rewrite<F: FracBits>(bytes: &[u8], mut edit: impl FnMut(&mut Event<'_, F>) -> Edit) -> Option<Vec<u8>> {
    let mut p = Parser::<F>::new(bytes);
    let mut out = Vec::new();
    let mut edited = false;
    let mut buf = [0u8; 2048];
    while let Some(ev) = p.next_event() {
        let mut ev = ev.ok()?;
        match edit(&mut ev) {
            Edit::Keep => {}
            Edit::Changed => edited = true,
            Edit::Drop => {
                edited = true;
                continue;
            }
        }
        let len = write_event(&ev, &mut buf).ok()?;
        out.extend_from_slice(&buf[..len]);
    }
    edited.then_some(out)
}

/// The trace with every record `change` changes (it says whether it did) re-encoded, so every
/// CRC is valid; `None` when it changed none (or the trace does not parse).
pub fn re_encode<F: FracBits>(bytes: &[u8], mut change: impl FnMut(&mut Event<'_, F>) -> bool) -> Option<Vec<u8>> {
    rewrite::<F>(bytes, |ev| if change(ev) { Edit::Changed } else { Edit::Keep })
}

/// The trace without its triangle records (exact occluders: the column's triangles),
/// re-encoded; `None` when it has none.
pub fn drop_triangles<F: FracBits>(bytes: &[u8]) -> Option<Vec<u8>> {
    rewrite::<F>(bytes, |ev| if matches!(ev, Event::Triangle(_)) { Edit::Drop } else { Edit::Keep })
}

/// The trace with one byte flipped in the middle of the first ray frame a link delivers
/// (`Recv` with a shadow or reflected ray), the record re-encoded around it: the record's CRC
/// is valid, the ray frame's own CRC (the link's) is not, as for a byte corrupted on the wire.
/// `None` when no ray came in on a link.
pub fn corrupt_first_ray_frame<F: FracBits>(bytes: &[u8]) -> Option<Vec<u8>> {
    let mut p = Parser::<F>::new(bytes);
    let mut out = Vec::new();
    let mut done = false;
    let mut buf = [0u8; 2048];
    while let Some(ev) = p.next_event() {
        let ev = ev.ok()?;
        let len = match ev {
            Event::Recv { port, frame } if !done && matches!(frame[0], KIND_SHADOW_RAY | KIND_REFLECT_RAY) => {
                let mut wire = frame.to_vec();
                wire[frame.len() / 2] ^= 0x08;
                done = true;
                write_event::<F>(&Event::Recv { port, frame: &wire }, &mut buf).ok()?
            }
            ev => write_event(&ev, &mut buf).ok()?,
        };
        out.extend_from_slice(&buf[..len]);
    }
    done.then_some(out)
}
