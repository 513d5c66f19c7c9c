"""bvhc: convert scenes into optimized, memory-mappable ``.bvh`` files, open them and trace numpy rays.

>>> import bvhc, numpy as np
>>> bvhc.convert("teapot.obj", "teapot.bvh")                       # doctest: +SKIP
>>> scene = bvhc.open("teapot.bvh")                                  # doctest: +SKIP
>>> hits = scene.closest_hits(origins, directions)                  # doctest: +SKIP
>>> depth = np.where(hits["triangle"] != bvhc.MISS, hits["t"], np.inf)  # doctest: +SKIP

Conversions take the options of one table as keywords (:func:`options_table`: the command line's flags with
``_`` for ``-``, ``split_method="pre-split"``, ``no_splits=True``; a ``no_*`` switch also by its positive name,
``splits=False``), resolved and refused exactly as ``bvhc`` resolves and refuses its flags, and skip an output
that is up to date; :func:`convert_many` converts a library on any executor (a process pool, a Dask cluster).
Tracing runs the loader's kernels on all cores with the GIL released.
Errors are :class:`Error` subclasses carrying the command line's messages.
"""

from __future__ import annotations

import builtins
import json
import os
import tempfile
from typing import Any, Callable, Dict, Iterator, List, Optional, Tuple, Union

import numpy as np

from . import _native
from .many import convert_many, options_table, run_job, run_jobs
from ._native import (
    Error,
    InternalError,
    InvalidFileError,
    InvalidInputError,
    IoError,
    OptionsError,
    OutOfMemoryError,
)

__all__ = [
    "MISS",
    "FORMAT_VERSION",
    "REBUILD_COST_RATIO",
    "Error",
    "InvalidInputError",
    "InvalidFileError",
    "OptionsError",
    "OutOfMemoryError",
    "IoError",
    "InternalError",
    "Scene",
    "build",
    "convert",
    "convert_iter",
    "convert_many",
    "options_table",
    "run_job",
    "run_jobs",
    "open",
    "options",
    "verify",
]

#: The cost ratio past which :meth:`Scene.refit` recommends converting again (``bvhc refit``'s default).
REBUILD_COST_RATIO = 1.2

#: ``triangle``, ``source_id`` and ``instance`` of a miss (and absent ids), as in ``format-spec/rays-and-hits.md``.
MISS = 0xFFFFFFFF
#: The newest ``.bvh`` version this package writes and reads (``major.minor``).
FORMAT_VERSION: str = _native.FORMAT_VERSION

PathLike = Union[str, "os.PathLike[str]"]
Progress = Callable[[str, Optional[int], Optional[float], Optional[float]], None]


def convert(
    src: PathLike,
    dst: PathLike,
    preset: str = "balanced",
    *,
    force: bool = False,
    threads: Optional[int] = None,
    progress: Optional[Progress] = None,
    **options: Any,
) -> Dict[str, Any]:
    """Convert the scene ``src`` (``.gltf``, ``.glb``, ``.obj``, ``.ply``, ``.obj.gz``, ``.ply.gz``) into ``dst``.

    ``preset`` is ``fast``, ``balanced`` or ``max-quality``; ``options`` override it, named as in
    :func:`options_table` (the command line's flags with underscores: ``max_leaf_size=4``,
    ``instancing="always"``, ``opacity="opaque"``, ``pose="Run@0.5"``, ``max_memory="8G"``, ``no_splits=True``;
    a ``no_*`` switch also by its positive name: ``splits=False``, ``merge_leaves=False``). The output is written atomically; when it is up to date (same inputs, options
    and format) nothing is done unless ``force``. ``threads`` defaults to all cores; the bytes do not depend on
    it. ``progress(stage, batch, cost, best_cost)`` is called at each stage (``import``, ``build``,
    ``optimize``, ``write``; the numbers ``None``) and optimizer batch (``"batch"``); an exception it raises
    cancels the optimization and propagates.

    Returns ``bvhc --json``'s report as a dict: ``output``, ``up_to_date``, ``files_read`` and ``report`` (``None``
    when up to date). Raises :class:`OptionsError` (a setting out of range or made inert by another),
    :class:`InvalidInputError`, :class:`IoError`, :class:`OutOfMemoryError`.
    """
    text = _native.convert(os.fspath(src), os.fspath(dst), preset, options, force, threads, progress)
    return json.loads(text)


def convert_iter(
    src: PathLike, dst: PathLike, preset: str = "balanced", **options: Any
) -> Iterator[Tuple[str, Optional[int], Optional[float], Optional[float]]]:
    """:func:`convert` as an iterator of its progress events ``(stage, batch, cost, best_cost)``, for loops and
    progress bars (``for event in tqdm(bvhc.convert_iter(...))``). The conversion runs in a thread; the report is
    the value of the ``StopIteration`` (``report = yield from bvhc.convert_iter(...)``), errors are raised by
    the iteration."""
    import queue
    import threading

    events: "queue.Queue[Any]" = queue.Queue()
    done = object()
    outcome: Dict[str, Any] = {}

    def run() -> None:
        try:
            outcome["report"] = convert(src, dst, preset, progress=lambda *e: events.put(e), **options)
        except BaseException as error:  # re-raised in the iterating thread
            outcome["error"] = error
        events.put(done)

    worker = threading.Thread(target=run, daemon=True)
    worker.start()
    while True:
        event = events.get()
        if event is done:
            break
        yield event
    worker.join()
    if "error" in outcome:
        raise outcome["error"]
    return outcome["report"]


def options(preset: str = "balanced", **options: Any) -> Dict[str, Any]:
    """The options a conversion would use, resolved and checked (``bvhc options``): the metadata's ``build``
    object. Raises :class:`OptionsError` where ``bvhc`` exits 2."""
    return json.loads(_native.resolve(preset, options))


def _ply_bytes(vertices: np.ndarray, faces: np.ndarray) -> bytes:
    """A binary little-endian PLY of the arrays: the vertices in their own precision, the faces as uint32."""
    kind = "double" if vertices.dtype == np.float64 else "float"
    header = (
        "ply\nformat binary_little_endian 1.0\n"
        f"element vertex {len(vertices)}\n"
        f"property {kind} x\nproperty {kind} y\nproperty {kind} z\n"
        f"element face {len(faces)}\nproperty list uchar uint vertex_indices\nend_header\n"
    ).encode()
    vertex_type = "<f8" if kind == "double" else "<f4"
    records = np.empty(len(faces), dtype=[("n", "u1"), ("i", "<u4", (3,))])
    records["n"] = 3
    records["i"] = faces
    return header + np.ascontiguousarray(vertices, dtype=vertex_type).tobytes() + records.tobytes()


def build(
    vertices: Any,
    faces: Any,
    dst: PathLike,
    preset: str = "balanced",
    *,
    force: bool = False,
    threads: Optional[int] = None,
    progress: Optional[Progress] = None,
    **options: Any,
) -> Dict[str, Any]:
    """Convert a triangle mesh held in memory into ``dst``: ``vertices`` an ``(n, 3)`` float32 or float64 array,
    ``faces`` an ``(m, 3)`` integer array of vertex indices (a trimesh ``Trimesh`` works through its
    ``.vertices`` and ``.faces``).

    The arrays go through the PLY importer (written as ``mesh.ply``, binary, in a temporary folder), so they
    get its checks and their errors (a non-finite coordinate, an index out of range, degenerate triangles
    dropped) and the same tree as converting that PLY file; the file's metadata names ``mesh.ply`` and its
    hash, so building the same arrays again is up to date. Options and the return value as :func:`convert`.
    """
    v = np.asarray(vertices)
    f = np.asarray(faces)
    if v.ndim != 2 or v.shape[1] != 3 or v.dtype not in (np.float32, np.float64):
        raise InvalidInputError(f"vertices: expected an (n, 3) float32 or float64 array, got {v.dtype} {v.shape}")
    if f.ndim != 2 or f.shape[1] != 3 or not np.issubdtype(f.dtype, np.integer):
        raise InvalidInputError(f"faces: expected an (m, 3) integer array, got {f.dtype} {f.shape}")
    if f.size and (f.min() < 0 or f.max() >= len(v)):
        bad = int(np.argmax((f < 0).any(axis=1) | (f >= len(v)).any(axis=1)))
        raise InvalidInputError(f"faces: face {bad} {f[bad].tolist()} indexes outside the {len(v)} vertices")
    with tempfile.TemporaryDirectory(prefix="bvhc-build-") as folder:
        mesh = os.path.join(folder, "mesh.ply")
        with builtins.open(mesh, "wb") as out:
            out.write(_ply_bytes(v, f.astype(np.uint32)))
        try:
            return convert(mesh, dst, preset, force=force, threads=threads, progress=progress, **options)
        except Error as error:
            # Name the arrays rather than the temporary file.
            raise type(error)(str(error).replace(mesh, "bvhc.build's arrays (as mesh.ply)")) from None



class Scene:
    """A ``.bvh`` file opened over its bytes (a read-only memory map by default); see :func:`open`.

    Array sections are read-only numpy views of those bytes, without a copy: :attr:`nodes`, :attr:`triangles`,
    :attr:`triangle_ids`, :attr:`source_vertices`, :attr:`triangle_flags`, :attr:`instances`; :meth:`section`
    gives any section's raw bytes.
    """

    def __init__(self, native: "_native.Scene") -> None:
        self._native = native
        self._info: Optional[Dict[str, Any]] = None

    @property
    def path(self) -> str:
        """The file's path as given to :func:`open`."""
        return self._native.path

    @property
    def bounds(self) -> Optional[Tuple[Tuple[float, float, float], Tuple[float, float, float]]]:
        """``((min x, y, z), (max x, y, z))`` of the scene, or ``None`` when it is empty."""
        bounds = self._native.bounds
        if bounds is None:
            return None
        (x0, y0, z0), (x1, y1, z1) = bounds
        return (x0, y0, z0), (x1, y1, z1)

    def info(self) -> Dict[str, Any]:
        """The ``bvhc info --json`` report: version, sections, counts, tree statistics, costs, metadata."""
        if self._info is None:
            self._info = json.loads(self._native.info_json())
        return self._info

    def verify(self) -> None:
        """Check every validity rule; raises :class:`InvalidFileError` naming the first broken one."""
        self._native.verify()

    def section(self, name: str) -> Optional[np.ndarray]:
        """The raw bytes of the section ``name`` (as ``info()["sections"]`` names them), a read-only uint8 view;
        ``None`` when the file has no such section."""
        for entry in self.info()["sections"]:
            if entry["name"] == name:
                start = entry["byte_offset"]
                return self._native.data[start : start + entry["byte_len"]]
        return None

    def _typed(self, name: str, dtype: Any) -> Optional[np.ndarray]:
        raw = self.section(name)
        return None if raw is None else raw.view(dtype)

    def _required(self, name: str, dtype: Any) -> np.ndarray:
        typed = self._typed(name, dtype)
        if typed is None:  # verify() guarantees both required sections
            raise InvalidFileError(f"{self.path}: no {name} section")
        return typed

    @property
    def nodes(self) -> np.ndarray:
        """The binary nodes: fields ``min`` and ``max`` (3 float32), ``index``, ``count`` (uint32)."""
        dtype = np.dtype([("min", "<f4", (3,)), ("max", "<f4", (3,)), ("index", "<u4"), ("count", "<u4")])
        return self._required("nodes", dtype)

    @property
    def triangles(self) -> np.ndarray:
        """The triangle records' vertices, ``(n, 3, 3)`` float32 (in a two-level file, every mesh's records)."""
        return self._required("triangles", "<f4").reshape(-1, 3, 3)

    @property
    def triangle_ids(self) -> Optional[np.ndarray]:
        """Each record's source triangle id (uint32), or ``None`` without ids."""
        return self._typed("triangle_ids", "<u4")

    @property
    def source_vertices(self) -> Optional[np.ndarray]:
        """Each record's vertex indices in its source primitive, ``(n, 3)`` uint32, or ``None``."""
        ids = self._typed("source_vertices", "<u4")
        return None if ids is None else ids.reshape(-1, 3)

    @property
    def triangle_flags(self) -> Optional[np.ndarray]:
        """Each record's flags (uint8; bit 0: not opaque), or ``None`` (every triangle opaque)."""
        return self._typed("triangle_flags", "u1")

    @property
    def meshes(self) -> Optional[np.ndarray]:
        """A two-level file's meshes, or ``None``: each one's ``first_node``, ``node_count``, ``first_triangle``,
        ``triangle_count`` (its records, in :attr:`triangles`), ``first_wide_node``, ``wide_node_count``,
        ``first_packet``, ``packet_count`` (uint32)."""
        fields = ["first_node", "node_count", "first_triangle", "triangle_count"]
        fields += ["first_wide_node", "wide_node_count", "first_packet", "packet_count"]
        return self._typed("meshes", np.dtype([(field, "<u4") for field in fields]))

    @property
    def instances(self) -> Optional[np.ndarray]:
        """A two-level file's placements, or ``None``: ``object_to_world`` and ``world_to_object`` (3x4 float32
        rows ``[a, b, c, d]``: ``p' = a.p + d``), ``mesh_index``, ``node_index`` (glTF), ``gpu_instance_index``."""
        dtype = np.dtype(
            [
                ("object_to_world", "<f4", (3, 4)),
                ("world_to_object", "<f4", (3, 4)),
                ("mesh_index", "<u4"),
                ("node_index", "<u4"),
                ("gpu_instance_index", "<u4"),
                ("reserved", "<u4"),
            ]
        )
        return self._typed("instances", dtype)

    @property
    def source_id_count(self) -> int:
        """Source ids of the file: the length of a ``cutout`` mask (0 without ids)."""
        return self._native.source_id_count

    @property
    def source_ranges(self) -> Optional[np.ndarray]:
        """The source table (``None`` without one): where source ids come from, a row a range of ids with fields
        ``first_source_triangle``, ``source_triangle_count``, ``file_index`` (the input), ``node_index``,
        ``mesh_index``, ``primitive_index`` (glTF: the material's primitive) and ``instance_index``
        (``EXT_mesh_gpu_instancing``); absent values are :data:`MISS`."""
        fields = ["first_source_triangle", "source_triangle_count", "file_index", "node_index", "mesh_index"]
        fields += ["primitive_index", "instance_index", "reserved"]
        return self._typed("source_table", np.dtype([(name, "<u4") for name in fields]))

    def closest_hits(
        self,
        origins: Any,
        directions: Any,
        t_min: Any = 0.0,
        t_max: Any = np.inf,
        *,
        threads: Optional[int] = None,
        cutout: Optional[np.ndarray] = None,
        cutout_primitives: Optional[Any] = None,
        filter: Optional[Callable[..., bool]] = None,
        filter_scope: str = "every",
        coherent: bool = False,
        lean: bool = False,
    ) -> Dict[str, np.ndarray]:
        """The closest hit of each ray: ``origins`` and ``directions`` are ``(n, 3)`` float32 or float64 arrays
        (C-ordered or strided, read in place; float64 is rounded to float32), ``t_min`` and ``t_max`` numbers or
        ``(n,)`` arrays. Rays are checked as ``bvhc trace`` checks them (finite origin and direction, direction
        not below 2^-64, ``0 <= t_min <= t_max``); the first bad one raises :class:`InvalidInputError` naming it.

        Returns a dict of arrays, one row a ray: ``t`` (float32, ``inf`` for a miss), ``triangle`` (uint32 record
        index, :data:`MISS` for a miss), ``source_id`` (uint32, :data:`MISS` for a miss or a file without ids),
        ``u``, ``v`` (float32 weights of the record's ``v1`` and ``v2``, 0 for a miss), ``normal`` ((n, 3) float32,
        unnormalized, in world space), ``front_face`` (bool) and ``instance`` (uint32, :data:`MISS` in a one-level
        file). Traced on all cores (or ``threads``) with the GIL released.

        Hit filters (alpha cut-outs): ``cutout`` is a bool array of :attr:`source_id_count` values, true where a
        triangle is cut out (as if absent); ``cutout_primitives`` a list of ``(mesh, primitive)`` pairs whose
        triangles are cut out. Both are applied without calling Python, on every core. ``filter`` is a callable
        ``filter(ray, t, u, v, triangle, source_id, instance) -> bool`` (``ray`` the ray's index; true keeps the
        candidate), asked about each candidate the masks keep: the call then traces on one thread with the GIL,
        and an exception it raises is raised here. ``filter_scope`` is ``"every"`` (every candidate is asked) or
        ``"not_opaque"`` (only candidates on triangles the file marks not opaque, glTF ``MASK``/``BLEND``
        materials; :attr:`triangle_flags`).

        ``coherent=True`` says the rays come in the order of neighbouring pixels (camera or shadow rays of an
        image, row by row): each 8 consecutive rays are traced together as a packet, faster on such rays and
        with the same hits as without (a callable ``filter`` traces one ray at a time either way). Without it,
        groups of 8 consecutive rays that start at the same point bit for bit (a pinhole camera's, a point light's,
        one point's ambient-occlusion rays), or close together with directions in one octant (shadow rays from
        neighbouring hits toward a light), are traced together all the same.

        ``lean=True`` returns only ``t``, ``triangle``, ``u``, ``v`` and ``instance``, the same values: the
        normal, side and source id are then not computed (without a callable ``filter``), which is faster when
        they are not needed or needed for a few hits only.
        """
        return self._native.closest_hits(
            origins, directions, t_min, t_max, threads, cutout, cutout_primitives, filter, filter_scope, coherent,
            lean,
        )

    def any_hits(
        self,
        origins: Any,
        directions: Any,
        t_min: Any = 0.0,
        t_max: Any = np.inf,
        *,
        threads: Optional[int] = None,
        cutout: Optional[np.ndarray] = None,
        cutout_primitives: Optional[Any] = None,
        filter: Optional[Callable[..., bool]] = None,
        filter_scope: str = "every",
        coherent: bool = False,
    ) -> np.ndarray:
        """Whether each ray hits anything in ``[t_min, t_max]`` (that the filters keep): a bool array. Arguments
        as :meth:`closest_hits`."""
        return self._native.any_hits(
            origins, directions, t_min, t_max, threads, cutout, cutout_primitives, filter, filter_scope, coherent
        )

    def all_hits(
        self,
        origins: Any,
        directions: Any,
        t_min: Any = 0.0,
        t_max: Any = np.inf,
        *,
        max_hits: int = 64,
        threads: Optional[int] = None,
        cutout: Optional[np.ndarray] = None,
        cutout_primitives: Optional[Any] = None,
        filter: Optional[Callable[..., bool]] = None,
        filter_scope: str = "every",
    ) -> Dict[str, np.ndarray]:
        """Every surface each ray crosses in ``[t_min, t_max]``, nearest first: a dict of arrays with a row a hit,
        sorted by ray and then ``t``: ``ray`` (uint32, the ray's index) and the columns of :meth:`closest_hits`;
        and two arrays with a row a ray, ``count`` (hits kept) and ``found`` (hits found; a ray with more than
        ``max_hits`` keeps its nearest ``max_hits``). The test is watertight, and a ray exactly through an edge or
        vertex that triangles share counts as if moved infinitesimally off it: it crosses there once (one hit, not
        one a triangle), a ray touching a silhouette gets a front and a back hit or none, and a ray from outside a
        closed mesh has an even number of hits. Filters as :meth:`closest_hits`."""
        return self._native.all_hits(
            origins, directions, t_min, t_max, max_hits, threads, cutout, cutout_primitives, filter, filter_scope
        )

    def contains(self, points: Any, *, threads: Optional[int] = None) -> np.ndarray:
        """Whether each point of ``points`` (``(n, 3)`` float32 or float64) lies inside the scene's closed meshes:
        a bool array. A ray from the point counts the surfaces it crosses as :meth:`all_hits` does, front faces
        against back faces (so either winding works). Meshes must be closed (watertight) for the answer to mean
        anything; a point on the surface counts as inside."""
        return self._native.contains(points, threads)

    def closest_points(
        self,
        points: Any,
        max_distance: Optional[float] = None,
        *,
        threads: Optional[int] = None,
        cutout: Optional[np.ndarray] = None,
        cutout_primitives: Optional[Any] = None,
    ) -> Dict[str, np.ndarray]:
        """The closest point of the surface to each of ``points`` (``(n, 3)`` float32 or float64; float64 is
        rounded to float32), within ``max_distance`` (inclusive; ``None`` for no bound), as
        ``format-spec/point-queries.md`` defines it: the spec's binary64 arithmetic a triangle, ties to the lowest
        instance, then the lowest record, the distance within ``2^-24`` of itself plus ``2^-40`` of the
        coordinates' scale. A point that is not finite, or a negative ``max_distance``, raises
        :class:`InvalidInputError`.

        Returns a dict of arrays, one row a point: ``point`` ((n, 3) float32, world space, NaN where nothing is
        within ``max_distance``), ``distance`` (float32, ``inf`` there), ``triangle`` (uint32 record index),
        ``source_id``, ``instance`` (uint32; :data:`MISS` where there is none, or for no ids / a one-level file),
        ``u``, ``v`` (float32 weights of the record's ``v1`` and ``v2``, 0 where there is none). Runs on all cores
        (or ``threads``) with the GIL released, the points taken in a spatial order inside (the answers do not
        depend on it).

        ``cutout`` and ``cutout_primitives`` are the masks :meth:`closest_hits` takes (a bool array of
        :attr:`source_id_count` values, true where a triangle is cut out; ``(mesh, primitive)`` pairs): the
        closest point among the triangles they keep, as if the others were absent."""
        return self._native.closest_points(points, max_distance, threads, cutout, cutout_primitives)

    def distance(
        self,
        points: Any,
        *,
        threads: Optional[int] = None,
        cutout: Optional[np.ndarray] = None,
        cutout_primitives: Optional[Any] = None,
    ) -> np.ndarray:
        """The distance from each of ``points`` (``(n, 3)``) to the surface, as a float32 array: the
        ``distance`` column of :meth:`closest_points` with no bound (``inf`` for a file with no triangles, or
        none the masks keep)."""
        return self._native.closest_points(points, None, threads, cutout, cutout_primitives)["distance"]

    def signed_distance(self, points: Any, *, threads: Optional[int] = None) -> np.ndarray:
        """The signed distance from each of ``points`` (``(n, 3)``) to the surface, as a float32 array: the
        :meth:`distance`, negative where the generalized winding number's magnitude exceeds 1/2 (inside a closed
        mesh of either winding; open and self-intersecting meshes get the sign their winding number gives), 0 on
        the surface. The winding numbers are summed fast (far parts of the tree by their dipole expansion, within
        about 0.05 of the exact sum near surfaces, far less away from them); their moments are computed by the first
        call, in time linear in the triangles, and kept for later calls while the file's bytes stay the same (a
        refit, pose or instance move computes them again)."""
        return self._native.winding(points, True, threads)

    def winding_number(self, points: Any, *, threads: Optional[int] = None) -> np.ndarray:
        """The generalized winding number of the surface at each of ``points`` (``(n, 3)``), as a float64 array:
        1 inside a closed mesh wound counter-clockwise seen from outside (-1 for the other winding), 0 outside,
        fractions near holes (Jacobson et al. 2013; summed fast as Barill et al. 2018). Through a two-level file,
        every instance's mesh is summed in world space."""
        return self._native.winding(points, False, threads)

    def spawn(self, hits: Dict[str, np.ndarray], directions: Any) -> Tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Secondary rays leaving ``hits`` (a dict as :meth:`closest_hits` returns, misses removed) in
        ``directions`` ((n, 3)), with no epsilon to choose: the origins are moved off the surface by the hit
        point's error bound and the rays never meet the triangle they leave (``t_min = 0``). Returns
        ``(origins, directions, t_min, t_max)`` for :meth:`closest_hits` or :meth:`any_hits`."""
        h = {k: np.asarray(v) for k, v in hits.items()}
        return self._native.spawn(
            np.ascontiguousarray(h["t"], dtype=np.float32),
            np.ascontiguousarray(h["triangle"], dtype=np.uint32),
            np.ascontiguousarray(h["u"], dtype=np.float32),
            np.ascontiguousarray(h["v"], dtype=np.float32),
            np.asarray(h["normal"], dtype=np.float32),
            np.ascontiguousarray(h["front_face"], dtype=bool),
            np.ascontiguousarray(h["instance"], dtype=np.uint32),
            np.ascontiguousarray(h["source_id"], dtype=np.uint32),
            directions,
        )

    def refit(
        self,
        positions: Any = None,
        *,
        source_vertices: Optional[List[Any]] = None,
        threads: Optional[int] = None,
        max_cost_ratio: float = REBUILD_COST_RATIO,
    ) -> Dict[str, Any]:
        """Move the triangle records and refit the file's trees in place, keeping their shape (skinned or
        morphed meshes, each frame). The scene must be opened with ``writable=True``. In a two-level file the
        records are each mesh's, in the mesh's own space, and every instance follows its mesh. With split
        references, each reference is boxed as its whole triangle (convert meshes meant to deform with
        ``splits=False`` for tighter trees).

        ``positions``: ``(n, 3, 3)`` float32, C-contiguous (read in place), one triangle a record in record
        order (as :attr:`triangles` holds them). Or ``source_vertices``: for each source range
        (:attr:`source_ranges`), an ``(m, 3)`` float32 array of its primitive's vertex positions indexed as the
        source indexes them (:attr:`source_vertices`), or ``None`` to keep that range. Positions are in the
        file's space (world space after the glTF node's transform, as skinning produces them). The same result
        on any number of ``threads`` (default: all cores).

        Returns the refit tree's costs beside the file's own: ``cost``, ``file_cost`` (binary tree),
        ``wide_cost``, ``file_wide_cost`` (``None`` where the file states none), ``cost_ratio`` and
        ``rebuild_recommended`` (the ratio above ``max_cost_ratio``: converting the posed geometry anew would
        trace faster). Raises :class:`InvalidInputError` for positions that do not fit (naming the record, range
        or vertex), and :class:`OptionsError` where ``bvhc refit`` refuses its flags (``max_cost_ratio`` below 1
        or not finite, ``threads`` outside 1 to 1024, neither or both of ``positions`` and ``source_vertices``),
        with the file unchanged. :attr:`triangles` and the other views show the new values; call
        :meth:`write` to ship the posed file."""
        self._info = None
        return self._native.refit(positions, source_vertices, threads, max_cost_ratio)

    def pose(
        self,
        asset: Union[str, "os.PathLike[str]"],
        pose: Optional[str] = None,
        *,
        threads: Optional[int] = None,
        max_cost_ratio: float = REBUILD_COST_RATIO,
    ) -> Dict[str, Any]:
        """Pose the file in place (opened ``writable=True``) as the ``asset`` it was converted from stands in its
        default pose or at ``pose`` (``"CLIP@SECONDS"``, the glTF animation clip by index or name): the asset is
        imported as the conversion imported it (its recorded scene, instancing and animation clips), every
        triangle record given its triangle's positions there and every instance that a glTF node places the
        node's transform. The deforming geometry is refit, an instanced mesh only where its positions differ
        from the file's, and the moving instances are placed (``bvhc refit FILE --positions ASSET --pose
        CLIP@SECONDS`` does the same, then writes the file).

        Returns :meth:`refit`'s dict (a two-level file states no costs, so they are ``None``) with
        ``instances_placed``. Raises :class:`InvalidInputError` for an asset that is not the file's (another
        topology, a clip it does not have), :class:`IoError` for one that cannot be read and
        :class:`OptionsError` for ``threads`` or ``max_cost_ratio`` as :meth:`refit`, with the file unchanged.
        :meth:`write` then refuses to write over the asset or a buffer it read (:class:`IoError`)."""
        self._info = None
        return self._native.pose(os.fspath(asset), pose, threads, max_cost_ratio)

    def move_instances(self, instances: Any, transforms: Any) -> None:
        """Place instances of a two-level file anew, in place (opened ``writable=True``): ``instances`` (indices)
        by ``transforms`` (``(k, 3, 4)`` float32 object-to-world rows ``[a, b, c, d]``, as :attr:`instances`
        stores them); their inverses and world boxes are computed and the top trees refit."""
        self._info = None
        indices = [int(i) for i in np.asarray(instances, dtype=np.int64).reshape(-1)]
        self._native.move_instances(indices, np.ascontiguousarray(transforms, dtype=np.float32))

    def move_instances_in_frame(self, instances: Any, transforms: Any) -> None:
        """:meth:`move_instances` without recomputing the checksums, for a frame of an animation: hashing a large
        file's sections costs more than moving its instances. :meth:`verify` fails until :meth:`write` (which
        recomputes them) or :meth:`move_instances`."""
        self._info = None
        indices = [int(i) for i in np.asarray(instances, dtype=np.int64).reshape(-1)]
        self._native.move_instances_in_frame(indices, np.ascontiguousarray(transforms, dtype=np.float32))

    def refit_mesh(self, mesh: int, positions: Any, *, threads: Optional[int] = None) -> None:
        """Refit one mesh of a two-level file in place (opened ``writable=True``): ``positions`` (``(n, 3, 3)``
        float32, C-contiguous, read in place) are its records in its own space and record order (``n`` its
        triangle count), and its instances' world boxes and the top trees follow; every other mesh is left
        untouched, so a frame that deforms one mesh beside large rigid ones costs that mesh's refit. Checksums are
        left as :meth:`refit` leaves them. Raises :class:`InvalidInputError` for a one-level file, a mesh that
        does not exist or positions that do not fit, with the file unchanged."""
        self._info = None
        self._native.refit_mesh(int(mesh), np.ascontiguousarray(positions, dtype=np.float32), threads)

    @property
    def top_tree_cost(self) -> Optional[float]:
        """A two-level file's binary top tree SAH cost (its nodes' areas over the root's, each instance counted
        once), ``None`` for a one-level file: compare the refit tree's after :meth:`move_instances` with
        :meth:`rebuilt_top_trees`' to decide whether a rebuild pays."""
        return self._native.top_tree_cost

    def rebuilt_top_trees(self) -> "Scene":
        """A new scene (in memory, writable) holding this two-level file with both top trees built anew over
        its instances as they now stand, by the converter's own builder (binned SAH over the instances' world
        boxes): after large :meth:`move_instances` the refit trees keep their old grouping and trace slowly.
        The file is laid out anew (the wide top tree may change its node count) and verified. Raises
        :class:`InvalidInputError` for a one-level file."""
        return Scene(_native.Scene(self._native.rebuilt_top_trees(), self.path, False))

    def write(self, path: PathLike) -> None:
        """Write the file to ``path`` atomically with the costs its metadata states and its checksums recomputed
        (a refit leaves both stale, so :meth:`verify` fails on the scene itself), so that it passes ``bvhc verify``.
        After :meth:`pose`, while no :meth:`refit`, :meth:`refit_mesh` or instance move has followed it, the
        metadata records the pose as ``bvhc refit`` does (the key ``refit``: the asset's files with their hashes,
        and the clip and time), so the file says which geometry its records hold; posed back to the asset and
        pose it was converted from, it records none."""
        self._native.write(os.fspath(path))

    def __repr__(self) -> str:
        info = self.info()
        return f"<bvhc.Scene {self.path!r}: .bvh {info['format_version']}, {info['triangle_count']} triangles>"


def open(path: PathLike, verify: bool = True, mmap: bool = True, writable: bool = False) -> Scene:
    """Open the ``.bvh`` file at ``path``: a read-only memory map of it (``mmap=False`` reads it into memory
    instead), checked structurally, and with ``verify`` against every validity rule. Raises :class:`IoError`
    for a file that cannot be read, :class:`InvalidFileError` for one that breaks a rule.

    ``writable=True`` makes a scene that :meth:`Scene.refit` and :meth:`Scene.move_instances` change in place:
    a private copy-on-write map (or the bytes read into memory); the file on disk never changes.

    As with any memory map, the file must not be changed while open: replace files by renaming them (as
    ``bvhc`` writes them)."""
    name = os.fspath(path)
    data: np.ndarray
    try:
        if mmap and os.path.getsize(name) > 0:
            # Still the map, without memmap's subclass behaviour; "c" is copy-on-write, private to this process.
            data = np.memmap(name, dtype=np.uint8, mode="c" if writable else "r").view(np.ndarray)
        else:
            data = np.fromfile(name, dtype=np.uint8)
            data.flags.writeable = writable
    except OSError as error:
        raise IoError(f"{name}: {error.strerror or error}") from error
    return Scene(_native.Scene(data, name, verify))


def verify(path: PathLike) -> str:
    """Check every validity rule of the file at ``path``; returns ``bvhc verify``'s line, raises
    :class:`InvalidFileError` naming the first broken rule (or :class:`IoError`)."""
    return _native.verify(os.fspath(path))
