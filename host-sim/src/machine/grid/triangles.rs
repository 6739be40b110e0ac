//! The triangles each column keeps for exact occluders (thesis §5.5.6; `cell_core::occluder`),
//! loaded with the facets.
//!
//! A cell keeps the lattice triangles of the facets whose projection meets its column's square
//! (`Triangle::crosses_column`), at most [`TRIANGLE_CAP`] in stream order; the triangles a full
//! column leaves out are counted ([`ColumnTriangles::overflows`]). The host holds every
//! column's store in one array (CSR: a column's triangles are a slice), not n² fixed stores:
//! a firmware cell's `TriangleStore<64>` is 2.3 KB, the host's columns keep 1–11 triangles on
//! average.

use anyhow::{bail, Result};
use cell_core::occluder::{near_windows, NearWindows, Triangle};
use cell_core::units::Depth;

use crate::machine::grid::capacity::TRIANGLE_CAP;
use crate::machine::grid::pieces::{par_map, prefetch};

/// Every column's triangles (empty when the scene was loaded without them).
#[derive(Clone, Debug, Default)]
pub struct ColumnTriangles {
    n: u32,
    /// Column `i = y·n + x` holds `tris[start[i] .. start[i + 1]]` (empty `start`: none).
    start: Vec<u32>,
    tris: Vec<Triangle>,
    /// Beside each kept triangle, its index in `distinct` (the scene's triangles, each once).
    ids: Vec<u32>,
    distinct: Vec<Triangle>,
    /// Beside each kept triangle, its depth window ([`NearWindows`]).
    near: Vec<NearWindows>,
    overflows: u64,
}

impl ColumnTriangles {
    /// The stores of an n × n grid loaded from `polygons` (planar convex polygons on the
    /// loading lattice, `X = 16·x + 8` sixteenths, as `precompute::prepare` makes them), each
    /// cut into a fan of triangles.
    pub fn from_polygons(polygons: &[Vec<[i64; 3]>], n: u32) -> Result<Self> {
        Self::from_polygons_keeping(polygons, n, TRIANGLE_CAP)
    }

    /// [`ColumnTriangles::from_polygons`] with columns of `cap` triangles instead of the cell's
    /// [`TRIANGLE_CAP`]: what exact occluders do with stores that never fill (an experiment:
    /// `usize::MAX` keeps every triangle).
    pub fn from_polygons_keeping(polygons: &[Vec<[i64; 3]>], n: u32, cap: usize) -> Result<Self> {
        let mut tris = Vec::new();
        for poly in polygons {
            // Voxel centres at multiples of 16.
            let v: Vec<[i32; 3]> = poly.iter().map(|p| p.map(|c| (c - 8) as i32)).collect();
            for k in 1..v.len().saturating_sub(1) {
                let Some(t) = Triangle::new([v[0], v[k], v[k + 1]]) else {
                    bail!("a facet of the loaded scene lies outside the exact occluders' coordinate range");
                };
                tris.push(t);
            }
        }
        let cols = n as usize * n as usize;
        let mut per: Vec<Vec<(Triangle, u32)>> = vec![Vec::new(); cols];
        let mut overflows = 0u64;
        for (id, t) in tris.iter().enumerate() {
            let range = |c: usize| {
                let (lo, hi) = t
                    .vertices()
                    .iter()
                    .fold((i64::MAX, i64::MIN), |(lo, hi), v| (lo.min(v[c] as i64), hi.max(v[c] as i64)));
                ((lo - 8).div_euclid(16).max(0), (hi + 8 + 15).div_euclid(16).min(n as i64 - 1))
            };
            let ((x0, x1), (y0, y1)) = (range(0), range(1));
            for y in y0..=y1 {
                for x in x0..=x1 {
                    if t.crosses_column(x as i32, y as i32) {
                        let col = &mut per[(y * n as i64 + x) as usize];
                        if col.len() < cap {
                            col.push((*t, id as u32));
                        } else {
                            overflows += 1;
                        }
                    }
                }
            }
        }
        let mut start = Vec::with_capacity(cols + 1);
        let (mut flat, mut ids) = (Vec::new(), Vec::new());
        start.push(0);
        for col in per {
            for (t, id) in col {
                flat.push(t);
                ids.push(id);
            }
            start.push(flat.len() as u32);
        }
        let near = all_near_windows(&start, &flat, n);
        Ok(ColumnTriangles { n, start, tris: flat, ids, distinct: tris, near, overflows })
    }

    /// Column (x, y)'s triangles, their indices in [`ColumnTriangles::distinct`] and their
    /// near windows, from one lookup.
    pub fn column_parts(&self, x: u32, y: u32) -> (&[Triangle], &[u32], &[NearWindows]) {
        let i = (y * self.n + x) as usize;
        if x < self.n {
            if let Some(&[a, b]) = self.start.get(i..i + 2) {
                let r = a as usize..b as usize;
                if let (Some(t), Some(ids), Some(near)) =
                    (self.tris.get(r.clone()), self.ids.get(r.clone()), self.near.get(r))
                {
                    return (t, ids, near);
                }
            }
        }
        (&[], &[], &[])
    }

    /// Start loading what [`ColumnTriangles::column_parts`] reads of column (x, y) first.
    pub fn prefetch(&self, x: u32, y: u32) {
        let i = (y * self.n + x) as usize;
        if let Some(&a) = self.start.get(i) {
            prefetch(self.near.as_ptr().wrapping_add(a as usize));
        }
    }

    /// The range of column (x, y) in the flat arrays (empty outside the grid or unloaded).
    fn range(&self, x: u32, y: u32) -> std::ops::Range<usize> {
        if self.start.is_empty() || x >= self.n || y >= self.n {
            return 0..0;
        }
        let i = (y * self.n + x) as usize;
        self.start[i] as usize..self.start[i + 1] as usize
    }

    /// Beside each of column (x, y)'s triangles, its index in [`ColumnTriangles::distinct`].
    pub fn ids(&self, x: u32, y: u32) -> &[u32] {
        &self.ids[self.range(x, y)]
    }

    /// The scene's triangles, each once (what the columns' triangles are copies of).
    pub fn distinct(&self) -> &[Triangle] {
        &self.distinct
    }

    /// The triangles column (x, y) keeps.
    pub fn column(&self, x: u32, y: u32) -> &[Triangle] {
        &self.tris[self.range(x, y)]
    }

    /// Whether the stores were loaded (a grid loaded without them has none).
    pub fn loaded(&self) -> bool {
        !self.start.is_empty()
    }

    /// Triangles kept, over all columns.
    pub fn kept(&self) -> usize {
        self.tris.len()
    }

    /// Triangles left out by full columns.
    pub fn overflows(&self) -> u64 {
        self.overflows
    }

    /// The largest number of triangles one column keeps.
    pub fn max_per_column(&self) -> usize {
        self.start.windows(2).map(|w| (w[1] - w[0]) as usize).max().unwrap_or(0)
    }
}

/// The windows of every kept triangle (`flat`, columns cut by `start`), row by row in parallel.
fn all_near_windows(start: &[u32], flat: &[Triangle], n: u32) -> Vec<NearWindows> {
    let rows = par_map(n as usize, &|y| {
        let (a, b) = (start[y * n as usize] as usize, start[(y + 1) * n as usize] as usize);
        let mut out = Vec::with_capacity(b - a);
        for x in 0..n as usize {
            let i = y * n as usize + x;
            for t in &flat[start[i] as usize..start[i + 1] as usize] {
                out.push(near_windows(t, x as i32, y as i32, Depth::MAX));
            }
        }
        out
    });
    rows.concat()
}
