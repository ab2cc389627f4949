"""MJX locomotion environments for ANYmal C with any foot variant, and their registry.

    env = footforge.envs.make("flat", feet="aof", policy="BH")

Tasks x feet x policy types: flat x {ball, aff, aof} x {B, BH}; rough x {ball, aff, aof} x
{B, P, BH, PH} (the haptic types, BH and PH, need adaptive feet).
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any, get_args

from footforge.envs.config import (
    CommandConfig,
    ContactModel,
    EnvConfig,
    ResetConfig,
    RewardConfig,
    check_feet_and_policy,
)
from footforge.errors import InputError
from footforge.variants import FEET, HAPTIC, TASKS, foot_variant

FLAT_FEET_AIR_TIME = 1.0
"""The flat task's scale of RewardConfig.feet_air_time, a term the paper does not list: legged_gym's
1.0. Without it a ball policy under a straight command tracked it on three legs; with it, on all four
(docs/defaults.md). The rough task keeps the paper's ten terms."""
FLAT_TUNED_REWARDS = {"lin_vel_xy": 2.0, "yaw_rate": 1.0, "base_height": -2.0}
"""The flat task's reward scales that the paper leaves unpublished ("opportunely tuned"), tuned:
tracking weighed twice the baseline's 1.0 and 0.5 against the same penalties (MuJoCo Playground's
Go1 weighs tracking 3 and 1.5) and base height -2 where -10 was a guess. Chosen by an ablation in
which the tuning kept more robots up through 20 s, with either PPO settings
(docs/defaults.md)."""

FLAT_REWARD_SCALES = {"lin_vel_z": -0.03, "joint_acc": -3e-4, "action_rate": -0.006, **FLAT_TUNED_REWARDS}
"""The flat task's scales of the paper's terms where they differ from RewardConfig's (the rough baseline's,
OmniIsaacGymEnvs' AnymalTerrain): the flat baseline's published lin_vel_z, joint_acc and action_rate
(OmniIsaacGymEnvs' Anymal) and the tuned FLAT_TUNED_REWARDS. The rough `cpu` preset takes them too
(footforge.rl.presets.ROUGH_PRESETS says why)."""

FLAT_COMMAND_RESAMPLE_S = 5.0
"""The flat task's CommandConfig.resample_s, s: a new command every 5 s, three changes per 20-s
training episode where legged_gym's 10 s gives one. New commands are what walking policies fail
on (most falls over a 60-s evaluation come within 2 s of one); fine-tunes of the shipped policies
with commands every 5 s fell less over 60 s on every feet (ball 26 -> 14 of 64, AFF 29 -> 20, AOF
35 -> 28; ball's same fine-tune at 10 s: 37; docs/defaults.md, one training seed each). Evaluations
keep the 10-s schedule for every policy (footforge.rl.evaluate.EVALUATION_COMMAND_EVERY_S)."""


def default_config(task: str, feet: str, policy: str, contact_model: str | None = None) -> EnvConfig:
    """The task's configuration for (feet, policy), with `contact_model` (default
    EnvConfig.contact_model) and the physics step and solver iterations it needs on `feet`
    (with_contact_model).

    Raises:
      InputError: an unknown task, feet, policy type or contact model, or a haptic policy on ball feet.
    """
    if task not in TASKS:
        raise InputError(f"unknown task '{task}'", fix=f"use one of {', '.join(TASKS)}")
    if feet not in FEET:
        raise InputError(
            f"unknown feet '{feet}' for training",
            fix=f"use one of {', '.join(FEET)} (the full closed chain is for evaluation on the CPU)",
        )
    if policy not in TASKS[task]:
        raise InputError(
            f"policy type '{policy}' is not available for the {task} task", fix=f"use one of {', '.join(TASKS[task])}"
        )
    check_feet_and_policy(feet, policy)
    if task == "flat":
        # The flat baseline's published scales where it has them (the rest: the rough baseline's),
        # with the tracking terms doubled and the unpublished base-height scale -10 -> -2
        # (FLAT_TUNED_REWARDS). Its reset puts the joints at the defaults (only their velocities
        # are drawn). Position actions, default + 0.5 a, as the rough baseline, legged_gym and
        # Playground (EnvConfig.action says why not the flat baseline's velocity actions).
        flat_rewards = RewardConfig().with_scales(**FLAT_REWARD_SCALES, feet_air_time=FLAT_FEET_AIR_TIME)
        config = EnvConfig(
            task="flat",
            feet=feet,
            policy=policy,
            action="position",
            action_scale=0.5,
            rewards=flat_rewards,
            reset=ResetConfig(joint_pos_factor_range=(1.0, 1.0)),
            commands=CommandConfig(resample_s=FLAT_COMMAND_RESAMPLE_S),
        )
    else:
        # The rough baseline: position targets default + 0.5 a, planar commands in [-1, 1] m/s with
        # slow ones zeroed.
        commands = CommandConfig(lin_vel_x_range=(-1.0, 1.0), lin_vel_y_range=(-1.0, 1.0), zero_below=0.25)
        config = EnvConfig(
            task="rough", feet=feet, policy=policy, action="position", action_scale=0.5, commands=commands
        )
    contact_model = contact_model or config.contact_model
    # A str contact_model: physics() refuses an unknown one.
    return replace(config, contact_model=contact_model, **physics(feet, contact_model))  # type: ignore[arg-type]


CONTACT_MODELS = get_args(ContactModel)
POLICY_DT = EnvConfig.sim_dt * EnvConfig.decimation
"""The policy step of every task, s (50 Hz, the baselines')."""


def physics(feet: str, contact_model: str) -> dict:
    """EnvConfig's sim_dt, decimation, solver_iterations and solver_ls_iterations for `contact_model`
    on `feet` at the 50 Hz policy step (what envs.default_config sets): the step and the minimum
    iterations of its row in envs.contact_physics (float32; the same on either ground), or
    contact_physics.DEFAULT_ITERATIONS where the row has no minimum.

    Step: 'fast' the baselines' 5 ms x 4 on every feet; 'stance' and 'build' 2.5 ms x 8, the
    step at which they hold a stance. The adaptive feet take 5 ms under 'fast' too, half the
    physics of 2.5 ms: with the parameter file's passive-joint armature (1e-3 kg m^2) none diverges
    there under a policy's actions, where AOF did with the earlier 1e-5 (docs/defaults.md).

    Raises:
      InputError: an unknown contact model.
    """
    from footforge.envs.contact_physics import DEFAULT_ITERATIONS, resolve

    row = resolve(contact_model, feet, float64_physics=False, on_heightfield=False)
    iterations, ls_iterations = row.min_iterations or DEFAULT_ITERATIONS
    return {
        "sim_dt": row.sim_dt_s,
        "decimation": int(round(POLICY_DT / row.sim_dt_s)),
        "solver_iterations": iterations,
        "solver_ls_iterations": ls_iterations,
    }


def on_feet(config, feet: str):
    """`config` (a policy's training configuration) moved to `feet`: the same policy step and
    contact model, at the physics step `feet` need with it (physics()) unless the policy's own is
    finer, and with at least the solver iterations its contact model needs on `feet`
    (with_contact_model). A ball policy trained with float64 'stance' (2.5 ms x 8, 8/16
    iterations) evaluated on AOF feet thus steps AOF at 2.5 ms with 16/16 iterations, and still
    acts every 20 ms; a policy trained at a finer step than its feet need keeps its own."""
    sim_dt = min(config.sim_dt, physics(feet, config.contact_model)["sim_dt"])
    decimation = config.policy_dt / sim_dt
    if abs(decimation - round(decimation)) > 1e-6:  # a policy step the feet's step does not divide
        sim_dt, decimation = config.sim_dt, config.decimation
    moved = replace(config, feet=feet, sim_dt=sim_dt, decimation=int(round(decimation)))
    return with_contact_model(moved, config.contact_model)


def with_contact_model(config, contact_model: str):
    """`config` with `contact_model` (EnvConfig.contact_model) and what its row in envs.contact_physics
    needs beyond config's own physics, in config's precision: a step of at most the row's longest
    ('stance': 2.5 ms; the policy step kept) and at least its minimum solver iterations ('stance',
    'build'). Settings already finer than those are kept (envs.default_config sets a model's own
    physics, physics()).

    Raises:
      InputError: an unknown contact model, or a policy step the longest step does not divide.
    """
    from footforge.envs.contact_physics import resolve

    # Step and iterations are the same on either ground (tests/test_contact_physics.py).
    row = resolve(contact_model, config.feet, config.float64_physics, on_heightfield=False)
    changes: dict[str, Any] = {"contact_model": contact_model}
    longest = row.max_sim_dt_s
    if longest is not None and config.sim_dt > longest:
        decimation = config.policy_dt / longest
        if abs(decimation - round(decimation)) > 1e-6:
            raise InputError(
                f"contact_model '{contact_model}' steps at most {longest} s, which does not "
                f"divide the policy step {config.policy_dt:g} s",
                fix=f"use a policy step (sim_dt x decimation) that is a multiple of {longest * 1e3:g} ms",
            )
        changes |= {"sim_dt": longest, "decimation": int(round(decimation))}
    if row.min_iterations:
        iterations, ls_iterations = row.min_iterations
        changes |= {
            "solver_iterations": max(config.solver_iterations, iterations),
            "solver_ls_iterations": max(config.solver_ls_iterations, ls_iterations),
        }
    return replace(config, **changes)


def with_float64_physics(config, on: bool = True):
    """`config` with EnvConfig.float64_physics `on`, and the solver iterations its contact model
    needs in that precision (float64 'stance' on the adaptive feet: 16/16, where AOF takes 8/16 in
    float32; envs.contact_physics); iterations already finer are kept. JAX's x64
    mode is still the caller's to turn on (enable_float64_physics)."""
    return with_contact_model(replace(config, float64_physics=on), config.contact_model)


def enable_float64_physics(config) -> None:
    """Turns on JAX's x64 mode where `config` asks for float64 physics (EnvConfig.float64_physics).
    Process-wide: call it before JAX makes its first array (footforge's entry points do)."""
    if config.float64_physics:
        import jax

        jax.config.update("jax_enable_x64", True)


def from_config(config):
    """The environment for a configuration: LocomotionEnv (flat) or RoughEnv (rough)."""
    if config.task == "rough":
        from footforge.envs.rough import RoughEnv

        return RoughEnv(config)
    from footforge.envs.locomotion import LocomotionEnv

    return LocomotionEnv(config)


def make(task: str, feet: str, policy: str, **overrides):
    """An environment of the registry; `overrides` replace EnvConfig fields (e.g. build_dir). A
    contact_model among them comes with its own physics (default_config); a step or iterations
    given beside it win."""
    config = default_config(task, feet, policy, overrides.pop("contact_model", None))
    return from_config(replace(config, **overrides))


def registry() -> list[tuple[str, str, str]]:
    """Every valid (task, feet, policy) combination."""
    return [
        (t, f, p)
        for t, policies in TASKS.items()
        for f in FEET
        for p in policies
        if foot_variant(f).adaptive or p not in HAPTIC  # check_feet_and_policy's rule
    ]


def policy_types(task: str, feet: str, requested) -> list[str]:
    """The policy types among `requested` that `task` has on `feet`, in order and without repeats; on
    ball feet a haptic type stands for its non-haptic one (PH -> P): ball feet have no passive
    joints to sense. For benchmarks that sweep tasks, feet and policy types."""
    kept = []
    for policy in requested:
        if policy in HAPTIC and not foot_variant(feet).adaptive:
            policy = policy.replace("H", "")
        if policy in TASKS[task] and policy not in kept:
            kept.append(policy)
    return kept
