"""Domain randomisation: one draw per robot, within the configured ranges, reproducible, and
acting on the physics it names."""

import functools

import jax
import jax.numpy as jp
import numpy as np
import pytest

from footforge import constants as C, envs
from footforge.envs.config import RandomizationConfig
from footforge.envs.randomization import randomizer

FULL = RandomizationConfig(
    friction_range=(0.5, 1.25), payload_mass_kg_range=(-1.0, 1.0), motor_strength_range=(0.9, 1.1)
)


@pytest.fixture(scope="module")
def env(built):
    return envs.make("flat", "ball", "B", build_dir=str(built["ball"][0]), randomization=FULL)


def test_draws_are_per_robot_in_range_and_reproducible(env):
    keys = jax.random.split(jax.random.PRNGKey(0), 64)
    fn = randomizer(env)
    batched, in_axes = fn(env.sys, keys)
    again, _ = fn(env.sys, keys)
    friction = np.asarray(batched.geom_friction[:, :, 0])
    assert friction.shape == (64, env.sys.ngeom)
    assert np.all(friction == friction[:, :1])  # every geom of a robot: the same draw
    assert 0.5 <= friction.min() and friction.max() <= 1.25 and friction[:, 0].std() > 0.1
    np.testing.assert_array_equal(friction, np.asarray(again.geom_friction[:, :, 0]))
    assert in_axes.geom_friction == 0 and in_axes.body_mass == 0 and in_axes.geom_size is None
    # Payload: the robot's total mass changes by exactly the draw, within +-1 kg.
    base = env.robot.model.body(C.BASE_BODY).id
    added = np.asarray(batched.body_mass.sum(axis=1)) - float(env.sys.body_mass.sum())
    np.testing.assert_allclose(
        added, np.asarray(batched.body_mass[:, base]) - float(env.sys.body_mass[base]), atol=1e-5
    )
    assert -1.0 <= added.min() and added.max() <= 1.0 and added.std() > 0.2
    # Motor strength: kp, kv and the torque limit scaled by one factor per robot.
    kp = np.asarray(batched.actuator_gainprm[:, :, 0]) / float(env.sys.actuator_gainprm[0, 0])
    kv = np.asarray(batched.actuator_biasprm[:, :, 2]) / float(env.sys.actuator_biasprm[0, 2])
    limit = np.asarray(batched.actuator_forcerange[:, :, 1]) / float(env.sys.actuator_forcerange[0, 1])
    np.testing.assert_allclose(kp, kv, rtol=1e-5)
    np.testing.assert_allclose(kp, limit, rtol=1e-5)
    assert 0.9 <= kp.min() and kp.max() <= 1.1
    np.testing.assert_allclose(
        -np.asarray(batched.actuator_biasprm[:, :, 1]), np.asarray(batched.actuator_gainprm[:, :, 0]), rtol=1e-6
    )  # still a PD at the target


def test_nothing_randomised_gives_no_function(built):
    off = RandomizationConfig(friction_range=None)
    env = envs.make("flat", "ball", "B", build_dir=str(built["ball"][0]), randomization=off)
    assert randomizer(env) is None


@pytest.mark.slow  # compiles a batch of per-robot models: about 3 minutes on 2 cores
@pytest.mark.timeout(600)  # explicit budget: several times its time on 2 quiet cores
def test_randomised_robots_step_with_their_own_physics(env):
    """Through Brax's wrapper each robot steps its own model: under the same PD gains a heavier
    robot sags lower (about 1.7 mm per kg at kp 80)."""
    from dataclasses import replace

    from footforge.envs.config import ResetConfig
    from footforge.envs.wrappers import wrap_for_training

    payload = RandomizationConfig(friction_range=None, payload_mass_kg_range=(-1.0, 1.0))
    heavy = envs.from_config(replace(env.config, randomization=payload, reset=ResetConfig((1.0, 1.0), 0.0)))
    keys = jax.random.split(jax.random.PRNGKey(1), 4)
    wrapped = wrap_for_training(heavy, 1000, randomization_fn=functools.partial(randomizer(heavy), rng=keys))
    state = jax.jit(wrapped.reset)(jax.random.split(jax.random.PRNGKey(2), 4))
    step = jax.jit(wrapped.step)
    for _ in range(50):  # 1 s: settled again after the payload's step change
        state = step(state, jp.zeros((4, 12)))
    batched, _ = randomizer(heavy)(heavy.sys, keys)
    mass = np.asarray(batched.body_mass.sum(axis=1))
    heights = np.asarray(state.pipeline_state.qpos[:, 2])
    assert np.all(np.isfinite(heights)) and not np.asarray(state.done).any()
    order = np.argsort(mass)
    assert np.all(np.diff(heights[order]) < 0), (mass, heights)


def test_the_c_engine_steps_each_robot_with_its_own_model(built):
    """Under MuJoCo's C engine (EnvConfig.physics 'mujoco') each robot steps its own randomised
    model: robot i's state after 0.5 s equals MuJoCo's own mj_step, run by hand on a copy of the
    model with robot i's draw (payload and motor strength) written into it, to the solver's
    tolerance; the same by hand with the model as built parts from it by millimetres (so the draw
    is what made the difference)."""
    import copy
    from dataclasses import replace

    import mujoco

    from footforge.envs.config import ResetConfig
    from footforge.envs.wrappers import wrap_for_training

    draws = RandomizationConfig(friction_range=None, payload_mass_kg_range=(-1.0, 1.0), motor_strength_range=(0.9, 1.1))
    config = envs.default_config("flat", "ball", "B")
    env = envs.make(
        "flat",
        "ball",
        "B",
        build_dir=str(built["ball"][0]),
        physics="mujoco",
        randomization=draws,
        reset=ResetConfig((1.0, 1.0), 0.0),
        pushes=replace(config.pushes, enabled=False),
    )
    keys = jax.random.split(jax.random.PRNGKey(1), 4)
    wrapped = wrap_for_training(env, 1000, randomization_fn=functools.partial(randomizer(env), rng=keys))
    state = jax.jit(wrapped.reset)(jax.random.split(jax.random.PRNGKey(2), 4))
    start = state.pipeline_state
    step, policy_steps = jax.jit(wrapped.step), 25
    for _ in range(policy_steps):
        state = step(state, jp.zeros((4, 12)))
    end = state.pipeline_state
    assert not np.asarray(state.done).any()
    batched, _ = randomizer(env)(env.sys, keys)

    def by_hand(i, model):
        data = mujoco.MjData(model)
        data.qpos[:] = np.asarray(start.qpos[i], np.float64) + np.asarray(start.qpos_rest[i], np.float64)
        data.qvel[:] = np.asarray(start.qvel[i], np.float64) + np.asarray(start.qvel_rest[i], np.float64)
        data.ctrl[:] = np.asarray(start.ctrl[i], np.float64)  # zero actions: the default targets throughout
        for _ in range(policy_steps * env.config.decimation):
            mujoco.mj_step(model, data)
        return data.qpos

    for i in range(4):
        own = copy.copy(env.robot.engine_model)
        for name in ("body_mass", "body_inertia", "actuator_gainprm", "actuator_biasprm", "actuator_forcerange"):
            getattr(own, name)[:] = np.asarray(getattr(batched, name)[i], np.float64)
        engine_qpos = np.asarray(end.qpos[i], np.float64) + np.asarray(end.qpos_rest[i], np.float64)
        assert np.max(np.abs(by_hand(i, own) - engine_qpos)) < 1e-6, i
        assert np.max(np.abs(by_hand(i, env.robot.engine_model) - engine_qpos)) > 1e-4, i
