"""Geoms: colliders (CollisionAPI, convex hulls or primitives, a physics material for friction)
and visuals (render-only meshes and primitives), kept in separate scopes under each body.

A MuJoCo geom is a collider when its contype or conaffinity is set, otherwise visual. MuJoCo
collides a mesh through its convex hull, so every collider mesh is authored with the convexHull
approximation; CoACD already split the non-convex parts into hulls of at most 64 vertices
(PhysX's default cap). Colliders get purpose "guide" so renderers show the visuals.
"""

from __future__ import annotations

import mujoco
import numpy as np
from pxr import Gf, Sdf, Usd, UsdGeom, UsdPhysics, UsdShade, Vt

from footforge.usd.bodies import body_in_group_frame, set_pose
from footforge.usd.context import ExportContext, mj_name, mul_pose

PHYSX_HULL_VERTEX_LIMIT = 64
GEOM = mujoco.mjtGeom


def is_collider(model: mujoco.MjModel, g: int) -> bool:
    return bool(model.geom_contype[g] or model.geom_conaffinity[g])


def add_geoms(ctx: ExportContext) -> None:
    m = ctx.model
    materials = _friction_materials(ctx)
    colliders: dict[int, Sdf.Path] = {}
    """Colliders of moving bodies: geom id -> prim."""
    for g in range(m.ngeom):
        b = int(m.geom_bodyid[g])
        collider = is_collider(m, g)
        scope = ctx.body_paths[b].AppendChild("collisions" if collider else "visuals")
        if not ctx.stage.GetPrimAtPath(scope):
            UsdGeom.Scope.Define(ctx.stage, scope)
        name = mj_name(m, mujoco.mjtObj.mjOBJ_GEOM, g, "geom")
        prim = _define_shape(
            ctx,
            ctx.child_path(scope, name),
            g,
            f"geom '{name}'",
            mul_pose(body_in_group_frame(ctx, b), (m.geom_pos[g], m.geom_quat[g])),
            collider,
        )
        if prim is None:
            continue
        prim.SetCustomDataByKey("footforge:mjcfName", name)
        if collider:
            UsdPhysics.CollisionAPI.Apply(prim)
            UsdGeom.Imageable(prim).CreatePurposeAttr(UsdGeom.Tokens.guide)
            UsdShade.MaterialBindingAPI.Apply(prim).Bind(
                materials[float(m.geom_friction[g][0])], UsdShade.Tokens.weakerThanDescendants, "physics"
            )
            if m.body_weldid[b]:
                colliders[g] = prim.GetPath()
        else:
            rgba = m.mat_rgba[m.geom_matid[g]] if m.geom_matid[g] >= 0 else m.geom_rgba[g]
            gprim = UsdGeom.Gprim(prim)
            gprim.CreateDisplayColorAttr(Vt.Vec3fArray([Gf.Vec3f(*map(float, rgba[:3]))]))
            if rgba[3] < 1:
                gprim.CreateDisplayOpacityAttr(Vt.FloatArray([float(rgba[3])]))
    _self_collision_group(ctx, colliders)
    _report_contact_settings(ctx)


def _define_shape(ctx: ExportContext, path: Sdf.Path, g: int, name: str, pose, collider: bool) -> Usd.Prim | None:
    m, stage = ctx.model, ctx.stage
    kind, size = int(m.geom_type[g]), m.geom_size[g]
    scale = None
    if kind == GEOM.mjGEOM_BOX:
        shape = UsdGeom.Cube.Define(stage, path)
        shape.CreateSizeAttr(2.0)  # a cube of half-extent 1, scaled by MuJoCo's half-extents
        scale = size
    elif kind == GEOM.mjGEOM_SPHERE:
        shape = UsdGeom.Sphere.Define(stage, path)
        shape.CreateRadiusAttr(float(size[0]))
    elif kind in (GEOM.mjGEOM_CYLINDER, GEOM.mjGEOM_CAPSULE):
        shape = (UsdGeom.Cylinder if kind == GEOM.mjGEOM_CYLINDER else UsdGeom.Capsule).Define(stage, path)
        shape.CreateRadiusAttr(float(size[0]))
        shape.CreateHeightAttr(float(2 * size[1]))  # the capsule's height excludes its caps, as in MuJoCo
        shape.CreateAxisAttr(UsdGeom.Tokens.z)
    elif kind == GEOM.mjGEOM_PLANE:
        shape = UsdGeom.Plane.Define(stage, path)
        shape.CreateAxisAttr(UsdGeom.Tokens.z)
        # MuJoCo planes collide as infinite planes; size only sets the rendered extent.
        shape.CreateWidthAttr(float(2 * size[0]) if size[0] > 0 else 100.0)
        shape.CreateLengthAttr(float(2 * size[1]) if size[1] > 0 else 100.0)
    elif kind == GEOM.mjGEOM_MESH:
        shape = _mesh(ctx, path, int(m.geom_dataid[g]))
        if collider:
            UsdPhysics.MeshCollisionAPI.Apply(shape.GetPrim()).CreateApproximationAttr(UsdPhysics.Tokens.convexHull)
            count = int(m.mesh_vertnum[m.geom_dataid[g]])
            if count > PHYSX_HULL_VERTEX_LIMIT:
                ctx.lose(
                    name,
                    f"collision mesh of {count} vertices",
                    f"approximated: PhysX reduces convex hulls to {PHYSX_HULL_VERTEX_LIMIT} vertices",
                )
    else:
        ctx.lose(name, f"geom type {GEOM(kind).name}", "dropped")
        return None
    set_pose(shape, pose[0], pose[1], scale)
    return shape.GetPrim()


def _mesh(ctx: ExportContext, path: Sdf.Path, mesh_id: int) -> UsdGeom.Mesh:
    """A triangle mesh from the compiled model: vertices in the geom frame (MuJoCo recentres
    meshes at compile time and moves the geom frame to match)."""
    m = ctx.model
    v0, nv = int(m.mesh_vertadr[mesh_id]), int(m.mesh_vertnum[mesh_id])
    f0, nf = int(m.mesh_faceadr[mesh_id]), int(m.mesh_facenum[mesh_id])
    points = m.mesh_vert[v0 : v0 + nv]
    faces = m.mesh_face[f0 : f0 + nf]
    mesh = UsdGeom.Mesh.Define(ctx.stage, path)
    mesh.CreatePointsAttr(Vt.Vec3fArray.FromNumpy(points.astype(np.float32)))
    mesh.CreateFaceVertexCountsAttr(Vt.IntArray([3] * nf))
    mesh.CreateFaceVertexIndicesAttr(Vt.IntArray.FromNumpy(faces.astype(np.int32).ravel()))
    mesh.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.none)
    lo, hi = points.min(axis=0), points.max(axis=0)
    mesh.CreateExtentAttr(Vt.Vec3fArray([Gf.Vec3f(*map(float, lo)), Gf.Vec3f(*map(float, hi))]))
    return mesh


def _friction_materials(ctx: ExportContext) -> dict[float, UsdShade.Material]:
    """One physics material per distinct sliding friction of the colliders."""
    m = ctx.model
    values = sorted({float(m.geom_friction[g][0]) for g in range(m.ngeom) if is_collider(m, g)})
    materials = {}
    if values:
        scope = UsdGeom.Scope.Define(ctx.stage, ctx.child_path(ctx.root, "physics_materials")).GetPath()
        for mu in values:
            material = UsdShade.Material.Define(ctx.stage, ctx.child_path(scope, f"friction_{mu:g}".replace(".", "_")))
            api = UsdPhysics.MaterialAPI.Apply(material.GetPrim())
            api.CreateStaticFrictionAttr(mu)
            api.CreateDynamicFrictionAttr(mu)
            api.CreateRestitutionAttr(0.0)
            materials[mu] = material
        ctx.notes.append(
            "friction: MuJoCo combines two geoms' friction by their maximum; PhysX averages "
            "by default (set PhysxMaterialAPI frictionCombineMode to max to match)"
        )
    return materials


def _self_collision_group(ctx: ExportContext, colliders: dict[int, Sdf.Path]) -> None:
    """MuJoCo's contype/conaffinity bits decide which geom pairs may touch. When no pair of the
    moving bodies' colliders can, they form one collision group that filters itself, and still
    collide with the world (ground, obstacles)."""
    if not colliders:
        return
    m = ctx.model
    g = np.array(list(colliders))
    contype, conaffinity, weld = m.geom_contype[g], m.geom_conaffinity[g], m.body_weldid[m.geom_bodyid[g]]
    pairs = (contype[:, None] & conaffinity[None, :]) != 0
    touching = ((pairs | pairs.T) & (weld[:, None] != weld[None, :])).any()
    if touching:
        ctx.notes.append(
            "self-collision: some colliders of different bodies may touch (contype/conaffinity); "
            "PhysX's articulation self-collision filtering may differ from MuJoCo's parent-child rule"
        )
        return
    group = UsdPhysics.CollisionGroup.Define(ctx.stage, ctx.child_path(ctx.root, "self_collisions"))
    group.CreateFilteredGroupsRel().SetTargets([group.GetPath()])
    collection = group.GetCollidersCollectionAPI()
    collection.CreateIncludesRel().SetTargets(list(colliders.values()))


def _report_contact_settings(ctx: ExportContext) -> None:
    m = ctx.model
    colliders = [g for g in range(m.ngeom) if is_collider(m, g)]
    if colliders:
        torsion = sorted({(float(m.geom_friction[g][1]), float(m.geom_friction[g][2])) for g in colliders})
        ctx.lose(
            f"geoms ({len(colliders)} colliders)",
            "torsional and rolling friction "
            + ", ".join(f"({a:g}, {b:g})" for a, b in torsion)
            + "; contact softness solref/solimp; condim; margins",
        )
    if m.npair or m.nexclude:
        ctx.lose("contact", f"{m.npair} explicit contact pairs, {m.nexclude} exclusions", "dropped")
