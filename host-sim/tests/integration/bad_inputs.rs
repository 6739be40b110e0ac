//! The bad-input catalogue: every malformed scene in `tests/fixtures/bad/`
//! and every bad argument below, through the real binary, gives a one-line `error: …` naming
//! the problem and a non-zero exit, never a panic or an allocator abort. The README's
//! "Troubleshooting" section lists these messages.

use std::path::{Path, PathBuf};
use std::process::Command;

fn host_sim(args: &[&str], env: &[(&str, &str)]) -> (i32, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_host-sim"))
        .args(args)
        .envs(env.iter().copied())
        .output()
        .expect("run host-sim");
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(!stderr.contains("panicked"), "panic on {args:?}:\n{stderr}");
    assert!(!stderr.contains("memory allocation"), "allocator abort on {args:?}:\n{stderr}");
    (out.status.code().unwrap_or(-1), stderr)
}

fn corpus() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../tests/fixtures/bad")
}

fn tmp_dir() -> PathBuf {
    let d = std::env::temp_dir().join(format!("rc2-bad-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// Exactly one `error: ` line, containing `expect`, and a non-zero exit.
fn assert_clear_error(what: &str, code: i32, stderr: &str, expect: &str) {
    assert_ne!(code, 0, "{what} should fail:\n{stderr}");
    let errors: Vec<&str> = stderr.lines().filter(|l| l.starts_with("error")).collect();
    assert_eq!(errors.len(), 1, "{what}: one error line expected:\n{stderr}");
    assert!(errors[0].contains(expect), "{what}: expected '{expect}' in: {}", errors[0]);
}

/// Each corpus file and the message it must produce (`None`: loads, with a warning).
const CORPUS: &[(&str, Option<&str>)] = &[
    ("truncated-face.obj", Some("a face needs at least 3 vertices")),
    ("truncated-vertex.obj", Some("malformed OBJ (position parse error)")),
    ("truncated-mid-number.obj", Some("malformed OBJ (position parse error)")),
    ("binary-junk.obj", Some("not a text OBJ file (invalid UTF-8 at byte")),
    ("utf8-junk.obj", Some("the mesh has no faces")),
    ("zero-index.obj", Some("face vertex index out of bounds")),
    ("negative-index.obj", Some("face vertex index out of bounds")),
    ("out-of-range-index.obj", Some("face vertex index out of bounds")),
    ("huge-index.obj", Some("malformed OBJ (face parse error)")),
    ("nan.obj", Some("non-finite coordinate")),
    ("inf.obj", Some("non-finite coordinate")),
    ("minus-inf.obj", Some("non-finite coordinate")),
    ("overflow-1e309.obj", Some("non-finite coordinate")),
    ("extent-overflow.obj", Some("all vertices coincide (or the extent overflows)")),
    ("far-1e30.obj", Some("every facet is degenerate after quantisation")),
    ("empty.obj", Some("the mesh has no faces")),
    ("comments-only.obj", Some("the mesh has no faces")),
    ("vertices-only.obj", Some("the mesh has no faces")),
    ("single-point.obj", Some("all vertices coincide")),
    ("coincident.obj", Some("all vertices coincide")),
    ("collinear-only.obj", Some("every facet is degenerate after quantisation")),
    ("line-face.obj", Some("a face needs at least 3 vertices")),
    ("bowtie.obj", Some("self-overlapping polygon")),
    ("bad-mtl.obj", None),
];

#[test]
fn every_corpus_file_fails_clearly() {
    let dir = corpus();
    let mut on_disk: Vec<String> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|f| f.ends_with(".obj"))
        .collect();
    on_disk.sort();
    let mut listed: Vec<String> = CORPUS.iter().map(|c| c.0.to_string()).collect();
    listed.sort();
    assert_eq!(on_disk, listed, "the corpus and this table must list the same files");
    let out = tmp_dir().join("out.binvox");
    for (file, expect) in CORPUS {
        let p = dir.join(file);
        for job in ["voxelize", "render"] {
            let mut args = vec![job, p.to_str().unwrap(), "--n", "16", "--quiet", "--out", out.to_str().unwrap()];
            if job == "render" {
                args[6] = "/dev/null";
            }
            let (code, err) = host_sim(&args, &[]);
            match expect {
                Some(e) => assert_clear_error(&format!("{job} {file}"), code, &err, e),
                None => {
                    assert_eq!(code, 0, "{job} {file}: {err}");
                    assert!(err.contains("warning: bad-mtl: material library not loaded"), "{err}");
                }
            }
        }
    }
}

#[test]
fn bad_arguments_fail_clearly() {
    let cases: &[(&[&str], &str)] = &[
        (&["render", "--n", "0"], "too small"),
        (&["render", "--n", "3"], "too small"),
        (&["voxelize", "cornell", "--n", "65537"], "exceeds the largest grid"),
        (&["render", "--n", "65536"], "of memory available"),
        (&["light", "--n", "40000"], "of memory available"),
        (&["light", "empty", "--n", "65536"], "of memory available"),
        (&["render", "--fa", "0"], "--fa 0 is out of range"),
        (&["render", "--fa", "65"], "--fa 65 is out of range"),
        (&["render", "--n", "16", "--light", "1.5,0.5,0.5"], "outside the grid"),
        (&["render", "--n", "16", "--light=-0.1,0.5,0.5"], "outside the grid"),
        (&["render", "--n", "16", "--light", "nan,0.5,0.5"], "outside the grid"),
        (&["render", "--n", "16", "--frac-bits", "9"], "--frac-bits 9 is not supported"),
        (&["render", "--n", "200", "--frac-bits", "24"], "exceeds the beam bit budget"),
        (&["render", "no-such-scene"], "neither a file nor a built-in scene"),
        (&["voxelize", "cornell", "--n", "16", "--dexel-capacity", "7"], "not a compiled dexel capacity"),
        (&["render", "--n", "16", "--light", "0.5,0.5"], "--light"),
        (&["render", "--n", "sixteen"], "--n"),
        // Cameras (docs/CAMERA.md).
        (&["render", "--n", "16", "--eye", "278,273,0", "--look-at", "278,273,0"], "at the look-at point"),
        (&["render", "--n", "16", "--eye", "278,273,-800", "--look-at", "278,273,0", "--up", "0,0,1"], "parallel"),
        (
            &["render", "--n", "16", "--eye", "278,273,-800", "--look-at", "278,273,0", "--fov", "180"],
            "outside (0, 180)",
        ),
        (
            &[
                "render",
                "--n",
                "16",
                "--eye",
                "278,273,-800",
                "--look-at",
                "278,273,0",
                "--near",
                "900",
                "--far",
                "100",
            ],
            "below far",
        ),
        (&["render", "--n", "16", "--eye", "278,273,2000", "--look-at", "278,273,3000"], "behind the eye"),
        (&["render", "--n", "16", "--eye", "278,273,200", "--look-at", "278,273,300"], "behind the eye"),
        (
            &["render", "--n", "16", "--eye", "5000,273,-800", "--look-at", "5000,273,0", "--fov", "10"],
            "inside the camera's view",
        ),
        (&["render", "--n", "16", "--view", "scene", "--reflections", "2"], "--reflections needs the fitted view"),
        (&["render", "--n", "16", "teapot", "--view", "scene"], "no camera of its own"),
        (&["render", "--policy", "fastest"], "--policy"),
        (&["render", "--n", "16", "--hold", "5000"], "--hold"),
        (&["render", "--n", "16", "--skip-frustum", "maybe"], "--skip-frustum"),
        (&["render", "--n", "16", "--lit-visible-only", "false", "--skip-hidden"], "needs the visible-only lit store"),
        (&["light", "--n", "16", "--skip-hidden"], "needs the visible-only lit store"),
        (&["render", "--n", "16", "--skip-hidden", "maybe"], "--skip-hidden"),
        (&["light", "--n", "16", "--skip-frustum", "true", "--frustum-blocks", "12"], "--frustum-blocks"),
        (
            &["render", "--n", "16", "--lighting", "classic", "--lit-rule", "exact", "--ray-connectivity", "18"],
            "use --ray-connectivity 6",
        ),
        (
            &["light", "--n", "16", "--lighting", "classic", "--rays-from", "light"],
            "--rays-from light is a diffusion option",
        ),
        (&["render", "--n", "16", "--fa", "2"], "--rays-from voxel"),
        (&["light", "--n", "16", "--lighting", "refined"], "is a render option"),
        (&["trace", "--n", "16", "--lighting", "refined", "--out", "/nonexistent/t"], "not recorded by trace"),
        (&["render", "--n", "16", "--lighting", "refined", "--lit-rule", "thesis"], "needs visible surfaces"),
        (&["render", "--n", "16", "--lighting", "refined", "--ray-connectivity", "18"], "use --ray-connectivity 6"),
        (
            &["render", "cornell-mirror", "--n", "16", "--lighting", "refined", "--reflections", "1"],
            "without --reflections",
        ),
        (
            &[
                "trace",
                "--n",
                "16",
                "--skip-frustum",
                "true",
                "--frustum-blocks",
                "32",
                "--busiest",
                "--out",
                "/nonexistent/t",
            ],
            "record with --frustum-blocks 8",
        ),
        (
            &["render", "cornell-mirror", "--n", "16", "--reflections", "1", "--lit-visible-only"],
            "run without --lit-visible-only",
        ),
        // Area lights: every sample is a source of the machine (at most 32).
        (&["render", "--n", "16", "--area-light", "6"], "make 36 point sources"),
        (
            &[
                "render",
                "--n",
                "16",
                "--light",
                "0.3,0.9,0.3",
                "--light",
                "0.7,0.9,0.7",
                "--light-size",
                "0.1",
                "--area-light",
                "5",
            ],
            "make 50 point sources",
        ),
        (&["light", "--n", "16", "--area-light", "6"], "at most 32"),
        (&["render", "--n", "16", "--area-light", "0"], "--area-light"),
        (&["render", "--n", "16", "--light-size", "0.2"], "add --light"),
        (&["render", "--n", "16", "--light", "0.05,0.9,0.5", "--light-size", "0.2"], "reaches outside the grid"),
        (&["render", "--n", "16", "--light", "0.5,0.9,0.5", "--light-size", "0"], "0 < W <= 1"),
        (&["render", "--n", "16", "--radiosity", "--area-light", "2"], "point lights only"),
        (&["trace", "--n", "16", "--area-light", "2", "--out", "/nonexistent/t"], "a trace records point lights"),
        // The lit-ray ratio: counted by exact occluders' cells, shown by render's diffusion.
        (&["render", "--n", "16", "--visibility", "ratio", "--lit-rule", "plane"], "needs exact occluders"),
        (&["render", "--n", "16", "--visibility", "majority", "--reflections", "2"], "not done with --reflections"),
        (
            &["render", "--n", "16", "--visibility", "ratio", "--lighting", "classic"],
            "not done with --lighting classic",
        ),
        (&["render", "--n", "16", "--visibility", "ratio", "--radiosity"], "not done with --radiosity"),
        (&["light", "--n", "16", "--visibility", "ratio"], "a render option"),
        // Samples per pixel: 1 to 4, on the visible surface, flat normals.
        (&["render", "--n", "16", "--samples", "0"], "between 1 and 4"),
        (&["render", "--n", "16", "--samples", "5"], "between 1 and 4"),
        (&["render", "--n", "16385", "--samples", "2"], "up to n = 16384"),
        (&["render", "--n", "16", "--samples", "2", "--lit-rule", "thesis"], "not done with --lit-rule thesis"),
        (&["render", "--n", "16", "--samples", "2", "--normals", "phong"], "not done with --normals"),
        (&["render", "--n", "16", "--samples", "2", "--reflections", "1"], "not done with --reflections"),
        (&["render", "--n", "16", "--samples", "2", "--radiosity"], "not done with --radiosity"),
        // Shots in flight: at least one; a choice only with several.
        (&["radiosity", "--n", "16", "--in-flight", "0"], "--in-flight"),
        (&["radiosity", "--n", "16", "--shooter-choice", "rounds"], "required arguments were not provided"),
        (&["no-such-command"], "no-such-command"),
    ];
    for (args, expect) in cases {
        let mut a = args.to_vec();
        match args[0] {
            "render" | "voxelize" => a.extend(["--quiet", "--out", "/dev/null"]),
            "light" => a.push("--quiet"),
            _ => {}
        }
        let (code, err) = host_sim(&a, &[]);
        assert_clear_error(&format!("{args:?}"), code, &err, expect);
    }
    // The memory guard, forced: a modest grid against a 1 MiB limit.
    let (code, err) =
        host_sim(&["render", "--n", "64", "--quiet", "--out", "/dev/null"], &[("RC2_MEMORY_LIMIT_MIB", "1")]);
    assert_clear_error("memory limit", code, &err, "of memory available");
}

/// Two million copies of one face: loaded as one facet (the copies are counted skips), same
/// voxels as the face alone, in seconds rather than two million wave cycles.
#[test]
fn millions_of_duplicate_faces() {
    let dir = tmp_dir();
    let head = "v 0 0 0\nv 1 0 0\nv 0 1 0.3\n";
    let one = dir.join("one.obj");
    std::fs::write(&one, format!("{head}f 1 2 3\n")).unwrap();
    let many = dir.join("dup.obj");
    let mut text = String::from(head);
    text.push_str(&"f 1 2 3\n".repeat(2_000_000));
    std::fs::write(&many, text).unwrap();
    let stats = |p: &Path| -> serde_json::Value {
        let s = p.with_extension("json");
        let (code, err) = host_sim(
            &[
                "voxelize",
                p.to_str().unwrap(),
                "--n",
                "32",
                "--quiet",
                "--out",
                "/dev/null",
                "--stats",
                s.to_str().unwrap(),
            ],
            &[],
        );
        assert_eq!(code, 0, "{err}");
        serde_json::from_str(&std::fs::read_to_string(s).unwrap()).unwrap()
    };
    let (a, b) = (stats(&one), stats(&many));
    assert_eq!(b["faces"], 2_000_000);
    assert_eq!(b["facets"], 1);
    assert_eq!(b["facets_skipped"], 1_999_999);
    assert_eq!(a["voxels"], b["voxels"]);
    assert!(b["load_cycles"].as_u64().unwrap() < 1000);
    let _ = std::fs::remove_file(many);
}

/// Smooth shading reads the file's vertex normals: one that is not a direction (NaN, infinite,
/// zero length) or an index past the file's `vn` lines is a clear error naming it, and a smooth
/// mode the run cannot do (the thesis's lit rule) is refused before any work.
#[test]
fn bad_vertex_normals_fail_clearly_under_smooth_shading() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../tests/fixtures/normals");
    let cases = [
        ("bad-vn-nan.obj", "normal 2 (vn NaN 0 1) of face 1 is not a direction"),
        ("bad-vn-inf.obj", "normal 2 (vn inf 0 1) of face 1 is not a direction"),
        ("bad-vn-zero.obj", "normal 2 (vn 0 0 0) of face 1 is not a direction"),
        ("bad-vn-index.obj", "face normal index out of bounds"),
    ];
    for (file, expect) in cases {
        let p = dir.join(file);
        for mode in ["phong", "gouraud"] {
            let args = ["render", p.to_str().unwrap(), "--n", "16", "--normals", mode, "--quiet", "--out", "/dev/null"];
            let (code, err) = host_sim(&args, &[]);
            assert_clear_error(&format!("{file} --normals {mode}"), code, &err, expect);
        }
    }
    let (code, err) = host_sim(&["render", "--n", "16", "--normals", "phong", "--lit-rule", "thesis", "--quiet"], &[]);
    assert_clear_error("--normals phong --lit-rule thesis", code, &err, "need --lit-rule plane or exact");
}
