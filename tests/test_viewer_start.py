"""Every built model starts sensibly where a viewer opens it: from qpos0 (no keyframe, what
`python -m mujoco.viewer --mjcf build/V/scene.xml` loads) and from each keyframe, 2 s of MuJoCo
steps with no warning, the clock advancing, and the robot (or the rig's carriage) neither
launched nor sinking."""

import mujoco
import numpy as np
import pytest

from footforge.build import VARIANTS
from footforge.mjcf.foot import collision_points

SECONDS = 2.0
PENETRATION_TOL_M = 1e-3
"""Collision geometry at qpos0 may touch the floor, not pass through it (a contact's distance)."""
CLOSURE_TOL = 1e-6
"""Equality constraints (loop closures, roll coupling) satisfied at qpos0: the closed chain
authored at its reference pose, m or rad."""
RISE_TOL_M = 0.01
"""How far the base (or the rig's carriage) may rise above where it started: a model launched by
interpenetration rises metres."""
SINK_TOL_M = {"scene.xml": 0.15, "foot_rig.xml": 0.05}
"""How far it may settle: the legs give about 4-7 cm under the robot's weight from `home` (kp 80),
the closed chain's sole about 2 cm under the rig's payload; a model through the floor falls on."""


def _height(model: mujoco.MjModel, data: mujoco.MjData, file: str) -> float:
    return float(data.qpos[2] if file == "scene.xml" else data.qpos[model.jnt_qposadr[model.joint("slider").id]])


def _start(model: mujoco.MjModel, key: str | None) -> mujoco.MjData:
    data = mujoco.MjData(model)
    if key is None:
        mujoco.mj_resetData(model, data)
    else:
        mujoco.mj_resetDataKeyframe(model, data, model.key(key).id)
    mujoco.mj_forward(model, data)
    return data


@pytest.mark.parametrize("file", ["scene.xml", "foot_rig.xml"])
@pytest.mark.parametrize("variant", VARIANTS)
def test_qpos0_is_a_consistent_pose_resting_on_the_floor(built, variant, file):
    model = mujoco.MjModel.from_xml_path(str(built[variant][0] / file))
    data = _start(model, None)
    lowest = collision_points(model, data, [model.body(b).name for b in range(1, model.nbody)])[:, 2].min()
    assert -PENETRATION_TOL_M <= lowest <= PENETRATION_TOL_M, (
        f"{file} at qpos0: lowest collision point at {lowest:.4f} m"
    )
    if data.ncon:
        assert data.contact.dist[: data.ncon].min() >= -PENETRATION_TOL_M
    equality = data.efc_type == mujoco.mjtConstraint.mjCNSTR_EQUALITY
    if variant == "full":
        assert equality.sum() > 0
    if equality.any():
        assert np.abs(data.efc_pos[equality]).max() < CLOSURE_TOL


STARTS = [
    pytest.param(
        variant,
        file,
        # The closed-chain robot (four 34-joint feet) steps near real time: 2 s from each of its
        # starts takes about half a minute, run with the slow tests.
        marks=[pytest.mark.slow, pytest.mark.timeout(600)] if (variant, file) == ("full", "scene.xml") else [],
        id=f"{variant}-{file}",
    )
    for file in ("scene.xml", "foot_rig.xml")
    for variant in VARIANTS
]


@pytest.mark.parametrize("variant,file", STARTS)
def test_every_start_steps_two_seconds_quietly(built, variant, file):
    model = mujoco.MjModel.from_xml_path(str(built[variant][0] / file))
    starts = [None] + [model.key(k).name for k in range(model.nkey)]
    assert len(starts) >= 2, f"{file}: no keyframe"
    steps = int(round(SECONDS / model.opt.timestep))
    for key in starts:
        data = _start(model, key)
        start = _height(model, data, file)
        heights = np.empty(steps)
        for i in range(steps):
            mujoco.mj_step(model, data)
            heights[i] = _height(model, data, file)
        where = f"{variant} {file} from {key or 'qpos0'}"
        warnings = {mujoco.mjtWarning(i).name: int(w.number) for i, w in enumerate(data.warning) if w.number}
        assert not warnings, f"{where}: {warnings}"
        # A diverging simulation resets itself (the warning above) and its clock starts again.
        assert data.time == pytest.approx(steps * model.opt.timestep), where
        assert heights.max() <= start + RISE_TOL_M, f"{where}: rose to {heights.max():.3f} m from {start:.3f} m"
        assert heights.min() >= start - SINK_TOL_M[file], f"{where}: sank to {heights.min():.3f} m from {start:.3f} m"
        # It has come to rest: the last 0.2 s move less than 1 mm.
        tail = heights[-int(round(0.2 / model.opt.timestep)) :]
        assert np.ptp(tail) < 1e-3, f"{where}: still moving ({np.ptp(tail) * 1e3:.1f} mm in the last 0.2 s)"
