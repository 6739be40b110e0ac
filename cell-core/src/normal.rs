//! 16-bit octahedral normal code: what a dexel stores for shading (§5.2.1).
//!
//! A unit vector is projected onto the octahedron |x| + |y| + |z| = 1, the lower half folded
//! over the upper one, and the two remaining coordinates quantised to 8 bits each. Encoding
//! needs no square root; decoding gives an unnormalised vector. The angular error of the code
//! is below 1° (measured in the tests: the largest error over a dense sphere sampling).

/// A facet normal quantised to 16 bits (8 bits per octahedral coordinate).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct NormalCode(pub u16);

fn quantise(v: f32) -> u16 {
    // v in [-1, 1] -> 0 ..= 255, rounded to nearest.
    let s = (v.clamp(-1.0, 1.0) + 1.0) * 127.5 + 0.5;
    (s as u16).min(255)
}

fn dequantise(c: u16) -> f32 {
    c as f32 / 127.5 - 1.0
}

fn sign_not_zero(v: f32) -> f32 {
    if v < 0.0 {
        -1.0
    } else {
        1.0
    }
}

impl NormalCode {
    /// Encode a (not necessarily unit) non-zero vector. A zero or non-finite vector encodes +z.
    pub fn encode(n: [f32; 3]) -> NormalCode {
        let l1 = n[0].abs() + n[1].abs() + n[2].abs();
        if !(l1 > 0.0 && l1.is_finite()) {
            return NormalCode::encode([0.0, 0.0, 1.0]);
        }
        let (mut x, mut y, z) = (n[0] / l1, n[1] / l1, n[2] / l1);
        if z < 0.0 {
            let (ox, oy) = (x, y);
            x = (1.0 - oy.abs()) * sign_not_zero(ox);
            y = (1.0 - ox.abs()) * sign_not_zero(oy);
        }
        NormalCode(quantise(x) << 8 | quantise(y))
    }

    /// Decode to an unnormalised vector pointing the same way as the encoded normal.
    pub fn decode(self) -> [f32; 3] {
        let mut x = dequantise(self.0 >> 8);
        let mut y = dequantise(self.0 & 0xff);
        let z = 1.0 - x.abs() - y.abs();
        if z < 0.0 {
            let (ox, oy) = (x, y);
            x = (1.0 - oy.abs()) * sign_not_zero(ox);
            y = (1.0 - ox.abs()) * sign_not_zero(oy);
        }
        [x, y, z]
    }
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;

    fn angle_deg(a: [f32; 3], b: [f32; 3]) -> f64 {
        let dot = (a[0] * b[0] + a[1] * b[1] + a[2] * b[2]) as f64;
        let la = ((a[0] * a[0] + a[1] * a[1] + a[2] * a[2]) as f64).sqrt();
        let lb = ((b[0] * b[0] + b[1] * b[1] + b[2] * b[2]) as f64).sqrt();
        (dot / (la * lb)).clamp(-1.0, 1.0).acos().to_degrees()
    }

    #[test]
    fn angular_error_below_one_degree_over_the_sphere() {
        // Fibonacci sphere sampling, 20 000 directions, both hemispheres and the axes.
        let mut worst: f64 = 0.0;
        let m = 20_000;
        for i in 0..m {
            let z = 1.0 - 2.0 * (i as f64 + 0.5) / m as f64;
            let r = (1.0 - z * z).sqrt();
            let phi = i as f64 * 2.399_963_229_728_653;
            let v = [(r * phi.cos()) as f32, (r * phi.sin()) as f32, z as f32];
            worst = worst.max(angle_deg(v, NormalCode::encode(v).decode()));
        }
        for v in [[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0], [0.0, 0.0, 1.0]] {
            worst = worst.max(angle_deg(v, NormalCode::encode(v).decode()));
        }
        assert!(worst < 1.0, "worst angular error {worst}°");
    }

    #[test]
    fn degenerate_input_encodes_plus_z() {
        assert_eq!(NormalCode::encode([0.0; 3]), NormalCode::encode([0.0, 0.0, 1.0]));
        assert_eq!(NormalCode::encode([f32::NAN, 0.0, 1.0]), NormalCode::encode([0.0, 0.0, 1.0]));
    }
}
