//! s × s samples per pixel (issue 54 item 5(c), `cell_core::subpixel`) against independent
//! oracles:
//!
//! * each sample's hit test against exact rational geometry on the lattice triangle itself
//!   (point in the projected triangle by the signs of its edges' cross products, depth from
//!   the plane through its vertices), not from the packet's coefficients: at every sample of
//!   every column of small facets in every orientation, thin and watertight surfaces, and at
//!   the bit budget's limit (n = MAX_SAMPLED_N, facets spanning the grid);
//! * one sample (s = 1), and the middle one of 3 × 3, against the centre line's own test
//!   (`cell_core::visible::hit`);
//! * the render: samples leave the lighting as it was (cycles, beams, coverage, lit masks) and
//!   bring the image nearer the reference that averages 4 × 4 points per pixel than one sample
//!   does, on the Cornell box through its camera and on teapot-floor.

use cell_core::dexel::FacetTag;
use cell_core::subpixel::{hit_at, RowSlopes, Sample, SampleHit, MAX_SAMPLED_N, MAX_SAMPLES};
use host_sim::machine::shading::smooth_surface::row_at;
use host_sim::precompute::{facet_packet, LoadConfig, Q};
use host_sim::rng::Rng;

/// What the oracle says of a sample's line and a triangle.
#[derive(Debug, PartialEq)]
enum Truth {
    /// Strictly inside the projected triangle, at depth z* = num/den voxels (den > 0).
    Inside(i128, i128),
    /// On one of its edges (either answer is right: the host's strict bit decides), at that depth.
    OnEdge(i128, i128),
    /// Strictly outside, or seen edge-on.
    Outside,
}

/// The oracle, exact in `i128`: the sample's point in lattice units times 2s is
/// `2s·(Q·x + Q/2) + Q·m` (voxel x's centre at lattice Q·x + Q/2).
fn truth(tri: &[[i64; 3]; 3], x: u32, y: u32, at: Sample) -> Truth {
    let s2 = 2 * at.s as i128;
    let q = Q as i128;
    let p = [s2 * (q * x as i128 + q / 2) + q * at.mx as i128, s2 * (q * y as i128 + q / 2) + q * at.my as i128];
    let v: Vec<[i128; 3]> = tri.iter().map(|a| a.map(|c| c as i128)).collect();
    let cross2 = |a: [i128; 3], b: [i128; 3], pt: [i128; 2]| {
        (b[0] - a[0]) * (pt[1] - s2 * a[1]) - (b[1] - a[1]) * (pt[0] - s2 * a[0])
    };
    let area = (v[1][0] - v[0][0]) * (v[2][1] - v[0][1]) - (v[1][1] - v[0][1]) * (v[2][0] - v[0][0]);
    if area == 0 {
        return Truth::Outside;
    }
    let e = [cross2(v[0], v[1], p), cross2(v[1], v[2], p), cross2(v[2], v[0], p)].map(|e| e * area.signum());
    if e.iter().any(|&e| e < 0) {
        return Truth::Outside;
    }
    // The plane N·(P − V0) = 0 with N = (V1 − V0) × (V2 − V0): Z = V0z − (Nx·ΔX + Ny·ΔY)/Nz, in
    // lattice units times 2s; z* = (Z − Q/2)/Q voxels.
    let d = |k: usize, c: usize| v[k][c] - v[0][c];
    let nv = [d(1, 1) * d(2, 2) - d(1, 2) * d(2, 1), d(1, 2) * d(2, 0) - d(1, 0) * d(2, 2), area];
    let z_num = s2 * v[0][2] * nv[2] - (nv[0] * (p[0] - s2 * v[0][0]) + nv[1] * (p[1] - s2 * v[0][1]));
    // Z·2s = z_num / nv[2]; z* = (Z − Q/2)/Q = (z_num − s2·(Q/2)·nz) / (s2·Q·nz).
    let (mut num, mut den) = (z_num - s2 * (q / 2) * nv[2], s2 * q * nv[2]);
    if den < 0 {
        (num, den) = (-num, -den);
    }
    if e.contains(&0) {
        Truth::OnEdge(num, den)
    } else {
        Truth::Inside(num, den)
    }
}

/// Check every sample of every column of `cols` for the facet `tri` at grid side `n` (both
/// contour modes); returns the number of samples strictly inside that were checked.
fn check(n: u32, tri: &[[i64; 3]; 3], s: u32, cols: &[(u32, u32)]) -> usize {
    let mut inside = 0;
    for cfg in [LoadConfig::watertight(n), LoadConfig::thin(n)] {
        let Ok(pkt) = facet_packet(tri, FacetTag::default(), &cfg).unwrap() else { continue };
        let slopes = RowSlopes::of(&pkt);
        let b = cell_core::subpixel::sampled_box(pkt.bbox, n);
        for &(x, y) in cols {
            let in_box =
                (b.x_min as u32..=b.x_max as u32).contains(&x) && (b.y_min as u32..=b.y_max as u32).contains(&y);
            let row = row_at(&pkt, x, y);
            for at in Sample::all(s) {
                let want = truth(tri, x, y, at);
                let in_depth = |num: i128, den: i128| 2 * num >= -den && 2 * num < (2 * n as i128 - 1) * den;
                // A packet reaches only its (sampled) box: a facet met outside it would be lost.
                if let Truth::Inside(num, den) = want {
                    if in_depth(num, den) {
                        assert!(in_box, "{tri:?} n = {n}: sample {at:?} of ({x}, {y}) meets the facet outside its box");
                    }
                }
                if !in_box {
                    continue;
                }
                let got = hit_at(&row, &slopes, at, n);
                let same = |num: i128, den: i128, a: i64, b: i64| num * b as i128 == a as i128 * den;
                match (want, got) {
                    (Truth::Inside(num, den), SampleHit::Hit(a, b)) => {
                        assert!(same(num, den, a, b), "{tri:?} ({x}, {y}) {at:?}: z* {a}/{b}, truth {num}/{den}");
                        inside += 1;
                    }
                    (Truth::Inside(num, den), SampleHit::Miss) => {
                        assert!(!in_depth(num, den), "{tri:?} n = {n} ({x}, {y}) {at:?}: inside at {num}/{den}, missed")
                    }
                    (Truth::OnEdge(num, den), SampleHit::Hit(a, b)) => assert!(same(num, den, a, b)),
                    (Truth::OnEdge(..), SampleHit::Miss) => {}
                    (Truth::Outside, SampleHit::Miss) => {}
                    (w, g) => panic!("{tri:?} n = {n} ({x}, {y}) {at:?}: truth {w:?}, cell {g:?}"),
                }
            }
        }
    }
    inside
}

/// Every column of a facet's box, one column around it too.
fn box_columns(tri: &[[i64; 3]; 3], n: u32) -> Vec<(u32, u32)> {
    let range = |k: usize| {
        let lo = (tri.iter().map(|p| p[k]).min().unwrap() / Q - 1).max(0);
        let hi = (tri.iter().map(|p| p[k]).max().unwrap() / Q + 1).min(n as i64 - 1);
        lo as u32..=hi as u32
    };
    range(1).flat_map(|y| range(0).map(move |x| (x, y))).collect()
}

/// Small and thin facets at n = 24 in every orientation, every sample of every column of their
/// box, for s = 1 … 4.
#[test]
fn sample_hits_match_exact_lattice_geometry_on_small_facets() {
    let mut rng = Rng(0x5a_3b1e);
    let n = 24;
    let mut inside = [0; MAX_SAMPLES as usize];
    for _ in 0..80 {
        let tri: [[i64; 3]; 3] = std::array::from_fn(|_| std::array::from_fn(|_| (rng.f() * (Q * 24) as f64) as i64));
        let cols = box_columns(&tri, n);
        for s in 1..=MAX_SAMPLES {
            inside[s as usize - 1] += check(n, &tri, s, &cols);
        }
    }
    assert!(inside.iter().all(|&k| k > 2_000), "samples strictly inside, by s: {inside:?}");
}

/// At the bit budget's limit (n = MAX_SAMPLED_N, vertices on the lattice's corners, needles
/// across the grid): exact, no overflow.
#[test]
fn sample_hits_are_exact_at_the_bit_budget() {
    let n = MAX_SAMPLED_N;
    let facets = crate::common::budget_facets(n);
    let mut rng = Rng(54);
    let mut inside = 0;
    for tri in &facets {
        // Columns at the corners, along the diagonals and at random.
        let mut cols = vec![(0, 0), (n - 1, 0), (0, n - 1), (n - 1, n - 1), (n / 2, n / 2)];
        cols.extend((0..40).map(|_| ((rng.f() * n as f64) as u32, (rng.f() * n as f64) as u32)));
        cols.extend((0..20).map(|_| {
            let t = (rng.f() * n as f64) as u32;
            (t, n - 1 - t)
        }));
        for s in 1..=MAX_SAMPLES {
            inside += check(n, tri, s, &cols);
        }
    }
    assert!(inside > 500, "only {inside} samples inside");
}

/// One sample per side is the centre line; so is the middle sample of 3 × 3.
#[test]
fn the_centre_sample_is_the_centre_lines_hit() {
    let mut rng = Rng(7);
    let n = 32;
    let mut met = 0;
    for _ in 0..60 {
        let tri: [[i64; 3]; 3] = std::array::from_fn(|_| std::array::from_fn(|_| (rng.f() * (Q * 32) as f64) as i64));
        let Ok(pkt) = facet_packet(&tri, FacetTag::default(), &LoadConfig::watertight(n)).unwrap() else { continue };
        let slopes = RowSlopes::of(&pkt);
        for (x, y) in box_columns(&tri, n) {
            let row = row_at(&pkt, x, y);
            let centre = cell_core::visible::hit(&row, n);
            for at in [Sample::new(0, 0, 1).unwrap(), Sample::new(1, 1, 3).unwrap()] {
                let got = match hit_at(&row, &slopes, at, n) {
                    SampleHit::Hit(a, b) => Some((a, b)),
                    SampleHit::Miss => None,
                    SampleHit::Overflow => panic!("overflow at n = {n}"),
                };
                match (centre, got) {
                    (Some((a, b)), Some((c, d))) => assert_eq!(a as i128 * d as i128, c as i128 * b as i128),
                    (None, None) => {}
                    other => panic!("{tri:?} ({x}, {y}) {at:?}: {other:?}"),
                }
                met += centre.is_some() as usize;
            }
        }
    }
    assert!(met > 500, "{met}");
}

/// Render `scene` through its default view at n with S × S samples (the render's default
/// diffusion).
fn render_sampled(scene: &str, n: u32, s: u32) -> host_sim::jobs::render::Rendered {
    render_sampled_with(scene, n, s, cell_core::visibility::Visibility::Target)
}

/// [`render_sampled`] with the pixels' lights decided by `visibility`.
fn render_sampled_with(
    scene: &str,
    n: u32,
    s: u32,
    visibility: cell_core::visibility::Visibility,
) -> host_sim::jobs::render::Rendered {
    use host_sim::jobs::render::{render, RenderConfig, RenderInput};
    let mesh = host_sim::scene::camera::apply(
        host_sim::scene::load(scene).unwrap(),
        &host_sim::scene::camera::ViewChoice::Auto,
        n,
    )
    .unwrap();
    let load = LoadConfig::watertight(n);
    let loaded = host_sim::machine::loading::loaded_scene::load_scene(&mesh, &load).unwrap();
    let lights = host_sim::machine::loading::loaded_scene::resolve_lights(&mesh, &loaded, &[]).unwrap();
    let grid = (s > 1).then(|| {
        host_sim::machine::shading::samples::sample_grid(&mesh, &loaded, &load, s, Default::default()).unwrap()
    });
    let light =
        host_sim::machine::lighting::diffuse::LightConfig { visibility, ..host_sim::config::Preset::Render.light() };
    let cfg = RenderConfig { samples: s, ..RenderConfig::diffusion(light, cell_core::shade::NormalMode::Facet) };
    let input = RenderInput { samples: grid.as_ref(), ..RenderInput::new(&mesh, &loaded, &lights) };
    render(&input, &cfg, |_, _| {}).unwrap()
}

/// The reference of `scene` at n averaging s × s points per pixel.
fn reference_sampled(scene: &str, n: u32, s: u32) -> host_sim::truth::refrender::RefImage {
    use host_sim::jobs::render::{reference_image, RenderConfig};
    let mesh = host_sim::scene::camera::apply(
        host_sim::scene::load(scene).unwrap(),
        &host_sim::scene::camera::ViewChoice::Auto,
        n,
    )
    .unwrap();
    let loaded = host_sim::machine::loading::loaded_scene::load_scene(&mesh, &LoadConfig::watertight(n)).unwrap();
    let lights = host_sim::machine::loading::loaded_scene::resolve_lights(&mesh, &loaded, &[]).unwrap();
    let cfg = RenderConfig {
        samples: s,
        ..RenderConfig::diffusion(host_sim::config::Preset::Render.light(), cell_core::shade::NormalMode::Facet)
    };
    reference_image(&mesh, &loaded, &lights, &cfg).unwrap()
}

/// Samples change the picture, not the machine's lighting: the same cycles, beams, coverage and
/// lit masks as one sample; and against the reference that averages 4 × 4 points per pixel
/// (the limit the samples approach) the image comes nearer with 2 × 2 and 4 × 4 samples than
/// with one.
#[test]
fn samples_bring_the_image_nearer_the_supersampled_reference() {
    let n = 48;
    for scene in ["cornell", "teapot-floor"] {
        let truth = reference_sampled(scene, n, 4);
        let one = render_sampled(scene, n, 1);
        let all = vec![true; (n * n) as usize];
        let psnr =
            |r: &host_sim::jobs::render::Rendered| host_sim::truth::compare::psnr(&r.image.rgb, &truth.rgb, &all);
        let base = psnr(&one);
        for s in [2, 4] {
            let r = render_sampled(scene, n, s);
            assert_eq!(r.stats.light.totals.cycles, one.stats.light.totals.cycles, "{scene} S = {s}");
            assert_eq!(r.stats.light.totals.beams_processed, one.stats.light.totals.beams_processed);
            assert_eq!((&r.image.covered, &r.image.lit), (&one.image.covered, &one.image.lit), "{scene} S = {s}");
            let st = r.stats.samples.as_ref().expect("sample statistics");
            assert_eq!((st.samples_per_pixel, st.overflows), (s * s, 0));
            assert!(st.mixed_pixels > 0 && st.exchange_messages > 0);
            let got = psnr(&r);
            eprintln!(
                "{scene} n = {n}: PSNR against the 4 × 4 reference, 1 sample {base:.2} dB, {s} × {s} {got:.2} dB"
            );
            assert!(got > base, "{scene}: {s} × {s} samples {got:.2} dB, one {base:.2} dB");
        }
    }
}

/// Under the lit-ray ratio the samples borrow their neighbours' weights: the image comes nearer
/// the 4 × 4 reference with 2 × 2 samples than with one, the lighting the same.
#[test]
fn samples_borrow_the_lit_ray_ratio() {
    let (n, ratio) = (48, cell_core::visibility::Visibility::Ratio);
    let truth = reference_sampled("cornell", n, 4);
    let all = vec![true; (n * n) as usize];
    let psnr = |r: &host_sim::jobs::render::Rendered| host_sim::truth::compare::psnr(&r.image.rgb, &truth.rgb, &all);
    let (one, two) = (render_sampled_with("cornell", n, 1, ratio), render_sampled_with("cornell", n, 2, ratio));
    assert_eq!(two.stats.light.totals.beams_processed, one.stats.light.totals.beams_processed);
    assert_eq!(two.image.lit, one.image.lit);
    let st = two.stats.samples.as_ref().expect("sample statistics");
    assert_eq!(st.exchange_bytes_per_message, 6 + 1, "facet, normal code and one weight");
    assert!(psnr(&two) > psnr(&one), "2 × 2 {:.2} dB, one {:.2} dB", psnr(&two), psnr(&one));
}
