//! The parsed arguments converted into the jobs' plain options: the one place where the
//! command line's types meet the jobs'. The grid side's default per job is filled in here.

use super::phase_args::LightingArg;
use super::{
    AccuracyArgs, AuditArgs, BenchArgs, EmissionArg, LightArgs, LightOpts, RadiosityArgs, RenderArgs, SourceAtArg,
    SubdivideArgs, TableArgs, TimingArg, TraceArgs, VoxelizeArgs, DEFAULT_N, TRACE_N,
};
use crate::jobs::accuracy::AccuracyOptions;
use crate::jobs::audit::AuditOptions;
use crate::jobs::bench::BenchOptions;
use crate::jobs::light::{LightOptions, LightingOptions};
use crate::jobs::radiosity::RadiosityOptions;
use crate::jobs::render::RenderOptions;
use crate::jobs::render_radiosity::{RenderRadiosity, DEFAULT_DISPLAY};
use crate::jobs::scenes::SubdivideOptions;
use crate::jobs::table::{NamedTiming, TableOptions};
use crate::jobs::trace::TraceOptions;
use crate::jobs::voxelize::VoxelizeOptions;
use crate::machine::diffuse::{FrustumBlocks, LightConfig};
use crate::machine::timing::{Emission, Timing};

impl LightOpts {
    /// Refuse diffusion-only options with classic shadow rays: they would be ignored.
    pub fn check(&self) -> anyhow::Result<()> {
        if self.classic.lighting != LightingArg::Classic {
            return Ok(());
        }
        if self.rays_from == Some(crate::cli::RaysFromArg::Light) {
            anyhow::bail!(
                "--rays-from light is a diffusion option: classic shadow rays are traced to the light itself"
            );
        }
        Ok(())
    }

    /// The jobs' lighting options; `accurate`: the defaults are exact occluders with rays from
    /// the light ([`LightOpts::rule_and_rays`]).
    fn options(&self, accurate: bool) -> LightingOptions {
        let a = self;
        let (rule, rays) = a.rule_and_rays(accurate);
        LightingOptions {
            lights: a.lights.clone(),
            frac_bits: a.frac_bits,
            diffusion: LightConfig {
                fa: a.fa,
                policy: a.policy.into(),
                merge: a.merge.resolve(a.policy),
                record_visits: false,
                stepping: a.stepping.into(),
                skip_receding: a.skip_receding,
                skip_dead_directions: a.skip_dead_directions,
                faults: a.link_faults,
                stall_cycles: a.stall_cycles,
                lit_visible_only: false,
                hold: a.hold,
                skip_frustum: a.skip_frustum,
                skip_hidden: false,
                frustum_blocks: FrustumBlocks::default(),
                rule,
                rays,
                timing: Timing::RC2,
                stop_at: None,
            },
            lit_visible_only: a.lit_visible_only,
            skip_hidden: a.skip_hidden,
            frustum_blocks: a.frustum_blocks.map(Into::into),
            classic: (a.classic.lighting == LightingArg::Classic).then(|| a.classic.config(a.fa, rule)),
            refine: (a.classic.lighting == LightingArg::Refined).then(|| a.classic.config(a.fa, rule)),
        }
    }
}

impl RenderArgs {
    /// Refuse diffusion-only options with classic shadow rays, and radiosity options without
    /// `--radiosity`: they would change nothing.
    pub fn check(&self) -> anyhow::Result<()> {
        self.light.check()?;
        let stray = self.radiosity_opts.first_given().or(self.radiosity_display.map(|_| "--radiosity-display"));
        match stray {
            Some(flag) if !self.radiosity => anyhow::bail!("{flag} is a radiosity option: add --radiosity"),
            _ => Ok(()),
        }
    }
}

impl From<&RenderArgs> for RenderOptions {
    fn from(a: &RenderArgs) -> Self {
        let (fa, (rule, _)) = (a.light.fa, a.light.rule_and_rays(true));
        RenderOptions {
            radiosity: a.radiosity.then(|| RenderRadiosity {
                solve: (&a.radiosity_opts).into(),
                display: a.radiosity_display.map_or(DEFAULT_DISPLAY, Into::into),
            }),
            scene: a.load.scene.clone(),
            view: a.load.camera.choice(),
            load: a.load.config(DEFAULT_N),
            light: a.light.options(true),
            normals: a.normals.into(),
            reflections: (a.reflect.reflections > 0).then(|| a.reflect.config(fa, &a.light.classic.config(fa, rule))),
            out: a.out.clone(),
            reference: a.reference,
            stats: a.stats.clone(),
            quiet: a.quiet,
        }
    }
}

impl From<&LightArgs> for LightOptions {
    fn from(a: &LightArgs) -> Self {
        LightOptions {
            scene: a.load.scene.clone(),
            view: a.load.camera.choice(),
            load: a.load.config(DEFAULT_N),
            light: a.light.options(true),
            stats: a.stats.clone(),
            lit_out: a.lit_out.clone(),
            dump_lit: a.dump_lit.clone(),
            quiet: a.quiet,
        }
    }
}

impl From<&TraceArgs> for TraceOptions {
    fn from(a: &TraceArgs) -> Self {
        TraceOptions {
            scene: a.load.scene.clone(),
            view: a.load.camera.choice(),
            load: a.load.config(TRACE_N),
            light: a.light.options(false),
            reflections: (a.reflect.reflections > 0).then(|| {
                let (fa, (rule, _)) = (a.light.fa, a.light.rule_and_rays(false));
                a.reflect.config(fa, &a.light.classic.config(fa, rule))
            }),
            cells: a.cells.clone(),
            busiest: a.busiest,
            out: a.out.clone(),
        }
    }
}

impl From<&VoxelizeArgs> for VoxelizeOptions {
    fn from(a: &VoxelizeArgs) -> Self {
        VoxelizeOptions {
            scene: a.load.scene.clone(),
            view: a.load.camera.choice(),
            load: a.load.config(DEFAULT_N),
            engine: a.engine.into(),
            dexel_capacity: a.dexel_capacity,
            out: a.out.clone(),
            stats: a.stats.clone(),
            quiet: a.quiet,
        }
    }
}

impl From<&RadiosityArgs> for RadiosityOptions {
    fn from(a: &RadiosityArgs) -> Self {
        RadiosityOptions {
            scene: a.load.scene.clone(),
            load: a.load.config(DEFAULT_N),
            solve: (&a.solve).into(),
            reference: a.reference,
            reference_self_error: a.reference_self_error,
            patches_csv: a.patches_csv.clone(),
            shots_csv: a.shots_csv.clone(),
            residual_plot: a.residual_plot.clone(),
            stats: a.stats.clone(),
            quiet: a.quiet,
        }
    }
}

impl From<&AuditArgs> for AuditOptions {
    fn from(a: &AuditArgs) -> Self {
        AuditOptions {
            scene: a.load.scene.clone(),
            view: a.load.camera.choice(),
            load: a.load.config(DEFAULT_N),
            fa: a.fa,
            json: a.json.clone(),
            csv: a.csv.clone(),
            elfs: a.elf.clone(),
        }
    }
}

impl From<&TableArgs> for TableOptions {
    fn from(a: &TableArgs) -> Self {
        TableOptions {
            n: a.n.clone(),
            fa: a.fa.clone(),
            policies: a.policy.iter().map(|&p| p.into()).collect(),
            merge: a.merge.choice(),
            frac_bits: a.frac_bits,
            timings: a.timing.iter().map(|&t| table_timing(a, t)).collect(),
            origin: a.source == SourceAtArg::Origin,
            published: a.published,
            timelapse: a.timelapse.clone(),
            timelapse_fa: a.timelapse_fa.clone(),
            out: a.out.clone(),
            plot: a.plot.clone(),
            quiet: a.quiet,
        }
    }
}

/// A `diffusion-table` timing: the preset with the command line's overrides, named after both
/// (e.g. `rc2+link_rate=3`).
fn table_timing(a: &TableArgs, t: TimingArg) -> NamedTiming {
    let (mut name, mut timing) = match t {
        TimingArg::Rc2 => ("rc2".to_string(), Timing::RC2),
        TimingArg::Thesis => ("thesis".to_string(), Timing::THESIS),
    };
    if let Some(k) = a.link_rate {
        timing.link_rate = k;
        name += &format!("+link_rate={k}");
    }
    if let Some(r) = a.register {
        timing.register = r;
        name += &format!("+register={r}");
    }
    if let Some(f) = a.free_ports {
        timing.free_ports = f;
        name += &format!("+free_ports={f}");
    }
    if let Some(e) = a.emission {
        timing.emission = match e {
            EmissionArg::XyFirst => Emission::XyFirst,
            EmissionArg::ZFirst => Emission::ZFirst,
        };
        name += &format!("+emission={}", if e == EmissionArg::XyFirst { "xy" } else { "z" });
    }
    if let Some(b) = a.burst {
        timing.burst = b;
        name += &format!("+burst={b}");
    }
    NamedTiming { name, timing }
}

impl From<&AccuracyArgs> for AccuracyOptions {
    fn from(a: &AccuracyArgs) -> Self {
        AccuracyOptions {
            scene: a.scene.clone(),
            n: a.n.clone(),
            frac_bits: a.frac_bits.clone(),
            fa: a.fa,
            policy: a.policy.into(),
            lights: a.lights.clone(),
            out: a.out.clone(),
        }
    }
}

impl From<&BenchArgs> for BenchOptions {
    fn from(a: &BenchArgs) -> Self {
        BenchOptions {
            scenes: a.scene.clone(),
            n: a.n.clone(),
            frac_bits: a.frac_bits.clone(),
            out: a.out.clone(),
            plot: a.plot.clone(),
            quiet: a.quiet,
            view: a.camera.choice(),
        }
    }
}

impl From<&SubdivideArgs> for SubdivideOptions {
    fn from(a: &SubdivideArgs) -> Self {
        SubdivideOptions { scene: a.scene.clone(), target: a.target, out: a.out.clone() }
    }
}
