"""MJX locomotion environments: registry, observation layout, reset/step, rewards, termination."""

import math
from dataclasses import replace

import jax
import jax.numpy as jp
import numpy as np
import pytest

from footforge import envs
from footforge.envs import observations, rewards
from footforge.envs.anymal import GEOM_BASE
from footforge.envs.config import EnvConfig
from footforge.envs.locomotion import LocomotionEnv, ground_contacts
from footforge.errors import InputError


def test_registry_and_its_errors():
    assert [r for r in envs.registry() if r[0] == "flat"] == [
        ("flat", "ball", "B"), ("flat", "aff", "B"), ("flat", "aff", "BH"), ("flat", "aof", "B"), ("flat", "aof", "BH")]
    assert [r for r in envs.registry() if r[0] == "rough"] == [
        ("rough", "ball", "B"), ("rough", "ball", "P"), ("rough", "aff", "B"), ("rough", "aff", "P"),
        ("rough", "aff", "BH"), ("rough", "aff", "PH"), ("rough", "aof", "B"), ("rough", "aof", "P"),
        ("rough", "aof", "BH"), ("rough", "aof", "PH")]
    with pytest.raises(InputError, match="not available for the flat task"):
        envs.default_config("flat", "aof", "P")
    with pytest.raises(InputError, match="ball foot has none"):
        envs.default_config("flat", "ball", "BH")
    with pytest.raises(InputError, match="unknown task 'stairs'"):
        envs.default_config("stairs", "aof", "B")
    with pytest.raises(InputError, match="unknown feet 'full'"):
        envs.default_config("flat", "full", "B")


def test_observation_layout_is_documented_and_sized():
    b, bh = EnvConfig(policy="B"), EnvConfig(policy="BH")
    assert observations.size(b, 16) == 48  # the baseline's 48
    assert observations.size(bh, 8) == 48 + 16 and observations.size(bh, 16) == 48 + 32
    assert [name for name, _ in observations.layout(bh, 16)][-2:] == ["foot_joint_pos", "foot_joint_vel"]
    assert all(len(entry) == 3 and entry[2] for entry in observations.LAYOUT)


RICHEST = {"ball": "B", "aff": "BH", "aof": "BH"}


@pytest.fixture(scope="module")
def rollouts(built):
    """Per feet, the richest flat policy type's env with reset and step compiled once, a reset
    and 3 steps of random actions: {feet: (env, states, jitted step)}. Pushes are off: the
    zero-action test measures standing, not push recovery."""
    out = {}
    for feet, policy in RICHEST.items():
        config = envs.default_config("flat", feet, policy)
        env = envs.make("flat", feet, policy, build_dir=str(built[feet][0]),
                        pushes=replace(config.pushes, enabled=False))
        step = jax.jit(env.step)
        states = [jax.jit(env.reset)(jax.random.PRNGKey(0))]
        for k in jax.random.split(jax.random.PRNGKey(1), 3):
            states.append(step(states[-1], jax.random.normal(k, (env.action_size,))))
        out[feet] = (env, states, step)
    return out


def test_reset_and_step_every_registered_env(rollouts, built):
    for feet, (env, states, _) in rollouts.items():
        n_passive = {"ball": 0, "aff": 8, "aof": 16}[feet]
        assert len(env.robot.passive_qpos) == n_passive
        assert env.observation_size == observations.size(env.config, n_passive)
        for state in states:
            assert state.obs.shape == (env.observation_size,)
            assert bool(jp.isfinite(state.obs).all()) and bool(jp.isfinite(state.reward))
            assert float(jp.abs(state.obs).max()) <= env.config.observations.clip
        assert set(states[-1].metrics) == set(states[0].metrics)
        assert {f"reward/{t}" for t in rewards.TERMS} <= set(states[-1].metrics)
        # The flat task starts at the build's `stand` keyframe (at rest under the published
        # default targets), the PD targets at those defaults, joint velocities within +-0.1 rad/s.
        first = states[0]
        np.testing.assert_allclose(first.pipeline_state.qpos, env.robot.stand_qpos, atol=1e-6)
        np.testing.assert_allclose(first.info["target"], env.robot.default_q, atol=1e-9)
        np.testing.assert_allclose(first.pipeline_state.ctrl[env.robot.actuator_ids], env.robot.default_q, atol=1e-9)
        qd = np.asarray(first.pipeline_state.qvel[env.robot.actuated_dof])
        assert np.abs(qd).max() <= env.config.reset.joint_vel_max and np.abs(qd).max() > 0
        assert float(jp.abs(first.pipeline_state.qvel[:6]).max()) == 0.0
        # The other policy types of these feet differ from the richest only in the observation:
        # each one's observation of the stepped state is sized by its layout, finite, and a
        # prefix of the richest one's (noise off).
        quiet = replace(env.config.observations, noise=False)
        full = LocomotionEnv(replace(env.config, observations=quiet), env.robot)._observe(
            states[-1].pipeline_state, states[-1].info, jax.random.PRNGKey(0))
        for task, f, policy in envs.registry():
            if task == "flat" and f == feet:
                other = LocomotionEnv(replace(envs.default_config("flat", feet, policy), observations=quiet,
                                              build_dir=str(built[feet][0])), env.robot)
                obs = other._observe(states[-1].pipeline_state, states[-1].info, jax.random.PRNGKey(0))
                assert obs.shape == (other.observation_size,)
                np.testing.assert_allclose(obs, full[:other.observation_size], atol=1e-6)


def test_reward_terms_on_known_states():
    sigma = 0.25
    assert float(rewards.lin_vel_xy(jp.array([1.0, 0.0]), jp.array([1.0, 0.0]), sigma)) == pytest.approx(1.0)
    assert float(rewards.lin_vel_xy(jp.array([1.0, 0.0]), jp.array([0.5, 0.0]), sigma)) == pytest.approx(math.exp(-1))
    assert float(rewards.yaw_rate(0.5, 0.0, sigma)) == pytest.approx(math.exp(-1))
    assert float(rewards.lin_vel_z(0.3)) == pytest.approx(0.09)
    assert float(rewards.ang_vel_xy(jp.array([0.1, 0.2, 5.0]))) == pytest.approx(0.05)
    assert float(rewards.orientation(jp.array([0.0, 0.0, -1.0]))) == 0.0
    tilt = math.radians(30)  # base rolled by 30 deg: gravity has sin(30) along base y
    assert float(rewards.orientation(jp.array([0.0, math.sin(tilt), -math.cos(tilt)]))) == pytest.approx(0.25)
    assert float(rewards.base_height(0.42, 0.52)) == pytest.approx(0.01)
    assert float(rewards.torques(jp.full(12, 10.0))) == pytest.approx(1200.0)
    assert float(rewards.joint_acc(jp.ones(12), jp.zeros(12))) == pytest.approx(12.0)
    assert float(rewards.action_rate(jp.ones(12), jp.ones(12))) == 0.0
    assert float(rewards.hip(jp.array([0.13, -0.13, 0.03, -0.03]), jp.array([0.03, -0.03, 0.03, -0.03]))) == pytest.approx(0.2)


def test_ground_contacts_count_base_and_knees():
    category = jp.array([0, GEOM_BASE, 3, 4, 5, 6])  # geom 0 is the floor
    geoms = jp.array([[0, 1], [0, 3], [4, 0], [0, 5]])
    base, knees = ground_contacts(category, 0, geoms, jp.array([0.01, -0.001, -0.002, 0.02]))
    assert not bool(base) and int(knees) == 2  # thighs of legs 0 and 1 touch; leg 2's is 2 cm above
    base, knees = ground_contacts(category, 0, geoms, jp.array([-0.001, 0.01, 0.01, 0.01]))
    assert bool(base) and int(knees) == 0


def test_base_on_the_ground_terminates_and_time_out_is_a_truncation(rollouts):
    env, states, step = rollouts["ball"]
    state = states[0]
    data = state.pipeline_state
    sunk = step(state.replace(pipeline_state=data.replace(qpos=data.qpos.at[2].set(0.05))), jp.zeros(12))
    assert float(sunk.done) == 1.0 and float(sunk.info["time_out"]) == 0.0  # a fall, not a time-out
    np.testing.assert_allclose(sunk.pipeline_state.qpos, env.robot.stand_qpos, atol=1e-6)  # restarted standing
    assert float(sunk.reward) == pytest.approx(env.config.rewards.fall)  # the fall penalty survives the clip
    assert float(sunk.metrics["reward/fall"]) == pytest.approx(env.config.rewards.fall)
    last = state.replace(info=state.info | {"episode_step": jp.array(env.config.episode_steps - 1, jp.int32)})
    after = step(last, jp.zeros(12))
    assert float(after.info["time_out"]) == 1.0 and float(after.done) == 1.0
    assert int(after.info["episode_step"]) == 0
    assert float(after.metrics["reward/fall"]) == 0.0 and float(after.reward) >= 0.0  # a time-out is no fall


def test_velocity_actions_integrate_onto_the_previous_target(rollouts):
    """Flat task: target_t = target_t-1 + 13.5 x clip(a, +-1) x dt, whatever the joints do; the
    reward and the next observation see the clipped action."""
    env, states, step = rollouts["ball"]
    state = states[0]
    dt, scale = env.config.policy_dt, env.config.action_scale
    action = jp.linspace(-3.0, 3.0, 12)  # half of it beyond the clip
    after = step(state, action)
    clipped = np.clip(np.asarray(action), -1.0, 1.0)
    expected = np.clip(np.asarray(state.info["target"]) + scale * clipped * dt, env.robot.q_limits[:, 0],
                       env.robot.q_limits[:, 1])
    np.testing.assert_allclose(after.info["target"], expected, atol=1e-6)
    np.testing.assert_allclose(after.pipeline_state.ctrl[env.robot.actuator_ids], expected, atol=1e-6)
    np.testing.assert_allclose(after.info["last_action"], clipped, atol=1e-7)
    # A zero action keeps the target where it was, although the joints moved.
    again = step(after, jp.zeros(12))
    np.testing.assert_allclose(again.info["target"], after.info["target"], atol=1e-7)
    moved = np.abs(np.asarray(again.pipeline_state.qpos[env.robot.actuated_qpos]) - expected).max()
    assert moved > 1e-3


@pytest.mark.parametrize("feet", list(RICHEST))
def test_zero_action_robot_stands_a_whole_episode(rollouts, feet):
    """The flat task's robot, given zero actions, holds its stance for a full 20 s episode: no
    fall, no divergence, the base within 5 cm of where it started."""
    env, states, step = rollouts[feet]
    state = states[0]
    z0 = float(env.base_height(state.pipeline_state))
    lowest = z0
    for _ in range(env.config.episode_steps - 1):
        state = step(state, jp.zeros(12))
        assert float(state.done) == 0.0, f"{feet}: fell at episode step {int(state.info['episode_step'])}"
        lowest = min(lowest, float(env.base_height(state.pipeline_state)))
    assert z0 - lowest < 0.05, (feet, z0, lowest)
