"""The run folder: what footforge writes where a training run lives, and the checks before it does.

footforge marks the folder as a training run (footforge.outputs.MARKER). Training into a folder
that already holds a run is refused unless `resume` (continue it) or `force` (start over: only
the files and folders footforge writes in a run folder, RUN_ENTRIES, are removed; anything else
in the folder stays). These checks run before any compilation. `<run>/config.json` holds the
environment and PPO configs the run was started with (load_run_config).
"""

from __future__ import annotations

import gzip
import json
import os
import shutil
from collections.abc import Callable
from pathlib import Path

from footforge.atomic import atomic_file
from footforge.envs.config import EnvConfig
from footforge.errors import InputError
from footforge.outputs import MARKER, TRAINING_RUN, check_output_folder, marker_kind, write_marker
from footforge.rl.checkpoints import checkpoints, latest_checkpoint, latest_intact_checkpoint
from footforge.rl.config import PPOConfig, env_config_from_dict, from_dict

CURVE = "metrics.jsonl"
"""The learning curve: one JSON row per evaluation or training-episodes log, appended as the run goes."""
CURVE_KEPT = "metrics.jsonl.gz"
"""The same curve gzipped, as a run folder kept in git holds it (policies/README.md): about a sixth of the
bytes (the tracked tree's size limit, scripts/check_tree_size.py). A resume unpacks it into CURVE."""
CURVE_SET_ASIDE = "metrics.set_aside.jsonl"
"""Rows of the curve that a resume left behind (logged after the checkpoint it restored), each
with "set_aside_by_resume": the number of that resume."""

RUN_ENTRIES = (
    "config.json",
    "progress.json",
    CURVE,
    CURVE_KEPT,
    CURVE_SET_ASIDE,
    "tensorboard",
    "checkpoints",
    "policy",
    "terrain.png",
    MARKER,
)
"""What footforge writes in a run folder: all that `force` removes (with these names' temporaries)."""


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


def prepare_run_dir(
    run_dir: Path,
    *,
    resume: bool = False,
    force: bool = False,
    write: bool = True,
    notice: Callable[[str], None] | None = None,
) -> Path:
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
        raise InputError(
            "--resume and --force exclude each other: --resume continues the run, --force starts it over",
            fix="pass one of them",
        )
    if resume:
        if not (run_dir / "config.json").is_file():
            raise InputError(
                f"--out {given}: nothing to resume (no config.json: not a training run)",
                file=str(run_dir),
                fix="start without --resume, or give the folder of an earlier run",
            )
        if (run_dir / CURVE).exists() and (run_dir / CURVE_KEPT).exists():
            raise InputError(
                f"--out {given}: holds both {CURVE} and {CURVE_KEPT}, two copies of the learning curve, and a "
                "resume continues one",
                file=str(run_dir / CURVE_KEPT),
                fix=f"keep the one to continue: remove the other (or gunzip {CURVE_KEPT} into {CURVE} yourself)",
            )
        return run_dir
    if run_dir.is_dir() and any(run_dir.iterdir()):
        if is_run_folder(run_dir):
            last = latest_checkpoint(run_dir)
            # A run that never reached a checkpoint (stopped while compiling or in its first epoch)
            # has nothing to continue: the same command starts it again.
            unfinished = last is None and not (run_dir / "policy").exists()
            if not force and not unfinished:
                raise InputError(
                    f"--out {given}: holds a training run (its last checkpoint at step {last[0]:,})"
                    if last
                    else f"--out {given}: holds a finished training run",
                    fix="pass --resume to continue it, --force to start it over (removes only the "
                    "files footforge wrote there), or give another --out",
                )
            if write:
                removed = _remove_run_files(run_dir)
                if notice and removed:
                    why = "--force" if force else "the earlier run reached no checkpoint, so it starts again"
                    notice(f"{why}: removed its {', '.join(removed)} from {run_dir}")
        else:
            if not force:
                raise InputError(
                    f"--out {given}: the folder holds files footforge did not write (no {MARKER})",
                    fix="give another --out, or pass --force to train into it beside those files (they are kept)",
                )
            clash = [name for name in RUN_ENTRIES if (run_dir / name).exists() or (run_dir / name).is_symlink()]
            if clash:
                raise InputError(
                    f"--out {given}: holds {', '.join(clash)}, which footforge did not write and a run would overwrite",
                    fix="move them away or give another --out",
                )
    if write:
        run_dir.mkdir(parents=True, exist_ok=True)
        write_marker(run_dir, kind=TRAINING_RUN)
    return run_dir


def load_run_config(run_dir: Path) -> tuple[EnvConfig, PPOConfig]:
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
        raise InputError(
            "not a training run (no config.json)",
            file=str(run_dir),
            fix="give the folder of an earlier run, or start without --resume",
        ) from None
    except (OSError, ValueError, KeyError, TypeError) as e:
        raise InputError(
            f"unreadable ({type(e).__name__}: {e})",
            file=str(path),
            fix="start the run over with --force, or give another run",
        ) from None


def keep_run(run_dir: Path, dest: Path) -> list[str]:
    """Copies into `dest` what git keeps of the run in `run_dir` (policies/README.md): config.json,
    progress.json, the marker, the learning curve gzipped (CURVE_KEPT: a sixth of its bytes; a
    resume unpacks it), and the run's weights once. A run that reached its total keeps policy/ (and
    dest's checkpoints/ go); a run still in training keeps its newest intact checkpoint under
    checkpoints/ (the older checkpoints in dest go). dest's other files (evaluation/, closed_chain/)
    stay. Each entry is written beside its place and renamed in, so a kill leaves dest as it was or
    with whole entries. Returns what it wrote.

    Raises:
      InputError: run_dir is not a training run, has no intact checkpoint, or dest holds files that
        are not a run's.
    """
    run_dir, dest = Path(run_dir).resolve(), Path(dest).resolve()
    if not is_run_folder(run_dir) or not (run_dir / "progress.json").is_file():
        raise InputError(
            "not a training run (no config.json or progress.json)", file=str(run_dir), fix="give a run's --out"
        )
    if dest == run_dir:
        raise InputError("the run and where to keep it are the same folder", file=str(dest), fix="give another folder")
    if dest.exists() and any(dest.iterdir()) and not is_run_folder(dest):
        raise InputError(
            "holds files that are not a footforge run's, which keeping a run there could mix with its own",
            file=str(dest),
            fix="give a new folder or the folder this run was kept in before",
        )
    saved = json.loads((run_dir / "config.json").read_text())
    step = int(json.loads((run_dir / "progress.json").read_text()).get("global_step", 0))
    finished = step >= int(saved["ppo"]["num_timesteps"])
    if finished:
        from footforge.rl.policy_files import policy_problem  # it imports this module

        problem = "missing" if not (run_dir / "policy").is_dir() else policy_problem(run_dir)
        if problem:
            raise InputError(
                f"reached its total steps but its policy/ is not the final one ({problem})",
                file=str(run_dir / "policy"),
                fix=f"footforge train {saved['env'].get('task', 'flat')} --out {run_dir} --resume writes it",
            )
    newest = None if finished else latest_intact_checkpoint(run_dir)
    if not finished and newest is None:
        raise InputError(
            "has no intact checkpoint to keep", file=str(run_dir / "checkpoints"), fix="resume the run first"
        )
    dest.mkdir(parents=True, exist_ok=True)
    written = []
    for name in ("config.json", "progress.json", MARKER):
        if (run_dir / name).is_file():
            with atomic_file(dest / name) as tmp:
                shutil.copyfile(run_dir / name, tmp)
            written.append(name)
    if (run_dir / CURVE).is_file():
        with atomic_file(dest / CURVE_KEPT) as tmp:
            tmp.write_bytes(gzip.compress((run_dir / CURVE).read_bytes(), mtime=0))  # mtime 0: the same bytes each time
        (dest / CURVE).unlink(missing_ok=True)  # the gzipped copy replaces it (prepare_run_dir refuses both)
        written.append(CURVE_KEPT)
    if finished:
        _replace_tree(run_dir / "policy", dest / "policy")
        shutil.rmtree(dest / "checkpoints", ignore_errors=True)
        written.append("policy")
    else:
        assert newest is not None
        target = dest / "checkpoints" / newest[1].name
        target.parent.mkdir(exist_ok=True)
        _replace_tree(newest[1], target)
        for _, older in checkpoints(dest):
            if older != target:
                shutil.rmtree(older)
        written.append(f"checkpoints/{newest[1].name}")
    return written


def _replace_tree(source: Path, target: Path) -> None:
    """Copies the folder `source` to `target`, replacing it whole: a copy beside it, renamed in."""
    tmp = target.with_name(f".{target.name}.tmp-{os.getpid()}")
    shutil.rmtree(tmp, ignore_errors=True)
    shutil.copytree(source, tmp)
    if target.exists():
        old = target.with_name(f".{target.name}.old-{os.getpid()}")
        os.replace(target, old)
        os.replace(tmp, target)
        shutil.rmtree(old)
    else:
        os.replace(tmp, target)
