"""Policy folders: what a run leaves in `<run>/policy/` and how it is read back.

A policy folder is the run's newest intact checkpoint (Brax's files and the manifest) plus
`footforge.json`: the environment and PPO configs, the global step, and from training runs the
training wall time over every call and the machine (footforge.rl.train.machine), which the policy
card shows. The commands that take a policy accept the folder or the run folder around it
(policy_folder).
"""

from __future__ import annotations

import json
import shutil
from dataclasses import dataclass
from pathlib import Path

from footforge.atomic import atomic_directory, write_json
from footforge.envs.config import EnvConfig
from footforge.errors import InputError
from footforge.rl.checkpoints import CHECKPOINT_MANIFEST, checkpoint_problem, latest_intact_checkpoint, \
    write_checkpoint_manifest
from footforge.rl.config import PPOConfig, env_config_from_dict, from_dict, to_dict
from footforge.rl.networks import network_factory
from footforge.rl.run_folder import is_run_folder


def write_policy(run_dir: Path, env_config: EnvConfig, ppo: PPOConfig, this_machine: dict) -> None:
    """run_dir/policy: the newest intact checkpoint (the final parameters) and the configs."""
    final = latest_intact_checkpoint(run_dir)
    if final is None:
        return
    state_file = run_dir / "progress.json"
    with atomic_directory(run_dir / "policy") as tmp:
        shutil.copytree(final[1], tmp, dirs_exist_ok=True)
        recorded = json.loads(state_file.read_text()) if state_file.exists() else {}
        write_json(tmp / "footforge.json", {"env": to_dict(env_config), "ppo": to_dict(ppo),
                                             "global_step": final[0], "wall_s": recorded.get("wall_s_total"),
                                             "machine": this_machine})


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
        write_checkpoint_manifest(tmp)
        write_json(tmp / "footforge.json", {"env": to_dict(env_config), "ppo": to_dict(ppo), "global_step": 0})
    return out_dir


def load_policy_config(policy_dir: Path) -> EnvConfig:
    """The environment configuration a saved policy was trained with.

    Raises:
      InputError: the folder is not a footforge policy.
    """
    return env_config_from_dict(_policy_meta(Path(policy_dir).resolve())["env"])


def policy_folder(path: Path) -> Path:
    """`path` itself, or where `path` is a training run's folder, the policy/ folder inside it: the
    commands that take a policy accept either."""
    path = Path(path)
    if not (path / "footforge.json").is_file() and (path / "policy" / "footforge.json").is_file():
        return path / "policy"
    return path


def policy_meta(policy_dir: Path) -> dict:
    """A policy folder's footforge.json: "env" and "ppo" (the configurations as dicts),
    "global_step", and from training runs "wall_s" and "machine" (absent in older ones).

    Raises:
      InputError: the folder is not a footforge policy.
    """
    return _policy_meta(Path(policy_dir).resolve())


def _policy_meta(policy_dir: Path) -> dict:
    meta_file = policy_dir / "footforge.json"
    if not policy_dir.exists():
        raise InputError(f"{policy_dir} does not exist", file=str(policy_dir),
                         fix="pass a training run's folder, or its policy/ folder (a run writes it when it ends, or "
                             "stops at its time budget)")
    if not policy_dir.is_dir():
        raise InputError(f"{policy_dir} is a file, not a policy folder", file=str(policy_dir),
                         fix="pass a training run's folder (footforge train), or its policy/ folder")
    if not meta_file.is_file() and is_run_folder(policy_dir):
        raise InputError(f"{policy_dir} is a training run without a policy yet", file=str(policy_dir),
                         fix="a run writes policy/ when it ends or stops at --max-minutes; `footforge train ... "
                             "--resume --max-minutes 1` writes it from the newest checkpoint")
    if not meta_file.is_file():
        raise InputError(f"{policy_dir} is not a footforge policy (no footforge.json)", file=str(policy_dir),
                         fix="pass a training run's folder (footforge train), or its policy/ folder")
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
    """What a policy folder holds, read but not yet made a function (footforge.rl.export_onnx reads
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
    env_config, ppo = env_config_from_dict(meta["env"]), from_dict(PPOConfig, meta["ppo"])
    if (policy_dir / CHECKPOINT_MANIFEST).is_file():  # policies from before manifests have none
        problem = checkpoint_problem(policy_dir, read=False)
        if problem:
            raise InputError(f"the policy is damaged: {problem}", file=str(policy_dir),
                             fix="use the run's newest intact checkpoints/<step>/ (the same files), or train again")
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
