#!/usr/bin/env python3
"""rc2 against outside tools, in one run. Called by bench/compare.sh.

voxel   — `host-sim voxelize` against trimesh's `mesh.voxelized(pitch)` and Open3D's
          `VoxelGrid.create_from_triangle_mesh_within_bounds` on the same mesh, same grid:
          wall-time medians and the agreement of the voxel sets.
light   — `host-sim light` (beam diffusion on the simulated machine) against exact shadow rays
          cast with Embree (embreex) from the same voxels toward the same light: wall-time
          medians and the agreement of the lit/shadow classification.

Grid matching. rc2 fits the mesh's bounding box into n − 2 voxels (a one-voxel margin,
centred; host-sim/src/precompute.rs) and voxel (i, j, k) is the world cube
origin + [i, i+1)·voxel per axis; `voxelize --stats` reports origin (`translate`) and
`voxel_size`. Open3D is given exactly that box (min_bound = origin, voxel_size = voxel:
its index is ⌊(p − origin)/voxel⌋, the same cubes). trimesh rounds surface sample points to
the nearest multiple of the pitch (voxel centres at k·pitch), so the mesh is first moved by
−(origin + ½·voxel): its voxel k is then rc2's voxel k.

Shadow rays. For an occupied voxel and a light, the ray goes from the voxel's centre toward the
light and starts where it leaves the voxel's own cube (geometry inside the voxel itself is the
surface the voxel stands for; the same convention as host-sim's own accuracy measure, which
ignores the voxel's own face). The voxel is lit iff Embree finds nothing between that point
and the light. rc2's voxel is lit iff a beam of that light reached it (`--dump-lit`).
"""

import argparse
import csv
import json
import os
import statistics
import subprocess
import sys
import time

import numpy as np


def median_time(fn, runs):
    times, out = [], None
    for _ in range(runs):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times), out


def run_host(host, args):
    r = subprocess.run([host] + args, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    if r.returncode != 0:
        sys.exit(f"error: host-sim {' '.join(args)} failed: {r.stderr.strip().splitlines()[-1:]}")
    return r


def time_host(host, args, stats, runs):
    """Median process wall time and median of the job's own `wall_seconds` (from --stats)."""
    walls, inner = [], []
    for _ in range(runs):
        t0 = time.perf_counter()
        run_host(host, args)
        walls.append(time.perf_counter() - t0)
        inner.append(json.load(open(stats))["wall_seconds"])
    return statistics.median(walls), statistics.median(inner)


def read_binvox(path):
    """Occupied voxel indices (N × 3, int) of a binvox file (x slowest, then z, y fastest)."""
    with open(path, "rb") as f:
        if not f.readline().startswith(b"#binvox"):
            sys.exit(f"error: {path} is not a binvox file")
        dims = None
        while True:
            line = f.readline().strip()
            if line.startswith(b"dim"):
                dims = [int(x) for x in line.split()[1:]]
            if line == b"data":
                break
        raw = np.frombuffer(f.read(), dtype=np.uint8)
    values, counts = raw[0::2], raw[1::2]
    dense = np.repeat(values, counts.astype(np.int64)).astype(bool)
    n = dims[0]
    if dense.size != n * n * n:
        sys.exit(f"error: {path}: {dense.size} voxels for dim {dims}")
    flat = np.nonzero(dense)[0]
    x, rem = np.divmod(flat, n * n)
    z, y = np.divmod(rem, n)
    return np.stack([x, y, z], axis=1)


def as_keys(idx, n):
    idx = np.asarray(idx, dtype=np.int64)
    inside = np.all((idx >= 0) & (idx < n), axis=1)
    idx = idx[inside]
    return np.unique((idx[:, 0] * n + idx[:, 1]) * n + idx[:, 2]), int((~inside).sum())


def agreement(ours, theirs):
    inter = np.intersect1d(ours, theirs, assume_unique=True).size
    union = ours.size + theirs.size - inter
    return {
        "ours": int(ours.size),
        "theirs": int(theirs.size),
        "only_ours": int(ours.size - inter),
        "only_theirs": int(theirs.size - inter),
        "iou": inter / union if union else 1.0,
    }


def load_obj(path):
    import trimesh

    m = trimesh.load(path, force="mesh", process=False)
    return np.asarray(m.vertices, dtype=np.float64), np.asarray(m.faces, dtype=np.int64)


def voxel_bench(a, host, out_dir, rows):
    import trimesh

    try:
        import open3d as o3d
    except ImportError:
        o3d = None
        print("note: open3d is not installed: comparing with trimesh only", file=sys.stderr)
    configs = [("standard", "conservative"), ("naive", "projected")]
    for mesh_name in a.meshes:
        verts, faces = load_obj(os.path.join(a.scenes, f"{mesh_name}.obj"))
        for n in a.n:
            ours_keys = {}
            for sigma, contour in configs:
                vox = os.path.join(out_dir, f"{mesh_name}-{n}-{sigma}-{contour}.binvox")
                stats = os.path.join(out_dir, f"{mesh_name}-{n}-{sigma}-{contour}.json")
                args = ["voxelize", mesh_name, "--n", str(n), "--sigma", sigma, "--contour", contour]
                args += ["--out", vox, "--stats", stats, "--quiet"]
                wall, inner = time_host(host, args, stats, a.runs)
                keys, _ = as_keys(read_binvox(vox), n)
                ours_keys[(sigma, contour)] = (keys, wall, inner, json.load(open(stats)))
            _, _, _, st = ours_keys[configs[0]]
            origin, voxel = np.array(st["translate"]), st["voxel_size"]

            tools = {}
            if o3d is not None:
                # Open3D: the same cubes, conservative triangle–box test.
                o3m = o3d.geometry.TriangleMesh(
                    o3d.utility.Vector3dVector(verts), o3d.utility.Vector3iVector(faces)
                )
                hi = origin + n * voxel

                def run_o3d():
                    return o3d.geometry.VoxelGrid.create_from_triangle_mesh_within_bounds(o3m, voxel, origin, hi)

                # Timed: the voxelization; not timed: reading the voxels back into Python.
                t_o3d, grid = median_time(run_o3d, a.runs)
                o3_idx = np.array([v.grid_index for v in grid.get_voxels()], dtype=np.int64).reshape(-1, 3)
                tools["open3d"] = (t_o3d, as_keys(o3_idx, n))

            # trimesh: surface samples rounded to the nearest centre; centres moved onto k·pitch.
            tm = trimesh.Trimesh(verts - (origin + 0.5 * voxel), faces, process=False)

            if n > a.trimesh_max_n:
                print(f"note: trimesh skipped at n = {n} (> --trimesh-max-n {a.trimesh_max_n})", file=sys.stderr)
                tools_done(rows, mesh_name, n, ours_keys, tools)
                continue

            def run_trimesh():
                vg = tm.voxelized(pitch=voxel)
                # sparse_indices are relative to the grid's first index; add its offset.
                offset = np.round(vg.transform[:3, 3] / voxel).astype(np.int64)
                return vg.sparse_indices.astype(np.int64) + offset

            t_tm, tm_idx = median_time(run_trimesh, a.runs)
            tools["trimesh"] = (t_tm, as_keys(tm_idx, n))
            tools_done(rows, mesh_name, n, ours_keys, tools)


def tools_done(rows, mesh_name, n, ours_keys, tools):
    """One row per (our configuration, tool)."""
    for (sigma, contour), (keys, wall, inner, st) in ours_keys.items():
        for tool, (t_tool, (their_keys, outside)) in tools.items():
            ag = agreement(keys, their_keys)
            rows.append(
                {
                    "mesh": mesh_name,
                    "n": n,
                    "ours": f"{sigma}+{contour}",
                    "tool": tool,
                    "ours_process_s": round(wall, 4),
                    "ours_compute_s": round(inner, 4),
                    "tool_s": round(t_tool, 4),
                    "ratio_compute": round(inner / t_tool, 3),
                    "voxels_ours": ag["ours"],
                    "voxels_tool": ag["theirs"],
                    "only_ours": ag["only_ours"],
                    "only_tool": ag["only_theirs"],
                    "tool_outside_grid": outside,
                    "iou": round(ag["iou"], 4),
                }
            )
            print(rows[-1], flush=True)


def exit_and_first_neighbour(centres, target, voxel):
    """Per ray: the unit direction, the distance to where it leaves the voxel's cube, the
    distance to the light, and the 6-neighbour through whose face it leaves."""
    d = target - centres
    dist = np.linalg.norm(d, axis=1)
    u = d / dist[:, None]
    with np.errstate(divide="ignore"):
        t_axis = np.where(np.abs(u) > 0, 0.5 * voxel / np.abs(u), np.inf)
    axis = np.argmin(t_axis, axis=1)
    t_exit = t_axis[np.arange(len(u)), axis]
    step = np.zeros((len(u), 3), dtype=np.int64)
    step[np.arange(len(u)), axis] = np.sign(u[np.arange(len(u)), axis]).astype(np.int64)
    return u, t_exit, dist, step


def embree_lit(verts, tris, centres, light, voxel):
    from embreex import rtcore_scene as rtcs
    from embreex.mesh_construction import TriangleMesh

    scene = rtcs.EmbreeScene()
    TriangleMesh(scene, verts.astype(np.float32), tris)
    u, t_exit, dist, _ = exit_and_first_neighbour(centres, light, voxel)
    origins = (centres + u * t_exit[:, None]).astype(np.float32)
    tfar = (dist - t_exit).astype(np.float32)
    hit = scene.run(origins, u.astype(np.float32), dists=tfar, query="OCCLUDED")
    return (hit == -1) | (tfar <= 0)


def light_bench(a, host, out_dir, rows):
    for scene_name in a.light_scenes:
        for n in a.light_n:
            dump = os.path.join(out_dir, f"{scene_name}-{n}.lit.json")
            stats = os.path.join(out_dir, f"{scene_name}-{n}.light.json")
            args = ["light", scene_name, "--n", str(n), "--view", "fitted", "--sigma", a.sigma, "--contour", a.contour]
            args += ["--dump-lit", dump, "--stats", stats, "--quiet"]
            wall, inner = time_host(host, args, stats, a.runs)
            d = json.load(open(dump))
            verts = np.array(d["vertices"], dtype=np.float64).reshape(-1, 3)
            tris = np.array(d["triangles"], dtype=np.int64).reshape(-1, 3)
            vox = np.array(d["voxels"], dtype=np.int64).reshape(-1, 4)
            origin, voxel = np.array(d["origin"]), d["voxel"]
            centres = origin + (vox[:, :3] + 0.5) * voxel
            occupied = set(((vox[:, 0] * n + vox[:, 1]) * n + vox[:, 2]).tolist())
            # Camera-visible voxels: the first occupied voxel of each column (view along +z).
            order = np.lexsort((vox[:, 2], vox[:, 1], vox[:, 0]))
            cols = vox[order, 0] * n + vox[order, 1]
            first = np.zeros(len(vox), dtype=bool)
            first[order[np.r_[True, cols[1:] != cols[:-1]]]] = True
            for li, light in enumerate(d["lights_world"]):
                light = np.array(light)
                t_emb, emb = median_time(lambda: embree_lit(verts, tris, centres, light, voxel), a.runs)
                ours = (vox[:, 3] >> li) & 1 == 1
                _, _, _, step = exit_and_first_neighbour(centres, light, voxel)
                nb = vox[:, :3] + step
                nb_key = (nb[:, 0] * n + nb[:, 1]) * n + nb[:, 2]
                inside = np.all((nb >= 0) & (nb < n), axis=1)
                # Exposed toward the light: the voxel the shadow ray enters first is empty.
                exposed = ~inside | np.array([k not in occupied for k in nb_key.tolist()])
                for subset, mask in [("all occupied", np.ones(len(vox), bool)), ("exposed", exposed),
                                     ("camera-visible", first), ("visible+exposed", first & exposed)]:
                    o, e = ours[mask], emb[mask]
                    total = int(mask.sum())
                    rows.append(
                        {
                            "scene": scene_name,
                            "n": n,
                            "light": li,
                            "voxels": subset,
                            "count": total,
                            "lit_ours": int(o.sum()),
                            "lit_embree": int(e.sum()),
                            "false_lit": int((o & ~e).sum()),
                            "false_dark": int((~o & e).sum()),
                            "disagreement_pct": round(100.0 * int((o != e).sum()) / max(total, 1), 2),
                            "ours_process_s": round(wall, 4),
                            "ours_diffusion_s": round(inner, 4),
                            "cycles": d["cycles"],
                            "beams": d["beams_processed"],
                            "embree_s": round(t_emb, 4),
                            "embree_rays": len(vox),
                            "ratio_diffusion": round(inner / t_emb, 1),
                        }
                    )
                    print(rows[-1], flush=True)


def write_csv(path, rows):
    if not rows:
        return
    with open(path, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0].keys()))
        w.writeheader()
        w.writerows(rows)
    print(f"wrote {path}")


def print_tables(out_dir):
    """The Markdown tables of BENCHMARKS.md, from the CSVs of a run."""
    vpath, lpath = os.path.join(out_dir, "voxelize.csv"), os.path.join(out_dir, "light.csv")
    if os.path.exists(vpath):
        print("| mesh | n | rc2 surfaces | tool | rc2 s | tool s | rc2 / tool | voxels rc2 | voxels tool "
              "| rc2 only | tool only | IoU |")
        print("|---|---|---|---|---|---|---|---|---|---|---|---|")
        for r in csv.DictReader(open(vpath)):
            print(f"| {r['mesh']} | {r['n']} | {r['ours']} | {r['tool']} | {r['ours_compute_s']} | {r['tool_s']} "
                  f"| {r['ratio_compute']} | {r['voxels_ours']} | {r['voxels_tool']} | {r['only_ours']} "
                  f"| {r['only_tool']} | {r['iou']} |")
    if os.path.exists(lpath):
        print("\n| scene | n | voxels | count | lit rc2 | lit Embree | false lit | false dark | disagreement % "
              "| rc2 diffusion s | Embree s | rc2 / Embree |")
        print("|---|---|---|---|---|---|---|---|---|---|---|---|")
        for r in csv.DictReader(open(lpath)):
            print(f"| {r['scene']} | {r['n']} | {r['voxels']} | {r['count']} | {r['lit_ours']} | {r['lit_embree']} "
                  f"| {r['false_lit']} | {r['false_dark']} | {r['disagreement_pct']} | {r['ours_diffusion_s']} "
                  f"| {r['embree_s']} | {r['ratio_diffusion']} |")


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--host", required=True, help="the host-sim binary")
    p.add_argument("--scenes", default="host-sim/scenes", help="folder of the built-in meshes' OBJ files")
    p.add_argument("--out", default="bench-out/compare")
    p.add_argument("--runs", type=int, default=3)
    p.add_argument("--meshes", nargs="+", default=["teapot", "cow", "fandisk"])
    p.add_argument("--n", type=int, nargs="+", default=[128, 256, 512])
    p.add_argument("--light-scenes", nargs="+", default=["teapot-floor", "cow-floor", "cornell"])
    p.add_argument("--light-n", type=int, nargs="+", default=[128])
    p.add_argument("--sigma", default="naive", help="surfaces for the lighting run (render default)")
    p.add_argument("--contour", default="projected")
    p.add_argument("--trimesh-max-n", type=int, default=256, help="trimesh's subdivision voxelizer is slow beyond")
    p.add_argument("--only", choices=["voxel", "light"], help="run one half")
    p.add_argument("--tables", action="store_true", help="only print the Markdown tables of --out's CSVs")
    a = p.parse_args()
    if a.tables:
        print_tables(a.out)
        return
    os.makedirs(a.out, exist_ok=True)
    if a.only != "light":
        rows = []
        voxel_bench(a, a.host, a.out, rows)
        write_csv(os.path.join(a.out, "voxelize.csv"), rows)
    if a.only != "voxel":
        rows = []
        light_bench(a, a.host, a.out, rows)
        write_csv(os.path.join(a.out, "light.csv"), rows)
    print_tables(a.out)


if __name__ == "__main__":
    main()
