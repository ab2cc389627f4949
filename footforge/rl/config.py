"""PPO's settings and how a run saves them.

PPOConfig holds Brax PPO's hyperparameters; steps_per_iteration, training_epochs and planned_steps
say where a run of them ends (Brax trains whole iterations); to_dict/from_dict are config.json's
form of any frozen config (the environment's and PPO's), config_differences compares two.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields, is_dataclass, replace

from footforge.envs.config import EnvConfig
from footforge.errors import InputError


@dataclass(frozen=True)
class PPOConfig:
    """PPO hyperparameters (Brax): networks and rollout after the paper (flat task) and its
    baseline, learning rate, KL target, entropy and output initialisation after legged_gym."""

    num_timesteps: int = 100_000_000
    """Environment steps in total."""
    num_envs: int = 2048
    """Parallel robots (the paper's 2048)."""
    unroll_length: int = 48
    """Policy steps per robot per PPO iteration (the paper's 48)."""
    num_minibatches: int = 4
    batch_size: int = 512
    """Trajectories per minibatch; batch_size * num_minibatches must be a multiple of num_envs."""
    num_updates_per_batch: int = 5
    """Epochs over each batch."""
    learning_rate: float = 1e-3
    """Adam's initial rate (rsl_rl's in legged_gym; the paper's rl_games baseline starts at 3e-4)."""
    adaptive_kl: float = 0.01
    """Desired KL of the adaptive learning-rate schedule (legged_gym's 0.01; the baseline's 0.008);
    0 keeps the rate fixed."""
    entropy_cost: float = 0.01
    """Weight of the entropy bonus in PPO's loss: legged_gym's 0.01 (the paper's rl_games baseline
    uses 0.001). Chosen, with learning_rate, adaptive_kl and policy_output_init_scale, by an ablation
    in which legged_gym's settings tracked the full commands in about half the steps of the
    baseline's (docs/defaults.md)."""
    discounting: float = 0.99
    gae_lambda: float = 0.95
    clipping_epsilon: float = 0.2
    vf_loss_coefficient: float = 2.0
    max_grad_norm: float = 1.0
    reward_scaling: float = 1.0
    normalize_observations: bool = True
    policy_hidden_layers: tuple[int, ...] = (256, 128, 64)
    """The paper's flat-task network; state-independent Gaussian std."""
    value_hidden_layers: tuple[int, ...] = (256, 128, 64)
    init_noise_std: float = 1.0
    policy_mean_clip: float | None = None
    """Bounds the policy mean to +-this with Brax's softsign (mean_clip_scale: c x m / (1 + |m|));
    None leaves it unbounded. rl_games (the paper's framework) keeps the mean near the action
    bounds with its bounds loss; Brax's PPO has no such loss, and an unbounded mean far past the
    environment's clip (EnvConfig.action_clip) gets no gradient from the clipped action."""
    policy_output_init_scale: float = 0.01
    """Factor on the initial weights of the policy's output (mean) layer (Brax's lecun_uniform
    scaled); below 1 the first actions sit near zero (the default pose under position actions)
    instead of up to +-3. Only the initialisation: a saved policy loads the same either way."""
    checkpoint_every_steps: int = 5_000_000
    """Environment steps between checkpoints (each one is also an evaluation)."""
    num_eval_envs: int = 128
    seed: int = 0

    def check(self, names: dict[str, str] | None = None) -> None:
        """Raises InputError on values Brax would reject later with a cryptic assertion; each
        field is named as `names` spells it for the user (a command's flags), else by itself."""

        def name(f: str) -> str:
            return (names or {}).get(f, f)

        for f in (
            "num_timesteps",
            "num_envs",
            "unroll_length",
            "num_minibatches",
            "batch_size",
            "num_updates_per_batch",
            "checkpoint_every_steps",
            "num_eval_envs",
        ):
            if getattr(self, f) < 1:
                raise InputError(
                    f"{name(f)} must be positive, got {getattr(self, f)}", fix=f"give a positive {name(f)}"
                )
        if (self.batch_size * self.num_minibatches) % self.num_envs:
            raise InputError(
                f"{name('batch_size')} x {name('num_minibatches')} ({self.batch_size} x "
                f"{self.num_minibatches}) is not a multiple of {name('num_envs')} ({self.num_envs})",
                fix=f"e.g. {name('num_envs')} = {name('batch_size')} x {name('num_minibatches')} "
                "(the defaults: 2048 = 512 x 4)",
            )


def steps_per_iteration(ppo: PPOConfig) -> int:
    """Environment steps of one PPO iteration: batch_size x num_minibatches trajectories of
    unroll_length steps (Brax's env_step_per_training_step)."""
    return ppo.batch_size * ppo.num_minibatches * ppo.unroll_length


def training_epochs(ppo: PPOConfig, done: int = 0) -> int:
    """Epochs (each ending in a checkpoint) of a run that has done `done` steps: as many whole
    iterations each as fit in checkpoint_every_steps (at least one), enough epochs for the iterations
    the remaining steps need. Brax then trains the same whole number of iterations in every epoch
    (planned_steps), so the run ends less than one iteration per epoch past num_timesteps. (Until
    2026-11-29 the epochs were the remaining steps over checkpoint_every_steps, rounded up: with a
    checkpoint every 2.6 iterations, as the CPU's 258,048 steps of the rough task's 98,304-step
    iterations, each epoch rounded up to 3 and a 200 M-step run planned 235 M.)"""
    iteration = steps_per_iteration(ppo)
    per_epoch = max(1, ppo.checkpoint_every_steps // iteration)
    return max(1, math.ceil(math.ceil(max(ppo.num_timesteps - done, 0) / iteration) / per_epoch))


def planned_steps(ppo: PPOConfig, done: int = 0) -> int:
    """The step at which a run that has done `done` steps will end. Brax trains whole iterations,
    the same number in each epoch: ppo.num_timesteps rounded up to epochs x iterations x
    steps_per_iteration (its train.py: num_training_steps_per_epoch)."""
    remaining = ppo.num_timesteps - done
    if remaining <= 0:
        return done
    epochs, iteration = training_epochs(ppo, done), steps_per_iteration(ppo)
    return done + epochs * math.ceil(remaining / (epochs * iteration)) * iteration


def default_ppo(task: str, **overrides) -> PPOConfig:
    """The paper's PPO settings for a task: rough terrain uses the larger 512-256-128 networks and
    the rough baseline's budget (OmniIsaacGymEnvs' AnymalTerrainPPO: 2000 iterations of 2048
    robots x 48 steps, about 200 M steps; the paper stopped when 1000 iterations brought no gain)."""
    if task == "rough":
        overrides = {
            "policy_hidden_layers": (512, 256, 128),
            "value_hidden_layers": (512, 256, 128),
            "num_timesteps": 200_000_000,
        } | overrides
    return PPOConfig(**overrides)


def to_dict(config) -> dict:
    """A (nested) frozen dataclass as config.json holds it: every field but those declared in code
    (metadata "saved": False, e.g. an observation group's reading function or a reward term's
    function); a mapping (a reward term's params) as a JSON object."""
    return {f.name: _saved(getattr(config, f.name)) for f in fields(config) if f.metadata.get("saved", True)}


def _saved(value):
    if is_dataclass(value):
        return to_dict(value)
    if isinstance(value, dict):
        return {k: _saved(v) for k, v in value.items()}
    return list(value) if isinstance(value, tuple) else value


def from_dict(cls, data: dict, default=None):
    """A (nested) frozen dataclass from its to_dict() form; tuples restored from lists. Fields
    not in `data` keep their defaults (`default`, an instance, where the class has none); a
    mapping (a reward term's params) is updated key by key over its default."""
    kwargs = {}
    types = {f.name: f for f in fields(cls)}
    for name, value in data.items():
        if name not in types:
            raise InputError(
                f"unknown configuration key '{name}' for {cls.__name__}",
                fix="use the footforge version that wrote the configuration",
            )
        factory = types[name].default_factory
        field_default = (
            getattr(default, name) if default is not None else (factory() if callable(factory) else types[name].default)
        )
        if is_dataclass(field_default):
            value = from_dict(type(field_default), value, field_default)
        elif isinstance(field_default, dict) and isinstance(value, dict):
            value = field_default | {k: tuple(v) if isinstance(v, list) else v for k, v in value.items()}
        elif isinstance(value, list):
            value = tuple(value)
        kwargs[name] = value
    return replace(default, **kwargs) if default is not None else cls(**kwargs)


def env_config_from_dict(data: dict) -> EnvConfig:
    """An EnvConfig from a run's config.json "env" (older forms upgraded: envs.config.upgrade_saved)."""
    from footforge.envs.config import upgrade_saved

    return from_dict(EnvConfig, upgrade_saved(data))


def config_differences(saved: dict, now: dict, prefix: str = "") -> list[str]:
    """'field: saved -> now' for every leaf that differs between two to_dict()/JSON forms."""
    out = []
    for key in sorted(set(saved) | set(now)):
        a, b = saved.get(key), now.get(key)
        if isinstance(a, dict) and isinstance(b, dict):
            out += config_differences(a, b, f"{prefix}{key}.")
        elif a != b:
            out.append(f"{prefix}{key}: {a!r} in the run, {b!r} now")
    return out


def steps_before(origin: dict) -> int:
    """Steps trained before a run whose config.json says it was initialised from `origin`, every
    earlier source included (a record from before "steps_before" was kept gives its checkpoint's step)."""
    return int(origin.get("steps_before", origin["step"]))
