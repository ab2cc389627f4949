"""The closed-chain evaluation: CPU observations, targets and commands equal the MJX environment's;
a short run of an untrained policy on the full feet and on its training feet; refusals."""

import math
from dataclasses import replace

import jax
import jax.numpy as jp
import mujoco
import numpy as np
import pytest
from mujoco import mjx

from footforge import constants as C, envs
from footforge.envs import observation_layout, terrain as terrain_lib
from footforge.envs.config import ObservationConfig
from footforge.errors import InputError
from footforge.rl import train
from footforge.rl.evaluate_closed_chain import (
    TERRAIN_TILES,
    Controller,
    comparison_markdown,
    cpu_robot,
    evaluate_closed_chain,
    place_at_start,
)
from footforge.rl.verdict import VERDICTS

from conftest import REPO

NOISELESS = ObservationConfig(noise=False)
TILE = terrain_lib.TerrainConfig(
    num_levels=1, num_columns=1, tile_size_m=2.0, border_m=1.0, platform_m=0.5, proportions=(0, 1, 0, 0, 0, 0)
)
"""One rough-slope tile: the smallest heightfield with heights under the scan."""


@pytest.mark.parametrize("task, policy", [("flat", "B"), ("rough", "P")])
def test_cpu_controller_matches_the_mjx_env(built, monkeypatch, task, policy):
    """Same state in, same observation (the height scan on a heightfield included), PD targets,
    command, tracking errors and base height out, on AOF feet (its passive joints sit between the
    legs' joints, so the index tables matter). The physics is switched off on the MJX side: the
    two simulators differ by design, the maths around them must not, and MJX's collision code
    would take most of a minute to compile on the CPU."""
    monkeypatch.setattr(mjx, "step", lambda model, data: data)
    monkeypatch.setattr(mjx, "forward", lambda model, data: data)
    config = replace(
        envs.default_config(task, "aof", policy), build_dir=str(built["aof"][0]), observations=NOISELESS, terrain=TILE
    )
    env = envs.from_config(config)
    seed, action = 3, jp.linspace(-1.0, 1.0, 12)
    control = Controller(env, env.robot, lambda obs, key: (jp.broadcast_to(action, (obs.shape[0], 12)), {}))
    state = jax.jit(env.reset)(jax.random.split(jax.random.PRNGKey(seed), 1)[0])  # the controller's key of robot 0
    qpos = np.array(state.pipeline_state.qpos)  # the environment's spawn (on the tile for rough)
    info, obs = control.start(qpos[None], np.array(state.pipeline_state.qvel)[None], seed)
    np.testing.assert_allclose(obs[0], state.obs, atol=1e-5)

    # A state that exercises every slice: base turned and tilted, moving; joints off their defaults.
    rng = np.random.default_rng(0)
    qvel = rng.normal(0.0, 0.5, env.robot.model.nv)
    quat = rng.normal(size=4)
    qpos[3:7] = quat / np.linalg.norm(quat)
    qpos[env.robot.actuated_qpos] += rng.normal(0.0, 0.2, 12)
    state = state.replace(pipeline_state=state.pipeline_state.replace(qpos=jp.asarray(qpos), qvel=jp.asarray(qvel)))
    after = jax.jit(env.step)(state, action)
    assert not after.done  # an ended episode would restart: nothing to compare
    _, targets, _, _, info, keys = control.act(obs, qpos[None], info)
    np.testing.assert_allclose(targets[0], after.pipeline_state.ctrl[env.robot.actuator_ids], atol=1e-6)
    info, obs, row = control.settle(
        qpos[None], qvel[None], info, keys, action[None], after.pipeline_state.actuator_force[None]
    )
    np.testing.assert_allclose(obs[0], after.obs, atol=1e-5)
    np.testing.assert_allclose(info["command"][0], after.info["command"], atol=1e-6)
    # Both sides call the same observation functions, so the proprioceptive block is also computed
    # here by hand, from MuJoCo's own conventions (a free joint's linear velocity is in the world
    # frame, its angular velocity in the body frame) and joints found by name.
    q, v = np.asarray(after.pipeline_state.qpos), np.asarray(after.pipeline_state.qvel)
    rot = np.zeros(9)
    mujoco.mju_quat2Mat(rot, q[3:7])
    rot = rot.reshape(3, 3)
    model = env.robot.model
    joints = [model.joint(name) for name in C.ACTUATED_JOINTS]
    joint_q = np.array([q[j.qposadr[0]] for j in joints]) - np.array(
        [C.DEFAULT_JOINT_ANGLES_RAD[n] for n in C.ACTUATED_JOINTS]
    )
    joint_v = np.array([v[j.dofadr[0]] for j in joints])
    by_hand = np.concatenate(
        [
            2.0 * rot.T @ v[:3],
            0.25 * v[3:6],
            rot.T @ [0.0, 0.0, -1.0],
            np.asarray(after.info["command"]) * [2.0, 2.0, 0.25],
            joint_q,
            0.05 * joint_v,
            np.asarray(action),
        ]
    )
    np.testing.assert_allclose(obs[0][: by_hand.size], by_hand, atol=1e-5)
    for ours, theirs in (
        ("lin_vel_x_error", "error/lin_vel_x_per_step"),
        ("lin_vel_y_error", "error/lin_vel_y_per_step"),
        ("yaw_rate_error", "error/yaw_rate_per_step"),
        ("base_height", "base_height_m_per_step"),
    ):
        assert row[ours][0] == pytest.approx(float(after.metrics[theirs]), abs=1e-5)


@pytest.fixture(scope="module")
def untrained(built, tmp_path_factory):
    """Freshly initialised B (ball) and BH (aof) policy folders."""
    root = tmp_path_factory.mktemp("policies")
    b = replace(envs.default_config("flat", "ball", "B"), build_dir=str(built["ball"][0]))
    bh = replace(envs.default_config("flat", "aof", "BH"), build_dir=str(built["aof"][0]))
    return {
        "B": train.initial_policy(b, train.PPOConfig(), root / "B", observation_size=observation_layout.size(b, 0)),
        "BH": train.initial_policy(
            bh, train.PPOConfig(), root / "BH", observation_size=observation_layout.size(bh, 16)
        ),
    }


def test_short_run_on_the_closed_chain_and_the_training_feet(built, untrained):
    result = evaluate_closed_chain(untrained["B"], seconds=0.2, num_robots=1, build_root=built["full"][0].parent)
    assert list(result["feet"]) == ["ball", "full"]
    for feet, column in result["feet"].items():
        assert column["physics_steps_per_policy_step"] == {"ball": 8, "full": 80}[feet]  # 2.5 ms (stance), 0.25 ms
        assert column["finite"] and column["falls"] == 0 and column["fall_times_s"] == [None]
        figures = [v for index in column["indices"].values() for v in index.values()]
        figures += [column["simulated_s"], column["wall_s"], column["real_time_factor"]]
        assert len(figures) == 17 and np.isfinite(figures).all()
        assert column["traces"]["vx_m_s"].shape == (1, 10)
        assert column["walking"]["verdict"] in VERDICTS and column["walking"]["uptime"] == 1.0
    closure = result["feet"]["full"]["closure"]
    assert result["feet"]["ball"]["closure"] is None
    assert closure["num_closures"] == 12 and closure["num_couplings"] == 4
    assert np.isfinite(list(closure.values())).all()
    # The loop closures are soft constraints (solref 1 ms time constant, damping ratio 1; solimp
    # impedance d = 0.99 at zero violation): MuJoCo holds a residual r = (1 - d) / d x a0 x (1 ms)^2,
    # with a0 the acceleration the load would give the chain's links unconstrained. A standing
    # robot puts about 40 N through each chain of 8 g links, a0 ~ 5e3 m/s^2: r ~ 0.05 mm. 0.5 mm
    # leaves ten times that for touchdown peaks and is still 40 times below the 17-20 mm that
    # MuJoCo's default settings let the loops open by.
    assert closure["closure_gap_max_m"] < 0.5e-3
    assert closure["closure_gap_mean_m"] <= closure["closure_gap_max_m"]
    assert closure["coupling_max_rad"] < math.radians(1.0)  # the roll coupling, same constraint softness
    table = comparison_markdown([result])
    assert "ball (trained)" in table and "full (zero-shot)" in table
    assert result["feet"]["full"]["walking"]["line"] in table


@pytest.mark.parametrize("feet", ["aof", "full"])
def test_every_robot_spawns_clear_of_the_terrain_tiles(built, feet):
    """`--terrain` starts robot i on the centre of tile i of the hardest level: its whole stance
    (feet up to 0.55 m from the base) on the flat platform, no collision geom more than 1 mm into
    the ground. With a 1 m platform the front feet stood 15-19 mm into the smooth slope, and the
    closed chain diverged within 0.04 s."""
    config = replace(envs.default_config("flat", "aof", "B"), build_dir=str(built["aof"][0]))
    terrain = terrain_lib.generate(TERRAIN_TILES)
    robot = cpu_robot(config, feet, built["full"][0].parent, terrain, own_physics=feet == "full")
    data = mujoco.MjData(robot.model)
    for i in range(TERRAIN_TILES.num_columns):
        place_at_start(robot, data, terrain, i)
        deepest = min((data.contact[k].dist for k in range(data.ncon)), default=0.0)
        assert data.ncon > 0 and deepest > -1e-3, (terrain.column_kinds[i], deepest)


def test_a_haptic_policy_runs_on_the_closed_chain_through_the_foot_imus(built, untrained, monkeypatch):
    """A BH policy trained on AOF reads its 16 passive joints on the closed chain from the feet's
    IMU estimates (footforge.rl.foot_imu), which reach the observation where AOF's joints would."""
    from footforge.rl import evaluate_closed_chain as closed_chain

    seen = []
    original = closed_chain.FootImuEstimator.__call__

    def recording(self, data):
        angles, rates = original(self, data)
        seen.append((angles, rates))
        return angles, rates

    monkeypatch.setattr(closed_chain.FootImuEstimator, "__call__", recording)
    result = evaluate_closed_chain(untrained["BH"], seconds=0.1, num_robots=1, build_root=built["full"][0].parent)
    assert list(result["feet"]) == ["aof", "full"]
    assert result["passive_joints_on_full"]["joints"][:4] == [
        "LF_foot/ankle_pitch",
        "LF_foot/ankle_roll",
        "LF_foot/sole_back",
        "LF_foot/sole_front",
    ]
    assert all(column["finite"] for column in result["feet"].values())
    assert seen and all(
        a.shape == (16,) and r.shape == (16,) and np.isfinite(a).all() and np.isfinite(r).all() for a, r in seen
    )
    # The robot starts at `stand` and settles: its feet deform, so the estimates move off zero.
    assert max(np.abs(a).max() for a, _ in seen) > math.radians(0.5)


def test_bad_inputs_are_refused(untrained):
    with pytest.raises(InputError, match="must be positive"):
        evaluate_closed_chain(untrained["B"], seconds=0.0)


@pytest.mark.slow  # 4 closed-chain robots for 6 s at 0.25 ms: about a minute on 2 cores
@pytest.mark.timeout(600)  # explicit budget: several times its time on 2 quiet cores
def test_a_walking_policy_does_not_break_the_closed_chain(built):
    """The shipped AOF policy walking the closed chain: no robot's simulation diverges and the
    loops stay shut within 3 mm. With MuJoCo's default (soft) joint stops and the chain pins'
    old armature of 1e-6 kg m^2, robots 1 and 0 of this seed diverged at 3.4 and 5.6 s, the
    loops opening by 6.3 mm (benchmarks/RESULTS.md, the shipped policies on the closed chain)."""
    result = evaluate_closed_chain(
        REPO / "policies/flat_aof_B/policy", seconds=6.0, num_robots=4, seed=0, build_root=built["full"][0].parent
    )
    full = result["feet"]["full"]
    assert full["diverged"] == 0 and full["finite"], full["fall_times_s"]
    assert full["closure"]["closure_gap_max_m"] < 3e-3
