//! §1.1, §1.2.5 — the refracted branch's direction: Snell's law as one cell computes it.
//!
//! The thesis's intensity model has a reflected and a refracted term (`I = I_local + Kr·I_R +
//! Kt·I_T`, §1.1) and its ray tree two children per node (§1.2.5). [`crate::reflect`] gives the
//! reflected child's direction; this module gives the transmitted one, for a surface between
//! media of refractive indices n₁ (the incident ray's side) and n₂, or says that there is none
//! (total internal reflection: the ray is only reflected, [`crate::reflect::mirror`]).
//!
//! **Invariant: for an integer incident direction I and an integer normal N (either
//! orientation), [`refract`] returns a positive multiple of Snell's transmitted direction T,
//! `T = p·|N|²·I − (p·a + s)·N` with `a = N·I ≤ 0` (N turned to face the ray), `η = n₁/n₂ =
//! p/q` and `s = ⌊√D⌋`, `D = q²·|I|²·|N|² − p²·(|I|²·|N|² − a²)`, or
//! [`Refraction::TotalInternal`] exactly when `D < 0`. Everything but the square root is exact
//! integer arithmetic: T lies in the plane of I and N exactly, the critical angle is decided
//! exactly for the integer inputs, and with η = 1 or at normal incidence T is parallel to I.**
//!
//! # Derivation
//!
//! With unit vectors Î = I/|I|, N̂ = N/|N| facing each other (N̂·Î = −c₁ ≤ 0), Snell's law
//! gives `T̂ = η·Î + (η·c₁ − c₂)·N̂`, `c₂ = √(1 − η²(1 − c₁²))`, a unit vector. Multiplying by
//! `q·|N|²·|I|` turns every term into an integer but c₂'s: `q·|I|·|N|·c₂ = √D`. So
//! `T = q·|N|²·|I|·T̂` up to the floor of the root, and D < 0 is the ray beyond the critical
//! angle (`sin θ₂ = η·sin θ₁ > 1`).
//!
//! # Error bound
//!
//! The root's floor is the only rounding: `0 ≤ √D − s < 1`, so the returned vector differs
//! from the exact `q·|N|²·|I|·T̂` by less than |N|, and its direction from T̂ by less than
//! `1 / (q·|N|·|I|)` radians (for n₂ = 1, glass's q = 256, a normal of length 255 and the
//! shortest lattice direction |I| ≥ 1: 1.5·10⁻⁵ rad; the normal's own 16-bit code and the
//! indices' 1/[`IOR_ONE`] steps are the inputs' errors, not this function's). The tests check
//! the bound against f64 Snell at random directions and at the bit budget's limits.
//!
//! # Bit budget
//!
//! |I_i| ≤ [`MAX_SPAN`] = 2²⁰ (|I|² < 2⁴²), |N_i| ≤ 2⁹ (|N|² < 2¹⁹; [`normal_int`] gives
//! |N|² ≤ 255²), indices coded in [1, [`MAX_IOR`]] = [1, 2¹⁰] 1/256 steps (p, q ≤ 2¹⁰):
//! `|I|²·|N|² < 2⁶¹`, `D < 2²⁰·2⁶¹ = 2⁸¹` (`i128`), `s < 2⁴¹`, `p·|N|²·|I_i| < 2⁴⁹`,
//! `(p·|a| + s)·|N_i| < (2⁴¹ + 2⁴¹)·2⁹ = 2⁵¹`: each component of T below 2⁵² (`i64`).
//!
//! # Example
//!
//! ```
//! use cell_core::refract::{ior_code, refract, Refraction};
//!
//! // Out of glass (n = 1.5) into air, against the floor's normal +z: the ray (4, 2, −5) meets
//! // the surface at exactly the critical angle (sin²θ = 20/45 = (1/1.5)²) and leaves grazing it.
//! let (glass, air) = (ior_code(1.5).unwrap(), ior_code(1.0).unwrap());
//! let Refraction::Through(t) = refract([4, 2, -5], [0, 0, 1], glass, air) else { panic!() };
//! assert_eq!(t[2], 0);
//! assert_eq!(t[0], 2 * t[1]);
//! // A little steeper still gets out; a little shallower is reflected.
//! assert!(matches!(refract([4, 2, -6], [0, 0, 1], glass, air), Refraction::Through(_)));
//! assert_eq!(refract([4, 2, -4], [0, 0, 1], glass, air), Refraction::TotalInternal);
//! // Into glass, the ray bends toward the normal: its slope falls by 1/1.5 in sine.
//! let Refraction::Through(t) = refract([1, 0, -1], [0, 0, 1], air, glass) else { panic!() };
//! assert!(t[2] < 0 && t[0] > 0 && t[0] < -t[2]);
//! ```
//!
//! [`MAX_SPAN`]: crate::ray::MAX_SPAN
//! [`normal_int`]: crate::reflect::normal_int

/// An index of refraction in 1/[`IOR_ONE`] steps: 256 is vacuum (1.0), 384 glass (1.5).
pub type IorCode = u16;

/// The code of index 1.0.
pub const IOR_ONE: IorCode = 256;

/// The largest index code the bit budget admits: 4.0 (diamond is 2.42).
pub const MAX_IOR: IorCode = 1024;

/// The largest normal component the bit budget admits (|N_i| ≤ 2⁹).
pub const MAX_NORMAL: i32 = 1 << 9;

/// The code of index `n` (rounded to the nearest 1/[`IOR_ONE`]), if it is finite and within
/// (0, 4].
pub fn ior_code(n: f32) -> Option<IorCode> {
    let c = n * IOR_ONE as f32 + 0.5;
    // `as` truncates toward zero, and `c` is positive: the floor of n·256 + ½.
    (n.is_finite() && n > 0.0 && c >= 1.0 && c < MAX_IOR as f32 + 1.0).then_some(c as IorCode)
}

/// What a surface does with a ray that reaches it from a medium of another index.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Refraction {
    /// It passes, along this direction (a positive multiple of Snell's, components below 2⁵²).
    Through([i64; 3]),
    /// Beyond the critical angle: no transmitted ray, only the reflected one.
    TotalInternal,
}

/// Snell's transmitted direction for incident direction `i` (lattice units, |i_k| ≤ 2²⁰, not
/// zero) at a surface of normal `n` (either orientation, |n_k| ≤ [`MAX_NORMAL`], not zero), from
/// a medium of index code `from` into one of index code `to` (both in 1 ..= [`MAX_IOR`]). See
/// the module doc for the formula, the exact parts and the error bound.
///
/// A zero `i` or `n`, or a code out of range, is outside the bit budget: the caller's bug, and
/// the result is unspecified (the tests' overflow checks would catch an overflow).
pub fn refract(i: [i32; 3], n: [i32; 3], from: IorCode, to: IorCode) -> Refraction {
    let (iv, mut nv) = (i.map(i128::from), n.map(i128::from));
    let dot = |u: [i128; 3], v: [i128; 3]| u[0] * v[0] + u[1] * v[1] + u[2] * v[2];
    let mut a = dot(nv, iv);
    if a > 0 {
        // The normal on the ray's side: a ≤ 0 from here on.
        nv = nv.map(|c| -c);
        a = -a;
    }
    let (ii, nn) = (dot(iv, iv), dot(nv, nv));
    let (p, q) = (i128::from(from), i128::from(to));
    let sin2 = ii * nn - a * a; // |I|²·|N|²·sin²θ₁ ≥ 0
    let d = q * q * ii * nn - p * p * sin2;
    if d < 0 {
        return Refraction::TotalInternal;
    }
    let s = isqrt(d as u128) as i128;
    let k = p * a + s;
    Refraction::Through([0, 1, 2].map(|c| (p * nn * iv[c] - k * nv[c]) as i64))
}

/// ⌊√d⌋, exact: the digit-by-digit method in base 4 (no floating point on the cell).
fn isqrt(d: u128) -> u128 {
    let (mut x, mut root) = (d, 0u128);
    let mut bit = 1u128 << 126;
    while bit > x {
        bit >>= 2;
    }
    while bit != 0 {
        if x >= root + bit {
            x -= root + bit;
            root = (root >> 1) + bit;
        } else {
            root >>= 1;
        }
        bit >>= 2;
    }
    root
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::normal::NormalCode;
    use crate::reflect::normal_int;
    use proptest::prelude::*;

    /// f64 Snell with unit vectors (the textbook formula), `None` beyond the critical angle.
    fn snell(i: [f64; 3], n: [f64; 3], eta: f64) -> Option<[f64; 3]> {
        let len = |v: [f64; 3]| (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
        let (li, ln) = (len(i), len(n));
        let i = i.map(|c| c / li);
        let mut n = n.map(|c| c / ln);
        let mut c1 = -(n[0] * i[0] + n[1] * i[1] + n[2] * i[2]);
        if c1 < 0.0 {
            n = n.map(|c| -c);
            c1 = -c1;
        }
        let k = 1.0 - eta * eta * (1.0 - c1 * c1);
        (k >= 0.0).then(|| [0, 1, 2].map(|j| eta * i[j] + (eta * c1 - k.sqrt()) * n[j]))
    }

    fn angle(u: [f64; 3], v: [f64; 3]) -> f64 {
        let len = |v: [f64; 3]| (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
        let c = [u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]];
        let d = u[0] * v[0] + u[1] * v[1] + u[2] * v[2];
        len(c).atan2(d)
    }

    fn f(v: [i64; 3]) -> [f64; 3] {
        v.map(|c| c as f64)
    }

    /// The root's floor at the squares and just below them, up to the budget's 2⁸¹ and past it.
    #[test]
    fn isqrt_is_the_floor_of_the_root() {
        for k in [0u128, 1, 2, 3, 255, 1 << 20, (1 << 40) + 12_345, (1 << 41) - 1, 1 << 60, u64::MAX as u128] {
            assert_eq!(isqrt(k * k), k);
            if k > 0 {
                assert_eq!(isqrt(k * k - 1), k - 1);
                assert_eq!(isqrt(k * k + 2 * k), k, "just below (k + 1)²");
            }
        }
        assert_eq!(isqrt(u128::MAX), u64::MAX as u128);
    }

    #[test]
    fn codes_of_indices() {
        assert_eq!(ior_code(1.0), Some(IOR_ONE));
        assert_eq!(ior_code(1.5), Some(384));
        assert_eq!(ior_code(4.0), Some(MAX_IOR));
        assert_eq!(ior_code(1.0 / 256.0), Some(1));
        for bad in [0.0, -1.5, 4.01, f32::NAN, f32::INFINITY, 0.001] {
            assert_eq!(ior_code(bad), None, "{bad}");
        }
    }

    /// Same index on both sides, or a ray along the normal: it goes straight on, exactly.
    #[test]
    fn equal_indices_and_normal_incidence_go_straight() {
        for (i, n) in [([3, -7, 11], [0, 0, 255]), ([1 << 20, -(1 << 20), 5], [100, -120, 35]), ([0, 0, -9], [1, 2, 3])]
        {
            for c in [1, 256, 384, MAX_IOR] {
                let Refraction::Through(t) = refract(i, n, c, c) else { panic!("{i:?} {n:?} {c}") };
                let l = t[0].abs().max(t[1].abs()).max(t[2].abs()) / i.iter().map(|v| v.abs() as i64).max().unwrap();
                assert!(l > 0 && t == i.map(|v| v as i64 * l), "{i:?} {n:?} {c}: {t:?}");
            }
        }
        for (from, to) in [(256, 384), (384, 256), (1, MAX_IOR), (MAX_IOR, 1)] {
            let Refraction::Through(t) = refract([0, 0, -40], [0, 0, 7], from, to) else { panic!() };
            assert!(t[0] == 0 && t[1] == 0 && t[2] < 0, "{t:?}");
        }
    }

    /// The critical angle decided exactly: sin²θ = 20/45 = (256/384)² out of glass grazes,
    /// one step either way passes or is reflected; and the same for water (1.33 → 340/256,
    /// sin²θ = (256/340)² = 4096/7225 = 0.5669…: the critical (60, 0, −52.44…) is not an
    /// integer direction, its neighbours (60, 0, −53) and (60, 0, −52) fall either side).
    #[test]
    fn the_critical_angle_is_exact() {
        let (glass, air) = (ior_code(1.5).unwrap(), IOR_ONE);
        for s in [1, 3, 1 << 16] {
            let Refraction::Through(t) = refract([4 * s, 2 * s, -5 * s], [0, 0, 1], glass, air) else { panic!() };
            assert_eq!((t[2], t[0], t[0] > 0), (0, 2 * t[1], true));
        }
        assert!(matches!(refract([4, 2, -6], [0, 0, 1], glass, air), Refraction::Through(_)));
        assert_eq!(refract([4, 2, -4], [0, 0, 5], glass, air), Refraction::TotalInternal);
        let water = 340;
        // sin²θ = 3600 / (3600 + z²) against 4096/7225 = 0.5669: z = 53 gives 0.5617 (passes),
        // z = 52 0.5711 (reflected); the critical z is 52.44.
        assert!(matches!(refract([60, 0, -53], [0, 0, 1], water, air), Refraction::Through(_)));
        assert!(matches!(refract([60, 0, -52], [0, 0, 1], water, air), Refraction::TotalInternal));
        // Into the denser medium there is no critical angle, even grazing.
        assert!(matches!(refract([1 << 20, 0, -1], [0, 0, 1], air, glass), Refraction::Through(_)));
    }

    /// At the bit budget's limits (overflow checks on in tests): the largest directions,
    /// normals and indices, every sign.
    #[test]
    fn the_bit_budget_holds_at_its_limits() {
        let m = 1 << 20;
        for i in [[m, m, m], [m, -m, 1], [-m, m, -m], [1, 0, -m]] {
            for n in [[MAX_NORMAL; 3], [MAX_NORMAL, -MAX_NORMAL, 1], [0, 0, -MAX_NORMAL]] {
                for (from, to) in [(MAX_IOR, MAX_IOR), (1, MAX_IOR), (MAX_IOR, 1), (256, 384)] {
                    if let Refraction::Through(t) = refract(i, n, from, to) {
                        assert!(t.iter().all(|c| c.abs() < 1 << 52), "{i:?} {n:?}: {t:?}");
                        assert!(t != [0; 3]);
                    }
                }
            }
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(4000))]

        /// Against f64 Snell, for indices between 0.25 and 4: the same decision, the
        /// direction within the module doc's bound, the plane of incidence kept exactly, and
        /// the ray on the far side of the surface. Rays within `cos²θ₂ < 10⁻³` of the critical
        /// angle are left to `the_critical_angle_is_exact`: there the f64 formula's own
        /// rounding (`√k` of a k near 0) exceeds the bound.
        #[test]
        fn agrees_with_f64_snell(
            i in prop::array::uniform3(-(1i32 << 20)..=(1 << 20)),
            code in any::<u16>(),
            from in 64u16..=MAX_IOR,
            to in 64u16..=MAX_IOR,
        ) {
            prop_assume!(i != [0; 3]);
            let n = normal_int(NormalCode(code));
            let eta = from as f64 / to as f64;
            let (fi, fnn) = (i.map(f64::from), n.map(f64::from));
            let li = fi.iter().map(|c| c * c).sum::<f64>().sqrt();
            let ln = fnn.iter().map(|c| c * c).sum::<f64>().sqrt();
            let c1 = (fi.iter().zip(&fnn).map(|(a, b)| a * b).sum::<f64>() / (li * ln)).abs();
            let k = 1.0 - eta * eta * (1.0 - c1 * c1);
            let r = refract(i, n, from, to);
            if k.abs() < 1e-3 {
                return Ok(());
            }
            match (r, snell(fi, fnn, eta)) {
                (Refraction::TotalInternal, None) => {}
                (Refraction::Through(t), Some(exact)) => {
                    let bound = 1.0 / (to as f64 * ln * li) + 1e-13;
                    let e = angle(f(t), exact);
                    prop_assert!(e <= bound, "{i:?} {n:?} {from}/{to}: {t:?} vs {exact:?}, {e} rad > {bound}");
                    // In the plane of incidence, exactly: T·(I × N) = 0.
                    let (iv, nv) = (i.map(i128::from), n.map(i128::from));
                    let x = [iv[1] * nv[2] - iv[2] * nv[1], iv[2] * nv[0] - iv[0] * nv[2], iv[0] * nv[1] - iv[1] * nv[0]];
                    let tv = t.map(i128::from);
                    prop_assert_eq!(tv[0] * x[0] + tv[1] * x[1] + tv[2] * x[2], 0);
                    // Through the surface: on the side of N opposite to where I came from
                    // (or along it, grazing).
                    let side = |v: [i128; 3]| v[0] * nv[0] + v[1] * nv[1] + v[2] * nv[2];
                    prop_assert!(side(tv).signum() * side(iv).signum() >= 0, "{t:?}");
                }
                (got, want) => prop_assert!(false, "{i:?} {n:?} {from}/{to}: {got:?} vs f64 {want:?}"),
            }
        }
    }
}
