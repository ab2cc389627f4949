"""Figures of the build report (build_report.json) that describe a compiled model."""

from __future__ import annotations

import mujoco
import numpy as np


def model_counts(model: mujoco.MjModel) -> dict:
    kinds = {
        int(mujoco.mjtJoint.mjJNT_FREE): "free",
        int(mujoco.mjtJoint.mjJNT_BALL): "ball",
        int(mujoco.mjtJoint.mjJNT_SLIDE): "slide",
        int(mujoco.mjtJoint.mjJNT_HINGE): "hinge",
    }
    by_kind: dict[str, int] = {}
    for t in model.jnt_type:
        by_kind[kinds[int(t)]] = by_kind.get(kinds[int(t)], 0) + 1
    eq_kinds = {
        int(mujoco.mjtEq.mjEQ_CONNECT): "connect",
        int(mujoco.mjtEq.mjEQ_WELD): "weld",
        int(mujoco.mjtEq.mjEQ_JOINT): "joint",
        int(mujoco.mjtEq.mjEQ_TENDON): "tendon",
    }
    eqs: dict[str, int] = {}
    for t in model.eq_type:
        eqs[eq_kinds.get(int(t), str(int(t)))] = eqs.get(eq_kinds.get(int(t), str(int(t))), 0) + 1
    return {
        "bodies": int(model.nbody - 1),
        "joints_by_kind": by_kind,
        "nq": int(model.nq),
        "dof": int(model.nv),
        "actuators": int(model.nu),
        "sensors": int(model.nsensor),
        "equality_constraints": eqs,
        "tendons": int(model.ntendon),
        "geoms": int(model.ngeom),
        "mesh_assets": int(model.nmesh),
        "total_mass_kg": float(mujoco.mj_getTotalmass(model)),
        "timestep_s": float(model.opt.timestep),
    }


def closure_gaps(model: mujoco.MjModel, data: mujoco.MjData) -> dict[str, float]:
    """Distance between the two sites of every closure equality (m)."""
    gaps = {}
    for e in range(model.neq):
        if model.eq_type[e] == mujoco.mjtEq.mjEQ_CONNECT and model.eq_objtype[e] == mujoco.mjtObj.mjOBJ_SITE:
            a, b = model.eq_obj1id[e], model.eq_obj2id[e]
            gaps[model.eq(e).name] = float(np.linalg.norm(data.site_xpos[a] - data.site_xpos[b]))
    return gaps
