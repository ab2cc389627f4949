"""Policy folders: what a run leaves in `<run>/policy/` and how it is read back.

A policy folder is the run's newest intact checkpoint (Brax's files and the manifest) plus
`footforge.json`: the environment and PPO configs, the global step, and from training runs the
training wall time over every call and the machine (footforge.rl.train.machine), which the policy
card shows. The commands that take a policy (export, evaluate, play) accept the policy folder, the
run folder around it, or one of the run's checkpoint folders (`<run>/checkpoints/<step>/`, its
configs read from the run's config.json): a run without a policy yet, or with a damaged one, is used
through its newest intact checkpoint (policy_folder, policy_meta).
"""

from __future__ import annotations

import json
import shutil
from dataclasses import dataclass
from pathlib import Path

from footforge.atomic import atomic_directory, write_json
from footforge.envs.config import EnvConfig
from footforge.errors import InputError
from footforge.rl.checkpoints import (
    CHECKPOINT_MANIFEST,
    checkpoint_problem,
    latest_intact_checkpoint,
    legacy_run,
    write_checkpoint_manifest,
)
from footforge.rl.config import PPOConfig, env_config_from_dict, from_dict, to_dict
from footforge.rl.networks import network_factory
from footforge.rl.run_folder import is_run_folder


def write_policy(run_dir: Path, env_config: EnvConfig, ppo: PPOConfig, this_machine: dict) -> int | None:
    """run_dir/policy: the newest intact checkpoint (the final parameters) and the configs. Returns
    that checkpoint's step (None: no intact checkpoint, nothing written)."""
    final = latest_intact_checkpoint(run_dir)
    if final is None:
        return None
    state_file = run_dir / "progress.json"
    with atomic_directory(run_dir / "policy") as tmp:
        shutil.copytree(final[1], tmp, dirs_exist_ok=True)
        recorded = json.loads(state_file.read_text()) if state_file.exists() else {}
        write_json(
            tmp / "footforge.json",
            {
                "env": to_dict(env_config),
                "ppo": to_dict(ppo),
                "global_step": final[0],
                "wall_s": recorded.get("wall_s_total"),
                "machine": this_machine,
            },
        )
    return final[0]


def policy_problem(run_dir: Path) -> str | None:
    """Why run_dir/policy is not the run's final policy (missing, damaged, or older than the
    newest intact checkpoint), or None when it is, or when there is no intact checkpoint to
    write it from."""
    final = latest_intact_checkpoint(run_dir)
    if final is None:
        return None
    folder = Path(run_dir) / "policy"
    try:
        step = int(json.loads((folder / "footforge.json").read_text())["global_step"])
    except FileNotFoundError:
        return "it has no policy/ yet"
    except (OSError, ValueError, KeyError, TypeError):
        return "its policy/footforge.json is unreadable"
    problem = _damaged(folder)
    if problem:
        return f"its policy/ is damaged ({problem})"
    if step != final[0]:
        return f"its policy/ is from step {step:,}, its newest intact checkpoint from {final[0]:,}"
    return None


def initial_policy(
    env_config: EnvConfig, ppo: PPOConfig, out_dir: Path, observation_size, action_size: int = 12
) -> Path:
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
    networks = factory(
        observation_size=observation_size,
        action_size=action_size,
        preprocess_observations_fn=running_statistics.normalize,
    )
    k_policy, k_value = jax.random.split(jax.random.PRNGKey(ppo.seed))
    spec = (
        {key: specs.Array(shape, jp.dtype("float32")) for key, shape in observation_size.items()}
        if isinstance(observation_size, dict)
        else specs.Array((observation_size,), jp.dtype("float32"))
    )
    normalizer = running_statistics.init_state(spec)
    params = (normalizer, networks.policy_network.init(k_policy), networks.value_network.init(k_value))
    out_dir = Path(out_dir)
    with atomic_directory(out_dir) as tmp:
        brax_checkpoint.save(
            str(tmp),
            0,
            params,
            brax_checkpoint.network_config(observation_size, action_size, ppo.normalize_observations, factory),
        )
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
    return env_config_from_dict(_policy_meta(policy_folder(policy_dir).resolve())["env"])


def policy_folder(path: Path) -> Path:
    """The folder whose parameters a command given `path` uses: `path` itself (a policy folder or a
    checkpoint folder), or for a training run's folder its policy/ when intact, else its newest
    intact checkpoint (a run stopped before it wrote policy/)."""
    path = Path(path)
    if (path / "footforge.json").is_file():
        return path
    policy = path / "policy"
    intact_policy = (policy / "footforge.json").is_file() and not _damaged(policy)
    if intact_policy or not is_run_folder(path):
        return policy if (policy / "footforge.json").is_file() else path
    # A run without policy/, or with a damaged one: its newest intact checkpoint (hashed only here);
    # with none, the damaged policy (whose damage the loader reports) or the run (which it names).
    final = latest_intact_checkpoint(path)
    return final[1] if final is not None else policy if (policy / "footforge.json").is_file() else path


def policy_digest(path: Path) -> str:
    """sha256 over the files of the folder whose parameters `path` gives (policy_folder): their names and
    bytes, footforge's output marker left out (a copy made by keep_run or cp -r has the same digest). An
    evaluation records it, so a result can be told to be of these very parameters and reused.

    Raises:
      InputError: the folder holds no files.
    """
    import hashlib

    from footforge.outputs import MARKER

    folder = policy_folder(path)
    files = sorted(p for p in folder.rglob("*") if p.is_file() and p.name != MARKER)
    if not files:
        raise InputError(f"{path}: no policy files to digest", fix="give a policy, run or checkpoint folder")
    h = hashlib.sha256()
    for f in files:
        h.update(str(f.relative_to(folder)).encode() + b"\0" + f.read_bytes())
    return h.hexdigest()


def folder_note(given: Path, used: Path) -> str | None:
    """What a command says when `policy_folder(given)` chose a checkpoint of a run: which, and why."""
    if Path(used).parent.name != "checkpoints" or Path(given).resolve() == Path(used).resolve():
        return None
    why = "its policy/ is damaged" if (Path(given) / "policy").exists() else "it has no policy/ yet"
    return f"{given}: {why}; using its newest intact checkpoint, step {int(Path(used).name):,} ({used})"


def _damaged(policy_dir: Path) -> str | None:
    if not (policy_dir / CHECKPOINT_MANIFEST).is_file():  # policies from before manifests have none
        return None
    return checkpoint_problem(policy_dir, read=False)


def _checkpoint_run(folder: Path) -> Path | None:
    """The run folder of a checkpoint folder `<run>/checkpoints/<step>/`, or None."""
    if folder.name.isdigit() and folder.parent.name == "checkpoints" and is_run_folder(folder.parent.parent):
        return folder.parent.parent
    return None


def steps_in_all(policy_dir: Path, global_step: int) -> int:
    """`global_step` of the policy in `policy_dir` (a run's policy/ or checkpoint folder) plus the steps of
    the runs its run went on from (config.json's "initialised_from", rl.config.steps_before): what the
    policy trained for in all. A folder outside a run (an exported copy) has only its own steps."""
    from footforge.rl.config import steps_before

    folder = Path(policy_dir).resolve()
    run = _checkpoint_run(folder) or (folder.parent if is_run_folder(folder.parent) else None)
    if run is None:
        return global_step
    try:
        origin = json.loads((run / "config.json").read_text()).get("initialised_from")
    except (OSError, ValueError):  # the run's own loaders report a damaged config.json
        return global_step
    return global_step + (steps_before(origin) if origin else 0)


def policy_meta(policy_dir: Path) -> dict:
    """A policy folder's footforge.json: "env" and "ppo" (the configurations as dicts),
    "global_step", and from training runs "wall_s" and "machine" (absent in older ones).

    Raises:
      InputError: the folder is not a footforge policy.
    """
    return _policy_meta(policy_folder(policy_dir).resolve())


def _policy_meta(policy_dir: Path) -> dict:
    meta_file = policy_dir / "footforge.json"
    run = _checkpoint_run(policy_dir) if not meta_file.is_file() else None
    if run is not None:  # a checkpoint folder: the configs of its run
        problem = checkpoint_problem(policy_dir, read=False, legacy=legacy_run(run))
        if problem:
            final = latest_intact_checkpoint(run)
            raise InputError(
                f"the checkpoint is damaged or incomplete: {problem}",
                file=str(policy_dir),
                fix=f"pass the run's newest intact checkpoint, {final[1]}"
                if final
                else "the run has no intact checkpoint: train it again",
            )
        saved = json.loads((run / "config.json").read_text())
        progress = run / "progress.json"
        recorded = json.loads(progress.read_text()) if progress.is_file() else {}
        meta = {"env": saved["env"], "ppo": saved["ppo"], "global_step": int(policy_dir.name)}
        if recorded.get("global_step") == meta["global_step"]:  # the run's time and machine up to this step
            meta |= {"wall_s": recorded.get("wall_s_total"), "machine": recorded.get("machine")}
        return meta
    if not policy_dir.exists():
        raise InputError(
            f"{policy_dir} does not exist",
            file=str(policy_dir),
            fix="pass a training run's folder, or its policy/ folder (a run writes it when it ends, or "
            "stops at its time budget)",
        )
    if not policy_dir.is_dir():
        raise InputError(
            f"{policy_dir} is a file, not a policy folder",
            file=str(policy_dir),
            fix="pass a training run's folder (footforge train), or its policy/ folder",
        )
    if not meta_file.is_file() and is_run_folder(policy_dir):
        raise InputError(
            f"{policy_dir} is a training run without a policy or an intact checkpoint yet",
            file=str(policy_dir),
            fix="train it until its first checkpoint: footforge train ... --out "
            f"{policy_dir} --resume (or the same command that started it)",
        )
    if not meta_file.is_file():
        raise InputError(
            f"{policy_dir} is not a footforge policy (no footforge.json)",
            file=str(policy_dir),
            fix="pass a training run's folder (footforge train), or its policy/ folder",
        )
    return json.loads(meta_file.read_text())


def _observation_size(saved):
    """The observation size as Brax's networks take it, from Brax's saved network config: an
    int, an array spec ({"shape": [n], ...}), or for dict observations a mapping of each key to one
    of these (made a shape tuple)."""
    if isinstance(saved, dict) and "shape" not in saved:
        return {
            key: tuple(v["shape"]) if isinstance(v, dict) else tuple(v) if isinstance(v, list) else (int(v),)
            for key, v in saved.items()
        }
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

    policy_dir = policy_folder(policy_dir).resolve()
    meta = _policy_meta(policy_dir)
    env_config, ppo = env_config_from_dict(meta["env"]), from_dict(PPOConfig, meta["ppo"])
    problem = _damaged(policy_dir) if (policy_dir / "footforge.json").is_file() else None
    if problem:
        run = policy_dir.parent
        fix = "train again"
        if policy_dir.name == "policy" and is_run_folder(run):
            final = latest_intact_checkpoint(run)
            task = meta["env"].get("task", "flat")
            fix = (
                f"pass the run folder {run} (or its checkpoint {final[1]}) instead, or rewrite the policy with "
                f"footforge train {task} --out {run} --resume"
                if final
                else fix
            )
        raise InputError(f"the policy is damaged: {problem}", file=str(policy_dir), fix=fix)
    config_file = policy_dir / "ppo_network_config.json"
    try:
        cfg = json.loads(config_file.read_text())
        params = brax_checkpoint.load(str(policy_dir))
    except (OSError, ValueError, KeyError) as e:  # orbax's errors for a missing or damaged checkpoint
        reason = (str(e).splitlines() or [type(e).__name__])[0]
        raise InputError(
            f"the policy's checkpoint cannot be read: {reason}",
            file=str(policy_dir),
            fix="pass a complete policy/ folder written by training",
        ) from None
    return SavedPolicy(tuple(params), env_config, ppo, cfg, int(meta.get("global_step", 0)))


def load_policy(policy_dir: Path, *, deterministic: bool = True):
    """(policy function obs, key -> (action, extras), EnvConfig, PPOConfig) of a saved policy."""
    import jax
    from brax.training.acme import running_statistics
    from brax.training.agents.ppo import networks as ppo_networks

    saved = load_policy_parameters(policy_dir)
    env_config, ppo, cfg = saved.env, saved.ppo, saved.network_config
    networks = network_factory(ppo, env_config.privileged_critic)(
        observation_size=_observation_size(cfg["observation_size"]),
        action_size=cfg["action_size"],
        preprocess_observations_fn=running_statistics.normalize if ppo.normalize_observations else (lambda x, y: x),
    )
    make = ppo_networks.make_inference_fn(networks)
    return jax.jit(make(saved.params, deterministic=deterministic)), env_config, ppo
