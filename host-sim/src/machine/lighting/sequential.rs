//! The thesis's other emission mode, rays one after another (§4.2.4 "Envoi de rayons les uns
//! après les autres"), on the diffusion table's grid: an empty n³ scene, the source at voxel
//! (n/2, n/2, n/2), the same rays as the beams carry (the six initial beams' lattices, far
//! distance D = n − 1, f fraction bits).
//!
//! The source emits ray i at cycle i; every cycle each ray moves one layer, processed by the
//! cell that owns its voxel. The thesis counts no conflicts ("il ne peut donc y avoir 2 rayons
//! simultanément dans la même cellule"), so ray i is processed at layer k in cycle i + k and
//! the run ends when the last ray leaves: T = max_i (i + L_i), L_i the layers ray i spends in
//! the grid — the thesis's T = N_T + n. (In 3D two rays of different distances can share a
//! column in one cycle; counting that would only add cycles: this T is the mode's best case.)
//! Messages: the steps from one layer to the next that change cell (every step of a ±x or ±y
//! ray; a ±z ray's steps that change column).

use anyhow::{anyhow, Result};
use cell_core::beam::{trace_ray_voxel, Beam, FarDistance, FarOffset, FracBits, Layer, Source, SourceCoord, SourceId};

use crate::machine::lighting::timing::Emission;

/// The ray-by-ray mode's (cycles, inter-cell messages) on the empty n³ grid, source at the
/// centre (or at the origin, `origin`), initial beams in the default emission order.
pub fn ray_by_ray(n: u32, origin: bool, f: u32) -> Result<(u64, u64)> {
    crate::machine::lighting::diffuse::with_f!(f, F => ray_by_ray_f::<F>(n, origin))
}

/// [`ray_by_ray`] under f = `F`.
fn ray_by_ray_f<F: FracBits>(n: u32, origin: bool) -> Result<(u64, u64)> {
    let c = SourceCoord::from_num(if origin { 0 } else { n / 2 });
    let src = Source::new(SourceId(0), [c; 3]);
    let far = FarDistance::<F>::new(n.max(2) - 1)
        .ok_or_else(|| anyhow!("far distance {} exceeds the beam bit budget for {} fraction bits", n - 1, F::U32))?;
    let (d, steps) = (far.get() as i64, 1i64 << F::U32);
    let sv = src.voxel().map(i64::from);
    let inside = |p: i64| (0..n as i64).contains(&p);
    let (mut index, mut t, mut messages) = (0u64, 0u64, 0u64);
    for dir in Emission::XyFirst.order() {
        let (w, s) = (dir.principal().index(), dir.sign() as i64);
        debug_assert_eq!(Beam::initial(&src, dir, far).ray_count(), ((2 * d * steps + 1) * (2 * d * steps + 1)) as u64);
        for u in -d * steps..=d * steps {
            for v in -d * steps..=d * steps {
                let (fu, fv) = (FarOffset::<F>::from_bits(u as i32), FarOffset::<F>::from_bits(v as i32));
                let mut last: Option<(i64, i64)> = None;
                let mut k = 0u32;
                while inside(sv[w] + s * k as i64) {
                    let at = trace_ray_voxel(&src, dir, fu, fv, far, Layer(k));
                    if !inside(at.0) || !inside(at.1) {
                        break;
                    }
                    let moves = w != 2 || last.is_some_and(|l| l != at);
                    messages += u64::from(k > 0 && moves);
                    last = Some(at);
                    k += 1;
                }
                t = t.max(index + k as u64);
                index += 1;
            }
        }
    }
    Ok((t, messages))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The mode traced again in f64, ray by ray (voxel ⌊s + u·k/D + ½⌋ per transverse axis,
    /// exact for these small integers), in the same emission order.
    fn oracle(n: u32, origin: bool) -> (u64, u64) {
        let c = if origin { 0.0 } else { (n / 2) as f64 };
        let d = (n - 1) as f64;
        let inside = |p: f64| p >= 0.0 && p < n as f64;
        let (mut i, mut t, mut messages) = (0u64, 0u64, 0u64);
        // Principal axis and sign of +x, −x, +y, −y, +z, −z; the transverse axes in order.
        for (w, s) in [(0, 1.0), (0, -1.0), (1, 1.0), (1, -1.0), (2, 1.0), (2, -1.0)] {
            for u in -(n as i64 - 1)..n as i64 {
                for v in -(n as i64 - 1)..n as i64 {
                    let (mut k, mut last) = (0u64, None);
                    loop {
                        let kk = k as f64;
                        let at = ((c + u as f64 * kk / d + 0.5).floor(), (c + v as f64 * kk / d + 0.5).floor());
                        if !inside(c + s * kk) || !inside(at.0) || !inside(at.1) {
                            break;
                        }
                        if k > 0 && (w != 2 || last != Some(at)) {
                            messages += 1;
                        }
                        last = Some(at);
                        k += 1;
                    }
                    t = t.max(i + k);
                    i += 1;
                }
            }
        }
        (t, messages)
    }

    /// Against the f64 oracle, from the centre and from the origin; and the thesis's
    /// T = N_T + n up to how far the last ray travels (between 1 and n layers).
    #[test]
    fn ray_by_ray_matches_the_f64_oracle() {
        for n in [2u32, 5, 8, 16] {
            for origin in [false, true] {
                let got = ray_by_ray(n, origin, 0).unwrap();
                assert_eq!(got, oracle(n, origin), "n {n}, origin {origin}");
                let rays = 6 * (2 * n as u64 - 1).pow(2);
                assert!(got.0 >= rays && got.0 <= rays + n as u64, "n {n}: T {}, N_T {rays}", got.0);
            }
        }
    }
}
