//! Command-line options of the classic, reflection and radiosity phases (flattened into
//! `light`/`render`, and `radiosity`).

use cell_core::lit::LitRule;
use cell_core::ray::Connectivity;
use cell_core::reflect::{HitPoint, ReflectNormal};
use cell_core::route::RoutePolicy;

use crate::jobs::radiosity::{RadiositySettings, ShotsBy};
use crate::machine::rays::classic::ClassicConfig;
use crate::machine::rays::mirror::ReflectConfig;
use crate::machine::shooting::indirect::Display;
use crate::machine::shooting::proxels::Update;

/// How the lighting jobs compute the lit state.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum LightingArg {
    /// Beam diffusion from each source (§4.3).
    Diffusion,
    /// One shadow ray per visible voxel and source, answers routed back (§4.1.2).
    Classic,
    /// Beam diffusion, then one classic shadow ray from each pixel on a diffused shadow's edge
    /// (a neighbour lit otherwise), whose answer replaces the diffused one (`render` only).
    Refined,
}

/// Answer routing of the classic phase.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum RouteArg {
    /// Diagonal first, then straight.
    Dor,
    /// The minimal move with the most free buffer space.
    Adaptive,
}

/// Command-line options of the classic phase (flattened into the lighting options).
#[derive(clap::Args, Debug, Clone)]
pub struct ClassicOpts {
    /// Lighting method: diffusion (beams), classic (shadow rays, answers routed back), or
    /// refined (diffusion, then classic shadow rays from the pixels on shadow edges only, whose
    /// answers replace the diffused ones; its cost and gain: BENCHMARKS.md).
    #[arg(long, value_enum, default_value_t = LightingArg::Diffusion)]
    pub lighting: LightingArg,
    /// Connectivity of classic shadow rays: 6 (Amanatides–Woo; no surface thickness lets it
    /// through), 18, or 26 (DDA; passes through naive surfaces).
    #[arg(long, default_value_t = 6, value_parser = parse_connectivity)]
    pub ray_connectivity: u8,
    /// Routing of classic answers.
    #[arg(long, value_enum, default_value_t = RouteArg::Adaptive)]
    pub route: RouteArg,
    /// Which voxels send classic shadow rays: the visible ones (what the image needs) or all
    /// occupied voxels (the thesis's count, §4.1.6).
    #[arg(long, value_enum, default_value_t = EmittersArg::Visible)]
    pub emitters: EmittersArg,
    /// Shadow bias of classic rays: the first K voxels after the emitter's are not tested, so
    /// a ray ignores the neighbouring facets of its own object (shadow acne) but misses shadows
    /// cast within K voxels. 0 (default) = only the emitter's own facet is ignored. The thesis's
    /// and the plane rule only: under exact occluders a ray's segment starts ¼ voxel in front
    /// of its surface.
    #[arg(long, default_value_t = 0)]
    pub shadow_bias: u8,
}

/// Emitters of classic shadow rays.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum EmittersArg {
    /// The first occupied voxel of each column.
    Visible,
    /// Every occupied voxel.
    All,
}

/// The connectivity of a `--ray-connectivity` value (6, 18 or 26).
pub fn connectivity(k: u8) -> Connectivity {
    match k {
        18 => Connectivity::Eighteen,
        26 => Connectivity::TwentySix,
        _ => Connectivity::Six,
    }
}

pub(crate) fn parse_connectivity(s: &str) -> std::result::Result<u8, String> {
    match s {
        "6" => Ok(6),
        "18" => Ok(18),
        "26" => Ok(26),
        _ => Err(format!("'{s}' is not a ray connectivity: 6, 18 or 26")),
    }
}

impl ClassicOpts {
    /// The classic configuration with FIFO limit `fa` and lit rule `rule`.
    pub fn config(&self, fa: usize, rule: LitRule) -> ClassicConfig {
        ClassicConfig {
            fa,
            connectivity: connectivity(self.ray_connectivity),
            route: match self.route {
                RouteArg::Dor => RoutePolicy::DiagonalFirst,
                RouteArg::Adaptive => RoutePolicy::Adaptive,
            },
            all_voxels: self.emitters == EmittersArg::All,
            bias: self.shadow_bias,
            rule,
        }
    }
}

/// Normal that mirrors reflected rays (§5.2).
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum ReflectNormalArg {
    /// The facet normal stored in each dexel (§5.2.1).
    Facet,
    /// The face of the voxel the ray entered: flip that component (§5.2.2, the face flip of §5.5.4).
    Face,
}

/// Where a reflected ray leaves the voxel it reflects from (§5.3).
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum HitArg {
    /// Where the incident ray entered the voxel, on the face it crossed (§5.3.1).
    Edge,
    /// The voxel's centre: the incident ray moved parallel to itself through it (§5.3.2).
    Centre,
    /// Where the incident ray meets the plane the voxel's dexel stores, kept inside the voxel
    /// (§5.3.3).
    Exact,
}

impl From<ReflectNormalArg> for ReflectNormal {
    fn from(a: ReflectNormalArg) -> Self {
        match a {
            ReflectNormalArg::Facet => ReflectNormal::Facet,
            ReflectNormalArg::Face => ReflectNormal::Face,
        }
    }
}

impl From<HitArg> for HitPoint {
    fn from(a: HitArg) -> Self {
        match a {
            HitArg::Edge => HitPoint::Edge,
            HitArg::Centre => HitPoint::Centre,
            HitArg::Exact => HitPoint::Exact,
        }
    }
}

/// Command-line options of the reflection phase (`render`, `trace`).
#[derive(clap::Args, Debug, Clone)]
pub struct ReflectOpts {
    /// Mirror reflections: largest depth of the distributed ray tree (reflections per path);
    /// 0 = off. Needs `--lighting diffusion` (the lit state of every voxel).
    #[arg(long, default_value_t = 0, value_parser = clap::value_parser!(u8).range(0..=32))]
    pub reflections: u8,
    /// Hall's adaptive depth (§1.2.5.1): a voxel reflects only while the product of the Kr along
    /// the path is at least this.
    #[arg(long, default_value_t = 0.01)]
    pub reflect_threshold: f32,
    /// Normal that mirrors the reflected rays: facet (stored normal) or face (face flip, §5.5.4).
    #[arg(long, value_enum, default_value_t = ReflectNormalArg::Facet)]
    pub reflect_normal: ReflectNormalArg,
    /// Where a reflected ray leaves the voxel it reflects from, and so the origin of its line
    /// (thesis §5.3): the entry point on the voxel's face, the voxel's centre, or the exact
    /// intersection with the facet plane the voxel stores (moved into the voxel when it lies
    /// outside it).
    #[arg(long, value_enum, default_value_t = HitArg::Centre)]
    pub hit: HitArg,
    /// Let reflected rays hit the voxels of the facet they left (shows the §5.5.2 self-collision).
    #[arg(long)]
    pub reflect_self_hits: bool,
}

impl ReflectOpts {
    /// The configuration (rays use the classic options' connectivity and routing).
    pub fn config(&self, fa: usize, classic: &crate::machine::rays::classic::ClassicConfig) -> ReflectConfig {
        ReflectConfig {
            depth: self.reflections,
            threshold: self.reflect_threshold,
            normal: self.reflect_normal.into(),
            hit: self.hit.into(),
            skip_own_facet: !self.reflect_self_hits,
            connectivity: classic.connectivity,
            fa,
            route: classic.route,
        }
    }
}

/// Command-line options of a radiosity solution: the `radiosity` job's and `render --radiosity`'s.
/// Unset, each takes the default its help gives ([`RadiositySettings::default`]).
#[derive(clap::Args, Debug, Clone)]
pub struct RadiosityOpts {
    /// Largest patch edge, in voxels [default: 24].
    #[arg(long)]
    pub patch_size: Option<f64>,
    /// Shot budget [default: 100000].
    #[arg(long)]
    pub shots: Option<usize>,
    /// Stop when the unshot power is at most this fraction of the emitted power [default: 0.01].
    #[arg(long)]
    pub residual: Option<f64>,
    /// Push of each shot's source off its patch's centre, voxels along the normal [default: 2].
    #[arg(long)]
    pub offset: Option<f64>,
    /// How the f64 reference (--reference) samples its form factors [default: beams]. `beams`:
    /// the exact contour integral times a ray-cast visible fraction. A projective surface of
    /// the radiosity thesis, ch. 2, applied at each sample point of a patch: `hemicube:R`
    /// (R even), `sillion:R`, `recker:R1/R2`, `hemisphere-uniform:R`, `hemisphere:R`, `disk:R`
    /// (docs/FORM-FACTORS.md; R up to 4000). The machine shoots by beam diffusion whatever
    /// this says.
    #[arg(long, value_name = "METHOD", value_parser = crate::cli::parse_form_factors)]
    pub form_factors: Option<crate::truth::formfactor::Estimator>,
    /// With --reference: also solve a converged truth (the contour estimator with 6 × 6 sample
    /// points per patch triangle, to a tenth of --residual) and report the reference's (with
    /// its --form-factors) and the machine's per-patch errors against it, on the reflected
    /// radiosity; `render` also renders the truth's image and gives the PSNR of the
    /// reference's and the machine's images against it.
    #[arg(long, requires = "reference")]
    pub truth_error: bool,
    /// How the machine computes each shot's form factors [default: beams]. `beams`: one beam
    /// diffusion from the shooting patch (radiosity thesis ch. 5). `proxels-hemicube`,
    /// `proxels-disk`: the shooter's hemicube or projection disk distributed over the cells
    /// (thesis §6.2: cyclic proxels, patches modulo the cells, each triangle's projection
    /// broadcast and z-tested in the zones its bounding rectangle covers). `hybrid`: the
    /// hemicube by the method of §6.4 (each triangle cut into spans by the cell that owns it,
    /// the spans sent to the cells of their first proxels and z-buffered along the rows). The
    /// shots CSV then adds the projection's and every update strategy's costs
    /// (docs/RADIOSITY.md).
    #[arg(long, value_enum, value_name = "METHOD")]
    pub shots_by: Option<ShotsByArg>,
    /// With --shots-by proxels-* or hybrid: the surface's resolution R (the hemicube's R × R top face,
    /// R even; the disk's R × R square) [default: 2n].
    #[arg(long, value_name = "R", requires = "shots_by")]
    pub resolution: Option<u32>,
    /// With --shots-by proxels-* or hybrid: the update (proxel quanta to their patches' cells, thesis
    /// §6.2.6) the shots' cycles count; the CSV has them all [default: reduce]. `xnet-proxels`:
    /// proxels move east then south, zone after zone; `xnet-modulo`: each cell starts at its
    /// own zone; `xnet-facets`: patches visit every cell; `router-proxels`, `router-modulo`:
    /// through a global router of 16-cell groups (the MasPar's); `reduce`: per-cell sums
    /// merged to cell (0, 0) along the rows and column 0.
    #[arg(long, value_enum, value_name = "STRATEGY", requires = "shots_by")]
    pub update: Option<UpdateArg>,
    /// Shots under way at once (the radiosity thesis's "several emissions at once", ch. 5):
    /// each carries its shooter's unshot radiosity as it was when chosen, and what a patch
    /// receives while its own shot is under way stays unshot; the shots land in the order they
    /// started. 1: the one-shot-at-a-time supervisor [default: 1].
    #[arg(long, value_name = "K", value_parser = clap::value_parser!(u32).range(1..=1024))]
    pub in_flight: Option<u32>,
    /// With --in-flight K > 1: how the shooters are chosen [default: table]. `table`: a central
    /// table of unshot power (Feda's): whenever a shot lands the patch with the most unshot
    /// power not under way starts, so K shots are always under way. `rounds`: the K patches
    /// with the most unshot power shoot together, and the next K are chosen once all have
    /// landed (Thomin's).
    #[arg(long, value_enum, value_name = "CHOICE", requires = "in_flight")]
    pub shooter_choice: Option<ShooterChoiceArg>,
}

/// `--shooter-choice`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum ShooterChoiceArg {
    /// A central table of unshot power: a new shooter as each shot lands.
    Table,
    /// Rounds of the K largest.
    Rounds,
}

impl From<ShooterChoiceArg> for crate::machine::shooting::shots::ShooterChoice {
    fn from(a: ShooterChoiceArg) -> Self {
        use crate::machine::shooting::shots::ShooterChoice;
        match a {
            ShooterChoiceArg::Table => ShooterChoice::Table,
            ShooterChoiceArg::Rounds => ShooterChoice::Rounds,
        }
    }
}

/// `--shots-by`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum ShotsByArg {
    /// Beam diffusion (thesis ch. 5).
    Beams,
    /// The hemicube on the cells (§6.2).
    ProxelsHemicube,
    /// The projection disk on the cells (§6.2).
    ProxelsDisk,
    /// The hemicube by spans (§6.4).
    Hybrid,
}

impl From<ShotsByArg> for ShotsBy {
    fn from(a: ShotsByArg) -> Self {
        match a {
            ShotsByArg::Beams => ShotsBy::Beams,
            ShotsByArg::ProxelsHemicube => ShotsBy::ProxelsHemicube,
            ShotsByArg::ProxelsDisk => ShotsBy::ProxelsDisk,
            ShotsByArg::Hybrid => ShotsBy::Hybrid,
        }
    }
}

/// `--update`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum UpdateArg {
    /// Proxels over the links, zone after zone.
    XnetProxels,
    /// Proxels over the links, the modulo zone choice.
    XnetModulo,
    /// Patches visiting every cell.
    XnetFacets,
    /// Proxels through a global router.
    RouterProxels,
    /// The router, the modulo zone choice.
    RouterModulo,
    /// Per-cell sums merged to cell (0, 0).
    Reduce,
}

impl From<UpdateArg> for Update {
    fn from(a: UpdateArg) -> Self {
        match a {
            UpdateArg::XnetProxels => Update::XnetProxels,
            UpdateArg::XnetModulo => Update::XnetModulo,
            UpdateArg::XnetFacets => Update::XnetFacets,
            UpdateArg::RouterProxels => Update::RouterProxels,
            UpdateArg::RouterModulo => Update::RouterModulo,
            UpdateArg::Reduce => Update::Reduce,
        }
    }
}

impl RadiosityOpts {
    /// The first option given, as its flag (to refuse it where radiosity is off).
    pub fn first_given(&self) -> Option<&'static str> {
        [
            (self.patch_size.is_some(), "--patch-size"),
            (self.shots.is_some(), "--shots"),
            (self.residual.is_some(), "--residual"),
            (self.offset.is_some(), "--offset"),
            (self.form_factors.is_some(), "--form-factors"),
            (self.truth_error, "--truth-error"),
            (self.shots_by.is_some(), "--shots-by"),
            (self.resolution.is_some(), "--resolution"),
            (self.update.is_some(), "--update"),
            (self.in_flight.is_some(), "--in-flight"),
            (self.shooter_choice.is_some(), "--shooter-choice"),
        ]
        .into_iter()
        .find_map(|(given, flag)| given.then_some(flag))
    }
}

impl From<&RadiosityOpts> for RadiositySettings {
    fn from(a: &RadiosityOpts) -> Self {
        let d = RadiositySettings::default();
        RadiositySettings {
            patch_size: a.patch_size.unwrap_or(d.patch_size),
            shots: a.shots.unwrap_or(d.shots),
            residual: a.residual.unwrap_or(d.residual),
            offset: a.offset.unwrap_or(d.offset),
            estimator: a.form_factors.unwrap_or(d.estimator),
            shots_by: a.shots_by.map_or(d.shots_by, Into::into),
            resolution: a.resolution.or(d.resolution),
            update: a.update.map_or(d.update, Into::into),
            in_flight: a.in_flight.map_or(d.in_flight, |k| k as usize),
            choice: a.shooter_choice.map_or(d.choice, Into::into),
        }
    }
}

/// How `render --radiosity` shows a patch's radiosity.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum DisplayArg {
    /// The value of the patch holding the visible point.
    Flat,
    /// Vertex values (the mean of the patches around each vertex) interpolated over the patch.
    Smooth,
}

impl From<DisplayArg> for Display {
    fn from(a: DisplayArg) -> Self {
        match a {
            DisplayArg::Flat => Display::Flat,
            DisplayArg::Smooth => Display::Smooth,
        }
    }
}
