//! Error of the shading math against libm, in 8-bit output levels.
//!
//! `cargo run --release -p cell-core --example micromath_error`
//!
//! Compares, on one million random shading inputs (normals facing the viewer, 1–3 lights,
//! random materials with Ns up to 200), three implementations of the same Phong/Blinn formula:
//! exact f64 (libm), raw `micromath` (invsqrt, powf for the specular and the gamma), and the
//! cell's (`cell_core::shade::shade`: micromath invsqrt + Newton, integer power, gamma table).
#![allow(clippy::needless_range_loop, clippy::type_complexity)]

use cell_core::shade::{shade, Material, NormalMode, PointLight, ShadeParams};
use micromath::F32Ext;

struct Rng(u64);
impl Rng {
    fn next(&mut self) -> f32 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        (self.0 >> 40) as f32 / (1u64 << 24) as f32
    }
}

fn dot<T: Copy + std::ops::Mul<Output = T> + std::ops::Add<Output = T>>(a: [T; 3], b: [T; 3]) -> T {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// The formula in f64 with libm, or in f32 with raw micromath.
fn reference(p: [f32; 3], n: [f32; 3], m: &Material, lights: &[PointLight], raw_micromath: bool) -> [u8; 3] {
    let mut c = [0.0f64; 3];
    for i in 0..3 {
        c[i] = (m.ka[i] * 0.2) as f64;
    }
    for l in lights {
        let d = [l.pos[0] - p[0], l.pos[1] - p[1], l.pos[2] - p[2]];
        let (ld, h, spec_of): ([f64; 3], [f64; 3], Box<dyn Fn(f64) -> f64>) = if raw_micromath {
            let r = dot(d, d).invsqrt();
            let ld = d.map(|v| v * r);
            let hv = [ld[0], ld[1], ld[2] - 1.0];
            let rh = dot(hv, hv).invsqrt();
            let ns = m.ns;
            (ld.map(|v| v as f64), hv.map(|v| (v * rh) as f64), Box::new(move |x: f64| (x as f32).powf(ns) as f64))
        } else {
            let d = d.map(|v| v as f64);
            let l2 = dot(d, d).sqrt();
            let ld = d.map(|v| v / l2);
            let hv = [ld[0], ld[1], ld[2] - 1.0];
            let lh = dot(hv, hv).sqrt();
            let ns = m.ns.round() as f64;
            (ld, hv.map(|v| v / lh), Box::new(move |x: f64| x.powf(ns)))
        };
        let nn = n.map(|v| v as f64);
        let ndl = dot(nn, ld);
        if ndl <= 0.0 {
            continue;
        }
        let nh = dot(nn, h).max(0.0);
        let spec = if nh > 0.0 { spec_of(nh) } else { 0.0 };
        for i in 0..3 {
            c[i] += (l.color[i] as f64) * ((m.kd[i] as f64) * ndl + (m.ks[i] as f64) * spec);
        }
    }
    c.map(|v| {
        let v = v.clamp(0.0, 1.0);
        let g = if raw_micromath { (v as f32).powf(1.0 / 2.2) as f64 } else { v.powf(1.0 / 2.2) };
        (g * 255.0 + 0.5).min(255.0) as u8
    })
}

fn main() {
    let mut rng = Rng(0x9e37_79b9_7f4a_7c15);
    let params = ShadeParams { ambient: [0.2; 3], normal_mode: NormalMode::Facet, eye: cell_core::shade::Eye::Grid };
    let (mut raw_max, mut raw_sum, mut cell_max, mut cell_sum, mut count) = (0u8, 0u64, 0u8, 0u64, 0u64);
    let trials = 1_000_000;
    for _ in 0..trials {
        let mut n = [rng.next() * 2.0 - 1.0, rng.next() * 2.0 - 1.0, -rng.next()];
        let l = dot(n, n).sqrt().max(1e-3);
        n = n.map(|v| v / l);
        let m = Material {
            ka: [rng.next() * 0.3; 3],
            kd: [rng.next(), rng.next(), rng.next()],
            ks: [rng.next() * 0.5; 3],
            ns: 1.0 + (rng.next() * 200.0).round(),
            ke: [0.0; 3],
        };
        let lights: Vec<PointLight> = (0..1 + (rng.next() * 3.0) as usize)
            .map(|_| PointLight {
                pos: [rng.next() * 160.0 - 16.0, rng.next() * 160.0 - 16.0, rng.next() * 160.0 - 80.0],
                color: [1.0 / 1.7; 3],
            })
            .collect();
        let p = [rng.next() * 128.0, rng.next() * 128.0, rng.next() * 128.0];
        let exact = reference(p, n, &m, &lights, false);
        let raw = reference(p, n, &m, &lights, true);
        let cell = shade(p, n, &m, &lights, (1 << lights.len()) - 1, &params);
        for k in 0..3 {
            let (r, c) = (raw[k].abs_diff(exact[k]), cell[k].abs_diff(exact[k]));
            raw_max = raw_max.max(r);
            cell_max = cell_max.max(c);
            raw_sum += r as u64;
            cell_sum += c as u64;
            count += 1;
        }
    }
    println!("shading error against libm over {trials} random inputs (8-bit levels, gamma 2.2 output):");
    println!("| implementation | max | mean |");
    println!("|---|---|---|");
    println!(
        "| raw micromath (invsqrt, powf specular, powf gamma) | {raw_max} | {:.3} |",
        raw_sum as f64 / count as f64
    );
    println!(
        "| cell (invsqrt + 3 Newton steps, integer power, gamma table) | {cell_max} | {:.4} |",
        cell_sum as f64 / count as f64
    );
}
