//! Progressive-refinement radiosity in `f64` (Cohen et al. 1988; radiosity thesis §1.3.2,
//! "radiosité par raffinement progressif"): the reference solution the machine's radiosity is
//! measured against.
//!
//! The system solved is the thesis's Eq. 1.4, per channel, `B_j = E_j + ρ_j H_j` with the
//! irradiance `H_j = Σ_i B_i F_ij A_i / A_j` (the reciprocity form of `Σ_i F_ji B_i`, so that
//! the progressive and the direct solutions use the very same numbers `F_ij`, rows of shooters).
//! Shooting: every patch keeps its *unshot* radiosity ("radiosité latente") `U`, first its
//! emission `E`. Each shot picks the patch i with the largest unshot power, `U_i A_i` summed
//! over the three channels (every channel counts alike: the solution is the same, only the shot
//! order depends on it), gives every other patch j `ΔH_j = U_i F_ij A_i / A_j`, adds `ρ_j ΔH_j`
//! to its radiosity and to its unshot radiosity, and sets `U_i = 0`.
//!
//! Invariants, after every shot, with powers summed over the channels:
//! * `emitted = absorbed + unshot + leaked` ([`balance`]): `absorbed = Σ (1−ρ_j) H_j A_j`,
//!   `leaked` = shot power that reached no patch (`1 − Σ_j F_ij` of each shot: 0 in a closed
//!   scene with exact form factors);
//! * the residual fraction (unshot / emitted power) never increases when `Σ_j F_ij ≤ 1` and
//!   `ρ ≤ 1`;
//! * it stops when the residual fraction is at most [`ShootConfig::stop_fraction`] (before a
//!   shot) or after [`ShootConfig::max_shots`] shots.
//!
//! The ambient term of §1.3.2 ("utilisation d'un terme ambiant") is for display only and never
//! enters the solution: [`ambient`], [`displayed`].

use anyhow::{bail, Result};

use super::formfactor::FormFactors;
use crate::scene::patches::Patch;

/// When to stop shooting.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct ShootConfig {
    /// Stop once the unshot power is at most this fraction of the emitted power (0..1).
    pub stop_fraction: f64,
    /// Stop after this many shots at the most.
    pub max_shots: usize,
}

impl Default for ShootConfig {
    fn default() -> Self {
        ShootConfig { stop_fraction: 0.01, max_shots: 100_000 }
    }
}

/// One shot.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ShotRecord {
    /// The patch that shot.
    pub patch: usize,
    /// Its unshot power before the shot (`U_i A_i`, channels summed).
    pub unshot_power: f64,
    /// Unshot over emitted power after the shot.
    pub residual_after: f64,
}

/// Why shooting stopped.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum Stop {
    /// The residual fraction reached [`ShootConfig::stop_fraction`].
    Converged,
    /// [`ShootConfig::max_shots`] shots were made first.
    ShotBudget,
}

/// A progressive solution.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Solution {
    /// Radiosity `B` per patch (RGB).
    pub radiosity: Vec<[f64; 3]>,
    /// Irradiance received so far `H` per patch (RGB).
    pub irradiance: Vec<[f64; 3]>,
    /// Unshot radiosity `U` per patch ("radiosité latente").
    pub unshot: Vec<[f64; 3]>,
    /// Every shot, in order.
    pub shots: Vec<ShotRecord>,
    /// Why it stopped.
    pub stop: Stop,
    /// Emitted power `Σ E A` (channels summed).
    pub emitted_power: f64,
    /// Unshot over emitted power at the end.
    pub residual: f64,
    /// Power shot in all (channels summed).
    pub shot_power: f64,
    /// Power received by patches in all (channels summed).
    pub received_power: f64,
}

/// Power of a per-area RGB quantity on an area: channels summed.
pub fn power(v: [f64; 3], area: f64) -> f64 {
    (v[0] + v[1] + v[2]) * area
}

/// Check what the solvers assume of the patches: area > 0, ρ in [0, 1], E ≥ 0, all finite;
/// and some patch emits. Returns the emitted power.
pub fn check_patches(patches: &[Patch]) -> Result<f64> {
    for (i, p) in patches.iter().enumerate() {
        if !(p.area.is_finite() && p.area > 0.0) {
            bail!("radiosity: patch {i} (face {}) has area {}", p.face, p.area);
        }
        if !p.reflectance.iter().all(|r| (0.0..=1.0).contains(r)) {
            bail!("radiosity: patch {i} (face {}) has reflectance {:?}, outside [0, 1]", p.face, p.reflectance);
        }
        if !p.emission.iter().all(|e| e.is_finite() && *e >= 0.0) {
            bail!("radiosity: patch {i} (face {}) has emission {:?}: not a finite E ≥ 0", p.face, p.emission);
        }
    }
    let emitted: f64 = patches.iter().map(|p| power(p.emission, p.area)).sum();
    if emitted.is_nan() || emitted <= 0.0 {
        bail!("radiosity: no emitter: no patch has a material with Ke > 0 ({} patches)", patches.len());
    }
    Ok(emitted)
}

/// Progressive refinement with form factor rows from `row(i)` (`F_ij` for every j; the
/// machine's own rows plug in here as well as [`FormFactors::row`]).
///
/// Errors: the patches fail [`check_patches`] (no emitter included), `stop_fraction` is not in
/// [0, 1), or a row has the wrong length or a negative or non-finite entry.
pub fn progressive<R>(patches: &[Patch], cfg: &ShootConfig, mut row: R) -> Result<Solution>
where
    R: FnMut(usize) -> Result<Vec<f64>>,
{
    let emitted = check_patches(patches)?;
    if !(cfg.stop_fraction >= 0.0 && cfg.stop_fraction < 1.0) {
        bail!("radiosity: the stop fraction must be in [0, 1), got {}", cfg.stop_fraction);
    }
    let mut s = start(patches, emitted);
    loop {
        if s.residual <= cfg.stop_fraction {
            s.stop = Stop::Converged;
            break;
        }
        if s.shots.len() >= cfg.max_shots {
            break;
        }
        let i = select(patches, &s.unshot);
        let f = row(i)?;
        check_row(i, &f, patches.len())?;
        shoot(patches, &mut s, i, &f);
    }
    Ok(s)
}

/// [`progressive`] with rows from `ff` ([`FormFactors::row`]: a shooter shot again reuses its
/// row).
pub fn solve(patches: &[Patch], ff: &FormFactors, cfg: &ShootConfig) -> Result<Solution> {
    if ff.len() != patches.len() {
        bail!("radiosity: {} patches but form factors for {}", patches.len(), ff.len());
    }
    progressive(patches, cfg, |i| ff.row(i))
}

/// The initial state: B = U = E, nothing shot.
fn start(patches: &[Patch], emitted: f64) -> Solution {
    let e: Vec<[f64; 3]> = patches.iter().map(|p| p.emission).collect();
    Solution {
        radiosity: e.clone(),
        irradiance: vec![[0.0; 3]; patches.len()],
        unshot: e,
        shots: Vec::new(),
        stop: Stop::ShotBudget,
        emitted_power: emitted,
        residual: 1.0,
        shot_power: 0.0,
        received_power: 0.0,
    }
}

/// The patch with the largest unshot power (the lowest index among equals).
fn select(patches: &[Patch], unshot: &[[f64; 3]]) -> usize {
    let mut best = (0, f64::NEG_INFINITY);
    for (i, (p, u)) in patches.iter().zip(unshot).enumerate() {
        let w = power(*u, p.area);
        if w > best.1 {
            best = (i, w);
        }
    }
    best.0
}

fn check_row(i: usize, f: &[f64], n: usize) -> Result<()> {
    if f.len() != n {
        bail!("radiosity: the form factor row of patch {i} has {} entries for {n} patches", f.len());
    }
    if let Some(j) = f.iter().position(|x| !(x.is_finite() && *x >= 0.0)) {
        bail!("radiosity: F[{i}][{j}] = {} is not a finite non-negative number", f[j]);
    }
    Ok(())
}

/// Patch i shoots its unshot radiosity through row `f`.
fn shoot(patches: &[Patch], s: &mut Solution, i: usize, f: &[f64]) {
    let u = s.unshot[i];
    let shot = power(u, patches[i].area);
    let mut received = 0.0;
    for (j, (pj, &fij)) in patches.iter().zip(f).enumerate() {
        if j == i || fij == 0.0 {
            continue;
        }
        let t = fij * patches[i].area / pj.area;
        for (c, uc) in u.iter().enumerate() {
            let dh = uc * t;
            s.irradiance[j][c] += dh;
            s.radiosity[j][c] += pj.reflectance[c] * dh;
            s.unshot[j][c] += pj.reflectance[c] * dh;
        }
        received += power(u, fij * patches[i].area);
    }
    s.unshot[i] = [0.0; 3];
    s.shot_power += shot;
    s.received_power += received;
    let unshot: f64 = patches.iter().zip(&s.unshot).map(|(p, u)| power(*u, p.area)).sum();
    s.residual = unshot / s.emitted_power;
    s.shots.push(ShotRecord { patch: i, unshot_power: shot, residual_after: s.residual });
}

/// The ambient radiosity of §1.3.2 (Cohen et al. 1988): the unshot power spread over the
/// whole area and multiplied by the interreflection factor `1 / (1 − ρ̄)` of the area-weighted
/// mean reflectance ρ̄, per channel — an estimate of what the unshot energy will add to an
/// average patch. Display only. A channel with ρ̄ = 1 and some unshot power gives ∞.
pub fn ambient(patches: &[Patch], unshot: &[[f64; 3]]) -> [f64; 3] {
    let area: f64 = patches.iter().map(|p| p.area).sum();
    if area.is_nan() || area <= 0.0 {
        return [0.0; 3];
    }
    let mut out = [0.0; 3];
    for c in 0..3 {
        let rho: f64 = patches.iter().map(|p| p.reflectance[c] * p.area).sum::<f64>() / area;
        let u: f64 = patches.iter().zip(unshot).map(|(p, u)| u[c] * p.area).sum::<f64>() / area;
        out[c] = if u == 0.0 { 0.0 } else { u / (1.0 - rho) };
    }
    out
}

/// The radiosity to display while iterating: `B_j + ρ_j · ambient` (§1.3.2).
pub fn displayed(patches: &[Patch], s: &Solution) -> Vec<[f64; 3]> {
    let a = ambient(patches, &s.unshot);
    patches.iter().zip(&s.radiosity).map(|(p, b)| [0, 1, 2].map(|c| b[c] + p.reflectance[c] * a[c])).collect()
}

/// The power bookkeeping of a solution (channels summed).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct Balance {
    /// `Σ E A`.
    pub emitted: f64,
    /// `Σ (1 − ρ_j) H_j A_j`.
    pub absorbed: f64,
    /// `Σ U A`.
    pub unshot: f64,
    /// Shot power that reached no patch.
    pub leaked: f64,
}

/// The power balance of a solution: `emitted = absorbed + unshot + leaked` up to rounding.
pub fn balance(patches: &[Patch], s: &Solution) -> Balance {
    let absorbed = patches
        .iter()
        .zip(&s.irradiance)
        .map(|(p, h)| (0..3).map(|c| (1.0 - p.reflectance[c]) * h[c]).sum::<f64>() * p.area)
        .sum();
    let unshot = patches.iter().zip(&s.unshot).map(|(p, u)| power(*u, p.area)).sum();
    Balance { emitted: s.emitted_power, absorbed, unshot, leaked: s.shot_power - s.received_power }
}

/// Direct solution of the same system (Jacobi iteration, the thesis's "approximations
/// successives" of §1.3.1 started from `B = E`) with the full matrix `f[i][j] = F_ij`: until the
/// largest change of an iteration is at most `tol` × the largest radiosity.
///
/// Errors: the patches fail [`check_patches`], `f` is not n × n, or no convergence in
/// `max_iter` iterations.
pub fn jacobi(patches: &[Patch], f: &[Vec<f64>], tol: f64, max_iter: usize) -> Result<Vec<[f64; 3]>> {
    check_patches(patches)?;
    let n = patches.len();
    if f.len() != n || f.iter().any(|r| r.len() != n) {
        bail!("radiosity: the form factor matrix is not {n} × {n}");
    }
    let mut b: Vec<[f64; 3]> = patches.iter().map(|p| p.emission).collect();
    for _ in 0..max_iter {
        let mut h = vec![[0.0; 3]; n];
        for (i, (pi, bi)) in patches.iter().zip(&b).enumerate() {
            for (j, hj) in h.iter_mut().enumerate() {
                let t = f[i][j] * pi.area;
                for c in 0..3 {
                    hj[c] += t * bi[c];
                }
            }
        }
        let next: Vec<[f64; 3]> = patches
            .iter()
            .zip(&h)
            .map(|(p, h)| [0, 1, 2].map(|c| p.emission[c] + p.reflectance[c] * h[c] / p.area))
            .collect();
        let scale = next.iter().flatten().fold(0.0f64, |m, x| m.max(x.abs()));
        let change = next.iter().flatten().zip(b.iter().flatten()).fold(0.0f64, |m, (x, y)| m.max((x - y).abs()));
        b = next;
        if change <= tol * scale {
            return Ok(b);
        }
    }
    bail!("radiosity: Jacobi did not converge to {tol} in {max_iter} iterations")
}

/// The indirect irradiance of a solution (RGB per patch): its irradiance less the direct light,
/// `Σ E_i F_ij A_i / A_j` over the emitters i that shot (a patch's emission is in its unshot
/// radiosity until its first shot, and leaves then). `row(i)` gives `F_ij` for every j, the rows
/// the solution was made with. Rounding below zero is clamped to zero.
///
/// Errors: a row fails or has the wrong length.
pub fn indirect_irradiance<R>(patches: &[Patch], s: &Solution, mut row: R) -> Result<Vec<[f64; 3]>>
where
    R: FnMut(usize) -> Result<Vec<f64>>,
{
    let mut h = s.irradiance.clone();
    let mut shooters: Vec<usize> = s.shots.iter().map(|r| r.patch).collect();
    shooters.sort_unstable();
    shooters.dedup();
    for i in shooters.into_iter().filter(|&i| patches[i].emission.iter().any(|&e| e > 0.0)) {
        let f = row(i)?;
        check_row(i, &f, patches.len())?;
        for (j, (pj, fij)) in patches.iter().zip(&f).enumerate() {
            if j == i {
                continue;
            }
            for (hc, ec) in h[j].iter_mut().zip(patches[i].emission) {
                *hc -= ec * fij * patches[i].area / pj.area;
            }
        }
    }
    Ok(h.into_iter().map(|v| v.map(|x| x.max(0.0))).collect())
}

/// The reflected part of a radiosity solution, `B − E` per patch: what the solvers compute (the
/// emission is given). Compare these rather than `B` when bright emitters would dominate.
pub fn reflected(patches: &[Patch], radiosity: &[[f64; 3]]) -> Vec<[f64; 3]> {
    patches.iter().zip(radiosity).map(|(p, b)| [0, 1, 2].map(|c| b[c] - p.emission[c])).collect()
}

/// Area-weighted RMS relative error of `other` against `reference`, per-patch RGB solutions:
/// `√(Σ A_i |b_i − a_i|² / Σ A_i |a_i|²)` (|·| the Euclidean norm over the channels): the RMS
/// error relative to the reference's RMS, so dark patches do not blow it up (and bright ones
/// weigh in: see [`reflected`]).
///
/// Errors: the lengths differ, a value or area is not finite, or the reference is all zero.
pub fn rms_relative_error(reference: &[[f64; 3]], other: &[[f64; 3]], areas: &[f64]) -> Result<f64> {
    if reference.len() != other.len() || reference.len() != areas.len() {
        bail!(
            "radiosity: {} reference values, {} values, {} areas: the lengths differ",
            reference.len(),
            other.len(),
            areas.len()
        );
    }
    let (mut num, mut den) = (0.0, 0.0);
    for ((a, b), w) in reference.iter().zip(other).zip(areas) {
        for c in 0..3 {
            num += w * (b[c] - a[c]) * (b[c] - a[c]);
            den += w * a[c] * a[c];
        }
    }
    if !(num.is_finite() && den.is_finite()) {
        bail!("radiosity: a radiosity or an area is not finite");
    }
    if den == 0.0 {
        bail!("radiosity: the reference solution is zero everywhere: no relative error");
    }
    Ok((num / den).sqrt())
}
