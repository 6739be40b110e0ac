//! `light`'s lit set under its default rule against f64 visibility, on a mesh the lit rule was
//! not designed on (the cow): the voxel's ray arrives at its layer iff the light reaches the
//! voxel, measured where the exact segment from the light enters the voxel (`entry`) and one
//! voxel back along its major axis (`reach`, the machine's own point); grazing light (thesis
//! §5.5.6) counted apart (docs/LIGHTING.md, "The lit set"). The bound is the goal,
//! 1 % of the surface voxels: at the machine's point over every surface voxel, where the
//! segment enters away from grazing light. The preset's f = 1 is checked against f = 0, which
//! it replaced as `light`'s default for its grazed voxels.

use host_sim::config::Preset;
use host_sim::jobs::accuracy::{accuracy, Accuracy, Measure};
use host_sim::machine::lighting::diffuse::LightConfig;
use host_sim::machine::lighting::run::run_diffusion;
use host_sim::machine::loading::loaded_scene::{load_scene, resolve_lights};
use host_sim::precompute::LoadConfig;

#[test]
fn lights_lit_set_agrees_with_f64_visibility_within_one_percent() {
    let mesh = host_sim::scene::load("cow").unwrap();
    let n = 128;
    let loaded = load_scene(&mesh, &LoadConfig::watertight(n)).unwrap();
    for light in [[0.7, 0.85, 0.3], [0.15, 0.4, 0.8]] {
        let lights = resolve_lights(&mesh, &loaded, &[light]).unwrap();
        let (lit, _) = run_diffusion(&mesh, &loaded, &lights, &Preset::Light.light(), |_, _| {}).unwrap();
        let at = |m| accuracy(&mesh, &loaded, &lights, &lit, m).unwrap();
        let (centre, entry, reach): (Accuracy, Accuracy, Accuracy) =
            (at(Measure::Centre), at(Measure::Entry), at(Measure::Reach));
        eprintln!("light {light:?}: centre {centre:?}\n  entry {entry:?}\n  reach {reach:?}");
        // Not vacuous: lit and dark surface voxels, most of them not grazed.
        let s = entry.surface_voxels;
        assert!(entry.lit_continuous > s / 10 && entry.lit_continuous < s * 9 / 10, "{entry:?}");
        assert!(entry.grazing_voxels < s / 2, "{entry:?}");
        for a in [&entry, &reach] {
            assert!(a.disagreement_pct_not_grazing <= 1.0, "light {light:?}: {a:?}");
        }
        assert!(reach.disagreement_pct <= 1.0, "light {light:?}, grazed voxels included: {reach:?}");
        // f = 0's lattice, a voxel apart near the far plane, gets more of them wrong.
        let f0 = LightConfig { frac_bits: 0, ..Preset::Light.light() };
        let (lit0, _) = run_diffusion(&mesh, &loaded, &lights, &f0, |_, _| {}).unwrap();
        let reach0 = accuracy(&mesh, &loaded, &lights, &lit0, Measure::Reach).unwrap();
        assert!(
            Preset::Light.light().frac_bits == 1 && reach.disagreement_pct < reach0.disagreement_pct,
            "{reach:?}\n{reach0:?}"
        );
        // The centre, inside the solid for many surface voxels, is the worst point to measure.
        assert!(reach.disagreement_pct < centre.disagreement_pct && entry.disagreement_pct < centre.disagreement_pct);
    }
}
