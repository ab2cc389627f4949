"""Checks of an exported stage: usd-core's validators, and a comparison with the compiled MuJoCo
model it came from, computed independently of the exporter (numpy sums here, Pinocchio there).

UsdPhysics stores masses, inertias, joint frames, limits and gains as 32-bit floats, so a value
read back equals the MuJoCo value to float32 rounding (relative 6e-8), not to double precision.
"""

from __future__ import annotations

from typing import Any

import mujoco
import numpy as np
from pxr import Gf, Usd, UsdGeom, UsdPhysics, UsdValidation

from footforge import units
from footforge.models import massprops
from footforge.usd.context import mj_name
from footforge.usd.joints import AXES, servo_joint

VALIDATOR_KEYWORDS = ("UsdCoreValidators", "UsdGeomValidators", "UsdPhysicsValidators", "UsdShadeValidators")
FLOAT32_RTOL = 2.0**-23
"""One float32 ulp, relative: the precision of every UsdPhysics float attribute."""


def validate_stage(stage: Usd.Stage) -> list[dict]:
    """Runs usd-core's core, geometry, shading and physics validators; returns their findings."""
    registry = UsdValidation.ValidationRegistry()
    names = sorted({meta.name for kw in VALIDATOR_KEYWORDS for meta in registry.GetValidatorMetadataForKeyword(kw)})
    context = UsdValidation.ValidationContext(registry.GetOrLoadValidatorsByName(names))
    findings = []
    for error in context.Validate(stage):
        findings.append(
            {
                "severity": str(error.GetType()).rsplit(".", 1)[-1].lower(),
                "name": str(error.GetName()),
                "message": error.GetMessage(),
                "prims": [str(site.GetPrim().GetPath()) for site in error.GetSites() if site.GetPrim()],
            }
        )
    return findings


def _pose(cache: UsdGeom.XformCache, prim: Usd.Prim) -> tuple[np.ndarray, np.ndarray]:
    """World (position, rotation matrix) of a prim, double precision (column-vector convention)."""
    m = cache.GetLocalToWorldTransform(prim)
    return np.array(m.ExtractTranslation()), np.array(m.ExtractRotationMatrix()).T


def _rotation(q: Gf.Quatf | Gf.Quatd) -> np.ndarray:
    return np.array(Gf.Matrix3d(Gf.Rotation(Gf.Quatd(q)))).T


def read_stage(stage: Usd.Stage) -> dict:
    """Bodies and joints as UsdPhysics parses them, with world poses and mass properties."""
    parsed = UsdPhysics.UsdPhysicsLoadStageFromPrimRange(stage, [str(stage.GetDefaultPrim().GetPath())])
    cache = UsdGeom.XformCache()
    out: dict[str, Any] = {"bodies": {}, "joints": {}, "articulation_roots": []}
    for kind, (paths, descs) in parsed.items():
        for path, desc in zip(paths, descs):
            prim = stage.GetPrimAtPath(path)
            name = prim.GetCustomDataByKey("footforge:mjcfName")
            if kind == UsdPhysics.ObjectType.RigidBody:
                mass = UsdPhysics.MassAPI(prim)
                pos, R = _pose(cache, prim)
                out["bodies"][name] = {
                    "path": str(path),
                    "position": pos,
                    "rotation": R,
                    "mass": mass.GetMassAttr().Get(),
                    "com": np.array(mass.GetCenterOfMassAttr().Get()),
                    "diagonal_inertia": np.array(mass.GetDiagonalInertiaAttr().Get()),
                    "principal_axes": _rotation(mass.GetPrincipalAxesAttr().Get()),
                }
            elif kind == UsdPhysics.ObjectType.Articulation:
                out["articulation_roots"] += [str(p) for p in desc.rootPrims]
            elif hasattr(desc, "localPose0Position"):
                # Read what was authored, not the parser's normalised copy (it may swap the bodies).
                authored = UsdPhysics.Joint(prim)
                joint: dict[str, Any] = {
                    "path": str(path),
                    "type": str(kind).rsplit(".", 1)[-1],
                    "exclude": bool(authored.GetExcludeFromArticulationAttr().Get()),
                    "frames": [],
                }
                for rel, lp, lr in (
                    (authored.GetBody0Rel(), authored.GetLocalPos0Attr(), authored.GetLocalRot0Attr()),
                    (authored.GetBody1Rel(), authored.GetLocalPos1Attr(), authored.GetLocalRot1Attr()),
                ):
                    targets = rel.GetTargets()
                    bp, bR = _pose(cache, stage.GetPrimAtPath(targets[0])) if targets else (np.zeros(3), np.eye(3))
                    joint["frames"].append((bp + bR @ np.array(lp.Get()), bR @ _rotation(lr.Get())))
                usd_joint = (
                    UsdPhysics.RevoluteJoint(prim)
                    if prim.IsA(UsdPhysics.RevoluteJoint)
                    else (UsdPhysics.PrismaticJoint(prim) if prim.IsA(UsdPhysics.PrismaticJoint) else None)
                )
                if usd_joint is not None:
                    joint["axis"] = AXES[usd_joint.GetAxisAttr().Get()]
                    lo, hi = usd_joint.GetLowerLimitAttr(), usd_joint.GetUpperLimitAttr()
                    joint["limits"] = (lo.Get(), hi.Get()) if lo.HasAuthoredValue() else None
                    drive = UsdPhysics.DriveAPI(prim, "angular" if prim.IsA(UsdPhysics.RevoluteJoint) else "linear")
                    if drive:
                        joint["drive"] = {
                            "stiffness": drive.GetStiffnessAttr().Get(),
                            "damping": drive.GetDampingAttr().Get(),
                            "targetPosition": drive.GetTargetPositionAttr().Get(),
                            "maxForce": drive.GetMaxForceAttr().Get(),
                        }
                out["joints"][name] = joint
    return out


def _group_mass_properties(model: mujoco.MjModel, data: mujoco.MjData, root: int):
    """Mass, world centre of mass and world inertia about it of a weld group (parallel axes)."""
    members = [b for b in range(1, model.nbody) if model.body_weldid[b] == root]
    masses = model.body_mass[members]
    total = float(masses.sum())
    com = (masses[:, None] * data.xipos[members]).sum(axis=0) / total if total else data.xpos[root].copy()
    inertia = np.zeros((3, 3))
    for b, mass in zip(members, masses):
        R = data.ximat[b].reshape(3, 3)
        r = data.xipos[b] - com
        inertia += R @ np.diag(model.body_inertia[b]) @ R.T + mass * (r @ r * np.eye(3) - np.outer(r, r))
    return total, com, inertia


def compare_with_model(stage: Usd.Stage, model: mujoco.MjModel, *, keyframe: str | None = None) -> dict:
    """The stage against the compiled model at `keyframe`: largest errors per quantity.

    Returns a dict of figures (relative for masses, inertias, limits and gains; metres and
    radians for anchors and axes) plus the lists of missing or extra bodies and joints.
    """
    data = massprops.at_keyframe(model, keyframe)
    usd = read_stage(stage)

    def name(obj, i):  # the exporter's names, fallbacks for unnamed elements included
        return mj_name(
            model,
            obj,
            i,
            {
                mujoco.mjtObj.mjOBJ_BODY: "body",
                mujoco.mjtObj.mjOBJ_JOINT: "joint",
                mujoco.mjtObj.mjOBJ_EQUALITY: "equality",
            }[obj],
        )

    roots = {name(mujoco.mjtObj.mjOBJ_BODY, b): b for b in range(1, model.nbody) if model.body_weldid[b] == b}
    out: dict[str, Any] = {
        "bodies_missing": sorted(set(roots) - set(usd["bodies"])),
        "bodies_extra": sorted(set(usd["bodies"]) - set(roots)),
        "mass_rel": 0.0,
        "com_m": 0.0,
        "principal_inertia_rel": 0.0,
        "inertia_tensor_rel": 0.0,
    }
    for body_name, b in roots.items():
        u = usd["bodies"].get(body_name)
        if u is None:
            continue
        mass, com, inertia = _group_mass_properties(model, data, b)
        out["mass_rel"] = max(out["mass_rel"], abs(u["mass"] - mass) / mass)
        out["com_m"] = max(out["com_m"], float(np.linalg.norm(u["position"] + u["rotation"] @ u["com"] - com)))
        R = u["rotation"] @ u["principal_axes"]
        usd_inertia = R @ np.diag(u["diagonal_inertia"]) @ R.T
        scale = np.linalg.norm(inertia)
        moments = np.linalg.eigvalsh(inertia)
        out["principal_inertia_rel"] = max(
            out["principal_inertia_rel"],
            float(np.max(np.abs(np.sort(u["diagonal_inertia"]) - moments) / moments.max())),
        )
        out["inertia_tensor_rel"] = max(out["inertia_tensor_rel"], float(np.linalg.norm(usd_inertia - inertia) / scale))

    kinds = {
        int(mujoco.mjtJoint.mjJNT_HINGE): "RevoluteJoint",
        int(mujoco.mjtJoint.mjJNT_SLIDE): "PrismaticJoint",
        int(mujoco.mjtJoint.mjJNT_BALL): "SphericalJoint",
    }
    expected: dict[str, int] = {}
    for j in range(model.njnt):
        if int(model.jnt_type[j]) in kinds:
            expected[kinds[int(model.jnt_type[j])]] = expected.get(kinds[int(model.jnt_type[j])], 0) + 1
    closures = sum(int(model.eq_type[e]) == mujoco.mjtEq.mjEQ_CONNECT for e in range(model.neq))
    if closures:
        expected["SphericalJoint (loop closure)"] = int(closures)
    counted: dict[str, int] = {}
    for j in usd["joints"].values():
        key = j["type"] + (" (loop closure)" if j["type"] == "SphericalJoint" and j["exclude"] else "")
        counted[key] = counted.get(key, 0) + 1
    out["joint_counts"] = {"mjcf": expected, "usd": counted}
    out.update(anchor_m=0.0, axis_rad=0.0, limit_rel=0.0, gain_rel=0.0, closure_anchor_m=0.0)
    for j in range(model.njnt):
        if int(model.jnt_type[j]) not in (mujoco.mjtJoint.mjJNT_HINGE, mujoco.mjtJoint.mjJNT_SLIDE):
            continue
        u = usd["joints"].get(name(mujoco.mjtObj.mjOBJ_JOINT, j))
        if u is None:
            out.setdefault("joints_missing", []).append(name(mujoco.mjtObj.mjOBJ_JOINT, j))
            continue
        revolute = int(model.jnt_type[j]) == mujoco.mjtJoint.mjJNT_HINGE
        # Both sides of a revolute joint share its anchor; a prismatic joint's child side has slid
        # by q - qpos0 from it (MuJoCo's xanchor is the parent side's).
        slid = 0.0 if revolute else float(data.qpos[model.jnt_qposadr[j]] - model.qpos0[model.jnt_qposadr[j]])
        for (pos, R), shift in zip(u["frames"], (0.0, slid)):
            anchor = data.xanchor[j] + shift * data.xaxis[j]
            out["anchor_m"] = max(out["anchor_m"], float(np.linalg.norm(pos - anchor)))
            cos = np.clip(float((R @ u["axis"]) @ data.xaxis[j]), -1.0, 1.0)
            out["axis_rad"] = max(out["axis_rad"], float(np.arccos(cos)))
        if model.jnt_limited[j]:
            q0 = model.qpos0[model.jnt_qposadr[j]]
            lo, hi = (units.deg_to_rad(v) if revolute else v for v in u["limits"])
            span = max(abs(model.jnt_range[j]).max(), 1e-9)
            out["limit_rel"] = max(
                out["limit_rel"], float(np.abs(np.array([lo, hi]) + q0 - model.jnt_range[j]).max() / span)
            )
        in_tendon = any(
            model.wrap_objid[w] == j and int(model.wrap_type[w]) == mujoco.mjtWrap.mjWRAP_JOINT
            for w in range(model.nwrap)
        )
        servos = [a for a in range(model.nu) if servo_joint(model, a) == j]  # the ones a drive carries
        want = {
            "stiffness": model.jnt_stiffness[j] + sum(model.actuator_gainprm[a][0] for a in servos),
            "damping": model.dof_damping[model.jnt_dofadr[j]] - sum(model.actuator_biasprm[a][2] for a in servos),
        }
        if in_tendon:
            want.pop("stiffness")  # the tendon's share is an approximation, reported as such
        for key, value in want.items():
            if value:
                got = u.get("drive", {}).get(key, 0.0)
                got = units.gain_per_rad(got) if revolute else got
                out["gain_rel"] = max(out["gain_rel"], abs(got - value) / value)
    for e in range(model.neq):
        if int(model.eq_type[e]) == mujoco.mjtEq.mjEQ_CONNECT and int(model.eq_objtype[e]) == mujoco.mjtObj.mjOBJ_SITE:
            u = usd["joints"].get(name(mujoco.mjtObj.mjOBJ_EQUALITY, e))
            for pos, _ in u["frames"] if u else []:
                site = data.site_xpos[model.eq_obj1id[e]]
                out["closure_anchor_m"] = max(out["closure_anchor_m"], float(np.linalg.norm(pos - site)))
    out["articulation_roots"] = usd["articulation_roots"]
    return out


TOLERANCES = {
    "mass_rel": 2 * FLOAT32_RTOL,
    "principal_inertia_rel": 2 * FLOAT32_RTOL,
    "limit_rel": 2 * FLOAT32_RTOL,
    "gain_rel": 2 * FLOAT32_RTOL,
    "inertia_tensor_rel": 1e-6,
    "com_m": 1e-6,
    "anchor_m": 1e-6,
    "axis_rad": 1e-6,
    "closure_anchor_m": 1e-6,
}
"""Largest accepted differences: float32 rounding for values stored as one float attribute;
1e-6 (m, rad, relative) for quantities composed from several (a pose times a local frame)."""


def comparison_failures(comparison: dict) -> list[str]:
    """What in a `compare_with_model` result exceeds TOLERANCES or does not match; empty if fine."""
    failures = [
        f"{key} = {comparison[key]:.3g} > {limit:.3g}" for key, limit in TOLERANCES.items() if comparison[key] > limit
    ]
    for key in ("bodies_missing", "bodies_extra", "joints_missing"):
        if comparison.get(key):
            failures.append(f"{key}: {', '.join(comparison[key])}")
    counts = comparison["joint_counts"]
    if counts["mjcf"] != counts["usd"]:
        failures.append(f"joint counts differ: MJCF {counts['mjcf']}, USD {counts['usd']}")
    return failures
