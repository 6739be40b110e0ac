//! Shading and the rendered image (issue 4): the cell's micromath shading equals the f64
//! formula within a stated tolerance on random inputs; the whole render is deterministic; the
//! discrete image agrees with the f64 reference where the geometry is simple.

use cell_core::shade::{shade, Material as CellMaterial, NormalMode, PointLight, ShadeParams};
use host_sim::precompute::{Contour, LoadConfig, Thickness};
use host_sim::truth::refrender::{shade_f64, RefLight};
use host_sim::scene::Material;
use proptest::prelude::*;

/// Tolerance of the cell's shading against f64 on the same inputs: one 8-bit level (the cell's
/// math is exact up to f32 rounding, which can move a value across a rounding boundary).
const TOLERANCE_LEVELS: u8 = 1;

fn unit(v: [f32; 3]) -> [f32; 3] {
    let l = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    v.map(|c| c / l)
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(2000))]
    #[test]
    fn cell_shading_matches_f64(
        n in prop::array::uniform3(-1.0f32..1.0),
        p in prop::array::uniform3(0.0f32..128.0),
        lights in prop::collection::vec((prop::array::uniform3(-20.0f32..150.0), prop::array::uniform3(0.0f32..1.0)), 1..4),
        mask in 0u32..16,
        kd in prop::array::uniform3(0.0f32..1.0),
        ks in prop::array::uniform3(0.0f32..0.6),
        ns in 1.0f32..200.0,
        ka in prop::array::uniform3(0.0f32..0.3),
    ) {
        prop_assume!(n.iter().map(|c| c * c).sum::<f32>() > 1e-3);
        let mut nn = unit(n);
        if nn[2] > 0.0 { nn = nn.map(|c| -c); } // facing the viewer (VIEW = −z)
        let ns = ns.round(); // the cell raises to an integer power
        let m = Material { name: "m".into(), ka, kd, ks, ns, ke: [0.0; 3], kr: 0.0 };
        let cm = CellMaterial { ka, kd, ks, ns, ke: [0.0; 3] };
        let pl: Vec<PointLight> = lights.iter().map(|(pos, color)| PointLight { pos: *pos, color: *color }).collect();
        let rl: Vec<RefLight> = lights.iter().map(|(pos, color)| RefLight { pos: pos.map(|c| c as f64), color: color.map(|c| c as f64) }).collect();
        let params = ShadeParams { ambient: [0.2; 3], normal_mode: NormalMode::Facet };
        let got = shade(p, nn, &cm, &pl, mask, &params);
        let want = shade_f64(p.map(|c| c as f64), nn.map(|c| c as f64), &m, &rl, mask, [0.2; 3]);
        for k in 0..3 {
            prop_assert!(got[k].abs_diff(want[k]) <= TOLERANCE_LEVELS, "channel {}: cell {:?} vs f64 {:?}", k, got, want);
        }
    }
}

fn render_once(scene: &str, n: u32) -> (host_sim::machine::shade::Image, host_sim::jobs::render::RenderStats) {
    let mesh = host_sim::scene::load(scene).unwrap();
    let cfg = LoadConfig { n, thickness: Thickness::Naive, contour: Contour::Projected };
    let loaded = host_sim::machine::loaded::load_scene(&mesh, &cfg).unwrap();
    let lights = host_sim::machine::loaded::resolve_lights(&mesh, &loaded, &[]).unwrap();
    let reference = host_sim::jobs::render::reference_image(&mesh, &loaded, &lights).unwrap();
    let rcfg = host_sim::jobs::render::RenderConfig {
        light: host_sim::machine::diffuse::LightConfig {
            fa: 16,
            policy: cell_core::light::Policy::Wavefront,
            merge: true,
            record_visits: false,
            ..Default::default()
        },
        normals: NormalMode::Facet,
    };
    let r = host_sim::jobs::render::render::<cell_core::beam::frac::U0>(
        &mesh,
        &loaded,
        &lights,
        &rcfg,
        Some(&reference),
        0.0,
        0.0,
        |_, _| {},
    )
    .unwrap();
    (r.image, r.stats)
}

#[test]
fn render_is_deterministic_and_close_to_the_reference() {
    let (a, sa) = render_once("cornell", 48);
    let (b, _) = render_once("cornell", 48);
    assert_eq!(a.rgb, b.rgb, "same input, same pixels");
    let dir = std::env::temp_dir().join(format!("rc2-render-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let (p, q) = (dir.join("a.png"), dir.join("b.png"));
    host_sim::report::png::write_png(&p, a.n, &a.rgb).unwrap();
    host_sim::report::png::write_png(&q, b.n, &b.rgb).unwrap();
    assert_eq!(std::fs::read(&p).unwrap(), std::fs::read(&q).unwrap(), "same bytes");
    // The cell's arithmetic against f64 on every pixel, same inputs.
    assert!(sa.shading_max_err_levels <= TOLERANCE_LEVELS, "{}", sa.shading_max_err_levels);
    let c = sa.reference.unwrap();
    // Bounds from the measured behaviour (README): the box's walls are covered exactly alike
    // except at their voxelized edges, and most shadow states agree at f = 0.
    assert!(c.coverage_disagreement_pct < 5.0, "{c:?}");
    assert!(c.shadow_disagreement_pct < 25.0, "{c:?}");
    assert!(c.psnr_db > 15.0, "{c:?}");
    // A mesh in front of a floor: the cast shadow is found.
    let (_, st) = render_once("cow-floor", 64);
    let c = st.reference.unwrap();
    assert!(c.shadow_disagreement_pct < 8.0 && c.coverage_disagreement_pct < 1.0, "{c:?}");
}
