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

from footforge import massprops
from footforge.usd.context import ExportContext, quat_conj, quat_mul, quat_rotate


def body_in_group_frame(ctx: ExportContext, body: int) -> tuple[np.ndarray, np.ndarray]:
    """Pose (pos, wxyz quat) of `body` in the frame of its weld-group root (rigid, so read at
    the exported pose)."""
    m, d = ctx.model, ctx.data
    root = int(m.body_weldid[body])
    if root == body:
        return np.zeros(3), np.array([1.0, 0, 0, 0])
    inv = quat_conj(d.xquat[root])
    return quat_rotate(inv, d.xpos[body] - d.xpos[root]), quat_mul(inv, d.xquat[body])


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
        name = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_BODY, b) or f"body_{b}"
        xform = UsdGeom.Xform.Define(stage, ctx.child_path(ctx.root, name))
        set_pose(xform, d.xpos[b], d.xquat[b])
        prim = xform.GetPrim()
        members = [mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_BODY, o) or f"body_{o}"
                   for o in range(1, m.nbody) if m.body_weldid[o] == b]
        prim.SetCustomDataByKey("footforge:mjcfName", name)
        if len(members) > 1:
            prim.SetCustomDataByKey("footforge:weldedBodies", Vt.StringArray(members))
        UsdPhysics.RigidBodyAPI.Apply(prim)
        _author_mass(ctx, prim, b)
        ctx.body_paths[b] = xform.GetPath()
    for b in range(1, m.nbody):  # welded members resolve to their group's prim
        ctx.body_paths.setdefault(b, ctx.body_paths[int(m.body_weldid[b])])
    free = [int(m.jnt_bodyid[j]) for j in range(m.njnt) if int(m.jnt_type[j]) == mujoco.mjtJoint.mjJNT_FREE]
    for b in free:
        UsdPhysics.ArticulationRootAPI.Apply(stage.GetPrimAtPath(ctx.body_paths[b]))


def _author_mass(ctx: ExportContext, prim, body: int) -> None:
    m, d = ctx.model, ctx.data
    group = massprops.weld_group_inertia(m, d, body)
    inv = quat_conj(d.xquat[body])
    com_local = quat_rotate(inv, np.asarray(group.lever) - d.xpos[body])
    R = d.xmat[body].reshape(3, 3)
    inertia_local = R.T @ np.asarray(group.inertia) @ R
    if np.count_nonzero(m.body_weldid[1:] == body) == 1:
        # A body on its own: MuJoCo's compiled principal frame, exactly as simulated.
        moments, axes = m.body_inertia[body].copy(), m.body_iquat[body].copy()
        com_local = m.body_ipos[body].copy()
    else:
        moments, axes = massprops.principal_axes(inertia_local)
    mass = UsdPhysics.MassAPI.Apply(prim)
    mass.CreateMassAttr(float(group.mass))
    mass.CreateCenterOfMassAttr(Gf.Vec3f(*map(float, com_local)))
    mass.CreateDiagonalInertiaAttr(Gf.Vec3f(*map(float, moments)))
    mass.CreatePrincipalAxesAttr(Gf.Quatf(float(axes[0]), Gf.Vec3f(*map(float, axes[1:]))))


def add_sites(ctx: ExportContext) -> None:
    """Sites (IMU, touchdown points, foot mounts) as plain Xforms under their body: frames that
    Isaac users can attach sensors to. They carry no physics."""
    m = ctx.model
    for s in range(m.nsite):
        b = int(m.site_bodyid[s])
        name = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_SITE, s) or f"site_{s}"
        pos, quat = site_in_body_frame(ctx, s)
        parent = ctx.body_paths[b].AppendChild("sites")
        if not ctx.stage.GetPrimAtPath(parent):
            UsdGeom.Scope.Define(ctx.stage, parent)
        xform = UsdGeom.Xform.Define(ctx.stage, ctx.child_path(parent, name))
        set_pose(xform, pos, quat)
        xform.GetPrim().SetCustomDataByKey("footforge:mjcfName", name)


def site_in_body_frame(ctx: ExportContext, site: int) -> tuple[np.ndarray, np.ndarray]:
    """A site's pose in the frame of the USD body that carries it."""
    m = ctx.model
    b = int(m.site_bodyid[site])
    return compose(body_in_group_frame(ctx, b), (m.site_pos[site], m.site_quat[site]))


def compose(a: tuple[np.ndarray, np.ndarray], b: tuple[np.ndarray, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """Pose a * pose b, each (pos, wxyz quat)."""
    return a[0] + quat_rotate(a[1], b[0]), quat_mul(a[1], b[1])

