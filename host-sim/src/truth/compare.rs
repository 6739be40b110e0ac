//! The machine's image against the reference: shadow and coverage disagreement, PSNR (one
//! formula for every caller), and the difference image.

use super::refrender::RefImage;

/// Comparison of a discrete image with the reference.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct Comparison {
    /// (pixel, light) pairs, over pixels covered in both images, whose lit state differs: % of
    /// those pairs (0 if none). Lit = the surface faces the light and sees it.
    pub shadow_disagreement_pct: f64,
    /// Pixels covered in exactly one image, % of the pixels covered in either (0 if none).
    pub coverage_disagreement_pct: f64,
    /// PSNR over all n² pixels and the 3 channels, MAX = 255; `f64::INFINITY` if identical.
    pub psnr_db: f64,
    /// Largest per-channel absolute difference over all pixels.
    pub max_abs_diff: u8,
}

fn check_len(what: &str, len: usize, npix: usize) {
    assert_eq!(len, npix, "refrender: {what} has {len} pixels, the reference has {npix}");
}

/// Compare a discrete image (same layout as [`RefImage`]) with the reference.
///
/// Panics if a slice's length is not `reference.n²`.
pub fn compare(rgb: &[[u8; 3]], covered: &[bool], lit: &[u32], reference: &RefImage) -> Comparison {
    let npix = reference.n as usize * reference.n as usize;
    check_len("rgb", rgb.len(), npix);
    check_len("covered", covered.len(), npix);
    check_len("lit", lit.len(), npix);
    let (mut both, mut shadow_diff, mut either, mut one) = (0u64, 0u64, 0u64, 0u64);
    let mut sq = 0u64;
    let mut max_abs = 0u8;
    for i in 0..npix {
        let (a, b) = (covered[i], reference.covered[i]);
        if a && b {
            both += 1;
            shadow_diff += u64::from((lit[i] ^ reference.lit[i]).count_ones());
        }
        if a || b {
            either += 1;
        }
        if a != b {
            one += 1;
        }
        for (&a, &b) in rgb[i].iter().zip(&reference.rgb[i]) {
            let d = a.abs_diff(b);
            max_abs = max_abs.max(d);
            sq += u64::from(d) * u64::from(d);
        }
    }
    let pct = |num: u64, den: u64| {
        if den == 0 {
            0.0
        } else {
            100.0 * num as f64 / den as f64
        }
    };
    let psnr_db = psnr_of(sq, 3 * npix as u64);
    Comparison {
        shadow_disagreement_pct: pct(shadow_diff, both * u64::from(reference.lights.max(1))),
        coverage_disagreement_pct: pct(one, either),
        psnr_db,
        max_abs_diff: max_abs,
    }
}

/// Difference image (same layout): per pixel `min(255, 4·|a − b|)` per channel; pixels covered
/// in exactly one of the two images are magenta `(255, 0, 255)`.
///
/// Panics if a slice's length is not `reference.n²`.
pub fn difference_image(rgb: &[[u8; 3]], covered: &[bool], reference: &RefImage) -> Vec<[u8; 3]> {
    let npix = reference.n as usize * reference.n as usize;
    check_len("rgb", rgb.len(), npix);
    check_len("covered", covered.len(), npix);
    (0..npix)
        .map(|i| {
            if covered[i] != reference.covered[i] {
                [255, 0, 255]
            } else {
                [0, 1, 2].map(|c| (u32::from(rgb[i][c].abs_diff(reference.rgb[i][c])) * 4).min(255) as u8)
            }
        })
        .collect()
}

/// PSNR (dB, MAX 255, 3 channels) of `a` against `b` over the pixels where `keep` is set.
pub fn psnr(a: &[[u8; 3]], b: &[[u8; 3]], keep: &[bool]) -> f64 {
    let (mut sq, mut cnt) = (0u64, 0u64);
    for ((pa, pb), _) in a.iter().zip(b).zip(keep).filter(|(_, &k)| k) {
        for c in 0..3 {
            let d = pa[c].abs_diff(pb[c]) as u64;
            sq += d * d;
            cnt += 1;
        }
    }
    psnr_of(sq, cnt)
}

/// The one PSNR formula: `sq` summed squared 8-bit differences over `samples` channel values.
fn psnr_of(sq: u64, samples: u64) -> f64 {
    if sq == 0 {
        f64::INFINITY
    } else {
        10.0 * (255.0f64 * 255.0 / (sq as f64 / samples as f64)).log10()
    }
}
