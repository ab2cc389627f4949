"""The defaults are coherent: every configuration a user gets without setting anything (the
dataclasses alone, each task's defaults for every feet and policy type, every named preset) is
one the environments accept and that means what it says. No model is loaded or compiled."""

from dataclasses import replace

import pytest

from footforge import envs
from footforge.envs import contact_physics
from footforge.envs.anymal import check_contact_model
from footforge.envs.config import EnvConfig, PushConfig
from footforge.envs.stability import VELOCITY_ACTION_SCALE
from footforge.errors import InputError
from footforge.rl import presets
from footforge.rl.config import PPOConfig

CONFIGURATIONS = [("EnvConfig()", EnvConfig(), PPOConfig())] + [
    (f"{task} {feet} {policy} --preset {name}", *presets.resolve(task, feet, policy, name))
    for task, feet, policy in envs.registry()
    for name in presets.PRESETS[task]
]


def _coherent(env: EnvConfig, ppo: PPOConfig) -> None:
    # The physics: accepted by the contact model's own check on the task's ground, at the 50 Hz
    # policy step, with the step and at least the iterations its row of the table gives.
    check_contact_model(env, on_heightfield=env.task == "rough")
    assert env.sim_dt * env.decimation == pytest.approx(envs.POLICY_DT) == pytest.approx(0.02)
    row = contact_physics.resolve(env.contact_model, env.feet, env.float64_physics, env.task == "rough")
    assert env.sim_dt == row.sim_dt_s
    least = row.min_iterations or contact_physics.DEFAULT_ITERATIONS
    assert env.solver_iterations >= least[0] and env.solver_ls_iterations >= least[1]
    # The action: joint angles around the defaults, at most 1 rad per unit, or the flat baseline's
    # integrated joint velocities, 13.5 rad/s per unit; the PD targets are observed only where they
    # are not the defaults plus the last action (velocity actions).
    if env.action == "position":
        assert 0 < env.action_scale <= 1.0 and not env.observations.pd_targets
    else:
        assert env.action_scale == VELOCITY_ACTION_SCALE
    assert env.action_clip > 0
    # An episode holds whole policy steps, and a command lasts at least one.
    assert env.episode_length_s / env.policy_dt == pytest.approx(round(env.episode_length_s / env.policy_dt))
    assert env.commands.resample_s >= env.policy_dt and (not env.pushes.enabled or env.pushes.interval_s > 0)
    # PPO: Brax's batch arithmetic, and evaluations and checkpoints that happen.
    ppo.check()
    assert (ppo.batch_size * ppo.num_minibatches) % ppo.num_envs == 0
    assert 0 < ppo.num_eval_envs and 0 < ppo.checkpoint_every_steps <= ppo.num_timesteps


@pytest.mark.parametrize("name, env, ppo", CONFIGURATIONS, ids=[c[0] for c in CONFIGURATIONS])
def test_every_default_configuration_is_coherent(name, env, ppo):
    _coherent(env, ppo)


def test_the_dataclass_defaults_are_the_flat_task_s_physics_and_action():
    """EnvConfig() alone is a flat AOF B configuration: the `stance` contact's physics on AOF, the
    position actions with their 0.5 rad per unit (until 2026-11-28 it paired them with 13.5)."""
    bare, task = EnvConfig(), envs.default_config("flat", "aof", "B")
    for field in ("task", "feet", "policy", "contact_model", "sim_dt", "decimation", "solver_iterations"):
        assert getattr(bare, field) == getattr(task, field), field
    assert (bare.action, bare.action_scale) == (task.action, task.action_scale) == ("position", 0.5)


def test_the_coherence_check_can_fail():
    """The check above refuses what an incoherent default would be."""
    bare = EnvConfig()
    for broken, error in (
        (replace(bare, action_scale=13.5), AssertionError),  # position actions of 13.5 rad per unit
        (replace(bare, action="velocity"), AssertionError),  # velocity actions at 0.5 rad/s per unit
        (replace(bare, decimation=4), AssertionError),  # a 100 Hz policy
        (replace(bare, solver_iterations=2), InputError),  # fewer iterations than stance needs on AOF
        (replace(bare, sim_dt=0.005, decimation=4), InputError),  # stance at 5 ms
        (replace(bare, pushes=PushConfig(interval_s=0.0)), AssertionError),
    ):
        with pytest.raises(error):
            _coherent(broken, PPOConfig())
