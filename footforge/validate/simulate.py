"""One drop test: compile the scenario's rig, release the foot, record what the ground feels.

Runs in a worker process: inputs are plain MJCF text and asset bytes, outputs plain arrays.
"""

from __future__ import annotations

import collections
import time
from dataclasses import dataclass

import mujoco
import numpy as np

from footforge.mjcf.foot import collision_points
from footforge.validate.scenarios import Scenario

SAMPLE_DT_S = 0.002
"""Recording interval, s: a multiple of every variant's timestep (0.25 ms full, 2 ms others), so
all variants are sampled at the same instants. Forces are not sampled at this rate but integrated
over every physics step of each interval (see `run`), so that a 0.25 ms impact between two samples
is neither missed nor counted twice."""
PEAK_WINDOW_S = 0.002
"""Peak force is the largest mean ground force over any window of this length, slid one physics
step at a time. It is the physics step of the coarsest variants, so that every variant's peak is
an average over the same duration (a single 0.25 ms step of the closed chain, when a light link
strikes, can be several times its 2 ms average); it does not depend on the recording interval."""
SETTLE_BAND_M = 0.0005
"""Settling: the mount stays within this of its final height."""


@dataclass(frozen=True)
class RigCase:
    """A compiled-to-be rig for one (scenario, variant)."""

    scenario: Scenario
    variant: str
    xml: str
    assets: dict
    sole_bodies: tuple[str, ...] = ()
    """Foot bodies whose bottoms form the sole (footforge.mjcf.foot.sole_bodies), without the rig's
    `foot/` prefix; none for the ball."""
    patch: dict | None = None
    """Calibration trial values applied to the compiled model: {"joints": {name: {"stiffness":
    N m/rad, "damping": N m s/rad}}, "sole_lift_delta_m": m added to the sole collision geoms' height}."""


def compile_case(xml: str, assets: dict, patch: dict | None) -> mujoco.MjModel:
    """The case's model with a calibration trial's values (`patch`, Case.patch) applied. The sole
    lift moves the sole collision geoms before compiling: moved in a compiled model, a body with
    several colliding geoms keeps its compiled bounding box, and MuJoCo's midphase then misses
    contacts of the moved geoms (spheres or capsules lowered 1 mm into a plane found none)."""
    delta = (patch or {}).get("sole_lift_delta_m", 0.0)
    if delta:
        spec = mujoco.MjSpec.from_string(xml, assets=assets)
        for geom in spec.geoms:
            if geom.name.startswith("foot/sole") and geom.name.endswith("_collision"):
                # Sole body frames are aligned with the mount; a capsule given by fromto moves by it.
                if np.isnan(geom.fromto[0]):
                    geom.pos[2] += delta
                else:
                    geom.fromto[2] += delta
                    geom.fromto[5] += delta
        model = spec.compile()
    else:
        model = mujoco.MjModel.from_xml_string(xml, assets)
    for name, values in (patch or {}).get("joints", {}).items():
        joint = model.joint(f"foot/{name}")
        if "stiffness" in values:
            model.jnt_stiffness[joint.id] = values["stiffness"]
        if "damping" in values:
            model.dof_damping[joint.dofadr[0]] = values["damping"]
    return model


def _foot_mask(model: mujoco.MjModel) -> np.ndarray:
    """Per body: does it hang from the slider (the carriage and the foot)."""
    return model.body_rootid == model.body_rootid[model.body("carriage").id]


def _sole_points(model: mujoco.MjModel, data: mujoco.MjData, sole_bodies) -> tuple[np.ndarray, np.ndarray]:
    """Material points on the bottom of each sole body (within 1 mm of its lowest collision
    point along the foot mount's z axis, at the reference pose), as (body ids (N,), points in
    the body frames (N, 3)). Measured in the mount frame, so a tilted leg selects the same points."""
    mount = model.site("mount").id
    R_mount, p_mount = data.site_xmat[mount].reshape(3, 3), data.site_xpos[mount]
    bodies, local = [], []
    for name in (f"foot/{n}" for n in sole_bodies):
        b = model.body(name).id
        pts = collision_points(model, data, [name])
        if not len(pts):
            continue
        height = (pts - p_mount) @ R_mount[:, 2]
        bottom = pts[height <= height.min() + 1e-3]
        local.append((bottom - data.xpos[b]) @ data.xmat[b].reshape(3, 3))
        bodies += [b] * len(bottom)
    return np.array(bodies, int), (np.concatenate(local) if local else np.zeros((0, 3)))


def _sole_world(data: mujoco.MjData, bodies: np.ndarray, local: np.ndarray) -> np.ndarray:
    return np.einsum("nij,nj->ni", data.xmat[bodies].reshape(-1, 3, 3), local) + data.xpos[bodies]


def _sole_orientation(world: np.ndarray) -> tuple[float, float]:
    """Pitch and roll (rad) of the least-squares plane through the sole points, world frame.
    Pitch positive: toe down; roll positive: left side up (right-hand rotations about y, x)."""
    if len(world) < 3:
        return float("nan"), float("nan")
    A = np.c_[np.ones(len(world)), world[:, 0], world[:, 1]]
    (_, slope_x, slope_y), *_ = np.linalg.lstsq(A, world[:, 2], rcond=None)
    return float(-np.arctan(slope_x)), float(np.arctan(slope_y))


def _ground_contacts(model, data, foot_mask):
    """World positions (N, 3), world forces on the foot (N, 3), penetrations (N,) and geom pairs
    (N, 2) of the foot-ground contacts. After mj_step, `data.contact` and the constraint forces are
    those computed at the start of that step: the forces that moved the state to the current one."""
    ncon = data.ncon
    geoms = data.contact.geom[:ncon].reshape(-1, 2)
    on_foot = foot_mask[model.geom_bodyid[geoms]]
    chosen = np.flatnonzero(on_foot[:, 0] != on_foot[:, 1])
    forces = np.zeros((len(chosen), 3))
    force = np.zeros(6)
    for n, i in enumerate(chosen):
        mujoco.mj_contactForce(model, data, i, force)
        f_world = data.contact.frame[i].reshape(3, 3).T @ force[:3]  # on geom2, along the normal 1 -> 2
        forces[n] = -f_world if on_foot[i, 0] else f_world
    return (
        data.contact.pos[chosen].reshape(-1, 3),
        forces,
        np.maximum(0.0, -data.contact.dist[chosen]).reshape(-1),
        geoms[chosen],
    )


def _place(model, data, slider_adr, foot_mask, drop_height_m) -> None:
    """Sets the slider so the foot's lowest point is `drop_height_m` above the obstacle
    (bisection on the first contact; works for every geom type, heightfields included)."""

    def touching(z):
        data.qpos[slider_adr] = z
        mujoco.mj_kinematics(model, data)
        mujoco.mj_collision(model, data)
        geoms = data.contact.geom[: data.ncon].reshape(-1, 2)
        on_foot = foot_mask[model.geom_bodyid[geoms]]
        return bool(((on_foot[:, 0] != on_foot[:, 1]) & (data.contact.dist[: data.ncon] < 0)).any())

    lo, hi = -0.5, 0.5
    while not touching(lo):
        lo -= 0.5
    for _ in range(50):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if touching(mid) else (lo, mid)
    data.qpos[slider_adr] = hi + drop_height_m
    mujoco.mj_forward(model, data)


class _RigState:
    """What a drop test records of the rig's state at a sample: the mount's height, the hanging
    parts' vertical momentum, the sole's orientation and position, the ground contacts' count,
    penetration, centre of pressure and spread, the closure gap and the energy."""

    def __init__(self, model: mujoco.MjModel, sole_bodies, sole_local):
        self.model, self.sole_bodies, self.sole_local = model, sole_bodies, sole_local
        self.root = int(model.body_rootid[model.body("carriage").id])
        self.hanging_mass = float(model.body_subtreemass[self.root])
        self.mount = model.site("mount").id
        connect = [
            e
            for e in range(model.neq)
            if model.eq_type[e] == mujoco.mjtEq.mjEQ_CONNECT and model.eq_objtype[e] == mujoco.mjtObj.mjOBJ_SITE
        ]
        self.site_a, self.site_b = model.eq_obj1id[connect], model.eq_obj2id[connect]
        self._com_jac = np.zeros((3, model.nv))

    def record(self, series: dict, i: int, data: mujoco.MjData, pos, force, penetration) -> np.ndarray:
        """Fills sample i of `series` from `data` and its ground contacts (positions, forces,
        penetrations); returns the footprint: (x, y relative to the mount, normal force) per contact."""
        # The current velocities through the centre-of-mass Jacobian (data.cvel and
        # subtree_linvel still hold the previous step's velocities after mj_step).
        mujoco.mj_jacSubtreeCom(self.model, data, self._com_jac, self.root)
        series["momentum_z_ns"][i] = self.hanging_mass * float(self._com_jac[2] @ data.qvel)
        series["height_m"][i] = data.site_xpos[self.mount][2]
        sole_world = _sole_world(data, self.sole_bodies, self.sole_local)
        series["pitch_rad"][i], series["roll_rad"][i] = _sole_orientation(sole_world)
        if len(sole_world):
            series["sole_x_m"][i], series["sole_y_m"][i] = sole_world[:, :2].mean(axis=0)
        series["contacts"][i] = len(pos)
        series["penetration_m"][i] = penetration.max(initial=0.0)
        weights = np.maximum(force[:, 2], 0.0)
        planar = pos[:, :2] - data.site_xpos[self.mount][:2]
        if weights.sum() > 1e-9:
            cop = weights @ planar / weights.sum()
            series["cop_x_m"][i], series["cop_y_m"][i] = cop
            series["spread_m"][i] = float(np.sqrt(weights @ ((planar - cop) ** 2).sum(axis=1) / weights.sum()))
        gaps = np.linalg.norm(data.site_xpos[self.site_a] - data.site_xpos[self.site_b], axis=1)
        series["closure_gap_m"][i] = gaps.max(initial=0.0)
        series["energy_j"][i] = data.energy.sum()
        return np.c_[planar, force[:, 2]]


def run(case: RigCase, sample_dt_s: float = SAMPLE_DT_S) -> dict:
    """Simulates one case; returns time series (sampled every `sample_dt_s`) and scalars.

    Ground force is accumulated at the physics rate: for sample i > 0, `impulse_ns` is the ground
    impulse of every physics step since sample i-1 (sum of F dt), `force_z_n` that impulse divided
    by the interval (the interval's mean force) and `force_peak_n` the largest PEAK_WINDOW_S mean
    force that ended in it. Kinematic quantities (height, orientation, centre of pressure) are the state at the sample.
    `momentum_z_ns` is the vertical momentum of everything that hangs from the slider (the payload,
    carriage and foot, from their centre of mass velocity), so that impulse and momentum can be
    checked against each other.

    `wall_s` is the wall-clock time spent in mj_step alone (the recording is not counted), so
    that variants' speeds compare the physics, not this function's bookkeeping.
    """
    scenario = case.scenario
    model = compile_case(case.xml, case.assets, case.patch)
    model.opt.enableflags |= mujoco.mjtEnableBit.mjENBL_ENERGY
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, model.key("reference").id)
    mujoco.mj_forward(model, data)
    foot_mask = _foot_mask(model)
    sole_bodies, sole_local = _sole_points(model, data, case.sole_bodies)
    slider = model.joint("slider")
    _place(model, data, int(slider.qposadr[0]), foot_mask, scenario.drop_height_m)
    weight = float(-model.opt.gravity[2] * mujoco.mj_getTotalmass(model))  # payload, carriage and foot
    steps = int(round(scenario.duration_s / model.opt.timestep))
    every = max(1, int(round(sample_dt_s / model.opt.timestep)))
    if not np.isclose(every * model.opt.timestep, sample_dt_s, rtol=1e-9, atol=0.0):
        raise ValueError(f"sample interval {sample_dt_s} s is not a multiple of the timestep {model.opt.timestep} s")
    n = steps // every + 1
    series = {
        k: np.full(n, np.nan)
        for k in (
            "time_s",
            "force_z_n",
            "force_peak_n",
            "impulse_ns",
            "momentum_z_ns",
            "height_m",
            "pitch_rad",
            "roll_rad",
            "contacts",
            "cop_x_m",
            "cop_y_m",
            "spread_m",
            "penetration_m",
            "closure_gap_m",
            "energy_j",
            "sole_x_m",
            "sole_y_m",
        )
    }
    rig = _RigState(model, sole_bodies, sole_local)
    hanging_mass = rig.hanging_mass
    failed, wall, footprint = None, 0.0, np.zeros((0, 3))
    obstacle = int(model.geom("obstacle").id) if scenario.obstacle not in ("flat", "slope") else -1
    obstacle_impulse = 0.0  # through the obstacle, over the whole run
    impulse, peak = 0.0, 0.0  # over the physics steps since the last sample
    # Compression phase at the physics rate: from the first step with ground force until the step
    # after which the mount no longer descends (its slider velocity >= 0).
    slider_dof = int(slider.dofadr[0])
    touched, compressing, compression_impulse = False, True, 0.0
    window: collections.deque[float] = collections.deque(maxlen=max(1, int(round(PEAK_WINDOW_S / model.opt.timestep))))
    # The foot-ground contacts of the current state: from the placing forward pass, then after
    # every step those of the step just taken (read once, for the force sums and the records).
    pos, force, penetration, pairs = _ground_contacts(model, data, foot_mask)
    for k in range(steps + 1):
        if k % every == 0:
            i = k // every
            series["time_s"][i] = data.time
            if i == 0:  # released: the force of the placing forward pass (zero: the foot hangs above the ground)
                series["force_z_n"][i] = series["force_peak_n"][i] = force[:, 2].sum()
                series["impulse_ns"][i] = 0.0
            else:
                series["force_z_n"][i] = impulse / (every * model.opt.timestep)
                series["force_peak_n"][i], series["impulse_ns"][i] = peak, impulse
            impulse, peak = 0.0, 0.0
            footprint = rig.record(series, i, data, pos, force, penetration)
        if k == steps:
            break
        t0 = time.perf_counter()
        mujoco.mj_step(model, data)
        wall += time.perf_counter() - t0
        pos, force, penetration, pairs = _ground_contacts(model, data, foot_mask)
        f_z = float(force[:, 2].sum())
        obstacle_impulse += float(force[(pairs == obstacle).any(axis=1), 2].sum()) * model.opt.timestep
        impulse += f_z * model.opt.timestep
        touched |= f_z > 0.0
        if touched and compressing:
            compression_impulse += f_z * model.opt.timestep
            compressing = data.qvel[slider_dof] < 0.0
        window.append(f_z)
        peak = max(peak, sum(window) / window.maxlen)  # type: ignore[operator]  # maxlen given above
        if data.warning.number.any() or not np.isfinite(data.qacc).all():
            warnings = [mujoco.mjtWarning(j).name for j, w in enumerate(data.warning) if w.number]
            failed = f"step {k}: " + (", ".join(warnings) if warnings else "non-finite acceleration")
            footprint = np.zeros((0, 3))
            break
    result_scalars = scalars(series, weight, failed, compression_impulse)
    if obstacle >= 0 and not failed:
        total = float(np.nansum(series["impulse_ns"]))
        result_scalars["obstacle_share"] = obstacle_impulse / total if total > 0 else 0.0
    return {
        "footprint": footprint,
        "scenario": scenario.name,
        "variant": case.variant,
        "series": series,
        "scalars": result_scalars,
        "failed": failed,
        "wall_s": wall,
        "steps": k,
        "timestep_s": model.opt.timestep,
        "supported_weight_n": weight,
        "hanging_mass_kg": hanging_mass,
    }


def _tail_mean_deg(values: np.ndarray) -> float:
    return float(np.degrees(np.nanmean(values))) if np.isfinite(values).any() else float("nan")


def scalars(s: dict, weight_n: float, failed: str | None, compression_impulse_ns: float) -> dict:
    """The per-run figures of the report, from the recorded series, the supported weight and the
    compression-phase impulse summed at the physics rate (see `run`)."""
    t, f, h = s["time_s"], s["force_z_n"], s["height_m"]
    ok = np.isfinite(h)
    if failed or not ok.any():
        return {"failed": True}
    touched = np.flatnonzero(f > 1e-6)
    first = int(touched[0]) if touched.size else 0
    final_h = float(np.nanmean(h[-50:]))
    outside = np.flatnonzero(np.abs(h - final_h) > SETTLE_BAND_M)
    settle = float(t[outside[-1]] - t[first]) if outside.size else 0.0
    # Compression phase: from first contact until the mount stops descending.
    v = np.gradient(h, t)
    rising = np.flatnonzero(v[first:] >= 0)
    end = first + int(rising[0]) if rising.size else len(t) - 1
    impulse = float(compression_impulse_ns)
    low = first + int(np.argmin(h[first : end + 1])) if end > first else first
    rebound = float(max(0.0, np.nanmax(h[low:]) - final_h))
    peak = int(np.nanargmax(s["force_peak_n"]))
    cop = np.c_[s["cop_x_m"], s["cop_y_m"]]
    tail = slice(-50, None)
    cop_final = np.nanmean(cop[tail], axis=0) if np.isfinite(cop[tail]).any() else np.full(2, np.nan)
    # Slip: how far the sole (the centroid of its bottom points) slides horizontally from the
    # moment the ground first carries the supported weight to the end. The slider holds the
    # mount in x and y, so this is the foot's own sliding and rolling on the surface.
    sole = np.c_[s["sole_x_m"], s["sole_y_m"]]
    supported = np.flatnonzero(f >= weight_n)
    start = int(supported[0]) if supported.size else first
    slip = (
        float(np.linalg.norm(np.nanmean(sole[tail], axis=0) - sole[start])) if np.isfinite(sole[start]).all() else 0.0
    )
    # Released at rest, the rig has only gravity (in the energy), springs (in it too) and
    # dissipative forces acting: its energy may never exceed the initial value.
    energy = s["energy_j"]
    gain = float(np.nanmax(energy) - energy[0])
    return {
        "peak_force_n": float(s["force_peak_n"][peak]),
        "impulse_ns": impulse,
        "settling_time_s": settle,
        "final_height_m": final_h,
        "final_force_n": float(np.nanmean(f[tail])),
        "final_pitch_deg": _tail_mean_deg(s["pitch_rad"][tail]),
        "final_roll_deg": _tail_mean_deg(s["roll_rad"][tail]),
        "contacts": float(np.nanmean(s["contacts"][tail])),
        "cop_x_mm": float(cop_final[0] * 1e3),
        "cop_y_mm": float(cop_final[1] * 1e3),
        "spread_mm": float(np.nanmean(s["spread_m"][tail]) * 1e3) if np.isfinite(s["spread_m"][tail]).any() else 0.0,
        "rebound_mm": rebound * 1e3,
        "slip_mm": slip * 1e3,
        "max_penetration_mm": float(np.nanmax(s["penetration_m"]) * 1e3),
        "max_closure_gap_mm": float(np.nanmax(s["closure_gap_m"]) * 1e3),
        "energy_gain_j": gain,
        "failed": False,
    }
