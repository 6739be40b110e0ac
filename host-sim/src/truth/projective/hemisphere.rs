//! The hemisphere cut non-uniformly (radiosity thesis §2.4.1, "découpage non uniforme",
//! Fig. 2.11): R rings whose projections on the base disk have equal areas (outer radius
//! `R_i = √(i/R)`, so each ring is an equal share of the form factor by Nusselt's analogue),
//! each cut into 4R equal sectors of longitude; R × 4R proxels, each carrying the same FFE
//! `1 / 4R²` (the thesis's `π/N` in units where the disk's area π is the whole).
//!
//! One FFE stored (§2.5.3: `Q_hsnu = 32 R²`). Samples: each proxel's direction at its ring's
//! equal-area middle radius `√((i + ½)/R)` and its sector's middle longitude.

use std::f64::consts::PI;

use anyhow::Result;

use super::{check_resolution, ProjectionSurface, Resolution};

/// The non-uniformly cut hemisphere at resolution R.
#[derive(Clone, Debug)]
pub struct Hemisphere {
    r: u32,
    /// The one FFE.
    delta: f64,
}

impl Hemisphere {
    /// The hemisphere with `r` equal-area rings and `4r` sectors.
    pub fn new(r: u32) -> Result<Hemisphere> {
        check_resolution("hemisphere", r, false)?;
        Ok(Hemisphere { r, delta: 1.0 / (4.0 * (r as f64).powi(2)) })
    }

    /// A bound on any proxel's angular radius about its sample direction: the widest rings
    /// (the first and the last, `asin √(1/R)` wide in φ) by `π / 2R` in θ, their whole diagonal
    /// (the equal-area middle is not the angular middle).
    pub fn widest(&self) -> f64 {
        let r = self.r as f64;
        let dphi = (1.0 / r).sqrt().asin();
        let dtheta = PI / (2.0 * r);
        dphi.hypot(dtheta)
    }
}

impl ProjectionSurface for Hemisphere {
    fn name(&self) -> &'static str {
        "hemisphere"
    }
    fn resolution(&self) -> Resolution {
        Resolution::Single(self.r)
    }
    /// R × 4R (Table 2.2).
    fn proxels(&self) -> u64 {
        4 * (self.r as u64).pow(2)
    }
    /// Every proxel's: `1 / 4R²`.
    fn largest_delta_ff(&self) -> f64 {
        self.delta
    }
    /// §2.5.3: 8 bytes a proxel, the one FFE negligible: `Q_hsnu = 32 R²`.
    fn memory_bytes(&self) -> u64 {
        32 * (self.r as u64).pow(2)
    }
    fn samples(&self) -> usize {
        4 * (self.r as usize).pow(2)
    }
    fn direction(&self, k: usize) -> [f64; 3] {
        let m = 4 * self.r as usize;
        let (ring, s) = (k / m, k % m);
        let rho = ((ring as f64 + 0.5) / self.r as f64).sqrt();
        let theta = (s as f64 + 0.5) * 2.0 * PI / m as f64;
        [rho * theta.cos(), rho * theta.sin(), (1.0 - rho * rho).sqrt()]
    }
    fn delta(&self, _k: usize) -> f64 {
        self.delta
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::truth::projective::testkit;

    #[test]
    fn deltas_sum_to_one() {
        testkit::deltas_sum_to(&Hemisphere::new(25).unwrap(), 1.0);
    }

    #[test]
    fn enclosure_parallel_perpendicular_occlusion() {
        let make: testkit::Make = |r| {
            let h = Hemisphere::new(r).unwrap();
            let d = h.widest();
            (Box::new(h), d)
        };
        testkit::all_checks(make, 16, 64, 1.0);
    }

    #[test]
    fn zero_resolution_is_refused() {
        assert!(Hemisphere::new(0).is_err());
    }
}
