//! Outside flood fill and leak detection (thesis §3.8: "a closed mesh must voxelize without
//! tunnels", §7 hole and tunnel counts).
//!
//! The grid is `n × n × n` voxels, index `x + n·(y + n·z)`. Imagine the grid surrounded by a
//! layer of empty space: every **unoccupied** voxel on a boundary face of the grid touches it,
//! so those voxels are the seeds. From them the fill spreads through unoccupied voxels by
//! k-adjacency (k = 26 for [`outside_reach_26`]: a 26-connected discrete ray can slip through
//! a vertex-only gap). The fill is iterative (an explicit stack) and O(k·n³).
//!
//! A **leak** is a voxel reached from outside whose centre is strictly inside the mesh
//! according to the [`InsideOracle`] (`Some(true)`); voxels whose centre is on the surface
//! (`None`) are never leaks. A voxelization of a closed mesh is 26-tight iff it has no
//! 26-leak.

use crate::oracle::inside::InsideOracle;
use crate::oracle::tunnels::half_neighbourhood;

/// Voxels reachable from outside the grid through unoccupied voxels, k-adjacency
/// (`connectivity` ∈ {6, 18, 26}); index `x + n·(y + n·z)`. `occupied` is called once per voxel.
///
/// # Panics
/// If `connectivity` is not 6, 18 or 26.
pub fn outside_reach(n: i64, occupied: &dyn Fn(i64, i64, i64) -> bool, connectivity: u8) -> Vec<bool> {
    let half = half_neighbourhood(connectivity);
    if n <= 0 {
        return Vec::new();
    }
    let nu = n as usize;
    let total = nu * nu * nu;
    let mut occ = vec![false; total];
    for z in 0..n {
        for y in 0..n {
            for x in 0..n {
                occ[(x + n * (y + n * z)) as usize] = occupied(x, y, z);
            }
        }
    }
    let deltas: Vec<[i64; 3]> = half.iter().flat_map(|d| [*d, [-d[0], -d[1], -d[2]]]).collect();
    let mut reached = vec![false; total];
    let mut stack: Vec<usize> = Vec::new();
    for z in 0..n {
        for y in 0..n {
            for x in 0..n {
                let on_face = x == 0 || y == 0 || z == 0 || x == n - 1 || y == n - 1 || z == n - 1;
                let i = (x + n * (y + n * z)) as usize;
                if on_face && !occ[i] && !reached[i] {
                    reached[i] = true;
                    stack.push(i);
                }
            }
        }
    }
    while let Some(i) = stack.pop() {
        let x = (i % nu) as i64;
        let y = ((i / nu) % nu) as i64;
        let z = (i / (nu * nu)) as i64;
        for d in &deltas {
            let (a, b, c) = (x + d[0], y + d[1], z + d[2]);
            if a < 0 || b < 0 || c < 0 || a >= n || b >= n || c >= n {
                continue;
            }
            let j = (a + n * (b + n * c)) as usize;
            if !occ[j] && !reached[j] {
                reached[j] = true;
                stack.push(j);
            }
        }
    }
    reached
}

/// [`outside_reach`] with 26-adjacency.
pub fn outside_reach_26(n: i64, occupied: &dyn Fn(i64, i64, i64) -> bool) -> Vec<bool> {
    outside_reach(n, occupied, 26)
}

/// Voxels reached from outside (k-adjacency) whose centre is strictly inside, sorted `[x, y, z]`.
pub fn leaks_with(
    n: i64,
    occupied: &dyn Fn(i64, i64, i64) -> bool,
    inside: &InsideOracle,
    connectivity: u8,
) -> Vec<[i64; 3]> {
    let reached = outside_reach(n, occupied, connectivity);
    let mut out = Vec::new();
    for x in 0..n {
        for y in 0..n {
            for z in 0..n {
                if reached[(x + n * (y + n * z)) as usize] && inside.inside(x, y, z) == Some(true) {
                    out.push([x, y, z]);
                }
            }
        }
    }
    out
}

/// 26-leaks: voxels reached from outside by [`outside_reach_26`] whose centre is strictly
/// inside the mesh (`inside.inside(..) == Some(true)`), sorted `[x, y, z]`.
pub fn leaks(n: i64, occupied: &dyn Fn(i64, i64, i64) -> bool, inside: &InsideOracle) -> Vec<[i64; 3]> {
    leaks_with(n, occupied, inside, 26)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::oracle::brute::tests::Rng;
    use crate::oracle::brute::{facet_voxels_all, Contour, Thickness};
    use crate::oracle::inside::tests::{box_mesh, sphere_mesh};
    use std::collections::HashSet;

    const Q: i64 = 16;

    /// The 1-voxel shell of the voxel box [2, 7]³ in a 10³ grid. With `pocket`, the face voxel
    /// P = (2, 4, 4) is freed and all of its 18 face- and edge-neighbours are occupied: P then
    /// touches the outside (e.g. (1, 3, 3)) and the interior (e.g. (3, 3, 3)) through vertices
    /// only — a 26-only gap.
    fn shell(pocket: bool) -> impl Fn(i64, i64, i64) -> bool {
        move |x, y, z| {
            let p = [x, y, z];
            if pocket {
                let d = [x - 2, y - 4, z - 4];
                if d == [0, 0, 0] {
                    return false;
                }
                let nonzero = d.iter().filter(|c| **c != 0).count();
                if d.iter().all(|c| c.abs() <= 1) && nonzero <= 2 {
                    return true;
                }
            }
            let inb = p.iter().all(|c| (2..=7).contains(c));
            inb && p.iter().any(|c| *c == 2 || *c == 7)
        }
    }

    /// Mesh of the box strictly between the shell's voxel centres: lattice [41, 119]³.
    fn shell_oracle() -> InsideOracle {
        InsideOracle::new(&box_mesh([41; 3], [119; 3], false), Q, 10)
    }

    #[test]
    fn closed_shell_does_not_leak() {
        let occ = shell(false);
        let r = outside_reach_26(10, &occ);
        let reached = r.iter().filter(|b| **b).count();
        assert_eq!(reached, 1000 - 216, "everything but the shell and its interior");
        assert!(!r[(4 + 10 * (4 + 10 * 4)) as usize]);
        assert!(leaks(10, &occ, &shell_oracle()).is_empty());
    }

    #[test]
    fn diagonal_gap_leaks_26_but_not_6() {
        let occ = shell(true);
        let o = shell_oracle();
        let l26 = leaks(10, &occ, &o);
        // The whole interior (3..=6)³ minus the 5 added voxels at x = 3 is reached.
        assert_eq!(l26.len(), 64 - 5);
        assert!(l26.contains(&[4, 4, 4]));
        assert!(leaks_with(10, &occ, &o, 6).is_empty());
        assert!(leaks_with(10, &occ, &o, 18).is_empty());
        // The pocket itself is reached only with 26-adjacency.
        let pocket = (2 + 10 * (4 + 10 * 4)) as usize;
        assert!(outside_reach(10, &occ, 26)[pocket]);
        assert!(!outside_reach(10, &occ, 6)[pocket]);
    }

    #[test]
    fn degenerate_grids() {
        assert!(outside_reach_26(0, &|_, _, _| false).is_empty());
        assert_eq!(outside_reach_26(1, &|_, _, _| false), vec![true]);
        assert_eq!(outside_reach_26(1, &|_, _, _| true), vec![false]);
        // Fully occupied: nothing reached.
        assert!(outside_reach_26(4, &|_, _, _| true).iter().all(|b| !b));
    }

    /// Voxelize a mesh with the brute-force oracle and count 26- and 6-leaks.
    fn mesh_leaks(mesh: &[[[i64; 3]; 3]], n: i64, th: Thickness, ct: Contour) -> (usize, usize) {
        let mut occ: HashSet<[i64; 3]> = HashSet::new();
        for t in mesh {
            occ.extend(facet_voxels_all(t, Q, th, ct));
        }
        let o = InsideOracle::new(mesh, Q, n);
        assert!(o.odd_columns().is_empty());
        let f = |x, y, z| occ.contains(&[x, y, z]);
        (leaks_with(n, &f, &o, 26).len(), leaks_with(n, &f, &o, 6).len())
    }

    #[test]
    fn brute_voxelized_closed_meshes() {
        // A box, a coarse sphere and random (possibly flat or sliver) tetrahedra: standard
        // thickness with a conservative contour does not leak, even 26-connected; naive
        // thickness with a conservative contour does not leak 6-connected.
        let mut meshes = vec![
            ("cube".to_string(), box_mesh([37, 45, 29], [211, 190, 205], true), 16),
            ("sphere".to_string(), sphere_mesh([16 * 12 + 8; 3], 16.0 * 9.3, 6), 24),
        ];
        let mut rng = Rng(99);
        for k in 0..10 {
            let mut p = || [rng.range(8, 300), rng.range(8, 300), rng.range(8, 300)];
            let v = [p(), p(), p(), p()];
            let tet = vec![[v[0], v[1], v[2]], [v[0], v[3], v[1]], [v[1], v[3], v[2]], [v[2], v[3], v[0]]];
            meshes.push((format!("tetrahedron {k} {v:?}"), tet, 20));
        }
        for (name, mesh, n) in &meshes {
            let (mesh, n) = (mesh.as_slice(), *n);
            let (l26, l6) = mesh_leaks(mesh, n, Thickness::Standard, Contour::Conservative);
            assert_eq!((l26, l6), (0, 0), "{name}: standard + conservative");
            let (_, l6) = mesh_leaks(mesh, n, Thickness::Naive, Contour::Conservative);
            assert_eq!(l6, 0, "{name}: naive + conservative has no 6-leak");
        }
    }
}
