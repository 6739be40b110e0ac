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

use crate::machine::timing::Emission;

/// The ray-by-ray mode's (cycles, inter-cell messages) on the empty n³ grid, source at the
/// centre (or at the origin, `origin`), initial beams in the default emission order.
pub fn ray_by_ray<F: FracBits>(n: u32, origin: bool) -> Result<(u64, u64)> {
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
    use cell_core::beam::frac::U0;

    /// The thesis's T = N_T + n, up to how far the last ray travels: N_T rays, each in the
    /// grid for at most n/2 + 1 layers from the centre.
    #[test]
    fn ray_by_ray_takes_n_t_plus_at_most_n() {
        for n in [2u32, 5, 8, 16] {
            let (t, messages) = ray_by_ray::<U0>(n, false).unwrap();
            let d = n as u64 - 1;
            let rays = 6 * (2 * d + 1) * (2 * d + 1);
            assert!(t > rays && t <= rays + n as u64, "n {n}: T {t}, N_T {rays}");
            // Every ray of ±x and ±y changes cell at each of its steps: at least one message
            // per ray that makes a step (n ≥ 2: all of those pointing inward at layer 1).
            assert!(messages >= 4 * (2 * d + 1), "n {n}: {messages} messages");
        }
    }
}
