"""The run folder: what footforge writes where a training run lives, and the checks before it does.

footforge marks the folder as a training run (footforge.outputs.MARKER). Training into a folder
that already holds a run is refused unless `resume` (continue it) or `force` (start over: only
the files and folders footforge writes in a run folder, RUN_ENTRIES, are removed; anything else
in the folder stays). These checks run before any compilation. `<run>/config.json` holds the
environment and PPO configs the run was started with (load_run_config).
"""

from __future__ import annotations

import json
import shutil
from collections.abc import Callable
from pathlib import Path

from footforge.envs.config import EnvConfig
from footforge.errors import InputError
from footforge.outputs import MARKER, TRAINING_RUN, check_output_folder, marker_kind, write_marker
from footforge.rl.checkpoints import latest_checkpoint
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
