"""AFF's and AOF's passive joints estimated on the closed chain from its orientation sensors
(footforge.rl.foot_imu): exact on rigid poses of known angle, rates that are the angles' derivatives,
and a standing closed chain read like a standing AOF."""

import math

import mujoco
import numpy as np
import pinocchio as pin
import pytest

from footforge.errors import InputError
from footforge.rl.foot_imu import ESTIMATED, FootImuEstimator

LF = [f"LF_foot/{j}" for j in ESTIMATED]


@pytest.fixture(scope="module")
def full(built):
    model = mujoco.MjModel.from_xml_path(str(built["full"][0] / "scene.xml"))
    return model, FootImuEstimator(model, LF)


def _posed(model, **turns_rad):
    """The `home` keyframe (the reference pose) with LF's joints turned by the given angles."""
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, model.key("home").id)
    for joint, turn in turns_rad.items():
        data.qpos[model.joint(f"LF_foot/{joint}").qposadr[0]] += turn
    mujoco.mj_forward(model, data)
    return data


def test_rigid_pitch_and_roll_of_the_whole_foot_are_read_back(full):
    """Turning both arches the same way about the mount's y axis pitches the whole foot rigidly
    (the back arch's axis is -y); turning the roll links together rolls it. Either keeps the
    loops closed, so these are poses of the closed chain whose answer is known."""
    model, imu = full
    home, _ = imu(_posed(model))
    assert home[0] == pytest.approx(0.0, abs=1e-9) and home[1] == pytest.approx(0.0, abs=1e-9)
    theta = math.radians(10.0)
    pitched, _ = imu(_posed(model, front_arch=theta, back_arch=-theta))
    assert pitched[0] == pytest.approx(theta, abs=1e-9) and pitched[1] == pytest.approx(0.0, abs=1e-9)
    np.testing.assert_allclose(pitched[2:], home[2:], atol=1e-9)  # the sole turned with the pitch line
    # The arches' spread lowers both roll pivots and is no pitch.
    spread, _ = imu(_posed(model, front_arch=theta, back_arch=theta))
    assert spread[0] == pytest.approx(0.0, abs=1e-9)
    phi = math.radians(8.0)
    rolled, _ = imu(_posed(model, front_roll=phi, back_roll=-phi))  # coupled: back = -front
    # The roll links' axis is tilted 6 degrees (0.1047 rad) from the sole's length: cos(6 deg) of
    # the turn shows as roll, to 0.6%.
    assert rolled[1] == pytest.approx(phi, rel=0.01) and rolled[0] == pytest.approx(0.0, abs=1e-9)
    np.testing.assert_allclose(rolled[2:], home[2:], atol=math.radians(0.1))


def test_rates_are_the_time_derivatives_of_the_angles(full):
    """The gyroscope rates against central differences of the angles along random velocities
    of the base and of every joint of the foot (loops need not close for the kinematics)."""
    model, imu = full
    data = _posed(model)
    rng = np.random.default_rng(0)
    velocity = np.zeros(model.nv)
    velocity[:6] = rng.normal(0.0, 0.5, 6)
    for j in range(model.njnt):
        if model.joint(j).name.startswith("LF_foot/"):
            velocity[model.jnt_dofadr[j]] = rng.normal(0.0, 1.0)
    start = data.qpos.copy()

    def at(h):
        qpos = start.copy()
        mujoco.mj_integratePos(model, qpos, velocity, h)
        data.qpos[:], data.qvel[:] = qpos, velocity
        mujoco.mj_forward(model, data)
        return imu(data)

    h = 1e-6
    _, rates = at(0.0)
    differences = (at(h)[0] - at(-h)[0]) / (2 * h)
    assert np.abs(rates).max() > 0.1  # the check has something to check
    # Pitch and the sole halves' chords are differentiated exactly; the roll, an average of six
    # links' decomposed rolls, through its axis alone (exact while the halves are flat).
    np.testing.assert_allclose(rates[[0, 2, 3]], differences[[0, 2, 3]], rtol=1e-4, atol=1e-6)
    assert rates[1] == pytest.approx(differences[1], rel=0.05)


def test_a_standing_closed_chain_reads_its_stance_like_a_standing_aof(built, full):
    """Both robots settle 0.5 s at `stand` on flat ground: the closed chain's estimates against
    AOF's own passive joints. The stance pitches the feet's mounts past the arches' pitch stop:
    the closed chain's pitch estimate sits at its stop (within 1 degree; the stops hold), AOF's
    ankle, whose stop keeps MuJoCo's default softness, at or past its own. AOF's sole lies flat,
    so its ankle pitch is the mount's pitch over the ground; the part of it the closed chain's
    stop refuses bends the chain's sole halves instead, and they read flat within 2 degrees (the
    chain's inner and outer links zigzag by up to 7 degrees on the ground; the three-link chords
    average that out) plus that refused pitch."""
    model, _ = full
    names = [f"{leg}_foot/{j}" for leg in ("LF", "RF", "LH", "RH") for j in ESTIMATED]
    imu = FootImuEstimator(model, names)
    aof = mujoco.MjModel.from_xml_path(str(built["aof"][0] / "scene.xml"))
    readings = {}
    for feet, m in (("full", model), ("aof", aof)):
        data = mujoco.MjData(m)
        mujoco.mj_resetDataKeyframe(m, data, m.key("stand").id)
        for _ in range(int(round(0.5 / m.opt.timestep))):
            mujoco.mj_step(m, data)
        readings[feet] = (
            imu(data)[0] if feet == "full" else np.array([data.qpos[m.joint(n).qposadr[0]] for n in names])
        ).reshape(4, 4)
    full_angles, aof_angles = readings["full"], readings["aof"]
    arch_stop = model.jnt_range[model.joint("LF_foot/front_arch").id, 1]
    ankle_stop = aof.jnt_range[aof.joint("LF_foot/ankle_pitch").id, 1]
    np.testing.assert_allclose(np.abs(full_angles[:, 0]), arch_stop, atol=math.radians(1.0))
    np.testing.assert_array_equal(np.sign(full_angles[:, 0]), np.sign(aof_angles[:, 0]))
    assert np.abs(aof_angles[:, 0]).min() > ankle_stop - math.radians(0.5)
    refused = np.abs(aof_angles[:, 0]) - arch_stop
    assert np.all(np.abs(full_angles[:, 2:]).max(axis=1) < math.radians(2.0) + refused)
    assert np.abs(aof_angles[:, 2:]).max() < math.radians(2.0)


def test_names_and_models_it_cannot_estimate_are_refused(built, full):
    model, _ = full
    with pytest.raises(InputError, match="cannot estimate the passive joint 'LF_foot/heel'"):
        FootImuEstimator(model, ["LF_foot/heel"])
    aof = mujoco.MjModel.from_xml_path(str(built["aof"][0] / "scene.xml"))
    with pytest.raises(InputError, match="not a closed-chain SoftFoot-Q robot"):
        FootImuEstimator(aof, LF)


def _on_a_step(model_path, under: str, height_m: float = 0.02) -> tuple[mujoco.MjModel, mujoco.MjData]:
    """The robot settled 1 s at `stand` with a box `height_m` high and 20 cm long under the front
    or back half of LF's sole: its edge 1 cm ahead of LF's mount, about under the chain's middle
    once the foot settles (the foot is pitched under the leg, its sole's middle ahead of the
    mount), the box ahead of the edge or behind it."""
    spec = mujoco.MjSpec.from_file(str(model_path))
    model = spec.compile()
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, model.key("stand").id)
    mujoco.mj_forward(model, data)
    mount = data.xpos[model.body("LF_foot/mount").id]
    side = 1.0 if under == "front" else -1.0
    spec.worldbody.add_geom(
        type=mujoco.mjtGeom.mjGEOM_BOX,
        size=[0.1, 0.1, height_m / 2],
        pos=[mount[0] + 0.01 + side * 0.1, mount[1], height_m / 2],
    )
    model = spec.compile()
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, model.key("stand").id)
    data.qpos[2] += height_m
    for _ in range(int(round(1.0 / model.opt.timestep))):
        mujoco.mj_step(model, data)
    return model, data


@pytest.mark.parametrize("under", ["front", "back"])
def test_the_half_of_the_sole_resting_on_a_step_reads_flat(built, under):
    """A 2 cm step under one half of LF's sole: that half lies on the step's flat top, so the
    plate it stands for, composed from the estimates (the mount's orientation, the ankle pitch
    and roll, that half's hinge), is level in the world within 1 degree, while the pivot line is
    pitched by about 20 degrees. Also computed the other way, from positions: the pitch of the
    line between the roll pivots, and each half's chord between its pins."""
    model, data = _on_a_step(built["full"][0] / "scene.xml", under)
    imu = FootImuEstimator(model, LF)
    pitch, roll, front, back = imu(data)[0]
    assert abs(pitch) > math.radians(10)  # the step tilts the foot: a level plate is no accident
    mount = data.xmat[model.body("LF_foot/mount").id].reshape(3, 3)
    sole = mount @ pin.utils.rotate("y", pitch) @ pin.utils.rotate("x", roll)
    # AOF's front plate reaches back from its hinge (-x), turned about +y; the back plate reaches
    # forward (+x), turned about -y.
    plate = sole @ (
        pin.utils.rotate("y", front) @ [-1.0, 0.0, 0.0]
        if under == "front"
        else pin.utils.rotate("y", -back) @ [1.0, 0.0, 0.0]
    )
    assert abs(plate[2]) < math.sin(math.radians(1.0)), (under, np.degrees([pitch, roll, front, back]))

    def in_mount(body):
        return mount.T @ (data.xpos[model.body(f"LF_foot/{body}").id] - data.xpos[model.body("LF_foot/mount").id])

    reference = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, reference, model.key("home").id)
    mujoco.mj_kinematics(model, reference)
    ref_mount = reference.xmat[model.body("LF_foot/mount").id].reshape(3, 3)
    line = in_mount("front_roll") - in_mount("back_roll")
    ref_line = ref_mount.T @ (
        reference.xpos[model.body("LF_foot/front_roll").id] - reference.xpos[model.body("LF_foot/back_roll").id]
    )
    assert pitch == pytest.approx(math.atan2(-line[2], line[0]) - math.atan2(-ref_line[2], ref_line[0]), abs=1e-9)
    to_sole = (pin.utils.rotate("y", pitch) @ pin.utils.rotate("x", roll)).T
    chord_front = to_sole @ (in_mount("chain_middle_5") - in_mount("chain_middle_2"))  # pins 2 to 5: links 2-4
    chord_back = to_sole @ (in_mount("chain_middle_6") - in_mount("chain_middle_9"))  # pins 9 to 6: links 8-6
    assert front == pytest.approx(math.atan2(chord_front[2], -chord_front[0]), abs=1e-9)
    assert back == pytest.approx(math.atan2(chord_back[2], chord_back[0]), abs=1e-9)
