#!/usr/bin/env python3
"""Writes, with Pixar's usd-core, a stage that uses every mesh feature bvhc's USD import handles, for
tests/suite/usd_oracle.rs: transform ops of every kind (translate, scale, rotateX/rotateXYZ/rotateZYX, orient,
transform, !invert!, !resetXformStack!), inherits, specializes and a variant set, a negative scale, faces of 3 to 5 vertices, a face of 2, hole indices,
a leftHanded mesh, visibility (an invisible subtree), purposes (proxy, guide, render), time-sampled points and
transforms, native instances of one prototype (a mirrored one too) and a point instancer with two prototypes,
orientations, scales, ids and invisible ids.

usage: usd-feature-stage.py OUT.usda [OUT.usdc OUT.usdz ...]  (the same stage in each format)
"""
import sys

from pxr import Gf, Sdf, Usd, UsdGeom, UsdUtils, Vt


def mesh(stage, path, points, counts, indices, **attrs):
    m = UsdGeom.Mesh.Define(stage, path)
    m.CreatePointsAttr(Vt.Vec3fArray([Gf.Vec3f(*p) for p in points]))
    m.CreateFaceVertexCountsAttr(counts)
    m.CreateFaceVertexIndicesAttr(indices)
    if "holes" in attrs:
        m.CreateHoleIndicesAttr(attrs["holes"])
    if "orientation" in attrs:
        m.CreateOrientationAttr(attrs["orientation"])
    if "purpose" in attrs:
        m.CreatePurposeAttr(attrs["purpose"])
    return m


GRID = [(x, y, 0.1 * x * y) for y in range(3) for x in range(3)]
QUADS = ([4, 4, 4, 4], [0, 1, 4, 3, 1, 2, 5, 4, 3, 4, 7, 6, 4, 5, 8, 7])


def build(stage):
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.z)
    UsdGeom.SetStageMetersPerUnit(stage, 0.01)
    world = UsdGeom.Xform.Define(stage, "/World")
    world.AddTranslateOp().Set(Gf.Vec3d(1, 2, 3))
    world.AddRotateXYZOp().Set(Gf.Vec3f(10, 20, 30))
    world.AddScaleOp().Set(Gf.Vec3f(1, 2, 0.5))

    # Faces of 3, 4 and 5 vertices, one of 2, and a hole.
    pts = [(0, 0, 0), (1, 0, 0), (2, 0, 0), (2, 1, 0), (1, 1, 0), (0, 1, 0), (0, 2, 0), (1, 2, 1), (2, 2, 0)]
    mesh(stage, "/World/Faces", pts, [3, 4, 5, 2, 4], [0, 1, 5, 1, 2, 3, 4, 5, 4, 3, 8, 7, 6, 0, 1, 6, 7, 8],
         holes=[4])
    left = UsdGeom.Xform.Define(stage, "/World/LeftXf")
    left.AddOrientOp().Set(Gf.Quatf(0.8, 0.2, 0.5, 0.1).GetNormalized())
    left.AddTranslateOp(opSuffix="pivot").Set(Gf.Vec3d(0.5, 0.5, 0))
    left.AddRotateZYXOp().Set(Gf.Vec3f(5, 15, 25))
    left.AddTranslateOp(opSuffix="pivot", isInverseOp=True)
    mesh(stage, "/World/LeftXf/Left", GRID, *QUADS, orientation=UsdGeom.Tokens.leftHanded)

    reset = UsdGeom.Xform.Define(stage, "/World/Reset")
    reset.SetResetXformStack(True)
    reset.AddTransformOp().Set(Gf.Matrix4d(Gf.Rotation(Gf.Vec3d(1, 1, 0), 40), Gf.Vec3d(-3, 0, 2)))
    mesh(stage, "/World/Reset/Mesh", GRID, *QUADS)

    mirror = UsdGeom.Xform.Define(stage, "/World/Mirror")
    mirror.AddScaleOp().Set(Gf.Vec3f(-1, 1, 1))
    mirror.AddRotateXOp().Set(33.0)
    mesh(stage, "/World/Mirror/Mesh", GRID, *QUADS)

    hidden = UsdGeom.Xform.Define(stage, "/World/Hidden")
    hidden.CreateVisibilityAttr(UsdGeom.Tokens.invisible)
    mesh(stage, "/World/Hidden/Mesh", GRID, *QUADS)
    mesh(stage, "/World/Proxy", GRID, *QUADS, purpose=UsdGeom.Tokens.proxy)
    mesh(stage, "/World/Guide", GRID, *QUADS, purpose=UsdGeom.Tokens.guide)
    scope = UsdGeom.Scope.Define(stage, "/World/RenderScope")
    scope.CreatePurposeAttr(UsdGeom.Tokens.render)
    mesh(stage, "/World/RenderScope/Mesh", GRID, *QUADS)

    # Time samples: points and a transform, with an authored default too.
    moving = UsdGeom.Xform.Define(stage, "/World/Moving")
    op = moving.AddTranslateOp()
    op.Set(Gf.Vec3d(0, 0, 10))
    op.Set(Gf.Vec3d(0, 0, 0), 0.0)
    op.Set(Gf.Vec3d(4, 0, 0), 10.0)
    animated = mesh(stage, "/World/Moving/Mesh", GRID, *QUADS)
    points = animated.GetPointsAttr()
    points.Set(Vt.Vec3fArray([Gf.Vec3f(x, y, 0) for x, y, _ in GRID]), 0.0)
    points.Set(Vt.Vec3fArray([Gf.Vec3f(x, y, 2.0 * x) for x, y, _ in GRID]), 10.0)

    # Composition arcs: a class the prim inherits, a prim it specializes, and a variant set.
    base = UsdGeom.Xform.Define(stage, "/Classes/Raised")
    stage.GetPrimAtPath("/Classes").SetSpecifier(Sdf.SpecifierClass)
    base.AddTranslateOp().Set(Gf.Vec3d(0, 0, 7))
    inheriting = mesh(stage, "/World/Inheriting", GRID, *QUADS)
    inheriting.GetPrim().GetInherits().AddInherit("/Classes/Raised")
    special = UsdGeom.Xform.Define(stage, "/Classes/Turned")
    special.AddRotateYOp().Set(60.0)
    specializing = mesh(stage, "/World/Specializing", GRID, *QUADS)
    specializing.GetPrim().GetSpecializes().AddSpecialize("/Classes/Turned")
    holder = UsdGeom.Xform.Define(stage, "/World/Variant")
    shapes = holder.GetPrim().GetVariantSets().AddVariantSet("shape")
    for name, (points, counts, indices) in [("grid", (GRID, *QUADS)), ("pair", (pts[:6], [3, 3], [0, 1, 5, 1, 2, 3]))]:
        shapes.AddVariant(name)
        shapes.SetVariantSelection(name)
        with shapes.GetVariantEditContext():
            mesh(stage, "/World/Variant/Shape", points, counts, indices)
    shapes.SetVariantSelection("pair")

    # Native instances of one prototype (two meshes), one mirrored, one hidden.
    thing = UsdGeom.Xform.Define(stage, "/Prototypes/Thing")
    stage.GetPrimAtPath("/Prototypes").SetSpecifier(Sdf.SpecifierClass)
    mesh(stage, "/Prototypes/Thing/A", GRID, *QUADS)
    inner = UsdGeom.Xform.Define(stage, "/Prototypes/Thing/Inner")
    inner.AddTranslateOp().Set(Gf.Vec3d(0, 0, 1))
    mesh(stage, "/Prototypes/Thing/Inner/B", pts[:6], [3, 3], [0, 1, 5, 1, 2, 3])
    for i, (t, s) in enumerate([((5, 0, 0), 1), ((5, 5, 0), -1), ((0, 5, 0), 2), ((9, 9, 9), 1)]):
        inst = UsdGeom.Xform.Define(stage, f"/World/Inst{i}")
        inst.GetPrim().GetReferences().AddInternalReference("/Prototypes/Thing")
        inst.GetPrim().SetInstanceable(True)
        inst.AddTranslateOp().Set(Gf.Vec3d(*t))
        inst.AddScaleOp().Set(Gf.Vec3f(s, 1, 1))
        if i == 3:
            inst.CreateVisibilityAttr(UsdGeom.Tokens.invisible)

    # A point instancer: two prototypes (an Xform with its own transform, and a bare mesh).
    forest = UsdGeom.PointInstancer.Define(stage, "/World/Forest")
    forest.AddTranslateOp().Set(Gf.Vec3d(0, -6, 0))
    tree = UsdGeom.Xform.Define(stage, "/World/Forest/Protos/Tree")
    tree.AddRotateZOp().Set(45.0)
    mesh(stage, "/World/Forest/Protos/Tree/Trunk", GRID, *QUADS)
    mesh(stage, "/World/Forest/Protos/Rock", pts[:6], [3, 3], [0, 1, 5, 1, 2, 3])
    forest.CreatePrototypesRel().SetTargets(["/World/Forest/Protos/Tree", "/World/Forest/Protos/Rock"])
    n = 7
    forest.CreateProtoIndicesAttr([i % 2 for i in range(n)])
    forest.CreatePositionsAttr(Vt.Vec3fArray([Gf.Vec3f(3 * i, 0, 0) for i in range(n)]))
    forest.CreateOrientationsAttr(Vt.QuathArray([Gf.Quath(Gf.Quatf(1, 0.1 * i, 0.2, 0).GetNormalized())
                                                 for i in range(n)]))
    forest.CreateScalesAttr(Vt.Vec3fArray([Gf.Vec3f(1 + 0.1 * i, 1, 1) for i in range(n)]))
    forest.CreateIdsAttr(Vt.Int64Array([100 + i for i in range(n)]))
    forest.CreateInvisibleIdsAttr(Vt.Int64Array([102]))


def main():
    outputs = sys.argv[1:]
    stage = Usd.Stage.CreateInMemory()
    build(stage)
    for out in outputs:
        if out.endswith(".usdz"):
            layer = out[:-1] + "c"
            stage.GetRootLayer().Export(layer)
            UsdUtils.CreateNewUsdzPackage(layer, out)
        else:
            stage.GetRootLayer().Export(out)


if __name__ == "__main__":
    main()
