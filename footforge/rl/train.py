"""Brax PPO training of the locomotion environments: the loop, resumable and time-limited.

A run lives in a run folder (footforge.rl.run_folder): config.json, checkpoints after every epoch
(footforge.rl.checkpoints), `metrics.jsonl` (every evaluation's and training-episode log's
metrics: the learning curve), `tensorboard/`, `progress.json` (the global step, the training wall
time over every call to the last checkpoint, `wall_s_total`, and the machine, machine()) and at
the end the policy folder (footforge.rl.policy_files). `resume` restores the latest intact
checkpoint and trains the remaining steps with a new seed (the same seed would replay the same
experience); a resume of a run already at its total writes a missing, damaged or stale policy/
from that checkpoint (finish_run), so a run killed after its last checkpoint is never stranded.

One curve per run, whatever the kills: a resume continues `metrics.jsonl` from the step it
restored (continue_curve: the rows logged after that checkpoint by the call that was killed, or of
a checkpoint found damaged, move to `metrics.set_aside.jsonl`), TensorBoard hides the same steps
(tensorboardX's purge_step), and each row's `wall_s` counts the training time of every call, so
both axes only grow.

Optimiser state: Brax 0.14.2's PPO cannot restore it. Its `train` builds the Adam moments (and
the adaptive-KL learning rate, which lives in the same optax state) with `optimizer.init` inside
the function, passes only (normaliser, policy, value) parameters to `policy_params_fn` and
returns only those, and its restore paths (`restore_params`, `restore_checkpoint_path`) set
parameters alone. Keeping the optimiser state would mean re-implementing Brax's PPO loop, so a
resumed run continues from the same policy, value and normaliser, with Adam's moments restarting.
The adaptive-KL learning rate goes on from the one the curve last logged before the checkpoint
(logged_learning_rate; config.json keeps the run's own `learning_rate`): restarting it at
`PPOConfig.learning_rate` (1e-3, where the schedule had brought it to about 5e-5) made the first
updates after each resume of rough AOF P overshoot (KL 0.19-0.45 against the 0.01 sought) and lose
about a level of the curriculum for a million steps.

`max_wall_s` bounds a call's wall-clock time for machines whose jobs have a time limit
(WallTimeBudget): after each checkpoint and its evaluation, training stops when the next epoch
would end past the budget; the policy folder then holds the last checkpoint and `progress.json`
says `"stopped": "wall-time budget"`; `resume` continues.

The names of the modules this one was split into are re-exported here, where callers have long
found them (PPOConfig, load_policy, prepare_run_dir, ...).
"""

from __future__ import annotations

import gzip
import json
import os
import re
import sys
import time
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path
from typing import TypeVar

from footforge.atomic import atomic_file, write_json
from footforge.envs import terrain
from footforge.envs.config import EnvConfig
from footforge.envs.terrain import KINDS
from footforge.errors import InputError
from footforge.rl.checkpoints import (  # noqa: F401 (re-exported)
    CHECKPOINT_MANIFEST,
    checkpoint_problem,
    checkpoints,
    latest_checkpoint,
    latest_intact_checkpoint,
    resume_point,
    save_checkpoint,
    write_checkpoint_manifest,
)
from footforge.rl.config import (  # noqa: F401 (re-exported)
    PPOConfig,
    config_differences,
    default_ppo,
    env_config_from_dict,
    from_dict,
    planned_steps,
    steps_before,
    steps_per_iteration,
    to_dict,
    training_epochs,
)
from footforge.rl.networks import network_factory
from footforge.rl.policy_files import (  # noqa: F401 (re-exported)
    SavedPolicy,
    initial_policy,
    load_policy,
    load_policy_config,
    load_policy_parameters,
    policy_folder,
    policy_meta,
    policy_problem,
    write_policy,
)
from footforge.rl.run_folder import (  # noqa: F401 (re-exported)
    CURVE,
    CURVE_KEPT,
    CURVE_SET_ASIDE,
    RUN_ENTRIES,
    is_run_folder,
    load_run_config,
    prepare_run_dir,
)


def continue_curve(run_dir: Path, step: int, resume: int) -> bool:
    """Before resume number `resume` continues the run from its checkpoint at `step`: the curve's rows
    past `step` move to CURVE_SET_ASIDE (appended), the others stay in order. Returns whether a kept
    row at `step` holds an evaluation: then the resumed call's first evaluation, of the same
    parameters, is not written again. A curve kept gzipped (CURVE_KEPT, a folder from git) is
    unpacked into CURVE, which the run then appends to; the gzipped copy goes once CURVE is written
    (prepare_run_dir refused a folder holding both)."""
    path, packed = Path(run_dir) / CURVE, Path(run_dir) / CURVE_KEPT
    unpacking = not path.is_file() and packed.is_file()
    if path.is_file():
        text = path.read_text()
    elif unpacking:
        try:
            with gzip.open(packed, "rt") as f:
                text = f.read()
        except (OSError, EOFError, UnicodeDecodeError) as e:  # gzip.BadGzipFile is an OSError
            raise InputError(
                f"{packed}: the run's gzipped learning curve cannot be read ({e})",
                file=str(packed),
                fix=f"restore it (git checkout -- {packed.name} in its folder), or remove it to continue "
                "without the earlier curve",
            ) from e
    else:
        return False
    kept, aside, evaluated = [], [], False
    for line in text.splitlines():
        try:
            row = json.loads(line)
            row_step = int(row["global_step"])
        except (ValueError, KeyError, TypeError):  # a line cut short by a kill
            continue
        if row_step > step:
            aside.append(json.dumps(row | {"set_aside_by_resume": resume}))
        else:
            kept.append(line)
            evaluated |= row_step == step and any(k.startswith("eval/") for k in row)
    if aside:
        with open(Path(run_dir) / CURVE_SET_ASIDE, "a") as f:
            f.write("\n".join(aside) + "\n")
    with atomic_file(path) as tmp:
        Path(tmp).write_text("".join(line + "\n" for line in kept))
    if unpacking:
        packed.unlink()
    return evaluated


T = TypeVar("T")

LEVEL_SHARE = "episode/terrain/at_level_{}_per_step"
"""The curve's key of the share of ended episodes on a level (the rough environment's metrics)."""
KIND_LEVEL_STEPS = "episode/" + terrain.KIND_LEVEL_STEPS
"""The curve's key of the mean steps the ended episodes spent on one terrain kind and level (proportional to the
robots' time there): 60 numbers a log, kept out of the curve and TensorBoard (they would double a kept run's
metrics.jsonl.gz) and written with each checkpoint's progress.json, whence a resume restores the curriculum kind
by kind (checkpoint_level_shares_by_kind)."""
_BY_KIND = re.compile(terrain.KIND_LEVEL_STEPS.format("[a-z_]+", r"\d+") + "(_std)?$")
"""Those keys, in training's and evaluations' logs alike (Brax's evaluator adds each one's spread, _std)."""


def curve_rows(run_dir: Path, step: int) -> list[dict]:
    """The run's curve's rows at or before `step`, in order, read once for what a resume takes from
    them (logged_level_shares, logged_learning_rate); lines cut short by a kill are left out. The gzipped
    copy (CURVE_KEPT) where CURVE is not there (continue_curve unpacks it on process 0 only)."""
    path, packed = Path(run_dir) / CURVE, Path(run_dir) / CURVE_KEPT
    try:
        text = path.read_text() if path.is_file() else gzip.decompress(packed.read_bytes()).decode()
    except (OSError, EOFError, UnicodeDecodeError):  # none, or unreadable (continue_curve names it on process 0)
        text = ""
    rows = []
    for line in text.splitlines():
        try:
            row = json.loads(line)
            if int(row["global_step"]) <= step:
                rows.append(row)
        except (ValueError, KeyError, TypeError):
            continue
    return rows


def _last_logged(rows: list[dict], read: Callable[[dict], T | None]) -> T | None:
    """read(row) of the last of `rows` for which it returns a value: it raises KeyError, ValueError or
    TypeError, or returns None, for rows that lack it (another row kind). None where no row has it."""
    for row in reversed(rows):
        try:
            value = read(row)
        except (ValueError, KeyError, TypeError):
            continue
        if value is not None:
            return value
    return None


def logged_level_shares(rows: list[dict], num_levels: int) -> tuple[float, ...] | None:
    """The share of robots on each of `num_levels` levels in the last of a curve's `rows` (curve_rows)
    that logged them (a rough run's training episodes), normalised; None where no row did (a flat
    run, a rough run resumed before its first log, a curve of another level count)."""

    def shares(row: dict) -> tuple[float, ...] | None:
        x = [float(row[LEVEL_SHARE.format(k)]) for k in range(num_levels)]
        ok = LEVEL_SHARE.format(num_levels) not in row and min(x) >= 0 and sum(x) > 0
        return tuple(round(v / sum(x), 6) for v in x) if ok else None

    return _last_logged(rows, shares)


def checkpoint_level_shares_by_kind(progress: dict, step: int, num_levels: int) -> tuple[tuple[float, ...], ...] | None:
    """The shares of the robots' time on each terrain kind (KINDS order) and level that a run's progress.json
    recorded with its checkpoint at `step` (KIND_LEVEL_STEPS, normalised over all), one row per kind; None
    where it recorded none at that step (a checkpoint older than progress.json's, a run from before these
    shares, a flat run, a terrain of another level count, or nothing logged yet)."""
    metrics = progress.get("metrics")
    if progress.get("global_step") != step or not isinstance(metrics, dict):
        return None
    try:
        rows = tuple(
            tuple(float(metrics[KIND_LEVEL_STEPS.format(kind, k)]) for k in range(num_levels)) for kind in KINDS
        )
    except (KeyError, TypeError, ValueError):
        return None
    values = [v for row in rows for v in row]
    total = sum(values)
    if KIND_LEVEL_STEPS.format(KINDS[0], num_levels) in metrics or min(values) < 0 or not 0 < total < float("inf"):
        return None
    return tuple(tuple(round(v / total, 6) for v in row) for row in rows)


def logged_learning_rate(rows: list[dict]) -> float | None:
    """The learning rate in the last of a curve's `rows` (curve_rows) that logged one (Brax's
    "training/learning_rate": the adaptive-KL schedule's), or None where none did."""

    def rate(row: dict) -> float | None:
        value = float(row["training/learning_rate"])
        return value if 0.0 < value < float("inf") else None

    return _last_logged(rows, rate)


def finish_run(run_dir: Path) -> tuple[int, str] | None:
    """Writes run_dir/policy from the run's newest intact checkpoint where it is missing, damaged or
    older than that checkpoint (a run killed after its last checkpoint, during its final
    evaluation). Returns (the step written, what was wrong), or None when policy/ was the final one
    already (or there is no intact checkpoint)."""
    problem = policy_problem(run_dir)
    if problem is None:
        return None
    env_config, ppo = load_run_config(run_dir)
    state_file = Path(run_dir) / "progress.json"
    recorded = json.loads(state_file.read_text()) if state_file.is_file() else {}
    step = write_policy(Path(run_dir), env_config, ppo, recorded.get("machine") or machine())
    return (step, problem) if step is not None else None


class _OutOfTime(Exception):
    """Raised from Brax's progress callback to stop training at a checkpoint (max_wall_s)."""


class WallTimeBudget:
    """Whether a call with `max_wall_s` seconds (None: no limit) should stop at the checkpoint
    just written: it stops when one more epoch (training, checkpoint, evaluation) would end past
    the budget. The next epoch is timed as the last one, except after the first, whose time holds
    the compilation (minutes for the adaptive feet): that one is estimated from the throughput of
    the training-episode logs (Brax's episode/sps, the first log left out for the same reason)
    plus the evaluation's time (next_epoch_seconds)."""

    def __init__(self, max_wall_s: float | None, steps_per_epoch: int, start_s: float):
        self.max_wall_s = max_wall_s
        self.steps_per_epoch = steps_per_epoch
        self.start_s = start_s
        self.last_epoch_end_s = start_s
        self.epochs = 0
        self.throughput_logs = 0
        self.steps_per_s: float | None = None
        self.stopped = False

    def record(self, metrics: dict) -> None:
        """Notes the training throughput of a training-episodes log."""
        if "episode/sps" in metrics:
            self.throughput_logs += 1
            if self.throughput_logs > 1:  # the first log's interval holds the compilation
                self.steps_per_s = float(metrics["episode/sps"])

    def out_of_time(self, now_s: float, evaluation_s: float = 0.0) -> bool:
        """At the end of an epoch (now_s, its evaluation's seconds): whether to stop here."""
        epoch_s = next_epoch_seconds(
            now_s - self.last_epoch_end_s, self.epochs == 0, self.steps_per_s, self.steps_per_epoch, evaluation_s
        )
        self.last_epoch_end_s = now_s
        self.epochs += 1
        return self.max_wall_s is not None and now_s + epoch_s > self.start_s + self.max_wall_s


def _check_run_settings(ppo: PPOConfig, max_wall_s: float | None) -> None:
    """Raises InputError for settings this machine cannot run: bad hyperparameters, a time budget
    that is not positive or spans several processes, robots that do not split over the devices."""
    import jax

    ppo.check()
    if max_wall_s is not None and max_wall_s <= 0:
        raise InputError(f"max_wall_s must be positive, got {max_wall_s}", fix="give a positive time budget")
    if max_wall_s is not None and jax.process_count() > 1:  # only process 0 would stop; the others would wait
        raise InputError(
            "a wall-time budget works on one machine only (one JAX process)",
            fix="leave out the time budget with --coordinator",
        )
    if ppo.num_envs % jax.device_count():
        raise InputError(
            f"num_envs ({ppo.num_envs}) must be a multiple of the number of JAX devices "
            f"({jax.device_count()}): Brax splits the robots evenly over them",
            fix=f"e.g. --num-envs {ppo.num_envs - ppo.num_envs % jax.device_count() or jax.device_count()}",
        )


def _initialisation(source: Path, env_config: EnvConfig, ppo: PPOConfig, notice):
    """(step, parameters) of the newest intact checkpoint of run `source`, refused where its
    networks cannot be this run's: other observations (policy type, PD targets, height scan, a
    haptic policy on other feet), another critic, other hidden layers or observation normalising."""
    from footforge.envs import observation_layout

    source_env, source_ppo = load_run_config(source)
    problems = []
    if (source_env.haptic or env_config.haptic) and source_env.feet != env_config.feet:
        problems.append(
            f"a haptic policy reads its feet's joints: feet {source_env.feet} there, {env_config.feet} here"
        )
    else:
        widths = observation_layout.size(source_env, 16), observation_layout.size(env_config, 16)
        if widths[0] != widths[1]:
            problems.append(
                f"observation width {widths[0]} there, {widths[1]} here (policy {source_env.policy} / "
                f"{env_config.policy})"
            )
    for name in ("policy_hidden_layers", "value_hidden_layers", "normalize_observations"):
        if getattr(source_ppo, name) != getattr(ppo, name):
            problems.append(f"{name} {getattr(source_ppo, name)} there, {getattr(ppo, name)} here")
    if source_env.privileged_critic != env_config.privileged_critic:
        problems.append(f"privileged_critic {source_env.privileged_critic} there, {env_config.privileged_critic} here")
    if problems:
        raise InputError(
            f"--init-from {source}: its networks do not fit this run: {'; '.join(problems)}",
            file=str(source / "config.json"),
            fix="start from a run with the same networks, or without --init-from",
        )
    step, params = resume_point(source, notice, set_aside=False)
    notice(f"starting from the parameters of {source} at step {step:,}")
    return step, params


def _origin(source: Path, step: int) -> dict:
    """config.json's "initialised_from" of a run started from checkpoint `step` of run `source`: the
    source, that step, and "steps_before", the steps trained before this run in all (the step, plus
    the steps the source had started from where it was itself initialised from another run)."""
    earlier = json.loads((source / "config.json").read_text()).get("initialised_from")
    before = step + (steps_before(earlier) if earlier else 0)
    return {"run": os.path.abspath(source), "step": step, "steps_before": before}


def _resume_state(run_dir: Path, env_config: EnvConfig, ppo: PPOConfig, notice, primary: bool):
    """(steps done, the checkpoint to restore, the number of this resume, training seconds so far)
    of the run in run_dir, refused where it was started with other settings."""
    saved_env, saved_ppo = load_run_config(run_dir)
    # The engine (EnvConfig.physics) may change between calls: both step the same model, so a run
    # started on a GPU (mjx) resumes on a CPU (mujoco) and back.
    saved = json.loads(
        json.dumps({"env": to_dict(saved_env) | {"physics": None}, "ppo": to_dict(saved_ppo) | {"num_timesteps": 0}})
    )
    now = json.loads(
        json.dumps({"env": to_dict(env_config) | {"physics": None}, "ppo": to_dict(ppo) | {"num_timesteps": 0}})
    )
    differences = config_differences(saved, now)  # tuples as lists: compared as JSON
    if differences:
        raise InputError(
            f"the run was started with other settings: {'; '.join(differences)}",
            file=str(run_dir / "config.json"),
            fix="resume with the run's own settings (the pipelines read them from config.json), "
            "or start a new run with another --out",
        )
    offset, restore = resume_point(run_dir, notice, set_aside=primary)
    state_file = run_dir / "progress.json"
    previous = json.loads(state_file.read_text()) if state_file.exists() else {}
    # Training time of the earlier calls, up to their last checkpoint (a killed call's time after
    # it is lost with its work).
    return offset, restore, previous.get("resumes", 0) + 1, previous.get("wall_s_total", previous.get("wall_s", 0.0))


def train(
    env_config: EnvConfig,
    ppo: PPOConfig,
    run_dir: Path,
    *,
    resume: bool = False,
    force: bool = False,
    progress: Callable[[int, int, dict, bool], None] | None = None,
    max_wall_s: float | None = None,
    notice: Callable[[str], None] | None = None,
    evaluate: bool = True,
    init_from: Path | None = None,
    recipe: dict | None = None,
) -> dict:
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
    `recipe`: {"preset": name, "overrides": [...]} that resolve to these configs (rl.presets), kept in
    config.json; a resume keeps the run's own.

    Raises:
      InputError: bad hyperparameters; a run folder that needs --resume or --force; --resume
        without an intact checkpoint or with other configs; `init_from` with `resume`, or a source
        whose networks do not fit this run.
    """
    import jax
    from brax.training.agents.ppo import train as ppo_train
    from tensorboardX import SummaryWriter

    from footforge.envs import enable_float64_physics, from_config
    from footforge.envs.randomization import randomizer
    from footforge.envs.wrappers import wrap_for_training
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
            raise InputError(
                "--init-from starts a new run from another run's parameters; --resume continues this one",
                fix="give one of them",
            )
        step, restore = _initialisation(Path(init_from), env_config, ppo, notice)
        origin = {"initialised_from": _origin(Path(init_from), step)}
    run_dir = (
        prepare_run_dir(run_dir, resume=resume, force=force, notice=notice)
        if primary
        else Path(os.path.abspath(run_dir))
    )
    state_file = run_dir / "progress.json"
    if resume:
        offset, restore, resumes, wall_s_before = _resume_state(run_dir, env_config, ppo, notice, primary)
        saved = json.loads((run_dir / "config.json").read_text())
        origin = {k: v for k, v in saved.items() if k in ("initialised_from", "recipe")}
        if "recipe" in origin and saved.get("ppo", {}).get("num_timesteps") != ppo.num_timesteps:
            # --timesteps moved the run's total: its recipe says so (rl.presets), so that it still
            # resolves to config.json.
            kept = [o for o in origin["recipe"].get("overrides", []) if not o.startswith("ppo.num_timesteps=")]
            origin["recipe"] = origin["recipe"] | {"overrides": kept + [f"ppo.num_timesteps={ppo.num_timesteps}"]}
    elif recipe is not None:
        origin["recipe"] = recipe
    if primary:
        write_json(
            run_dir / "config.json", {"env": to_dict(env_config), "ppo": to_dict(ppo), "evaluations": evaluate} | origin
        )
    remaining = ppo.num_timesteps - offset
    if remaining <= 0:
        if primary:
            finished = finish_run(run_dir)
            if finished:
                notice(f"{run_dir}: {finished[1]}: wrote policy/ from checkpoint {finished[0]:,}")
        return json.loads(state_file.read_text()).get("metrics", {}) if state_file.exists() else {}
    # The curve continues from the restored checkpoint (module docstring).
    evaluated_at_offset = continue_curve(run_dir, offset, resumes) if resume and primary else False

    # What a resume takes from the curve so far, read once: a rough run's robots start on the levels where
    # its curriculum stood (CurriculumConfig.initial_level_shares; config.json keeps the configuration the
    # run began with), and the adaptive learning rate goes on where it stood (module docstring).
    logged = curve_rows(run_dir, offset) if resume else []
    shares = logged_level_shares(logged, env_config.terrain.num_levels) if env_config.task == "rough" else None
    resumed_rate = logged_learning_rate(logged) if ppo.adaptive_kl else None
    del logged
    by_kind = (
        checkpoint_level_shares_by_kind(json.loads(state_file.read_text()), offset, env_config.terrain.num_levels)
        if resume and env_config.task == "rough" and state_file.exists()
        else None
    )
    if shares is not None or by_kind is not None:
        if by_kind is not None:
            means = ", ".join(
                f"{kind} {sum(k * x for k, x in enumerate(row)) / sum(row):.2f}"
                for kind, row in zip(KINDS, by_kind)
                if sum(row) > 0
            )
            notice(f"the curriculum goes on kind by kind from the shares recorded with checkpoint {offset:,} ({means})")
        if shares is not None:
            notice(
                f"the curriculum goes on from the level shares logged at or before step {offset:,} (mean level "
                f"{sum(k * x for k, x in enumerate(shares)):.2f})"
                + (" where a kind recorded none" if by_kind is not None else "")
            )
        curriculum = replace(env_config.curriculum, initial_level_shares=shares, initial_level_shares_by_kind=by_kind)
        env = from_config(replace(env_config, curriculum=curriculum))
    else:
        env = from_config(env_config)  # Brax evaluates on the same environment
    if primary and env_config.task == "rough":  # the terrain this run walks
        from footforge.envs.terrain import preview

        with atomic_file(run_dir / "terrain.png") as tmp:
            preview(env.terrain, tmp)
    # On a resume, TensorBoard hides what the killed call logged after the checkpoint (purge_step).
    writer = SummaryWriter(str(run_dir / "tensorboard"), purge_step=offset + 1 if resume else None) if primary else None
    epochs = training_epochs(ppo, offset)
    total = planned_steps(ppo, offset)  # what Brax will run: whole iterations
    # Until this call logs its own, its checkpoints record the shares it resumed from.
    last: dict = (
        {}
        if by_kind is None
        else {KIND_LEVEL_STEPS.format(kind, k): x for kind, row in zip(KINDS, by_kind) for k, x in enumerate(row)}
    )
    t0 = time.time()
    this_machine = machine()
    budget = WallTimeBudget(max_wall_s, (total - offset) // epochs, t0)  # Brax's epochs: whole iterations

    def save(step: int, make_policy, params) -> None:
        global_step = offset + step
        if step == 0:
            return
        save_checkpoint(
            run_dir, global_step, params, env.observation_size, env.action_size, ppo, env_config.privileged_critic
        )
        write_json(
            state_file,
            {
                "global_step": global_step,
                "resumes": resumes,
                "metrics": last,
                "wall_s": time.time() - t0,
                "wall_s_total": wall_s_before + time.time() - t0,
                "num_timesteps": ppo.num_timesteps,
                "machine": this_machine,
                "physics": env_config.physics,
            },
        )

    def log(step: int, metrics: dict) -> None:
        if not primary:
            return
        global_step = offset + step
        now = {k: float(v) for k, v in metrics.items() if hasattr(v, "__float__")}
        last.update(now)
        # A resumed call's first evaluation evaluates the checkpoint's parameters, which the curve
        # holds already unless the killed call died before evaluating them.
        if not (step == 0 and evaluated_at_offset):
            curve = {k: v for k, v in now.items() if not _BY_KIND.search(k)}  # those go to progress.json
            for key, value in curve.items():
                writer.add_scalar(key, value, global_step)  # type: ignore[union-attr]  # primary: a writer
            writer.flush()  # type: ignore[union-attr]
            with open(run_dir / CURVE, "a") as f:  # one line per evaluation or training-episodes log
                f.write(
                    json.dumps({"global_step": global_step, "wall_s": wall_s_before + time.time() - t0} | curve) + "\n"
                )
        # The end of an epoch (its checkpoint written, its evaluation run if any) is the call that
        # carries Brax's training/sps; the initial evaluation and the training-episode logs do not.
        epoch_end = "training/sps" in metrics
        budget.record(metrics)
        if progress:
            progress(global_step, total, last, epoch_end or "eval/walltime" in metrics)
        # Stop here if one more epoch, timed as the last one (training, checkpoint, evaluation),
        # would overrun the budget.
        if max_wall_s is not None and step > 0 and epoch_end and offset + step < total:
            if budget.out_of_time(time.time(), float(metrics.get("eval/epoch_eval_time", 0.0))):
                raise _OutOfTime()

    if resumed_rate is not None:
        notice(f"the adaptive learning rate goes on from {resumed_rate:.3g} (logged at or before step {offset:,})")
    try:
        _run_ppo(
            ppo_train,
            env,
            env_config,
            ppo if resumed_rate is None else replace(ppo, learning_rate=resumed_rate),
            remaining,
            epochs,
            restore,
            resumes,
            log,
            save,
            wrap_for_training,
            randomizer,
            evaluate,
        )
    except _OutOfTime:
        budget.stopped = True
    if writer:
        writer.close()
    if primary:
        write_policy(run_dir, env_config, ppo, this_machine)
    if budget.stopped:
        last["stopped_for_time"] = 1.0
        if primary and state_file.exists():
            write_json(
                state_file, json.loads(state_file.read_text()) | {"metrics": last, "stopped": "wall-time budget"}
            )
    return last


def next_epoch_seconds(
    last_epoch_s: float, first: bool, steps_per_s: float | None, steps_per_epoch: int, evaluation_s: float = 0.0
) -> float:
    """The wall time the next epoch will take (for the max_wall_s stop): the last epoch's, except
    after the first epoch, whose time holds the compilation; that one is estimated as its steps at
    the measured training throughput plus an evaluation, when a throughput was measured, and never
    above the observed time."""
    if first and steps_per_s:
        return min(last_epoch_s, steps_per_epoch / steps_per_s + evaluation_s)
    return last_epoch_s


def machine() -> dict:
    """What trains, for the policy card: JAX's backend and devices (over every process), the
    processes, this machine's CPU cores and operating system."""
    import platform

    import jax

    devices = jax.devices()
    return {
        "backend": jax.default_backend(),
        "devices": len(devices),
        "device_kind": devices[0].device_kind,
        "processes": jax.process_count(),
        "cpu_cores": os.cpu_count(),
        "platform": platform.platform(),
        "jax": jax.__version__,
    }


def _run_ppo(
    ppo_train,
    env,
    env_config: EnvConfig,
    ppo: PPOConfig,
    remaining: int,
    epochs: int,
    restore,
    resumes: int,
    log,
    save,
    wrap_for_training,
    randomizer,
    evaluate: bool = True,
) -> None:
    from footforge.rl import jax_compat

    with jax_compat.brax_compiles_once():  # its training epoch and evaluation compiled once each, not twice
        ppo_train.train(
            environment=env,
            num_timesteps=remaining,
            episode_length=env_config.episode_steps,
            num_envs=ppo.num_envs,
            unroll_length=ppo.unroll_length,
            batch_size=ppo.batch_size,
            num_minibatches=ppo.num_minibatches,
            num_updates_per_batch=ppo.num_updates_per_batch,
            learning_rate=ppo.learning_rate,
            entropy_cost=ppo.entropy_cost,
            discounting=ppo.discounting,
            gae_lambda=ppo.gae_lambda,
            clipping_epsilon=ppo.clipping_epsilon,
            vf_loss_coefficient=ppo.vf_loss_coefficient,
            max_grad_norm=ppo.max_grad_norm,
            reward_scaling=ppo.reward_scaling,
            normalize_observations=ppo.normalize_observations,
            bootstrap_on_timeout=True,
            learning_rate_schedule="ADAPTIVE_KL" if ppo.adaptive_kl else None,
            desired_kl=ppo.adaptive_kl or 0.01,
            network_factory=network_factory(ppo, env_config.privileged_critic),
            seed=ppo.seed + 1000 * resumes,
            num_evals=epochs + 1,
            run_evals=evaluate,
            num_eval_envs=ppo.num_eval_envs,
            progress_fn=log,
            policy_params_fn=save,
            restore_params=tuple(restore) if restore is not None else None,
            wrap_env_fn=wrap_for_training,
            randomization_fn=randomizer(env),  # EnvConfig.randomization: one draw per robot for the run
            # Evaluations (the learning curve) run the policy's mean, as a deployed policy runs.
            deterministic_eval=True,
            # Training episodes' metrics (episode/...: the terrain levels the curriculum reached, reward
            # terms, tracking errors), logged between evaluations.
            log_training_metrics=True,
            training_metrics_steps=max(ppo.checkpoint_every_steps // 4, 1),
        )
