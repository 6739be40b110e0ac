//! The parsed arguments converted into the jobs' plain options: the one place where the
//! command line's types meet the jobs'. The grid side's default per job is filled in here.

use anyhow::{bail, Result};

use super::phase_args::LightingArg;
use super::{
    AccuracyArgs, AuditArgs, BenchArgs, EmissionArg, FormFactorsArgs, LightArgs, LightOpts, LoadArgs, RadiosityArgs,
    RenderArgs, SourceAtArg, SubdivideArgs, TableArgs, TimingArg, TraceArgs, VoxelizeArgs,
};
use crate::config::{Needs, Overrides, Preset, RunConfig};
use crate::jobs::accuracy::AccuracyOptions;
use crate::jobs::audit::AuditOptions;
use crate::jobs::bench::BenchOptions;
use crate::jobs::form_factors::FormFactorsOptions;
use crate::jobs::light::{LightOptions, LightingOptions};
use crate::jobs::radiosity::RadiosityOptions;
use crate::jobs::render::RenderOptions;
use crate::jobs::render_radiosity::{RenderRadiosity, DEFAULT_DISPLAY};
use crate::jobs::scenes::SubdivideOptions;
use crate::jobs::table::{NamedTiming, TableOptions};
use crate::jobs::trace::TraceOptions;
use crate::jobs::voxelize::VoxelizeOptions;
use crate::machine::lighting::timing::{Emission, Timing};

impl LightOpts {
    /// The preset asked for (`--preset`, `--thesis`), or the job's own.
    fn preset(&self, job: Preset) -> Preset {
        match (self.thesis, self.preset) {
            (true, _) => Preset::Thesis,
            (false, p) => p.map_or(job, Into::into),
        }
    }

    /// What this command line changes in a preset.
    fn overrides(&self, load: &LoadArgs) -> Overrides {
        Overrides {
            n: load.n,
            thickness: load.sigma.map(Into::into),
            contour: load.contour.map(Into::into),
            frac_bits: self.frac_bits,
            fa: self.fa,
            policy: self.policy.map(Into::into),
            merge: self.merge.choice(),
            stepping: self.stepping.map(Into::into),
            skip_receding: self.skip_receding,
            skip_dead_directions: self.skip_dead_directions,
            faults: self.link_faults,
            stall_cycles: self.stall_cycles,
            lit_visible_only: self.lit_visible_only,
            skip_frustum: self.skip_frustum,
            skip_hidden: self.skip_hidden,
            frustum_blocks: self.frustum_blocks.map(Into::into),
            hold: self.hold,
            rule: self.lit_rule.map(Into::into),
            rays: self.rays_from.map(Into::into),
            oracle_skip: self.oracle_skip.map(Into::into),
            area_light: self.area_light,
            visibility: self.visibility.map(Into::into),
        }
    }

    /// The jobs' lighting options: `job`'s preset (or the one asked for) with this command
    /// line's overrides, resolved and validated for a job that reflects rays or not.
    fn options(&self, load: &LoadArgs, job: Preset, reflections: bool) -> Result<LightingOptions> {
        let classic = self.classic.lighting == LightingArg::Classic;
        let needs = Needs { classic, reflections };
        let run = RunConfig::resolve(self.preset(job), &self.overrides(load), needs)?;
        let shadow_rays = self.classic.config(run.light.fa, run.light.rule);
        Ok(LightingOptions {
            lights: self.lights.clone(),
            light_size: self.light_size,
            run,
            classic: classic.then_some(shadow_rays),
            refine: (self.classic.lighting == LightingArg::Refined).then_some(shadow_rays),
        })
    }
}

impl RenderArgs {
    /// Refuse radiosity options without `--radiosity`: they would change nothing.
    pub fn check(&self) -> Result<()> {
        let stray = self.radiosity_opts.first_given().or(self.radiosity_display.map(|_| "--radiosity-display"));
        match stray {
            Some(flag) if !self.radiosity => bail!("{flag} is a radiosity option: add --radiosity"),
            _ => Ok(()),
        }
    }
}

impl TryFrom<&RenderArgs> for RenderOptions {
    type Error = anyhow::Error;

    fn try_from(a: &RenderArgs) -> Result<Self> {
        a.check()?;
        let reflecting = a.reflect.reflections > 0;
        let light = a.light.options(&a.load, Preset::Render, reflecting)?;
        let (fa, rule) = (light.run.light.fa, light.run.light.rule);
        Ok(RenderOptions {
            radiosity: a.radiosity.then(|| RenderRadiosity {
                solve: (&a.radiosity_opts).into(),
                display: a.radiosity_display.map_or(DEFAULT_DISPLAY, Into::into),
                truth: a.radiosity_opts.truth_error,
            }),
            scene: a.load.scene.clone(),
            view: a.load.camera.choice(),
            normals: a.normals.into(),
            smooth: a.normals.smooth(),
            samples: a.samples,
            sample_lights: a.sample_lights.into(),
            reflections: reflecting.then(|| a.reflect.config(fa, &a.light.classic.config(fa, rule))),
            light,
            out: a.out.clone(),
            reference: a.reference,
            stats: a.stats.clone(),
            quiet: a.quiet,
        })
    }
}

impl TryFrom<&LightArgs> for LightOptions {
    type Error = anyhow::Error;

    fn try_from(a: &LightArgs) -> Result<Self> {
        Ok(LightOptions {
            scene: a.load.scene.clone(),
            view: a.load.camera.choice(),
            light: render_only_visibility(a.light.options(&a.load, Preset::Light, false)?, "light")?,
            stats: a.stats.clone(),
            lit_out: a.lit_out.clone(),
            dump_lit: a.dump_lit.clone(),
            quiet: a.quiet,
        })
    }
}

/// `light` refused `--visibility ratio|majority` for a `job` that shows no pixels.
fn render_only_visibility(light: LightingOptions, job: &str) -> Result<LightingOptions> {
    let v = light.run.light.visibility;
    if v.counts_rays() {
        bail!(
            "--visibility {} weighs the lights of each pixel: a render option (`{job}` reports lit voxels, not pixels)",
            v.name()
        );
    }
    Ok(light)
}

impl TryFrom<&TraceArgs> for TraceOptions {
    type Error = anyhow::Error;

    fn try_from(a: &TraceArgs) -> Result<Self> {
        let reflecting = a.reflect.reflections > 0;
        let light = render_only_visibility(a.light.options(&a.load, Preset::Trace, reflecting)?, "trace")?;
        if light.run.area_light > 1 || light.light_size.is_some() {
            bail!("--area-light and --light-size are render and light options: a trace records point lights");
        }
        let (fa, rule) = (light.run.light.fa, light.run.light.rule);
        Ok(TraceOptions {
            scene: a.load.scene.clone(),
            view: a.load.camera.choice(),
            reflections: reflecting.then(|| a.reflect.config(fa, &a.light.classic.config(fa, rule))),
            light,
            cells: a.cells.clone(),
            busiest: a.busiest,
            out: a.out.clone(),
        })
    }
}

impl From<&VoxelizeArgs> for VoxelizeOptions {
    fn from(a: &VoxelizeArgs) -> Self {
        VoxelizeOptions {
            scene: a.load.scene.clone(),
            view: a.load.camera.choice(),
            load: a.load.config(Preset::Render.load()),
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
            load: a.load.config(Preset::Render.load()),
            solve: (&a.solve).into(),
            reference: a.reference,
            reference_self_error: a.reference_self_error,
            truth_error: a.solve.truth_error,
            truth_cache: a.truth_cache.clone(),
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
            load: a.load.config(Preset::Render.load()),
            fa: a.fa,
            lights: a.lights.clone(),
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
            rule: a.lit_rule.into(),
            lights: a.lights.clone(),
            measure: a.measure.into(),
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

impl From<&FormFactorsArgs> for FormFactorsOptions {
    fn from(a: &FormFactorsArgs) -> Self {
        FormFactorsOptions {
            tables: a.tables,
            csv: a.csv.clone(),
            figure: a.figure.clone(),
            figure_csv: a.figure_csv.clone(),
            ray_traced: (!a.ray_traced.is_empty()).then(|| crate::jobs::ray_traced::RayTracedOptions {
                scenes: a.ray_traced.clone(),
                patch: a.ray_traced_patch,
                max_level: a.ray_traced_level,
                csv: a.ray_traced_csv.clone(),
            }),
        }
    }
}

#[cfg(test)]
mod tests {
    use clap::Parser;

    use super::*;
    use crate::cli::{Cli, Command};
    use crate::config::Preset;

    fn parse(args: &str) -> Command {
        Cli::try_parse_from(std::iter::once("host-sim").chain(args.split_whitespace())).unwrap().command
    }

    fn render(args: &str) -> Result<RenderOptions> {
        match parse(args) {
            Command::Render(a) => (&a).try_into(),
            c => panic!("not render: {c:?}"),
        }
    }

    fn light(args: &str) -> Result<LightOptions> {
        match parse(args) {
            Command::Light(a) => (&a).try_into(),
            c => panic!("not light: {c:?}"),
        }
    }

    /// A flagless `host-sim render`, `light` and `trace` run their presets, every field.
    #[test]
    fn flagless_commands_run_their_presets() {
        let r = render("render").unwrap();
        assert_eq!(r.light.run, Preset::Render.config());
        assert_eq!((r.scene.as_str(), r.view), ("cornell", crate::scene::camera::ViewChoice::Auto));
        assert!(
            r.light.classic.is_none() && r.light.refine.is_none() && r.reflections.is_none() && r.radiosity.is_none()
        );
        assert_eq!(light("light").unwrap().light.run, Preset::Light.config());
        let Command::Trace(t) = parse("trace") else { panic!("not trace") };
        assert_eq!(TraceOptions::try_from(&t).unwrap().light.run, Preset::Trace.config());
    }

    /// `--preset` and `--thesis` choose the run; other flags change it; contradictions are
    /// refused before any work.
    #[test]
    fn flags_override_the_preset() {
        assert_eq!(render("render --thesis").unwrap().light.run, Preset::Thesis.config());
        assert_eq!(light("light --preset thesis").unwrap().light.run, Preset::Thesis.config());
        let r = render("render --preset light --fa 8 --n 64 --sigma naive").unwrap().light.run;
        assert_eq!(r.light, crate::machine::lighting::diffuse::LightConfig { fa: 8, ..Preset::Light.light() });
        assert_eq!((r.load.n, r.load.thickness), (64, crate::precompute::Thickness::Naive));
        let r = render("render --lit-rule plane --rays-from voxel").unwrap().light.run.light;
        assert_eq!((r.rule, r.rays), (cell_core::lit::LitRule::Plane, cell_core::beam::Origin::SourceVoxel));
        // Reflections read hidden voxels: the full store unless told, and then refused.
        let r = render("render --reflections 1").unwrap().light.run.light;
        assert!(!r.lit_visible_only && !r.skip_hidden);
        assert!(render("render --reflections 1 --lit-visible-only").is_err());
        assert!(render("render --lighting classic --rays-from light").is_err());
        assert!(light("light --skip-hidden").is_err(), "the hidden skip needs the visible-only store");
        assert!(Cli::try_parse_from(["host-sim", "render", "--thesis", "--preset", "render"]).is_err());
    }
}
