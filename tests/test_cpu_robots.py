"""The CPU runner (footforge.envs.engine_mujoco.CpuRobots), which the closed-chain evaluation and
play step their robots with through the C engine's pool: it is MuJoCo's own mj_step, its
ground contacts are those of MuJoCo's contact list, its closure residuals those of MuJoCo's
constraint rows, and its results do not depend on the threads."""

from dataclasses import replace

import mujoco
import numpy as np
import pytest

from footforge import envs
from footforge.envs import terrain as terrain_lib
from footforge.envs.contacts import foot_contacts, ground_contacts
from footforge.envs.engine_mujoco import THREADS_ENV, ClosureResiduals, CpuRobots
from footforge.rl.evaluate_closed_chain import TERRAIN_TILES, cpu_robot, place_at_start


def _robot(built, feet, terrain=None):
    config = replace(envs.default_config("flat", "aof", "B"), build_dir=str(built["aof"][0]))
    return cpu_robot(config, feet, built["full"][0].parent, terrain, own_physics=feet == "full")


def _targets(robot, n, seed=0):
    return robot.default_q + np.random.default_rng(seed).normal(0.0, 0.2, (n, 12))


def _contact_list(data):
    """MuJoCo's contact list of `data`: (geom pairs (ncon, 2), signed distances (ncon,))."""
    return data.contact.geom[: data.ncon].copy().reshape(-1, 2), data.contact.dist[: data.ncon].copy()


def _placed(robot, n, terrain=None):
    robots, data = CpuRobots(robot, n), mujoco.MjData(robot.engine_model)
    for i in range(n):
        place_at_start(robot, data, terrain, i)
        robots.take(i, data)
    return robots


@pytest.mark.parametrize("feet", ["aof", "full"])
def test_one_policy_step_is_mujocos_own_mj_step(built, feet):
    """From placed robots (no solver warm start, as a fresh MjData), one policy step of the runner
    (robot 1 pushed first, as the environment pushes) gives the state, actuator forces and foot
    contacts of MuJoCo's mj_step called `nstep` times by hand on an MjData, to the last bit."""
    terrain = terrain_lib.generate(TERRAIN_TILES) if feet == "aof" else None
    robot = _robot(built, feet, terrain)
    n, nstep = 2, 8
    robots = _placed(robot, n, terrain)
    targets = _targets(robot, n)
    push = np.array([[np.nan, np.nan], [0.6, -0.4]])
    sensors = robots.step(targets, nstep, push=push)
    assert sensors.shape == (n, nstep, robots.model.nsensordata)
    model = robots.model
    for i in range(n):
        d = mujoco.MjData(model)
        place_at_start(robot, d, terrain, i)
        d.ctrl[robot.actuator_ids] = targets[i]
        if i == 1:
            d.qvel[:2] = push[1]
        for _ in range(nstep):
            mujoco.mj_step(model, d)
        np.testing.assert_array_equal(robots.qpos[i], d.qpos)
        np.testing.assert_array_equal(robots.qvel[i], d.qvel)
        np.testing.assert_array_equal(robots.actuator_force()[i], d.actuator_force)
        # Each foot's contact from MuJoCo's contact list of the last step, read as the MJX
        # environment reads its contact slots (footforge.envs.contacts).
        touching = foot_contacts(robot.geom_category, robot.floor_geom, *_contact_list(d))
        np.testing.assert_array_equal(robots.feet_on_ground()[i], np.asarray(touching))
    assert robots.feet_on_ground()[0].all()  # the controls: the standing robot touches with every foot,
    assert np.abs(robots.qvel[1, :2] - robots.qvel[0, :2]).max() > 0.1  # and the push moved robot 1


@pytest.mark.parametrize("feet", ["ball", "full"])
def test_base_and_thigh_ground_contacts_are_mujocos(built, feet):
    """A robot lowered through the ground: the runner's base and thigh contacts (sensors) are
    those MuJoCo's contact list names (a contact at a negative distance), and a standing robot has
    none."""
    robot = _robot(built, feet)
    robots, data = CpuRobots(robot, 3), mujoco.MjData(robot.engine_model)
    drops = (0.0, 0.35, 0.55)  # standing; thighs in the ground; the base too
    for i, drop in enumerate(drops):
        place_at_start(robot, data, None, 0)
        data.qpos[2] -= drop
        mujoco.mj_forward(robot.engine_model, data)
        robots.take(i, data)
        base, knees = ground_contacts(robot.geom_category, robot.floor_geom, *_contact_list(data))
        got_base, got_knees = robots.ground_contacts()
        assert (bool(got_base[i]), int(got_knees[i])) == (bool(base), int(knees)), drop
    base, knees = robots.ground_contacts()
    assert (bool(base[0]), int(knees[0])) == (False, 0)
    assert knees[1] == 4 and base[2]  # the controls: lowered robots do touch


def test_closure_residuals_are_mujocos_constraint_rows(built):
    """The closed chain's closure gaps and roll couplings read from sensors equal MuJoCo's own
    constraint violations (efc_pos of the equality rows), on a chain pulled open."""
    robot = _robot(built, "full")
    model = robot.engine_model
    residuals = ClosureResiduals(model)
    assert len(residuals.connect) == 12 and len(residuals.coupling) == 4
    data = mujoco.MjData(model)
    place_at_start(robot, data)
    rng = np.random.default_rng(1)
    free = np.arange(7, model.nq)
    data.qpos[free] += rng.normal(0.0, 0.05, free.size)  # every joint off: the loops open
    mujoco.mj_forward(model, data)
    gaps, couplings = residuals(data.sensordata)
    rows = data.ne  # the equality rows come first, three per connect, one per joint coupling
    by_rows = np.sqrt(np.bincount(data.efc_id[:rows], data.efc_pos[:rows] ** 2, minlength=model.neq))
    np.testing.assert_allclose(gaps, by_rows[residuals.connect], rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(couplings, by_rows[residuals.coupling], rtol=1e-9, atol=1e-12)
    assert gaps.min() > 1e-3 and couplings.min() > 1e-3  # the control: the chain is open


def test_the_runner_gives_the_same_bytes_whatever_its_threads(built, monkeypatch):
    """Several policy steps (the solver's warm start carried between them) of four closed-chain
    robots on one thread and on two: identical states."""
    robot = _robot(built, "full")
    states = []
    for threads in ("1", "2"):
        monkeypatch.setenv(THREADS_ENV, threads)
        robots = _placed(robot, 4)
        assert robots._rollouts.threads == int(threads)
        for k in range(3):
            robots.step(_targets(robot, 4, seed=k), 80)
        states.append(robots.state.copy())
    np.testing.assert_array_equal(states[0], states[1])
    assert np.abs(states[0][:, 1:] - _placed(robot, 4).state[:, 1:]).max() > 1e-3  # the control: they moved
