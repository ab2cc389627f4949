"""Joints and drives; loop closures, couplings and tendon springs, carried where UsdPhysics can.

Conventions. A USD joint's angle is zero when its two local frames coincide; MuJoCo's hinge
angle is zero at qpos0 (the joint's `ref`), where the child sits at body_pos/body_quat in its
parent. So localPose1 is the joint frame in the child body, localPose0 the same frame seen from
the parent at qpos0, and limits and targets are shifted by qpos0. The joint axis must be a token
(X, Y or Z): a frame whose X axis is the MuJoCo axis is used when the axis is not a coordinate
axis. Bodies are authored at the home pose, from which an engine reads the initial joint angles.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import mujoco
import numpy as np
from pxr import Gf, Sdf, UsdGeom, UsdPhysics, Vt

from footforge import units
from footforge.usd.bodies import body_in_group_frame, site_in_body_frame
from footforge.usd.context import IDENTITY_QUAT, ExportContext, mj_name, mul_pose, neg_pose

AXES = {"X": np.array([1.0, 0, 0]), "Y": np.array([0, 1.0, 0]), "Z": np.array([0, 0, 1.0])}
"""UsdPhysics joint axis tokens and the unit vectors they stand for (in the joint frame)."""
JNT = mujoco.mjtJoint


def axis_frame(axis: np.ndarray) -> tuple[str, np.ndarray]:
    """(token, wxyz rotation of the joint frame in the body) so that the token's axis of the
    rotated frame is `axis`. Coordinate axes keep an identity frame, for readable output."""
    a = np.asarray(axis, float) / np.linalg.norm(axis)
    for token, e in AXES.items():
        if np.allclose(a, e, rtol=0, atol=1e-12):
            return token, IDENTITY_QUAT.copy()
    x = AXES["X"]
    w = 1.0 + float(x @ a)
    if w < 1e-12:  # -X: half a turn about Z
        return "X", np.array([0.0, 0, 0, 1.0])
    q = np.concatenate([[w], np.cross(x, a)])
    return "X", q / np.linalg.norm(q)


@dataclass
class DriveTerms:
    """Springs and dampers acting on one joint, in MuJoCo units, summed into one USD drive."""

    springs: list[tuple[float, float]] = field(default_factory=list)
    """(stiffness per rad or per m, target joint position in rad or m)."""
    damping: float = 0.0
    max_force: float | None = None
    role: str = "passive"

    def add_spring(self, stiffness: float, target: float) -> None:
        if stiffness:
            self.springs.append((float(stiffness), float(target)))

    @property
    def stiffness(self) -> float:
        return sum(k for k, _ in self.springs)

    @property
    def target(self) -> float:
        """One spring equivalent to the sum: sum(k_i (t_i - q)) = K (t - q)."""
        k = self.stiffness
        return sum(k_i * t_i for k_i, t_i in self.springs) / k if k else 0.0


def add_joints(ctx: ExportContext) -> dict[int, Sdf.Path]:
    """Defines a USD joint per MuJoCo hinge/slide/ball joint; returns joint id -> prim path."""
    m = ctx.model
    # Named after the bodies exist, so a body called "joints" keeps its name and this moves aside.
    scope = ctx.joints_scope = UsdGeom.Scope.Define(ctx.stage, ctx.child_path(ctx.root, "joints")).GetPath()
    terms = _drive_terms(ctx)
    paths: dict[int, Sdf.Path] = {}
    for b in range(1, m.nbody):
        count = int(m.body_jntnum[b])
        if count == 0:
            continue
        j = int(m.body_jntadr[b])
        if count > 1:
            ctx.lose(
                f"body '{mj_name(m, mujoco.mjtObj.mjOBJ_BODY, b, 'body')}'",
                f"{count} joints on one body; USD needs one joint per body pair (only the first is exported)",
            )
        if int(m.jnt_type[j]) == JNT.mjJNT_FREE:
            continue  # a floating base: no joint, the articulation root is on the body
        paths[j] = _add_joint(ctx, scope, j, terms.get(j))
    return paths


def _add_joint(ctx: ExportContext, scope: Sdf.Path, j: int, terms: DriveTerms | None) -> Sdf.Path:
    m = ctx.model
    b, parent = int(m.jnt_bodyid[j]), int(m.body_parentid[m.jnt_bodyid[j]])
    name = mj_name(m, mujoco.mjtObj.mjOBJ_JOINT, j, "joint")
    kind = int(m.jnt_type[j])
    token, rot = axis_frame(m.jnt_axis[j])
    frame1 = (m.jnt_pos[j].copy(), rot)
    frame0 = mul_pose(mul_pose(body_in_group_frame(ctx, parent), (m.body_pos[b], m.body_quat[b])), frame1)
    path = ctx.child_path(scope, name)
    if kind == JNT.mjJNT_HINGE:
        joint = UsdPhysics.RevoluteJoint.Define(ctx.stage, path)
    elif kind == JNT.mjJNT_SLIDE:
        joint = UsdPhysics.PrismaticJoint.Define(ctx.stage, path)
    else:
        joint = UsdPhysics.SphericalJoint.Define(ctx.stage, path)
        if m.jnt_limited[j]:
            ctx.lose(
                f"joint '{name}'",
                f"ball joint limit {m.jnt_range[j][1]:g} rad",
                "dropped: MuJoCo limits the total rotation angle, USD a cone about the axis",
            )
    _connect(ctx, joint, parent, b, frame0, frame1)
    joint.CreateAxisAttr(token)
    prim = joint.GetPrim()
    prim.SetCustomDataByKey("footforge:mjcfName", name)
    revolute = kind == JNT.mjJNT_HINGE
    if kind in (JNT.mjJNT_HINGE, JNT.mjJNT_SLIDE):
        q0 = float(m.qpos0[m.jnt_qposadr[j]])
        if m.jnt_limited[j]:
            joint.CreateLowerLimitAttr(units.joint_coordinate_to_usd(m.jnt_range[j][0] - q0, revolute=revolute))
            joint.CreateUpperLimitAttr(units.joint_coordinate_to_usd(m.jnt_range[j][1] - q0, revolute=revolute))
        if terms is not None and (terms.stiffness or terms.damping):
            drive = UsdPhysics.DriveAPI.Apply(prim, "angular" if revolute else "linear")
            drive.CreateTypeAttr("force")
            drive.CreateStiffnessAttr(units.joint_gain_to_usd(terms.stiffness, revolute=revolute))
            drive.CreateDampingAttr(units.joint_gain_to_usd(terms.damping, revolute=revolute))
            drive.CreateTargetPositionAttr(units.joint_coordinate_to_usd(terms.target - q0, revolute=revolute))
            drive.CreateTargetVelocityAttr(0.0)
            if terms.max_force is not None:
                drive.CreateMaxForceAttr(float(terms.max_force))
            prim.SetCustomDataByKey("footforge:role", terms.role)
        dof = int(m.jnt_dofadr[j])
        lost = [
            (key, label, float(value), unit)
            for key, label, value, unit in (
                ("frictionloss", "dry friction", m.dof_frictionloss[dof], "N m" if revolute else "N"),
                ("armature", "armature", m.dof_armature[dof], "kg m^2" if revolute else "kg"),
            )
            if value
        ]
        for key, _, value, _ in lost:
            prim.SetCustomDataByKey(f"footforge:{key}", value)
        if lost:
            ctx.lose(
                f"joint '{name}'",
                ", ".join(f"{label} {v:g} {u}" for _, label, v, u in lost),
                "recorded in customData only (PhysX: PhysxJointAPI jointFriction and armature)",
            )
    return path


def _connect(ctx: ExportContext, joint: UsdPhysics.Joint, body0: int, body1: int, frame0, frame1) -> None:
    """Body relationships and local frames; a body welded to the world is left as the world."""
    m = ctx.model
    if m.body_weldid[body0] != 0:
        joint.CreateBody0Rel().SetTargets([ctx.body_paths[body0]])
    joint.CreateBody1Rel().SetTargets([ctx.body_paths[body1]])
    for pos_attr, rot_attr, (pos, quat) in (
        (joint.CreateLocalPos0Attr, joint.CreateLocalRot0Attr, frame0),
        (joint.CreateLocalPos1Attr, joint.CreateLocalRot1Attr, frame1),
    ):
        pos_attr(Gf.Vec3f(*map(float, pos)))
        rot_attr(Gf.Quatf(float(quat[0]), Gf.Vec3f(*map(float, quat[1:]))))


def _drive_terms(ctx: ExportContext) -> dict[int, DriveTerms]:
    """Per joint: its own spring and damper, position servos acting on it, tendon springs."""
    m = ctx.model
    terms: dict[int, DriveTerms] = {}
    for j in range(m.njnt):
        if int(m.jnt_type[j]) in (JNT.mjJNT_HINGE, JNT.mjJNT_SLIDE):
            t = terms[j] = DriveTerms(damping=float(m.dof_damping[m.jnt_dofadr[j]]))
            t.add_spring(m.jnt_stiffness[j], m.qpos_spring[m.jnt_qposadr[j]])
    for a in range(m.nu):
        name = mj_name(m, mujoco.mjtObj.mjOBJ_ACTUATOR, a, "actuator")
        joint = servo_joint(m, a)
        if joint is None:
            ctx.lose(f"actuator '{name}'", "not a unit-gear position servo on a hinge or slide joint", "dropped")
            continue
        # The servo's target at the exported pose: the keyframe's ctrl, else the joint's angle there.
        target = ctx.data.ctrl[a] if ctx.keyframe is not None else ctx.data.qpos[m.jnt_qposadr[joint]]
        t = terms[joint]
        t.role = "actuated"
        t.add_spring(m.actuator_gainprm[a][0], target)
        t.damping += float(-m.actuator_biasprm[a][2])
        if m.actuator_forcelimited[a]:
            lo, hi = m.actuator_forcerange[a]
            t.max_force = float(max(-lo, hi))
            if lo != -hi:
                ctx.lose(
                    f"actuator '{name}'",
                    f"asymmetric force range [{lo:g}, {hi:g}]",
                    f"approximated: USD maxForce {t.max_force:g} both ways",
                )
    _tendon_springs(ctx, terms)
    return terms


def servo_joint(model: mujoco.MjModel, actuator: int) -> int | None:
    """The hinge or slide joint `actuator` drives when it is a unit-gear position servo (what a
    USD drive can carry: kp (q* - q) - kv qd), else None."""
    m, a = model, actuator
    j = int(m.actuator_trnid[a][0])
    servo = (
        int(m.actuator_trntype[a]) == mujoco.mjtTrn.mjTRN_JOINT
        and int(m.jnt_type[j]) in (JNT.mjJNT_HINGE, JNT.mjJNT_SLIDE)
        and int(m.actuator_gaintype[a]) == mujoco.mjtGain.mjGAIN_FIXED
        and int(m.actuator_biastype[a]) == mujoco.mjtBias.mjBIAS_AFFINE
        and m.actuator_biasprm[a][0] == 0
        and m.actuator_biasprm[a][1] == -m.actuator_gainprm[a][0]
        and m.actuator_gear[a][0] == 1.0
    )
    return j if servo else None


def _tendon_springs(ctx: ExportContext, terms: dict[int, DriveTerms]) -> None:
    """A fixed tendon spring E = k/2 (c.q - L0)^2 couples its joints; UsdPhysics has only per-joint
    drives. Each joint gets stiffness k|c|^2 about the target that makes the torque exact for any
    motion along c through the exported pose (both arches bending together, for the arch band);
    motion orthogonal to c, which the tendon leaves free, gets the same stiffness."""
    m, d = ctx.model, ctx.data
    for t in range(m.ntendon):
        name = mj_name(m, mujoco.mjtObj.mjOBJ_TENDON, t, "tendon")
        wraps = range(m.tendon_adr[t], m.tendon_adr[t] + m.tendon_num[t])
        fixed = all(int(m.wrap_type[w]) == mujoco.mjtWrap.mjWRAP_JOINT for w in wraps)
        k = float(m.tendon_stiffness[t])
        if not fixed:
            ctx.lose(f"tendon '{name}'", "spatial tendon", "dropped")
            continue
        if m.tendon_damping[t] or m.tendon_limited[t] or m.tendon_frictionloss[t]:
            ctx.lose(f"tendon '{name}'", "tendon damping, friction or length limit", "dropped")
        if not k:
            continue
        joints = [int(m.wrap_objid[w]) for w in wraps]
        c = np.array([m.wrap_prm[w] for w in wraps])
        q = np.array([d.qpos[m.jnt_qposadr[j]] for j in joints])
        lo, hi = m.tendon_lengthspring[t]
        length = float(c @ q)
        rest = min(max(length, lo), hi)  # MuJoCo's dead band [lo, hi]
        k_joint = k * float(c @ c)
        for j, c_i, q_i in zip(joints, c, q):
            terms[j].add_spring(k_joint, q_i - c_i * (length - rest) / float(c @ c))
        names = [mj_name(m, mujoco.mjtObj.mjOBJ_JOINT, j, "joint") for j in joints]
        ctx.lose(
            f"tendon '{name}'",
            f"fixed-tendon spring k={k:g} on {' + '.join(f'{ci:g}*{n}' for ci, n in zip(c, names))}",
            f"approximated: per-joint drives of stiffness {k_joint:g} per rad, exact along the tendon "
            "direction through the home pose, spurious for motion orthogonal to it "
            "(PhysX fixed tendons would be exact but are not in UsdPhysics)",
        )


def add_equalities(ctx: ExportContext, joint_paths: dict[int, Sdf.Path]) -> None:
    """connect -> spherical joint excluded from the articulation (PhysX articulations are trees);
    joint couplings and other kinds are reported."""
    m = ctx.model
    scope = ctx.joints_scope
    for e in range(m.neq):
        name = mj_name(m, mujoco.mjtObj.mjOBJ_EQUALITY, e, "equality")
        kind = int(m.eq_type[e])
        if kind == mujoco.mjtEq.mjEQ_CONNECT:
            _add_loop_closure(ctx, scope, e, name)
        elif kind == mujoco.mjtEq.mjEQ_JOINT:
            j1, j2 = int(m.eq_obj1id[e]), int(m.eq_obj2id[e])
            coef = m.eq_data[e][:5]
            n1 = mj_name(m, mujoco.mjtObj.mjOBJ_JOINT, j1, "joint")
            n2 = mj_name(m, mujoco.mjtObj.mjOBJ_JOINT, j2, "joint")
            relation = f"{n1} = {coef[0]:g} + {coef[1]:g}*{n2}" + (" + higher-order terms" if np.any(coef[2:]) else "")
            if j1 in joint_paths:
                prim = ctx.stage.GetPrimAtPath(joint_paths[j1])
                prim.SetCustomDataByKey("footforge:coupledTo", str(joint_paths.get(j2, n2)))
                prim.SetCustomDataByKey("footforge:couplingPolycoef", Vt.DoubleArray([float(x) for x in coef]))
            ctx.lose(
                f"equality '{name}'",
                f"joint coupling {relation}",
                "recorded in customData only: UsdPhysics has no coupling joint "
                "(in Isaac Sim, PhysxMimicJointAPI on the first joint expresses it)",
            )
        else:
            ctx.lose(f"equality '{name}'", f"{mujoco.mjtEq(kind).name} equality", "dropped")


def _add_loop_closure(ctx: ExportContext, scope: Sdf.Path, e: int, name: str) -> None:
    m, d = ctx.model, ctx.data
    if int(m.eq_objtype[e]) == mujoco.mjtObj.mjOBJ_SITE:
        s1, s2 = int(m.eq_obj1id[e]), int(m.eq_obj2id[e])
        b1, b2 = int(m.site_bodyid[s1]), int(m.site_bodyid[s2])
        p1, p2 = site_in_body_frame(ctx, s1)[0], site_in_body_frame(ctx, s2)[0]
    else:  # anchors given in each body's frame
        b1, b2 = int(m.eq_obj1id[e]), int(m.eq_obj2id[e])
        p1 = mul_pose(body_in_group_frame(ctx, b1), (m.eq_data[e][0:3], IDENTITY_QUAT))[0]
        p2 = mul_pose(body_in_group_frame(ctx, b2), (m.eq_data[e][3:6], IDENTITY_QUAT))[0]
    g1, g2 = int(m.body_weldid[b1]), int(m.body_weldid[b2])
    joint = UsdPhysics.SphericalJoint.Define(ctx.stage, ctx.child_path(scope, name))
    # Frames aligned with the world at the exported pose, so both sides agree on orientation.
    world_aligned = [neg_pose((np.zeros(3), d.xquat[g]))[1] for g in (g1, g2)]
    _connect(ctx, joint, b1, b2, (p1, world_aligned[0]), (p2, world_aligned[1]))
    joint.CreateExcludeFromArticulationAttr(True)
    prim = joint.GetPrim()
    prim.SetCustomDataByKey("footforge:mjcfName", name)
    prim.SetCustomDataByKey("footforge:role", "loop closure")
    if not m.eq_active0[e]:
        joint.CreateJointEnabledAttr(False)
