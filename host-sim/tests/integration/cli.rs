//! Bad input through the real binary: a clear one-line error, a non-zero exit, never a panic.

use std::path::PathBuf;
use std::process::Command;

fn host_sim(args: &[&str]) -> (i32, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_host-sim")).args(args).output().expect("run host-sim");
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(!stderr.contains("panicked"), "panic on {args:?}:\n{stderr}");
    (out.status.code().unwrap_or(-1), stderr)
}

fn tmp(name: &str, contents: &[u8]) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("rc2-cli-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let p = dir.join(name);
    std::fs::write(&p, contents).unwrap();
    p
}

fn voxelize_file(name: &str, contents: &[u8]) -> (i32, String) {
    let p = tmp(name, contents);
    let out = p.with_extension("binvox");
    host_sim(&["voxelize", p.to_str().unwrap(), "--n", "32", "--quiet", "--out", out.to_str().unwrap()])
}

/// Voxelize OBJ text into an n-grid and return the exit code, stderr and the stats JSON.
fn voxelize_with_stats(name: &str, obj: &[u8], n: &str) -> (i32, String, serde_json::Value) {
    let p = tmp(name, obj);
    let stats = p.with_extension("json");
    let out = p.with_extension("binvox");
    let (code, err) = host_sim(&[
        "voxelize",
        p.to_str().unwrap(),
        "--n",
        n,
        "--quiet",
        "--out",
        out.to_str().unwrap(),
        "--stats",
        stats.to_str().unwrap(),
    ]);
    let s = std::fs::read_to_string(stats).ok().and_then(|t| serde_json::from_str(&t).ok());
    (code, err, s.unwrap_or_default())
}

#[test]
fn malformed_and_empty_obj() {
    let cases: &[(&str, &[u8], &str)] = &[
        ("bad-index.obj", b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 7\n", "vertex"),
        ("junk.obj", &[0xff, 0xfe, 0x00, 0x12, 0x80, 0x81], "not a text OBJ"),
        ("garbage-number.obj", b"v 0 0 zero\nv 1 0 0\nv 0 1 0\nf 1 2 3\n", "malformed OBJ"),
        ("empty.obj", b"# nothing here\n", "no faces"),
        ("point.obj", b"v 1 1 1\nv 1 1 1\nv 1 1 1\nf 1 2 3\n", "coincide"),
        ("nan.obj", b"v 0 0 0\nv 1 0 NaN\nv 0 1 0\nf 1 2 3\n", "non-finite"),
        ("inf.obj", b"v 0 0 0\nv 1 0 inf\nv 0 1 0\nf 1 2 3\n", "non-finite"),
        ("bowtie.obj", b"v 0 0 0\nv 1 1 0\nv 1 0 0\nv 0 1 0\nf 1 2 3 4\n", "face 1"),
    ];
    for (name, text, expect) in cases {
        let (code, err) = voxelize_file(name, text);
        assert_ne!(code, 0, "{name} should fail");
        assert!(err.contains(expect), "{name}: expected '{expect}' in: {err}");
        assert!(err.lines().any(|l| l.starts_with("error: ")), "{name}: {err}");
    }
}

#[test]
fn degenerate_facets_are_counted_skips() {
    // One good triangle, one zero-area triangle (collinear), one repeated vertex.
    let obj = b"v 0 0 0\nv 1 0 0\nv 0 1 0\nv 2 0 0\nf 1 2 3\nf 1 2 4\nf 1 1 2\n";
    let (code, err, s) = voxelize_with_stats("degenerate.obj", obj, "16");
    assert_eq!(code, 0, "{err}");
    assert_eq!(s["facets"], 1);
    assert_eq!(s["facets_skipped"], 2);
    assert!(s["voxels"].as_u64().unwrap() > 0);
}

#[test]
fn non_planar_and_non_convex_polygons_are_split_and_counted() {
    // A skewed quad (non-planar) and an L-shaped hexagon (non-convex, planar).
    let obj = b"v 0 0 0\nv 1 0 0\nv 1 1 0.3\nv 0 1 0\n\
v 0 0 2\nv 2 0 2\nv 2 1 2\nv 1 1 2\nv 1 2 2\nv 0 2 2\nf 1 2 3 4\nf 5 6 7 8 9 10\n";
    let (code, err, s) = voxelize_with_stats("polys.obj", obj, "32");
    assert_eq!(code, 0, "{err}");
    assert_eq!(s["polygons_split"], 2);
    assert_eq!(s["facets"], 2 + 4);
}

#[test]
fn far_vertex_warns_and_bad_arguments_fail() {
    let mut obj = String::from("v 1e30 1e30 1e30\n");
    for i in 0..20 {
        obj += &format!("v {i} 0 0\nv {i} 1 0\nv {i} 0 1\n");
    }
    obj += "f 1 2 3\n";
    for i in 0..20 {
        obj += &format!("f {} {} {}\n", 2 + 3 * i, 3 + 3 * i, 4 + 3 * i);
    }
    let (code, err) = voxelize_file("far.obj", obj.as_bytes());
    // Every small facet collapses: nothing useful can be produced.
    assert_ne!(code, 0, "{err}");
    assert!(err.contains("collapsed") || err.contains("degenerate"), "{err}");

    for args in [
        &["voxelize", "cornell", "--n", "0"][..],
        &["voxelize", "cornell", "--n", "3"],
        &["voxelize", "cornell", "--n", "100000"],
        &["voxelize", "cornell", "--dexel-capacity", "7"],
        &["voxelize", "no-such-scene"],
        &["voxelize", "cornell", "--sigma", "thick"],
    ] {
        let (code, err) = host_sim(args);
        assert_ne!(code, 0, "{args:?} should fail");
        assert!(!err.is_empty());
    }
}

#[test]
fn dexel_overflow_is_an_error_naming_the_cell() {
    let dir = std::env::temp_dir().join(format!("rc2-cli-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let out = dir.join("ovf.binvox");
    let (code, err) = host_sim(&[
        "voxelize",
        "teapot",
        "--n",
        "64",
        "--dexel-capacity",
        "8",
        "--quiet",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert_ne!(code, 0);
    assert!(
        err.contains("dexel store overflow") && err.contains("cell (") && err.contains("--dexel-capacity"),
        "{err}"
    );
    assert!(!out.exists(), "no output file after a loss");
}

#[test]
fn help_explains_every_option() {
    let out = Command::new(env!("CARGO_BIN_EXE_host-sim")).args(["voxelize", "--help"]).output().unwrap();
    let help = String::from_utf8_lossy(&out.stdout);
    for opt in ["--n", "--sigma", "--contour", "--engine", "--dexel-capacity", "--out", "--stats", "--quiet"] {
        assert!(help.contains(opt), "{opt} missing from --help");
    }
}

#[test]
fn light_writes_lit_csv_and_stats() {
    let dir = std::env::temp_dir().join(format!("rc2-cli-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let (csv, stats) = (dir.join("lit.csv"), dir.join("light.json"));
    let (code, err) = host_sim(&[
        "light",
        "cornell",
        "--n",
        "24",
        "--fa",
        "4",
        "--frac-bits",
        "2",
        "--quiet",
        "--lit-out",
        csv.to_str().unwrap(),
        "--stats",
        stats.to_str().unwrap(),
    ]);
    assert_eq!(code, 0, "{err}");
    let s: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&stats).unwrap()).unwrap();
    for key in [
        "cycles",
        "lower_bound",
        "beams_processed",
        "messages",
        "rays_emitted",
        "rays_absorbed",
        "rays_exited",
        "lit_voxels",
        "peak_fifo",
        "blocked_cell_cycles",
        "wall_seconds",
    ] {
        assert!(s.get(key).is_some(), "stats lack {key}");
    }
    let text = std::fs::read_to_string(&csv).unwrap();
    let mut lines = text.lines();
    assert_eq!(lines.next(), Some("x,y,z,source_mask"));
    let rows: Vec<Vec<u32>> = lines.map(|l| l.split(',').map(|v| v.parse().unwrap()).collect()).collect();
    assert_eq!(rows.len() as u64, s["lit_voxels"].as_u64().unwrap());
    assert!(rows.iter().all(|r| r.len() == 4 && r[3] == 1 && r[..3].iter().all(|&c| c < 24)));
    assert_eq!(
        s["rays_emitted"].as_u64().unwrap(),
        s["rays_absorbed"].as_u64().unwrap() + s["rays_exited"].as_u64().unwrap() + s["rays_skipped"].as_u64().unwrap()
    );
}

#[test]
fn light_rejects_bad_arguments() {
    for (args, expect) in [
        (&["light", "empty", "--n", "16", "--fa", "0"][..], "--fa"),
        (&["light", "empty", "--n", "16", "--fa", "65"], "--fa"),
        (&["light", "empty", "--n", "16", "--light", "1.5,0.5,0.5"], "outside the grid"),
        (&["light", "empty", "--n", "16", "--light", "0.5,0.5"], "X,Y,Z"),
        (&["light", "empty", "--n", "16", "--frac-bits", "9"], "frac-bits"),
        (&["light", "empty", "--n", "2"], "too small"),
    ] {
        let (code, err) = host_sim(args);
        assert_ne!(code, 0, "{args:?} should fail");
        assert!(err.contains(expect), "{args:?}: expected '{expect}' in {err}");
    }
}

#[test]
fn render_handles_materials_and_lights() {
    let dir = std::env::temp_dir().join(format!("rc2-cli-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    // A missing MTL and a texture reference: a warning, the default material, an image.
    let obj = b"mtllib nowhere.mtl\nusemtl wood\nv 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nf 1/1 2/1 3/1\n";
    let p = tmp("textured.obj", obj);
    let out = dir.join("textured.png");
    let (code, err) =
        host_sim(&["render", p.to_str().unwrap(), "--n", "16", "--quiet", "--out", out.to_str().unwrap()]);
    assert_eq!(code, 0, "{err}");
    assert!(err.contains("material library not loaded"), "{err}");
    assert!(err.contains("has no lights"), "a scene without lights gets the documented default: {err}");
    assert!(std::fs::read(&out).unwrap().starts_with(b"\x89PNG"));
    // Lights outside the grid and the reference of an empty scene are errors.
    for (args, expect) in [
        (&["render", "cornell", "--n", "16", "--light", "0.5,-0.1,0.5", "--out", "/dev/null"][..], "outside the grid"),
        (&["render", "empty", "--n", "16", "--reference", "--out", "/dev/null"], "needs a scene with geometry"),
    ] {
        let (code, err) = host_sim(args);
        assert_ne!(code, 0, "{args:?}");
        assert!(err.contains(expect), "{args:?}: {err}");
    }
}

#[test]
fn audit_reports_sizes_and_the_budget() {
    let dir = std::env::temp_dir().join(format!("rc2-cli-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let json = dir.join("audit.json");
    let (code, err) = host_sim(&["audit", "cornell", "--n", "32", "--json", json.to_str().unwrap()]);
    assert_eq!(code, 0, "{err}");
    let a: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let get = |k: &str| a[k].as_u64().unwrap_or_else(|| panic!("{k} missing"));
    assert_eq!(get("budget_ram"), 64 * 1024);
    assert_eq!(a["fits_budget"], true);
    assert!(get("used_dexels") >= 1 && get("used_dexels") <= get("capacity_dexels"));
    assert!(get("needed_total") < get("static_total"));
    assert_eq!(
        get("static_total"),
        get("static_cell") + get("bytes_row_packet") + get("static_light_cell"),
        "the static total is the sum of its parts"
    );
    // The Cornell box keeps at most a few triangles in a column: none left out.
    assert!(get("used_triangles") >= 1 && get("used_triangles") <= 64);
    assert_eq!(get("triangle_overflows"), 0);
    // Lit from a light of the user's: the geometry's peaks are the scene's, the light's own
    // (FIFO, lit runs) within their capacities; a light outside the grid is refused.
    let lit = dir.join("audit-lit.json");
    let (code, err) =
        host_sim(&["audit", "cornell", "--n", "32", "--light", "0.2,0.9,0.1", "--json", lit.to_str().unwrap()]);
    assert_eq!(code, 0, "{err}");
    let b: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&lit).unwrap()).unwrap();
    for k in ["used_dexels", "used_triangles", "triangle_overflows", "static_total"] {
        assert_eq!(a[k], b[k], "{k} does not depend on the light");
    }
    assert!(b["used_fifo"].as_u64().unwrap() <= get("capacity_fifo"));
    let (code, err) = host_sim(&["audit", "cornell", "--n", "16", "--light", "1.5,0.5,0.5"]);
    assert_ne!(code, 0);
    assert!(err.contains("outside"), "{err}");
    // A firmware image that is not there, or not an ELF: a clear error, no table, no panic.
    let missing = dir.join("no-such-image");
    let (code, err) = host_sim(&["audit", "cornell", "--n", "16", "--elf", missing.to_str().unwrap()]);
    assert_ne!(code, 0);
    assert!(err.contains("cannot read"), "{err}");
    let (code, err) = host_sim(&["audit", "cornell", "--n", "16", "--elf", json.to_str().unwrap()]);
    assert_ne!(code, 0);
    assert!(err.contains("is not an ELF file"), "{err}");
}

#[test]
fn classic_lighting_options() {
    // A ray connectivity that does not exist: a clear error, no panic.
    let (code, err) =
        host_sim(&["light", "cornell", "--n", "16", "--quiet", "--lighting", "classic", "--ray-connectivity", "7"]);
    assert_ne!(code, 0);
    assert!(err.contains("not a ray connectivity"), "{err}");
    // FA out of range for the classic phase too.
    let (code, err) = host_sim(&["light", "cornell", "--n", "16", "--quiet", "--lighting", "classic", "--fa", "0"]);
    assert_ne!(code, 0);
    assert!(err.contains("--fa 0 is out of range"), "{err}");
    // A classic render runs and reports the classic counters and the reference comparison.
    let out = tmp("classic.png", b"");
    let (code, err) = host_sim(&[
        "render",
        "cornell",
        "--n",
        "16",
        "--quiet",
        "--lighting",
        "classic",
        "--reference",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert_eq!(code, 0, "{err}");
    assert!(err.contains("classic:") && err.contains("shadow disagreement"), "{err}");
}

/// `diffusion-table` under both timings: the published T beside ours with the ratio (N = 8,
/// FA = 1 is a published point: 61 cycles), the time-lapse pictures; an input register that
/// does not fit the compiled FIFO is a clear error.
#[test]
fn diffusion_table_compares_timings_with_the_thesis() {
    let dir = tmp("t.keep", b"").with_file_name("");
    let (csv, png, lapse) = (dir.join("t.csv"), dir.join("t.png"), dir.join("lapse.png"));
    let (code, err) = host_sim(&[
        "diffusion-table",
        "--n",
        "8",
        "--fa",
        "1,2",
        "--policy",
        "thesis",
        "--timing",
        "rc2,thesis",
        "--source",
        "origin",
        "--timelapse",
        lapse.to_str().unwrap(),
        "--timelapse-fa",
        "1",
        "--quiet",
        "--out",
        csv.to_str().unwrap(),
        "--plot",
        png.to_str().unwrap(),
    ]);
    assert_eq!(code, 0, "{err}");
    let text = std::fs::read_to_string(&csv).unwrap();
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let col = |name: &str| header.iter().position(|h| *h == name).unwrap_or_else(|| panic!("no column {name}"));
    let rows: Vec<Vec<&str>> = lines.map(|l| l.split(',').collect()).collect();
    assert_eq!(rows.len(), 4, "2 timings × 2 FIFO sizes");
    for r in &rows {
        let cycles: f64 = r[col("cycles")].parse().unwrap();
        if r[col("fa")] == "1" {
            assert_eq!(r[col("thesis_t")], "61");
            let ratio: f64 = r[col("ratio")].parse().unwrap();
            assert!((ratio - cycles / 61.0).abs() < 1e-3, "{r:?}");
        } else {
            assert_eq!(r[col("ratio")], "", "N = 8, FA = 2 is not published");
        }
        // The ray-by-ray mode takes at least one cycle per ray.
        assert!(r[col("ray_by_ray_t")].parse::<u64>().unwrap() >= 6 * 15 * 15);
    }
    assert_eq!(rows.iter().filter(|r| r[col("timing")] == "thesis").count(), 2);
    assert!(png.exists() && dir.join("lapse.fa1.png").exists());

    let bad = dir.join("bad.csv");
    let args = ["diffusion-table", "--n", "8", "--fa", "64", "--register", "true", "--quiet", "--out"];
    let (code, err) = host_sim(&[&args[..], &[bad.to_str().unwrap()]].concat());
    assert_ne!(code, 0);
    assert!(err.contains("FIFO slots"), "{err}");
    assert!(!bad.exists(), "nothing written on a refused timing");
}

#[test]
fn form_factors_toward_the_source_by_rays_and_beams() {
    let csv = tmp("ray_traced.csv", b"");
    let (code, err) = host_sim(&[
        "form-factors",
        "--ray-traced",
        "cornell",
        "--ray-traced-patch",
        "0.25",
        "--ray-traced-csv",
        csv.to_str().unwrap(),
    ]);
    assert_eq!(code, 0, "{err}");
    let text = std::fs::read_to_string(&csv).unwrap();
    let rows: Vec<Vec<&str>> = text.lines().skip(1).map(|l| l.split(',').collect()).collect();
    let methods: Vec<&str> = rows.iter().map(|r| r[5]).collect();
    assert_eq!(methods, ["ray:1x1", "ray:4x4", "ray:5x5", "beam:4"], "{text}");
    let error = |m: usize| rows[m][13].parse::<f64>().unwrap();
    // Against 32 × 32 jittered rays per vertex: one ray per vertex is far off (a binary answer
    // per vertex), 25 closer, the beam closest (exact but for its last-level sub-beams).
    assert!(error(3) < error(2) && error(2) < error(0), "{text}");
    let work = |m: usize| rows[m][8].parse::<f64>().unwrap();
    assert!(work(0) <= 1.0 && work(1) > 8.0 * work(0), "rays per vertex: {text}");

    let flat = tmp("dark.obj", b"v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n");
    for (args, says) in [
        (vec!["--ray-traced", "no-such-scene"], "no-such-scene"),
        (vec!["--ray-traced", "cornell", "--ray-traced-level", "9"], "at most 8"),
        (vec!["--ray-traced", "cornell", "--ray-traced-patch", "0"], "(0, 1]"),
        (vec!["--ray-traced", flat.to_str().unwrap()], "no patch emits light"),
    ] {
        let mut a = vec!["form-factors"];
        a.extend(args);
        let (code, err) = host_sim(&a);
        assert_ne!(code, 0, "{a:?}");
        assert!(err.contains(says), "{a:?}: {err}");
    }
}

/// `host-sim radiosity ARGS --quiet` with its outputs in files named after `name`: the exit
/// code, stderr and the `--stats` JSON (`null` when the run wrote none).
fn radiosity_run(name: &str, args: &[&str]) -> (i32, String, serde_json::Value) {
    let stats = tmp(&format!("{name}.json"), b"");
    std::fs::remove_file(&stats).unwrap();
    let files = [("--residual-plot", "png"), ("--patches-csv", "patches.csv"), ("--shots-csv", "shots.csv")]
        .map(|(flag, ext)| (flag, stats.with_extension(ext).to_str().unwrap().to_string()));
    let mut all: Vec<&str> = vec!["radiosity"];
    all.extend(args);
    all.extend(["--quiet", "--stats", stats.to_str().unwrap()]);
    for (flag, path) in &files {
        all.extend([*flag, path.as_str()]);
    }
    let (code, err) = host_sim(&all);
    let json = std::fs::read_to_string(&stats).map_or(serde_json::Value::Null, |t| serde_json::from_str(&t).unwrap());
    (code, err, json)
}

/// `--shots-by proxels-*`: the run says what it shot by, its shots CSV balances every shot in
/// integers and carries every update strategy's costs; bad resolutions and options that need a
/// projection are refused.
#[test]
fn radiosity_shots_by_projection() {
    for method in ["proxels-hemicube", "proxels-disk"] {
        let name = format!("shots-by-{method}");
        let (code, err, json) =
            radiosity_run(&name, &["cornell", "--n", "16", "--residual", "0.05", "--shots-by", method]);
        assert_eq!(code, 0, "{err}");
        assert!(err.contains(&format!("shots by {method} (R = 32")), "{err}");
        assert_eq!(json["proxels"]["shots_by"], method, "{json}");
        assert!(json["residual"].as_f64().unwrap() <= 0.05, "{json}");
        let csv = std::fs::read_to_string(tmp(&format!("{name}.json"), b"x").with_extension("shots.csv")).unwrap();
        let mut lines = csv.lines();
        let header: Vec<&str> = lines.next().unwrap().split(',').collect();
        let col = |c: &str| header.iter().position(|h| *h == c).unwrap_or_else(|| panic!("no column {c}"));
        for c in
            ["update_xnet_modulo_cycles", "update_router_modulo_messages", "update_reduce_cycles", "projection_cycles"]
        {
            col(c);
        }
        let mut shots = 0;
        for line in lines {
            let v: Vec<i64> = line.split(',').map(|x| x.parse::<f64>().unwrap() as i64).collect();
            let [e, r, l, o] = ["emitted", "received", "lost", "left"].map(|c| v[col(c)]);
            assert_eq!(r + l + o, e, "{line}");
            assert_eq!(e, 1 << 30, "a surface's quanta are 2^30: {line}");
            shots += 1;
        }
        assert_eq!(shots, json["shots"].as_u64().unwrap());
    }
    for (bad, why) in [
        (&["--shots-by", "proxels-hemicube", "--resolution", "9"][..], "even"),
        (&["--shots-by", "proxels-disk", "--resolution", "4000"][..], "--resolution"),
        (&["--shots-by", "beams", "--resolution", "16"][..], "beam shots have none"),
        (&["--resolution", "16"][..], "--shots-by"),
        (&["--update", "reduce"][..], "--shots-by"),
    ] {
        let mut args = vec!["radiosity", "cornell", "--n", "16", "--quiet"];
        args.extend(bad);
        let (code, err) = host_sim(&args);
        assert_ne!(code, 0, "{bad:?}: {err}");
        assert!(err.contains(why), "{bad:?}: {err}");
    }
}

/// A beam shot's cell, as `radiosity --stats` counts it, is the cell `render --thesis` counts
/// (the shots' diffusion runs the thesis's rule from the source voxel with f = 0: dexels, row
/// packet, lighting cell, no triangle store or summary) and what radiosity adds to it; the
/// summary line names the whole.
#[test]
fn a_radiosity_cell_is_the_thesis_render_cell_and_what_radiosity_adds() {
    let (code, err, shots) = radiosity_run("bytes-radiosity", &["cornell", "--n", "16", "--residual", "0.2"]);
    assert_eq!(code, 0, "{err}");
    let render_stats = tmp("bytes-render.json", b"");
    let png = render_stats.with_extension("png");
    let (code, err) = host_sim(&[
        "render",
        "cornell",
        "--n",
        "16",
        "--thesis",
        "--quiet",
        "--out",
        png.to_str().unwrap(),
        "--stats",
        render_stats.to_str().unwrap(),
    ]);
    assert_eq!(code, 0, "{err}");
    let render: serde_json::Value = serde_json::from_slice(&std::fs::read(&render_stats).unwrap()).unwrap();
    assert_eq!(render["bytes_per_cell_stores"], 0, "{render}");
    let [whole, added, light] =
        ["bytes_per_cell", "bytes_per_cell_added", "bytes_per_light_cell"].map(|k| shots[k].as_u64().unwrap());
    assert_eq!(whole - added, render["bytes_per_cell"].as_u64().unwrap(), "{shots}\n{render}");
    assert_eq!(light, render["light"]["bytes_light_cell"].as_u64().unwrap(), "{shots}\n{render}");
    assert!(added > 0 && light > 0 && whole > added + light, "{shots}");
}

#[test]
fn radiosity_against_a_converged_truth_converges_with_the_hemicube() {
    let error = |spec: &str| {
        let name = format!("truth-{}", spec.replace(':', "-"));
        let (code, err, json) = radiosity_run(
            &name,
            &["cornell", "--n", "32", "--residual", "0.05", "--reference", "--truth-error", "--form-factors", spec],
        );
        assert_eq!(code, 0, "{err}");
        assert!(err.contains("against the converged truth"), "{err}");
        let t = &json["reference"]["truth"];
        assert_eq!(t["strata"], 6, "{json}");
        assert!((t["residual"].as_f64().unwrap() - 0.005).abs() < 1e-12, "{json}");
        let machine = t["machine_rms_relative_error"].as_f64().unwrap();
        assert!(machine.is_finite() && machine > 0.0, "{json}");
        // The cost in samples: a hemicube of R has R² + 4 · R²/2 proxels (§2.2), every
        // projection counts them all, and it casts no ray.
        let r: u64 = spec.trim_start_matches("hemicube:").parse().unwrap();
        let proxels = json["reference"]["proxels"].as_u64().unwrap();
        assert!(proxels > 0 && proxels % (3 * r * r) == 0, "{proxels} proxels for R = {r}");
        assert_eq!(json["reference"]["rays_cast"], 0, "{json}");
        assert!(json["beams_processed"].as_u64().unwrap() > 0, "{json}");
        t["reference_rms_relative_error"].as_f64().unwrap()
    };
    // A hemicube of 4 × 4 proxels on top aliases badly; at 64 the reference comes close to the
    // truth (which samples the same patches with another, finer estimator).
    let (coarse, fine) = (error("hemicube:4"), error("hemicube:64"));
    assert!(fine < coarse / 2.0, "hemicube:64 {fine}, hemicube:4 {coarse}");
    let (code, err) = host_sim(&["radiosity", "cornell", "--n", "16", "--truth-error"]);
    assert_ne!(code, 0, "--truth-error needs --reference: {err}");
}

#[test]
fn a_truth_cache_is_read_for_the_same_patches_and_solved_again_for_others() {
    let cache = tmp("truth-cache.json", b"");
    std::fs::remove_file(&cache).unwrap();
    let run = |residual: &str, spec: &str| {
        let name = format!("truth-cache-{residual}-{}", spec.replace(':', "-"));
        let c = cache.to_str().unwrap();
        let (code, err, json) = radiosity_run(
            &name,
            &["cornell", "--n", "16", "--residual", residual, "--reference", "--truth-error"]
                .into_iter()
                .chain(["--truth-cache", c, "--form-factors", spec])
                .collect::<Vec<_>>(),
        );
        assert_eq!(code, 0, "{err}");
        json["reference"]["truth"].clone()
    };
    let solved = run("0.05", "beams");
    assert_eq!(solved["cached"], false, "{solved}");
    assert!(cache.exists());
    // The same truth read back: the same errors to the last bit, for any reference.
    let read = run("0.05", "beams");
    assert_eq!(read["cached"], true, "{read}");
    for k in ["shots", "reference_rms_relative_error", "machine_rms_relative_error"] {
        assert_eq!(read[k], solved[k], "{k}: {read} / {solved}");
    }
    assert_eq!(run("0.05", "hemicube:16")["cached"], true);
    // Another stopping rule is another truth.
    assert_eq!(run("0.1", "beams")["cached"], false);
    std::fs::write(&cache, b"{ not json").unwrap();
    let bad = ["cornell", "--n", "16", "--reference", "--truth-error", "--truth-cache", cache.to_str().unwrap()];
    let (code, err, json) = radiosity_run("truth-cache-bad", &bad);
    assert_ne!(code, 0);
    assert!(err.contains("not a truth written by host-sim"), "{err}");
    assert!(json.is_null(), "no summary from a refused run: {json}");
}

#[test]
fn a_radiosity_render_against_the_truths_image() {
    let psnr = |spec: &str| {
        let out = tmp(&format!("truth-render-{}.png", spec.replace(':', "-")), b"");
        let stats = out.with_extension("json");
        let (code, err) = host_sim(&[
            "render",
            "cornell",
            "--n",
            "32",
            "--radiosity",
            "--residual",
            "0.01",
            "--reference",
            "--truth-error",
            "--form-factors",
            spec,
            "--quiet",
            "--out",
            out.to_str().unwrap(),
            "--stats",
            stats.to_str().unwrap(),
        ]);
        assert_eq!(code, 0, "{err}");
        assert!(err.contains("against the converged truth's image"), "{err}");
        let json: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&stats).unwrap()).unwrap();
        let t = &json["radiosity"]["truth_image"];
        let machine = t["machine_psnr_db"].as_f64().unwrap();
        assert!(machine.is_finite() && machine > 10.0, "{json}");
        t["reference_psnr_db"].as_f64().unwrap()
    };
    // The same shots and display with finer form factors: a picture closer to the truth's (at
    // a 1 % residual, where what is left unshot no longer dominates the difference).
    let (coarse, fine) = (psnr("hemicube:4"), psnr("hemicube:64"));
    assert!(fine > coarse + 3.0, "hemicube:64 {fine} dB, hemicube:4 {coarse} dB");
    let (code, err) = host_sim(&["render", "cornell", "--n", "16", "--reference", "--truth-error"]);
    assert_ne!(code, 0, "--truth-error is a radiosity option: {err}");
    assert!(err.contains("add --radiosity"), "{err}");
}

/// `--normals facet` is the default (issue 54: smooth shading adds modes, changes nothing
/// else): the same PNG bytes and the same statistics, timings and memory aside; a smooth render
/// reports what its vertex normals cost, a facet render has no such key.
#[test]
fn normals_facet_renders_byte_identical_to_the_default() {
    let dir = std::env::temp_dir().join(format!("rc2-normals-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let run = |label: &str, extra: &[&str]| -> (Vec<u8>, serde_json::Value) {
        let (png, json) = (dir.join(format!("{label}.png")), dir.join(format!("{label}.json")));
        let mut args = vec!["render", "teapot-floor", "--n", "32", "--quiet", "--reference"];
        args.extend_from_slice(extra);
        args.extend_from_slice(&["--out", png.to_str().unwrap(), "--stats", json.to_str().unwrap()]);
        let (code, err) = host_sim(&args);
        assert_eq!(code, 0, "{args:?}: {err}");
        let mut v: serde_json::Value = serde_json::from_slice(&std::fs::read(&json).unwrap()).unwrap();
        fn drop_timings(v: &mut serde_json::Value) {
            match v {
                serde_json::Value::Object(m) => {
                    m.retain(|k, _| !["wall", "seconds", "secs", "rss", "time"].iter().any(|t| k.contains(t)));
                    m.values_mut().for_each(drop_timings);
                }
                serde_json::Value::Array(a) => a.iter_mut().for_each(drop_timings),
                _ => {}
            }
        }
        drop_timings(&mut v);
        (std::fs::read(&png).unwrap(), v)
    };
    let (default_png, default_stats) = run("default", &[]);
    let (facet_png, facet_stats) = run("facet", &["--normals", "facet"]);
    assert!(default_png == facet_png, "--normals facet changed the image");
    assert_eq!(default_stats, facet_stats);
    assert!(default_stats.get("smooth").is_none());
    let (phong_png, phong_stats) = run("phong", &["--normals", "phong"]);
    assert!(phong_png != default_png, "phong shading looks like flat shading");
    assert_eq!(phong_stats["normals"], "phong");
    assert_eq!(phong_stats["smooth"]["bytes_per_packet"], 6);
    assert_eq!(phong_stats["smooth"]["bytes_per_cell"], 12);
    assert_eq!(phong_stats["smooth"]["normals_from"], "averaged");
}

/// `--area-light 1` is the run without the option: the same image, reference and difference
/// PNGs to the byte, the same summary line and `run` statistics; `--area-light 2` samples the
/// Cornell lamp by 4 sources and says so.
#[test]
fn area_light_one_is_the_point_light_to_the_byte() {
    let run = |name: &str, extra: &[&str]| {
        let out = tmp(&format!("{name}.png"), b"");
        let stats = out.with_extension("json");
        let mut args = vec!["render", "cornell", "--n", "24", "--reference", "--quiet"];
        args.extend(["--out", out.to_str().unwrap(), "--stats", stats.to_str().unwrap()]);
        args.extend(extra);
        let (code, err) = host_sim(&args);
        assert_eq!(code, 0, "{err}");
        let read = |ext: &str| std::fs::read(out.with_file_name(format!("{name}{ext}"))).unwrap();
        let json: serde_json::Value = serde_json::from_slice(&std::fs::read(&stats).unwrap()).unwrap();
        let pngs = [read(".png"), read(".reference.png"), read(".diff.png")];
        (pngs, json, err.lines().next().unwrap_or_default().to_string())
    };
    let (plain, plain_json, plain_line) = run("area-plain", &[]);
    let (one, one_json, one_line) = run("area-one", &["--area-light", "1"]);
    assert!(plain == one, "--area-light 1 changed the images");
    assert_eq!(plain_json["run"], one_json["run"]);
    assert_eq!(plain_json["light"]["sources"], one_json["light"]["sources"]);
    assert_eq!(plain_line, one_line);
    let (_, two_json, two_line) = run("area-two", &["--area-light", "2"]);
    assert_eq!(two_json["run"]["area_light"], 2);
    assert_eq!(two_json["light"]["sources"].as_array().unwrap().len(), 4);
    assert!(two_line.ends_with("area lights sampled 2 × 2"), "{two_line}");
}

/// `render --visibility ratio`: the beam skips (which drop only beams no pixel's voxel needs)
/// leave its image unchanged to the byte; the machine's counts are the target run's; the
/// weights change pixels (the option is not a no-op), and the run line names it.
#[test]
fn lit_ray_ratio_is_exact_under_the_skips() {
    let dir = std::env::temp_dir().join(format!("rc2-cli-ratio-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let run = |name: &str, extra: &[&str]| {
        let (png, json) = (dir.join(format!("{name}.png")), dir.join(format!("{name}.json")));
        let mut args = vec!["render", "teapot-floor", "--n", "64", "--frac-bits", "1", "--quiet"];
        args.extend(extra);
        args.extend(["--out", png.to_str().unwrap(), "--stats", json.to_str().unwrap()]);
        let (code, err) = host_sim(&args);
        assert_eq!(code, 0, "{args:?}: {err}");
        let stats: serde_json::Value = serde_json::from_slice(&std::fs::read(&json).unwrap()).unwrap();
        (std::fs::read(&png).unwrap(), stats)
    };
    let (target, t) = run("target", &[]);
    let (ratio, r) = run("ratio", &["--visibility", "ratio"]);
    let off = ["--skip-hidden", "false", "--skip-receding", "false", "--skip-dead-directions", "false"];
    let (unskipped, _) = run("unskipped", &[&["--visibility", "ratio"][..], &off[..]].concat());
    assert_eq!(ratio, unskipped, "the skips changed a weight");
    assert_ne!(ratio, target, "the ratio changed no pixel");
    for key in ["cycles", "beams_processed", "messages", "rays_absorbed"] {
        assert_eq!(t["light"][key], r["light"][key], "{key}");
    }
    assert_eq!(r["run"]["visibility"], "ratio");
    assert!(t["run"].get("visibility").is_none());
}
