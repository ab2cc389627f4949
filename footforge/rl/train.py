"""Brax PPO training of the locomotion environments, with checkpoints that survive a kill.

Also written: `<run>/metrics.jsonl` (every evaluation's metrics: the reward curve) and
`<run>/tensorboard/`. Brax's own checkpoints hold the policy, value and normaliser parameters but restart the step
count on resume; footforge keeps its own: after every epoch the parameters go to
`<run>/checkpoints/<global step>/` (Brax's format) and `<run>/progress.json` records the global
step, the training wall time over every call (`wall_s_total`, to the last checkpoint) and the
machine (`machine()`); the policy's footforge.json repeats the last two for its card. `--resume`
restores the latest intact checkpoint and trains the remaining steps with a new seed
(the same seed would replay the same experience).

Optimiser state: Brax 0.14.2's PPO cannot restore it. Its `train` builds the Adam moments (and
the adaptive-KL learning rate, which lives in the same optax state) with `optimizer.init` inside
the function, passes only (normaliser, policy, value) parameters to `policy_params_fn` and
returns only those, and its restore paths (`restore_params`, `restore_checkpoint_path`) set
parameters alone. Keeping the optimiser state would mean re-implementing Brax's PPO loop, so a
resumed run continues from the same policy, value and normaliser, with Adam's moments and the
learning rate restarting from `PPOConfig.learning_rate`.

Checkpoint integrity: every checkpoint gets `footforge_checkpoint.json` (CHECKPOINT_MANIFEST),
written whole after Brax's and orbax's files are complete, with each file's size and SHA-256.
`--resume` verifies checkpoints from the newest down and continues from the newest intact one;
the ones it skips (no manifest, a file truncated, missing or changed, or unreadable by orbax) are
named on stderr and renamed to `<step>.corrupt` so the resumed run can write that step again.
Checkpoints of runs from before the manifest are accepted when orbax reads them.

The run folder: footforge marks it as a training run (footforge.outputs.MARKER). Training into a
folder that already holds a run is refused unless `resume` (continue it) or `force` (start over:
only the files and folders footforge writes in a run folder, RUN_ENTRIES, are removed; anything
else in the folder stays). These checks run before any compilation.

`max_wall_s` bounds a call's wall-clock time for machines whose jobs have a time limit: after each
checkpoint and its evaluation, training stops when the next epoch would end past the budget; the
policy folder then holds the last checkpoint and `progress.json` says `"stopped": "wall-time
budget"`; `--resume` continues. The next epoch is estimated by the last one, except after the
first, whose time holds the compilation (minutes for the adaptive feet): that one is estimated
from the throughput of the training-episode logs (Brax's episode/sps, the first log left out for
the same reason) plus the evaluation's time (next_epoch_seconds).
"""

from __future__ import annotations

import dataclasses
import functools
import hashlib
import json
import math
import os
import shutil
import sys
import time
from dataclasses import dataclass, fields, is_dataclass, replace
from pathlib import Path
from typing import Callable

from footforge.atomic import atomic_directory, atomic_file
from footforge.envs.config import EnvConfig
from footforge.errors import InputError
from footforge.outputs import MARKER, TRAINING_RUN, check_output_folder, marker_kind, write_marker


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
    """legged_gym's (the baseline's 0.001 let the policy's std fall only from 1.0 to 0.94 in 3 M
    CPU steps). These three and policy_output_init_scale 0.01 were chosen by the H100 ablations of
    2026-11-26 (benchmarks/log/2026-11-21_to_26.md): with position actions under the full commands the forward
    error of the training episodes fell to 0.14 m/s in 4 M steps against 0.34 with the baseline's."""
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



def steps_per_iteration(ppo: PPOConfig) -> int:
    """Environment steps of one PPO iteration: batch_size x num_minibatches trajectories of
    unroll_length steps (Brax's env_step_per_training_step)."""
    return ppo.batch_size * ppo.num_minibatches * ppo.unroll_length


def training_epochs(ppo: PPOConfig, done: int = 0) -> int:
    """Epochs (each ending in a checkpoint) of a run that has done `done` steps: checkpoint_every_steps each."""
    return max(1, math.ceil((ppo.num_timesteps - done) / ppo.checkpoint_every_steps))


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
        overrides = {"policy_hidden_layers": (512, 256, 128), "value_hidden_layers": (512, 256, 128),
                     "num_timesteps": 200_000_000} | overrides
    return PPOConfig(**overrides)


def to_dict(config) -> dict:
    """A (nested) frozen dataclass as config.json holds it: every field but those declared in code
    (metadata "saved": False, e.g. an observation group's reading function)."""
    return {f.name: to_dict(v) if is_dataclass(v := getattr(config, f.name)) else
            (list(v) if isinstance(v, tuple) else v)
            for f in fields(config) if f.metadata.get("saved", True)}


def from_dict(cls, data: dict, default=None):
    """A (nested) frozen dataclass from its to_dict() form; tuples restored from lists. Fields
    not in `data` keep their defaults (`default`, an instance, where the class has none)."""
    kwargs = {}
    types = {f.name: f for f in fields(cls)}
    for name, value in data.items():
        if name not in types:
            raise InputError(f"unknown configuration key '{name}' for {cls.__name__}",
                             fix="use the footforge version that wrote the configuration")
        field_default = getattr(default, name) if default is not None else (
            types[name].default_factory() if callable(types[name].default_factory) else types[name].default)
        if is_dataclass(field_default):
            value = from_dict(type(field_default), value, field_default)
        elif isinstance(value, list):
            value = tuple(value)
        kwargs[name] = value
    return replace(default, **kwargs) if default is not None else cls(**kwargs)


def env_config_from_dict(data: dict) -> EnvConfig:
    """An EnvConfig from a run's config.json "env" (older forms upgraded: envs.config.upgrade_saved)."""
    from footforge.envs.config import upgrade_saved

    return from_dict(EnvConfig, upgrade_saved(data))


def network_factory(ppo: PPOConfig, privileged: bool = False):
    """Brax's PPO networks; with `privileged` (EnvConfig.privileged_critic) the value network
    reads the observation dict's "privileged_state" and the policy its "state"."""
    from brax.training.agents.ppo import networks as ppo_networks
    from flax import linen

    keys = {"policy_obs_key": "state", "value_obs_key": "privileged_state"} if privileged else {}

    # Brax records the factory's keyword defaults (inspect.signature, which follows __wrapped__)
    # in ppo_network_config.json: the wrapper keeps make_ppo_networks' signature.
    @functools.wraps(ppo_networks.make_ppo_networks)
    def float32_networks(*args, **kwargs):
        # Under JAX's x64 mode (EnvConfig.float64_physics) Brax's log-std parameter is made in
        # float64 (jnp.full of a Python float), and optax's inject_hyperparams then makes Adam's
        # decay rates float64 too, which turns the float32 parameters' moments float64 and breaks
        # PPO's minibatch scan. Every parameter is made float32 (a no-op without x64).
        networks = ppo_networks.make_ppo_networks(*args, **kwargs)
        return dataclasses.replace(networks, policy_network=_float32_init(networks.policy_network,
                                                                           ppo.policy_output_init_scale),
                                   value_network=_float32_init(networks.value_network))

    return functools.partial(
        float32_networks, policy_hidden_layer_sizes=ppo.policy_hidden_layers,
        value_hidden_layer_sizes=ppo.value_hidden_layers, activation=linen.elu,
        distribution_type="normal", noise_std_type="log", init_noise_std=ppo.init_noise_std,
        **({"mean_clip_scale": ppo.policy_mean_clip} if ppo.policy_mean_clip is not None else {}), **keys)


def _float32_init(network, output_scale: float = 1.0):
    """`network` (Brax's FeedForwardNetwork) whose init returns float32 parameters, the policy's
    output (mean) layer, "Dense_0", scaled by `output_scale` (PPOConfig.policy_output_init_scale)."""
    import jax
    import jax.numpy as jp

    def init(*args, **kwargs):
        params = network.init(*args, **kwargs)
        if output_scale != 1.0:
            inner = dict(params["params"])
            inner["Dense_0"] = jax.tree_util.tree_map(lambda x: x * output_scale, inner["Dense_0"])
            params = dict(params) | {"params": inner}
        return jax.tree_util.tree_map(lambda x: x.astype(jp.float32) if jp.issubdtype(x.dtype, jp.floating) else x,
                                      params)
    return dataclasses.replace(network, init=init)


CHECKPOINT_MANIFEST = "footforge_checkpoint.json"
"""In every checkpoint folder (and the policy folder copied from one): {"files": {relative path:
{"bytes", "sha256"}}}, written whole once the checkpoint's files are complete."""

RUN_ENTRIES = ("config.json", "progress.json", "metrics.jsonl", "tensorboard", "checkpoints", "policy",
               "terrain.png", MARKER)
"""What footforge writes in a run folder: all that `force` removes (with these names' temporaries)."""


def checkpoints(run_dir: Path) -> list[tuple[int, Path]]:
    """(global step, folder) of the run's checkpoints, oldest first (intact or not)."""
    folder = Path(run_dir) / "checkpoints"
    found = sorted((int(p.name), p) for p in folder.iterdir() if p.name.isdigit()) if folder.is_dir() else []
    return found


def latest_checkpoint(run_dir: Path) -> tuple[int, Path] | None:
    """The newest checkpoint, intact or not (latest_intact_checkpoint checks)."""
    found = checkpoints(run_dir)
    return found[-1] if found else None


def _sha256(path: Path) -> str:
    digest = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def write_checkpoint_manifest(folder: Path) -> None:
    """Records every file under the checkpoint folder `folder` (size and SHA-256) in its manifest."""
    folder = Path(folder)
    files = {str(p.relative_to(folder)): {"bytes": p.stat().st_size, "sha256": _sha256(p)}
             for p in sorted(folder.rglob("*")) if p.is_file() and p.name != CHECKPOINT_MANIFEST}
    _write_json(folder / CHECKPOINT_MANIFEST, {"files": files})


def checkpoint_problem(folder: Path, *, read: bool = True) -> str | None:
    """Why the checkpoint folder `folder` cannot be trusted, or None if it is intact.

    With a manifest, every file it lists must be there with its size and SHA-256. Without one (a
    write that did not finish, or a run from before manifests), Brax's network config must be
    there and, as with `read`, orbax must read the parameters.
    """
    folder = Path(folder)
    manifest = folder / CHECKPOINT_MANIFEST
    if manifest.is_file():
        try:
            files = json.loads(manifest.read_text())["files"]
        except (OSError, ValueError, KeyError, TypeError):
            return f"its {CHECKPOINT_MANIFEST} is unreadable"
        for name, expected in files.items():
            path = folder / name
            if not path.is_file():
                return f"{name} is missing"
            if path.stat().st_size != expected["bytes"]:
                return f"{name} has {path.stat().st_size} bytes, {expected['bytes']} were written"
            if _sha256(path) != expected["sha256"]:
                return f"{name} changed since it was written (SHA-256 differs)"
    elif not (folder / "ppo_network_config.json").is_file():
        return f"no {CHECKPOINT_MANIFEST} and no ppo_network_config.json: its write did not finish"
    else:
        read = True
    if read:
        try:
            _load_params(folder)
        except Exception as e:  # orbax raises many types on damaged files; the reason is reported
            first = (str(e).strip().splitlines() or [""])[0]
            return f"orbax cannot read it ({type(e).__name__}: {first[:160]})"
    return None


def _load_params(folder: Path):
    from brax.training.agents.ppo import checkpoint as brax_checkpoint

    return brax_checkpoint.load(os.path.abspath(folder))  # orbax refuses a relative path


def latest_intact_checkpoint(run_dir: Path, *, read: bool = False) -> tuple[int, Path] | None:
    """The newest checkpoint that passes checkpoint_problem."""
    for step, path in reversed(checkpoints(run_dir)):
        if checkpoint_problem(path, read=read) is None:
            return step, path
    return None


def _resume_point(run_dir: Path, notice: Callable[[str], None], set_aside: bool):
    """(global step, parameters) of the newest intact checkpoint; the newer ones are reported and,
    with `set_aside`, renamed to <step>.corrupt (the resumed run writes those steps again).

    Raises:
      InputError: no checkpoint, or none intact.
    """
    found = checkpoints(run_dir)
    if not found:
        raise InputError(f"nothing to resume: no checkpoints in {run_dir / 'checkpoints'}", file=str(run_dir),
                         fix="start without --resume (with --force to start this run over), or give another run")
    skipped = []
    for step, path in reversed(found):
        problem = checkpoint_problem(path, read=False)
        params = None
        if problem is None:
            try:
                params = _load_params(path)
            except Exception as e:  # as in checkpoint_problem
                problem = f"orbax cannot read it ({type(e).__name__})"
        if problem is None:
            for _, bad in skipped:
                if set_aside:
                    aside = bad.with_name(f"{bad.name}.corrupt")
                    n = 1
                    while aside.exists():
                        aside, n = bad.with_name(f"{bad.name}.corrupt{n}"), n + 1
                    os.replace(bad, aside)
            return step, params
        notice(f"skipping checkpoint {path.name} of {run_dir}: {problem}")
        skipped.append((step, path))
    raise InputError(f"no intact checkpoint to resume in {run_dir / 'checkpoints'} ({len(found)} checked, "
                     f"all damaged; the reasons are above)", file=str(run_dir),
                     fix="start the run over with --force (it removes the run's files), or give another --out")


def is_run_folder(folder: Path) -> bool:
    """Whether `folder` holds a footforge training run: its marker says so, or (a run from before
    the marker) its config.json holds an environment and a PPO config."""
    folder = Path(folder)
    if marker_kind(folder) == TRAINING_RUN:
        return True
    try:
        saved = json.loads((folder / "config.json").read_text())
        return isinstance(saved, dict) and {"env", "ppo"} <= set(saved)
    except (OSError, ValueError):
        return False


def _remove_run_files(run_dir: Path) -> list[str]:
    """Removes RUN_ENTRIES and their temporaries from run_dir; returns the names removed."""
    removed = []
    stems = tuple(f".{name.split('.')[0]}." for name in RUN_ENTRIES if not name.startswith("."))
    for entry in sorted(run_dir.iterdir()):  # temporaries: .config.json.tmp, .policy.tmp-PID-x, .terrain.tmp-PID.png
        temporary = entry.name.startswith(stems) and (".tmp" in entry.name or entry.name.startswith(".policy.old-"))
        if entry.name in RUN_ENTRIES or temporary:
            if entry.is_dir() and not entry.is_symlink():
                shutil.rmtree(entry)
            else:
                entry.unlink()
            removed.append(entry.name)
    return removed


def prepare_run_dir(run_dir: Path, *, resume: bool = False, force: bool = False, write: bool = True,
                    notice: Callable[[str], None] | None = None) -> Path:
    """Checks (and for a new run makes and marks) the run folder; returns its absolute path.

    Fresh runs go into a new or empty folder; a folder holding a run needs `resume` or `force`
    (which removes RUN_ENTRIES only); a folder with other files needs `force`, and then must not
    hold any of RUN_ENTRIES. `write=False` checks without changing anything (JAX processes other
    than the first). Cheap: call it before any compilation.

    Raises:
      InputError: the folder cannot be used as asked; exit 2.
    """
    given = run_dir
    run_dir = check_output_folder(run_dir, force=True)  # the checks that always apply (a file, the cwd, ...)
    if resume and force:
        raise InputError("--resume and --force exclude each other: --resume continues the run, --force starts it over",
                         fix="pass one of them")
    if resume:
        if not (run_dir / "config.json").is_file():
            raise InputError(f"--out {given}: nothing to resume (no config.json: not a training run)",
                             file=str(run_dir), fix="start without --resume, or give the folder of an earlier run")
        return run_dir
    if run_dir.is_dir() and any(run_dir.iterdir()):
        if is_run_folder(run_dir):
            last = latest_checkpoint(run_dir)
            # A run that never reached a checkpoint (stopped while compiling or in its first epoch)
            # has nothing to continue: the same command starts it again.
            unfinished = last is None and not (run_dir / "policy").exists()
            if not force and not unfinished:
                raise InputError(f"--out {given}: holds a training run (its last checkpoint at step {last[0]:,})"
                                 if last else f"--out {given}: holds a finished training run",
                                 fix="pass --resume to continue it, --force to start it over (removes only the "
                                     "files footforge wrote there), or give another --out")
            if write:
                removed = _remove_run_files(run_dir)
                if notice and removed:
                    why = "--force" if force else "the earlier run reached no checkpoint, so it starts again"
                    notice(f"{why}: removed its {', '.join(removed)} from {run_dir}")
        else:
            if not force:
                raise InputError(f"--out {given}: the folder holds files footforge did not write (no {MARKER})",
                                 fix="give another --out, or pass --force to train into it beside those files "
                                     "(they are kept)")
            clash = [name for name in RUN_ENTRIES if (run_dir / name).exists() or (run_dir / name).is_symlink()]
            if clash:
                raise InputError(f"--out {given}: holds {', '.join(clash)}, which footforge did not write and a run "
                                 f"would overwrite", fix="move them away or give another --out")
    if write:
        run_dir.mkdir(parents=True, exist_ok=True)
        write_marker(run_dir, kind=TRAINING_RUN)
    return run_dir


def load_run_config(run_dir: Path) -> tuple[EnvConfig, "PPOConfig"]:
    """The environment and PPO configs a run was started with (its config.json).

    Raises:
      InputError: no readable config.json in run_dir.
    """
    path = Path(run_dir) / "config.json"
    if not Path(run_dir).is_dir():
        raise InputError(f"{run_dir} does not exist", file=str(run_dir), fix="give the folder of an earlier run")
    try:
        saved = json.loads(path.read_text())
        return env_config_from_dict(saved["env"]), from_dict(PPOConfig, saved["ppo"])
    except FileNotFoundError:
        raise InputError("not a training run (no config.json)", file=str(run_dir),
                         fix="give the folder of an earlier run, or start without --resume") from None
    except (OSError, ValueError, KeyError, TypeError) as e:
        raise InputError(f"unreadable ({type(e).__name__}: {e})", file=str(path),
                         fix="start the run over with --force, or give another run") from None


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


class _OutOfTime(Exception):
    """Raised from Brax's progress callback to stop training at a checkpoint (max_wall_s)."""


def _check_run_settings(ppo: PPOConfig, max_wall_s: float | None) -> None:
    """Raises InputError for settings this machine cannot run: bad hyperparameters, a time budget
    that is not positive or spans several processes, robots that do not split over the devices."""
    import jax

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


def _initialisation(source: Path, env_config: EnvConfig, ppo: PPOConfig, notice):
    """(step, parameters) of the newest intact checkpoint of run `source`, refused where its
    networks cannot be this run's: other observations (policy type, PD targets, height scan, a
    haptic policy on other feet), another critic, other hidden layers or observation normalising."""
    from footforge.envs import observations

    source_env, source_ppo = load_run_config(source)
    problems = []
    if (source_env.haptic or env_config.haptic) and source_env.feet != env_config.feet:
        problems.append(f"a haptic policy reads its feet's joints: feet {source_env.feet} there, {env_config.feet} here")
    else:
        widths = observations.size(source_env, 16), observations.size(env_config, 16)
        if widths[0] != widths[1]:
            problems.append(f"observation width {widths[0]} there, {widths[1]} here (policy {source_env.policy} / "
                            f"{env_config.policy})")
    for name in ("policy_hidden_layers", "value_hidden_layers", "normalize_observations"):
        if getattr(source_ppo, name) != getattr(ppo, name):
            problems.append(f"{name} {getattr(source_ppo, name)} there, {getattr(ppo, name)} here")
    if source_env.privileged_critic != env_config.privileged_critic:
        problems.append(f"privileged_critic {source_env.privileged_critic} there, {env_config.privileged_critic} here")
    if problems:
        raise InputError(f"--init-from {source}: its networks do not fit this run: {'; '.join(problems)}",
                         file=str(source / "config.json"), fix="start from a run with the same networks, or without "
                                                                "--init-from")
    step, params = _resume_point(source, notice, set_aside=False)
    notice(f"starting from the parameters of {source} at step {step:,}")
    return step, params


def _resume_state(run_dir: Path, env_config: EnvConfig, ppo: PPOConfig, notice, primary: bool):
    """(steps done, the checkpoint to restore, the number of this resume, training seconds so far)
    of the run in run_dir, refused where it was started with other settings."""
    saved_env, saved_ppo = load_run_config(run_dir)
    saved = json.loads(json.dumps({"env": to_dict(saved_env), "ppo": to_dict(saved_ppo) | {"num_timesteps": 0}}))
    now = json.loads(json.dumps({"env": to_dict(env_config), "ppo": to_dict(ppo) | {"num_timesteps": 0}}))
    differences = config_differences(saved, now)  # tuples as lists: compared as JSON
    if differences:
        raise InputError(f"the run was started with other settings: {'; '.join(differences)}",
                         file=str(run_dir / "config.json"),
                         fix="resume with the run's own settings (the pipelines read them from config.json), "
                             "or start a new run with another --out")
    offset, restore = _resume_point(run_dir, notice, set_aside=primary)
    state_file = run_dir / "progress.json"
    previous = json.loads(state_file.read_text()) if state_file.exists() else {}
    # Training time of the earlier calls, up to their last checkpoint (a killed call's time after
    # it is lost with its work).
    return offset, restore, previous.get("resumes", 0) + 1, previous.get("wall_s_total", previous.get("wall_s", 0.0))


def _write_policy(run_dir: Path, env_config: EnvConfig, ppo: PPOConfig, this_machine: dict) -> None:
    """run_dir/policy: the newest intact checkpoint (the final parameters) and the configs."""
    final = latest_intact_checkpoint(run_dir)
    if final is None:
        return
    state_file = run_dir / "progress.json"
    with atomic_directory(run_dir / "policy") as tmp:
        shutil.copytree(final[1], tmp, dirs_exist_ok=True)
        recorded = json.loads(state_file.read_text()) if state_file.exists() else {}
        _write_json(tmp / "footforge.json", {"env": to_dict(env_config), "ppo": to_dict(ppo),
                                             "global_step": final[0], "wall_s": recorded.get("wall_s_total"),
                                             "machine": this_machine})


def train(env_config: EnvConfig, ppo: PPOConfig, run_dir: Path, *, resume: bool = False, force: bool = False,
          progress: Callable[[int, int, dict, bool], None] | None = None, max_wall_s: float | None = None,
          notice: Callable[[str], None] | None = None, evaluate: bool = True, init_from: Path | None = None) -> dict:
    """Trains a policy; writes checkpoints, TensorBoard logs and the final policy into run_dir.

    Returns the final metrics. `progress(global_step, total_steps, metrics, evaluation)` is called
    after each evaluation (`evaluation` True) and each log of the training episodes' metrics, with
    the latest value of every metric so far. `resume` continues the run in run_dir from its newest
    intact checkpoint, `force` starts it over (prepare_run_dir); without either, a run_dir that
    holds a run is refused. `notice(text)` reports what was skipped or removed (default: stderr).
    `max_wall_s`: stop at the last checkpoint that leaves time for no further epoch (see the
    module's docstring); the returned metrics then hold "stopped_for_time": 1.0.
    `evaluate`: Brax's deterministic evaluation (num_eval_envs robots, one whole episode) at the
    start and at each checkpoint. Its policy steps run one after another, so on a GPU one
    evaluation takes as long as about 20 PPO iterations of the paper's settings (measured on an
    H100, benchmarks/log/2026-11-21_to_26.md); time-limited jobs may turn it off. The learning curve then comes
    from the training episodes (episode/...: the stochastic policy), and footforge evaluate
    evaluates the policy afterwards. A run-time choice, not a setting of the run: it changes
    nothing that is learned, and a resumed run may choose again.
    `init_from`: a new run starts from the newest intact checkpoint of that earlier run (its
    normaliser, policy and value parameters, the policy's exploration deviation included), with
    settings of its own: fine-tuning with other PPO settings, rewards or feet. Its step count
    starts at 0; config.json records the source as "initialised_from". Brax starts Adam afresh.

    Raises:
      InputError: bad hyperparameters; a run folder that needs --resume or --force; --resume
        without an intact checkpoint or with other configs; `init_from` with `resume`, or a source
        whose networks do not fit this run.
    """
    from brax.training.agents.ppo import train as ppo_train
    from tensorboardX import SummaryWriter

    from footforge.envs import enable_float64_physics, from_config
    from footforge.envs.randomization import randomizer
    from footforge.envs.wrappers import wrap_for_training

    import jax

    from footforge.rl import jax_compat

    if notice is None:
        def notice(text: str) -> None:
            print(text, file=sys.stderr, flush=True)
    jax_compat.install()  # Brax 0.14.2's PPO on JAX >= 0.10
    enable_float64_physics(env_config)  # EnvConfig.float64_physics: before the environment's first array
    _check_run_settings(ppo, max_wall_s)
    # On several machines only process 0 writes (Brax saves and evaluates there alone).
    primary = jax.process_index() == 0
    # Only process 0 checks the folder: the others may look before or after it wrote its marker.
    offset, restore, resumes, wall_s_before = 0, None, 0, 0.0
    origin = {}
    if init_from is not None:  # before the run folder is touched
        if resume:
            raise InputError("--init-from starts a new run from another run's parameters; --resume continues "
                             "this one", fix="give one of them")
        step, restore = _initialisation(Path(init_from), env_config, ppo, notice)
        origin = {"initialised_from": {"run": os.path.abspath(init_from), "step": step}}
    run_dir = prepare_run_dir(run_dir, resume=resume, force=force, notice=notice) if primary else \
        Path(os.path.abspath(run_dir))
    state_file = run_dir / "progress.json"
    if resume:
        offset, restore, resumes, wall_s_before = _resume_state(run_dir, env_config, ppo, notice, primary)
        origin = {k: v for k, v in json.loads((run_dir / "config.json").read_text()).items()
                  if k == "initialised_from"}
    if primary:
        _write_json(run_dir / "config.json", {"env": to_dict(env_config), "ppo": to_dict(ppo), "evaluations": evaluate}
                    | origin)
    remaining = ppo.num_timesteps - offset
    if remaining <= 0:
        return json.loads(state_file.read_text()).get("metrics", {}) if state_file.exists() else {}

    env = from_config(env_config)  # Brax evaluates on the same environment
    if primary and env_config.task == "rough":  # the terrain this run walks
        from footforge.envs.terrain import preview

        with atomic_file(run_dir / "terrain.png") as tmp:
            preview(env.terrain, tmp)
    writer = SummaryWriter(str(run_dir / "tensorboard")) if primary else None
    epochs = training_epochs(ppo, offset)
    total = planned_steps(ppo, offset)  # what Brax will run: whole iterations
    last: dict = {}
    t0 = time.time()
    this_machine = machine()
    clock = {"last_eval": t0, "stopped": False, "epochs": 0, "sps_logs": 0, "sps": None}

    def save(step: int, make_policy, params) -> None:
        global_step = offset + step
        if step == 0:
            return
        save_checkpoint(run_dir, global_step, params, env.observation_size, env.action_size, ppo,
                        env_config.privileged_critic)
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
        # The end of an epoch (its checkpoint written, its evaluation run if any) is the call that
        # carries Brax's training/sps; the initial evaluation and the training-episode logs do not.
        epoch_end = "training/sps" in metrics
        if "episode/sps" in metrics:
            clock["sps_logs"] += 1
            if clock["sps_logs"] > 1:  # the first log's interval holds the compilation
                clock["sps"] = float(metrics["episode/sps"])
        if progress:
            progress(global_step, total, last, epoch_end or "eval/walltime" in metrics)
        # Stop here if one more epoch, timed as the last one (training, checkpoint, evaluation),
        # would overrun the budget.
        if max_wall_s is not None and step > 0 and epoch_end and offset + step < total:
            now_t = time.time()
            epoch_s = next_epoch_seconds(now_t - clock["last_eval"], clock["epochs"] == 0, clock["sps"],
                                         ppo.checkpoint_every_steps, float(metrics.get("eval/epoch_eval_time", 0.0)))
            clock["last_eval"] = now_t
            clock["epochs"] += 1
            if now_t + epoch_s > t0 + max_wall_s:
                raise _OutOfTime()

    try:
        _run_ppo(ppo_train, env, env_config, ppo, remaining, epochs, restore, resumes, log, save,
                 wrap_for_training, randomizer, evaluate)
    except _OutOfTime:
        clock["stopped"] = True
    if writer:
        writer.close()
    if primary:
        _write_policy(run_dir, env_config, ppo, this_machine)
    if clock["stopped"]:
        last["stopped_for_time"] = 1.0
        if primary and state_file.exists():
            _write_json(state_file, json.loads(state_file.read_text()) | {"metrics": last, "stopped": "wall-time budget"})
    return last


def next_epoch_seconds(last_epoch_s: float, first: bool, steps_per_s: float | None, steps_per_epoch: int,
                       evaluation_s: float = 0.0) -> float:
    """The wall time the next epoch will take (for the max_wall_s stop): the last epoch's, except
    after the first epoch, whose time holds the compilation; that one is estimated as its steps at
    the measured training throughput plus an evaluation, when a throughput was measured, and never
    above the observed time."""
    if first and steps_per_s:
        return min(last_epoch_s, steps_per_epoch / steps_per_s + evaluation_s)
    return last_epoch_s


def save_checkpoint(run_dir: Path, global_step: int, params, observation_size, action_size: int, ppo: PPOConfig,
                    privileged: bool = False) -> Path:
    """Writes <run_dir>/checkpoints/<global_step>/ as training does: Brax's checkpoint of
    (normaliser, policy, value) parameters, then its manifest (CHECKPOINT_MANIFEST)."""
    from brax.training.agents.ppo import checkpoint as brax_checkpoint

    brax_checkpoint.save(str(Path(run_dir) / "checkpoints"), global_step, params,
                         brax_checkpoint.network_config(observation_size, action_size, ppo.normalize_observations,
                                                        network_factory(ppo, privileged)))
    folder = Path(run_dir) / "checkpoints" / f"{global_step:012d}"
    write_checkpoint_manifest(folder)
    return folder


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
             resumes: int, log, save, wrap_for_training, randomizer, evaluate: bool = True) -> None:
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
        num_evals=epochs + 1, run_evals=evaluate,
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
        write_checkpoint_manifest(tmp)
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
