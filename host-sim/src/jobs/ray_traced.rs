//! `form-factors --ray-traced SCENE,...`: the radiosity thesis's Tables 3.2 and 3.3 (§3.4.2)
//! on the office scenes — the form factor from every vertex of the scene to its brightest
//! source, by rays toward the source (Wallace, §3.1) and by the subdivided beam (§3.4), timed
//! on one thread, with each estimate's error against a converged reference.
//!
//! The scene is cut into patches (edges at most `patch` × its largest extent); the source is
//! the patch with the most emitted power (the progressive solution's first shot); the
//! receivers are the other patches' distinct (vertex, normal) pairs; the occluders are every
//! other patch's triangles, tested one by one (the thesis's timings use no acceleration
//! structure). The reference is Wallace's estimate at 32 × 32 jittered rays per receiver
//! through the f64 BVH of [`crate::truth::visibility`] (another intersection code), run in
//! parallel and not timed.

use std::collections::HashSet;
use std::io::Write;
use std::path::PathBuf;
use std::time::Instant;

use anyhow::{bail, Context, Result};
use parry3d_f64::math::Vector;
use rayon::prelude::*;

use crate::report::files::create;
use crate::scene::patches::{subdivide, Patches};
use crate::truth::raytraced::beam::{self, BeamStats};
use crate::truth::raytraced::wallace::{self, Sampling};
use crate::truth::raytraced::{Occluders, Receiver, Source};
use crate::truth::visibility::Reference;

/// Options of the ray-traced form-factor comparison.
#[derive(Clone, Debug, PartialEq)]
pub struct RayTracedOptions {
    /// Scenes (built-in names or .obj files).
    pub scenes: Vec<String>,
    /// Largest patch edge, as a fraction of the scene's largest extent.
    pub patch: f64,
    /// The beam's deepest cut (the thesis's 4).
    pub max_level: u32,
    /// Write one CSV line per (scene, method) here.
    pub csv: Option<PathBuf>,
}

/// The methods compared, by name: Wallace's rays at `k × k` per receiver, and the beam.
const RAYS: [usize; 3] = [1, 4, 5];

/// Cuts per side of the reference's jittered rays.
const REFERENCE_K: usize = 32;

/// The most patches a scene may be cut into here.
const MAX_PATCHES: usize = 200_000;

/// One method on one scene.
#[derive(Clone, Debug, PartialEq)]
pub struct MethodRow {
    /// `ray:K×K` or `beam:L`.
    pub method: String,
    /// Wall seconds over every receiver, one thread.
    pub seconds: f64,
    /// Rays cast (Wallace) per receiver, or sub-beams cut (beam) per receiver.
    pub work_per_receiver: f64,
    /// Σ|F − F_ref| / Σ F_ref over the receivers.
    pub relative_error: f64,
    /// The beam's phase shares of its time: candidates, recursion, form factors.
    pub shares: Option<[f64; 3]>,
    /// The beam's candidates per receiver.
    pub candidates_per_receiver: Option<f64>,
}

/// One scene's comparison.
#[derive(Clone, Debug, PartialEq)]
pub struct SceneRows {
    /// The scene.
    pub scene: String,
    /// Receivers (distinct vertex, normal pairs).
    pub receivers: usize,
    /// Occluding triangles.
    pub occluders: usize,
    /// The source's area and vertex count.
    pub source: (f64, usize),
    /// Every method, the rays first.
    pub methods: Vec<MethodRow>,
}

/// Run the comparison on every scene; print the table and write the CSV if asked.
pub fn run(o: &RayTracedOptions) -> Result<()> {
    if !(o.patch > 0.0 && o.patch <= 1.0) {
        bail!("--ray-traced-patch must be in (0, 1], got {}", o.patch);
    }
    if o.max_level > 8 {
        bail!("--ray-traced-level must be at most 8 (4^8 sub-beams a receiver), got {}", o.max_level);
    }
    let mut file = o.csv.as_deref().map(create).transpose()?;
    let mut rows = Vec::new();
    for scene in &o.scenes {
        let r = compare(scene, o)?;
        eprintln!("{scene}: done");
        rows.push(r);
    }
    print!("{}", render(&rows));
    if let (Some(f), Some(path)) = (file.as_mut(), &o.csv) {
        f.write_all(csv(&rows).as_bytes())?;
        f.flush()?;
        eprintln!("written to {}", path.display());
    }
    Ok(())
}

/// The scene's patches, source, receivers and occluders.
pub fn setup(scene: &str, patch: f64) -> Result<(Source, Vec<Receiver>, Vec<[Vector; 3]>)> {
    let mesh = crate::scene::load(scene)?;
    let (lo, hi) = mesh.positions.iter().fold(([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]), |(lo, hi), p| {
        (std::array::from_fn(|i| lo[i].min(p[i])), std::array::from_fn(|i| hi[i].max(p[i])))
    });
    let extent = (0..3).map(|i| hi[i] - lo[i]).fold(0.0, f64::max);
    let patches = subdivide(&mesh, extent * patch, MAX_PATCHES)?;
    let power = |k: usize| patches.patches[k].emission.iter().sum::<f64>() * patches.patches[k].area;
    let Some(src) =
        (0..patches.patches.len()).filter(|&k| power(k) > 0.0).max_by(|&a, &b| power(a).total_cmp(&power(b)))
    else {
        bail!("{scene}: no patch emits light (an MTL `Ke`): there is no source to trace toward");
    };
    let source =
        Source::new(patches.patches[src].polygon.clone()).with_context(|| format!("{scene}: the source patch"))?;
    Ok((source, receivers(&patches, src), occluders(&patches, src)))
}

/// Every patch's distinct (vertex, normal) pairs but the source's.
fn receivers(p: &Patches, src: usize) -> Vec<Receiver> {
    let mut seen = HashSet::new();
    let mut out = Vec::new();
    for (_, patch) in p.patches.iter().enumerate().filter(|&(k, _)| k != src) {
        for &v in &patch.polygon {
            let key = (v.to_array().map(f64::to_bits), patch.normal.to_array().map(f64::to_bits));
            if seen.insert(key) {
                out.push(Receiver { point: v, normal: patch.normal });
            }
        }
    }
    out
}

/// Every triangle but the source's.
fn occluders(p: &Patches, src: usize) -> Vec<[Vector; 3]> {
    p.patches
        .iter()
        .enumerate()
        .filter(|&(k, _)| k != src)
        .flat_map(|(_, patch)| patch.triangles.iter().copied())
        .collect()
}

/// One scene: the reference, then each method timed on this thread.
fn compare(scene: &str, o: &RayTracedOptions) -> Result<SceneRows> {
    let (source, receivers, tris) = setup(scene, o.patch)?;
    let occ = Occluders::new(tris.iter().copied());
    let ids = (0..tris.len() as u32).collect();
    let bvh = Reference::new(tris.iter().map(|t| t.map(|p| p.to_array())).collect(), ids)?;
    let reference: Vec<f64> = receivers
        .par_iter()
        .enumerate()
        .map(|(i, r)| {
            let jitter = Some(i as u64 + 1);
            wallace::form_factor(r, &source, &bvh, &Sampling::Uniform { k: REFERENCE_K, jitter }).form_factor
        })
        .collect();
    let reference_sum: f64 = reference.iter().sum();
    if !(reference_sum.is_finite() && reference_sum > 0.0) {
        bail!("{scene}: no vertex receives light from the source (the reference's form factors sum to {reference_sum}): nothing to compare");
    }
    let error = |f: &[f64]| f.iter().zip(&reference).map(|(a, b)| (a - b).abs()).sum::<f64>() / reference_sum;
    let n = receivers.len() as f64;
    let mut methods = Vec::new();
    for k in RAYS {
        let t0 = Instant::now();
        let est: Vec<wallace::Estimate> = receivers
            .iter()
            .map(|r| wallace::form_factor(r, &source, &occ, &Sampling::Uniform { k, jitter: None }))
            .collect();
        let seconds = t0.elapsed().as_secs_f64();
        let f: Vec<f64> = est.iter().map(|e| e.form_factor).collect();
        methods.push(MethodRow {
            method: format!("ray:{k}x{k}"),
            seconds,
            work_per_receiver: est.iter().map(|e| e.rays).sum::<u64>() as f64 / n,
            relative_error: error(&f),
            shares: None,
            candidates_per_receiver: None,
        });
    }
    let mut st = BeamStats::default();
    let t0 = Instant::now();
    let f: Vec<f64> = receivers.iter().map(|r| beam::form_factor(r, &source, &occ, o.max_level, &mut st)).collect();
    let seconds = t0.elapsed().as_secs_f64();
    let phases = [st.candidates_time, st.recursion_time, st.form_factor_time].map(|d| d.as_secs_f64());
    let total: f64 = phases.iter().sum();
    methods.push(MethodRow {
        method: format!("beam:{}", o.max_level),
        seconds,
        work_per_receiver: st.subdivisions as f64 / n,
        relative_error: error(&f),
        shares: Some(phases.map(|p| p / total.max(f64::MIN_POSITIVE))),
        candidates_per_receiver: Some(st.candidates as f64 / n),
    });
    Ok(SceneRows {
        scene: scene.to_string(),
        receivers: receivers.len(),
        occluders: occ.triangles().len(),
        source: (source.area, source.polygon.len()),
        methods,
    })
}

/// The table: Table 3.2's times and ratio, Table 3.3's shares, the errors.
pub fn render(rows: &[SceneRows]) -> String {
    let mut s = String::new();
    s.push_str("| scene | receivers | occluders | method | seconds (1 thread) | × ray:1x1 | rays or cuts / receiver | candidates / receiver | candidates % | recursion % | form factor % | error vs reference |\n");
    s.push_str("|---|---|---|---|---|---|---|---|---|---|---|---|\n");
    for r in rows {
        let base = r.methods[0].seconds.max(f64::MIN_POSITIVE);
        for m in &r.methods {
            let pct = |i: usize| m.shares.map_or("".into(), |sh| format!("{:.1}", 100.0 * sh[i]));
            s.push_str(&format!(
                "| {} | {} | {} | {} | {:.3} | {:.1} | {:.2} | {} | {} | {} | {} | {:.2} % |\n",
                r.scene,
                r.receivers,
                r.occluders,
                m.method,
                m.seconds,
                m.seconds / base,
                m.work_per_receiver,
                m.candidates_per_receiver.map_or("".into(), |c| format!("{c:.1}")),
                pct(0),
                pct(1),
                pct(2),
                100.0 * m.relative_error
            ));
        }
    }
    s
}

/// One CSV line per (scene, method).
pub fn csv(rows: &[SceneRows]) -> String {
    let mut s = String::from("scene,receivers,occluders,source_area,source_vertices,method,seconds,ratio_to_ray1,work_per_receiver,candidates_per_receiver,candidates_share,recursion_share,form_factor_share,relative_error\n");
    for r in rows {
        let base = r.methods[0].seconds.max(f64::MIN_POSITIVE);
        for m in &r.methods {
            let sh = |i: usize| m.shares.map_or(String::new(), |sh| format!("{:.4}", sh[i]));
            s.push_str(&format!(
                "{},{},{},{:.6},{},{},{:.6},{:.3},{:.4},{},{},{},{},{:.6}\n",
                r.scene,
                r.receivers,
                r.occluders,
                r.source.0,
                r.source.1,
                m.method,
                m.seconds,
                m.seconds / base,
                m.work_per_receiver,
                m.candidates_per_receiver.map_or(String::new(), |c| format!("{c:.2}")),
                sh(0),
                sh(1),
                sh(2),
                m.relative_error
            ));
        }
    }
    s
}
