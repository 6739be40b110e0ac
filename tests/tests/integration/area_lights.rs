//! Area lights sampled by point sources (issue 54 item 5(b), `--area-light S`) against
//! independent oracles:
//!
//! * the samples are the S × S cell centres of the Cornell lamp's published rectangle
//!   (213..343 × 227..332 at y = 548.8), computed here from its corners, and each carries
//!   1/S² of the light's intensity (those of a `--light` with `--light-size` likewise);
//! * S = 1 is the point light at the lamp's centre, the same sources and intensities as a run
//!   without the option, and the same image to the byte;
//! * on the Cornell box with S = 3 the reference shows a penumbra on the floor (pixels lit by
//!   some of the samples and not all); each sample's lit bit in the machine and in the reference
//!   is that of a run with that sample alone (the sources are diffused one after another); and
//!   the image is no further from the reference than the point light's image is from its own
//!   by more than the bound derived in [`penumbra_on_the_floor_matches_the_reference`].

use cell_core::shade::NormalMode;
use host_sim::config::Preset;
use host_sim::jobs::render::{reference_image_lit, render, RenderConfig, RenderInput, Rendered};
use host_sim::machine::loading::loaded_scene::{
    load_scene, normalised_to_voxel, resolve_lights, resolve_sources, world_to_voxel, LightSampling, LoadedScene,
    Sources,
};
use host_sim::precompute::LoadConfig;
use host_sim::scene::builtin::CORNELL_LAMP;
use host_sim::scene::camera::ViewChoice;
use host_sim::scene::{LightAt, Mesh};
use host_sim::truth::refrender::RefImage;

/// The published lamp: x 213..343, z 227..332, y = 548.8 (host-sim/scenes/cornell.obj).
const LAMP_X: [f64; 2] = [213.0, 343.0];
const LAMP_Z: [f64; 2] = [227.0, 332.0];
const LAMP_Y: f64 = 548.8;

fn sampling(area: u32) -> LightSampling<'static> {
    LightSampling { cli: &[], cli_size: None, area }
}

/// The S × S cell centres of the lamp, row-major z outer, from its corners.
fn lamp_cell_centres(s: u32) -> Vec<[f64; 3]> {
    let at = |lo: f64, hi: f64, i: u32| lo + (hi - lo) * (2 * i + 1) as f64 / (2 * s) as f64;
    (0..s)
        .flat_map(|k| (0..s).map(move |i| [at(LAMP_X[0], LAMP_X[1], i), LAMP_Y, at(LAMP_Z[0], LAMP_Z[1], k)]))
        .collect()
}

fn load(scene: &str, n: u32, view: ViewChoice) -> (Mesh, LoadedScene) {
    let mesh = host_sim::scene::camera::apply(host_sim::scene::load(scene).unwrap(), &view, n).unwrap();
    let loaded = load_scene(&mesh, &LoadConfig::watertight(n)).unwrap();
    (mesh, loaded)
}

/// The samples of the Cornell lamp are its S × S cell centres; each sample's voxel position is
/// its world position's (x and z exactly; y stepped down out of the ceiling, never up); the
/// weights are 1/S² of the one light's intensity 1 and sum to it.
#[test]
fn samples_are_the_cell_centres_of_the_lamp_and_share_its_intensity() {
    for s in 1..=5 {
        let got = CORNELL_LAMP.samples(s);
        let want = lamp_cell_centres(s);
        assert_eq!(got.len(), want.len(), "S = {s}");
        for (g, w) in got.iter().zip(&want) {
            let LightAt::World(p) = *g else { panic!("a world light's samples are world positions") };
            assert!(p.iter().zip(w).all(|(a, b)| (a - b).abs() < 1e-9), "S = {s}: {p:?} against {w:?}");
        }
    }
    assert_eq!(CORNELL_LAMP.samples(1), vec![LightAt::World([278.0, 548.8, 279.5])], "S = 1 is the centre");
    let (mesh, loaded) = load("cornell", 32, ViewChoice::Fitted);
    for s in 1..=5 {
        let src = resolve_sources(&mesh, &loaded, &sampling(s)).unwrap();
        let n2 = (s * s) as usize;
        assert_eq!((src.positions.len(), src.intensity.len()), (n2, n2), "S = {s}");
        assert!(src.light.iter().all(|&l| l == 0));
        for (p, w) in src.positions.iter().zip(lamp_cell_centres(s)) {
            let v = world_to_voxel(&loaded.fit, w);
            assert_eq!((p[0], p[2]), (v[0], v[2]), "S = {s}: x and z are the sample's");
            assert!(p[1] <= v[1] && p[1] > v[1] - 3.0, "S = {s}: stepped down out of the ceiling only: {p:?} {v:?}");
        }
        let each = 1.0 / n2 as f32;
        assert!(src.intensity.iter().all(|&e| e == each), "S = {s}: {:?}", src.intensity);
        let sum: f64 = src.intensity.iter().map(|&e| f64::from(e)).sum();
        assert!((sum - 1.0).abs() <= n2 as f64 * f64::from(f32::EPSILON), "S = {s}: the weights sum to {sum}");
        if s.is_power_of_two() {
            assert_eq!(sum, 1.0, "S = {s}: 1/S² is exact in binary");
        }
    }
}

/// Two `--light` lamps W wide: each sampled at the S × S cell centres of its square (grid-
/// normalised), each sample 1/S² of the light's 1/√2.
#[test]
fn light_size_makes_square_lamps_of_the_cli_lights() {
    let (mesh, loaded) = load("cornell", 32, ViewChoice::Fitted);
    let cli = [[0.3, 0.9, 0.4], [0.6, 0.8, 0.5]];
    let (w, s) = (0.2, 3u32);
    let src = resolve_sources(&mesh, &loaded, &LightSampling { cli: &cli, cli_size: Some(w), area: s }).unwrap();
    assert_eq!(src.positions.len(), 18);
    let mut want = Vec::new();
    for c in cli {
        for k in 0..s {
            for i in 0..s {
                let at = |c: f64, j: u32| c - w / 2.0 + w * (2 * j + 1) as f64 / (2 * s) as f64;
                want.push(normalised_to_voxel([at(c[0], i), c[1], at(c[2], k)], 32));
            }
        }
    }
    for (p, q) in src.positions.iter().zip(&want) {
        assert!(p.iter().zip(q).all(|(a, b)| (a - b).abs() < 1e-9), "{p:?} against {q:?}");
    }
    assert_eq!(src.light, [vec![0; 9], vec![1; 9]].concat());
    let each = (1.0 / 2f32.sqrt()) / 9.0;
    assert!(src.intensity.iter().all(|&e| e == each));
    // Without an extent a --light stays a point whatever S.
    let src = resolve_sources(&mesh, &loaded, &LightSampling { cli: &cli, cli_size: None, area: 3 }).unwrap();
    assert_eq!(src.positions, resolve_lights(&mesh, &loaded, &cli).unwrap());
}

fn render_lit(mesh: &Mesh, loaded: &LoadedScene, src: &Sources, with_reference: bool) -> (Rendered, Option<RefImage>) {
    let cfg = RenderConfig::diffusion(Preset::Render.light(), NormalMode::Facet);
    let input = RenderInput::new(mesh, loaded, &src.positions).with_sources(src);
    let reference = with_reference.then(|| reference_image_lit(mesh, loaded, &input.point_lights(), &cfg).unwrap());
    let input = match &reference {
        Some(r) => input.compared_with(r),
        None => input,
    };
    let r = render(&input, &cfg, |_, _| {}).unwrap();
    assert_eq!(r.stats.light.lit_overflows, 0, "every lit mark kept");
    (r, reference)
}

/// S = 1: the same sources as without the option, the same intensities as the plain render's
/// lights, the same image and reference to the byte.
#[test]
fn one_sample_is_the_point_light() {
    let (mesh, loaded) = load("cornell", 32, ViewChoice::Auto);
    let lights = resolve_lights(&mesh, &loaded, &[]).unwrap();
    let src = resolve_sources(&mesh, &loaded, &sampling(1)).unwrap();
    assert_eq!(src.positions, lights);
    let plain = host_sim::machine::shading::pixels::point_lights(&lights);
    assert_eq!(host_sim::machine::shading::pixels::weighted_lights(&src.positions, &src.intensity), plain);
    let cfg = RenderConfig::diffusion(Preset::Render.light(), NormalMode::Facet);
    let before = render(&RenderInput::new(&mesh, &loaded, &lights), &cfg, |_, _| {}).unwrap();
    let (after, reference) = render_lit(&mesh, &loaded, &src, true);
    assert_eq!(before.image.rgb, after.image.rgb);
    assert_eq!(before.image.lit, after.image.lit);
    let plain_ref = host_sim::jobs::render::reference_image(&mesh, &loaded, &lights, &cfg).unwrap();
    assert_eq!(reference.unwrap(), plain_ref);
}

/// Mean squared 8-bit error over all pixels and channels.
fn mse(a: &[[u8; 3]], b: &[[u8; 3]]) -> f64 {
    let sq: u64 = a.iter().zip(b).flat_map(|(p, q)| (0..3).map(move |c| u64::from(p[c].abs_diff(q[c])).pow(2))).sum();
    sq as f64 / (3 * a.len()) as f64
}

/// The Cornell box through its camera at n = 64, S = 3.
///
/// * The reference has a penumbra: floor pixels lit by some of the 9 samples and not all, and
///   the machine has such pixels too.
/// * Sample s's lit bit, in the machine and in the reference, is the lit state of a run lit by
///   sample s alone (the sources are diffused, and ray-cast, one after another).
/// * So the (pixel, light) shadow disagreement is the mean of the samples' own, and the image's
///   error is bounded by the point light's: in linear light a pixel whose k of S² samples
///   disagree is off by k/S² of the light's contribution, against all of it for a pixel the
///   point light gets wrong, so with disagreements as frequent per (pixel, light) pair as the
///   point light's the squared error is at most the point light's (equal when the samples of a
///   pixel all err together). The bound allows the measured ratio of the disagreement rates
///   and a factor 2 (3 dB) for the gamma curve, steeper at the darker penumbra levels:
///   MSE₃ ≤ 2 · MSE₁ · max(1, p₃/p₁).
#[test]
fn penumbra_on_the_floor_matches_the_reference() {
    let n = 64;
    let (mesh, loaded) = load("cornell", n, ViewChoice::Auto);
    let screen = mesh.screen.as_ref().expect("the Cornell box through its camera");
    let floor: Vec<bool> =
        mesh.faces.iter().map(|f| f.verts.iter().all(|&v| screen.world[v as usize][1] == 0.0)).collect();
    assert!(floor.iter().any(|&f| f), "the floor is y = 0");
    let src = resolve_sources(&mesh, &loaded, &sampling(3)).unwrap();
    let (area, reference) = render_lit(&mesh, &loaded, &src, true);
    let reference = reference.unwrap();
    let all = (1u32 << 9) - 1;
    let on_floor = |i: usize| reference.covered[i] && floor.get(reference.facet[i] as usize).copied().unwrap_or(false);
    let floor_px: Vec<usize> = (0..reference.lit.len()).filter(|&i| on_floor(i)).collect();
    let partial = |lit: &[u32]| floor_px.iter().filter(|&&i| lit[i] != 0 && lit[i] != all).count();
    let (full, dark) = (
        floor_px.iter().filter(|&&i| reference.lit[i] == all).count(),
        floor_px.iter().filter(|&&i| reference.lit[i] == 0).count(),
    );
    let (ref_pen, machine_pen) = (partial(&reference.lit), partial(&area.image.lit));
    assert!(ref_pen > 0 && full > 0 && dark > 0, "floor: {full} lit, {dark} shadowed, {ref_pen} in penumbra");
    assert!(machine_pen > 0, "the machine's floor has a penumbra too");
    // The penumbra's colour lies strictly between the fully lit and the shadowed floor's.
    let lum = |p: [u8; 3]| p.iter().map(|&c| u32::from(c)).sum::<u32>();
    let max_dark = floor_px.iter().filter(|&&i| reference.lit[i] == 0).map(|&i| lum(reference.rgb[i])).max().unwrap();
    assert!(floor_px
        .iter()
        .any(|&i| reference.lit[i] != 0 && reference.lit[i] != all && lum(reference.rgb[i]) > max_dark));

    // Each sample alone.
    let mut mean_pct = 0.0;
    for (s, p) in src.positions.iter().enumerate() {
        let one = Sources { positions: vec![*p], intensity: vec![src.intensity[s]], light: vec![0] };
        let (r, rf) = render_lit(&mesh, &loaded, &one, true);
        let rf = rf.unwrap();
        let bit = |m: u32| (m >> s) & 1;
        assert!(area.image.lit.iter().zip(&r.image.lit).all(|(a, b)| bit(*a) == *b), "machine, sample {s}");
        assert!(reference.lit.iter().zip(&rf.lit).all(|(a, b)| bit(*a) == *b), "reference, sample {s}");
        mean_pct += r.stats.reference.unwrap().shadow_disagreement_pct / 9.0;
    }
    let c3 = area.stats.reference.unwrap();
    assert!((c3.shadow_disagreement_pct - mean_pct).abs() < 1e-9, "{} against {mean_pct}", c3.shadow_disagreement_pct);

    // The point light at the lamp's centre, against its own reference.
    let point = resolve_sources(&mesh, &loaded, &sampling(1)).unwrap();
    let (r1, rf1) = render_lit(&mesh, &loaded, &point, true);
    let c1 = r1.stats.reference.unwrap();
    let (m1, m3) = (mse(&r1.image.rgb, &rf1.unwrap().rgb), mse(&area.image.rgb, &reference.rgb));
    let ratio = (c3.shadow_disagreement_pct / c1.shadow_disagreement_pct.max(1e-9)).max(1.0);
    assert!(
        m3 <= 2.0 * m1 * ratio,
        "S = 3: MSE {m3:.2} (PSNR {:.2} dB, shadow {:.2} %) against S = 1: MSE {m1:.2} (PSNR {:.2} dB, shadow {:.2} %)",
        c3.psnr_db,
        c3.shadow_disagreement_pct,
        c1.psnr_db,
        c1.shadow_disagreement_pct
    );
}
