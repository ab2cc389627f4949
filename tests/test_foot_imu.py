"""AFF's and AOF's passive joints estimated on the closed chain from its orientation sensors
(footforge.foot_imu): exact on rigid poses of known angle, rates that are the angles' derivatives,
and a standing closed chain read like a standing AOF."""

import math

import mujoco
import numpy as np
import pytest

from footforge.errors import InputError
from footforge.foot_imu import ESTIMATED, FootImuEstimator

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


def test_a_standing_closed_chain_reads_like_a_standing_aof(built, full):
    """Both robots settle 0.5 s at `stand` on flat ground: the closed chain's estimates against
    AOF's own passive joints. Flat soles read as flat: hinge angles within 2 degrees of zero (the
    chain's inner and outer links zigzag by up to 7 degrees on the ground; the three-link chords
    average that out), and the ankle pitch within 1 degree of AOF's."""
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
        readings[feet] = (imu(data)[0] if feet == "full"
                          else np.array([data.qpos[m.joint(n).qposadr[0]] for n in names])).reshape(4, 4)
    full_angles, aof_angles = readings["full"], readings["aof"]
    assert np.abs(full_angles[:, 0]).min() > math.radians(20)  # the legs' stance pitches the feet a lot
    np.testing.assert_allclose(full_angles[:, 0], aof_angles[:, 0], atol=math.radians(1.0))
    assert np.abs(full_angles[:, 2:]).max() < math.radians(2.0)
    assert np.abs(aof_angles[:, 2:]).max() < math.radians(2.0)


def test_names_and_models_it_cannot_estimate_are_refused(built, full):
    model, _ = full
    with pytest.raises(InputError, match="cannot estimate the passive joint 'LF_foot/heel'"):
        FootImuEstimator(model, ["LF_foot/heel"])
    aof = mujoco.MjModel.from_xml_path(str(built["aof"][0] / "scene.xml"))
    with pytest.raises(InputError, match="not a closed-chain SoftFoot-Q robot"):
        FootImuEstimator(aof, LF)
