//! `host-sim bench`: run time against error. Sweeps the knobs that trade speed for accuracy —
//! fraction bits f, thickness, contour, the lit rule and its rays' origin, shadow-edge
//! refinement, normals, FIFO size, policy — renders each
//! configuration, compares it with the f64 reference (ray-cast once per scene and n), and keeps
//! machine cycles, wall time, bytes per cell (the column's triangle store included under exact
//! occluders; shadow-edge refinement's ray FIFO and router not, as diffusion's FIFO is idle
//! by then), shadow disagreement and PSNR. The Pareto front is error against machine cycles.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::Result;
use cell_core::beam::Origin;
use cell_core::light::Policy;
use cell_core::lit::LitRule;
use cell_core::shade::NormalMode;

use crate::jobs::render::{reference_image, render, RenderConfig, RenderInput, RenderLighting, RenderStats};
use crate::machine::lighting::diffuse::LightConfig;
use crate::machine::lighting::run::policy_name;
use crate::machine::loading::loaded_scene::{load_scene, resolve_lights};
use crate::machine::rays::classic::ClassicConfig;
use crate::precompute::{Contour, LoadConfig, Thickness};
use crate::report::pareto::{pareto_front, plot_pareto, ParetoPoint};
use crate::scene::Mesh;
use crate::truth::compare::Comparison;
use crate::truth::refrender::RefImage;

/// One point of the sweep.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Knobs {
    /// Fraction bits.
    pub f: u32,
    /// Plane thickness.
    pub thickness: Thickness,
    /// Facet contour.
    pub contour: Contour,
    /// Normal mode.
    pub normals: NormalMode,
    /// FIFO size.
    pub fa: usize,
    /// Scheduling policy (merging follows it: on for wavefront and radial).
    pub policy: Policy,
    /// The lit rule.
    pub rule: LitRule,
    /// Where the rays leave from.
    pub rays: Origin,
    /// Shadow-edge refinement after diffusion (`--lighting refined`).
    pub refine: bool,
}

impl Knobs {
    /// The configuration `render` runs with no options: its preset's
    /// ([`crate::config::Preset::Render`]), flat normals, no shadow-edge refinement.
    pub const DEFAULT: Knobs = {
        let (load, light) = (crate::config::Preset::Render.load(), crate::config::Preset::Render.light());
        Knobs {
            f: light.frac_bits,
            thickness: load.thickness,
            contour: load.contour,
            normals: NormalMode::Facet,
            fa: light.fa,
            policy: light.policy,
            rule: light.rule,
            rays: light.rays,
            refine: false,
        }
    };

    /// What `render` ran with no options before the plane rule: the thesis's rule on thin
    /// surfaces, f = 0, the wavefront policy.
    pub const THESIS_FORMER: Knobs = Knobs {
        f: 0,
        thickness: Thickness::Naive,
        contour: Contour::Projected,
        policy: Policy::Wavefront,
        rule: LitRule::Thesis,
        rays: Origin::SourceVoxel,
        ..Knobs::DEFAULT
    };

    /// The CSV columns `f,thickness,contour,normals,fa,policy,rule,rays,refined,is_default`.
    fn csv(&self) -> String {
        format!(
            "{},{:?},{:?},{:?},{},{},{:?},{:?},{},{}",
            self.f,
            self.thickness,
            self.contour,
            self.normals,
            self.fa,
            policy_name(self.policy),
            self.rule,
            self.rays,
            self.refine,
            *self == Knobs::DEFAULT
        )
    }

    /// The knobs that differ from the default, as a short label.
    pub fn label(&self) -> String {
        let d = Knobs::DEFAULT;
        let mut parts = vec![format!("f={}", self.f)];
        if self.rule != d.rule {
            parts.push(format!("{:?} rule", self.rule).to_lowercase());
        }
        if self.rays != d.rays {
            parts.push(format!("rays from the {}", if self.rays == Origin::Light { "light" } else { "source voxel" }));
        }
        if self.refine {
            parts.push("refined edges".into());
        }
        if self.thickness != d.thickness {
            parts.push(format!("{:?}", self.thickness).to_lowercase());
        }
        if self.contour != d.contour {
            parts.push(format!("{:?}", self.contour).to_lowercase());
        }
        if self.normals != d.normals {
            parts.push("face normals".into());
        }
        if self.fa != d.fa {
            parts.push(format!("FA={}", self.fa));
        }
        if self.policy != d.policy {
            parts.push(format!("{} policy", policy_name(self.policy)));
        }
        parts.join(", ")
    }
}

/// The sweep: every (f, thickness, contour) combination under each lit rule (exact occluders
/// with rays from the light, the others from the source voxel) at the default normals, FIFO
/// and policy, the former default, shadow-edge refinement at each f, then each remaining
/// knob varied alone around the default.
pub fn sweep(fs: &[u32]) -> Vec<Knobs> {
    let d = Knobs::DEFAULT;
    let mut v = Vec::new();
    for (rule, rays) in
        [(LitRule::Exact, Origin::Light), (LitRule::Plane, Origin::SourceVoxel), (LitRule::Thesis, Origin::SourceVoxel)]
    {
        for &f in fs {
            for thickness in [Thickness::Naive, Thickness::Thesis, Thickness::Standard] {
                for contour in [Contour::Projected, Contour::Conservative] {
                    v.push(Knobs { f, thickness, contour, rule, rays, ..d });
                }
            }
        }
    }
    v.push(Knobs::THESIS_FORMER);
    v.extend(fs.iter().map(|&f| Knobs { f, refine: true, ..d }));
    v.push(Knobs { normals: NormalMode::Face, ..d });
    for fa in [4, 64] {
        v.push(Knobs { fa, ..d });
    }
    v.push(Knobs { policy: Policy::Thesis, ..d });
    v.push(Knobs { policy: Policy::Wavefront, ..d });
    let mut seen = Vec::new();
    v.retain(|k| {
        !seen.contains(k) && {
            seen.push(*k);
            true
        }
    });
    v
}

/// What the `bench` job sweeps and writes.
#[derive(Clone, Debug)]
pub struct BenchOptions {
    /// Scenes (.obj files or built-in names); errors are averaged over them.
    pub scenes: Vec<String>,
    /// Grid sizes.
    pub n: Vec<u32>,
    /// Fraction bits swept.
    pub frac_bits: Vec<u32>,
    /// Output CSV.
    pub out: PathBuf,
    /// Output Pareto plot (one per n: `<stem>-n<N>.png` when several).
    pub plot: PathBuf,
    /// No progress lines.
    pub quiet: bool,
    /// The view each scene is seen through (applied at each n).
    pub view: crate::scene::camera::ViewChoice,
}

/// Run the `bench` job on its scenes ([`run_bench`]).
pub fn run(o: &BenchOptions) -> Result<()> {
    let meshes = o.scenes.iter().map(|s| crate::scene::load(s)).collect::<Result<Vec<_>>>()?;
    run_bench(&meshes, &o.view, &o.n, &o.frac_bits, &o.out, &o.plot, o.quiet)
}

/// Run the sweep on several scenes at each n; write the CSV (one row per scene and
/// configuration, plus an `all` row per configuration: error and cycles averaged over the scenes,
/// bytes the largest) and one Pareto plot per n over the averaged rows
/// (`<plot stem>-n<N>.png`, or the plot path itself for a single n). Each scene is seen
/// through `view` ([`crate::scene::camera::apply`]).
pub fn run_bench(
    meshes: &[Mesh],
    view: &crate::scene::camera::ViewChoice,
    ns: &[u32],
    fs: &[u32],
    csv_path: &Path,
    plot_path: &Path,
    quiet: bool,
) -> Result<()> {
    let mut csv = crate::report::files::create(csv_path)?;
    writeln!(
        csv,
        "scene,n,f,thickness,contour,normals,fa,policy,rule,rays,refined,is_default,load_cycles,light_cycles,shade_cycles,cycles,t_over_lb,beams,bytes_per_cell,wall_seconds,shadow_disagreement_pct,coverage_disagreement_pct,psnr_db,pareto"
    )?;
    let knobs = sweep(fs);
    let names: Vec<&str> = meshes.iter().map(|m| m.name.as_str()).collect();
    for &n in ns {
        let mut sums = vec![Sums::default(); knobs.len()];
        for mesh in meshes {
            let mesh = &crate::scene::camera::apply(mesh.clone(), view, n)?;
            let mut reference = None;
            for (k, sum) in knobs.iter().zip(&mut sums) {
                let r = measure(mesh, n, k, &mut reference)?;
                if !quiet {
                    eprintln!(
                        "{:>13} n = {n} {:36} cycles {:>8}  shadow {:6.2} %  PSNR {:6.2} dB  wall {:.2} s",
                        mesh.name,
                        k.label(),
                        r.cycles,
                        r.cmp.shadow_disagreement_pct,
                        r.cmp.psnr_db,
                        r.stats.wall_seconds
                    );
                }
                write_row(&mut csv, &mesh.name, n, k, &r)?;
                sum.add(&r);
            }
        }
        let m = meshes.len().max(1) as f64;
        let points: Vec<ParetoPoint> = knobs.iter().zip(&sums).map(|(k, a)| a.point(k, m)).collect();
        let front = pareto_front(&points);
        write_mean_rows(&mut csv, n, &knobs, &sums, m, &front)?;
        let path = plot_path_for(plot_path, ns.len(), n);
        let title = format!(
            "{}, n = {n}: shadow error against machine cycles and host seconds (means over the scenes)",
            names.join(" + ")
        );
        plot_pareto(&points, &title, &path)?;
        if !quiet {
            print_front(n, &points, &sums, m, &front, &path);
        }
    }
    csv.flush()?;
    Ok(())
}

/// One configuration rendered on one scene and compared with the reference.
struct Measured {
    stats: RenderStats,
    cmp: Comparison,
    /// Light cycles, shadow-edge refinement included.
    light_cycles: u64,
    /// Load + light + shade cycles.
    cycles: u64,
    /// Bytes of a cell compiled for this FIFO size.
    bytes: usize,
}

/// Load, light and shade `mesh` at grid side `n` with the knobs `k`; the reference is ray-cast
/// once per scene and n (the first call makes it).
fn measure(mesh: &Mesh, n: u32, k: &Knobs, reference: &mut Option<RefImage>) -> Result<Measured> {
    let cfg = LoadConfig { n, thickness: k.thickness, contour: k.contour };
    let t0 = Instant::now();
    let loaded = load_scene(mesh, &cfg)?;
    let load_seconds = t0.elapsed().as_secs_f64();
    let lights = resolve_lights(mesh, &loaded, &[])?;
    let rcfg = RenderConfig::diffusion(
        LightConfig {
            fa: k.fa,
            policy: k.policy,
            merge: k.policy.by_layer(),
            record_visits: false,
            rule: k.rule,
            rays: k.rays,
            frac_bits: k.f,
            ..crate::config::plane_rule()
        },
        k.normals,
    );
    let rcfg = if k.refine {
        let rays = ClassicConfig {
            fa: k.fa.min(crate::machine::grid::capacity::SHADOW_FA_CAP),
            connectivity: cell_core::ray::Connectivity::Six,
            route: cell_core::route::RoutePolicy::Adaptive,
            all_voxels: false,
            bias: 0,
            rule: k.rule,
        };
        RenderConfig { lighting: RenderLighting::Refined(rays), ..rcfg }
    } else {
        rcfg
    };
    if reference.is_none() {
        *reference = Some(reference_image(mesh, &loaded, &lights, &rcfg)?);
    }
    let input = RenderInput { reference: reference.as_ref(), load_seconds, ..RenderInput::new(mesh, &loaded, &lights) };
    let r = render(&input, &rcfg, |_, _| {})?;
    let st = r.stats;
    let cmp = st.reference.expect("compared with the reference");
    let light_cycles = st.light.totals.cycles + st.refine.as_ref().map_or(0, |r| r.cycles);
    let cycles = st.light.load_cycles + light_cycles + st.shade_cycles;
    // A cell compiled for this FIFO size (the host compiles FA_CAP, limits at run time), with
    // the stores the run uses (the column's triangle store under exact occluders).
    let bytes = st.bytes_per_cell - (crate::machine::grid::capacity::FA_CAP - k.fa) * st.light.bytes_beam_message;
    Ok(Measured { stats: st, cmp, light_cycles, cycles, bytes })
}

/// The CSV row of one scene and configuration.
fn write_row(csv: &mut impl Write, scene: &str, n: u32, k: &Knobs, r: &Measured) -> Result<()> {
    let (st, c) = (&r.stats, &r.cmp);
    writeln!(
        csv,
        "{scene},{n},{},{},{},{},{},{:.4},{},{},{:.4},{:.4},{:.4},{:.4},",
        k.csv(),
        st.light.load_cycles,
        r.light_cycles,
        st.shade_cycles,
        r.cycles,
        st.light.t_over_lb,
        st.light.totals.beams_processed,
        r.bytes,
        st.wall_seconds,
        c.shadow_disagreement_pct,
        c.coverage_disagreement_pct,
        c.psnr_db
    )?;
    Ok(())
}

/// One configuration's results summed over the scenes (bytes: the largest).
#[derive(Clone, Copy, Debug, Default)]
struct Sums {
    cycles: f64,
    error: f64,
    bytes: usize,
    psnr: f64,
    coverage: f64,
    wall: f64,
}

impl Sums {
    fn add(&mut self, r: &Measured) {
        self.cycles += r.cycles as f64;
        self.error += r.cmp.shadow_disagreement_pct;
        self.bytes = self.bytes.max(r.bytes);
        self.psnr += r.cmp.psnr_db;
        self.coverage += r.cmp.coverage_disagreement_pct;
        self.wall += r.stats.wall_seconds;
    }

    /// The configuration's point of the Pareto plot: means over `m` scenes.
    fn point(&self, k: &Knobs, m: f64) -> ParetoPoint {
        ParetoPoint {
            label: k.label(),
            cycles: self.cycles / m,
            error: self.error / m,
            bytes: self.bytes as f64,
            seconds: self.wall / m,
            is_default: *k == Knobs::DEFAULT,
        }
    }
}

/// The `all` rows: each configuration's means over `m` scenes, and whether it is on the front.
fn write_mean_rows(
    csv: &mut impl Write,
    n: u32,
    knobs: &[Knobs],
    sums: &[Sums],
    m: f64,
    front: &[usize],
) -> Result<()> {
    for (i, (k, a)) in knobs.iter().zip(sums).enumerate() {
        writeln!(
            csv,
            "all,{n},{},,,,{:.1},,,{},{:.4},{:.4},{:.4},{:.4},{}",
            k.csv(),
            a.cycles / m,
            a.bytes,
            a.wall,
            a.error / m,
            a.coverage / m,
            a.psnr / m,
            front.contains(&i)
        )?;
    }
    Ok(())
}

/// The plot of grid side `n`: the plot path itself for a single n, `<stem>-n<N>.png` otherwise.
fn plot_path_for(plot_path: &Path, sizes: usize, n: u32) -> PathBuf {
    if sizes == 1 {
        plot_path.to_path_buf()
    } else {
        let stem = plot_path.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
        plot_path.with_file_name(format!("{stem}-n{n}.png"))
    }
}

/// The front as a Markdown table on stderr.
fn print_front(n: u32, points: &[ParetoPoint], sums: &[Sums], m: f64, front: &[usize], path: &Path) {
    let on = points.iter().position(|p| p.is_default).is_some_and(|i| front.contains(&i));
    eprintln!("n = {n}: default configuration on the Pareto front: {on}; plot {}", path.display());
    eprintln!("| knobs | mean cycles | mean shadow disagreement % | mean PSNR dB | bytes/cell | Pareto |");
    eprintln!("|---|---|---|---|---|---|");
    for (i, (p, a)) in points.iter().zip(sums).enumerate() {
        eprintln!(
            "| {}{} | {:.0} | {:.2} | {:.2} | {} | {} |",
            if p.is_default { "**default** " } else { "" },
            p.label,
            p.cycles,
            p.error,
            a.psnr / m,
            p.bytes,
            if front.contains(&i) { "yes" } else { "" }
        );
    }
}
