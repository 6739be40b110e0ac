//! Spencer's hemisphere cut uniformly (radiosity thesis §2.4.1, Fig. 2.9–2.10): the unit
//! hemisphere cut at constant steps of latitude φ (R bands from the pole, φ the angle from the
//! normal) and longitude θ (4R sectors, the same angular step `π / 2R`); R × 4R proxels.
//!
//! FFE of a proxel of band `[φ1, φ2]`: exactly `(sin² φ2 − sin² φ1) / 4R` (the thesis writes
//! `(2/M) sin((φ1 + φ2)/2)(sin φ2 − sin φ1)` with M = 4R the number of sectors, which drops a
//! factor `cos((φ2 − φ1)/2)`), equal along a band, largest at φ = π/4 (§2.5.2). One FFE stored
//! per band. Samples: the centre direction of each proxel (φ and θ at mid-step), band-major.

use std::f64::consts::FRAC_PI_2;

use anyhow::Result;

use super::{check_resolution, ProjectionSurface, Resolution};

/// Spencer's uniformly cut hemisphere at resolution R.
#[derive(Clone, Debug)]
pub struct UniformHemisphere {
    r: u32,
    /// One FFE per band.
    band: Vec<f64>,
}

impl UniformHemisphere {
    /// The hemisphere with `r` bands of latitude and `4r` sectors.
    pub fn new(r: u32) -> Result<UniformHemisphere> {
        check_resolution("hemisphere-uniform", r, false)?;
        let step = FRAC_PI_2 / r as f64;
        let band = (0..r)
            .map(|b| {
                let (s1, s2) = ((b as f64 * step).sin(), ((b + 1) as f64 * step).sin());
                (s2 * s2 - s1 * s1) / (4 * r) as f64
            })
            .collect();
        Ok(UniformHemisphere { r, band })
    }

    /// The angular step `π / 2R` (both φ and θ).
    pub fn step(&self) -> f64 {
        FRAC_PI_2 / self.r as f64
    }
}

impl ProjectionSurface for UniformHemisphere {
    fn name(&self) -> &'static str {
        "hemisphere-uniform"
    }
    fn resolution(&self) -> Resolution {
        Resolution::Single(self.r)
    }
    /// R × 4R (Table 2.2).
    fn proxels(&self) -> u64 {
        4 * (self.r as u64).pow(2)
    }
    /// The band nearest φ = π/4.
    fn largest_delta_ff(&self) -> f64 {
        self.band.iter().copied().fold(0.0, f64::max)
    }
    /// §2.5.3: 8 bytes a proxel and one 4-byte FFE per band: `Q_hsu = 32 R² + 4 R`.
    fn memory_bytes(&self) -> u64 {
        32 * (self.r as u64).pow(2) + 4 * self.r as u64
    }
    fn samples(&self) -> usize {
        4 * (self.r as usize).pow(2)
    }
    fn direction(&self, k: usize) -> [f64; 3] {
        let m = 4 * self.r as usize;
        let (b, s) = (k / m, k % m);
        let phi = (b as f64 + 0.5) * self.step();
        let theta = (s as f64 + 0.5) * self.step();
        [phi.sin() * theta.cos(), phi.sin() * theta.sin(), phi.cos()]
    }
    fn delta(&self, k: usize) -> f64 {
        self.band[k / (4 * self.r as usize)]
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::truth::projective::testkit;

    #[test]
    fn deltas_sum_to_one_and_peak_at_45_degrees() {
        let h = UniformHemisphere::new(30).unwrap();
        testkit::deltas_sum_to(&h, 1.0);
        let peak = h.band.iter().enumerate().fold((0, 0.0), |a, (i, &f)| if f > a.1 { (i, f) } else { a }).0;
        let mid = (peak as f64 + 0.5) * h.step();
        assert!((mid - std::f64::consts::FRAC_PI_4).abs() <= h.step());
    }

    #[test]
    fn enclosure_parallel_perpendicular_occlusion() {
        // δ: half the diagonal of a (Δφ × Δθ sin φ ≤ Δφ) cell, as an angle.
        let make: testkit::Make = |r| {
            let h = UniformHemisphere::new(r).unwrap();
            let d = h.step() * std::f64::consts::SQRT_2 / 2.0;
            (Box::new(h), d)
        };
        testkit::all_checks(make, 16, 64, 1.0);
    }

    #[test]
    fn zero_resolution_is_refused() {
        assert!(UniformHemisphere::new(0).is_err());
    }
}
