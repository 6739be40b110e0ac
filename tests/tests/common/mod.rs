//! Helpers shared by the integration tests: mode mapping between the product and the oracles.
#![allow(dead_code)]

use host_sim::precompute::{Contour, Thickness};
use rc2_tests::oracle::brute;

pub const THICKNESSES: [Thickness; 3] = [Thickness::Naive, Thickness::Thesis, Thickness::Standard];
pub const CONTOURS: [Contour; 2] = [Contour::Projected, Contour::Conservative];

pub fn oracle_thickness(t: Thickness) -> brute::Thickness {
    match t {
        Thickness::Naive => brute::Thickness::Naive,
        Thickness::Thesis => brute::Thickness::Thesis,
        Thickness::Standard => brute::Thickness::Standard,
    }
}

pub fn oracle_contour(c: Contour) -> brute::Contour {
    match c {
        Contour::Projected => brute::Contour::Projected,
        Contour::Conservative => brute::Contour::Conservative,
    }
}
