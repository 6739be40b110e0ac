//! One home for what a run is: the named presets, the overrides a command line may give, the
//! one validation, and the description every output carries.
//!
//! A run of the lighting jobs is a [`RunConfig`]: the scene's loading ([`LoadConfig`]) and the
//! complete diffusion configuration ([`LightConfig`], the fraction bits f of the rays included).
//! Each [`Preset`] is one such configuration, written out field by field in [`Preset::load`]
//! and [`Preset::light`]; docs/CONFIGURATION.md says what each is for and lists the line each
//! prints (a test keeps that page in step with this code).
//!
//! The command line's options are [`Overrides`] of the preset a job starts from (`--preset`,
//! `--thesis`); [`RunConfig::resolve`] applies them and validates the result once. Every job
//! prints [`RunConfig::describe`] as its summary's first line and writes [`RunSummary`] into
//! its `--stats` JSON, so an output always says what ran.

use anyhow::{bail, Result};
use cell_core::beam::Origin;
use cell_core::light::Policy;
use cell_core::lit::LitRule;
use cell_core::visibility::Visibility;

use crate::machine::grid::capacity::TRIANGLE_CAP;
use crate::machine::lighting::diffuse::{FrustumBlocks, LightConfig, OracleSkip, Stepping, DEFAULT_STALL_CYCLES};
use crate::machine::lighting::timing::Timing;
use crate::machine::links::faults::LinkFaults;
use crate::precompute::{Contour, LoadConfig, Thickness};

/// Fraction bits f of the presets but `light`'s: the thesis's integer rays. f = 1 is the
/// accuracy knob for faces lit at grazing angles, at about twice the cycles
/// (BENCHMARKS.md, "How accurate is the image?").
pub const DEFAULT_FRAC_BITS: u32 = 0;

/// Fraction bits f of the `light` preset: its lit set is every voxel's, grazed faces included,
/// and at f = 0 the lattice is a voxel apart at the far plane — twice the disagreement with f64
/// visibility of f = 1 on the held-out meshes (BENCHMARKS.md, "Is `light`'s lit set right?").
/// The image reads one target ray per pixel and keeps f = 0.
pub const LIGHT_FRAC_BITS: u32 = 1;

/// A named run configuration ([`Preset::config`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Preset {
    /// What `host-sim render` runs: exact occluders, rays from the light, the lit marks the
    /// pixels read only, and the beams that can reach no visible voxel dropped.
    Render,
    /// What `host-sim light` runs: `render`'s machine with the full lit store (every lit voxel
    /// kept), no hidden-voxel skip.
    Light,
    /// What `host-sim trace` records and the firmware replays: the plane rule from the source
    /// voxel (no triangle store), the 8 × 8 × 8 occupancy summary a cell trace carries, n = 32.
    Trace,
    /// The thesis's machine: its lit rule (§5.5.5), integer rays from the source voxel (§4.3),
    /// the wavefront policy, its free-port timing, naive planes and projected contours (§3.8),
    /// none of rc2's skips.
    Thesis,
}

impl Preset {
    /// Every preset, in the order the table of the module doc lists them.
    pub const ALL: [Preset; 4] = [Preset::Render, Preset::Light, Preset::Trace, Preset::Thesis];

    /// The name the command line and the outputs use.
    pub const fn name(self) -> &'static str {
        match self {
            Preset::Render => "render",
            Preset::Light => "light",
            Preset::Trace => "trace",
            Preset::Thesis => "thesis",
        }
    }

    /// The whole configuration, every field written out.
    pub const fn config(self) -> RunConfig {
        RunConfig { preset: self, load: self.load(), light: self.light(), area_light: 1 }
    }

    /// How the preset loads a scene.
    pub const fn load(self) -> LoadConfig {
        match self {
            Preset::Render | Preset::Light => LoadConfig::watertight(128),
            Preset::Trace => LoadConfig::watertight(32),
            Preset::Thesis => LoadConfig { n: 128, thickness: Thickness::Naive, contour: Contour::Projected },
        }
    }

    /// The preset's diffusion configuration.
    pub const fn light(self) -> LightConfig {
        let rc2 = LightConfig {
            frac_bits: DEFAULT_FRAC_BITS,
            fa: 16,
            policy: Policy::Radial,
            merge: true,
            record_visits: false,
            stepping: Stepping::Active,
            skip_receding: true,
            skip_dead_directions: true,
            faults: None,
            stall_cycles: DEFAULT_STALL_CYCLES,
            lit_visible_only: false,
            hold: 0,
            skip_frustum: false,
            skip_hidden: false,
            frustum_blocks: FrustumBlocks::B32,
            rule: LitRule::Exact,
            rays: Origin::Light,
            timing: Timing::RC2,
            oracle_skip: OracleSkip::Off,
            stop_at: None,
            visibility: Visibility::Target,
        };
        match self {
            Preset::Render => LightConfig { lit_visible_only: true, skip_hidden: true, ..rc2 },
            Preset::Light => LightConfig { frac_bits: LIGHT_FRAC_BITS, ..rc2 },
            Preset::Trace => LightConfig {
                rule: LitRule::Plane,
                rays: Origin::SourceVoxel,
                frustum_blocks: FrustumBlocks::B8,
                ..rc2
            },
            Preset::Thesis => LightConfig {
                policy: Policy::Wavefront,
                skip_receding: false,
                skip_dead_directions: false,
                rule: LitRule::Thesis,
                rays: Origin::SourceVoxel,
                timing: Timing::THESIS,
                ..rc2
            },
        }
    }
}

impl std::fmt::Display for Preset {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// The plane rule from the source voxel on the `light` preset's machine (full lit store,
/// 32-block summaries) with the thesis's integer rays (f = 0): what the firmware's default
/// image runs, with the lit set every voxel has. Tests of the diffusion engine itself start
/// from it (fast, and every lit voxel kept).
pub const fn plane_rule() -> LightConfig {
    LightConfig {
        rule: LitRule::Plane,
        rays: Origin::SourceVoxel,
        frac_bits: DEFAULT_FRAC_BITS,
        ..Preset::Light.light()
    }
}

/// A run: what is loaded and the diffusion.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct RunConfig {
    /// The preset it started from.
    pub preset: Preset,
    /// The scene's loading.
    pub load: LoadConfig,
    /// The diffusion (f included).
    pub light: LightConfig,
    /// S: every light with an extent is sampled by S × S point sources (1: a point at its
    /// centre), [`crate::machine::loading::loaded_scene::resolve_sources`].
    pub area_light: u32,
}

/// What a command line changes in a preset: `None` keeps the preset's value.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Overrides {
    /// Grid side.
    pub n: Option<u32>,
    /// Plane thickness.
    pub thickness: Option<Thickness>,
    /// Facet contour.
    pub contour: Option<Contour>,
    /// Fraction bits f.
    pub frac_bits: Option<u32>,
    /// FIFO size FA.
    pub fa: Option<usize>,
    /// Scheduling policy.
    pub policy: Option<Policy>,
    /// Merging; `None`: on unless the policy is the thesis's.
    pub merge: Option<bool>,
    /// Host stepping.
    pub stepping: Option<Stepping>,
    /// The receding-beam skip.
    pub skip_receding: Option<bool>,
    /// The dead-direction skip.
    pub skip_dead_directions: Option<bool>,
    /// Faulty links.
    pub faults: Option<LinkFaults>,
    /// Stall detection.
    pub stall_cycles: Option<u64>,
    /// The visible-only lit store.
    pub lit_visible_only: Option<bool>,
    /// The empty-frustum skip.
    pub skip_frustum: Option<bool>,
    /// The hidden-voxel skip.
    pub skip_hidden: Option<bool>,
    /// Summary resolution.
    pub frustum_blocks: Option<FrustumBlocks>,
    /// The sibling wait.
    pub hold: Option<u16>,
    /// The lit rule.
    pub rule: Option<LitRule>,
    /// The rays' origin.
    pub rays: Option<Origin>,
    /// The oracle skip.
    pub oracle_skip: Option<OracleSkip>,
    /// S × S samples per area light.
    pub area_light: Option<u32>,
    /// How a pixel's visibility of a light is decided.
    pub visibility: Option<Visibility>,
}

/// What the job around the diffusion needs of it.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Needs {
    /// Classic shadow rays replace diffusion (their rays leave from the source voxel).
    pub classic: bool,
    /// Reflected rays read the lit state of hidden voxels: the full lit store.
    pub reflections: bool,
}

impl RunConfig {
    /// `preset` with `o` applied for a job that `needs` this, validated ([`RunConfig::validate`]).
    pub fn resolve(preset: Preset, o: &Overrides, needs: Needs) -> Result<RunConfig> {
        let base = preset.config();
        let b = &base.light;
        let policy = o.policy.unwrap_or(b.policy);
        // A preset's merge is auto: on for the wavefront and radial policies.
        let merge = o.merge.unwrap_or(policy != Policy::Thesis);
        // Reflections need the full lit store (and so no hidden-voxel skip) unless told.
        let lit_visible_only = o.lit_visible_only.unwrap_or(b.lit_visible_only && !needs.reflections);
        let skip_hidden = o.skip_hidden.unwrap_or(b.skip_hidden && lit_visible_only);
        let rays = o.rays.unwrap_or(if needs.classic { Origin::SourceVoxel } else { b.rays });
        let light = LightConfig {
            frac_bits: o.frac_bits.unwrap_or(b.frac_bits),
            fa: o.fa.unwrap_or(b.fa),
            policy,
            merge,
            stepping: o.stepping.unwrap_or(b.stepping),
            skip_receding: o.skip_receding.unwrap_or(b.skip_receding),
            skip_dead_directions: o.skip_dead_directions.unwrap_or(b.skip_dead_directions),
            faults: o.faults.or(b.faults),
            stall_cycles: o.stall_cycles.unwrap_or(b.stall_cycles),
            lit_visible_only,
            skip_frustum: o.skip_frustum.unwrap_or(b.skip_frustum),
            skip_hidden,
            frustum_blocks: o.frustum_blocks.unwrap_or(b.frustum_blocks),
            hold: o.hold.unwrap_or(b.hold),
            rule: o.rule.unwrap_or(b.rule),
            rays,
            oracle_skip: o.oracle_skip.unwrap_or(b.oracle_skip),
            visibility: o.visibility.unwrap_or(b.visibility),
            ..*b
        };
        let load = LoadConfig {
            n: o.n.unwrap_or(base.load.n),
            thickness: o.thickness.unwrap_or(base.load.thickness),
            contour: o.contour.unwrap_or(base.load.contour),
        };
        let run = RunConfig { preset, load, light, area_light: o.area_light.unwrap_or(base.area_light) };
        run.validate(needs)?;
        Ok(run)
    }

    /// Refuse what cannot run, or would silently run something else than asked.
    pub fn validate(&self, needs: Needs) -> Result<()> {
        let l = &self.light;
        self.load.validate()?;
        if crate::machine::lighting::diffuse::light_cell_bytes(l.frac_bits).is_none() {
            return Err(crate::machine::lighting::diffuse::unsupported_frac_bits(l.frac_bits));
        }
        if l.skip_hidden && !l.lit_visible_only {
            bail!(
                "--skip-hidden drops the light of hidden voxels: it needs the visible-only lit store \
                 (--lit-visible-only)"
            );
        }
        if needs.reflections && l.lit_visible_only {
            bail!(
                "--reflections reads the lit state of the voxels reflected rays hit, hidden ones included: \
                 run without --lit-visible-only (and --skip-hidden)"
            );
        }
        if l.oracle_skip != OracleSkip::Off && (!l.rule.needs_triangles() || !l.lit_visible_only) {
            bail!(
                "--oracle-skip drops the beams no pixel's target ray is in: it needs exact occluders \
                 (--lit-rule exact) and the visible-only lit store (render's default)"
            );
        }
        if l.visibility.counts_rays() && !l.rule.needs_triangles() {
            bail!(
                "--visibility {} counts the rays reaching each pixel's target voxel: it needs exact occluders \
                 (--lit-rule exact, the default)",
                l.visibility.name()
            );
        }
        if self.area_light == 0 {
            bail!("--area-light 0: S is the number of samples along each side of a light, at least 1");
        }
        if needs.classic && l.rays == Origin::Light {
            bail!("--rays-from light is a diffusion option: classic shadow rays are traced to the light itself");
        }
        Ok(())
    }

    /// The summary's first line: the preset and everything that decides what the machine does.
    pub fn describe(&self) -> String {
        self.summary().line()
    }

    /// What ran, for the outputs.
    pub fn summary(&self) -> RunSummary {
        let l = &self.light;
        let skips = [
            (l.skip_receding, "receding"),
            (l.skip_dead_directions, "dead directions"),
            (l.skip_frustum, "empty frustum"),
            (l.skip_hidden, "hidden"),
            (l.oracle_skip == OracleSkip::Voxels, "oracle (target voxels)"),
            (l.oracle_skip == OracleSkip::Rays, "oracle (target rays)"),
        ];
        RunSummary {
            preset: self.preset,
            lit_rule: rule_name(l.rule),
            rays_from: match l.rays {
                Origin::Light => "light",
                Origin::SourceVoxel => "voxel",
            },
            thickness: format!("{:?}", self.load.thickness).to_lowercase(),
            contour: format!("{:?}", self.load.contour).to_lowercase(),
            n: self.load.n,
            frac_bits: l.frac_bits,
            fa: l.fa,
            policy: crate::machine::lighting::run::policy_name(l.policy),
            merge: l.merge,
            timing: if l.timing == Timing::THESIS {
                "thesis"
            } else if l.timing == Timing::RC2 {
                "rc2"
            } else {
                "custom"
            },
            lit_store: if l.lit_visible_only { "visible" } else { "full" },
            skips: skips.iter().filter(|s| s.0).map(|s| s.1).collect(),
            frustum_blocks: match l.frustum_blocks {
                FrustumBlocks::B8 => 8,
                FrustumBlocks::B16 => 16,
                FrustumBlocks::B32 => 32,
            },
            hold: l.hold,
            link_faults: l.faults.is_some(),
            area_light: self.area_light,
            visibility: l.visibility.name(),
        }
    }
}

/// The CLI name of a lit rule.
pub const fn rule_name(r: LitRule) -> &'static str {
    r.name()
}

/// Bytes of a cell's loading state: its dexel store (the default capacity) and the row packet
/// it receives facets in.
pub const fn loading_cell_bytes() -> usize {
    std::mem::size_of::<cell_core::cell::Cell<{ cell_core::cell::DEFAULT_DEXELS }>>()
        + std::mem::size_of::<cell_core::facet::RowPacket>()
}

/// Bytes a cell's stores take beyond its dexels and its lighting cell under run `l`: the
/// column's triangle store under exact occluders, the occupancy summary when a skip tests it.
pub fn extra_cell_bytes(l: &LightConfig) -> usize {
    let triangles = if l.rule.needs_triangles() {
        std::mem::size_of::<cell_core::occluder::TriangleStore<TRIANGLE_CAP>>()
    } else {
        0
    };
    let summary = if l.skip_frustum || l.skip_hidden { l.frustum_blocks.bytes() } else { 0 };
    triangles + summary
}

/// What ran, as the outputs record it (`--stats` JSON `run`; the summary's first line).
#[derive(Clone, Debug, PartialEq, Eq, serde::Serialize)]
pub struct RunSummary {
    /// The preset the run started from.
    pub preset: Preset,
    /// `exact`, `plane` or `thesis`.
    pub lit_rule: &'static str,
    /// `light` or `voxel`.
    pub rays_from: &'static str,
    /// Plane thickness.
    pub thickness: String,
    /// Facet contour.
    pub contour: String,
    /// Grid side.
    pub n: u32,
    /// Fraction bits f.
    pub frac_bits: u32,
    /// FIFO size FA.
    pub fa: usize,
    /// Scheduling policy.
    pub policy: &'static str,
    /// Merging on.
    pub merge: bool,
    /// `rc2`, `thesis` or `custom` timing rules.
    pub timing: &'static str,
    /// `visible` (only the voxels pixels read) or `full`.
    pub lit_store: &'static str,
    /// The beam skips on.
    pub skips: Vec<&'static str>,
    /// Blocks per axis of the occupancy summary (used by the frustum and hidden skips).
    pub frustum_blocks: u32,
    /// The sibling wait in cycles (0: off).
    pub hold: u16,
    /// Faulty links.
    pub link_faults: bool,
    /// S: area lights sampled by S × S point sources (not written when 1: a point each).
    #[serde(skip_serializing_if = "is_one")]
    pub area_light: u32,
    /// `ratio` or `majority`: how pixels weigh the rays reaching them (not written for
    /// `target`, the default).
    #[serde(skip_serializing_if = "is_target")]
    pub visibility: &'static str,
}

fn is_target(v: &&'static str) -> bool {
    *v == Visibility::Target.name()
}

fn is_one(s: &u32) -> bool {
    *s == 1
}

impl RunSummary {
    /// One line: `preset render: exact rule, rays from the light, n = 128, f = 0, FA = 16, …`.
    pub fn line(&self) -> String {
        let skips = if self.skips.is_empty() { "none".to_string() } else { self.skips.join(" + ") };
        let mut s = format!(
            "preset {}: {} rule, rays from the {}, n = {}, {} + {} surfaces, f = {}, FA = {}, {}{} policy, {} timing, {} lit store, skips {}",
            self.preset,
            self.lit_rule,
            if self.rays_from == "light" { "light" } else { "source voxel" },
            self.n,
            self.thickness,
            self.contour,
            self.frac_bits,
            self.fa,
            self.policy,
            if self.merge { " + merge" } else { "" },
            self.timing,
            self.lit_store,
            skips,
        );
        if self.skips.iter().any(|k| *k == "empty frustum" || *k == "hidden") {
            s += &format!(" ({}-block summary)", self.frustum_blocks);
        }
        if self.hold > 0 {
            s += &format!(", hold {}", self.hold);
        }
        if self.link_faults {
            s += ", faulty links";
        }
        if self.area_light > 1 {
            s += &format!(", area lights sampled {0} × {0}", self.area_light);
        }
        if self.visibility != Visibility::Target.name() {
            s += &format!(", visibility by lit-ray {}", self.visibility);
        }
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// No override: the preset itself, and it validates.
    #[test]
    fn presets_resolve_to_themselves() {
        for p in Preset::ALL {
            let r = RunConfig::resolve(p, &Overrides::default(), Needs::default()).unwrap();
            assert_eq!(r, p.config(), "{p}");
        }
    }

    /// Reflections take the full store from `render` unless the command asks otherwise (then
    /// it is refused); the hidden skip follows the store; classic rays leave from the voxel.
    #[test]
    fn needs_adjust_the_defaults_and_refuse_contradictions() {
        let refl = Needs { reflections: true, ..Needs::default() };
        let r = RunConfig::resolve(Preset::Render, &Overrides::default(), refl).unwrap();
        assert!(!r.light.lit_visible_only && !r.light.skip_hidden);
        let o = Overrides { lit_visible_only: Some(true), ..Overrides::default() };
        assert!(RunConfig::resolve(Preset::Render, &o, refl).is_err());
        let o = Overrides { lit_visible_only: Some(false), ..Overrides::default() };
        let r = RunConfig::resolve(Preset::Render, &o, Needs::default()).unwrap();
        assert!(!r.light.skip_hidden, "the hidden skip follows the store");
        let o = Overrides { lit_visible_only: Some(false), skip_hidden: Some(true), ..Overrides::default() };
        assert!(RunConfig::resolve(Preset::Render, &o, Needs::default()).is_err());
        let classic = Needs { classic: true, ..Needs::default() };
        let r = RunConfig::resolve(Preset::Render, &Overrides::default(), classic).unwrap();
        assert_eq!(r.light.rays, Origin::SourceVoxel);
        let o = Overrides { rays: Some(Origin::Light), ..Overrides::default() };
        assert!(RunConfig::resolve(Preset::Render, &o, classic).is_err());
    }

    /// f is part of the diffusion's configuration, and only the values a build of the cells
    /// exists for validate (the cell_core list: 0..=8, 10, 12, 16, 20, 24).
    #[test]
    fn frac_bits_resolve_into_the_light_and_unbuilt_ones_are_refused() {
        for f in (0..=8).chain([10, 12, 16, 20, 24]) {
            let o = Overrides { frac_bits: Some(f), ..Overrides::default() };
            assert_eq!(RunConfig::resolve(Preset::Light, &o, Needs::default()).unwrap().light.frac_bits, f);
        }
        for f in [9, 11, 13, 17, 25, 32, u32::MAX] {
            let o = Overrides { frac_bits: Some(f), ..Overrides::default() };
            let e = RunConfig::resolve(Preset::Render, &o, Needs::default()).unwrap_err().to_string();
            assert!(e.contains(&format!("--frac-bits {f} is not supported")), "{e}");
        }
    }

    /// Merge is auto: off when the policy is overridden to the thesis's, unless asked.
    #[test]
    fn merge_follows_the_policy_unless_given() {
        let o = Overrides { policy: Some(Policy::Thesis), ..Overrides::default() };
        assert!(!RunConfig::resolve(Preset::Light, &o, Needs::default()).unwrap().light.merge);
        let o = Overrides { policy: Some(Policy::Thesis), merge: Some(true), ..Overrides::default() };
        assert!(RunConfig::resolve(Preset::Light, &o, Needs::default()).unwrap().light.merge);
    }

    /// docs/CONFIGURATION.md shows the line each preset prints, as printed.
    #[test]
    fn the_configuration_page_lists_each_presets_line() {
        let page = include_str!("../../../docs/CONFIGURATION.md");
        for p in Preset::ALL {
            let line = p.config().describe();
            assert!(page.lines().any(|l| l == line), "docs/CONFIGURATION.md lacks the line\n{line}");
        }
    }

    /// `--area-light S` is a field of the run: named in the description and the JSON only when
    /// S > 1 (S = 1, the presets', prints and writes what it did before the option); S = 0 is
    /// refused.
    #[test]
    fn area_light_is_described_only_when_sampled() {
        let o = Overrides { area_light: Some(3), ..Overrides::default() };
        let r = RunConfig::resolve(Preset::Render, &o, Needs::default()).unwrap();
        assert_eq!(r.area_light, 3);
        assert!(r.describe().ends_with(", area lights sampled 3 × 3"), "{}", r.describe());
        assert_eq!(serde_json::to_value(r.summary()).unwrap()["area_light"], 3);
        let one = Overrides { area_light: Some(1), ..Overrides::default() };
        let r1 = RunConfig::resolve(Preset::Render, &one, Needs::default()).unwrap();
        assert_eq!(r1, Preset::Render.config());
        assert!(serde_json::to_value(r1.summary()).unwrap().get("area_light").is_none());
        let zero = Overrides { area_light: Some(0), ..Overrides::default() };
        assert!(RunConfig::resolve(Preset::Render, &zero, Needs::default()).is_err());
    }

    /// `--visibility ratio|majority` is described and written; `target` (every preset's) is
    /// not; a rule without exact occluders refuses it.
    #[test]
    fn visibility_is_described_only_when_counting() {
        for v in [Visibility::Ratio, Visibility::Majority] {
            let o = Overrides { visibility: Some(v), ..Overrides::default() };
            let r = RunConfig::resolve(Preset::Render, &o, Needs::default()).unwrap();
            assert!(r.describe().ends_with(&format!(", visibility by lit-ray {}", v.name())), "{}", r.describe());
            assert_eq!(serde_json::to_value(r.summary()).unwrap()["visibility"], v.name());
            let plane = Overrides { rule: Some(LitRule::Plane), ..o };
            assert!(RunConfig::resolve(Preset::Render, &plane, Needs::default()).is_err());
        }
        for p in Preset::ALL {
            assert_eq!(p.light().visibility, Visibility::Target, "{p}");
            assert!(serde_json::to_value(p.config().summary()).unwrap().get("visibility").is_none());
        }
    }

    /// The description names the preset and the decisive settings.
    #[test]
    fn the_description_says_what_ran() {
        let d = Preset::Render.config().describe();
        for part in ["preset render", "exact rule", "rays from the light", "visible lit store", "hidden"] {
            assert!(d.contains(part), "{d:?} lacks {part:?}");
        }
        let d = Preset::Thesis.config().describe();
        for part in ["preset thesis", "thesis rule", "source voxel", "naive + projected", "skips none"] {
            assert!(d.contains(part), "{d:?} lacks {part:?}");
        }
    }
}
