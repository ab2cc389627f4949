"""Mass properties of compiled MuJoCo models, summed with Pinocchio's spatial-inertia algebra."""

from __future__ import annotations

from typing import Any

import mujoco
import numpy as np
import pinocchio as pin

from footforge.inputs.inertia import principal_moments


def body_inertia_world(model: mujoco.MjModel, data: mujoco.MjData, body_id: int) -> pin.Inertia:
    """Spatial inertia of one body in world coordinates (after mj_kinematics)."""
    R = data.ximat[body_id].reshape(3, 3)
    local = pin.Inertia(float(model.body_mass[body_id]), np.zeros(3), np.diag(model.body_inertia[body_id]))
    return pin.SE3(R, data.xipos[body_id].copy()).act(local)


def subtree_inertia(model: mujoco.MjModel, data: mujoco.MjData, body_id: int) -> pin.Inertia:
    """Composite spatial inertia of `body_id` and all its descendants, world coordinates."""
    total = pin.Inertia.Zero()
    for b in range(1, model.nbody):  # the world body has no mass
        a = b
        while a != body_id and a > 0:
            a = model.body_parentid[a]
        if a == body_id:
            total += body_inertia_world(model, data, b)
    return total


def at_keyframe(model: mujoco.MjModel, key: str | None, *, free_joint_qpos=None) -> mujoco.MjData:
    """Data at keyframe `key` (None: qpos0) after kinematics; `free_joint_qpos` (7) overrides
    the root pose."""
    data = mujoco.MjData(model)
    if key is not None:
        mujoco.mj_resetDataKeyframe(model, data, model.key(key).id)
    if free_joint_qpos is not None:
        data.qpos[:7] = free_joint_qpos
    mujoco.mj_kinematics(model, data)
    return data


def summary(inertia: pin.Inertia) -> dict:
    """Total mass (kg), centre of mass (m) and centroidal inertia (kg m^2, world axes)."""
    return {
        "mass_kg": float(inertia.mass),
        "com_m": np.array(inertia.lever).tolist(),
        "centroidal_inertia_kgm2": np.array(inertia.inertia).tolist(),
    }


def weld_group_inertia(model: mujoco.MjModel, data: mujoco.MjData, root_id: int) -> pin.Inertia:
    """Composite spatial inertia (world coordinates) of the bodies MuJoCo welds to `root_id`:
    the bodies without joints of their own between it and the next jointed body. Together they
    move as one rigid body, which is what a USD or PhysX rigid body represents."""
    total = pin.Inertia.Zero()
    for b in range(1, model.nbody):
        if model.body_weldid[b] == root_id:
            total += body_inertia_world(model, data, b)
    return total


def principal_axes(inertia_3x3: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Principal moments and the rotation (wxyz quaternion, right-handed) whose columns are the
    principal axes: inertia = R diag(moments) R^T."""
    moments, axes = principal_moments(inertia_3x3)
    if np.linalg.det(axes) < 0:
        axes[:, 2] *= -1.0
    quat = np.zeros(4)
    mujoco.mju_mat2Quat(quat, axes.flatten())
    return moments, quat


MASS_RTOL = 1e-9
"""Total mass and centre of mass of aff/aof must equal the closed chain's to this (relative)."""


INERTIA_RTOL = 1e-9
"""Each foot's centroidal inertia likewise (relative, Frobenius norm)."""


def compare_mass_properties(
    variant_model: mujoco.MjModel, full_model: mujoco.MjModel, key: str, foot_roots: list[str]
) -> dict:
    """Total mass, centre of mass and each foot's centroidal inertia, variant against full, with
    the base of both at the closed-chain model's keyframe pose (the home heights differ by the
    feet's touchdown points)."""
    df = at_keyframe(full_model, key)
    dv = at_keyframe(variant_model, key, free_joint_qpos=df.qpos[:7])
    tv, tf = subtree_inertia(variant_model, dv, 0), subtree_inertia(full_model, df, 0)
    scale = max(float(np.linalg.norm(tf.lever)), 1.0)
    report: dict[str, Any] = {
        "total_mass": {
            "variant_kg": tv.mass,
            "full_kg": tf.mass,
            "relative_error": abs(tv.mass - tf.mass) / tf.mass,
            "tolerance": MASS_RTOL,
        },
        "com": {
            "variant_m": np.array(tv.lever).tolist(),
            "full_m": np.array(tf.lever).tolist(),
            "relative_error": float(np.linalg.norm(tv.lever - tf.lever)) / scale,
            "tolerance": MASS_RTOL,
        },
        "feet": {},
    }
    for body in foot_roots:
        fv = subtree_inertia(variant_model, dv, variant_model.body(body).id)
        ff = subtree_inertia(full_model, df, full_model.body(body).id)
        report["feet"][body] = {
            "mass_relative_error": abs(fv.mass - ff.mass) / ff.mass,
            "com_error_m": float(np.linalg.norm(fv.lever - ff.lever)),
            "centroidal_inertia_relative_error": float(
                np.linalg.norm(fv.inertia - ff.inertia) / np.linalg.norm(ff.inertia)
            ),
            "tolerance": INERTIA_RTOL,
        }
    errs = [report["total_mass"]["relative_error"], report["com"]["relative_error"]] + [
        max(f["mass_relative_error"], f["com_error_m"] / scale, f["centroidal_inertia_relative_error"])
        for f in report["feet"].values()
    ]
    report["passed"] = bool(max(errs) <= MASS_RTOL)
    return report
