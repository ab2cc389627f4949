"""Rigid bodies: one USD rigid body per group of MuJoCo bodies welded together, mass in full.

MuJoCo lets a body without joints hang off its parent (an attachment frame, a foot mount); it
moves rigidly with the nearest jointed ancestor. USD/PhysX would give such a body a joint of its
own, and a massless one would get a mass computed from colliders (or 1 kg without colliders).
So each weld group becomes one rigid body named after its jointed root; its welded members'
geoms and sites keep their poses relative to it, and their masses are summed with Pinocchio's
spatial-inertia algebra. MassAPI is always authored in full: mass, centre of mass, diagonal
inertia and principal axes, so that no engine recomputes them from the colliders.
"""

from __future__ import annotations

import mujoco
import numpy as np
from pxr import Gf, UsdGeom, UsdPhysics, Vt

from footforge.models import massprops
from footforge.usd.context import IDENTITY_QUAT, ExportContext, Pose, mj_name, mul_pose, neg_pose


def body_in_group_frame(ctx: ExportContext, body: int) -> Pose:
    """Pose of `body` in the frame of its weld-group root (rigid, so read at the exported pose)."""
    m, d = ctx.model, ctx.data
    root = int(m.body_weldid[body])
    if root == body:
        return np.zeros(3), IDENTITY_QUAT.copy()
    return mul_pose(neg_pose((d.xpos[root], d.xquat[root])), (d.xpos[body], d.xquat[body]))


def set_pose(xformable: UsdGeom.Xformable, pos, quat_wxyz, scale=None) -> None:
    """translate, orient (and scale) ops in double precision."""
    xformable.AddTranslateOp(UsdGeom.XformOp.PrecisionDouble).Set(Gf.Vec3d(*map(float, pos)))
    q = np.asarray(quat_wxyz, float)
    xformable.AddOrientOp(UsdGeom.XformOp.PrecisionDouble).Set(Gf.Quatd(float(q[0]), Gf.Vec3d(*map(float, q[1:]))))
    if scale is not None:
        xformable.AddScaleOp(UsdGeom.XformOp.PrecisionDouble).Set(Gf.Vec3d(*map(float, scale)))


def add_bodies(ctx: ExportContext) -> None:
    """Defines a prim per weld group (world included, as a static Xform) and fills body_paths."""
    m, d, stage = ctx.model, ctx.data, ctx.stage
    world = UsdGeom.Xform.Define(stage, ctx.root.AppendChild("world"))
    world.GetPrim().SetCustomDataByKey("footforge:mjcfName", "world")
    ctx.body_paths[0] = world.GetPath()
    for b in range(1, m.nbody):
        if m.body_weldid[b] != b:
            continue
        name = mj_name(m, mujoco.mjtObj.mjOBJ_BODY, b, "body")
        xform = UsdGeom.Xform.Define(stage, ctx.child_path(ctx.root, name))
        set_pose(xform, d.xpos[b], d.xquat[b])
        prim = xform.GetPrim()
        members = [o for o in range(1, m.nbody) if m.body_weldid[o] == b]
        prim.SetCustomDataByKey("footforge:mjcfName", name)
        if len(members) > 1:
            prim.SetCustomDataByKey(
                "footforge:weldedBodies",
                Vt.StringArray([mj_name(m, mujoco.mjtObj.mjOBJ_BODY, o, "body") for o in members]),
            )
        UsdPhysics.RigidBodyAPI.Apply(prim)
        _author_mass(ctx, prim, b, len(members))
        ctx.body_paths[b] = xform.GetPath()
    for b in range(1, m.nbody):  # welded members resolve to their group's prim
        ctx.body_paths.setdefault(b, ctx.body_paths[int(m.body_weldid[b])])


def _author_mass(ctx: ExportContext, prim, body: int, members: int) -> None:
    m, d = ctx.model, ctx.data
    if members == 1:  # a body on its own: MuJoCo's compiled principal frame, exactly as simulated
        total = float(m.body_mass[body])
        com_local, moments, axes = m.body_ipos[body], m.body_inertia[body], m.body_iquat[body]
    else:
        group = massprops.weld_group_inertia(m, d, body)
        total = float(group.mass)
        com_local = mul_pose(neg_pose((d.xpos[body], d.xquat[body])), (np.asarray(group.lever), IDENTITY_QUAT))[0]
        R = d.xmat[body].reshape(3, 3)
        moments, axes = massprops.principal_axes(R.T @ np.asarray(group.inertia) @ R)
    mass = UsdPhysics.MassAPI.Apply(prim)
    mass.CreateMassAttr(total)
    mass.CreateCenterOfMassAttr(Gf.Vec3f(*map(float, com_local)))
    mass.CreateDiagonalInertiaAttr(Gf.Vec3f(*map(float, moments)))
    mass.CreatePrincipalAxesAttr(Gf.Quatf(float(axes[0]), Gf.Vec3f(*map(float, axes[1:]))))


def add_sites(ctx: ExportContext) -> None:
    """Sites (IMU, touchdown points, foot mounts) as plain Xforms under their body: frames that
    Isaac users can attach sensors to. They carry no physics."""
    m = ctx.model
    for s in range(m.nsite):
        b = int(m.site_bodyid[s])
        name = mj_name(m, mujoco.mjtObj.mjOBJ_SITE, s, "site")
        pos, quat = site_in_body_frame(ctx, s)
        parent = ctx.body_paths[b].AppendChild("sites")
        if not ctx.stage.GetPrimAtPath(parent):
            UsdGeom.Scope.Define(ctx.stage, parent)
        xform = UsdGeom.Xform.Define(ctx.stage, ctx.child_path(parent, name))
        set_pose(xform, pos, quat)
        xform.GetPrim().SetCustomDataByKey("footforge:mjcfName", name)


def site_in_body_frame(ctx: ExportContext, site: int) -> Pose:
    """A site's pose in the frame of the USD body that carries it."""
    m = ctx.model
    b = int(m.site_bodyid[site])
    return mul_pose(body_in_group_frame(ctx, b), (m.site_pos[site], m.site_quat[site]))
