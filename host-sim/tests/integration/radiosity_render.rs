//! `render --radiosity` against its independent oracle: the image shaded with the f64 reference
//! solver's per-patch radiosity (ray-cast form factors, the same patches and stopping rule),
//! shown the same way at each exact hit point (`jobs::render_radiosity`). On a small Cornell box
//! through its camera, for both displays: the machine's radiosity image is closer to that
//! reference than the direct-light-only image is, and the colour bleeding the reference shows
//! (the white ceiling redder on the red wall's side, greener on the green wall's) is in the
//! machine's image too, while direct light alone has none. Bad input goes through the binary.

use cell_core::shade::NormalMode;
use host_sim::jobs::radiosity::RadiositySettings;
use host_sim::jobs::render::{render, RenderConfig, RenderInput, Rendered};
use host_sim::jobs::render_radiosity::{solve, F64Solution};
use host_sim::machine::lighting::diffuse::LightConfig;
use host_sim::machine::loading::loaded_scene::{load_scene, resolve_lights};
use host_sim::machine::shooting::indirect::Display;
use host_sim::precompute::LoadConfig;
use host_sim::scene::camera::{apply, ViewChoice};
use host_sim::scene::patches::area_vector;
use host_sim::scene::Mesh;
use host_sim::truth::compare::compare;
use host_sim::truth::refrender::RefImage;
use parry3d_f64::math::Vector;

/// The machine's radiosity renders of the Cornell box at grid side `n` (its camera, the render
/// defaults), one per display of one solution, each with the reference shaded with the f64
/// solver's radiosity shown the same way.
fn cornell(n: u32, displays: &[Display]) -> (Mesh, Vec<(Display, Rendered, RefImage)>) {
    let mesh = apply(host_sim::scene::load("cornell").unwrap(), &ViewChoice::Auto, n).unwrap();
    let load = LoadConfig::watertight(n);
    let loaded = load_scene(&mesh, &load).unwrap();
    let lights = resolve_lights(&mesh, &loaded, &[]).unwrap();
    let light = LightConfig { lit_visible_only: true, skip_hidden: true, ..host_sim::config::plane_rule() };
    let cfg = RenderConfig::diffusion(light, NormalMode::Facet);
    // Patches of n/4 voxels (about 190), a budget of 200 shots, the same stopping rule for both
    // solvers: residual ≈ 0.07, so the ambient term of §1.3.2 (uniform, what is still unshot)
    // no longer hides the bleeding.
    let settings = RadiositySettings { patch_size: n as f64 / 4.0, shots: 200, ..Default::default() };
    let solved = solve(&mesh, &loaded, &load, &settings, true, false, true).unwrap();
    let renders = displays
        .iter()
        .map(|&display| {
            let shown = solved.show(&mesh, &loaded, &lights, display, light.rule).unwrap();
            let reference = solved
                .f64_image(F64Solution::Reference, &shown, &mesh, &loaded, &lights)
                .unwrap()
                .expect("asked for it");
            let input = RenderInput { indirect: Some(&shown.cells), ..RenderInput::new(&mesh, &loaded, &lights) };
            let r = render(&input.compared_with(&reference), &cfg, |_, _| {}).unwrap();
            (display, r, reference)
        })
        .collect();
    (mesh, renders)
}

/// How much greener than red the ceiling is, in linear chromaticity `(G − R)/(R + G + B)` of
/// the sums over its pixels, on the green wall's half of the image less on the red wall's.
/// The ceiling (a white face facing down) gets no direct light from the light just below it,
/// so its colour is indirect light, never clamped at 255 by the direct term. The reference
/// says which face a pixel shows (its material, its normal in world space).
fn bleeding(mesh: &Mesh, reference: &RefImage, rgb: &[[u8; 3]]) -> f64 {
    let n = reference.n as usize;
    let world = &mesh.screen.as_ref().expect("seen through the camera").world;
    let face = |i: usize| mesh.faces.get(reference.facet[i] as usize);
    let material = |i: usize| face(i).map(|f| mesh.materials[f.material as usize].name.as_str());
    let faces_down = |f: &host_sim::scene::Face| {
        let poly: Vec<Vector> = f.verts.iter().map(|&v| Vector::from(world[v as usize])).collect();
        area_vector(&poly).normalize().y < -0.99
    };
    let ceiling = |i: usize| material(i) == Some("white") && face(i).is_some_and(faces_down);
    // Which half of the image each wall is on.
    let mean_x = |m: &str| {
        let xs: Vec<usize> = (0..n * n).filter(|&i| material(i) == Some(m)).map(|i| i % n).collect();
        assert!(!xs.is_empty(), "the reference shows the {m} wall");
        xs.iter().sum::<usize>() as f64 / xs.len() as f64
    };
    let green_left = mean_x("green") < mean_x("red");
    let linear = |c: u8| (c as f64 / 255.0).powf(2.2);
    let greenness = |green_half: bool| {
        let px: Vec<usize> =
            (0..n * n).filter(|&i| ((i % n < n / 2) == green_left) == green_half && ceiling(i)).collect();
        assert!(px.len() > 20, "ceiling pixels: {}", px.len());
        let sum = |c: usize| px.iter().map(|&i| linear(rgb[i][c])).sum::<f64>();
        (sum(1) - sum(0)) / (sum(0) + sum(1) + sum(2))
    };
    greenness(true) - greenness(false)
}

#[test]
fn radiosity_images_are_closer_to_the_radiosity_reference_and_bleed_its_colours() {
    let (mesh, renders) = cornell(48, &[Display::Smooth, Display::Flat]);
    for (display, r, reference) in renders {
        let direct = r.direct_only.as_ref().expect("a radiosity render keeps its direct-only image");
        let machine = r.stats.reference.expect("compared").psnr_db;
        let direct_psnr = compare(&direct.rgb, &direct.covered, &direct.lit, &reference).psnr_db;
        // The direct image lacks the whole indirect term; the machine's differs from the
        // reference's by its per-patch error (form factors through the voxel grid, a few %)
        // and by the direct light both images share. Ask for at most half the RMS error of
        // the direct image: 6 dB.
        assert!(
            machine >= direct_psnr + 6.0,
            "{display:?}: radiosity {machine:.2} dB, direct only {direct_psnr:.2} dB"
        );

        // Colour bleeding: the white ceiling greener on the green wall's side, redder on the
        // red wall's.
        let bleed = |rgb: &[[u8; 3]]| bleeding(&mesh, &reference, rgb);
        let (want, got, none) = (bleed(&reference.rgb), bleed(&r.image.rgb), bleed(&direct.rgb));
        // The oracle shows it (white light on a white ceiling: no difference between the
        // halves under direct light alone, to rounding).
        assert!(
            want > 0.02 && none.abs() < 0.1 * want,
            "{display:?}: reference bleeding {want:.4}, direct only {none:.4}"
        );
        // The machine shows it too, weaker: its form factors are point-to-area from each
        // patch's centre pushed --offset (2) voxels off it, which underestimates the exchange
        // between patches meeting at a corner — the ceiling strip along each wall. At least
        // 40 %, at most 125 %: a machine that lost the indirect light or swapped the walls'
        // colours gives 0 or less.
        assert!(got >= 0.4 * want && got <= 1.25 * want, "{display:?}: machine bleeding {got:.4}, reference {want:.4}");
    }
}

fn host_sim(args: &[&str]) -> (i32, String) {
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_host-sim")).args(args).output().expect("run host-sim");
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(!stderr.contains("panicked"), "panic on {args:?}:\n{stderr}");
    (out.status.code().unwrap_or(-1), stderr)
}

/// One `error: ` line containing `expect`, and a non-zero exit.
fn assert_clear_error(args: &[&str], expect: &str) {
    let (code, err) = host_sim(args);
    assert_ne!(code, 0, "{args:?} should fail:\n{err}");
    let errors: Vec<&str> = err.lines().filter(|l| l.starts_with("error")).collect();
    assert_eq!(errors.len(), 1, "{args:?}: one error line expected:\n{err}");
    assert!(errors[0].contains(expect), "{args:?}: expected '{expect}' in: {}", errors[0]);
}

#[test]
fn bad_radiosity_renders_fail_clearly() {
    // A scene with no emitting surface and no light of its own (an OBJ without materials).
    let dir = std::env::temp_dir().join(format!("rc2-radiosity-render-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let obj = dir.join("dark.obj");
    std::fs::write(&obj, "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0 0 1\nf 1 2 3 4\nf 1 2 5\n").unwrap();
    let dark = obj.to_str().unwrap();
    let out = dir.join("r.png");
    let base = |scene: &str, extra: &[&str]| -> Vec<String> {
        let out = out.to_str().unwrap();
        ["render", scene, "--n", "16", "--quiet", "--out", out].iter().chain(extra).map(|s| s.to_string()).collect()
    };
    // Every face zero-area.
    let flat = dir.join("flat.obj");
    std::fs::write(&flat, "v 0 0 0\nv 1 0 0\nv 2 0 0\nv 0 1 0\nf 1 2 3\n").unwrap();
    let flat = flat.to_str().unwrap();
    let big = |extra: &[&str]| -> Vec<String> {
        let mut a = base("cornell", extra);
        a[3] = "48".into();
        a
    };
    let cases = [
        (base(dark, &["--radiosity"]), "nothing emits"),
        (base(flat, &["--radiosity"]), "every facet is degenerate"),
        // Patches beyond what the cells hold: a column crossing more than the compiled patch
        // map's runs, and more patches than a 16-bit id names.
        (big(&["--radiosity", "--patch-size", "1.5"]), "do not fit the cells' patch maps"),
        (base("cornell", &["--radiosity", "--patch-size", "0.01"]), "above the cap of 65535"),
        (base("empty", &["--radiosity"]), "nothing emits"),
        (base("cornell-mirror", &["--radiosity", "--reflections", "1"]), "cannot be combined with --reflections"),
        (base("cornell", &["--shots", "5"]), "--shots is a radiosity option: add --radiosity"),
        (base("cornell", &["--radiosity-display", "flat"]), "--radiosity-display is a radiosity option"),
        (base("cornell", &["--radiosity", "--residual", "1.5"]), "residual must be in [0, 1)"),
        (base("cornell", &["--radiosity", "--patch-size", "0"]), "patch size in voxels must be positive"),
        (base("cornell", &["--radiosity", "--offset=-1"]), "source offset"),
        (base("cornell", &["--radiosity", "--radiosity-display", "gouraud"]), "--radiosity-display"),
    ];
    for (args, expect) in cases {
        let a: Vec<&str> = args.iter().map(String::as_str).collect();
        assert_clear_error(&a, expect);
    }
}

/// A zero-area face among good ones gets no patch: counted in the stats and the summary, and
/// the render goes on (a lamp over a floor, seen from above, with a collinear triangle).
#[test]
fn zero_area_faces_are_counted_and_reported() {
    let dir = std::env::temp_dir().join(format!("rc2-radiosity-zero-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(dir.join("lamp.mtl"), "newmtl white\nKd 0.7 0.7 0.7\nnewmtl lamp\nKd 0 0 0\nKe 5 5 5\n").unwrap();
    let obj = "mtllib lamp.mtl\nv 0 0 0\nv 4 0 0\nv 4 4 0\nv 0 4 0\nv 1.5 1.5 3\nv 2.5 1.5 3\nv 2.5 2.5 3\n\
               v 1.5 2.5 3\nv 1 1 1\nv 2 1 1\nv 3 1 1\nusemtl white\nf 1 2 3 4\nusemtl lamp\nf 5 8 7 6\n\
               usemtl white\nf 9 10 11\n";
    std::fs::write(dir.join("lamp.obj"), obj).unwrap();
    let (obj, out, stats) = (dir.join("lamp.obj"), dir.join("l.png"), dir.join("l.json"));
    let args = ["render", obj.to_str().unwrap(), "--n", "32", "--quiet", "--radiosity", "--out"];
    let args: Vec<&str> =
        args.iter().copied().chain([out.to_str().unwrap(), "--stats", stats.to_str().unwrap()]).collect();
    let (code, err) = host_sim(&args);
    assert_eq!(code, 0, "{err}");
    assert!(err.contains("zero-area faces skipped 1"), "{err}");
    let json: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&stats).unwrap()).unwrap();
    let solution = &json["radiosity"]["solution"];
    assert_eq!(solution["zero_area_faces"], 1, "{solution}");
    assert_eq!(solution["unmapped_voxels"], 0, "{solution}");
    // Every covered pixel shows a patch: the skipped face left no voxel behind.
    assert!(json["covered_pixels"].as_u64().unwrap() > 0, "{json}");
    assert_eq!(json["radiosity"]["pixels_without_patch"], 0, "{json}");
}
