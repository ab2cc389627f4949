"""What the environment asks of the robot and does to it, checked against numbers derived here:
command sampling and its dead zone (zero_below), the heading controller, the command resampling
period, the push schedule, and the total reward with and without the clip at zero.

No physics runs: the pieces are LocomotionEnv methods called eagerly, and the step test switches
MJX's step off (the reward bookkeeping around it is what is checked; the physics has tests of its
own) so nothing slow compiles."""

import math
from dataclasses import replace
from types import SimpleNamespace

import jax
import jax.numpy as jp
import numpy as np
import pytest
from mujoco import mjx

from footforge import envs
from footforge.envs.config import CommandConfig, PushConfig

DRAWS = 4000


def _env(built, **changes):
    config = replace(envs.default_config("flat", "ball", "B"), build_dir=str(built["ball"][0]), **changes)
    return envs.from_config(config)


def _yaw_quat(yaw):
    return jp.array([math.cos(yaw / 2), 0.0, 0.0, math.sin(yaw / 2)])  # MuJoCo's (w, x, y, z), about z


@pytest.fixture(scope="module")
def env(built):
    commands = CommandConfig(
        lin_vel_x_range=(-2.0, 2.0),
        lin_vel_y_range=(-1.0, 1.0),
        zero_below=0.5,
        heading_range=(-1.0, 2.0),
        heading_gain=0.5,
        yaw_rate_limit=1.0,
        resample_s=10.0,
    )
    return _env(built, commands=commands, pushes=PushConfig(interval_s=15.0, max_speed=1.0, enabled=True))


def test_commands_are_uniform_in_their_ranges_with_a_dead_zone(env):
    """vx ~ U(-2, 2), vy ~ U(-1, 1): the planar command is zeroed with the probability that a
    uniform point of the 4 x 2 m/s rectangle lies within the 0.5 m/s disc, pi 0.5^2 / 8 = 0.0982;
    every kept command is faster than 0.5 m/s; the yaw slot is left to the heading controller."""
    commands, headings, standing = jax.vmap(env.sample_command)(jax.random.split(jax.random.PRNGKey(0), DRAWS))
    commands, headings = np.asarray(commands), np.asarray(headings)
    assert not np.asarray(standing).any()  # standing_fraction 0: no standing command
    speed = np.hypot(commands[:, 0], commands[:, 1])
    zeroed = speed == 0.0
    p = math.pi * 0.5**2 / 8.0
    assert zeroed.mean() == pytest.approx(p, abs=4 * math.sqrt(p * (1 - p) / DRAWS))  # 4 sigma
    assert (speed[~zeroed] > 0.5).all()
    assert (commands[:, 2] == 0.0).all()
    kept = commands[~zeroed]
    assert kept[:, 0].min() >= -2.0 and kept[:, 0].max() <= 2.0 and kept[:, 1].min() >= -1.0 and kept[:, 1].max() <= 1.0
    # Uniform: beyond the disc's reach (|vx| > 0.5, three quarters of all draws) |vx| ~ U(0.5, 2),
    # mean 1.25 and standard deviation 1.5 / sqrt(12); headings' mean at the middle of (-1, 2).
    outside = np.abs(kept[:, 0])[np.abs(kept[:, 0]) > 0.5]
    assert outside.size / DRAWS == pytest.approx(0.75, abs=4 * math.sqrt(0.75 * 0.25 / DRAWS))
    assert outside.mean() == pytest.approx(1.25, abs=4 * (1.5 / math.sqrt(12)) / math.sqrt(outside.size))
    assert headings.min() >= -1.0 and headings.max() <= 2.0
    assert headings.mean() == pytest.approx(0.5, abs=4 * (3 / math.sqrt(12)) / math.sqrt(DRAWS))


def test_without_a_dead_zone_no_command_is_zero(built):
    env = _env(built, commands=CommandConfig(zero_below=0.0))
    commands, _, _ = jax.vmap(env.sample_command)(jax.random.split(jax.random.PRNGKey(1), 500))
    assert (np.hypot(commands[:, 0], commands[:, 1]) > 0).all()


def test_a_share_of_standing_commands_is_all_zero_and_holds_the_heading(built):
    """standing_fraction 0.25 (Isaac Lab's rel_standing_envs): a quarter of the draws (within 4
    sigma) are standing commands, zero in vx and vy and zero in yaw rate whatever the heading error;
    the other draws are the same numbers as without standing commands (their own random stream)."""
    env = _env(built, commands=CommandConfig(zero_below=0.0, standing_fraction=0.25))
    plain = _env(built, commands=CommandConfig(zero_below=0.0))
    keys = jax.random.split(jax.random.PRNGKey(3), DRAWS)
    commands, headings, standing = map(np.asarray, jax.vmap(env.sample_command)(keys))
    reference, reference_headings, _ = map(np.asarray, jax.vmap(plain.sample_command)(keys))
    assert standing.mean() == pytest.approx(0.25, abs=4 * math.sqrt(0.25 * 0.75 / DRAWS))
    assert (commands[standing] == 0.0).all() and (np.hypot(commands[~standing, 0], commands[~standing, 1]) > 0).all()
    np.testing.assert_array_equal(commands[~standing], reference[~standing])
    np.testing.assert_array_equal(headings, reference_headings)
    data = SimpleNamespace(qpos=jp.concatenate([jp.array([0.0, 0.0, 0.5]), _yaw_quat(0.0)]))
    for flag, yaw_rate in ((True, 0.0), (False, 0.5)):  # a heading error of 1 rad at gain 0.5
        info = {"command": jp.zeros(3), "heading_target": jp.float32(1.0), "standing": jp.array(flag)}
        assert float(env.heading_command(info, data)[2]) == pytest.approx(yaw_rate)


@pytest.mark.parametrize(
    "yaw, heading, expected",
    [
        (0.0, 0.5, 0.25),  # gain 0.5 x error 0.5
        (0.0, 3.0, 1.0),  # 1.5 clipped at the 1 rad/s limit
        (0.0, -3.0, -1.0),
        (3.0, -3.0, 0.5 * (2 * math.pi - 6.0)),  # the short way round: +0.283 rad, not -6
        (-3.0, 3.0, -0.5 * (2 * math.pi - 6.0)),
        (1.2, 1.2, 0.0),
    ],
)
def test_heading_controller_turns_the_short_way_within_the_limit(env, yaw, heading, expected):
    data = SimpleNamespace(qpos=jp.concatenate([jp.array([0.0, 0.0, 0.5]), _yaw_quat(yaw)]))
    info = {"command": jp.array([0.3, -0.2, 0.7]), "heading_target": jp.float32(heading), "standing": jp.array(False)}
    command = np.asarray(env.heading_command(info, data))
    np.testing.assert_allclose(command, [0.3, -0.2, expected], atol=1e-5)


def test_commands_are_redrawn_every_resample_period(env):
    """resample_s 10 s at the 0.02 s policy step: a new command and heading at steps 500, 1000,
    ..., the old ones in between (the yaw rate always follows the heading)."""
    every = round(10.0 / env.config.policy_dt)
    assert every == 500
    data = SimpleNamespace(qpos=jp.concatenate([jp.array([0.0, 0.0, 0.5]), _yaw_quat(0.0)]))
    info = {"command": jp.array([1.0, 0.0, 0.0]), "heading_target": jp.float32(0.4), "standing": jp.array(False)}
    new, new_heading = jp.array([-0.5, 0.6, 0.0]), jp.float32(-0.8)
    for step, redrawn in ((499, False), (500, True), (501, False), (999, False), (1000, True)):
        out = env.next_command(info, data, step, new, new_heading, jp.array(False))
        heading = -0.8 if redrawn else 0.4
        planar = [-0.5, 0.6] if redrawn else [1.0, 0.0]
        assert float(out["heading_target"]) == pytest.approx(heading), step
        np.testing.assert_allclose(np.asarray(out["command"]), [*planar, 0.5 * heading], atol=1e-6, err_msg=str(step))


def test_pushes_come_every_interval_with_uniform_velocities(env, built):
    """interval 15 s = 750 policy steps; each push sets vx, vy ~ U(-1, 1) m/s (standard deviation
    1 / sqrt(3)); a disabled push never fires."""
    fires = [bool(env.push(step, jax.random.PRNGKey(step))[0]) for step in (0, 1, 749, 750, 751, 1500, 2249)]
    assert fires == [True, False, False, True, False, True, False]
    velocities = np.asarray(jax.vmap(lambda k: env.push(750, k)[1])(jax.random.split(jax.random.PRNGKey(2), DRAWS)))
    assert velocities.shape == (DRAWS, 2) and np.abs(velocities).max() <= 1.0
    np.testing.assert_allclose(velocities.mean(axis=0), 0.0, atol=4 / math.sqrt(3 * DRAWS))
    np.testing.assert_allclose(velocities.std(axis=0), 1 / math.sqrt(3), rtol=0.05)
    off = _env(built, pushes=PushConfig(interval_s=15.0, enabled=False))
    assert not any(bool(off.push(step, jax.random.PRNGKey(0))[0]) for step in (0, 750, 1500))


def test_the_total_reward_is_the_sum_of_its_terms_clipped_at_zero_or_not(built, monkeypatch):
    """With the tracking terms off only penalties remain, so the sum of the weighted terms (the
    metrics reward/<term>, scale x term x dt) is negative: the step's reward is that sum with
    clip_total_at_zero False, and exactly 0 with it True (no fall: the robot stands at its spawn)."""
    monkeypatch.setattr(mjx, "step", lambda model, data: data)
    monkeypatch.setattr(mjx, "forward", lambda model, data: data)
    rewards = {}
    for clip in (False, True):
        config = envs.default_config("flat", "ball", "B")
        r = config.rewards
        r = replace(
            r,
            clip_total_at_zero=clip,
            lin_vel_xy=replace(r.lin_vel_xy, scale=0.0),
            yaw_rate=replace(r.yaw_rate, scale=0.0),
        )
        env = _env(built, rewards=r, pushes=replace(config.pushes, enabled=False))
        state = jax.jit(env.reset)(jax.random.PRNGKey(0))
        after = jax.jit(env.step)(state, jp.full(env.action_size, 0.8))  # off the default pose: the penalties bite
        assert not bool(after.done)
        terms = {k: float(v) for k, v in after.metrics.items() if k.startswith("reward/") and k != "reward/fall"}
        total = sum(terms.values())
        assert total < 0, terms
        rewards[clip] = (float(after.reward), total)
    assert rewards[False][0] == pytest.approx(rewards[False][1], rel=1e-5)
    assert rewards[True][0] == 0.0
