"""Brax PPO training of the locomotion environments, with checkpoints that survive a kill.

Also written: `<run>/metrics.jsonl` (every evaluation's metrics: the reward curve) and
`<run>/tensorboard/`. Brax's own checkpoints hold the policy, value and normaliser parameters but restart the step
count on resume; footforge keeps its own: after every epoch the parameters go to
`<run>/checkpoints/<global step>/` (Brax's format) and `<run>/progress.json` records the global
step, the training wall time over every call (`wall_s_total`, to the last checkpoint) and the
machine (`machine()`); the policy's footforge.json repeats the last two for its card. `--resume`
restores the latest checkpoint and trains the remaining steps with a new seed (the same seed
would replay the same experience). Adam's moments are not in Brax's checkpoints
and restart: a resumed run continues from the same policy, not the same optimiser state.

`max_wall_s` bounds a call's wall-clock time for machines whose jobs have a time limit: after each
checkpoint and its evaluation, training stops when the next epoch (estimated by the last one)
would end past the budget; the policy folder then holds the last checkpoint and
`progress.json` says `"stopped": "wall-time budget"`; `--resume` continues. The first epoch's
time includes the compilation, so a call may stop after its first checkpoint although another
epoch would have fitted: keep epochs (checkpoint_every_steps) short against the budget.
"""

from __future__ import annotations

import functools
import json
import math
import os
import shutil
import time
from dataclasses import asdict, dataclass, fields, is_dataclass
from pathlib import Path
from typing import Callable

from footforge.atomic import atomic_directory, atomic_file
from footforge.envs.config import EnvConfig
from footforge.errors import InputError


@dataclass(frozen=True)
class PPOConfig:
    """PPO hyperparameters (Brax), defaults after the paper (flat task) and its baseline."""

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
    learning_rate: float = 3e-4
    adaptive_kl: float = 0.008
    """Desired KL of the adaptive learning-rate schedule; 0 keeps the rate fixed."""
    entropy_cost: float = 0.001
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
    checkpoint_every_steps: int = 5_000_000
    """Environment steps between checkpoints (each one is also an evaluation)."""
    num_eval_envs: int = 128
    seed: int = 0

    def check(self) -> None:
        """Raises InputError on values Brax would reject later with a cryptic assertion."""
        for f in ("num_timesteps", "num_envs", "unroll_length", "num_minibatches", "batch_size",
                  "num_updates_per_batch", "checkpoint_every_steps", "num_eval_envs"):
            if getattr(self, f) < 1:
                raise InputError(f"{f} must be positive, got {getattr(self, f)}", fix=f"give a positive {f}")
        if (self.batch_size * self.num_minibatches) % self.num_envs:
            raise InputError(f"batch_size x num_minibatches ({self.batch_size} x {self.num_minibatches}) is not a "
                             f"multiple of num_envs ({self.num_envs})",
                             fix="e.g. num_envs = batch_size x num_minibatches (the defaults: 2048 = 512 x 4)")



def default_ppo(task: str, **overrides) -> PPOConfig:
    """The paper's PPO settings for a task: rough terrain uses the larger 512-256-128 networks and
    the rough baseline's budget (OmniIsaacGymEnvs' AnymalTerrainPPO: 2000 iterations of 2048
    robots x 48 steps, about 200 M steps; the paper stopped when 1000 iterations brought no gain)."""
    if task == "rough":
        overrides = {"policy_hidden_layers": (512, 256, 128), "value_hidden_layers": (512, 256, 128),
                     "num_timesteps": 200_000_000} | overrides
    return PPOConfig(**overrides)


def to_dict(config) -> dict:
    return asdict(config)


def from_dict(cls, data: dict):
    """A (nested) frozen dataclass from its asdict() form; tuples restored from lists."""
    kwargs = {}
    types = {f.name: f for f in fields(cls)}
    for name, value in data.items():
        default = types[name].default_factory() if callable(types[name].default_factory) else types[name].default
        if is_dataclass(default):
            value = from_dict(type(default), value)
        elif isinstance(value, list):
            value = tuple(value)
        kwargs[name] = value
    return cls(**kwargs)


def network_factory(ppo: PPOConfig, privileged: bool = False):
    """Brax's PPO networks; with `privileged` (EnvConfig.privileged_critic) the value network
    reads the observation dict's "privileged_state" and the policy its "state"."""
    from brax.training.agents.ppo import networks as ppo_networks
    from flax import linen

    keys = {"policy_obs_key": "state", "value_obs_key": "privileged_state"} if privileged else {}
    return functools.partial(
        ppo_networks.make_ppo_networks, policy_hidden_layer_sizes=ppo.policy_hidden_layers,
        value_hidden_layer_sizes=ppo.value_hidden_layers, activation=linen.elu,
        distribution_type="normal", noise_std_type="log", init_noise_std=ppo.init_noise_std, **keys)


def latest_checkpoint(run_dir: Path) -> tuple[int, Path] | None:
    folder = Path(run_dir) / "checkpoints"
    steps = sorted(int(p.name) for p in folder.iterdir() if p.name.isdigit()) if folder.is_dir() else []
    return (steps[-1], folder / f"{steps[-1]:012d}") if steps else None


class _OutOfTime(Exception):
    """Raised from Brax's progress callback to stop training at a checkpoint (max_wall_s)."""


def train(env_config: EnvConfig, ppo: PPOConfig, run_dir: Path, *, resume: bool = False,
          progress: Callable[[int, int, dict], None] | None = None, max_wall_s: float | None = None) -> dict:
    """Trains a policy; writes checkpoints, TensorBoard logs and the final policy into run_dir.

    Returns the final metrics. `progress(global_step, total_steps, metrics)` is called after each
    evaluation and each log of the training episodes' metrics, with the latest value of every
    metric so far. `max_wall_s`: stop at the last checkpoint that leaves time for no further epoch
    (see the module's docstring); the returned metrics then hold "stopped_for_time": 1.0.

    Raises:
      InputError: bad hyperparameters, or --resume without a checkpoint / with other configs.
    """
    from brax.training.agents.ppo import checkpoint as brax_checkpoint
    from brax.training.agents.ppo import train as ppo_train
    from tensorboardX import SummaryWriter

    from footforge.envs import from_config
    from footforge.envs.randomization import randomizer
    from footforge.envs.wrappers import wrap_for_training

    import jax

    from footforge import jax_compat

    jax_compat.install()  # Brax 0.14.2's PPO on JAX >= 0.10
    ppo.check()
    if max_wall_s is not None and max_wall_s <= 0:
        raise InputError(f"max_wall_s must be positive, got {max_wall_s}", fix="give a positive time budget")
    if max_wall_s is not None and jax.process_count() > 1:  # only process 0 would stop; the others would wait
        raise InputError("a wall-time budget works on one machine only (one JAX process)",
                         fix="leave out the time budget with --coordinator")
    if ppo.num_envs % jax.device_count():
        raise InputError(f"num_envs ({ppo.num_envs}) must be a multiple of the number of JAX devices "
                         f"({jax.device_count()}): Brax splits the robots evenly over them",
                         fix=f"e.g. --num-envs {ppo.num_envs - ppo.num_envs % jax.device_count() or jax.device_count()}")
    run_dir = Path(run_dir).resolve()
    state_file = run_dir / "progress.json"
    offset, restore, resumes, wall_s_before = 0, None, 0, 0.0
    if resume:
        found = latest_checkpoint(run_dir)
        if found is None:
            raise InputError(f"nothing to resume in {run_dir}", file=str(run_dir),
                             fix="start without --resume, or point --out at an earlier run")
        saved = json.loads((run_dir / "config.json").read_text())
        now = json.loads(json.dumps({"env": to_dict(env_config), "ppo": to_dict(ppo)}))  # tuples as lists
        if saved["env"] != now["env"] or saved["ppo"] | {"num_timesteps": 0} != now["ppo"] | {"num_timesteps": 0}:
            raise InputError("the run was started with other settings", file=str(run_dir / "config.json"),
                             fix="resume with the same options as the original run")
        offset, path = found
        restore = brax_checkpoint.load(str(path))
        previous = json.loads(state_file.read_text()) if state_file.exists() else {}
        resumes = previous.get("resumes", 0) + 1
        # Training time of the earlier calls, up to their last checkpoint (a killed call's time
        # after it is lost with its work).
        wall_s_before = previous.get("wall_s_total", previous.get("wall_s", 0.0))
    # On several machines only process 0 writes (Brax saves and evaluates there alone).
    primary = jax.process_index() == 0
    run_dir.mkdir(parents=True, exist_ok=True)
    if primary:
        _write_json(run_dir / "config.json", {"env": to_dict(env_config), "ppo": to_dict(ppo)})
    remaining = ppo.num_timesteps - offset
    if remaining <= 0:
        return json.loads(state_file.read_text()).get("metrics", {})

    env = from_config(env_config)  # Brax evaluates on the same environment
    if primary and env_config.task == "rough":  # the terrain this run walks
        from footforge.envs.terrain import preview

        with atomic_file(run_dir / "terrain.png") as tmp:
            preview(env.terrain, tmp)
    writer = SummaryWriter(str(run_dir / "tensorboard")) if primary else None
    epochs = max(1, math.ceil(remaining / ppo.checkpoint_every_steps))
    last: dict = {}
    t0 = time.time()
    this_machine = machine()
    clock = {"last_eval": t0, "stopped": False}

    def save(step: int, make_policy, params) -> None:
        global_step = offset + step
        if step == 0:
            return
        brax_checkpoint.save(str(run_dir / "checkpoints"), global_step, params,
                             brax_checkpoint.network_config(env.observation_size, env.action_size,
                                                            ppo.normalize_observations,
                                                            network_factory(ppo, env_config.privileged_critic)))
        _write_json(state_file, {"global_step": global_step, "resumes": resumes, "metrics": last,
                                 "wall_s": time.time() - t0, "wall_s_total": wall_s_before + time.time() - t0,
                                 "num_timesteps": ppo.num_timesteps, "machine": this_machine})

    def log(step: int, metrics: dict) -> None:
        if not primary:
            return
        global_step = offset + step
        for key, value in metrics.items():
            try:
                writer.add_scalar(key, float(value), global_step)
            except (TypeError, ValueError):
                continue
        writer.flush()
        now = {k: float(v) for k, v in metrics.items() if hasattr(v, "__float__")}
        last.update(now)
        with open(run_dir / "metrics.jsonl", "a") as f:  # one line per evaluation or training-episodes log
            f.write(json.dumps({"global_step": global_step, "wall_s": time.time() - t0} | now) + "\n")
        if progress:
            progress(global_step, ppo.num_timesteps, last)
        # An evaluation follows each checkpoint (step 0 has none): stop here if one more epoch,
        # timed as the last one (training, checkpoint, evaluation), would overrun the budget.
        if max_wall_s is not None and step > 0 and "eval/walltime" in metrics and offset + step < ppo.num_timesteps:
            now_t = time.time()
            epoch_s, clock["last_eval"] = now_t - clock["last_eval"], now_t
            if now_t + epoch_s > t0 + max_wall_s:
                raise _OutOfTime()

    try:
        _run_ppo(ppo_train, env, env_config, ppo, remaining, epochs, restore, resumes, log, save,
                 wrap_for_training, randomizer)
    except _OutOfTime:
        clock["stopped"] = True
    if writer:
        writer.close()
    final = latest_checkpoint(run_dir)
    if final is not None and primary:  # the policy: the last checkpoint (the final parameters) and the configs
        with atomic_directory(run_dir / "policy") as tmp:
            shutil.copytree(final[1], tmp, dirs_exist_ok=True)
            recorded = json.loads(state_file.read_text()) if state_file.exists() else {}
            _write_json(tmp / "footforge.json", {"env": to_dict(env_config), "ppo": to_dict(ppo),
                                                 "global_step": final[0], "wall_s": recorded.get("wall_s_total"),
                                                 "machine": this_machine})
    if clock["stopped"]:
        last["stopped_for_time"] = 1.0
        if primary and state_file.exists():
            _write_json(state_file, json.loads(state_file.read_text()) | {"metrics": last, "stopped": "wall-time budget"})
    return last


def machine() -> dict:
    """What trains, for the policy card: JAX's backend and devices (over every process), the
    processes, this machine's CPU cores and operating system."""
    import platform

    import jax

    devices = jax.devices()
    return {"backend": jax.default_backend(), "devices": len(devices), "device_kind": devices[0].device_kind,
            "processes": jax.process_count(), "cpu_cores": os.cpu_count(), "platform": platform.platform(),
            "jax": jax.__version__}


def _run_ppo(ppo_train, env, env_config: EnvConfig, ppo: PPOConfig, remaining: int, epochs: int, restore,
             resumes: int, log, save, wrap_for_training, randomizer) -> None:
    ppo_train.train(
        environment=env, num_timesteps=remaining, episode_length=env_config.episode_steps,
        num_envs=ppo.num_envs, unroll_length=ppo.unroll_length, batch_size=ppo.batch_size,
        num_minibatches=ppo.num_minibatches, num_updates_per_batch=ppo.num_updates_per_batch,
        learning_rate=ppo.learning_rate, entropy_cost=ppo.entropy_cost, discounting=ppo.discounting,
        gae_lambda=ppo.gae_lambda, clipping_epsilon=ppo.clipping_epsilon, vf_loss_coefficient=ppo.vf_loss_coefficient,
        max_grad_norm=ppo.max_grad_norm, reward_scaling=ppo.reward_scaling,
        normalize_observations=ppo.normalize_observations, bootstrap_on_timeout=True,
        learning_rate_schedule="ADAPTIVE_KL" if ppo.adaptive_kl else None, desired_kl=ppo.adaptive_kl or 0.01,
        network_factory=network_factory(ppo, env_config.privileged_critic), seed=ppo.seed + 1000 * resumes,
        num_evals=epochs + 1,
        num_eval_envs=ppo.num_eval_envs, progress_fn=log, policy_params_fn=save,
        restore_params=tuple(restore) if restore is not None else None, wrap_env_fn=wrap_for_training,
        randomization_fn=randomizer(env),  # EnvConfig.randomization: one draw per robot for the run
        # Evaluations (the learning curve) run the policy's mean, as a deployed policy runs.
        deterministic_eval=True,
        # Training episodes' metrics (episode/...: the terrain levels the curriculum reached, reward
        # terms, tracking errors), logged between evaluations.
        log_training_metrics=True, training_metrics_steps=max(ppo.checkpoint_every_steps // 4, 1))


def initial_policy(env_config: EnvConfig, ppo: PPOConfig, out_dir: Path, observation_size,
                   action_size: int = 12) -> Path:
    """Writes a policy folder (as train() does) holding freshly initialised networks (seed ppo.seed).

    For checking pipelines end to end without training: evaluation of such a policy exercises
    every code path; its indices mean nothing. `observation_size` is the environment's (an int,
    or with a privileged critic the dict of shapes).
    """
    import jax
    import jax.numpy as jp
    from brax.training.acme import running_statistics, specs
    from brax.training.agents.ppo import checkpoint as brax_checkpoint

    factory = network_factory(ppo, env_config.privileged_critic)
    networks = factory(observation_size=observation_size, action_size=action_size,
                       preprocess_observations_fn=running_statistics.normalize)
    k_policy, k_value = jax.random.split(jax.random.PRNGKey(ppo.seed))
    spec = ({key: specs.Array(shape, jp.dtype("float32")) for key, shape in observation_size.items()}
            if isinstance(observation_size, dict) else specs.Array((observation_size,), jp.dtype("float32")))
    normalizer = running_statistics.init_state(spec)
    params = (normalizer, networks.policy_network.init(k_policy), networks.value_network.init(k_value))
    out_dir = Path(out_dir)
    with atomic_directory(out_dir) as tmp:
        brax_checkpoint.save(str(tmp), 0, params, brax_checkpoint.network_config(
            observation_size, action_size, ppo.normalize_observations, factory))
        for item in (tmp / f"{0:012d}").iterdir():
            item.rename(tmp / item.name)
        (tmp / f"{0:012d}").rmdir()
        _write_json(tmp / "footforge.json", {"env": to_dict(env_config), "ppo": to_dict(ppo), "global_step": 0})
    return out_dir


def _write_json(path: Path, data: dict) -> None:
    """Whole or not at all: a run killed mid-write must still resume."""
    tmp = path.with_name(f".{path.name}.tmp")
    tmp.write_text(json.dumps(data, indent=1, default=float))
    os.replace(tmp, path)


def load_policy_config(policy_dir: Path) -> EnvConfig:
    """The environment configuration a saved policy was trained with.

    Raises:
      InputError: the folder is not a footforge policy.
    """
    return from_dict(EnvConfig, _policy_meta(Path(policy_dir).resolve())["env"])


def policy_meta(policy_dir: Path) -> dict:
    """A policy folder's footforge.json: "env" and "ppo" (the configurations as dicts),
    "global_step", and from training runs "wall_s" and "machine" (absent in older ones).

    Raises:
      InputError: the folder is not a footforge policy.
    """
    return _policy_meta(Path(policy_dir).resolve())


def _policy_meta(policy_dir: Path) -> dict:
    meta_file = policy_dir / "footforge.json"
    if not meta_file.is_file():
        raise InputError(f"{policy_dir} is not a footforge policy (no footforge.json)", file=str(policy_dir),
                         fix="pass the policy/ folder of a train_flat.py or train_rough.py run")
    return json.loads(meta_file.read_text())


def _observation_size(saved):
    """The observation size as Brax's networks take it, from Brax's saved network config: an
    int, an array spec ({"shape": [n], ...}), or for dict observations a mapping of each key to one
    of these (made a shape tuple)."""
    if isinstance(saved, dict) and "shape" not in saved:
        return {key: tuple(v["shape"]) if isinstance(v, dict) else tuple(v) if isinstance(v, list) else (int(v),)
                for key, v in saved.items()}
    return int(saved["shape"][0]) if isinstance(saved, dict) else int(saved)


@dataclass(frozen=True)
class SavedPolicy:
    """What a policy folder holds, read but not yet made a function (footforge.export_onnx reads
    the parameters directly)."""

    params: tuple
    """Brax's (normaliser state, policy parameters, value parameters)."""
    env: EnvConfig
    ppo: PPOConfig
    network_config: dict
    """Brax's ppo_network_config.json: observation_size, action_size, network_factory_kwargs."""
    global_step: int
    """Environment steps the policy was trained for (0: freshly initialised)."""


def load_policy_parameters(policy_dir: Path) -> SavedPolicy:
    """The parameters and configurations of a saved policy.

    Raises:
      InputError: the folder is not a footforge policy, or its checkpoint cannot be read.
    """
    from brax.training.agents.ppo import checkpoint as brax_checkpoint

    policy_dir = Path(policy_dir).resolve()
    meta = _policy_meta(policy_dir)
    env_config, ppo = from_dict(EnvConfig, meta["env"]), from_dict(PPOConfig, meta["ppo"])
    config_file = policy_dir / "ppo_network_config.json"
    try:
        cfg = json.loads(config_file.read_text())
        params = brax_checkpoint.load(str(policy_dir))
    except (OSError, ValueError, KeyError) as e:  # orbax's errors for a missing or damaged checkpoint
        reason = (str(e).splitlines() or [type(e).__name__])[0]
        raise InputError(f"the policy's checkpoint cannot be read: {reason}", file=str(policy_dir),
                         fix="pass a complete policy/ folder written by training") from None
    return SavedPolicy(tuple(params), env_config, ppo, cfg, int(meta.get("global_step", 0)))


def load_policy(policy_dir: Path, *, deterministic: bool = True):
    """(policy function obs, key -> (action, extras), EnvConfig, PPOConfig) of a saved policy."""
    import jax
    from brax.training.acme import running_statistics
    from brax.training.agents.ppo import networks as ppo_networks

    saved = load_policy_parameters(policy_dir)
    env_config, ppo, cfg = saved.env, saved.ppo, saved.network_config
    networks = network_factory(ppo, env_config.privileged_critic)(
        observation_size=_observation_size(cfg["observation_size"]), action_size=cfg["action_size"],
        preprocess_observations_fn=running_statistics.normalize if ppo.normalize_observations else (lambda x, y: x))
    make = ppo_networks.make_inference_fn(networks)
    return jax.jit(make(saved.params, deterministic=deterministic)), env_config, ppo
