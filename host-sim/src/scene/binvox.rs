//! The `.binvox` format (Patrick Min's binvox; read by binvox-rw-py, trimesh, Open3D …).
//!
//! ```text
//! #binvox 1
//! dim D D D
//! translate tx ty tz
//! scale s
//! data
//! <run-length pairs: value byte (0/1), count byte (1..=255)>
//! ```
//!
//! Voxel order: x slowest, then z, then y fastest (index = x·D² + z·D + y). Voxel (i, j, k)
//! occupies the world cube `translate + [i, i+1) · scale / D` per axis, so its centre is
//! `translate + (i + ½)·scale/D` — with `translate` = the grid's low corner and
//! `scale = D · voxel size`, rc2's voxel indices map back to the mesh's own coordinates.

use anyhow::{bail, Context, Result};
use std::io::{BufRead, Read, Write};

/// A dense occupancy bitset in binvox order.
#[derive(Clone, Debug, PartialEq)]
pub struct Voxels {
    /// Side.
    pub dim: u32,
    /// World position of the grid's low corner.
    pub translate: [f64; 3],
    /// World side of the whole grid.
    pub scale: f64,
    bits: Vec<u64>,
}

impl Voxels {
    /// All-empty grid.
    pub fn new(dim: u32, translate: [f64; 3], scale: f64) -> Self {
        let len = (dim as usize).pow(3).div_ceil(64);
        Voxels { dim, translate, scale, bits: vec![0; len] }
    }

    fn index(&self, x: u32, y: u32, z: u32) -> usize {
        let d = self.dim as usize;
        (x as usize * d + z as usize) * d + y as usize
    }

    /// Mark a voxel.
    pub fn set(&mut self, x: u32, y: u32, z: u32) {
        let i = self.index(x, y, z);
        self.bits[i / 64] |= 1 << (i % 64);
    }

    /// Whether a voxel is occupied.
    pub fn get(&self, x: u32, y: u32, z: u32) -> bool {
        let i = self.index(x, y, z);
        self.bits[i / 64] >> (i % 64) & 1 == 1
    }

    /// Number of occupied voxels.
    pub fn count(&self) -> u64 {
        self.bits.iter().map(|w| w.count_ones() as u64).sum()
    }

    /// Write in binvox format.
    pub fn write(&self, mut w: impl Write) -> Result<()> {
        let d = self.dim;
        let t = self.translate;
        write!(w, "#binvox 1\ndim {d} {d} {d}\ntranslate {} {} {}\nscale {}\ndata\n", t[0], t[1], t[2], self.scale)?;
        let total = (d as usize).pow(3);
        let mut out = Vec::with_capacity(1 << 16);
        let (mut value, mut run) = (self.bits.first().map_or(0, |w| (w & 1) as u8), 0usize);
        let flush = |value: u8, mut run: usize, out: &mut Vec<u8>| {
            while run > 0 {
                let c = run.min(255);
                out.extend_from_slice(&[value, c as u8]);
                run -= c;
            }
        };
        let mut i = 0usize;
        while i < total {
            let word = self.bits[i / 64];
            // Fast path: a whole word equal to the current run's value.
            if i % 64 == 0 && i + 64 <= total && (word == 0 && value == 0 || word == u64::MAX && value == 1) {
                run += 64;
                i += 64;
                continue;
            }
            let bit = (word >> (i % 64) & 1) as u8;
            if bit == value {
                run += 1;
            } else {
                flush(value, run, &mut out);
                value = bit;
                run = 1;
            }
            i += 1;
            if out.len() >= 1 << 16 {
                w.write_all(&out)?;
                out.clear();
            }
        }
        flush(value, run, &mut out);
        w.write_all(&out)?;
        Ok(())
    }

    /// Read a binvox file (cubic grids only).
    pub fn read(r: impl Read) -> Result<Voxels> {
        let mut r = std::io::BufReader::new(r);
        let mut line = String::new();
        r.read_line(&mut line)?;
        if !line.starts_with("#binvox") {
            bail!("not a binvox file");
        }
        let (mut dim, mut translate, mut scale) = (None, [0.0; 3], 1.0);
        loop {
            line.clear();
            if r.read_line(&mut line)? == 0 {
                bail!("binvox: missing data section");
            }
            let mut it = line.split_whitespace();
            match it.next() {
                Some("dim") => {
                    let v: Vec<u32> = it.map(|s| s.parse()).collect::<Result<_, _>>().context("binvox: bad dim")?;
                    if v.len() != 3 || v[0] != v[1] || v[1] != v[2] || v[0] == 0 || v[0] > 4096 {
                        bail!("binvox: unsupported dim {v:?}");
                    }
                    dim = Some(v[0]);
                }
                Some("translate") => {
                    let v: Vec<f64> =
                        it.map(|s| s.parse()).collect::<Result<_, _>>().context("binvox: bad translate")?;
                    translate = v.try_into().map_err(|_| anyhow::anyhow!("binvox: bad translate"))?;
                }
                Some("scale") => scale = it.next().context("binvox: bad scale")?.parse()?,
                Some("data") => break,
                _ => {}
            }
        }
        let dim = dim.context("binvox: no dim")?;
        let mut v = Voxels::new(dim, translate, scale);
        let mut data = Vec::new();
        r.read_to_end(&mut data)?;
        let total = (dim as usize).pow(3);
        let mut i = 0usize;
        for pair in data.chunks_exact(2) {
            let (val, cnt) = (pair[0], pair[1] as usize);
            if i + cnt > total {
                bail!("binvox: data longer than dim³");
            }
            if val != 0 {
                for k in i..i + cnt {
                    v.bits[k / 64] |= 1 << (k % 64);
                }
            }
            i += cnt;
        }
        if i != total {
            bail!("binvox: data covers {i} voxels, expected {total}");
        }
        Ok(v)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trip_and_layout() {
        let mut v = Voxels::new(5, [1.0, 2.0, 3.0], 10.0);
        let pts = [(0, 0, 0), (4, 4, 4), (1, 2, 3), (3, 0, 4)];
        for &(x, y, z) in &pts {
            v.set(x, y, z);
        }
        let mut buf = Vec::new();
        v.write(&mut buf).unwrap();
        let r = Voxels::read(&buf[..]).unwrap();
        assert_eq!(r, v);
        // binvox order: y fastest. Voxel (0, 1, 0) is the 2nd, (0, 0, 1) the 6th.
        let mut w = Voxels::new(5, [0.0; 3], 1.0);
        w.set(0, 0, 1);
        let mut buf = Vec::new();
        w.write(&mut buf).unwrap();
        let data = &buf[buf.windows(5).position(|s| s == b"data\n").unwrap() + 5..];
        assert_eq!(&data[..4], &[0, 5, 1, 1]);
    }

    #[test]
    fn long_runs_split_at_255() {
        let v = Voxels::new(10, [0.0; 3], 1.0);
        let mut buf = Vec::new();
        v.write(&mut buf).unwrap();
        let data = &buf[buf.windows(5).position(|s| s == b"data\n").unwrap() + 5..];
        assert_eq!(data.len(), 2 * 4); // 1000 = 3·255 + 235
        assert_eq!(Voxels::read(&buf[..]).unwrap().count(), 0);
    }
}
