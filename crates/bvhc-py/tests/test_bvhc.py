"""The Python package against the command line: hits equal `bvhc trace`'s records, one- and two-level; arrays
build the same file as converting their PLY; every error path raises its exception; no leak over repeated opens.

Run by tests/suite/python_package.rs (which sets BVHC_BIN to the built `bvhc` and installs nothing: .ci/run
builds the wheel and installs it into a virtual environment, as a user would); scenes from BVHC_SCENES or
../shared/scenes, skipped without them.
"""

import gc
import json
import os
import pathlib
import subprocess
import sys

import numpy as np
import pytest

import bvhc

ROOT = pathlib.Path(__file__).resolve().parents[3]
TEAPOT = ROOT / "fixtures" / "scenes" / "teapot.obj"
BIN = os.environ.get("BVHC_BIN", str(ROOT / "target" / "release" / "bvhc"))
SCENES = pathlib.Path(os.environ.get("BVHC_SCENES", ROOT.parent / "shared" / "scenes"))


def cli(*args):
    run = subprocess.run([BIN, *map(str, args)], capture_output=True, text=True)
    assert run.returncode == 0, run.stderr
    return run.stdout


def scene(relative):
    path = SCENES / relative
    if not path.is_file():
        pytest.skip(f"scene {relative} not found (set BVHC_SCENES)")
    return path


def random_rays(bounds, n, seed):
    rng = np.random.default_rng(seed)
    lo, hi = (np.asarray(b, dtype=np.float64) for b in bounds)
    size = (hi - lo).max()
    origins = rng.uniform(lo - 0.1 * size, hi + 0.1 * size, (n, 3)).astype(np.float32)
    directions = rng.normal(size=(n, 3)).astype(np.float32)
    # Some aimed at vertices of the box's middle, so that a good share hits.
    targets = rng.uniform(lo, hi, (n // 2, 3)).astype(np.float32)
    directions[: n // 2] = targets - origins[: n // 2]
    directions[np.abs(directions).max(axis=1) < 1e-6] = (0, 0, 1)
    return origins, directions


def camera_rays(bounds, width, height):
    """A camera's primary rays, row by row, from outside the box looking at its centre: (origins, directions)."""
    low, high = np.asarray(bounds[0], np.float64), np.asarray(bounds[1], np.float64)
    centre, size = (low + high) / 2, float(np.max(high - low))
    eye = centre + np.array([0.3, 0.4, 1.5]) * size
    forward = (centre - eye) / np.linalg.norm(centre - eye)
    right = np.cross(forward, [0.0, 1.0, 0.0])
    right /= np.linalg.norm(right)
    up = np.cross(right, forward)
    x, y = np.meshgrid((np.arange(width) + 0.5) / width - 0.5, (np.arange(height) + 0.5) / height - 0.5)
    directions = forward + 0.8 * (x.reshape(-1, 1) * right - y.reshape(-1, 1) * up)
    origins = np.broadcast_to(eye, directions.shape)
    return origins.astype(np.float32), directions.astype(np.float32)


def trace_with_cli(bvh, origins, directions, t_min, t_max, tmp_path, any_hit=False):
    rays = np.zeros(len(origins), dtype=[("o", "<f4", 3), ("d", "<f4", 3), ("lo", "<f4"), ("hi", "<f4")])
    rays["o"], rays["d"], rays["lo"], rays["hi"] = origins, directions, t_min, t_max
    ray_file, hit_file = tmp_path / "rays.bin", tmp_path / "hits.bin"
    rays.tofile(ray_file)
    cli("trace", bvh, "--rays", ray_file, "-o", hit_file, *(["--any-hit"] if any_hit else []))
    if any_hit:
        return np.fromfile(hit_file, dtype=np.uint8).astype(bool)
    return np.fromfile(
        hit_file,
        dtype=[("t", "<f4"), ("triangle", "<u4"), ("source_id", "<u4"), ("u", "<f4"), ("v", "<f4"), ("instance", "<u4")],
    )


def assert_same_hits(hits, records, fields=("t", "triangle", "source_id", "u", "v", "instance")):
    for field in fields:
        mine, theirs = hits[field], records[field]
        if mine.dtype == np.float32:  # bit for bit (inf for misses included)
            mine, theirs = mine.view(np.uint32), theirs.view(np.uint32)
        differ = np.flatnonzero(mine != theirs)
        assert differ.size == 0, f"{field}: {differ.size} rays differ, first {differ[:5]}"


def assert_same_hits_up_to_records(opened, hits, records):
    """As assert_same_hits, except that with split references (a triangle stored in several records) a ray may
    name another record of the same triangle: the spec leaves which record open (11.1), not the triangle."""
    assert_same_hits(hits, records, fields=("t", "source_id", "u", "v", "instance"))
    differ = np.flatnonzero(hits["triangle"] != records["triangle"])
    if differ.size:
        assert not np.isin(bvhc.MISS, hits["triangle"][differ]) and not np.isin(bvhc.MISS, records["triangle"][differ])
        triangles = opened.triangles
        mine, theirs = triangles[hits["triangle"][differ]], triangles[records["triangle"][differ]]
        assert np.array_equal(mine.view(np.uint32), theirs.view(np.uint32)), f"rays {differ[:5]} name other triangles"


CASES = [
    ("teapot", None, []),
    ("engine", "khr-2cylinder-engine/2CylinderEngine.gltf", []),
    ("engine-two-level", "khr-2cylinder-engine/2CylinderEngine.gltf", ["--instancing", "always"]),
    ("truck-two-level", "khr-cesium-milk-truck/CesiumMilkTruck.gltf", ["--instancing", "always"]),
]


@pytest.mark.parametrize("name,relative,flags", CASES, ids=[c[0] for c in CASES])
def test_hits_equal_bvhc_trace_record_for_record(name, relative, flags, tmp_path):
    source = TEAPOT if relative is None else scene(relative)
    bvh = tmp_path / f"{name}.bvh"
    cli(source, "-o", bvh, "-q", *flags)
    opened = bvhc.open(bvh)
    assert (opened.instances is not None) == ("two-level" in name)
    origins, directions = random_rays(opened.bounds, 20_000, seed=7)
    t_max = np.where(np.arange(len(origins)) % 3 == 0, np.float32(np.inf), np.float32(2.0))
    hits = opened.closest_hits(origins, directions, 0.0, t_max)
    records = trace_with_cli(bvh, origins, directions, 0.0, t_max, tmp_path)
    assert_same_hits(hits, records)
    assert 0.05 < (hits["triangle"] != bvhc.MISS).mean() < 1.0
    occluded = opened.any_hits(origins, directions, 0.0, t_max)
    assert np.array_equal(occluded, trace_with_cli(bvh, origins, directions, 0.0, t_max, tmp_path, any_hit=True))
    assert np.array_equal(occluded, hits["triangle"] != bvhc.MISS)
    # float64, strided (every other row of a larger array), one thread: the same hits.
    wide = np.zeros((2 * len(origins), 3))
    wide[::2] = origins
    same = opened.closest_hits(wide[::2], directions.astype(np.float64), np.zeros(len(origins)), t_max, threads=1)
    assert_same_hits(same, records)
    # Coherent packets (8 consecutive rays together): the same hits, here on incoherent rays and on a camera's.
    packets = opened.closest_hits(origins, directions, 0.0, t_max, coherent=True)
    assert_same_hits_up_to_records(opened, packets, records)
    assert np.array_equal(opened.any_hits(origins, directions, 0.0, t_max, coherent=True), occluded)
    eye, camera = camera_rays(opened.bounds, 64, 48)
    single = opened.closest_hits(eye, camera)
    packets = opened.closest_hits(eye, camera, coherent=True)
    assert_same_hits_up_to_records(opened, packets, single)
    assert 0.0 < (single["triangle"] != bvhc.MISS).mean()
    assert np.array_equal(opened.any_hits(eye, camera, coherent=True), single["triangle"] != bvhc.MISS)
    # Handed off lean: the same t, triangle, u, v, instance, and nothing else; on the camera's rays too.
    for rays, full in (((origins, directions, 0.0, t_max), hits), ((eye, camera), single)):
        for coherent in (False, True):
            lean = opened.closest_hits(*rays, lean=True, coherent=coherent)
            assert sorted(lean) == ["instance", "t", "triangle", "u", "v"]
            if coherent:  # with split references a packet may name another record of the triangle: as above
                assert np.array_equal(lean["t"], full["t"])
                continue
            for key in lean:
                assert np.array_equal(lean[key], full[key]), key
    # Normals and front faces as the records' vertices say.
    hit = np.flatnonzero(hits["triangle"] != bvhc.MISS)
    if opened.instances is None:
        tri = opened.triangles[hits["triangle"][hit]].astype(np.float64)
        normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        assert np.allclose(hits["normal"][hit], normal, rtol=1e-4, atol=1e-6 * np.abs(normal).max())
        facing = np.einsum("ij,ij->i", directions[hit].astype(np.float64), normal) < 0
        assert np.array_equal(hits["front_face"][hit], facing)


def test_arrays_build_the_file_converting_their_ply_gives(tmp_path):
    rng = np.random.default_rng(3)
    vertices = rng.uniform(-1, 1, (300, 3)).astype(np.float32)
    faces = rng.integers(0, 300, (500, 3))
    built = bvhc.build(vertices, faces, tmp_path / "built.bvh")
    assert built["report"]["triangle_count"] > 0
    # The same PLY the package writes, converted by the command line, gives the same bytes (the metadata names
    # mesh.ply and its hash in both).
    folder = tmp_path / "ply"
    folder.mkdir()
    (folder / "mesh.ply").write_bytes(bvhc._ply_bytes(vertices, faces.astype(np.uint32)))
    cli(folder / "mesh.ply", "-o", tmp_path / "cli.bvh", "-q")
    assert (tmp_path / "built.bvh").read_bytes() == (tmp_path / "cli.bvh").read_bytes()
    # Building the same arrays again is up to date; float64 vertices build a file of the same triangles.
    assert bvhc.build(vertices, faces, tmp_path / "built.bvh")["up_to_date"]
    bvhc.build(vertices.astype(np.float64), faces, tmp_path / "f64.bvh")
    a, b = bvhc.open(tmp_path / "built.bvh"), bvhc.open(tmp_path / "f64.bvh")
    assert np.array_equal(a.triangles, b.triangles)
    # Against an OBJ of the same triangles: the same tree and triangles (OBJ and PLY name their source
    # primitives differently, so the source table and metadata differ).
    obj = tmp_path / "mesh.obj"
    with open(obj, "w") as out:
        out.writelines(f"v {x!r} {y!r} {z!r}\n" for x, y, z in vertices.tolist())
        out.writelines(f"f {i + 1} {j + 1} {k + 1}\n" for i, j, k in faces.tolist())
    cli(obj, "-o", tmp_path / "obj.bvh", "-q")
    c = bvhc.open(tmp_path / "obj.bvh")
    for section in ["nodes", "triangles", "triangle_ids", "wide_nodes", "triangle_packets", "source_vertices"]:
        assert np.array_equal(a.section(section), c.section(section)), section


def test_a_trimesh_builds_through_its_arrays(tmp_path):
    trimesh = pytest.importorskip("trimesh")
    mesh = trimesh.creation.icosphere(subdivisions=3)
    report = bvhc.build(mesh.vertices, mesh.faces, tmp_path / "sphere.bvh")
    assert report["report"]["triangle_count"] == len(mesh.faces)
    opened = bvhc.open(tmp_path / "sphere.bvh")
    # Rays from outside towards the center hit the unit sphere at t = 1 (within its flat facets).
    origins = np.array([[0, 0, 2.0], [2.0, 0, 0], [0, -2.0, 0]])
    hits = opened.closest_hits(origins, -origins)
    assert np.all((hits["t"] > 0.49) & (hits["t"] <= 0.5 + 1e-6)), hits["t"]


def test_memory_the_system_refuses_raises_out_of_memory(tmp_path):
    # A child whose address space is capped just above what it holds: the conversion's probe for its working
    # set (about 270 bytes a triangle) is refused.
    code = """
import resource, sys
import numpy as np
import bvhc
v = np.random.default_rng(1).uniform(-1, 1, (600_000, 3)).astype(np.float32)
f = np.arange(600_000).reshape(-1, 3)
with open("/proc/self/status") as status:
    size = next(int(line.split()[1]) for line in status if line.startswith("VmSize")) * 1024
resource.setrlimit(resource.RLIMIT_AS, (size + 160 * 2**20, resource.RLIM_INFINITY))
try:
    bvhc.build(v, f, sys.argv[1], max_memory="unlimited", threads=1)
except bvhc.OutOfMemoryError as error:
    print("OutOfMemoryError:", error)
    sys.exit(0)
except BaseException as error:
    print(type(error).__name__, error)
    sys.exit(1)
sys.exit(2)
"""
    run = subprocess.run([sys.executable, "-c", code, str(tmp_path / "big.bvh")], capture_output=True, text=True)
    assert run.returncode == 0, run.stdout + run.stderr
    assert "bvhc.build's arrays (as mesh.ply): out of memory" in run.stdout
    assert not (tmp_path / "big.bvh").exists()


def test_build_checks_its_arrays(tmp_path):
    vertices = np.zeros((3, 3), dtype=np.float32)
    with pytest.raises(bvhc.InvalidInputError, match="vertices"):
        bvhc.build(vertices[:, :2], [[0, 1, 2]], tmp_path / "x.bvh")
    with pytest.raises(bvhc.InvalidInputError, match="face 1"):
        bvhc.build(vertices, [[0, 1, 2], [0, 1, 3]], tmp_path / "x.bvh")
    with pytest.raises(bvhc.InvalidInputError, match="faces"):
        bvhc.build(vertices, np.zeros((1, 3), dtype=np.float32), tmp_path / "x.bvh")
    bad = np.array([[0, 0, 0], [1, 0, 0], [np.nan, 1, 0]], dtype=np.float32)
    with pytest.raises(bvhc.InvalidInputError, match=r"^bvhc.build's arrays \(as mesh.ply\): "):
        bvhc.build(bad, [[0, 1, 2]], tmp_path / "x.bvh")
    assert not (tmp_path / "x.bvh").exists()


def test_options_are_the_command_lines(tmp_path):
    resolved = bvhc.options("max-quality", splits=False)
    printed = json.loads(cli("options", "--preset", "max-quality", "--no-splits"))
    assert resolved == printed
    assert bvhc.options(split_method="pre_split") == json.loads(cli("options", "--split-method", "pre-split"))
    # The same bytes as the command line with the same flags.
    bvhc.convert(TEAPOT, tmp_path / "py.bvh", "fast", max_leaf_size=4, opacity="filtered", source_vertices=False)
    cli(TEAPOT, "-o", tmp_path / "cli.bvh", "--preset", "fast", "--max-leaf-size", "4", "--opacity", "filtered",
        "--no-source-vertices", "-q")
    assert (tmp_path / "py.bvh").read_bytes() == (tmp_path / "cli.bvh").read_bytes()
    for threads in [1, 2]:
        bvhc.convert(TEAPOT, tmp_path / f"t{threads}.bvh", threads=threads)
    assert (tmp_path / "t1.bvh").read_bytes() == (tmp_path / "t2.bvh").read_bytes()


@pytest.mark.parametrize(
    "options,message",
    [
        ({"bogus": 1}, "bogus: not a conversion option"),
        ({"max_leaf_size": 4, "merge_leaves": False}, "does nothing with"),
        ({"split_method": "octree"}, "split_method='octree': expected one of sbvh, pre-split"),
        ({"split_budget": 9.0}, "split_budget=9.0"),
        ({"time_budget": -1}, "time_budget=-1"),
        ({"max_leaf_size": "four"}, "max_leaf_size='four'"),
        ({"splits": "no"}, "splits='no': expected true or false"),
        ({"no_splits": 1}, "no_splits=1: expected true or false"),
        ({"max_memory": "lots"}, "max_memory"),
    ],
)
def test_refused_options_raise_options_error(options, message, tmp_path):
    with pytest.raises(bvhc.OptionsError, match=message):
        bvhc.convert(TEAPOT, tmp_path / "x.bvh", **options)
    assert not (tmp_path / "x.bvh").exists()
    with pytest.raises(bvhc.OptionsError):
        bvhc.convert(TEAPOT, tmp_path / "x.bvh", preset="slow")


def test_an_openusd_stage_converts_as_the_command_line_converts_it(tmp_path):
    stage = ROOT / "fixtures" / "usd" / "features.usdc"
    bvhc.convert(stage, tmp_path / "py.bvh", "fast", pose=2.5, purposes="render,proxy")
    cli(stage, "-o", tmp_path / "cli.bvh", "--preset", "fast", "--pose", "2.5", "--purposes", "render,proxy", "-q")
    assert (tmp_path / "py.bvh").read_bytes() == (tmp_path / "cli.bvh").read_bytes()
    metadata = bvhc.open(tmp_path / "py.bvh").info()["metadata"]
    assert metadata["build"]["import"]["time_code"] == 2.5
    assert metadata["usd"]["up_axis"] == "Z" and "/World/Forest" in metadata["usd"]["prims"]
    with pytest.raises(bvhc.OptionsError, match="shadow"):
        bvhc.convert(stage, tmp_path / "x.bvh", purposes="render,shadow")


def test_conversion_errors_raise_their_exception(tmp_path):
    with pytest.raises(bvhc.IoError, match="missing.obj"):
        bvhc.convert(tmp_path / "missing.obj", tmp_path / "x.bvh")
    bad = tmp_path / "bad.obj"
    bad.write_text("v 0 0 0\nv 1 0 0\nf 1 2 7\n")
    with pytest.raises(bvhc.InvalidInputError, match="bad.obj"):
        bvhc.convert(bad, tmp_path / "x.bvh")
    with pytest.raises(bvhc.InvalidInputError, match="max-memory|memory"):
        bvhc.convert(TEAPOT, tmp_path / "x.bvh", max_memory="1K")
    with pytest.raises(bvhc.IoError):
        bvhc.convert(TEAPOT, TEAPOT)  # the output is the input
    with pytest.raises(bvhc.IoError):
        bvhc.convert(TEAPOT, tmp_path / "no-such-folder" / "x.bvh")
    assert issubclass(bvhc.OptionsError, bvhc.InvalidInputError) and issubclass(bvhc.IoError, bvhc.Error)


def test_progress_is_reported_and_a_raising_callback_cancels(tmp_path):
    events = []
    report = bvhc.convert(TEAPOT, tmp_path / "a.bvh", progress=lambda *e: events.append(e))
    stages = [e[0] for e in events if e[0] != "batch"]
    assert stages == ["import", "build", "optimize", "write"], stages
    assert any(e[0] == "batch" and e[1] >= 1 and e[2] > 0 for e in events)
    assert report["report"]["triangle_count"] == 6320

    class Stop(Exception):
        pass

    def stop(stage, *rest):
        if stage == "batch":
            raise Stop()

    with pytest.raises(Stop):
        bvhc.convert(TEAPOT, tmp_path / "b.bvh", progress=stop)
    iterated = list(bvhc.convert_iter(TEAPOT, tmp_path / "c.bvh"))
    assert [e[0] for e in iterated if e[0] != "batch"] == ["import", "build", "optimize", "write"]
    with pytest.raises(bvhc.OptionsError):
        list(bvhc.convert_iter(TEAPOT, tmp_path / "d.bvh", bogus=True))


def test_open_gives_views_info_and_errors(tmp_path):
    bvh = tmp_path / "t.bvh"
    bvhc.convert(TEAPOT, bvh)
    for mmap in [True, False]:
        opened = bvhc.open(bvh, mmap=mmap)
        info = opened.info()
        printed = json.loads(cli("info", bvh, "--json"))
        assert info == printed
        assert opened.triangles.shape == (info["triangle_count"], 3, 3)
        assert len(opened.nodes) == info["node_count"] and opened.triangle_flags is None
        with pytest.raises(ValueError):
            opened.triangles[0, 0, 0] = 1.0  # read-only views of the file
        root = opened.nodes[0]
        assert opened.bounds == (tuple(root["min"].tolist()), tuple(root["max"].tolist()))
    assert "every rule" in bvhc.verify(bvh)
    with pytest.raises(bvhc.IoError):
        bvhc.open(tmp_path / "missing.bvh")
    data = bytearray(bvh.read_bytes())
    data[0] ^= 0xFF
    (tmp_path / "magic.bvh").write_bytes(bytes(data))
    with pytest.raises(bvhc.InvalidFileError, match="magic.bvh"):
        bvhc.open(tmp_path / "magic.bvh")
    data = bytearray(bvh.read_bytes())
    info = bvhc.open(bvh).info()
    nodes = next(s for s in info["sections"] if s["name"] == "nodes")
    data[nodes["byte_offset"] + 24 : nodes["byte_offset"] + 28] = (10**9).to_bytes(4, "little")  # a child index
    (tmp_path / "child.bvh").write_bytes(bytes(data))
    with pytest.raises(bvhc.InvalidFileError, match="child.bvh"):
        bvhc.open(tmp_path / "child.bvh")
    with pytest.raises(bvhc.InvalidFileError):
        bvhc.verify(tmp_path / "child.bvh")
    (tmp_path / "empty.bvh").write_bytes(b"")
    with pytest.raises(bvhc.InvalidFileError):
        bvhc.open(tmp_path / "empty.bvh")


def test_bad_rays_raise_naming_the_ray(tmp_path):
    bvh = tmp_path / "t.bvh"
    bvhc.convert(TEAPOT, bvh)
    opened = bvhc.open(bvh)
    origins = np.zeros((5, 3), dtype=np.float32)
    directions = np.ones((5, 3), dtype=np.float32)
    bad = origins.copy()
    bad[3, 1] = np.nan
    with pytest.raises(bvhc.InvalidInputError, match="ray 3: the origin is not finite"):
        opened.closest_hits(bad, directions)
    with pytest.raises(bvhc.InvalidInputError, match="ray 3"):
        opened.any_hits(bad, directions)
    zero = directions.copy()
    zero[1] = 0
    with pytest.raises(bvhc.InvalidInputError, match="ray 1: the direction"):
        opened.closest_hits(origins, zero)
    with pytest.raises(bvhc.InvalidInputError, match="ray 0: .*t_max"):
        opened.closest_hits(origins, directions, 2.0, 1.0)
    with pytest.raises(bvhc.InvalidInputError, match="ray 4"):
        opened.closest_hits(origins, directions, np.array([0, 0, 0, 0, -1.0]))
    with pytest.raises(bvhc.InvalidInputError, match="ray 2"):
        opened.closest_hits(origins, directions, 0.0, np.array([1, 1, np.nan, 1, 1], dtype=np.float32))
    with pytest.raises(bvhc.InvalidInputError, match=r"shape \[5, 2\]"):
        opened.closest_hits(origins[:, :2], directions)
    with pytest.raises(bvhc.InvalidInputError, match="5 origins but 4 directions"):
        opened.closest_hits(origins, directions[:4])
    with pytest.raises(bvhc.InvalidInputError, match="t_max: 3 values for 5 rays"):
        opened.closest_hits(origins, directions, 0.0, np.ones(3))
    with pytest.raises(bvhc.InvalidInputError, match="dtype float32 or float64"):
        opened.closest_hits(origins.astype(np.int32), directions)
    with pytest.raises(bvhc.InvalidInputError, match="threads"):
        opened.closest_hits(origins, directions, threads=0)
    assert opened.closest_hits(origins[:0], directions[:0])["t"].shape == (0,)


def test_spawned_rays_leave_their_triangle(tmp_path):
    bvh = tmp_path / "t.bvh"
    bvhc.convert(TEAPOT, bvh)
    opened = bvhc.open(bvh)
    origins, directions = random_rays(opened.bounds, 20_000, seed=11)
    hits = opened.closest_hits(origins, directions)
    hit = hits["triangle"] != bvhc.MISS
    kept = {k: v[hit] for k, v in hits.items()}
    # Away from the surface, on the side the ray came from.
    side = np.where(kept["front_face"], 1.0, -1.0)[:, None] * kept["normal"]
    o, d, lo, hi = opened.spawn(kept, side)
    again = opened.closest_hits(o, d, lo, hi)
    assert not np.any(again["source_id"] == kept["source_id"]), "a spawned ray met the triangle it left"
    with pytest.raises(bvhc.InvalidInputError, match="miss"):
        opened.spawn({k: v[~hit][:3] for k, v in hits.items()}, directions[~hit][:3])
    foreign = dict(kept)
    foreign["triangle"] = np.full(len(o), 10**8, dtype=np.uint32)
    with pytest.raises(bvhc.InvalidInputError, match="hit 0"):
        opened.spawn(foreign, side)
    # Barycentrics off the triangle or NaN, and directions with no side to leave by, are refused.
    for u, v in [(3.0, -2.5), (np.nan, 0.25)]:
        off = {k: val[:1].copy() for k, val in kept.items()}
        off["u"][:] = u
        off["v"][:] = v
        with pytest.raises(bvhc.InvalidInputError, match="not on its triangle"):
            opened.spawn(off, side[:1])
    one = {k: val[:1] for k, val in kept.items()}
    for direction, rule in [([np.nan, 0.0, 1.0], "not finite"), ([0.0, 0.0, 0.0], "zero")]:
        with pytest.raises(bvhc.InvalidInputError, match=rule):
            opened.spawn(one, np.array([direction], dtype=np.float32))


def test_opening_a_directory_says_so(tmp_path):
    with pytest.raises(bvhc.IoError, match="(?i)is a directory"):
        bvhc.open(tmp_path)


def test_repeated_opens_do_not_leak(tmp_path):
    bvh = tmp_path / "t.bvh"
    bvhc.convert(TEAPOT, bvh)
    origins, directions = random_rays(bvhc.open(bvh).bounds, 1000, seed=5)

    def resident_kib():
        with open("/proc/self/status") as status:
            return next(int(line.split()[1]) for line in status if line.startswith("VmRSS"))

    def fds():
        return len(os.listdir("/proc/self/fd"))

    def cycle(count):
        for _ in range(count):
            opened = bvhc.open(bvh)
            opened.closest_hits(origins, directions)
            opened.info()
            del opened
        gc.collect()

    cycle(200)
    before, before_fds = resident_kib(), fds()
    cycle(2000)
    assert fds() <= before_fds
    growth = resident_kib() - before
    assert growth < 20_000, f"resident memory grew by {growth} KiB over 2000 opens"


def sphere_scene(tmp_path, subdivisions=3):
    trimesh = pytest.importorskip("trimesh")
    mesh = trimesh.creation.icosphere(subdivisions=subdivisions)
    bvhc.build(mesh.vertices, mesh.faces, tmp_path / "sphere.bvh")
    return mesh, bvhc.open(tmp_path / "sphere.bvh")


def test_all_hits_are_every_crossing_nearest_first(tmp_path):
    bvh = tmp_path / "t.bvh"
    bvhc.convert(TEAPOT, bvh)
    opened = bvhc.open(bvh)
    origins, directions = random_rays(opened.bounds, 5_000, seed=21)
    every = opened.all_hits(origins, directions)
    closest = opened.closest_hits(origins, directions)
    n = len(origins)
    assert every["count"].shape == (n,) and np.array_equal(every["count"], every["found"])
    assert np.array_equal(np.bincount(every["ray"], minlength=n), every["count"])
    assert np.all(np.diff(every["ray"].astype(np.int64)) >= 0), "sorted by ray"
    same_ray = every["ray"][1:] == every["ray"][:-1]
    assert np.all(every["t"][1:][same_ray] >= every["t"][:-1][same_ray]), "nearest first"
    # The first hit of each ray is its closest hit; a ray with no hit has no closest hit.
    first = np.searchsorted(every["ray"], np.arange(n))
    hit = every["count"] > 0
    assert np.array_equal(hit, closest["triangle"] != bvhc.MISS)
    assert np.array_equal(every["t"][first[hit]], closest["t"][hit])
    assert every["count"].max() > 2, "rays through the teapot cross it several times"
    # The cap keeps the nearest.
    capped = opened.all_hits(origins, directions, max_hits=1)
    assert np.array_equal(capped["count"], np.minimum(every["count"], 1))
    assert np.array_equal(capped["found"], every["found"])
    assert np.array_equal(capped["t"], every["t"][first[hit]])
    with pytest.raises(bvhc.InvalidInputError, match="max_hits"):
        opened.all_hits(origins, directions, max_hits=0)


def test_rays_through_vertices_of_a_closed_mesh_cross_it_twice(tmp_path):
    mesh, opened = sphere_scene(tmp_path)
    # From outside, through the mesh's own vertices (a ray's first crossing there is shared by up to six
    # triangles, its second by as many) and through the middle of the sphere: in and out, once each.
    vertices = np.asarray(mesh.vertices, dtype=np.float32)
    origins = np.tile(np.array([[0.31, 0.2, 3.0]], dtype=np.float32), (len(vertices), 1))
    directions = (vertices - origins).astype(np.float32)
    every = opened.all_hits(origins, directions)
    across = np.einsum("ij,ij->i", directions, vertices) / np.linalg.norm(directions, axis=1) < -0.2
    assert across.sum() > 100
    assert np.all(every["count"][across] == 2), np.unique(every["count"][across], return_counts=True)
    in_and_out = np.zeros(len(origins), dtype=np.int64)
    np.add.at(in_and_out, every["ray"], np.where(every["front_face"], 1, -1))
    assert np.all(in_and_out == 0), "every ray from outside leaves as often as it enters"
    try:  # trimesh's ray queries need rtree or embreex, which the test environment need not have
        _, index_ray, _ = mesh.ray.intersects_location(origins[across], directions[across], multiple_hits=True)
    except ImportError:
        return
    peer = np.bincount(index_ray, minlength=int(across.sum()))
    print(f"\nrays through vertices: bvhc 2 crossings on all {across.sum()}; trimesh's counts {np.bincount(peer)}")


def test_contains_is_the_inside_of_closed_meshes(tmp_path):
    mesh, opened = sphere_scene(tmp_path)
    rng = np.random.default_rng(3)
    points = rng.uniform(-1.3, 1.3, (20_000, 3))
    radius = np.linalg.norm(points, axis=1)
    clear = (radius < 0.98) | (radius > 1.001)  # the facets lie between radius 0.98 and 1
    inside = opened.contains(points)
    assert inside.dtype == bool and inside.shape == (len(points),)
    assert np.array_equal(inside[clear], radius[clear] < 0.98)
    # Turned inside out (the other winding), the same answer.
    bvhc.build(mesh.vertices, mesh.faces[:, ::-1], tmp_path / "flipped.bvh")
    assert np.array_equal(bvhc.open(tmp_path / "flipped.bvh").contains(points)[clear], radius[clear] < 0.98)
    # On its vertices: on the surface, inside.
    assert opened.contains(np.asarray(mesh.vertices)).all()
    assert np.array_equal(opened.contains(points, threads=1), inside)
    with pytest.raises(bvhc.InvalidInputError, match="point 1"):
        opened.contains(np.array([[0, 0, 0], [np.nan, 0, 0]]))
    try:  # as above
        assert np.array_equal(mesh.contains(points[clear]), inside[clear])
    except ImportError:
        pass


def test_cutouts_and_filters_leave_out_what_they_reject(tmp_path):
    bvh = tmp_path / "t.bvh"
    bvhc.convert(TEAPOT, bvh)
    opened = bvhc.open(bvh)
    origins, directions = random_rays(opened.bounds, 20_000, seed=31)
    plain = opened.closest_hits(origins, directions)
    count = opened.source_id_count
    assert count == len(opened.triangles) or count > 0
    cut = np.zeros(count, dtype=bool)
    cut[::3] = True
    masked = opened.closest_hits(origins, directions, cutout=cut)
    hit = masked["triangle"] != bvhc.MISS
    assert not cut[masked["source_id"][hit]].any(), "no hit on a cut-out triangle"
    assert np.all(masked["t"][hit] >= plain["t"][hit]), "a cut-out only removes hits"
    changed = (plain["triangle"] != bvhc.MISS) & cut[np.where(plain["triangle"] != bvhc.MISS, plain["source_id"], 0)]
    assert changed.sum() > 100
    # The same cut-out as a callback: the same hits, on one thread.
    asked = []

    def keep(ray, t, u, v, triangle, source_id, instance):
        asked.append(ray)
        return not cut[source_id]

    called = opened.closest_hits(origins, directions, filter=keep)
    for key in ("t", "triangle", "u", "v"):
        assert np.array_equal(called[key], masked[key]), key
    assert len(asked) > 1000 and max(asked) < len(origins)
    assert np.array_equal(opened.any_hits(origins, directions, cutout=cut), hit)
    assert np.array_equal(opened.any_hits(origins, directions, filter=keep), hit)
    every = opened.all_hits(origins, directions, cutout=cut)
    assert not cut[every["source_id"]].any()
    again = opened.all_hits(origins, directions, filter=keep)
    assert np.array_equal(again["t"], every["t"]) and np.array_equal(again["ray"], every["ray"])
    # By primitive: the source table's ranges name them; cutting every one leaves nothing.
    ranges = opened.source_ranges
    assert ranges is not None and len(ranges) >= 1
    everything = [(int(r["mesh_index"]), int(r["primitive_index"])) for r in ranges]
    assert not opened.any_hits(origins, directions, cutout_primitives=everything).any()
    # A file's flags: the teapot has none, so with "not_opaque" the filter is never asked.
    assert np.array_equal(opened.closest_hits(origins, directions, filter=keep, filter_scope="not_opaque")["t"], plain["t"])


def test_filter_errors_are_named(tmp_path):
    bvh = tmp_path / "t.bvh"
    bvhc.convert(TEAPOT, bvh)
    opened = bvhc.open(bvh)
    origins, directions = random_rays(opened.bounds, 1_000, seed=41)
    with pytest.raises(bvhc.InvalidInputError, match="cutout: 3 values"):
        opened.closest_hits(origins, directions, cutout=np.zeros(3, dtype=bool))
    with pytest.raises(bvhc.InvalidInputError, match="dtype bool"):
        opened.closest_hits(origins, directions, cutout=np.zeros(opened.source_id_count))
    with pytest.raises(bvhc.InvalidInputError, match="filter_scope"):
        opened.closest_hits(origins, directions, filter=lambda *a: True, filter_scope="some")
    with pytest.raises(bvhc.InvalidInputError, match="callable"):
        opened.any_hits(origins, directions, filter=3)

    def fails(*candidate):
        raise ValueError("the filter's own error")

    with pytest.raises(ValueError, match="the filter's own error"):
        opened.closest_hits(origins, directions, filter=fails)
    with pytest.raises(ValueError, match="the filter's own error"):
        opened.all_hits(origins, directions, filter=fails)


def obj_vertices(path):
    return np.array(
        [[float(c) for c in line.split()[1:4]] for line in path.read_text().splitlines() if line.startswith("v ")],
        dtype=np.float32,
    )


def bend(vertices):
    x, y, z = vertices[:, 0], vertices[:, 1], vertices[:, 2]
    return np.stack([x + np.float32(0.2) * y * y, y, z + np.float32(0.1) * x * y], axis=1).astype(np.float32)


def test_refit_in_place_equals_bvhc_refit_of_the_moved_asset(tmp_path):
    bvh = tmp_path / "t.bvh"
    cli(TEAPOT, "--no-splits", "-o", bvh, "-q")
    # The moved asset: every `v` line bent (floats written exactly), the faces untouched.
    bent = bend(obj_vertices(TEAPOT))
    lines, k = [], 0
    for line in TEAPOT.read_text().splitlines():
        if line.startswith("v "):
            lines.append("v " + " ".join("%.9g" % c for c in bent[k]))
            k += 1
        else:
            lines.append(line)
    moved = tmp_path / "moved.obj"
    moved.write_text("\n".join(lines) + "\n")
    cli("refit", bvh, "--positions", moved, "-o", tmp_path / "cli.bvh")
    scene = bvhc.open(bvh, writable=True)
    before = np.array(scene.triangles)
    report = scene.refit(source_vertices=[bent], threads=2)
    assert report["cost_ratio"] > 1.0 and report["wide_cost"] is not None and not report["rebuild_recommended"]
    assert report["planned_cost_ratio"] is None, "converted without animation=True"
    scene.write(tmp_path / "py.bvh")
    # The same sections; the command line's metadata also records the asset it took the positions from, which
    # a refit from the program's own positions cannot know.
    py_file, cli_file = bvhc.open(tmp_path / "py.bvh"), bvhc.open(tmp_path / "cli.bvh")
    names = [entry["name"] for entry in cli_file.info()["sections"]]
    assert names == [entry["name"] for entry in py_file.info()["sections"]]
    for name in (n for n in names if n != "metadata"):
        assert np.array_equal(py_file.section(name), cli_file.section(name)), name
    cli_metadata = cli_file.info()["metadata"]
    assert cli_metadata.pop("refit")["inputs"][0]["file_name"] == "moved.obj"
    assert py_file.info()["metadata"] == cli_metadata
    assert "every rule" in bvhc.verify(tmp_path / "py.bvh")
    assert bvh.read_bytes() == bvhc.open(bvh)._native.data.tobytes(), "the file on disk never changes"
    # The views show the new records; per record, the same positions give the same bytes back.
    records = np.array(scene.triangles)
    assert not np.array_equal(records, before)
    again = scene.refit(records, threads=1)
    assert again["cost_ratio"] == report["cost_ratio"]
    # Hits follow the records.
    origins = np.array([[0.0, 1.0, 8.0]] * 3, dtype=np.float32) + np.array([[0, 0, 0], [0.5, 0, 0], [-0.5, 0.3, 0]])
    directions = np.tile(np.array([[0.0, 0.0, -1.0]], dtype=np.float32), (3, 1))
    hits = scene.closest_hits(origins, directions, np.zeros(3), np.full(3, np.inf))
    moved_scene = bvhc.open(tmp_path / "cli.bvh")
    expected = moved_scene.closest_hits(origins, directions, np.zeros(3), np.full(3, np.inf))
    assert np.array_equal(hits["t"], expected["t"]) and np.array_equal(hits["triangle"], expected["triangle"])


def test_pose_from_the_asset_equals_bvhc_refit(tmp_path):
    truck = scene("khr-cesium-milk-truck/CesiumMilkTruck.gltf")
    for instancing in ["always", "never"]:
        bvh = tmp_path / f"truck-{instancing}.bvh"
        cli(truck, "--animation", "--instancing", instancing, "-o", bvh, "-q")
        cli("refit", bvh, "--positions", truck, "--pose", "Wheels@0.6", "-o", tmp_path / "cli.bvh")
        posed = bvhc.open(bvh, writable=True)
        report = posed.pose(truck, "Wheels@0.6", threads=2)
        # Two-level: the wheels are moving instances; one level: they are refit with the rest.
        assert report["instances_placed"] == (2 if instancing == "always" else 0)
        posed.write(tmp_path / "py.bvh")
        assert (tmp_path / "py.bvh").read_bytes() == (tmp_path / "cli.bvh").read_bytes(), instancing
        # The metadata says which pose the records hold; `inputs` is still the conversion's.
        record = bvhc.open(tmp_path / "py.bvh").info()["metadata"]["refit"]
        assert record["pose"] == {"clip": {"name": "Wheels"}, "seconds": 0.6}
        assert record["inputs"] == bvhc.open(bvh).info()["metadata"]["inputs"]
        # Posed back to the default pose, the records are the file's own again, and so are its bytes.
        posed.pose(truck)
        assert np.array_equal(np.array(posed.triangles), np.array(bvhc.open(bvh).triangles))
        posed.write(tmp_path / "back.bvh")
        assert (tmp_path / "back.bvh").read_bytes() == bvh.read_bytes(), instancing
        # A refit from the program's own positions after a pose: the pose is no longer what the records hold.
        posed.pose(truck, "Wheels@0.6")
        posed.refit(np.array(posed.triangles))
        posed.write(tmp_path / "own.bvh")
        assert "refit" not in bvhc.open(tmp_path / "own.bvh").info()["metadata"]
    with pytest.raises(bvhc.InvalidInputError, match="Fly"):
        posed.pose(truck, "Fly@1")
    with pytest.raises(bvhc.InvalidInputError, match="pose: 'Wheels' is not CLIP@SECONDS"):
        posed.pose(truck, "Wheels")
    with pytest.raises(bvhc.IoError, match="missing.gltf"):
        posed.pose(tmp_path / "missing.gltf")
    with pytest.raises(bvhc.InvalidInputError, match="writable=True"):
        bvhc.open(bvh).pose(truck, "Wheels@0.6")


def test_a_frame_refits_one_mesh_and_moves_instances_without_hashing(tmp_path):
    # The milk truck's body flattened into mesh 0, its wheels moving instances of a shared mesh.
    truck = scene("khr-cesium-milk-truck/CesiumMilkTruck.gltf")
    bvh = tmp_path / "truck.bvh"
    cli(truck, "--animation", "--instancing", "always", "-o", bvh, "-q")
    whole, frame = bvhc.open(bvh, writable=True), bvhc.open(bvh, writable=True)
    # Mesh 0 (the flattened body) lifted in its own space, and instance 1 (a wheel) carried forward.
    records = np.array(whole.triangles)
    meshes = whole.meshes
    first, count = int(meshes["first_triangle"][0]), int(meshes["triangle_count"][0])
    lifted = records.copy()
    lifted[first : first + count, :, 1] += np.float32(0.25)
    transform = np.array(whole.instances["object_to_world"][1:2], dtype=np.float32)
    transform[0, 0, 3] += np.float32(0.5)
    whole.refit(lifted, threads=2)
    whole.move_instances([1], transform)
    frame.refit_mesh(0, lifted[first : first + count], threads=2)
    frame.move_instances_in_frame([1], transform)
    with pytest.raises(bvhc.InvalidFileError):
        frame.verify()  # the checksums wait for write
    whole.write(tmp_path / "whole.bvh")
    frame.write(tmp_path / "frame.bvh")
    assert (tmp_path / "frame.bvh").read_bytes() == (tmp_path / "whole.bvh").read_bytes()
    assert np.array_equal(np.array(frame.triangles), lifted)
    with pytest.raises(bvhc.InvalidInputError, match=f"mesh {len(meshes)}: the file has {len(meshes)} meshes"):
        frame.refit_mesh(len(meshes), lifted[first : first + count])
    with pytest.raises(bvhc.InvalidInputError, match="mesh 0: 1 positions for"):
        frame.refit_mesh(0, lifted[first : first + 1])
    with pytest.raises(bvhc.InvalidInputError, match="move_instances_in_frame: 1 transforms for 2 instances"):
        frame.move_instances_in_frame([0, 1], transform)
    flat = tmp_path / "flat.bvh"
    cli(TEAPOT, "--no-splits", "-o", flat, "-q")
    with pytest.raises(bvhc.InvalidInputError, match="one-level file has no meshes"):
        bvhc.open(flat, writable=True).refit_mesh(0, np.zeros((1, 3, 3), dtype=np.float32))


def test_refit_refuses_what_does_not_fit(tmp_path):
    bvh = tmp_path / "t.bvh"
    cli(TEAPOT, "--no-splits", "-o", bvh, "-q")
    with pytest.raises(bvhc.InvalidInputError, match="writable=True"):
        bvhc.open(bvh).refit(np.zeros((1, 3, 3), dtype=np.float32))
    for mmap in [True, False]:
        scene = bvhc.open(bvh, writable=True, mmap=mmap)
        records = np.array(scene.triangles)
        with pytest.raises(bvhc.InvalidInputError, match="positions for"):
            scene.refit(records[1:])
        records[5, 1, 2] = np.nan
        with pytest.raises(bvhc.InvalidInputError, match="triangle record 5"):
            scene.refit(records)
        with pytest.raises(bvhc.InvalidInputError, match="shape"):
            scene.refit(np.zeros((4, 9), dtype=np.float32))
        with pytest.raises(bvhc.InvalidInputError, match="vertex 0"):
            scene.refit(source_vertices=[np.full((3000, 3), np.inf, dtype=np.float32)])
        with pytest.raises(bvhc.InvalidInputError, match="one-level file has no instances"):
            scene.move_instances([0], np.zeros((1, 3, 4), dtype=np.float32))
        # The command line's refusals: --max-cost-ratio below 1, --threads outside 1..1024, neither input.
        with pytest.raises(bvhc.OptionsError, match="max_cost_ratio -1: a finite ratio of at least 1"):
            scene.refit(records, max_cost_ratio=-1)
        for bad in [0, 5000]:
            with pytest.raises(bvhc.OptionsError, match=f"threads {bad}: expected 1 to 1024"):
                scene.refit(records, threads=bad)
            with pytest.raises(bvhc.OptionsError, match=f"threads {bad}"):
                scene.pose(TEAPOT, threads=bad)
        with pytest.raises(bvhc.OptionsError, match="give positions or source_vertices$"):
            scene.refit()
        with pytest.raises(bvhc.OptionsError, match="not both"):
            scene.refit(records, source_vertices=[None])
        assert scene._native.data.tobytes() == bvh.read_bytes(), "a refused call changes nothing"
    with pytest.raises(bvhc.OptionsError, match="threads 0"):
        bvhc.convert(TEAPOT, tmp_path / "zero.bvh", threads=0)
    # A scene posed from an asset never writes over it (nor over a buffer it read).
    asset = tmp_path / "asset.obj"
    asset.write_bytes(TEAPOT.read_bytes())
    cli(asset, "--no-splits", "-o", tmp_path / "asset.bvh", "-q")
    posed = bvhc.open(tmp_path / "asset.bvh", writable=True)
    posed.pose(asset)
    with pytest.raises(bvhc.IoError, match="the output is one of the inputs"):
        posed.write(asset)
    assert asset.read_bytes() == TEAPOT.read_bytes()


def nan_keyframes_gltf(path):
    """One triangle whose translation clip has keyframe times [NaN, 0.5, NaN] (a panic before bvhc 0.1's fix)."""
    import base64
    import struct

    data = struct.pack("<9f", 0, 0, 0, 1, 0, 0, 0, 1, 0) + struct.pack("<3f", float("nan"), 0.5, float("nan"))
    data += struct.pack("<9f", *([0.0] * 9))
    gltf = {
        "asset": {"version": "2.0"},
        "buffers": [{"byteLength": len(data), "uri": "data:;base64," + base64.b64encode(data).decode()}],
        "bufferViews": [
            {"buffer": 0, "byteOffset": 0, "byteLength": 36},
            {"buffer": 0, "byteOffset": 36, "byteLength": 12},
            {"buffer": 0, "byteOffset": 48, "byteLength": 36},
        ],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3", "min": [0, 0, 0], "max": [1, 1, 0]},
            {"bufferView": 1, "componentType": 5126, "count": 3, "type": "SCALAR"},
            {"bufferView": 2, "componentType": 5126, "count": 3, "type": "VEC3"},
        ],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}}]}],
        "nodes": [{"mesh": 0}],
        "scenes": [{"nodes": [0]}],
        "scene": 0,
        "animations": [{"channels": [{"sampler": 0, "target": {"node": 0, "path": "translation"}}],
                        "samplers": [{"input": 1, "output": 2}]}],
    }
    path.write_text(json.dumps(gltf))
    return path


def test_a_broken_clip_is_an_error_not_a_panic(tmp_path):
    asset = nan_keyframes_gltf(tmp_path / "nan.gltf")
    message = "animation 0 sampler 0 input accessor 1: keyframe time 0 is NaN"
    with pytest.raises(bvhc.InvalidInputError, match=message):
        bvhc.convert(asset, tmp_path / "posed.bvh", pose="0@0")
    with pytest.raises(bvhc.InvalidInputError, match=message):
        bvhc.convert(asset, tmp_path / "animated.bvh", animation=True)
    # The default pose reads no keyframe: it converts; posing that file from the asset is refused the same way.
    bvhc.convert(asset, tmp_path / "rest.bvh", splits=False)
    scene = bvhc.open(tmp_path / "rest.bvh", writable=True)
    try:
        scene.pose(asset, "0@0")
    except Exception as error:  # what a caller catches: an Exception, never a PanicException
        assert isinstance(error, bvhc.InvalidInputError) and message in str(error), error
    else:
        raise AssertionError("posed from a clip with NaN keyframe times")


def test_moved_instances_and_meshes_trace_where_they_stand(tmp_path):
    # One mesh (two triangles) placed twice by glTF nodes, converted two-level.
    positions = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], dtype=np.float32)
    indices = np.array([0, 1, 2, 0, 2, 3], dtype=np.uint16)
    (tmp_path / "quad.bin").write_bytes(positions.tobytes() + indices.tobytes())
    gltf = {
        "asset": {"version": "2.0"},
        "scene": 0,
        "scenes": [{"nodes": [0, 1]}],
        "nodes": [{"mesh": 0}, {"mesh": 0, "translation": [3.0, 0.0, 0.0]}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1}]}],
        "buffers": [{"uri": "quad.bin", "byteLength": 60}],
        "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 48}, {"buffer": 0, "byteOffset": 48, "byteLength": 12}],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3", "min": [0, 0, 0], "max": [1, 1, 0]},
            {"bufferView": 1, "componentType": 5123, "count": 6, "type": "SCALAR"},
        ],
    }
    (tmp_path / "quads.gltf").write_text(json.dumps(gltf))
    bvh = tmp_path / "quads.bvh"
    cli(tmp_path / "quads.gltf", "--instancing", "always", "-o", bvh, "-q")
    scene = bvhc.open(bvh, writable=True)
    assert scene.instances is not None and len(scene.instances) == 2
    # Instance 1 carried from x = 3 to x = 10 and lifted by 2 in z.
    transform = np.array([[[1, 0, 0, 10], [0, 1, 0, 0], [0, 0, 1, 2]]], dtype=np.float32)
    scene.move_instances([1], transform)
    assert scene.instances["object_to_world"][1].tolist() == transform[0].tolist()
    scene.verify()
    origins = np.array([[10.5, 0.5, 5.0], [3.5, 0.5, 5.0]], dtype=np.float32)
    directions = np.array([[0, 0, -1], [0, 0, -1]], dtype=np.float32)
    hits = scene.closest_hits(origins, directions, np.zeros(2), np.full(2, np.inf))
    assert hits["instance"].tolist() == [1, bvhc.MISS]
    assert hits["t"][0] == np.float32(3.0)
    with pytest.raises(bvhc.InvalidInputError, match="instance 2"):
        scene.move_instances([2], transform)
    # The mesh itself lifted by 1 in its own space: both instances follow it.
    lifted = scene.triangles.copy()
    lifted[:, :, 2] += 1.0
    report = scene.refit(lifted, threads=2)
    assert report["cost"] is None and report["cost_ratio"] == 1.0, "a two-level file states no costs"
    scene.write(tmp_path / "lifted.bvh")
    bvhc.verify(tmp_path / "lifted.bvh")
    origins = np.array([[10.5, 0.5, 5.0], [0.5, 0.5, 5.0]], dtype=np.float32)
    hits = scene.closest_hits(origins, directions, np.zeros(2), np.full(2, np.inf))
    assert hits["instance"].tolist() == [1, 0]
    assert hits["t"].tolist() == [2.0, 4.0]
    # The top trees built anew over the instances where they now stand: the same hits, a cost no higher.
    rebuilt = scene.rebuilt_top_trees()
    assert rebuilt.top_tree_cost <= scene.top_tree_cost
    rebuilt.verify()
    again = rebuilt.closest_hits(origins, directions, np.zeros(2), np.full(2, np.inf))
    assert again["instance"].tolist() == [1, 0] and again["t"].tolist() == [2.0, 4.0]
    one_level = tmp_path / "flat.bvh"
    cli(tmp_path / "quads.gltf", "--instancing", "never", "-o", one_level, "-q")
    flat = bvhc.open(one_level)
    assert flat.top_tree_cost is None
    with pytest.raises(bvhc.InvalidInputError, match="one-level file has no top tree"):
        flat.rebuilt_top_trees()


def test_pose_is_the_command_lines_flag():
    resolved = bvhc.options(pose="Run@0.5")
    printed = json.loads(cli("options", "--pose", "Run@0.5"))
    assert resolved == printed and resolved["import"]["pose"] == {"clip": {"name": "Run"}, "seconds": 0.5}
    with pytest.raises(bvhc.OptionsError, match="CLIP@SECONDS"):
        bvhc.options(pose="Run")


def test_splits_deforming_is_the_command_lines_flag():
    resolved = bvhc.options(splits_deforming=False)
    printed = json.loads(cli("options", "--no-splits-deforming"))
    assert resolved == printed and resolved["splits"]["deforming"] is False
    with pytest.raises(bvhc.OptionsError, match="no-splits-deforming"):
        bvhc.options(splits=False, splits_deforming=False)


def test_animation_is_the_command_lines_flag():
    assert bvhc.options(animation=True) == json.loads(cli("options", "--animation"))
    resolved = bvhc.options(animation="0,Run", animation_poses=4)
    printed = json.loads(cli("options", "--animation", "0,Run", "--animation-poses", "4"))
    assert resolved == printed
    assert resolved["animation"] == {"clips": [{"index": 0}, {"name": "Run"}], "poses_per_clip": 4}
    # The default instancing (auto, left out) flattens rigid motion; "always" keeps it instanced.
    assert "splits" not in resolved and "instancing" not in resolved
    rigid = bvhc.options(animation=True, instancing="always")
    assert rigid == json.loads(cli("options", "--animation", "--instancing", "always"))
    assert rigid["instancing"] == "always"
    assert "animation" not in bvhc.options(animation=False)
    with pytest.raises(bvhc.OptionsError, match="needs --animation"):
        bvhc.options(animation_poses=4)
    # A part of each clip, as --animation-window says it.
    part = bvhc.options(animation=True, animation_window="2.5..5")
    assert part == json.loads(cli("options", "--animation", "--animation-window", "2.5..5"))
    assert part["animation"]["window"] == {"start": 2.5, "end": 5.0}
    with pytest.raises(bvhc.OptionsError, match="ends before it starts"):
        bvhc.options(animation=True, animation_window="5..2.5")
    with pytest.raises(bvhc.OptionsError, match="--animation-window: needs --animation"):
        bvhc.options(animation_window="0..1")
    with pytest.raises(bvhc.OptionsError, match="--split-budget does nothing with --animation"):
        bvhc.options(animation=True, split_budget=0.2)
    with pytest.raises(bvhc.OptionsError, match="an empty clip name"):
        bvhc.options(animation="0,,1")


def point_triangle_distances(p, tris):
    """Distance from the point p to each triangle of tris ((m, 3, 3), float64), by Ericson's Voronoi regions
    (Real-Time Collision Detection, 5.1.5) vectorized: an arithmetic independent of bvhc's."""
    a, b, c = tris[:, 0], tris[:, 1], tris[:, 2]

    def seg(x, y):
        d = y - x
        dd = np.einsum("ij,ij->i", d, d)
        t = np.where(dd > 0, np.einsum("ij,ij->i", p - x, d) / np.where(dd > 0, dd, 1), 0).clip(0, 1)
        return np.linalg.norm(p - (x + d * t[:, None]), axis=1)

    edges = np.minimum(np.minimum(seg(a, b), seg(b, c)), seg(c, a))
    n = np.cross(b - a, c - a)
    nn = np.einsum("ij,ij->i", n, n)
    w = [np.einsum("ij,ij->i", np.cross(y - x, p - x), n) for x, y in ((b, c), (c, a), (a, b))]
    inside = (nn > 0) & (w[0] >= 0) & (w[1] >= 0) & (w[2] >= 0)
    plane = np.abs(np.einsum("ij,ij->i", p - a, n)) / np.sqrt(np.where(nn > 0, nn, 1))
    return np.where(inside, np.minimum(plane, edges), edges)


def test_closest_points_are_the_nearest_on_the_surface(tmp_path):
    bvh = tmp_path / "t.bvh"
    bvhc.convert(TEAPOT, bvh)
    opened = bvhc.open(bvh)
    tris = opened.triangles.astype(np.float64)
    rng = np.random.default_rng(31)
    lo, hi = (np.asarray(b, dtype=np.float64) for b in opened.bounds)
    size = (hi - lo).max()
    on = tris[rng.integers(0, len(tris), 300)].mean(axis=1)
    points = np.concatenate(
        [
            rng.uniform(lo - size, hi + size, (300, 3)),  # around and far
            on + rng.normal(scale=1e-3 * size, size=on.shape),  # near the surface
            tris[rng.integers(0, len(tris), 100), 0],  # on vertices
        ]
    ).astype(np.float32)
    found = opened.closest_points(points)
    assert set(found) == {"point", "distance", "triangle", "source_id", "u", "v", "instance"}
    assert found["point"].shape == (len(points), 3) and found["distance"].dtype == np.float32
    assert (found["instance"] == bvhc.MISS).all()
    for k, p in enumerate(points.astype(np.float64)):
        d = point_triangle_distances(p, tris)
        exact = d.min()
        assert abs(found["distance"][k] - exact) <= exact * 2.0**-24 + 2.0**-40 * (size + np.abs(p).max()) * 4, k
        # The named triangle is at that distance, and the point lies on it at u, v, at that distance from p.
        t = found["triangle"][k]
        assert abs(d[t] - exact) <= 1e-6 * size, k
        u, v = found["u"][k], found["v"][k]
        on_triangle = tris[t, 0] * (1 - u - v) + tris[t, 1] * u + tris[t, 2] * v
        assert np.abs(on_triangle - found["point"][k]).max() <= 1e-5 * size, k
        assert abs(np.linalg.norm(found["point"][k] - p) - found["distance"][k]) <= 1e-5 * size, k
    assert np.array_equal(opened.distance(points), found["distance"])
    one = opened.closest_points(points, threads=1)
    assert all(np.array_equal(one[key], found[key], equal_nan=True) for key in found)
    # A bound: what lies beyond it gets the miss markers; the bound is inclusive.
    bound = float(np.median(found["distance"]))
    near = opened.closest_points(points, max_distance=bound)
    within, beyond = found["distance"] < bound, found["distance"] > bound
    assert within.sum() > 100 and beyond.sum() > 100
    assert np.array_equal(near["triangle"][within], found["triangle"][within])
    assert (near["triangle"][beyond] == bvhc.MISS).all() and np.isinf(near["distance"][beyond]).all()
    assert np.isnan(near["point"][beyond]).all()
    with pytest.raises(bvhc.InvalidInputError, match="point 1"):
        opened.closest_points(np.array([[0, 0, 0], [np.nan, 0, 0]]))
    with pytest.raises(bvhc.InvalidInputError, match="max_distance"):
        opened.closest_points(points, max_distance=-1.0)
    # A peer's answer, where it is installed: trimesh's closest points on the same triangles.
    try:
        import trimesh

        mesh = trimesh.Trimesh(tris.reshape(-1, 3), np.arange(3 * len(tris)).reshape(-1, 3), process=False)
        _, peer_distance, _ = trimesh.proximity.closest_point(mesh, points[:200].astype(np.float64))
        assert np.allclose(found["distance"][:200], peer_distance, rtol=1e-5, atol=1e-6 * size)
    except ImportError:
        pass


def test_winding_moments_kept_between_calls_follow_a_refit(tmp_path):
    mesh, _ = sphere_scene(tmp_path)
    opened = bvhc.open(tmp_path / "sphere.bvh", writable=True)
    points = np.array([[0.0, 0.0, 0.0], [3.0, 0.0, 0.0], [1.5, 0.0, 0.0]], dtype=np.float32)
    first = opened.signed_distance(points)
    assert np.array_equal(opened.signed_distance(points), first), "the kept moments answer the same"
    assert first[0] < 0 < first[1] and first[2] > 0
    # Moved by 3 along x: the kept moments are of other bytes now and must not be used.
    moved = np.array(opened.triangles, dtype=np.float32) + np.array([3.0, 0.0, 0.0], dtype=np.float32)
    opened.refit(np.ascontiguousarray(moved))
    after = opened.signed_distance(points)
    assert after[0] > 0 > after[1], after
    opened.write(tmp_path / "moved.bvh")
    fresh = bvhc.open(tmp_path / "moved.bvh")
    assert np.array_equal(after, fresh.signed_distance(points))
    assert np.array_equal(opened.winding_number(points), fresh.winding_number(points))


def test_closest_points_among_the_triangles_the_cutout_keeps(tmp_path):
    bvh = tmp_path / "t.bvh"
    bvhc.convert(TEAPOT, bvh)  # spatial splits: several records of one triangle share its source id
    opened = bvhc.open(bvh)
    ids, records = np.asarray(opened.triangle_ids), np.asarray(opened.triangles, dtype=np.float32)
    cut = np.zeros(opened.source_id_count, dtype=bool)
    cut[::3] = True
    # The oracle: a file of the kept triangles alone, whose distances come from the same arithmetic.
    kept = np.unique(records[~cut[ids]].reshape(-1, 9), axis=0).reshape(-1, 3, 3)
    bvhc.build(kept.reshape(-1, 3), np.arange(3 * len(kept)).reshape(-1, 3), tmp_path / "kept.bvh")
    alone = bvhc.open(tmp_path / "kept.bvh")
    lo, hi = (np.asarray(b, dtype=np.float64) for b in opened.bounds)
    points = np.random.default_rng(35).uniform(lo - 0.2 * (hi - lo), hi, (3000, 3)).astype(np.float32)
    found = opened.closest_points(points, cutout=cut)
    assert not cut[found["source_id"]].any(), "no answer lies on a cut-out triangle"
    assert np.array_equal(found["distance"], alone.distance(points))
    assert np.array_equal(opened.distance(points, cutout=cut, threads=1), found["distance"])
    whole = opened.closest_points(points)
    assert (found["distance"] >= whole["distance"]).all() and (found["distance"] > whole["distance"]).any()
    nothing = np.zeros_like(cut)
    assert all(np.array_equal(opened.closest_points(points, cutout=nothing)[k], whole[k]) for k in whole)
    with pytest.raises(bvhc.InvalidInputError, match="cutout"):
        opened.closest_points(points, cutout=cut[:-1])


def test_closest_points_through_instances_are_in_world_space(tmp_path):
    engine = scene("khr-2cylinder-engine/2CylinderEngine.gltf")
    flat, placed = tmp_path / "flat.bvh", tmp_path / "placed.bvh"
    bvhc.convert(engine, flat, instancing="never")
    bvhc.convert(engine, placed, instancing="always")
    one, two = bvhc.open(flat), bvhc.open(placed)
    assert two.instances is not None and one.instances is None
    rng = np.random.default_rng(32)
    lo, hi = (np.asarray(b, dtype=np.float64) for b in one.bounds)
    points = rng.uniform(lo, hi, (2000, 3)).astype(np.float32)
    a, b = one.closest_points(points), two.closest_points(points)
    # The same surface, placed by instances or flattened: the same distances up to the world vertices'
    # rounding (the flat file stores them in float32).
    size = (hi - lo).max()
    assert np.allclose(a["distance"], b["distance"], rtol=0, atol=1e-5 * size)
    assert (b["instance"] != bvhc.MISS).all() and (a["instance"] == bvhc.MISS).all()


def test_signed_distance_and_winding_number_of_a_closed_mesh(tmp_path):
    mesh, opened = sphere_scene(tmp_path)
    rng = np.random.default_rng(33)
    points = rng.uniform(-1.3, 1.3, (20_000, 3)).astype(np.float32)
    radius = np.linalg.norm(points, axis=1)
    clear = (radius < 0.98) | (radius > 1.001)  # the facets lie between radius 0.98 and 1
    signed = opened.signed_distance(points)
    assert signed.dtype == np.float32 and signed.shape == (len(points),)
    assert np.array_equal(np.abs(signed), opened.distance(points))
    assert np.array_equal((signed < 0)[clear], (radius < 0.98)[clear])
    winding = opened.winding_number(points)
    assert winding.dtype == np.float64
    assert np.abs(winding[clear] - (radius[clear] < 0.98)).max() < 0.06
    # The other winding: the winding number changes sign, the signed distance does not.
    bvhc.build(mesh.vertices, mesh.faces[:, ::-1], tmp_path / "flipped.bvh")
    flipped = bvhc.open(tmp_path / "flipped.bvh")
    assert np.array_equal(flipped.signed_distance(points), signed)
    assert np.abs(flipped.winding_number(points[clear]) + winding[clear]).max() < 1e-9
    assert np.array_equal(opened.signed_distance(points, threads=1), signed)
    with pytest.raises(bvhc.InvalidInputError, match="point 1"):
        opened.signed_distance(np.array([[0, 0, 0], [np.nan, 0, 0]]))
    try:  # Open3D's signed distance, where installed: the same magnitudes and, clear of the surface, signs
        import open3d as o3d

        scene = o3d.t.geometry.RaycastingScene()
        scene.add_triangles(o3d.core.Tensor(np.asarray(mesh.vertices, dtype=np.float32)),
                            o3d.core.Tensor(np.asarray(mesh.faces, dtype=np.uint32)))
        peer = scene.compute_signed_distance(o3d.core.Tensor(points)).numpy()
        assert np.allclose(np.abs(peer), np.abs(signed), atol=1e-5)
        assert np.array_equal((peer < 0)[clear], (signed < 0)[clear])
    except ImportError:
        pass
