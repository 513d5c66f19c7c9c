#!/usr/bin/env python3
"""World-space triangles of an OpenUSD stage as Pixar's own library (usd-core) composes it: the oracle that
tests/suite/usd_oracle.rs holds bvhc's USD import to.

usage: usd-triangles.py STAGE OUT.f64 [--time T] [--purposes default,render]

Writes every drawn triangle to OUT.f64 as 9 little-endian doubles (its corners in winding order, counter-clockwise
seen from the front) and prints a JSON summary: the triangle count, the triangles of each mesh prim, and each
point instancer's instance count. What is drawn, as Hydra draws it: UsdGeomMesh prims that the default predicate
reaches (active, loaded, defined, not abstract), through instance proxies, visible at the time, of a kept purpose;
each face a fan from its first vertex, the faces of holeIndices left out, faces of fewer than 3 vertices skipped,
a leftHanded mesh's triangles reversed; a point instancer's subtree drawn only through its prototypes, each
instance placed by ComputeInstanceTransformsAtTime (which includes the prototype root's own transform); a mesh
that UsdSkel binds to a skeleton skinned by UsdSkel's own skinning query at the time (its points in skeleton space,
placed by the skeleton's transform, as UsdSkel's imaging places them).
"""
import json
import sys

import numpy as np
from pxr import Gf, Usd, UsdGeom, UsdSkel


def fan_triangles(counts, indices, holes):
    """Vertex-index triangles of a mesh's faces, as Hydra's HdMeshUtil fans them (v0, vk, vk+1)."""
    counts = np.asarray(counts, dtype=np.int64)
    indices = np.asarray(indices, dtype=np.int64)
    if len(counts) == 0:
        return np.zeros((0, 3), dtype=np.int64)
    starts = np.cumsum(counts) - counts
    keep = counts >= 3
    if len(holes):
        hole = np.zeros(len(counts), dtype=bool)
        valid = [h for h in holes if 0 <= h < len(counts)]
        hole[valid] = True
        keep &= ~hole
    faces = np.nonzero(keep)[0]
    per_face = counts[faces] - 2
    face_of = np.repeat(faces, per_face)
    first_of_face = np.repeat(np.cumsum(per_face) - per_face, per_face)
    k = np.arange(len(face_of)) - first_of_face + 1
    s = starts[face_of]
    return np.stack([indices[s], indices[s + k], indices[s + k + 1]], axis=1)


def skinned_meshes(stage, time):
    """Mesh prim path -> (points in skeleton space, the skeleton's local-to-world), for every skinned mesh."""
    skinned = {}
    cache = UsdSkel.Cache()
    predicate = Usd.TraverseInstanceProxies(Usd.PrimDefaultPredicate)
    for prim in Usd.PrimRange.Stage(stage, predicate):
        if not prim.IsA(UsdSkel.Root):
            continue
        root = UsdSkel.Root(prim)
        cache.Populate(root, predicate)
        for binding in cache.ComputeSkelBindings(root, predicate):
            query = cache.GetSkelQuery(binding.GetSkeleton())
            xforms = query.ComputeSkinningTransforms(time)
            skeleton_world = UsdGeom.Xformable(binding.GetSkeleton().GetPrim()).ComputeLocalToWorldTransform(time)
            for target in binding.GetSkinningTargets():
                mesh = UsdGeom.Mesh(target.GetPrim())
                points = mesh.GetPointsAttr().Get(time)
                if points is None or xforms is None:
                    continue
                if target.IsRigidlyDeformed():
                    rigid = target.ComputeSkinnedTransform(xforms, time)
                    skinned[str(target.GetPrim().GetPath())] = (points, rigid * skeleton_world)
                    continue
                if target.ComputeSkinnedPoints(xforms, points, time):
                    skinned[str(target.GetPrim().GetPath())] = (points, skeleton_world)
    return skinned


def mesh_triangles(prim, time, matrix, points=None):
    """The mesh's triangles placed by `matrix` (a Gf.Matrix4d, row vectors), shape (n, 3, 3); `points` replaces
    the mesh's own (skinned points)."""
    mesh = UsdGeom.Mesh(prim)
    counts = mesh.GetFaceVertexCountsAttr().Get() or []
    indices = mesh.GetFaceVertexIndicesAttr().Get() or []
    holes = mesh.GetHoleIndicesAttr().Get() or []
    if points is None:
        points = mesh.GetPointsAttr().Get(time)
    points = np.asarray(points if points is not None else [], dtype=np.float64).reshape(-1, 3)
    triangles = fan_triangles(counts, indices, holes)
    if mesh.GetOrientationAttr().Get() == UsdGeom.Tokens.leftHanded:
        triangles = triangles[:, [0, 2, 1]]
    m = np.array(matrix, dtype=np.float64).reshape(4, 4)
    world = points @ m[:3, :3] + m[3, :3]
    if m[:3, :3].size and np.linalg.det(m[:3, :3]) < 0:
        triangles = triangles[:, [0, 2, 1]]
    return world[triangles] if len(triangles) else np.zeros((0, 3, 3))


def drawn(prim, time, purposes):
    imageable = UsdGeom.Imageable(prim)
    return (imageable.ComputeVisibility(time) != UsdGeom.Tokens.invisible
            and imageable.ComputePurpose() in purposes)


def main():
    args = sys.argv[1:]
    stage_path, out_path = args[0], args[1]
    time = Usd.TimeCode.Default()
    purposes = {UsdGeom.Tokens.default_, UsdGeom.Tokens.render}
    if "--time" in args:
        time = Usd.TimeCode(float(args[args.index("--time") + 1]))
    if "--purposes" in args:
        purposes = set(args[args.index("--purposes") + 1].split(",")) | {UsdGeom.Tokens.default_}
    stage = Usd.Stage.Open(stage_path)
    cache = UsdGeom.XformCache(time)
    pieces, per_prim, instancers = [], {}, {}

    skinned = skinned_meshes(stage, time)

    def add(prim, matrix):
        points = None
        if str(prim.GetPath()) in skinned:
            points, matrix = skinned[str(prim.GetPath())]
        tris = mesh_triangles(prim, time, matrix, points)
        pieces.append(tris)
        key = str(prim.GetPath())
        per_prim[key] = per_prim.get(key, 0) + len(tris)

    it = iter(Usd.PrimRange.Stage(stage, Usd.TraverseInstanceProxies(Usd.PrimDefaultPredicate)))
    for prim in it:
        if prim.IsA(UsdGeom.PointInstancer):
            it.PruneChildren()
            instancer = UsdGeom.PointInstancer(prim)
            if UsdGeom.Imageable(prim).ComputeVisibility(time) == UsdGeom.Tokens.invisible:
                continue
            targets = instancer.GetPrototypesRel().GetTargets()
            proto_indices = instancer.GetProtoIndicesAttr().Get(time) or []
            xforms = instancer.ComputeInstanceTransformsAtTime(time, time)
            instancer_world = cache.GetLocalToWorldTransform(prim)
            instancers[str(prim.GetPath())] = len(xforms)
            mask = instancer.ComputeMaskAtTime(time)
            # ComputeInstanceTransformsAtTime leaves out invisible ids; match its instances to their prototypes.
            visible = [i for i in range(len(proto_indices)) if not mask or mask[i]]
            for i, xform in zip(visible, xforms):
                root = stage.GetPrimAtPath(targets[proto_indices[i]])
                root_world = cache.GetLocalToWorldTransform(root)
                for p in Usd.PrimRange(root, Usd.TraverseInstanceProxies(Usd.PrimDefaultPredicate)):
                    if p.IsA(UsdGeom.Mesh) and drawn(p, time, purposes):
                        chain = cache.GetLocalToWorldTransform(p) * root_world.GetInverse()
                        add(p, chain * xform * instancer_world)
            continue
        if prim.IsA(UsdGeom.Mesh) and drawn(prim, time, purposes):
            add(prim, cache.GetLocalToWorldTransform(prim))
    triangles = np.concatenate(pieces) if pieces else np.zeros((0, 3, 3))
    triangles.astype("<f8").tofile(out_path)
    json.dump({"triangles": len(triangles), "prims": per_prim, "point_instancers": instancers}, sys.stdout)


if __name__ == "__main__":
    main()
