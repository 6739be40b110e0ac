//! Faulty links: every transfer goes through the wire codec (frame + CRC-32) and a
//! seeded fault injector that corrupts and drops data frames and acknowledgements. Corrupted
//! frames must never be applied, and with acknowledgement and retransmission a run must light
//! exactly the voxels a clean run lights and give the same image bytes, in more cycles (with
//! the thesis's rays and with rays from the light).

use cell_core::beam::Origin;
use cell_core::light::Policy;
use cell_core::shade::NormalMode;
use host_sim::machine::lighting::diffuse::LightConfig;
use host_sim::machine::lighting::run::run_diffusion;
use host_sim::machine::links::faults::LinkFaults;
use host_sim::machine::loading::loaded_scene::{load_scene, resolve_lights};
use host_sim::machine::shading::pixels::{point_lights, shade_grid};
use host_sim::precompute::LoadConfig;

#[test]
fn faulty_links_light_exactly_what_clean_links_light() {
    for (scene, n, policy, rays) in [
        ("cornell", 32, Policy::Wavefront, Origin::SourceVoxel),
        ("teapot-floor", 24, Policy::Thesis, Origin::SourceVoxel),
        ("cornell", 24, Policy::Radial, Origin::SourceVoxel),
        ("cornell", 24, Policy::Wavefront, Origin::Light),
    ] {
        let mesh = host_sim::scene::load(scene).unwrap();
        let loaded = load_scene(&mesh, &LoadConfig::thin(n)).unwrap();
        let lights = resolve_lights(&mesh, &loaded, &[]).unwrap();
        let run = |faults: Option<LinkFaults>| {
            let cfg =
                LightConfig { fa: 4, policy, merge: policy.by_layer(), faults, rays, ..host_sim::config::plane_rule() };
            let (l, stats) = run_diffusion(&mesh, &loaded, &lights, &cfg, |_, _| {}).unwrap();
            let img = shade_grid(&mesh, &loaded, &point_lights(&lights), &l, NormalMode::Facet);
            (l.lit_voxels().collect::<Vec<_>>(), img.rgb, stats)
        };
        let (lit, rgb, clean) = run(None);
        assert!(clean.link_faults.is_none());
        for (corrupt, drop, delay, seed) in [(0.01, 0.01, 0.05, 7), (0.2, 0.2, 0.2, 11)] {
            let ppm = |r: f64| (r * 1e6) as u32;
            let f = LinkFaults {
                corrupt_ppm: ppm(corrupt),
                drop_ppm: ppm(drop),
                delay_ppm: ppm(delay),
                delay_cycles: 8,
                seed,
            };
            let (flit, frgb, st) = run(Some(f));
            let c = st.link_faults.unwrap();
            assert_eq!(flit, lit, "{scene}: lit voxels differ under {f:?}");
            assert_eq!(frgb, rgb, "{scene}: image differs under {f:?}");
            assert!(c.data_corrupted > 0 && c.data_dropped > 0 && c.acks_lost > 0 && c.duplicates > 0, "{c:?}");
            // Delays of 1 ..= 8 cycles each, none of them a loss.
            assert!(c.data_delayed > 0 && (c.data_delayed..=8 * c.data_delayed).contains(&c.delay_cycles), "{c:?}");
            // Every corrupted data frame was refused by the CRC (none was applied: the lit sets
            // are exact), and only acknowledged messages left their buffers.
            assert!(c.crc_rejected >= c.data_corrupted, "{c:?}");
            // Every failed send was sent again: a run ends with every output buffer empty.
            assert_eq!(c.retransmissions, c.data_corrupted + c.data_dropped + c.acks_lost, "{c:?}");
            eprintln!("{scene} n={n} {f:?}: {} cycles (clean {}), {c:?}", st.totals.cycles, clean.totals.cycles);
            assert!(st.totals.cycles > clean.totals.cycles, "faults cost cycles");
            assert_eq!(st.totals.rays_emitted, clean.totals.rays_emitted);
            assert_eq!(st.totals.rays_absorbed, clean.totals.rays_absorbed);
        }
    }
}

/// The stall detector: a dead link (every frame lost) stops the run after `stall_cycles`
/// cycles without progress, naming the blocked cells and their queues, instead of spinning;
/// with perfect links the machine never goes a single cycle without progress.
#[test]
fn a_dead_link_is_reported_as_a_stall_and_perfect_links_never_stall() {
    let mesh = host_sim::scene::load("cornell").unwrap();
    let loaded = load_scene(&mesh, &LoadConfig::thin(24)).unwrap();
    let lights = resolve_lights(&mesh, &loaded, &[]).unwrap();
    let dead = LinkFaults { drop_ppm: 1_000_000, ..LinkFaults::NONE };
    let cfg = LightConfig { fa: 4, faults: Some(dead), stall_cycles: 7, ..host_sim::config::plane_rule() };
    let err = run_diffusion(&mesh, &loaded, &lights, &cfg, |_, _| {}).err().expect("a dead link must stall");
    let msg = err.to_string();
    // A delay as long as the stall limit is refused up front, not reported as a stall.
    let slow = LinkFaults { delay_ppm: 1_000_000, delay_cycles: 7, ..LinkFaults::NONE };
    let cfg_slow = LightConfig { fa: 4, faults: Some(slow), stall_cycles: 7, ..host_sim::config::plane_rule() };
    let e = run_diffusion(&mesh, &loaded, &lights, &cfg_slow, |_, _| {}).err().expect("refused");
    assert!(e.to_string().contains("delay-cycles=7 must be below --stall-cycles 7"), "{e}");
    // Every frame held up to 6 cycles: slow, but never a stall, and the same lit voxels.
    let clean =
        run_diffusion(&mesh, &loaded, &lights, &LightConfig { fa: 4, ..host_sim::config::plane_rule() }, |_, _| {});
    let (clean, cs) = clean.unwrap();
    let all_slow = LinkFaults { delay_ppm: 1_000_000, delay_cycles: 6, ..LinkFaults::NONE };
    let cfg_all = LightConfig { fa: 4, faults: Some(all_slow), stall_cycles: 7, ..host_sim::config::plane_rule() };
    let (l, st) = run_diffusion(&mesh, &loaded, &lights, &cfg_all, |_, _| {}).expect("delays are not stalls");
    assert!(l.lit_voxels().eq(clean.lit_voxels()));
    let c = st.link_faults.unwrap();
    assert_eq!(c.data_delayed, c.data_frames, "every frame was delayed: {c:?}");
    assert!(st.totals.cycles > 2 * cs.totals.cycles, "{} vs {}", st.totals.cycles, cs.totals.cycles);
    assert!(msg.contains("no progress for 7 cycle(s)") && msg.contains("blocked cells"), "{msg}");
    assert!(msg.contains("fifo") && msg.contains("out ["), "the report shows the queues: {msg}");
    for policy in [Policy::Wavefront, Policy::Thesis, Policy::Radial] {
        let cfg = LightConfig { fa: 1, policy, merge: false, stall_cycles: 1, ..host_sim::config::plane_rule() };
        run_diffusion(&mesh, &loaded, &lights, &cfg, |_, _| {}).expect("perfect links never stall");
    }
}
